# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch (not adopted): a coarse projection of the fluid's velocity after every ``SolverXPBD.step``.

After each step the fluid's velocities are averaged over cells of ``COARSE_CELL`` spacings
(``COARSE_D`` [m]) in the closed box ``[0, COARSE_BOX]`` [m]; in the cells at least half full the
divergence of that coarse field (central differences, no flow through the box's walls) is removed by
``COARSE_BETA`` times the gradient of the potential solving ``lap phi = div`` (zero in the cells less
than half full: the free surface; no gradient through the walls; a dense solve, NumPy, CPU only).
Then runs ``python -m benchmarks ARGS`` (or a script, if the first argument ends in ``.py``).
docs/archive/validation_notebook.md, "What moves in still water".

Usage: COARSE_BOX=0.6,0.6,1.8 COARSE_D=0.05 [COARSE_CELL=3 COARSE_BETA=1] python
docs/archive/scratch/coarse_projection.py rest_column --layers 24
"""

import os
import sys

import numpy as np

import newton

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from run_around import run_around  # noqa: E402

BETA = float(os.environ.get("COARSE_BETA", "1"))
CELL = int(os.environ.get("COARSE_CELL", "3"))
BOX = np.array([float(x) for x in os.environ["COARSE_BOX"].split(",")])
H = CELL * float(os.environ["COARSE_D"])
DIMS = np.maximum(np.ceil(BOX / H - 1e-9).astype(int), 1)
N = int(np.prod(DIMS))
EXACT = os.environ.get("COARSE_EXACT", "0") == "1"
SURFACE = os.environ.get("COARSE_SURFACE", "0") == "1"
_solves = {}


def operators(full: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The central gradient (every cell, from the full cells' potential) and divergence (at the full cells).

    ``COARSE_EXACT=1``: the projection solves ``D G phi = D u`` with these two (least squares), so the
    corrected field has no divergence in the full cells, and every cell holding fluid is corrected.
    """
    cells = np.nonzero(full)[0]
    index = -np.ones(N, dtype=int)
    index[cells] = np.arange(len(cells))
    g = np.zeros((3 * N, len(cells)))
    d = np.zeros((len(cells), 3 * N))
    for c, ijk in enumerate(np.array(np.unravel_index(np.arange(N), DIMS)).T):
        for axis in range(3):
            for side in (-1, 1):
                nb = ijk.copy()
                nb[axis] += side
                if nb[axis] < 0 or nb[axis] >= DIMS[axis]:
                    # beyond a wall: the potential is the cell's own, the normal velocity its opposite
                    if index[c] >= 0:
                        g[3 * c + axis, index[c]] += side / (2.0 * H)
                        d[index[c], 3 * c + axis] -= side / (2.0 * H)
                    continue
                k = np.ravel_multi_index(nb, DIMS)
                if index[k] >= 0:
                    g[3 * c + axis, index[k]] += side / (2.0 * H)
                if index[c] >= 0:
                    d[index[c], 3 * k + axis] += side / (2.0 * H)
    return g, d, cells


def laplacian(full: np.ndarray, fill: np.ndarray, solid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The Laplacian over the full cells (zero potential in the others, none through the walls) and those cells.

    ``solid``: cells a body fills, through which nothing flows either (coarse_density.py's ``COARSE_BODIES``).

    ``COARSE_SURFACE=1``: the zero of the potential is placed at the free surface a partly filled
    neighbour holds, ``fill + 1/2`` cells from the full cell's centre (ghost fluid), not at its centre.
    """
    index = -np.ones(N, dtype=int)
    cells = np.nonzero(full)[0]
    index[cells] = np.arange(len(cells))
    a = np.zeros((len(cells), len(cells)))
    for row, ijk in enumerate(np.array(np.unravel_index(cells, DIMS)).T):
        for axis in range(3):
            for side in (-1, 1):
                nb = ijk.copy()
                nb[axis] += side
                if nb[axis] < 0 or nb[axis] >= DIMS[axis]:
                    continue
                flat = np.ravel_multi_index(nb, DIMS)
                k = index[flat]
                if k >= 0:
                    a[row, row] -= 1.0
                    a[row, k] += 1.0
                elif solid is not None and solid[flat]:
                    continue
                elif SURFACE:
                    a[row, row] -= 1.0 / (np.clip(fill[flat], 0.0, 0.5) + 0.5)
                else:
                    a[row, row] -= 1.0
    return a / H**2, cells


def central(field: np.ndarray, axis: int, wall_sign: float) -> np.ndarray:
    """Central difference along ``axis``, the value beyond a wall ``wall_sign`` times the one inside it."""
    plus, minus = np.roll(field, -1, axis=axis), np.roll(field, 1, axis=axis)
    last, first = [slice(None)] * 3, [slice(None)] * 3
    last[axis], first[axis] = -1, 0
    plus[tuple(last)] = wall_sign * field[tuple(last)]
    minus[tuple(first)] = wall_sign * field[tuple(first)]
    return (plus - minus) / (2.0 * H)


def project(q: np.ndarray, v: np.ndarray, fluid: np.ndarray) -> None:
    cell = np.ravel_multi_index(np.clip((q[fluid] / H).astype(int), 0, DIMS - 1).T, DIMS)
    count = np.bincount(cell, minlength=N).astype(float)
    u = np.stack([np.bincount(cell, weights=v[fluid, a], minlength=N) for a in range(3)], axis=1)
    u[count > 0] /= count[count > 0, None]
    full = count >= 0.5 * CELL**3
    key = full.tobytes()
    if EXACT:
        if key not in _solves:
            g, d, cells = operators(full)
            _solves.clear()
            _solves[key] = (g @ np.linalg.pinv(d @ g) @ d if len(cells) else None, cells)
        projector, _ = _solves[key]
        if projector is None:
            return
        correction = (projector @ u.reshape(-1)).reshape(N, 3)
        v[fluid] -= BETA * correction[cell]
        return
    fill = count / CELL**3
    if SURFACE:
        key = np.round(np.minimum(fill, 0.5) * 8.0).astype(np.int8).tobytes()
    if key not in _solves:
        a, cells = laplacian(full, fill)
        _solves.clear()
        _solves[key] = (np.linalg.inv(a) if len(cells) else None, cells)
    inverse, cells = _solves[key]
    if inverse is None:
        return
    grid = u.reshape(*DIMS, 3)
    div = sum(central(grid[..., a], a, -1.0) for a in range(3))
    phi = np.zeros(N)
    phi[cells] = inverse @ div.reshape(-1)[cells]
    phi = phi.reshape(DIMS)
    grad = np.stack([central(phi, a, 1.0) for a in range(3)], axis=-1).reshape(N, 3)
    inside = full[cell]
    v[np.nonzero(fluid)[0][inside]] -= BETA * grad[cell[inside]]


_step = newton.solvers.SolverXPBD.step


def step(self, state_in, state_out, control, contacts, dt, **kwargs):
    _step(self, state_in, state_out, control, contacts, dt, **kwargs)
    if BETA > 0.0:
        fluid = (self.model.particle_flags.numpy() & int(newton.ParticleFlags.FLUID)) != 0
        project(state_out.particle_q.numpy().astype(np.float64), state_out.particle_qd.numpy(), fluid)


if __name__ == "__main__":
    run_around(step)
