# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Many isolated fluid worlds in one model: a small dam break per world, all in the same place.

Every world has its own tank and water column; the columns come in four heights (world index
mod 4). All worlds occupy the same space in the simulation (they overlap completely) and are
drawn side by side; the fluid solver's neighbourhoods are per world, so they never see each
other and each costs what its own particles cost.

Success criteria:
- Worlds with the same column height end in the same state; different heights give different pools.
- Every world keeps its water inside its own tank, and near its rest density although all worlds
  overlap in space (fluid of other worlds would crush it).

Runs:
- `python -m newton.examples fluid_xpbd_multiworld`
- `python -m newton.examples fluid_xpbd_multiworld --world-count 16 --particle-count 20000`
"""

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import FluidExample, add_tank

TANK_HALF = 0.15  # inner half extent in x and y [m]
WALL_HEIGHT = 0.3  # [m]
WALL_THICKNESS = 0.02  # [m]
COLUMN_HEIGHTS = (0.08, 0.12, 0.16, 0.2)  # [m], by world index mod 4
COLUMN_LENGTH = 0.1  # [m] against the -x wall


class Example(FluidExample):
    particle_count_help = "Fluid particles over all worlds"

    def __init__(self, viewer, args):
        super().__init__(viewer, args)
        self.world_count = args.world_count

        # spacing from the particle budget over all worlds
        mean_height = np.mean([COLUMN_HEIGHTS[w % 4] for w in range(self.world_count)])
        volume = self.world_count * COLUMN_LENGTH * 2 * TANK_HALF * mean_height
        d = (volume / args.particle_count) ** (1.0 / 3.0)
        self.spacing = d
        builder = newton.ModelBuilder()
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        flags = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)
        h = TANK_HALF
        for w in range(self.world_count):
            builder.begin_world()
            height = COLUMN_HEIGHTS[w % 4]
            builder.add_particle_grid(
                pos=wp.vec3(-h + 0.5 * d, -h + 0.5 * d, 0.5 * d),
                rot=wp.quat_identity(),
                vel=wp.vec3(0.0),
                dim_x=max(2, round(COLUMN_LENGTH / d)),
                dim_y=max(2, int(2 * h / d)),
                dim_z=max(2, round(height / d)),
                cell_x=d,
                cell_y=d,
                cell_z=d,
                mass=1000.0 * d**3,
                jitter=0.0,
                radius_mean=0.5 * d,
                flags=flags,
            )
            add_tank(builder, TANK_HALF, TANK_HALF, WALL_HEIGHT, WALL_THICKNESS)
            builder.end_world()
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0

        self.solver = newton.solvers.SolverXPBD(
            self.model, iterations=2, fluid_rest_distance=d, fluid_cohesion=0.3, fluid_viscosity=0.02
        )
        self.setup_simulation()
        self.viewer.set_world_offsets((2 * TANK_HALF + 0.15, 2 * TANK_HALF + 0.15, 0.0))
        self.viewer.set_camera(wp.vec3(0.0, -1.6, 2.2), pitch=-52.0, yaw=90.0)

    def log_fluids(self):
        # all worlds overlap in the simulation; draw each at its tank's place in the grid
        self.log_water_by_world()

    def test_final(self):
        q = self.state_0.particle_q.numpy()
        world = self.model.particle_world.numpy()
        d = self.spacing
        tol = 0.25 * d
        inside = (np.abs(q[:, 0]) <= TANK_HALF + tol) & (np.abs(q[:, 1]) <= TANK_HALF + tol) & (q[:, 2] >= -tol)
        assert inside.all(), f"{np.count_nonzero(~inside)} particles left their tank"
        stats = self.solver.fluid_diagnostics(self.state_0)
        # overlapping worlds that saw each other would be crushed far beyond this
        assert stats["max_compression"] < 0.08, stats
        mean_height = []
        for w in range(self.world_count):
            qw = q[world == w]
            mean_height.append(qw[:, 2].mean())
            twin = w + 4
            if twin < self.world_count:
                # the same setup in another world: the same result, bit for bit on the CPU; CUDA's
                # atomics reorder sums and a splash amplifies the difference, so there the twins
                # agree in their centroid (a world that saw another would be pushed far off)
                if wp.get_device().is_cuda:
                    diff = np.linalg.norm(q[world == twin].mean(axis=0) - qw.mean(axis=0))
                    assert diff < 0.5 * d, (w, twin, diff)
                else:
                    diff = np.abs(q[world == twin] - qw).max()
                    assert diff == 0.0, (w, twin, diff)
        if self.world_count >= 4:
            # each world levels out its own water: a tall column's world stays deeper than a short
            # one's (2.5x once settled), which a shared pool would even out
            assert mean_height[3] > 1.5 * mean_height[0], mean_height[:4]

    @classmethod
    def create_parser(cls):
        parser = super().create_parser()
        newton.examples.add_world_count_arg(parser)
        parser.set_defaults(world_count=16)
        return parser


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_multiworld")
