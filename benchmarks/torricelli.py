# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Torricelli: a tank drains through a small hole in its side wall (issue #27 item 2).

Water fills a tank ``--length`` x ``--width`` to ``--height`` (spacing ``--spacing``, mass ``1000 d^3``)
behind frictionless walls; the wall at ``x = L`` (one spacing thick) has a square hole ``--hole``
spacings wide whose lower edge is ``--sill`` spacings above the floor. Outside, the jet falls to a
ground plane ``--drop`` below the floor. Once the flow has set up (``--skip`` seconds) it compares:

- the jet speed just outside the hole (the mean horizontal velocity of the particles two spacings
  long from half the hole's width beyond the wall, the vena contracta, in the hole's height band) against ``sqrt(2 g H)``, ``H`` the head of the
  hole's centre below the level inside (the fluid inside over the floor area, at the rest spacing);
- the jet's trajectory: where each particle crosses the plane ``--fall`` below the hole's centre,
  against the free-fall range of a jet leaving horizontally at Torricelli's speed for the head when
  it left, ``x = 2 sqrt(H dz)`` from the wall's outer face.

Usage::

    python -m benchmarks torricelli [--spacing 0.02 --hole 4] [--json out.json]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import warp as wp

import newton
from newton.examples.fluid.common import add_water_lattice
from newton.examples.fluid.progress import track

from .frames import Frames, add_solver_arguments, run_on_device, solver_keywords
from .run_record import write_record

GRAVITY = 9.81  # [m/s^2]


def add_box(builder, lo, hi, cfg) -> None:
    """A static box spanning ``lo`` to ``hi`` [m]."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c, e = 0.5 * (lo + hi), 0.5 * (hi - lo)
    builder.add_shape_box(-1, xform=wp.transform(wp.vec3(*c), wp.quat_identity()), hx=e[0], hy=e[1], hz=e[2], cfg=cfg)


def build(args, device):
    """The tank with its holed wall, the water and the ground; returns the model and the hole's geometry."""
    d = args.spacing
    nx, ny, nz = round(args.length / d), round(args.width / d), round(args.height / d)
    length, width = nx * d, ny * d
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -GRAVITY))
    add_water_lattice(builder, d, (nx, ny, nz))
    cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
    t, top = 0.1, 1.5 * nz * d
    wall = d  # the holed wall: thin, so the hole is an orifice, not a pipe
    # floor, back wall, side walls (each reaching past the others)
    add_box(builder, (-t, -t, -t), (length + wall, width + t, 0.0), cfg)
    add_box(builder, (-t, -t, 0.0), (0.0, width + t, top), cfg)
    add_box(builder, (-t, -t, 0.0), (length + wall, 0.0, top), cfg)
    add_box(builder, (-t, width, 0.0), (length + wall, width + t, top), cfg)
    # the wall at x = L around the hole
    a, z0 = args.hole * d, args.sill * d
    y0, y1 = 0.5 * (width - a), 0.5 * (width + a)
    x0, x1 = length, length + wall
    if z0 > 0.0:
        add_box(builder, (x0, 0.0, 0.0), (x1, width, z0), cfg)
    add_box(builder, (x0, 0.0, z0 + a), (x1, width, top), cfg)
    add_box(builder, (x0, 0.0, z0), (x1, y0, z0 + a), cfg)
    add_box(builder, (x0, y1, z0), (x1, width, z0 + a), cfg)
    builder.add_ground_plane(height=-args.drop, cfg=cfg)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    hole = {"x_out": x1, "z_center": z0 + 0.5 * a, "z_low": z0, "z_high": z0 + a, "area": length * width}
    return model, d, hole


def run(args, device) -> dict:
    model, d, hole = build(args, device)
    solver = newton.solvers.SolverXPBD(model, **solver_keywords(args, d))
    pipeline = newton.CollisionPipeline(model, soft_contact_max=6 * model.particle_count, soft_contact_gap=0.5 * d)
    contacts = pipeline.contacts()
    states = [model.state(), model.state()]
    x_out, zc = hole["x_out"], hole["z_center"]
    z_plane = zc - args.fall

    frame = Frames(solver, pipeline, contacts, states, args.substeps, device)

    n = model.particle_count
    exit_head = np.full(n, np.nan)  # head when the particle left through the hole [m]
    landed = np.zeros(n, bool)
    speed_rows, range_rows = [], []
    q_prev = states[0].particle_q.numpy().astype(np.float64)
    start = time.perf_counter()
    frames = round(args.seconds * 60.0)
    simulated = 0.0  # [s] of the frames themselves, read-backs left out
    for f in track(range(frames), "torricelli: draining", unit="frame"):
        tick = time.perf_counter()
        frame()
        wp.synchronize_device(device)
        simulated += time.perf_counter() - tick
        t = (f + 1) / 60.0
        q = states[0].particle_q.numpy().astype(np.float64)
        v = states[0].particle_qd.numpy().astype(np.float64)
        inside = q[:, 0] < x_out - d
        level = inside.sum() * d**3 / hole["area"]
        head = level - zc
        left = np.isnan(exit_head) & (q_prev[:, 0] < x_out) & (q[:, 0] >= x_out)
        exit_head[left] = head
        crossed = ~landed & ~np.isnan(exit_head) & (q_prev[:, 2] > z_plane) & (q[:, 2] <= z_plane)
        if crossed.any():
            # where it crossed the plane, interpolated within the frame
            s = (q_prev[crossed, 2] - z_plane) / (q_prev[crossed, 2] - q[crossed, 2])
            x = q_prev[crossed, 0] + s * (q[crossed, 0] - q_prev[crossed, 0]) - x_out
            landed[crossed] = True
            if t >= args.skip:
                speed = np.linalg.norm(v[crossed], axis=1)
                predicted = np.sqrt(2.0 * GRAVITY * (np.maximum(exit_head[crossed], 0.0) + args.fall))
                range_rows.extend(zip(speed.tolist(), predicted.tolist(), x.tolist(), strict=True))
        # past the vena contracta (about half the hole's width beyond it), before the jet bends much
        x_jet = x_out + 0.5 * args.hole * d
        jet = (q[:, 0] >= x_jet) & (q[:, 0] < x_jet + 2.0 * d) & (q[:, 2] > hole["z_low"] - d)
        jet &= q[:, 2] < hole["z_high"] + d
        if t >= args.skip and jet.sum() >= 3 and head > 2.0 * d:
            energy = (v[jet] ** 2).sum(axis=1) - 2.0 * GRAVITY * (zc - q[jet, 2])
            speed = float(np.sqrt(np.maximum(energy, 0.0)).mean())
            angle = float(np.degrees(np.arctan2(-v[jet, 2], v[jet, 0])).mean())
            speed_rows.append((t, head, speed, math.sqrt(2.0 * GRAVITY * head), int(jet.sum()), angle))
        q_prev = q
    wall = time.perf_counter() - start
    speeds = np.asarray(speed_rows) if speed_rows else np.zeros((0, 6))
    ranges = np.asarray(range_rows) if range_rows else np.zeros((0, 3))
    ratio = speeds[:, 2] / speeds[:, 3] if len(speeds) else np.array([math.nan])
    range_ratio = ranges[:, 0] / np.maximum(ranges[:, 1], 1e-9) if len(ranges) else np.array([math.nan])
    stats = solver.fluid_diagnostics(states[0])
    q = states[0].particle_q.numpy()
    return {
        "particles": int(n),
        "spacing_m": d,
        "hole_spacings": args.hole,
        "hole_m": args.hole * d,
        "sill_spacings": args.sill,
        "initial_head_m": round(args.height / d) * d - zc,
        "substeps": args.substeps,
        "iterations": args.iterations,
        "viscosity": solver.fluid_viscosity,
        "warm_start": solver.fluid_warm_start,
        "smoothing_length_m": solver.fluid_smoothing_length,
        "nonaffine_damping": solver.fluid_nonaffine_damping,
        "seconds": args.seconds,
        "speed_samples": int(len(speeds)),
        # frames with the jet's speed against Torricelli's; the mean ratio and its worst over the draining
        "jet_speed_ratio_mean": float(ratio.mean()),
        "jet_speed_ratio_min": float(ratio.min()),
        "jet_speed_ratio_max": float(ratio.max()),
        "range_samples": int(len(ranges)),
        "jet_exit_angle_deg": float(speeds[:, 5].mean()) if len(speeds) else math.nan,
        # speed where the jet crosses the plane --fall below the hole, against Torricelli's plus the fall
        "fall_speed_ratio_mean": float(range_ratio.mean()),
        "fall_speed_ratio_p10": float(np.percentile(range_ratio, 10)) if len(ranges) else math.nan,
        "fall_speed_ratio_p90": float(np.percentile(range_ratio, 90)) if len(ranges) else math.nan,
        "drained_fraction": float((q[:, 0] >= x_out).mean()),
        "all_finite": bool(np.isfinite(q).all()),
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        "ms_per_frame": 1000.0 * simulated / frames,
        "wall_s": wall,
        "speed_rows_t_head_v_theory_n_angle": speeds[:: max(1, len(speeds) // 100)].tolist(),
    }


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spacing", type=float, default=0.02, help="[m]")
    p.add_argument("--length", type=float, default=0.3, help="tank length along the jet [m]")
    p.add_argument("--width", type=float, default=0.16, help="[m]")
    p.add_argument("--height", type=float, default=0.4, help="initial water height [m]")
    p.add_argument("--hole", type=int, default=4, help="hole side [spacings]")
    p.add_argument("--sill", type=int, default=4, help="hole's lower edge above the floor [spacings]")
    p.add_argument("--drop", type=float, default=1.0, help="ground below the tank's floor [m]")
    p.add_argument("--fall", type=float, default=0.2, help="drop below the hole's centre where the range is read [m]")
    p.add_argument("--seconds", type=float, default=1.5, help="[s]")
    p.add_argument("--skip", type=float, default=0.25, help="set-up time left out of the comparison [s]")
    add_solver_arguments(p)
    return p


def main(argv=None):
    args = parser().parse_args(argv)
    device, r = run_on_device(run, args)
    print(
        f"{'device':<10}{'particles':>10}{'hole':>6}{'sub x it':>9}{'v/v_T':>7}{'min':>7}{'max':>7}"
        f"{'angle':>7}{'fall/T':>8}{'p10':>7}{'p90':>7}{'mean|e|':>8}"
    )
    name = device.name if device.is_cuda else "cpu"
    print(
        f"{name:<10}{r['particles']:>10}{r['hole_spacings']:>6}{r['substeps']:>5} x {r['iterations']:<1}"
        f"{r['jet_speed_ratio_mean']:>7.3f}{r['jet_speed_ratio_min']:>7.3f}{r['jet_speed_ratio_max']:>7.3f}"
        f"{r['jet_exit_angle_deg']:>7.1f}{r['fall_speed_ratio_mean']:>8.3f}{r['fall_speed_ratio_p10']:>7.3f}"
        f"{r['fall_speed_ratio_p90']:>7.3f}"
        f"{100 * r['mean_abs_density_error']:>7.2f}%"
    )
    return write_record("torricelli", device, r, args.json)


if __name__ == "__main__":
    main()
