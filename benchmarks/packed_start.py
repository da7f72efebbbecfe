# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""A bad start: fluid placed packed closer than its rest spacing in a closed tank, and how hard it springs apart.

A block of ``--block`` x ``--block`` x ``--layers`` fluid particles (rest spacing 0.1 m) is placed at
``--fraction`` of the rest spacing on the floor of a closed frictionless box as wide as the block is at
its rest spacing (so it expands upward, with no dam break's collapse) and ``--height`` m tall, and
simulated for ``--seconds`` at 60 Hz with ``--substeps`` x ``--iterations`` and the solver's default
keywords. It records the particles that leave the tank (a
centre more than a spacing beyond a wall), the highest particle reached, the level the expanded fluid
settles to (the 99th percentile height at the end, plus half a spacing), the largest speed, and what the
diagnostics reported, and the time of the first frame (which relaxes the over-packed placement, see
``newton/_src/solvers/xpbd/fluid/placement.py``) beside the median frame's. Issue #23, item 3: none
leaves, and none rises more than 5 spacings above the settled level.

Usage::

    python -m benchmarks packed_start [--fraction 0.7] [--no-continuous-collision] [--graph] [--json out.json]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
import warp as wp

import newton
from newton.examples.fluid.common import add_closed_box
from newton.examples.fluid.progress import track

from .frames import add_solver_arguments, solver_keywords, solver_record
from .run_record import write_record

SPACING = 0.1  # rest spacing [m]


def run(args, device) -> dict:
    d = SPACING
    builder = newton.ModelBuilder()
    packed = args.fraction * d
    edge = args.block * d
    corner = 0.5 * (edge - args.block * packed) + 0.5 * packed
    builder.add_particle_grid(
        pos=wp.vec3(corner, corner, 0.5 * d),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0),
        dim_x=args.block,
        dim_y=args.block,
        dim_z=args.layers,
        cell_x=packed,
        cell_y=packed,
        cell_z=packed,
        mass=1000.0 * d**3,
        jitter=0.01 * d,
        radius_mean=0.5 * d,
        flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
    )
    add_closed_box(builder, edge, args.height, thickness=2.0 * d)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    solver = newton.solvers.SolverXPBD(model, **solver_keywords(args, d))
    pipeline = newton.CollisionPipeline(model, soft_contact_max=4 * model.particle_count, soft_contact_gap=0.5 * d)
    contacts = pipeline.contacts()
    s0, s1 = model.state(), model.state()
    dt = 1.0 / (60.0 * args.substeps)
    highest, fastest, left = 0.0, 0.0, 0
    fastest_first_frame = 0.0
    if args.check_placement:
        # a reset from a state the host cannot see into: the first step checks it (and finds nothing at 1.0)
        solver.reset(s0, None, fluid_source=s1)
    states = [s0, s1]

    def simulate():
        for _ in range(args.substeps):
            states[0].clear_forces()
            pipeline.collide(states[0], contacts)
            solver.step(states[0], states[1], None, contacts, dt)
            states.reverse()

    advance = simulate
    if args.graph:
        # one frame captured (an even count of substeps leaves the states where they were); its first replay
        # checks and relaxes the placement in conditional nodes, which the later replays skip
        if not device.is_cuda or args.substeps % 2:
            raise ValueError(f"--graph needs a CUDA device and an even --substeps, got {device}, {args.substeps}")
        with wp.ScopedCapture(device=device) as capture:
            simulate()

        def advance():
            wp.capture_launch(capture.graph)

    frame_s = []
    for frame in track(range(int(round(args.seconds * 60.0))), "packed_start", unit="frame"):
        wp.synchronize_device(device)
        start = time.perf_counter()
        advance()
        s0 = states[0]
        wp.synchronize_device(device)
        frame_s.append(time.perf_counter() - start)
        q = s0.particle_q.numpy().astype(np.float64)
        speed = float(np.linalg.norm(s0.particle_qd.numpy(), axis=1).max())
        if frame == 0:
            fastest_first_frame = speed
        highest = max(highest, float(q[:, 2].max()))
        fastest = max(fastest, speed)
        outside = np.any(q[:, :2] < -d, axis=1) | np.any(q[:, :2] > edge + d, axis=1)
        left = max(left, int(np.count_nonzero(outside | (q[:, 2] < -d) | (q[:, 2] > args.height + d))))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        stats = solver.fluid_diagnostics(s0)
    level = float(np.percentile(q[:, 2], 99)) + 0.5 * d
    return {
        "particles": int(model.particle_count),
        "spacing_m": d,
        "packed_fraction": args.fraction,
        "box_m": [edge, edge, args.height],
        "substeps": args.substeps,
        "seconds": args.seconds,
        **solver_record(solver),
        "left_tank": left,
        "settled_level_m": level,
        "highest_m": highest,
        "rise_above_level_spacings": (highest - level) / d,
        "max_speed_m_s": fastest,
        "max_speed_first_frame_m_s": fastest_first_frame,
        # frames with a collision every substep, eager or a graph's replays; the first one relaxes an
        # over-packed placement
        "check_placement": args.check_placement,
        "graph": args.graph,
        "first_frame_ms": 1.0e3 * frame_s[0],
        "frame_ms_median": 1.0e3 * float(np.median(frame_s[1:])),
        "overpacked_placed": stats["overpacked_placed"],
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        "peak_compression": stats["peak_compression"],
        "warnings": [str(w.message) for w in caught],
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fraction", type=float, default=0.7, help="placed spacing over the rest spacing")
    parser.add_argument("--block", type=int, default=14, help="particles along each side of the block")
    parser.add_argument("--layers", type=int, default=10)
    parser.add_argument("--height", type=float, default=3.0, help="inner height of the closed box [m]")
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument(
        "--check-placement",
        action="store_true",
        help="reset from a copy of the start before the first frame, so that its step checks the placement "
        "(with --fraction 1 the first frame's extra time is the check where nothing is packed)",
    )
    parser.add_argument(
        "--graph",
        action="store_true",
        help="replay a frame captured in a CUDA graph (the relaxation's rounds a conditional loop) instead of "
        "eager frames (a fixed count of rounds launched)",
    )
    add_solver_arguments(parser)
    args = parser.parse_args(argv)
    wp.config.quiet = True
    device = wp.get_device(args.device)
    with wp.ScopedDevice(device):
        r = run(args, device)
    print(
        f"{'device':<24}{'particles':>10}{'packed':>7}{'sub x it':>9}{'left':>6}{'rise [d]':>9}{'max m/s':>9}"
        f"{'mean|e|':>9}{'peak c':>8}{'1st ms':>9}{'ms/frame':>9}"
    )
    name = device.name if device.is_cuda else "cpu"
    print(
        f"{name:<24}{r['particles']:>10}{r['packed_fraction']:>7.2f}{r['substeps']:>5} x {r['iterations']:<1}"
        f"{r['left_tank']:>6}{r['rise_above_level_spacings']:>9.1f}{r['max_speed_m_s']:>9.1f}"
        f"{100 * r['mean_abs_density_error']:>8.2f}%{100 * r['peak_compression']:>7.0f}%"
        f"{r['first_frame_ms']:>9.1f}{r['frame_ms_median']:>9.1f}"
    )
    return write_record("packed_start", device, r, args.json)


if __name__ == "__main__":
    main()
