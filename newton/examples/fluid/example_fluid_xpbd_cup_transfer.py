# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""A Franka Panda arm carries a cup of water from one side to the other without spilling, in one world or many.

The arm is built from Franka Emika's published kinematic parameters (modified Denavit-Hartenberg,
see :mod:`newton.examples.fluid.panda`; no assets, no network) as kinematic links, posed on the
device by forward kinematics from each world's joint angles before every substep, so the frame
stays one CUDA graph. The cup is a triangle mesh held in the hand, filled by
``ModelBuilder.add_fluid_fill`` up to its fill line; the water is confined by the mesh's signed
distance and sloshes as the cup accelerates. By default a scripted controller drives the joints
along a keyframe path (smoothstep between keyframes, joint 6 chosen so the hand points straight
down) that lifts the cup, swings it about the base through a point in front of the robot, and
sets it down on the other side over 9 s.

With ``--world-count N`` the worlds overlap in the simulation and are drawn side by side. The task
is a batched environment (:class:`~newton.examples.fluid.tasks.FluidTask`, ``docs/batched.rst``):

- actions (7): joint velocities [rad/s], clamped to the Panda's limits (and the angles to theirs);
- observations (14): joint angles [rad] (7); the cup's centre [m] (3) and its tilt from upright
  [rad]; the shares of the world's water in the cup and spilled; episode time [s];
- rewards: -10 x the gain of the spilled share over the step, minus the cup's distance to its goal
  [m] x 0.1;
- terminated: the cup within ``GOAL_RADIUS`` (3 cm) of its goal (where the path sets it down)
  holding at least ``KEEP`` (95 %) of the water, or more than ``SPILL_LIMIT`` (5 %) spilled;
- truncated: 12 s reached.

Success criteria:
- Not a drop spills: at every sampled frame, every world's cup holds all its water.
- The cup really travels, more than 0.7 m, and every world's first episode ends at its goal.

Runs:
- `python -m newton.examples fluid_xpbd_cup_transfer`
- `python -m newton.examples fluid_xpbd_cup_transfer --world-count 64 --particle-count 2000`
"""

import math

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import revolved_container
from newton.examples.fluid.panda import (
    FLANGE_D,
    HAND_LENGTH,
    JOINT_LOWER,
    JOINT_SPEED,
    JOINT_UPPER,
    READY,
    add_panda,
    flange_down_q6,
    forward_kinematics,
    joint_frames,
    path_angle,
    pose_panda,
)
from newton.examples.fluid.tasks import FluidTask, begin_observation, end_observation

CUP_RADIUS = 0.05  # inner radius [m]
CUP_HEIGHT = 0.12  # inner depth [m]
CUP_WALL = 0.008  # [m]
FILL = 0.06  # water depth in the cup [m]
# keyframes: time [s], (q1, q2, q4) [rad]; q3 = q5 = 0, q7 as in the ready pose, q6 keeps the hand down
KEYFRAMES = (
    (0.0, (-0.8, 0.2, -2.2)),
    (1.0, (-0.8, 0.2, -2.2)),
    (2.5, (-0.8, 0.0, -2.0)),
    (4.5, (0.0, 0.1, -1.7)),
    (6.5, (0.8, 0.0, -2.0)),
    (8.0, (0.8, 0.2, -2.2)),
    (9.0, (0.8, 0.2, -2.2)),
)
GOAL_RADIUS = 0.03  # [m]
KEEP = 0.95  # share of the water the cup must still hold at its goal
SPILL_LIMIT = 0.05
EPISODE_SECONDS = 12.0


def keyframe_angles() -> np.ndarray:
    """Joint angles of the keyframes, shape (K, 7) [rad]."""
    rows = []
    for _t, (q1, q2, q4) in KEYFRAMES:
        rows.append((q1, q2, 0.0, q4, 0.0, flange_down_q6(q1, q2, q4, READY[6]), READY[6]))
    return np.asarray(rows)


# the cup in link 7's frame: beside the fingertips, turned over so it opens upward while the hand points down
CUP_OFFSET = wp.transform(
    wp.vec3(CUP_RADIUS + CUP_WALL + 0.012, 0.0, FLANGE_D + HAND_LENGTH + 0.5 * CUP_HEIGHT),
    wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), math.pi),
)
# the cup mesh has its outer floor at z = 0: its frame in link 7's
CUP_MESH_XFORM = CUP_OFFSET * wp.transform(wp.vec3(0.0, 0.0, -0.5 * CUP_HEIGHT - CUP_WALL), wp.quat_identity())


def to_transform(m: np.ndarray) -> wp.transform:
    return wp.transform(wp.vec3(*m[:3, 3]), wp.quat_from_matrix(wp.mat33(*m[:3, :3].ravel())))


def cup_centre_world(angles) -> np.ndarray:
    """World position of the cup's centre (the middle of its cavity) at joint angles ``angles``."""
    link7 = to_transform(forward_kinematics(angles)[6])
    return np.array(wp.transform_get_translation(link7 * CUP_OFFSET))


@wp.kernel
def drive_joints(
    actions: wp.array2d[float],
    speed: wp.array[float],
    lower: wp.array[float],
    upper: wp.array[float],
    dt: float,
    q: wp.array2d[float],
    q_start: wp.array2d[float],
):
    """Advance joint ``j`` of world ``w`` by its velocity action over a substep (both clamped to the limits)."""
    w, j = wp.tid()
    q_start[w, j] = q[w, j]
    v = wp.clamp(actions[w, j], -speed[j], speed[j])
    q[w, j] = wp.clamp(q[w, j] + v * dt, lower[j], upper[j])


@wp.kernel
def follow_path(
    episode_steps: wp.array[wp.int32],
    frame_dt: float,
    times: wp.array[float],
    angles: wp.array2d[float],
    q: wp.array2d[float],
    speed: wp.array[float],
    actions: wp.array2d[float],
):
    """The scripted controller: joint velocities that reach the keyframe path's angles one frame ahead."""
    w, j = wp.tid()
    t = float(episode_steps[w] + 1) * frame_dt
    actions[w, j] = wp.clamp((path_angle(t, times, angles, j) - q[w, j]) / frame_dt, -speed[j], speed[j])


@wp.kernel
def restart_arms(
    mask: wp.array[wp.bool],
    start: wp.array[float],
    q: wp.array2d[float],
    q_start: wp.array2d[float],
    previous: wp.array[float],
):
    w, j = wp.tid()
    if mask[w]:
        q[w, j] = start[j]
        q_start[w, j] = start[j]
        previous[w] = 0.0


@wp.kernel
def observe_carry(
    q: wp.array2d[float],
    bodies: wp.array2d[wp.int32],
    body_q: wp.array[wp.transform],
    cup_offset: wp.transform,
    goal: wp.vec3,
    goal_radius: float,
    keep: float,
    spill_limit: float,
    region_fraction: wp.array[float],
    spilled_count: wp.array[wp.int32],
    fluid_count: wp.array[wp.int32],
    frame_dt: float,
    max_steps: int,
    first: int,
    first_mask: wp.array[wp.bool],
    # in/out
    episode_steps: wp.array[wp.int32],
    previous: wp.array[float],
    episodes: wp.array2d[wp.int32],
    # outputs
    observations: wp.array2d[float],
    rewards: wp.array[float],
    terminated: wp.array[wp.bool],
    truncated: wp.array[wp.bool],
):
    """The task's arrays after a step; with ``first``, of the worlds ``first_mask`` selects after their restart."""
    w = wp.tid()
    if not begin_observation(w, first, first_mask, episode_steps):
        return
    cup = body_q[bodies[w, 7]] * cup_offset
    centre = wp.transform_get_translation(cup)
    # the cup opens along its frame's +z (CUP_OFFSET turns it over in the hand's frame)
    axis = wp.quat_rotate(wp.transform_get_rotation(cup), wp.vec3(0.0, 0.0, 1.0))
    tilt = wp.acos(wp.clamp(axis[2], -1.0, 1.0))
    kept = region_fraction[w]
    spilled = float(spilled_count[w]) / float(wp.max(fluid_count[w], 1))
    for j in range(7):
        observations[w, j] = q[w, j]
    observations[w, 7] = centre[0]
    observations[w, 8] = centre[1]
    observations[w, 9] = centre[2]
    observations[w, 10] = tilt
    observations[w, 11] = kept
    observations[w, 12] = spilled
    observations[w, 13] = float(episode_steps[w]) * frame_dt
    distance = wp.length(centre - goal)
    reward = -10.0 * (spilled - previous[w]) - 0.1 * distance
    arrived = distance < goal_radius and kept >= keep
    failed = spilled > spill_limit
    previous[w] = spilled
    end_observation(
        w,
        first,
        reward,
        arrived or failed,
        arrived and not failed,
        max_steps,
        episode_steps,
        episodes,
        rewards,
        terminated,
        truncated,
    )


class Example(FluidTask):
    sim_substeps = 10
    action_dim = 7
    observation_dim = 14
    episode_seconds = EPISODE_SECONDS
    default_particle_count = 20_000
    particle_count_help = "Fluid particles per world"

    def __init__(self, viewer, args):
        super().__init__(viewer, args)
        self.world_count = args.world_count
        volume = math.pi * CUP_RADIUS**2 * FILL
        d = (volume / args.particle_count) ** (1.0 / 3.0)
        self.spacing = d
        angles = keyframe_angles()

        world = newton.ModelBuilder()
        links = add_panda(world)
        hand = links[-1]
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0, density=0.0, has_shape_collision=False)
        # the hand and a finger reaching to the cup
        world.add_shape_box(
            hand,
            xform=wp.transform(wp.vec3(0.0, 0.0, FLANGE_D + 0.5 * HAND_LENGTH), wp.quat_identity()),
            hx=0.03,
            hy=0.1,
            hz=0.5 * HAND_LENGTH,
            cfg=cfg,
        )
        world.add_shape_box(
            hand,
            xform=wp.transform(wp.vec3(0.03, 0.0, FLANGE_D + HAND_LENGTH), wp.quat_identity()),
            hx=0.03,
            hy=0.01,
            hz=0.02,
            cfg=cfg,
        )
        inner = np.stack([np.full(8, CUP_RADIUS), np.linspace(CUP_WALL, CUP_WALL + CUP_HEIGHT, 8)], axis=1)
        cup = revolved_container(inner, CUP_WALL, segments=48)
        world.add_shape_mesh(hand, xform=CUP_MESH_XFORM, mesh=cup, cfg=cfg)
        # the sensor's region: the cup's cavity (a quarter spacing of slack at its wall and floor)
        world.add_site(
            hand,
            xform=CUP_OFFSET,
            type=newton.GeoType.CYLINDER,
            scale=(CUP_RADIUS + 0.25 * d, 0.5 * CUP_HEIGHT + 0.25 * d, 0.0),
            label="cup_inside",
        )
        # water at rest in the cup, FILL deep above its inner floor, where the cup is at the first keyframe
        link7 = to_transform(forward_kinematics(angles[0])[6])
        world.add_fluid_fill(cup, d, xform=link7 * CUP_MESH_XFORM, fill_height=CUP_WALL + FILL)

        builder = newton.ModelBuilder()
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        builder.replicate(world, self.world_count)
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        self.solver = newton.solvers.SolverXPBD(
            self.model, iterations=2, fluid_rest_distance=d, fluid_viscosity=0.05, fluid_cohesion=0.2
        )
        self.sensor = newton.sensors.SensorFluid(self.model, regions="*cup_inside")

        self.start_cup = cup_centre_world(angles[0])
        self.goal = cup_centre_world(angles[-1])
        per_world = world.body_count
        with wp.ScopedDevice(self.model.device):
            self.bodies = wp.array(
                [[w * per_world + b for b in links] for w in range(self.world_count)], dtype=wp.int32
            )
            self.frames = wp.array(joint_frames(), dtype=wp.transform)
            self.times = wp.array([k[0] for k in KEYFRAMES], dtype=float)
            self.angles = wp.array(angles, dtype=float)
            self.start_q = wp.array(angles[0], dtype=float)
            self.q = wp.array(np.tile(angles[0], (self.world_count, 1)), dtype=float)
            self.q_start = wp.array(np.tile(angles[0], (self.world_count, 1)), dtype=float)
            self.speed = wp.array(JOINT_SPEED, dtype=float)
            self.lower = wp.array(JOINT_LOWER, dtype=float)
            self.upper = wp.array(JOINT_UPPER, dtype=float)
            self.previous = wp.zeros(self.world_count, dtype=float)
        self.max_spilled = 0.0  # the largest spilled share of any world at a sampled frame
        self.setup_task()
        gap = 2.0
        self.viewer.set_world_offsets((gap, gap, 0.0))
        self.viewer.set_camera(wp.vec3(0.95, -0.25, 0.95), pitch=-58.0, yaw=138.0)

    # --- the task (see FluidTask) ---------------------------------------------------------------

    def _pose(self, state: newton.State) -> None:
        wp.launch(
            pose_panda,
            dim=(self.world_count, 8),
            inputs=[self.q_start, self.q, self.sim_dt, self.bodies, self.frames],
            outputs=[state.body_q, state.body_qd],
        )

    def restart_worlds(self, mask: wp.array) -> None:
        wp.launch(
            restart_arms, dim=(self.world_count, 7), inputs=[mask, self.start_q, self.q, self.q_start, self.previous]
        )
        self._pose(self.state_0)

    def scripted_actions(self) -> None:
        wp.launch(
            follow_path,
            dim=(self.world_count, 7),
            inputs=[self.episode_steps, self.frame_dt, self.times, self.angles, self.q, self.speed],
            outputs=[self.actions],
        )

    def prescribe(self, state: newton.State) -> None:
        # the arm at the end of the coming substep, with the velocity that takes it there
        wp.launch(
            drive_joints,
            dim=(self.world_count, 7),
            inputs=[self.actions, self.speed, self.lower, self.upper, self.sim_dt, self.q, self.q_start],
        )
        self._pose(state)

    def observe(self, first: bool, mask: wp.array | None = None) -> None:
        self.sensor.update(self.state_0)
        s = self.sensor
        tail, outputs = self.observation_args(first, mask)
        wp.launch(
            observe_carry,
            dim=self.world_count,
            inputs=[
                self.q,
                self.bodies,
                self.state_0.body_q,
                CUP_OFFSET,
                wp.vec3(*self.goal),
                GOAL_RADIUS,
                KEEP,
                SPILL_LIMIT,
                s.region_fraction,
                s.spilled_count,
                s.fluid_count,
                self.frame_dt,
                *tail,
            ],
            outputs=outputs,
        )

    # --- drawing and checking -------------------------------------------------------------------

    def step(self):
        super().step()
        if round(self.sim_time * self.fps) % 10 == 0:
            self.max_spilled = max(self.max_spilled, float(self.observations.numpy()[:, 12].max()))

    gui = FluidTask.viscosity_gui

    def log_fluids(self):
        self.log_water_by_world()

    def test_final(self):
        assert self.max_spilled == 0.0, f"a world spilled {100 * self.max_spilled:.1f} % of its water"
        assert np.linalg.norm(self.goal - self.start_cup) > 0.7, (self.start_cup, self.goal)
        if self.sim_time >= KEYFRAMES[-2][0] + 0.5:
            succeeded, failed = self.episodes.numpy().T
            assert (succeeded >= 1).all(), f"worlds whose cup did not arrive: {np.flatnonzero(succeeded == 0)}"
            assert (failed == 0).all(), f"worlds that failed: {np.flatnonzero(failed)}"

    @classmethod
    def create_parser(cls):
        parser = super().create_parser()
        newton.examples.add_world_count_arg(parser)
        parser.set_defaults(world_count=1)
        return parser


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_cup_transfer")
