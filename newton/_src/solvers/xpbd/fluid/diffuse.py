# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Diffuse particles: spray, foam and bubbles emitted by the fluid, for rendering only.

After Ihmsen, Akinci, Akinci & Teschner, "Unified spray, foam and bubbles for particle-based
fluids", The Visual Computer 28, 2012, simplified. Once per substep, after the fluid solve, new
particles are emitted (2.) and then all live ones advected (1.), so that a new particle placed
inside a shape leaves it in the same substep:

1. **advect** every live diffuse particle with the fluid velocity interpolated at its position
   (a kernel-weighted mean over the fluid particles within h); it is classified by how many fluid
   particles are within h: *spray* (fewer than ``SPRAY_MAX_NEIGHBORS``) flies ballistically under
   gravity, *foam* (in between) moves with the fluid, *bubble* (at least ``BUBBLE_MIN_NEIGHBORS``)
   rises against gravity and is dragged toward the fluid velocity. The shapes that collide with
   particles in its world, of every type the fluid's continuous collision knows (those of dynamic
   bodies too, where they are), push it out and remove its velocity into them (one caught where
   shapes overlap dies).
   Its lifetime runs down; at zero it dies.
2. **emit**: each fluid particle has a trapped-air potential (the relative speed of neighbours
   approaching it, ``sum |v_ij| (1 - v_ij.x_ij / |v_ij||x_ij|) (1 - r/h)`` [m/s]) and a wave-crest
   potential (how far below rest density it is, if it moves along its outward surface normal),
   each clamped to [0, 1] between two thresholds and scaled by its kinetic-energy potential; with
   the probability ``rate * dt * (trapped air + wave crest) * energy`` it emits one diffuse
   particle at a random point within half a rest distance, with its velocity.

The particles live in a fixed-capacity ring buffer (the oldest is overwritten when it is full);
counters and random numbers (a hash of the substep counter and the particle) stay on the device,
so the passes can be captured in a graph. Nothing here feeds back into the fluid.
"""

import warp as wp

from .continuous_collision import GuardedShapes, guarded_surface_distance, near_shape, shape_poses, world_row
from .neighbors import _NO_WORLD, fluid_cell, fluid_cell_hash, fluid_cell_range
from .sph import FluidParams, FluidSlots, neighbor_sum

DIFFUSE_DEAD = wp.constant(-1)
DIFFUSE_SPRAY = wp.constant(0)
DIFFUSE_FOAM = wp.constant(1)
DIFFUSE_BUBBLE = wp.constant(2)

# threads per diffuse particle in the advection (one per scanned cell, rounded up to a warp)
DIFFUSE_BLOCK_DIM = 32
SPRAY_MAX_NEIGHBORS = wp.constant(6)
BUBBLE_MIN_NEIGHBORS = wp.constant(20)
# potentials map linearly to [0, 1] between these thresholds
TRAPPED_AIR_MIN = wp.constant(2.0)  # [m/s]
TRAPPED_AIR_MAX = wp.constant(10.0)
WAVE_CREST_MIN = wp.constant(0.05)  # (1 - rho/rho0) * cos(v, n), dimensionless
WAVE_CREST_MAX = wp.constant(0.3)
ENERGY_MIN = wp.constant(0.5)  # kinetic energy per unit mass [m^2/s^2]
ENERGY_MAX = wp.constant(5.0)
EMISSION_RATE = wp.constant(200.0)  # diffuse particles per fluid particle per second at full potential
LIFETIME_MIN = wp.constant(1.0)  # [s]
LIFETIME_MAX = wp.constant(3.0)
BUBBLE_BUOYANCY = wp.constant(2.0)  # upward acceleration of a bubble, in units of |g|
BUBBLE_DRAG = wp.constant(0.5)  # per-substep blend of a bubble's velocity toward the fluid's
PUSH_SLOP = wp.constant(1.0e-3)  # a push out of a shape ends this share of the radius past it


@wp.struct
class DiffuseBuffers:
    """The ring buffer of diffuse particles."""

    position: wp.array[wp.vec3]  # [m]
    velocity: wp.array[wp.vec3]  # [m/s]
    lifetime: wp.array[float]  # remaining life [s], <= 0 for a dead entry
    kind: wp.array[wp.int32]  # DIFFUSE_SPRAY, _FOAM, _BUBBLE or _DEAD
    world: wp.array[wp.int32]
    counters: wp.array[wp.int32]  # [0]: next ring index, [1]: emitted in total, [2]: substeps so far


@wp.func
def _potential(value: float, lo: float, hi: float):
    return wp.clamp((value - lo) / (hi - lo), 0.0, 1.0)


@wp.struct
class EmitterSlot:
    """What a neighbour's share of the emission potentials needs of slot ``i``."""

    x: wp.vec3  # position [m]
    v: wp.vec3  # velocity [m/s]
    velocity: wp.array[wp.vec3]  # every slot's velocity [m/s]


@wp.func
def emission_term(slots: FluidSlots, j: int, me: EmitterSlot, p: FluidParams):
    """Neighbour ``j``'s share of the surface normal (xyz, ``sum w x_hat``) and of the trapped air (w).

    Trapped air: the relative speed of the pair weighted by how far it is from moving along their
    line, ``|v_ij| (1 - v_ij_hat . x_hat) w`` with ``w = 1 - r / h`` (Ihmsen et al. 2012).
    """
    xj4 = slots.xm[j]
    xij = me.x - wp.vec3(xj4[0], xj4[1], xj4[2])
    r = wp.length(xij)
    if r >= p.h or r <= 0.0:
        return wp.vec4(0.0)
    w = 1.0 - r / p.h
    xhat = xij / r
    normal = w * xhat
    vij = me.v - me.velocity[j]
    speed = wp.length(vij)
    trapped_air = float(0.0)
    if speed > 0.0:
        trapped_air = speed * (1.0 - wp.dot(vij / speed, xhat)) * w
    return wp.vec4(normal[0], normal[1], normal[2], trapped_air)


emission_sum = neighbor_sum(emission_term)


@wp.kernel
def emit_diffuse_particles(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    sorted_v: wp.array[wp.vec3],
    density: wp.array[float],
    particle_world: wp.array[wp.int32],
    dt: float,
    capacity: int,
    # outputs
    buffers: DiffuseBuffers,
):
    """One fluid slot: emission potentials from its neighbourhood, then at most one emission.

    Reads the slot-ordered positions and velocities of the step's result (``slots.xm``, ``sorted_v``).
    """
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0:
        return
    vi = sorted_v[i]
    speed_i = wp.length(vi)
    # most of a calm or slow fluid fails this test and skips the neighbour loop
    energy = _potential(0.5 * speed_i * speed_i, ENERGY_MIN, ENERGY_MAX)
    if energy <= 0.0:
        return
    p = params[0]
    xi4 = slots.xm[i]
    xi = wp.vec3(xi4[0], xi4[1], xi4[2])
    me = EmitterSlot()
    me.x = xi
    me.v = vi
    me.velocity = sorted_v
    sums = emission_sum(slots, i, me, p, wp.vec4(0.0))
    normal = wp.vec3(sums[0], sums[1], sums[2])
    trapped_air = sums[3]
    wave_crest = float(0.0)
    n_len = wp.length(normal)
    if n_len > 0.0:
        along = wp.dot(vi / speed_i, normal / n_len)
        if along >= 0.6:
            wave_crest = wp.max(1.0 - density[i] * p.inv_rest_density, 0.0) * along
    chance = EMISSION_RATE * dt * energy
    chance *= _potential(trapped_air, TRAPPED_AIR_MIN, TRAPPED_AIR_MAX) + _potential(
        wave_crest, WAVE_CREST_MIN, WAVE_CREST_MAX
    )
    if chance <= 0.0:
        return
    rng = wp.rand_init(buffers.counters[2] * 7919 + 1, pi)
    if wp.randf(rng) >= chance:
        return
    index = wp.atomic_add(buffers.counters, 0, 1)
    wp.atomic_add(buffers.counters, 1, 1)
    slot = index % capacity
    if slot < 0:
        slot += capacity
    offset = wp.sample_unit_sphere(rng) * (0.5 * p.rest_distance)
    buffers.position[slot] = xi + offset
    buffers.velocity[slot] = vi
    buffers.lifetime[slot] = LIFETIME_MIN + (LIFETIME_MAX - LIFETIME_MIN) * wp.randf(rng)
    buffers.kind[slot] = DIFFUSE_FOAM
    buffers.world[slot] = particle_world[pi]


@wp.kernel
def advect_diffuse_particles(
    params: wp.array[FluidParams],
    cell_offset: wp.array[wp.int32],
    sorted_xm: wp.array[wp.vec4],
    sorted_v: wp.array[wp.vec3],
    sorted_world: wp.array[wp.int32],
    inv_cell: float,
    cell_bits: int,
    table_mask: int,
    gravity: wp.array[wp.vec3],
    shapes: GuardedShapes,
    any_shapes: int,
    dt: float,
    # outputs
    buffers: DiffuseBuffers,
):
    # one block per diffuse particle: its lanes scan the 27 cells around it in parallel (a lone
    # thread per particle would wait on one cell after the other; there are few diffuse particles)
    k, lane = wp.tid()
    if k == 0 and lane == 0:
        # the substep counter seeds the next emission's random numbers
        buffers.counters[2] = buffers.counters[2] + 1
    life = buffers.lifetime[k]
    if life <= 0.0:
        return
    p = params[0]
    x = buffers.position[k]
    v = buffers.velocity[k]
    world = buffers.world[k]
    c = fluid_cell(x, inv_cell)
    # a world without fluid has no block in the table: nothing to scan
    scan = world >= -1 and ((world + 1) << cell_bits) <= table_mask
    partial = wp.vec4(0.0)  # weighted fluid velocity (xyz) and weight (w)
    partial_count = float(0.0)
    for cell in range(lane, 27, wp.block_dim()):
        if not scan:
            continue
        dx = cell % 3 - 1
        dy = (cell // 3) % 3 - 1
        dz = cell // 9 - 1
        key = fluid_cell_hash(c[0] + dx, c[1] + dy, c[2] + dz, world, cell_bits)
        start, end = fluid_cell_range(cell_offset, key)
        # slots of one cell are contiguous: these reads are coalesced
        for j in range(start, end):
            if sorted_world[j] == _NO_WORLD:
                continue
            xj4 = sorted_xm[j]
            r = wp.length(x - wp.vec3(xj4[0], xj4[1], xj4[2]))
            if r >= p.h:
                continue
            w = 1.0 - r / p.h
            vj = sorted_v[j]
            partial += wp.vec4(w * vj[0], w * vj[1], w * vj[2], w)
            partial_count += 1.0
    total = wp.tile_sum(wp.tile(partial, preserve_type=True))[0]
    count = int(wp.tile_sum(wp.tile(partial_count))[0] + 0.5)
    if lane != 0:
        return
    v_fluid = wp.vec3(total[0], total[1], total[2])
    w_sum = total[3]
    g = gravity[wp.max(world, 0)]
    kind = DIFFUSE_FOAM
    if count < SPRAY_MAX_NEIGHBORS:
        kind = DIFFUSE_SPRAY
        v = v + g * dt
    elif count < BUBBLE_MIN_NEIGHBORS:
        v = v_fluid / w_sum
    else:
        kind = DIFFUSE_BUBBLE
        v = v - BUBBLE_BUOYANCY * g * dt
        v = v + BUBBLE_DRAG * (v_fluid / w_sum - v)
    x = x + v * dt

    radius = 0.25 * p.rest_distance
    # push out of every shape; where shapes overlap (tank corners) one push can land in the next
    # shape, so a second round follows, and a particle still inside after it dies
    # (the shapes of its world and the global ones; none without a guard)
    first_shape = int(0)
    end_shape = int(0)
    if any_shapes != 0:
        row = world_row(world, shapes.world_count)
        first_shape = shapes.row_start[row]
        end_shape = shapes.row_start[row + 1]
    trapped = int(0)
    for push_round in range(3):
        trapped = int(0)
        for k_shape in range(first_shape, end_shape):
            s = shapes.shape[k_shape]
            if not near_shape(shapes, s, x, radius):
                continue
            # (held where they are: both poses are the current one)
            _held, xf = shape_poses(shapes, s)
            local = wp.transform_point(wp.transform_inverse(xf), x)
            hit = guarded_surface_distance(shapes, s, local, p.h)
            if hit[3] < radius:
                trapped = int(1)
                if push_round < 2:
                    n = wp.transform_vector(xf, wp.vec3(hit[0], hit[1], hit[2]))
                    # (a hair past the radius: the next round's measure, rounded, must not find it inside again)
                    x = x + ((1.0 + PUSH_SLOP) * radius - hit[3]) * n
                    vn = wp.dot(v, n)
                    if vn < 0.0:
                        v = v - vn * n
    if trapped != 0:
        life = 0.0

    life -= dt
    if life <= 0.0:
        kind = DIFFUSE_DEAD
    buffers.position[k] = x
    buffers.velocity[k] = v
    buffers.lifetime[k] = life
    buffers.kind[k] = kind
