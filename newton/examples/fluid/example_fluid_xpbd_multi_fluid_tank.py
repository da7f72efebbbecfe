# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Three fluids of different density released side by side in one tank layer themselves, with two boxes.

An oil (800 kg/m^3), water (1000 kg/m^3) and a syrup (1350 kg/m^3) start as three columns of
equal height. Each group is its own particle mass at the same spacing, so one density solve
treats them as three fluids (a particle's rest density follows its mass): the syrup runs under
the water, the oil over it, and after some sloshing they lie in three layers. Two boxes fall in:
one of 900 kg/m^3, lighter than water but heavier than oil, comes to rest at the oil-water
interface; one of 1150 kg/m^3 sinks through the water and stops on the syrup. Each fluid is
drawn as its own batch with its own material.

Success criteria:
- The fluids layer by density: the syrup's mean height is lowest, the oil's highest, and most of
  each fluid lies in its own layer.
- The 900 kg/m^3 box rests at the oil-water interface, the 1150 kg/m^3 box lower, off the floor.
- No fluid leaves the tank.

Runs:
- `python -m newton.examples fluid_xpbd_multi_fluid_tank`
- `python -m newton.examples fluid_xpbd_multi_fluid_tank --particle-count 20000`
"""

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import FluidExample, add_tank

TANK_HALF = (0.45, 0.2)  # inner half extents in x and y [m]
WALL_HEIGHT = 0.6  # [m]
FILL_HEIGHT = 0.36  # initial height of the three columns [m]
# name, density [kg/m^3], colour (alpha: scattering), absorption [1/m]
FLUIDS = (
    ("oil", 800.0, (0.95, 0.75, 0.2, 0.35), (0.3, 1.2, 5.0)),
    ("water", 1000.0, (0.2, 0.45, 0.9, 0.2), (4.0, 1.2, 0.5)),
    ("syrup", 1350.0, (0.55, 0.1, 0.1, 0.6), (1.5, 8.0, 9.0)),
)
BOX_HALF = (0.06, 0.06, 0.035)  # [m]
BOXES = ((-0.2, 900.0), (0.2, 1150.0))  # x [m], density [kg/m^3]


class Example(FluidExample):
    def __init__(self, viewer, args):
        super().__init__(viewer, args)
        hx, hy = TANK_HALF
        d = (4.0 * hx * hy * FILL_HEIGHT / args.particle_count) ** (1.0 / 3.0)
        self.spacing = d
        builder = newton.ModelBuilder()
        ny = max(2, int(2 * hy / d))
        nz = max(2, round(FILL_HEIGHT / d))
        nx_total = max(3, int(2 * hx / d))
        # one column per fluid, in the order oil | water | syrup, so all three must move to layer
        counts = [nx_total // 3, nx_total // 3, nx_total - 2 * (nx_total // 3)]
        self.groups = []
        x0 = -hx + 0.5 * d
        for (_name, density, _color, _absorption), nx in zip(FLUIDS, counts, strict=True):
            start = builder.particle_count
            builder.add_particle_grid(
                pos=wp.vec3(x0, -hy + 0.5 * d, 0.5 * d),
                rot=wp.quat_identity(),
                vel=wp.vec3(0.0),
                dim_x=nx,
                dim_y=ny,
                dim_z=nz,
                cell_x=d,
                cell_y=d,
                cell_z=d,
                mass=density * d**3,
                jitter=0.05 * d,
                radius_mean=0.5 * d,
                flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
            )
            self.groups.append(slice(start, builder.particle_count))
            x0 += nx * d
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        add_tank(builder, hx, hy, WALL_HEIGHT, 0.04)
        for x, density in BOXES:
            body = builder.add_body(xform=wp.transform(wp.vec3(x, 0.0, FILL_HEIGHT + 0.1), wp.quat_identity()))
            cfg = newton.ModelBuilder.ShapeConfig(mu=0.1, density=density)
            builder.add_shape_box(body, hx=BOX_HALF[0], hy=BOX_HALF[1], hz=BOX_HALF[2], cfg=cfg)
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        # the layers' heights once settled: each fluid's volume over the tank's floor
        self.layer_tops = np.cumsum([(g.stop - g.start) * d**3 / (4.0 * hx * hy) for g in self.groups[::-1]])[::-1]
        self.solver = newton.solvers.SolverXPBD(
            self.model, iterations=2, fluid_rest_distance=d, fluid_viscosity=0.02, fluid_cohesion=0.1
        )
        self.setup_simulation()
        self.viewer.set_camera(wp.vec3(0.0, -1.5, 0.5), pitch=-15.0, yaw=90.0)

    gui = FluidExample.viscosity_gui

    def log_fluids(self):
        for (name, _density, color, absorption), group in zip(FLUIDS, self.groups, strict=True):
            self.log_water(f"/{name}", particles=group, color=color, absorption=absorption)

    def test_final(self):
        q = self.state_0.particle_q.numpy()
        d = self.spacing
        oil, water, syrup = (q[g, 2] for g in self.groups)
        assert syrup.mean() < water.mean() < oil.mean(), (syrup.mean(), water.mean(), oil.mean())
        if self.sim_time > 3.5:
            # settled: most of each fluid is in its own layer (interfaces blur over a couple of spacings)
            tops = self.layer_tops  # oil, water, syrup tops from the floor
            band = 2.0 * d
            assert np.mean(syrup < tops[2] + band) > 0.85, np.mean(syrup < tops[2] + band)
            assert np.mean((water > tops[2] - band) & (water < tops[1] + band)) > 0.85
            assert np.mean(oil > tops[1] - band) > 0.85, np.mean(oil > tops[1] - band)
            body_z = self.state_0.body_q.numpy()[:, 2]
            light, heavy = body_z
            # 900 kg/m^3 sinks through the oil and floats on the water; 1150 kg/m^3 sinks through the
            # water and floats on the syrup (within a spacing: the contacts' reach at this resolution)
            assert abs(light - tops[1]) < BOX_HALF[2] + d, (light, tops[1])
            assert abs(heavy - tops[2]) < BOX_HALF[2] + d, (heavy, tops[2])
        hx, hy = TANK_HALF
        tol = 0.25 * d
        inside = (np.abs(q[:, 0]) <= hx + tol) & (np.abs(q[:, 1]) <= hy + tol) & (q[:, 2] >= -tol)
        assert inside.all(), f"{np.count_nonzero(~inside)} particles left the tank"


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_multi_fluid_tank")
