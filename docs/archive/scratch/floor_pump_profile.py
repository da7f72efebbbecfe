# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch: where a settled deep fluid's particle-scale motion lives, by height and by distance from the side walls.

The fluid of ``python -m benchmarks rest_column`` (default 24 x 24 x 40, 8 x 2, the defaults unless the solver's flags
say otherwise) is settled for ``--settle`` seconds; then, over ``--measure`` seconds, each particle's speed against
its cell's mean (cells of ``CELL`` spacings, rest_column's "fine" part) is averaged by layer (z / d) and by the
distance to the nearest side wall [d] (docs/archive/validation_notebook.md, "The floor's pump"). With
``docs/archive/patches/density_sees_constraint_moves.patch`` put on, the same for the density passes that start
from the contacts' moves.

Usage (from the repository root):
    PYTHONPATH=. python docs/archive/scratch/floor_pump_profile.py [--n 24] [--layers 40] [--settle 7] [--measure 1]
        [--soft-contact-relaxation 0.2] ...
"""

import argparse

import numpy as np
import warp as wp

from benchmarks import rest_column
from benchmarks.frames import add_solver_arguments, contact_frames
from newton.examples.fluid.progress import track


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=24)
    parser.add_argument("--layers", type=int, default=40)
    parser.add_argument("--settle", type=float, default=7.0, help="[s]")
    parser.add_argument("--measure", type=float, default=1.0, help="[s]")
    add_solver_arguments(parser)
    args = parser.parse_args()
    wp.config.quiet = True
    d = rest_column.SPACING
    device = wp.get_device(args.device)
    with wp.ScopedDevice(device):
        model = rest_column.build(args.n, args.layers, device)
        _, frame = contact_frames(model, args, d, device)
        for _ in track(range(round(args.settle * 60)), "floor_pump_profile: settling", unit="frame"):
            frame()
        layers, walls = args.layers + 4, args.n // 2 + 1
        by_layer, in_layer = np.zeros(layers), np.zeros(layers)
        by_wall, at_wall = np.zeros(walls), np.zeros(walls)
        side = args.n * d
        for _ in track(range(round(args.measure * 60)), "floor_pump_profile: measuring", unit="frame"):
            frame()
            q = frame.states[0].particle_q.numpy().astype(np.float64)
            v = frame.states[0].particle_qd.numpy().astype(np.float64)
            fine2 = np.sum((v - rest_column.cell_velocity(q, v, rest_column.CELL * d)) ** 2, axis=1)
            layer = np.clip((q[:, 2] / d).astype(int), 0, layers - 1)
            wall = np.minimum(np.minimum(q[:, 0], side - q[:, 0]), np.minimum(q[:, 1], side - q[:, 1]))
            wall = np.clip((wall / d).astype(int), 0, walls - 1)
            np.add.at(by_layer, layer, fine2)
            np.add.at(in_layer, layer, 1)
            np.add.at(by_wall, wall, fine2)
            np.add.at(at_wall, wall, 1)
    rms = np.sqrt(by_layer.sum() / in_layer.sum())
    print(f"particle-scale RMS speed [m/s] over {args.settle:g}-{args.settle + args.measure:g} s: {rms:.4f}")
    print("by layer:", " ".join(f"{k}:{np.sqrt(by_layer[k] / in_layer[k]):.4f}" for k in range(layers) if in_layer[k]))
    print(
        "by side-wall distance:",
        " ".join(f"{k}:{np.sqrt(by_wall[k] / at_wall[k]):.4f}" for k in range(walls) if at_wall[k]),
    )


if __name__ == "__main__":
    main()
