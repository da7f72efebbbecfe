# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Mouse picking of fluid: upstream's body picking, plus dragging a blob of fluid particles.

A ray that meets a fluid particle before any body picks that particle; the spring of the pick then
pulls every fluid particle within :attr:`FluidPicking.fluid_pick_radius` of it toward the target,
each with the acceleration the spring gives the picked particle (so a handful of water moves as a
blob instead of one particle slipping through its neighbours). Gains and the acceleration limit
are upstream's (``pick_stiffness``, ``pick_damping``, ``pick_max_acceleration``).
"""

from __future__ import annotations

import numpy as np
import warp as wp
from newton._src.geometry.flags import ParticleFlags
from newton._src.viewer.kernels import PickingState
from newton._src.viewer.picking import Picking

from .upstream import body_pick_distance, body_pick_state

GRAVITY = 9.81  # [m/s^2], the unit of upstream's pick_max_acceleration


@wp.func
def fluid_ray_hit(
    pi: int,
    particle_q: wp.array[wp.vec3],
    particle_radius: wp.array[float],
    particle_world: wp.array[wp.int32],
    world_offsets: wp.array[wp.vec3],
    ray_start: wp.vec3,
    ray_dir: wp.vec3,
):
    """Ray parameter at which the ray enters particle ``pi``'s sphere (drawn at its world's offset); inf if missed."""
    x = particle_q[pi]
    w = particle_world[pi]
    if world_offsets.shape[0] > 0 and w >= 0 and w < world_offsets.shape[0]:
        x = x + world_offsets[w]
    r = particle_radius[pi]
    rel = x - ray_start
    t = wp.dot(rel, ray_dir)
    miss2 = wp.dot(rel, rel) - t * t
    if t > 0.0 and miss2 < r * r:
        return t - wp.sqrt(r * r - miss2)
    return wp.inf


@wp.kernel
def raycast_fluid_particles(
    fluid_particle: wp.array[wp.int32],
    particle_q: wp.array[wp.vec3],
    particle_radius: wp.array[float],
    particle_world: wp.array[wp.int32],
    world_offsets: wp.array[wp.vec3],
    ray_start: wp.vec3,
    ray_dir: wp.vec3,
    # outputs
    hit_distance: wp.array[float],
):
    """Smallest ray parameter at which the ray meets a fluid particle's sphere (``hit_distance[0]``)."""
    pi = fluid_particle[wp.tid()]
    h = fluid_ray_hit(pi, particle_q, particle_radius, particle_world, world_offsets, ray_start, ray_dir)
    if h != wp.inf:
        wp.atomic_min(hit_distance, 0, h)


@wp.kernel
def select_fluid_particle(
    fluid_particle: wp.array[wp.int32],
    particle_q: wp.array[wp.vec3],
    particle_radius: wp.array[float],
    particle_world: wp.array[wp.int32],
    world_offsets: wp.array[wp.vec3],
    ray_start: wp.vec3,
    ray_dir: wp.vec3,
    hit_distance: wp.array[float],
    # outputs
    picked: wp.array[wp.int32],
):
    """The particle (largest index on ties) whose hit is ``hit_distance[0]``."""
    pi = fluid_particle[wp.tid()]
    h = fluid_ray_hit(pi, particle_q, particle_radius, particle_world, world_offsets, ray_start, ray_dir)
    if h == hit_distance[0]:
        wp.atomic_max(picked, 0, pi)


@wp.kernel
def apply_fluid_pick_force(
    fluid_particle: wp.array[wp.int32],
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    particle_mass: wp.array[float],
    picked: wp.array[wp.int32],
    target: wp.array[wp.vec3],
    pick_state: wp.array[PickingState],
    radius: wp.array[float],
    # outputs
    particle_f: wp.array[wp.vec3],
    picked_point: wp.array[wp.vec3],
):
    """Spring force toward the target on the fluid particles within ``radius`` of the picked one."""
    i = wp.tid()
    p = picked[0]
    if p < 0:
        return
    pi = fluid_particle[i]
    anchor = particle_q[p]
    if pi == p:
        picked_point[0] = anchor
    if wp.length(particle_q[pi] - anchor) > radius[0]:
        return
    s = pick_state[0]
    acc = s.pick_stiffness * (target[0] - anchor) - s.pick_damping * particle_qd[pi]
    limit = s.pick_max_acceleration * GRAVITY
    a = wp.length(acc)
    if a > limit:
        acc *= limit / a
    particle_f[pi] = particle_f[pi] + particle_mass[pi] * acc


@wp.kernel
def move_fluid_pick_target(ray_start: wp.vec3, ray_dir: wp.vec3, depth: wp.array[float], target: wp.array[wp.vec3]):
    target[0] = ray_start + ray_dir * depth[0]


class FluidPicking(Picking):
    """:class:`newton.viewer.Picking` that also picks fluid particles (ViewerGL uses it for models with fluid).

    Args:
        model: The model to pick from.
        fluid_pick_radius: Particles within this distance [m] of the picked one are dragged with it;
            ``None`` uses four particle radii of the picked particle.
        **kwargs: Upstream's picking arguments (gains, limit, world offsets, visible worlds).
    """

    def __init__(self, model, *, fluid_pick_radius: float | None = None, **kwargs) -> None:
        super().__init__(model, **kwargs)
        if fluid_pick_radius is not None and not (np.isfinite(fluid_pick_radius) and fluid_pick_radius > 0.0):
            raise ValueError(f"fluid_pick_radius={fluid_pick_radius!r} is out of range: expected None or (0, inf) [m]")
        #: distance [m] from the picked particle within which fluid is dragged (None: four radii)
        self.fluid_pick_radius = fluid_pick_radius
        flags = model.particle_flags.numpy() if model.particle_count else np.zeros(0, dtype=np.int32)
        with wp.ScopedDevice(model.device):
            self._fluid_particle = wp.array(np.flatnonzero(flags & int(ParticleFlags.FLUID)), dtype=wp.int32)
            # device state read by apply_force, so captured graphs see picks and moves
            self._fluid_picked = wp.array([-1], dtype=wp.int32)
            self._fluid_target = wp.zeros(1, dtype=wp.vec3)
            self._fluid_point = wp.zeros(1, dtype=wp.vec3)
            self._fluid_depth = wp.zeros(1, dtype=float)
            self._fluid_hit = wp.zeros(1, dtype=float)
            self._fluid_radius = wp.zeros(1, dtype=float)
            self._no_offsets = wp.zeros(0, dtype=wp.vec3)
        self._fluid_active = False

    @property
    def pick_particle(self) -> int:
        """Index of the picked fluid particle, or -1 when no fluid is picked."""
        return int(self._fluid_picked.numpy()[0])

    def is_picking(self) -> bool:
        return self._fluid_active or super().is_picking()

    @property
    def pick_point(self):
        if self._fluid_active:
            return wp.vec3(*self._fluid_point.numpy()[0])
        return super().pick_point

    @property
    def pick_target(self):
        if self._fluid_active:
            return wp.vec3(*self._fluid_target.numpy()[0])
        return super().pick_target

    @pick_target.setter
    def pick_target(self, target) -> None:
        if self._fluid_active:
            self._fluid_target.assign([wp.vec3(*target)])
        else:
            Picking.pick_target.fset(self, target)

    def release(self) -> None:
        super().release()
        self._fluid_picked.fill_(-1)
        self._fluid_active = False

    def pick(self, state, ray_start, ray_dir) -> None:
        """Pick what the ray meets first: a body (upstream) or a fluid particle. Synchronises."""
        super().pick(state, ray_start, ray_dir)
        self._fluid_picked.fill_(-1)
        self._fluid_active = False
        n = len(self._fluid_particle)
        if n == 0:
            return
        body_distance = body_pick_distance(self) if super().is_picking() else np.inf
        m = self.model
        start = wp.vec3(*ray_start)
        direction = wp.normalize(wp.vec3(*ray_dir))
        offsets = self.world_offsets if self.world_offsets is not None else self._no_offsets
        args = [self._fluid_particle, state.particle_q, m.particle_radius, m.particle_world, offsets, start, direction]
        self._fluid_hit.fill_(np.inf)
        wp.launch(raycast_fluid_particles, dim=n, inputs=args, outputs=[self._fluid_hit], device=m.device)
        hit = float(self._fluid_hit.numpy()[0])
        if not np.isfinite(hit) or hit >= body_distance:
            return
        wp.launch(
            select_fluid_particle,
            dim=n,
            inputs=[*args, self._fluid_hit],
            outputs=[self._fluid_picked],
            device=m.device,
        )
        picked = self.pick_particle
        if picked < 0:
            return
        # the fluid is closer than any body: drop the body pick
        super().release()
        x = state.particle_q.numpy()[picked]
        w = int(m.particle_world.numpy()[picked])
        if self.world_offsets is not None and 0 <= w < len(self.world_offsets):
            x = x + self.world_offsets.numpy()[w]
        depth = float(np.dot(np.asarray(x, dtype=np.float64) - np.asarray(start), np.asarray(direction)))
        self._fluid_depth.fill_(depth)
        self._fluid_target.assign([wp.vec3(*state.particle_q.numpy()[picked])])
        self._fluid_point.assign([wp.vec3(*state.particle_q.numpy()[picked])])
        radius = float(m.particle_radius.numpy()[picked])
        self._fluid_radius.fill_(self.fluid_pick_radius if self.fluid_pick_radius is not None else 4.0 * radius)
        self._fluid_active = True

    def update(self, ray_start, ray_dir) -> None:
        if not self._fluid_active:
            super().update(ray_start, ray_dir)
            return
        start, direction = wp.vec3(*ray_start), wp.normalize(wp.vec3(*ray_dir))
        if self.world_offsets is not None:
            w = int(self.model.particle_world.numpy()[self.pick_particle])
            if 0 <= w < len(self.world_offsets):
                start = start - wp.vec3(*self.world_offsets.numpy()[w])
        wp.launch(
            move_fluid_pick_target,
            dim=1,
            inputs=[start, direction, self._fluid_depth, self._fluid_target],
            device=self.model.device,
        )

    def apply_force(self, state) -> None:
        """Add the body pick's wrench (upstream) and the fluid pick's forces to ``state``'s force arrays.

        Launched whether or not fluid is picked, so it can be captured in a CUDA graph.
        """
        super().apply_force(state)
        n = len(self._fluid_particle)
        if n == 0 or state.particle_f is None:
            return
        wp.launch(
            apply_fluid_pick_force,
            dim=n,
            inputs=[
                self._fluid_particle,
                state.particle_q,
                state.particle_qd,
                self.model.particle_mass,
                self._fluid_picked,
                self._fluid_target,
                body_pick_state(self),
                self._fluid_radius,
            ],
            outputs=[state.particle_f, self._fluid_point],
            device=self.model.device,
        )
