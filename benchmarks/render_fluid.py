# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Cost of drawing the fluid surface: update_render_particles plus each ViewerGL fluid pass.

Simulates the dam break (``fluid_xpbd_dam_break`` scene, ``--particles``) for ``--sim-frames``
frames, then draws ``--frames`` frames headless (EGL) at ``--width`` x ``--height`` and reports
medians of: the GPU time of each fluid pass (GL timestamp queries), the GPU time of
``update_render_particles`` (CUDA events around a captured graph on GPU, wall time on CPU), and
the wall time of the instance upload (``log_fluid``) and of the whole ``end_frame`` with and
without the fluid. Each ``--splatting`` mode is measured in turn: ``raster`` (GLSL passes) and
``compute`` (Warp kernels for depth, thickness and smoothing; their GPU time from CUDA events, the
GL-timeline span of the whole fluid render from GL timestamps). Writes a PNG of the last frame of
each mode with ``--png``.

Usage::

    PYGLET_HEADLESS=1 python -m benchmarks render_fluid [--particles N] [--width W --height H] [--json out.json]
"""

from __future__ import annotations

import argparse
import ctypes
import os
import platform
import statistics
import sys
import time

import numpy as np
import warp as wp

if not os.environ.get("DISPLAY"):
    import pyglet

    pyglet.options["headless"] = True

import newton.viewer

import newton
from newton.examples.fluid.example_fluid_xpbd_dam_break import Example

from .run_record import write_record


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=int, default=100_000)
    parser.add_argument("--width", type=int, default=1920)
    parser.add_argument("--height", type=int, default=1080)
    parser.add_argument("--sim-frames", type=int, default=45)
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--device", default=None)
    parser.add_argument("--png", default=None, help="file name; the mode is inserted before the extension")
    parser.add_argument("--splatting", nargs="+", default=["raster", "compute"], choices=["raster", "compute", "auto"])
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)

    wp.init()
    device = wp.get_device(args.device)
    with wp.ScopedDevice(device):
        viewer = newton.viewer.ViewerGL(width=args.width, height=args.height, headless=True)
        example = Example(viewer, argparse.Namespace(particle_count=args.particles))
        for _ in range(args.sim_frames):
            example.step()
        wp.synchronize()
        fluid = viewer.fluid_renderer

        def timed(fn):
            wp.synchronize()
            t = time.perf_counter()
            fn()
            viewer.renderer.gl.glFinish()
            wp.synchronize()
            return 1000.0 * (time.perf_counter() - t)

        plain = [
            timed(lambda: (viewer.begin_frame(0.0), viewer.log_state(example.state_0), viewer.end_frame()))
            for _ in range(args.frames)
        ]
        render_particles = []
        solver, state = example.solver, example.state_0
        graph = None
        if device.is_cuda:
            solver.update_render_particles(state)
            with wp.ScopedCapture() as capture:
                solver.update_render_particles(state)
            graph = capture.graph
        for _ in range(args.frames):
            if graph is None:
                render_particles.append(timed(lambda: solver.update_render_particles(state)))
                continue
            start, end = wp.Event(enable_timing=True), wp.Event(enable_timing=True)
            wp.record_event(start)
            wp.capture_launch(graph)
            wp.record_event(end)
            wp.synchronize()
            render_particles.append(wp.get_event_elapsed_time(start, end))
        per_mode = {}
        fluid.measure_timings = True
        for mode in args.splatting:
            fluid.splatting = mode
            per_mode[mode] = measure_mode(args, viewer, example, timed)
        # the scene's simulation settings and density at the drawn state (the solver's own measure)
        stats = example.solver.fluid_diagnostics(example.state_0)
        gl = viewer.renderer.gl
        gl_renderer = ctypes.cast(gl.glGetString(gl.GL_RENDERER), ctypes.c_char_p).value.decode()
        viewer.close()

    med = statistics.median
    result = {
        "platform": platform.platform(),
        "device": str(device),
        "device_name": device.name,
        "gl_renderer": gl_renderer,
        "particles": int(example.model.particle_count),
        "substeps": int(example.sim_substeps),
        "iterations": int(example.solver.iterations),
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        "resolution": [args.width, args.height],
        "cuda_gl_interop": bool(device.is_cuda and fluid.cuda_interop),
        "ms_update_render_particles": med(render_particles),
        "ms_end_frame_without_fluid": med(plain),
        "modes": per_mode,
    }
    print(f"{'device':<10} {'GL renderer':<32} {'particles':>9} {'resolution':>10}")
    print(
        f"{result['device']:<10} {result['gl_renderer'][:32]:<32} {result['particles']:>9} {args.width}x{args.height}"
    )
    for key in ("ms_update_render_particles", "ms_end_frame_without_fluid"):
        print(f"  {key:<40} {result[key]:8.3f}")
    for mode, values in per_mode.items():
        print(f"  -- splatting {mode} (drawn with {values['drawn_with']})")
        for key in (
            "ms_log_fluid_upload",
            "ms_end_frame_with_fluid",
            "ms_end_frame_with_fluid_timed_passes",
            "gpu_ms_fluid_passes",
            "gpu_ms_fluid_busy",
        ):
            print(f"  {key:<40} {values[key]:8.3f}")
        for key, value in values["gpu_ms_per_pass"].items():
            print(f"  gpu ms, pass {key:<27} {value:8.3f}")
    return write_record("render_fluid", device, result, args.json)


def log_fluid(viewer, example):
    """The dam-break example's fluid batch, as its render loop logs it."""
    viewer.log_fluid(
        "/fluid",
        example.solver.render_positions,
        radii=example.model.particle_radius,
        radius_scale=1.3,
        color=(0.2, 0.45, 0.9, 0.3),
        absorption=(4.0, 1.2, 0.5),
        anisotropy=example.solver.render_anisotropy,
        anisotropy_secondary=example.solver.render_anisotropy_secondary,
        anisotropy_tertiary=example.solver.render_anisotropy_tertiary,
    )


def measure_mode(args, viewer, example, timed):
    """Draw ``args.frames`` frames with the fluid renderer's current splatting mode; medians of the timings.

    ``gpu_ms_fluid_passes`` is the GL timeline from the scene copy to the end of shading (in compute mode
    it spans the CUDA kernels, the transfers and any wait for the host between them);
    ``gpu_ms_fluid_busy`` counts the GPU's work only: the GL passes plus, in compute mode, the CUDA
    kernels in place of the GL interval that holds them (that interval minus the kernels is reported as
    ``host_waits``).
    """
    fluid = viewer.fluid_renderer
    med = statistics.median
    upload, full, passes, untimed = [], [], [], []
    fluid.measure_timings = False
    for _ in range(args.frames):
        viewer.begin_frame(0.0)
        viewer.log_state(example.state_0)
        log_fluid(viewer, example)
        untimed.append(timed(viewer.end_frame))
    fluid.measure_timings = True
    for _ in range(args.frames):
        viewer.begin_frame(0.0)
        viewer.log_state(example.state_0)
        upload.append(timed(lambda: log_fluid(viewer, example)))
        full.append(timed(viewer.end_frame))
        timings = dict(fluid.last_timings_ms)
        cuda = sum(v for k, v in timings.items() if k.startswith("cuda_"))
        if "compute" in timings:
            timings["host_waits"] = timings["compute"] - cuda
        passes.append(timings)
    if args.png:
        frame = viewer.get_frame().numpy()
        root, ext = os.path.splitext(args.png)
        name = f"{root}_{fluid.splatting}{ext}"
        try:
            from PIL import Image  # noqa: PLC0415

            Image.fromarray(frame).save(name)
        except ImportError:
            np.save(name + ".npy", frame)

    def span(p):
        return sum(v for k, v in p.items() if k not in ("present", "host_waits") and not k.startswith("cuda_"))

    def busy(p):
        return sum(v for k, v in p.items() if k not in ("present", "compute", "host_waits"))

    return {
        "drawn_with": fluid.last_splatting,
        "ms_log_fluid_upload": med(upload),
        "ms_end_frame_with_fluid_timed_passes": med(full),
        "ms_end_frame_with_fluid": med(untimed),
        "gpu_ms_per_pass": {k: med([p[k] for p in passes]) for k in passes[0]},
        "gpu_ms_fluid_passes": med([span(p) for p in passes]),
        "gpu_ms_fluid_busy": med([busy(p) for p in passes]),
    }


if __name__ == "__main__":
    main(sys.argv[1:])
