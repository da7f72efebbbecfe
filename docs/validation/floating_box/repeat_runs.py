# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""test_floating_box_comes_to_rest's measurement repeated, at each non-affine damping given (the data beside this file).

On a GPU the summation order differs from run to run, so the test's outcome does too: this runs the test's
``floating_box`` ``--runs`` times per damping and writes, per run, the largest tilt [deg], the mean angular
[rad/s] and vertical [m/s] speeds over the last second and the draft over Archimedes', with the count of
runs that meet all four of issue #23's bounds. On the CPU every run is the same unless ``--offset`` moves
run ``k``'s box ``k x offset`` [m] off centre at its start. ``--smoothing-ratio R`` sets ``fluid_smoothing_length``
to ``R`` spacings (with ``docs/archive/patches/one_kernel_density.patch`` applied: the one-kernel solver's box).
Run from the repository root:
``python docs/validation/floating_box/repeat_runs.py --device cuda:0 --runs 6 --damping 0.05 0.1 0.15 0.2 --json F``,
``python docs/validation/floating_box/repeat_runs.py --device cpu --runs 30 --offset 1e-6 --json F``;
``--density-kernel one_kernel --coarse-correction 0.5`` sets those keywords.
"""

import argparse
import json
import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
from benchmarks.floating_box import REST_BOUNDS  # noqa: E402
from newton.examples.fluid.progress import track  # noqa: E402
from newton.tests.test_fluid_still_water import BOX_SPACING, floating_box  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--runs", type=int, default=6)
    parser.add_argument("--damping", type=float, nargs="+", default=[0.1], help="fluid_nonaffine_damping values")
    parser.add_argument("--offset", type=float, default=0.0, help="run k starts the box k x this [m] off centre")
    parser.add_argument(
        "--smoothing-ratio",
        type=float,
        default=None,
        help="fluid_smoothing_length over the spacing (default: the solver's)",
    )
    parser.add_argument("--density-kernel", default=None, help="fluid_density_kernel (default: the solver's)")
    parser.add_argument("--coarse-correction", type=float, default=None, help="fluid_coarse_correction (default: off)")
    parser.add_argument(
        "--compression-damping", type=float, default=None, help="fluid_compression_damping (default: off)"
    )
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    wp.config.quiet = True
    device = wp.get_device(args.device)
    record = {
        "device": device.name if device.is_cuda else "cpu",
        "offset_m": args.offset,
        "smoothing_ratio": args.smoothing_ratio,
        "density_kernel": args.density_kernel,
        "coarse_correction": args.coarse_correction,
        "compression_damping": args.compression_damping,
        "runs": {},
    }
    extra = {} if args.smoothing_ratio is None else {"fluid_smoothing_length": args.smoothing_ratio * BOX_SPACING}
    if args.density_kernel is not None:
        extra["fluid_density_kernel"] = args.density_kernel
    if args.coarse_correction is not None:
        extra["fluid_coarse_correction"] = args.coarse_correction
    if args.compression_damping is not None:
        extra["fluid_compression_damping"] = args.compression_damping
    for damping in args.damping:
        rows = []
        for k in track(range(args.runs), f"damping {damping}", unit="run"):
            offset = k * args.offset
            tilt, spin, sink, draft = floating_box(args.device, offset, fluid_nonaffine_damping=damping, **extra)
            rows.append({"offset_m": offset, "tilt_deg": tilt, "spin_rad_s": spin, "sink_m_s": sink, "draft": draft})
        record["runs"][str(damping)] = rows
        t = np.array([r["tilt_deg"] for r in rows])
        s = np.array([r["spin_rad_s"] for r in rows])
        met = sum(
            r["tilt_deg"] < REST_BOUNDS["tilt_max_deg"]
            and r["spin_rad_s"] < REST_BOUNDS["angular_speed_rad_s"]
            and r["sink_m_s"] < REST_BOUNDS["vertical_speed_m_s"]
            and abs(r["draft"] - 1.0) < REST_BOUNDS["draft_error"]
            for r in rows
        )
        print(
            f"damping {damping}: tilt median {np.median(t):.2f} deg (max {t.max():.2f}), angular speed median "
            f"{np.median(s):.4f} rad/s (max {s.max():.4f}); all four bounds met in {met} of {len(rows)} runs"
        )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
