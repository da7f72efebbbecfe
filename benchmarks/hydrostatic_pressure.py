# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Hydrostatic pressure: the pressure and wall forces the density constraint implies in a settled column (issue #27 item 3).

The column of ``rest_column.py`` (``--n`` x ``--n`` x ``--layers`` particles, spacing 0.05 m, in a closed
frictionless box) settles for ``--settle`` seconds with the non-affine damping at ``--settle-damping``,
runs ``--relax`` seconds at the keywords under test, then averages over ``--measure`` seconds (every
frame's last substep):

- the pressure: a substep moves particle ``i`` by ``w (m / rho0) sum_j (L_i + L_j) grad W_ij`` from the
  multipliers ``L`` it summed over its density passes (``w`` the relaxation), a force ``m / dt^2`` times
  that. The pressure it implies is the ``p = -K L`` whose gradient, on the rest lattice, those pair
  forces equal (``-V grad p``, ``V = d^3``): ``K = w m rho_V |sum_j s(r_j) r_j| / (3 rho0 dt^2)``, ``s`` the
  magnitude of the gradient the density constraint moves along (the spiky kernel's with ``"poly6"``, the
  one kernel's own), ``rho_V = m / d^3``. With ``fluid_coarse_correction`` the correction's move carries
  the rest of the pressure, ``-rho_V beta phi / dt^2`` (:func:`coarse_pressure`), added to it. Compared per
  layer with ``rho_V g (H - z)``, ``H`` the level at the rest spacing (the fluid's volume over the floor),
  below the top two layers;
- the forces on the walls: from the straight line through the layers' pressures, the floor's
  ``p(0) A`` against the fluid's weight and a side wall's ``W integral p dz`` against ``rho_V g H^2 W / 2``;
  and the part of each the wall's ghost density carries, ``(m w / dt^2) sum_i L_i grad c_wall(x_i)``
  (the particle-shape contacts carry the rest).

The multipliers are read from the warm-start store (``SolverXPBD.fluid_warm_start_multipliers``):
``fluid_warm_start`` keeps that share of a substep's summed multipliers for the next; at the default
``--warm-start 1e-6`` the carried part changes the step by a millionth.

Usage::

    python -m benchmarks hydrostatic_pressure [--n 8 --layers 16] [--substeps 8 --iterations 2] [--json out.json]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import warp as wp

from newton._src.solvers.xpbd.fluid.calibration import kernel_slope, lattice_density, rest_lattice, wall_density_tables
from newton.examples.fluid.progress import track

from .frames import add_solver_arguments, contact_frames, run_on_device
from .rest_column import GRAVITY, SPACING, build
from .run_record import write_record


def rest_density(solver, mass: float, d: float) -> float:
    """The rest density in use [kg/m^3]: the one set, else the rest lattice's (the solver's default)."""
    rho0 = solver.fluid_rest_density
    if rho0 is None:
        return lattice_density(d, solver.fluid_smoothing_length, mass, kernel=solver.fluid_density_kernel)
    return rho0


def pressure_factor(solver, mass: float, d: float, dt: float) -> float:
    """``K`` of ``p = -K L`` [Pa/m^2]: the pressure whose lattice gradient the multipliers' pair forces equal."""
    h = solver.fluid_smoothing_length
    r = np.linalg.norm(rest_lattice(d, h), axis=1)
    r = r[(r > 0.0) & (r < h)]
    slope = kernel_slope(solver.fluid_density_kernel, r, d, h)
    rho_v = mass / d**3
    return (
        solver.fluid_relaxation
        * mass
        * rho_v
        * float((slope * r).sum())
        / (3.0 * rest_density(solver, mass, d) * dt * dt)
    )


def coarse_pressure(solver, state, rho_v: float, dt: float) -> np.ndarray:
    """Each particle's pressure carried by the coarse density correction [Pa]; zeros without it.

    The correction moves a fluid particle by ``beta grad phi``, a force ``m beta grad phi / dt^2``: the pressure
    whose ``-V grad p`` equals it is ``-rho_V beta phi / dt^2``, zero at the free surface as ``phi`` is
    (``SolverXPBD.fluid_coarse_potential``, the frame's last substep's).
    """
    phi = solver.fluid_coarse_potential(state)
    if phi is None:
        return np.zeros(state.particle_q.shape[0])
    return -rho_v * solver.fluid_coarse_correction * phi.numpy().astype(np.float64) / (dt * dt)


def wall_gradient(solver, mass: float, d: float, distance: np.ndarray) -> np.ndarray:
    """The walls' share of ``rho / rho0`` differentiated against the distance from the wall [1/m]."""
    h = solver.fluid_smoothing_length
    _, drho = wall_density_tables(d, h, mass, kernel=solver.fluid_density_kernel)
    step = h / (len(drho) - 1)
    u = np.clip(distance, 0.0, None) / step
    return np.interp(u, np.arange(len(drho)), drho, right=0.0) / rest_density(solver, mass, d)


def run(args, device) -> dict:
    d = SPACING
    model = build(args.n, args.layers, device)
    solver, frame = contact_frames(model, args, d, device, damping=False)
    damping = solver.fluid_nonaffine_damping if args.nonaffine_damping is None else args.nonaffine_damping
    states = frame.states
    mass = float(model.particle_mass.numpy()[0])
    start = time.perf_counter()
    solver.fluid_nonaffine_damping = args.settle_damping
    for _ in track(range(round(args.settle * 60.0)), "hydrostatic_pressure: settling", unit="frame"):
        frame()
    solver.fluid_nonaffine_damping = damping
    for _ in track(range(round(args.relax * 60.0)), "hydrostatic_pressure: relaxing", unit="frame"):
        frame()
    count = model.particle_count
    dt = 1.0 / 60.0 / args.substeps
    rho_v = mass / d**3
    lam_sum = np.zeros(count)
    coarse_sum = np.zeros(count)
    q_sum = np.zeros((count, 3))
    frames = round(args.measure * 60.0)
    simulated = 0.0  # [s] of the frames themselves, read-backs left out
    for _ in track(range(frames), "hydrostatic_pressure: measuring", unit="frame"):
        tick = time.perf_counter()
        frame()
        wp.synchronize_device(device)
        simulated += time.perf_counter() - tick
        lam_sum += solver.fluid_warm_start_multipliers.numpy().astype(np.float64) / args.warm_start
        coarse_sum += coarse_pressure(solver, states[0], rho_v, dt)
        q_sum += states[0].particle_q.numpy().astype(np.float64)
    wall = time.perf_counter() - start
    lam, q = lam_sum / frames, q_sum / frames
    edge = args.n * d
    level = count * d**3 / (edge * edge)
    weight = count * mass * GRAVITY
    # the walls' pushes on the fluid through their ghost density: the floor (z = 0) and the wall at x = 0
    force = mass * solver.fluid_relaxation / (dt * dt)
    floor = float(force * (lam * wall_gradient(solver, mass, d, q[:, 2])).sum())
    side = float(force * (lam * wall_gradient(solver, mass, d, q[:, 0])).sum())
    side_theory = 0.5 * rho_v * GRAVITY * level**2 * edge
    # the pressure per layer, away from the side walls' first layer (their ghost density shares the load)
    coarse = coarse_sum / frames
    p = -pressure_factor(solver, mass, d, dt) * lam + coarse
    inner = (q[:, 0] > d) & (q[:, 0] < edge - d) & (q[:, 1] > d) & (q[:, 1] < edge - d)
    layer = np.floor(q[:, 2] / d).astype(int)
    rows = []
    for k in range(layer.max() + 1):
        pick = inner & (layer == k)
        if not pick.any():
            continue
        z = float(q[pick, 2].mean())
        theory = rho_v * GRAVITY * (level - z)
        rows.append(
            {
                "layer": k,
                "z_m": z,
                "pressure_Pa": float(p[pick].mean()),
                "coarse_Pa": float(coarse[pick].mean()),
                "theory_Pa": theory,
            }
        )
    below = [r for r in rows if r["layer"] < max(r["layer"] for r in rows) - 1]
    errors = np.array([r["pressure_Pa"] / r["theory_Pa"] - 1.0 for r in below])
    # the layers' pressures through a [1, 2, 1] / 4 filter (both sides alike): a multiplier alternating
    # from layer to layer exerts no force where a particle has neighbours above and below (in
    # (L_i + L_j) grad W_ij the pairs an odd number of layers apart cancel its alternating part, and
    # those an even number apart come in opposite pairs), so the filter keeps the pressure that pushes
    for k in range(1, len(rows) - 1):
        a, b, c = rows[k - 1 : k + 2]
        rows[k]["filtered_error"] = (a["pressure_Pa"] + 2.0 * b["pressure_Pa"] + c["pressure_Pa"]) / (
            a["theory_Pa"] + 2.0 * b["theory_Pa"] + c["theory_Pa"]
        ) - 1.0
    filtered = np.array([r["filtered_error"] for r in below if "filtered_error" in r])
    # the straight line through the layers' pressures: its slope against -rho g, and the forces it puts
    # on the floor (its value at z = 0 over the floor) and on a side wall (its integral up to its zero)
    slope, p0 = np.polyfit([r["z_m"] for r in below], [r["pressure_Pa"] for r in below], 1)
    top = -p0 / slope
    stats = solver.fluid_diagnostics(states[0])
    return {
        "particles": int(count),
        "n": args.n,
        "layers": args.layers,
        "substeps": args.substeps,
        "iterations": args.iterations,
        "nonaffine_damping": damping,
        "warm_start": args.warm_start,
        "relaxation": solver.fluid_relaxation,
        "level_m": level,
        "weight_N": weight,
        "pressure_gradient_error": float(-slope / (rho_v * GRAVITY) - 1.0),
        "floor_force_N": float(p0 * edge * edge),
        "floor_force_error": float(p0 * edge * edge / weight - 1.0),
        "side_force_theory_N": side_theory,
        "side_force_N": float(0.5 * p0 * top * edge),
        "side_force_error": float(0.5 * p0 * top * edge / side_theory - 1.0),
        # the walls' own pushes through their ghost density (the particle-shape contacts carry the rest)
        "floor_ghost_force_share": floor / weight,
        "side_ghost_force_share": side / side_theory,
        "pressure_error_max": float(np.abs(errors).max()),
        "pressure_error_mean": float(errors.mean()),
        # the largest error of the filtered profile, the floor layer (no layer below it) left out
        "pressure_error_max_filtered": float(np.abs(filtered).max()),
        # the coarse correction's share of the pressure below the top two layers (0 without it)
        "coarse_pressure_share": sum(r["coarse_Pa"] for r in below) / sum(r["pressure_Pa"] for r in below),
        "pressure_rows": rows,
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        "ms_per_frame": 1000.0 * simulated / frames,
        "wall_s": wall,
    }


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=8, help="particles along each side of the column")
    p.add_argument("--layers", type=int, default=16)
    p.add_argument("--settle", type=float, default=2.0, help="[s]")
    p.add_argument(
        "--settle-damping",
        type=float,
        default=1.0,
        help="the non-affine damping while settling (then the one under test)",
    )
    p.add_argument("--relax", type=float, default=1.0, help="[s] at the keywords under test before measuring")
    p.add_argument("--measure", type=float, default=1.0, help="[s]")
    # (the multipliers are read through the warm start's store)
    add_solver_arguments(p, defaults={"fluid_warm_start": 1e-6})
    return p


def main(argv=None):
    args = parser().parse_args(argv)
    device, r = run_on_device(run, args)
    print(f"{'layer':>6}{'z [m]':>8}{'p [Pa]':>10}{'rho g (H - z)':>15}{'error':>8}{'[1,2,1]':>9}")
    for row in r["pressure_rows"]:
        filtered = f"{100 * row['filtered_error']:>8.1f}%" if "filtered_error" in row else ""
        print(
            f"{row['layer']:>6}{row['z_m']:>8.3f}{row['pressure_Pa']:>10.1f}{row['theory_Pa']:>15.1f}"
            f"{100 * (row['pressure_Pa'] / row['theory_Pa'] - 1):>7.1f}%{filtered}"
        )
    print(
        f"{'device':<10}{'particles':>10}{'sub x it':>9}{'floor/W':>9}{'side/theory':>12}{'grad err':>9}{'p err max':>10}"
        f"{'filtered':>9}{'p err mean':>11}{'ghost floor':>12}{'mean|e|':>9}"
    )
    name = device.name if device.is_cuda else "cpu"
    print(
        f"{name:<10}{r['particles']:>10}{r['substeps']:>5} x {r['iterations']:<1}{1 + r['floor_force_error']:>9.4f}"
        f"{1 + r['side_force_error']:>12.4f}{100 * r['pressure_gradient_error']:>8.1f}%"
        f"{100 * r['pressure_error_max']:>9.1f}%{100 * r['pressure_error_max_filtered']:>8.1f}%"
        f"{100 * r['pressure_error_mean']:>10.1f}%"
        f"{r['floor_ghost_force_share']:>12.3f}{100 * r['mean_abs_density_error']:>8.2f}%"
    )
    return write_record("hydrostatic_pressure", device, r, args.json)


if __name__ == "__main__":
    main()
