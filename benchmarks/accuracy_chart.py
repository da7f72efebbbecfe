# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Physical error against cost: the standing wave and Torricelli's jet over substeps x iterations (issue #27 item 5).

Runs ``sloshing.py`` (the period's error against linear theory, and the share of the amplitude kept per
period), ``torricelli.py`` (the jet speed's error against sqrt(2 g H)) and ``hydrostatic_pressure.py``
(the floor force against the weight, the largest layer's pressure error) for every substeps x iterations
of ``--substeps`` x ``--iterations`` in each mode: the solver's defaults (``--density-kernel`` sets the kernel of
the modes that name none), without the non-affine damping, with the warm start, and ``fluid_density_kernel="one_kernel"`` with ``fluid_coarse_correction=0.5``, with and
without the damping. ``--size small`` is the CPU size (800, 2,400 and 1,024 particles), ``--size large``
the GPU one (about 100k, 150k and 100k). Prints a table, writes every run's record to ``--json`` and, with
``--plot``, one panel per error against ms per frame (the frames alone, read-backs left out, no graph
capture on the CPU, one CUDA graph per frame on a GPU), one curve per mode and iteration count, with the real-time line (16.7 ms per 60 Hz frame).

Usage::

    python -m benchmarks accuracy_chart --size small --json chart_cpu.json --plot chart_cpu.png
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json

import warp as wp

from newton._src.solvers.xpbd.fluid.calibration import DENSITY_KERNELS
from newton._src.solvers.xpbd.fluid.config import FluidConfig
from newton.examples.fluid.progress import track

from . import hydrostatic_pressure, sloshing, torricelli
from .run_record import write_record

#: the kernel of the modes that name none, unless ``--density-kernel`` is given
DEFAULT_DENSITY_KERNEL = FluidConfig.fluid_density_kernel
PAIR = ["--density-kernel", "one_kernel", "--coarse-correction", "0.5"]
MODES = {
    "default": [],
    "no damping": ["--nonaffine-damping", "0"],
    "warm start 0.5": ["--warm-start", "0.5"],
    # the one kernel with the coarse correction: the still-water and sloshing setting of docs/validation.rst
    "one kernel + correction": PAIR,
    "one kernel + correction, no damping": [*PAIR, "--nonaffine-damping", "0"],
}
SIZES = {
    "small": {"sloshing": ["--per-length", "20", "--depth-particles", "4"], "torricelli": [], "pressure": []},
    "large": {
        "sloshing": ["--per-length", "160", "--depth-particles", "8"],
        "torricelli": ["--spacing", "0.005", "--hole", "16", "--sill", "16"],
        "pressure": ["--n", "50", "--layers", "40"],
    },
}


def measure(problem: str, extra: list[str], device) -> dict:
    """One run of a problem's benchmark with ``extra`` arguments; its record."""
    module = {"sloshing": sloshing, "torricelli": torricelli, "pressure": hydrostatic_pressure}[problem]
    args = module.parser().parse_args([*extra, "--device", str(device)])
    with contextlib.redirect_stdout(io.StringIO()), wp.ScopedDevice(device):
        return module.run(args, device)


def error(problem: str, r: dict) -> dict:
    """The physical errors a run is charted by."""
    if problem == "sloshing":
        return {"period_error": r["period_error"], "amplitude_kept_per_period": r["amplitude_kept_per_period"]}
    if problem == "pressure":
        return {"floor_force_error": r["floor_force_error"], "pressure_error_max": r["pressure_error_max"]}
    return {"jet_speed_error": r["jet_speed_ratio_mean"] - 1.0}


def plot(rows: list[dict], path: str, title: str) -> None:
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    panels = [
        ("sloshing", "period_error", "standing wave: |period error|", True),
        ("sloshing", "amplitude_kept_per_period", "standing wave: 1 - amplitude kept per period", False),
        ("torricelli", "jet_speed_error", "Torricelli: |jet speed error|", True),
        ("pressure", "floor_force_error", "hydrostatic: |floor force error|", True),
    ]
    panels = [panel for panel in panels if any(r["problem"] == panel[0] for r in rows)]
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4.2), squeeze=False)
    axes = axes[0]
    for ax, (problem, key, label, absolute) in zip(axes, panels, strict=True):
        curves = {}
        for r in rows:
            if r["problem"] == problem:
                curves.setdefault((r["mode"], r["iterations"]), []).append(r)
        for (mode, iterations), runs in sorted(curves.items()):
            runs.sort(key=lambda r: r["ms_per_frame"])
            y = [abs(r[key]) if absolute else 1.0 - r[key] for r in runs]
            ax.plot([r["ms_per_frame"] for r in runs], y, "o-", label=f"{mode}, {iterations} it")
            for r, v in zip(runs, y, strict=True):
                ax.annotate(str(r["substeps"]), (r["ms_per_frame"], v), fontsize=7)
        ax.axvline(1000.0 / 60.0, color="gray", ls="--", lw=1, label="real time (60 Hz)")
        ax.set_xscale("log")
        ax.set_xlabel("ms per frame (labels: substeps)")
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", choices=sorted(SIZES), default="small")
    parser.add_argument("--substeps", type=int, nargs="+", default=[4, 8, 16, 32])
    parser.add_argument("--iterations", type=int, nargs="+", default=[2, 4])
    parser.add_argument("--modes", nargs="+", default=list(MODES), choices=list(MODES))
    parser.add_argument("--problems", nargs="+", default=["sloshing", "torricelli", "pressure"])
    parser.add_argument(
        "--density-kernel",
        choices=DENSITY_KERNELS,
        default=None,
        help="the density kernel of the modes that name none (unset: the solver's default; charts before "
        "2026-11-30 were drawn with poly6, the default then)",
    )
    parser.add_argument("--device", default=None)
    parser.add_argument("--json", default=None)
    parser.add_argument("--plot", default=None)
    parser.add_argument(
        "--from-json", nargs="+", default=None, help="plot the rows of these records instead of running"
    )
    args = parser.parse_args(argv)
    wp.config.quiet = True
    if args.from_json:
        records = [json.load(open(path)) for path in args.from_json]
        rows = [row for record in records for row in record["rows"]]
        first = records[0]
        plot(rows, args.plot, f"{first['device']}, {first['size']} ({first['date']}): error against cost")
        return {"rows": rows}
    device = wp.get_device(args.device)
    grid = [
        (problem, mode, substeps, iterations)
        for problem in args.problems
        for mode in args.modes
        for iterations in args.iterations
        for substeps in args.substeps
    ]
    rows = []
    print(
        f"{'problem':<11}{'mode':<37}{'particles':>10}{'sub x it':>9}{'ms/frame':>10}{'error':>9}{'kept/T':>8}{'mean|e|':>9}"
    )
    for problem, mode, substeps, iterations in track(grid, "accuracy_chart", unit="run"):
        flags = MODES[mode]
        if args.density_kernel is not None and "--density-kernel" not in flags:
            flags = [*flags, "--density-kernel", args.density_kernel]
        kernel = flags[flags.index("--density-kernel") + 1] if "--density-kernel" in flags else DEFAULT_DENSITY_KERNEL
        extra = [
            *SIZES[args.size][problem],
            *flags,
            "--substeps",
            str(substeps),
            "--iterations",
            str(iterations),
        ]
        r = measure(problem, extra, device)
        r = {k: v for k, v in r.items() if not k.startswith(("signal", "speed_rows"))}
        row = {"problem": problem, "mode": mode, "density_kernel": kernel, **r, **error(problem, r)}
        rows.append(row)
        e = row.get("period_error", row.get("jet_speed_error", row.get("floor_force_error")))
        kept = row.get("amplitude_kept_per_period", float("nan"))
        # after every run: a run cut short keeps what it measured
        record = write_record("accuracy_chart", device, {"size": args.size}, args.json, rows=rows)
        print(
            f"{problem:<11}{mode:<37}{row['particles']:>10}{substeps:>5} x {iterations:<1}{row['ms_per_frame']:>10.2f}"
            f"{100 * e:>8.1f}%{kept:>8.3f}{100 * row['mean_abs_density_error']:>8.2f}%"
        )
    record = write_record("accuracy_chart", device, {"size": args.size}, args.json, rows=rows)
    if args.plot:
        name = device.name if device.is_cuda else "CPU"
        plot(rows, args.plot, f"{name}, {args.size} ({record['date']}): error against cost")
    return record


if __name__ == "__main__":
    main()
