# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Cost of Warp's radix sort of (key, index) pairs at the fluid's size, against the key's bit count.

The fluid solver sorts one int32 key per fluid particle every substep (``neighbors.py``: world block
+ Morton code of the cell, ``table_bits + 1`` bits). This times ``wp.utils.radix_sort_pairs`` alone:
8 sorts captured in one CUDA graph (each after restoring the keys), replayed, minus the same graph
without the sorts. Prints a table and writes JSON.

Usage::

    python -m benchmarks radix_sort [--count 99960] [--bits 15 16 17 19 24 32] [--json out.json]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import warp as wp

from .dam_break import graph_ms
from .run_record import write_record

SORTS_PER_GRAPH = 8


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=99_960, help="keys (fluid particles)")
    parser.add_argument("--bits", type=int, nargs="+", default=[15, 16, 17, 19, 24, 32])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    wp.config.quiet = True
    device = wp.get_device(args.device)
    if not device.is_cuda:
        parser.error("needs a CUDA device (the timing replays CUDA graphs)")
    n = args.count
    rng = np.random.default_rng(0)
    rows = []
    print(f"{'device':<24}{'keys':>8}{'bits':>6}{'us/sort':>10}")
    with wp.ScopedDevice(device):
        for bits in args.bits:
            # sorted keys, as the solver's nearly are from one substep to the next
            source = wp.array(np.sort(rng.integers(0, min(2**bits, 2**31 - 1), n)).astype(np.int32))
            index = wp.array(np.arange(n, dtype=np.int32))
            keys = wp.zeros(2 * n, dtype=wp.int32)
            values = wp.zeros(2 * n, dtype=wp.int32)

            def restore(keys=keys, values=values, source=source, index=index):
                wp.copy(keys, source, count=n)
                wp.copy(values, index, count=n)

            def restore_and_sort(keys=keys, values=values, restore=restore, bits=bits):
                restore()
                wp.utils.radix_sort_pairs(keys, values, n, end_bit=bits)

            def sorts(body=restore_and_sort):
                for _ in range(SORTS_PER_GRAPH):
                    body()

            def restores(body=restore):
                for _ in range(SORTS_PER_GRAPH):
                    body()

            us = (graph_ms(device, sorts) - graph_ms(device, restores)) * 1000.0 / SORTS_PER_GRAPH
            rows.append({"bits": bits, "us_per_sort": us})
            print(f"{device.name:<24}{n:>8}{bits:>6}{us:>10.1f}")
    # Warp's sort alone, no fluid step: one key per fluid particle
    return write_record("radix_sort", device, {"particles": n, "keys": n}, args.json, rows=rows, fluid_step=False)


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
