# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Throughput of batched fluid worlds: batch frames per second and environment steps per second.

For each scene (``pouring``: the task of ``fluid_xpbd_pouring``, one frame = one environment step,
resets and measurements included; ``multiworld``: the dam breaks of ``fluid_xpbd_multiworld``), world
count and particles per world: build the example, run ``--warmup`` frames (the first ones compile and
capture the frame's graph), then time ``--frames`` frames (graph replays on CUDA) and report batch
frames/s, environment steps/s (worlds x frames/s) and the fluid's mean density error at the end.
``--breakdown`` also lists the GPU time of each kernel over one frame run without a graph (where
the time goes at many worlds: the collision pipeline, the solver, the task's own work).

Usage::

    python -m benchmarks batched_worlds [--scene pouring multiworld] [--worlds 1 16 256 1024 4096]
        [--per-world 1000 4000] [--frames 60] [--json out.json] [--plot out.png] [--breakdown]
"""

from __future__ import annotations

import argparse
import json
import time

import newton.viewer
import numpy as np
import warp as wp

import newton
from newton.examples.fluid.progress import track

from . import dam_break
from .run_record import write_record


def build(scene: str, worlds: int, per_world: int, collide_every: int):
    if scene == "pouring":
        from newton.examples.fluid.example_fluid_xpbd_pouring import Example  # noqa: PLC0415

        extra = {"policy": "scripted"}
        count = per_world
    else:
        from newton.examples.fluid.example_fluid_xpbd_multiworld import Example  # noqa: PLC0415

        extra = {}
        count = per_world * worlds
    args = argparse.Namespace(world_count=worlds, particle_count=count, collide_every=collide_every, **extra)
    return Example(newton.viewer.ViewerNull(num_frames=10**9), args)


def timed(fn, repeats: int) -> float:
    wp.synchronize()
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    wp.synchronize()
    return (time.perf_counter() - start) / repeats


def kernel_breakdown(example) -> list:
    """GPU time [ms] per kernel name over one frame run without a graph (after one such frame), largest first."""
    example.simulate()
    return dam_break.kernel_breakdown(example.simulate, wp.get_device())


def lone_memset_ms(count: int, repeats: int = 100) -> float:
    """Wall time [ms] of one clear of a particle-sized ``vec3`` array (as the solver clears its particle
    deltas every pass), alone on the device: beside the memset records of a frame, which overlap the kernel
    ahead of them."""
    deltas = wp.zeros(count, dtype=wp.vec3)
    return 1e3 * timed(deltas.zero_, repeats)


def soft_contact_split(example) -> dict:
    """GPU time [ms] of upstream's particle-shape contact generation over one frame without a graph: as
    built, with the worlds' meshes not colliding with particles, and with no shape of a world colliding
    (the pairs still enumerated, the ground plane still met).

    The two frames with shapes switched off let fluid through them; the model's shape flags are
    restored afterwards, so run it after everything that is measured of the example.
    """
    model = example.model
    flags = model.shape_flags.numpy()
    kind = model.shape_type.numpy()
    world = model.shape_world.numpy()
    off = int(newton.ShapeFlags.COLLIDE_PARTICLES)
    meshes = (kind == int(newton.GeoType.MESH)) | (kind == int(newton.GeoType.CONVEX_MESH))
    split = {}
    for name, switched in (("as built", None), ("without meshes", meshes), ("without world shapes", world >= 0)):
        f = flags.copy()
        if switched is not None:
            f[switched] &= ~off
        model.shape_flags.assign(f)
        # (the example's kernels are loaded: no frame ahead of the timed one)
        kernels = dam_break.kernel_breakdown(example.simulate, wp.get_device())
        split[name] = sum(ms for kernel, ms, _ in kernels if "create_soft_contacts" in kernel)
    model.shape_flags.assign(flags)
    return split


def run(args) -> list[dict]:
    rows = []
    configs = [
        (s, w, p, k) for s in args.scene for p in args.per_world for w in args.worlds for k in args.collide_every
    ]
    for scene, worlds, per_world, collide_every in track(configs, "batched_worlds", quiet=args.quiet):
        if worlds * per_world > args.max_particles:
            continue
        ex = build(scene, worlds, per_world, collide_every)
        for _ in range(args.warmup):
            ex.step()
        seconds = timed(ex.step, args.frames)
        stats = ex.solver.fluid_diagnostics(ex.state_0)
        row = {
            "scene": scene,
            "worlds": worlds,
            "particles_per_world": ex.model.particle_count / worlds,
            "particles": ex.model.particle_count,
            "substeps": ex.sim_substeps,
            "iterations": ex.solver.iterations,
            "collide_every": collide_every,
            "frames": args.frames,
            "graph": ex.graph is not None,
            "ms_per_frame": 1e3 * seconds,
            "batch_frames_per_s": 1.0 / seconds,
            "env_steps_per_s": worlds / seconds,
            "mean_abs_density_error": stats["mean_abs_density_error"],
            "mean_compression": stats["mean_compression"],
            "max_compression": stats["max_compression"],
            "compressed_particle_substeps": stats["compressed_particle_substeps"],
            "peak_compression": stats["peak_compression"],
            "neighbors_max": stats["neighbors_max"],
            "neighbor_overflow": stats["neighbor_overflow"],
        }
        if scene == "pouring" and args.task_frames > 0:
            # the scripted pour's outcome: worlds whose first episode succeeded, none failed
            for _ in range(max(0, args.task_frames - args.warmup - args.frames)):
                ex.step()
            succeeded, failed = ex.episodes.numpy().T
            row["task_frames"] = args.task_frames
            row["worlds_poured"] = float(np.mean((succeeded >= 1) & (failed == 0)))
        if args.breakdown and wp.get_device().is_cuda:
            row["kernels"] = kernel_breakdown(ex)
            row["lone_memset_ms"] = lone_memset_ms(ex.model.particle_count)
            row["soft_contacts_ms"] = soft_contact_split(ex)
        rows.append(row)
        del ex
    return rows


def report(rows: list[dict], args) -> None:
    """Print the table (and, for rows with a breakdown, the largest kernels)."""
    header = f"{'scene':<11}{'worlds':>7}{'per world':>10}{'ms/frame':>10}{'frames/s':>10}{'env-steps/s':>13}{'density err':>12}"
    print(f"{rows[0]['substeps']} substeps x {rows[0]['iterations']} iterations")
    print(header)
    for r in rows:
        print(
            f"{r['scene']:<11}{r['worlds']:>7}{r['particles_per_world']:>10.0f}{r['ms_per_frame']:>10.2f}"
            f"{r['batch_frames_per_s']:>10.1f}{r['env_steps_per_s']:>13,.0f}{100 * r['mean_abs_density_error']:>11.2f}%"
            f"   {r['compressed_particle_substeps']:,} particle substeps past 10 % (peak "
            f"{100 * r['peak_compression']:.0f} %), neighbours max {r['neighbors_max']}, collide every "
            f"{r['collide_every']}"
            + (f", {100 * r['worlds_poured']:.0f} % of worlds poured" if "worlds_poured" in r else "")
        )
        if "kernels" in r:
            # memset records start before the kernel ahead of them ends (their sum exceeds what the graph's
            # frame leaves to them; a lone clear of the particle deltas is timed beside them): not summed
            kernels = [k for k in r["kernels"] if k[0] != "memset"]
            memsets = sum(k[1] for k in r["kernels"] if k[0] == "memset")
            total = sum(k[1] for k in kernels)
            print(
                f"    {total:.2f} ms of kernels in a frame without a graph (memset records {memsets:.2f} ms, "
                f"overlapping them; one particle-sized clear alone {r['lone_memset_ms']:.3f} ms); the largest:"
            )
            for name, ms, count in kernels[: args.top]:
                print(f"    {ms:8.3f} ms {count:5d} x {name}")
        if "soft_contacts_ms" in r:
            split = ", ".join(f"{name} {ms:.2f}" for name, ms in r["soft_contacts_ms"].items())
            print(f"    upstream's particle-shape contact generation [ms]: {split}")


def plot(rows: list[dict], path: str) -> None:
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, ax = plt.subplots(figsize=(7, 4.5))

    def curve(r):
        # (to the thousand: a world's count depends on its scene's lattice, 3,780 for one dam break of
        # ~4,000 and 4,060 for many)
        return (r["scene"], round(r["particles_per_world"], -3), r.get("collide_every", 1))

    for key in sorted({curve(r) for r in rows}):
        sel = [r for r in rows if curve(r) == key]
        label = f"{key[0]}, ~{key[1]:.0f} per world" + (f", collide every {key[2]}" if key[2] > 1 else "")
        ax.plot([r["worlds"] for r in sel], [r["env_steps_per_s"] for r in sel], "o-", label=label)
    ax.axhline(1.0e5, color="gray", ls="--", lw=0.8, label="100k env-steps/s")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("worlds")
    ax.set_ylabel("environment steps per second")
    ax.set_title(f"{rows[0]['substeps']} substeps x {rows[0]['iterations']} iterations, 60 Hz")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", nargs="+", choices=("pouring", "multiworld"), default=["pouring"])
    parser.add_argument("--worlds", type=int, nargs="+", default=[1, 16, 256, 1024, 4096])
    parser.add_argument("--per-world", type=int, nargs="+", default=[1000, 4000], help="Particles per world.")
    parser.add_argument("--warmup", type=int, default=10, help="Frames before timing.")
    parser.add_argument("--frames", type=int, default=60, help="Frames timed.")
    parser.add_argument(
        "--collide-every", type=int, nargs="+", default=[1], help="Substeps between collision runs (each value a run)."
    )
    parser.add_argument(
        "--task-frames",
        type=int,
        default=0,
        help="Pouring: run this many frames in all, then report the share of worlds whose scripted pour succeeded.",
    )
    parser.add_argument("--max-particles", type=int, default=20_000_000, help="Skip larger configurations.")
    parser.add_argument(
        "--breakdown",
        action="store_true",
        help="Also the GPU time of each kernel over a frame run without a graph (CUDA).",
    )
    parser.add_argument("--top", type=int, default=8, help="Kernels listed per configuration with --breakdown.")
    parser.add_argument("--json", type=str, default=None)
    parser.add_argument("--plot", type=str, default=None, help="PNG of env-steps/s against worlds.")
    parser.add_argument(
        "--from-json", type=str, nargs="+", default=None, help="Print and plot these results instead of running."
    )
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args(argv)
    if args.from_json:
        records = [json.load(open(path)) for path in args.from_json]
        rows = [r for record in records for r in record["rows"]]
        print(f"device {records[0]['device']}, {records[0]['date']}")
        report(rows, args)
        if args.plot:
            plot(rows, args.plot)
        return
    device = wp.get_device()
    rows = run(args)
    print(f"device {device.name if device.is_cuda else 'cpu'}")
    report(rows, args)
    write_record("batched_worlds", device, {}, args.json, rows=rows)
    if args.plot:
        plot(rows, args.plot)


if __name__ == "__main__":
    main()
