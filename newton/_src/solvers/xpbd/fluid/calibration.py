# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""What the rest lattice fixes before the first step: the stable relaxation and the walls' ghost density.

The defaults that need no tuning are read off a cubic lattice at the rest distance: the Jacobi
pass's largest eigenvalue on it (so the default ``fluid_relaxation`` keeps every mode stable) and the
density a wall lends a particle near it (the lattice continued beyond the wall).
"""

from __future__ import annotations

import math

import numpy as np

# share of the stable step (stable_pass_bound) the default relaxation takes on the rest lattice
JACOBI_STEP_MARGIN = 0.875


# samples of the wall density tables over [0, h]
WALL_TABLE_SIZE = 64


def rest_lattice(rest_distance: float, h: float) -> np.ndarray:
    """Offsets [m] of the cubic lattice points with spacing ``rest_distance`` within ``h`` of the origin (origin included)."""
    n = int(math.ceil(h / rest_distance))
    r = np.arange(-n, n + 1, dtype=np.float64) * rest_distance
    grid = np.stack(np.meshgrid(r, r, r, indexing="ij"), axis=-1).reshape(-1, 3)
    return grid[np.einsum("ij,ij->i", grid, grid) < h * h]


def jacobi_spectral_radius(rest_distance: float, h: float, samples: int = 24) -> float:
    """Largest eigenvalue of one Jacobi pass of the density constraint on the rest lattice.

    A pass moves the particles by ``-J^T D^-1 C`` (``J`` the constraint gradients, ``D`` the diagonal of
    ``J J^T``), so the constraint error ``C`` goes to ``(I - J J^T D^-1) C``. On the cubic lattice the
    operator is translation invariant: a displacement wave ``u e^(i k.x)`` changes ``C`` by
    ``b(k) . u`` with ``b(k) = sum_j grad W(r_j) sin(k . r_j)`` (up to a phase), so the eigenvalue at wave
    vector ``k`` is ``|b(k)|^2 / sum_j |grad W(r_j)|^2``. Sampled over the Brillouin zone (the largest sits
    at its edge): 2.43 at the default h = 1.8 d. Above 2 a pass overshoots those modes, and two passes
    amplify them: the lattice's shortest waves grow every substep.
    """
    lattice = rest_lattice(rest_distance, h)
    r = np.sqrt(np.einsum("ij,ij->i", lattice, lattice))
    keep = r > 0.0
    offsets, r = lattice[keep], r[keep]
    grad = offsets / r[:, None] * ((h - r) ** 2)[:, None]
    k = (np.arange(samples + 1) / samples) * (math.pi / rest_distance)
    waves = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)
    b = np.sin(waves @ offsets.T) @ grad
    return float(np.einsum("ij,ij->i", b, b).max() / np.einsum("ij,ij->", grad, grad))


def stable_pass_bound(fewest: int, most: int) -> float:
    """Largest ``relaxation x eigenvalue`` for which any substep of ``fewest`` to ``most`` Jacobi passes is stable.

    After ``k`` passes a mode of eigenvalue ``mu`` keeps ``p = (1 - w mu)^k`` of its error, and the
    substep turns the correction into velocity: ``x' = p (x + v dt)``, ``v' = (x' - x) / dt``, whose
    eigenvalues solve ``z^2 - 2 p z + p = 0``. They stay inside the unit circle for ``-1/3 < p < 1``: for an
    even ``k`` while ``w mu < 2``, for an odd one while ``w mu < 1 + 3^(-1/k)`` (4/3 for one pass). The
    bound is the least over the counts a substep may run.
    """
    odd = fewest if fewest % 2 else fewest + 1
    return 1.0 + 3.0 ** (-1.0 / odd) if odd <= most else 2.0


def stable_relaxation(rest_distance: float, h: float, fewest: int = 2, most: int = 2) -> float:
    """Default ``fluid_relaxation``: a step that keeps every mode of the rest lattice stable, at most 1.

    ``JACOBI_STEP_MARGIN`` of :func:`stable_pass_bound` over :func:`jacobi_spectral_radius`: 0.72 at
    h = 1.8 d for two passes a substep, 0.48 for one. A disordered neighbourhood's spectral radius is
    close to the lattice's (2.45 measured in a settled column against 2.43), within the margin.
    """
    bound = stable_pass_bound(fewest, most)
    return min(1.0, JACOBI_STEP_MARGIN * bound / jacobi_spectral_radius(rest_distance, h))


def poly6_np(r2: np.ndarray, h: float) -> np.ndarray:
    return 315.0 / (64.0 * math.pi * h**9) * np.maximum(h * h - r2, 0.0) ** 3


def lattice_density(rest_distance: float, h: float, mass: float) -> float:
    """Poly6 density [kg/m^3] of a particle of ``mass`` [kg] in the cubic lattice at ``rest_distance`` [m].

    The default rest density (``fluid_rest_density`` None): such a lattice is exactly at rest.
    """
    lattice = rest_lattice(rest_distance, h)
    r2 = np.einsum("ij,ij->i", lattice, lattice)
    return float(mass * poly6_np(r2, h).sum())


def wall_density_tables(rest_distance: float, h: float, mass: float, size: int = WALL_TABLE_SIZE):
    """Poly6 density [kg/m^3] of a lattice at rest continued beyond a plane wall, and its derivative.

    For a particle whose centre is ``delta`` from the wall (``delta`` sampled uniformly on
    ``[0, h]``), the ghost lattice has layers at ``delta + d/2 + k d`` behind the wall: exactly
    the layers a lattice would have if the fluid went on, when the particle touches the wall
    (``delta = d/2``). The density is tapered to zero between ``0.75 d`` and ``d`` (where it is
    below 5 % and 1 % of the lattice density) so that it vanishes before particle-shape contacts
    end, at ``radius + soft_contact_gap``: with a gap of at least the radius it never jumps.

    Returns:
        tuple: densities and their derivatives against ``delta`` [kg/m^4], each of ``size`` samples.
    """
    d = rest_distance
    n = int(math.ceil(h / d))
    ab = np.arange(-n, n + 1) * d
    plane = (ab[:, None] ** 2 + ab[None, :] ** 2).reshape(-1)
    k = 315.0 / (64.0 * math.pi * h**9)
    deltas = np.linspace(0.0, h, size)
    rho = np.zeros(size)
    grad = np.zeros(size)
    for i, delta in enumerate(deltas):
        z = delta + 0.5 * d + np.arange(n + 1) * d
        q = np.maximum(h * h - plane[None, :] - z[:, None] ** 2, 0.0)
        rho[i] = mass * k * (q**3).sum()
        # d/d(delta) of (h^2 - r^2)^3 with dr^2/d(delta) = 2 z
        grad[i] = mass * k * (-6.0 * z[:, None] * q**2).sum()
    t = np.clip((deltas - 0.75 * d) / (0.25 * d), 0.0, 1.0)
    window = 1.0 - t * t * (3.0 - 2.0 * t)
    dwindow = np.where((t > 0.0) & (t < 1.0), -6.0 * t * (1.0 - t) / (0.25 * d), 0.0)
    return rho * window, grad * window + rho * dwindow
