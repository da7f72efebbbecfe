# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Still water: a column at rest in a closed frictionless box, and how much it moves after settling.

A lattice of ``--n`` x ``--n`` x ``--layers`` fluid particles (spacing 0.05 m, 1000 kg/m^3) fills the
floor of a closed box of frictionless walls 1.5 times the column's height, at 60 Hz with ``--substeps``
x ``--iterations`` and the solver's default keywords unless their flags are given (``--viscosity``,
``--density-ramp``, ``--relaxation``, ``--nonaffine-damping``, ...: every keyword, named after it). After ``--settle`` seconds it measures for ``--measure`` seconds (with several
``--settle`` times, one run measures over each window in turn, each read as a run from its time alone would be): the RMS and largest particle
speed (sampled every frame), the mean and largest displacement [spacings], the height span of the top
layer [spacings] (of the particles that started in it, ``top``, and of the surface, the top particle of each
column of cells ``SURFACE_CELL`` spacings wide, ``surf``), the fluid's own density error and the total energy per unit mass (kinetic plus
g z) at the start and end of the measurement, and the fluid's true number density in the interior (the
particles at least one smoothing length from every wall and from the top, by their Voronoi cells; a
kernel sum reads a disordered packing differently from the lattice it was calibrated on, so this is
the reading no kernel decides), beside its poly6 sum there. The RMS speed is also split by scale (the
columns ``whole``, ``long`` and ``fine``, each averaged over the frames like the RMS): the whole fluid's
mean velocity (the column moving together: its first acoustic mode), the mean velocities of cells of
``CELL`` spacings less that (waves longer than a cell) and each particle's velocity against its
cell's (the particle-scale churn). The targets of issue #23: RMS below 0.005 m/s, max below
0.02 m/s, mean displacement below 0.05 spacings and max below 0.5, top layer flat within 0.5 spacings.

Usage::

    python -m benchmarks rest_column [--n 12 --layers 24] [--substeps 8 --iterations 2] [--offset 0.01]
        [--settle 2 7 12 17] [--json out.json]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import warp as wp
from scipy.spatial import ConvexHull, Voronoi

import newton
from newton.examples.fluid.common import add_closed_box, add_water_lattice
from newton.examples.fluid.progress import track

from .dam_break import poly6_density
from .frames import add_solver_arguments, contact_frames, solver_record
from .run_record import write_record

SPACING = 0.05  # [m]
GRAVITY = 9.81  # [m/s^2]
CELL = 4  # cells of the velocity's split by scale [spacings]
SURFACE_CELL = 2  # cells whose top particles are the surface [spacings]


def build(n: int, layers: int, device, offset: float = 0.0):
    """The column and its closed box, the column moved ``offset`` [spacings] along x; returns the model."""
    d = SPACING
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -GRAVITY))
    add_water_lattice(builder, d, (n, n, layers))
    add_closed_box(builder, n * d, 1.5 * layers * d)
    if offset != 0.0:
        for i, (x, y, z) in enumerate(builder.particle_q):
            builder.particle_q[i] = (x + offset * d, y, z)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model


def surface_span(q: np.ndarray, d: float, cell: float = SURFACE_CELL) -> float:
    """The height span [spacings] of the fluid's surface: the top particle of each column of cells ``cell``
    spacings wide.

    Unlike the span of the particles that started in the top layer, a top-layer particle that has settled into a
    hollow below its neighbours does not count, and the particle that took its place does. Cells of two spacings
    hold a top particle each however the layer has moved.
    """
    cell = np.floor(q[:, :2] / (cell * d)).astype(np.int64)
    key = cell[:, 0] * 1_000_003 + cell[:, 1]
    order = np.lexsort((q[:, 2], key))
    last = np.r_[key[order][1:] != key[order][:-1], True]
    return float(np.ptp(q[order][last, 2]) / d)


def energy(state) -> float:
    """Kinetic plus gravitational energy per unit mass [J/kg], averaged over the particles."""
    q, v = state.particle_q.numpy().astype(np.float64), state.particle_qd.numpy().astype(np.float64)
    return float((0.5 * (v * v).sum(axis=1) + GRAVITY * q[:, 2]).mean())


def cell_velocity(q: np.ndarray, v: np.ndarray, cell: float) -> np.ndarray:
    """Each particle's ``cell``-sized cell's mean velocity [m/s] (one row per particle)."""
    keys = np.floor(q / cell).astype(np.int64)
    keys -= keys.min(axis=0)
    span = keys.max(axis=0) + 1
    _, inverse = np.unique((keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2], return_inverse=True)
    count = np.bincount(inverse).astype(np.float64)
    cell_v = np.stack([np.bincount(inverse, weights=v[:, a]) for a in range(3)], axis=1) / count[:, None]
    return cell_v[inverse]


def velocity_scales(q: np.ndarray, v: np.ndarray, cell: float) -> tuple[float, float, float]:
    """RMS speeds [m/s] of the mean motion, the ``cell``-sized cells' motion less it, and each particle's against its cell."""
    mean = v.mean(axis=0)
    cell_v = cell_velocity(q, v, cell)

    def rms(x):
        return float(np.sqrt((x * x).sum(axis=-1).mean()))

    return rms(mean), rms(cell_v - mean), rms(v - cell_v)


def interior_density(q: np.ndarray, d: float, h: float) -> dict:
    """Number density and poly6 sum of the particles at least ``h`` inside the column's box, over the lattice's.

    The number density is each such particle's Voronoi cell volume over ``d^3``, inverted and averaged;
    the poly6 sum is the dam break's estimator (:func:`.dam_break.poly6_density`: no walls), over the lattice's.
    """
    lo, hi = q.min(axis=0), q.max(axis=0)
    inner = np.nonzero(np.all((q > lo + h) & (q < hi - h), axis=1))[0]
    if len(inner) == 0:
        return {"interior_particles": 0, "interior_number_density": None, "interior_poly6_density": None}
    vor = Voronoi(q)
    volume = np.array([ConvexHull(vor.vertices[vor.regions[vor.point_region[i]]]).volume for i in inner])
    rho, rho0 = poly6_density(q, 1.0, d, h)
    return {
        "interior_particles": len(inner),
        "interior_number_density": float(np.mean(d**3 / volume)),
        "interior_poly6_density": float(np.mean(rho[inner]) / rho0),
    }


def measure_window(model, solver, frame, args, d: float, settle_s: float, frames_done: int) -> dict:
    """Step from frame ``frames_done`` to ``settle_s`` and measure the next ``args.measure`` seconds.

    See the module's docstring for the readings.
    """
    states = frame.states
    measure = round(args.measure * 60.0)
    for _ in track(range(round(settle_s * 60.0) - frames_done), "rest_column: settling", unit="frame"):
        frame()
    settled = states[0].particle_q.numpy().astype(np.float64)
    energy_start = energy(states[0])
    rms, scales, fastest = [], [], 0.0
    for _ in track(range(measure), "rest_column: measuring", unit="frame"):
        frame()
        v = states[0].particle_qd.numpy().astype(np.float64)
        speed = np.linalg.norm(v, axis=1)
        rms.append(float(np.sqrt(np.mean(speed * speed))))
        fastest = max(fastest, float(speed.max()))
        scales.append(velocity_scales(states[0].particle_q.numpy().astype(np.float64), v, CELL * d))
    whole, long_waves, fine = np.mean(scales, axis=0)
    q = states[0].particle_q.numpy().astype(np.float64)
    moved = np.linalg.norm(q - settled, axis=1) / d
    # the top layer: the particles that started in it
    top = model.particle_q.numpy()[:, 2] > (args.layers - 1) * d
    stats = solver.fluid_diagnostics(states[0])
    return {
        "settle_s": settle_s,
        "measure_s": args.measure,
        "rms_speed_m_s": float(np.mean(rms)),
        "rms_whole_m_s": float(whole),
        "rms_long_waves_m_s": float(long_waves),
        "rms_particle_scale_m_s": float(fine),
        "max_speed_m_s": fastest,
        "mean_displacement_spacings": float(moved.mean()),
        "max_displacement_spacings": float(moved.max()),
        "top_layer_span_spacings": float(np.ptp(q[top, 2]) / d),
        "surface_span_spacings": surface_span(q, d),
        "energy_start_J_kg": energy_start,
        "energy_end_J_kg": energy(states[0]),
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        **interior_density(q, d, solver.fluid_smoothing_length),
    }


def run(args, device) -> dict:
    """The column measured over each window of ``args.measure`` seconds from the times in ``args.settle``, in one run.

    The first window's readings are the record's own fields; with more than one window they are all under
    ``windows``. Measuring reads the state and leaves it as it is, so a window reads as a run measured from its
    settling time alone would.
    """
    d = SPACING
    model = build(args.n, args.layers, device, args.offset)
    solver, frame = contact_frames(model, args, d, device)
    start = time.perf_counter()
    windows, frames_done = [], 0
    for settle_s in args.settle:
        windows.append(measure_window(model, solver, frame, args, d, settle_s, frames_done))
        frames_done = round(settle_s * 60.0) + round(args.measure * 60.0)
    record = {
        "particles": int(model.particle_count),
        "n": args.n,
        "layers": args.layers,
        "substeps": args.substeps,
        **solver_record(solver),
        "start_offset_spacings": args.offset,
        **windows[0],
        "wall_s": time.perf_counter() - start,
    }
    if len(windows) > 1:
        record["windows"] = windows
    return record


def _ratio(x) -> str:
    return "-" if x is None else f"{x:.4f}"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=12, help="particles along each side of the column")
    parser.add_argument("--layers", type=int, default=24)
    parser.add_argument(
        "--settle",
        type=float,
        nargs="+",
        default=[2.0],
        help="when each measurement starts [s]; several: one run measured over each window in turn",
    )
    parser.add_argument("--measure", type=float, default=3.0, help="[s]")
    parser.add_argument(
        "--offset",
        type=float,
        default=0.0,
        help="the column's start moved along x [spacings]: another draw of the same still water (its motion is "
        "chaotic; a GPU's run is otherwise bitwise repeated)",
    )
    add_solver_arguments(parser)
    args = parser.parse_args(argv)
    times = args.settle
    if any(t < 0.0 for t in times) or any(b < a + args.measure for a, b in zip(times, times[1:], strict=False)):
        parser.error(
            f"--settle {' '.join(f'{t:g}' for t in times)}: expected times >= 0 in increasing order, each at least "
            f"--measure ({args.measure:g} s) after the one before"
        )
    wp.config.quiet = True
    device = wp.get_device(args.device)
    with wp.ScopedDevice(device):
        r = run(args, device)
    print(
        f"{'device':<24}{'particles':>10}{'sub x it':>9}{'from s':>7}{'rms m/s':>9}{'max m/s':>9}{'mean d':>8}"
        f"{'max d':>7}{'top':>6}{'surf':>6}{'mean|e|':>9}{'max c':>7}{'inner n':>9}{'poly6':>8}{'whole':>8}{'long':>8}"
        f"{'fine':>8}"
    )
    name = device.name if device.is_cuda else "cpu"
    for w in r.get("windows", [r]):
        print(
            f"{name:<24}{r['particles']:>10}{r['substeps']:>5} x {r['iterations']:<1}{w['settle_s']:>7g}"
            f"{w['rms_speed_m_s']:>9.4f}{w['max_speed_m_s']:>9.3f}{w['mean_displacement_spacings']:>8.3f}"
            f"{w['max_displacement_spacings']:>7.2f}{w['top_layer_span_spacings']:>6.2f}{w['surface_span_spacings']:>6.2f}"
            f"{100 * w['mean_abs_density_error']:>8.2f}%{100 * w['max_compression']:>6.2f}%"
            f"{_ratio(w['interior_number_density']):>9}{_ratio(w['interior_poly6_density']):>8}"
            f"{w['rms_whole_m_s']:>8.4f}{w['rms_long_waves_m_s']:>8.4f}{w['rms_particle_scale_m_s']:>8.4f}"
        )
    return write_record("rest_column", device, r, args.json)


if __name__ == "__main__":
    main()
