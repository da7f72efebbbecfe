# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch (not adopted): coarse_density.py's correction in Warp kernels, for its cost on a GPU and inside a graph.

The same correction as ``coarse_density.py`` (``COARSE_SOURCE=constraint``, no bodies): the density constraint's
error from the step's last pass is spread over cells of ``COARSE_CELL`` spacings (``COARSE_D`` [m]) in the box
``COARSE_ORIGIN + [0, COARSE_BOX]`` [m] with trilinear weights; in the cells at least ``COARSE_FULL`` full,
``lap phi = max(e, 0)`` (``phi`` zero in the other cells, no flux through the box's walls) and every fluid
particle moves by ``COARSE_BETA`` times ``grad phi`` interpolated with the same weights, the move becoming
velocity. A cell is full against its own share of the box (a box that is not a whole number of cells ends inside
its last ones). In place of the dense inverse, ``COARSE_SWEEPS`` red-black sweeps of successive over-relaxation
(``COARSE_OMEGA``) run at every step, starting from the previous step's ``phi``: the load a still fluid carries
changes little from one substep to the next, so the solve follows it (with fewer than 4 sweeps it trails too far
and runs away). The cells are made with the solver, and a step allocates and reads back nothing: the frame,
correction included, can be captured in a CUDA graph.

Run around a benchmark as coarse_density.py is (``COARSE_BOX=0.6,0.6,3.0 COARSE_D=0.05 python
docs/archive/scratch/coarse_density_warp.py rest_column --layers 40``), or ``--time N LAYERS DEVICE [REPS]``: the
frame of ``rest_column``'s column of N x N x LAYERS, captured with and without the correction, each replayed
REPS times, and the milliseconds per frame of each (the box is the column's own: ``COARSE_BOX`` unset).
docs/archive/validation_notebook.md, "A coarse density correction against the ring".
"""

import argparse
import os
import sys
import time

import numpy as np
import warp as wp

import newton
from newton._src.solvers.xpbd.fluid.coarse_correction import cell_index, inside_box, trilinear_corner

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from run_around import run_around  # noqa: E402

BETA = float(os.environ.get("COARSE_BETA", "0.5"))
FULL = float(os.environ.get("COARSE_FULL", "0.97"))
CELL = int(os.environ.get("COARSE_CELL", "3"))
SWEEPS = int(os.environ.get("COARSE_SWEEPS", "4"))
OMEGA = float(os.environ.get("COARSE_OMEGA", "1.8"))
ENABLED = [True]


@wp.func
def cell_coordinates(x: wp.vec3, origin: wp.vec3, inv_cell: float) -> wp.vec3:
    """A position in cell units from the first cell's centre."""
    return (x - origin) * inv_cell - wp.vec3(0.5)


@wp.kernel
def spread_error(
    q: wp.array[wp.vec3],
    fluid_particle: wp.array[wp.int32],
    slot_of_particle: wp.array[wp.int32],
    density: wp.array[float],
    inv_rest_density: float,
    origin: wp.vec3,
    inv_cell: float,
    dims: wp.vec3i,
    particle_fill: float,
    fill: wp.array[float],
    spread: wp.array[float],
):
    t = wp.tid()
    p = fluid_particle[t]
    slot = slot_of_particle[p]
    error = float(0.0)
    if slot >= 0:
        error = density[slot] * inv_rest_density - 1.0
    s = cell_coordinates(q[p], origin, inv_cell)
    for corner in range(8):
        c, w = trilinear_corner(s, dims, corner)
        wp.atomic_add(fill, c, w * particle_fill)
        wp.atomic_add(spread, c, w * particle_fill * error)


@wp.kernel
def mark_full_cells(
    fill: wp.array[float],
    spread: wp.array[float],
    capacity: wp.array[float],
    full: float,
    inside: wp.array[wp.int32],
    source: wp.array[float],
    phi: wp.array[float],
):
    c = wp.tid()
    if fill[c] >= full * capacity[c]:
        inside[c] = 1
        # the weighted mean error: both sums carry the same weights
        source[c] = wp.max(spread[c] / fill[c], 0.0)
    else:
        inside[c] = 0
        source[c] = 0.0
        phi[c] = 0.0


@wp.func
def potential_or(phi: wp.array[float], i: int, j: int, k: int, dims: wp.vec3i, beyond: float) -> float:
    """The potential of cell ``(i, j, k)``, or ``beyond`` where that cell lies past a wall."""
    if inside_box(i, j, k, dims):
        return phi[cell_index(i, j, k, dims)]
    return beyond


@wp.func
def open_face(i: int, j: int, k: int, dims: wp.vec3i) -> float:
    """1 where the neighbour ``(i, j, k)`` lies inside the box (flux passes), 0 past a wall."""
    if inside_box(i, j, k, dims):
        return 1.0
    return 0.0


@wp.kernel
def relax_potential(
    inside: wp.array[wp.int32],
    source: wp.array[float],
    dims: wp.vec3i,
    cell: float,
    omega: float,
    colour: int,
    phi: wp.array[float],
):
    c = wp.tid()
    k = c % dims[2]
    j = (c // dims[2]) % dims[1]
    i = c // (dims[1] * dims[2])
    if inside[c] == 0 or (i + j + k) % 2 != colour:
        return
    # a neighbour beyond a wall passes no flux (it adds nothing and is not counted); one outside the full cells
    # is the free surface (its phi is 0)
    total = (
        potential_or(phi, i - 1, j, k, dims, 0.0)
        + potential_or(phi, i + 1, j, k, dims, 0.0)
        + potential_or(phi, i, j - 1, k, dims, 0.0)
        + potential_or(phi, i, j + 1, k, dims, 0.0)
        + potential_or(phi, i, j, k - 1, dims, 0.0)
        + potential_or(phi, i, j, k + 1, dims, 0.0)
    )
    count = (
        open_face(i - 1, j, k, dims)
        + open_face(i + 1, j, k, dims)
        + open_face(i, j - 1, k, dims)
        + open_face(i, j + 1, k, dims)
        + open_face(i, j, k - 1, dims)
        + open_face(i, j, k + 1, dims)
    )
    solved = (total - cell * cell * source[c]) / count
    phi[c] = (1.0 - omega) * phi[c] + omega * solved


@wp.kernel
def potential_gradient(phi: wp.array[float], dims: wp.vec3i, cell: float, gradient: wp.array[wp.vec3]):
    c = wp.tid()
    k = c % dims[2]
    j = (c // dims[2]) % dims[1]
    i = c // (dims[1] * dims[2])
    # beyond a wall the potential is the cell's own
    here = phi[c]
    g = wp.vec3(
        potential_or(phi, i + 1, j, k, dims, here) - potential_or(phi, i - 1, j, k, dims, here),
        potential_or(phi, i, j + 1, k, dims, here) - potential_or(phi, i, j - 1, k, dims, here),
        potential_or(phi, i, j, k + 1, dims, here) - potential_or(phi, i, j, k - 1, dims, here),
    )
    gradient[c] = g / (2.0 * cell)


@wp.kernel
def move_by_gradient(
    fluid_particle: wp.array[wp.int32],
    origin: wp.vec3,
    inv_cell: float,
    dims: wp.vec3i,
    gradient: wp.array[wp.vec3],
    beta: float,
    inv_dt: float,
    q: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
):
    t = wp.tid()
    p = fluid_particle[t]
    s = cell_coordinates(q[p], origin, inv_cell)
    dx = wp.vec3(0.0)
    for corner in range(8):
        c, w = trilinear_corner(s, dims, corner)
        dx += w * gradient[c]
    dx = beta * dx
    q[p] = q[p] + dx
    v[p] = v[p] + dx * inv_dt


class CoarseDensity:
    """The cells and their arrays, made at the first step of a solver."""

    def __init__(self, solver, box: np.ndarray, origin: np.ndarray, spacing: float):
        self.cell = CELL * spacing
        dims = np.maximum(np.ceil(box / self.cell - 1e-9).astype(int), 1)
        self.dims = wp.vec3i(*[int(x) for x in dims])
        self.count = int(np.prod(dims))
        self.origin = wp.vec3(*[float(x) for x in origin])
        self.particle_fill = (spacing / self.cell) ** 3
        device = solver.model.device
        self.fill = wp.zeros(self.count, dtype=float, device=device)
        # the share of each cell inside the box: a box that is not a whole number of cells ends inside its last
        # cells, which hold less fluid when full (counted as free surface, they would pull the fluid to that wall)
        share = [np.clip(box[a] / self.cell - np.arange(dims[a]), 0.0, 1.0) for a in range(3)]
        capacity = share[0][:, None, None] * share[1][None, :, None] * share[2][None, None, :]
        self.capacity = wp.array(capacity.reshape(-1), dtype=float, device=device)
        self.spread = wp.zeros(self.count, dtype=float, device=device)
        self.inside = wp.zeros(self.count, dtype=wp.int32, device=device)
        self.source = wp.zeros(self.count, dtype=float, device=device)
        self.phi = wp.zeros(self.count, dtype=float, device=device)
        self.gradient = wp.zeros(self.count, dtype=wp.vec3, device=device)

    def correct(self, solver, state, dt: float) -> None:
        f = solver._fluid
        n = f.fluid_count
        inv_cell = 1.0 / self.cell
        self.fill.zero_()
        self.spread.zero_()
        wp.launch(
            spread_error,
            n,
            inputs=[
                state.particle_q,
                f.fluid_particle,
                f.search.slot_of_particle,
                f.density,
                1.0 / f.rest_density,
                self.origin,
                inv_cell,
                self.dims,
                self.particle_fill,
            ],
            outputs=[self.fill, self.spread],
        )
        wp.launch(
            mark_full_cells,
            self.count,
            inputs=[self.fill, self.spread, self.capacity, FULL],
            outputs=[self.inside, self.source, self.phi],
        )
        for _ in range(SWEEPS):
            for colour in (0, 1):
                wp.launch(
                    relax_potential,
                    self.count,
                    inputs=[self.inside, self.source, self.dims, self.cell, OMEGA, colour],
                    outputs=[self.phi],
                )
        wp.launch(potential_gradient, self.count, inputs=[self.phi, self.dims, self.cell], outputs=[self.gradient])
        wp.launch(
            move_by_gradient,
            n,
            inputs=[f.fluid_particle, self.origin, inv_cell, self.dims, self.gradient, BETA, 1.0 / dt],
            outputs=[state.particle_q, state.particle_qd],
        )


_init = newton.solvers.SolverXPBD.__init__
_step = newton.solvers.SolverXPBD.step
_cells = {}


def init(self, model, *args, **kwargs):
    _init(self, model, *args, **kwargs)
    # the cells are made here, not at the first step: a first step inside a graph capture would capture their
    # allocation and zeroing, and every replay would start the potential again from zero
    if getattr(self, "_fluid", None) is not None:
        _cells[id(self)] = CoarseDensity(self, *box_of(self))


def box_of(solver) -> tuple[np.ndarray, np.ndarray, float]:
    """``COARSE_BOX`` / ``COARSE_ORIGIN`` / ``COARSE_D`` from the environment, else the column of --time."""
    spacing = float(os.environ.get("COARSE_D", solver._fluid.config.fluid_rest_distance))
    origin = np.array([float(x) for x in os.environ.get("COARSE_ORIGIN", "0,0,0").split(",")])
    if "COARSE_BOX" in os.environ:
        box = np.array([float(x) for x in os.environ["COARSE_BOX"].split(",")])
    else:
        q = solver.model.particle_q.numpy()
        box = np.array([q[:, 0].max() + 0.5 * spacing, q[:, 1].max() + 0.5 * spacing, 1.5 * q[:, 2].max()])
    return box, origin, spacing


def step(self, state_in, state_out, control, contacts, dt, **kwargs):
    _step(self, state_in, state_out, control, contacts, dt, **kwargs)
    if BETA > 0.0 and ENABLED[0] and id(self) in _cells:
        _cells[id(self)].correct(self, state_out, dt)


def time_frames(n: int, layers: int, device: str, reps: int) -> None:
    """Milliseconds per captured frame of rest_column's column, without and with the correction."""
    sys.path.insert(0, ".")
    from benchmarks.frames import add_solver_arguments, contact_frames  # noqa: PLC0415
    from benchmarks.rest_column import SPACING, build  # noqa: PLC0415

    parser = argparse.ArgumentParser()
    add_solver_arguments(parser)
    args = parser.parse_args([])
    newton.solvers.SolverXPBD.__init__ = init
    newton.solvers.SolverXPBD.step = step
    with wp.ScopedDevice(device):
        model = build(n, layers, device)
        _, frame = contact_frames(model, args, SPACING, wp.get_device(device))
        for _ in range(30):
            frame()
        times = {}
        for enabled in (False, True, False, True):
            ENABLED[0] = enabled
            frame.graph = None
            frame()
            wp.synchronize_device()
            start = time.perf_counter()
            for _ in range(reps):
                frame()
            wp.synchronize_device()
            times.setdefault(enabled, []).append((time.perf_counter() - start) / reps * 1000.0)
    off, on = min(times[False]), min(times[True])
    cells = next(iter(_cells.values())).count
    print(
        f"{model.particle_count} particles, {cells} cells, {SWEEPS} sweeps: {off:.3f} ms per frame without the "
        f"correction, {on:.3f} with it (+{on - off:.3f} ms, {100.0 * (on - off) / off:.1f} %)"
    )


if __name__ == "__main__":
    if sys.argv[1] == "--time":
        time_frames(int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], int(sys.argv[5]) if len(sys.argv) > 5 else 100)
    else:
        newton.solvers.SolverXPBD.__init__ = init
        run_around(step)
