# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""A kinematic paddle makes waves that run across a pool and up a sloped beach; floating boxes ride them.

The paddle is a kinematic body whose pose and velocity are set on the device before every
substep (a sine stroke), so the whole frame stays one captured graph. The waves it makes travel
down the pool and break on a static ramp; three boxes of different density (250, 500 and
800 kg/m^3) float at their own depths and heave with the passing waves (two-way coupling).

Success criteria:
- The paddle keeps waves going: the water level in the middle of the pool swings by more than a
  few spacings, again and again, until the end.
- The waves run up the beach beyond the still-water shoreline.
- The boxes float near the heights Archimedes gives them in the still water (the lighter, the higher)
  and heave with the waves; no water leaves the pool.

Runs:
- `python -m newton.examples fluid_xpbd_wave_pool`
- `python -m newton.examples fluid_xpbd_wave_pool --particle-count 20000`
"""

import math

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import FluidExample, add_tank, advance_clock

POOL_HALF = (1.0, 0.2)  # inner half extents in x and y [m]
WALL_HEIGHT = 0.6  # [m]
DEPTH = 0.2  # depth of the water's starting lattice [m] (it settles lower: :func:`still_level`)
BEACH_SLOPE = math.radians(14.0)
BEACH_TOE = 0.1  # x where the ramp leaves the floor [m]
PADDLE_X = -0.85  # rest position of the paddle's centre [m]
PADDLE_HALF = (0.02, 0.2, 0.2)  # [m]
STROKE = 0.09  # amplitude of the paddle's stroke [m]
PERIOD = 1.1  # [s]
BOXES = ((-0.45, 250.0), (-0.2, 500.0), (0.05, 800.0))  # x [m], density [kg/m^3]
BOX_HALF = (0.06, 0.06, 0.04)  # [m]


@wp.kernel
def move_paddle(
    body: int,
    clock: wp.array[float],
    dt: float,
    rest: wp.vec3,
    stroke: float,
    omega: float,
    body_q: wp.array[wp.transform],
    body_qd: wp.array[wp.spatial_vector],
):
    # the pose at the end of the substep about to run, with the velocity that gets it there
    t = clock[0] + dt
    x = rest[0] + stroke * wp.sin(omega * t)
    body_q[body] = wp.transform(wp.vec3(x, rest[1], rest[2]), wp.quat_identity())
    body_qd[body] = wp.spatial_vector(wp.vec3(stroke * omega * wp.cos(omega * t), 0.0, 0.0), wp.vec3(0.0))


def beach_height(x):
    """Height of the ramp's surface [m] at ``x`` [m] (0 before its toe)."""
    return np.maximum(np.asarray(x, dtype=np.float64) - BEACH_TOE, 0.0) * math.tan(BEACH_SLOPE)


def still_level(volume):
    """Level [m] of ``volume`` [m^3] of water at rest between the paddle and the beach.

    The starting lattice is narrower than the pool and leaves the paddle's stroke dry, so the water
    settles below :data:`DEPTH`: over the floor from the paddle's face to the toe, and a wedge on the
    beach, ``2 hy (a h + h^2 / (2 tan(slope)))`` with ``a`` the floor's length.
    """
    a = BEACH_TOE - (PADDLE_X + PADDLE_HALF[0])
    b = 1.0 / (2.0 * math.tan(BEACH_SLOPE))
    c = volume / (2.0 * POOL_HALF[1])
    return (-a + math.sqrt(a * a + 4.0 * b * c)) / (2.0 * b)


def archimedes_height(level, density):
    """Height [m] of a box's centre floating at rest in water at ``level`` [m]: its draft is density / 1000 of its height."""
    return level - density / 1000.0 * 2.0 * BOX_HALF[2] + BOX_HALF[2]


class Example(FluidExample):
    def __init__(self, viewer, args):
        super().__init__(viewer, args)
        hx, hy = POOL_HALF
        x0 = PADDLE_X + PADDLE_HALF[0] + STROKE  # water starts in front of the paddle's stroke; behind it is dry
        shore = BEACH_TOE + DEPTH / math.tan(BEACH_SLOPE)
        volume = 2.0 * hy * DEPTH * ((BEACH_TOE - x0) + 0.5 * (shore - BEACH_TOE))
        d = (volume / args.particle_count) ** (1.0 / 3.0)
        self.spacing = d
        builder = newton.ModelBuilder()
        # a lattice over the water's cross-section, clipped to the beach
        xs = np.arange(x0 + 0.5 * d, shore, d)
        ys = np.arange(-hy + 0.5 * d, hy - 0.49 * d, d)  # at least half a spacing from the walls
        zs = np.arange(0.5 * d, DEPTH, d)
        x, y, z = np.meshgrid(xs, ys, zs, indexing="ij")
        pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
        pts = pts[pts[:, 2] > beach_height(pts[:, 0]) + 0.5 * d / math.cos(BEACH_SLOPE)]
        #: still-water shoreline: the farthest particle up the beach at rest [m]
        self.shoreline = float(pts[:, 0].max())
        builder.add_particles(
            pos=[wp.vec3(*p) for p in pts],
            vel=[wp.vec3(0.0)] * len(pts),
            mass=[1000.0 * d**3] * len(pts),
            radius=[0.5 * d] * len(pts),
            flags=[int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)] * len(pts),
        )
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        add_tank(builder, hx, hy, WALL_HEIGHT, 0.04)
        # the beach: a thick slab rotated about y, its top face through the toe
        # from the toe to the far wall along the slope
        slab_half = (0.5 * (hx - BEACH_TOE) / math.cos(BEACH_SLOPE), hy, 0.1)
        c, s = math.cos(BEACH_SLOPE), math.sin(BEACH_SLOPE)
        top_mid = np.array([BEACH_TOE + slab_half[0] * c, 0.0, slab_half[0] * s])
        center = top_mid - slab_half[2] * np.array([-s, 0.0, c])
        rot = wp.quat_from_axis_angle(wp.vec3(0.0, 1.0, 0.0), -BEACH_SLOPE)
        builder.add_shape_box(
            -1,
            xform=wp.transform(wp.vec3(*center), rot),
            hx=slab_half[0],
            hy=slab_half[1],
            hz=slab_half[2],
            cfg=newton.ModelBuilder.ShapeConfig(mu=0.0),
        )
        self.paddle_rest = wp.vec3(PADDLE_X, 0.0, PADDLE_HALF[2])
        self.paddle = builder.add_body(
            xform=wp.transform(self.paddle_rest, wp.quat_identity()), is_kinematic=True, label="paddle"
        )
        builder.add_shape_box(self.paddle, hx=PADDLE_HALF[0], hy=PADDLE_HALF[1] - 0.005, hz=PADDLE_HALF[2])
        # the particles' volume and the boxes' displacement, at rest
        box_volume = 8.0 * BOX_HALF[0] * BOX_HALF[1] * BOX_HALF[2]
        self.still_level = still_level(len(pts) * d**3 + sum(box_volume * rho / 1000.0 for _, rho in BOXES))
        self.boxes = []
        for x, density in BOXES:
            # dropped from just above the starting lattice (a box started among the particles sinks through them)
            body = builder.add_body(xform=wp.transform(wp.vec3(x, 0.0, DEPTH + 0.06), wp.quat_identity()))
            cfg = newton.ModelBuilder.ShapeConfig(mu=0.1, density=density)
            builder.add_shape_box(body, hx=BOX_HALF[0], hy=BOX_HALF[1], hz=BOX_HALF[2], cfg=cfg)
            self.boxes.append(body)
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        # no non-affine damping: the tests' waves (4,500 particles) are a few spacings high, close to the
        # particle scale the damping is meant for, and it took their energy (the 800 kg/m^3 box heaved 1.0
        # spacing in the last two periods at the default 0.1, 1.8 without it)
        self.solver = newton.solvers.SolverXPBD(
            self.model,
            iterations=2,
            fluid_rest_distance=d,
            fluid_viscosity=0.02,
            fluid_cohesion=0.1,
            fluid_nonaffine_damping=0.0,
        )
        self.clock = wp.zeros(1, dtype=float)
        # (time, level in the middle of the pool, farthest run-up, box heights), sampled every 5 frames
        self.samples = []
        self.setup_simulation()
        self.viewer.set_camera(wp.vec3(0.0, -2.2, 0.8), pitch=-18.0, yaw=90.0)

    def prescribe(self, state):
        wp.launch(
            move_paddle,
            dim=1,
            inputs=[self.paddle, self.clock, self.sim_dt, self.paddle_rest, STROKE, 2.0 * math.pi / PERIOD],
            outputs=[state.body_q, state.body_qd],
        )
        wp.launch(advance_clock, dim=1, inputs=[self.clock, self.sim_dt])

    def step(self):
        super().step()
        if round(self.sim_time * self.fps) % 5 == 0:
            q = self.state_0.particle_q.numpy()
            mid = np.abs(q[:, 0] + 0.2) < 1.5 * self.spacing
            level = float(np.percentile(q[mid, 2], 95)) if mid.any() else 0.0
            runup = float(q[:, 0].max())  # the farthest water up the beach
            self.samples.append((self.sim_time, level, runup, self.state_0.body_q.numpy()[self.boxes, 2].copy()))

    gui = FluidExample.viscosity_gui

    def test_final(self):
        d = self.spacing
        q = self.state_0.particle_q.numpy()
        hx, hy = POOL_HALF
        tol = 0.25 * d
        inside = (np.abs(q[:, 0]) <= hx + tol) & (np.abs(q[:, 1]) <= hy + tol) & (q[:, 2] >= -tol)
        assert inside.all(), f"{np.count_nonzero(~inside)} particles left the pool"
        if self.sim_time < 3.0 * PERIOD:
            return
        t = np.array([s[0] for s in self.samples])
        level = np.array([s[1] for s in self.samples])
        runup = np.array([s[2] for s in self.samples])
        heights = np.array([s[3] for s in self.samples])
        late = t > t[-1] - 2.0 * PERIOD
        # sustained: the level still swings by several spacings in the last two periods
        assert np.ptp(level[late]) > 2.0 * d, (np.ptp(level[late]), d)
        # the waterline runs up past the still shoreline and back down the beach
        assert runup.max() > self.shoreline + d, (runup.max(), self.shoreline)
        assert np.ptp(runup[late]) > 2.0 * d, (np.ptp(runup[late]), d)
        # the boxes float at Archimedes' heights, the lighter higher, and heave with the waves. At the tests'
        # 4,500 particles a box is 2.8 spacings tall, and its draft in still water is resolved to about half
        # a spacing (the 800 kg/m^3 box rides 0.6 spacings low; benchmarks/floating_box.py maps it)
        mean = heights[late].mean(axis=0)
        expected = np.array([archimedes_height(self.still_level, rho) for _, rho in BOXES])
        assert np.all(np.abs(mean - expected) < 1.5 * d), (mean, expected, d)
        assert mean[0] > mean[1] > mean[2], mean
        assert np.all(np.ptp(heights[late], axis=0) > 1.0 * d), np.ptp(heights[late], axis=0)


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_wave_pool")
