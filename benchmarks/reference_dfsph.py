# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The 2:1 dam break in our XPBD fluid and in SPlisHSPlasH's DFSPH, measured the same way.

Both run the column of Koshizuka & Oka (1996) (width L = 0.146 m, height 2L, ``--depth`` layers
deep, ``--per-l`` particles across L; 20 x 16 layers = 12,800 particles) in a frictionless tank
5L long. Recorded for each, at the same simulated times: the surge front (as in
``validate_dam_break.py``) at the experiment's data points, the energy (kinetic + potential over
the initial potential) and the density error of the independent poly6 estimator of
``dam_break.py`` (ghost-lattice walls at the fluid's boundary, kernel support 1.8 spacings). Prints a
table and writes JSON (``--json``) and, with ``--plot``, a figure.

SPlisHSPlasH (``pip install pysplishsplash``, CPU, OpenMP) runs DFSPH with its volume-map walls
(Bender et al. 2019), adaptive CFL time step, its dam-break defaults (density error 0.05 %,
divergence error 0.1 %, standard viscosity 0.01). Its fluid rests about one spacing from the wall
geometry and particles closer than about 1.5 spacings are shot away at the start, so its walls are
placed one spacing behind the column's faces (centres 1.5 spacings from them). For the density and
energy its boundary planes are half a spacing behind the column's faces (where its resting centres
are half a spacing inside them, as ours are inside ours); the front is measured from the column's
back face for both.
Importing it needs ``LD_PRELOAD=/lib/x86_64-linux-gnu/libGLdispatch.so.0``, which this script sets
by re-executing itself.

Usage::

    python -m benchmarks reference_dfsph [--per-l 20] [--depth 16] [--t-end 1.5] [--json out.json] [--plot out.png]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .frames import add_solver_arguments, solver_keywords, solver_record
from .run_record import write_record

GL_DISPATCH = "/lib/x86_64-linux-gnu/libGLdispatch.so.0"
G = 9.81


def sample_times(t_end: float, points: np.ndarray, L: float) -> np.ndarray:
    """Every 1/60 s up to ``t_end`` and the experiment's data points, sorted [s]."""
    frames = np.arange(1, int(round(t_end * 60.0)) + 1) / 60.0
    return np.unique(np.concatenate([frames, points[:, 0] * math.sqrt(L / (2.0 * G))]))


class Recorder:
    """Front, energy and density of one run at the sample times (positions from the column's corner)."""

    def __init__(self, L: float, d: float, mass: float, h: float, width: float, wall_shift: float = 0.0):
        from . import dam_break, validate_dam_break  # noqa: PLC0415

        self.bench = dam_break
        self.validate = validate_dam_break
        self.L, self.d, self.mass, self.h = L, d, mass, h
        # the fluid's boundary, ``wall_shift`` [m] beyond the column's faces (and the tank's far end):
        # resting particle centres are half a spacing inside these planes
        self.shift = wall_shift
        length, width = 5.0 * L + 2.0 * wall_shift, width + 2.0 * wall_shift
        self.walls = [
            ((0.0, 0.0, 1.0), 0.0),
            ((1.0, 0.0, 0.0), 0.0),
            ((-1.0, 0.0, 0.0), -length),
            ((0.0, 1.0, 0.0), 0.0),
            ((0.0, -1.0, 0.0), -width),
        ]
        self.rows = []
        self.potential0 = None

    def record(self, t: float, q: np.ndarray, v: np.ndarray):
        front = self.validate.surge_front(q.astype(np.float64), self.d)
        q = q.astype(np.float64) + self.shift
        v = v.astype(np.float64)
        potential = self.mass * G * q[:, 2].sum()
        kinetic = 0.5 * self.mass * float(np.einsum("ij,ij->", v, v))
        if self.potential0 is None:
            self.potential0 = potential
        density = self.bench.measure_density_error(q, self.mass, self.d, self.h, self.walls)
        self.rows.append(
            {
                "t": float(t),
                "T": float(t / math.sqrt(self.L / (2.0 * G))),
                "front_over_L": front / self.L,
                "energy": (kinetic + potential) / self.potential0,
                "kinetic": kinetic / self.potential0,
                "mean_abs_density_error": density["mean_abs_density_error_walls"],
                "mean_compression": density["mean_compression_walls"],
                "p99_compression": density["p99_compression_walls"],
                "max_compression": density["max_compression_walls"],
                "min_wall_distance": float(min(q[:, 0].min(), q[:, 1].min(), q[:, 2].min())) / self.d,
                # particles beyond a wall of the tank: fluid thrown over the walls or let through them
                "outside_tank": int(
                    np.any([q @ np.asarray(n, dtype=np.float64) < o for n, o in self.walls], axis=0).sum()
                ),
            }
        )


def run_xpbd(args, L: float, times: np.ndarray) -> dict:
    import warp as wp  # noqa: PLC0415

    from newton.examples.fluid.progress import track  # noqa: PLC0415

    from . import validate_dam_break as validate  # noqa: PLC0415

    wp.config.quiet = True
    device = wp.get_device(args.device)
    d = L / args.per_l
    gap = args.xpbd_wall_gap * d
    model, solver, pipeline, dt = validate.build_plain(
        args.per_l, args.depth, args.substeps, device, wall_gap=gap, **solver_keywords(args, d)
    )
    # with a gap the fluid's boundary planes are the walls, as for DFSPH (resting centres half a spacing inside)
    rec = Recorder(L, d, 1000.0 * d**3, solver.fluid_smoothing_length, args.depth * d, wall_shift=gap)
    stepper = validate.Stepper(model, solver, pipeline, dt)
    rec.record(0.0, stepper.state.particle_q.numpy(), stepper.state.particle_qd.numpy())
    wall = 0.0
    for target in track(times, "reference_dfsph: XPBD", unit="sample"):
        t0 = time.perf_counter()
        state = stepper.advance_to(target)
        wp.synchronize_device(device)
        wall += time.perf_counter() - t0
        rec.record(stepper.time, state.particle_q.numpy(), state.particle_qd.numpy())
    return {
        "solver": "newton-fluid XPBD",
        "device": device.name if device.is_cuda else "cpu",
        "particles": int(model.particle_count),
        "substeps": args.substeps,
        **solver_record(solver),
        "wall_gap_spacings": args.xpbd_wall_gap,
        "steps": stepper.steps,
        "wall_s": wall,
        "ms_per_frame": 1000.0 * wall / (stepper.time * 60.0),
        "samples": rec.rows,
    }


def wall_box_scene(
    d: float,
    lo,
    hi,
    block_lo,
    block_hi,
    t_end: float,
    workdir: Path,
    configuration: dict,
    material: dict,
    map_cells: float = 1.0,
) -> dict:
    """A SPlisHSPlasH scene: a closed box of volume-map walls from ``lo`` to ``hi`` and a fluid block [m].

    Args:
        d: The particle spacing [m].
        lo: The box's lower corner [m].
        hi: The box's upper corner [m].
        block_lo: The fluid lattice's first particle centre [m] (its regular sampling steps by ``d``).
        block_hi: The fluid lattice's last particle centre [m].
        t_end: Simulated time [s].
        workdir: Where the box's mesh is written (and SPlisHSPlasH caches its volume map).
        configuration: The solver's settings (SPlisHSPlasH's ``Configuration`` keys besides the common ones).
        material: The fluid's settings besides its density (viscosity method and coefficient).
        map_cells: The walls' volume-map cells per spacing.
    """
    box = workdir / "box.obj"
    corners = [(x, y, z) for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)]
    faces = [(1, 3, 4, 2), (5, 6, 8, 7), (1, 2, 6, 5), (3, 7, 8, 4), (1, 5, 7, 3), (2, 4, 8, 6)]
    lines = [f"v {x} {y} {z}" for x, y, z in corners]
    lines += [f"f {a} {b} {c}\nf {a} {c} {e}" for a, b, c, e in faces]
    box.write_text("\n".join(lines) + "\n")
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    res = np.maximum(8, np.round(map_cells * (hi - lo) / d).astype(int))
    return {
        "Configuration": {
            "particleRadius": 0.5 * d,
            "gravitation": [0.0, 0.0, -G],
            "stopAt": float(t_end) + 1.0e-4,
            "boundaryHandlingMethod": 2,
            **configuration,
        },
        "Materials": [{"id": "Fluid", "density0": 1000, **material}],
        "RigidBodies": [
            {
                "geometryFile": str(box),
                "translation": (0.5 * (lo + hi)).tolist(),
                "scale": (hi - lo).tolist(),
                "isDynamic": False,
                "isWall": True,
                "mapInvert": True,
                "mapThickness": 0.0,
                "mapResolution": res.tolist(),
            }
        ],
        # its regular sampling puts floor((end - start) / d) - 1 particles at start + d, start + 2d, ...
        # (the 0.2 d keeps the last one away from rounding)
        "FluidBlocks": [
            {
                "denseMode": 0,
                "start": (np.asarray(block_lo) - d).tolist(),
                "end": (np.asarray(block_hi) + 1.2 * d).tolist(),
            }
        ],
    }


#: DFSPH as in SPlisHSPlasH's dam-break scene: adaptive CFL step and the error bounds of its ``DFSPH`` group
DFSPH_CONFIGURATION = {
    "simulationMethod": 4,
    "timeStepSize": 0.001,
    "cflMethod": 1,
    "cflFactor": 1.0,
    "cflMaxTimeStepSize": 0.005,
    "DFSPH": {
        "minIterations": 2,
        "maxIterations": 100,
        "maxError": 0.05,
        "maxIterationsV": 100,
        "maxErrorV": 0.1,
        "enableDivergenceSolver": True,
    },
}


def dfsph_scene(L: float, d: float, depth: int, workdir: Path, t_end: float) -> dict:
    """SPlisHSPlasH scene: the column (0, 0, 0) to (L, depth d, 2L), walls one spacing beyond."""
    width = depth * d
    # our lattice: centres from d/2 to L - d/2
    return wall_box_scene(
        d,
        (-d, -d, -d),
        (5.0 * L + d, width + d, 4.0 * L),
        (0.5 * d,) * 3,
        (L - 0.5 * d, width - 0.5 * d, 2.0 * L - 0.5 * d),
        t_end,
        workdir,
        DFSPH_CONFIGURATION,
        {"viscosityMethod": 1, "Standard viscosity": {"viscosity": 0.01}},
    )


def preload_gl_dispatch(case: str, argv, gl_dispatch: str = GL_DISPATCH) -> None:
    """Re-execute ``python -m benchmarks <case> argv`` with ``gl_dispatch`` preloaded, unless it already is.

    pysplishsplash segfaults on import without it.
    """
    preload = os.environ.get("LD_PRELOAD", "")
    if gl_dispatch not in preload and os.path.exists(gl_dispatch):
        os.environ["LD_PRELOAD"] = (gl_dispatch + " " + preload).strip()
        rest = sys.argv[1:] if argv is None else argv
        os.execv(sys.executable, [sys.executable, "-m", "benchmarks", case, *rest])


def run_dfsph(args, L: float, times: np.ndarray, h: float) -> dict:
    import pysplishsplash as sph  # noqa: PLC0415

    d = L / args.per_l
    # the volume map of the walls (a minute to build) is cached there between runs
    workdir = Path(args.workdir or tempfile.mkdtemp(prefix="dfsph_"))
    workdir.mkdir(parents=True, exist_ok=True)
    scene = workdir / "dam_break.json"
    scene.write_text(json.dumps(dfsph_scene(L, d, args.depth, workdir, float(times[-1])), indent=1))
    base = sph.Exec.SimulatorBase()
    base.init(useGui=False, outputDir=str(workdir / "out"), sceneFile=str(scene))
    base.initSimulation()
    sim = sph.Simulation.getCurrent()
    fluid = sim.getFluidModel(0)
    n = fluid.numActiveParticles()
    expected = args.per_l * args.depth * 2 * args.per_l
    if n != expected:
        raise RuntimeError(f"SPlisHSPlasH sampled {n} particles, not the column's {expected}")
    mass = fluid.getMass(0)
    rec = Recorder(L, d, mass, h, args.depth * d, wall_shift=0.5 * d)

    def state():
        q = np.array([fluid.getPosition(i) for i in range(n)])
        v = np.array([fluid.getVelocity(i) for i in range(n)])
        return q, v

    rec.record(0.0, *state())
    pending = list(times)
    counters = {"steps": 0, "sampling_s": 0.0}
    # (imported after SPlisHSPlasH, like everything that imports Warp: see main)
    from newton.examples.fluid.progress import FluidProgress  # noqa: PLC0415

    progress = FluidProgress(len(pending), "reference_dfsph: DFSPH", unit="sample")

    def on_step():
        counters["steps"] += 1
        t = sph.TimeManager.getCurrent().getTime()
        while pending and t >= pending[0] - 1.0e-9:
            t0 = time.perf_counter()
            rec.record(t, *state())
            counters["sampling_s"] += time.perf_counter() - t0
            pending.pop(0)
            progress.update()

    base.setTimeStepCB(on_step)
    t0 = time.perf_counter()
    base.runSimulation()
    wall = time.perf_counter() - t0 - counters["sampling_s"]
    progress.close()
    base.cleanup()
    sim_t = rec.rows[-1]["t"]
    return {
        "solver": "SPlisHSPlasH DFSPH (pysplishsplash)",
        "device": "cpu",
        "threads": os.cpu_count(),
        "particles": int(n),
        "particle_mass_kg": float(mass),
        # adaptive: DFSPH's steps follow the CFL condition, its solver iterations the error bounds
        "substeps": "adaptive (CFL)",
        "iterations": "adaptive (to maxError)",
        "steps": counters["steps"],
        "mean_dt_s": sim_t / max(1, counters["steps"]),
        "wall_s": wall,
        "ms_per_frame": 1000.0 * wall / (sim_t * 60.0),
        "settings": "DFSPH, maxError 0.05 %, maxErrorV 0.1 %, CFL 1 (dt <= 5 ms), standard viscosity 0.01, "
        "Bender 2019 volume-map walls",
        "samples": rec.rows,
    }


def front_errors(run: dict, points: np.ndarray) -> list:
    by_t = {round(r["T"], 3): r["front_over_L"] for r in run["samples"]}
    out = []
    for t_value, z in points:
        key = min(by_t, key=lambda k: abs(k - t_value))
        out.append((by_t[key] - z) / z)
    return out


def plot(result: dict, path: str):
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    points = np.asarray(result["experiment"]["points"])
    axes[0].plot(points[:, 0], points[:, 1], "ko", label="Koshizuka & Oka 1996")
    # (records written before 2026-11-26 name the rows "runs")
    for run, style in zip(result.get("rows", result.get("runs", [])), ("C0-", "C3--"), strict=False):
        s = run["samples"]
        label = f"{run['solver']} ({run['particles']:,})"
        keep = [r for r in s if r["T"] <= points[-1, 0] * 1.1]
        axes[0].plot([r["T"] for r in keep], [r["front_over_L"] for r in keep], style, label=label)
        axes[1].plot([r["t"] for r in s], [r["energy"] for r in s], style, label=label + " total")
        axes[1].plot([r["t"] for r in s], [r["kinetic"] for r in s], style, alpha=0.5, label="kinetic")
        axes[2].semilogy([r["t"] for r in s[1:]], [r["mean_abs_density_error"] for r in s[1:]], style, label="mean |e|")
        axes[2].semilogy(
            [r["t"] for r in s[1:]], [r["p99_compression"] for r in s[1:]], style, alpha=0.5, label="p99 c"
        )
    axes[0].set(xlabel="T = t sqrt(2g/L)", ylabel="front / L", title="surge front")
    axes[1].set(xlabel="t [s]", ylabel="energy / initial potential", title="energy")
    axes[2].set(xlabel="t [s]", ylabel="density error (poly6 estimator)", title="density")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--per-l", type=int, default=20, help="particles across L")
    parser.add_argument("--depth", type=int, default=16, help="particle layers in y")
    parser.add_argument("--t-end", type=float, default=1.5, help="simulated time [s]")
    parser.add_argument(
        "--xpbd-wall-gap",
        type=float,
        default=0.0,
        help="ours: floor and walls this many spacings beyond the column's faces (0.5: the column drops and "
        "spreads half a spacing at the start, as DFSPH's does against its walls)",
    )
    parser.add_argument("--skip-dfsph", action="store_true")
    parser.add_argument("--skip-xpbd", action="store_true")
    parser.add_argument(
        "--workdir", default=str(Path.home() / ".cache" / "newton-fluid" / "dfsph"), help="scene + volume-map cache"
    )
    parser.add_argument("--plot", default=None)
    # ours: substeps, iterations and every solver keyword, on --device (the CPU unless given)
    add_solver_arguments(parser)
    parser.set_defaults(device="cpu")
    parser.add_argument("--gl-dispatch", default=GL_DISPATCH, help="libGLdispatch to preload for pysplishsplash")
    args = parser.parse_args(argv)
    if not args.skip_dfsph:
        preload_gl_dispatch("reference_dfsph", argv, args.gl_dispatch)

    from . import validate_dam_break as validate  # noqa: PLC0415

    data = json.loads(validate.DATA.read_text())
    points = np.asarray(data["points"], dtype=np.float64)
    L = validate.L
    times = sample_times(args.t_end, points, L)
    runs = [] if args.skip_xpbd else [run_xpbd(args, L, times)]
    h = 1.8 * L / args.per_l
    if not args.skip_dfsph:
        runs.append(run_dfsph(args, L, times, h))
    for run in runs:
        run["front_relative_error"] = front_errors(run, points)
        # the density error over the samples after the start (measured the same way for both solvers)
        run["mean_abs_density_error"] = float(np.mean([r["mean_abs_density_error"] for r in run["samples"][1:]]))
        run["max_compression"] = float(max(r["max_compression"] for r in run["samples"][1:]))
    import warp as wp  # noqa: PLC0415

    result = {
        "L_m": L,
        "per_L": args.per_l,
        "depth_layers": args.depth,
        "t_end_s": args.t_end,
        "experiment": {"source": data["source"], "points": points.tolist()},
    }
    print(
        f"{'solver':<38}{'particles':>10}{'ms/frame':>10}{'front max|err|':>15}{'mean|e|':>9}{'p99 c':>8}{'E(end)':>8}"
    )
    for run in runs:
        s = run["samples"][1:]
        print(
            f"{run['solver']:<38}{run['particles']:>10}{run['ms_per_frame']:>10.1f}"
            f"{100 * max(abs(e) for e in run['front_relative_error']):>14.1f}%"
            f"{100 * np.mean([r['mean_abs_density_error'] for r in s]):>8.2f}%"
            f"{100 * np.mean([r['p99_compression'] for r in s]):>7.2f}%{run['samples'][-1]['energy']:>8.3f}"
        )
    # (ours ran on --device, SPlisHSPlasH on the CPU: each run records its device)
    record = write_record("reference_dfsph", wp.get_device(args.device), result, args.json, rows=runs)
    if args.plot:
        plot(record, args.plot)
    return record


if __name__ == "__main__":
    main(sys.argv[1:])
