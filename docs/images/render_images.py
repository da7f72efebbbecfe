# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Render the reference pictures of the fluid surface in docs/images (headless, CPU or GPU).

Usage::

    PYGLET_HEADLESS=1 python docs/images/render_images.py [--particles N] [--frames F]

Writes ``multi_fluid_tank.png``: two fluids with their own materials (clear blue water from the
-x wall, an orange, milky fluid from the +x wall) meeting in the dam-break tank. The dam-break
picture (``dam_break.png``) comes from ``benchmarks/render_fluid.py --png`` (see docs/rendering.rst).
"""

import argparse
import os

import warp as wp

if not os.environ.get("DISPLAY"):
    import pyglet

    pyglet.options["headless"] = True

import newton.viewer
from PIL import Image

import newton
from newton.examples.fluid.example_fluid_xpbd_dam_break import TANK_HALF_LENGTH, add_dam_break


def multi_fluid_tank(particles: int, frames: int, path: str) -> None:
    builder = newton.ModelBuilder()
    scene = add_dam_break(builder, particles // 2, obstacles=False)
    s = scene["spacing"]
    water = builder.particle_count
    dims = scene["dims"]
    builder.add_particle_grid(
        pos=wp.vec3(TANK_HALF_LENGTH - (dims[0] - 0.5) * s, -scene["half_width"] + 0.5 * s, 0.5 * s),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0),
        dim_x=dims[0],
        dim_y=dims[1],
        dim_z=dims[2] * 2 // 3,
        cell_x=s,
        cell_y=s,
        cell_z=s,
        mass=1000.0 * s**3,
        jitter=0.1 * s,
        radius_mean=0.5 * s,
        flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
    )
    model = builder.finalize()
    model.soft_contact_mu = 0.0
    dt = 1.0 / 60.0 / 8
    model.particle_max_velocity = 0.25 * s / dt
    solver = newton.solvers.SolverXPBD(model, iterations=2, fluid_rest_distance=s, fluid_cohesion=0.5)
    s0, s1 = model.state(), model.state()
    pipeline = newton.CollisionPipeline(model, soft_contact_max=model.particle_count, soft_contact_gap=0.5 * s)
    contacts = pipeline.contacts()
    for _ in range(frames * 8):
        s0.clear_forces()
        pipeline.collide(s0, contacts)
        solver.step(s0, s1, None, contacts, dt)
        s0, s1 = s1, s0

    viewer = newton.viewer.ViewerGL(width=960, height=540, headless=True)
    viewer.set_model(model)
    viewer.set_camera(wp.vec3(0.0, -2.6, 1.4), pitch=-22.0, yaw=90.0)
    solver.update_render_particles(s0)
    n = model.particle_count
    materials = (
        ("/water", 0, water, {"color": (0.2, 0.45, 0.9, 0.3), "absorption": (4.0, 1.2, 0.5)}),
        ("/orange", water, n, {"color": (1.0, 0.45, 0.1, 0.9), "absorption": (0.5, 3.0, 12.0), "ior": 1.45}),
    )
    for _ in range(2):
        viewer.begin_frame(0.0)
        viewer.log_state(s0)
        for name, a, b, material in materials:
            viewer.log_fluid(
                name,
                solver.render_positions[a:b],
                radii=0.5 * s,
                radius_scale=1.3,
                anisotropy=solver.render_anisotropy[a:b],
                anisotropy_secondary=solver.render_anisotropy_secondary[a:b],
                anisotropy_tertiary=solver.render_anisotropy_tertiary[a:b],
                **material,
            )
        viewer.end_frame()
    Image.fromarray(viewer.get_frame().numpy()).save(path)
    viewer.close()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=int, default=30_000)
    parser.add_argument("--frames", type=int, default=45)
    args = parser.parse_args()
    here = os.path.dirname(os.path.abspath(__file__))
    multi_fluid_tank(args.particles, args.frames, os.path.join(here, "multi_fluid_tank.png"))
