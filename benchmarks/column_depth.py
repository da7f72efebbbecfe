# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""How deep a closed column the density solve holds, against the XPBD iterations.

The column of Koshizuka & Oka (``validate_dam_break.py``: width L = 0.146 m, height 2L, a slice
``--depth`` layers deep between frictionless box walls) stands behind a gate, so it is closed on
every side but the top, and settles from a lattice at rest for ``--seconds``. ``--per-l`` sets the
depth in particles (2 x per L layers, spacing L / per L). A run counts as held if no particle left
the column's box and the largest compression at the end is below ``--collapse`` (a collapsing
column reaches 50-100 %); the particles outside it at the end that never rose above the walls
(through a wall or a joint, not over the open top) are counted apart. Each run records the estimate
g H / c^2 of the bottom's compression, c = iterations x spacing / substep duration
(docs/archive/validation_notebook.md, "Where the method fails"). Prints a table, writes JSON and, with ``--plot``,
the map (``--inputs``: from a JSON written before).

Usage::

    python -m benchmarks column_depth --per-l 10 20 30 --iterations 1 2 4 --json out.json --plot map.png
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import numpy as np

from newton.examples.fluid.progress import track

from .frames import add_solver_arguments, solver_keywords, solver_record
from .run_record import write_record


def run_one(per_l: int, iterations: int, args, device) -> dict:
    from . import validate_dam_break as validate  # noqa: PLC0415

    # walls 2.5L tall, as validate_dam_break.py's own runs
    wall_top = 2.5 * validate.L
    keywords = solver_keywords(args, validate.L / per_l, iterations=iterations)
    model, solver, pipeline, dt = validate.build_plain(
        per_l, args.depth, args.substeps, device, height=wall_top, gate=True, **keywords
    )
    stepper = validate.Stepper(model, solver, pipeline, dt)
    L, d = validate.L, validate.L / per_l
    width = args.depth * d
    outside = 0
    top = []
    highest = model.particle_q.numpy()[:, 2].copy()
    frames = int(round(args.seconds * 60.0))
    for k in range(1, frames + 1):
        # every substep: a particle thrown just over a wall's top can be above it for less than a frame
        for j in range(1, args.substeps + 1):
            q = stepper.advance_to((k - 1 + j / args.substeps) / 60.0).particle_q.numpy()
            highest = np.maximum(highest, q[:, 2])
        # a centre more than a spacing beyond a face of the column's box has left it: over the walls' top
        # (the box is open there), or through a wall or a joint if it never rose above them
        out = (q[:, 0] < -d) | (q[:, 0] > L + d) | (q[:, 1] < -d) | (q[:, 1] > width + d) | (q[:, 2] < -d)
        outside = max(outside, int(np.count_nonzero(out) + np.count_nonzero(~np.isfinite(q).all(axis=1))))
        top.append(float(np.percentile(q[:, 2], 99.0)) / d)
    # at the end only: a collapse presses particles deeper than a spacing into the walls for a while
    through = int(np.count_nonzero(out & (highest < wall_top)))
    stats = solver.fluid_diagnostics(stepper.state)
    c = iterations * d / dt
    height = 2.0 * L
    held = outside == 0 and stats["max_compression"] < args.collapse
    return {
        "per_L": per_l,
        "layers": 2 * per_l,
        "spacing_m": d,
        "iterations": iterations,
        "particles": int(model.particle_count),
        "estimate_gH_over_c2": 9.81 * height / c**2,
        "held": bool(held),
        "particles_outside": outside,
        "particles_through_walls": through,
        "substeps": args.substeps,
        **solver_record(solver),
        # at the end
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        "mean_compression": stats["mean_compression"],
        # 99th percentile of the particles' heights over the run [spacings]: the column's top, and how far it sank
        "top_start_spacings": top[0],
        "top_min_spacings": min(top),
        "top_end_spacings": top[-1],
    }


def plot(result: dict, path: str) -> None:
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    # (records written before 2026-11-26 name the rows "runs" and the compression "..._end")
    runs = result.get("rows", result.get("runs"))
    iterations = sorted({r["iterations"] for r in runs})
    layers = sorted({r["layers"] for r in runs})
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for r in runs:
        x, y = iterations.index(r["iterations"]), layers.index(r["layers"])
        color = "tab:green" if r["held"] else "tab:red"
        ax.add_patch(plt.Rectangle((x - 0.45, y - 0.45), 0.9, 0.9, color=color, alpha=0.35))
        outcome = "held" if r["held"] else f"{r['particles_outside']} out" if r["particles_outside"] else "crushed"
        if r["particles_outside"] and "particles_through_walls" in r:
            through = r["particles_through_walls"]
            outcome += f", {through} through walls" if through else " over the top"
        ax.annotate(
            f"{outcome}\ngH/c² {100 * r['estimate_gH_over_c2']:.1f} %\n"
            f"max c {100 * r.get('max_compression', r.get('max_compression_end')):.0f} %",
            (x, y),
            ha="center",
            va="center",
            fontsize=8,
        )
    ax.set_xlim(-0.5, len(iterations) - 0.5)
    ax.set_ylim(-0.5, len(layers) - 0.5)
    ax.set_xticks(range(len(iterations)), [str(i) for i in iterations])
    ax.set_yticks(range(len(layers)), [str(n) for n in layers])
    ax.set(
        xlabel=f"XPBD iterations ({result['substeps']} substeps per 1/60 s)",
        ylabel="column height [particle layers]",
        title=f"closed column of height 2L = 0.292 m, {result['depth_layers']} layers deep, {result['device']}",
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--per-l", type=int, nargs="+", default=[10, 20, 30], help="particles across L")
    parser.add_argument("--iterations", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--substeps", type=int, default=8)
    parser.add_argument("--depth", type=int, default=6, help="particle layers in y")
    parser.add_argument("--seconds", type=float, default=1.0)
    parser.add_argument("--collapse", type=float, default=0.3, help="largest compression that counts as collapsed")
    add_solver_arguments(parser, step_flags=False)
    parser.add_argument("--plot", default=None)
    parser.add_argument("--inputs", default=None, help="plot this JSON instead of running")
    args = parser.parse_args(argv)
    if args.inputs:
        plot(json.loads(Path(args.inputs).read_text()), args.plot)
        return None

    import warp as wp  # noqa: PLC0415

    wp.config.quiet = True
    device = wp.get_device(args.device)
    result = {
        "substeps": args.substeps,
        "depth_layers": args.depth,
        "seconds": args.seconds,
        "collapse_threshold": args.collapse,
    }
    rows = []
    print(
        f"{'layers':>7}{'iters':>6}{'particles':>10}{'gH/c^2':>8}{'held':>6}{'outside':>8}{'through':>8}{'max c':>8}"
        f"{'top sank':>9}"
    )
    for per_l, iterations in track(list(itertools.product(args.per_l, args.iterations)), "column_depth"):
        r = run_one(per_l, iterations, args, device)
        rows.append(r)
        # after every run: a sweep cut short keeps what it measured
        record = write_record("column_depth", device, result, args.json, rows=rows)
        print(
            f"{r['layers']:>7}{r['iterations']:>6}{r['particles']:>10}{100 * r['estimate_gH_over_c2']:>7.1f}%"
            f"{'yes' if r['held'] else 'no':>6}{r['particles_outside']:>8}{r['particles_through_walls']:>8}"
            f"{100 * r['max_compression']:>7.1f}%"
            f"{r['top_start_spacings'] - r['top_min_spacings']:>9.2f}",
            flush=True,
        )
    if args.plot:
        plot(record, args.plot)
    return record


if __name__ == "__main__":
    main(sys.argv[1:])
