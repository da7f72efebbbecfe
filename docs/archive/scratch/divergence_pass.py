# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch (not adopted): DFSPH's divergence solve on the fluid's velocity after every ``SolverXPBD.step``.

SPlisHSPlasH's DFSPH keeps 0.78 of the standing wave per period at 20 per L and 0.68 with its divergence
solve switched off (docs/archive/validation_notebook.md, "The same wave in SPlisHSPlasH"). This runs that
solve (Bender & Koschier 2015, eq. 9 and algorithm 2, written for this scratch) after each of our substeps,
on the CPU in NumPy: with the spiky gradient of support ``h`` (the solver's smoothing length),

    drho_i/dt = sum_j m (v_i - v_j) . grad W_ij            (clamped at 0: only compression is removed),
    alpha_i   = 1 / (|sum_j m grad W_ij|^2 + sum_j |m grad W_ij|^2),
    v_i      -= DIV_OMEGA sum_j m (alpha_i drho_i/dt + alpha_j drho_j/dt) grad W_ij,

``DIV_ITERATIONS`` Jacobi passes (each with the rates of the velocities it starts from), only for fluid
particles with at least ``DIV_MIN_NEIGHBORS`` neighbours (DFSPH's 20: the surface's particles lack
neighbours and their rates mean nothing). Walls take no part (the solver's contacts already stop the
velocity into them). Then runs ``python -m benchmarks ARGS`` (or a script, if the first argument ends in
``.py``).

Usage: [DIV_ITERATIONS=2 DIV_OMEGA=0.5 DIV_MIN_NEIGHBORS=20] python docs/archive/scratch/divergence_pass.py
sloshing --per-length 20
"""

import os
import sys

import numpy as np
from scipy.spatial import cKDTree

import newton

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from run_around import run_around  # noqa: E402

ITERATIONS = int(os.environ.get("DIV_ITERATIONS", "2"))
OMEGA = float(os.environ.get("DIV_OMEGA", "0.5"))
MIN_NEIGHBORS = int(os.environ.get("DIV_MIN_NEIGHBORS", "20"))


def divergence_solve(q: np.ndarray, v: np.ndarray, h: float, m: float) -> None:
    """DFSPH's divergence solve on ``v`` [m/s] (fluid particles at ``q`` [m], support ``h`` [m], mass ``m``
    [kg]), in place."""
    pairs = cKDTree(q).query_pairs(h, output_type="ndarray")
    if len(pairs) == 0:
        return
    i, j = pairs[:, 0], pairs[:, 1]
    r = q[i] - q[j]
    dist = np.linalg.norm(r, axis=1)
    keep = dist > 1.0e-9
    i, j, r, dist = i[keep], j[keep], r[keep], dist[keep]
    # spiky gradient at i (from j): -45 / (pi h^6) (h - r)^2 r / |r|
    grad = (-45.0 / (np.pi * h**6) * (h - dist) ** 2 / dist)[:, None] * r
    n = len(q)
    count = np.bincount(i, minlength=n) + np.bincount(j, minlength=n)
    mg = m * grad
    sum_g = np.zeros((n, 3))
    np.add.at(sum_g, i, mg)
    np.add.at(sum_g, j, -mg)
    sum_g2 = np.bincount(i, (mg * mg).sum(1), n) + np.bincount(j, (mg * mg).sum(1), n)
    denominator = (sum_g * sum_g).sum(1) + sum_g2
    alpha = np.where((count >= MIN_NEIGHBORS) & (denominator > 0.0), 1.0 / np.maximum(denominator, 1e-30), 0.0)
    for _ in range(ITERATIONS):
        rel = ((v[i] - v[j]) * mg).sum(1)
        rate = np.bincount(i, rel, n) + np.bincount(j, rel, n)
        kappa = alpha * np.maximum(rate, 0.0)
        push = (kappa[i] + kappa[j])[:, None] * mg
        dv = np.zeros((n, 3))
        np.add.at(dv, i, -push)
        np.add.at(dv, j, push)
        v += OMEGA * dv


_step = newton.solvers.SolverXPBD.step


def step(self, state_in, state_out, control, contacts, dt, **kwargs):
    _step(self, state_in, state_out, control, contacts, dt, **kwargs)
    if ITERATIONS > 0:
        fluid = np.nonzero((self.model.particle_flags.numpy() & int(newton.ParticleFlags.FLUID)) != 0)[0]
        q = state_out.particle_q.numpy().astype(np.float64)[fluid]
        qd = state_out.particle_qd.numpy()
        v = qd[fluid].astype(np.float64)
        m = float(self.model.particle_mass.numpy()[fluid[0]])
        divergence_solve(q, v, self.fluid_smoothing_length, m)
        qd[fluid] = v.astype(np.float32)


if __name__ == "__main__":
    run_around(step)
