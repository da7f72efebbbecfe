# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Pour a falling column of water into a shallow basin and watch spray, foam and bubbles form.

The column hits the pool at about 3 m/s: the impact throws spray, foam gathers on the spreading
rings, air is dragged under as bubbles (diffuse particles of SolverXPBD, drawn as sprites).

Success criteria:
- The impact emits diffuse particles; spray, foam and bubbles all occur while it splashes.
- Live diffuse particles stay inside the basin; the water stays inside it too.
- The water settles into a pool whose depth matches its volume over the basin's area.

Runs:
- `python -m newton.examples fluid_xpbd_foam`
- `python -m newton.examples fluid_xpbd_foam --capture foam.mp4 --num-frames 600` (headless video)
- `python -m newton.examples fluid_xpbd_foam --particle-count 20000`
"""

import numpy as np
import warp as wp

import newton
import newton.examples
from newton._src.solvers.xpbd.fluid.diffuse import DIFFUSE_BUBBLE, DIFFUSE_DEAD, DIFFUSE_FOAM, DIFFUSE_SPRAY
from newton.examples.fluid.capture import add_capture_arguments
from newton.examples.fluid.capture import main as capture_or_run

BASIN_HALF = 0.35  # inner half extent of the square basin [m]
WALL_HEIGHT = 0.6  # [m]
WALL_THICKNESS = 0.04  # [m]
POOL_DEPTH = 0.06  # [m]
COLUMN_HALF = 0.08  # half width of the falling column [m]
COLUMN_HEIGHT = 0.45  # [m]
DROP = 0.3  # gap between the pool's surface and the column's bottom [m]


class Example:
    def __init__(self, viewer, args):
        self.viewer = viewer
        self.fps = 60
        self.frame_dt = 1.0 / self.fps
        self.sim_substeps = 8
        self.sim_dt = self.frame_dt / self.sim_substeps
        self.sim_time = 0.0

        # spacing from the particle budget: the pool and the column share it by volume
        volume = (2 * BASIN_HALF) ** 2 * POOL_DEPTH + (2 * COLUMN_HALF) ** 2 * COLUMN_HEIGHT
        d = (volume / args.particle_count) ** (1.0 / 3.0)
        self.spacing = d
        builder = newton.ModelBuilder()
        flags = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)
        n_pool = max(2, int(2 * BASIN_HALF / d))
        n_col = max(2, int(2 * COLUMN_HALF / d))
        for dims, origin in (
            ((n_pool, n_pool, max(1, round(POOL_DEPTH / d))), (-BASIN_HALF + 0.5 * d, -BASIN_HALF + 0.5 * d, 0.5 * d)),
            (
                (n_col, n_col, max(2, round(COLUMN_HEIGHT / d))),
                (-COLUMN_HALF + 0.5 * d, -COLUMN_HALF + 0.5 * d, POOL_DEPTH + DROP),
            ),
        ):
            builder.add_particle_grid(
                pos=wp.vec3(*origin),
                rot=wp.quat_identity(),
                vel=wp.vec3(0.0),
                dim_x=dims[0],
                dim_y=dims[1],
                dim_z=dims[2],
                cell_x=d,
                cell_y=d,
                cell_z=d,
                mass=1000.0 * d**3,
                jitter=0.05 * d,
                radius_mean=0.5 * d,
                flags=flags,
            )
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
        glass = newton.ModelBuilder.ShapeConfig(mu=0.0, is_visible=False)
        builder.add_ground_plane(cfg=cfg)
        t, h, hz = WALL_THICKNESS, BASIN_HALF, 0.5 * WALL_HEIGHT
        walls = (
            ((-h - t, 0.0, hz), (t, h + 2 * t, hz)),
            ((h + t, 0.0, hz), (t, h + 2 * t, hz)),
            ((0.0, -h - t, hz), (h, t, hz)),  # the front, toward the camera: not drawn
            ((0.0, h + t, hz), (h, t, hz)),
        )
        for k, (center, half) in enumerate(walls):
            xform = wp.transform(wp.vec3(*center), wp.quat_identity())
            builder.add_shape_box(-1, xform=xform, hx=half[0], hy=half[1], hz=half[2], cfg=glass if k == 2 else cfg)
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        self.model.particle_max_velocity = 0.25 * d / self.sim_dt
        self.fluid_volume = self.model.particle_count * d**3

        self.solver = newton.solvers.SolverXPBD(
            self.model,
            iterations=2,
            fluid_rest_distance=d,
            fluid_cohesion=0.3,
            fluid_viscosity=0.02,
            max_diffuse_particles=args.particle_count // 2,
        )
        self.state_0 = self.model.state()
        self.state_1 = self.model.state()
        self.collision = newton.CollisionPipeline(
            self.model, soft_contact_max=self.model.particle_count, soft_contact_gap=0.5 * d
        )
        self.contacts = self.collision.contacts()
        # kinds of diffuse particle seen so far, and the most alive at once
        self.kinds_seen = set()
        self.max_alive = 0
        self.viewer.set_model(self.model)
        self.viewer.set_camera(wp.vec3(0.0, -1.5, 0.75), pitch=-24.0, yaw=90.0)
        self.capture()

    def capture(self):
        self.graph = None
        if wp.get_device().is_cuda:
            with wp.ScopedCapture() as capture:
                self.simulate()
            self.graph = capture.graph

    def simulate(self):
        for _ in range(self.sim_substeps):
            self.state_0.clear_forces()
            self.collision.collide(self.state_0, self.contacts)
            self.solver.step(self.state_0, self.state_1, None, self.contacts, self.sim_dt)
            self.state_0, self.state_1 = self.state_1, self.state_0

    def step(self):
        if self.graph:
            wp.capture_launch(self.graph)
        else:
            self.simulate()
        self.sim_time += self.frame_dt
        if round(self.sim_time * self.fps) % 10 == 0:
            # an occasional look at the kinds, for test_final (a host read; not every frame)
            kinds = self.solver.diffuse_kinds.numpy()
            self.kinds_seen.update(int(k) for k in np.unique(kinds) if k != DIFFUSE_DEAD)
            self.max_alive = max(self.max_alive, int(np.count_nonzero(kinds != DIFFUSE_DEAD)))

    def render(self):
        self.solver.update_render_particles(self.state_0)
        self.viewer.begin_frame(self.sim_time)
        self.viewer.log_state(self.state_0)
        self.viewer.log_fluid(
            "/water",
            self.solver.render_positions,
            radii=self.model.particle_radius,
            radius_scale=1.3,
            color=(0.2, 0.45, 0.9, 0.2),
            absorption=(3.0, 1.0, 0.4),
            anisotropy=self.solver.render_anisotropy,
            anisotropy_secondary=self.solver.render_anisotropy_secondary,
            anisotropy_tertiary=self.solver.render_anisotropy_tertiary,
        )
        self.viewer.log_fluid_diffuse(
            "/foam",
            self.solver.diffuse_positions,
            self.solver.diffuse_velocities,
            self.solver.diffuse_lifetimes,
            self.solver.diffuse_kinds,
            radius=0.6 * self.spacing,
            color=(1.0, 1.0, 1.0, 0.9),
        )
        self.viewer.end_frame()

    def test_final(self):
        emitted = int(self.solver.diffuse_emitted_count.numpy()[0])
        assert emitted > 0.01 * self.model.particle_count, f"only {emitted} diffuse particles emitted"
        assert {DIFFUSE_SPRAY, DIFFUSE_FOAM, DIFFUSE_BUBBLE} <= self.kinds_seen, self.kinds_seen
        d = self.spacing
        kinds = self.solver.diffuse_kinds.numpy()
        p = self.solver.diffuse_positions.numpy()[kinds != DIFFUSE_DEAD]
        assert np.all(np.abs(p[:, :2]) <= BASIN_HALF + 1.0e-3) and np.all(p[:, 2] >= -1.0e-3), "diffuse left the basin"
        q = self.state_0.particle_q.numpy()
        tol = 0.25 * d
        assert np.all(np.abs(q[:, :2]) <= BASIN_HALF + tol) and np.all(q[:, 2] >= -tol), "water left the basin"
        # settled: the pool's depth is the water's volume over the basin's area (within two particle layers)
        if self.sim_time > 1.9:
            depth = np.percentile(q[:, 2], 99) + 0.5 * d
            expected = self.fluid_volume / (2 * BASIN_HALF) ** 2
            assert abs(depth - expected) < 2.0 * d + 0.1 * expected, (depth, expected)
        stats = self.solver.fluid_diagnostics(self.state_0)
        assert stats["nonfinite_recovered"] == 0, stats

    @staticmethod
    def create_parser():
        parser = newton.examples.create_parser()
        add_capture_arguments(parser)
        parser.add_argument("--particle-count", type=int, default=60_000, help="Approximate fluid particle count.")
        return parser


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_foam")
