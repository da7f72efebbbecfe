# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The coarse density correction: the compression the density passes leave, removed on cells of a few spacings.

A Jacobi density pass moves a compression about one particle spacing: a load spread over many spacings (a
deep column's weight) is removed a few thousandths a pass, and the column rings as a soft spring
(docs/archive/validation_notebook.md, "The one-kernel column's slow breathing"). With
``fluid_coarse_correction`` > 0, after the substep's passes:

1. the fluid's bounds are found per world (:func:`bound_fluid_cells`, :func:`place_coarse_cells`): each
   world gets a box of cells of ``fluid_coarse_cell`` rest distances over its fluid, with one cell to spare
   on every side, in its own block of a table sized with the solver (cells twice as large, and again, while
   the box does not fit in the block: fluid thrown far is still corrected, more coarsely);
2. each particle's constraint error ``e = rho / rho0 - 1`` from the substep's last density pass is spread
   to the 8 cell centres around it with trilinear weights (:func:`spread_density_error`, in slot order, so
   that the threads of a warp, neighbours in space, sum what they add to a cell before one adds it);
3. a cell whose fluid fills at least ``FULL_FILL`` of its room (the share of it in front of the static walls
   its particles list for the density pass) is full, one that holds less is free surface, and one with no
   fluid or with its centre behind a wall holds none (:func:`mark_coarse_cells`);
4. on the full cells ``lap phi - phi / (SCREENING_CELLS cells)^2 = max(e, 0)`` is relaxed by ``SWEEPS``
   red-black sweeps of over-relaxed Gauss-Seidel started from the last substep's ``phi``
   (:func:`relax_coarse_potential`): ``phi`` is 0 on the free surface and passes no flux into cells
   without fluid, which is what a wall is to the cells (so no shape is read); the screening keeps ``phi``
   bounded where a fluid fills a closed container and no free surface takes its compression. The surface
   is where a free-surface cell's fill puts it, ``theta`` cells from its full neighbour's centre, and the
   face to it weighs ``1 / theta`` (the ghost-fluid condition of Gibou et al. 2002, "A second-order-accurate
   symmetric discretization of the Poisson equation on irregular domains", J. Comput. Phys. 176): with the
   surface at the surface cell's centre instead, the potential's boundary sat up to a cell from the fluid's
   top and did not follow a wave's surface within a cell, which slowed a standing wave by a quarter of its
   period (docs/validation.rst, "Standing wave");
5. each fluid particle moves by ``fluid_coarse_correction * grad phi`` read with the same weights, and
   the move becomes velocity, as a density pass's does (:func:`move_by_coarse_gradient`).

Only compression drives it: a free surface finding its level or a wave is left to the density passes.
The cells' potential is the pressure field a converged solve would have in its long waves; the density
passes keep the particle scale. The sweeps are warm-started; with too few the potential trails the
compression and the column runs away (a 40-layer column moves at 0.14 m/s with 2; with 4 it holds on
``(1 - r/h)^2.5`` but rings at 0.023 m/s on the default kernel, with 8 at 0.0054; docs/archive/
validation_notebook.md, "The coarse correction in the solver"). Nothing is allocated or read back in
a step: every launch covers the table's fixed size, and a cell past its world's box does nothing.
"""

import warnings
from typing import Any

import numpy as np
import warp as wp

from ....geometry import ShapeFlags
from .continuous_collision import still_shapes, world_row
from .reset import world_selected
from .walls import WALL_CONTACTS_PER_SLOT

# approximate division and square root in CUDA code (no effect on the CPU; see :mod:`.sph`)
wp.set_module_options({"fast_math": True})

#: share of its room a cell's fluid fills from which it counts as full: particles at the rest distance fill
#: exactly the room (trilinear weights sum to one cell per cell of volume); a free surface's cells hold less
FULL_FILL = 0.97
#: red-black over-relaxed Gauss-Seidel sweeps per substep, and their over-relaxation
SWEEPS = 8
OMEGA = 1.8
#: nearest a free surface is taken to a full cell's centre [cells]: the face to it weighs ``1 / theta``, and a
#: surface read within a hair of the centre would make that face outweigh the rest of the cell's equation
GHOST_MIN = 0.25
#: screening length of the potential [cells]: far longer than the deepest fluid it corrects
SCREENING_CELLS = 64.0
#: a world's cells in the table: this many times the cells its fluid fills at rest, plus a 5^3 block
CELLS_PER_FILLED_CELL = 8
SMALLEST_BLOCK = 125
#: particles per bin of a world's bounds: the bins spread the atomic minima and maxima over addresses (a few
#: addresses taking every particle's atomics serialise them), and one block of threads a world reduces them
PARTICLES_PER_BIN = 32
PLACE_BLOCK_DIM = 256
#: most bins a world: a block's threads reduce at most 8 each (a 1M-particle world's 31,000 bins took one block of
#: 128 threads 97 us a substep on an H200)
BINS_PER_WORLD = 8 * PLACE_BLOCK_DIM
#: coarsest level (cells 2^level times the base size) tried before a box is given up for the substep
MAX_LEVEL = 20
# a bound no cell coordinate reaches (coordinates are clamped to +-COORDINATE_LIMIT)
COORDINATE_LIMIT = 1 << 24
NO_BOUND = 1 << 30
# cell kinds
CELL_OUTSIDE = wp.constant(0)
CELL_SURFACE = wp.constant(1)
CELL_FULL = wp.constant(2)


@wp.struct
class CoarseBoxes:
    """Each world's box of cells (one row a world, the global world ``-1`` last): its first cell in the table,
    its lower corner and size in cells, and its cells' level (edge ``base_cell * 2^level``; -1: no box yet)."""

    first: wp.array[wp.int32]
    corner: wp.array[wp.vec3i]
    dims: wp.array[wp.vec3i]
    level: wp.array[wp.int32]
    base_cell: float


@wp.func
def floor_divide(a: int, s: int) -> int:
    """``floor(a / s)`` for ``s`` > 0 (integer division truncates toward zero)."""
    if a >= 0:
        return a // s
    return -((-a + s - 1) // s)


@wp.func
def cell_index(i: int, j: int, k: int, dims: wp.vec3i) -> int:
    return (i * dims[1] + j) * dims[2] + k


@wp.func
def box_cell(local: int, dims: wp.vec3i) -> wp.vec3i:
    """The cell (i, j, k) of a box's flat index (``k`` the fastest)."""
    return wp.vec3i(local // (dims[1] * dims[2]), (local // dims[2]) % dims[1], local % dims[2])


@wp.func
def inside_box(i: int, j: int, k: int, dims: wp.vec3i) -> bool:
    return i >= 0 and i < dims[0] and j >= 0 and j < dims[1] and k >= 0 and k < dims[2]


@wp.func
def takes_part(slot: int, x: wp.vec3) -> bool:
    """Whether a fluid particle is corrected: it is in the substep's neighbour search, at a finite position."""
    return slot >= 0 and wp.isfinite(x)


@wp.func
def cell_edge(boxes: CoarseBoxes, row: int) -> float:
    """Edge of a world's cells this substep [m]."""
    return boxes.base_cell * float(1 << boxes.level[row])


@wp.func
def position_in_cells(boxes: CoarseBoxes, row: int, x: wp.vec3) -> wp.vec3:
    """``x`` in cells from the centre of the world's first cell."""
    corner = boxes.corner[row]
    h = cell_edge(boxes, row)
    return (x - wp.vec3(float(corner[0]), float(corner[1]), float(corner[2])) * h) / h - wp.vec3(0.5)


@wp.func
def cell_centre(boxes: CoarseBoxes, row: int, local: int) -> wp.vec3:
    """Centre of the world's cell ``local`` [m]."""
    ijk = boxes.corner[row] + box_cell(local, boxes.dims[row])
    return (wp.vec3(float(ijk[0]), float(ijk[1]), float(ijk[2])) + wp.vec3(0.5)) * cell_edge(boxes, row)


@wp.func
def trilinear_corner(s: wp.vec3, dims: wp.vec3i, corner: int):
    """Index in the box and trilinear weight of one of the 8 cell centres around ``s`` (in cells from the first centre)."""
    w = float(1.0)
    c = int(0)
    stride = int(1)
    for axis in range(2, -1, -1):
        low = int(wp.floor(s[axis]))
        f = s[axis] - float(low)
        o = (corner >> axis) & 1
        # (a particle of the box is at least half a cell from its edge; the clamp only guards rounding)
        i = wp.clamp(low + o, 0, dims[axis] - 1)
        if o == 1:
            w *= f
        else:
            w *= 1.0 - f
        c += i * stride
        stride *= dims[axis]
    return c, w


@wp.func
def share_in_front(distance: float) -> float:
    """Share of a cell's trilinear weight in front of a plane its centre is ``distance`` >= 0 cells in front of."""
    t = wp.min(distance, 1.0)
    return 1.0 - 0.5 * (1.0 - t) * (1.0 - t)


@wp.kernel
def bound_fluid_cells(
    fluid_particle: wp.array[wp.int32],
    slot_of_particle: wp.array[wp.int32],
    particle_q: wp.array[wp.vec3],
    fluid_row: wp.array[wp.int32],
    bin_first: wp.array[wp.int32],
    bin_count: wp.array[wp.int32],
    inv_base_cell: float,
    # outputs
    bin_lower: wp.array2d[wp.int32],
    bin_upper: wp.array2d[wp.int32],
):
    """The cells (of the base size) each world's fluid occupies, as minima and maxima per bin."""
    t = wp.tid()
    p = fluid_particle[t]
    x = particle_q[p]
    if not takes_part(slot_of_particle[p], x):
        return
    row = fluid_row[t]
    b = bin_first[row] + t % bin_count[row]
    limit = float(COORDINATE_LIMIT)
    for axis in range(3):
        c = int(wp.floor(wp.clamp(x[axis] * inv_base_cell, -limit, limit)))
        wp.atomic_min(bin_lower, b, axis, c)
        wp.atomic_max(bin_upper, b, axis, c)


@wp.kernel
def place_coarse_cells(
    bin_first: wp.array[wp.int32],
    bin_count: wp.array[wp.int32],
    row_capacity: wp.array[wp.int32],
    # outputs
    bin_lower: wp.array2d[wp.int32],
    bin_upper: wp.array2d[wp.int32],
    boxes: CoarseBoxes,
    last: CoarseBoxes,
):
    """Each world's box of cells over its fluid's bounds (the last substep's kept in ``last`` for the warm start).

    One block a world: its threads reduce the world's bins (and clear them for the next substep).
    """
    row, lane = wp.tid()
    lower = wp.vec3i(NO_BOUND, NO_BOUND, NO_BOUND)
    upper = wp.vec3i(-NO_BOUND, -NO_BOUND, -NO_BOUND)
    b = bin_first[row] + lane
    end = bin_first[row] + bin_count[row]
    while b < end:
        for axis in range(3):
            lower[axis] = wp.min(lower[axis], bin_lower[b, axis])
            upper[axis] = wp.max(upper[axis], bin_upper[b, axis])
            bin_lower[b, axis] = NO_BOUND
            bin_upper[b, axis] = -NO_BOUND
        b += wp.block_dim()
    for axis in range(3):
        lower[axis] = wp.tile_min(wp.tile(lower[axis]))[0]
        upper[axis] = wp.tile_max(wp.tile(upper[axis]))[0]
    if lane != 0:
        return
    last.corner[row] = boxes.corner[row]
    last.dims[row] = boxes.dims[row]
    last.level[row] = boxes.level[row]
    boxes.dims[row] = wp.vec3i(0, 0, 0)
    if upper[0] < lower[0]:
        return
    for k in range(MAX_LEVEL + 1):
        s = 1 << k
        first = wp.vec3i(floor_divide(lower[0], s), floor_divide(lower[1], s), floor_divide(lower[2], s))
        final = wp.vec3i(floor_divide(upper[0], s), floor_divide(upper[1], s), floor_divide(upper[2], s))
        # one spare cell on every side: the trilinear weights of a particle in the box's outer cells reach it
        n = final - first + wp.vec3i(3, 3, 3)
        if n[0] * n[1] * n[2] <= row_capacity[row]:
            boxes.corner[row] = first - wp.vec3i(1, 1, 1)
            boxes.dims[row] = n
            boxes.level[row] = k
            return


@wp.func_native(
    """
#if defined(__CUDA_ARCH__)
    const unsigned int active = __activemask();
    const unsigned int peers = __match_any_sync(active, i);
    float total_a = 0.0f;
    float total_b = 0.0f;
    for (unsigned int rest = peers; rest; rest &= rest - 1) {
        const int lane = __ffs(rest) - 1;
        total_a += __shfl_sync(peers, value_a, lane);
        total_b += __shfl_sync(peers, value_b, lane);
    }
    if ((threadIdx.x & 31) == __ffs(peers) - 1) {
        atomicAdd(wp::address(sum_a, i), total_a);
        atomicAdd(wp::address(sum_b, i), total_b);
    }
#else
    wp::atomic_add(sum_a, i, value_a);
    wp::atomic_add(sum_b, i, value_b);
#endif
"""
)
def add_to_cell(sum_a: wp.array[float], sum_b: wp.array[float], i: int, value_a: float, value_b: float):
    """``sum_a[i] += value_a`` and ``sum_b[i] += value_b``, atomically.

    On a CUDA device the threads of a warp that add to the same cell sum their values first and one of them
    adds the total: the particles of a warp are neighbours in slot order, and most of them spread to the
    same few cells, so per-thread atomics would queue on each cell's address.
    """
    ...


@wp.kernel
def spread_density_error(
    slot_particle: wp.array[wp.int32],
    slot_world: wp.array[wp.int32],
    particle_q: wp.array[wp.vec3],
    world_count: int,
    density: wp.array[float],
    inv_rest_density: float,
    boxes: CoarseBoxes,
    wall_count: wp.array[wp.int32],
    wall_plane: wp.array[wp.vec4],
    # outputs
    weight: wp.array[float],
    weighted_error: wp.array[float],
    room: wp.array[float],
):
    """Each particle's trilinear weight and constraint error, summed per cell, and the cells' room; a thread a slot.

    A cell's room is the share of it the fluid may fill, as the particle that knows most about it sees it:
    the least, over the particles around the cell, of the share its walls (the static walls listed for the
    density pass, :func:`~.walls.fluid_wall_share`) leave open. A particle lists only the walls it is near,
    so the particles by a wall decide how much of a cell it takes.
    """
    slot = wp.tid()
    p = slot_particle[slot]
    if p < 0:
        return
    x = particle_q[p]
    if not wp.isfinite(x):
        return
    row = world_row(slot_world[slot], world_count)
    n = boxes.dims[row]
    if n[0] == 0:
        return
    relative = density[slot] * inv_rest_density
    h = cell_edge(boxes, row)
    s = position_in_cells(boxes, row, x)
    walls = wp.min(wall_count[slot], WALL_CONTACTS_PER_SLOT)
    slot_count = wall_count.shape[0]
    for k in range(8):
        local, w = trilinear_corner(s, n, k)
        c = boxes.first[row] + local
        add_to_cell(weight, weighted_error, c, w, w * (relative - 1.0))
        if walls > 0:
            centre = cell_centre(boxes, row, local)
            open_share = float(1.0)
            for e in range(walls):
                plane = wall_plane[e * slot_count + slot]
                distance = wp.dot(wp.vec3(plane[0], plane[1], plane[2]), centre) - plane[3]
                # (a centre behind any wall marks the cell as the wall's: -1)
                if distance < 0.0:
                    open_share = -1.0
                    break
                open_share *= share_in_front(distance / h)
            wp.atomic_min(room, c, open_share)


@wp.kernel
def mark_coarse_cells(
    cell_row: wp.array[wp.int32],
    boxes: CoarseBoxes,
    last: CoarseBoxes,
    last_phi: wp.array[float],
    rest_distance: float,
    # outputs
    weight: wp.array[float],
    weighted_error: wp.array[float],
    room: wp.array[float],
    kind: wp.array[wp.int32],
    source: wp.array[float],
    phi: wp.array[float],
):
    """Full, free-surface or outside cells, the full cells' source and their potential from the last substep.

    A free-surface cell's ``source`` holds instead the distance [cells] from a full neighbour's centre to the
    surface its fill implies (:func:`surface_distance`). Clears the sums for the next substep.
    """
    c = wp.tid()
    row = cell_row[c]
    n = boxes.dims[row]
    local = c - boxes.first[row]
    w = weight[c]
    open_share = room[c]
    mean_error = float(0.0)
    if w > 0.0:
        mean_error = weighted_error[c] / w
    weight[c] = 0.0
    weighted_error[c] = 0.0
    room[c] = 1.0
    source[c] = 0.0
    phi[c] = 0.0
    kind[c] = CELL_OUTSIDE
    # a cell no particle reaches, or with its centre behind a wall, holds no fluid
    if local >= n[0] * n[1] * n[2] or w <= 0.0 or open_share < 0.0:
        return
    # one whose fluid does not fill its room is the free surface
    spacings = rest_distance / cell_edge(boxes, row)
    fill = w * spacings * spacings * spacings / wp.max(open_share, 1.0e-6)
    if fill < FULL_FILL:
        kind[c] = CELL_SURFACE
        source[c] = surface_distance(fill)
        return
    kind[c] = CELL_FULL
    source[c] = wp.max(mean_error, 0.0)
    # the potential a substep ago at this cell, where the last box had cells of this size
    if last.level[row] != boxes.level[row]:
        return
    ijk = box_cell(local, n) + boxes.corner[row] - last.corner[row]
    m = last.dims[row]
    if inside_box(ijk[0], ijk[1], ijk[2], m):
        phi[c] = last_phi[last.first[row] + cell_index(ijk[0], ijk[1], ijk[2], m)]


@wp.func
def surface_distance(fill: float) -> float:
    """Distance [cells] from a full cell's centre to the free surface in its neighbour, from the neighbour's fill.

    Fluid up to ``z`` cells past the full centre (and no further) gives the neighbour's centre a trilinear fill
    of ``z^2 / 2`` for ``z`` <= 1 and ``1 - (2 - z)^2 / 2`` up to 2: this inverts it (on a lattice of 3 spacings
    a cell, within 0.03 cells of the lattice's top), no nearer than ``GHOST_MIN``.
    """
    f = wp.clamp(fill, 0.0, 1.0)
    z = float(0.0)
    if f <= 0.5:
        z = wp.sqrt(2.0 * f)
    else:
        z = 2.0 - wp.sqrt(2.0 * (1.0 - f))
    return wp.max(z, GHOST_MIN)


@wp.func
def neighbour_potential(
    phi: wp.array[float],
    kind: wp.array[wp.int32],
    source: wp.array[float],
    first: int,
    ijk: wp.vec3i,
    n: wp.vec3i,
    own: float,
):
    """A neighbour's potential and the weight of the face to it: no flux (``own``, 0) where it holds no fluid; at a
    free-surface neighbour the potential 0 where the surface is, ``theta`` cells away (weight ``1 / theta``), as the
    ghost value ``own (1 - 1 / theta)`` at its centre."""
    if inside_box(ijk[0], ijk[1], ijk[2], n):
        c = first + cell_index(ijk[0], ijk[1], ijk[2], n)
        k = kind[c]
        if k == CELL_FULL:
            return phi[c], 1.0
        if k == CELL_SURFACE:
            theta = source[c]
            return own * (1.0 - 1.0 / theta), 1.0 / theta
    return own, 0.0


@wp.kernel
def relax_coarse_potential(
    cell_row: wp.array[wp.int32],
    boxes: CoarseBoxes,
    kind: wp.array[wp.int32],
    source: wp.array[float],
    colour: int,
    # outputs
    phi: wp.array[float],
):
    """One colour of a red-black over-relaxed Gauss-Seidel sweep of ``lap phi - phi / L^2 = source`` on the full cells."""
    c = wp.tid()
    if kind[c] != CELL_FULL:
        return
    row = cell_row[c]
    n = boxes.dims[row]
    first = boxes.first[row]
    ijk = box_cell(c - first, n)
    if (ijk[0] + ijk[1] + ijk[2]) % 2 != colour:
        return
    total = float(0.0)
    faces = float(0.0)
    for axis in range(3):
        for side in range(2):
            o = wp.vec3i(0, 0, 0)
            o[axis] = 2 * side - 1
            value, open_face = neighbour_potential(phi, kind, source, first, ijk + o, n, 0.0)
            total += value
            faces += open_face
    h = cell_edge(boxes, row)
    solved = (total - h * h * source[c]) / (faces + 1.0 / (SCREENING_CELLS * SCREENING_CELLS))
    phi[c] = (1.0 - OMEGA) * phi[c] + OMEGA * solved


@wp.kernel
def coarse_potential_gradient(
    cell_row: wp.array[wp.int32],
    boxes: CoarseBoxes,
    kind: wp.array[wp.int32],
    source: wp.array[float],
    phi: wp.array[float],
    # outputs
    gradient: wp.array[wp.vec3],
    last_phi: wp.array[float],
):
    """Central differences of the potential (a face to a cell without fluid passes no flux; a full cell reads a
    free-surface neighbour at its ghost value, :func:`neighbour_potential`); keeps ``phi``."""
    c = wp.tid()
    own = phi[c]
    last_phi[c] = own
    gradient[c] = wp.vec3(0.0)
    if kind[c] == CELL_OUTSIDE:
        return
    row = cell_row[c]
    n = boxes.dims[row]
    first = boxes.first[row]
    ijk = box_cell(c - first, n)
    g = wp.vec3(0.0)
    for axis in range(3):
        o = wp.vec3i(0, 0, 0)
        o[axis] = 1
        ahead, _a = neighbour_potential(phi, kind, source, first, ijk + o, n, own)
        behind, _b = neighbour_potential(phi, kind, source, first, ijk - o, n, own)
        g[axis] = ahead - behind
    gradient[c] = g / (2.0 * cell_edge(boxes, row))


@wp.func
def read_cells_with_fluid(
    boxes: CoarseBoxes, row: int, x: wp.vec3, kind: wp.array[wp.int32], values: wp.array(dtype=Any), zero: Any
):
    """The trilinear sum of ``values`` over the 8 cell centres around ``x``, and the weight it took: a cell without
    fluid (a wall's) has no value, so the cells with fluid share its weight."""
    n = boxes.dims[row]
    s = position_in_cells(boxes, row, x)
    total = float(0.0)
    weighted = zero
    for k in range(8):
        local, w = trilinear_corner(s, n, k)
        c = boxes.first[row] + local
        if kind[c] != CELL_OUTSIDE:
            weighted += w * values[c]
            total += w
    return weighted, total


@wp.kernel
def move_by_coarse_gradient(
    fluid_particle: wp.array[wp.int32],
    slot_of_particle: wp.array[wp.int32],
    fluid_row: wp.array[wp.int32],
    boxes: CoarseBoxes,
    kind: wp.array[wp.int32],
    gradient: wp.array[wp.vec3],
    share: float,
    inv_dt: float,
    # outputs
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
):
    """``dx = share * grad phi`` at each fluid particle, added to its position and, over the substep, its velocity."""
    t = wp.tid()
    p = fluid_particle[t]
    x = particle_q[p]
    if not takes_part(slot_of_particle[p], x):
        return
    row = fluid_row[t]
    n = boxes.dims[row]
    if n[0] == 0:
        return
    dx, total = read_cells_with_fluid(boxes, row, x, kind, gradient, wp.vec3(0.0))
    if total <= 0.0:
        return
    dx = (share / total) * dx
    if wp.isfinite(dx):
        particle_q[p] = x + dx
        particle_qd[p] = particle_qd[p] + dx * inv_dt


@wp.kernel
def coarse_potential_at_particles(
    fluid_particle: wp.array[wp.int32],
    fluid_row: wp.array[wp.int32],
    boxes: CoarseBoxes,
    kind: wp.array[wp.int32],
    phi: wp.array[float],
    particle_q: wp.array[wp.vec3],
    # outputs
    potential: wp.array[float],
):
    """The last substep's potential at each fluid particle, read from the cells with fluid around it as the move
    reads their gradients (0 where none)."""
    t = wp.tid()
    p = fluid_particle[t]
    x = particle_q[p]
    row = fluid_row[t]
    n = boxes.dims[row]
    if n[0] == 0 or not wp.isfinite(x):
        return
    value, total = read_cells_with_fluid(boxes, row, x, kind, phi, float(0.0))
    if total > 0.0:
        potential[p] = value / total


@wp.kernel
def forget_coarse_potential(
    world_mask: wp.array[wp.bool],
    world_count: int,
    use_mask: int,
    # outputs
    level: wp.array[wp.int32],
):
    """A reset world's next substep starts its potential from zero (its last box no longer matches)."""
    row = wp.tid()
    world = row
    if row == world_count:
        world = -1
    if world_selected(world, world_mask, world_count, use_mask):
        level[row] = -1


def block_sizes(counts: np.ndarray, cells_filled_per_particle: float) -> np.ndarray:
    """Cells each world's block of the table holds: ``CELLS_PER_FILLED_CELL`` times those its fluid fills, and more."""
    filled = np.ceil(counts * cells_filled_per_particle).astype(np.int64)
    return np.where(counts > 0, CELLS_PER_FILLED_CELL * filled + SMALLEST_BLOCK, 0)


class CoarseCorrection:
    """The cells and passes of the coarse density correction of one fluid solve.

    Args:
        fluid_row: Row of each fluid particle (its world; the global world ``-1`` last), host array.
        world_count: Worlds of the model.
        rest_distance: Rest distance of the fluid [m].
        cell_spacings: Edge of a cell [rest distances].
        share: Share of the potential's gradient each substep moves the fluid by [dimensionless].
        device: Device of the fluid solve.
    """

    def __init__(
        self,
        fluid_row: np.ndarray,
        world_count: int,
        rest_distance: float,
        cell_spacings: float,
        share: float,
        device,
    ):
        self.world_count = int(world_count)
        self.base_cell = float(cell_spacings * rest_distance)
        self.rest_distance = float(rest_distance)
        self.share = float(share)
        rows = self.world_count + 1
        counts = np.bincount(fluid_row, minlength=rows)
        capacity = block_sizes(counts, 1.0 / cell_spacings**3)
        first = np.concatenate(([0], np.cumsum(capacity)[:-1]))
        self.cell_count = int(capacity.sum())
        bins = np.clip((counts + PARTICLES_PER_BIN - 1) // PARTICLES_PER_BIN, 1, BINS_PER_WORLD)
        bin_first = np.concatenate(([0], np.cumsum(bins)[:-1]))
        with wp.ScopedDevice(device):
            self.fluid_row = wp.array(fluid_row.astype(np.int32), dtype=wp.int32)
            self.row_first = wp.array(first.astype(np.int32), dtype=wp.int32)
            self.row_capacity = wp.array(capacity.astype(np.int32), dtype=wp.int32)
            self.cell_row = wp.array(np.repeat(np.arange(rows), capacity).astype(np.int32), dtype=wp.int32)
            self.bin_first = wp.array(bin_first.astype(np.int32), dtype=wp.int32)
            self.bin_count = wp.array(bins.astype(np.int32), dtype=wp.int32)
            total_bins = int(bins.sum())
            self.bin_lower = wp.full((total_bins, 3), NO_BOUND, dtype=wp.int32)
            self.bin_upper = wp.full((total_bins, 3), -NO_BOUND, dtype=wp.int32)
            #: each world's box this substep and the last (level -1: no box yet, the potential starts from zero)
            self.boxes, self.last = CoarseBoxes(), CoarseBoxes()
            for b in (self.boxes, self.last):
                b.first = self.row_first
                b.corner = wp.zeros(rows, dtype=wp.vec3i)
                b.dims = wp.zeros(rows, dtype=wp.vec3i)
                b.level = wp.full(rows, -1, dtype=wp.int32)
                b.base_cell = self.base_cell
            n = self.cell_count
            self.weight = wp.zeros(n, dtype=float)
            self.weighted_error = wp.zeros(n, dtype=float)
            self.room = wp.ones(n, dtype=float)
            self.kind = wp.zeros(n, dtype=wp.int32)
            self.source = wp.zeros(n, dtype=float)
            self.phi = wp.zeros(n, dtype=float)
            self.last_phi = wp.zeros(n, dtype=float)
            self.gradient = wp.zeros(n, dtype=wp.vec3)
        self.device = device

    def apply(
        self,
        fluid_particle: wp.array,
        slot_of_particle: wp.array,
        slot_particle: wp.array,
        slot_world: wp.array,
        wall_count: wp.array,
        wall_plane: wp.array,
        density: wp.array,
        rest_density: float,
        state_out,
        dt: float,
    ) -> None:
        """Move the fluid of ``state_out`` by the coarse correction of the substep's last density pass."""
        n, cells, d = fluid_particle.shape[0], self.cell_count, self.device
        q = state_out.particle_q
        rows = self.world_count + 1
        wp.launch(
            bound_fluid_cells,
            dim=n,
            inputs=[
                fluid_particle,
                slot_of_particle,
                q,
                self.fluid_row,
                self.bin_first,
                self.bin_count,
                1.0 / self.base_cell,
            ],
            outputs=[self.bin_lower, self.bin_upper],
            device=d,
        )
        wp.launch_tiled(
            place_coarse_cells,
            dim=[rows],
            inputs=[self.bin_first, self.bin_count, self.row_capacity],
            outputs=[self.bin_lower, self.bin_upper, self.boxes, self.last],
            block_dim=PLACE_BLOCK_DIM,
            device=d,
        )
        sums = [self.weight, self.weighted_error, self.room]
        wp.launch(
            spread_density_error,
            dim=n,
            inputs=[
                slot_particle,
                slot_world,
                q,
                self.world_count,
                density,
                1.0 / rest_density,
                self.boxes,
                wall_count,
                wall_plane,
            ],
            outputs=sums,
            device=d,
        )
        wp.launch(
            mark_coarse_cells,
            dim=cells,
            inputs=[self.cell_row, self.boxes, self.last, self.last_phi, self.rest_distance],
            outputs=[*sums, self.kind, self.source, self.phi],
            device=d,
        )
        for _ in range(SWEEPS):
            for colour in (0, 1):
                wp.launch(
                    relax_coarse_potential,
                    dim=cells,
                    inputs=[self.cell_row, self.boxes, self.kind, self.source, colour],
                    outputs=[self.phi],
                    device=d,
                )
        wp.launch(
            coarse_potential_gradient,
            dim=cells,
            inputs=[self.cell_row, self.boxes, self.kind, self.source, self.phi],
            outputs=[self.gradient, self.last_phi],
            device=d,
        )
        wp.launch(
            move_by_coarse_gradient,
            dim=n,
            inputs=[
                fluid_particle,
                slot_of_particle,
                self.fluid_row,
                self.boxes,
                self.kind,
                self.gradient,
                self.share,
                1.0 / dt,
            ],
            outputs=[q, state_out.particle_qd],
            device=d,
        )

    def potential_at(self, fluid_particle: wp.array, particle_q: wp.array) -> wp.array:
        """The last substep's potential [m^2] at each particle of ``particle_q`` (0 for particles not fluid)."""
        potential = wp.zeros(particle_q.shape[0], dtype=float, device=self.device)
        wp.launch(
            coarse_potential_at_particles,
            dim=fluid_particle.shape[0],
            inputs=[fluid_particle, self.fluid_row, self.boxes, self.kind, self.phi, particle_q],
            outputs=[potential],
            device=self.device,
        )
        return potential

    def forget(self, world_mask: wp.array, use_mask: int) -> None:
        """Start the potential of the worlds ``world_mask`` selects from zero at their next substep."""
        wp.launch(
            forget_coarse_potential,
            dim=self.world_count + 1,
            inputs=[world_mask, self.world_count, use_mask],
            outputs=[self.boxes.level],
            device=self.device,
        )


def warn_about_dynamic_shapes(model) -> None:
    """Warn when dynamic bodies' shapes meet the fluid: the cells do not hold them, and they float high."""
    if not model.shape_count:
        return
    touches = (model.shape_flags.numpy() & int(ShapeFlags.COLLIDE_PARTICLES)) != 0
    dynamic = int((touches & ~still_shapes(model)).sum())
    if dynamic:
        warnings.warn(
            f"fluid_coarse_correction with {dynamic} shapes of dynamic bodies that collide with particles: the "
            "coarse cells read the water by a dynamic body as free surface and move it into the body, so a floating "
            'body sits about 55 % high (docs/validation.rst, "Still water and floating bodies"); use '
            "fluid_coarse_correction=0 in such scenes",
            RuntimeWarning,
            stacklevel=5,
        )
