# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Drift of a settled water column: how far its particles move while it should be at rest.

A ``--width`` x ``--width`` x ``--height`` column (spacing 0.1 m) stands in a frictionless walled
tank under gravity; after ``--settle`` seconds the positions are taken as the reference, and every
second for ``--seconds`` the mean, median, 90th percentile and largest displacement (in spacings)
are printed, for the whole column and for its top layer, with the RMS speed and the solver's
density error. Writes JSON with ``--json``.

Usage::

    python -m benchmarks hydrostatic_drift [--iterations 2] [--substeps 8] [--viscosity 0.05] [--json out.json]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import warp as wp

import newton
from newton.examples.fluid.common import add_tank
from newton.examples.fluid.progress import track

from .frames import add_solver_arguments, solver_keywords, solver_record
from .run_record import write_record

D = 0.1  # spacing [m]


def start_positions(n: int, layers: int, packing: str, jitter: float) -> np.ndarray:
    """Start positions of an ``n`` x ``n`` column of ``layers`` cubic layers' worth of particles [m]."""
    if packing == "cubic":
        i, j, k = np.meshgrid(np.arange(n), np.arange(n), np.arange(layers), indexing="ij")
        q = (np.stack([i, j, k], axis=-1).reshape(-1, 3) + 0.5) * D
    else:
        # the layers' particles alternate between n^2 and (n-1)^2, so the layer height that keeps the
        # cubic lattice's particles per height is the mean of the two over n^2
        dz = D * (n * n + (n - 1) * (n - 1)) / (2.0 * n * n)
        q, k = [], 0
        while sum(len(a) for a in q) < n * n * layers:
            m, offset = (n, 0.5) if k % 2 == 0 else (n - 1, 1.0)
            i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
            q.append(np.stack([(i.ravel() + offset) * D, (j.ravel() + offset) * D, np.full(m * m, (k + 0.5) * dz)], 1))
            k += 1
        q = np.concatenate(q)[: n * n * layers]
    rng = np.random.default_rng(42)
    return q + jitter * D * rng.uniform(-1.0, 1.0, q.shape) * np.array([1.0, 1.0, 0.0])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--width", type=int, default=6, help="particles across the column")
    parser.add_argument("--height", type=int, default=10, help="particles up the column")
    parser.add_argument(
        "--packing",
        choices=("cubic", "staggered"),
        default="cubic",
        help="cubic: a cubic lattice at the spacing; staggered: layers of n x n and (n-1) x (n-1) particles "
        "in turn, each over the hollows of the one below, as many particles per height as the cubic lattice",
    )
    parser.add_argument("--jitter", type=float, default=0.0, help="random offset of the start positions [spacings]")
    parser.add_argument("--settle", type=float, default=3.0, help="seconds before the reference positions")
    parser.add_argument("--seconds", type=int, default=5, help="seconds of drift measured")
    add_solver_arguments(parser, defaults={"fluid_viscosity": 0.05})
    args = parser.parse_args(argv)

    wp.config.quiet = True
    device = wp.get_device(args.device)
    n, w = args.width, args.width * D
    builder = newton.ModelBuilder()
    for q in start_positions(n, args.height, args.packing, args.jitter):
        builder.add_particle(
            pos=wp.vec3(*q),
            vel=wp.vec3(0.0),
            mass=1000.0 * D**3,
            radius=0.5 * D,
            flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
        )
    builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    add_tank(builder, 0.5 * w, 0.5 * w, 2.0 * args.height * D, 0.05, center=(0.5 * w, 0.5 * w))
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    solver = newton.solvers.SolverXPBD(model, **solver_keywords(args, D))
    # contacts out to one diameter from the surface, so the particles see the walls' density
    pipeline = newton.CollisionPipeline(model, soft_contact_gap=0.5 * D)
    contacts = pipeline.contacts()
    states = [model.state(), model.state()]
    dt = 1.0 / (60.0 * args.substeps)

    def run(seconds: float):
        for _ in range(int(round(seconds * 60.0 * args.substeps))):
            states[0].clear_forces()
            pipeline.collide(states[0], contacts)
            solver.step(states[0], states[1], None, contacts, dt)
            states[0], states[1] = states[1], states[0]

    start = solver.fluid_diagnostics(states[0])
    # the fastest particle while settling, sampled every frame (a start far from rest throws particles)
    settle_max_speed = 0.0
    for _ in track(range(int(round(args.settle * 60.0))), "hydrostatic_drift: settling", unit="frame"):
        run(1.0 / 60.0)
        settle_max_speed = max(settle_max_speed, float(np.linalg.norm(states[0].particle_qd.numpy(), axis=1).max()))
    print(
        f"start: max compression {100 * start['max_compression']:.2f} % (solver's measure, walls left out); "
        f"fastest particle while settling {settle_max_speed:.2f} m/s",
        flush=True,
    )
    settled = states[0].particle_q.numpy().astype(np.float64)
    top = settled[:, 2] > settled[:, 2].max() - 1.5 * D
    # the particles of the outer ring, within one spacing of a side wall, and the rest of the column
    edge = np.minimum.reduce([settled[:, 0], w - settled[:, 0], settled[:, 1], w - settled[:, 1]]) < D
    # (a start far from rest can throw particles over the walls of the open tank)
    inside = np.all((settled[:, :2] > 0.0) & (settled[:, :2] < w), axis=1) & (settled[:, 2] > 0.0)
    rows = []
    for k in track(range(args.seconds), "hydrostatic_drift: measuring", unit="second"):
        run(1.0)
        q = states[0].particle_q.numpy().astype(np.float64)
        disp = np.linalg.norm(q - settled, axis=1) / D
        speed = np.linalg.norm(states[0].particle_qd.numpy().astype(np.float64), axis=1)
        stats = solver.fluid_diagnostics(states[0])
        rows.append(
            {
                "t_after_settling_s": k + 1,
                "mean_spacings": float(disp.mean()),
                "median_spacings": float(np.median(disp)),
                "p90_spacings": float(np.percentile(disp, 90)),
                "max_spacings": float(disp.max()),
                "top_layer_mean_spacings": float(disp[top].mean()),
                "below_top_mean_spacings": float(disp[~top].mean()),
                "edge_mean_spacings": float(disp[edge & inside].mean()),
                "inner_mean_spacings": float(disp[~edge & inside].mean()),
                "outside_tank": int(np.count_nonzero(~inside)),
                "rms_speed_m_s": float(np.sqrt(np.mean(speed**2))),
                "max_speed_m_s": float(speed.max()),
                "mean_abs_density_error": stats["mean_abs_density_error"],
                "max_compression": stats["max_compression"],
            }
        )
        r = rows[-1]
        print(
            f"+{k + 1} s: displacement mean {r['mean_spacings']:.4f} median {r['median_spacings']:.4f} "
            f"p90 {r['p90_spacings']:.4f} max {r['max_spacings']:.3f} spacings (top layer "
            f"{r['top_layer_mean_spacings']:.4f}, below {r['below_top_mean_spacings']:.4f}; within a spacing of a "
            f"side wall {r['edge_mean_spacings']:.4f}, further in {r['inner_mean_spacings']:.4f}; "
            f"{r['outside_tank']} outside the tank); RMS speed "
            f"{r['rms_speed_m_s']:.4f} m/s (max {r['max_speed_m_s']:.3f}); mean|e| {100 * r['mean_abs_density_error']:.2f} %, max compression "
            f"{100 * r['max_compression']:.2f} %",
            flush=True,
        )
    result = {
        "particles": int(model.particle_count),
        "column": [n, n, args.height],
        "packing": args.packing,
        "jitter_spacings": args.jitter,
        "spacing_m": D,
        "substeps": args.substeps,
        **solver_record(solver),
        "settle_s": args.settle,
        "start_max_compression": start["max_compression"],
        "settle_max_speed_m_s": settle_max_speed,
    }
    return write_record("hydrostatic_drift", device, result, args.json, rows=rows)


if __name__ == "__main__":
    main(sys.argv[1:])
