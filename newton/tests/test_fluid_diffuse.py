# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Diffuse particles (spray, foam, bubbles): emission, classification, lifetime, capacity, no feedback."""

import unittest

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton
from newton._src.solvers.xpbd.fluid.diffuse import (
    DIFFUSE_BUBBLE,
    DIFFUSE_DEAD,
    DIFFUSE_FOAM,
    DIFFUSE_SPRAY,
)
from newton.tests.test_fluid_continuous_collision import inside, surface_height

D = 0.05
FLUID = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)
DT = 1.0 / 240.0


class Scene:
    """A box tank (inner half extents ``half``) with a fluid block ``dims`` at ``origin``."""

    def __init__(
        self, device, dims, origin, velocity=(0.0, 0.0, 0.0), half=(0.25, 0.25), capacity=4096, add_shape=None
    ):
        builder = newton.ModelBuilder()
        builder.add_particle_grid(
            pos=wp.vec3(*origin),
            rot=wp.quat_identity(),
            vel=wp.vec3(*velocity),
            dim_x=dims[0],
            dim_y=dims[1],
            dim_z=dims[2],
            cell_x=D,
            cell_y=D,
            cell_z=D,
            mass=1000.0 * D**3,
            jitter=0.0,
            radius_mean=0.5 * D,
            flags=FLUID,
        )
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
        builder.add_ground_plane(cfg=cfg)
        t, hz = 0.05, 0.5
        hx, hy = half
        for center, ext in (
            ((-hx - t, 0.0, hz), (t, hy + 2 * t, hz)),
            ((hx + t, 0.0, hz), (t, hy + 2 * t, hz)),
            ((0.0, -hy - t, hz), (hx, t, hz)),
            ((0.0, hy + t, hz), (hx, t, hz)),
        ):
            builder.add_shape_box(
                -1, xform=wp.transform(wp.vec3(*center), wp.quat_identity()), hx=ext[0], hy=ext[1], hz=ext[2], cfg=cfg
            )
        if add_shape is not None:
            add_shape(builder, cfg)
        self.model = builder.finalize(device=device)
        self.model.particle_max_velocity = 0.25 * D / DT
        self.solver = newton.solvers.SolverXPBD(
            self.model, iterations=2, fluid_rest_distance=D, max_diffuse_particles=capacity
        )
        self.s0, self.s1 = self.model.state(), self.model.state()
        self.pipeline = newton.CollisionPipeline(
            self.model, soft_contact_max=self.model.particle_count, soft_contact_gap=0.5 * D
        )
        self.contacts = self.pipeline.contacts()

    def run(self, substeps):
        for _ in range(substeps):
            self.s0.clear_forces()
            self.pipeline.collide(self.s0, self.contacts)
            self.solver.step(self.s0, self.s1, None, self.contacts, DT)
            self.s0, self.s1 = self.s1, self.s0

    def emitted(self):
        return int(self.solver.diffuse_emitted_count.numpy()[0])


def calm_pool(device, capacity=4096):
    # fills the 0.5 x 0.5 m tank to 0.2 m, at the rest spacing
    return Scene(device, (10, 10, 4), (-0.25 + 0.5 * D, -0.25 + 0.5 * D, 0.5 * D), capacity=capacity)


def test_calm_pool_emits_nothing(test, device):
    scene = calm_pool(device)
    scene.run(60)
    test.assertEqual(scene.emitted(), 0)
    test.assertTrue(np.all(scene.solver.diffuse_kinds.numpy() == DIFFUSE_DEAD))


def test_splash_emits_within_capacity(test, device):
    capacity = 64
    # a block dropped from 0.4 m hits the floor at about 3 m/s
    scene = Scene(device, (6, 6, 4), (-0.125, -0.125, 0.4), velocity=(0.0, 0.0, -1.0), capacity=capacity)
    scene.run(80)
    emitted = scene.emitted()
    test.assertGreater(emitted, capacity, "a splash should emit more than the ring holds")
    counters = scene.solver._fluid.diffuse.counters.numpy()
    test.assertEqual(counters[0], counters[1])  # the ring index advanced once per emission
    kinds = scene.solver.diffuse_kinds.numpy()
    life = scene.solver.diffuse_lifetimes.numpy()
    q = scene.solver.diffuse_positions.numpy()
    test.assertEqual(len(kinds), capacity)
    alive = kinds != DIFFUSE_DEAD
    test.assertGreater(alive.sum(), 0)
    test.assertTrue(np.all(life[alive] > 0.0))
    test.assertTrue(np.all(np.isfinite(q)))
    # shapes confine them: nothing below the floor or outside the walls
    test.assertTrue(np.all(q[alive, 2] > -1.0e-4))
    test.assertTrue(np.all(np.abs(q[alive, :2]) < 0.25 + 1.0e-3))


def test_classification_and_motion(test, device):
    scene = calm_pool(device)
    scene.run(20)
    b = scene.solver._fluid.diffuse
    # above the surface (spray), at the surface (foam), deep inside (bubble)
    q0 = np.array([[0.0, 0.0, 0.45], [0.0, 0.0, 0.2], [0.0, 0.0, 0.08]], dtype=np.float32)
    n = 3
    q = b.position.numpy()
    q[:n] = q0
    b.position.assign(q)
    v = b.velocity.numpy()
    v[:n] = 0.0
    b.velocity.assign(v)
    life = b.lifetime.numpy()
    life[:n] = 2.0
    b.lifetime.assign(life)
    b.world.fill_(int(scene.model.particle_world.numpy()[0]))
    scene.run(1)
    kinds = b.kind.numpy()[:n]
    test.assertEqual(kinds.tolist(), [DIFFUSE_SPRAY, DIFFUSE_FOAM, DIFFUSE_BUBBLE])
    v = b.velocity.numpy()[:n]
    np.testing.assert_allclose(v[0], (0.0, 0.0, -9.81 * DT), atol=1.0e-5)  # ballistic
    test.assertGreater(v[2, 2], 0.0)  # buoyant
    np.testing.assert_allclose(b.lifetime.numpy()[:n], 2.0 - DT, atol=1.0e-6)


def test_particles_die_at_end_of_life(test, device):
    scene = calm_pool(device)
    b = scene.solver._fluid.diffuse
    life = np.zeros(b.lifetime.shape[0], dtype=np.float32)
    life[:2] = (0.5 * DT, 1.5 * DT)
    b.lifetime.assign(life)
    q = b.position.numpy()
    q[:2] = (0.0, 0.0, 0.45)
    b.position.assign(q)
    scene.run(1)
    test.assertEqual(b.kind.numpy()[:2].tolist(), [DIFFUSE_DEAD, DIFFUSE_SPRAY])
    scene.run(1)
    test.assertEqual(b.kind.numpy()[1], DIFFUSE_DEAD)
    test.assertTrue(np.all(b.lifetime.numpy()[:2] <= 0.0))


# a hill over the tank's floor: 5 x 5 heights, its centre 0.2 m high
HILL = newton.Heightfield(np.pad([[1.0]], 2), 5, 5, hx=0.25, hy=0.25, min_z=0.0, max_z=0.2)
CENTRE = wp.transform(wp.vec3(0.0, 0.0, 0.1), wp.quat_identity())
SHAPES = {
    "cone": (
        lambda b, cfg: b.add_shape_cone(-1, xform=CENTRE, radius=0.1, half_height=0.1, cfg=cfg),
        lambda q: inside(newton.GeoType.CONE, (0.1, 0.1, 0.0), q - (0.0, 0.0, 0.1)),
    ),
    "barrel": (
        # a barrel-sided cylinder whose side bulges from 0.07 to 0.1 m
        lambda b, cfg: b.add_shape_cylinder(
            -1, xform=CENTRE, radius=0.07, half_height=0.1, barrel_radius=0.18, cfg=cfg
        ),
        lambda q: inside(newton.GeoType.CYLINDER, (0.07, 0.1, 0.18), q - (0.0, 0.0, 0.1)),
    ),
    "ellipsoid": (
        lambda b, cfg: b.add_shape_ellipsoid(-1, xform=CENTRE, rx=0.1, ry=0.08, rz=0.1, cfg=cfg),
        lambda q: inside(newton.GeoType.ELLIPSOID, (0.1, 0.08, 0.1), q - (0.0, 0.0, 0.1)),
    ),
    "mesh": (
        lambda b, cfg: b.add_shape_mesh(-1, xform=CENTRE, mesh=newton.Mesh.create_box(0.08), cfg=cfg),
        lambda q: inside(newton.GeoType.BOX, (0.08, 0.08, 0.08), q - (0.0, 0.0, 0.1)),
    ),
    "heightfield": (
        lambda b, cfg: b.add_shape_heightfield(heightfield=HILL, cfg=cfg),
        lambda q: q[:, 2] < surface_height(HILL.data, HILL.hx, HILL.hy, HILL.min_z, HILL.max_z, q[:, 0], q[:, 1]),
    ),
}


def test_spray_stays_out_of_every_shape_type(test, device):
    # spray thrown down at 3 m/s onto a cone, a barrel, an ellipsoid, a triangle mesh and a terrain's hill in the tank
    rng = np.random.default_rng(2)
    for kind, (add_shape, inside_shape) in SHAPES.items():
        with test.subTest(shape=kind):
            # 128 seeded in the ring's last slots (what the fluid's block emits as it settles fills the first);
            # the block sits in a corner of a 1 m tank, out of reach of the spray sliding off the shape
            scene = Scene(
                device, (3, 3, 2), (-0.45, -0.45, 0.5 * D), half=(0.5, 0.5), capacity=512, add_shape=add_shape
            )
            b = scene.solver._fluid.diffuse
            n, seeded = 128, np.arange(512) >= 384
            q = np.zeros((512, 3), dtype=np.float32)
            q[seeded, :2] = rng.uniform(-0.07, 0.07, (n, 2))
            q[seeded, 2] = rng.uniform(0.4, 0.6, n)
            b.position.assign(q)
            b.velocity.assign(np.tile(np.array([0.0, 0.0, -3.0], dtype=np.float32), (512, 1)))
            b.lifetime.assign(np.where(seeded, 3.0, 0.0).astype(np.float32))
            b.kind.assign(np.where(seeded, DIFFUSE_SPRAY, DIFFUSE_DEAD).astype(np.int32))
            b.world.fill_(int(scene.model.particle_world.numpy()[0]))
            most_inside = 0
            for _ in range(60):
                scene.run(1)
                alive = b.kind.numpy() != DIFFUSE_DEAD
                most_inside = max(most_inside, int(np.count_nonzero(inside_shape(b.position.numpy()[alive]))))
            test.assertEqual(most_inside, 0)
            # the seeded ones came to the shape and rest on it (not killed on the way)
            test.assertLess(scene.emitted(), 384)
            alive = (b.kind.numpy() != DIFFUSE_DEAD) & seeded
            test.assertGreater(int(alive.sum()), n // 2)
            test.assertLess(float(b.position.numpy()[alive, 2].max()), 0.25)


def test_no_effect_on_fluid(test, device):
    results = []
    for capacity in (0, 256):
        scene = Scene(device, (6, 6, 4), (-0.125, -0.125, 0.4), velocity=(0.0, 0.0, -1.0), capacity=capacity)
        scene.run(60)
        if capacity:
            test.assertGreater(scene.emitted(), 0)
        else:
            test.assertIsNone(scene.solver.diffuse_positions)
        results.append((scene.s0.particle_q.numpy(), scene.s0.particle_qd.numpy()))
    np.testing.assert_array_equal(results[0][0], results[1][0])
    np.testing.assert_array_equal(results[0][1], results[1][1])


def test_diffuse_capturable(test, device):
    scene = Scene(device, (6, 6, 4), (-0.125, -0.125, 0.4), velocity=(0.0, 0.0, -1.0), capacity=256)
    scene.run(2)
    with wp.ScopedCapture(device=device) as capture:
        scene.run(2)  # an even count: the state ping-pong ends where it began
    for _ in range(30):
        wp.capture_launch(capture.graph)
    test.assertGreater(scene.emitted(), 0)
    # the substep counter lives on the device: 2 plain substeps, then 30 replays of 2 (capture runs nothing)
    test.assertEqual(int(scene.solver._fluid.diffuse.counters.numpy()[2]), 2 + 60)


class TestFluidDiffuse(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        # bit-for-bit comparison needs the deterministic CPU path (CUDA atomics reorder sums)
        if _name == "test_no_effect_on_fluid":
            add_function_test(TestFluidDiffuse, _name, _func, devices=[wp.get_device("cpu")])
        else:
            add_function_test(TestFluidDiffuse, _name, _func, devices=devices)
del _name, _func

if __name__ == "__main__":
    unittest.main(verbosity=2)
