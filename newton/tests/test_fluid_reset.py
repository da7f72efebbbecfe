# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Per-world reset of the fluid (``SolverXPBD.reset`` with a world mask)."""

import unittest

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton
from newton.examples.fluid.common import add_tank
from newton.tests.test_solver_xpbd_fluid import D, Sim, add_block

WORLDS = 3
# each world's block is thrown at the tank wall at its own speed, so the worlds differ and splash
THROW = ((2.0, 0.0, 0.0), (3.0, 1.0, 0.0), (-2.5, 0.5, 0.0))


def thrown_blocks(device):
    """Three isolated worlds at the same place: a 4 x 4 x 5 block in a tank, thrown at ``THROW[w]``."""
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    for w in range(WORLDS):
        world = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
        add_block(world, (4, 4, 5), origin=(-0.15, -0.15, 0.05), vel=THROW[w])
        add_tank(world, 0.4, 0.4, 0.6, 0.1)
        builder.add_world(world)
    builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model


def make_sim(device):
    # warm start, diffuse particles and the coarse correction on: each is state a reset must clear
    return Sim(
        thrown_blocks(device),
        contacts=True,
        fluid_warm_start=0.5,
        max_diffuse_particles=512,
        fluid_coarse_correction=0.5,
    )


def mask(device, *worlds):
    m = np.zeros(WORLDS + 1, dtype=bool)
    m[list(worlds)] = True
    return wp.array(m, dtype=wp.bool, device=device)


def by_world(sim, array):
    world = sim.model.particle_world.numpy()
    a = array.numpy()
    return [a[world == w] for w in range(WORLDS)]


def assert_same(test, device, a, b):
    """Bitwise on the CPU; on CUDA the contacts' atomic sums reorder, so within float noise of a short run."""
    if device.is_cuda:
        np.testing.assert_allclose(a, b, atol=2.0e-3)
    else:
        np.testing.assert_array_equal(a, b)


def test_reset_world_replays_and_others_continue(test, device):
    reset_run, plain_run, fresh = make_sim(device), make_sim(device), make_sim(device)
    reset_run.step(8)
    plain_run.step(8)
    lam_before = by_world(reset_run, reset_run.solver.fluid_warm_start_multipliers)
    test.assertTrue(np.any(lam_before[1] != 0.0), "the warm start carried no multiplier: nothing to clear")
    diffuse_world = reset_run.solver._fluid.diffuse.world.numpy()
    kinds_before = reset_run.solver.diffuse_kinds.numpy()
    alive_before = kinds_before >= 0
    test.assertGreater(np.count_nonzero(alive_before & (diffuse_world == 1)), 0, "world 1 emitted no diffuse particle")

    reset_run.solver.reset(reset_run.state_0, mask(device, 1))

    # the reset world is back at its start with no history, the others keep theirs bitwise
    q = by_world(reset_run, reset_run.state_0.particle_q)
    q0 = by_world(reset_run, reset_run.model.particle_q)
    np.testing.assert_array_equal(q[1], q0[1])
    np.testing.assert_array_equal(by_world(reset_run, reset_run.state_0.particle_qd)[1], np.tile(THROW[1], (80, 1)))
    lam = by_world(reset_run, reset_run.solver.fluid_warm_start_multipliers)
    np.testing.assert_array_equal(lam[1], 0.0)
    for w in (0, 2):
        np.testing.assert_array_equal(lam[w], lam_before[w])
    kinds = reset_run.solver.diffuse_kinds.numpy()
    test.assertFalse(np.any((kinds >= 0) & (diffuse_world == 1)))
    others = diffuse_world != 1
    np.testing.assert_array_equal(kinds[others], kinds_before[others])

    reset_run.step(8)
    plain_run.step(8)
    fresh.step(8)
    after = by_world(reset_run, reset_run.state_0.particle_q)
    after_qd = by_world(reset_run, reset_run.state_0.particle_qd)
    for w in (0, 2):
        assert_same(test, device, after[w], by_world(plain_run, plain_run.state_0.particle_q)[w])
        assert_same(test, device, after_qd[w], by_world(plain_run, plain_run.state_0.particle_qd)[w])
    assert_same(test, device, after[1], by_world(fresh, fresh.state_0.particle_q)[1])
    assert_same(test, device, after_qd[1], by_world(fresh, fresh.state_0.particle_qd)[1])
    # and the reset did something: world 1 of the run without reset is elsewhere
    test.assertGreater(np.abs(after[1] - by_world(plain_run, plain_run.state_0.particle_q)[1]).max(), 0.1 * D)


def test_reset_from_a_given_state_and_flags(test, device):
    sim = make_sim(device)
    sim.step(4)
    snapshot = sim.model.state()
    snapshot.particle_q.assign(sim.state_0.particle_q)
    snapshot.particle_qd.assign(sim.state_0.particle_qd)
    sim.step(4)
    moved_q = by_world(sim, sim.state_0.particle_q)
    moved_qd = by_world(sim, sim.state_0.particle_qd)

    # positions only: velocities stay as they were
    sim.solver.reset(sim.state_0, mask(device, 2), newton.StateFlags.PARTICLE_Q, fluid_source=snapshot)
    q, qd = by_world(sim, sim.state_0.particle_q), by_world(sim, sim.state_0.particle_qd)
    np.testing.assert_array_equal(q[2], by_world(sim, snapshot.particle_q)[2])
    np.testing.assert_array_equal(qd[2], moved_qd[2])
    for w in (0, 1):
        np.testing.assert_array_equal(q[w], moved_q[w])
        np.testing.assert_array_equal(qd[w], moved_qd[w])

    # no mask: every world, velocities too
    sim.solver.reset(sim.state_0, fluid_source=snapshot)
    np.testing.assert_array_equal(sim.state_0.particle_q.numpy(), snapshot.particle_q.numpy())
    np.testing.assert_array_equal(sim.state_0.particle_qd.numpy(), snapshot.particle_qd.numpy())

    # flags without particles leave the fluid alone
    sim.step(1)
    before = sim.state_0.particle_q.numpy()
    sim.solver.reset(sim.state_0, None, newton.StateFlags.BODY_Q)
    np.testing.assert_array_equal(sim.state_0.particle_q.numpy(), before)


def test_reset_rejects_bad_input(test, device):
    sim = make_sim(device)
    with test.assertRaisesRegex(ValueError, "world_mask"):
        sim.solver.reset(sim.state_0, wp.zeros(WORLDS, dtype=wp.bool, device=device))
    other = newton.ModelBuilder()
    add_block(other, (2, 2, 2))
    wrong = other.finalize(device=device).state()
    with test.assertRaisesRegex(ValueError, r"fluid_source has 8 particles .* expected a State of this model \(240"):
        sim.solver.reset(sim.state_0, fluid_source=wrong)


def test_reset_inside_captured_graph(test, device):
    """One graph of reset(mask) and a frame; the mask's contents change between replays, as eager calls do."""
    graph_sim, eager = make_sim(device), make_sim(device)
    m = mask(device)
    with wp.ScopedCapture(device=device) as capture:
        graph_sim.solver.reset(graph_sim.state_0, m)
        graph_sim.step(1)  # an even number of substeps: state_0 is the graph's input and output
    # the capture ran nothing: start both from the initial state
    for selected in ((), (), (1,), (), (0, 2), ()):
        m.assign(mask(device, *selected).numpy())
        wp.capture_launch(capture.graph)
        eager.solver.reset(eager.state_0, mask(device, *selected))
        eager.step(1)
        np.testing.assert_allclose(graph_sim.q(), eager.q(), atol=1.0e-4)
    # world 1 was reset two frames before the end, worlds 0 and 2 one frame before: they differ
    q = by_world(graph_sim, graph_sim.state_0.particle_q)
    test.assertGreater(np.abs(q[1] - q[0]).max(), 0.1 * D)


class TestFluidReset(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestFluidReset, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
