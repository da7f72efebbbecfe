# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Collapse a water column into a tank with two rigid obstacles (position-based fluids in SolverXPBD).

Success criteria:
- The column collapses, the surge crosses the tank floor and splashes against the obstacles.
- Water stays inside the tank and out of the obstacles; nothing goes below the ground.
- The fluid stays nearly incompressible (max compression a few percent).

Runs:
- `python -m newton.examples fluid_xpbd_dam_break`
- `python -m newton.examples fluid_xpbd_dam_break --capture dam_break.mp4 --num-frames 600` (headless video)
- `python -m newton.examples fluid_xpbd_dam_break --particle-count 20000`
"""

import math

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import FluidExample, add_tank

# the benchmark column of the Newton-fluid performance target: 34 x 49 x 60 particles
BASE_DIMS = (34, 49, 60)
BASE_SPACING = 0.0201439  # [m]
TANK_HALF_LENGTH = 1.2  # inner half-length in x [m]
WALL_HEIGHT = 1.6  # [m]
WALL_THICKNESS = 0.05  # [m]


def add_dam_break(
    builder: newton.ModelBuilder,
    particle_count: int,
    obstacles: bool,
    jitter: float = 0.1,
    terrain_bump: float = 0.0,
) -> dict:
    """Add the dam-break tank, its water column and optionally two obstacles to ``builder``.

    The column of ``BASE_DIMS`` particles at ``BASE_SPACING`` is rescaled to about
    ``particle_count`` particles by changing the spacing, so the geometry stays the same.

    Args:
        builder: Builder to add to (z up).
        particle_count: Approximate number of fluid particles.
        obstacles: Add two static boxes in the path of the surge.
        jitter: Random offset of the initial lattice, as a fraction of the spacing.
        terrain_bump: If above 0, the floor is a heightfield (:class:`newton.Heightfield`) instead of the
            ground plane: cells of two spacings, heights random between 0 and this fraction of the spacing.

    Returns:
        dict: ``spacing`` [m], ``dims`` (particles per axis), ``half_width`` (tank, y) [m] and
        ``obstacles`` (list of (center, half extents) of the boxes).
    """
    scale = (particle_count / math.prod(BASE_DIMS)) ** (1.0 / 3.0)
    dims = tuple(max(2, round(n * scale)) for n in BASE_DIMS)
    spacing = BASE_SPACING * BASE_DIMS[1] / dims[1]
    half_width = 0.5 * dims[1] * spacing
    builder.add_particle_grid(
        pos=wp.vec3(-TANK_HALF_LENGTH + 0.5 * spacing, -half_width + 0.5 * spacing, 0.5 * spacing),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0),
        dim_x=dims[0],
        dim_y=dims[1],
        dim_z=dims[2],
        cell_x=spacing,
        cell_y=spacing,
        cell_z=spacing,
        mass=1000.0 * spacing**3,
        jitter=jitter * spacing,
        radius_mean=0.5 * spacing,
        flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
    )
    # water slips along the tank: no Coulomb friction between particles and these shapes
    if terrain_bump > 0.0:
        cells = (round(2.0 * TANK_HALF_LENGTH / (2.0 * spacing)), round(2.0 * half_width / (2.0 * spacing)))
        heights = np.random.default_rng(1).uniform(0.0, 1.0, (cells[1] + 1, cells[0] + 1))
        terrain = newton.Heightfield(
            heights,
            cells[1] + 1,
            cells[0] + 1,
            hx=TANK_HALF_LENGTH,
            hy=half_width,
            min_z=0.0,
            max_z=terrain_bump * spacing,
        )
        builder.add_shape_heightfield(heightfield=terrain, cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    else:
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    add_tank(builder, TANK_HALF_LENGTH, half_width, WALL_HEIGHT, WALL_THICKNESS)
    boxes = []
    if obstacles:
        boxes = [
            ((0.1, -0.45 * half_width, 0.15), (0.06, 0.25 * half_width, 0.15)),
            ((0.6, 0.4 * half_width, 0.2), (0.06, 0.25 * half_width, 0.2)),
        ]
    for center, half in boxes:
        xform = wp.transform(wp.vec3(*center), wp.quat_identity())
        builder.add_shape_box(
            -1, xform=xform, hx=half[0], hy=half[1], hz=half[2], cfg=newton.ModelBuilder.ShapeConfig(mu=0.0)
        )
    return {"spacing": spacing, "dims": dims, "half_width": half_width, "obstacles": boxes}


class Example(FluidExample):
    def __init__(self, viewer, args):
        super().__init__(viewer, args)
        builder = newton.ModelBuilder()
        self.scene = add_dam_break(builder, args.particle_count, obstacles=True)
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        self.spacing = self.scene["spacing"]

        self.solver = newton.solvers.SolverXPBD(
            self.model,
            iterations=2,
            fluid_rest_distance=self.spacing,
            fluid_cohesion=0.5,
            fluid_viscosity=0.05,
            # spray and foam where the wave breaks, for the picture only
            max_diffuse_particles=args.particle_count // 4,
        )
        self.setup_simulation()
        self.viewer.set_camera(wp.vec3(0.0, -2.6, 1.4), pitch=-22.0, yaw=90.0)

    def gui(self, ui):
        # these parameters live on the device, so a captured graph picks up the new values
        for name, hi in (("fluid_viscosity", 1.0), ("fluid_cohesion", 1.0), ("fluid_relaxation", 2.0)):
            changed, value = ui.slider_float(name.removeprefix("fluid_"), getattr(self.solver, name), 0.0, hi)
            if changed:
                setattr(self.solver, name, max(value, 1.0e-3) if name == "fluid_relaxation" else value)

    def log_fluids(self):
        # smoothed centres and ellipsoids for the surface; they do not feed back into the simulation
        self.log_water("/fluid")
        self.log_foam(radius=0.25 * self.spacing)

    def test_final(self):
        q = self.state_0.particle_q.numpy()
        r = 0.5 * self.scene["spacing"]
        tol = 0.5 * r
        hw = self.scene["half_width"]
        inside = (
            (np.abs(q[:, 0]) <= TANK_HALF_LENGTH + tol)
            & (np.abs(q[:, 1]) <= hw + tol)
            & (q[:, 2] >= -tol)
            & (q[:, 2] <= WALL_HEIGHT)
        )
        assert inside.all(), f"{np.count_nonzero(~inside)} particles left the tank"
        for center, half in self.scene["obstacles"]:
            depth = np.min(np.asarray(half) - np.abs(q - np.asarray(center)), axis=1)
            assert (depth < r).all(), f"{np.count_nonzero(depth >= r)} particles inside an obstacle"
        column_length = self.scene["dims"][0] * self.scene["spacing"]
        front = np.percentile(q[:, 0], 99.5) + TANK_HALF_LENGTH
        assert front > 1.5 * column_length, f"surge front {front:.3f} m has not left the column ({column_length:.3f} m)"
        stats = self.solver.fluid_diagnostics(self.state_0)
        assert stats["max_compression"] < 0.08, stats
        assert stats["nonfinite_recovered"] == 0, stats


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_dam_break")
