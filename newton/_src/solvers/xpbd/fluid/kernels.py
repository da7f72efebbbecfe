# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Warp kernels of the position-based fluid (PBF) solve.

All per-particle passes run over the fluid particles in *sorted slot* order (see
:mod:`.neighbors`): slot ``i`` holds particle ``slots.particle[i]`` (``-1`` for a slot
whose particle is inactive or non-finite), its neighbours are slots too, and the
current positions and masses of all slots are held in slot order in ``slots.xm``
(``xyz`` = position [m], ``w`` = mass [kg]) so that neighbour reads are coherent:
gathered by the build, or written by the correction pass of the iteration before
(:class:`ParticleApply`). :class:`FluidSlots` bundles these arrays.

Scalar parameters are read from a one-element :class:`FluidParams` array, not passed
by value, so that changing them between steps also changes a captured CUDA graph.

References:
    - M. Macklin, M. Müller. Position Based Fluids. ACM TOG 32(4), 2013.
    - M. Müller, D. Charypar, M. Gross. Particle-based fluid simulation for interactive
      applications. SCA 2003 (poly6 and spiky kernels).
    - N. Akinci, G. Akinci, M. Teschner. Versatile surface tension and adhesion for SPH
      fluids. ACM TOG 32(6), 2013 (cohesion spline).
"""

import warp as wp

from ....geometry import ParticleFlags
from ....sim.enums import BodyFlags

# approximate division and square root in CUDA code (Warp ignores it on the CPU): up to a few hundred
# thousand particles a pass takes as long as one thread's chain of dependent steps, and each pair's
# direction, mass share and kernel values put divisions and a root on it (100k dam break on an H100:
# 2.48 -> 2.31 ms per frame, the density errors the same to 0.01 %; docs/performance.md)
wp.set_module_options({"fast_math": True})

# |r| below this fraction of h counts as coincident: the direction r/|r| is not usable there.
COINCIDENT_FRACTION = 1.0e-5
# bins of the compression sum of density sub-iterations: spreads the atomics over several addresses
COMPRESSION_BINS = wp.constant(64)
# a particle compressed by more than this (of rho/rho0 - 1) in a substep's last density pass is counted, and
# the peak kept, on the device until the next fluid_diagnostics reports it (healthy flows stay well below)
PEAK_COMPRESSION = wp.constant(0.1)
# the bins' compression sums, then their particle counts
COMPRESSION_SUMS = wp.constant(128)
# ParticleApply.on: the correction pass writes the position SolverXPBD will apply, or the position
# moved by the pass's correction (density sub-passes)
APPLY_AS_XPBD = wp.constant(1)
APPLY_ADVANCE = wp.constant(2)

# FluidParams.max_displacement at and above this means no limit
MAX_DISPLACEMENT_OFF = 1.0e30
# static-wall contacts whose ghost density a fluid particle can take (more are left out of its density;
# a particle in the corner of a box tank has three)
WALL_CONTACTS_PER_SLOT = 4


@wp.struct
class FluidParams:
    """Scalar parameters of the fluid solve, kept on the device (see :meth:`FluidSolver.update_params`)."""

    h: float  # smoothing length [m]
    h2: float
    poly6: float  # 315 / (64 pi h^9)
    spiky_grad: float  # -45 / (pi h^6)
    rest_density: float  # of a particle of the reference mass [kg/m^3]
    inv_rest_density: float
    reference_mass: float  # mean fluid particle mass [kg]: the density sums count neighbours at this mass
    rest_distance: float  # [m]
    epsilon: float  # regulariser of the lambda denominator [1/m^2]
    relaxation: float
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


@wp.func
def poly6(r2: float, p: FluidParams):
    """Poly6 kernel W(r) for ``r2 = |r|^2 < h^2`` [1/m^3]."""
    d = p.h2 - r2
    return p.poly6 * d * d * d


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
    return n * (p.spiky_grad * d * d)


@wp.func
def density_constraint_lambda(rho: float, grad_i: wp.vec3, grad_sq: float, p: FluidParams):
    """Jacobi multiplier of the unilateral density constraint ``C = max(rho / rho0 - 1, 0)``.

    With ``density_ramp`` d > 0 the multiplier is that of ``C^2 / (2 d)`` below d and of ``C - d / 2``
    above (continuous, and so is its slope): particles near rest density, which switch a constraint
    with a kink on and off from substep to substep, take it in gradually, and fluid at rest stops
    humming, for d / 2 more compression where it carries a load (docs/validation.md, "Hydrostatics").
    """
    c = wp.max(rho * p.inv_rest_density - 1.0, 0.0)
    d = p.density_ramp
    if c < d:
        c = c * c / (2.0 * d)
    else:
        c = c - 0.5 * d
    return -c / (grad_sq + wp.dot(grad_i, grad_i) + p.epsilon)


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


@wp.func
def density_term(xi: wp.vec3, xj4: wp.vec4, pi: int, sorted_particle: wp.array[wp.int32], j: int, p: FluidParams):
    """Neighbour ``j``'s share of slot ``i``'s constraint: ``(grad C_i w.r.t. x_j, m W_ij)``, zero beyond ``h``.

    ``m`` is the reference mass, not ``m_j``: the constraint is on the number density, so that a
    particle's rest density is in proportion to its own mass and fluids of different density mix.
    """
    r = xi - wp.vec3(xj4[0], xj4[1], xj4[2])
    r2 = wp.dot(r, r)
    if r2 >= p.h2:
        return wp.vec4(0.0)
    g = spiky_gradient(r, r2, pi, sorted_particle, j, p) * (p.reference_mass * p.inv_rest_density)
    return wp.vec4(g[0], g[1], g[2], p.reference_mass * poly6(r2, p))


@wp.func
def pair_share(xi4: wp.vec4, xj4: wp.vec4):
    """Mass weight ``2 m_j / (m_i + m_j)`` of a pair's correction (1 for equal masses).

    It keeps the pair's momentum: the lighter particle gives way, which is what makes a heavier
    fluid sink.
    """
    return 2.0 * xj4[3] / (xi4[3] + xj4[3])


@wp.func
def cohesion_weight(rel_i: float, rel_j: float, p: FluidParams):
    """Share of the cohesion a pair takes, from the pair's relative densities ``rho / rho0``.

    Full where the pair is under-dense by ``cohesion_gate`` or more, none at or above rest density:
    where the fluid is at rest density the density constraint holds it together, and cohesion
    there would only compress it (the unilateral constraint pushes back only once compressed).
    """
    if p.cohesion <= 0.0:
        return 0.0
    under = 1.0 - 0.5 * (rel_i + rel_j)
    return wp.clamp(under / p.cohesion_gate, 0.0, 1.0)


@wp.func
def correction_term(
    xi4: wp.vec4,
    lam_i: float,
    xj4: wp.vec4,
    lam_j: float,
    pi: int,
    sorted_particle: wp.array[wp.int32],
    j: int,
    p: FluidParams,
    cohesion: float,
):
    """Neighbour ``j``'s density correction (top) and its cohesion pull (bottom) on slot ``i``.

    The pull is weighted by ``cohesion`` (the pair's share, :func:`cohesion_weight`) and not yet scaled
    by the strength. It is evaluated for every pair while cohesion is on, also where the share is 0:
    a branch on the share diverges within a warp (measured 0.01 ms per frame slower at 100k, 0.05 ms at 1M).
    """
    r = wp.vec3(xi4[0] - xj4[0], xi4[1] - xj4[1], xi4[2] - xj4[2])
    r2 = wp.dot(r, r)
    if r2 >= p.h2:
        return wp.spatial_vector(wp.vec3(0.0), wp.vec3(0.0))
    dist = wp.sqrt(r2)
    n = pair_direction(r, dist, pi, sorted_particle, j, p)
    d = p.h - dist
    share = pair_share(xi4, xj4)
    dx = n * (p.spiky_grad * d * d * (lam_i + lam_j) * p.reference_mass * p.inv_rest_density * share)
    coh = wp.vec3(0.0)
    if p.cohesion > 0.0:
        coh = n * (-share * cohesion * akinci_cohesion(dist, p))
    return wp.spatial_vector(dx, coh)


@wp.kernel
def gather_fluid_positions(
    slots: FluidSlots,
    active: wp.array[wp.int32],
    particle_q: wp.array[wp.vec3],
    particle_mass: wp.array[float],
):
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0 or active[0] == 0:
        return
    x = particle_q[pi]
    slots.xm[i] = wp.vec4(x[0], x[1], x[2], particle_mass[pi])


@wp.func
def velocity_pass_on(p: FluidParams):
    """Whether the velocity pass runs: for viscosity, the non-affine damping, or the vorticity estimate of confinement."""
    return p.viscosity > 0.0 or p.nonaffine_damping > 0.0 or p.vorticity > 0.0


@wp.kernel
def gather_fluid_state(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    particle_mass: wp.array[float],
    for_velocity_pass: int,
    # outputs
    sorted_v: wp.array[wp.vec3],
):
    """Gather positions, masses and velocities into slot order (for the velocity pass: only if it runs)."""
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0:
        return
    if for_velocity_pass != 0 and not velocity_pass_on(params[0]):
        return
    x = particle_q[pi]
    slots.xm[i] = wp.vec4(x[0], x[1], x[2], particle_mass[pi])
    sorted_v[i] = particle_qd[pi]


@wp.func
def plane_after(a: wp.vec4, b: wp.vec4):
    """Whether plane ``a`` comes after ``b`` in the order (offset, normal x, y, z)."""
    if a[3] != b[3]:
        return a[3] > b[3]
    if a[0] != b[0]:
        return a[0] > b[0]
    if a[1] != b[1]:
        return a[1] > b[1]
    return a[2] > b[2]


@wp.func
def fluid_wall_share(
    slots: FluidSlots,
    i: int,
    x: wp.vec3,
    p: FluidParams,
    wall_table: wp.array[float],
    wall_table_grad: wp.array[float],
):
    """The static walls' share of slot ``i``'s ``rho / rho0`` at ``x`` (``w``) and its gradient (``xyz``).

    The fluid would continue beyond a wall as a lattice at rest; the tables hold that ghost fluid's
    poly6 density (over the lattice density) and its derivative against the distance from the
    particle centre to the wall plane. Without it a particle by a wall misses neighbours and packs
    closer than the rest distance before the constraint acts. The walls are the planes listed for
    the slot from the step's contacts (:func:`list_wall_contact`), added in the order of
    :func:`plane_after` (equal planes at once): the contacts arrive in any order on a GPU, and the
    sum of three or more floats depends on its order.
    """
    n = slots.particle.shape[0]
    count = wp.min(slots.wall_count[i], WALL_CONTACTS_PER_SLOT)
    share = wp.vec4(0.0)
    last = wp.vec4(0.0)
    for t in range(count):
        # the next plane after the last one added, and how often it is listed
        found = int(0)
        plane = wp.vec4(0.0)
        for e in range(count):
            q = slots.wall_plane[e * n + i]
            if t > 0 and not plane_after(q, last):
                continue
            if found == 0 or plane_after(plane, q):
                plane = q
                found = 1
            elif q == plane:
                found += 1
        if found == 0:
            break
        last = plane
        normal = wp.vec3(plane[0], plane[1], plane[2])
        dist = wp.max(wp.dot(normal, x) - plane[3], 0.0)
        if dist < p.h:
            u = dist / p.wall_table_step
            j = wp.min(int(u), wall_table.shape[0] - 2)
            f = u - float(j)
            c = (wall_table[j] * (1.0 - f) + wall_table[j + 1] * f) * p.wall_scale
            dc = (wall_table_grad[j] * (1.0 - f) + wall_table_grad[j + 1] * f) * p.wall_scale
            share += wp.vec4(normal[0] * dc, normal[1] * dc, normal[2] * dc, c) * float(found)
    return share


@wp.struct
class FluidWallContacts:
    """The particle-shape contacts a neighbour build lists as walls (``contact_max`` 0: none)."""

    count: wp.array[int]  # contacts found (one element)
    particle: wp.array[int]
    shape: wp.array[int]
    point: wp.array[wp.vec3]  # contact point on the shape, in its body's frame (static: world) [m]
    normal: wp.array[wp.vec3]  # world frame
    contact_max: int
    shape_body: wp.array[int]  # body of each shape, -1 for a static one
    body_q: wp.array[wp.transform]  # body poses of the step (kinematic bodies keep theirs through it)
    body_flags: wp.array[wp.int32]


@wp.func
def list_wall_contact(k: int, walls: FluidWallContacts, slot_of_particle: wp.array[wp.int32], slots: FluidSlots):
    """List particle-shape contact ``k`` as a wall of its particle's slot, if its shape is static or kinematic.

    Once per step, after the build cleared the slots' counts. A wall lends the density of the fluid
    missing behind it, and pushes the fluid with it: a dynamic body would have to take the reaction,
    so only static shapes and those of kinematic bodies (which take none: they move as prescribed)
    lend density. A kinematic wall is placed where its body is during the step.
    """
    if k >= wp.min(walls.count[0], walls.contact_max):
        return
    slot = slot_of_particle[walls.particle[k]]
    if slot < 0:
        return
    body = walls.shape_body[walls.shape[k]]
    point = walls.point[k]
    if body >= 0:
        if (walls.body_flags[body] & int(BodyFlags.KINEMATIC)) == 0:
            return
        point = wp.transform_point(walls.body_q[body], point)
    t = wp.atomic_add(slots.wall_count, slot, 1)
    if t < WALL_CONTACTS_PER_SLOT:
        normal = walls.normal[k]
        plane = wp.vec4(normal[0], normal[1], normal[2], wp.dot(normal, point))
        slots.wall_plane[t * slots.particle.shape[0] + slot] = plane


@wp.kernel
def compute_fluid_density_lambda(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    active: wp.array[wp.int32],
    wall_table: wp.array[float],
    wall_table_grad: wp.array[float],
    track_compression: int,
    track_peaks: int,
    # outputs
    density: wp.array[float],
    lambda_rho: wp.array[wp.vec2],
    wall_grad: wp.array[wp.vec3],
    compression_bins: wp.array[float],
    peaks: wp.array[float],
):
    """Poly6 density and the Jacobi multiplier of the unilateral constraint C = max(rho/rho0 - 1, 0).

    The static walls listed for the slot add their share of ``rho / rho0`` (:func:`fluid_wall_share`);
    its gradient is kept in ``wall_grad`` for the correction. Does nothing while ``active[0]`` is 0.
    With ``track_compression``, also sums max(rho/rho0 - 1, 0) into ``compression_bins[0, B)`` and
    counts the particles in ``[B, 2B)`` (``B = COMPRESSION_BINS``, spreading the atomics). With
    ``track_peaks`` (a substep's last pass), counts the particles compressed by more than
    ``PEAK_COMPRESSION`` into ``peaks[0, B)`` and keeps their largest compression in ``peaks[B, 2B)``,
    until :meth:`~.solver_fluid.FluidSolver.diagnostics` reads and clears them.
    """
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0 or active[0] == 0:
        return
    p = params[0]
    xi4 = slots.xm[i]
    xi = wp.vec3(xi4[0], xi4[1], xi4[2])
    rho = p.reference_mass * poly6(0.0, p)
    grad_i = wp.vec3(0.0)
    grad_sq = float(0.0)
    layout = fluid_neighbor_layout(slots, i)
    count = layout[2]
    # two neighbours per trip: their loads are independent and overlap
    k = int(0)
    while k + 1 < count:
        j0 = fluid_neighbor(slots, i, k, layout)
        j1 = fluid_neighbor(slots, i, k + 1, layout)
        t0 = density_term(xi, slots.xm[j0], pi, slots.particle, j0, p)
        t1 = density_term(xi, slots.xm[j1], pi, slots.particle, j1, p)
        g0 = wp.vec3(t0[0], t0[1], t0[2])
        g1 = wp.vec3(t1[0], t1[1], t1[2])
        rho += t0[3] + t1[3]
        grad_i += g0 + g1
        grad_sq += wp.dot(g0, g0) + wp.dot(g1, g1)
        k += 2
    if k < count:
        j = fluid_neighbor(slots, i, k, layout)
        t = density_term(xi, slots.xm[j], pi, slots.particle, j, p)
        g = wp.vec3(t[0], t[1], t[2])
        rho += t[3]
        grad_i += g
        grad_sq += wp.dot(g, g)
    # the walls do not move: their gradient only adds to the particle's own
    wall = fluid_wall_share(slots, i, xi, p, wall_table, wall_table_grad)
    wall_g = wp.vec3(wall[0], wall[1], wall[2])
    rho += wall[3] * p.rest_density
    grad_i += wall_g
    wall_grad[i] = wall_g
    density[i] = rho
    # the multiplier and the relative density, which the correction reads for each neighbour
    lambda_rho[i] = wp.vec2(density_constraint_lambda(rho, grad_i, grad_sq, p), rho * p.inv_rest_density)
    if track_compression != 0:
        b = i % COMPRESSION_BINS
        wp.atomic_add(compression_bins, b, wp.max(rho * p.inv_rest_density - 1.0, 0.0))
        wp.atomic_add(compression_bins, COMPRESSION_BINS + b, 1.0)
    if track_peaks != 0:
        c = rho * p.inv_rest_density - 1.0
        if c > PEAK_COMPRESSION:
            b = i % COMPRESSION_BINS
            wp.atomic_add(peaks, b, 1.0)
            wp.atomic_max(peaks, COMPRESSION_BINS + b, c)


@wp.func
def relaxed_correction(dx: wp.vec3, p: FluidParams):
    """A density correction scaled by ``fluid_relaxation`` and bounded to ``max_correction`` per pass."""
    dx *= p.relaxation
    dx_len = wp.length(dx)
    if dx_len > p.max_correction:
        dx *= p.max_correction / dx_len
    return dx


@wp.struct
class ParticleApply:
    """Where the correction pass writes each fluid particle's corrected position (besides its delta).

    ``on`` = 1 (``APPLY_AS_XPBD``): the position and velocity after ``SolverXPBD`` applies the iteration's
    deltas with its ``apply_particle_deltas`` (same formula: ``x = x_pred + delta``,
    ``v = (x - x_start) / dt``, ``v`` bounded to ``v_max`` and ``x`` moved back with it), in slot
    order, so the next iteration and the viscosity pass need not gather them. ``on`` = 2
    (``APPLY_ADVANCE``): the slot's position moved by this pass's correction, for the next density
    sub-pass (only ``xm`` is used). 0: nothing.
    """

    on: int
    x_pred: wp.array[wp.vec3]  # positions the deltas are applied to [m]
    x_start: wp.array[wp.vec3]  # positions at the start of the substep [m]
    dt: float  # [s]
    v_max: float  # [m/s]
    xm: wp.array[wp.vec4]  # output: the applied positions [m] and masses [kg], in slot order
    v: wp.array[wp.vec3]  # output: the applied velocities [m/s], in slot order


@wp.func
def applied_particle(apply: ParticleApply, pi: int, delta: wp.vec3):
    """Position and velocity of particle ``pi`` once ``SolverXPBD`` applies ``delta`` (see :class:`ParticleApply`)."""
    x0 = apply.x_start[pi]
    x = apply.x_pred[pi] + delta
    v = (x - x0) / apply.dt
    speed = wp.length(v)
    if speed > apply.v_max:
        v *= apply.v_max / speed
        x = x0 + v * apply.dt
    return x, v


@wp.kernel
def applied_particles(apply: ParticleApply, particle_deltas: wp.array[wp.vec3]):
    """:func:`applied_particle` of every particle, in particle order (the seam's check of upstream's formula)."""
    i = wp.tid()
    x, v = applied_particle(apply, i, particle_deltas[i])
    apply.xm[i] = wp.vec4(x[0], x[1], x[2], 0.0)
    apply.v[i] = v


@wp.kernel
def apply_fluid_density_correction(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    active: wp.array[wp.int32],
    lambda_rho: wp.array[wp.vec2],
    particle_inv_mass: wp.array[float],
    wall_grad: wp.array[wp.vec3],
    apply: ParticleApply,
    store_warm: int,
    # outputs
    particle_deltas: wp.array[wp.vec3],
    lambda_sum: wp.array[float],
    particle_lambda: wp.array[float],
):
    """Add the density correction and the cohesion bias of slot ``i`` to its particle's Jacobi delta.

    Each pair takes the share of the cohesion :func:`cohesion_weight` gives it.

    ``wall_grad`` is the walls' gradient of the density pass before it. With ``apply.on``, the
    corrected position goes to ``apply.xm`` (see :class:`ParticleApply`). With the warm start, the
    multiplier is added to the substep's sum ``lambda_sum``; with ``store_warm`` (the substep's last
    correction), ``warm_start`` times that sum is kept in ``particle_lambda`` for the next substep
    (as :func:`store_fluid_warm_start` does, without a pass of its own).
    """
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0 or active[0] == 0:
        return
    xi4 = slots.xm[i]
    p = params[0]
    if particle_inv_mass[pi] == 0.0:
        if store_warm != 0 and p.warm_start > 0.0:
            particle_lambda[pi] = p.warm_start * lambda_sum[i]
        if apply.on == APPLY_AS_XPBD:
            x, v = applied_particle(apply, pi, particle_deltas[pi])
            apply.xm[i] = wp.vec4(x[0], x[1], x[2], xi4[3])
            apply.v[i] = v
        elif apply.on == APPLY_ADVANCE:
            apply.xm[i] = xi4
        return
    lr_i = lambda_rho[i]
    lam_i = lr_i[0]
    rel_i = lr_i[1]
    wall_g = wall_grad[i]
    acc = wp.spatial_vector(wp.vec3(0.0), wp.vec3(0.0))
    layout = fluid_neighbor_layout(slots, i)
    count = layout[2]
    # two neighbours per trip: their loads are independent and overlap
    k = int(0)
    while k + 1 < count:
        j0 = fluid_neighbor(slots, i, k, layout)
        j1 = fluid_neighbor(slots, i, k + 1, layout)
        lr0 = lambda_rho[j0]
        lr1 = lambda_rho[j1]
        c0 = cohesion_weight(rel_i, lr0[1], p)
        c1 = cohesion_weight(rel_i, lr1[1], p)
        acc += correction_term(xi4, lam_i, slots.xm[j0], lr0[0], pi, slots.particle, j0, p, c0)
        acc += correction_term(xi4, lam_i, slots.xm[j1], lr1[0], pi, slots.particle, j1, p, c1)
        k += 2
    if k < count:
        j = fluid_neighbor(slots, i, k, layout)
        lr = lambda_rho[j]
        c = cohesion_weight(rel_i, lr[1], p)
        acc += correction_term(xi4, lam_i, slots.xm[j], lr[0], pi, slots.particle, j, p, c)
    dx = wp.spatial_top(acc) + wall_g * lam_i
    coh = wp.spatial_bottom(acc)
    dx = relaxed_correction(dx, p)
    if p.cohesion > 0.0:
        # the bias is bounded so a crowded neighbourhood cannot pull harder than one rest spacing allows
        coh *= p.cohesion
        coh_len = wp.length(coh)
        coh_max = 4.0 * p.cohesion
        if coh_len > coh_max:
            coh *= coh_max / coh_len
        dx += coh
    delta = particle_deltas[pi] + dx
    particle_deltas[pi] = delta
    if p.warm_start > 0.0:
        lam_sum = lambda_sum[i] + lam_i
        lambda_sum[i] = lam_sum
        if store_warm != 0:
            particle_lambda[pi] = p.warm_start * lam_sum
    if apply.on == APPLY_AS_XPBD:
        x, v = applied_particle(apply, pi, delta)
        apply.xm[i] = wp.vec4(x[0], x[1], x[2], xi4[3])
        apply.v[i] = v
    elif apply.on == APPLY_ADVANCE:
        apply.xm[i] = wp.vec4(xi4[0] + dx[0], xi4[1] + dx[1], xi4[2] + dx[2], xi4[3])


@wp.kernel
def apply_fluid_warm_start(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    active: wp.array[wp.int32],
    warm_lambda: wp.array[float],
    particle_inv_mass: wp.array[float],
    wall_table: wp.array[float],
    wall_table_grad: wp.array[float],
    # outputs
    particle_deltas: wp.array[wp.vec3],
    moved_xm: wp.array[wp.vec4],
    lambda_sum: wp.array[float],
):
    """Start the substep's density solve from the multipliers of the last one (warm start).

    Moves slot ``i`` by the correction of the carried multipliers ``warm_lambda`` (gathered into slot
    order by the sort, :meth:`~.neighbors.FluidNeighborSearch.carry_values`; as
    :func:`apply_fluid_density_correction` does with fresh ones, without cohesion) before the first
    density evaluation, writing the moved position to ``moved_xm`` (the other position buffer: the
    neighbours' positions are read from ``slots.xm`` meanwhile): a load the fluid carried last
    substep, like the weight of a deep column, is already held when the iterations start, which then
    only correct what changed. Starts the substep's sum of multipliers from the carried one.
    """
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0:
        return
    xi4 = slots.xm[i]
    lam_i = warm_lambda[i]
    lambda_sum[i] = lam_i
    p = params[0]
    if active[0] == 0 or p.warm_start <= 0.0 or particle_inv_mass[pi] == 0.0:
        moved_xm[i] = xi4
        return
    xi = wp.vec3(xi4[0], xi4[1], xi4[2])
    wall = fluid_wall_share(slots, i, xi, p, wall_table, wall_table_grad)
    dx = wp.vec3(wall[0], wall[1], wall[2]) * lam_i
    layout = fluid_neighbor_layout(slots, i)
    count = layout[2]
    for k in range(count):
        j = fluid_neighbor(slots, i, k, layout)
        # the multipliers alone: no cohesion
        dx += wp.spatial_top(correction_term(xi4, lam_i, slots.xm[j], warm_lambda[j], pi, slots.particle, j, p, 0.0))
    dx = relaxed_correction(dx, p)
    particle_deltas[pi] = particle_deltas[pi] + dx
    moved_xm[i] = wp.vec4(xi[0] + dx[0], xi[1] + dx[1], xi[2] + dx[2], xi4[3])


@wp.kernel
def store_fluid_warm_start(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    lambda_sum: wp.array[float],
    # outputs
    particle_lambda: wp.array[float],
):
    """Keep ``warm_start`` times each particle's multipliers of this substep for the next one.

    For the tolerance modes, whose last correction is decided on the device; with fixed counts the
    last correction pass stores them itself. A particle left out of this substep's solve (inactive,
    non-finite) carries nothing: the sort set its value to 0.
    """
    i = wp.tid()
    p = params[0]
    if p.warm_start <= 0.0:
        return
    pi = slots.particle[i]
    if pi < 0:
        return
    particle_lambda[pi] = p.warm_start * lambda_sum[i]


@wp.func
def affine_velocity_at_particle(s0: float, sx: wp.vec3, sv: wp.vec3, sxx: wp.mat33, svx: wp.mat33, p: FluidParams):
    """Velocity at the particle of the affine field ``v(x) = v_bar + A (x - x_bar)`` fitted to its neighbourhood.

    The moments are weighted sums over the neighbourhood (the particle included) of 1, the offsets
    ``r_j = x_j - x_i``, the velocities, ``r_j r_j^T`` and ``v_j r_j^T``. ``A`` is the weighted
    least-squares velocity gradient ``C_vx (C_xx + eps I)^-1`` (moving least squares of first order),
    so the field reproduces any uniform, rotating, shearing or expanding motion exactly; ``eps`` keeps a
    flat or thin neighbourhood (a surface, a filament) from amplifying noise.
    """
    inv = 1.0 / s0
    x_bar = sx * inv
    v_bar = sv * inv
    c_xx = sxx * inv - wp.outer(x_bar, x_bar) + wp.identity(n=3, dtype=float) * p.affine_regularizer
    c_vx = svx * inv - wp.outer(v_bar, x_bar)
    grad_v = c_vx * wp.inverse(c_xx)
    # the particle sits at r = 0
    return v_bar - grad_v * x_bar


@wp.kernel
def apply_fluid_viscosity(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    sorted_v: wp.array[wp.vec3],
    density: wp.array[float],
    damping_steps: float,
    # outputs
    particle_qd: wp.array[wp.vec3],
    vorticity: wp.array[wp.vec3],
):
    """The substep's velocity pass: XSPH viscosity, non-affine damping and the vorticity estimate, in one loop.

    Viscosity blends each velocity toward the mass- and density-weighted (Shepard) neighbourhood
    velocity: ``v_i <- v_i + nu (sum_j V_j W_ij v_j / sum_j V_j W_ij - v_i)`` with ``V_j = m_j / rho_j``,
    the sums including ``j = i``. The non-affine damping removes the share ``beta`` of the velocity's
    deviation from the affine field fitted to the neighbourhood with the same weights
    (:func:`affine_velocity_at_particle`): ``v_i <- v_i + beta (v_aff(x_i) - v_i)``, where a substep of
    ``damping_steps`` reference steps (``NONAFFINE_DAMPING_STEP``) takes ``beta = 1 - (1 - damping)^steps``:
    the damping per second does not depend on the substep count. Motion the kernel
    resolves (translation, rotation, shear, expansion across ``h``) is left alone; what goes is the
    particle-scale jitter no smooth field carries. Both act on the velocities of the step's result.
    With vorticity confinement on, the same loop also estimates the vorticity
    ``omega_i = sum_j V_j (v_j - v_i) x grad W_ij`` for the confinement pass.
    """
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0:
        return
    p = params[0]
    # checked here rather than by a conditional graph node, which costs more than this launch
    if not velocity_pass_on(p):
        return
    compute_vorticity = p.vorticity > 0.0
    fit_affine = p.nonaffine_damping > 0.0
    xi4 = slots.xm[i]
    xi = wp.vec3(xi4[0], xi4[1], xi4[2])
    vi = sorted_v[i]
    w_self = xi4[3] / wp.max(density[i], 1.0e-6) * poly6(0.0, p)
    num = vi * w_self
    den = w_self
    sx = wp.vec3(0.0)
    sxx = wp.mat33(0.0)
    svx = wp.mat33(0.0)
    omega = wp.vec3(0.0)
    layout = fluid_neighbor_layout(slots, i)
    count = layout[2]
    for k in range(count):
        j = fluid_neighbor(slots, i, k, layout)
        xj4 = slots.xm[j]
        r = xi - wp.vec3(xj4[0], xj4[1], xj4[2])
        r2 = wp.dot(r, r)
        if r2 < p.h2:
            vol_j = xj4[3] / wp.max(density[j], 1.0e-6)
            w = vol_j * poly6(r2, p)
            vj = sorted_v[j]
            num += vj * w
            den += w
            if fit_affine:
                # offsets from the particle to its neighbour
                sx -= r * w
                sxx += wp.outer(r, r) * w
                svx -= wp.outer(vj, r) * w
            if compute_vorticity:
                omega += wp.cross(vj - vi, spiky_gradient(r, r2, pi, slots.particle, j, p)) * vol_j
    v = vi
    if p.viscosity > 0.0:
        v += (num / den - vi) * p.viscosity
    if fit_affine:
        # (exact at the reference step, where fast math's power would round)
        beta = p.nonaffine_damping
        if damping_steps != 1.0:
            beta = 1.0 - wp.pow(1.0 - beta, damping_steps)
        v += (affine_velocity_at_particle(den, sx, num, sxx, svx, p) - vi) * beta
    if p.viscosity > 0.0 or fit_affine:
        particle_qd[pi] = v
    if compute_vorticity:
        vorticity[i] = omega


@wp.func
def recover_fluid_particle(
    k: int,
    pi: int,
    particle_flags: wp.array[wp.int32],
    rest_distance: float,
    dt: float,
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    last_finite_q: wp.array[wp.vec3],
    nonfinite_count: wp.array[wp.int32],
    fast_count: wp.array[wp.int32],
):
    """Restore fluid particle ``k`` (particle ``pi``) to its last finite position at rest if it is not finite.

    Counts the recovered particles, and the particles that would travel more than one rest distance
    in the next substep: past that a particle can cross a thin wall before its contact is found.
    """
    if (particle_flags[pi] & ParticleFlags.ACTIVE) == 0:
        return
    x = particle_q[pi]
    v = particle_qd[pi]
    if wp.isfinite(x) and wp.isfinite(v):
        last_finite_q[k] = x
        if wp.length(v) * dt > rest_distance:
            wp.atomic_add(fast_count, 0, 1)
    else:
        particle_q[pi] = last_finite_q[k]
        particle_qd[pi] = wp.vec3(0.0)
        wp.atomic_add(nonfinite_count, 0, 1)


@wp.kernel
def confine_vorticity_and_recover(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    density: wp.array[float],
    vorticity: wp.array[wp.vec3],
    slot_fluid: wp.array[wp.int32],
    fluid_particle: wp.array[wp.int32],
    particle_flags: wp.array[wp.int32],
    dt: float,
    # in/out
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    last_finite_q: wp.array[wp.vec3],
    nonfinite_count: wp.array[wp.int32],
    fast_count: wp.array[wp.int32],
):
    """Vorticity confinement, then the non-finite recovery of the slot's particle (the substep's last pass).

    Confinement: ``v_i += dt * eps * (N x omega_i)`` with ``N`` the normalised gradient of ``|omega|``.
    Then :func:`recover_fluid_particle` for the particle of every slot, the left-out ones included
    (``slot_fluid``: the fluid index of each slot), so the recovery costs no pass of its own.
    """
    i = wp.tid()
    pi = slots.particle[i]
    p = params[0]
    if pi >= 0 and p.vorticity > 0.0:
        xi4 = slots.xm[i]
        xi = wp.vec3(xi4[0], xi4[1], xi4[2])
        eta = wp.vec3(0.0)
        layout = fluid_neighbor_layout(slots, i)
        count = layout[2]
        for k in range(count):
            j = fluid_neighbor(slots, i, k, layout)
            xj4 = slots.xm[j]
            r = xi - wp.vec3(xj4[0], xj4[1], xj4[2])
            r2 = wp.dot(r, r)
            if r2 < p.h2:
                vol_j = xj4[3] / wp.max(density[j], 1.0e-6)
                eta += spiky_gradient(r, r2, pi, slots.particle, j, p) * (vol_j * wp.length(vorticity[j]))
        # grad W points from j to i, so -eta points toward larger |omega|
        eta_len = wp.length(eta)
        if eta_len > 1.0e-9:
            n = -eta / eta_len
            particle_qd[pi] = particle_qd[pi] + wp.cross(n, vorticity[i]) * (p.vorticity * dt)
    f = slot_fluid[i]
    recover_fluid_particle(
        f,
        fluid_particle[f],
        particle_flags,
        p.rest_distance,
        dt,
        particle_q,
        particle_qd,
        last_finite_q,
        nonfinite_count,
        fast_count,
    )


@wp.func
def take_compression(bins: wp.array[float]):
    """Total compression and particle count of the compression bins (see :func:`compute_fluid_density_lambda`).

    Clears the bins for the next evaluation. Called by every thread of one block: the bins are summed
    as tiles (a tree over the block, where one thread's loop over them took about 10 us on an H100).
    """
    total = wp.tile_sum(wp.tile_load(bins, shape=COMPRESSION_BINS, offset=0))[0]
    count = wp.tile_sum(wp.tile_load(bins, shape=COMPRESSION_BINS, offset=COMPRESSION_BINS))[0]
    # (every thread has passed the sums, so every load is done)
    wp.tile_store(bins, wp.tile_zeros(shape=COMPRESSION_SUMS, dtype=float))
    return wp.vec2(total, count)


@wp.func
def compression_within_tolerance(sums: wp.vec2, tolerance: float, stop_uncompressed: int):
    """Whether a pass's mean compression (``sums`` from :func:`take_compression`) lets the passes stop.

    Nothing evaluated always stops. A tolerance of 0 stops only where nothing is compressed, and
    only with ``stop_uncompressed`` (the passes within an XPBD iteration); on the XPBD iterations
    0 means no early stop.
    """
    total = sums[0]
    count = sums[1]
    if count == 0.0:
        return True
    if tolerance > 0.0 or stop_uncompressed != 0:
        return total <= tolerance * count
    return False


@wp.kernel
def decide_after_first_fluid_pass(
    params: wp.array[FluidParams],
    more: int,
    stop_uncompressed: int,
    # in/out
    bins: wp.array[float],
    go_on: wp.array[wp.int32],
    loop_count: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Whether density passes follow the first one, which always corrects, from the compression it measured.

    The first pass of a substep (of each XPBD iteration with sub-passes) corrects whatever the
    tolerance says: the mean counts the under-dense surface as 0, so a small or splashing fluid meets
    any tolerance while some of its particles are compressed. Passes follow while its mean
    compression, measured before its correction, is not within the tolerance (the rule of the later
    passes' decisions: :func:`compression_within_tolerance`) and ``more`` passes are allowed. Counts the first pass, opens the loop's count, and
    reads and clears the pass's compression sums. One block of ``COMPRESSION_BINS`` threads.
    """
    _, lane = wp.tid()
    sums = take_compression(bins)
    if lane != 0:
        return
    iterations_total[0] = iterations_total[0] + 1
    loop_count[0] = 0
    if more > 0 and not compression_within_tolerance(sums, params[0].density_tolerance, stop_uncompressed):
        go_on[0] = 1
    else:
        go_on[0] = 0


@wp.kernel
def decide_fluid_subiteration(
    params: wp.array[FluidParams],
    max_iterations: int,
    # in/out
    bins: wp.array[float],
    loop_active: wp.array[wp.int32],
    correct: wp.array[wp.int32],
    loop_count: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Decide whether this density pass (after the iteration's first) corrects and whether another one follows.

    It corrects unless the mean compression it measured is within the tolerance (or nothing is
    compressed); the loop ends with that or after ``max_iterations`` corrections in the loop. Reads and clears
    the pass's compression sums. Once the loop has ended (passes launched outside a graph), nothing
    corrects. One block of ``COMPRESSION_BINS`` threads; the first writes the decision (every thread
    reads the flags before the sums, so before it writes them).
    """
    _, lane = wp.tid()
    if loop_active[0] == 0:
        if lane == 0:
            correct[0] = 0
        return
    sums = take_compression(bins)
    if lane != 0:
        return
    if compression_within_tolerance(sums, params[0].density_tolerance, 1):
        correct[0] = 0
        loop_active[0] = 0
        return
    correct[0] = 1
    loop_count[0] = loop_count[0] + 1
    iterations_total[0] = iterations_total[0] + 1
    if loop_count[0] >= max_iterations:
        loop_active[0] = 0


@wp.kernel
def decide_fluid_density_converged(
    params: wp.array[FluidParams],
    # in/out
    bins: wp.array[float],
    active: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Skip this and the substep's remaining density passes once the mean compression is within the tolerance.

    Not launched for the substep's first pass (see :func:`decide_after_first_fluid_pass`). Reads and clears the compression sums of this pass's evaluation; counts the passes that go on
    to correct. One block of ``COMPRESSION_BINS`` threads, as :func:`decide_fluid_subiteration`.
    """
    _, lane = wp.tid()
    if active[0] == 0:
        return
    sums = take_compression(bins)
    if lane != 0:
        return
    if compression_within_tolerance(sums, params[0].density_tolerance, 0):
        active[0] = 0
        return
    iterations_total[0] = iterations_total[0] + 1


@wp.kernel
def recover_nonfinite_fluid(
    params: wp.array[FluidParams],
    fluid_particle: wp.array[wp.int32],
    particle_flags: wp.array[wp.int32],
    dt: float,
    # in/out
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    last_finite_q: wp.array[wp.vec3],
    nonfinite_count: wp.array[wp.int32],
    fast_count: wp.array[wp.int32],
):
    """:func:`recover_fluid_particle` for every fluid particle (where the substep ends without the vorticity pass)."""
    k = wp.tid()
    recover_fluid_particle(
        k,
        fluid_particle[k],
        particle_flags,
        params[0].rest_distance,
        dt,
        particle_q,
        particle_qd,
        last_finite_q,
        nonfinite_count,
        fast_count,
    )


@wp.kernel
def solve_particle_particle_contacts_skip_fluid_pairs(
    grid: wp.uint64,
    particle_x: wp.array[wp.vec3],
    particle_v: wp.array[wp.vec3],
    particle_invmass: wp.array[float],
    particle_radius: wp.array[float],
    particle_flags: wp.array[wp.int32],
    k_mu: float,
    k_cohesion: float,
    max_radius: float,
    dt: float,
    relaxation: float,
    # outputs
    deltas: wp.array[wp.vec3],
):
    """Particle contacts for models with fluid: a pair of two fluid particles is left to the density constraint.

    Same launch signature as upstream's particle-contact kernel (:mod:`.upstream` checks it and swaps
    this one in only while a fluid solver steps), and for every other pair upstream's contact law
    in upstream's order of operations, so that granular particles and cloth step bitwise as without
    fluid. For a pair at distance ``d`` with gap ``e = d - r_i - r_j <= k_cohesion``, normal ``n`` and
    tangential relative velocity ``v_t``, particle ``i`` moves by

        w_i * relaxation * sum_j (normalize(v_t) * max(mu * e, -|v_t| dt) - n * e) / (w_i + w_j)

    (inside the cohesion band, ``e > 0``, the friction term is upstream's too).
    """
    tid = wp.tid()
    i = wp.hash_grid_point_id(grid, tid)
    if i == -1:
        return
    flags_i = particle_flags[i]
    if (flags_i & ParticleFlags.ACTIVE) == 0:
        return
    fluid_i = (flags_i & ParticleFlags.FLUID) != 0
    proxy_i = (flags_i & ParticleFlags.PROXY) != 0
    xi = particle_x[i]
    vi = particle_v[i]
    ri = particle_radius[i]
    wi = particle_invmass[i]
    correction = wp.vec3(0.0)
    query = wp.hash_grid_query(grid, xi, ri + max_radius + k_cohesion)
    j = int(0)
    while wp.hash_grid_query_next(query, j):
        if j == i:
            continue
        flags_j = particle_flags[j]
        if (flags_j & ParticleFlags.ACTIVE) == 0:
            continue
        if fluid_i and (flags_j & ParticleFlags.FLUID) != 0:
            continue
        if proxy_i and ((flags_j & ParticleFlags.PROXY) != 0 or particle_invmass[j] <= 0.0):
            continue
        offset = xi - particle_x[j]
        dist = wp.length(offset)
        gap = dist - ri - particle_radius[j]
        w_sum = wi + particle_invmass[j]
        if gap <= k_cohesion and w_sum > 0.0 and dist > 0.0:
            n = offset / dist
            v_rel = vi - particle_v[j]
            normal = n * gap
            v_t = v_rel - n * wp.dot(n, v_rel)
            friction = wp.normalize(v_t) * wp.max(k_mu * gap, -wp.length(v_t) * dt)
            correction += (friction - normal) / w_sum
    wp.atomic_add(deltas, i, correction * wi * relaxation)
