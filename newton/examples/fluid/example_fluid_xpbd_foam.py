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
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import FluidExample, add_tank

BASIN_HALF = 0.35  # inner half extent of the square basin [m]
# the sheet the impact spreads runs up the walls, and where its rings meet in the middle they throw a jet up to
# 1.4 m high (60,000 particles; docs/archive/validation_notebook.md, "The foam example's clamp")
WALL_HEIGHT = 1.5  # [m]
WALL_THICKNESS = 0.04  # [m]
POOL_DEPTH = 0.12  # [m]
COLUMN_HALF = 0.08  # half width of the falling column [m]
COLUMN_HEIGHT = 0.45  # [m]
DROP = 0.3  # gap between the pool's surface and the column's bottom [m]


class Example(FluidExample):
    default_particle_count = 60_000

    def __init__(self, viewer, args):
        super().__init__(viewer, args)

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
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        add_tank(builder, BASIN_HALF, BASIN_HALF, WALL_HEIGHT, WALL_THICKNESS)
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        self.fluid_volume = self.model.particle_count * d**3

        self.solver = newton.solvers.SolverXPBD(
            self.model,
            # three: at the stable density step two let the splash compress a particle past 10 %
            iterations=3,
            fluid_rest_distance=d,
            fluid_cohesion=0.3,
            fluid_viscosity=0.02,
            max_diffuse_particles=args.particle_count // 2,
        )
        # kinds of diffuse particle seen so far, and the most alive at once
        self.kinds_seen = set()
        self.max_alive = 0
        self.setup_simulation()
        self.viewer.set_camera(wp.vec3(0.0, -1.25, 1.6), pitch=-45.0, yaw=90.0)

    def step(self):
        super().step()
        if round(self.sim_time * self.fps) % 10 == 0:
            # an occasional look at the kinds, for test_final (a host read; not every frame)
            kinds = self.solver.diffuse_kinds.numpy()
            self.kinds_seen.update(int(k) for k in np.unique(kinds) if k != DIFFUSE_DEAD)
            self.max_alive = max(self.max_alive, int(np.count_nonzero(kinds != DIFFUSE_DEAD)))

    def log_fluids(self):
        self.log_water(color=(0.2, 0.45, 0.9, 0.2), absorption=(3.0, 1.0, 0.4))
        self.log_foam(radius=0.6 * self.spacing, color=(1.0, 1.0, 1.0, 0.9))

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


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_foam")
