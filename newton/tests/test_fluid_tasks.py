# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The batched task interface of the fluid examples (``fluid_xpbd_pouring``): arrays, resets, actions."""

import unittest

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton
from newton.examples.fluid import example_fluid_xpbd_pouring as pouring

WORLDS = 3


def make(device, policy="scripted"):
    args = pouring.Example.create_parser().parse_args(
        ["--viewer", "null", "--world-count", str(WORLDS), "--particle-count", "300", "--policy", policy]
    )
    with wp.ScopedDevice(device):
        return pouring.Example(newton.viewer.ViewerNull(num_frames=1000), args)


def mask(device, *worlds):
    m = np.zeros(WORLDS + 1, dtype=bool)
    m[list(worlds)] = True
    return wp.array(m, dtype=wp.bool, device=device)


def assert_same(test, device, a, b):
    # bitwise on the CPU; CUDA's contact sums are reordered by atomics
    if device.is_cuda:
        np.testing.assert_allclose(a, b, atol=1.0e-3, rtol=0.0)
    else:
        np.testing.assert_array_equal(a, b)


def test_task_arrays_and_start(test, device):
    env = make(device)
    test.assertEqual(env.actions.shape, (WORLDS, 3))
    test.assertEqual(env.observations.shape, (WORLDS, 10))
    for name, dtype in (("rewards", wp.float32), ("terminated", wp.bool), ("truncated", wp.bool)):
        test.assertEqual(getattr(env, name).shape, (WORLDS,))
        test.assertEqual(getattr(env, name).dtype, dtype)
    test.assertEqual(env.episode_steps.dtype, wp.int32)
    obs = env.observations.numpy()
    # at the start: the cup where it starts, all the water in it, none in the tank or spilled
    np.testing.assert_allclose(obs[:, :3], np.tile(pouring.START, (WORLDS, 1)), atol=1e-6)
    np.testing.assert_allclose(obs[:, 3:6], np.tile([1.0, 0.0, 0.0], (WORLDS, 1)))
    np.testing.assert_array_equal(env.episode_steps.numpy(), 0)


def test_restarted_world_replays_its_start(test, device):
    env, fresh = make(device), make(device)
    start_obs = env.observations.numpy()
    for _ in range(20):
        env.step()
    before = env.observations.numpy()
    env.reset(mask(device, 1))
    obs = env.observations.numpy()
    # back at the start, observed as at the start (the centroid is an atomic float sum: last bits on CUDA)
    assert_same(test, device, obs[1], start_obs[1])
    np.testing.assert_array_equal(obs[[0, 2]], before[[0, 2]])  # the others are left as they were
    np.testing.assert_array_equal(env.episode_steps.numpy(), [20, 0, 20])
    for _ in range(20):
        env.step()
        fresh.step()
    # world 1 went through its first 20 steps again, as the fresh environment's did
    assert_same(test, device, env.observations.numpy()[1], fresh.observations.numpy()[1])
    q, q_fresh = env.state_0.particle_q.numpy(), fresh.state_0.particle_q.numpy()
    one = env.model.particle_world.numpy() == 1
    assert_same(test, device, q[one], q_fresh[one])
    test.assertGreater(np.abs(env.observations.numpy()[0] - env.observations.numpy()[1]).max(), 0.01)


def test_ended_episodes_restart_at_the_next_step(test, device):
    env = make(device)
    env.max_episode_steps = 4
    env.capture()  # the step reads the limit as a launch argument
    for k in range(4):
        env.step()
        test.assertEqual(bool(env.truncated.numpy().any()), k == 3)
    test.assertTrue(env.truncated.numpy().all())
    test.assertFalse(env.terminated.numpy().any())
    env.step()
    # every world began its next episode with this step: one step into it, the cup near its start
    np.testing.assert_array_equal(env.episode_steps.numpy(), 1)
    test.assertFalse(env.truncated.numpy().any())
    np.testing.assert_allclose(env.observations.numpy()[:, 0], pouring.START[0], atol=0.02)


def test_actions_drive_the_cups(test, device):
    env = make(device)
    actions = np.zeros((WORLDS, 3), dtype=np.float32)
    actions[:, 0] = [0.3, -0.3, 9.0]  # the last is clamped to ACTION_LIMIT
    env.set_actions(actions)
    for _ in range(6):
        env.step()
    x = env.observations.numpy()[:, 0]
    np.testing.assert_allclose(x - pouring.START[0], np.array([0.3, -0.3, 0.5]) * 6 / 60, atol=1e-5)
    # the scripted controller is off: the actions stay as set
    np.testing.assert_array_equal(env.actions.numpy(), actions)


def test_scripted_pour_fills_the_tank(test, device):
    env = make(device)
    ended = np.zeros(WORLDS, dtype=bool)
    kept = np.zeros(WORLDS)
    for _ in range(240):
        env.step()
        done = env.terminated.numpy() & ~ended
        kept[done] = env.observations.numpy()[done, 4]
        spilled = env.observations.numpy()[:, 5]
        test.assertTrue((spilled[~ended] <= 0.05).all(), spilled)
        ended |= done
    test.assertTrue(ended.all(), "the scripted pour did not end every world's episode")
    test.assertTrue((kept >= pouring.SUCCESS).all(), kept)


class TestFluidTasks(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestFluidTasks, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
