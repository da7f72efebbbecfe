# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""A step in the free surface: does it flatten, as water does, or does the packing hold part of it?

A slice ``--nx`` x ``--ny`` x ``--base`` particles (0.05 m) in a closed frictionless box, with ``--step``
more layers on its left half, started on the lattice (CPU, the defaults' 8 x 2). Every quarter second:
the mean height of the top particle of each column over the left quarter less the right quarter (the
step) and the spread of the top particles, both in spacings, and the RMS speed. docs/archive/
validation_notebook.md, "What moves in still water".

Usage: python docs/validation/still_modes/surface_step.py --out F.json [--step 2 --seconds 4 ...]
"""

import argparse
import json
import sys

import numpy as np
import warp as wp

import newton

sys.path.insert(0, ".")
from benchmarks.frames import add_solver_arguments, contact_frames  # noqa: E402
from newton.examples.fluid.common import add_closed_box  # noqa: E402
from newton.tests.test_solver_xpbd_fluid import add_block  # noqa: E402

SPACING = 0.05  # [m]


def build(nx: int, ny: int, base: int, step: int):
    d = SPACING
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    for columns, layers, z0 in ((nx, base, 0), (nx // 2, step, base)):
        add_block(
            builder, (columns, ny, layers), (0.5 * d, 0.5 * d, (z0 + 0.5) * d), d, mass=1000.0 * d**3, radius=0.5 * d
        )
    add_closed_box(builder, nx * d, 3.0 * (base + step) * d, width=ny * d)
    model = builder.finalize(device="cpu")
    model.soft_contact_mu = 0.0
    return model


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nx", type=int, default=24)
    parser.add_argument("--ny", type=int, default=6)
    parser.add_argument("--base", type=int, default=6)
    parser.add_argument("--step", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--out", required=True)
    add_solver_arguments(parser)
    args = parser.parse_args()
    d = SPACING
    model = build(args.nx, args.ny, args.base, args.step)
    _, frames = contact_frames(model, args, d, "cpu")
    states = frames.states
    quarter = args.nx // 4
    rows = []
    for frame in range(round(args.seconds * 60)):
        frames()
        if frame % 15 == 14:
            q, v = states[0].particle_q.numpy(), states[0].particle_qd.numpy()
            column = np.clip((q[:, 0] / d).astype(int), 0, args.nx - 1)
            top = np.array([q[column == k, 2].max() for k in range(args.nx)])
            step = float((top[:quarter].mean() - top[-quarter:].mean()) / d)
            row = ((frame + 1) / 60.0, step, float(np.ptp(top) / d), float(np.sqrt((v * v).sum(1).mean())))
            rows.append(row)
            print(f"{row[0]:.2f} s  step {row[1]:+.3f} spacings  top spread {row[2]:.2f}  rms {row[3]:.4f} m/s")
    with open(args.out, "w") as f:
        json.dump({"columns": ["t_s", "step_spacings", "top_spread_spacings", "rms_speed_m_s"], "rows": rows}, f)


if __name__ == "__main__":
    wp.config.quiet = True
    main()
