# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Static and kinematic walls in the density: the ghost fluid behind a wall, from the step's contacts.

A fluid particle by a wall misses the neighbours the wall stands in for; each static or kinematic
shape the particle touches is listed for its slot as a plane (:func:`list_wall_contact`, once per
step, from upstream's particle-shape contacts) and lends the density of a rest lattice continued
beyond it (:func:`fluid_wall_share`, from tables made at construction:
:func:`~.calibration.wall_density_tables`).

The half-spaces are the solid only beside flat faces. By a box's edge or corner the solid is what lies
behind two or three faces (:func:`~.calibration.wall_edge_tables`): the edge's plane would count water
the particle's own sum holds already (a rest lattice read 4.6 % over the rest density diagonal to an
edge). Where two walls meet square (a tank's wall and its floor) both half-spaces hold the quadrant
behind the two, which is lent once. Once per step, :func:`scale_wall_shares` measures the solid's share
of each slot at its listed position against the planes' and keeps the ratio, by which the passes scale
the planes' share: the passes stay as light as the planes alone.
"""

import warp as wp

from ....geometry import GeoType
from ....sim.enums import BodyFlags
from .calibration import EDGE_TABLE_SIZE, WALL_TABLE_SIZE
from .sph import FluidParams, FluidSlots

# approximate division and square root in CUDA code (no effect on the CPU; see :mod:`.sph`)
wp.set_module_options({"fast_math": True})

# static-wall contacts whose ghost density a fluid particle can take (more are left out of its density;
# a particle in the corner of a box tank has three)
WALL_CONTACTS_PER_SLOT = 4

# |cos| of the angle between two walls' normals below which they meet square (a tank's wall and floor)
PERPENDICULAR = wp.constant(0.05)


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
def plane_density(dist: float, p: FluidParams, wall_table: wp.array[float], wall_table_grad: wp.array[float]):
    """The half-space's share of ``rho / rho0`` (``y``) and its derivative against ``dist`` (``x``)."""
    u = dist / p.wall_table_step
    j = wp.min(int(u), WALL_TABLE_SIZE - 2)
    f = u - float(j)
    c = wall_table[j] * (1.0 - f) + wall_table[j + 1] * f
    dc = wall_table_grad[j] * (1.0 - f) + wall_table_grad[j + 1] * f
    return wp.vec2(dc, c) * p.wall_scale


@wp.func
def planes_share(
    slots: FluidSlots,
    i: int,
    x: wp.vec3,
    p: FluidParams,
    wall_table: wp.array[float],
    wall_table_grad: wp.array[float],
):
    """The listed planes' half-spaces' share of slot ``i``'s ``rho / rho0`` (:func:`fluid_wall_share`, unscaled)."""
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
            half = plane_density(dist, p, wall_table, wall_table_grad)
            share += wp.vec4(normal[0] * half[0], normal[1] * half[0], normal[2] * half[0], half[1]) * float(found)
    return share


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
    sum of three or more floats depends on its order. The sum is scaled by the slot's share of the
    solid behind them (:func:`scale_wall_shares`).
    """
    return planes_share(slots, i, x, p, wall_table, wall_table_grad) * slots.wall_factor[i]


@wp.func
def box_density(dist: float, depth: float, depth2: float, p: FluidParams, wall_table: wp.array[float]):
    """A box's share of ``rho / rho0`` by an edge or a corner.

    ``dist`` outside the first face, ``depth`` and ``depth2`` behind the planes of the second and the
    third (``h``: none). Trilinear in :func:`~.calibration.wall_edge_tables`, stored after the plane's
    table.
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
    value = float(0.0)
    for corner in range(8):
        di = corner & 1
        dj = (corner >> 1) & 1
        dk = (corner >> 2) & 1
        weight = wp.where(di == 1, fu, 1.0 - fu) * wp.where(dj == 1, fv, 1.0 - fv) * wp.where(dk == 1, fw, 1.0 - fw)
        value += wall_table[WALL_TABLE_SIZE + ((i + di) * EDGE_TABLE_SIZE + j + dj) * EDGE_TABLE_SIZE + k + dk] * weight
    return value * p.wall_scale


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


@wp.func
def box_face_plane(pose: wp.transform, scale: wp.vec3, axis: int, p: wp.vec3):
    """The world plane (outward normal, offset) of the box face on ``axis`` on the side of local point ``p``."""
    side = wp.where(p[axis] >= 0.0, 1.0, -1.0)
    local = wp.vec3(0.0)
    local[axis] = side
    normal = wp.transform_vector(pose, local)
    return wp.vec4(normal[0], normal[1], normal[2], wp.dot(normal, wp.transform_point(pose, local * scale[axis])))


@wp.func
def box_faces(pose: wp.transform, scale: wp.vec3, x: wp.vec3, reach: float):
    """The faces of a box that the solid within ``reach`` of ``x`` lies behind, as planes (outward normal, offset).

    The particle lies furthest outside the first face; the second is the next furthest, if within
    ``reach`` (behind its plane or outside it), and the third likewise; a face not needed is a zero
    vector. Inside the box (its contact pushes the particle out) there is no face.
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
    if q[first] <= 0.0:
        return none, none, none
    face = box_face_plane(pose, scale, first, p)
    edge = none
    corner = none
    if q[second] > -reach:
        edge = box_face_plane(pose, scale, second, p)
    if q[third] > -reach:
        corner = box_face_plane(pose, scale, third, p)
    return face, edge, corner


@wp.func
def behind(face: wp.vec4, x: wp.vec3):
    """How deep ``x`` lies behind a face's plane (outward normal, offset) [m]: negative outside it."""
    return face[3] - (face[0] * x[0] + face[1] * x[1] + face[2] * x[2])


@wp.func
def wall_after(plane_a: wp.vec4, shape_a: int, plane_b: wp.vec4, shape_b: int):
    """Whether a listed wall comes after another: by plane (:func:`plane_after`), then by shape."""
    if plane_after(plane_a, plane_b):
        return True
    if plane_after(plane_b, plane_a):
        return False
    return shape_a > shape_b


@wp.func
def next_wall(slots: FluidSlots, i: int, after_last: bool, last: wp.vec4, last_shape: int):
    """The first wall of slot ``i`` in :func:`wall_after`'s order (after the ``last`` one if ``after_last``).

    Returns how often it is listed (0: none left), its plane and its shape.
    """
    n = slots.particle.shape[0]
    count = wp.min(slots.wall_count[i], WALL_CONTACTS_PER_SLOT)
    found = int(0)
    plane = wp.vec4(0.0)
    shape = int(-1)
    for e in range(count):
        q = slots.wall_plane[e * n + i]
        qs = slots.wall_shape[e * n + i]
        if after_last and not wall_after(q, qs, last, last_shape):
            continue
        if found == 0 or wall_after(plane, shape, q, qs):
            plane = q
            shape = qs
            found = 1
        elif q == plane and qs == shape:
            found += 1
    return found, plane, shape


@wp.func
def wall_pose(walls: FluidWallContacts, shape: int):
    """World pose of a listed wall's shape (a kinematic body's where it is during the step)."""
    pose = walls.shape_transform[shape]
    body = walls.shape_body[shape]
    if body >= 0:
        pose = walls.body_q[body] * pose
    return pose


@wp.func
def wall_faces(walls: FluidWallContacts, shape: int, x: wp.vec3, reach: float):
    """:func:`box_faces` of a listed wall's shape if it is a box (else no face)."""
    if walls.shape_type[shape] == GeoType.BOX:
        return box_faces(wall_pose(walls, shape), walls.shape_scale[shape], x, reach)
    none = wp.vec4(0.0)
    return none, none, none


@wp.func
def solid_share(
    slots: FluidSlots,
    i: int,
    x: wp.vec3,
    walls: FluidWallContacts,
    p: FluidParams,
    wall_table: wp.array[float],
    wall_table_grad: wp.array[float],
):
    """The share of slot ``i``'s ``rho / rho0`` that the solid behind its listed walls holds, at ``x``.

    Each wall in :func:`wall_after`'s order: a box by an edge or a corner lends what lies behind its faces
    there (:func:`box_faces`, :func:`box_density`); any other wall its plane's half-space, less the quadrant
    it shares with each later such wall whose plane meets it square (lent by both).
    """
    count = wp.min(slots.wall_count[i], WALL_CONTACTS_PER_SLOT)
    total = float(0.0)
    last = wp.vec4(0.0)
    last_shape = int(-1)
    for t in range(count):
        found, plane, shape = next_wall(slots, i, t > 0, last, last_shape)
        if found == 0:
            break
        last = plane
        last_shape = shape
        face, edge, corner = wall_faces(walls, shape, x, p.h)
        if wp.length_sq(edge) > 0.0:
            depth2 = p.h
            if wp.length_sq(corner) > 0.0:
                depth2 = behind(corner, x)
            total += box_density(-behind(face, x), behind(edge, x), depth2, p, wall_table) * float(found)
            continue
        normal = wp.vec3(plane[0], plane[1], plane[2])
        dist = wp.max(wp.dot(normal, x) - plane[3], 0.0)
        if dist >= p.h:
            continue
        total += plane_density(dist, p, wall_table, wall_table_grad)[1] * float(found)
        # the quadrant it shares with each later plane that meets it square, taken off once
        other_last = plane
        other_last_shape = shape
        for _u in range(t + 1, count):
            other_found, other, other_shape = next_wall(slots, i, True, other_last, other_last_shape)
            if other_found == 0:
                break
            other_last = other
            other_last_shape = other_shape
            # (a box by its edge lends only what lies behind its faces)
            other_face, other_edge, other_corner = wall_faces(walls, other_shape, x, p.h)
            if wp.length_sq(other_edge) > 0.0:
                continue
            other_normal = wp.vec3(other[0], other[1], other[2])
            if wp.abs(wp.dot(normal, other_normal)) > PERPENDICULAR:
                continue
            other_dist = wp.max(wp.dot(other_normal, x) - other[3], 0.0)
            if other_dist < p.h:
                total -= box_density(dist, -other_dist, p.h, p, wall_table) * float(found * other_found)
    return total


@wp.kernel
def scale_wall_shares(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    walls: FluidWallContacts,
    wall_table: wp.array[float],
    wall_table_grad: wp.array[float],
):
    """Once per step, after the walls are listed: each slot's solid share over its planes' (1 for no wall).

    The passes scale the planes' share and its gradient by it (:func:`fluid_wall_share`): exact at the
    listed position, and the planes' gradient between.
    """
    i = wp.tid()
    if slots.particle[i] < 0:
        return
    factor = float(1.0)
    if slots.wall_count[i] > 0:
        p = params[0]
        xm = slots.xm[i]
        x = wp.vec3(xm[0], xm[1], xm[2])
        planes = planes_share(slots, i, x, p, wall_table, wall_table_grad)[3]
        if planes > 1.0e-6:
            # (a contact's plane supports its convex shape, and a corner's quadrant is lent at most twice: the
            # solid never lends more than the planes; clamped, a plane at the end of its taper cannot blow up)
            factor = wp.clamp(solid_share(slots, i, x, walls, p, wall_table, wall_table_grad) / planes, 0.0, 1.0)
    slots.wall_factor[i] = factor


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
        n = slots.particle.shape[0]
        slots.wall_plane[t * n + slot] = plane
        slots.wall_shape[t * n + slot] = walls.shape[k]
