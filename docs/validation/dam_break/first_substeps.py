# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The Koshizuka & Oka column's first substeps: how fast its start lattice is thrown, with and without the correction.

The column starts as a lattice at the rest distance, at rest. Where its start reads compressed (the bottom
layer by the walls' corners) the density passes, and the coarse correction, move it apart, and the move becomes
velocity over the substep: the smaller the substep, the faster. For each substep count and correction share this
steps the scene of ``python -m benchmarks validate_dam_break`` (20 per L, ``fluid_density_kernel="one_kernel"``,
2 iterations) 1, 2, 4 and 16 substeps and prints the fastest particle (where it is, in spacings from the back
wall and the floor) and the mean vertical velocity. Run from the repository root:
``python docs/validation/dam_break/first_substeps.py [--substeps 8 128] [--shares 0 0.5] --json F``.
"""

import argparse
import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
from benchmarks.run_record import write_record  # noqa: E402
from benchmarks.validate_dam_break import L, Stepper, build  # noqa: E402
from newton.examples.fluid.progress import track  # noqa: E402

STEPS = (1, 2, 4, 16)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--substeps", type=int, nargs="+", default=[8, 128], help="substeps per 1/60 s frame")
    parser.add_argument("--shares", type=float, nargs="+", default=[0.0, 0.5], help="fluid_coarse_correction")
    parser.add_argument("--per-l", type=int, default=20)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    wp.config.quiet = True
    d = L / args.per_l
    rows = []
    for substeps, share in track(
        [(s, b) for s in args.substeps for b in args.shares], "first substeps", unit="setting"
    ):
        scene = argparse.Namespace(substeps=substeps, speed_clamp=0.0, floor_friction=0.0)
        model, solver, pipeline, dt = build(
            args.per_l,
            6,
            scene,
            wp.get_device(args.device),
            fluid_rest_distance=d,
            iterations=2,
            fluid_density_kernel="one_kernel",
            fluid_coarse_correction=share,
        )
        stepper = Stepper(model, solver, pipeline, dt)
        steps = []
        for n in STEPS:
            state = stepper.advance_to(n * dt)
            v, q = state.particle_qd.numpy(), state.particle_q.numpy()
            speed = np.linalg.norm(v, axis=1)
            i = int(speed.argmax())
            steps.append(
                {
                    "substep": n,
                    "max_speed_m_s": float(speed[i]),
                    "fastest_x_spacings": float(q[i, 0] / d),
                    "fastest_z_spacings": float(q[i, 2] / d),
                    "mean_vertical_velocity_m_s": float(v[:, 2].mean()),
                }
            )
        stats = solver.fluid_diagnostics(stepper.state)
        rows.append(
            {
                "substeps": substeps,
                "fluid_coarse_correction": share,
                "particles": int(model.particle_count),
                "iterations": 2,
                "mean_abs_density_error": stats["mean_abs_density_error"],
                "max_compression": stats["max_compression"],
                "steps": steps,
            }
        )
        print(
            f"{substeps:>4} substeps, correction {share}: "
            + "; ".join(
                f"after {s['substep']}: max {s['max_speed_m_s']:.3f} m/s at x {s['fastest_x_spacings']:.1f}, "
                f"z {s['fastest_z_spacings']:.1f} d, mean vz {s['mean_vertical_velocity_m_s']:+.4f}"
                for s in steps
            ),
            flush=True,
        )
    write_record("dam_break_first_substeps", wp.get_device(args.device), {"per_l": args.per_l}, args.json, rows=rows)


if __name__ == "__main__":
    main()
