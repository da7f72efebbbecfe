# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""One Jacobi density pass on the rest lattice, for a density kernel and a correction gradient.

A pass maps the constraint error by ``I - w J_d J_c^T D_c^-1`` (``J_d`` the gradients of the kernel the
density sums, ``J_c`` those the correction moves along, ``D_c`` the diagonal of ``J_c J_c^T``). On the
cubic lattice a wave ``k`` has the eigenvalue ``b_d(k) . b_c(k) / sum |g_c|^2`` with
``b(k) = sum_j g(r_j) sin(k . r_j)``, both gradients over the density kernel's lattice sum, as the
solver scales them. Prints, for
today's pair (poly6 density, spiky gradient) and for one kernel on both sides, the largest and
smallest eigenvalue, the stable step (0.875 x 2 over the largest, at most 1; today's default 0.72
is computed with the spiky gradient on both sides), the long-wave correction per pass (step x the
eigenvalue of the longest wave sampled) and the sum's response to a uniform compression
(-d ln(sum) / d ln(spacing); the number density's is 3). Then the same for the poly6 density with a
correction gradient blended from spiky's and poly6's. docs/archive/validation_notebook.md, "One
kernel for the density and its gradient" and "What moves in still water".

Usage: python docs/validation/one_kernel/operator_spectrum.py
"""

import math

import numpy as np

from newton._src.solvers.xpbd.fluid.calibration import rest_lattice

H = 1.8  # smoothing length over the rest distance
SAMPLES = 48  # waves per axis over [0, pi / d]

# each kernel with its normalising constant (in units of the rest distance): the solver divides both
# gradients by the rest density, the density kernel's lattice sum, so a correction gradient from another
# kernel keeps its own scale
P6, SP = 315.0 / (64.0 * math.pi * H**9), 15.0 / (math.pi * H**6)
KERNELS = {
    "poly6": (
        lambda r: P6 * np.maximum(H * H - r * r, 0) ** 3,
        lambda r: -6 * P6 * r * np.maximum(H * H - r * r, 0) ** 2,
    ),
    "spiky": (lambda r: SP * np.maximum(H - r, 0) ** 3, lambda r: -3 * SP * np.maximum(H - r, 0) ** 2),
    "(h - r)^2": (lambda r: np.maximum(H - r, 0) ** 2, lambda r: -2 * np.maximum(H - r, 0)),
}


def main():
    lattice = rest_lattice(1.0, H)
    r = np.linalg.norm(lattice, axis=1)
    off, rn = lattice[r > 0], r[r > 0]
    axis = np.arange(SAMPLES + 1) / SAMPLES * math.pi
    waves = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    longest = np.argsort(np.linalg.norm(waves, axis=1))[1]
    sines = np.sin(waves @ off.T)

    def gradient(name, density):
        rest = KERNELS[density][0](r).sum()
        return off / rn[:, None] * (-KERNELS[name][1](rn) / rest)[:, None]

    print(f"{'density, gradient':<22}{'largest':>9}{'smallest':>10}{'step':>7}{'long wave':>11}{'response':>10}")
    for dens, corr in (("poly6", "spiky"), ("spiky", "spiky"), ("poly6", "poly6"), ("(h - r)^2", "(h - r)^2")):
        gd, gc = gradient(dens, dens), gradient(corr, dens)
        mu = np.einsum("ij,ij->i", sines @ gd, sines @ gc) / np.einsum("ij,ij->", gc, gc)
        step = min(1.0, 0.875 * 2.0 / mu.max())
        if (dens, corr) == ("poly6", "spiky"):
            step = 0.7208  # today's default, from the spiky gradient on both sides
        w, dw = KERNELS[dens]
        response = -(r * dw(r)).sum() / w(r).sum()
        print(
            f"{dens + ', ' + corr:<22}{mu.max():>9.3f}{mu.min():>10.3f}{step:>7.3f}{step * mu[longest]:>11.5f}"
            f"{response:>10.2f}"
        )
    blend_table(KERNELS["poly6"], KERNELS["spiky"], r, off, rn, sines, longest)


def blend_table(poly6, spiky, r, off, rn, sines, longest):
    """The poly6 density with the correction gradient ``alpha spiky + (1 - alpha) poly6``, per ``alpha``.

    The spiky part is scaled so the blend keeps poly6's long-wave response (as
    ``docs/archive/patches/blended_correction_gradient.patch`` does in the solver).
    """
    rest = poly6[0](r).sum()
    g_poly6 = off / rn[:, None] * (-poly6[1](rn) / rest)[:, None]
    g_spiky = off / rn[:, None] * (-spiky[1](rn) / rest)[:, None]
    g_spiky *= np.einsum("ij,ij", g_poly6, g_poly6) / np.einsum("ij,ij", g_spiky, g_poly6)
    print(f"\npoly6 density, blended gradient\n{'alpha':>6}{'largest':>9}{'smallest':>10}{'step':>7}{'long wave':>11}")
    for alpha in (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0):
        g = alpha * g_spiky + (1.0 - alpha) * g_poly6
        mu = np.einsum("ij,ij->i", sines @ g_poly6, sines @ g) / np.einsum("ij,ij->", g, g)
        step = min(1.0, 0.875 * 2.0 / mu.max())
        print(f"{alpha:>6.1f}{mu.max():>9.3f}{mu.min():>10.4f}{step:>7.3f}{step * mu[longest]:>11.5f}")


if __name__ == "__main__":
    main()
