# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch: the mean neighbour count of the dam break of ``python -m benchmarks dam_break`` over its first seconds.

The scene of the benchmark (no obstacles, jitter 0.1, frictionless, 60 Hz, 8 x 2) at ``--particles`` on the CPU,
with ``--density-kernel``; every ``--every`` frames the mean number of other particles within the smoothing
length (a k-d tree on the positions, independent of the solver's lists). The work of the density passes grows with
it, so two kernels that cost the same per pair cost in proportion to it (docs/archive/performance_notebook.md,
"The one kernel's cost is its neighbours").

Usage: python docs/archive/scratch/dam_break_neighbours.py [--particles 10000] [--density-kernel one_kernel]
[--frames 150] [--every 15] [--json out.json]
"""

import argparse
import json

import numpy as np
import warp as wp
from scipy.spatial import cKDTree

import newton
from newton.examples.fluid.example_fluid_xpbd_dam_break import add_dam_break
from newton.examples.fluid.progress import track


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=int, default=10000)
    parser.add_argument("--density-kernel", default="poly6", choices=("poly6", "one_kernel"))
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--every", type=int, default=15)
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    wp.config.quiet = True
    builder = newton.ModelBuilder()
    scene = add_dam_break(builder, args.particles, obstacles=False, jitter=0.1)
    model = builder.finalize(device="cpu")
    spacing, substeps = scene["spacing"], 8
    dt = 1.0 / 60.0 / substeps
    model.soft_contact_mu = 0.0
    model.particle_max_velocity = 1.0e5
    solver = newton.solvers.SolverXPBD(
        model, iterations=2, fluid_rest_distance=spacing, fluid_density_kernel=args.density_kernel
    )
    h = solver.fluid_smoothing_length
    collision = newton.CollisionPipeline(model, soft_contact_max=model.particle_count, soft_contact_gap=0.5 * spacing)
    contacts = collision.contacts()
    states = [model.state(), model.state()]
    rows = []
    for frame in track(range(1, args.frames + 1), "dam_break_neighbours", unit="frame"):
        for _ in range(substeps):
            states[0].clear_forces()
            collision.collide(states[0], contacts)
            solver.step(states[0], states[1], None, contacts, dt)
            states[0], states[1] = states[1], states[0]
        if frame % args.every == 0:
            q = states[0].particle_q.numpy().astype(np.float64)
            counts = np.array([len(found) - 1 for found in cKDTree(q).query_ball_point(q, h)])
            rows.append({"frame": frame, "mean_neighbours": float(counts.mean())})
    for row in rows:
        print(f"{args.density_kernel:>10}  frame {row['frame']:>4}  mean neighbours {row['mean_neighbours']:.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                {"particles": model.particle_count, "density_kernel": args.density_kernel, "rows": rows}, f, indent=1
            )


if __name__ == "__main__":
    main()
