# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The shape of a one-kernel density constraint: the loaded lattice's shear stiffness and its slip stiffness.

With one kernel for the density and its gradient (docs/archive/patches/one_kernel_density.patch, and
one_kernel_polynomial.patch for the shapes below) a fluid held at its rest density by a uniform pressure ``p``
is in equilibrium, and its stiffness against a displacement ``u`` that keeps every particle's sum to first
order is ``p`` times the second variation of ``sum_i S_i``. For a wave ``u_j = U e^(i k.x_j)`` on the cubic
lattice that is ``U^T H(k) U`` with

    H(k) = sum_j 2 (1 - cos k.r_j) Hess W(r_j),     U restricted to U . g(k) = 0,
    g(k) = sum_j grad W(r_j) sin k.r_j             (the waves that change the sum at first order),

per particle, over the sum at rest. A negative value is a way for a loaded packing to rearrange (buckle); the
long-wave limit is the lattice's shear stiffness under pressure, what lattice_shear.py reads as
``d^2 ln S / d gamma^2`` (``simple``: x along z, the stiffness C44; ``pure``: ``diag(e^g, e^-g, 1)``,
(C11 - C12) / 2). For ``h < 2 d`` every neighbour lies in the next lattice plane along an axis, so the
transverse branch along [001] is ``c1 (1 - cos k)``: the layers' slip at the zone's edge (``slip``, k = (0, 0,
pi), U along y) and the long-wave shear C44 are the same constant, ``slip = 4 x simple``. A packing that
resists its layers slipping therefore resists a simple shear in proportion; only (C11 - C12) / 2 is free.

The kernels: ``W = sum_n c_n (1 - r / h)^n``, given as ``n:c,...`` (spiky: ``3:1``). Prints, per kernel and
``h / d``: the two shear curvatures; ``wave``, what a two-dimensional standing wave in a tank along the lattice's
axes meets (simple + pure / 4: its flow strains the packing as much in ``e_xz`` as in ``e_xx = -e_zz``, per
unit strain); ``random``, a simple shear in a random orientation (0.6 simple + 0.1 pure, lattice_shear.py's
"random orientations" column); the slip stiffness; and the least value of ``H`` over the zone (``k`` on a grid of ``--samples`` per axis,
with the long-wave branch divided by ``|k|^2`` so that it reads as a modulus). docs/archive/
validation_notebook.md, "The kernel's shape".

Usage: python docs/validation/one_kernel/kernel_shape.py [--kernel 3:1@1.8 2.5:1@1.8 ...] [--samples 12]
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "sloshing"))
from lattice_shear import lattice, pure_shear, shear_curvature, simple_shear  # noqa: E402

# the shapes measured in the solver (archive, "The kernel's shape"); the last two are mixtures chosen for a small
# mean curvature with a positive least value on the lattice
KERNELS = (
    "3:1@1.8",
    "3:1@2.0",
    "2.4:1@1.8",
    "2.5:1@1.8",
    "2.75:1@1.8",
    "2.5:1@1.85",
    "2.5:1,3:0.117,4:-0.07,2:0.193@1.8",
    "2:-0.0064,3:1,4:5.8334,5:-9.0433,6:4.0885@2.0",
)


class Shape:
    """``W(r) = sum_n c_n (1 - r / h)^n`` for ``r < h`` and its first two derivatives against ``r``."""

    def __init__(self, spec: str):
        self.terms = [(float(n), float(c)) for n, c in (t.split(":") for t in spec.split(","))]

    def _q(self, r, h):
        return np.maximum(1.0 - np.asarray(r, dtype=float) / h, 0.0)

    def __call__(self, r, h):
        q = self._q(r, h)
        return sum(c * q**n for n, c in self.terms)

    def d1(self, r, h):
        q = self._q(r, h)
        return sum(-c * n / h * q ** (n - 1.0) for n, c in self.terms)

    def d2(self, r, h):
        q = self._q(r, h)
        return sum(c * n * (n - 1.0) / h**2 * q ** (n - 2.0) for n, c in self.terms if n != 1.0)


def loaded_stiffness(shape: Shape, h: float, waves: np.ndarray) -> np.ndarray:
    """Least stiffness ``min_U U^T H(k) U / S`` over the displacements that keep the sum, for each wave vector."""
    offsets = lattice("sc")
    r = np.linalg.norm(offsets, axis=1)
    keep = r < h
    offsets, r = offsets[keep], r[keep]
    s0 = float(shape(r, h).sum() + shape(0.0, h))
    u = offsets / r[:, None]
    outer = u[:, :, None] * u[:, None, :]
    hess = shape.d2(r, h)[:, None, None] * outer + (shape.d1(r, h) / r)[:, None, None] * (np.eye(3) - outer)
    phase = waves @ offsets.T
    stiff = np.einsum("kj,jab->kab", 2.0 * (1.0 - np.cos(phase)), hess)
    g = np.einsum("kj,ja->ka", np.sin(phase), shape.d1(r, h)[:, None] * u)
    norm = np.linalg.norm(g, axis=1)
    n = np.where(norm[:, None] > 1.0e-9 * abs(s0), g / np.maximum(norm, 1.0e-300)[:, None], 0.0)
    project = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
    # the first-order direction is held by the constraint: pushed out of the least eigenvalue
    held = 1.0e3 * abs(s0) * n[:, :, None] * n[:, None, :]
    return np.linalg.eigvalsh(project @ stiff @ project + held)[:, 0] / s0


def describe(spec: str, samples: int) -> dict:
    shape_spec, h = spec.rsplit("@", 1)
    shape, h = Shape(shape_spec), float(h)
    cubic = lattice("sc")
    simple = shear_curvature(shape, cubic, h, simple_shear)
    pure = shear_curvature(shape, cubic, h, pure_shear)
    k = np.linspace(0.0, np.pi, samples + 1)
    waves = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)[1:]
    least = loaded_stiffness(shape, h, waves)
    # as a modulus: the branch divided by the wave's |k|^2 (2 - 2 cos per axis)
    modulus = least / (2.0 - 2.0 * np.cos(waves)).sum(axis=1)
    slip = loaded_stiffness(shape, h, np.array([[0.0, 0.0, np.pi]]))[0]
    return {
        "kernel": shape_spec,
        "h_over_d": h,
        "simple": simple,
        "pure": pure,
        "wave": simple + 0.25 * pure,
        "random": 0.6 * simple + 0.1 * pure,
        "slip": slip,
        "least_modulus": float(modulus.min()),
        "least_at_k_over_pi": (waves[modulus.argmin()] / np.pi).round(2).tolist(),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kernel", nargs="+", default=list(KERNELS), help="n:c,...@h/d")
    parser.add_argument("--samples", type=int, default=12, help="wave vectors per axis of the zone")
    args = parser.parse_args()
    print(f"{'kernel':44}{'h/d':>6}{'simple':>9}{'pure':>9}{'wave':>8}{'random':>8}{'slip':>9}{'least':>9}  at k/pi")
    for spec in args.kernel:
        row = describe(spec, args.samples)
        print(
            f"{row['kernel']:44}{row['h_over_d']:>6.2f}{row['simple']:>+9.3f}{row['pure']:>+9.3f}{row['wave']:>+8.3f}{row['random']:>+8.3f}"
            f"{row['slip']:>+9.3f}{row['least_modulus']:>+9.4f}  {row['least_at_k_over_pi']}"
        )


if __name__ == "__main__":
    main()
