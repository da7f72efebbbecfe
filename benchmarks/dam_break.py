# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Dam-break benchmark: milliseconds per frame beside an independently measured density error.

Scene: the tank of ``fluid_xpbd_dam_break`` without obstacles (inner half-length 1.2 m, width =
column width, 1.6 m walls, ground) and a 34 x 49 x 60 column (99,960 particles at 0.0201439 m)
against the -x wall; ``--particles`` rescales the spacing. 60 Hz, 8 substeps, 2 iterations,
cohesion 1.0, viscosity 0.05, vorticity 0, speed clamp 0.5 radius per substep.

The density error is measured outside the solver: a poly6 kernel sum over all particles within
h (SciPy cKDTree), divided by the rest density of a cubic lattice at the spacing.

Usage::

    python -m benchmarks dam_break [--particles N] [--device cuda:0] [--json out.json] [--kernel-timing]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time

import numpy as np
import warp as wp

import newton
from newton._src.solvers.xpbd.fluid.calibration import wall_density_tables
from newton._src.solvers.xpbd.fluid.config import FluidTuning
from newton.examples.fluid.example_fluid_xpbd_dam_break import TANK_HALF_LENGTH, add_dam_break
from newton.examples.fluid.progress import track

from .frames import add_solver_arguments, solver_keywords
from .run_record import write_record


def poly6(r2: np.ndarray, h: float) -> np.ndarray:
    return 315.0 / (64.0 * math.pi * h**9) * np.maximum(h * h - r2, 0.0) ** 3


def quarter_density_table(spacing: float, h: float, mass: float, size: int = 33):
    """Density of the ghost lattice behind both of two perpendicular walls, on a grid of the two distances.

    The sum over the lattice points behind both planes (layers half a spacing behind each, as in
    the plane table), for distances on ``[0, spacing]`` from each, tapered in each distance like the
    plane table (so it is what the two plane tables both counted). Returns (distances, table).
    """
    d = spacing
    n = int(math.ceil(h / d))
    b = np.arange(-n, n + 1) * d
    deltas = np.linspace(0.0, d, size)
    x = deltas[:, None] + 0.5 * d + np.arange(n + 1)[None, :] * d
    r2 = x[:, None, :, None, None] ** 2 + x[None, :, None, :, None] ** 2 + b[None, None, None, None, :] ** 2
    rho = mass * poly6(r2, h).sum(axis=(2, 3, 4))
    t = np.clip((deltas - 0.75 * d) / (0.25 * d), 0.0, 1.0)
    window = 1.0 - t * t * (3.0 - 2.0 * t)
    return deltas, rho * window[:, None] * window[None, :]


def poly6_density(q: np.ndarray, mass: float, spacing: float, h: float) -> tuple[np.ndarray, float]:
    """Each particle's poly6 density over all particles (its own included, no walls) [kg/m^3], and the
    rest lattice's at ``spacing`` (the reference both estimators are read against)."""
    from scipy.spatial import cKDTree  # noqa: PLC0415

    n = int(math.ceil(h / spacing))
    r = np.arange(-n, n + 1) * spacing
    lattice = np.stack(np.meshgrid(r, r, r, indexing="ij"), -1).reshape(-1, 3)
    rho0 = mass * poly6(np.einsum("ij,ij->i", lattice, lattice), h).sum()
    tree = cKDTree(q)
    pairs = tree.query_pairs(h, output_type="ndarray")
    d = q[pairs[:, 0]] - q[pairs[:, 1]]
    w = poly6(np.einsum("ij,ij->i", d, d), h) * mass
    rho = np.full(len(q), mass * poly6(np.zeros(1), h)[0])
    np.add.at(rho, pairs[:, 0], w)
    np.add.at(rho, pairs[:, 1], w)
    return rho, rho0


def measure_density_error(q: np.ndarray, mass: float, spacing: float, h: float, walls=()) -> dict:
    """Poly6 density of every particle relative to the rest-lattice density, independent of the solver.

    ``walls`` are planes ``(normal, offset)`` (fluid side ``dot(normal, x) > offset``). The
    ``*_walls`` results add the density of the lattice the fluid would continue as behind each
    plane (the tabulated ghost-lattice sum the solver also uses), less, for each pair of
    perpendicular planes, that of the lattice behind both (counted by both; an exact sum here,
    where the solver uses a product of the two distances' factors); the others are the fluid's own sum.
    """
    from scipy.interpolate import RegularGridInterpolator  # noqa: PLC0415

    rho, rho0 = poly6_density(q, mass, spacing, h)
    rho_walls = rho.copy()
    table, _ = wall_density_tables(spacing, h, mass)
    samples = np.linspace(0.0, h, len(table))
    deltas = []
    for normal, offset in walls:
        delta = np.maximum(q @ np.asarray(normal, dtype=np.float64) - offset, 0.0)
        deltas.append(delta)
        near = delta < h
        rho_walls[near] += np.interp(delta[near], samples, table)
    grid, quarter = quarter_density_table(spacing, h, mass)
    behind_both = RegularGridInterpolator((grid, grid), quarter)
    for a in range(len(walls)):
        for b in range(a + 1, len(walls)):
            if abs(np.dot(walls[a][0], walls[b][0])) > 0.05:
                continue
            near = (deltas[a] < spacing) & (deltas[b] < spacing)
            rho_walls[near] -= behind_both(np.stack([deltas[a][near], deltas[b][near]], axis=1))
    result = {}
    for suffix, values in (("", rho), ("_walls", rho_walls)):
        e = values / rho0 - 1.0
        c = np.maximum(e, 0.0)
        result[f"mean_abs_density_error{suffix}"] = float(np.abs(e).mean())
        result[f"mean_compression{suffix}"] = float(c.mean())
        result[f"p99_compression{suffix}"] = float(np.percentile(c, 99))
        result[f"max_compression{suffix}"] = float(c.max())
    return result


def kernel_breakdown(simulate, device) -> list:
    """GPU time per kernel name over one un-captured frame (CUDA only; activity records: the times
    exclude the gaps between launches)."""
    wp.synchronize_device(device)
    wp.timing_begin(cuda_filter=wp.TIMING_KERNEL | wp.TIMING_KERNEL_BUILTIN | wp.TIMING_MEMSET | wp.TIMING_MEMCPY)
    simulate()
    results = wp.timing_end()
    total = {}
    for r in results:
        key = r.name.split("(")[0]
        t, c = total.get(key, (0.0, 0))
        total[key] = (t + r.elapsed, c + 1)
    return sorted(([k, t, c] for k, (t, c) in total.items()), key=lambda x: -x[1])


def graph_ms(device, body, replays: int = 30) -> float:
    """Median ms of one replay of a CUDA graph captured from ``body`` (after one un-captured call)."""
    body()
    with wp.ScopedCapture(device=device) as capture:
        body()
    times = []
    for _ in range(replays):
        wp.synchronize_device(device)
        t0 = time.perf_counter()
        wp.capture_launch(capture.graph)
        wp.synchronize_device(device)
        times.append((time.perf_counter() - t0) * 1000.0)
    return statistics.median(times)


def run(args) -> dict:
    device = wp.get_device(args.device)
    builder = newton.ModelBuilder()
    scene = add_dam_break(builder, args.particles, obstacles=False, jitter=0.1, terrain_bump=args.terrain_bump)
    model = builder.finalize(device=device)
    spacing = scene["spacing"]
    frame_dt = 1.0 / 60.0
    dt = frame_dt / args.substeps
    model.soft_contact_mu = 0.0
    model.particle_max_velocity = args.speed_clamp * 0.5 * spacing / dt if args.speed_clamp > 0 else 1.0e5
    solver = newton.solvers.SolverXPBD(
        model,
        **solver_keywords(args, spacing),
        _fluid_tuning=FluidTuning(concurrent_passes=not args.single_stream, scan_lanes=args.scan_lanes),
    )
    # contacts reach one diameter from the surface, where the walls' ghost density has vanished
    collision = newton.CollisionPipeline(model, soft_contact_max=model.particle_count, soft_contact_gap=0.5 * spacing)
    hw = scene["half_width"]
    walls = [
        ((0.0, 0.0, 1.0), 0.0),
        ((1.0, 0.0, 0.0), -TANK_HALF_LENGTH),
        ((-1.0, 0.0, 0.0), -TANK_HALF_LENGTH),
        ((0.0, 1.0, 0.0), -hw),
        ((0.0, -1.0, 0.0), -hw),
    ]
    contacts = collision.contacts()
    states = [model.state(), model.state()]

    def simulate():
        for _ in range(args.substeps):
            states[0].clear_forces()
            collision.collide(states[0], contacts)
            solver.step(states[0], states[1], None, contacts, dt)
            states[0], states[1] = states[1], states[0]

    with wp.ScopedDevice(device):
        simulate()  # compile everything, then run the warm-up frames
        graph = None
        if device.is_cuda:
            with wp.ScopedCapture() as capture:
                simulate()
            graph = capture.graph
        frame = (lambda: wp.capture_launch(graph)) if graph else simulate
        for _ in range(args.warmup_frames):
            frame()
        breakdown = kernel_breakdown(simulate, device) if args.kernel_timing and device.is_cuda else []

        trials, errors = [], []
        # (the progress line counts trials: nothing of it runs inside a timed trial)
        for _ in track(range(args.trials), "dam_break", unit="trial"):
            wp.synchronize_device(device)
            t0 = time.perf_counter()
            for _ in range(args.frames):
                frame()
            wp.synchronize_device(device)
            trials.append((time.perf_counter() - t0) * 1000.0 / args.frames)
            q = states[0].particle_q.numpy().astype(np.float64)
            errors.append(measure_density_error(q, 1000.0 * spacing**3, spacing, solver.fluid_smoothing_length, walls))

        render_ms = None
        if graph is not None:
            # cost of the render particles (smoothed centres and ellipsoids), captured and replayed
            solver.update_render_particles(states[0])
            with wp.ScopedCapture() as capture:
                solver.update_render_particles(states[0])
            wp.synchronize_device(device)
            t0 = time.perf_counter()
            for _ in range(50):
                wp.capture_launch(capture.graph)
            wp.synchronize_device(device)
            render_ms = (time.perf_counter() - t0) * 1000.0 / 50

    # the first frame, the warm-up, the kernel timer's frame and the trials (a graph capture records a
    # frame without simulating it)
    stats = solver.fluid_diagnostics(states[0])
    frames_simulated = 1 + args.warmup_frames + (1 if breakdown else 0) + args.trials * args.frames
    density = {k: float(np.mean([e[k] for e in errors])) for k in errors[0]}
    for key in ("max_compression", "max_compression_walls"):
        density[key] = float(max(e[key] for e in errors))
    return {
        "particles": int(model.particle_count),
        "spacing_m": spacing,
        "substeps": args.substeps,
        "iterations": args.iterations,
        "cohesion": solver.fluid_cohesion,
        "relaxation": solver.fluid_relaxation,
        "nonaffine_damping": solver.fluid_nonaffine_damping,
        "fluid_warm_start": solver.fluid_warm_start,
        "fluid_density_ramp": solver.fluid_density_ramp,
        "fluid_max_iterations": solver.fluid_max_iterations,
        "fluid_density_tolerance": solver.fluid_density_tolerance,
        "density_subiterations_per_substep": stats["density_subiterations"] / max(1, frames_simulated * args.substeps),
        "viscosity": solver.fluid_viscosity,
        "max_diffuse_particles": solver.max_diffuse_particles,
        "diffuse_emitted": int(solver.diffuse_emitted_count.numpy()[0]) if solver.max_diffuse_particles else 0,
        "speed_clamp_radii_per_substep": args.speed_clamp,
        "fluid_continuous_collision": solver.fluid_continuous_collision,
        "fluid_coarse_correction": solver.fluid_coarse_correction,
        "fluid_coarse_cell": solver.fluid_coarse_cell,
        "fluid_density_kernel": solver.fluid_density_kernel,
        "terrain_bump_spacings": args.terrain_bump,
        "shape_entries_stopped": stats["shape_entries_stopped"],
        "cuda_graph": graph is not None,
        "scan_lanes": args.scan_lanes or "solver's choice",
        "concurrent_passes": not args.single_stream and device.is_cuda,
        "sim_time_s": frames_simulated * frame_dt,
        "ms_per_frame_median": statistics.median(trials),
        "ms_per_frame_trials": trials,
        **density,
        "update_render_particles_ms": render_ms,
        "kernel_ms_per_frame": breakdown,
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=int, default=99_960)
    add_solver_arguments(parser, defaults={"fluid_cohesion": 1.0, "fluid_viscosity": 0.05})
    parser.add_argument("--speed-clamp", type=float, default=0.5, help="max displacement per substep [radii]; 0: off")
    parser.add_argument(
        "--scan-lanes", type=int, default=0, help="threads per particle of the neighbour scan (0: the solver's choice)"
    )
    parser.add_argument(
        "--single-stream",
        action="store_true",
        help="run every fluid pass on the step's stream (default on CUDA: the sort, scan and next density pass "
        "on a second stream beside upstream's work)",
    )
    parser.add_argument(
        "--terrain-bump",
        type=float,
        default=0.0,
        help="a heightfield floor (cells of two spacings, random heights up to this many spacings) for the ground plane",
    )
    parser.add_argument("--warmup-frames", type=int, default=60)
    parser.add_argument("--frames", type=int, default=30, help="frames per timed trial")
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument("--kernel-timing", action="store_true", help="per-kernel GPU time of one frame (CUDA)")
    args = parser.parse_args(argv)
    wp.config.quiet = True
    r = write_record("dam_break", wp.get_device(args.device), run(args), args.json)
    cols = ("mean_abs_density_error", "mean_compression", "max_compression")
    print(
        f"{'device':<24}{'particles':>10}{'substeps':>9}{'iters':>6}{'ms/frame':>10}"
        f"{'mean|e|':>9}{'mean c':>8}{'max c':>8}  | with walls:{'mean|e|':>9}{'mean c':>8}{'max c':>8}"
    )
    fluid = "".join(f"{100 * r[k]:>{9 if k == cols[0] else 8}.2f}"[1:] + "%" for k in cols)
    walls = "".join(f"{100 * r[k + '_walls']:>{9 if k == cols[0] else 8}.2f}"[1:] + "%" for k in cols)
    print(
        f"{r['device']:<24}{r['particles']:>10}{r['substeps']:>9}{r['iterations']:>6}"
        f"{r['ms_per_frame_median']:>10.3f}{fluid}{'':>14}{walls}"
    )
    if r["fluid_continuous_collision"]:
        print(f"continuous collision: {r['shape_entries_stopped']} particle substeps stopped at a wall")
    if r["update_render_particles_ms"] is not None:
        print(f"update_render_particles: {r['update_render_particles_ms']:.3f} ms (graph replay)")
    if r["kernel_ms_per_frame"]:
        busy = sum(t for _, t, _ in r["kernel_ms_per_frame"])
        print(f"per-kernel GPU time of one frame [ms] (launches); sum {busy:.3f} ms, the rest is gaps between them:")
        for name, t, c in r["kernel_ms_per_frame"][:25]:
            print(f"  {t:8.3f}  ({c:4d})  {name}")
    return r


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
