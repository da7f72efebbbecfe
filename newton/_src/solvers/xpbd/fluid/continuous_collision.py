# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Continuous collision of fluid particles with static and kinematic shapes.

Upstream's particle-shape contacts are found once per :meth:`~newton.CollisionPipeline.collide`,
within a small gap of each shape: a particle that travels further than that gap between two
collisions (20 m/s is a third of a metre per 1/60 s frame) meets no contact and passes through a
wall. After each substep this pass follows every fluid particle's path, from where the substep
started to where the solve left it, in the frame of each static or kinematic shape it can reach
(the shape's pose at the start of the substep for the start, at its end for the end, so a moving
wall that sweeps over a particle is met too). A kinematic body is where its ``body_q`` puts it at
the end of the substep and moved there at its ``body_qd`` (as a prescribed body is set before each
substep); a pose set without the velocity that gets it there is a jump, not a sweep. Where the path enters a shape, the particle is put
on the entry point's tangent plane at its radius (a contact the collision missed: frictionless and
inelastic, the motion along the wall kept) and its velocity is recomputed from its move, less
what still points into the wall. A path pushed off one shape is followed again, so a particle
thrown into a corner stops at every wall; one still entering a shape after ``GUARD_ROUNDS`` rounds
stops just before its first entry.

Boxes, spheres, capsules, straight cylinders, cones, ellipsoids and planes are intersected exactly; triangle
meshes (and convex hulls) by a ray cast against their BVH; heightfields triangle by triangle along the
cells the path crosses (:mod:`.heightfields`); barrel-sided cylinders (convex) by Newton's method on
the path's distance outside their side. Shapes of dynamic bodies are left to upstream's contacts: they
take the fluid's reaction, which a hard stop would not give them.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ....geometry import GeoType, ParticleFlags, ShapeFlags
from ....sim.enums import BodyFlags
from ....utils.heightfield import HeightfieldData
from .heightfields import heightfield_distance, heightfield_entry

# a segment parameter past the end of the path: no entry
NO_ENTRY = wp.constant(2.0)
# rounds of following a path pushed off a shape; the last one stops the particle before its entry
# (passed as a kernel argument: Warp unrolls a loop over a constant count, which would copy the shape
# tests four times into the kernel)
GUARD_ROUNDS = 4
# the stop before an entry, as a share of the path (keeps the stopped centre outside under rounding)
STOP_SHORT = wp.constant(1.0e-4)
# most Newton steps into a barrel-sided cylinder's side (they converge from outside, quadratically once close)
BARREL_STEPS = wp.constant(24)
# shape types this pass intersects
GUARDED_TYPES = (
    GeoType.PLANE,
    GeoType.SPHERE,
    GeoType.BOX,
    GeoType.CAPSULE,
    GeoType.CYLINDER,
    GeoType.CONE,
    GeoType.ELLIPSOID,
    GeoType.MESH,
    GeoType.CONVEX_MESH,
    GeoType.HFIELD,
)


@wp.struct
class GuardedShapes:
    """The static and kinematic shapes each world's fluid can reach, with what their intersection needs."""

    row_start: wp.array[wp.int32]  # shapes of world w: shape[row_start[w]:row_start[w + 1]]; row world_count: all
    shape: wp.array[wp.int32]
    world_count: int
    shape_type: wp.array[wp.int32]
    shape_scale: wp.array[wp.vec3]
    shape_source: wp.array[wp.uint64]
    # 1 for a watertight mesh: inside it is inside (an open one has two sides); measured for the placement's
    # guard only (one zero otherwise: the paths' intersection needs no inside)
    shape_solid: wp.array[wp.int32]
    shape_heightfield: wp.array[wp.int32]  # a heightfield shape's row in heightfield (-1: none)
    heightfield: wp.array[HeightfieldData]
    heightfield_elevation: wp.array[wp.float32]
    shape_transform: wp.array[wp.transform]
    shape_body: wp.array[wp.int32]
    body_q: wp.array[wp.transform]  # body poses at the end of the substep
    body_qd: wp.array[wp.spatial_vector]  # their velocities over it (linear of the centre of mass, angular)
    body_com: wp.array[wp.vec3]  # centres of mass in the bodies' frames [m]
    dt: float  # substep [s]
    local_lower: wp.array[wp.vec3]  # bounds of each shape in its own frame [m] (x below -1e29: unbounded)
    local_upper: wp.array[wp.vec3]
    lower: wp.array[wp.vec3]  # world bounds of each guarded shape over the substep [m]
    upper: wp.array[wp.vec3]


@wp.func
def _entry(t: float, n: wp.vec3):
    return wp.vec4(n[0], n[1], n[2], t)


@wp.func
def _no_entry():
    return wp.vec4(0.0, 0.0, 1.0, NO_ENTRY)


@wp.func
def _box_interval(a: wp.vec3, d: wp.vec3, lo: wp.vec3, hi: wp.vec3):
    """Parameters where ``a + t d`` enters and leaves the box ``[lo, hi]`` (enter > leave: it misses), and the entry face's normal."""
    t_in = float(-1.0e30)
    t_out = float(1.0e30)
    n = wp.vec3(0.0)
    for k in range(3):
        if wp.abs(d[k]) < 1.0e-30:
            if a[k] < lo[k] or a[k] > hi[k]:
                t_in = 1.0e30
        else:
            t1 = (lo[k] - a[k]) / d[k]
            t2 = (hi[k] - a[k]) / d[k]
            near = wp.min(t1, t2)
            if near > t_in:
                t_in = near
                n = wp.vec3(0.0)
                n[k] = -wp.sign(d[k])
            t_out = wp.min(t_out, wp.max(t1, t2))
    return t_in, t_out, n


@wp.func
def _sphere_interval(a: wp.vec3, d: wp.vec3, c: wp.vec3, radius: float):
    """Parameters where ``a + t d`` enters and leaves the ball of ``radius`` about ``c``, and the entry normal."""
    f = a - c
    qa = wp.dot(d, d)
    qb = wp.dot(f, d)
    qc = wp.dot(f, f) - radius * radius
    disc = qb * qb - qa * qc
    if qa < 1.0e-30 or disc < 0.0:
        # no motion: inside for all t or never
        return wp.where(qc <= 0.0, -1.0e30, 1.0e30), wp.where(qc <= 0.0, 1.0e30, -1.0e30), wp.vec3(0.0, 0.0, 1.0)
    root = wp.sqrt(disc)
    t_in = (-qb - root) / qa
    n = (f + t_in * d) / radius
    return t_in, (-qb + root) / qa, n


@wp.func
def _tube_interval(a: wp.vec3, d: wp.vec3, radius: float):
    """Parameters where ``a + t d`` enters and leaves the infinite cylinder of ``radius`` about the z axis."""
    qa = d[0] * d[0] + d[1] * d[1]
    qb = a[0] * d[0] + a[1] * d[1]
    qc = a[0] * a[0] + a[1] * a[1] - radius * radius
    disc = qb * qb - qa * qc
    if qa < 1.0e-30 or disc < 0.0:
        return wp.where(qc <= 0.0, -1.0e30, 1.0e30), wp.where(qc <= 0.0, 1.0e30, -1.0e30), wp.vec3(1.0, 0.0, 0.0)
    root = wp.sqrt(disc)
    t_in = (-qb - root) / qa
    p = a + t_in * d
    return t_in, (-qb + root) / qa, wp.vec3(p[0], p[1], 0.0) / radius


@wp.func
def _convex_entry(t_in: float, t_out: float, n: wp.vec3):
    """The entry of a path ``t`` in [0, 1] into a convex solid it overlaps for ``t`` in [t_in, t_out]; none from inside."""
    if t_in > t_out or t_in < 0.0 or t_in > 1.0:
        return _no_entry()
    return _entry(t_in, n)


@wp.func
def _slab_interval(a: wp.vec3, d: wp.vec3, half_height: float):
    """Parameters where ``a + t d`` enters and leaves the slab ``|z| <= half_height``, and the entry face's normal."""
    return _box_interval(a, d, wp.vec3(-1.0e30, -1.0e30, -half_height), wp.vec3(1.0e30, 1.0e30, half_height))


@wp.func
def _capped_entry(a: wp.vec3, d: wp.vec3, t_in: float, t_out: float, n: wp.vec3, half_height: float):
    """The entry of ``a + t d`` into a solid of the z axis it overlaps for ``t`` in [t_in, t_out] (entry normal
    ``n``), cut by the slab ``|z| <= half_height``."""
    s_in, s_out, s_n = _slab_interval(a, d, half_height)
    if s_in > t_in:
        return _convex_entry(s_in, wp.min(t_out, s_out), s_n)
    return _convex_entry(t_in, wp.min(t_out, s_out), n)


@wp.func
def _cylinder_entry(a: wp.vec3, d: wp.vec3, radius: float, half_height: float):
    t_in, t_out, n = _tube_interval(a, d, radius)
    return _capped_entry(a, d, t_in, t_out, n, half_height)


@wp.func
def barrel_bulge(z: float, half_height: float, barrel: float):
    """How far [m] a barrel-sided cylinder's side stands out at height ``z`` beyond its ends' radius.

    The side is an arc of radius ``barrel`` through both rims, revolved about the axis:
    ``sqrt(barrel^2 - z^2) - sqrt(barrel^2 - half_height^2)``, written without the difference of two near
    numbers that a flat arc (a large ``barrel``) would round away.
    """
    return (half_height * half_height - z * z) / (
        wp.sqrt(wp.max(barrel * barrel - z * z, 0.0))
        + wp.sqrt(wp.max(barrel * barrel - half_height * half_height, 0.0))
    )


@wp.func
def _barrel_excess(p: wp.vec3, d: wp.vec3, radius: float, barrel: float, half_height: float):
    """How far ``p`` lies outside a barrel-sided cylinder's side (its distance from the axis less the profile's
    radius at its height, ``g``), and ``g``'s rate along ``d``."""
    rho = wp.sqrt(p[0] * p[0] + p[1] * p[1])
    root = wp.sqrt(wp.max(barrel * barrel - p[2] * p[2], 1.0e-12 * barrel * barrel))
    rate = p[2] * d[2] / root
    if rho > 0.0:
        rate += (p[0] * d[0] + p[1] * d[1]) / rho
    return rho - radius - barrel_bulge(p[2], half_height, barrel), rate


@wp.func
def _barrel_entry(a: wp.vec3, d: wp.vec3, radius: float, half_height: float, barrel: float):
    """The entry of ``a + t d`` into a barrel-sided cylinder (end radius ``radius``, half height ``half_height``,
    side arc of radius ``barrel``).

    The solid is convex (a distance from the axis below a concave profile), so its excess ``g`` (see
    :func:`_barrel_excess`) is convex along the path: Newton's steps from the path's start in the slab
    ``|z| <= half_height`` approach the first root from below, never past it, and a rate that no longer falls
    means the path misses.
    """
    s_in, s_out, s_n = _slab_interval(a, d, half_height)
    lo = wp.max(s_in, 0.0)
    hi = wp.min(s_out, 1.0)
    if lo > hi:
        return _no_entry()
    t = lo
    g, rate = _barrel_excess(a + t * d, d, radius, barrel, half_height)
    if g <= 0.0:
        if s_in >= 0.0:
            # through an end cap
            return _entry(s_in, s_n)
        return _no_entry()
    # stop within a millionth of the shape's size of the side
    tolerance = 1.0e-6 * (radius + half_height)
    # a while loop: Warp would unroll a loop over a constant count
    k = int(0)
    while g > tolerance and k < BARREL_STEPS:
        if rate >= 0.0:
            return _no_entry()
        t = t - g / rate
        if t > hi:
            return _no_entry()
        g, rate = _barrel_excess(a + t * d, d, radius, barrel, half_height)
        k += 1
    p = a + t * d
    rho = wp.sqrt(p[0] * p[0] + p[1] * p[1])
    side = wp.where(rho > 0.0, wp.vec3(p[0], p[1], 0.0) / wp.max(rho, 1.0e-12), wp.vec3(1.0, 0.0, 0.0))
    # the arc's outward normal, (sqrt(barrel^2 - z^2), z) / barrel
    n = wp.normalize(wp.sqrt(wp.max(barrel * barrel - p[2] * p[2], 0.0)) * side + wp.vec3(0.0, 0.0, p[2]))
    return _entry(t, n)


@wp.func
def _cone_interval(a: wp.vec3, d: wp.vec3, radius: float, half_height: float):
    """Parameters where ``a + t d`` enters and leaves the infinite cone of the z axis with its apex at
    ``half_height`` opening downwards to ``radius`` at ``-half_height`` (its nappe below the apex), and the
    entry normal.

    Inside: ``rho <= k w`` with ``rho`` the distance from the axis, ``w = half_height - z`` and
    ``k = radius / (2 half_height)``, that is ``q(t) = k^2 w^2 - rho^2 >= 0`` with ``w >= 0``; ``q`` is
    quadratic in ``t`` (``A t^2 + 2 B t + C``) and its two nappes are told apart by the sign of ``w``.
    """
    k = radius / (2.0 * half_height)
    aw = half_height - a[2]
    dw = -d[2]
    qa = k * k * dw * dw - d[0] * d[0] - d[1] * d[1]
    qb = k * k * aw * dw - a[0] * d[0] - a[1] * d[1]
    qc = k * k * aw * aw - a[0] * a[0] - a[1] * a[1]
    lo = float(-1.0e30)
    hi = float(1.0e30)
    if wp.abs(qa) < 1.0e-30:
        # along a generator: q is linear
        if wp.abs(qb) < 1.0e-30:
            if qc < 0.0:
                lo = 1.0e30
        elif qb > 0.0:
            lo = -qc / (2.0 * qb)
        else:
            hi = -qc / (2.0 * qb)
    else:
        disc = qb * qb - qa * qc
        if disc < 0.0:
            if qa < 0.0:
                lo = 1.0e30
        else:
            root = wp.sqrt(disc)
            r1 = wp.min((-qb - root) / qa, (-qb + root) / qa)
            r2 = wp.max((-qb - root) / qa, (-qb + root) / qa)
            if qa < 0.0:
                lo = r1
                hi = r2
            elif aw + r1 * dw >= aw + r2 * dw:
                # the line crosses both nappes: the lower one is where w is positive at its root
                hi = r1
            else:
                lo = r2
    # w >= 0: below the apex
    if wp.abs(dw) < 1.0e-30:
        if aw < 0.0:
            lo = 1.0e30
    elif dw > 0.0:
        lo = wp.max(lo, -aw / dw)
    else:
        hi = wp.min(hi, -aw / dw)
    n = wp.vec3(0.0, 0.0, 1.0)
    if wp.abs(lo) < 1.0e29:
        p = a + lo * d
        slope = wp.vec3(p[0], p[1], k * wp.sqrt(p[0] * p[0] + p[1] * p[1]))
        if wp.length_sq(slope) > 0.0:
            n = wp.normalize(slope)
    return lo, hi, n


@wp.func
def _cone_entry(a: wp.vec3, d: wp.vec3, radius: float, half_height: float):
    t_in, t_out, n = _cone_interval(a, d, radius, half_height)
    return _capped_entry(a, d, t_in, t_out, n, half_height)


@wp.func
def _plane_entry(a: wp.vec3, d: wp.vec3, scale: wp.vec3):
    """An infinite plane is the half-space z < 0; a finite one (``scale`` its width and length) a sheet met from either side."""
    b = a + d
    finite = scale[0] > 0.0 and scale[1] > 0.0
    if not ((a[2] >= 0.0 and b[2] < 0.0) or (finite and a[2] <= 0.0 and b[2] > 0.0)):
        return _no_entry()
    t = a[2] / (a[2] - b[2])
    p = a + t * d
    if finite and (wp.abs(p[0]) > 0.5 * scale[0] or wp.abs(p[1]) > 0.5 * scale[1]):
        return _no_entry()
    return _entry(t, wp.vec3(0.0, 0.0, wp.sign(a[2] - b[2])))


@wp.func
def _mesh_entry(mesh: wp.uint64, a: wp.vec3, d: wp.vec3, scale: wp.vec3):
    """The first face the path crosses from its front (outside) side, by a ray cast in the mesh's own frame."""
    hit = wp.mesh_query_ray(mesh, wp.cw_div(a, scale), wp.cw_div(d, scale), 1.0)
    if not hit.result:
        return _no_entry()
    # normals map with the inverse transpose of the scale
    n = wp.normalize(wp.cw_div(hit.normal, scale))
    if wp.dot(n, d) >= 0.0:
        # it leaves the mesh: it started inside (upstream's contact pushes it out)
        return _no_entry()
    return _entry(hit.t, n)


@wp.func
def segment_entry(shape_type: int, scale: wp.vec3, source: wp.uint64, a: wp.vec3, d: wp.vec3):
    """Where the path ``a + t d``, ``t`` in [0, 1], first enters the shape from outside (``w``; ``NO_ENTRY``: it does
    not), and the shape's outward unit normal there (``xyz``), in the shape's frame.

    Heightfields need their grid: :func:`shape_entry`."""
    if shape_type == GeoType.BOX:
        t_in, t_out, n = _box_interval(a, d, -scale, scale)
        return _convex_entry(t_in, t_out, n)
    if shape_type == GeoType.SPHERE:
        t_in, t_out, n = _sphere_interval(a, d, wp.vec3(0.0), scale[0])
        return _convex_entry(t_in, t_out, n)
    if shape_type == GeoType.ELLIPSOID:
        # the unit ball in coordinates scaled by the semi-axes (t is the same)
        t_in, t_out, n = _sphere_interval(wp.cw_div(a, scale), wp.cw_div(d, scale), wp.vec3(0.0), 1.0)
        if t_in > t_out or t_in < 0.0 or t_in > 1.0:
            return _no_entry()
        return _entry(t_in, wp.normalize(wp.cw_div(n, scale)))
    if shape_type == GeoType.CYLINDER:
        if scale[2] > 0.0:
            return _barrel_entry(a, d, scale[0], scale[1], scale[2])
        return _cylinder_entry(a, d, scale[0], scale[1])
    if shape_type == GeoType.CONE:
        return _cone_entry(a, d, scale[0], scale[1])
    if shape_type == GeoType.CAPSULE:
        # a tube and two balls: from outside all three, the union is entered where the first of them is
        radius = scale[0]
        axis_z = wp.clamp(a[2], -scale[1], scale[1])
        if wp.length_sq(a - wp.vec3(0.0, 0.0, axis_z)) <= radius * radius:
            return _no_entry()
        best = _cylinder_entry(a, d, radius, scale[1])
        for side in range(2):
            c = wp.vec3(0.0, 0.0, wp.where(side == 0, -scale[1], scale[1]))
            t_in, t_out, n = _sphere_interval(a, d, c, radius)
            ball = _convex_entry(t_in, t_out, n)
            if ball[3] < best[3]:
                best = ball
        return best
    if shape_type == GeoType.PLANE:
        return _plane_entry(a, d, scale)
    if shape_type == GeoType.MESH or shape_type == GeoType.CONVEX_MESH:
        return _mesh_entry(source, a, d, scale)
    return _no_entry()


@wp.func
def shape_entry(shapes: GuardedShapes, s: int, a: wp.vec3, d: wp.vec3):
    """:func:`segment_entry` of guarded shape ``s``, heightfields included."""
    shape_type = shapes.shape_type[s]
    if shape_type == GeoType.HFIELD:
        return heightfield_entry(shapes.heightfield[shapes.shape_heightfield[s]], shapes.heightfield_elevation, a, d)
    return segment_entry(shape_type, shapes.shape_scale[s], shapes.shape_source[s], a, d)


@wp.func
def shape_poses(shapes: GuardedShapes, s: int):
    """World poses of shape ``s`` at the start and at the end of the substep (a kinematic body's rewound by its velocity)."""
    b = shapes.shape_body[s]
    local = shapes.shape_transform[s]
    if b < 0:
        return local, local
    end = shapes.body_q[b]
    qd = shapes.body_qd[b]
    w = wp.spatial_bottom(qd)
    # the rigid motion at constant velocity, undone about the centre of mass
    c = wp.transform_point(end, shapes.body_com[b])
    turn = wp.quat_identity()
    speed = wp.length(w)
    if speed > 0.0:
        turn = wp.quat_from_axis_angle(w / speed, -speed * shapes.dt)
    p = wp.transform_get_translation(end)
    c_start = c - wp.spatial_top(qd) * shapes.dt
    start = wp.transform(c_start + wp.quat_rotate(turn, p - c), turn * wp.transform_get_rotation(end))
    return start * local, end * local


@wp.func
def pose_bounds(pose: wp.transform, lo: wp.vec3, hi: wp.vec3):
    """World bounds of the local box ``[lo, hi]`` placed at ``pose``."""
    center = wp.transform_point(pose, 0.5 * (lo + hi))
    half = 0.5 * (hi - lo)
    rot = wp.quat_to_matrix(wp.transform_get_rotation(pose))
    extent = wp.vec3(0.0)
    for r in range(3):
        extent[r] = wp.abs(rot[r, 0]) * half[0] + wp.abs(rot[r, 1]) * half[1] + wp.abs(rot[r, 2]) * half[2]
    return center - extent, center + extent


@wp.kernel
def bound_guarded_shapes(shapes: GuardedShapes, guarded: wp.array[wp.int32]):
    """World bounds of each guarded shape over the substep: the union of its bounds at the start and at the end."""
    s = guarded[wp.tid()]
    lo = shapes.local_lower[s]
    hi = shapes.local_upper[s]
    if lo[0] < -1.0e29:
        shapes.lower[s] = wp.vec3(-1.0e30)
        shapes.upper[s] = wp.vec3(1.0e30)
        return
    start, end = shape_poses(shapes, s)
    lo0, hi0 = pose_bounds(start, lo, hi)
    lo1, hi1 = pose_bounds(end, lo, hi)
    # (a margin for the rounding of the poses)
    pad = 1.0e-5 * wp.length(hi - lo) + 1.0e-6
    shapes.lower[s] = wp.min(lo0, lo1) - wp.vec3(pad)
    shapes.upper[s] = wp.max(hi0, hi1) + wp.vec3(pad)


@wp.func
def first_shape_entry(shapes: GuardedShapes, lo: int, hi: int, x0: wp.vec3, x1: wp.vec3):
    """The earliest entry of the path ``x0 -> x1`` into shapes ``lo..hi`` of its row.

    Returns the entry parameter (``NO_ENTRY``: none), the entered shape's world-frame outward normal at
    the entry, the entry point at the end of the substep and where that point was at its start [m].
    """
    best = _no_entry()
    best_s = int(-1)
    best_local = wp.vec3(0.0)
    path_lo = wp.min(x0, x1)
    path_hi = wp.max(x0, x1)
    for k in range(lo, hi):
        s = shapes.shape[k]
        # most paths are far from most shapes: their bounds part
        s_lo = shapes.lower[s]
        s_hi = shapes.upper[s]
        if (
            path_hi[0] < s_lo[0]
            or path_hi[1] < s_lo[1]
            or path_hi[2] < s_lo[2]
            or path_lo[0] > s_hi[0]
            or path_lo[1] > s_hi[1]
            or path_lo[2] > s_hi[2]
        ):
            continue
        a = wp.vec3(0.0)
        b = wp.vec3(0.0)
        if shapes.shape_body[s] < 0:
            # a static shape: one pose
            into = wp.transform_inverse(shapes.shape_transform[s])
            a = wp.transform_point(into, x0)
            b = wp.transform_point(into, x1)
        else:
            start, end = shape_poses(shapes, s)
            a = wp.transform_point(wp.transform_inverse(start), x0)
            b = wp.transform_point(wp.transform_inverse(end), x1)
        e = shape_entry(shapes, s, a, b - a)
        if e[3] < best[3]:
            best = e
            best_s = s
            best_local = a + e[3] * (b - a)
    if best_s < 0:
        return NO_ENTRY, wp.vec3(0.0), wp.vec3(0.0), wp.vec3(0.0)
    start, end = shape_poses(shapes, best_s)
    normal = wp.transform_vector(end, wp.vec3(best[0], best[1], best[2]))
    return best[3], normal, wp.transform_point(end, best_local), wp.transform_point(start, best_local)


@wp.func
def stop_inward(v: wp.vec3, normal: wp.vec3, v_wall: wp.vec3):
    """``v`` less its velocity into a wall of outward ``normal`` moving at ``v_wall`` (an inelastic, frictionless hit)."""
    vn = wp.dot(v - v_wall, normal)
    if vn < 0.0:
        return v - vn * normal
    return v


@wp.func
def world_row(world: int, world_count: int):
    """Row of a world in the per-world arrays: its index, and ``world_count`` for the global world -1."""
    return wp.where(world >= 0 and world < world_count, world, world_count)


@wp.func
def shape_distance(shape_type: int, scale: wp.vec3, p: wp.vec3):
    """Signed distance [m] (xyz: outward normal in the shape frame, w: distance) of local point ``p``.

    Planes, spheres, capsules and boxes; any other shape reads as far away (1e10 m).
    """
    if shape_type == GeoType.PLANE:
        return wp.vec4(0.0, 0.0, 1.0, p[2])
    if shape_type == GeoType.SPHERE:
        r = wp.length(p)
        n = wp.where(r > 0.0, p / wp.max(r, 1.0e-12), wp.vec3(0.0, 0.0, 1.0))
        return wp.vec4(n[0], n[1], n[2], r - scale[0])
    if shape_type == GeoType.CAPSULE:
        axis_z = wp.clamp(p[2], -scale[1], scale[1])
        radial = p - wp.vec3(0.0, 0.0, axis_z)
        r = wp.length(radial)
        n = wp.where(r > 0.0, radial / wp.max(r, 1.0e-12), wp.vec3(1.0, 0.0, 0.0))
        return wp.vec4(n[0], n[1], n[2], r - scale[0])
    if shape_type == GeoType.BOX:
        q = wp.vec3(wp.abs(p[0]) - scale[0], wp.abs(p[1]) - scale[1], wp.abs(p[2]) - scale[2])
        outside = wp.vec3(wp.max(q[0], 0.0), wp.max(q[1], 0.0), wp.max(q[2], 0.0))
        out_len = wp.length(outside)
        if out_len > 0.0:
            n = wp.vec3(wp.sign(p[0]) * outside[0], wp.sign(p[1]) * outside[1], wp.sign(p[2]) * outside[2]) / out_len
            return wp.vec4(n[0], n[1], n[2], out_len)
        # inside: the nearest face
        n = wp.vec3(wp.sign(p[0]), 0.0, 0.0)
        depth = q[0]
        if q[1] > depth:
            n = wp.vec3(0.0, wp.sign(p[1]), 0.0)
            depth = q[1]
        if q[2] > depth:
            n = wp.vec3(0.0, 0.0, wp.sign(p[2]))
            depth = q[2]
        return wp.vec4(n[0], n[1], n[2], depth)
    return wp.vec4(0.0, 0.0, 1.0, 1.0e10)


@wp.func
def cylinder_distance(scale: wp.vec3, p: wp.vec3):
    """Signed distance [m] (xyz: outward normal, w: distance) of local ``p`` to a straight cylinder along z
    (radius ``scale[0]``, half height ``scale[1]``)."""
    radial = wp.vec3(p[0], p[1], 0.0)
    r = wp.length(radial)
    side = wp.where(r > 0.0, radial / wp.max(r, 1.0e-12), wp.vec3(1.0, 0.0, 0.0))
    cap = wp.vec3(0.0, 0.0, wp.where(p[2] >= 0.0, 1.0, -1.0))
    dr = r - scale[0]
    dz = wp.abs(p[2]) - scale[1]
    if dr > 0.0 and dz > 0.0:
        # beyond the rim: the rim's nearest point
        v = dr * side + dz * cap
        d = wp.length(v)
        n = v / d
        return wp.vec4(n[0], n[1], n[2], d)
    if dr > dz:
        return wp.vec4(side[0], side[1], side[2], dr)
    return wp.vec4(cap[0], cap[1], cap[2], dz)


@wp.func
def barrel_distance(scale: wp.vec3, p: wp.vec3):
    """Signed distance [m] (xyz: outward normal, w: distance) of local ``p`` to a barrel-sided cylinder along z
    (end radius ``scale[0]``, half height ``scale[1]``, side arc of radius ``scale[2]``).

    In the half-plane of ``p`` and the axis, folded to ``z >= 0``, the surface is the end's segment and the arc
    of radius ``scale[2]`` whose centre lies ``s = sqrt(scale[2]^2 - scale[1]^2)`` inside the rim's radius, from
    mid-height up to the rim. Offsets are taken from the rim, so a flat arc keeps its precision.
    """
    r = scale[0]
    hh = scale[1]
    barrel = scale[2]
    rho = wp.sqrt(p[0] * p[0] + p[1] * p[1])
    side = wp.where(rho > 0.0, wp.vec3(p[0], p[1], 0.0) / wp.max(rho, 1.0e-12), wp.vec3(1.0, 0.0, 0.0))
    up = wp.where(p[2] >= 0.0, 1.0, -1.0)
    # q: (radial, axial) offset from the rim's height and radius
    q = wp.vec2(rho - r, wp.abs(p[2]))
    s = wp.sqrt(wp.max(barrel * barrel - hh * hh, 0.0))
    from_centre = wp.vec2(q[0] + s, q[1])
    reach = wp.length(from_centre)
    # the circle's nearest point if it lies on the arc, else the rim (the arc's end nearer every such point)
    to_arc = wp.length(q - wp.vec2(0.0, hh))
    on_arc = False
    u = wp.vec2(1.0, 0.0)
    if reach > 1.0e-12:
        u = from_centre / reach
        on_arc = u[0] >= 0.0 and barrel * u[1] <= hh
    if on_arc:
        # |q - centre| - barrel, from the squares' difference
        to_arc = wp.abs((q[0] * q[0] + 2.0 * q[0] * s + q[1] * q[1] - hh * hh) / (reach + barrel))
    to_end = wp.length(wp.vec2(wp.max(q[0], 0.0), q[1] - hh))
    inside = q[1] <= hh and q[0] <= barrel_bulge(q[1], hh, barrel)
    sign = wp.where(inside, -1.0, 1.0)
    # outward: the arc's radial direction, or from the nearest point of the end (or the rim) to q, signed
    out = wp.vec2(0.0, 1.0)
    if to_end >= to_arc and on_arc:
        out = u
    elif to_end >= to_arc and to_arc > 1.0e-9:
        out = (q - wp.vec2(0.0, hh)) * (sign / to_arc)
    elif to_end < to_arc and to_end > 1.0e-9:
        out = wp.vec2(wp.max(q[0], 0.0), q[1] - hh) * (sign / to_end)
    n = out[0] * side + wp.vec3(0.0, 0.0, out[1] * up)
    return wp.vec4(n[0], n[1], n[2], sign * wp.min(to_end, to_arc))


@wp.func
def cone_distance(scale: wp.vec3, p: wp.vec3):
    """Signed distance [m] (xyz: outward normal, w: distance) of local ``p`` to a cone along z (base radius
    ``scale[0]`` at ``-scale[1]``, apex at ``scale[1]``).

    In the half-plane of ``p`` and the axis the cone is the triangle (0, -H), (r, -H), (0, H) of
    (distance from the axis, z); its surface is the base edge and the slanted edge.
    """
    r = scale[0]
    hh = scale[1]
    rho = wp.sqrt(p[0] * p[0] + p[1] * p[1])
    side = wp.where(rho > 0.0, wp.vec3(p[0], p[1], 0.0) / wp.max(rho, 1.0e-12), wp.vec3(1.0, 0.0, 0.0))
    q = wp.vec2(rho, p[2])
    base = wp.vec2(wp.clamp(rho, 0.0, r), -hh)
    rim = wp.vec2(r, -hh)
    edge = wp.vec2(-r, 2.0 * hh)
    slant = rim + wp.clamp(wp.dot(q - rim, edge) / wp.dot(edge, edge), 0.0, 1.0) * edge
    to_base = wp.length(q - base)
    to_slant = wp.length(q - slant)
    if p[2] >= -hh and rho * 2.0 * hh <= r * (hh - p[2]):
        # inside: the nearer face
        if to_base <= to_slant:
            return wp.vec4(0.0, 0.0, -1.0, -to_base)
        out = wp.normalize(wp.vec2(2.0 * hh, r))
        n = out[0] * side + wp.vec3(0.0, 0.0, out[1])
        return wp.vec4(n[0], n[1], n[2], -to_slant)
    nearest = wp.where(to_base <= to_slant, base, slant)
    dist = wp.min(to_base, to_slant)
    out = wp.vec2(0.0, 1.0)
    if dist > 0.0:
        out = (q - nearest) / dist
    n = out[0] * side + wp.vec3(0.0, 0.0, out[1])
    return wp.vec4(n[0], n[1], n[2], dist)


@wp.func
def ellipsoid_distance(scale: wp.vec3, p: wp.vec3):
    """Approximate signed distance [m] (xyz: outward normal, w: distance) of local ``p`` to an ellipsoid of
    semi-axes ``scale``: ``k0 (k0 - 1) / k1`` with ``k0 = |p / r|``, ``k1 = |p / r^2|`` (Quilez, "Ellipsoid SDF",
    2008), exact on a sphere and with the true sign everywhere."""
    pr = wp.cw_div(p, scale)
    prr = wp.cw_div(pr, scale)
    k0 = wp.length(pr)
    k1 = wp.length(prr)
    if k1 <= 0.0:
        # the centre: the shortest semi-axis
        smallest = wp.min(wp.min(scale[0], scale[1]), scale[2])
        n = wp.vec3(0.0, 0.0, 1.0)
        if smallest == scale[0]:
            n = wp.vec3(1.0, 0.0, 0.0)
        elif smallest == scale[1]:
            n = wp.vec3(0.0, 1.0, 0.0)
        return wp.vec4(n[0], n[1], n[2], -smallest)
    n = prr / k1
    return wp.vec4(n[0], n[1], n[2], k0 * (k0 - 1.0) / k1)


@wp.func
def surface_distance(shape_type: int, scale: wp.vec3, source: wp.uint64, solid: int, p: wp.vec3, reach: float):
    """:func:`shape_distance` for cylinders (straight and barrel-sided), cones, ellipsoids and triangle meshes too
    (``source`` the mesh, looked for within ``reach`` [m]). A watertight mesh (``solid``) is signed by its
    angle-weighted normals; an open one has no inside, and its normal points to ``p``'s side. Meshes farther than
    ``reach`` read as far away (1e10 m); heightfields need their grid
    (:func:`~.heightfields.heightfield_distance`)."""
    if shape_type == GeoType.CONE:
        return cone_distance(scale, p)
    if shape_type == GeoType.ELLIPSOID:
        return ellipsoid_distance(scale, p)
    if shape_type == GeoType.CYLINDER:
        if scale[2] > 0.0:
            return barrel_distance(scale, p)
        return cylinder_distance(scale, p)
    if shape_type == GeoType.MESH or shape_type == GeoType.CONVEX_MESH:
        smallest = wp.min(wp.min(wp.abs(scale[0]), wp.abs(scale[1])), wp.abs(scale[2]))
        q = wp.mesh_query_point_sign_normal(source, wp.cw_div(p, scale), reach / smallest)
        if not q.result:
            return wp.vec4(0.0, 0.0, 1.0, 1.0e10)
        sign = wp.where(solid != 0, q.sign, 1.0)
        closest = wp.cw_mul(wp.mesh_eval_position(source, q.face, q.u, q.v), scale)
        offset = p - closest
        d = wp.length(offset)
        n = wp.vec3()
        if d > 1.0e-9:
            n = sign * offset / d
        else:
            # on the surface: the face's normal, through the scale
            n = wp.normalize(wp.cw_div(wp.mesh_eval_face_normal(source, q.face), scale))
        return wp.vec4(n[0], n[1], n[2], sign * d)
    return shape_distance(shape_type, scale, p)


@wp.func
def near_shape(shapes: GuardedShapes, s: int, x: wp.vec3, reach: float):
    """Whether ``x`` lies within ``reach`` [m] of guarded shape ``s``'s world bounds (most points are far from
    most shapes: their bounds part)."""
    lo = shapes.lower[s]
    hi = shapes.upper[s]
    return not (
        x[0] + reach < lo[0]
        or x[1] + reach < lo[1]
        or x[2] + reach < lo[2]
        or x[0] - reach > hi[0]
        or x[1] - reach > hi[1]
        or x[2] - reach > hi[2]
    )


@wp.func
def guarded_surface_distance(shapes: GuardedShapes, s: int, p: wp.vec3, reach: float):
    """:func:`surface_distance` of guarded shape ``s`` at local ``p``, heightfields included."""
    if shapes.shape_type[s] == GeoType.HFIELD:
        return heightfield_distance(shapes.heightfield[shapes.shape_heightfield[s]], shapes.heightfield_elevation, p)
    return surface_distance(
        shapes.shape_type[s], shapes.shape_scale[s], shapes.shape_source[s], shapes.shape_solid[s], p, reach
    )


@wp.kernel
def stop_fluid_paths_at_shapes(
    shapes: GuardedShapes,
    fluid_particle: wp.array[wp.int32],
    slot_of_particle: wp.array[wp.int32],
    particle_flags: wp.array[wp.int32],
    particle_world: wp.array[wp.int32],
    particle_radius: wp.array[float],
    particle_inv_mass: wp.array[float],
    particle_q_start: wp.array[wp.vec3],
    rounds: int,
    # outputs
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    slot_xm: wp.array[wp.vec4],
    sorted_v: wp.array[wp.vec3],
    stopped_count: wp.array[wp.int32],
):
    """Keep each fluid particle's path of the substep out of the static and kinematic shapes (module docstring).

    In particle order (the state's reads are coalesced). A stopped particle's position and velocity are
    written to the state and to its slot (``slot_xm``, ``sorted_v``), so the velocity passes after it
    read them; ``stopped_count`` counts the stops.
    """
    pi = fluid_particle[wp.tid()]
    if (particle_flags[pi] & ParticleFlags.ACTIVE) == 0 or particle_inv_mass[pi] == 0.0:
        return
    row = world_row(particle_world[pi], shapes.world_count)
    lo = shapes.row_start[row]
    hi = shapes.row_start[row + 1]
    if lo == hi:
        return
    x0 = particle_q_start[pi]
    x1 = particle_q[pi]
    radius = particle_radius[pi]
    # the walls met (outward normal, and the wall's velocity at the entry point)
    n0 = wp.vec3(0.0)
    n1 = wp.vec3(0.0)
    n2 = wp.vec3(0.0)
    n3 = wp.vec3(0.0)
    w0 = wp.vec3(0.0)
    w1 = wp.vec3(0.0)
    w2 = wp.vec3(0.0)
    w3 = wp.vec3(0.0)
    met = int(0)
    for r in range(rounds):
        t, normal, point, point_start = first_shape_entry(shapes, lo, hi, x0, x1)
        if t > 1.0:
            break
        if r < rounds - 1:
            # onto the entry's tangent plane, one radius off it, as the missed contact would have put it
            x1 = x1 + (radius - wp.dot(normal, x1 - point)) * normal
        else:
            # still entering after every round (a narrow crevice): stop before the entry
            # (toward its start as the shape carried it: a wall moving onto the particle pushes it along)
            x1 = point + (x0 - point_start) * STOP_SHORT
        v_wall = (point - point_start) / shapes.dt
        if r == 0:
            n0 = normal
            w0 = v_wall
        elif r == 1:
            n1 = normal
            w1 = v_wall
        elif r == 2:
            n2 = normal
            w2 = v_wall
        else:
            n3 = normal
            w3 = v_wall
        met += 1
    if met == 0:
        return
    v = (x1 - x0) / shapes.dt
    v = stop_inward(v, n0, w0)
    if met > 1:
        v = stop_inward(v, n1, w1)
    if met > 2:
        v = stop_inward(v, n2, w2)
    if met > 3:
        v = stop_inward(v, n3, w3)
    particle_q[pi] = x1
    particle_qd[pi] = v
    i = slot_of_particle[pi]
    if i >= 0:
        xm = slot_xm[i]
        slot_xm[i] = wp.vec4(x1[0], x1[1], x1[2], xm[3])
        sorted_v[i] = v
    wp.atomic_add(stopped_count, 0, 1)


def still_shapes(model) -> np.ndarray:
    """Per shape of ``model``, whether it is static or on a kinematic body: it moves only as prescribed and takes no
    reaction from the fluid (such shapes lend wall density and are kept out of by continuous collision)."""
    shape_body = model.shape_body.numpy()
    kinematic_body = np.zeros(max(int(model.body_count), 1), dtype=bool)
    if model.body_count:
        kinematic_body[: model.body_count] = (model.body_flags.numpy() & int(BodyFlags.KINEMATIC)) != 0
    on_body = shape_body >= 0
    return ~on_body | kinematic_body[np.where(on_body, shape_body, 0)]


def local_bounds(shape_type: int, scale: np.ndarray, source) -> np.ndarray:
    """Lower and upper corner [m] of a guarded shape in its own frame (an infinite plane: x below -1e29)."""
    if shape_type in (GeoType.BOX, GeoType.ELLIPSOID):
        half = np.abs(scale)
    elif shape_type == GeoType.SPHERE:
        half = np.full(3, scale[0])
    elif shape_type == GeoType.CAPSULE:
        half = np.array([scale[0], scale[0], scale[1] + scale[0]])
    elif shape_type in (GeoType.CYLINDER, GeoType.CONE):
        bulge = 0.0
        if shape_type == GeoType.CYLINDER and scale[2] > 0.0:
            # a barrel's side stands out most at mid-height (barrel_bulge at z = 0)
            bulge = scale[1] ** 2 / (scale[2] + np.sqrt(max(scale[2] ** 2 - scale[1] ** 2, 0.0)))
        half = np.array([scale[0] + bulge, scale[0] + bulge, scale[1]])
    elif shape_type == GeoType.HFIELD:
        # solid below its surface to any depth (a kilometre here)
        top = max(source.min_z * scale[2], source.max_z * scale[2])
        half_x, half_y = abs(source.hx * scale[0]), abs(source.hy * scale[1])
        return np.array([[-half_x, -half_y, -1.0e3], [half_x, half_y, top]])
    elif shape_type == GeoType.PLANE:
        if scale[0] > 0.0 and scale[1] > 0.0:
            half = np.array([0.5 * scale[0], 0.5 * scale[1], 0.0])
        else:
            return np.array([[-1.0e30] * 3, [1.0e30] * 3])
    else:
        points = np.asarray(source.vertices, dtype=np.float64) * scale
        return np.stack([points.min(axis=0), points.max(axis=0)])
    return np.stack([-half, half])


def watertight_meshes(model) -> np.ndarray:
    """Per shape of ``model``: 1 for a watertight triangle mesh (its inside is an inside), else 0."""
    kinds = model.shape_type.numpy()
    solid = np.zeros(max(model.shape_count, 1), dtype=np.int32)
    for s in np.flatnonzero((kinds == int(GeoType.MESH)) | (kinds == int(GeoType.CONVEX_MESH))):
        solid[s] = int(bool(getattr(model.shape_source[s], "is_watertight", False)))
    return solid


def model_heightfields(model):
    """``model``'s heightfield rows per shape, their grids and elevations (one empty grid without any)."""
    d = model.device
    index = getattr(model, "shape_heightfield_index", None)
    grids = getattr(model, "heightfield_data", None)
    elevation = getattr(model, "heightfield_elevations", None)
    if index is None or grids is None or elevation is None:
        index = wp.full(max(model.shape_count, 1), -1, dtype=wp.int32, device=d)
        grids = wp.zeros(1, dtype=HeightfieldData, device=d)
        elevation = wp.zeros(1, dtype=wp.float32, device=d)
    return index, grids, elevation


class ContinuousCollision:
    """The shapes :func:`stop_fluid_paths_at_shapes` guards, per world, and its launch.

    Built once with the solver; a model without a guarded shape that particles collide with has
    none (``ContinuousCollision.build`` returns ``None``) and pays nothing.
    """

    def __init__(
        self,
        model,
        rows: np.ndarray,
        shape_list: np.ndarray,
        guarded: np.ndarray,
        local_bounds: np.ndarray,
        kinematic: bool,
        solid: np.ndarray,
    ):
        d = model.device
        self.model = model
        self.shapes = GuardedShapes()
        s = self.shapes
        s.row_start = wp.array(rows.astype(np.int32), dtype=wp.int32, device=d)
        s.shape = wp.array(shape_list.astype(np.int32), dtype=wp.int32, device=d)
        s.world_count = int(model.world_count)
        s.shape_type = model.shape_type
        s.shape_scale = model.shape_scale
        s.shape_source = model.shape_source_ptr
        s.shape_solid = wp.array(solid, dtype=wp.int32, device=d)
        s.shape_heightfield, s.heightfield, s.heightfield_elevation = model_heightfields(model)
        s.shape_transform = model.shape_transform
        s.shape_body = model.shape_body
        #: whether a guarded shape is on a (kinematic) body
        self.kinematic = kinematic
        s.body_com = model.body_com if kinematic else wp.zeros(1, dtype=wp.vec3, device=d)
        self._no_body_q = wp.zeros(1, dtype=wp.transform, device=d)
        self._no_body_qd = wp.zeros(1, dtype=wp.spatial_vector, device=d)
        s.local_lower = wp.array(local_bounds[:, 0], dtype=wp.vec3, device=d)
        s.local_upper = wp.array(local_bounds[:, 1], dtype=wp.vec3, device=d)
        s.lower = wp.zeros(model.shape_count, dtype=wp.vec3, device=d)
        s.upper = wp.zeros(model.shape_count, dtype=wp.vec3, device=d)
        self._guarded = wp.array(guarded.astype(np.int32), dtype=wp.int32, device=d)
        s.dt = 0.0
        # static shapes do not move: their bounds once (kinematic ones before every pass)
        self._bound(self._no_body_q, self._no_body_qd)
        #: particle substeps whose path into a shape was stopped, since the solver was created (device counter)
        self.stopped_count = wp.zeros(1, dtype=wp.int32, device=d)

    @classmethod
    def build(cls, model, dynamic: bool = False) -> ContinuousCollision | None:
        """The guard of ``model``'s static and kinematic shapes that collide with particles, or ``None`` without any.

        With ``dynamic``, the shapes of dynamic bodies too (for moves that take no time, where a body is
        held where it is: :mod:`.placement`), and which meshes are watertight (its test of a centre inside).
        """
        if not model.shape_count:
            return None
        shape_type = model.shape_type.numpy()
        shape_body = model.shape_body.numpy()
        flags = model.shape_flags.numpy()
        scale = model.shape_scale.numpy()
        guarded = (
            (still_shapes(model) | dynamic)
            & ((flags & int(ShapeFlags.COLLIDE_PARTICLES)) != 0)
            & np.isin(shape_type, [int(t) for t in GUARDED_TYPES])
        )
        index = np.flatnonzero(guarded)
        if not len(index):
            return None
        world_count = int(model.world_count)
        shape_world = model.shape_world.numpy()[index]
        rows, shapes = [0], []
        # world w meets its own shapes and the global ones; a global particle meets every shape
        for w in range(world_count):
            mine = index[(shape_world == w) | (shape_world < 0)]
            shapes.append(mine)
            rows.append(rows[-1] + len(mine))
        shapes.append(index)
        rows.append(rows[-1] + len(index))
        bounds = np.zeros((model.shape_count, 2, 3), dtype=np.float32)
        for s in index:
            bounds[s] = local_bounds(int(shape_type[s]), scale[s], model.shape_source[s])
        kinematic = bool((shape_body[index] >= 0).any())
        solid = watertight_meshes(model) if dynamic else np.zeros(1, dtype=np.int32)
        return cls(model, np.array(rows), np.concatenate(shapes), index, bounds, kinematic, solid)

    def _bound(self, body_q, body_qd) -> None:
        s = self.shapes
        s.body_q, s.body_qd = body_q, body_qd
        wp.launch(bound_guarded_shapes, dim=len(self._guarded), inputs=[s, self._guarded], device=self.model.device)

    def hold(self, body_q, body_qd) -> None:
        """Put the shapes where ``body_q`` has them, not moving: for moves that take no time (see :mod:`.placement`)."""
        self.shapes.dt = 0.0
        if self.kinematic:
            self._bound(body_q, body_qd)

    def apply(
        self, fluid_particle, slot_of_particle, slot_xm, sorted_v, particle_q_start, state_out, dt: float
    ) -> None:
        """Stop the paths of the substep that ended in ``state_out`` at the shapes they enter.

        ``slot_xm`` and ``sorted_v``: the fluid's slot copies of positions and velocities, kept up to date.
        """
        m = self.model
        s = self.shapes
        s.dt = dt
        if self.kinematic:
            # (static shapes were bounded once, at construction)
            self._bound(state_out.body_q, state_out.body_qd)
        wp.launch(
            stop_fluid_paths_at_shapes,
            dim=fluid_particle.shape[0],
            inputs=[
                s,
                fluid_particle,
                slot_of_particle,
                m.particle_flags,
                m.particle_world,
                m.particle_radius,
                m.particle_inv_mass,
                particle_q_start,
                GUARD_ROUNDS,
            ],
            outputs=[state_out.particle_q, state_out.particle_qd, slot_xm, sorted_v, self.stopped_count],
            device=m.device,
        )
