# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""What the rest lattice fixes before the first step: the density kernel's scale, the stable relaxation, the walls.

The defaults that need no tuning are read off a cubic lattice at the rest distance: its density (the
default rest density), the Jacobi pass's largest eigenvalue on it (so the default ``fluid_relaxation``
keeps every mode stable) and the density a wall lends a particle near it (the lattice continued
beyond the wall). Each is read with the density kernel ``fluid_density_kernel`` names: ``"poly6"``
(Macklin & Müller 2013: the poly6 density, moved along the spiky kernel's gradient) or
``"one_kernel"`` (``(1 - r/h)^2.5`` for the density and its own gradient, scaled so that the lattice's
density is ``m / d^3``; docs/formulation.rst, "The density kernel").
"""

from __future__ import annotations

import functools
import math

import numpy as np

# share of the stable step (stable_pass_bound) the default relaxation takes on the rest lattice
JACOBI_STEP_MARGIN = 0.875


#: share of the default step an odd count's last pass takes: with the even bound (2) it corrects the shortest wave
#: at most fully (``w mu <= 1``), so the substep keeps ``p >= 0`` of its error (:func:`stable_pass_bound`)
CLOSING_PASS_SHARE = 0.5


# samples of the wall density tables over [0, h]
WALL_TABLE_SIZE = 64


#: the values of ``fluid_density_kernel``
DENSITY_KERNELS = ("poly6", "one_kernel")


# exponent of the one kernel (1 - r/h)^e: below 3 its packing gives way to shear, above 2 it holds its layers
# (docs/archive/validation_notebook.md, "The kernel's shape")
ONE_KERNEL_EXPONENT = 2.5


def poly6_np(r2: np.ndarray, h: float) -> np.ndarray:
    return 315.0 / (64.0 * math.pi * h**9) * np.maximum(h * h - r2, 0.0) ** 3


def one_kernel_shape(r: np.ndarray, h: float) -> np.ndarray:
    """The one kernel's shape ``(1 - r/h)^2.5``, zero beyond ``h``, before its scale [dimensionless]."""
    return np.maximum(1.0 - r / h, 0.0) ** ONE_KERNEL_EXPONENT


@functools.cache
def one_kernel_scale(rest_distance: float, h: float) -> float:
    """Factor [1/m^3] on :func:`one_kernel_shape` that makes the rest lattice's kernel sum ``1 / d^3``.

    So water of particle mass ``1000 d^3`` rests at 1000 kg/m^3, as the cubic lattice it starts from. Kept
    per ``(d, h)``: the wall tables and the other calibrations ask for it at every sample.
    """
    lattice = rest_lattice(rest_distance, h)
    r = np.sqrt(np.einsum("ij,ij->i", lattice, lattice))
    return float(1.0 / (rest_distance**3 * one_kernel_shape(r, h).sum()))


def kernel_weight(kernel: str, r2: np.ndarray, rest_distance: float, h: float) -> np.ndarray:
    """The density kernel ``W(r)`` of ``fluid_density_kernel`` [1/m^3] at squared distances ``r2`` [m^2]."""
    if kernel == "poly6":
        return poly6_np(r2, h)
    return one_kernel_scale(rest_distance, h) * one_kernel_shape(np.sqrt(r2), h)


def kernel_slope(kernel: str, r: np.ndarray, rest_distance: float, h: float) -> np.ndarray:
    """How steeply the density constraint moves a pair at distances ``r`` [1/m^4]: ``-dW/dr`` of its gradient's kernel.

    For ``"poly6"`` the spiky kernel's, ``45 / (pi h^6) (h - r)^2``; for ``"one_kernel"`` the kernel's own.
    """
    if kernel == "poly6":
        return 45.0 / (math.pi * h**6) * kernel_slope_shape(kernel, r, h)
    return one_kernel_scale(rest_distance, h) * ONE_KERNEL_EXPONENT / h * kernel_slope_shape(kernel, r, h)


def kernel_slope_shape(kernel: str, r: np.ndarray, h: float) -> np.ndarray:
    """:func:`kernel_slope` without its constant factor: ``(h - r)^2`` for ``"poly6"``, ``(1 - r/h)^1.5`` else."""
    if kernel == "poly6":
        return np.maximum(h - r, 0.0) ** 2
    return np.maximum(1.0 - r / h, 0.0) ** (ONE_KERNEL_EXPONENT - 1.0)


def rest_lattice(rest_distance: float, h: float) -> np.ndarray:
    """Offsets [m] of the cubic lattice points with spacing ``rest_distance`` within ``h`` of the origin (origin included)."""
    n = int(math.ceil(h / rest_distance))
    r = np.arange(-n, n + 1, dtype=np.float64) * rest_distance
    grid = np.stack(np.meshgrid(r, r, r, indexing="ij"), axis=-1).reshape(-1, 3)
    return grid[np.einsum("ij,ij->i", grid, grid) < h * h]


def jacobi_spectral_radius(rest_distance: float, h: float, samples: int = 24, kernel: str = "poly6") -> float:
    """Largest eigenvalue of one Jacobi pass of the density constraint on the rest lattice.

    A pass moves the particles by ``-J^T D^-1 C`` (``J`` the constraint gradients, ``D`` the diagonal of
    ``J J^T``), so the constraint error ``C`` goes to ``(I - J J^T D^-1) C``. On the cubic lattice the
    operator is translation invariant: a displacement wave ``u e^(i k.x)`` changes ``C`` by
    ``b(k) . u`` with ``b(k) = sum_j grad W(r_j) sin(k . r_j)`` (up to a phase), so the eigenvalue at wave
    vector ``k`` is ``|b(k)|^2 / sum_j |grad W(r_j)|^2``. Sampled over the Brillouin zone (the largest sits
    at its edge): 2.43 at the default h = 1.8 d with ``kernel`` ``"poly6"``. Above 2 a pass overshoots
    those modes, and two passes amplify them: the lattice's shortest waves grow every substep.
    """
    lattice = rest_lattice(rest_distance, h)
    r = np.sqrt(np.einsum("ij,ij->i", lattice, lattice))
    keep = r > 0.0
    offsets, r = lattice[keep], r[keep]
    # (the eigenvalue does not depend on the kernel's scale)
    grad = offsets / r[:, None] * kernel_slope_shape(kernel, r, h)[:, None]
    k = (np.arange(samples + 1) / samples) * (math.pi / rest_distance)
    waves = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)
    b = np.sin(waves @ offsets.T) @ grad
    return float(np.einsum("ij,ij->i", b, b).max() / np.einsum("ij,ij->", grad, grad))


def stable_pass_bound(fewest: int, most: int, damping: float = 0.0) -> float:
    """Largest ``relaxation x eigenvalue`` for which any substep of ``fewest`` to ``most`` Jacobi passes is stable.

    After ``k`` passes a mode of eigenvalue ``mu`` keeps ``p = (1 - w mu)^k`` of its error, and the
    substep turns the correction into velocity: ``x' = p (x + v dt)``, ``v' = (x' - x) / dt``, whose
    eigenvalues solve ``z^2 - 2 p z + p = 0``. They stay inside the unit circle for ``-1/3 < p < 1``: for an
    even ``k`` while ``w mu < 2``, for an odd one while ``w mu < 1 + 3^(-1/k)`` (4/3 for one pass). With the
    compression damping ``g`` (``fluid_compression_damping``) the passes also remove ``g`` times the
    compression the substep's motion adds, ``x' = p x* - (1 - p) g (x* - x)`` with ``x* = x + v dt``, stable
    for ``(2 g - 1) / (3 + 2 g) < p < 1``: an even count is unchanged below ``g = 1/2``, an odd one needs
    ``w mu < 1 + ((1 - 2 g) / (3 + 2 g))^(1/k)``.

    A fixed count (``fewest == most``) takes the even bound, 2, whatever its parity: an odd count's last pass
    runs at :data:`CLOSING_PASS_SHARE` of the step, so that ``p >= 0`` (an odd count that keeps ``p < 0`` flips
    the error's sign every substep; the linear model calls it stable, but the unilateral constraint does not
    pull back the under-dense half, and still water hums: docs/validation.rst, "Odd pass counts"). A range of
    counts whose odd ones have no closing pass takes the least bound over them. The solver's schedules stop
    only after even counts or close an odd one (:mod:`.schedule`), so they all take the even bound.
    """
    if fewest == most:
        return 2.0
    odd = fewest if fewest % 2 else fewest + 1
    if odd > most:
        return 2.0
    if damping == 0.0:
        # (the undamped bound as it was written before the damping: the general form differs in the last bit at 3
        # passes, and the default relaxation, and so every undamped run, would not be bitwise the same)
        return 1.0 + 3.0 ** (-1.0 / odd)
    return 1.0 + ((1.0 - 2.0 * damping) / (3.0 + 2.0 * damping)) ** (1.0 / odd)


def stable_relaxation(
    rest_distance: float, h: float, fewest: int = 2, most: int = 2, kernel: str = "poly6", damping: float = 0.0
) -> float:
    """Default ``fluid_relaxation``: a step that keeps every mode of the rest lattice stable, at most 1.

    ``JACOBI_STEP_MARGIN`` of :func:`stable_pass_bound` over :func:`jacobi_spectral_radius`: 0.72 at
    h = 1.8 d for any count of passes the solver runs (``"poly6"``; an odd count's last pass takes half of it),
    0.48 for one to two passes of which an odd count has no closing pass. A disordered neighbourhood's spectral
    radius is close to the lattice's (2.45 measured in a settled column against 2.43), within the margin.
    """
    bound = stable_pass_bound(fewest, most, damping)
    return min(1.0, JACOBI_STEP_MARGIN * bound / jacobi_spectral_radius(rest_distance, h, kernel=kernel))


def lattice_density(rest_distance: float, h: float, mass: float, kernel: str = "poly6") -> float:
    """Density [kg/m^3] of a particle of ``mass`` [kg] in the cubic lattice at ``rest_distance`` [m].

    The default rest density (``fluid_rest_density`` None): such a lattice is exactly at rest. The
    poly6 sum reads 0.983 ``m / d^3`` at h = 1.8 d; the one kernel's is ``m / d^3`` by its scale.
    """
    lattice = rest_lattice(rest_distance, h)
    r2 = np.einsum("ij,ij->i", lattice, lattice)
    return float(mass * kernel_weight(kernel, r2, rest_distance, h).sum())


def rest_gradient_sq(rest_distance: float, h: float, scale: float, kernel: str = "poly6") -> float:
    """``sum_j |scale grad W_ij|^2`` of a particle of the rest lattice (its own term vanishes by symmetry).

    With ``scale = m / rho0`` [m^3] it is the constraint gradients' ``sum_j |grad C_i|^2`` at rest [1/m^2].
    """
    lattice = rest_lattice(rest_distance, h)
    r2 = np.einsum("ij,ij->i", lattice, lattice)
    grad = kernel_slope(kernel, np.sqrt(r2[r2 > 0.0]), rest_distance, h) * scale
    return float((grad * grad).sum())


def wall_density_tables(
    rest_distance: float, h: float, mass: float, size: int = WALL_TABLE_SIZE, kernel: str = "poly6"
):
    """Density [kg/m^3] of a lattice at rest continued beyond a plane wall, and its derivative.

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
    deltas = np.linspace(0.0, h, size)
    rho = np.zeros(size)
    grad = np.zeros(size)
    for i, delta in enumerate(deltas):
        z = delta + 0.5 * d + np.arange(n + 1) * d
        if kernel == "poly6":
            # (poly6's own sum in r^2, as before the kernel could be chosen: its tables stay bitwise the same)
            k = 315.0 / (64.0 * math.pi * h**9)
            q = np.maximum(h * h - plane[None, :] - z[:, None] ** 2, 0.0)
            rho[i] = mass * k * (q**3).sum()
            # d/d(delta) of (h^2 - r^2)^3 with dr^2/d(delta) = 2 z
            grad[i] = mass * k * (-6.0 * z[:, None] * q**2).sum()
        else:
            r2 = plane[None, :] + z[:, None] ** 2
            r = np.sqrt(r2)
            rho[i] = mass * kernel_weight(kernel, r2, d, h).sum()
            # dW/d(delta) = W'(r) z / r
            grad[i] = mass * (-kernel_slope(kernel, r, d, h) * z[:, None] / r).sum()
    t = np.clip((deltas - 0.75 * d) / (0.25 * d), 0.0, 1.0)
    window = 1.0 - t * t * (3.0 - 2.0 * t)
    dwindow = np.where((t > 0.0) & (t < 1.0), -6.0 * t * (1.0 - t) / (0.25 * d), 0.0)
    return rho * window, grad * window + rho * dwindow
