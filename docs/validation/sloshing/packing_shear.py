# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""How much a settled packing's kernel sums change under a shear that keeps the volume (its interior particles).

``lattice_shear.py`` beside this file reads the curvature ``d^2 ln S / d gamma^2`` of a kernel sum on perfect
lattices; the water the solver leaves is not one. This settles the still column of ``benchmarks/rest_column.py``
(``--n`` x ``--n`` x ``--layers`` at 0.05 m, ``--seconds`` at the solver's keywords, flags as the benchmarks')
or reads positions saved with ``--packing`` (a ``.npy`` of positions [m]), and for each particle at least
``REACH`` spacings inside the column deforms its neighbourhood by ``F = exp(gamma E)`` (``E`` symmetric and
traceless: no change of volume) in ``DIRECTIONS`` random directions. It prints, per kernel and smoothing
length: the curvature averaged over particles and directions (a loaded packing resists such a shear in
proportion to it and to the pressure; negative: a shear that lowers the sum, along which a loaded packing
buckles), the spread of the per-particle first derivative (zero on a lattice: how disordered the packing
is) and the sum's response to a uniform compression ``d ln S / d ln n``. docs/archive/validation_notebook.md,
"Why a small wave runs fast: the packing's shear stiffness".

Usage: python docs/validation/sloshing/packing_shear.py [--device cpu] [--packing F.npy] [--json F]
"""

import argparse
import json
import os
import sys

import numpy as np
import warp as wp
from scipy.linalg import expm
from scipy.spatial import cKDTree

sys.path.insert(0, ".")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from lattice_shear import STEP, poly6, spiky  # noqa: E402

from benchmarks import rest_column  # noqa: E402
from benchmarks.frames import add_solver_arguments, contact_frames  # noqa: E402
from newton.examples.fluid.progress import track  # noqa: E402

RATIOS = (1.8, 2.0, 2.2, 2.5)  # smoothing lengths [spacings]
REACH = 3.2  # interior: this far inside the packing's bounds [spacings]
DIRECTIONS = 12


def settled_packing(args) -> np.ndarray:
    """The still column after ``args.seconds`` [s], positions [m]."""
    wp.config.quiet = True
    device = wp.get_device(args.device)
    with wp.ScopedDevice(device):
        model = rest_column.build(args.n, args.layers, device)
        _, frame = contact_frames(model, args, rest_column.SPACING, device)
        for _ in track(range(round(args.seconds * 60.0)), "packing_shear: settling", unit="frame"):
            frame()
        return frame.states[0].particle_q.numpy()


def curvatures(q: np.ndarray, kernel, h: float, directions: list) -> dict:
    """Curvature, first-derivative spread and compression response of ``kernel`` at ``h`` (positions in spacings)."""
    lo, hi = q.min(axis=0), q.max(axis=0)
    inner = np.nonzero(np.all((q > lo + REACH) & (q < hi - REACH), axis=1))[0]
    tree = cKDTree(q)
    offsets = []
    for i in inner:
        o = q[tree.query_ball_point(q[i], h + 0.1)] - q[i]
        offsets.append(o[np.linalg.norm(o, axis=1) > 1.0e-9])

    def sums(f):
        return np.array([kernel(np.linalg.norm(o @ f.T, axis=1), h).sum() + kernel(0.0, h) for o in offsets])

    s0 = sums(np.eye(3))
    curv, first = [], []
    for e in directions:
        up, down = np.log(sums(expm(STEP * e))), np.log(sums(expm(-STEP * e)))
        curv.append(np.mean((up + down - 2.0 * np.log(s0)) / STEP**2))
        first.append(np.std((up - down) / (2.0 * STEP)))
    squeezed = sums(np.eye(3) * np.exp(-STEP / 3.0))
    return {
        "interior_particles": len(inner),
        "shear_curvature": float(np.mean(curv)),
        "shear_curvature_spread_over_directions": float(np.std(curv)),
        "first_derivative_spread": float(np.mean(first)),
        "compression_response": float(np.mean(np.log(squeezed / s0)) / STEP),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--packing", default=None, help="positions [m] saved with numpy.save, instead of settling")
    parser.add_argument("--n", type=int, default=12)
    parser.add_argument("--layers", type=int, default=24)
    parser.add_argument("--seconds", type=float, default=3.0)
    add_solver_arguments(parser)
    args = parser.parse_args()
    q = np.load(args.packing) if args.packing else settled_packing(args)
    q = q.astype(np.float64) / rest_column.SPACING
    rng = np.random.default_rng(1)
    directions = []
    for _ in range(DIRECTIONS):
        a = rng.normal(size=(3, 3))
        e = 0.5 * (a + a.T)
        e -= np.trace(e) / 3.0 * np.eye(3)
        directions.append(e / np.linalg.norm(e))
    rows = []
    print(f"{'kernel':<8}{'h/d':>5}{'curvature':>11}{'(spread)':>10}{'first-deriv spread':>20}{'compression':>13}")
    for name, kernel in (("poly6", poly6), ("spiky", spiky)):
        for h in RATIOS:
            row = {"kernel": name, "h_over_d": h, **curvatures(q, kernel, h, directions)}
            rows.append(row)
            print(
                f"{name:<8}{h:>5.1f}{row['shear_curvature']:>+11.3f}{row['shear_curvature_spread_over_directions']:>10.3f}"
                f"{row['first_derivative_spread']:>20.4f}{row['compression_response']:>13.3f}"
            )
    print(
        f"packing_shear: {len(q)} particles, {rows[0]['interior_particles']} inside, "
        f"{'from ' + args.packing if args.packing else f'settled {args.seconds} s'}"
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"packing": args.packing, "seconds": args.seconds, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
