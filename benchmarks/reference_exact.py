# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The standing wave in SPlisHSPlasH (its PBF and its DFSPH), measured as ours is.

The exact answer of issue #27 item 1 that our solver does not meet at 20 particles per L, run in
another implementation of the same method (SPlisHSPlasH's PBF: Macklin & Mueller 2013, a fixed
step of 1/(60 ``--substeps``) s and exactly ``--iterations`` passes) and in a stricter one (its DFSPH,
Bender & Koschier 2015, with the dam-break settings of :mod:`.reference_dfsph`), both with the
volume-map walls of Bender et al. 2019 and no viscosity during the wave unless ``--viscosity`` is given
(SPlisHSPlasH's standard viscosity, kinematic [m^2/s]). Their fluid is shot away from walls nearer than about 1.5
spacings, so the walls stand one spacing beyond the lattice's faces; the fluid spreads into that gap,
and the wave's tank length, width and depth are read from the settled fluid (its extent plus one
spacing; the depth from its volume at d^3 a particle, SPlisHSPlasH's lattice being its rest state).
The walls' volume map has ``--map-cells`` cells per spacing (at one, particles in the corners are
thrown at several m/s in the first step).

The wave is :mod:`.sloshing`'s: a tank slice ``--per-length`` particles along L = 0.5 m, h / L =
``--ratio``, 4 particles across, settled ``--settle`` s at the standard viscosity
``--settle-viscosity`` (ours settles damped too), then every particle given the first mode's linear
velocity (amplitude ``--amplitude`` h) and the viscosity set to ``--viscosity``; the period and the
amplitude kept per period come from the centre of mass less that of the same tank run without the wave
(as ``sloshing.py --control``; one thread, so that both are the same run bitwise), by
:func:`.sloshing.analyse`.

:mod:`.rest_column`'s still column has no counterpart here: with walls one spacing from the lattice's
outer centres DFSPH's start explodes, and with one and a half the column drops into the gap and is
still overturning after 5 s (RMS 0.04-0.25 m/s for DFSPH with and without viscosity), so it says
nothing of the method at rest.

Each row records the solver's own density error (mean ``|rho/rho0 - 1|`` over the particles at the
end, and the largest compression), the time steps taken and the wall-clock time on one core.

Usage::

    python -m benchmarks reference_exact [--per-length 20 --ratio 0.5] [--methods pbf dfsph] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from .reference_dfsph import DFSPH_CONFIGURATION, GL_DISPATCH, preload_gl_dispatch, wall_box_scene

#: layers of SPlisHSPlasH's wave tank over ours for the same settled depth over length (:func:`wave`)
SPREAD = 1.36


def configuration(method: str, substeps: int, dfsph_fixed_step: bool = False) -> dict:
    """SPlisHSPlasH's scene settings for ``method``: ``pbf`` at our fixed step, or ``dfsph`` (at its CFL step,
    or with ``dfsph_fixed_step`` at PBF's)."""
    if method == "dfsph":
        if dfsph_fixed_step:
            return {**DFSPH_CONFIGURATION, "timeStepSize": 1.0 / (60.0 * substeps), "cflMethod": 0}
        return DFSPH_CONFIGURATION
    # PBF: a fixed step and the first-order velocity update of the paper (:class:`Run` sets the passes)
    return {"simulationMethod": 2, "timeStepSize": 1.0 / (60.0 * substeps), "cflMethod": 0, "velocityUpdateMethod": 0}


class Run:
    """One SPlisHSPlasH simulation of a lattice in a closed box, sampled at given times; its solver settings read
    back from the solver (``settings``)."""

    def __init__(self, args, method: str, d: float, lo, hi, block_lo, block_hi, t_end: float, name: str):
        import pysplishsplash as sph  # noqa: PLC0415

        self.sph = sph
        workdir = Path(args.workdir) / name
        workdir.mkdir(parents=True, exist_ok=True)
        # the standard viscosity at the settling's coefficient; :meth:`set_viscosity` changes it mid-run
        material = {"viscosityMethod": 1, "Standard viscosity": {"viscosity": args.settle_viscosity}}
        scene = wall_box_scene(
            d,
            lo,
            hi,
            block_lo,
            block_hi,
            t_end,
            workdir,
            configuration(method, args.substeps, args.dfsph_fixed_step),
            material,
            args.map_cells,
        )
        path = workdir / f"{method}.json"
        path.write_text(json.dumps(scene, indent=1))
        self.base = sph.Exec.SimulatorBase()
        self.base.init(useGui=False, outputDir=str(workdir / "out"), sceneFile=str(path))
        self.base.initSimulation()
        step = sph.Simulation.getCurrent().getTimeStep()
        if method == "pbf":
            # exactly ``iterations`` passes (no error bound stops them first); read back with the rest below
            step.setValueUInt(step.MIN_ITERATIONS, args.iterations)
            step.setValueUInt(step.MAX_ITERATIONS, args.iterations)
            step.setValueFloat(step.MAX_ERROR, 1.0e-6)
        elif not args.divergence_solver:
            step.setValueBool(step.USE_DIVERGENCE_SOLVER, False)
        self.settings = {
            name.lower(): float(step.getValueFloat(pid)) if "ERROR" in name else int(step.getValueUInt(pid))
            for name in ("MIN_ITERATIONS", "MAX_ITERATIONS", "MAX_ERROR", "MAX_ITERATIONS_V", "MAX_ERROR_V")
            if (pid := getattr(step, name, None)) is not None
        }
        if method == "dfsph":
            self.settings["use_divergence_solver"] = bool(step.getValueBool(step.USE_DIVERGENCE_SOLVER))
        self.settings["time_step_s"] = float(sph.TimeManager.getCurrent().getTimeStepSize())
        self.fluid = sph.Simulation.getCurrent().getFluidModel(0)
        self.n = self.fluid.numActiveParticles()
        self.steps = 0

    def set_viscosity(self, coefficient: float) -> None:
        """The standard viscosity's coefficient from now on [m^2/s]."""
        viscosity = self.fluid.getViscosityBase()
        viscosity.setValueFloat(viscosity.VISCOSITY_COEFFICIENT, coefficient)

    def positions(self) -> np.ndarray:
        return np.array([self.fluid.getPosition(i) for i in range(self.n)], dtype=np.float64)

    def density_error(self) -> dict:
        rho = np.array([self.fluid.getDensity(i) for i in range(self.n)], dtype=np.float64) / 1000.0
        return {"mean_abs_density_error": float(np.abs(rho - 1.0).mean()), "max_compression": float(rho.max() - 1.0)}

    def run(self, times, sample, label: str) -> float:
        """Simulate to the last of ``times`` [s], calling ``sample(t)`` at the first step at or past each (``t``
        the simulated time there); returns the wall-clock time [s] spent simulating (sampling left out)."""
        from newton.examples.fluid.progress import FluidProgress  # noqa: PLC0415

        pending = list(times)
        progress = FluidProgress(len(pending), label, unit="sample")
        spent = {"sampling": 0.0}

        def on_step():
            self.steps += 1
            t = self.sph.TimeManager.getCurrent().getTime()
            while pending and t >= pending[0] - 1.0e-7:
                tick = time.perf_counter()
                # (DFSPH's adaptive step passes a sample time between steps: the sample is at its own time)
                pending.pop(0)
                sample(t)
                spent["sampling"] += time.perf_counter() - tick
                progress.update()

        self.base.setTimeStepCB(on_step)
        start = time.perf_counter()
        self.base.runSimulation()
        wall = time.perf_counter() - start - spent["sampling"]
        progress.close()
        self.final_density = self.density_error()
        self.base.cleanup()
        return wall


def wave(args, method: str, amplitude: float) -> dict:
    """One run of the wave at ``amplitude`` [over h] (0: the same tank without it): its settings and signal."""
    from .sloshing import mode_velocity  # noqa: PLC0415

    length, n = 0.5, args.per_length
    d = length / n
    # the fluid spreads into the spacing the walls keep free: 1.36 times the layers of our tank settle to
    # about the same depth over length (20 per L: 14 layers settle to h / L 0.5, 12 to 0.44)
    layers, across = args.wave_layers or max(1, round(SPREAD * args.ratio * n)), 4
    # (the tank asked for sets how long to run; the settled tank, read below, sets the theory)
    _, nominal = mode_velocity(np.zeros((1, 3)), length, args.ratio * length, 0.0)
    t_wave = (args.periods + 0.75) * 2.0 * math.pi / nominal
    frames = np.arange(1, round((args.settle + t_wave) * 60.0) + 1) / 60.0
    run = Run(
        args,
        method,
        d,
        (-d, -d, -d),
        (length + d, across * d + d, 2.0 * layers * d),
        (0.5 * d,) * 3,
        (length - 0.5 * d, (across - 0.5) * d, (layers - 0.5) * d),
        frames[-1],
        f"wave_{n}_{args.ratio}",
    )
    state = {}
    t, s = [0.0], [0.0]

    def sample(time_s: float):
        if time_s < args.settle - 1.0e-9:
            return
        q = run.positions()
        if "x0" not in state:
            # the settled tank: its length and width from the fluid's extent, its depth from its volume (the
            # lattice it started on is SPlisHSPlasH's rest state: d^3 a particle)
            lo, hi = q.min(axis=0) - 0.5 * d, q.max(axis=0) + 0.5 * d
            state["length"], state["across"] = float(hi[0] - lo[0]), float(hi[1] - lo[1])
            state["level"] = run.n * d**3 / (state["length"] * state["across"])
            v, omega = mode_velocity(q - lo, state["length"], state["level"], amplitude * state["level"])
            for i in range(run.n):
                run.fluid.setVelocity(i, v[i])
            run.set_viscosity(args.viscosity)
            state["omega"], state["x0"] = omega, float(q[:, 0].mean())
            return
        t.append(time_s - args.settle)
        s.append(float(q[:, 0].mean()) - state["x0"])

    label = f"reference_exact: {'wave' if amplitude > 0.0 else 'control'}, {method}"
    wall = run.run(frames, sample, label)
    period = 2.0 * math.pi / state["omega"]
    return {
        "solver": f"SPlisHSPlasH {method.upper()}",
        "particles": int(run.n),
        "per_length": n,
        "ratio_h_L": args.ratio,
        "length_m": state["length"],
        "layers": layers,
        "depth_m": state["level"],
        "settled_ratio_h_L": state["level"] / state["length"],
        "amplitude_m": amplitude * state["level"],
        "theory_period_s": period,
        **run.final_density,
        "solver_settings": run.settings,
        "steps": run.steps,
        "mean_time_step_s": float(frames[-1]) / max(1, run.steps),
        "wall_s": wall,
        # every frame's sample
        "signal_t_s": t,
        "signal_m": s,
    }


def measure(args, method: str) -> dict:
    """The wave's row: its run, less the same tank's run without the wave (unless ``--no-control``), analysed
    as :mod:`.sloshing` analyses ours."""
    from .sloshing import analyse  # noqa: PLC0415

    row = wave(args, method, args.amplitude)
    t, s = np.asarray(row["signal_t_s"]), np.asarray(row["signal_m"])
    if args.control:
        # (one thread: the same run bitwise, so the difference is the wave's alone; DFSPH's steps follow
        # the flow, so the control is read at the wave's sample times)
        quiet = wave(args, method, 0.0)
        s = s - np.interp(t, quiet["signal_t_s"], quiet["signal_m"])
        row["control_largest_drift_m"] = float(np.abs(quiet["signal_m"]).max())
        row["control_wall_s"] = quiet["wall_s"]
    result = analyse(t, s, args.periods)
    row.update(result)
    row["period_error"] = result["period_s"] / row["theory_period_s"] - 1.0
    row["period_error_extremes"] = result["period_from_extremes_s"] / row["theory_period_s"] - 1.0
    row["signal_m"] = s.tolist()
    return row


def print_rows(rows: list) -> None:
    print(
        f"{'solver':<20}{'particles':>10}{'N/L':>5}{'h/L':>6}{'steps':>7}{'T theory':>9}{'err':>7}{'kept/T':>8}"
        f"{'periods':>8}{'mean|e|':>8}"
    )
    for r in rows:
        print(
            f"{r['solver']:<20}{r['particles']:>10}{r['per_length']:>5}{r['settled_ratio_h_L']:>6.2f}{r['steps']:>7}"
            f"{r['theory_period_s']:>9.4f}{100 * r['period_error']:>6.1f}%{r['amplitude_kept_per_period']:>8.3f}"
            f"{r['periods_measured']:>8.1f}"
            f"{100 * r['mean_abs_density_error']:>7.2f}%"
        )


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--methods", nargs="+", default=["pbf", "dfsph"], choices=["pbf", "dfsph"])
    parser.add_argument("--substeps", type=int, default=8, help="PBF: steps per 1/60 s frame")
    parser.add_argument("--iterations", type=int, default=2, help="PBF: passes per step")
    parser.add_argument("--viscosity", type=float, default=0.0, help="standard viscosity during the wave [m^2/s]")
    parser.add_argument(
        "--settle-viscosity",
        type=float,
        default=0.01,
        help="standard viscosity while settling [m^2/s] (SPlisHSPlasH's dam-break value; ours settles damped too)",
    )
    parser.add_argument(
        "--dfsph-fixed-step",
        action="store_true",
        help="DFSPH: PBF's fixed step of 1/(60 substeps) s instead of its CFL step",
    )
    parser.add_argument(
        "--no-divergence-solver",
        dest="divergence_solver",
        action="store_false",
        help="DFSPH: switch its divergence (velocity) solve off, leaving the density solve",
    )
    parser.add_argument(
        "--no-control",
        dest="control",
        action="store_false",
        help="do not subtract the centre-of-mass drift of the same tank run without the wave",
    )
    parser.add_argument("--per-length", type=int, default=20, help="particles along L")
    parser.add_argument("--ratio", type=float, default=0.5, help="depth over length h / L")
    parser.add_argument("--wave-layers", type=int, default=None, help="layers (default: SPREAD x ratio x per-length)")
    parser.add_argument(
        "--map-cells", type=float, default=3.0, help="the walls' volume-map cells per spacing (1 blasts the corners)"
    )
    parser.add_argument("--amplitude", type=float, default=0.1, help="amplitude over depth a / h")
    parser.add_argument("--periods", type=int, default=10, help="periods measured")
    parser.add_argument("--settle", type=float, default=2.0, help="settling before the wave [s]")
    parser.add_argument(
        "--workdir",
        default=str(Path(tempfile.gettempdir()) / "newton-fluid-reference-exact"),
        help="scenes and SPlisHSPlasH's volume-map cache",
    )
    parser.add_argument("--json", default=None)
    parser.add_argument("--gl-dispatch", default=GL_DISPATCH, help="libGLdispatch to preload for pysplishsplash")
    args = parser.parse_args(argv)
    preload_gl_dispatch("reference_exact", argv, args.gl_dispatch)
    # one thread, so that the control run is the wave's run bitwise (OpenMP reads it as the library loads);
    # and before anything imports Warp (see reference_dfsph.main)
    os.environ["OMP_NUM_THREADS"] = "1"
    import pysplishsplash  # noqa: F401, PLC0415

    rows = []
    for method in args.methods:
        row = measure(args, method)
        fixed = method == "pbf" or args.dfsph_fixed_step
        row["substeps"] = args.substeps if fixed else "adaptive (CFL)"
        row["iterations"] = args.iterations if method == "pbf" else "adaptive (to maxError)"
        row["viscosity_m2_s"] = args.viscosity
        row["settle_viscosity_m2_s"] = args.settle_viscosity
        rows.append(row)
    print_rows(rows)
    import warp as wp  # noqa: PLC0415

    from .run_record import write_record  # noqa: PLC0415

    result = {"threads": 1, "settings": vars(args)}
    return write_record("reference_exact", wp.get_device("cpu"), result, args.json, rows=rows)


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
