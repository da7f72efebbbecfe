# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The floating box of test_floating_box_comes_to_rest over time, and the water's multipliers under it and away from it.

Runs the test's scene (``floating_box_sim``: a 500 kg/m^3 box 4 spacings tall on a 0.8 m pool, 8 x 2)
for ``--seconds`` and prints every half second the box's height, its draft over Archimedes' (as the test
measures it) and its tilt. Over the last second it averages each fluid particle's density multiplier and
prints them by height below the box's bottom, in bins of a spacing, for the particles under the box's
footprint and for those at least two spacings beside it (away from the pool's walls): water at rest has
the same pressure at the same height, so the two columns agree unless the water under the box holds a
load of its own. docs/archive/validation_notebook.md, "Floating bodies: Archimedes".

Usage: python docs/validation/floating_box/under_box.py [--device cpu] [--offset 0] [--seconds 5] [--json F]
"""

import argparse
import json
import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
from newton.examples.fluid.progress import track  # noqa: E402
from newton.tests.test_fluid_still_water import (  # noqa: E402
    BOX_HALF_HEIGHT,
    BOX_POOL_HALF,
    BOX_SPACING,
    draft_over_archimedes,
    floating_box_sim,
    tilt_deg,
)

BINS = 6  # height bins below the box's bottom [spacings]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--offset", type=float, default=0.0, help="the box's start off centre [m]")
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    wp.config.quiet = True
    d = BOX_SPACING
    sim = floating_box_sim(args.device, args.offset)
    fluid = sim.solver._fluid
    frames = round(args.seconds * 60.0)
    series, multipliers, heights = [], [], []
    for f in track(range(frames), "under_box", unit="frame"):
        sim.step(1)
        if (f + 1) % 30 == 0:
            body_q = sim.state_0.body_q.numpy()[0]
            series.append(
                {
                    "t_s": (f + 1) / 60.0,
                    "z_m": float(body_q[2]),
                    "draft": draft_over_archimedes(sim.q(), body_q),
                    "tilt_deg": tilt_deg(body_q),
                }
            )
        if f >= frames - 60 and f % 2 == 0:
            slot = fluid.search.slot_of_particle.numpy()
            multipliers.append(fluid.lambda_rho.numpy()[slot][:, 0])
            heights.append(sim.q()[:, 2])
    lam, z = np.mean(multipliers, axis=0), np.mean(heights, axis=0)
    q = sim.q()
    body_q = sim.state_0.body_q.numpy()[0]
    bottom = body_q[2] - BOX_HALF_HEIGHT
    under = (np.abs(q[:, 0] - body_q[0]) < 0.15 - 0.5 * d) & (np.abs(q[:, 1] - body_q[1]) < 0.15 - 0.5 * d)
    beside = (np.abs(q[:, 0] - body_q[0]) > 0.15 + 2.0 * d) | (np.abs(q[:, 1] - body_q[1]) > 0.15 + 2.0 * d)
    beside &= np.all(np.abs(q[:, :2]) < BOX_POOL_HALF - 1.5 * d, axis=1)
    rows = []
    for b in range(BINS):
        band = (z > bottom - (b + 1) * d) & (z <= bottom - b * d)
        if not (band & under).any() or not (band & beside).any():
            continue
        rows.append(
            {
                "below_bottom_spacings": [b, b + 1],
                "multiplier_under": float(lam[band & under].mean()),
                "multiplier_beside": float(lam[band & beside].mean()),
                "particles_under": int((band & under).sum()),
                "particles_beside": int((band & beside).sum()),
            }
        )
    print(f"{'t [s]':>6}{'z [m]':>9}{'draft':>8}{'tilt [deg]':>12}")
    for s in series:
        print(f"{s['t_s']:>6.1f}{s['z_m']:>9.4f}{s['draft']:>8.3f}{s['tilt_deg']:>12.2f}")
    print(f"{'below bottom [d]':>17}{'under':>13}{'beside':>13}{'ratio':>7}")
    for r in rows:
        lo, hi = r["below_bottom_spacings"]
        ratio = r["multiplier_under"] / r["multiplier_beside"]
        print(f"{lo:>8}-{hi:<8}{r['multiplier_under']:>13.3e}{r['multiplier_beside']:>13.3e}{ratio:>7.2f}")
    last = series[-1]
    print(
        f"under_box: after {args.seconds} s draft {last['draft']:.3f} of Archimedes', tilt {last['tilt_deg']:.2f} deg"
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                {"device": args.device, "offset_m": args.offset, "series": series, "multipliers": rows}, f, indent=1
            )


if __name__ == "__main__":
    main()
