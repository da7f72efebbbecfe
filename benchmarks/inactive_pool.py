# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Cost of the fluid's neighbour build with a pool of inactive fluid particles held in reserve.

An emitter keeps fluid particles inactive until it releases them; they sort into the left-out
entry of the cell table. This times ``build_neighborhood`` (sort and neighbour lists, the work done
once per substep) of a cubic block of active fluid with and without such a pool, on any device.
Prints a table and writes JSON.

Usage::

    python -m benchmarks inactive_pool [--active 50000] [--pool 50000] [--device cuda:0] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

import newton

from .run_record import machine_record

SPACING = 0.02  # [m]


def build_ms(device, active: int, pool: int, repeats: int) -> tuple[int, float]:
    side = round(active ** (1.0 / 3.0))
    grid = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3) * SPACING
    mass = 1000.0 * SPACING**3
    builder = newton.ModelBuilder()
    fluid = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)
    zero = [(0.0, 0.0, 0.0)]
    builder.add_particles(
        [tuple(p) for p in grid], zero * len(grid), [mass] * len(grid), [0.5 * SPACING] * len(grid), [fluid] * len(grid)
    )
    if pool:
        # parked below the block, inactive: fluid particles that take no part until released
        parked = [(0.0, 0.0, -1.0 - 1.0e-4 * k) for k in range(pool)]
        flags = [int(newton.ParticleFlags.FLUID)] * pool
        builder.add_particles(parked, zero * pool, [mass] * pool, [0.5 * SPACING] * pool, flags)
    model = builder.finalize(device=device)
    solver = newton.solvers.SolverXPBD(model, fluid_rest_distance=SPACING)
    state = model.state()
    solver._fluid.build_neighborhood(state.particle_q)
    times = []
    for _ in range(repeats):
        wp.synchronize_device(device)
        t0 = time.perf_counter()
        solver._fluid.build_neighborhood(state.particle_q)
        wp.synchronize_device(device)
        times.append((time.perf_counter() - t0) * 1000.0)
    return len(grid), statistics.median(times)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--active", type=int, default=50_000, help="active fluid particles (rounded to a cube)")
    parser.add_argument("--pool", type=int, default=50_000, help="inactive fluid particles")
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--device", default=None)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    wp.config.quiet = True
    device = wp.get_device(args.device)
    rows = []
    print(f"{'device':<24}{'active':>9}{'inactive':>9}{'ms/build':>10}")
    for pool in (0, args.pool):
        active, ms = build_ms(device, args.active, pool, args.repeats)
        rows.append({"active": active, "inactive": pool, "ms_per_build": ms})
        print(f"{device.name:<24}{active:>9}{pool:>9}{ms:>10.3f}")
    result = {
        "benchmark": "inactive_pool",
        **machine_record(device),
        "work": "one neighbour build (sort and lists), host-timed with synchronisation, median of repeats",
        "rows": rows,
    }
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    return result


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
