# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Where the still column's fastest particles are, and whether their density constraint holds them.

The column of ``benchmarks/rest_column.py`` (``--n`` x ``--n`` x ``--layers``, 0.05 m, the solver's
keywords from the same flags) settles for 2 s; over the next second, every frame, each particle's speed
and the density its last pass read (over the rest density; the constraint acts only above 1) are
recorded. Printed per group, by depth below the top particle and distance from the nearest side wall
(in spacings): the mean density read, the share of the frames' readings below rest (where the
particle's own constraint lets go), and the RMS and largest speed. docs/archive/validation_notebook.md,
"Where the fastest particles are".

``--trace``: instead, over issue #23's whole window (3 s after the 2 s), every frame whose fastest particle
exceeds 0.02 m/s prints its time, index, speed, depth and distance from a side wall, and at the end the
most displaced particle's start and end (archive, "The kernel's shape").

Usage: python docs/validation/still_modes/where_fastest.py [--n 12 --layers 24] [--json F.json | --trace]
"""

import argparse
import json
import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
from benchmarks import rest_column  # noqa: E402
from benchmarks.frames import add_solver_arguments, contact_frames  # noqa: E402

GROUPS = (
    ("top layer, by a wall", lambda depth, wall: (depth < 1) & (wall < 1)),
    ("top layer, inside", lambda depth, wall: (depth < 1) & (wall > 2)),
    ("second layer, by a wall", lambda depth, wall: (depth >= 1) & (depth < 2) & (wall < 1)),
    ("second layer, inside", lambda depth, wall: (depth >= 1) & (depth < 2) & (wall > 2)),
    ("below 4 layers, by a wall", lambda depth, wall: (depth > 4) & (wall < 1)),
    ("below 4 layers, inside", lambda depth, wall: (depth > 4) & (wall > 2)),
)


def trace(frame, edge: float, d: float):
    """Print every frame's fastest particle above 0.02 m/s over the next 3 s, then the most displaced one."""
    start = frame.states[0].particle_q.numpy().copy()
    for f in range(180):
        frame()
        speed = np.linalg.norm(frame.states[0].particle_qd.numpy(), axis=1)
        i = int(speed.argmax())
        if speed[i] > 0.02:
            q = frame.states[0].particle_q.numpy()
            wall = min(q[i, 0], edge - q[i, 0], q[i, 1], edge - q[i, 1]) / d
            depth = (q[:, 2].max() - q[i, 2]) / d
            print(f"t {2 + (f + 1) / 60:.2f} s  particle {i}  {speed[i]:.3f} m/s  depth {depth:.2f}  wall {wall:.2f}")
    q = frame.states[0].particle_q.numpy()
    moved = np.linalg.norm(q - start, axis=1) / d
    i = int(moved.argmax())
    print(f"most displaced: particle {i}, {moved[i]:.2f} spacings, from {start[i] / d} to {q[i] / d} [d]")
    print(f"more than 0.3 spacings: {int((moved > 0.3).sum())}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_solver_arguments(parser)
    parser.add_argument("--n", type=int, default=12)
    parser.add_argument("--layers", type=int, default=24)
    parser.add_argument("--trace", action="store_true", help="every frame's fastest particle over 2-5 s")
    args = parser.parse_args()
    wp.config.quiet = True
    d = rest_column.SPACING
    device = args.device or "cpu"
    model = rest_column.build(args.n, args.layers, device)
    solver, frame = contact_frames(model, args, d, device)
    fluid = solver._fluid
    for _ in range(120):
        frame()
    edge = args.n * d
    if args.trace:
        trace(frame, edge, d)
        return
    speeds, densities = [], []
    for _ in range(60):
        frame()
        slot = fluid.search.slot_of_particle.numpy()
        densities.append(fluid.density.numpy()[slot] / fluid.rest_density)
        speeds.append(np.linalg.norm(frame.states[0].particle_qd.numpy(), axis=1))
    speeds, densities = np.array(speeds), np.array(densities)
    q = frame.states[0].particle_q.numpy()
    wall = np.minimum.reduce([q[:, 0], edge - q[:, 0], q[:, 1], edge - q[:, 1]]) / d
    depth = (q[:, 2].max() - q[:, 2]) / d
    rows = []
    print(f"{'group':26}{'particles':>10}{'density':>9}{'below rest':>11}{'rms m/s':>9}{'max m/s':>9}")
    for name, select in GROUPS:
        s = select(depth, wall)
        row = {
            "group": name,
            "particles": int(s.sum()),
            "mean_density_over_rest": float(densities[:, s].mean()),
            "share_below_rest": float((densities[:, s] < 1.0).mean()),
            "rms_speed_m_s": float(np.sqrt((speeds[:, s] ** 2).mean())),
            "max_speed_m_s": float(speeds[:, s].max()),
        }
        rows.append(row)
        print(
            f"{name:26}{row['particles']:>10}{row['mean_density_over_rest']:>9.4f}{row['share_below_rest']:>11.2f}"
            f"{row['rms_speed_m_s']:>9.4f}{row['max_speed_m_s']:>9.4f}"
        )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"n": args.n, "layers": args.layers, "substeps": args.substeps, "groups": rows}, f, indent=1)


if __name__ == "__main__":
    main()
