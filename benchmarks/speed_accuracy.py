# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Speed against accuracy: the 2:1 dam break over iterations x substeps and the tolerance mode.

Scene: the column of Koshizuka & Oka (``validate_dam_break.py``; ``--per-l`` particles across L,
``--depth`` layers: 20 x 16 = 12,800 particles, 40 x 31 = 99,200) in a tank 5L long, no cohesion,
viscosity or speed clamp, simulated from release to ``--t-end`` (default 1.5 s: collapse, impact on
the far wall, plunging wave, sloshing). Every run is timed over all its frames but the first
(kernel compilation; on CUDA each frame is one replayed graph) and its density error is measured
every ``--sample-every`` frames with the independent estimator of ``reference_dfsph.py``
(poly6, ghost-lattice walls). Fixed counts: ``--iterations`` x ``--substeps``; tolerance mode: up
to ``--tolerance-iterations`` XPBD iterations whose density passes stop once the mean compression is
within each of ``--tolerances`` (``fluid_density_tolerance``); with ``--max-iterations N``
(``fluid_max_iterations``) above 1, each XPBD iteration instead runs up to N density passes that stop
there. Every other solver keyword is a flag named after it.

Prints a table and writes JSON; ``--plot PNG`` draws the chart from one or more JSON files
(``--inputs``, default: this run) with SPlisHSPlasH's points from ``reference_dfsph.py`` JSON
(``--reference``); with ``--worst`` it draws each run's worst sample instead of its average: the
moment a bound that must hold throughout (what a tolerance promises) is held to. A run whose mean
compression passes 50 % at a sample stops there (``crushed_at_s``; its time is of the frames it ran;
``--crushed 0`` runs every setting to the end). Each run records the most particles found beyond a
tank wall at a sample (``outside_tank``: fluid thrown over the walls or let through them).

Usage::

    python -m benchmarks speed_accuracy --device cpu --json docs/validation/speed_accuracy_12k_cpu.json
    python -m benchmarks speed_accuracy --plot docs/images/speed_accuracy.png --inputs a.json b.json --reference ref.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from newton.examples.fluid.progress import track

from .frames import add_solver_arguments, solver_keywords, solver_record
from .run_record import write_record

# a run whose mean compression passes this at a sample stops there, recorded as crushed (--crushed)
CRUSHED = 0.5


def run_one(args, device, substeps: int, iterations: int, tolerance: float, passes: int = 1) -> dict:
    import warp as wp  # noqa: PLC0415

    from . import reference_dfsph as reference  # noqa: PLC0415
    from . import validate_dam_break as validate  # noqa: PLC0415

    L = validate.L
    d = L / args.per_l
    # the keywords set by flags, then the run's own point of the sweep
    keywords = solver_keywords(args, d, iterations=iterations)
    keywords.update(fluid_density_tolerance=tolerance, fluid_max_iterations=passes)
    model, solver, pipeline, dt = validate.build_plain(args.per_l, args.depth, substeps, device, **keywords)
    rec = reference.Recorder(L, d, 1000.0 * d**3, solver.fluid_smoothing_length, args.depth * d)
    states = [model.state(), model.state()]
    contacts = pipeline.contacts()

    def simulate():
        for _ in range(substeps):
            states[0].clear_forces()
            pipeline.collide(states[0], contacts)
            solver.step(states[0], states[1], None, contacts, dt)
            states[0], states[1] = states[1], states[0]

    frames = int(round(args.t_end * 60.0))
    with wp.ScopedDevice(device):
        simulate()  # the first frame compiles (and is not timed)
        frame = simulate
        if device.is_cuda:
            with wp.ScopedCapture() as capture:
                simulate()
            frame = lambda: wp.capture_launch(capture.graph)  # noqa: E731
            start = 2
        else:
            start = 1
        elapsed, crushed_at, ran = 0.0, None, frames
        for k in range(start, frames):
            wp.synchronize_device(device)
            t0 = time.perf_counter()
            frame()
            wp.synchronize_device(device)
            elapsed += time.perf_counter() - t0
            if (k + 1) % args.sample_every == 0:
                rec.record((k + 1) / 60.0, states[0].particle_q.numpy(), states[0].particle_qd.numpy())
                if 0.0 < args.crushed < rec.rows[-1]["mean_compression"]:
                    # the setting does not hold the column; the crushed neighbourhoods only slow the rest down
                    crushed_at, ran = (k + 1) / 60.0, k + 1
                    break
        stats = solver.fluid_diagnostics(states[0])
    s = rec.rows
    if tolerance <= 0.0:
        mode = "fixed" if passes == 1 else "fixed, sub-passes"
    else:
        mode = "tolerance" if passes == 1 else "tolerance, sub-passes"
    return {
        "mode": mode,
        "substeps": substeps,
        **solver_record(solver),
        # the passes that corrected, over every substep of the run
        "density_passes_per_substep": (
            stats["density_subiterations"] / (ran * substeps) if tolerance > 0.0 or passes > 1 else iterations
        ),
        "ms_per_frame": 1000.0 * elapsed / (ran - start),
        # [s] when the mean compression passed CRUSHED and the run stopped; None: it ran to the end
        "crushed_at_s": crushed_at,
        "mean_abs_density_error": float(np.mean([r["mean_abs_density_error"] for r in s])),
        "mean_compression": float(np.mean([r["mean_compression"] for r in s])),
        "p99_compression": float(np.mean([r["p99_compression"] for r in s])),
        "max_compression": float(np.max([r["max_compression"] for r in s])),
        # the worst moment: what a bound that must hold at every sample (a tolerance's promise) is held to
        "worst_mean_compression": float(np.max([r["mean_compression"] for r in s])),
        "worst_p99_compression": float(np.max([r["p99_compression"] for r in s])),
        "samples": [
            {k: round(r[k], 6) for k in ("t", "mean_abs_density_error", "mean_compression", "p99_compression")}
            for r in s
        ],
        "nonfinite_recovered": int(stats["nonfinite_recovered"]),
        # the most particles beyond a tank wall at a sample
        "outside_tank": int(max(r["outside_tank"] for r in s)),
        "final_front_over_L": s[-1]["front_over_L"],
        "final_energy": s[-1]["energy"],
    }


def sweep(args) -> dict:
    import warp as wp  # noqa: PLC0415

    wp.config.quiet = True
    device = wp.get_device(args.device)
    configs = [(s, i, 0.0) for s in args.substeps for i in args.iterations]
    # with --max-iterations above 1 the tolerance stops density passes within each XPBD iteration
    # (upstream's per-iteration work is not repeated for a pass), else the XPBD iterations themselves
    passes = args.max_iterations or 1
    configs += [(s, args.tolerance_iterations, tol, passes) for s in args.substeps for tol in args.tolerances]
    runs = []
    print(
        f"{'mode':<10}{'substeps':>9}{'iters':>6}{'tol':>8}{'passes':>8}{'ms/frame':>10}"
        f"{'mean|e|':>9}{'mean c':>8}{'p99 c':>8}{'max c':>8}{'worst c':>9}{'worst p99':>10}{'outside':>8}"
    )
    particles = args.per_l * 2 * args.per_l * args.depth
    result = {
        "particles": particles,
        "per_L": args.per_l,
        "depth_layers": args.depth,
        "t_end_s": args.t_end,
        "sample_every_frames": args.sample_every,
        # mean compression at which a run stopped (0: every run to the end)
        "crushed_stop": args.crushed,
        "scene": "Koshizuka & Oka 2:1 dam break, tank 5L, no cohesion/viscosity/speed clamp, 60 Hz frames",
    }
    for config in track(configs, "speed_accuracy"):
        r = run_one(args, device, *config)
        runs.append(r)
        # written after every run, so an interrupted sweep keeps what it measured
        record = write_record("speed_accuracy", device, result, args.json, rows=runs)
        print(
            f"{r['mode'][:10]:<10}{r['substeps']:>9}{r['iterations']:>6}{r['fluid_density_tolerance']:>8.4f}"
            f"{r['density_passes_per_substep']:>8.2f}{r['ms_per_frame']:>10.2f}"
            f"{100 * r['mean_abs_density_error']:>8.2f}%{100 * r['mean_compression']:>7.2f}%"
            f"{100 * r['p99_compression']:>7.2f}%{100 * r['max_compression']:>7.2f}%"
            f"{100 * r['worst_mean_compression']:>8.2f}%{100 * r['worst_p99_compression']:>9.2f}%"
            f"{r['outside_tank']:>8}"
            + (f"  crushed at {r['crushed_at_s']:.2f} s" if r["crushed_at_s"] is not None else ""),
            flush=True,
        )
    return record


def rows_of(record: dict) -> list:
    """A record's runs (written before 2026-11-26 under "runs", since then under "rows")."""
    return record.get("rows", record.get("runs", []))


def run_mode(run: dict) -> str:
    """The run's curve: its mode, and whether it carried multipliers between substeps."""
    return run["mode"] + (", warm start" if run.get("fluid_warm_start", 0.0) > 0.0 else "")


def plot(inputs: list, reference: str | None, path: str, worst: bool = False):
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    # one row per scene and device: the runs of files of the same one are drawn together
    results = {}
    for p in inputs:
        result = json.loads(Path(p).read_text())
        row = results.setdefault((result["particles"], result["device"]), {**result, "runs": []})
        row["runs"] += rows_of(result)
    results = list(results.values())
    ref = json.loads(Path(reference).read_text()) if reference else None
    # (run's value, the samples' value it reduces, label); with ``worst`` the largest sample of the
    # run, otherwise the mean over its samples
    if worst:
        metrics = (
            ("worst_mean_compression", "mean_compression", "mean compression, worst sample"),
            ("worst_p99_compression", "p99_compression", "p99 compression, worst sample"),
        )
    else:
        metrics = (
            ("mean_abs_density_error", "mean_abs_density_error", "mean |rho/rho0 - 1|"),
            ("mean_compression", "mean_compression", "mean compression"),
            ("p99_compression", "p99_compression", "p99 compression"),
        )
    reduce = np.max if worst else np.mean
    fig, axes = plt.subplots(
        len(results), len(metrics), figsize=(19 if len(metrics) == 3 else 16, 5.5 * len(results)), squeeze=False
    )
    # a curve per mode (and XPBD iteration count of the sub-pass modes)
    curves = (
        ("fixed", None, "-o", "iterations"),
        ("fixed, warm start", None, "-D", "iterations, warm start 0.5"),
        ("tolerance", None, "--s", "tolerance on XPBD iterations"),
        ("tolerance, sub-passes", 1, ":^", "tolerance, sub-passes in 1 iteration"),
        ("tolerance, sub-passes", 2, "-.v", "tolerance, sub-passes in 2 iterations"),
    )
    for row, result in zip(axes, results, strict=True):
        title = f"{result['particles']:,} particles, {result['device']}"
        for ax, (key, sample_key, label) in zip(row, metrics, strict=True):
            for n, substeps in enumerate(sorted({r["substeps"] for r in result["runs"]})):
                color = f"C{n}"
                for mode, iterations, style, name in curves:
                    rs = [
                        r
                        for r in result["runs"]
                        if run_mode(r) == mode and r["substeps"] == substeps and iterations in (None, r["iterations"])
                    ]
                    rs.sort(key=lambda r: r["ms_per_frame"])
                    if not rs:
                        continue
                    ax.plot(
                        [r["ms_per_frame"] for r in rs],
                        [r[key] for r in rs],
                        style,
                        color=color,
                        label=f"{substeps} substeps, {name}",
                        alpha=1.0 if mode.startswith("fixed") else 0.8,
                    )
                    for r in rs:
                        fixed = mode.startswith("fixed")
                        tag = str(r["iterations"]) if fixed else f"{100 * r['fluid_density_tolerance']:g}%"
                        ax.annotate(
                            tag, (r["ms_per_frame"], r[key]), fontsize=7, xytext=(3, 3), textcoords="offset points"
                        )
            if (
                ref
                and ref.get("per_L") == result.get("per_L")
                and ref.get("depth_layers") == result.get("depth_layers")
            ):
                for run in rows_of(ref):
                    if "DFSPH" not in run["solver"]:
                        continue
                    s = run["samples"][1:]
                    value = float(reduce([r[sample_key] for r in s]))
                    ax.plot(
                        run["ms_per_frame"],
                        value,
                        "k*",
                        markersize=12,
                        label=f"SPlisHSPlasH DFSPH (CPU, {run['threads']} threads)",
                    )
            ax.axvline(1000.0 / 60.0, color="gray", linestyle=":", label="real time (60 Hz)")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set(xlabel="ms per frame (1/60 s)", ylabel=label, title=f"{label}: {title}")
            ax.grid(True, which="both", alpha=0.25)
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--per-l", type=int, default=20, help="particles across L")
    parser.add_argument("--depth", type=int, default=16, help="particle layers in y")
    parser.add_argument("--t-end", type=float, default=1.5, help="simulated time [s]")
    parser.add_argument("--sample-every", type=int, default=3, help="frames between density samples")
    parser.add_argument(
        "--crushed",
        type=float,
        default=CRUSHED,
        help="stop a run at a sample past this mean compression (0: run every setting to the end)",
    )
    parser.add_argument("--substeps", type=int, nargs="+", default=[2, 4, 8])
    parser.add_argument(
        "--iterations", type=int, nargs="*", default=[1, 2, 4, 8], help="fixed counts (none: only the tolerance runs)"
    )
    parser.add_argument(
        "--tolerances",
        type=float,
        nargs="*",
        default=[0.01, 0.005, 0.0025, 0.001],
        help="runs in the tolerance mode, one per fluid_density_tolerance",
    )
    parser.add_argument(
        "--tolerance-iterations", type=int, default=8, help="XPBD iterations of the tolerance runs (at most)"
    )
    # every other solver keyword; --max-iterations above 1 makes the tolerance runs stop density passes
    # within each XPBD iteration, and --density-tolerance is the sweep's (the runs set it)
    add_solver_arguments(parser, step_flags=False)
    parser.add_argument("--plot", default=None, help="draw the chart here (from --inputs, or this run)")
    parser.add_argument("--inputs", nargs="*", default=None, help="sweep JSON files to plot instead of running")
    parser.add_argument("--reference", default=None, help="reference_dfsph.py JSON (SPlisHSPlasH points)")
    parser.add_argument(
        "--worst", action="store_true", help="plot each run's worst sample (mean and p99 compression), not its mean"
    )
    args = parser.parse_args(argv)
    inputs = args.inputs
    if not inputs:
        sweep(args)
        inputs = [args.json] if args.json else []
    if args.plot and inputs:
        plot(inputs, args.reference, args.plot, args.worst)


if __name__ == "__main__":
    main(sys.argv[1:])
