# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The rest column over time: mean height, RMS speed and mean vertical velocity every 6 frames.

The column of ``benchmarks/rest_column.py`` (default 12 x 12 x 40, CPU) from its lattice start, for the
solver that is importable now (apply a patch of ``docs/archive/patches`` to compare). A mean vertical
velocity as large as the RMS speed is the whole column moving together: its first acoustic mode.
docs/archive/validation_notebook.md, "The one-kernel column's slow breathing".

Usage: python docs/validation/one_kernel/column_series.py --out series.json [--layers 40 --seconds 5 ...]
"""

import argparse
import json
import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
from benchmarks.frames import add_solver_arguments, contact_frames  # noqa: E402
from benchmarks.rest_column import SPACING, build  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layers", type=int, default=40)
    parser.add_argument("--n", type=int, default=12)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--out", required=True)
    add_solver_arguments(parser)
    args = parser.parse_args()
    d = SPACING
    model = build(args.n, args.layers, "cpu")
    _, frames = contact_frames(model, args, d, "cpu")
    states = frames.states
    rows = []
    for frame in range(round(args.seconds * 60)):
        frames()
        if frame % 6 == 5:
            q, v = states[0].particle_q.numpy(), states[0].particle_qd.numpy()
            rows.append(
                (
                    (frame + 1) / 60.0,
                    float(q[:, 2].mean()),
                    float(np.sqrt((v * v).sum(1).mean())),
                    float(v[:, 2].mean()),
                )
            )
            print(
                f"{rows[-1][0]:.2f} s  mean z {rows[-1][1]:.5f} m  rms {rows[-1][2]:.4f} m/s  mean vz {rows[-1][3]:+.4f}"
            )
    with open(args.out, "w") as f:
        json.dump({"columns": ["t_s", "mean_z_m", "rms_speed_m_s", "mean_vz_m_s"], "rows": rows}, f)


if __name__ == "__main__":
    wp.config.quiet = True
    main()
