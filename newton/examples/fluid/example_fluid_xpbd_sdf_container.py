# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Swirl water inside a vase: a non-convex triangle-mesh container holds the fluid through its SDF.

The vase is a closed triangle mesh (a bulb that narrows to a neck and flares at the rim, with
walls of finite thickness). Fluid particles collide with it through the mesh's signed distance
(upstream's particle-shape contacts, sign by ray parity on the watertight mesh), so the fluid can
sit under the bulb's overhang, where a convex hull would have cut through it. The water starts
spinning: it climbs the bulb's wall into the overhang, the neck keeps it in, and it settles.

Success criteria:
- No particle leaves the cavity (none above the rim, none beyond the inner wall) or ends up inside
  the wall.
- The spinning water climbs above its resting level, then settles to the level its volume gives.

Runs:
- `python -m newton.examples fluid_xpbd_sdf_container`
- `python -m newton.examples fluid_xpbd_sdf_container --particle-count 20000`
"""

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import main as capture_or_run
from newton.examples.fluid.common import FluidExample, revolved_container

WALL = 0.025  # wall and floor thickness [m]
RIM = 0.38  # height of the rim [m]
FILL = 0.12  # initial water level [m]
SPIN = 10.0  # initial angular velocity of the water [rad/s]


def inner_radius(z):
    """Radius of the vase's cavity [m] at height ``z`` [m]: a bulb (widest at 0.15 m), a neck, a flared rim."""
    z = np.asarray(z, dtype=np.float64)
    bulb = 0.09 + 0.09 * np.sin(np.pi * np.clip((z - WALL) / (0.28 - WALL), 0.0, 1.0))
    return np.where(z < 0.28, bulb, 0.09 + 0.5 * (z - 0.28))


def back_half(mesh: newton.Mesh) -> newton.Mesh:
    """The triangles of ``mesh`` behind the plane y = 0 (for a cut-away picture)."""
    v = np.asarray(mesh.vertices)
    tri = np.asarray(mesh.indices).reshape(-1, 3)
    keep = tri[v[tri].mean(axis=1)[:, 1] > 0.0]
    return newton.Mesh(v, keep.ravel(), compute_inertia=False, is_solid=False)


class Example(FluidExample):
    def __init__(self, viewer, args):
        super().__init__(viewer, args)
        # spacing from the volume of the cavity below the fill level
        zs = np.linspace(WALL, FILL, 200)
        volume = np.trapezoid(np.pi * inner_radius(zs) ** 2, zs)
        d = (volume / args.particle_count) ** (1.0 / 3.0)
        self.spacing = d
        builder = newton.ModelBuilder()
        # a lattice clipped to the cavity, half a spacing off the wall, spinning about the axis
        rmax = float(inner_radius(0.15))
        axis = np.arange(-rmax + 0.5 * d, rmax, d)
        x, y, z = np.meshgrid(axis, axis, np.arange(WALL + 0.5 * d, FILL, d), indexing="ij")
        pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
        r = np.hypot(pts[:, 0], pts[:, 1])
        pts = pts[r < inner_radius(pts[:, 2]) - 0.5 * d]
        vel = SPIN * np.stack([-pts[:, 1], pts[:, 0], np.zeros(len(pts))], axis=1)
        builder.add_particles(
            pos=[wp.vec3(*p) for p in pts],
            vel=[wp.vec3(*v) for v in vel],
            mass=[1000.0 * d**3] * len(pts),
            radius=[0.5 * d] * len(pts),
            flags=[int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)] * len(pts),
        )
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        profile = np.linspace(WALL, RIM, 40)
        vase = revolved_container(np.stack([inner_radius(profile), profile], axis=1), WALL, segments=64)
        # the water meets the whole vase; the picture shows its back half (a cut-away), so the water is seen
        builder.add_shape_mesh(-1, mesh=vase, cfg=newton.ModelBuilder.ShapeConfig(mu=0.0, is_visible=False))
        visual = newton.ModelBuilder.ShapeConfig(has_shape_collision=False, has_particle_collision=False)
        builder.add_shape_mesh(-1, mesh=back_half(vase), cfg=visual)
        self.model = builder.finalize()
        self.model.soft_contact_mu = 0.0
        self.rest_level = FILL
        self.highest = 0.0  # highest 99.5th-percentile height seen [m]
        self.solver = newton.solvers.SolverXPBD(
            self.model, iterations=2, fluid_rest_distance=d, fluid_viscosity=0.02, fluid_cohesion=0.2
        )
        self.setup_simulation()
        self.viewer.set_camera(wp.vec3(0.0, -0.9, 0.45), pitch=-18.0, yaw=90.0)

    def step(self):
        super().step()
        if round(self.sim_time * self.fps) % 10 == 0:
            q = self.state_0.particle_q.numpy()
            self.highest = max(self.highest, float(np.percentile(q[:, 2], 99.5)))

    gui = FluidExample.viscosity_gui

    def test_final(self):
        q = self.state_0.particle_q.numpy().astype(np.float64)
        d = self.spacing
        r = np.hypot(q[:, 0], q[:, 1])
        tol = 0.3 * d
        # inside the cavity: above the floor, below the rim, within the inner wall at its height
        assert q[:, 2].min() > WALL - tol and q[:, 2].max() < RIM, (q[:, 2].min(), q[:, 2].max())
        outside = r > inner_radius(q[:, 2]) + tol
        assert not outside.any(), f"{np.count_nonzero(outside)} particles beyond the inner wall"
        # the spin carried the water up the bulb's wall, under its overhang
        assert self.highest > self.rest_level + 2.0 * d, (self.highest, self.rest_level)
        if self.sim_time > 3.5:
            level = np.percentile(q[:, 2], 99) + 0.5 * d
            assert abs(level - self.rest_level) < 2.5 * d, (level, self.rest_level)


if __name__ == "__main__":
    capture_or_run(Example, "fluid_xpbd_sdf_container")
