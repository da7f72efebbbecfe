# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""What still moves in a settled pool: long waves or particle-scale churn.

The column of ``benchmarks/rest_column.py`` (``--n`` x ``--n`` x ``--layers`` at 0.05 m in a closed
frictionless box, the defaults' 8 x 2), started on its lattice. Every ``--every`` frames the fluid's
kinetic energy per mass is split in three: the whole fluid's mean velocity (the column moving
together: its first acoustic mode, or sloshing), the coarse cells' mean velocities less that (waves
longer than ``--cell`` spacings) and the rest, each particle against its cell's mean (particle-scale
churn). Prints the RMS speed of each part and writes them with the time, the centre of mass and the
top layer's spread to JSON. docs/archive/validation_notebook.md, "What moves in still water".

Usage: python docs/validation/still_modes/pool_modes.py --out F.json [--device cuda:0 --n 50 --layers 40]
"""

import argparse
import json
import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
from benchmarks.frames import add_solver_arguments, contact_frames  # noqa: E402
from benchmarks.rest_column import SPACING, build, velocity_scales  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=12)
    parser.add_argument("--layers", type=int, default=40)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--every", type=int, default=2, help="frames between samples")
    parser.add_argument("--cell", type=int, default=4, help="coarse cell size [spacings]")
    parser.add_argument("--out", required=True)
    add_solver_arguments(parser)
    args = parser.parse_args()
    d = SPACING
    with wp.ScopedDevice(args.device):
        model = build(args.n, args.layers, args.device)
        solver, frames = contact_frames(model, args, d, args.device)
        states = frames.states
        top = model.particle_q.numpy()[:, 2] > (args.layers - 1) * d
        rows = []
        for frame in range(round(args.seconds * 60)):
            frames()
            if frame % args.every == args.every - 1:
                q = states[0].particle_q.numpy().astype(np.float64)
                v = states[0].particle_qd.numpy().astype(np.float64)
                whole, coarse, fine = velocity_scales(q, v, args.cell * d)
                com = q.mean(axis=0)
                rows.append(
                    {
                        "t_s": (frame + 1) / 60.0,
                        "rms_m_s": float(np.sqrt((v * v).sum(1).mean())),
                        "mean_m_s": whole,
                        "coarse_m_s": coarse,
                        "fine_m_s": fine,
                        "mean_velocity_m_s": v.mean(axis=0).tolist(),
                        "centre_m": com.tolist(),
                        "top_span_spacings": float(np.ptp(q[top, 2]) / d),
                    }
                )
                r = rows[-1]
                print(
                    f"{r['t_s']:5.2f} s  rms {r['rms_m_s']:.4f}  mean {whole:.4f}  coarse {coarse:.4f}  "
                    f"fine {fine:.4f}  top {r['top_span_spacings']:.2f}",
                    flush=True,
                )
    record = {"device": args.device, "particles": int(model.particle_count), "n": args.n, "layers": args.layers}
    record.update(substeps=args.substeps, iterations=solver.iterations, cell_spacings=args.cell, rows=rows)
    with open(args.out, "w") as f:
        json.dump(record, f)


if __name__ == "__main__":
    wp.config.quiet = True
    main()
