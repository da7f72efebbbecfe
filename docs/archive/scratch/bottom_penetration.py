# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch: how far a still column's bottom layer presses into the floor's contact radius.

The column of ``python -m benchmarks rest_column`` (spacing d = 0.05 m on the rest lattice, radius d / 2, in a
closed frictionless box, 60 Hz, 8 x 2, the defaults) is settled for ``--seconds``; then, of the particles within a
spacing of the floor, how many sit nearer it than their radius (where upstream's particle-shape contact pushes them
out in every XPBD iteration) and by how much (docs/archive/validation_notebook.md, "The deep pool's pump and the
walls' contacts").

Usage: python docs/archive/scratch/bottom_penetration.py [--n 12] [--layers 24] [--seconds 3]
"""

import argparse

import warp as wp

import newton
from newton.examples.fluid.common import add_closed_box, add_water_lattice
from newton.examples.fluid.progress import track

SPACING = 0.05  # [m]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=12)
    parser.add_argument("--layers", type=int, default=24)
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    wp.config.quiet = True
    d = SPACING
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    add_water_lattice(builder, d, (args.n, args.n, args.layers))
    add_closed_box(builder, args.n * d, 1.5 * args.layers * d)
    model = builder.finalize("cpu")
    model.soft_contact_mu = 0.0
    solver = newton.solvers.SolverXPBD(model, iterations=2, fluid_rest_distance=d)
    pipeline = newton.CollisionPipeline(model, soft_contact_max=2 * model.particle_count, soft_contact_gap=0.5 * d)
    contacts = pipeline.contacts()
    states = [model.state(), model.state()]
    for _ in track(range(int(round(args.seconds * 60))), "bottom_penetration", unit="frame"):
        for _ in range(8):
            states[0].clear_forces()
            pipeline.collide(states[0], contacts)
            solver.step(states[0], states[1], None, contacts, 1.0 / 480.0)
            states[0], states[1] = states[1], states[0]
    z = states[0].particle_q.numpy()[:, 2]
    bottom = z[z < d]
    depth = 0.5 * d - bottom
    pressed = depth[depth > 0.0]
    mean = pressed.mean() / d if len(pressed) else 0.0
    print(
        f"{args.n} x {args.n} x {args.layers} after {args.seconds} s: {len(pressed)} of {len(bottom)} bottom particles "
        f"inside the floor's contact radius, by {mean:.4f} d on average and {depth.max() / d:.4f} d at most"
    )


if __name__ == "__main__":
    main()
