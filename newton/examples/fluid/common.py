# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""What the fluid examples share: a tank of four walls, the frame loop, and drawing the water."""

from __future__ import annotations

import warp as wp

import newton

WATER = {"color": (0.2, 0.45, 0.9, 0.3), "absorption": (4.0, 1.2, 0.5)}


def add_tank(builder: newton.ModelBuilder, half_x: float, half_y: float, height: float, thickness: float) -> None:
    """Four frictionless walls around ``|x| <= half_x``, ``|y| <= half_y`` [m] in the builder's current world.

    The front (-y) wall collides but is not drawn, like the glass of a real tank, so a camera in
    front sees in.
    """
    t, hz = thickness, 0.5 * height
    walls = (
        ((-half_x - t, 0.0, hz), (t, half_y + 2.0 * t, hz)),
        ((half_x + t, 0.0, hz), (t, half_y + 2.0 * t, hz)),
        ((0.0, -half_y - t, hz), (half_x, t, hz)),
        ((0.0, half_y + t, hz), (half_x, t, hz)),
    )
    for k, (center, half) in enumerate(walls):
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0, is_visible=k != 2)
        xform = wp.transform(wp.vec3(*center), wp.quat_identity())
        builder.add_shape_box(-1, xform=xform, hx=half[0], hy=half[1], hz=half[2], cfg=cfg)


class FluidExample:
    """Frame loop of a fluid example: ``sim_substeps`` collision + XPBD substeps per frame at ``fps``.

    A subclass builds ``self.model``, ``self.solver`` and ``self.spacing`` and then calls
    :meth:`setup_simulation`; on CUDA the whole frame is one captured graph.
    """

    fps = 60
    sim_substeps = 8

    def __init__(self, viewer):
        self.viewer = viewer
        self.frame_dt = 1.0 / self.fps
        self.sim_dt = self.frame_dt / self.sim_substeps
        self.sim_time = 0.0

    def setup_simulation(self) -> None:
        self.state_0 = self.model.state()
        self.state_1 = self.model.state()
        # contacts reach one diameter from a surface, so particles near walls see the walls' density
        self.collision = newton.CollisionPipeline(
            self.model, soft_contact_max=self.model.particle_count, soft_contact_gap=0.5 * self.spacing
        )
        self.contacts = self.collision.contacts()
        self.viewer.set_model(self.model)
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
            # mouse picking and wind of the GL viewer
            self.viewer.apply_forces(self.state_0)
            self.collision.collide(self.state_0, self.contacts)
            self.solver.step(self.state_0, self.state_1, None, self.contacts, self.sim_dt)
            self.state_0, self.state_1 = self.state_1, self.state_0

    def step(self):
        if self.graph:
            wp.capture_launch(self.graph)
        else:
            self.simulate()
        self.sim_time += self.frame_dt

    def log_water(self, name: str = "/water", positions: wp.array | None = None, **material) -> None:
        """Draw the fluid from the solver's render particles (after ``update_render_particles``;
        ``positions`` replaces their centres)."""
        self.viewer.log_fluid(
            name,
            self.solver.render_positions if positions is None else positions,
            radii=self.model.particle_radius,
            radius_scale=1.3,
            anisotropy=self.solver.render_anisotropy,
            anisotropy_secondary=self.solver.render_anisotropy_secondary,
            anisotropy_tertiary=self.solver.render_anisotropy_tertiary,
            **{**WATER, **material},
        )

    def log_foam(self, radius: float, **material) -> None:
        """Draw the solver's diffuse particles."""
        s = self.solver
        self.viewer.log_fluid_diffuse(
            "/foam",
            s.diffuse_positions,
            s.diffuse_velocities,
            s.diffuse_lifetimes,
            s.diffuse_kinds,
            radius=radius,
            **material,
        )
