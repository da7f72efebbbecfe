# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Mouse picking of fluid particles (the ray, the drag, the choice between fluid and bodies)."""

import unittest

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton
from newton._src.viewer.gl.fluid.picking import FluidPicking

D = 0.05  # rest distance [m]


def pool(device, box_height=None):
    """An 8 x 8 x 3 block of water on the ground (top layer centred at z = 2.5 D), optionally a box above it."""
    builder = newton.ModelBuilder()
    builder.add_particle_grid(
        pos=wp.vec3(-3.5 * D, -3.5 * D, 0.5 * D),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0),
        dim_x=8,
        dim_y=8,
        dim_z=3,
        cell_x=D,
        cell_y=D,
        cell_z=D,
        mass=1000.0 * D**3,
        jitter=0.0,
        radius_mean=0.5 * D,
        flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
    )
    builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    if box_height is not None:
        body = builder.add_body(xform=wp.transform(wp.vec3(0.0, 0.0, box_height), wp.quat_identity()))
        builder.add_shape_box(body, hx=0.05, hy=0.05, hz=0.05)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model


def drag(test, device, pick):
    """Positions after 20 frames of the pool, with (``pick``) or without a drag of 0.15 m along +x."""
    model = pool(device)
    solver = newton.solvers.SolverXPBD(model, iterations=2, fluid_rest_distance=D)
    picking = FluidPicking(model)
    s0, s1 = model.state(), model.state()
    pipeline = newton.CollisionPipeline(model, soft_contact_gap=0.5 * D)
    contacts = pipeline.contacts()
    dt = 1.0 / 60.0 / 4

    def simulate():
        nonlocal s0, s1
        for _ in range(4):
            s0.clear_forces()
            picking.apply_force(s0)
            pipeline.collide(s0, contacts)
            solver.step(s0, s1, None, contacts, dt)
            s0, s1 = s1, s0

    graph = None
    if wp.get_device(device).is_cuda:
        # captured before anything is picked: the pick must reach the graph through device memory
        with wp.ScopedCapture(device) as capture:
            simulate()
        graph = capture.graph

    picked = -1
    if pick:
        # a ray straight down onto the particle at (0.5 D, 0.5 D) of the top layer
        start, down = (0.5 * D, 0.5 * D, 1.0), (0.0, 0.0, -1.0)
        picking.pick(s0, start, down)
        test.assertTrue(picking.is_picking())
        test.assertEqual(picking.pick_body, -1)
        picked = picking.pick_particle
        np.testing.assert_allclose(s0.particle_q.numpy()[picked], (0.5 * D, 0.5 * D, 2.5 * D), atol=1.0e-6)
        # drag it 0.15 m along +x: the ray through the new target, at the same depth
        picking.update((0.5 * D + 0.15, 0.5 * D, 1.0), down)
        target = np.asarray(picking.pick_target)
        np.testing.assert_allclose(target, (0.5 * D + 0.15, 0.5 * D, 2.5 * D), atol=1.0e-5)
    for _ in range(20):
        if graph is not None:
            # four substeps swap the states back: the graph ends in s0 as the capture did
            wp.capture_launch(graph)
        else:
            simulate()
    q = s0.particle_q.numpy().copy()
    test.assertTrue(np.isfinite(q).all())
    if pick:
        # the point as of the last apply_force, one substep before the end
        np.testing.assert_allclose(np.asarray(picking.pick_point), q[picked], atol=0.01)
        picking.release()
        test.assertFalse(picking.is_picking())
        s0.clear_forces()
        picking.apply_force(s0)
        test.assertEqual(np.abs(s0.particle_f.numpy()).max(), 0.0)
    return q, picked


def test_pick_drags_a_blob_of_fluid(test, device):
    q0 = pool(device).particle_q.numpy()
    free, _ = drag(test, device, pick=False)  # the block spreads on its own (no walls)
    dragged, picked = drag(test, device, pick=True)
    moved = dragged[:, 0] - free[:, 0]
    test.assertGreater(moved[picked], 0.08)
    near = np.linalg.norm(q0 - q0[picked], axis=1) < 1.5 * D
    behind = q0[:, 0] < q0[picked, 0] - 2.5 * D
    # a blob follows the pick, not the one particle; the water behind it follows much less
    test.assertGreater(moved[near].mean(), 0.05)
    test.assertLess(np.abs(moved[behind]).mean(), 0.3 * moved[near].mean())


def test_pick_chooses_what_the_ray_meets_first(test, device):
    model = pool(device, box_height=0.5)
    state = model.state()
    newton.eval_fk(model, model.joint_q, model.joint_qd, state)
    picking = FluidPicking(model)
    down = (0.0, 0.0, -1.0)
    # the box (top at 0.55 m) is above the water on this ray
    picking.pick(state, (0.5 * D, 0.5 * D, 1.0), down)
    test.assertTrue(picking.is_picking())
    test.assertEqual(picking.pick_body, 0)
    test.assertEqual(picking.pick_particle, -1)
    # beside the box, the ray meets the water
    picking.pick(state, (3.5 * D, 3.5 * D, 1.0), down)
    test.assertEqual(picking.pick_body, -1)
    q = state.particle_q.numpy()
    np.testing.assert_allclose(q[picking.pick_particle], (3.5 * D, 3.5 * D, 2.5 * D), atol=1.0e-6)
    # from below the ground looking further down: nothing
    picking.pick(state, (0.0, 0.0, -1.0), down)
    test.assertFalse(picking.is_picking())
    with test.assertRaisesRegex(ValueError, "fluid_pick_radius=-1.0"):
        FluidPicking(model, fluid_pick_radius=-1.0)


class TestFluidPicking(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestFluidPicking, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
