# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Where the fluid solve fails: the largest stable substep against iterations and impact speed.

A block of ``--block``^3 fluid particles (spacing ``--spacing``) is thrown down at an impact speed
onto the floor of a closed box tank (lid included) and simulated for ``--seconds`` at 60 Hz with
every substep count of ``--substeps`` and XPBD iteration count of ``--iterations``. A run is
stable when, at every frame, every position is finite and inside the tank, and at the end the
fluid has gained no energy (RMS speed below what the throw and the fall from the lid allow) and is not crushed (99th percentile
compression of the solver's own density below 10 %); a particle centre more than one spacing inside a
wall counts as lost. The map records, per iteration count and
speed, the longest stable substep, with every run's numbers; ``--plot`` draws it.

Usage::

    python -m benchmarks stability_map [--device cpu] [--json out.json] [--plot out.png]
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

import newton
from newton.examples.fluid.common import add_closed_tank
from newton.examples.fluid.progress import track

from .frames import add_solver_arguments, solver_keywords
from .run_record import write_record

FLUID = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)


def build(args, speed: float, device):
    d = args.spacing
    n = args.block
    tank = 3.0 * n * d  # inner edge [m]
    builder = newton.ModelBuilder()
    builder.add_particle_grid(
        pos=wp.vec3(n * d + 0.5 * d, n * d + 0.5 * d, tank - n * d - 0.5 * d),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0, 0.0, -speed),
        dim_x=n,
        dim_y=n,
        dim_z=n,
        cell_x=d,
        cell_y=d,
        cell_z=d,
        mass=1000.0 * d**3,
        jitter=0.05 * d,
        radius_mean=0.5 * d,
        flags=FLUID,
    )
    add_closed_tank(builder, tank, thickness=4.0 * d)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model, tank


def run_one(args, device, substeps: int, iterations: int, speed: float) -> dict:
    d = args.spacing
    model, tank = build(args, speed, device)
    solver = newton.solvers.SolverXPBD(model, **solver_keywords(args, d, iterations=iterations))
    pipeline = newton.CollisionPipeline(model, soft_contact_max=2 * model.particle_count, soft_contact_gap=0.5 * d)
    contacts = pipeline.contacts()
    s0, s1 = model.state(), model.state()
    dt = 1.0 / (60.0 * substeps)
    reason, first_bad, max_penetration = "", None, 0.0
    frames = int(round(args.seconds * 60.0))
    for frame in range(frames):
        for _ in range(substeps):
            s0.clear_forces()
            pipeline.collide(s0, contacts)
            solver.step(s0, s1, None, contacts, dt)
            s0, s1 = s1, s0
        q = s0.particle_q.numpy()
        if not np.isfinite(q).all():
            reason, first_bad = "non-finite position", frame
            break
        depth = max(float(-q.min()), float(q.max() - tank), 0.0) / d
        max_penetration = max(max_penetration, depth)
        outside = np.any((q < -d) | (q > tank + d), axis=1)
        if outside.any():
            # a centre one spacing inside a wall has left the fluid (the contact may push it out beyond)
            reason, first_bad = f"{int(outside.sum())} particles left the tank", frame
            break
    stats = solver.fluid_diagnostics(s0)
    qd = s0.particle_qd.numpy()
    rms = float(np.sqrt(np.mean(np.sum(qd.astype(np.float64) ** 2, axis=1)))) if np.isfinite(qd).all() else np.inf
    rho = solver.fluid_density.numpy() / stats["rest_density"]
    p99 = float(np.percentile(np.maximum(rho - 1.0, 0.0), 99)) if np.isfinite(rho).all() else np.inf
    # faster than the throw and the fall from the block's height allow: the solve added energy
    limit = float(np.sqrt(speed**2 + 2.0 * 9.81 * tank))
    if not reason and rms > limit:
        reason = f"gained energy (RMS speed {rms:.2f} m/s > {limit:.2f})"
    if not reason and p99 > 0.1:
        reason = f"crushed (p99 compression {100 * p99:.0f} %)"
    return {
        "substeps": substeps,
        "substep_s": dt,
        "iterations": iterations,
        "impact_speed_m_s": speed,
        "displacement_per_substep_spacings": speed * dt / d,
        "stable": not reason,
        "failure": reason,
        "failed_at_frame": first_bad,
        "nonfinite_recovered": int(stats["nonfinite_recovered"]),
        "fast_particle_substeps": int(stats["fast_particle_substeps"]),
        "shape_entries_stopped": int(stats["shape_entries_stopped"]),
        "max_wall_penetration_spacings": max_penetration,
        # at the end
        "final_rms_speed_m_s": rms,
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "p99_compression": p99,
        "max_compression": float(stats["max_compression"]),
    }


def plot(result: dict, path: str):
    import matplotlib  # noqa: PLC0415

    # (records written before 2026-11-26 name the rows "runs")
    result = {**result, "runs": result.get("rows", result.get("runs"))}

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    iterations = sorted({r["iterations"] for r in result["runs"]})
    speeds = sorted({r["impact_speed_m_s"] for r in result["runs"]})
    substeps = sorted({r["substeps"] for r in result["runs"]})
    grid = np.full((len(iterations), len(speeds)), np.nan)
    for a, it in enumerate(iterations):
        for b, v in enumerate(speeds):
            ok = [
                r["substep_s"]
                for r in result["runs"]
                if r["iterations"] == it and r["impact_speed_m_s"] == v and r["stable"]
            ]
            grid[a, b] = 1000.0 * max(ok) if ok else np.nan
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6))
    ax = axes[0]
    image = ax.imshow(np.log2(grid), origin="lower", cmap="viridis", aspect="auto")
    for a in range(len(iterations)):
        for b in range(len(speeds)):
            text = "none" if np.isnan(grid[a, b]) else f"{grid[a, b]:.2f} ms"
            ax.text(b, a, text, ha="center", va="center", color="w", fontsize=8)
    ax.set_xticks(range(len(speeds)), [f"{v:g}" for v in speeds])
    ax.set_yticks(range(len(iterations)), [str(i) for i in iterations])
    ax.set(xlabel="impact speed [m/s]", ylabel="XPBD iterations", title="longest stable substep")
    fig.colorbar(image, ax=ax, label="log2(substep [ms])")
    ax = axes[1]
    for it in iterations:
        for r in result["runs"]:
            if r["iterations"] != it:
                continue
            marker = "o" if r["stable"] else "x"
            color = f"C{iterations.index(it)}"
            ax.scatter(
                r["impact_speed_m_s"] * (1 + 0.04 * iterations.index(it)),
                r["displacement_per_substep_spacings"],
                marker=marker,
                color=color,
                s=25,
                label=f"{it} iterations" if r is result["runs"][0] else None,
            )
    handles = [
        plt.Line2D([], [], color=f"C{k}", marker="o", linestyle="", label=f"{it} iterations")
        for k, it in enumerate(iterations)
    ]
    handles.append(plt.Line2D([], [], color="k", marker="x", linestyle="", label="unstable"))
    ax.legend(handles=handles, fontsize=8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set(
        xlabel="impact speed [m/s]",
        ylabel="impact displacement per substep [spacings]",
        title=f"every run ({', '.join(str(s) for s in substeps)} substeps per 1/60 s)",
    )
    ax.grid(True, which="both", alpha=0.25)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--block", type=int, default=8, help="particles per edge of the thrown block")
    parser.add_argument("--spacing", type=float, default=0.05, help="rest distance [m]")
    parser.add_argument("--seconds", type=float, default=1.5)
    parser.add_argument("--substeps", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32])
    parser.add_argument("--iterations", type=int, nargs="+", default=[1, 2, 4, 8])
    parser.add_argument("--speeds", type=float, nargs="+", default=[1.0, 4.0, 16.0, 64.0])
    add_solver_arguments(parser, defaults={"fluid_viscosity": 0.05}, step_flags=False)
    parser.add_argument("--plot", default=None)
    parser.add_argument("--inputs", default=None, help="plot this JSON instead of running")
    args = parser.parse_args(argv)
    if args.inputs:
        result = json.loads(Path(args.inputs).read_text())
    else:
        wp.config.quiet = True
        device = wp.get_device(args.device)
        runs = []
        t0 = time.perf_counter()
        sweep = list(itertools.product(args.iterations, args.speeds, sorted(args.substeps, reverse=True)))
        failed = set()
        for it, speed, substeps in track(sweep, "stability_map"):
            if (it, speed) in failed:
                # fewer substeps only fail harder: not run
                continue
            r = run_one(args, device, substeps, it, speed)
            runs.append(r)
            print(
                f"iterations {it} speed {speed:5.1f} m/s substeps {substeps:3d}: "
                f"{'stable' if r['stable'] else 'UNSTABLE: ' + r['failure']} "
                f"(penetration {r['max_wall_penetration_spacings']:.2f}, fast {r['fast_particle_substeps']})",
                flush=True,
            )
            if not r["stable"]:
                failed.add((it, speed))
        result = {
            "particles": args.block**3,
            "spacing_m": args.spacing,
            "seconds": args.seconds,
            # the keywords set (the rest at the solver's defaults); each row has its iterations
            **{k: v for k, v in solver_keywords(args, args.spacing, iterations=0).items() if k != "iterations"},
            "wall_s": time.perf_counter() - t0,
        }
        result = write_record("stability_map", device, result, args.json, rows=runs)
    if args.plot:
        plot(result, args.plot)


if __name__ == "__main__":
    main(sys.argv[1:])
