# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""A Franka Panda arm carries a cup of water from one side to the other without spilling.

The arm is built from Franka Emika's published kinematic parameters (modified Denavit-Hartenberg,
see :mod:`newton.examples.fluid.panda`; no assets, no network) as kinematic links. A scripted
joint path (smoothstep between keyframes, joint 6 chosen so the hand points straight down)
lifts the cup, swings it about the base through a point in front of the robot, and sets it down
on the other side over 9 s; forward kinematics on the device poses every link before each
substep, so the frame stays one CUDA graph. The cup is a triangle mesh held in the hand, filled
by ``ModelBuilder.add_fluid_fill`` up to its fill line; the water is confined by the mesh's signed
distance and sloshes as the cup accelerates.

Success criteria:
- Not a drop spills: at every sampled frame, every particle is inside the cup.
- The cup really travelled: its centre moves more than 0.7 m, and the water went with it.

Runs:
- `python -m newton.examples fluid_xpbd_cup_transfer`
- `python -m newton.examples fluid_xpbd_cup_transfer --particle-count 5000`
"""

import math

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import FluidExample, advance_clock, revolved_container
from newton.examples.fluid.panda import (
    FLANGE_D,
    HAND_LENGTH,
    READY,
    add_panda,
    flange_down_q6,
    forward_kinematics,
    joint_frames,
    pose_panda,
)

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


class Example(FluidExample):
    sim_substeps = 10

    default_particle_count = 20_000

    def __init__(self, viewer, args):
        super().__init__(viewer, args)
        volume = math.pi * CUP_RADIUS**2 * FILL
        d = (volume / args.particle_count) ** (1.0 / 3.0)
        self.spacing = d
        builder = newton.ModelBuilder()
        self.links = add_panda(builder)
        hand = self.links[-1]
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0, density=0.0, has_shape_collision=False)
        # the hand and a finger reaching to the cup
        builder.add_shape_box(
            hand,
            xform=wp.transform(wp.vec3(0.0, 0.0, FLANGE_D + 0.5 * HAND_LENGTH), wp.quat_identity()),
            hx=0.03,
            hy=0.1,
            hz=0.5 * HAND_LENGTH,
            cfg=cfg,
        )
        builder.add_shape_box(
            hand,
            xform=wp.transform(wp.vec3(0.03, 0.0, FLANGE_D + HAND_LENGTH), wp.quat_identity()),
            hx=0.03,
            hy=0.01,
            hz=0.02,
            cfg=cfg,
        )
        inner = np.stack([np.full(8, CUP_RADIUS), np.linspace(CUP_WALL, CUP_WALL + CUP_HEIGHT, 8)], axis=1)
        cup = revolved_container(inner, CUP_WALL, segments=48)
        # the cup mesh has its outer floor at z = 0; centre it on CUP_OFFSET
        self.cup_xform = CUP_OFFSET * wp.transform(wp.vec3(0.0, 0.0, -0.5 * CUP_HEIGHT - CUP_WALL), wp.quat_identity())
        builder.add_shape_mesh(hand, xform=self.cup_xform, mesh=cup, cfg=cfg)

        # water at rest in the cup, FILL deep above its inner floor, where the cup is at the first keyframe
        angles = keyframe_angles()
        cup_world = self._cup_world(forward_kinematics(angles[0])[6])
        placement = wp.transform(wp.vec3(*cup_world[:3, 3]), wp.quat_from_matrix(wp.mat33(*cup_world[:3, :3].ravel())))
        first = builder.particle_count
        builder.add_fluid_fill(cup, d, xform=placement, fill_height=CUP_WALL + FILL)
        pts = np.array(builder.particle_q[first:])
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        # the cup moves up to ~0.4 m/s: particles must be free to follow it
        self.model.particle_max_velocity = 0.5 * d / self.sim_dt

        self.solver = newton.solvers.SolverXPBD(
            self.model, iterations=2, fluid_rest_distance=d, fluid_viscosity=0.05, fluid_cohesion=0.2
        )
        self.clock = wp.zeros(1, dtype=float)
        self.bodies = wp.array(self.links, dtype=wp.int32)
        self.frames = wp.array(joint_frames(), dtype=wp.transform)
        self.times = wp.array([k[0] for k in KEYFRAMES], dtype=float)
        self.angles = wp.array(angles, dtype=float)
        self.start_cup = cup_world[:3, 3].copy()
        self.max_outside = 0  # most particles outside the cup at a sampled frame
        self.water_travel = 0.0
        self.start_water = pts.mean(axis=0)
        self.setup_simulation()
        self.viewer.set_camera(wp.vec3(0.95, -0.25, 0.95), pitch=-58.0, yaw=138.0)

    def _cup_world(self, link7: np.ndarray) -> np.ndarray:
        """4x4 world transform of the cup's frame (z up the cup's axis, origin on its outer floor)."""
        m = np.eye(4)
        m[:3, :3] = np.array(wp.quat_to_matrix(wp.transform_get_rotation(self.cup_xform))).reshape(3, 3)
        m[:3, 3] = np.array(wp.transform_get_translation(self.cup_xform))
        return link7 @ m

    def setup_simulation(self):
        super().setup_simulation()
        # pose the arm for the first frame drawn (prescribe poses it before every substep)
        wp.launch(
            pose_panda,
            dim=len(self.links),
            inputs=[self.clock, 0.0 + 1.0e-6, self.bodies, self.frames, self.times, self.angles],
            outputs=[self.state_0.body_q, self.state_0.body_qd],
        )

    def prescribe(self, state):
        wp.launch(
            pose_panda,
            dim=len(self.links),
            inputs=[self.clock, self.sim_dt, self.bodies, self.frames, self.times, self.angles],
            outputs=[state.body_q, state.body_qd],
        )
        wp.launch(advance_clock, dim=1, inputs=[self.clock, self.sim_dt])

    def cup_frame(self) -> np.ndarray:
        x = self.state_0.body_q.numpy()[self.links[-1]]
        link7 = np.eye(4)
        link7[:3, :3] = np.array(wp.quat_to_matrix(wp.quat(*x[3:]))).reshape(3, 3)
        link7[:3, 3] = x[:3]
        return self._cup_world(link7)

    def outside_count(self) -> int:
        """Particles outside the cup's cavity (a quarter spacing of slack)."""
        cup = self.cup_frame()
        q = self.state_0.particle_q.numpy().astype(np.float64)
        local = (q - cup[:3, 3]) @ cup[:3, :3]
        tol = 0.25 * self.spacing
        r = np.hypot(local[:, 0], local[:, 1])
        inside = (r < CUP_RADIUS + tol) & (local[:, 2] > CUP_WALL - tol) & (local[:, 2] < CUP_WALL + CUP_HEIGHT)
        return int(np.count_nonzero(~inside))

    def step(self):
        super().step()
        if round(self.sim_time * self.fps) % 10 == 0:
            self.max_outside = max(self.max_outside, self.outside_count())
            q = self.state_0.particle_q.numpy()
            self.water_travel = max(self.water_travel, float(np.linalg.norm(q.mean(axis=0) - self.start_water)))

    gui = FluidExample.viscosity_gui

    def test_final(self):
        assert self.max_outside == 0, f"{self.max_outside} particles outside the cup"
        assert self.outside_count() == 0, f"{self.outside_count()} particles outside the cup at the end"
        if self.sim_time >= KEYFRAMES[-1][0]:
            travel = float(np.linalg.norm(self.cup_frame()[:3, 3] - self.start_cup))
            assert travel > 0.7, travel
            assert self.water_travel > 0.7, self.water_travel


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_cup_transfer")
