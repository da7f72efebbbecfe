# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Floating boxes against Archimedes: the draft of a box at rest in a pool, by box density and resolution.

A square pool (1 m x 1 m, 0.4 m of water at rest spacing, frictionless walls) holds one dynamic box
(0.3 x 0.3 x 0.2 m) lowered onto the water at rest. Once it has settled, its draft (the still water
level away from the box minus the height of its bottom face) is compared with Archimedes' law,
``draft = rho_box / rho_water x box height``, with rho_water = particle mass / spacing^3 (the density
the solver's rest density is calibrated to). Two-way coupling, XPBD's particle-shape contacts: the
fluid's pressure reaches the box only through the contacts of the particles next to it, so the
box needs a few spacings of height before its draft is resolved.

    python -m benchmarks floating_box [--spacings 0.1 0.05] [--densities 250 500 750] [--json out.json]

Prints a table and writes JSON: per run the box's mean height and its spread over the last second,
the water level, the draft and Archimedes' draft, the fluid's density error at the end (the
solver's own measure) and the wall time per frame.
"""

from __future__ import annotations

import argparse
import itertools
import time

import numpy as np
import warp as wp

import newton
from newton.examples.fluid.common import add_tank
from newton.examples.fluid.progress import track

from .frames import add_solver_arguments, solver_keywords, solver_record
from .run_record import write_record

POOL_HALF = 0.5  # inner half-width of the square pool [m]
DEPTH = 0.4  # water depth at rest spacing [m]
BOX_HALF = (0.15, 0.15, 0.1)  # [m]
WATER_DENSITY = 1000.0  # particle mass / spacing^3 [kg/m^3]


def build(spacing: float, box_density: float, device, start_depth: float = 0.0):
    """The pool, its water at rest spacing and the box just above the surface (``start_depth`` spacings in it)."""
    d = spacing
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    # as many columns as fit between the walls (rounding up would start the outer ones inside them)
    n, nz = int(2.0 * POOL_HALF / d + 1.0e-3), int(round(DEPTH / d))
    builder.add_particle_grid(
        pos=wp.vec3(-POOL_HALF + 0.5 * d, -POOL_HALF + 0.5 * d, 0.5 * d),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0),
        dim_x=n,
        dim_y=n,
        dim_z=nz,
        cell_x=d,
        cell_y=d,
        cell_z=d,
        mass=WATER_DENSITY * d**3,
        jitter=0.0,
        radius_mean=0.5 * d,
        flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
    )
    builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    add_tank(builder, POOL_HALF, POOL_HALF, 1.0, 0.05)
    # resting on the lattice's surface (half a spacing above its top layer; DEPTH rounded to layers): it sinks
    # to its draft from there. Started in the water, the fluid inside it is moved out by the first step
    z = nz * d + BOX_HALF[2] - start_depth * d
    body = builder.add_body(xform=wp.transform(wp.vec3(0.0, 0.0, z), wp.quat_identity()))
    box_cfg = newton.ModelBuilder.ShapeConfig(mu=0.0, density=box_density)
    builder.add_shape_box(body, hx=BOX_HALF[0], hy=BOX_HALF[1], hz=BOX_HALF[2], cfg=box_cfg)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model


def run(spacing: float, box_density: float, args, device) -> dict:
    model = build(spacing, box_density, device, args.start_depth)
    solver = newton.solvers.SolverXPBD(model, **solver_keywords(args, spacing))
    pipeline = newton.CollisionPipeline(model, soft_contact_gap=0.5 * spacing)
    contacts = pipeline.contacts()
    states = [model.state(), model.state()]
    dt = 1.0 / 60.0 / args.substeps

    def frame():
        for _ in range(args.substeps):
            states[0].clear_forces()
            pipeline.collide(states[0], contacts)
            solver.step(states[0], states[1], None, contacts, dt)
            states[0], states[1] = states[1], states[0]

    frames = int(round(args.seconds * 60.0))
    averaged = int(round(args.average * 60.0))
    heights = []
    highest, fastest = -np.inf, 0.0
    t0 = time.perf_counter()
    for k in range(frames):
        frame()
        if k >= frames - averaged:
            heights.append(float(states[0].body_q.numpy()[0, 2]))
        if args.start_depth:
            # (a start in the water: how hard it was thrown; a sync per frame, so no time is recorded)
            highest = max(highest, float(states[0].body_q.numpy()[0, 2]))
            fastest = max(fastest, float(np.linalg.norm(states[0].body_qd.numpy()[0, :3])))
    wp.synchronize_device(device)
    ms = (time.perf_counter() - t0) * 1000.0 / frames
    q = states[0].particle_q.numpy()
    # the still level, away from the box (the box raised it by the water it displaced)
    far = (np.abs(q[:, 0]) > BOX_HALF[0] + 2.0 * spacing) | (np.abs(q[:, 1]) > BOX_HALF[1] + 2.0 * spacing)
    level = float(np.percentile(q[far, 2], 99)) + 0.5 * spacing
    centre = float(np.mean(heights))
    draft = level - (centre - BOX_HALF[2])
    expected = box_density / WATER_DENSITY * 2.0 * BOX_HALF[2]
    stats = solver.fluid_diagnostics(states[0])
    return {
        "spacing_m": spacing,
        "box_height_spacings": 2.0 * BOX_HALF[2] / spacing,
        "box_density": box_density,
        "particles": int(model.particle_count),
        "box_centre_m": centre,
        "box_centre_spread_m": float(np.ptp(heights)),
        "water_level_m": level,
        "draft_m": draft,
        "archimedes_draft_m": expected,
        "draft_relative_error": draft / expected - 1.0,
        **solver_record(solver),
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "mean_compression": stats["mean_compression"],
        "max_compression": stats["max_compression"],
        "ms_per_frame": ms,
        "start_depth_spacings": args.start_depth,
        **({"box_highest_m": highest, "box_max_speed_m_s": fastest} if args.start_depth else {}),
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--spacings", type=float, nargs="+", default=[0.1, 0.05])
    parser.add_argument("--densities", type=float, nargs="+", default=[250.0, 500.0, 750.0])
    parser.add_argument("--seconds", type=float, default=2.5, help="simulated time [s]")
    parser.add_argument(
        "--start-depth",
        type=float,
        default=0.0,
        help="spacings the box starts below the surface (records its largest height and speed)",
    )
    parser.add_argument("--average", type=float, default=1.0, help="the last seconds the box height is averaged over")
    add_solver_arguments(parser, defaults={"fluid_viscosity": 0.1})
    args = parser.parse_args(argv)
    device = wp.get_device(args.device)
    runs = []
    print(
        f"{'spacing':>8}{'box/h':>7}{'density':>9}{'particles':>10}{'draft':>8}{'Archimedes':>11}{'error':>8}"
        f"{'spread':>8}{'mean c':>8}{'ms/frame':>10}"
    )
    for spacing, density in track(list(itertools.product(args.spacings, args.densities)), "floating_box"):
        r = run(spacing, density, args, device)
        runs.append(r)
        print(
            f"{spacing:>8.4f}{r['box_height_spacings']:>7.1f}{density:>9.0f}{r['particles']:>10}"
            f"{r['draft_m']:>8.4f}{r['archimedes_draft_m']:>11.4f}{100.0 * r['draft_relative_error']:>7.1f}%"
            f"{r['box_centre_spread_m']:>8.4f}{100.0 * r['mean_compression']:>7.2f}%{r['ms_per_frame']:>10.1f}",
            flush=True,
        )
    result = {
        "substeps": args.substeps,
        "iterations": args.iterations,
        "seconds": args.seconds,
        "averaged_s": args.average,
        "box_half_extents_m": BOX_HALF,
        "pool_half_width_m": POOL_HALF,
        "depth_m": DEPTH,
    }
    return write_record("floating_box", device, result, args.json, rows=runs)


if __name__ == "__main__":
    main()
