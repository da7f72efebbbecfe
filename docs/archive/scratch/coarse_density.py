# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch (not adopted): a coarse density correction at the end of every ``SolverXPBD.step``.

The density constraint's error, as the step's last pass read it (``rho / rho0 - 1`` per particle), is averaged
over cells of ``COARSE_CELL`` spacings (``COARSE_D`` [m]) in the closed box ``COARSE_ORIGIN + [0, COARSE_BOX]``
[m], with trilinear weights to the cell centres, mirrored at the box's walls. In the cells at least
``COARSE_FULL`` full (the same weights counting particles), the compression ``e = max(error, 0)`` is removed by a
displacement ``dx = grad phi`` with ``lap phi = e`` (``phi`` zero in the other cells, the free surface; no flux
through the walls; a dense solve): ``div dx = e``, the volume the compression lacks. Each particle moves by
``COARSE_BETA`` times ``dx`` interpolated with the same weights, and, as a density pass's move does, that move
becomes velocity (``dx / dt``). Unlike the velocity projection of ``coarse_projection.py`` it acts only where
the fluid is compressed, so a free surface's flows, which compress nothing, are left to the fine passes.
``COARSE_SOURCE=count`` drives it by the deposited number density instead (``COARSE_BILATERAL=1``: both
signs); ``COARSE_BODIES=1`` makes the cells the model's box bodies fill solid instead of free surface, ``2``
makes them part of the problem and moves each body with their mean displacement, ``3`` makes each body a rigid
unknown of the problem (the fluid's and the bodies' moves of least kinetic energy that remove the compression,
Batty et al. 2007's coupling; ``COARSE_ROTATION=0``: the bodies move without turning), their shares of the cells
read at ``COARSE_SAMPLES``^3 points a cell (4); ``COARSE_VELOCITY=0`` keeps the move out of the velocity.
Then runs ``python -m benchmarks ARGS`` (or a script, if the first argument ends in ``.py``).
docs/archive/validation_notebook.md, "A coarse density correction against the ring".

Usage: COARSE_BOX=0.6,0.6,3.0 COARSE_D=0.05 [COARSE_CELL=3 COARSE_BETA=0.5 COARSE_FULL=0.97 COARSE_ORIGIN=0,0,0]
python docs/archive/scratch/coarse_density.py rest_column --layers 40
"""

import os
import sys

import numpy as np

import newton

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from coarse_projection import DIMS, H, N, central, laplacian  # noqa: E402
from run_around import run_around  # noqa: E402

BETA = float(os.environ.get("COARSE_BETA", "0.5"))
FULL = float(os.environ.get("COARSE_FULL", "0.97"))
# 1: the full cells are held at the rest density from both sides (``e = n d^3 - 1``), not only compressed ones
BILATERAL = os.environ.get("COARSE_BILATERAL", "0") == "1"
# "count": the deposited number density, whose particle-scale noise is the size of the load, instead of the
# constraint's own error
SOURCE = os.environ.get("COARSE_SOURCE", "constraint")
D = float(os.environ["COARSE_D"])
ORIGIN = np.array([float(x) for x in os.environ.get("COARSE_ORIGIN", "0,0,0").split(",")])
# 1: the cells the model's box bodies fill are solid (no flux through them), not free surface; 2: they are part
# of the coarse problem (no compression of their own) and each body moves with the mean displacement of its cells
BODIES = int(os.environ.get("COARSE_BODIES", "0"))
# 0: the move is not turned into velocity (the positions alone are corrected)
VELOCITY = os.environ.get("COARSE_VELOCITY", "1") == "1"
# 0: (COARSE_BODIES=3) the coarse problem moves bodies without turning them; their torque is the contacts' alone
ROTATION = os.environ.get("COARSE_ROTATION", "1") == "1"
_solves = {}
# sample points of a cell, in cell units from its centre, for the share a body fills
SAMPLES = int(os.environ.get("COARSE_SAMPLES", "4"))
_SAMPLES = (
    np.stack(np.meshgrid(*[np.arange(SAMPLES)] * 3, indexing="ij"), axis=-1).reshape(-1, 3) + 0.5
) / SAMPLES - 0.5


def solid_share(model, state) -> dict[int, np.ndarray]:
    """The share of each cell inside the boxes attached to each body, at ``state``'s body poses."""
    shares = {}
    centres = (np.array(np.unravel_index(np.arange(N), DIMS)).T + 0.5) * H + ORIGIN
    points = centres[:, None, :] + _SAMPLES[None] * H
    body_q = state.body_q.numpy()
    kinds, bodies = model.shape_type.numpy(), model.shape_body.numpy()
    scales, local = model.shape_scale.numpy(), model.shape_transform.numpy()
    for shape in np.nonzero((bodies >= 0) & (kinds == int(newton.GeoType.BOX)))[0]:
        pose = body_q[bodies[shape]]
        # the shape's frame in the world: body pose times the shape's local transform
        rot = _rotation(pose[3:]) @ _rotation(local[shape][3:])
        origin = pose[:3] + _rotation(pose[3:]) @ local[shape][:3]
        inside = np.all(np.abs((points - origin) @ rot) <= scales[shape], axis=-1)
        body = int(bodies[shape])
        shares[body] = np.maximum(shares.get(body, np.zeros(N)), inside.mean(axis=1))
    return shares


def _rotation(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of the unit quaternion ``(x, y, z, w)``."""
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def weights(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 8 cells (flat indices) and trilinear weights of each position; beyond a wall, the cell inside it."""
    s = (q - ORIGIN) / H - 0.5
    base = np.floor(s).astype(int)
    f = s - base
    cells, w = [], []
    for o in np.ndindex(2, 2, 2):
        o = np.array(o)
        ijk = np.clip(base + o, 0, DIMS - 1)
        cells.append(np.ravel_multi_index(ijk.T, DIMS))
        w.append(np.prod(np.where(o == 1, f, 1.0 - f), axis=1))
    return np.stack(cells, axis=1), np.stack(w, axis=1)


def spread_to_cells(x: np.ndarray, error: np.ndarray | None) -> tuple:
    """The cells and weights of the positions ``x``, each cell's fill, and its weighted mean ``1 + error``
    (``None`` without an error)."""
    cells, w = weights(x)
    fill = np.bincount(cells.reshape(-1), weights=w.reshape(-1), minlength=N) * (D / H) ** 3
    measured = None
    if error is not None:
        weight = np.bincount(cells.reshape(-1), weights=w.reshape(-1), minlength=N)
        spread = np.bincount(cells.reshape(-1), weights=(w * error[:, None]).reshape(-1), minlength=N)
        measured = 1.0 + spread / np.maximum(weight, 1.0e-12)
    return cells, w, fill, measured


def cell_gradient(phi: np.ndarray) -> np.ndarray:
    """The central gradient of a field on the cells (a potential, a body's share), ``(N, 3)``."""
    phi = phi.reshape(DIMS)
    return np.stack([central(phi, a, 1.0) for a in range(3)], axis=-1).reshape(N, 3)


def move_fluid(q, v, fluid, cells, w, grad, dt: float) -> None:
    """Move the fluid particles by ``COARSE_BETA`` times ``grad`` interpolated (and, with ``COARSE_VELOCITY``,
    turn the move into velocity)."""
    dx = BETA * np.einsum("pk,pka->pa", w, grad[cells])
    index = np.nonzero(fluid)[0]
    q[index] += dx.astype(q.dtype)
    if VELOCITY:
        v[index] += (dx / dt).astype(v.dtype)


def correct(
    q: np.ndarray,
    v: np.ndarray,
    fluid: np.ndarray,
    dt: float,
    error: np.ndarray | None = None,
    solid_part: np.ndarray | None = None,
) -> np.ndarray | None:
    """Move the fluid by the correction; returns the cells' displacement field (before ``COARSE_BETA``)."""
    cells, w, fill, measured = spread_to_cells(q[fluid].astype(np.float64), error)
    solid = None
    if solid_part is not None:
        solid = solid_part >= 0.5
        inside = ~solid & (fill + solid_part >= FULL)
        if BODIES == 2:
            inside |= solid
            solid = None
    else:
        inside = fill >= FULL
    key = inside.tobytes() + (b"" if solid is None else solid.tobytes())
    if key not in _solves:
        _solves.clear()
        _solves[key] = np.linalg.inv(laplacian(inside, fill, solid)[0]) if inside.any() else None
    inverse = _solves[key]
    if inverse is None:
        return None
    phi = np.zeros(N)
    excess = (fill if error is None else measured)[inside] - 1.0
    phi[inside] = inverse @ (excess if BILATERAL else np.maximum(excess, 0.0))
    if solid is not None:
        # no flux into a body: its cells take their fluid neighbours' mean potential
        phi = phi.reshape(DIMS)
        known = inside.reshape(DIMS).astype(float)
        total, count = np.zeros(DIMS), np.zeros(DIMS)
        for axis in range(3):
            for side in (-1, 1):
                total += np.roll(phi * known, side, axis=axis)
                count += np.roll(known, side, axis=axis)
        fill_in = solid.reshape(DIMS) & (count > 0)
        phi[fill_in] = total[fill_in] / count[fill_in]
    grad = cell_gradient(phi)
    move_fluid(q, v, fluid, cells, w, grad, dt)
    return grad


def coupled_correct(model, state, q, v, fluid, dt, error, shares):
    """``COARSE_BODIES=3``: the bodies are rigid unknowns of the coarse problem (Batty et al. 2007's coupling).

    The move minimises the kinetic energy of the fluid's and the bodies' displacements subject to
    ``div dx + grad s . (U + w x r) = e`` in the full cells (``s`` a body's share of the cell): the fluid moves
    by ``grad phi``, each body by ``-rho V M^-1 J^T phi``, so the pressure that expands the water pushes the
    body with the same impulse. Cells a body fills at least half are solid to the fluid (no flux).
    """
    cells, w, fill, measured = spread_to_cells(q[fluid].astype(np.float64), error)
    solid_part = np.max(list(shares.values()), axis=0)
    solid = solid_part >= 0.5
    inside = ~solid & (fill + solid_part >= FULL)
    if not inside.any():
        return
    a, index = laplacian(inside, fill, solid)
    mass = model.particle_mass.numpy()[np.nonzero(fluid)[0][0]]
    rho_v = mass / D**3 * H**3
    centres = (np.array(np.unravel_index(index, DIMS)).T + 0.5) * H + ORIGIN
    body_q, body_qd = state.body_q.numpy(), state.body_qd.numpy()
    couplings = []
    for body, share in shares.items():
        grad_s = cell_gradient(share)[index]
        pose = body_q[body]
        rot = _rotation(pose[3:])
        com = pose[:3] + rot @ model.body_com.numpy()[body]
        jac = np.concatenate([grad_s, np.cross(centres - com, grad_s)], axis=1)
        if not ROTATION:
            jac[:, 3:] = 0.0
        inv = np.zeros((6, 6))
        inv[:3, :3] = np.eye(3) / model.body_mass.numpy()[body]
        inv[3:, 3:] = np.linalg.inv(rot @ model.body_inertia.numpy()[body] @ rot.T)
        a -= rho_v * jac @ inv @ jac.T
        couplings.append((body, com, jac, inv))
    phi = np.zeros(N)
    phi[index] = np.linalg.solve(a, np.maximum(measured[index] - 1.0, 0.0))
    move_fluid(q, v, fluid, cells, w, cell_gradient(phi), dt)
    for body, com, jac, inv in couplings:
        move = -BETA * rho_v * inv @ (jac.T @ phi[index])
        lin, ang = move[:3], move[3:]
        pose = body_q[body]
        pose[:3] += (lin + np.cross(ang, pose[:3] - com)).astype(pose.dtype)
        x4, y4, z4, w4 = pose[3:]
        wx, wy, wz = ang
        dq = 0.5 * np.array(
            [
                wx * w4 + wy * z4 - wz * y4,
                wy * w4 + wz * x4 - wx * z4,
                wz * w4 + wx * y4 - wy * x4,
                -(wx * x4 + wy * y4 + wz * z4),
            ]
        )
        quat = pose[3:] + dq
        pose[3:] = (quat / np.linalg.norm(quat)).astype(pose.dtype)
        if VELOCITY:
            body_qd[body, :3] += (lin / dt).astype(body_qd.dtype)
            body_qd[body, 3:] += (ang / dt).astype(body_qd.dtype)


_step = newton.solvers.SolverXPBD.step


def step(self, state_in, state_out, control, contacts, dt, **kwargs):
    _step(self, state_in, state_out, control, contacts, dt, **kwargs)
    if BETA > 0.0:
        fluid = (self.model.particle_flags.numpy() & int(newton.ParticleFlags.FLUID)) != 0
        error = None
        if SOURCE == "constraint":
            f = self._fluid
            slot = f.search.slot_of_particle.numpy()
            error = f.density.numpy()[slot] / f.rest_density - 1.0
            error = error[np.nonzero(fluid)[0]] if len(error) == len(fluid) else error
        shares = solid_share(self.model, state_out) if BODIES else {}
        if BODIES == 3 and shares:
            coupled_correct(
                self.model,
                state_out,
                state_out.particle_q.numpy(),
                state_out.particle_qd.numpy(),
                fluid,
                dt,
                error,
                shares,
            )
            return
        solid_part = np.max(list(shares.values()), axis=0) if shares else None
        grad = correct(state_out.particle_q.numpy(), state_out.particle_qd.numpy(), fluid, dt, error, solid_part)
        if BODIES == 2 and grad is not None:
            body_q, body_qd = state_out.body_q.numpy(), state_out.body_qd.numpy()
            for body, share in shares.items():
                if share.sum() > 0.0:
                    move = BETA * (share[:, None] * grad).sum(axis=0) / share.sum()
                    body_q[body, :3] += move.astype(body_q.dtype)
                    body_qd[body, :3] += (move / dt).astype(body_qd.dtype)


if __name__ == "__main__":
    run_around(step)
