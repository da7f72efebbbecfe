# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Headless capture for the fluid examples: ``--capture out.mp4`` and ``--capture-still out.png``, and their entry point.

Renders an example headless in ViewerGL (EGL where there is no display), simulating at the
example's rate (60 Hz). ``--capture`` writes every second frame (30 fps) as H.264 through
imageio-ffmpeg; ``--capture-still`` saves one frame as a PNG (the last, or ``--still-frame N``),
alone (no video is encoded, and only that frame is rendered) or beside a video. A progress line
on stderr, a one-line summary, then a JSON sidecar beside the video (``out.mp4.json``) or, without
one, beside the still (``out.png.json``): scene, particle count, substeps, iterations, frames,
simulated and wall time, output fps, the density error of the last frame, device and versions.
"""

from __future__ import annotations

import json
import os
import platform
import time

CAPTURE_SIZE = (1280, 720)
OUTPUT_FPS = 30


def add_capture_arguments(parser) -> None:
    """Add ``--capture PATH``, ``--capture-size W H``, ``--capture-still PNG`` and ``--still-frame N`` to a parser."""
    parser.add_argument("--capture", type=str, default=None, help="Render headless into this MP4 file (H.264, 30 fps).")
    parser.add_argument(
        "--capture-size", type=int, nargs=2, default=list(CAPTURE_SIZE), metavar=("W", "H"), help="Image size [px]."
    )
    parser.add_argument(
        "--capture-still",
        type=str,
        default=None,
        help="Render headless and save one frame as this PNG file (alone: no video is encoded).",
    )
    parser.add_argument(
        "--still-frame",
        type=int,
        default=None,
        metavar="N",
        help="Frame (1 to --num-frames) that --capture-still saves; default: the last.",
    )


def capture(example_class, args, scene: str) -> dict:
    """Simulate ``example_class(viewer, args)`` for ``args.num_frames`` frames into ``args.capture`` and/or ``args.capture_still``.

    Returns:
        dict: The sidecar's content.
    """
    video, still = args.capture, getattr(args, "capture_still", None)
    frames = args.num_frames
    if frames < 1:
        raise ValueError(f"num_frames={frames!r} is invalid: a capture needs at least 1 frame")
    still_frame = getattr(args, "still_frame", None)
    if still_frame is None:
        still_frame = frames
    elif not still:
        raise ValueError(f"still_frame={still_frame!r} is invalid without --capture-still: name the PNG to write")
    elif not 1 <= still_frame <= frames:
        raise ValueError(f"still_frame={still_frame!r} is out of range: expected a frame in [1, {frames}]")
    width, height = args.capture_size
    if width % 2 or height % 2 or width < 16 or height < 16:
        raise ValueError(f"capture_size={width}x{height} is invalid: expected even sizes of at least 16 px (H.264)")
    if not os.environ.get("DISPLAY"):
        import pyglet  # noqa: PLC0415

        pyglet.options["headless"] = True
    import imageio.v2 as imageio  # noqa: PLC0415
    import newton.viewer  # noqa: PLC0415
    import warp as wp  # noqa: PLC0415

    import newton  # noqa: PLC0415

    if args.device:
        wp.set_device(args.device)
    viewer = newton.viewer.ViewerGL(width=width, height=height, headless=True)
    example = example_class(viewer, args)
    stride = max(1, round(example.fps / OUTPUT_FPS))
    written = 0
    progress = _progress_for(example, args, scene, frames)
    start = time.perf_counter()
    writer = None
    if video:
        writer = imageio.get_writer(
            video, fps=example.fps / stride, codec="libx264", quality=8, pixelformat="yuv420p", macro_block_size=1
        )
    try:
        for frame in range(1, frames + 1):
            example.step()
            progress.update()
            image = None
            if writer is not None and frame % stride == 0:
                example.render()
                image = viewer.get_frame().numpy()
                writer.append_data(image)
                written += 1
            if still and frame == still_frame:
                if image is None:
                    example.render()
                    image = viewer.get_frame().numpy()
                imageio.imwrite(still, image)
    finally:
        if writer is not None:
            writer.close()
        wall = time.perf_counter() - start
    progress.close()
    device = wp.get_device()
    solver = example.solver
    # the density at the last frame, by the solver's own measure (a synchronising read, after the timing)
    stats = solver.fluid_diagnostics(example.state_0)
    sidecar = {
        "scene": scene,
        "video": os.path.basename(video) if video else None,
        "still": os.path.basename(still) if still else None,
        "still_frame": still_frame if still else None,
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
    with open((video or still) + ".json", "w") as f:
        json.dump(sidecar, f, indent=2)
    viewer.close()
    return sidecar


def _progress_for(example, args, scene: str, total: int | None):
    """The progress line of a run of ``example`` (silent with ``--quiet``)."""
    from newton.examples.fluid.progress import FluidProgress  # noqa: PLC0415

    return FluidProgress(
        total,
        scene,
        solver=example.solver,
        state=lambda: example.state_0,
        particles=int(example.model.particle_count),
        quiet=bool(getattr(args, "quiet", False)),
    )


def choose_particle_count(example_class, args) -> None:
    """Set ``args.particle_count`` where it was not given: the example's GPU default, or its CPU default on a CPU.

    On a CPU the GPU's default would run at seconds per frame; one printed line says which count was
    chosen and how to set another (unless ``--quiet``).
    """
    if getattr(args, "particle_count", 0) is not None:
        return
    import warp as wp  # noqa: PLC0415

    device = wp.get_device(args.device)
    gpu, cpu = example_class.default_particle_count, example_class.cpu_particle_count
    args.particle_count = cpu if device.is_cpu else gpu
    if device.is_cpu and not getattr(args, "quiet", False):
        print(
            f"running on the CPU: {cpu:,} particles by default ({gpu:,} on a GPU); --particle-count sets any count",
            flush=True,
        )


def _bounded(viewer, args) -> bool:
    """Whether the run ends by itself (every viewer but an interactive window): then it shows a progress line."""
    import newton.viewer  # noqa: PLC0415

    return not (isinstance(viewer, newton.viewer.ViewerGL) and not getattr(args, "headless", False) and not args.test)


def main(example_class, scene: str) -> None:
    """Entry point of an example module: capture with ``--capture`` or ``--capture-still``, else run as Newton runs examples.

    Runs that end by themselves (``--viewer null``, ``usd``, headless) show a progress line and end
    with a one-line summary; ``--quiet`` silences both (and Warp's compilation messages).
    """
    import newton.examples  # noqa: PLC0415

    parser = example_class.create_parser()
    args = parser.parse_args()
    if args.still_frame is not None and not args.capture_still:
        raise ValueError(f"still_frame={args.still_frame!r} is invalid without --capture-still: name the PNG to write")
    if args.capture or args.capture_still:
        choose_particle_count(example_class, args)
        capture(example_class, args, scene)
        return
    viewer, args = newton.examples.init(parser)
    choose_particle_count(example_class, args)
    example = example_class(viewer, args)
    if not _bounded(viewer, args):
        newton.examples.run(example, args)
        return
    progress = _progress_for(example, args, scene, getattr(viewer, "num_frames", None))
    step = example.step

    def counted_step():
        step()
        progress.update()

    # counts the frames of every example, whichever step() it overrides
    example.step = counted_step
    try:
        newton.examples.run(example, args)
    finally:
        progress.close()
