# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Whether settled water follows a tilt of gravity: its surface levels again (a fluid) or stays (a yield).

The tank is the slice of ``benchmarks/sloshing.py`` (``--per-length``, ``--ratio``, ``--depth-particles``) or,
with ``--pool N LAYERS``, the square column of ``benchmarks/rest_column.py`` (``N`` x ``N`` x ``LAYERS`` at
0.05 m). It settles for ``--settle`` seconds with the non-affine damping at ``--settle-damping`` (as the
sloshing benchmark does), then gravity is turned by ``theta`` about y and the tank runs ``--seconds`` at the
keywords under test. A free surface that levels again under the new gravity tilts by ``theta`` against the
tank, which moves the centre of mass along x by ``s L^2 / (12 h)`` for a surface slope ``s``; the slope read
from the centre of mass, averaged over the last second, over ``tan(theta)`` is the share of the tilt the
surface followed (1 for water once its sloshing has died down). docs/archive/validation_notebook.md,
"Floating bodies: Archimedes".

Usage: python docs/validation/still_modes/gravity_tilt.py [--pool 16 6] [--thetas 0 0.5 1 2] [--json F]
"""

import json
import math
import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
from benchmarks import rest_column, sloshing  # noqa: E402
from newton.examples.fluid.progress import track  # noqa: E402

GRAVITY = 9.81  # [m/s^2]


def tilted(args, theta: float, device) -> dict:
    """One tank settled, gravity turned by ``theta`` [deg], and the surface's tilt read after ``args.seconds``."""
    if args.pool:
        n, layers = args.pool
        model, d = rest_column.build(n, layers, device), rest_column.SPACING
        length, width = n * d, n * d
    else:
        model, d = sloshing.build(args.length, args.per_length, args.ratio, args.depth_particles, device)
        length, width = args.length, args.depth_particles * (args.length / args.per_length)
    solver, frame, states, damping = sloshing.tank_frames(args, model, d, device)
    sloshing.settle(args, solver, frame, damping, f"gravity_tilt {theta} deg")
    level = model.particle_count * d**3 / (length * width)
    x_rest = float(states[0].particle_q.numpy()[:, 0].mean())
    t = math.radians(theta)
    model.set_gravity((GRAVITY * math.sin(t), 0.0, -GRAVITY * math.cos(t)))
    shift = []
    for _ in track(range(round(args.seconds * 60.0)), f"gravity_tilt {theta} deg: tilted", unit="frame"):
        frame()
        shift.append(float(states[0].particle_q.numpy()[:, 0].mean()) - x_rest)
    shift = np.asarray(shift)
    last = shift[-60:]
    slope = 12.0 * level * float(last.mean()) / length**2
    stats = solver.fluid_diagnostics(states[0])
    return {
        "theta_deg": theta,
        "particles": int(model.particle_count),
        "level_m": level,
        "surface_tilt_deg": math.degrees(math.atan(slope)),
        "followed": slope / math.tan(t) if theta else None,
        "centre_shift_m": float(last.mean()),
        "centre_swing_last_s_m": float(last.std()),
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "centre_shift_every_6_frames_m": shift[::6].tolist(),
    }


def main():
    parser = sloshing.parser()
    parser.description = __doc__.split("\n\n")[0]
    parser.add_argument("--pool", type=int, nargs=2, default=None, metavar=("N", "LAYERS"))
    parser.add_argument("--thetas", type=float, nargs="+", default=[0.0, 0.5, 1.0, 2.0], help="[deg]")
    parser.add_argument("--seconds", type=float, default=4.0, help="tilted [s]")
    args = parser.parse_args()
    wp.config.quiet = True
    device = wp.get_device(args.device)
    with wp.ScopedDevice(device):
        rows = [tilted(args, theta, device) for theta in args.thetas]
    print(f"{'theta [deg]':>12}{'surface [deg]':>15}{'followed':>10}{'swing [mm]':>12}{'mean|e|':>9}")
    for r in rows:
        followed = "-" if r["followed"] is None else f"{r['followed']:.2f}"
        print(
            f"{r['theta_deg']:>12.2f}{r['surface_tilt_deg']:>15.3f}{followed:>10}"
            f"{1000.0 * r['centre_swing_last_s_m']:>12.3f}{100.0 * r['mean_abs_density_error']:>8.2f}%"
        )
    shares = [r["followed"] for r in rows if r["followed"] is not None]
    print(
        f"gravity_tilt: {rows[0]['particles']} particles, {args.substeps} x {args.iterations}, followed "
        f"{min(shares):.2f}-{max(shares):.2f} of the tilt after {args.seconds} s"
        if shares
        else f"gravity_tilt: {rows[0]['particles']} particles, no tilt asked"
    )
    if args.json:
        record = {"device": device.name if device.is_cuda else "cpu", "args": vars(args), "rows": rows}
        with open(args.json, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
