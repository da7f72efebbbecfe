# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""``newton.sensors.SensorFluid``: per-world fluid counts in regions, centroid, velocity and spill."""

import math
import unittest

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton

WORLDS = 3
PER_WORLD = 400
FLUID = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)
BOX_HALF = (0.3, 0.2, 0.25)  # the cup's inside, a box site on the cup body
BOX_OFFSET = (0.1, 0.0, 0.2)  # the site in the cup's frame
CYL = (0.35, 0.3)  # radius and half height of a static cylinder site of each world
SPHERE_R = 0.4  # a global sphere site at (0.6, 0.6, 0.6), seen by every world


def rot_z(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def quat_z(angle):
    return wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), angle)


def build(device, seed=3):
    rng = np.random.default_rng(seed)
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    positions = []
    for w in range(WORLDS):
        world = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))
        cup = world.add_body(xform=wp.transform((0.0, 0.0, 0.0), wp.quat_identity()), label="cup")
        world.add_shape_sphere(cup, radius=0.05)
        world.add_site(
            cup,
            xform=wp.transform(BOX_OFFSET, quat_z(0.3)),
            type=newton.GeoType.BOX,
            scale=BOX_HALF,
            label="cup_inside",
        )
        world.add_site(
            -1,
            xform=wp.transform((-0.5, 0.4, 0.0), wp.quat_identity()),
            type=newton.GeoType.CYLINDER,
            scale=(*CYL, 0.0),
            label="target",
        )
        q = rng.uniform(-1.0, 1.0, size=(PER_WORLD, 3))
        positions.append(q)
        world.add_particles(
            pos=[wp.vec3(*p) for p in q],
            vel=[wp.vec3(*(rng.normal(size=3) + w)) for _ in q],
            mass=[1.0] * PER_WORLD,
            radius=[0.01] * PER_WORLD,
            flags=[FLUID] * PER_WORLD,
        )
        builder.add_world(world)
    builder.add_site(
        -1,
        xform=wp.transform((0.6, 0.6, 0.6), wp.quat_identity()),
        type=newton.GeoType.SPHERE,
        scale=(SPHERE_R, 0.0, 0.0),
        label="global_sphere",
    )
    return builder.finalize(device=device)


def expected(model, state, cup_pose):
    """What the sensor should report, from the particle arrays, in numpy."""
    q, qd = state.particle_q.numpy(), state.particle_qd.numpy()
    world, flags = model.particle_world.numpy(), model.particle_flags.numpy()
    ok = ((flags & int(newton.ParticleFlags.ACTIVE)) != 0) & np.isfinite(q).all(axis=1) & np.isfinite(qd).all(axis=1)
    body_pos, body_angle = cup_pose
    rows = {"count": [], "centroid": [], "velocity": [], "spilled": [], "cup": [], "target": []}
    in_sphere = np.linalg.norm(q - 0.6, axis=1) <= SPHERE_R
    for w in range(WORLDS):
        sel = ok & (world == w)
        # box: site at BOX_OFFSET turned 0.3 rad about z in the cup's frame, the cup at body_pos turned body_angle
        centre = body_pos[w] + rot_z(body_angle[w]) @ np.array(BOX_OFFSET)
        local = (q - centre) @ rot_z(body_angle[w] + 0.3)  # rows times R = R^T applied to each row
        in_box = np.all(np.abs(local) <= BOX_HALF, axis=1)
        rel = q - np.array([-0.5, 0.4, 0.0])
        in_cyl = (rel[:, 0] ** 2 + rel[:, 1] ** 2 <= CYL[0] ** 2) & (np.abs(rel[:, 2]) <= CYL[1])
        rows["count"].append(sel.sum())
        rows["centroid"].append(q[sel].mean(axis=0))
        rows["velocity"].append(qd[sel].mean(axis=0))
        rows["spilled"].append((sel & ~in_box & ~in_cyl & ~in_sphere).sum())
        rows["cup"].append((sel & in_box).sum())
        rows["target"].append((sel & in_cyl).sum())
    rows["sphere"] = (ok & in_sphere).sum()
    return rows


def check(test, model, sensor, state, cup_pose):
    e = expected(model, state, cup_pose)
    shapes = sensor.region_shapes
    labels = [model.shape_label[s] for s in shapes]
    count = sensor.region_count.numpy()
    fraction = sensor.region_fraction.numpy()
    # regions by world, then shape index: each world's cup and target, the global sphere last
    test.assertEqual(list(sensor.region_world.numpy()), [0, 0, 1, 1, 2, 2, -1])
    for w in range(WORLDS):
        cup, target = 2 * w, 2 * w + 1
        test.assertTrue(labels[cup].endswith("cup_inside") and labels[target].endswith("target"), labels)
        test.assertEqual(count[cup], e["cup"][w])
        test.assertEqual(count[target], e["target"][w])
        test.assertAlmostEqual(fraction[cup], e["cup"][w] / e["count"][w], places=6)
    test.assertEqual(count[-1], e["sphere"])
    test.assertAlmostEqual(fraction[-1], e["sphere"] / sum(e["count"]), places=6)
    np.testing.assert_array_equal(sensor.fluid_count.numpy(), [*e["count"], 0])
    np.testing.assert_array_equal(sensor.spilled_count.numpy(), [*e["spilled"], 0])
    np.testing.assert_allclose(sensor.centroid.numpy()[:WORLDS], e["centroid"], atol=1.0e-5)
    np.testing.assert_allclose(sensor.mean_velocity.numpy()[:WORLDS], e["velocity"], atol=1.0e-5)
    # every region of the scene caught something, so the test is not won by empty regions
    test.assertTrue(min(e["cup"]) > 0 and min(e["target"]) > 0 and e["sphere"] > 0, e)


def test_sensor_counts_regions_per_world(test, device):
    model = build(device)
    state = model.state()
    sensor = newton.sensors.SensorFluid(model, regions=["*cup_inside", "*target", "global_sphere"])
    sensor.update(state)
    check(test, model, sensor, state, ([np.zeros(3)] * WORLDS, [0.0] * WORLDS))

    # the cups move with their bodies; one particle turned inactive and one non-finite are not counted
    pose = ([np.array([0.2, -0.1, 0.1]), np.array([-0.3, 0.2, -0.2]), np.zeros(3)], [0.5, -1.0, 2.0])
    state.body_q.assign([wp.transform(wp.vec3(*p), quat_z(a)) for p, a in zip(*pose, strict=True)])
    flags = model.particle_flags.numpy()
    flags[5] = int(newton.ParticleFlags.FLUID)
    model.particle_flags.assign(flags)
    q = state.particle_q.numpy()
    q[PER_WORLD + 7] = np.nan
    state.particle_q.assign(q)
    sensor.update(state)
    check(test, model, sensor, state, pose)
    test.assertEqual(sensor.fluid_count.numpy()[0], PER_WORLD - 1)
    test.assertEqual(sensor.fluid_count.numpy()[1], PER_WORLD - 1)


def test_sensor_in_captured_graph(test, device):
    model = build(device)
    state = model.state()
    sensor = newton.sensors.SensorFluid(model, regions="*cup_inside")
    with wp.ScopedCapture(device=device) as capture:
        sensor.update(state)
    eager = newton.sensors.SensorFluid(model, regions="*cup_inside")
    rng = np.random.default_rng(5)
    for _ in range(2):
        state.particle_q.assign(rng.uniform(-1.0, 1.0, size=(model.particle_count, 3)).astype(np.float32))
        wp.capture_launch(capture.graph)
        eager.update(state)
        np.testing.assert_array_equal(sensor.region_count.numpy(), eager.region_count.numpy())
        np.testing.assert_array_equal(sensor.spilled_count.numpy(), eager.spilled_count.numpy())
        np.testing.assert_allclose(sensor.centroid.numpy(), eager.centroid.numpy(), atol=1.0e-6)


def test_sensor_rejects_bad_regions(test, device):
    model = build(device)
    with test.assertRaisesRegex(ValueError, r"regions='nothing\*' matches no shape label"):
        newton.sensors.SensorFluid(model, regions="nothing*")
    capsule = newton.ModelBuilder()
    b = capsule.add_body()
    capsule.add_site(b, type=newton.GeoType.CAPSULE, label="pill")
    capsule.add_particle((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0, flags=FLUID)
    with test.assertRaisesRegex(ValueError, "shape 0 .'pill'. of type CAPSULE, expected one of box, cylinder, sphere"):
        newton.sensors.SensorFluid(capsule.finalize(device=device), regions="pill")
    with test.assertRaisesRegex(ValueError, r"regions has shape index 99, expected an index in \[0, 10\)"):
        newton.sensors.SensorFluid(model, regions=[99])
    dry = newton.ModelBuilder()
    dry.add_particle((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0)
    with test.assertRaisesRegex(ValueError, "needs a model with fluid particles"):
        newton.sensors.SensorFluid(dry.finalize(device=device))


class TestFluidSensor(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestFluidSensor, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
