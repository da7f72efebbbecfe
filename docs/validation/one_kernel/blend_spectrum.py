# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The pass's spectrum with the poly6 density and a correction gradient blended from poly6's and spiky's.

The gradient ``alpha g_spiky + (1 - alpha) g_poly6``, the spiky part scaled so the blend keeps poly6's
long-wave response (as ``docs/archive/patches/blended_correction_gradient.patch`` does in the solver).
Prints, per ``alpha``, the largest and smallest eigenvalue of ``J_poly6 J_blend^T D^-1`` on the rest
lattice, the stable step (0.875 x 2 over the largest) and the long-wave correction per pass.
docs/archive/validation_notebook.md, "What moves in still water".

Usage: python docs/validation/one_kernel/blend_spectrum.py
"""

import math

import numpy as np

from newton._src.solvers.xpbd.fluid.calibration import rest_lattice

H = 1.8  # smoothing length over the rest distance
SAMPLES = 48  # waves per axis over [0, pi / d]
P6, SP = 315.0 / (64.0 * math.pi * H**9), 15.0 / (math.pi * H**6)


def main():
    lattice = rest_lattice(1.0, H)
    r = np.linalg.norm(lattice, axis=1)
    off, rn = lattice[r > 0], r[r > 0]
    axis = np.arange(SAMPLES + 1) / SAMPLES * math.pi
    waves = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    sines = np.sin(waves @ off.T)
    rest = (P6 * np.maximum(H * H - r * r, 0.0) ** 3).sum()
    g_poly6 = off / rn[:, None] * (6.0 * P6 * rn * (H * H - rn * rn) ** 2 / rest)[:, None]
    g_spiky = off / rn[:, None] * (3.0 * SP * (H - rn) ** 2 / rest)[:, None]
    g_spiky *= np.einsum("ij,ij", g_poly6, g_poly6) / np.einsum("ij,ij", g_spiky, g_poly6)
    longest = np.argsort(np.linalg.norm(waves, axis=1))[1]
    print(f"{'alpha':>6}{'largest':>9}{'smallest':>10}{'step':>7}{'long wave':>11}")
    for alpha in (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0):
        g = alpha * g_spiky + (1.0 - alpha) * g_poly6
        mu = np.einsum("ij,ij->i", sines @ g_poly6, sines @ g) / np.einsum("ij,ij->", g, g)
        step = min(1.0, 0.875 * 2.0 / mu.max())
        print(f"{alpha:>6.1f}{mu.max():>9.3f}{mu.min():>10.4f}{step:>7.3f}{step * mu[longest]:>11.5f}")


if __name__ == "__main__":
    main()
