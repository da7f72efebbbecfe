# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Drop three boxes of different densities into a water tank: they float, ride low or sink.

The boxes and the water act on each other through the particle-shape contacts of SolverXPBD
(two-way coupling): the water lifts a light box until it floats with the part of its volume
under water that its density asks for, a heavy box goes to the floor. In the GL viewer, the right mouse
button picks a box or drags a blob of water, whichever the cursor meets first.

Success criteria:
- The light box (250 kg/m^3) floats with its top out of the water; the middle one (700 kg/m^3)
  floats lower; the heavy one (2500 kg/m^3) sinks to the floor.
- No water inside a box; the water stays in the tank.

Runs:
- `python -m newton.examples fluid_xpbd_interactive_tank`
- `python -m newton.examples fluid_xpbd_interactive_tank --particle-count 20000`
"""

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import FluidExample, add_tank

TANK_HALF = 0.5  # inner half extent in x and y [m]
WALL_HEIGHT = 0.7  # [m]
WATER_DEPTH = 0.3  # [m]
BOX_HALF = (0.1, 0.1, 0.07)  # [m]
BOXES = ((-0.25, 250.0), (0.0, 700.0), (0.25, 2500.0))  # x [m], density [kg/m^3]


class Example(FluidExample):
    def __init__(self, viewer, args):
        super().__init__(viewer, args)
        d = ((2 * TANK_HALF) ** 2 * WATER_DEPTH / args.particle_count) ** (1.0 / 3.0)
        self.spacing = d
        builder = newton.ModelBuilder()
        n = max(2, int(2 * TANK_HALF / d))
        builder.add_particle_grid(
            pos=wp.vec3(-TANK_HALF + 0.5 * d, -TANK_HALF + 0.5 * d, 0.5 * d),
            rot=wp.quat_identity(),
            vel=wp.vec3(0.0),
            dim_x=n,
            dim_y=n,
            dim_z=max(2, round(WATER_DEPTH / d)),
            cell_x=d,
            cell_y=d,
            cell_z=d,
            mass=1000.0 * d**3,
            jitter=0.05 * d,
            radius_mean=0.5 * d,
            flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
        )
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        add_tank(builder, TANK_HALF, TANK_HALF, WALL_HEIGHT, 0.04)
        self.water_top = max(2, round(WATER_DEPTH / d)) * d
        for x, density in BOXES:
            body = builder.add_body(xform=wp.transform(wp.vec3(x, 0.0, self.water_top + 0.15), wp.quat_identity()))
            cfg = newton.ModelBuilder.ShapeConfig(mu=0.2, density=density)
            builder.add_shape_box(body, hx=BOX_HALF[0], hy=BOX_HALF[1], hz=BOX_HALF[2], cfg=cfg)
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        self.solver = newton.solvers.SolverXPBD(
            self.model, iterations=2, fluid_rest_distance=d, fluid_viscosity=0.02, fluid_cohesion=0.2
        )
        self.setup_simulation()
        self.viewer.set_camera(wp.vec3(0.0, -1.9, 1.1), pitch=-28.0, yaw=90.0)

    gui = FluidExample.viscosity_gui

    def test_final(self):
        body_q = self.state_0.body_q.numpy()
        z = body_q[:, 2]
        q = self.state_0.particle_q.numpy()
        d = self.spacing
        # the surface rises by the displaced volume; measure it from the water itself
        surface = np.percentile(q[:, 2], 99) + 0.5 * d
        light, middle, heavy = z
        assert light + BOX_HALF[2] > surface + 0.2 * BOX_HALF[2], (light, surface)
        assert middle < light - 0.2 * BOX_HALF[2], (middle, light)
        assert middle + BOX_HALF[2] > surface - 0.5 * d, (middle, surface)
        assert heavy < BOX_HALF[2] + 2.5 * d, (heavy, surface)
        for k in range(len(BOXES)):
            rot = body_q[k, 3:]
            local = q - body_q[k, :3]
            # axis-aligned test in the box frame: rotate the offsets back by the body's quaternion
            local = np.array([wp.quat_rotate_inv(wp.quat(*rot), wp.vec3(*p)) for p in local])
            inside = np.all(np.abs(local) < np.asarray(BOX_HALF) - 0.25 * d, axis=1)
            assert not inside.any(), f"{np.count_nonzero(inside)} particles inside box {k}"
        tol = 0.25 * d
        assert np.all(np.abs(q[:, :2]) <= TANK_HALF + tol) and np.all(q[:, 2] >= -tol), "water left the tank"


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_interactive_tank")
