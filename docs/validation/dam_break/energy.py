# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The Koshizuka & Oka dam break's energy over time, beside its surge front (the data beside this file).

An inviscid fluid on a frictionless floor keeps its energy until its front meets the far wall (Z = 5, at
about T = 3.4): what the solver loses before that is its own dissipation. For each setting this steps the
scene of ``python -m benchmarks validate_dam_break`` (20 particles across L unless ``--per-l``) and writes,
every frame, the kinetic and potential energy (the floor at z = 0) and the front, and at the experiment's
times the front's error; it prints the change of the total against the start [per mille] at a few T and the
front's largest and mean error. Settings are named: ``poly6``, ``one`` (``fluid_density_kernel="one_kernel"``)
or ``one_cc`` (with ``fluid_coarse_correction=0.5``), then ``_iN`` (iterations), and ``_d0`` for no non-affine
damping, e.g. ``poly6_i16_d0``. Run from the repository root:
``python docs/validation/dam_break/energy.py poly6_i2 one_cc_i2 [--substeps S] [--share B] [--cell C] [--sweeps N]
--json F``.
"""

import argparse
import json
import math
import re
import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
from benchmarks.run_record import write_record  # noqa: E402
from benchmarks.validate_dam_break import DATA, G, L, Stepper, build, surge_front  # noqa: E402
from newton._src.solvers.xpbd.fluid import coarse_correction  # noqa: E402
from newton.examples.fluid.progress import track  # noqa: E402

KERNELS = {"poly6": {}, "one": {"fluid_density_kernel": "one_kernel"}}


def keywords(name: str, share: float, cell: float | None) -> dict:
    """The solver keywords of a named setting (``poly6_i2``, ``one_cc_i8_d0``, ...)."""
    m = re.fullmatch(r"(poly6|one)(_cc)?_i(\d+)(_d0)?", name)
    if m is None:
        raise ValueError(f"setting {name!r} is invalid: expected (poly6|one)[_cc]_iN[_d0], e.g. one_cc_i2")
    kw = {**KERNELS[m.group(1)], "iterations": int(m.group(3))}
    if m.group(2):
        kw["fluid_coarse_correction"] = share
        if cell is not None:
            kw["fluid_coarse_cell"] = cell
    if m.group(4):
        kw["fluid_nonaffine_damping"] = 0.0
    return kw


def run(name: str, args, points: np.ndarray) -> dict:
    d = L / args.per_l
    scene = argparse.Namespace(substeps=args.substeps, speed_clamp=0.0, floor_friction=0.0)
    kw = keywords(name, args.share, args.cell)
    model, solver, pipeline, dt = build(args.per_l, 6, scene, wp.get_device(args.device), fluid_rest_distance=d, **kw)
    mass = model.particle_mass.numpy()
    stepper = Stepper(model, solver, pipeline, dt)
    t_scale = math.sqrt(L / (2.0 * G))
    end = args.frames / 60.0
    events = sorted(
        [(f / 60.0, "frame") for f in range(args.frames + 1)] + [(t, "point") for t in points[:, 0] * t_scale]
    )
    frames, fronts = [], []
    for t, kind in events:
        state = stepper.advance_to(t)
        q = state.particle_q.numpy()
        if kind == "point":
            fronts.append(surge_front(q, d) / L if t <= end + 1e-9 else float("nan"))
            continue
        v = state.particle_qd.numpy()
        kinetic = 0.5 * float((mass * (v * v).sum(axis=1)).sum())
        potential = float((mass * G * q[:, 2]).sum())
        frames.append({"T": t / t_scale, "kinetic_J": kinetic, "potential_J": potential, "Z": surge_front(q, d) / L})
    error = (np.asarray(fronts) - points[:, 1]) / points[:, 1]
    stats = solver.fluid_diagnostics(stepper.state)
    return {
        "setting": name,
        "particles": int(model.particle_count),
        "substeps": args.substeps,
        "iterations": kw["iterations"],
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        "front_max_abs_relative_error": float(np.nanmax(np.abs(error))),
        "front_mean_abs_relative_error": float(np.nanmean(np.abs(error))),
        "frames": frames,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("settings", nargs="+", help="named settings, e.g. poly6_i2 one_cc_i2_d0")
    parser.add_argument("--per-l", type=int, default=20, help="particles across L")
    parser.add_argument("--substeps", type=int, default=8)
    parser.add_argument("--share", type=float, default=0.5, help="fluid_coarse_correction of the _cc settings")
    parser.add_argument("--cell", type=float, default=None, help="fluid_coarse_cell of the _cc settings")
    parser.add_argument("--frames", type=int, default=24, help="frames at 60 Hz (24: past the far wall's impact)")
    parser.add_argument(
        "--sweeps", type=int, default=None, help="the correction's sweeps a substep (coarse_correction.SWEEPS)"
    )
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    wp.config.quiet = True
    if args.sweeps is not None:
        coarse_correction.SWEEPS = args.sweeps

    with open(DATA) as f:
        points = np.asarray(json.load(f)["points"])
    rows = []
    for name in track(args.settings, "dam break energy", unit="setting"):
        r = run(name, args, points)
        e0 = r["frames"][0]["kinetic_J"] + r["frames"][0]["potential_J"]
        change = [1e3 * (f["kinetic_J"] + f["potential_J"] - e0) / e0 for f in r["frames"]]
        r["energy_change_per_mille"] = change
        rows.append(r)
        steps = " ".join(f"T {f['T']:.2f}: {c:+.1f}" for f, c in list(zip(r["frames"], change, strict=True))[::3])
        print(
            f"{name:>14} {args.substeps} substeps: front {100 * r['front_max_abs_relative_error']:.1f} / "
            f"{100 * r['front_mean_abs_relative_error']:.1f} %, energy [per mille] {steps}",
            flush=True,
        )
    write_record(
        "dam_break_energy",
        wp.get_device(args.device),
        {"per_l": args.per_l, "share": args.share, "cell": args.cell, "sweeps": args.sweeps, "substeps": args.substeps},
        args.json,
        rows=rows,
    )


if __name__ == "__main__":
    main()
