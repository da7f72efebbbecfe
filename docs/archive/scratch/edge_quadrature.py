# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch (archive, "Walls at convex edges and in corners"): the ghost density a box's edge lends by the closest-point plane, against the solid wedge it stands for."""

import numpy as np

d = 1.0
h = 1.8 * d
g = np.arange(-4, 4.001, 0.05)
X, Y, Z = np.meshgrid(g, g, g, indexing="ij")


def w(r2):
    return np.where(r2 < h * h, (h * h - r2) ** 3, 0.0)


full = w(X**2 + Y**2 + Z**2).sum()
# solid: x < 0 and z > 0 (a box's bottom edge along y; water below z < 0 and beside x > 0)
for u, v in [(0.5, -0.5), (0.5, -1.0), (0.5, -1.5), (0.5, 0.3), (0.5, 0.0), (0.35, -0.35), (0.7, -0.7), (1.0, -0.5)]:
    px, pz = u, v  # particle at x = u (beside the side face), z = v (below the bottom when negative)
    rx, rz = X + px, Z + pz  # world coordinates of the integration points around the particle
    kern = w(X**2 + Y**2 + Z**2)
    wedge = kern[(rx < 0) & (rz > 0)].sum() / full
    # closest point on the solid and the plane there
    cx, cz = min(px, 0.0), max(pz, 0.0)
    n = np.array([px - cx, pz - cz])
    dist = np.linalg.norm(n)
    n = n / dist
    half = kern[(rx * n[0] + rz * n[1]) < 0.0].sum() / full  # beyond the plane through the closest point
    print(
        f"particle x {u:+.2f} d, z {v:+.2f} d (dist {dist:.2f} d): plane lends {half:.4f}, the wedge {wedge:.4f}, over by {half - wedge:+.4f}"
    )
