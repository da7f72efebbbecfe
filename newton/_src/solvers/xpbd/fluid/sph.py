# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The SPH side of the position-based fluid: parameters, slots, kernel functions and the neighbour loop.

All per-particle passes run over the fluid particles in *sorted slot* order (see
:mod:`.neighbors`): slot ``i`` holds particle ``slots.particle[i]`` (``-1`` for a slot
whose particle is inactive or non-finite), its neighbours are slots too, and the
current positions and masses of all slots are held in slot order in ``slots.xm``
(``xyz`` = position [m], ``w`` = mass [kg]) so that neighbour reads are coherent:
gathered by the build, or written by the correction pass of the iteration before
(:class:`~.density_constraint.ParticleApply`). :class:`FluidSlots` bundles these arrays, and
:func:`fluid_neighbor_layout` with :func:`fluid_neighbor` is how every pass walks a slot's neighbours;
:func:`neighbor_sum` makes the loop of a pass that sums one term over them.

Scalar parameters are read from a one-element :class:`FluidParams` array, not passed
by value, so that changing them between steps also changes a captured CUDA graph.

References:
    - M. Macklin, M. Müller. Position Based Fluids. ACM TOG 32(4), 2013.
    - M. Müller, D. Charypar, M. Gross. Particle-based fluid simulation for interactive
      applications. SCA 2003 (poly6 and spiky kernels).
    - N. Akinci, G. Akinci, M. Teschner. Versatile surface tension and adhesion for SPH
      fluids. ACM TOG 32(6), 2013 (cohesion spline).
"""

import enum
from typing import Any

import warp as wp

# approximate division and square root in CUDA code (Warp ignores it on the CPU): up to a few hundred
# thousand particles a pass takes as long as one thread's chain of dependent steps, and each pair's
# direction, mass share and kernel values put divisions and a root on it (100k dam break on an H100:
# 2.48 -> 2.31 ms per frame, the density errors the same to 0.01 %; docs/archive/performance_notebook.md)
wp.set_module_options({"fast_math": True})

# |r| below this fraction of h counts as coincident: the direction r/|r| is not usable there.
COINCIDENT_FRACTION = 1.0e-5


# FluidParams.max_displacement at and above this means no limit
MAX_DISPLACEMENT_OFF = 1.0e30


@wp.struct
class FluidParams:
    """Scalar parameters of the fluid solve, kept on the device (see :meth:`FluidSolver.update_params`)."""

    h: float  # smoothing length [m]
    h2: float
    poly6: float  # 315 / (64 pi h^9)
    spiky_grad: float  # -45 / (pi h^6)
    one_kernel_scale: float  # W(0) of the one kernel c (1 - r/h)^2.5, normalised on the rest lattice [1/m^3]
    one_kernel_slope: float  # 2.5 c / h: -dW/dr = one_kernel_slope (1 - r/h)^1.5 [1/m^4]
    rest_density: float  # of a particle of the reference mass [kg/m^3]
    inv_rest_density: float
    reference_mass: float  # mean fluid particle mass [kg]: the density sums count neighbours at this mass
    rest_distance: float  # [m]
    epsilon: float  # regulariser of the lambda denominator [1/m^2]
    relaxation: float
    closing_relaxation: float  # the relaxation of an odd count's last pass (calibration.CLOSING_PASS_SHARE)
    density_ramp: float  # compression over which the density constraint ramps in (0: it switches on at rest density)
    max_correction: float  # bound of one iteration's density correction [m]
    max_displacement: float  # bound of a fluid particle's travel in one substep [m]
    cohesion: float  # per-iteration cohesion displacement scale [m]
    cohesion_u0: float  # zero of Akinci's spline, as a fraction of h
    cohesion_in: float  # u0 / rest distance [1/m]
    cohesion_out: float  # (1 - u0) / (h - rest distance) [1/m]
    cohesion_gate: float  # under-density (1 - rho/rho0) of a pair at which its cohesion is full
    viscosity: float  # [0, 1]
    nonaffine_damping: (
        float  # share of a velocity's deviation from the kernel-scale affine field removed per 1/480 s [0, 1]
    )
    affine_regularizer: float  # added to the neighbourhood's position covariance of the affine fit [m^2]
    vorticity: float  # confinement strength [m/s]
    density_tolerance: float  # mean compression at which density sub-iterations stop
    warm_start: float  # share of a substep's summed multipliers that the next substep starts from (0: off)
    compression_damping: float  # share of the compression a substep's motion adds that its passes also remove
    wall_scale: float  # lattice density / rest density: converts the wall tables to constraint units
    wall_table_step: float  # wall distance between table samples [m]


@wp.struct
class FluidSlots:
    """The fluid particles in sorted slot order and their neighbour lists (see :mod:`.neighbors`)."""

    particle: wp.array[wp.int32]  # particle index of each slot, -1 for a left-out particle
    xm: wp.array[wp.vec4]  # gathered position [m] (xyz) and mass [kg] (w)
    neighbors: wp.array[wp.int32]  # neighbour slots, transposed: neighbors[row * slot_count + i]
    neighbor_count: wp.array[wp.int32]  # neighbours found by each lane of the scan: [lane * slot_count + i]
    capacity: int  # neighbours stored per slot, all lanes together (lanes * lane_capacity)
    lanes: int  # scan threads per slot (1, 2 or 3), each listing a part of the 27 cells
    lane_capacity: int  # list rows of each lane: lane l stores its finds in rows [l, l + 1) * lane_capacity
    wall_count: wp.array[wp.int32]  # static-wall contacts listed for the slot (may exceed WALL_CONTACTS_PER_SLOT)
    wall_plane: wp.array[wp.vec4]  # their planes, transposed: unit normal (xyz) and offset n . p [m] (w)


class SlotContent(enum.Enum):
    """What the current slot buffer (``slots.xm``, and ``sorted_v``) holds between the passes of a step."""

    #: out of date: a pass that reads positions gathers them first
    STALE = enum.auto()
    #: the positions the neighbourhood build gathered: a substep's first iteration uses them as they are
    BUILT = enum.auto()
    #: the positions SolverXPBD applied after the last iteration, written by its correction pass
    APPLIED = enum.auto()
    #: those positions, and in ``sorted_v`` the velocities it applied (the velocity pass gathers nothing)
    APPLIED_WITH_VELOCITIES = enum.auto()


@wp.func
def poly6(r2: float, p: FluidParams):
    """Poly6 kernel W(r) for ``r2 = |r|^2 < h^2`` [1/m^3]."""
    d = p.h2 - r2
    return p.poly6 * d * d * d


@wp.func
def one_kernel(q: float, p: FluidParams):
    """The one kernel ``W = c q^2.5`` at ``q = 1 - |r|/h`` in [0, 1] [1/m^3]."""
    return p.one_kernel_scale * q * q * wp.sqrt(q)


@wp.func
def one_kernel_slope(q: float, p: FluidParams):
    """``dW/d|r|`` of the one kernel at ``q = 1 - |r|/h`` in [0, 1]: ``-2.5 c / h q^1.5`` [1/m^4]."""
    return -p.one_kernel_slope * q * wp.sqrt(q)


@wp.func
def poly6_slope(dist: float, p: FluidParams):
    """``dW/d|r|`` of the poly6 kernel at ``|r| = dist`` < h: ``-6 c |r| (h^2 - |r|^2)^2`` [1/m^4]."""
    d = p.h2 - dist * dist
    return -6.0 * p.poly6 * dist * d * d


@wp.func
def spiky_slope(d: float, p: FluidParams):
    """``dW/d|r|`` of the spiky kernel at ``d = h - |r|`` in [0, h]: ``-45 / (pi h^6) d^2`` [1/m^4]."""
    return p.spiky_grad * d * d


@wp.func
def coincident_direction(pi: int, pj: int):
    """Deterministic unit direction for a coincident pair, antisymmetric in (pi, pj)."""
    lo = wp.min(pi, pj)
    hi = wp.max(pi, pj)
    state = wp.rand_init(lo * 1103515245 + 12345, hi)
    d = wp.sample_unit_sphere_surface(state)
    if pi > pj:
        d = -d
    return d


@wp.func
def pair_direction(r: wp.vec3, dist: float, pi: int, sorted_particle: wp.array[wp.int32], j: int, p: FluidParams):
    """``r / |r|``, or the deterministic direction of the pair (particle ``pi``, slot ``j``) if they coincide."""
    if dist < COINCIDENT_FRACTION * p.h:
        # the neighbour's particle index is only loaded in this rare branch
        return coincident_direction(pi, sorted_particle[j])
    return r / dist


@wp.func
def spiky_gradient(r: wp.vec3, r2: float, pi: int, sorted_particle: wp.array[wp.int32], j: int, p: FluidParams):
    """Gradient of the spiky kernel w.r.t. ``x_i`` for ``r = x_i - x_j`` (``j`` a slot) [1/m^4]."""
    dist = wp.sqrt(r2)
    n = pair_direction(r, dist, pi, sorted_particle, j, p)
    d = p.h - dist
    return n * spiky_slope(d, p)


@wp.func
def akinci_cohesion(dist: float, p: FluidParams):
    """Akinci's cohesion spline normalised to a peak of 1, its sign change moved to the rest distance.

    With ``u`` the spline argument over ``h``, ``c(u) = 64 (1-u)^3 u^3`` for ``u > 1/2`` and
    ``128 (1-u)^3 u^3 - 1`` below; ``u`` is remapped piecewise linearly from the distance so that
    the rest distance lands on the spline's own zero ``u0`` and ``h`` on 1: pairs closer than the
    rest distance repel, pairs between rest distance and ``h`` attract. Positive means attraction.
    """
    if dist < p.rest_distance:
        u = dist * p.cohesion_in
    else:
        u = p.cohesion_u0 + (dist - p.rest_distance) * p.cohesion_out
    a = (1.0 - u) * u
    a3 = a * a * a
    if u > 0.5:
        return 64.0 * a3
    return 128.0 * a3 - 1.0


@wp.func
def fluid_neighbor_layout(slots: FluidSlots, i: int):
    """Where slot ``i``'s stored neighbours end, lane by lane: ``(lane 0, lanes 0-1, all)``.

    ``layout[2]`` is the number of stored neighbours; pass the layout to :func:`fluid_neighbor`.
    """
    n = slots.particle.shape[0]
    cap = slots.lane_capacity
    end0 = wp.min(slots.neighbor_count[i], cap)
    end1 = end0
    if slots.lanes > 1:
        end1 += wp.min(slots.neighbor_count[n + i], cap)
    end2 = end1
    if slots.lanes > 2:
        end2 += wp.min(slots.neighbor_count[2 * n + i], cap)
    return wp.vec3i(end0, end1, end2)


@wp.func
def fluid_neighbor(slots: FluidSlots, i: int, k: int, layout: wp.vec3i):
    """Slot of the ``k``-th neighbour of slot ``i`` (``k < layout[2]``; see :func:`fluid_neighbor_layout`).

    The lanes' finds are read one lane after the other, so ``k`` runs through the 27 cells in the
    same order whatever the number of lanes. Lists are stored transposed for coalescing.
    """
    cap = slots.lane_capacity
    row = k + wp.where(k >= layout[0], cap - layout[0], 0) + wp.where(k >= layout[1], cap + layout[0] - layout[1], 0)
    return slots.neighbors[row * slots.particle.shape[0] + i]


def neighbor_sum(term, pairwise: bool = False):
    """A ``wp.func`` ``(slots, i, me, p, zero)`` summing ``term(slots, j, me, p)`` over the neighbours ``j`` of slot ``i``.

    ``me`` is what the term needs of slot ``i`` (a struct of the pass), ``zero`` the sum's starting value
    and type. Two neighbours per trip: their loads are independent and overlap (kept over one per trip;
    four gain nothing: docs/archive/performance_notebook.md). With ``pairwise`` a trip's two terms are
    added together before they join the sum, else one after the other (each pass keeps the order, and
    so the rounding, it has always had). Each term gets its own function, named after it, so that two
    sums in one module do not overload each other.
    """

    def sum_over_neighbors(slots: FluidSlots, i: int, me: Any, p: FluidParams, zero: Any):
        layout = fluid_neighbor_layout(slots, i)
        count = layout[2]
        acc = zero
        k = int(0)
        while k + 1 < count:
            j0 = fluid_neighbor(slots, i, k, layout)
            j1 = fluid_neighbor(slots, i, k + 1, layout)
            if wp.static(pairwise):
                acc += wp.static(term)(slots, j0, me, p) + wp.static(term)(slots, j1, me, p)
            else:
                acc += wp.static(term)(slots, j0, me, p)
                acc += wp.static(term)(slots, j1, me, p)
            k += 2
        if k < count:
            acc += wp.static(term)(slots, fluid_neighbor(slots, i, k, layout), me, p)
        return acc

    sum_over_neighbors.__name__ = sum_over_neighbors.__qualname__ = f"sum_over_neighbors_of_{term.key}"
    sum_over_neighbors.__module__ = term.func.__module__
    return wp.func(sum_over_neighbors)


@wp.func
def pair_share(xi4: wp.vec4, xj4: wp.vec4):
    """Mass weight ``2 m_j / (m_i + m_j)`` of a pair's correction (1 for equal masses).

    It keeps the pair's momentum: the lighter particle gives way, which is what makes a heavier
    fluid sink.
    """
    return 2.0 * xj4[3] / (xi4[3] + xj4[3])
