# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Over-packed placements: fluid placed closer than its rest spacing is moved apart before it moves.

PBF turns every position correction into velocity (``v = (x - x_start) / dt``). Fluid placed packed
(a block at 0.7 of its rest spacing, particles placed on top of each other) is corrected by the
first substeps' density passes, and that correction leaves as velocity: 75 m/s in the first frame
of ``benchmarks/packed_start.py`` at 0.7, particles thrown 12 spacings above the level the fluid
settles to. The method has no equation of state, so the packing holds no energy that it could
justify; it is an error of the placement. The solver undoes it the way a contact solver undoes an
overlap it did not cause: it moves positions and leaves the velocities alone.

When: at the first step after construction if the model's initial fluid is over-packed, and at the
first step after a :meth:`~newton.solvers.SolverXPBD.reset` that restored positions (from the
initial particles if those were over-packed, from a caller's state always, since it is not known on
the host). Which worlds: of those the placement touched, the ones with a fluid particle more than
:data:`PLACEMENT_COMPRESSION` above rest density by the fluid's own sum, or with a centre inside a
shape (a static one, or a body's, held where it is); their whole fluid is relaxed and every other world is left bitwise as it
was. How: rounds of a neighbour build at the current positions and
:data:`RELAXATION_PASSES` Jacobi density passes applied to the positions of the relaxing worlds
(bounded per pass as in a step, :data:`RELAXATION_MOMENTUM` of the last move carried on while the
particle is compressed), with the walls' density from the shapes themselves (:func:`list_shape_walls`:
the step's contacts were found at the packed positions), each move's path kept out of the shapes
(:mod:`.continuous_collision`'s intersection; a body's shapes held where they are) and the centre a
radius off the walls;
a world stops once all of its fluid is within :data:`PLACEMENT_TOLERANCE`. Gravity does not act while
positions relax, so the fluid spreads into the free space around it, up as well as sideways, and
starts to fall only in the step. The step's contacts of the moved fluid are then found again
(:func:`refresh_relaxed_contacts`).

A block deep in particles needs rounds in proportion to the square of its depth (a pass carries a
correction about one neighbour further): 40 layers take about 270. In a CUDA graph and on the CPU the
check runs only if a world was placed (a conditional node on a device flag, so a graph captured with
a reset runs nothing more when its mask selects no world) and the rounds are a conditional loop
that stops at the last relaxing world, up to :data:`RELAXATION_ROUNDS`. A CUDA step without a graph
cannot read those flags without synchronising, so it launches a graph of the same nodes that the
solver captured beforehand (at construction, or at a reset outside a capture), on copies of the
positions and body poses; where the CUDA driver has no conditional nodes it launches
:data:`EAGER_RELAXATION_ROUNDS` rounds,
which leave a 40-layer block packed; what is left springs apart with velocity, and the report says
so (docs/archive/validation_notebook.md, "Over-packed starts"). The conditional bodies' neighbour
builds sort with :mod:`.prefix_sum` (a body may not allocate). What was found is counted on the
device and reported, with a warning, by the next ``fluid_diagnostics`` call.
"""

import functools

import warp as wp

from ....geometry import ParticleFlags
from .continuous_collision import (
    GuardedShapes,
    first_shape_entry,
    guarded_surface_distance,
    near_shape,
    shape_poses,
    world_row,
)
from .density_constraint import CorrectionSlot, density_passes, named_variant, relaxed_correction
from .sph import FluidParams, FluidSlots
from .walls import WALL_CONTACTS_PER_SLOT

wp.set_module_options({"fast_math": True})

#: compression ``rho / rho0 - 1`` of a placed fluid particle above which its world's fluid is relaxed: the
#: compression the step's diagnostics call packed too tightly (healthy flows stay well below)
PLACEMENT_COMPRESSION = wp.constant(0.1)

#: compression ``rho / rho0 - 1`` (the walls' share counted) below which a relaxing world's fluid is relaxed
PLACEMENT_TOLERANCE = wp.constant(0.01)

#: most rounds of relaxation (a neighbour build and ``RELAXATION_PASSES`` density passes each) in a CUDA
#: graph or on the CPU: a conditional loop, which stops at the round that finds the last relaxing world's
#: fluid within ``PLACEMENT_TOLERANCE`` (a world stops at its own such round)
RELAXATION_ROUNDS = 512

#: rounds a CUDA step without a graph launches where the driver has no conditional graph nodes, every one of
#: them (it cannot read the flag that would stop
#: them without synchronising; those after the last world stopped return at once, but for their neighbour
#: builds)
EAGER_RELAXATION_ROUNDS = 64

#: density passes per neighbour build (a pair that comes within ``h`` during a round's passes is missed until
#: the next build; in a fluid that spreads, few do)
RELAXATION_PASSES = 4

#: share of a relaxing particle's last move carried into its next (Polyak's heavy ball)
RELAXATION_MOMENTUM = wp.constant(0.5)

# placed[w] of a world whose fluid the step found over-packed (its contacts are refreshed after the relaxation)
RELAXED = wp.constant(2)


@wp.kernel
def mark_placed_worlds(
    world_mask: wp.array[wp.bool],
    use_mask: int,
    # outputs
    placed: wp.array[wp.int32],
    any_placed: wp.array[wp.int32],
):
    """Mark the worlds a reset restored (all without a mask): their fluid is checked at the next step."""
    w = wp.tid()
    if use_mask == 0 or world_mask[w]:
        placed[w] = 1
        any_placed[0] = 1


@wp.kernel
def find_overpacked_worlds(
    slots: FluidSlots,
    lambda_rho: wp.array[wp.vec2],
    particle_world: wp.array[wp.int32],
    world_count: int,
    placed: wp.array[wp.int32],
    slot_fluid: wp.array[wp.int32],
    rounds: int,
    # outputs
    relaxing: wp.array[wp.int32],
    any_relaxing: wp.array[wp.int32],
    rounds_left: wp.array[wp.int32],
    found: wp.array[float],
    last_q: wp.array[wp.vec3],
):
    """A placed world relaxes if a fluid particle is past :data:`PLACEMENT_COMPRESSION` or inside a shape.

    The compression is the fluid's own sum (a lattice at rest reads 0 however close to a wall it was
    placed); inside is a centre behind a wall listed for the slot (:func:`list_shape_walls`). ``found``
    counts those particles (0) and keeps their largest compression (1) until reported (``found[2]``:
    worlds left packed after the last round, see :func:`keep_packed_worlds_relaxing`). Every placed
    particle's ``last_q`` (by fluid index ``slot_fluid``) becomes its position: the relaxation's moves
    start from rest. The relaxation that follows may run ``rounds`` rounds.
    """
    i = wp.tid()
    if i == 0:
        rounds_left[0] = rounds
    pi = slots.particle[i]
    if pi < 0:
        return
    row = world_row(particle_world[pi], world_count)
    if placed[row] == 0:
        return
    xm = slots.xm[i]
    # a relaxation starts at rest (its moves carry on from the last position)
    last_q[slot_fluid[i]] = wp.vec3(xm[0], xm[1], xm[2])
    c = lambda_rho[i][1] - 1.0
    inside = int(0)
    n = slots.particle.shape[0]
    for t in range(wp.min(slots.wall_count[i], WALL_CONTACTS_PER_SLOT)):
        plane = slots.wall_plane[t * n + i]
        if plane[0] * xm[0] + plane[1] * xm[1] + plane[2] * xm[2] < plane[3]:
            inside = 1
    if c <= PLACEMENT_COMPRESSION and inside == 0:
        return
    placed[row] = RELAXED
    relaxing[row] = 1
    any_relaxing[0] = 1
    wp.atomic_add(found, 0, 1.0)
    wp.atomic_max(found, 1, wp.max(c, 0.0))


@wp.kernel
def list_shape_walls(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    particle_world: wp.array[wp.int32],
    world_count: int,
    listed: wp.array[wp.int32],
    any_listed: wp.array[wp.int32],
    shapes: GuardedShapes,
):
    """List the guarded shapes within ``h`` of a slot as its walls: the plane at its nearest surface point.

    For the slots of the worlds ``listed`` selects (the placed ones, then the relaxing ones) while
    ``any_listed[0]`` is set.
    What a step lists from upstream's contacts (:func:`~.walls.list_wall_contact`), found here from
    the shapes themselves (:func:`~.continuous_collision.guarded_surface_distance`: every shape that
    collides with particles), since the contacts of the step were found at the packed positions.
    """
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0 or any_listed[0] == 0:
        return
    w = particle_world[pi]
    if listed[world_row(w, world_count)] == 0:
        return
    h = params[0].h
    xm = slots.xm[i]
    x = wp.vec3(xm[0], xm[1], xm[2])
    row = world_row(w, shapes.world_count)
    n = slots.particle.shape[0]
    count = int(0)
    for k in range(shapes.row_start[row], shapes.row_start[row + 1]):
        s = shapes.shape[k]
        if not near_shape(shapes, s, x, h):
            continue
        start, pose = shape_poses(shapes, s)
        local = wp.transform_point(wp.transform_inverse(pose), x)
        hit = guarded_surface_distance(shapes, s, local, h)
        if hit[3] >= h or count >= WALL_CONTACTS_PER_SLOT:
            continue
        normal = wp.transform_vector(pose, wp.vec3(hit[0], hit[1], hit[2]))
        slots.wall_plane[count * n + i] = wp.vec4(normal[0], normal[1], normal[2], wp.dot(normal, x) - hit[3])
        count += 1
    slots.wall_count[i] = count


@wp.func
def path_end_outside_shapes(
    shapes: GuardedShapes, lo: int, hi: int, x0: wp.vec3, x1: wp.vec3, radius: float, rounds: int
):
    """Where a move from ``x0`` to ``x1`` ends once kept out of the shapes ``lo..hi`` (no velocity to stop).

    Continuous collision's rule (:func:`~.continuous_collision.stop_fluid_paths_at_shapes`): onto each
    entered shape's tangent plane, a radius off it, for ``rounds`` rounds (a kernel argument, so that
    Warp does not unroll the loop), and back to ``x0`` if the last still enters.
    """
    for r in range(rounds):
        t, normal, point, point_start = first_shape_entry(shapes, lo, hi, x0, x1)
        if t > 1.0:
            return x1
        if r < rounds - 1:
            x1 = x1 + (radius - wp.dot(normal, x1 - point)) * normal
        else:
            return x0
    return x1


@functools.cache
def relaxation_kernel(kernel: str):
    """:func:`relax_overpacked_fluid` moving along the density constraint's gradient of ``kernel`` (``fluid_density_kernel``)."""
    passes = density_passes(kernel)

    def relax_overpacked_fluid(
        params: wp.array[FluidParams],
        slots: FluidSlots,
        lambda_rho: wp.array[wp.vec2],
        wall_grad: wp.array[wp.vec3],
        fluid_particle: wp.array[wp.int32],
        slot_of_particle: wp.array[wp.int32],
        particle_flags: wp.array[wp.int32],
        particle_world: wp.array[wp.int32],
        particle_radius: wp.array[float],
        particle_inv_mass: wp.array[float],
        world_count: int,
        relaxing: wp.array[wp.int32],
        any_relaxing: wp.array[wp.int32],
        shapes: GuardedShapes,
        guarded: int,
        guard_rounds: int,
        # outputs
        particle_q: wp.array[wp.vec3],
        last_finite_q: wp.array[wp.vec3],
        moved_xm: wp.array[wp.vec4],
    ):
        """Move a relaxing world's fluid particle by its density correction ``1/rho0 sum_j (lambda_i + lambda_j) grad W_ij``.

        The correction of one Jacobi pass (the walls' share included), bounded as in a step, applied to the
        position alone and kept out of the shapes. Over fluid index ``k`` (``last_finite_q`` is in that
        order), reading the slots' positions, so every particle moves from the same configuration; every
        slot's position after the pass goes to ``moved_xm`` for the next pass.
        """
        k = wp.tid()
        if any_relaxing[0] == 0:
            return
        pi = fluid_particle[k]
        i = slot_of_particle[pi]
        if i < 0:
            return
        xm = slots.xm[i]
        moved_xm[i] = xm
        w = particle_world[pi]
        if relaxing[world_row(w, world_count)] == 0:
            return
        if (particle_flags[pi] & ParticleFlags.ACTIVE) == 0 or particle_inv_mass[pi] == 0.0:
            return
        p = params[0]
        lr = lambda_rho[i]
        me = CorrectionSlot()
        me.xm = xm
        me.lam = lr[0]
        me.rel = lr[1]
        me.particle = pi
        me.lambda_rho = lambda_rho
        zero = wp.spatial_vector(wp.vec3(0.0), wp.vec3(0.0))
        dx = wp.spatial_top(wp.static(passes.density_correction_sum)(slots, i, me, p, zero)) + wall_grad[i] * me.lam
        dx = relaxed_correction(dx, p.relaxation, p)
        x0 = wp.vec3(xm[0], xm[1], xm[2])
        # the heavy ball: the last pass's move carried on, so a long wave (the whole block spreading)
        # converges in about as many passes as it is wide, not as its square; only while the particle is
        # compressed (the unilateral constraint has nothing to stop a move carried past rest density)
        x1 = x0 + dx
        if lr[1] > 1.0:
            x1 += RELAXATION_MOMENTUM * (x0 - last_finite_q[k])
        radius = particle_radius[pi]
        if guarded != 0:
            row = world_row(w, shapes.world_count)
            lo = shapes.row_start[row]
            hi = shapes.row_start[row + 1]
            if lo < hi:
                x1 = path_end_outside_shapes(shapes, lo, hi, x0, x1, radius, guard_rounds)
            # a radius off every wall listed for the slot, as the step's contacts will hold it
            n = slots.particle.shape[0]
            for t in range(wp.min(slots.wall_count[i], WALL_CONTACTS_PER_SLOT)):
                plane = slots.wall_plane[t * n + i]
                normal = wp.vec3(plane[0], plane[1], plane[2])
                gap = wp.dot(normal, x1) - plane[3]
                if gap < radius:
                    x1 += (radius - gap) * normal
        particle_q[pi] = x1
        # (the position before the move, which the next pass's heavy ball reads; a finite one for the recovery)
        last_finite_q[k] = x0
        moved_xm[i] = wp.vec4(x1[0], x1[1], x1[2], xm[3])

    return wp.kernel(named_variant(relax_overpacked_fluid, passes.suffix))


@wp.kernel
def find_packed_slots(
    slots: FluidSlots,
    lambda_rho: wp.array[wp.vec2],
    particle_world: wp.array[wp.int32],
    world_count: int,
    relaxing: wp.array[wp.int32],
    any_relaxing: wp.array[wp.int32],
    # outputs
    packed: wp.array[wp.int32],
):
    """Mark the relaxing worlds with a particle still past :data:`PLACEMENT_TOLERANCE` (walls counted)."""
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0 or any_relaxing[0] == 0:
        return
    row = world_row(particle_world[pi], world_count)
    if relaxing[row] != 0 and lambda_rho[i][1] - 1.0 > PLACEMENT_TOLERANCE:
        packed[row] = 1


@wp.kernel
def keep_packed_worlds_relaxing(
    packed: wp.array[wp.int32],
    # outputs
    relaxing: wp.array[wp.int32],
    any_relaxing: wp.array[wp.int32],
    rounds_left: wp.array[wp.int32],
    found: wp.array[float],
):
    """A world relaxes on while it is packed and rounds are left; ``any_relaxing`` is whether any does (one thread).

    Once the rounds run out, a world still packed is counted in ``found[2]`` for the report and stops.
    """
    if any_relaxing[0] == 0:
        return
    left = int(0)
    for w in range(packed.shape[0]):
        r = relaxing[w] * packed[w]
        relaxing[w] = r
        packed[w] = 0
        left += r
    budget = rounds_left[0]
    if left > 0 and budget == 0:
        found[2] = found[2] + float(left)
        for w in range(relaxing.shape[0]):
            relaxing[w] = 0
        left = 0
    rounds_left[0] = budget - 1
    any_relaxing[0] = wp.min(left, 1)


@wp.kernel
def refresh_relaxed_contacts(
    contact_count: wp.array[int],
    contact_particle: wp.array[int],
    contact_shape: wp.array[int],
    contact_max: int,
    particle_flags: wp.array[wp.int32],
    particle_world: wp.array[wp.int32],
    particle_q: wp.array[wp.vec3],
    world_count: int,
    placed: wp.array[wp.int32],
    shapes: GuardedShapes,
    measured: int,
    shape_transform: wp.array[wp.transform],
    shape_body: wp.array[int],
    body_q: wp.array[wp.transform],
    # outputs
    contact_body_pos: wp.array[wp.vec3],
    contact_normal: wp.array[wp.vec3],
):
    """Find again the step's particle-shape contacts of the fluid a relaxation moved.

    They were found at the packed positions: a particle moved out of a box through another face than
    the one its contact names would be pushed back through the box. Each such contact becomes the
    plane at the shape's surface point nearest to where the particle is now
    (:func:`~.continuous_collision.guarded_surface_distance` of ``shapes``, the placement's guard, while
    ``measured``); without a guard the
    plane is put a metre behind the particle, out of reach for the step (the next collision finds it
    again).
    """
    k = wp.tid()
    if k >= wp.min(contact_count[0], contact_max):
        return
    pi = contact_particle[k]
    if (particle_flags[pi] & ParticleFlags.FLUID) == 0:
        return
    if placed[world_row(particle_world[pi], world_count)] != RELAXED:
        return
    s = contact_shape[k]
    b = shape_body[s]
    body = wp.transform_identity()
    if b >= 0:
        body = body_q[b]
    pose = body * shape_transform[s]
    x = particle_q[pi]
    local = wp.transform_point(wp.transform_inverse(pose), x)
    hit = wp.vec4(0.0, 0.0, 1.0, 1.0e10)
    if measured != 0:
        hit = guarded_surface_distance(shapes, s, local, 1.0e6)
    normal = contact_normal[k]
    surface = x - normal
    if hit[3] < 1.0e9:
        normal = wp.transform_vector(pose, wp.vec3(hit[0], hit[1], hit[2]))
        surface = x - hit[3] * normal
    contact_normal[k] = normal
    contact_body_pos[k] = wp.transform_point(wp.transform_inverse(body), surface)


@wp.kernel
def clear_placement(
    # outputs
    placed: wp.array[wp.int32],
    any_placed: wp.array[wp.int32],
    relaxing: wp.array[wp.int32],
    any_relaxing: wp.array[wp.int32],
):
    """Forget the placement: no world placed or relaxing."""
    w = wp.tid()
    placed[w] = 0
    relaxing[w] = 0
    if w == 0:
        any_placed[0] = 0
        any_relaxing[0] = 0
