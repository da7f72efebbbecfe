# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Per-world reset of the fluid: restore the selected worlds' particles and forget their history.

A world's fluid carries three things from one step to the next besides its positions and
velocities: the warm-start multipliers (per particle), the last finite position of each particle
(where a non-finite one is put back) and the diffuse particles it emitted. A reset world gets all
three back as a fresh start has them (no multipliers, its restored positions, no diffuse
particles), so that it replays as if the model had just been created, while every other world
keeps its arrays untouched. The kernels read the mask on the device: a captured graph resets
whichever worlds the mask selects at each replay.

The mask follows :meth:`newton.solvers.SolverBase.reset`: ``world_count + 1`` booleans, the last
one selecting the global world ``-1``; ``None`` selects everything.
"""

import warp as wp


@wp.func
def world_selected(world: int, world_mask: wp.array[wp.bool], world_count: int, use_mask: int):
    """Whether a particle of ``world`` is reset: every world without a mask, else its mask entry."""
    if use_mask == 0:
        return True
    if world >= 0 and world < world_count:
        return world_mask[world]
    return world == -1 and world_mask[world_count]


@wp.kernel
def reset_fluid_worlds(
    fluid_particle: wp.array[wp.int32],
    particle_world: wp.array[wp.int32],
    world_mask: wp.array[wp.bool],
    world_count: int,
    use_mask: int,
    source_q: wp.array[wp.vec3],
    source_qd: wp.array[wp.vec3],
    restore_q: int,
    restore_qd: int,
    # outputs
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    last_finite_q: wp.array[wp.vec3],
    particle_lambda: wp.array[float],
):
    k = wp.tid()
    pi = fluid_particle[k]
    if not world_selected(particle_world[pi], world_mask, world_count, use_mask):
        return
    if restore_q != 0:
        particle_q[pi] = source_q[pi]
    if restore_qd != 0:
        particle_qd[pi] = source_qd[pi]
    # a recovery after the reset falls back to where the world restarted, not to where it was
    last_finite_q[k] = particle_q[pi]
    if particle_lambda.shape[0] > 0:
        particle_lambda[pi] = 0.0


@wp.kernel
def reset_diffuse_worlds(
    world_mask: wp.array[wp.bool],
    world_count: int,
    use_mask: int,
    diffuse_world: wp.array[wp.int32],
    dead_kind: int,
    # outputs
    lifetime: wp.array[float],
    kind: wp.array[wp.int32],
):
    i = wp.tid()
    if kind[i] == dead_kind:
        return
    if world_selected(diffuse_world[i], world_mask, world_count, use_mask):
        lifetime[i] = 0.0
        kind[i] = dead_kind
