# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Cost of a fluid step with a pool of inactive fluid particles held in reserve.

An emitter keeps fluid particles inactive until it releases them; they sort into the left-out
entry of the cell table and no pass works on them. This times whole ``SolverXPBD.step`` substeps
(the sort, neighbour lists, density passes and velocity passes; a CUDA graph on CUDA; ``--substeps``
per 60 Hz frame, ``--iterations`` and every solver keyword as flags) of a cubic
block of active fluid falling freely, with and without such a pool, on any device. Prints a table
and writes JSON.

Usage::

    python -m benchmarks inactive_pool [--active 50000] [--pool 50000] [--device cuda:0] [--json out.json]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np
import warp as wp

import newton

from .frames import Frames, add_solver_arguments, solver_keywords, solver_record
from .run_record import write_record

SPACING = 0.02  # [m]


def step_ms(device, active: int, pool: int, args) -> dict:
    """One row: median ms of a substep of the block with ``pool`` inactive fluid particles beside it."""
    side = round(active ** (1.0 / 3.0))
    grid = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3) * SPACING
    mass = 1000.0 * SPACING**3
    builder = newton.ModelBuilder()
    fluid = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)
    zero = [(0.0, 0.0, 0.0)]
    builder.add_particles(
        [tuple(p) for p in grid], zero * len(grid), [mass] * len(grid), [0.5 * SPACING] * len(grid), [fluid] * len(grid)
    )
    if pool:
        # parked below the block, inactive: fluid particles that take no part until released
        parked = [(0.0, 0.0, -1.0 - 1.0e-4 * k) for k in range(pool)]
        flags = [int(newton.ParticleFlags.FLUID)] * pool
        builder.add_particles(parked, zero * pool, [mass] * pool, [0.5 * SPACING] * pool, flags)
    model = builder.finalize(device=device)
    solver = newton.solvers.SolverXPBD(model, **solver_keywords(args, SPACING))
    states = [model.state(), model.state()]
    # a frame of substeps (one CUDA graph on CUDA with an even count); no shapes, no collision
    frame = Frames(solver, None, None, states, args.substeps, device)
    with wp.ScopedDevice(device):
        frame()  # compiles (and on CUDA captures)
        times = []
        for _ in range(args.repeats):
            wp.synchronize_device(device)
            t0 = time.perf_counter()
            frame()
            wp.synchronize_device(device)
            times.append((time.perf_counter() - t0) * 1000.0 / args.substeps)
    stats = solver.fluid_diagnostics(states[0])
    return {
        "particles": model.particle_count,
        "active": len(grid),
        "inactive": pool,
        "substeps": args.substeps,
        **solver_record(solver),
        "ms_per_substep": statistics.median(times),
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--active", type=int, default=50_000, help="active fluid particles (rounded to a cube)")
    parser.add_argument("--pool", type=int, default=50_000, help="inactive fluid particles")
    parser.add_argument("--repeats", type=int, default=10)
    add_solver_arguments(parser)
    args = parser.parse_args(argv)
    wp.config.quiet = True
    device = wp.get_device(args.device)
    rows = []
    print(f"{'device':<24}{'active':>9}{'inactive':>9}{'ms/substep':>11}{'mean|e|':>9}{'max c':>8}")
    for pool in (0, args.pool):
        row = step_ms(device, args.active, pool, args)
        rows.append(row)
        print(
            f"{device.name:<24}{row['active']:>9}{pool:>9}{row['ms_per_substep']:>11.3f}"
            f"{100 * row['mean_abs_density_error']:>8.2f}%{100 * row['max_compression']:>7.2f}%"
        )
    result = {
        "work": "a 60 Hz frame of whole SolverXPBD.step substeps (a CUDA graph on CUDA), per substep, median of repeats"
    }
    return write_record("inactive_pool", device, result, args.json, rows=rows)


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
