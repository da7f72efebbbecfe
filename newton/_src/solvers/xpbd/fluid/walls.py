# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Static and kinematic walls in the density: the ghost fluid behind a wall, from the step's contacts.

A fluid particle by a wall misses the neighbours the wall stands in for; each static or kinematic
shape the particle touches is listed for its slot as a plane (:func:`list_wall_contact`, once per
step, from upstream's particle-shape contacts) and lends the density of a rest lattice continued
beyond it (:func:`fluid_wall_share`, from tables made at construction:
:func:`~.config.wall_density_tables`).
"""

import warp as wp

from ....sim.enums import BodyFlags
from .sph import FluidParams, FluidSlots

# approximate division and square root in CUDA code (no effect on the CPU; see :mod:`.sph`)
wp.set_module_options({"fast_math": True})

# static-wall contacts whose ghost density a fluid particle can take (more are left out of its density;
# a particle in the corner of a box tank has three)
WALL_CONTACTS_PER_SLOT = 4


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
