# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The box of test_floating_box_comes_to_rest over time (the data beside this file).

Every 10 frames: time [s], tilt [deg], angular speed [rad/s], vertical speed [m/s], fluid RMS speed [m/s],
RMS speed of the fluid within two spacings of the box [m/s]. Run from the repository root:
``python docs/validation/floating_box/series.py cuda:0 8 > series.txt`` (device, seconds, optional JSON of
solver keywords).
"""

import json
import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
from newton.tests.test_fluid_still_water import (  # noqa: E402
    BOX_HALF_HEIGHT,
    BOX_SPACING,
    floating_box_sim,
    tilt_deg,
)


def main():
    wp.config.quiet = True
    device = sys.argv[1] if len(sys.argv) > 1 else "cpu"
    seconds = float(sys.argv[2]) if len(sys.argv) > 2 else 8.0
    keywords = json.loads(sys.argv[3]) if len(sys.argv) > 3 else {}
    d, box = BOX_SPACING, BOX_HALF_HEIGHT
    sim = floating_box_sim(device, **keywords)
    for k in range(int(seconds * 6)):
        sim.step(10)
        bq, bqd = sim.state_0.body_q.numpy()[0], sim.state_0.body_qd.numpy()[0]
        tilt = tilt_deg(bq)
        v, q = sim.qd(), sim.q()
        rms = float(np.sqrt((v * v).sum(1).mean()))
        # the fluid within two spacings of the box's sides and bottom
        near = np.all(np.abs(q - bq[:3]) < np.array([0.15 + 2 * d, 0.15 + 2 * d, box + 2 * d]), axis=1)
        rms_near = float(np.sqrt((v[near] * v[near]).sum(1).mean())) if near.any() else 0.0
        row = ((k + 1) / 6, tilt, float(np.linalg.norm(bqd[3:])), abs(float(bqd[2])), rms, rms_near)
        print(" ".join(f"{x:.4g}" for x in row), flush=True)


if __name__ == "__main__":
    main()
