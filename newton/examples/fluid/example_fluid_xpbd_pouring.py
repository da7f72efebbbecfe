# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""A cup pours its water into a tank, in many isolated worlds at once, with the arrays a policy trains on.

Every world has a kinematic cup (a triangle mesh filled with ``ModelBuilder.add_fluid_fill``) and
a small target tank; the worlds overlap in the simulation and are drawn side by side. The cup is
moved by an action per world (velocities in x and z, a tilt rate about y). By default a scripted
controller lifts the cup over the tank and tilts it until the tank holds three quarters of the water;
``--policy random`` drives it with random actions instead (what an untrained policy does).

The task is a batched environment (:class:`~newton.examples.fluid.tasks.FluidTask`): ``actions``,
``observations``, ``rewards``, ``terminated``, ``truncated`` and ``episode_steps`` live on the
device; a world that ended its episode restarts at the next step (its water back in its cup, the
same start every time), and the whole step, resets and measurements included, is one CUDA graph.

Columns:

- actions (3): cup velocity in x and z [m/s] (clamped to +-0.5), tilt rate about y [rad/s] (+-3);
- observations (10): cup x, z [m] and tilt [rad]; shares of the world's water in the cup, in the
  tank and spilled (on the floor outside the tank); the water's centroid relative to the cup's
  centre, x, y, z [m]; episode time [s];
- rewards: 10 x (gain of the tank's share - gain of the spilled share) over the step;
- terminated: at least ``SUCCESS`` of the water in the tank, or more than ``FAILURE`` spilled;
- truncated: ``EPISODE_SECONDS`` reached.

Success criteria:
- The scripted pour succeeds in every world: its first episode ends with at least 75 % of the
  water in the tank and at most 5 % spilled.

Runs:
- `python -m newton.examples fluid_xpbd_pouring`
- `python -m newton.examples fluid_xpbd_pouring --world-count 1024 --particle-count 1000 --viewer null`
"""

import math

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import add_tank, revolved_container
from newton.examples.fluid.tasks import FluidTask, begin_observation, end_observation

CUP_RADIUS = 0.035  # inner radius [m]
CUP_DEPTH = 0.09  # inner depth [m]
CUP_WALL = 0.006  # [m]
FILL = 0.045  # water depth in the cup [m]
CUP_HALF = 0.5 * (CUP_DEPTH + CUP_WALL)  # the cup's centre above its outer floor [m]
TANK_X = 0.1  # the target tank's centre [m]
TANK_HALF = 0.06  # its inner half extent in x and y [m]
TANK_HEIGHT = 0.07  # [m]
START = (-0.1, 0.16, 0.0)  # cup centre x, z [m] and tilt [rad] at the start of an episode
ACTION_LIMIT = (0.5, 0.5, 3.0)
WORKSPACE = ((-0.25, 0.25), (0.1, 0.35), (-0.3, 2.6))  # x, z, tilt bounds of the cup centre
SUCCESS = 0.75
FAILURE = 0.25
EPISODE_SECONDS = 6.0
# the scripted pour: time [s], cup x, z [m], tilt [rad]; the lip ends above the tank's middle
WAYPOINTS = (
    (0.0, -0.1, 0.16, 0.0),
    (0.3, -0.1, 0.16, 0.0),
    (1.3, 0.03, 0.15, 0.4),
    (3.3, 0.03, 0.15, 2.3),
    (4.3, 0.03, 0.15, 2.3),
    (5.3, 0.0, 0.16, 0.0),
)


@wp.func
def cup_transform(pose: wp.vec3):
    return wp.transform(wp.vec3(pose[0], 0.0, pose[1]), wp.quat_from_axis_angle(wp.vec3(0.0, 1.0, 0.0), pose[2]))


@wp.kernel
def move_cups(
    actions: wp.array2d[float],
    limit: wp.vec3,
    low: wp.vec3,
    high: wp.vec3,
    dt: float,
    cup_body: wp.array[wp.int32],
    pose: wp.array[wp.vec3],
    body_q: wp.array[wp.transform],
    body_qd: wp.array[wp.spatial_vector],
):
    """Advance each world's cup by its action over the coming substep, with the velocity that takes it there."""
    w = wp.tid()
    a = wp.vec3(actions[w, 0], actions[w, 1], actions[w, 2])
    a = wp.vec3(
        wp.clamp(a[0], -limit[0], limit[0]), wp.clamp(a[1], -limit[1], limit[1]), wp.clamp(a[2], -limit[2], limit[2])
    )
    p0 = pose[w]
    p1 = p0 + a * dt
    p1 = wp.vec3(wp.clamp(p1[0], low[0], high[0]), wp.clamp(p1[1], low[1], high[1]), wp.clamp(p1[2], low[2], high[2]))
    pose[w] = p1
    v = (p1 - p0) / dt
    b = cup_body[w]
    body_q[b] = cup_transform(p1)
    body_qd[b] = wp.spatial_vector(wp.vec3(v[0], 0.0, v[1]), wp.vec3(0.0, v[2], 0.0))


@wp.kernel
def restart_cups(
    mask: wp.array[wp.bool],
    start: wp.vec3,
    cup_body: wp.array[wp.int32],
    pose: wp.array[wp.vec3],
    body_q: wp.array[wp.transform],
    body_qd: wp.array[wp.spatial_vector],
    previous: wp.array2d[float],
):
    w = wp.tid()
    if mask[w]:
        pose[w] = start
        body_q[cup_body[w]] = cup_transform(start)
        body_qd[cup_body[w]] = wp.spatial_vector()
        # all the water starts in the cup: none in the tank, none spilled
        previous[w, 0] = 0.0
        previous[w, 1] = 0.0


@wp.kernel
def scripted_pour(
    episode_steps: wp.array[wp.int32],
    frame_dt: float,
    waypoints: wp.array2d[float],
    pose: wp.array[wp.vec3],
    limit: wp.vec3,
    actions: wp.array2d[float],
):
    """Velocities that bring the cup to the waypoint path's pose one frame ahead (linear between waypoints)."""
    w = wp.tid()
    t = float(episode_steps[w] + 1) * frame_dt
    k = int(0)
    while k + 2 < waypoints.shape[0] and waypoints[k + 1, 0] <= t:
        k += 1
    s = wp.clamp((t - waypoints[k, 0]) / (waypoints[k + 1, 0] - waypoints[k, 0]), 0.0, 1.0)
    for j in range(3):
        goal = (1.0 - s) * waypoints[k, j + 1] + s * waypoints[k + 1, j + 1]
        actions[w, j] = wp.clamp((goal - pose[w][j]) / frame_dt, -limit[j], limit[j])


@wp.kernel
def random_actions(seed: int, episode_steps: wp.array[wp.int32], limit: wp.vec3, actions: wp.array2d[float]):
    w = wp.tid()
    state = wp.rand_init(seed, w * 100003 + episode_steps[w])
    for j in range(3):
        actions[w, j] = limit[j] * (2.0 * wp.randf(state) - 1.0)


@wp.kernel
def observe_pour(
    pose: wp.array[wp.vec3],
    region_fraction: wp.array[float],
    spilled_count: wp.array[wp.int32],
    fluid_count: wp.array[wp.int32],
    centroid: wp.array[wp.vec3],
    frame_dt: float,
    success: float,
    failure: float,
    max_steps: int,
    first: int,
    first_mask: wp.array[wp.bool],
    # in/out
    episode_steps: wp.array[wp.int32],
    previous: wp.array2d[float],
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
    # regions per world: the cup, the tank, the air above the floor (the sensor orders them by shape)
    in_cup = region_fraction[3 * w]
    in_tank = region_fraction[3 * w + 1]
    spilled = float(spilled_count[w]) / float(wp.max(fluid_count[w], 1))
    p = pose[w]
    rel = centroid[w] - wp.vec3(p[0], 0.0, p[1])
    row = (p[0], p[1], p[2], in_cup, in_tank, spilled, rel[0], rel[1], rel[2], float(episode_steps[w]) * frame_dt)
    for j in range(10):
        observations[w, j] = row[j]
    reward = 10.0 * ((in_tank - previous[w, 0]) - (spilled - previous[w, 1]))
    ended = in_tank >= success or spilled > failure
    succeeded = in_tank >= success and spilled <= 0.05
    previous[w, 0] = in_tank
    previous[w, 1] = spilled
    end_observation(
        w, first, reward, ended, succeeded, max_steps, episode_steps, episodes, rewards, terminated, truncated
    )


class Example(FluidTask):
    action_dim = 3
    observation_dim = 10
    episode_seconds = EPISODE_SECONDS
    particle_count_help = "Fluid particles per world"
    default_particle_count = 1000
    cpu_particle_count = 500

    def __init__(self, viewer, args):
        super().__init__(viewer, args)
        self.world_count = args.world_count
        self.policy = args.policy
        volume = math.pi * CUP_RADIUS**2 * FILL
        d = (volume / args.particle_count) ** (1.0 / 3.0)
        self.spacing = d
        inner = np.stack([np.full(8, CUP_RADIUS), np.linspace(CUP_WALL, CUP_WALL + CUP_DEPTH, 8)], axis=1)
        cup_mesh = revolved_container(inner, CUP_WALL, segments=48)
        # the mesh's outer floor is at z = 0: the cup's frame has its origin at the cup's centre
        mesh_in_cup = wp.transform(wp.vec3(0.0, 0.0, -CUP_HALF), wp.quat_identity())
        start = wp.transform(
            wp.vec3(START[0], 0.0, START[1]), wp.quat_from_axis_angle(wp.vec3(0.0, 1.0, 0.0), START[2])
        )
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0, density=0.0, has_shape_collision=False)

        world = newton.ModelBuilder()
        cup = world.add_body(xform=start, is_kinematic=True, label="cup")
        world.add_shape_mesh(cup, xform=mesh_in_cup, mesh=cup_mesh, cfg=cfg)
        # regions of the sensor: the cup's inside, the tank's, and the air above the tank's rim
        cavity = wp.transform(wp.vec3(0.0, 0.0, CUP_WALL - CUP_HALF + 0.5 * CUP_DEPTH), wp.quat_identity())
        world.add_site(
            cup,
            xform=cavity,
            type=newton.GeoType.CYLINDER,
            scale=(CUP_RADIUS, 0.5 * CUP_DEPTH, 0.0),
            label="cup_inside",
        )
        add_tank(world, TANK_HALF, TANK_HALF, TANK_HEIGHT, 0.01, center=(TANK_X, 0.0))
        world.add_site(
            -1,
            xform=wp.transform(wp.vec3(TANK_X, 0.0, 0.5 * TANK_HEIGHT), wp.quat_identity()),
            type=newton.GeoType.BOX,
            scale=(TANK_HALF, TANK_HALF, 0.5 * TANK_HEIGHT),
            label="tank_inside",
        )
        world.add_site(
            -1,
            xform=wp.transform(wp.vec3(0.0, 0.0, TANK_HEIGHT + 0.5), wp.quat_identity()),
            type=newton.GeoType.BOX,
            scale=(1.0, 1.0, 0.5),
            label="air",
        )
        world.add_fluid_fill(cup_mesh, d, xform=start * mesh_in_cup, fill_height=CUP_WALL + FILL)

        builder = newton.ModelBuilder()
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        builder.replicate(world, self.world_count)
        cups = [cup + w * world.body_count for w in range(self.world_count)]
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        self.solver = newton.solvers.SolverXPBD(
            self.model, iterations=2, fluid_rest_distance=d, fluid_viscosity=0.02, fluid_cohesion=0.2
        )
        self.sensor = newton.sensors.SensorFluid(self.model, regions=["*cup_inside", "*tank_inside", "*air"])

        with wp.ScopedDevice(self.model.device):
            self.cup_body = wp.array(cups, dtype=wp.int32)
            self.pose = wp.array([START] * self.world_count, dtype=wp.vec3)
            self.waypoints = wp.array(np.array(WAYPOINTS, dtype=np.float32), dtype=float)
            self.previous = wp.zeros((self.world_count, 2), dtype=float)
        self.setup_task()
        gap = 2 * TANK_HALF + 0.25
        self.viewer.set_world_offsets((gap, gap, 0.0))
        # look at the middle of the grid of worlds, from farther away the more there are
        offsets = self.viewer.world_offsets
        middle = offsets.numpy().mean(axis=0) if offsets is not None else np.zeros(3)
        reach = 0.25 + 0.28 * math.sqrt(self.world_count)
        self.viewer.set_camera(wp.vec3(middle[0], middle[1] - reach, 0.25 + 0.6 * reach), pitch=-32.0, yaw=90.0)

    # --- the task (see FluidTask) ---------------------------------------------------------------

    def restart_worlds(self, mask: wp.array) -> None:
        wp.launch(
            restart_cups,
            dim=self.world_count,
            inputs=[mask, wp.vec3(*START), self.cup_body, self.pose, self.state_0.body_q, self.state_0.body_qd],
            outputs=[self.previous],
        )

    def scripted_actions(self) -> None:
        if self.policy == "random":
            wp.launch(
                random_actions,
                dim=self.world_count,
                inputs=[7, self.episode_steps, wp.vec3(*ACTION_LIMIT)],
                outputs=[self.actions],
            )
        else:
            wp.launch(
                scripted_pour,
                dim=self.world_count,
                inputs=[self.episode_steps, self.frame_dt, self.waypoints, self.pose, wp.vec3(*ACTION_LIMIT)],
                outputs=[self.actions],
            )

    def prescribe(self, state: newton.State) -> None:
        low, high = wp.vec3(*(b[0] for b in WORKSPACE)), wp.vec3(*(b[1] for b in WORKSPACE))
        wp.launch(
            move_cups,
            dim=self.world_count,
            inputs=[self.actions, wp.vec3(*ACTION_LIMIT), low, high, self.sim_dt, self.cup_body, self.pose],
            outputs=[state.body_q, state.body_qd],
        )

    def observe(self, first: bool, mask: wp.array | None = None) -> None:
        self.sensor.update(self.state_0)
        s = self.sensor
        tail, outputs = self.observation_args(first, mask)
        wp.launch(
            observe_pour,
            dim=self.world_count,
            inputs=[
                self.pose,
                s.region_fraction,
                s.spilled_count,
                s.fluid_count,
                s.centroid,
                self.frame_dt,
                SUCCESS,
                FAILURE,
                *tail,
            ],
            outputs=outputs,
        )

    # --- drawing and checking -------------------------------------------------------------------

    def log_fluids(self):
        self.log_water_by_world()

    def test_final(self):
        succeeded, failed = self.episodes.numpy().T
        # the scripted pour has reached full tilt, and held it half a second, by then
        if self.sim_time >= WAYPOINTS[3][0] + 0.5 and self.policy == "scripted":
            assert (succeeded >= 1).all(), f"worlds without a successful pour: {np.flatnonzero(succeeded == 0)}"
            assert (failed == 0).all(), f"worlds with a failed pour: {np.flatnonzero(failed)}"
        q = self.state_0.particle_q.numpy()
        assert np.isfinite(q).all()

    @classmethod
    def create_parser(cls):
        parser = super().create_parser()
        newton.examples.add_world_count_arg(parser)
        parser.set_defaults(world_count=16)
        parser.add_argument(
            "--policy",
            choices=("scripted", "random"),
            default="scripted",
            help="Who sets the actions: the scripted pour, or uniform random actions.",
        )
        return parser


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_pouring")
