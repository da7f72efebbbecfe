# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""How much a lattice's kernel sum changes when the lattice is sheared without a change of volume.

A continuum's density does not change under a shear that keeps the volume; a kernel sum over a lattice
does, at second order: ``S(F) = sum_j W(|F r_j|)``, ``F = I + gamma A``. A fluid loaded by gravity holds
its particles at the rest density with multipliers (a pressure), so a shear that raises the sum is
resisted in proportion to the pressure (a soft solid: a small wave runs fast), and one that lowers it
is where a loaded packing buckles. Prints ``d^2 ln S / d gamma^2`` for

* the cubic lattice, axis-aligned (the start of ``benchmarks/sloshing.py`` and ``rest_column``): simple
  shear of x along z and the pure shear ``diag(e^g, e^-g, 1)``;
* the cubic, body-centred and face-centred lattices at the same number density, averaged over 40
  random orientations of the lattice (simple shear; mean and the largest magnitude),

for poly6 and spiky at smoothing lengths of 1.6-3 rest distances, and the sum's response to a uniform
compression (``d ln S / d ln n``; the number density's is 1). docs/archive/validation_notebook.md,
"Standing wave (sloshing)", "Why a small wave runs fast".

Usage: python docs/validation/sloshing/lattice_shear.py
"""

import numpy as np

RATIOS = (1.6, 1.7, 1.8, 1.9, 2.0, 2.2, 2.5, 3.0)
STEP = 1.0e-3  # the shear's finite difference


def lattice(kind: str, n: int = 7) -> np.ndarray:
    """Neighbour offsets of a lattice of unit number density (its own point left out)."""
    g = np.arange(-n, n + 1)
    cell = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3).astype(float)
    basis = {
        "sc": [(0.0, 0.0, 0.0)],
        "bcc": [(0.0, 0.0, 0.0), (0.5, 0.5, 0.5)],
        "fcc": [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (0.5, 0.0, 0.5), (0.0, 0.5, 0.5)],
    }[kind]
    points = np.concatenate([cell + b for b in basis]) * len(basis) ** (1.0 / 3.0)
    return points[np.linalg.norm(points, axis=1) > 1.0e-9]


def poly6(r, h):
    return np.maximum(h * h - r * r, 0.0) ** 3


def spiky(r, h):
    return np.maximum(h - r, 0.0) ** 3


def kernel_sum(kernel, offsets, h, deformation) -> float:
    return float(kernel(np.linalg.norm(offsets @ deformation.T, axis=1), h).sum() + kernel(0.0, h))


def shear_curvature(kernel, offsets, h, deformation_of) -> float:
    """``d^2 ln S / d gamma^2`` at ``gamma = 0`` by a central difference."""
    s0 = kernel_sum(kernel, offsets, h, np.eye(3))
    up = kernel_sum(kernel, offsets, h, deformation_of(STEP))
    down = kernel_sum(kernel, offsets, h, deformation_of(-STEP))
    return (up + down - 2.0 * s0) / (STEP * STEP * s0)


def simple_shear(g):
    f = np.eye(3)
    f[0, 2] = g
    return f


def pure_shear(g):
    return np.diag([np.exp(g), np.exp(-g), 1.0])


def random_rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def main():
    rng = np.random.default_rng(0)
    rotations = [random_rotation(rng) for _ in range(40)]
    cubic = lattice("sc")
    print("kernel  h/d | cubic, aligned: simple  pure  compression | random orientations, simple: sc  bcc  fcc")
    for name, kernel in (("poly6", poly6), ("spiky", spiky)):
        for h in RATIOS:
            simple = shear_curvature(kernel, cubic, h, simple_shear)
            pure = shear_curvature(kernel, cubic, h, pure_shear)
            s0 = kernel_sum(kernel, cubic, h, np.eye(3))
            squeezed = kernel_sum(kernel, cubic, h, np.eye(3) * np.exp(-STEP / 3.0))
            compression = (squeezed - s0) / (STEP * s0)
            row = []
            for kind in ("sc", "bcc", "fcc"):
                offsets = lattice(kind)
                values = np.array([shear_curvature(kernel, offsets @ rot.T, h, simple_shear) for rot in rotations])
                row.append(f"{values.mean():+.3f} ({np.abs(values).max():.3f})")
            print(f"{name}  {h:.1f} | {simple:+.3f}  {pure:+.3f}  {compression:.3f} | {'  '.join(row)}")


if __name__ == "__main__":
    main()
