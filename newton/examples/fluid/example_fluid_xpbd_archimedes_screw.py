# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""An Archimedes screw lifts water out of a basin; the water it pours out turns a paddle wheel and falls back.

A helical blade on a shaft (a kinematic body, turned at a fixed rate on the device) rotates inside
a static inclined tube whose lower end is under water. Each turn traps water between the blade's
flights and carries it up the tube; at the top the water pours onto a paddle wheel, a dynamic
body on a revolute joint to the world, turns it, and falls back into the basin. Blade and tube
are triangle meshes (the water meets them through their signed distance).

Success criteria:
- Water is lifted: particles reach the top of the tube and fall out of it.
- The wheel turns (it is driven by the water alone) and stays on its bearing.
- The basin holds its water: nothing leaves it other than into the tube and back.

Runs:
- `python -m newton.examples fluid_xpbd_archimedes_screw`
- `python -m newton.examples fluid_xpbd_archimedes_screw --particle-count 30000`
"""

import math

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import FluidExample, add_tank, advance_clock, revolved_profile

BASIN = (-0.7, 0.8, 0.2)  # x from, x to, half width in y [m]
BASIN_WALL = 0.75  # [m]: above the outflow, so splashes from the wheel stay in
DEPTH = 0.15  # still water depth [m]
INCLINE = math.radians(32.0)
SCREW_BASE = (-0.55, 0.0, 0.12)  # centre of the tube's lower end [m]
SCREW_LENGTH = 1.05  # [m]
TUBE_RADIUS = 0.1  # inner radius [m]
TUBE_WALL = 0.015  # [m]
SHAFT_RADIUS = 0.025  # [m]
SHAFT_OVERHANG = 0.03  # the shaft's reach below the tube's lower end [m]
PITCH = 0.2  # axial advance of the blade per turn [m]
BLADE_THICKNESS = 0.012  # [m]
TURNS_PER_SECOND = 2.0
WHEEL_CENTER = (0.58, 0.0, 0.5)  # [m]
WHEEL_RADIUS = 0.17  # [m]
PADDLES = 8
LIFTED = 0.45  # height above which water counts as lifted by the screw [m] (the basin holds 0.15 m)


def helical_blade(r0: float, r1: float, pitch: float, length: float, thickness: float, steps_per_turn: int = 48):
    """A closed mesh of a helical blade about z from z = 0 to ``length``: a rectangle swept along the helix."""
    steps = max(2, round(steps_per_turn * length / pitch))
    s = np.linspace(0.0, length, steps + 1)
    phi = 2.0 * np.pi * s / pitch
    # rectangle corners (radius, axial offset), counter-clockwise
    section = ((r0, -0.5 * thickness), (r1, -0.5 * thickness), (r1, 0.5 * thickness), (r0, 0.5 * thickness))
    vertices = []
    for sk, pk in zip(s, phi, strict=True):
        c, sn = math.cos(pk), math.sin(pk)
        vertices.extend((r * c, r * sn, sk + a) for r, a in section)
    indices = []
    for k in range(steps):
        for e in range(4):
            a, b = 4 * k + e, 4 * k + (e + 1) % 4
            indices.extend((a, b, b + 4, a, b + 4, a + 4))
    last = 4 * steps
    indices.extend((0, 2, 1, 0, 3, 2, last, last + 1, last + 2, last, last + 2, last + 3))
    vertices = np.asarray(vertices)
    tri = np.asarray(indices).reshape(-1, 3)
    volume = np.einsum("ij,ij->i", vertices[tri[:, 0]], np.cross(vertices[tri[:, 1]], vertices[tri[:, 2]])).sum()
    if volume < 0.0:  # wind outward
        tri = tri[:, ::-1]
    return newton.Mesh(vertices.astype(np.float32), tri.ravel().astype(np.int32))


@wp.kernel
def turn_screw(
    body: int,
    clock: wp.array[float],
    dt: float,
    base: wp.transform,
    axis: wp.vec3,
    omega: float,
    body_q: wp.array[wp.transform],
    body_qd: wp.array[wp.spatial_vector],
):
    # the pose at the end of the substep about to run, with the angular velocity that gets it there
    angle = omega * (clock[0] + dt)
    spin = wp.transform(wp.vec3(0.0), wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), angle))
    body_q[body] = base * spin
    body_qd[body] = wp.spatial_vector(wp.vec3(0.0), axis * omega)


class Example(FluidExample):
    default_particle_count = 130_000
    # the screw's flights need about this many to carry water
    cpu_particle_count = 6_000

    def __init__(self, viewer, args):
        super().__init__(viewer, args)
        x_lo, x_hi, hy = BASIN
        volume = (x_hi - x_lo) * 2.0 * hy * DEPTH
        d = (volume / args.particle_count) ** (1.0 / 3.0)
        self.spacing = d
        builder = newton.ModelBuilder()
        # the screw's frame: origin at the tube's lower end, z up the axis
        self.axis = np.array([math.cos(INCLINE), 0.0, math.sin(INCLINE)])
        rot = wp.quat_from_axis_angle(wp.vec3(0.0, 1.0, 0.0), math.pi / 2 - INCLINE)
        self.screw_base = wp.transform(wp.vec3(*SCREW_BASE), rot)

        # the basin's water, outside the tube
        # at least half a spacing from every wall
        xs = np.arange(x_lo + 0.5 * d, x_hi - 0.49 * d, d)
        ys = np.arange(-hy + 0.5 * d, hy - 0.49 * d, d)
        zs = np.arange(0.5 * d, DEPTH, d)
        x, y, z = np.meshgrid(xs, ys, zs, indexing="ij")
        pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
        rel = pts - np.asarray(SCREW_BASE)
        along = rel @ self.axis
        radial = np.linalg.norm(rel - np.outer(along, self.axis), axis=1)
        in_tube = (along > -0.5 * d) & (radial < TUBE_RADIUS + TUBE_WALL + 0.5 * d)
        # (the shaft reaches SHAFT_OVERHANG below the tube)
        on_shaft = (along > -SHAFT_OVERHANG - 0.5 * d) & (radial < SHAFT_RADIUS + 0.5 * d)
        pts = pts[~(in_tube | on_shaft)]
        builder.add_particles(
            pos=[wp.vec3(*p) for p in pts],
            vel=[wp.vec3(0.0)] * len(pts),
            mass=[1000.0 * d**3] * len(pts),
            radius=[0.5 * d] * len(pts),
            flags=[int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)] * len(pts),
        )
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        cx, hx = 0.5 * (x_lo + x_hi), 0.5 * (x_hi - x_lo)
        add_tank(builder, hx, hy, BASIN_WALL, 0.04, center=(cx, 0.0))

        # tube and screw touch only the water: no rigid contacts between them (the screw is scripted)
        static = newton.ModelBuilder.ShapeConfig(mu=0.0, has_shape_collision=False)
        tube = revolved_profile(
            np.array(
                [
                    [TUBE_RADIUS, 0.0],
                    [TUBE_RADIUS + TUBE_WALL, 0.0],
                    [TUBE_RADIUS + TUBE_WALL, SCREW_LENGTH],
                    [TUBE_RADIUS, SCREW_LENGTH],
                ]
            ),
            segments=48,
        )
        builder.add_shape_mesh(-1, xform=self.screw_base, mesh=tube, cfg=static)

        # the screw: shaft and blade on one kinematic body, massless shapes (frame = centre of mass)
        kin = newton.ModelBuilder.ShapeConfig(mu=0.0, density=0.0, has_shape_collision=False)
        self.screw = builder.add_body(xform=self.screw_base, is_kinematic=True, label="screw")
        builder.add_shape_cylinder(
            self.screw,
            xform=wp.transform(wp.vec3(0.0, 0.0, 0.5 * SCREW_LENGTH), wp.quat_identity()),
            radius=SHAFT_RADIUS,
            half_height=0.5 * SCREW_LENGTH + SHAFT_OVERHANG,
            cfg=kin,
        )
        blade = helical_blade(0.5 * SHAFT_RADIUS, TUBE_RADIUS - 0.004, PITCH, SCREW_LENGTH - 0.02, BLADE_THICKNESS)
        builder.add_shape_mesh(
            self.screw, xform=wp.transform(wp.vec3(0.0, 0.0, 0.01), wp.quat_identity()), mesh=blade, cfg=kin
        )

        # the paddle wheel: hub and paddles about y, free to turn on a revolute joint to the world
        wheel_cfg = newton.ModelBuilder.ShapeConfig(mu=0.1, density=400.0, has_shape_collision=False)
        self.wheel = builder.add_link(xform=wp.transform(wp.vec3(*WHEEL_CENTER), wp.quat_identity()), label="wheel")
        y_axis = wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), -math.pi / 2)
        builder.add_shape_cylinder(
            self.wheel, xform=wp.transform(wp.vec3(0.0), y_axis), radius=0.03, half_height=0.12, cfg=wheel_cfg
        )
        for k in range(PADDLES):
            a = 2.0 * math.pi * k / PADDLES
            r = 0.5 * (0.03 + WHEEL_RADIUS)
            builder.add_shape_box(
                self.wheel,
                xform=wp.transform(
                    wp.vec3(r * math.cos(a), 0.0, r * math.sin(a)),
                    wp.quat_from_axis_angle(wp.vec3(0.0, 1.0, 0.0), -a),
                ),
                hx=0.5 * (WHEEL_RADIUS - 0.03),
                hy=0.1,
                hz=0.006,
                cfg=wheel_cfg,
            )
        joint = builder.add_joint_revolute(
            -1,
            self.wheel,
            parent_xform=wp.transform(wp.vec3(*WHEEL_CENTER), wp.quat_identity()),
            axis=(0.0, 1.0, 0.0),
            damping=0.0,
        )
        builder.add_articulation([joint], label="wheel")

        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        self.fluid_count = self.model.particle_count
        self.solver = newton.solvers.SolverXPBD(
            self.model, iterations=2, fluid_rest_distance=d, fluid_viscosity=0.02, fluid_cohesion=0.1
        )
        self.clock = wp.zeros(1, dtype=float)
        self.top = SCREW_LENGTH * self.axis + np.asarray(SCREW_BASE)  # centre of the tube's upper end
        # statistics for test_final: most particles lifted near the top at once, wheel angle
        self.max_lifted = 0
        self.wheel_angle = 0.0
        self._last_wheel = None
        self.setup_simulation()
        self.viewer.set_camera(wp.vec3(0.05, -2.0, 0.65), pitch=-12.0, yaw=90.0)

    def prescribe(self, state):
        wp.launch(
            turn_screw,
            dim=1,
            inputs=[
                self.screw,
                self.clock,
                self.sim_dt,
                self.screw_base,
                wp.vec3(*self.axis),
                # the blade's sense of turn that carries water up the tube
                -2.0 * math.pi * TURNS_PER_SECOND,
            ],
            outputs=[state.body_q, state.body_qd],
        )
        wp.launch(advance_clock, dim=1, inputs=[self.clock, self.sim_dt])

    def step(self):
        super().step()
        if round(self.sim_time * self.fps) % 5 == 0:
            q = self.state_0.particle_q.numpy()
            lifted = q[:, 2] > LIFTED
            self.max_lifted = max(self.max_lifted, int(np.count_nonzero(lifted)))
            x = self.state_0.body_q.numpy()[self.wheel]
            # the wheel's angle about y from its quaternion, unwrapped
            angle = 2.0 * math.atan2(float(x[4]), float(x[6]))
            if self._last_wheel is not None:
                step = (angle - self._last_wheel + math.pi) % (2.0 * math.pi) - math.pi
                self.wheel_angle += step
            self._last_wheel = angle

    gui = FluidExample.viscosity_gui

    def test_final(self):
        d = self.spacing
        q = self.state_0.particle_q.numpy()
        x_lo, x_hi, hy = BASIN
        tol = 0.25 * d
        inside = (q[:, 0] > x_lo - tol) & (q[:, 0] < x_hi + tol) & (np.abs(q[:, 1]) < hy + tol) & (q[:, 2] > -tol)
        assert inside.all(), f"{np.count_nonzero(~inside)} particles left the basin"
        # the bearing holds: the wheel's centre stays on its axis
        x = self.state_0.body_q.numpy()[self.wheel]
        assert np.linalg.norm(x[:3] - np.asarray(WHEEL_CENTER)) < 0.01, x[:3]
        assert abs(float(x[3])) < 0.01 and abs(float(x[5])) < 0.01, x[3:]
        if self.sim_time > 3.9:
            assert self.max_lifted > 0.01 * self.fluid_count, (self.max_lifted, self.fluid_count)
            assert abs(self.wheel_angle) > 0.5 * math.pi, self.wheel_angle


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_archimedes_screw")
