# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Over-packed placements: fluid placed closer than its rest spacing, overlapping or inside a shape (issue #23, item 3).

The step after the placement moves it apart, positions only (``newton/_src/solvers/xpbd/fluid/placement.py``);
before, PBF turned the packing's correction into velocity (``benchmarks/packed_start.py``).
"""

import unittest

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton
import newton._src.solvers.xpbd.fluid.solver_fluid as solver_fluid
from newton._src.solvers.xpbd.fluid.placement import EAGER_RELAXATION_ROUNDS, RELAXATION_ROUNDS
from newton.examples.fluid.common import add_closed_box
from newton.tests.test_fluid_continuous_collision import inside, surface_height
from newton.tests.test_fluid_reset import assert_same
from newton.tests.test_fluid_stress import report
from newton.tests.test_solver_xpbd_fluid import D, Sim, add_block

BLOCK = (6, 6, 5)  # particles of the placed block
EDGE = BLOCK[0] * D  # the closed box is as wide as the block at its rest spacing
HEIGHT = 1.5  # [m]


def add_packed_block(builder, fraction, vel=(0.0, 0.0, 0.0)):
    """``BLOCK`` placed at ``fraction`` of the rest spacing, centred on the floor of ``[0, EDGE]^2``."""
    s = fraction * D
    corner = 0.5 * (EDGE - BLOCK[0] * s) + 0.5 * s
    add_block(builder, BLOCK, origin=(corner, corner, 0.5 * s), spacing=s, vel=vel, jitter=0.01 * D)


def packed_box(device, fraction):
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    add_packed_block(builder, fraction)
    add_closed_box(builder, EDGE, HEIGHT, thickness=2.0 * D)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model


def two_worlds(device, fraction0):
    """World 0: the block at ``fraction0`` of its spacing; world 1: at rest spacing, thrown at a wall."""
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    for w, fraction in enumerate((fraction0, 1.0)):
        world = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
        add_packed_block(world, fraction, vel=(0.0, 0.0, 0.0) if w == 0 else (1.5, 0.5, 0.0))
        add_closed_box(world, EDGE, HEIGHT, thickness=2.0 * D)
        builder.add_world(world)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model


def world_of(sim, array, w):
    return array.numpy()[sim.model.particle_world.numpy() == w].astype(np.float64)


def test_packed_start_rises_no_more_than_five_spacings(test, device):
    for fraction in (0.5, 0.9):
        with test.subTest(fraction=fraction):
            sim = Sim(packed_box(device, fraction), substeps=8, contacts=True)
            test.assertTrue(sim.solver._fluid.initial_overpacked)
            sim.step(1)
            # the packing was undone without velocity: the first frame is a fall, not a burst
            # (before: 22-136 m/s in benchmarks/packed_start.py)
            test.assertLess(np.linalg.norm(sim.qd(), axis=1).max(), 1.5)
            highest = sim.q()[:, 2].max()
            for _ in range(59):
                sim.step(1)
                highest = max(highest, sim.q()[:, 2].max())
            q = sim.q()
            test.assertTrue(np.isfinite(q).all())
            # none leaves the box, and none rose more than 5 spacings above the level the fluid settles to
            test.assertGreater(q.min(), -D)
            test.assertLess(q[:, :2].max(), EDGE + D)
            level = np.percentile(q[:, 2], 99) + 0.5 * D
            test.assertLess(highest - level, 5.0 * D)
            stats, messages = report(sim)
            test.assertGreater(stats["overpacked_placed"], 0)
            named = [m for m in messages if "placed more than 10 % above rest density" in m]
            test.assertEqual(len(named), 1, messages)
            test.assertIn("within 1 % of rest density", named[0])


def test_relaxation_can_be_switched_off(test, device):
    sim = Sim(packed_box(device, 0.7), substeps=8, contacts=True, fluid_relax_overpacked=False)
    test.assertFalse(sim.solver._fluid.initial_overpacked)
    sim.step(1)
    # stepped as placed: the correction of the packing leaves as velocity
    test.assertGreater(np.linalg.norm(sim.qd(), axis=1).max(), 10.0)
    stats, messages = report(sim)
    test.assertEqual(stats["overpacked_placed"], 0)
    test.assertFalse(any("placed more than" in m for m in messages), messages)
    with test.assertRaisesRegex(ValueError, r"fluid_relax_overpacked='yes' is invalid: expected True or False"):
        newton.solvers.SolverXPBD(packed_box(device, 0.7), fluid_rest_distance=D, fluid_relax_overpacked="yes")


def test_relaxation_leaves_other_worlds_untouched(test, device):
    packed, plain = Sim(two_worlds(device, 0.6), contacts=True), Sim(two_worlds(device, 1.0), contacts=True)
    test.assertTrue(packed.solver._fluid.initial_overpacked)
    test.assertFalse(plain.solver._fluid.initial_overpacked)
    for _ in range(10):
        packed.step(1)
        plain.step(1)
        for array in ("particle_q", "particle_qd"):
            assert_same(
                test,
                device,
                world_of(packed, getattr(packed.state_0, array), 1),
                world_of(plain, getattr(plain.state_0, array), 1),
            )
    # the packed world did spread (at 0.6 the block filled 22 % of the box's floor)
    q0 = world_of(packed, packed.state_0.particle_q, 0)
    test.assertGreater(np.ptp(q0[:, 0]) * np.ptp(q0[:, 1]), 0.6 * EDGE * EDGE)


def squeezed(sim, w, factor):
    """A copy of the current state with world ``w``'s fluid squeezed about its centroid by ``factor``."""
    state = sim.model.state()
    q = sim.q()
    sel = sim.model.particle_world.numpy() == w
    centre = q[sel].mean(axis=0)
    q[sel] = centre + factor * (q[sel] - centre)
    state.particle_q.assign(q.astype(np.float32))
    state.particle_qd.zero_()
    return state


def world_mask(device, *worlds):
    m = np.zeros(3, dtype=bool)
    m[list(worlds)] = True
    return wp.array(m, dtype=wp.bool, device=device)


def test_reset_to_a_packed_state_relaxes_that_world(test, device):
    sim, plain = Sim(two_worlds(device, 1.0), contacts=True), Sim(two_worlds(device, 1.0), contacts=True)
    sim.step(10)
    plain.step(10)
    source = squeezed(sim, 0, 0.6)
    # a reset from the initial particles (not over-packed) asks for no check
    sim.solver.reset(sim.state_0, world_mask(device, 1), newton.StateFlags.PARTICLE_QD)
    test.assertFalse(sim.solver._fluid.placement_pending)
    sim.solver.reset(sim.state_0, world_mask(device, 0), fluid_source=source)
    test.assertTrue(sim.solver._fluid.placement_pending)
    # (the velocity reset of world 1 is matched in the run without the packed world)
    plain.solver.reset(plain.state_0, world_mask(device, 1), newton.StateFlags.PARTICLE_QD)
    sim.step(1)
    plain.step(1)
    test.assertLess(np.linalg.norm(world_of(sim, sim.state_0.particle_qd, 0), axis=1).max(), 1.0)
    assert_same(test, device, world_of(sim, sim.state_0.particle_q, 1), world_of(plain, plain.state_0.particle_q, 1))
    stats, messages = report(sim)
    test.assertEqual(stats["overpacked_placed"], np.prod(BLOCK))
    test.assertTrue(any("placed more than 10 %" in m for m in messages), messages)


# a hill under the middle of the block: a 5 x 5 terrain over the box's floor, its centre 0.3 m high
HILL = newton.Heightfield(np.pad([[1.0]], 2), 5, 5, hx=0.5 * EDGE, hy=0.5 * EDGE, min_z=0.0, max_z=0.3)


def inside_static_shape(kind, q, centre, half):
    """Whether each centre of ``q`` is inside the static shape of :func:`test_fluid_placed_inside_a_static_shape_moves_out`."""
    local = q - centre
    if kind == "cylinder":
        return (np.linalg.norm(local[:, :2], axis=1) < half) & (np.abs(local[:, 2]) < half)
    if kind == "barrel":
        return inside(newton.GeoType.CYLINDER, (0.7 * half, half, 1.8 * half), local)
    if kind == "cone":
        return inside(newton.GeoType.CONE, (half, half, 0.0), local)
    if kind == "ellipsoid":
        return inside(newton.GeoType.ELLIPSOID, (half, 0.8 * half, half), local)
    if kind == "heightfield":
        x, y = local[:, 0], local[:, 1]
        over = (np.abs(x) <= HILL.hx) & (np.abs(y) <= HILL.hy)
        return over & (q[:, 2] < surface_height(HILL.data, HILL.hx, HILL.hy, HILL.min_z, HILL.max_z, x, y))
    return np.all(np.abs(local) < half, axis=1)


def test_fluid_placed_inside_a_static_shape_moves_out(test, device):
    # a static box, a watertight triangle-mesh box, a straight and a barrel-sided cylinder, a cone and an ellipsoid
    # in the middle of a block at its rest spacing, and a terrain whose hill rises under it
    centre, half = np.array([0.5 * EDGE, 0.5 * EDGE, 0.25]), 0.12
    cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
    xform = wp.transform(wp.vec3(*centre), wp.quat_identity())
    shapes = {
        "box": lambda b: b.add_shape_box(-1, xform=xform, hx=half, hy=half, hz=half, cfg=cfg),
        "mesh": lambda b: b.add_shape_mesh(
            -1, xform=xform, mesh=newton.Mesh.create_box(half, duplicate_vertices=False), cfg=cfg
        ),
        "cylinder": lambda b: b.add_shape_cylinder(-1, xform=xform, radius=half, half_height=half, cfg=cfg),
        # (its side bulges from 0.7 to 1.0 times the half size)
        "barrel": lambda b: b.add_shape_cylinder(
            -1, xform=xform, radius=0.7 * half, half_height=half, barrel_radius=1.8 * half, cfg=cfg
        ),
        "cone": lambda b: b.add_shape_cone(-1, xform=xform, radius=half, half_height=half, cfg=cfg),
        "ellipsoid": lambda b: b.add_shape_ellipsoid(-1, xform=xform, rx=half, ry=0.8 * half, rz=half, cfg=cfg),
        "heightfield": lambda b: b.add_shape_heightfield(
            xform=wp.transform(wp.vec3(centre[0], centre[1], 0.0)), heightfield=HILL, cfg=cfg
        ),
    }
    for kind, add_shape in shapes.items():
        with test.subTest(shape=kind):
            builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
            add_packed_block(builder, 1.0)
            add_closed_box(builder, EDGE, HEIGHT, thickness=2.0 * D)
            add_shape(builder)
            model = builder.finalize(device=device)
            model.soft_contact_mu = 0.0
            placed_inside = int(inside_static_shape(kind, model.particle_q.numpy(), centre, half).sum())
            test.assertGreaterEqual(placed_inside, 4)
            sim = Sim(model, substeps=8, contacts=True)
            # (the block is at its rest spacing: only the centres inside the shape make it a bad start)
            test.assertTrue(sim.solver._fluid.initial_overpacked)
            sim.step(1)
            q = sim.q()
            # every centre is out of the shape and the fluid moved there without being thrown
            test.assertEqual(int(inside_static_shape(kind, q, centre, half).sum()), 0)
            test.assertGreater(q.min(), 0.0)
            test.assertLess(np.linalg.norm(sim.qd(), axis=1).max(), 1.5)
            stats, _ = report(sim)
            test.assertGreaterEqual(stats["overpacked_placed"], placed_inside)


def test_fluid_placed_inside_a_dynamic_body_moves_out(test, device):
    """A floating box started in the water: the fluid in it moves out, and neither is thrown."""
    speeds = {}
    for relax in (True, False):
        builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
        add_packed_block(builder, 1.0)
        add_closed_box(builder, EDGE, HEIGHT, thickness=2.0 * D)
        body = builder.add_body(xform=wp.transform(wp.vec3(0.5 * EDGE, 0.5 * EDGE, 0.4), wp.quat_identity()))
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0, density=500.0)
        builder.add_shape_box(body, hx=0.12, hy=0.12, hz=0.08, cfg=cfg)
        model = builder.finalize(device=device)
        model.soft_contact_mu = 0.0
        inside = np.all(np.abs(model.particle_q.numpy() - (0.5 * EDGE, 0.5 * EDGE, 0.4)) < (0.12, 0.12, 0.08), axis=1)
        test.assertEqual(int(inside.sum()), 8)
        sim = Sim(model, substeps=8, contacts=True, fluid_relax_overpacked=relax)
        sim.step(1)
        qd = sim.state_0.body_qd.numpy()[0]
        speeds[relax] = (np.linalg.norm(qd[:3]), np.linalg.norm(sim.qd(), axis=1).max())
        if relax:
            q = sim.q()
            box = sim.state_0.body_q.numpy()[0, :3]
            test.assertEqual(int(np.all(np.abs(q - box) < (0.12, 0.12, 0.08), axis=1).sum()), 0)
    # (Newton's spatial velocities: the linear part first)
    test.assertLess(speeds[True][0], 0.5)
    test.assertLess(speeds[True][1], 1.5)
    # stepped as placed, the box's contacts throw the fluid in it out (34 m/s on the CPU)
    test.assertGreater(speeds[False][1], 10.0)


def test_relaxation_inside_captured_graph(test, device):
    """One graph of reset(mask, packed state) and a frame; the mask changes between replays, as eager calls do."""
    graph_sim, eager = Sim(two_worlds(device, 1.0), contacts=True), Sim(two_worlds(device, 1.0), contacts=True)
    source = squeezed(graph_sim, 0, 0.6)
    squeezed_1 = squeezed(graph_sim, 1, 0.6)
    source.particle_q.assign(
        np.where(
            (graph_sim.model.particle_world.numpy() == 1)[:, None],
            squeezed_1.particle_q.numpy(),
            source.particle_q.numpy(),
        )
    )
    m = world_mask(device)
    with wp.ScopedCapture(device=device) as capture:
        graph_sim.solver.reset(graph_sim.state_0, m, fluid_source=source)
        graph_sim.step(1)
    for selected in ((), (0,), (), (1,), (0, 1)):
        m.assign(world_mask(device, *selected).numpy())
        wp.capture_launch(capture.graph)
        eager.solver.reset(eager.state_0, world_mask(device, *selected), fluid_source=source)
        eager.step(1)
        np.testing.assert_allclose(graph_sim.q(), eager.q(), atol=1.0e-4)
    stats, _ = report(eager)
    test.assertEqual(stats["overpacked_placed"], 4 * np.prod(BLOCK))


def deep_packed_column(device, fraction):
    """A column 4 x 4 particles wide and 40 deep at ``fraction`` of its spacing, in a closed box as wide as it is at rest."""
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    edge, s = 4 * D, fraction * D
    corner = 0.5 * (edge - 4 * s) + 0.5 * s
    add_block(builder, (4, 4, 40), origin=(corner, corner, 0.5 * s), spacing=s, jitter=0.01 * D)
    add_closed_box(builder, edge, 120 * D, thickness=2.0 * D)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model


def test_deep_column_relaxes_in_a_conditional_loop(test, device):
    # a correction travels about a neighbour per pass, so the rounds grow with the square of the depth: 40
    # layers take about 270 rounds. In a graph (and on the CPU) the rounds are a conditional loop that runs
    # until the last world is relaxed, up to RELAXATION_ROUNDS
    sim = Sim(deep_packed_column(device, 0.5), substeps=8, contacts=True)
    with wp.ScopedCapture(device=device) as capture:
        sim.step(1)
    wp.capture_launch(capture.graph)
    rounds = RELAXATION_ROUNDS - int(sim.solver._fluid.placement_rounds_left.numpy()[0])
    test.assertGreater(rounds, 2 * EAGER_RELAXATION_ROUNDS)
    test.assertLess(rounds, RELAXATION_ROUNDS)
    test.assertLess(np.linalg.norm(sim.qd(), axis=1).max(), 1.0)
    stats, messages = report(sim)
    test.assertEqual(stats["overpacked_placed"], 640)
    test.assertTrue(any("within 1 % of rest density" in m for m in messages), messages)
    # the graph's later replays skip the check: they step as the eager solver steps the relaxed column
    eager = Sim(deep_packed_column(device, 0.5), substeps=8, contacts=True)
    eager.state_0.particle_q.assign(sim.state_0.particle_q)
    eager.state_0.particle_qd.assign(sim.state_0.particle_qd)
    eager.solver._fluid.placement_pending = False
    wp.capture_launch(capture.graph)
    eager.step(1)
    np.testing.assert_allclose(sim.q(), eager.q(), atol=1.0e-4)
    test.assertEqual(report(sim)[0]["overpacked_placed"], 0)
    # with the rounds a CUDA step launches where the driver has no conditional nodes, the column is left packed
    # and springs apart
    kept, solver_fluid.RELAXATION_ROUNDS = solver_fluid.RELAXATION_ROUNDS, EAGER_RELAXATION_ROUNDS
    try:
        short = Sim(deep_packed_column(device, 0.5), substeps=8, contacts=True)
        short.step(1)
    finally:
        solver_fluid.RELAXATION_ROUNDS = kept
    test.assertGreater(np.linalg.norm(short.qd(), axis=1).max(), 5.0)
    _, messages = report(short)
    test.assertTrue(any("were still packed" in m for m in messages), messages)


def test_deep_column_relaxes_in_a_step_outside_a_graph(test, device):
    # a step that is not captured runs the same conditional loop: on the CPU directly, on CUDA as a graph the
    # solver captured at construction (its launch reads no flag on the host), on copies of the state's arrays
    sim = Sim(deep_packed_column(device, 0.5), substeps=8, contacts=True)
    if wp.get_device(device).is_cuda and wp.is_conditional_graph_supported():
        test.assertIsNotNone(sim.solver._fluid.eager_relaxation)
    sim.step(1)
    rounds = RELAXATION_ROUNDS - int(sim.solver._fluid.placement_rounds_left.numpy()[0])
    test.assertGreater(rounds, 2 * EAGER_RELAXATION_ROUNDS)
    test.assertLess(np.linalg.norm(sim.qd(), axis=1).max(), 1.0)
    stats, messages = report(sim)
    test.assertEqual(stats["overpacked_placed"], 640)
    test.assertTrue(any("within 1 % of rest density" in m for m in messages), messages)
    # a reset to the packed start asks for the check again and reuses the captured graph
    captured = sim.solver._fluid.eager_relaxation
    sim.solver.reset(sim.state_0)
    test.assertTrue(sim.solver._fluid.eager_relaxation is captured)
    sim.step(1)
    test.assertLess(np.linalg.norm(sim.qd(), axis=1).max(), 1.0)
    test.assertEqual(report(sim)[0]["overpacked_placed"], 640)


def test_open_mesh_has_no_inside(test, device):
    # a sheet of two triangles through the block (not watertight): fluid on either side is outside it, so
    # a block at its rest spacing is not a bad start (by the faces' normals, the lower half would be inside)
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    add_packed_block(builder, 1.0)
    add_closed_box(builder, EDGE, HEIGHT, thickness=2.0 * D)
    z = 2.0 * D
    points = np.array([[0.0, 0.0, z], [EDGE, 0.0, z], [EDGE, EDGE, z], [0.0, EDGE, z]], dtype=np.float32)
    sheet = newton.Mesh(points, np.array([0, 1, 2, 0, 2, 3], dtype=np.int32), compute_inertia=False, is_solid=False)
    test.assertFalse(sheet.is_watertight)
    builder.add_shape_mesh(-1, mesh=sheet, cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    model = builder.finalize(device=device)
    test.assertTrue(np.any(model.particle_q.numpy()[:, 2] < z))
    sim = Sim(model, substeps=8, contacts=True)
    test.assertFalse(sim.solver._fluid.initial_overpacked)


class TestFluidPlacement(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestFluidPlacement, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
