# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Video capture for the fluid examples: ``--capture out.mp4``.

Renders an example headless in ViewerGL (EGL where there is no display), simulating at the
example's rate (60 Hz) and writing every second frame (30 fps) as H.264 through imageio-ffmpeg,
with a progress bar on stderr, then a JSON sidecar beside the video (``out.mp4.json``): scene,
particle count, substeps, iterations, frames, simulated and wall time, output fps, the density
error of the last frame, device and versions. ``--capture-still out.png`` also keeps the last frame.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time

CAPTURE_SIZE = (1280, 720)
OUTPUT_FPS = 30


def add_capture_arguments(parser) -> None:
    """Add ``--capture PATH``, ``--capture-size W H`` and ``--capture-still PNG`` to an example's parser."""
    parser.add_argument("--capture", type=str, default=None, help="Render headless into this MP4 file (H.264, 30 fps).")
    parser.add_argument(
        "--capture-size", type=int, nargs=2, default=list(CAPTURE_SIZE), metavar=("W", "H"), help="Video size [px]."
    )
    parser.add_argument(
        "--capture-still", type=str, default=None, help="With --capture, also save the last frame as this PNG file."
    )


def _progress(done: int, total: int, start: float) -> None:
    width = 30
    filled = int(width * done / max(total, 1))
    rate = done / max(time.perf_counter() - start, 1.0e-9)
    sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} frames, {rate:.1f} frames/s")
    if done == total:
        sys.stderr.write("\n")
    sys.stderr.flush()


def capture(example_class, args, scene: str) -> dict:
    """Simulate ``example_class(viewer, args)`` for ``args.num_frames`` frames into ``args.capture``.

    Returns:
        dict: The sidecar's content.
    """
    if not os.environ.get("DISPLAY"):
        import pyglet  # noqa: PLC0415

        pyglet.options["headless"] = True
    import imageio.v2 as imageio  # noqa: PLC0415
    import newton.viewer  # noqa: PLC0415
    import warp as wp  # noqa: PLC0415

    import newton  # noqa: PLC0415

    if args.device:
        wp.set_device(args.device)
    width, height = args.capture_size
    if width % 2 or height % 2 or width < 16 or height < 16:
        raise ValueError(f"capture_size={width}x{height} is invalid: expected even sizes of at least 16 px (H.264)")
    viewer = newton.viewer.ViewerGL(width=width, height=height, headless=True)
    example = example_class(viewer, args)
    stride = max(1, round(example.fps / OUTPUT_FPS))
    frames = args.num_frames
    written = 0
    start = time.perf_counter()
    writer = imageio.get_writer(
        args.capture, fps=example.fps / stride, codec="libx264", quality=8, pixelformat="yuv420p", macro_block_size=1
    )
    image = None
    try:
        total = frames // stride
        for frame in range(frames):
            example.step()
            if (frame + 1) % stride == 0:
                example.render()
                image = viewer.get_frame().numpy()
                writer.append_data(image)
                written += 1
                _progress(written, total, start)
    finally:
        writer.close()
        wall = time.perf_counter() - start
    still = getattr(args, "capture_still", None)
    if still and image is not None:
        imageio.imwrite(still, image)
    device = wp.get_device()
    solver = example.solver
    # the density at the last frame, by the solver's own measure (a synchronising read, after the timing)
    stats = solver.fluid_diagnostics(example.state_0)
    sidecar = {
        "scene": scene,
        "video": os.path.basename(args.capture),
        "particles": int(example.model.particle_count),
        "substeps": int(example.sim_substeps),
        "iterations": int(solver.iterations),
        "frames_simulated": frames,
        "frames_written": written,
        "simulation_fps": example.fps,
        "output_fps": example.fps / stride,
        "resolution": [width, height],
        "simulated_time_s": frames / example.fps,
        "wall_time_s": wall,
        "frames_written_per_s": written / wall if wall > 0 else 0.0,
        "simulated_frames_per_s": frames / wall if wall > 0 else 0.0,
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        "device": device.name,
        "machine": platform.node(),
        "newton": newton.__version__,
        "warp": wp.config.version,
        "python": platform.python_version(),
    }
    with open(args.capture + ".json", "w") as f:
        json.dump(sidecar, f, indent=2)
    viewer.close()
    return sidecar


def main(example_class, scene: str) -> None:
    """Entry point of an example module: capture with ``--capture``, else run as Newton runs examples."""
    import newton.examples  # noqa: PLC0415

    parser = example_class.create_parser()
    args = parser.parse_args()
    if args.capture:
        capture(example_class, args, scene)
        return
    viewer, args = newton.examples.init(parser)
    newton.examples.run(example_class(viewer, args), args)
