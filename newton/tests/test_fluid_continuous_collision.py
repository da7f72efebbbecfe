# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Continuous collision: fluid paths never enter static or kinematic shapes, whatever the speed and the substep.

The intersections of a path with each shape type against dense sampling, then containers that
leaked before it (``fluid_continuous_collision=False`` is the solver without it): a block thrown
at 20 m/s into walls two spacings thick, water spun in the vase of ``fluid_xpbd_sdf_container`` at
one substep per frame, and a kinematic plate swept through a tank faster than its contacts follow.
"""

import unittest

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton
from newton._src.solvers.xpbd.fluid.continuous_collision import (
    NO_ENTRY,
    ContinuousCollision,
    GuardedShapes,
    segment_entry,
    shape_entry,
    shape_poses,
    surface_distance,
)
from newton.examples.fluid.common import add_closed_tank, revolved_container
from newton.examples.fluid.example_fluid_xpbd_sdf_container import FILL, RIM, WALL, inner_radius
from newton.tests.test_fluid_stress import TANK, report, thrown_block
from newton.tests.test_solver_xpbd_fluid import D, Sim, add_block

FLUID = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)


@wp.kernel
def entries_of_paths(
    shape_type: int,
    scale: wp.vec3,
    mesh: wp.uint64,
    start: wp.array[wp.vec3],
    end: wp.array[wp.vec3],
    entries: wp.array[wp.vec4],
):
    i = wp.tid()
    entries[i] = segment_entry(shape_type, scale, mesh, start[i], end[i] - start[i])


def inside(shape_type, scale, p):
    """Whether the points ``p`` (N, 3) lie inside the shape (numpy, the shape's frame)."""
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    if shape_type == newton.GeoType.BOX:
        return np.all(np.abs(p) <= scale, axis=1)
    if shape_type == newton.GeoType.SPHERE:
        return np.linalg.norm(p, axis=1) <= scale[0]
    if shape_type == newton.GeoType.ELLIPSOID:
        return np.linalg.norm(p / scale, axis=1) <= 1.0
    if shape_type == newton.GeoType.CYLINDER:
        if scale[2] > 0.0:
            # barrel-sided: the profile's radius at height z is c + sqrt(barrel^2 - z^2)
            c = scale[0] - np.sqrt(scale[2] ** 2 - scale[1] ** 2)
            profile = c + np.sqrt(np.maximum(scale[2] ** 2 - z * z, 0.0))
            return (np.hypot(x, y) <= profile) & (np.abs(z) <= scale[1])
        return (np.hypot(x, y) <= scale[0]) & (np.abs(z) <= scale[1])
    if shape_type == newton.GeoType.CAPSULE:
        return np.linalg.norm(p - np.stack([0 * x, 0 * y, np.clip(z, -scale[1], scale[1])], axis=1), axis=1) <= scale[0]
    if shape_type == newton.GeoType.CONE:
        # base of radius scale[0] at -scale[1], apex at +scale[1]
        return (z >= -scale[1]) & (z <= scale[1]) & (np.hypot(x, y) <= scale[0] * (scale[1] - z) / (2.0 * scale[1]))
    if shape_type == newton.GeoType.PLANE:
        return z <= 0.0
    raise AssertionError(shape_type)


def first_entries(shape_type, scale, a, b, samples=4001):
    """First sample parameter at which each path ``a -> b`` is inside, from outside (inf: it never enters)."""
    t = np.linspace(0.0, 1.0, samples)
    result = np.full(len(a), np.inf)
    for k in range(len(a)):
        pts = a[k] + t[:, None] * (b[k] - a[k])
        ins = inside(shape_type, scale, pts)
        if not ins[0] and ins.any():
            result[k] = t[np.argmax(ins)]
    return result


def test_path_entries_match_sampling(test, device):
    rng = np.random.default_rng(7)
    n = 400
    a = rng.uniform(-1.5, 1.5, (n, 3))
    b = rng.uniform(-1.5, 1.5, (n, 3))
    # some paths graze or end just inside
    b[:40] = a[:40] * 0.3
    shapes = (
        (newton.GeoType.BOX, (0.6, 0.3, 0.9)),
        (newton.GeoType.SPHERE, (0.7, 0.0, 0.0)),
        (newton.GeoType.ELLIPSOID, (0.8, 0.4, 0.6)),
        (newton.GeoType.CYLINDER, (0.5, 0.7, 0.0)),
        # barrel-sided: a strong bulge (0.5 -> 0.77 m) and a slight one
        (newton.GeoType.CYLINDER, (0.5, 0.7, 1.0)),
        (newton.GeoType.CYLINDER, (0.5, 0.7, 4.0)),
        (newton.GeoType.CAPSULE, (0.4, 0.6, 0.0)),
        (newton.GeoType.CONE, (0.8, 0.6, 0.0)),
        (newton.GeoType.PLANE, (0.0, 0.0, 0.0)),
    )
    with wp.ScopedDevice(device):
        start, end = wp.array(a, dtype=wp.vec3), wp.array(b, dtype=wp.vec3)
        out = wp.zeros(n, dtype=wp.vec4)
        for shape_type, scale in shapes:
            wp.launch(entries_of_paths, dim=n, inputs=[int(shape_type), wp.vec3(*scale), 0, start, end, out])
            e = out.numpy().astype(np.float64)
            expected = first_entries(shape_type, np.array(scale), a, b)
            hit = np.isfinite(expected)
            test.assertGreater(np.count_nonzero(hit), 40, shape_type)
            # every entry is found, at the sampled parameter (within one sample), and no other
            np.testing.assert_allclose(e[hit, 3], expected[hit], atol=3.0e-4, err_msg=str(shape_type))
            test.assertTrue(np.all(e[~hit, 3] == NO_ENTRY), shape_type)
            # unit outward normals, against the path
            normal = e[hit, :3]
            np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1.0, atol=1.0e-4)
            test.assertTrue(np.all(np.einsum("ij,ij->i", normal, (b - a)[hit]) < 0.0), shape_type)
            if shape_type == newton.GeoType.SPHERE:
                entry = a[hit] + e[hit, 3:4] * (b - a)[hit]
                np.testing.assert_allclose(normal, entry / scale[0], atol=1.0e-4)

        # a closed mesh (a box of triangles) against the box it stands for, scaled unevenly
        mesh_box = newton.Mesh.create_box(1.0, 1.0, 1.0, compute_inertia=False)
        mesh = wp.Mesh(
            points=wp.array(mesh_box.vertices, dtype=wp.vec3),
            indices=wp.array(mesh_box.indices.ravel(), dtype=wp.int32),
        )
        scale = np.array([0.6, 0.3, 0.9])
        wp.launch(entries_of_paths, dim=n, inputs=[int(newton.GeoType.MESH), wp.vec3(*scale), mesh.id, start, end, out])
        e = out.numpy().astype(np.float64)
        expected = first_entries(newton.GeoType.BOX, scale, a, b)
        hit = np.isfinite(expected)
        np.testing.assert_allclose(e[hit, 3], expected[hit], atol=3.0e-4)
        test.assertTrue(np.all(e[~hit, 3] == NO_ENTRY))
        test.assertTrue(np.all(np.einsum("ij,ij->i", e[hit, :3], (b - a)[hit]) < 0.0))


def surface_height(field, hx, hy, min_z, max_z, x, y):
    """Height [m] of a heightfield's surface over ``x``, ``y`` (numpy; the triangles upstream's contacts use)."""
    nrow, ncol = field.shape
    u = np.clip((x + hx) / (2.0 * hx) * (ncol - 1), 0.0, ncol - 1)
    v = np.clip((y + hy) / (2.0 * hy) * (nrow - 1), 0.0, nrow - 1)
    col = np.minimum(np.floor(u).astype(int), ncol - 2)
    row = np.minimum(np.floor(v).astype(int), nrow - 2)
    fx, fy = u - col, v - row
    h00, h10 = field[row, col], field[row, col + 1]
    h01, h11 = field[row + 1, col], field[row + 1, col + 1]
    lower = h00 + fx * (h10 - h00) + fy * (h11 - h10)
    upper = h00 + fy * (h01 - h00) + fx * (h11 - h01)
    return min_z + np.where(fx >= fy, lower, upper) * (max_z - min_z)


def rough_heightfield(rng, nrow=7, ncol=9, hx=0.9, hy=0.6):
    """A random terrain of nrow x ncol heights over [-hx, hx] x [-hy, hy], between -0.4 and 0.5 m."""
    return newton.Heightfield(rng.uniform(0.0, 1.0, (nrow, ncol)), nrow, ncol, hx=hx, hy=hy, min_z=-0.4, max_z=0.5)


@wp.kernel
def heightfield_entries_of_paths(
    shapes: GuardedShapes,
    s: int,
    start: wp.array[wp.vec3],
    end: wp.array[wp.vec3],
    entries: wp.array[wp.vec4],
):
    i = wp.tid()
    entries[i] = shape_entry(shapes, s, start[i], end[i] - start[i])


def test_heightfield_entries_match_sampling(test, device):
    """Paths into a random terrain: the first point below its surface (inside its footprint), from above it."""
    rng = np.random.default_rng(11)
    field = rough_heightfield(rng)
    builder = newton.ModelBuilder()
    builder.add_shape_heightfield(heightfield=field)
    model = builder.finalize(device=device)
    guard = ContinuousCollision.build(model)
    n = 600
    a = rng.uniform((-1.2, -0.9, -0.5), (1.2, 0.9, 0.8), (n, 3))
    b = a + rng.uniform(-0.6, 0.6, (n, 3))
    # long paths over many cells, and some straight down
    b[:60] = rng.uniform((-1.2, -0.9, -0.5), (1.2, 0.9, 0.8), (60, 3))
    b[60:100, :2] = a[60:100, :2]
    out = wp.zeros(n, dtype=wp.vec4, device=device)
    wp.launch(
        heightfield_entries_of_paths,
        dim=n,
        inputs=[guard.shapes, 0, wp.array(a, dtype=wp.vec3, device=device), wp.array(b, dtype=wp.vec3, device=device)],
        outputs=[out],
        device=device,
    )
    e = out.numpy().astype(np.float64)
    t = np.linspace(0.0, 1.0, 8001)
    expected = np.full(n, np.inf)
    for k in range(n):
        pts = a[k] + t[:, None] * (b[k] - a[k])
        over = (np.abs(pts[:, 0]) <= field.hx) & (np.abs(pts[:, 1]) <= field.hy)
        below = over & (pts[:, 2] < surface_height(field.data, field.hx, field.hy, -0.4, 0.5, pts[:, 0], pts[:, 1]))
        if not below[0] and below.any():
            expected[k] = t[np.argmax(below)]
    hit = np.isfinite(expected)
    test.assertGreater(np.count_nonzero(hit), 100)
    np.testing.assert_allclose(e[hit, 3], expected[hit], atol=2.0e-4)
    test.assertTrue(np.all(e[~hit, 3] == NO_ENTRY))
    normal = e[hit, :3]
    np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1.0, atol=1.0e-4)
    test.assertTrue(np.all(np.einsum("ij,ij->i", normal, (b - a)[hit]) < 0.0))


@wp.kernel
def poses_of_shape(shapes: GuardedShapes, s: int, poses: wp.array[wp.transform]):
    start, end = shape_poses(shapes, s)
    poses[0] = start
    poses[1] = end


def test_kinematic_shape_swept_back_along_its_velocity(test, device):
    # a kinematic body turning about its off-centre centre of mass while it moves: its shape's pose at the
    # substep's start is the end pose with the rigid motion of body_qd undone over the substep
    builder = newton.ModelBuilder()
    add_block(builder, (2, 2, 2))
    body = builder.add_body(xform=wp.transform_identity(), is_kinematic=True)
    offset = wp.transform(wp.vec3(0.0, 0.2, 0.0), wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), 0.3))
    builder.add_shape_box(body, xform=offset, hx=0.1, hy=0.2, hz=0.3)
    model = builder.finalize(device=device)
    model.body_com.assign(np.array([[0.1, 0.0, 0.05]], dtype=np.float32))
    cc = ContinuousCollision.build(model)
    test.assertTrue(cc.kinematic)
    angle, omega, v, dt = 0.7, np.array([0.0, 0.0, 3.0]), np.array([1.0, -2.0, 0.5]), 0.01
    end = wp.transform(wp.vec3(0.4, 0.5, 0.6), wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), angle))
    with wp.ScopedDevice(device):
        cc.shapes.body_q = wp.array([end], dtype=wp.transform)
        cc.shapes.body_qd = wp.array([np.concatenate([v, omega])], dtype=wp.spatial_vector)
        cc.shapes.dt = dt
        poses = wp.zeros(2, dtype=wp.transform)
        wp.launch(poses_of_shape, dim=1, inputs=[cc.shapes, 0, poses])
    start_shape, end_shape = poses.numpy().astype(np.float64)

    def rot_z(a):
        return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])

    def place(t, point):
        # a body point's world position at time t before the end (the body turns about z through its centre of mass)
        com = np.array([0.1, 0.0, 0.05])
        c_end = np.array([0.4, 0.5, 0.6]) + rot_z(angle) @ com
        return c_end - v * t + rot_z(angle - 3.0 * t) @ (point - com)

    corner = np.array([0.1, 0.2, 0.3])  # a box corner, in the shape's frame
    local = np.array(wp.transform_point(offset, wp.vec3(*corner)))
    for pose, t in ((start_shape, dt), (end_shape, 0.0)):
        q = wp.transform(wp.vec3(*pose[:3]), wp.quat(*pose[3:]))
        np.testing.assert_allclose(np.array(wp.transform_point(q, wp.vec3(*corner))), place(t, local), atol=1.0e-5)


def substep(sim, collide=True):
    """One substep of ``sim``, finding the particle-shape contacts first if ``collide``."""
    sim.state_0.clear_forces()
    if collide:
        sim.collision.collide(sim.state_0, sim.contacts)
    sim.solver.step(sim.state_0, sim.state_1, None, sim.contacts, sim.dt)
    sim.state_0, sim.state_1 = sim.state_1, sim.state_0


def run_thrown_block(device, substeps, collide_every, **kwargs):
    """Frames of the block thrown at 20 m/s into a floor two spacings thick: the most particles outside at once."""
    sim = Sim(thrown_block(device, 20.0, 2.0 * D), substeps=substeps, contacts=True, **kwargs)
    outside = 0
    for _ in range(20):
        for k in range(substeps):
            substep(sim, collide=k % collide_every == 0)
        q = sim.q()
        assert np.isfinite(q).all()
        outside = max(outside, int(np.count_nonzero(np.any((q < 0.0) | (q > TANK), axis=1))))
    return outside, report(sim)


def test_thrown_block_stays_in_tank(test, device):
    # 20 m/s is 3.3 spacings per substep at one substep per 1/60 s frame, and 0.4 at eight with the
    # contacts found once per frame (they reach half a spacing past the wall)
    for substeps, collide_every in ((1, 1), (8, 1), (8, 8)):
        outside, (stats, warned) = run_thrown_block(device, substeps, collide_every)
        test.assertEqual(outside, 0, (substeps, collide_every))
        test.assertEqual(stats["nonfinite_recovered"], 0)
        if substeps == 1:
            test.assertTrue(any("substep is too long" in m for m in warned), warned)
            test.assertGreater(stats["shape_entries_stopped"], 0)
    # without it, most of the block passes through the floor (CPU: 75 of 125 at one substep, 89 with the
    # contacts found once per eight substeps)
    outside, (stats, warned) = run_thrown_block(device, 1, 1, fluid_continuous_collision=False)
    test.assertGreater(outside, 25)
    test.assertEqual(stats["shape_entries_stopped"], 0)
    test.assertTrue(any("substep is too long" in m for m in warned), warned)
    outside, _ = run_thrown_block(device, 8, 8, fluid_continuous_collision=False)
    test.assertGreater(outside, 25)


def cone_depth(scale, p):
    """How deep [m] each point of ``p`` (N, 3) is inside the cone of ``scale`` (numpy, its frame; negative: outside):
    the distance to the nearer of its base and its slanted side, in the half-plane of the point and the axis."""
    r, hh = scale[0], scale[1]
    q = np.stack([np.hypot(p[:, 0], p[:, 1]), p[:, 2]], axis=1)

    def to_segment(a, b):
        e = np.asarray(b, dtype=float) - a
        s = np.clip(((q - a) @ e) / (e @ e), 0.0, 1.0)
        return np.linalg.norm(q - (a + s[:, None] * e), axis=1)

    distance = np.minimum(to_segment(np.array([0.0, -hh]), (r, -hh)), to_segment(np.array([r, -hh]), (0.0, hh)))
    return np.where(inside(newton.GeoType.CONE, scale, p), distance, -distance)


@wp.kernel
def distances_of_points(shape_type: int, scale: wp.vec3, points: wp.array[wp.vec3], out: wp.array[wp.vec4]):
    i = wp.tid()
    out[i] = surface_distance(shape_type, scale, wp.uint64(0), 0, points[i], 1.0)


def surface_distances(shape_type, scale, points, device):
    """:func:`surface_distance` of each of ``points`` (a warp array) to a shape at the origin (numpy, float64)."""
    out = wp.zeros(len(points), dtype=wp.vec4, device=device)
    wp.launch(
        distances_of_points, dim=len(points), inputs=[int(shape_type), wp.vec3(*scale), points, out], device=device
    )
    return out.numpy().astype(np.float64)


def assert_signed_distances(depth, p, e, atol):
    """``e`` (xyz: normal, w: distance) is the signed distance that ``depth`` (inside positive) measures, with unit
    normals that point from each point's nearest surface point to it."""
    np.testing.assert_allclose(e[:, 3], -depth(p), atol=atol)
    np.testing.assert_allclose(np.linalg.norm(e[:, :3], axis=1), 1.0, atol=1.0e-4)
    away = np.abs(e[:, 3]) > 1.0e-3
    foot = p[away] - e[away, 3:4] * e[away, :3]
    np.testing.assert_allclose(depth(foot), 0.0, atol=max(atol, 1.0e-4))


def test_cone_and_ellipsoid_distances(test, device):
    """The placement's measure of a cone is its exact signed distance; an ellipsoid's has the true sign."""
    rng = np.random.default_rng(5)
    p = rng.uniform(-1.2, 1.2, (2000, 3))
    points = wp.array(p, dtype=wp.vec3, device=device)
    cone = (0.8, 0.6, 0.0)
    e = surface_distances(newton.GeoType.CONE, cone, points, device)
    assert_signed_distances(lambda q: cone_depth(cone, q), p, e, 1.0e-5)
    axes = np.array([0.8, 0.4, 0.6])
    e = surface_distances(newton.GeoType.ELLIPSOID, axes, points, device)
    np.testing.assert_array_equal(e[:, 3] < 0.0, inside(newton.GeoType.ELLIPSOID, axes, p))
    e = surface_distances(newton.GeoType.ELLIPSOID, (0.7, 0.7, 0.7), points, device)
    np.testing.assert_allclose(e[:, 3], np.linalg.norm(p, axis=1) - 0.7, atol=1.0e-5)


def barrel_depth(scale, p):
    """How deep [m] each point of ``p`` (N, 3) is inside the barrel-sided cylinder of ``scale`` (numpy, its frame;
    negative: outside): the distance to its surface, sampled densely in the half-plane of the point and the axis."""
    r, hh, barrel = scale
    c = r - np.sqrt(barrel**2 - hh**2)
    # by angle: the arc turns horizontal at the rim where its end radius is the barrel's
    angle = np.linspace(-np.arcsin(hh / barrel), np.arcsin(hh / barrel), 20001)
    arc = np.stack([c + barrel * np.cos(angle), barrel * np.sin(angle)], axis=1)
    rim = np.linspace(0.0, r, 4001)
    ends = np.concatenate([np.stack([rim, np.full_like(rim, hh)], 1), np.stack([rim, np.full_like(rim, -hh)], 1)])
    boundary = np.concatenate([arc, ends])
    q = np.stack([np.hypot(p[:, 0], p[:, 1]), p[:, 2]], axis=1)
    distance = np.array([np.min(np.linalg.norm(boundary - point, axis=1)) for point in q])
    return np.where(inside(newton.GeoType.CYLINDER, np.asarray(scale), p), distance, -distance)


def test_barrel_cylinder_distance(test, device):
    """The placement's measure of a barrel-sided cylinder is its signed distance, and a straight one's in the
    limit of a flat arc."""
    rng = np.random.default_rng(9)
    p = rng.uniform(-1.2, 1.2, (1500, 3))
    points = wp.array(p, dtype=wp.vec3, device=device)
    for barrel in ((0.5, 0.7, 0.7), (0.5, 0.7, 1.0), (0.3, 0.4, 3.0)):
        e = surface_distances(newton.GeoType.CYLINDER, barrel, points, device)
        # (within the reference's sampling of the arc)
        assert_signed_distances(lambda q, b=barrel: barrel_depth(b, q), p, e, 2.0e-4)
    flat = surface_distances(newton.GeoType.CYLINDER, (0.5, 0.7, 1.0e4), points, device)
    straight = surface_distances(newton.GeoType.CYLINDER, (0.5, 0.7, 0.0), points, device)
    np.testing.assert_allclose(flat[:, 3], straight[:, 3], atol=1.0e-4)


def thrown_onto(device, kind, substeps, **kwargs):
    """The block of :func:`run_thrown_block` thrown at 20 m/s onto a static cone, a barrel-sided cylinder (its side
    bulging from 0.3 to 0.43 m) or a rough terrain on the tank's floor: the most centres more than 0.3 spacings inside it at once, and the diagnostics."""
    rng = np.random.default_rng(3)
    builder = newton.ModelBuilder()
    add_block(builder, (5, 5, 5), origin=(0.4, 0.4, 0.7), vel=(0.0, 0.0, -20.0), jitter=0.02 * D)
    add_closed_tank(builder, TANK, thickness=2.0 * D)
    cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
    centre = np.array([0.5 * TANK, 0.5 * TANK, 0.3])
    xform = wp.transform(wp.vec3(*centre), wp.quat_identity())
    scale = (0.45, 0.3, 0.0)
    field = newton.Heightfield(rng.uniform(0.0, 1.0, (5, 5)), 5, 5, hx=0.5 * TANK, hy=0.5 * TANK, min_z=0.0, max_z=0.4)
    barrel = (0.3, 0.3, 0.4)
    if kind == "cone":
        builder.add_shape_cone(-1, xform=xform, radius=scale[0], half_height=scale[1], cfg=cfg)
    elif kind == "barrel":
        builder.add_shape_cylinder(
            -1, xform=xform, radius=barrel[0], half_height=barrel[1], barrel_radius=barrel[2], cfg=cfg
        )
    else:
        builder.add_shape_heightfield(xform=wp.transform(wp.vec3(*centre[:2], 0.0)), heightfield=field, cfg=cfg)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    sim = Sim(model, substeps=substeps, contacts=True, **kwargs)
    most = 0
    for _ in range(20):
        sim.step()
        q = sim.q()
        assert np.isfinite(q).all()
        if kind == "cone":
            depth = cone_depth(scale, q - centre)
        elif kind == "barrel":
            depth = barrel_depth(barrel, q - centre)
        else:
            local = q - (centre[0], centre[1], 0.0)
            depth = surface_height(field.data, field.hx, field.hy, 0.0, 0.4, local[:, 0], local[:, 1]) - local[:, 2]
            depth[np.any(np.abs(local[:, :2]) > 0.5 * TANK, axis=1)] = -1.0
        most = max(most, int(np.count_nonzero(depth > 0.3 * D)))
    return most, report(sim)


def test_thrown_block_stays_out_of_cone_barrel_and_terrain(test, device):
    # the shapes upstream's contacts know besides the ones of the tank test: 3.3 spacings per substep at one
    # substep per frame, then the whole tank's fall at eight
    for kind in ("cone", "barrel", "heightfield"):
        with test.subTest(shape=kind):
            for substeps in (1, 8):
                inside_it, (stats, _) = thrown_onto(device, kind, substeps)
                test.assertEqual(inside_it, 0, substeps)
                test.assertEqual(stats["nonfinite_recovered"], 0)
                if substeps == 1:
                    test.assertGreater(stats["shape_entries_stopped"], 0)
            # without it, the block passes into the shape
            inside_before, _ = thrown_onto(device, kind, 1, fluid_continuous_collision=False)
            test.assertGreater(inside_before, 10)


def spun_vase(device, spin, substeps, **kwargs):
    """Water spun at ``spin`` [rad/s] in the vase, one collision per substep, no speed clamp: particles that
    pass through its wall or floor (below the rim, never above it) and the solver's diagnostics."""
    d = 0.02
    builder = newton.ModelBuilder()
    axis = np.arange(-0.17, 0.17, d)
    x, y, z = np.meshgrid(axis, axis, np.arange(WALL + 0.5 * d, FILL, d), indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) < inner_radius(pts[:, 2]) - 0.5 * d]
    vel = spin * np.stack([-pts[:, 1], pts[:, 0], np.zeros(len(pts))], axis=1)
    builder.add_particles(
        pos=[wp.vec3(*p) for p in pts],
        vel=[wp.vec3(*v) for v in vel],
        mass=[1000.0 * d**3] * len(pts),
        radius=[0.5 * d] * len(pts),
        flags=[FLUID] * len(pts),
    )
    builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    profile = np.linspace(WALL, RIM, 40)
    vase = revolved_container(np.stack([inner_radius(profile), profile], axis=1), WALL, segments=64)
    builder.add_shape_mesh(-1, mesh=vase, cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    sim = Sim(model, substeps=substeps, contacts=True, fluid_rest_distance=d, **kwargs)
    over_rim = np.zeros(model.particle_count, dtype=bool)
    crossed = np.zeros(model.particle_count, dtype=bool)
    for _ in range(40):
        sim.step()
        q = sim.q()
        assert np.isfinite(q).all()
        over_rim |= q[:, 2] > RIM
        through_wall = np.hypot(q[:, 0], q[:, 1]) > inner_radius(q[:, 2]) + 0.3 * d
        crossed |= ((q[:, 2] < RIM) & through_wall | (q[:, 2] < WALL - 0.3 * d)) & ~over_rim
    return int(np.count_nonzero(crossed)), report(sim)


def test_spun_water_stays_in_vase(test, device):
    # 30 rad/s at one substep per frame: the water hits the bulb's wall at up to 5 m/s, 4 spacings per substep
    crossed, (stats, warned) = spun_vase(device, 30.0, 1)
    test.assertEqual(crossed, 0)
    test.assertGreater(stats["shape_entries_stopped"], 0)
    test.assertTrue(any("substep is too long" in m for m in warned), warned)
    # without it, a third of the water leaves through the mesh (CPU: 231 of 684)
    crossed_before, _ = spun_vase(device, 30.0, 1, fluid_continuous_collision=False)
    test.assertGreater(crossed_before, 100)


def swept_plate(device, speed, substeps, **kwargs):
    """A kinematic plate, two spacings thick and closing the tank's cross-section, swept through its water at
    ``speed`` [m/s]: the most particles behind it at once (they passed through it) and the diagnostics."""
    builder = newton.ModelBuilder()
    add_block(builder, (6, 11, 4), origin=(0.55, 0.05, 0.05), jitter=0.02 * D)
    add_closed_tank(builder, TANK, thickness=2.0 * D)
    plate = builder.add_body(xform=wp.transform(wp.vec3(0.3, 0.6, 0.6), wp.quat_identity()), is_kinematic=True)
    cfg = newton.ModelBuilder.ShapeConfig(mu=0.0, density=0.0, has_shape_collision=False)
    builder.add_shape_box(plate, hx=D, hy=0.6, hz=0.6, cfg=cfg)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    sim = Sim(model, substeps=substeps, contacts=True, **kwargs)
    behind = 0
    x = 0.3
    for _ in range(6):
        for _ in range(substeps):
            x += speed * sim.dt
            pose = np.array([[x, 0.6, 0.6, 0.0, 0.0, 0.0, 1.0]], dtype=np.float32)
            sim.state_0.body_q.assign(pose)
            # (the pose at the end of the substep, and the velocity that gets it there)
            sim.state_0.body_qd.assign(np.array([[speed, 0.0, 0.0, 0.0, 0.0, 0.0]], dtype=np.float32))
            substep(sim)
        q = sim.q()
        assert np.isfinite(q).all()
        behind = max(behind, int(np.count_nonzero(q[:, 0] < x - D)))
    return behind, report(sim)


def test_kinematic_plate_sweeps_the_water(test, device):
    # 6 m/s is a spacing per 1/60 s substep, twice the contacts' reach: the plate pushes all the water ahead
    # (and crushes it: one substep of two iterations cannot hold the impact, and the diagnostics say so)
    behind, (stats, warned) = swept_plate(device, 6.0, 1)
    test.assertEqual(behind, 0)
    test.assertGreater(stats["shape_entries_stopped"], 0)
    test.assertTrue(any("compression" in m for m in warned), warned)
    # without it, the plate passes through part of the water (CPU: 22 particles)
    behind_before, _ = swept_plate(device, 6.0, 1, fluid_continuous_collision=False)
    test.assertGreater(behind_before, 5)


def test_guard_leaves_ordinary_flow_alone(test, device):
    """A column collapsing in a tank at 8 substeps never reaches a wall unseen: bitwise the same without the guard."""

    def run(**kwargs):
        builder = newton.ModelBuilder()
        add_block(builder, (4, 6, 8), origin=(0.05, 0.05, 0.05), jitter=0.02 * D)
        add_closed_tank(builder, TANK, thickness=2.0 * D)
        model = builder.finalize(device=device)
        model.soft_contact_mu = 0.0
        sim = Sim(model, substeps=8, contacts=True, **kwargs)
        sim.step(30)
        return sim.q(), report(sim)[0]

    q_on, stats = run()
    q_off, _ = run(fluid_continuous_collision=False)
    # (a guard that stopped nothing changed nothing; on the CPU the runs are also compared bitwise, on a GPU
    # the contacts' order differs from run to run)
    test.assertEqual(stats["shape_entries_stopped"], 0)
    test.assertTrue(np.isfinite(q_on).all())
    if wp.get_device(device).is_cpu:
        np.testing.assert_array_equal(q_on, q_off)


class TestFluidContinuousCollision(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestFluidContinuousCollision, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
