# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The water surface in USD: record the dam break with ViewerUSD, time the surface extraction, draw the mesh.

Runs the ``fluid_xpbd_dam_break`` example (``--particles``) for ``--frames`` frames into a USD file
through ``ViewerUSD`` (one time-sampled ``Mesh`` prim for the water, extracted each frame by Newton's
``ParticleSurface`` from the render particles), then times the extraction alone at the last frame
(median of ``--repeats``, synchronised: the extraction sizes its mesh on the host), reads the last
frame's mesh back from the file with ``pxr`` and, with ``--png``, draws it in a headless ViewerGL.
``--no-usd`` simulates without writing USD (the timing alone, where ``pxr`` is missing).

Usage::

    python -m benchmarks usd_surface [--particles N] [--frames N] [--usd out.usd] [--png out.png] [--json out.json]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time

import newton.viewer
import numpy as np
import warp as wp

import newton
from newton._src.viewer.gl.fluid.surface_mesh import FluidSurfaceMeshes
from newton.examples.fluid.example_fluid_xpbd_dam_break import Example
from newton.examples.fluid.progress import FluidProgress

from .run_record import write_record


def record(args, usd_path: str | None, device) -> dict:
    if usd_path is None:
        viewer = newton.viewer.ViewerNull(num_frames=args.frames)
    else:
        viewer = newton.viewer.ViewerUSD(usd_path, num_frames=args.frames)
    example = Example(viewer, argparse.Namespace(particle_count=args.particles))
    solver, model = example.solver, example.model
    progress = FluidProgress(
        args.frames,
        "usd_surface",
        solver=solver,
        state=lambda: example.state_0,
        particles=model.particle_count,
        quiet=args.quiet,
    )
    for _ in range(args.frames):
        example.step()
        example.render()
        progress.update()
    viewer.close()
    progress.close()
    stats = solver.fluid_diagnostics(example.state_0)

    # the extraction alone, at the last frame's render particles
    solver.update_render_particles(example.state_0)
    meshes = FluidSurfaceMeshes()
    times = []
    for _ in range(args.repeats + 1):
        wp.synchronize_device(device)
        t0 = time.perf_counter()
        vertices, indices, _ = meshes.extract("/fluid", solver.render_positions, model.particle_radius)
        wp.synchronize_device(device)
        times.append((time.perf_counter() - t0) * 1000.0)
    return {
        "particles": int(model.particle_count),
        "frames": args.frames,
        "substeps": int(example.sim_substeps),
        "iterations": int(solver.iterations),
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        # the first extraction allocates its context
        "extract_ms_median": statistics.median(times[1:]),
        "extract_ms_first": times[0],
        "vertices": int(len(vertices)),
        "triangles": int(len(indices) // 3),
    }


def draw(usd_path: str, png: str, size: tuple[int, int]) -> None:
    """Draw the last frame's water mesh of ``usd_path`` in a headless ViewerGL and save it as ``png``."""
    if not os.environ.get("DISPLAY"):
        import pyglet  # noqa: PLC0415

        pyglet.options["headless"] = True
    import imageio.v2 as imageio  # noqa: PLC0415
    from pxr import Usd, UsdGeom  # noqa: PLC0415

    stage = Usd.Stage.Open(usd_path)
    mesh = UsdGeom.Mesh(next(p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh) and p.GetName() == "fluid"))
    frame = mesh.GetPointsAttr().GetTimeSamples()[-1]
    points = np.asarray(mesh.GetPointsAttr().Get(frame), dtype=np.float32)
    faces = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(frame), dtype=np.int32)
    normals = np.asarray(mesh.GetNormalsAttr().Get(frame), dtype=np.float32)
    viewer = newton.viewer.ViewerGL(width=size[0], height=size[1], headless=True)
    viewer.set_camera(wp.vec3(0.0, -2.6, 1.4), pitch=-22.0, yaw=90.0)
    viewer.begin_frame(0.0)
    viewer.log_mesh(
        "/usd_water",
        wp.array(points, dtype=wp.vec3),
        wp.array(faces, dtype=wp.int32),
        wp.array(normals, dtype=wp.vec3),
        color=(0.25, 0.5, 0.9),
        backface_culling=False,
    )
    viewer.end_frame()
    imageio.imwrite(png, viewer.get_frame().numpy())
    viewer.close()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=int, default=100_000)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--device", default=None)
    parser.add_argument("--usd", default=None, help="USD file to write (default: a temporary file)")
    parser.add_argument(
        "--no-usd", action="store_true", help="simulate without writing USD (no pxr needed): the timing only"
    )
    parser.add_argument("--png", default=None, help="draw the last frame's mesh into this PNG")
    parser.add_argument("--size", type=int, nargs=2, default=[1280, 720], metavar=("W", "H"))
    parser.add_argument("--json", default=None)
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    wp.config.quiet = True
    device = wp.get_device(args.device)
    with tempfile.TemporaryDirectory() as tmp, wp.ScopedDevice(device):
        usd_path = None if args.no_usd else args.usd or os.path.join(tmp, "dam_break.usda")
        result = write_record("usd_surface", device, record(args, usd_path, device), args.json)
        if args.png and usd_path is not None:
            draw(usd_path, args.png, tuple(args.size))
    print(f"{'device':<24}{'particles':>10}{'substeps':>9}{'iters':>6}{'density err':>12}{'extract ms':>11}{'tris':>9}")
    print(
        f"{result['device']:<24}{result['particles']:>10}{result['substeps']:>9}{result['iterations']:>6}"
        f"{100 * result['mean_abs_density_error']:>11.2f}%{result['extract_ms_median']:>11.2f}{result['triangles']:>9}"
    )
    return result


if __name__ == "__main__":
    main()
