# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Static and kinematic walls in the density: the ghost fluid behind a wall, from the step's contacts.

A fluid particle by a wall misses the neighbours the wall stands in for; each static or kinematic
shape the particle touches is listed for its slot as a plane (:func:`list_wall_contact`, once per
step, from upstream's particle-shape contacts) and lends the density of a rest lattice continued
beyond it (:func:`fluid_wall_share`, from tables made at construction:
:func:`~.calibration.wall_density_tables`). Within ``h`` of a box's edge or corner the solid is not
that half-space but what lies behind two or three faces, which lends the density of
:func:`~.calibration.wall_edge_tables`: the plane's half-space would count water the particle's own
sum holds already (a rest lattice read 4.6 % over the rest density diagonal to an edge). Where two
perpendicular planes meet (a tank's wall and its floor), the quadrant behind both is lent once.
"""

import warp as wp

from ....geometry import GeoType
from ....sim.enums import BodyFlags
from .calibration import EDGE_TABLE_SIZE, WALL_TABLE_SIZE
from .sph import FluidParams, FluidSlots

# approximate division and square root in CUDA code (no effect on the CPU; see :mod:`.sph`)
wp.set_module_options({"fast_math": True})

# |cos| of the angle between two walls' normals below which they meet square (a tank's wall and floor)
PERPENDICULAR = wp.constant(0.05)

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
def wall_after(
    plane_a: wp.vec4, edge_a: wp.vec4, corner_a: wp.vec4, plane_b: wp.vec4, edge_b: wp.vec4, corner_b: wp.vec4
):
    """Whether wall ``a`` comes after ``b``: by plane (:func:`plane_after`), then its edge's face, then its corner's."""
    # (vectors compare by == only)
    if not (plane_a == plane_b):
        return plane_after(plane_a, plane_b)
    if not (edge_a == edge_b):
        return plane_after(edge_a, edge_b)
    return plane_after(corner_a, corner_b)


@wp.func
def box_density(
    dist: float,
    depth: float,
    depth2: float,
    p: FluidParams,
    wall_table: wp.array[float],
    wall_table_grad: wp.array[float],
):
    """A box's share of ``rho / rho0`` by an edge or a corner (``w``), and its derivatives (``xyz``).

    ``dist`` outside the first face, ``depth`` and ``depth2`` behind the planes of the second and the
    third (``h`` for none); the derivatives against the three. Trilinear in
    :func:`~.calibration.wall_edge_tables`, stored after the plane's table in both arrays (the
    derivatives against the depths after the one against ``dist``).
    """
    u = dist / p.wall_table_step
    i = wp.min(int(u), WALL_TABLE_SIZE - 2)
    fu = u - float(i)
    depth_step = 2.0 * p.h / float(EDGE_TABLE_SIZE - 1)
    v = (wp.clamp(depth, -p.h, p.h) + p.h) / depth_step
    j = wp.min(int(v), EDGE_TABLE_SIZE - 2)
    fv = v - float(j)
    w = (wp.clamp(depth2, -p.h, p.h) + p.h) / depth_step
    k = wp.min(int(w), EDGE_TABLE_SIZE - 2)
    fw = w - float(k)
    size = WALL_TABLE_SIZE * EDGE_TABLE_SIZE * EDGE_TABLE_SIZE
    share = wp.vec4(0.0)
    for corner in range(8):
        di = corner & 1
        dj = (corner >> 1) & 1
        dk = (corner >> 2) & 1
        weight = wp.where(di == 1, fu, 1.0 - fu) * wp.where(dj == 1, fv, 1.0 - fv) * wp.where(dk == 1, fw, 1.0 - fw)
        at = WALL_TABLE_SIZE + ((i + di) * EDGE_TABLE_SIZE + j + dj) * EDGE_TABLE_SIZE + k + dk
        sample = wp.vec4(
            wall_table_grad[at], wall_table_grad[at + size], wall_table_grad[at + 2 * size], wall_table[at]
        )
        share += sample * weight
    # beyond the table's depths the solid no longer changes with them
    if depth <= -p.h or depth >= p.h:
        share[1] = 0.0
    if depth2 <= -p.h or depth2 >= p.h:
        share[2] = 0.0
    return share * p.wall_scale


@wp.func
def next_wall(slots: FluidSlots, i: int, after_last: bool, last: wp.vec4, last_edge: wp.vec4, last_corner: wp.vec4):
    """The first wall of slot ``i`` in :func:`wall_after`'s order (after the ``last`` one if ``after_last``).

    Returns how often it is listed (0: none left), its plane, its edge's face and its corner's.
    """
    n = slots.particle.shape[0]
    count = wp.min(slots.wall_count[i], WALL_CONTACTS_PER_SLOT)
    found = int(0)
    plane = wp.vec4(0.0)
    edge = wp.vec4(0.0)
    corner = wp.vec4(0.0)
    for e in range(count):
        q = slots.wall_plane[e * n + i]
        qe = slots.wall_edge[e * n + i]
        qc = slots.wall_corner[e * n + i]
        if after_last and not wall_after(q, qe, qc, last, last_edge, last_corner):
            continue
        if found == 0 or wall_after(plane, edge, corner, q, qe, qc):
            plane = q
            edge = qe
            corner = qc
            found = 1
        elif q == plane and qe == edge and qc == corner:
            found += 1
    return found, plane, edge, corner


@wp.func
def plane_density(dist: float, p: FluidParams, wall_table: wp.array[float], wall_table_grad: wp.array[float]):
    """The half-space's share of ``rho / rho0`` (``y``) and its derivative against ``dist`` (``x``)."""
    u = dist / p.wall_table_step
    j = wp.min(int(u), WALL_TABLE_SIZE - 2)
    f = u - float(j)
    c = wall_table[j] * (1.0 - f) + wall_table[j + 1] * f
    dc = wall_table_grad[j] * (1.0 - f) + wall_table_grad[j + 1] * f
    return wp.vec2(dc, c) * p.wall_scale


@wp.func
def behind(face: wp.vec4, x: wp.vec3):
    """How deep ``x`` lies behind a face's plane (outward normal, offset) [m]: negative outside it."""
    return face[3] - (face[0] * x[0] + face[1] * x[1] + face[2] * x[2])


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
    :func:`wall_after` (:func:`next_wall`; equal walls at once): the contacts arrive in any order on a
    GPU, and the sum of three or more floats depends on its order.

    - A box's wall by an edge or a corner (listed with its second face, and its third: outward normal
      and offset, a zero normal for none) lends what lies behind all of them (:func:`box_density`).
    - Two perpendicular planes (a concave corner: a tank's wall and its floor) both lend the quadrant
      behind the two; the second time is taken off, as the wedge behind the first at ``-dist`` of the
      second.
    """
    count = wp.min(slots.wall_count[i], WALL_CONTACTS_PER_SLOT)
    share = wp.vec4(0.0)
    last = wp.vec4(0.0)
    last_edge = wp.vec4(0.0)
    last_corner = wp.vec4(0.0)
    for t in range(count):
        found, plane, edge, corner = next_wall(slots, i, t > 0, last, last_edge, last_corner)
        if found == 0:
            break
        last = plane
        last_edge = edge
        last_corner = corner
        normal = wp.vec3(plane[0], plane[1], plane[2])
        dist = wp.max(wp.dot(normal, x) - plane[3], 0.0)
        if dist >= p.h:
            continue
        side = wp.vec3(edge[0], edge[1], edge[2])
        if wp.length_sq(side) > 0.0:
            side2 = wp.vec3(corner[0], corner[1], corner[2])
            depth2 = p.h
            if wp.length_sq(side2) > 0.0:
                depth2 = behind(corner, x)
            solid = box_density(dist, behind(edge, x), depth2, p, wall_table, wall_table_grad)
            # the depths fall along the faces' outward normals
            g = normal * solid[0] - side * solid[1] - side2 * solid[2]
            share += wp.vec4(g[0], g[1], g[2], solid[3]) * float(found)
            continue
        half = plane_density(dist, p, wall_table, wall_table_grad)
        share += wp.vec4(normal[0] * half[0], normal[1] * half[0], normal[2] * half[0], half[1]) * float(found)
        # the quadrant this plane shares with each later perpendicular plane, taken off once
        other_last = plane
        other_last_edge = edge
        other_last_corner = corner
        for _u in range(t + 1, count):
            other_found, other, other_edge, other_corner = next_wall(
                slots, i, True, other_last, other_last_edge, other_last_corner
            )
            if other_found == 0:
                break
            other_last = other
            other_last_edge = other_edge
            other_last_corner = other_corner
            if wp.length_sq(wp.vec3(other_edge[0], other_edge[1], other_edge[2])) > 0.0:
                continue
            other_normal = wp.vec3(other[0], other[1], other[2])
            if wp.abs(wp.dot(normal, other_normal)) > PERPENDICULAR:
                continue
            other_dist = wp.max(wp.dot(other_normal, x) - other[3], 0.0)
            if other_dist >= p.h:
                continue
            quadrant = box_density(dist, -other_dist, p.h, p, wall_table, wall_table_grad)
            # the depth behind the other plane is -other_dist: it falls along that plane's normal
            g = normal * quadrant[0] - other_normal * quadrant[1]
            share -= wp.vec4(g[0], g[1], g[2], quadrant[3]) * float(found * other_found)
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
    shape_type: wp.array[wp.int32]
    shape_scale: wp.array[wp.vec3]
    shape_transform: wp.array[wp.transform]  # in the body's frame (static: world)
    reach: float  # a box's second face within this of the particle makes its wall an edge [m] (the kernel's h)


@wp.func
def box_face_plane(pose: wp.transform, scale: wp.vec3, axis: int, p: wp.vec3):
    """The world plane (outward normal, offset) of the box face on ``axis`` on the side of local point ``p``."""
    side = wp.where(p[axis] >= 0.0, 1.0, -1.0)
    local = wp.vec3(0.0)
    local[axis] = side
    normal = wp.transform_vector(pose, local)
    return wp.vec4(normal[0], normal[1], normal[2], wp.dot(normal, wp.transform_point(pose, local * scale[axis])))


@wp.func
def box_edge(pose: wp.transform, scale: wp.vec3, x: wp.vec3, reach: float, plane: wp.vec4):
    """A box wall's plane, edge and corner (:func:`fluid_wall_share`), from where the particle lies.

    The particle lies furthest outside the first face; the second is the next furthest, if within
    ``reach`` (behind its plane or outside it), and the third likewise. Outside ``reach`` of any edge,
    or inside the box (its contact pushes it out), the contact's ``plane`` stays and there is no edge
    (a zero vector).
    """
    p = wp.transform_point(wp.transform_inverse(pose), x)
    q = wp.vec3(wp.abs(p[0]) - scale[0], wp.abs(p[1]) - scale[1], wp.abs(p[2]) - scale[2])
    # the axes by how far the particle lies outside their faces
    first = int(0)
    if q[1] > q[first]:
        first = 1
    if q[2] > q[first]:
        first = 2
    second = wp.where(first == 0, 1, 0)
    third = 3 - first - second
    if q[third] > q[second]:
        second, third = third, second
    none = wp.vec4(0.0)
    if q[first] <= 0.0 or q[second] <= -reach:
        return plane, none, none
    corner = none
    if q[third] > -reach:
        corner = box_face_plane(pose, scale, third, p)
    return box_face_plane(pose, scale, first, p), box_face_plane(pose, scale, second, p), corner


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
        edge = wp.vec4(0.0)
        corner = wp.vec4(0.0)
        shape = walls.shape[k]
        if walls.shape_type[shape] == GeoType.BOX:
            pose = walls.shape_transform[shape]
            if body >= 0:
                pose = walls.body_q[body] * pose
            xm = slots.xm[slot]
            x = wp.vec3(xm[0], xm[1], xm[2])
            plane, edge, corner = box_edge(pose, walls.shape_scale[shape], x, walls.reach, plane)
        n = slots.particle.shape[0]
        slots.wall_plane[t * n + slot] = plane
        slots.wall_edge[t * n + slot] = edge
        slots.wall_corner[t * n + slot] = corner
