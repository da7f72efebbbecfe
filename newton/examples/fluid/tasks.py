# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Batched fluid tasks: the arrays a policy trains on over many worlds, and their per-world reset.

:class:`FluidTask` turns a multi-world fluid example into an environment without depending on a
training framework. Its arrays live on the model's device, one row per world:

- ``actions`` (world_count, action_dim), float: set with :meth:`FluidTask.set_actions` or written
  in place; read by the example's ``prescribe`` every substep;
- ``observations`` (world_count, observation_dim), float; ``rewards`` (world_count,), float;
- ``terminated`` and ``truncated`` (world_count,), bool: the episode ended (the task's end, or its
  time limit) with this step;
- ``episode_steps`` (world_count,), int32: steps since the world's episode began.

One :meth:`~newton.examples.fluid.common.FluidExample.step` is one environment step (a frame of
``sim_substeps`` substeps). It first restarts the worlds whose episode ended with the last step
(``SolverXPBD.reset`` with their mask, and the example's own restart), so a world that ended its
episode begins its next one at the next step, from the same start every time; then it sets the
scripted actions (unless :meth:`set_actions` took over), simulates, and measures. All of it is
device work, captured as one CUDA graph. :meth:`reset` restarts worlds at once, outside the step.

A subclass builds the scene, sets ``action_dim``, ``observation_dim`` and ``episode_seconds``,
allocates ``previous`` (per world, what its reward compares with), calls :meth:`setup_task` after
creating its solver, and implements :meth:`restart_worlds`, :meth:`scripted_actions`, ``prescribe``
and :meth:`observe`, whose kernel ends with :func:`begin_observation` / :func:`end_observation` and
takes :meth:`observation_args`.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from newton.examples.fluid.common import FluidExample


@wp.kernel
def mask_ended_worlds(terminated: wp.array[wp.bool], truncated: wp.array[wp.bool], mask: wp.array[wp.bool]):
    """The reset mask (``world_count + 1`` entries, the last for world -1) of the worlds whose episode ended."""
    w = wp.tid()
    if w < terminated.shape[0]:
        mask[w] = terminated[w] or truncated[w]
    else:
        mask[w] = False


@wp.func
def begin_observation(w: int, first: int, first_mask: wp.array[wp.bool], episode_steps: wp.array[wp.int32]):
    """Whether world ``w`` is observed now (after a step: every world; after restarts: those restarted),
    counting the step into its episode."""
    if first != 0:
        return first_mask[w]
    episode_steps[w] = episode_steps[w] + 1
    return True


@wp.func
def end_observation(
    w: int,
    first: int,
    reward: float,
    ended: bool,
    succeeded: bool,
    max_steps: int,
    episode_steps: wp.array[wp.int32],
    episodes: wp.array2d[wp.int32],
    rewards: wp.array[float],
    terminated: wp.array[wp.bool],
    truncated: wp.array[wp.bool],
):
    """Write world ``w``'s reward and ends (none just after a restart) and count an ended episode as a
    success (``episodes[w, 0]``) or not (``episodes[w, 1]``)."""
    if first != 0:
        reward = 0.0
        ended = False
    elif ended:
        if succeeded:
            episodes[w, 0] = episodes[w, 0] + 1
        else:
            episodes[w, 1] = episodes[w, 1] + 1
    rewards[w] = reward
    terminated[w] = ended
    truncated[w] = not ended and first == 0 and episode_steps[w] >= max_steps


@wp.kernel
def restart_episodes(mask: wp.array[wp.bool], episode_steps: wp.array[wp.int32]):
    w = wp.tid()
    if mask[w]:
        episode_steps[w] = 0


class FluidTask(FluidExample):
    """A fluid example as a batched environment (see the module notes)."""

    action_dim = 0
    observation_dim = 0
    #: an episode's time limit [s] (``truncated`` after it)
    episode_seconds = 0.0

    def setup_task(self) -> None:
        """Allocate the task's arrays, set up the simulation (capturing the step) and observe the start."""
        w = self.world_count
        self.max_episode_steps = round(self.episode_seconds * self.fps)
        with wp.ScopedDevice(self.model.device):
            #: per world: episodes that ended in success, and others (``end_observation`` counts them)
            self.episodes = wp.zeros((w, 2), dtype=wp.int32)
            self.actions = wp.zeros((w, self.action_dim), dtype=float)
            self.observations = wp.zeros((w, self.observation_dim), dtype=float)
            self.rewards = wp.zeros(w, dtype=float)
            self.terminated = wp.zeros(w, dtype=wp.bool)
            self.truncated = wp.zeros(w, dtype=wp.bool)
            self.episode_steps = wp.zeros(w, dtype=wp.int32)
            self._ended = wp.zeros(w + 1, dtype=wp.bool)
            self._everything = wp.array(np.ones(w + 1, dtype=bool), dtype=wp.bool)
        self.scripted = True
        self.setup_simulation()
        self.reset()

    # --- what a task implements ------------------------------------------------------------------

    def restart_worlds(self, mask: wp.array) -> None:
        """Put the task's own state of the worlds ``mask`` selects back to the start (device work)."""
        raise NotImplementedError

    def scripted_actions(self) -> None:
        """Write the scripted controller's actions into ``actions`` (device work)."""
        raise NotImplementedError

    def observe(self, first: bool, mask: wp.array | None = None) -> None:
        """Measure the worlds after a step into the task's arrays; with ``first``, the worlds ``mask``
        selects have just been restarted and took no step (no reward, no end), the others are left as they are."""
        raise NotImplementedError

    def observation_args(self, first: bool, mask: wp.array | None) -> tuple[list, list]:
        """The inputs an observation kernel ends with (step limit, ``first``, its mask) and its outputs."""
        inputs = [self.max_episode_steps, int(first), self._everything if mask is None else mask]
        outputs = [
            self.episode_steps,
            self.previous,
            self.episodes,
            self.observations,
            self.rewards,
            self.terminated,
            self.truncated,
        ]
        return inputs, outputs

    # --- the environment -------------------------------------------------------------------------

    def set_actions(self, actions) -> None:
        """Drive the worlds with these actions from now on (the scripted controller stops).

        Args:
            actions: ``wp.array`` or array-like of shape (world_count, action_dim).
        """
        if self.scripted:
            self.scripted = False
            self.capture()  # the captured step no longer writes the scripted actions
        self.actions.assign(actions)

    def reset(self, mask: wp.array | None = None) -> None:
        """Restart the worlds ``mask`` selects now (all with ``None``) and observe them.

        Args:
            mask: ``wp.array`` of ``world_count + 1`` bools on the model's device (the last for world -1),
                as ``SolverXPBD.reset`` takes it; ``None`` restarts every world.
        """
        mask = self._everything if mask is None else mask
        self._restart(mask)
        self.observe(first=True, mask=mask)

    def _restart(self, mask: wp.array) -> None:
        self.solver.reset(self.state_0, mask)
        wp.launch(restart_episodes, dim=self.world_count, inputs=[mask, self.episode_steps])
        self.restart_worlds(mask)

    def simulate(self):
        # worlds whose episode ended with the last step begin the next one
        wp.launch(
            mask_ended_worlds, dim=self.world_count + 1, inputs=[self.terminated, self.truncated], outputs=[self._ended]
        )
        self._restart(self._ended)
        if self.scripted:
            self.scripted_actions()
        super().simulate()
        self.observe(first=False)
