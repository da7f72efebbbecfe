# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Drift of a settled water column: how far its particles move while it should be at rest.

A ``--width`` x ``--width`` x ``--height`` column (spacing 0.1 m) stands in a frictionless walled
tank under gravity; after ``--settle`` seconds the positions are taken as the reference, and every
second for ``--seconds`` the mean, median, 90th percentile and largest displacement (in spacings)
are printed, for the whole column and for its top layer, with the RMS speed and the solver's
density error. Writes JSON with ``--json``.

Usage::

    python benchmarks/hydrostatic_drift.py [--iterations 2] [--substeps 8] [--viscosity 0.05] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

import numpy as np
import warp as wp

import newton
from newton.examples.fluid.common import add_tank

D = 0.1  # spacing [m]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--width", type=int, default=6, help="particles across the column")
    parser.add_argument("--height", type=int, default=10, help="particles up the column")
    parser.add_argument("--substeps", type=int, default=8)
    parser.add_argument("--iterations", type=int, default=2)
    parser.add_argument("--viscosity", type=float, default=0.05)
    parser.add_argument("--cohesion", type=float, default=0.0)
    parser.add_argument("--relaxation", type=float, default=1.0, help="fluid_relaxation")
    parser.add_argument("--smoothing", type=float, default=1.8, help="smoothing length over the spacing")
    parser.add_argument("--warm-start", type=float, default=0.0, help="fluid_warm_start")
    parser.add_argument("--settle", type=float, default=3.0, help="seconds before the reference positions")
    parser.add_argument("--seconds", type=int, default=5, help="seconds of drift measured")
    parser.add_argument("--device", default=None)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)

    wp.config.quiet = True
    device = wp.get_device(args.device)
    n, w = args.width, args.width * D
    builder = newton.ModelBuilder()
    builder.add_particle_grid(
        pos=wp.vec3(0.5 * D, 0.5 * D, 0.5 * D),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0),
        dim_x=n,
        dim_y=n,
        dim_z=args.height,
        cell_x=D,
        cell_y=D,
        cell_z=D,
        mass=1000.0 * D**3,
        jitter=0.0,
        radius_mean=0.5 * D,
        flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
    )
    builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    add_tank(builder, 0.5 * w, 0.5 * w, 2.0 * args.height * D, 0.05, center=(0.5 * w, 0.5 * w))
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    solver = newton.solvers.SolverXPBD(
        model,
        iterations=args.iterations,
        fluid_rest_distance=D,
        fluid_viscosity=args.viscosity,
        fluid_cohesion=args.cohesion,
        fluid_relaxation=args.relaxation,
        fluid_smoothing_length=args.smoothing * D,
        fluid_warm_start=args.warm_start,
    )
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

    run(args.settle)
    settled = states[0].particle_q.numpy().astype(np.float64)
    top = settled[:, 2] > settled[:, 2].max() - 1.5 * D
    rows = []
    for k in range(args.seconds):
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
            f"{r['top_layer_mean_spacings']:.4f}, below {r['below_top_mean_spacings']:.4f}); RMS speed "
            f"{r['rms_speed_m_s']:.4f} m/s (max {r['max_speed_m_s']:.3f}); mean|e| {100 * r['mean_abs_density_error']:.2f} %, max compression "
            f"{100 * r['max_compression']:.2f} %",
            flush=True,
        )
    result = {
        "benchmark": "hydrostatic_drift",
        "machine": platform.node(),
        "device": device.name if device.is_cuda else "cpu",
        "particles": int(model.particle_count),
        "column": [n, n, args.height],
        "spacing_m": D,
        "substeps": args.substeps,
        "iterations": args.iterations,
        "viscosity": args.viscosity,
        "cohesion": args.cohesion,
        "relaxation": args.relaxation,
        "warm_start": args.warm_start,
        "smoothing_over_spacing": args.smoothing,
        "settle_s": args.settle,
        "rows": rows,
    }
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    return result


if __name__ == "__main__":
    main(sys.argv[1:])
