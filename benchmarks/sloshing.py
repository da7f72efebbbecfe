# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Sloshing: the first standing wave of a rectangular tank against linear theory (issue #27 item 1).

A slice of water ``--length`` long (x), ``--depth-particles`` particles across (y) and ``h = ratio L`` deep
stands between six frictionless walls, ``--per-length`` particles along L (spacing ``d = L / N``, mass
``1000 d^3``). It settles for ``--settle`` seconds with the
non-affine damping at ``--settle-damping`` (the lattice start's own motion would otherwise stay in an
undamped tank), then runs with the keywords under test; every particle is given the velocity of the first
mode of linear potential theory with the surface flat and rising at the left wall,

    u = -a w sin(k x) cosh(k z) / sinh(k h),   w_z = a w cos(k x) sinh(k z) / sinh(k h),
    w^2 = g k tanh(k h),   k = pi / L   (z from the floor),

so the surface becomes ``eta = a cos(k x) sin(w t)`` with ``a = --amplitude h``. The wave is read from the
fluid's centre of mass, which the first mode moves by ``-2 L eta_1 / (pi^2 h)`` along x (an average over
every particle: no surface detection, no churn of single particles). From its zero crossings come the
periods (and again from the times of its extremes, which a centre of mass settling a hair off zero does not
move), from its extremes the share of the amplitude kept per period (each extreme against the one a
period later, the geometric mean over ``--periods`` periods). With ``--energy`` it also records, every
quarter period, the fluid's kinetic energy, its potential energy above the settled state and the kinetic
energy in the mode's velocity field: where the wave's energy goes (``--amplitude 0``: the tank's own).

One start's reading scatters: starts a micrometre apart give periods several percent apart, more than the
2 % the issue asks of it. ``--starts N`` runs N tanks at once as isolated worlds of one model, world ``w``
from the lattice moved by up to ``w x 1e-6`` spacings, and reports the mean over them with its standard
error (world 0's row is bitwise the single run's on the CPU).

Usage::

    python -m benchmarks sloshing [--per-length 20 --ratio 0.5 --amplitude 0.1] [--starts 16] [--json out.json]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import warp as wp

import newton
from newton.examples.fluid.common import add_closed_box, add_water_lattice
from newton.examples.fluid.progress import track

from .frames import Frames, add_solver_arguments, run_on_device, solver_keywords
from .run_record import write_record

GRAVITY = 9.81  # [m/s^2]
SIGNAL_STARTS = 8  # starts whose centre-of-mass signal a record of ``--starts`` keeps
START_OFFSET = 1.0e-6  # [spacings] per world of ``--starts``: world w's particles moved by up to w times this


def build(
    length: float,
    per_length: int,
    ratio: float,
    depth_particles: int,
    device,
    jitter: float = 0.0,
    starts: int = 1,
    start_offset: float = START_OFFSET,
):
    """The water slice on the rest lattice and its closed tank; returns the model and the spacing [m].

    With ``starts`` above 1 the model holds that many isolated worlds, each its own tank (they overlap in
    space and never see each other), world ``w`` with its particles moved by a uniform random offset of
    width ``w * start_offset`` spacings per coordinate: the same wave from starts a hair apart, whose
    outcomes scatter as a chaotic flow's do.
    """
    d = length / per_length
    layers = max(1, round(ratio * per_length))
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -GRAVITY))
    for w in range(starts):
        if starts > 1:
            builder.begin_world()
        first = builder.particle_count
        add_water_lattice(builder, d, (per_length, depth_particles, layers), jitter=jitter * d)
        if w > 0:
            rng = np.random.default_rng(w)
            for i in range(first, builder.particle_count):
                offset = rng.uniform(-0.5, 0.5, 3) * (w * start_offset * d)
                builder.particle_q[i] = wp.vec3(*(np.asarray(builder.particle_q[i], dtype=np.float64) + offset))
        add_closed_box(builder, length, 3.0 * layers * d, width=depth_particles * d)
        if starts > 1:
            builder.end_world()
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model, d


def mode_velocity(q: np.ndarray, length: float, depth: float, amplitude: float) -> tuple[np.ndarray, float]:
    """The first mode's velocity [m/s] at positions ``q`` with the surface flat and rising at x = 0; and w [rad/s]."""
    k = math.pi / length
    omega = math.sqrt(GRAVITY * k * math.tanh(k * depth))
    x, z = q[:, 0], np.clip(q[:, 2], 0.0, depth)
    scale = amplitude * omega / math.sinh(k * depth)
    v = np.zeros_like(q)
    v[:, 0] = -scale * np.sin(k * x) * np.cosh(k * z)
    v[:, 2] = scale * np.cos(k * x) * np.sinh(k * z)
    return v, omega


def energy_budget(
    q: np.ndarray, u: np.ndarray, q_rest: np.ndarray, mass: float, length: float, depth: float, t: float
) -> dict:
    """The fluid's kinetic energy, its potential energy above the settled state ``q_rest``, and the kinetic
    energy in the first mode's velocity field (the velocity's projection on it at positions ``q``) [J]."""
    mode, _ = mode_velocity(q, length, depth, 1.0)
    share = float((u * mode).sum()) / float((mode * mode).sum())
    return {
        "t_s": t,
        "kinetic_J": 0.5 * mass * float((u * u).sum()),
        "potential_J": mass * GRAVITY * float(q[:, 2].sum() - q_rest[:, 2].sum()),
        "mode_kinetic_J": 0.5 * mass * share * share * float((mode * mode).sum()),
    }


def crossings(t: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Times [s] where ``s`` changes sign, by linear interpolation."""
    i = np.nonzero(np.signbit(s[:-1]) != np.signbit(s[1:]))[0]
    return t[i] - s[i] * (t[i + 1] - t[i]) / (s[i + 1] - s[i])


def peak_index(t: np.ndarray, s: np.ndarray, a: float, b: float) -> int:
    """Index of the largest ``|s|`` between ``a`` and ``b``."""
    inside = np.nonzero((t >= a) & (t <= b))[0]
    return int(inside[np.argmax(np.abs(s[inside]))])


def peak_time(t: np.ndarray, s: np.ndarray, i: int) -> float:
    """Time [s] of the extreme at sample ``i``, refined by the parabola through it and its two samples beside it."""
    if i == 0 or i == len(t) - 1:
        return float(t[i])
    curvature = s[i - 1] - 2.0 * s[i] + s[i + 1]
    shift = 0.5 * (s[i - 1] - s[i + 1]) / curvature if curvature != 0.0 else 0.0
    return float(t[i] + np.clip(shift, -1.0, 1.0) * 0.5 * (t[i + 1] - t[i - 1]))


def analyse(t: np.ndarray, s: np.ndarray, periods: int, floor: float = 0.1) -> dict:
    """Period and amplitude kept per period of a standing wave's signal ``s(t)`` (centre-of-mass offset).

    Only the half periods whose extreme is above ``floor`` times the first count: below it the wave is
    lost in the tank's own motion, whose zero crossings say nothing of the wave. The period is read twice:
    from the zero crossings (``period_s``) and from the times of the extremes (``period_from_extremes_s``).
    A centre of mass that settles off zero (the fluid ending a hair to one side) moves the crossings of a
    decaying wave, one half period longer and the next shorter, and not its extremes.
    """
    # (t = 0 itself is the start's zero, not a crossing)
    zeros = crossings(t[1:], s[1:])
    bounds = np.concatenate([[0.0], zeros])
    peaks = [peak_index(t, s, a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    extremes = np.abs(s[peaks]).astype(np.float64)
    if len(extremes) == 0:
        return {
            "periods_measured": 0,
            "period_s": math.nan,
            "period_spread_s": math.nan,
            "period_from_extremes_s": math.nan,
            "first_extreme_m": 0.0,
            "amplitude_kept_per_period": math.nan,
            "amplitude_after_periods": math.nan,
        }
    extremes = extremes[: 2 * periods + 1]
    above = int(np.argmin(extremes >= floor * extremes[0])) if (extremes < floor * extremes[0]).any() else len(extremes)
    extremes = extremes[:above]
    # half periods between crossings; the first runs from t = 0, a quarter period before the first extreme
    half = np.diff(zeros)[: max(0, above - 1)]
    # and between the extremes of the same half periods
    half_extremes = np.diff([peak_time(t, s, i) for i in peaks[:above]])
    kept = extremes[2:] / extremes[:-2]
    return {
        "periods_measured": float(len(half) / 2),
        "period_s": float(2.0 * half.mean()) if len(half) else math.nan,
        "period_spread_s": float(2.0 * half.std()) if len(half) else math.nan,
        "period_from_extremes_s": float(2.0 * half_extremes.mean()) if len(half_extremes) else math.nan,
        "first_extreme_m": float(extremes[0]),
        "amplitude_kept_per_period": float(np.exp(np.log(kept).mean())) if len(kept) else math.nan,
        "amplitude_after_periods": float(extremes[-1] / extremes[0]),
    }


def tank_frames(args, model, d: float, device):
    """The solver (keywords from ``args``), its contacts and a :class:`Frames` for a tank of spacing ``d`` [m].

    Returns the solver, the frame, the two states and the non-affine damping under test (``--nonaffine-damping``,
    else the solver's default).
    """
    solver = newton.solvers.SolverXPBD(model, **solver_keywords(args, d, damping=False))
    damping = solver.fluid_nonaffine_damping if args.nonaffine_damping is None else args.nonaffine_damping
    pipeline = newton.CollisionPipeline(model, soft_contact_max=4 * model.particle_count, soft_contact_gap=0.5 * d)
    states = [model.state(), model.state()]
    return solver, Frames(solver, pipeline, pipeline.contacts(), states, args.substeps, device), states, damping


def settle(args, solver, frame, damping: float, label: str) -> None:
    """``--settle`` seconds at ``--settle-damping``, then the damping under test.

    The lattice start's settling motion would stay in an undamped tank as noise: it is settled out first.
    """
    solver.fluid_nonaffine_damping = args.settle_damping
    for _ in track(range(round(args.settle * 60.0)), f"{label}: settling", unit="frame"):
        frame()
    solver.fluid_nonaffine_damping = damping


def world_means(values: np.ndarray, world: np.ndarray, starts: int) -> np.ndarray:
    """The mean of ``values`` over each world's particles (``world``: 0 to ``starts - 1``)."""
    return np.bincount(world, weights=values, minlength=starts) / np.bincount(world, minlength=starts)


def ensemble(per_start: list[dict]) -> dict:
    """The mean over the starts of each one's period error and amplitude kept, with their spread and the
    standard error of the mean (the starts whose wave could not be read are counted, not averaged)."""
    out = {"starts": len(per_start)}
    for key in ("period_error", "period_error_extremes", "amplitude_kept_per_period", "periods_measured"):
        values = np.asarray([r[key] for r in per_start], dtype=np.float64)
        read = values[np.isfinite(values)]
        out[f"{key}_mean"] = float(read.mean()) if len(read) else math.nan
        out[f"{key}_std"] = float(read.std(ddof=1)) if len(read) > 1 else math.nan
        out[f"{key}_se"] = out[f"{key}_std"] / math.sqrt(len(read)) if len(read) > 1 else math.nan
        out[f"{key}_unread"] = int(len(values) - len(read))
    return out


def run(args, device, full_signal: bool = False) -> dict:
    length = args.length
    starts = args.starts
    if starts < 1:
        raise ValueError(f"--starts is {starts}; it must be at least 1")
    model, d = build(length, args.per_length, args.ratio, args.depth_particles, device, args.jitter, starts)
    layers = max(1, round(args.ratio * args.per_length))
    solver, frame, states, damping = tank_frames(args, model, d, device)
    # (a single tank's particles are global, world -1: its one mean is world 0's)
    world = np.maximum(model.particle_world.numpy(), 0)

    start = time.perf_counter()
    settle(args, solver, frame, damping, "sloshing")
    q = states[0].particle_q.numpy().astype(np.float64)
    # the settled surface: the particles' volume over the floor area (the tank's own level)
    level = float(model.particle_count / starts * d**3 / (length * args.depth_particles * d))
    amplitude = args.amplitude * level
    v, omega = mode_velocity(q, length, level, amplitude)
    states[0].particle_qd.assign(v.astype(np.float32))
    x_rest = world_means(q[:, 0], world, starts)
    period = 2.0 * math.pi / omega
    frames = math.ceil((args.periods + 0.75) * period * 60.0)
    t, s = [0.0], [np.zeros(starts)]
    mass = float(model.particle_mass.numpy()[0])
    energy, wave_energy = [], 0.5 * mass * float((v * v).sum())
    quarter = max(1, round(period * 60.0 / 4.0))
    simulated = 0.0  # [s] of the frames themselves, read-backs left out
    for f in track(range(frames), "sloshing: waves", unit="frame"):
        tick = time.perf_counter()
        frame()
        wp.synchronize_device(device)
        simulated += time.perf_counter() - tick
        t.append((f + 1) / 60.0)
        q_now = states[0].particle_q.numpy().astype(np.float64)
        s.append(world_means(q_now[:, 0], world, starts) - x_rest)
        if args.energy and (f + 1) % quarter == 0:
            u = states[0].particle_qd.numpy().astype(np.float64)
            energy.append(energy_budget(q_now, u, q, mass, length, level, (f + 1) / 60.0))
    wall = time.perf_counter() - start
    t, s = np.asarray(t), np.asarray(s)  # s: frames x starts
    control = None
    if args.control and args.amplitude > 0.0:
        # the same tank without the wave: its own drift of the centre of mass, taken out of the signal
        # (bitwise the same run on the CPU; on a GPU the contacts' sums reorder and it is approximate)
        quiet = argparse.Namespace(**{**vars(args), "amplitude": 0.0, "control": False, "json": None})
        control = run(quiet, device, full_signal=True)
        drift = np.asarray(control["signal_m"]).reshape(len(control["signal_t_s"]), -1)
        s = s - np.stack([np.interp(t, control["signal_t_s"], drift[:, w]) for w in range(starts)], axis=1)
    theory_extreme = 2.0 * length * amplitude / (math.pi**2 * level)
    per_start = []
    for w in range(starts):
        r = analyse(t, s[:, w], args.periods)
        per_start.append(
            {
                **r,
                "period_error": r["period_s"] / period - 1.0,
                "period_error_extremes": r["period_from_extremes_s"] / period - 1.0,
            }
        )
    stats = solver.fluid_diagnostics(states[0])
    record = {
        "particles": int(model.particle_count),
        "length_m": length,
        "per_length": args.per_length,
        "ratio_h_L": args.ratio,
        "depth_m": level,
        "layers": layers,
        "depth_particles": args.depth_particles,
        "jitter_spacings": args.jitter,
        "amplitude_m": amplitude,
        "substeps": args.substeps,
        "iterations": args.iterations,
        "viscosity": solver.fluid_viscosity,
        "warm_start": solver.fluid_warm_start,
        "coarse_correction": solver.fluid_coarse_correction,
        "coarse_cell": solver.fluid_coarse_cell,
        "density_kernel": solver.fluid_density_kernel,
        "smoothing_length_m": solver.fluid_smoothing_length,
        "nonaffine_damping": damping,
        "settle_s": args.settle,
        "settle_damping": args.settle_damping,
        "relaxation": solver.fluid_relaxation,
        "theory_period_s": period,
        "theory_first_extreme_m": theory_extreme,
        **per_start[0],
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        "ms_per_frame": 1000.0 * simulated / frames,
        "wall_s": wall,
        "control_largest_drift_m": None if control is None else float(np.abs(control["signal_m"]).max()),
        # --energy: the wave's kinetic energy at the start [J], and the budget every quarter period
        "wave_energy_J": wave_energy,
        "energy": energy,
    }
    if starts > 1:
        # the first start's reading stays the record's own (world 0 starts on the unmoved lattice)
        record.update(ensemble(per_start), start_offset_spacings=START_OFFSET, per_start=per_start)
    if full_signal:
        # (a control's, subtracted from the wave's frame by frame)
        record["signal_t_s"], record["signal_m"] = t, s
        return record
    every = max(1, len(t) // 400)
    record["signal_t_s"] = t[::every].tolist()
    # (a run of one start keeps the flat list of before; of several, a column for each of the first
    # SIGNAL_STARTS: the record stays small, and the analysis above read every start)
    if starts == 1:
        record["signal_m"] = s[::every, 0].tolist()
    else:
        record["signal_m"] = s[::every, :SIGNAL_STARTS].tolist()
    return record


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--length", type=float, default=0.5, help="tank length L [m]")
    p.add_argument("--per-length", type=int, default=20, help="particles along L")
    p.add_argument("--ratio", type=float, default=0.5, help="depth over length h / L")
    p.add_argument("--depth-particles", type=int, default=4, help="particles across the slice (y)")
    p.add_argument("--amplitude", type=float, default=0.1, help="wave amplitude over depth a / h")
    p.add_argument("--periods", type=int, default=10)
    p.add_argument("--settle", type=float, default=2.0, help="[s]")
    p.add_argument(
        "--settle-damping",
        type=float,
        default=1.0,
        help="the non-affine damping while settling (then the one under test)",
    )
    p.add_argument("--jitter", type=float, default=0.0, help="random offset of the start lattice [spacings]")
    p.add_argument(
        "--starts",
        type=int,
        default=1,
        help="isolated worlds in one model, each the tank from a start moved by w x 1e-6 spacings (world w): "
        "the period and amplitude kept as a mean over them, with its standard error",
    )
    p.add_argument(
        "--control", action="store_true", help="subtract the centre-of-mass drift of the same tank without the wave"
    )
    p.add_argument(
        "--energy",
        action="store_true",
        help="record and print the energy budget every quarter period (kinetic, potential, the mode's share)",
    )
    add_solver_arguments(p)
    return p


def main(argv=None):
    args = parser().parse_args(argv)
    device, r = run_on_device(run, args)
    print(
        f"{'device':<10}{'particles':>10}{'N/L':>5}{'h/L':>5}{'sub x it':>9}{'damping':>8}{'T theory':>9}"
        f"{'T':>8}{'err':>7}{'err ext':>8}{'kept/T':>8}{'mean|e|':>8}"
    )
    name = device.name if device.is_cuda else "cpu"
    if r["energy"]:
        # over the wave's starting energy, or in joules without a wave
        unit = r["wave_energy_J"] if r["wave_energy_J"] > 0.0 else 1.0
        # (the potential energy is in the record only: a 0.5 % change of the bulk's density moves it by
        # about the wave's energy, so it says little of the wave)
        print(f"{'t/T':>6}{'kinetic':>10}{'in mode':>10}  ({'over E0' if unit != 1.0 else 'J'})")
        for e in r["energy"]:
            k, m = e["kinetic_J"] / unit, e["mode_kinetic_J"] / unit
            print(f"{e['t_s'] / r['theory_period_s']:>6.2f}{k:>10.3g}{m:>10.3g}")
    print(
        f"{name:<10}{r['particles']:>10}{r['per_length']:>5}{r['ratio_h_L']:>5.2f}{r['substeps']:>5} x {r['iterations']:<1}"
        f"{r['nonaffine_damping']:>8.2f}{r['theory_period_s']:>9.4f}{r['period_s']:>8.4f}{100 * r['period_error']:>6.1f}%"
        f"{100 * r['period_error_extremes']:>7.1f}%"
        f"{r['amplitude_kept_per_period']:>8.3f}{100 * r['mean_abs_density_error']:>7.2f}%"
    )
    if r.get("starts", 1) > 1:
        print(
            f"over {r['starts']} starts (the first start's row above): period error "
            f"{100 * r['period_error_mean']:+.1f} % +- {100 * r['period_error_se']:.1f} % (standard error; spread "
            f"{100 * r['period_error_std']:.1f} %; from the extremes {100 * r['period_error_extremes_mean']:+.1f} % +- "
            f"{100 * r['period_error_extremes_se']:.1f} %), kept per period {r['amplitude_kept_per_period_mean']:.3f} +- "
            f"{r['amplitude_kept_per_period_se']:.3f} (spread {r['amplitude_kept_per_period_std']:.3f}); "
            f"unread {r['period_error_unread']}"
        )
    return write_record("sloshing", device, r, args.json)


if __name__ == "__main__":
    main()
