# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""What a density tolerance asks for over time: density passes per substep along a dam break.

The 2:1 column of ``speed_accuracy.py`` (Koshizuka & Oka, tank 5L, no cohesion, viscosity or speed
clamp) runs with ``fluid_density_tolerance`` and up to ``--max-passes`` density passes per XPBD
iteration; every ``--every`` frames it prints the passes that corrected per substep since the last
row, the RMS speed and the solver's largest compression. A tolerance can only save passes where
the substeps need fewer than the fixed count would run. Writes JSON with ``--json``.

Usage::

    python -m benchmarks tolerance_demand [--tolerance 0.0025] [--warm-start 0.5] [--seconds 5] [--json out.json]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import warp as wp

from newton.examples.fluid.progress import track

from .frames import add_solver_arguments, solver_keywords, solver_record
from .run_record import write_record


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--per-l", type=int, default=20, help="particles across L")
    parser.add_argument("--depth", type=int, default=16, help="particle layers in y")
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--every", type=int, default=15, help="frames per row")
    add_solver_arguments(parser, defaults={"fluid_max_iterations": 8, "fluid_density_tolerance": 0.0025}, iterations=1)
    args = parser.parse_args(argv)
    from . import validate_dam_break as validate  # noqa: PLC0415

    wp.config.quiet = True
    device = wp.get_device(args.device)
    model, solver, pipeline, dt = validate.build_plain(
        args.per_l, args.depth, args.substeps, device, **solver_keywords(args, validate.L / args.per_l)
    )
    stepper = validate.Stepper(model, solver, pipeline, dt)
    rows = []
    passes_before = 0
    samples = range(args.every, int(round(args.seconds * 60.0)) + 1, args.every)
    for frame in track(samples, "tolerance_demand", unit="sample"):
        state = stepper.advance_to(frame / 60.0)
        stats = solver.fluid_diagnostics(state)
        speed = np.linalg.norm(state.particle_qd.numpy().astype(np.float64), axis=1)
        passes = stats["density_subiterations"]
        rows.append(
            {
                "t_s": frame / 60.0,
                "passes_per_substep": (passes - passes_before) / (args.every * args.substeps),
                "rms_speed_m_s": float(np.sqrt(np.mean(speed**2))),
                "mean_abs_density_error": stats["mean_abs_density_error"],
                "max_compression": stats["max_compression"],
                "mean_compression": stats["mean_compression"],
            }
        )
        passes_before = passes
        r = rows[-1]
        print(
            f"t = {r['t_s']:.2f} s: {r['passes_per_substep']:.2f} passes per substep, RMS speed "
            f"{r['rms_speed_m_s']:.3f} m/s, mean / max compression {100 * r['mean_compression']:.2f} / "
            f"{100 * r['max_compression']:.2f} %",
            flush=True,
        )
    result = {
        "particles": int(model.particle_count),
        "per_L": args.per_l,
        "depth_layers": args.depth,
        "substeps": args.substeps,
        **solver_record(solver),
    }
    return write_record("tolerance_demand", device, result, args.json, rows=rows)


if __name__ == "__main__":
    main(sys.argv[1:])
