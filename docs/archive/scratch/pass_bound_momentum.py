# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch: whether the bound of a density pass's move (``max_correction``) breaks the fluid's momentum.

Two cases on the CPU, no gravity, no non-affine damping, each with either kernel, with the bound and with it lifted
(the parameter set to 1e9 on the device): four particles placed at one point (the over-packed placement's
relaxation off, so the step's passes push them apart), and two blocks of 216 and 64 particles colliding at
``--speed`` m/s each. Prints the fluid's centre after each of the first frames (the coincident start) and the
largest change of its momentum over twenty frames (the collision). docs/archive/validation_notebook.md, "The one
kernel as the default".

Usage: python docs/archive/scratch/pass_bound_momentum.py [--speed 10]
"""

import argparse

import numpy as np
import warp as wp

import newton
from newton.tests.test_solver_xpbd_fluid import FLUID, MASS, D, Sim, add_block

KERNELS = ("poly6", "one_kernel")


def solver_sim(model, kernel: str, bounded: bool, **kwargs) -> Sim:
    sim = Sim(model, substeps=8, fluid_density_kernel=kernel, fluid_nonaffine_damping=0.0, **kwargs)
    if not bounded:
        fluid = sim.solver._fluid
        params = fluid.params.numpy()
        params[0]["max_correction"] = 1.0e9
        fluid.params.assign(params)
    return sim


def coincident(kernel: str, bounded: bool) -> list:
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    for _ in range(4):
        builder.add_particle(pos=wp.vec3(0.0, 0.0, 1.0), vel=wp.vec3(0.0), mass=MASS, radius=0.5 * D, flags=FLUID)
    sim = solver_sim(builder.finalize(device="cpu"), kernel, bounded, fluid_relax_overpacked=False)
    centres = []
    for _ in range(3):
        sim.step(1)
        centres.append(np.round(sim.q().mean(axis=0) - (0.0, 0.0, 1.0), 6).tolist())
    return centres


def collision(kernel: str, bounded: bool, speed: float) -> float:
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    add_block(builder, (6, 6, 6), origin=(0.0, 0.0, 0.0), vel=(speed, 0.0, 0.0), jitter=0.05 * D)
    add_block(builder, (4, 4, 4), origin=(0.5, 0.05, 0.05), vel=(-speed, 0.0, 0.0), jitter=0.05 * D)
    model = builder.finalize(device="cpu")
    sim = solver_sim(model, kernel, bounded)
    mass = model.particle_mass.numpy()[:, None]
    p0 = (mass * sim.qd()).sum(axis=0)
    drift = 0.0
    for _ in range(20):
        sim.step(1)
        drift = max(drift, float(np.linalg.norm((mass * sim.qd()).sum(axis=0) - p0)))
    return drift / float(np.linalg.norm(p0))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--speed", type=float, default=10.0, help="each block's speed [m/s]")
    args = parser.parse_args()
    wp.config.quiet = True
    for kernel in KERNELS:
        for bounded in (True, False):
            label = f"{kernel:<11}{'bounded' if bounded else 'unbounded':<10}"
            print(f"{label} coincident centre [m] {coincident(kernel, bounded)}")
            print(f"{label} collision momentum change / momentum {collision(kernel, bounded, args.speed):.2e}")


if __name__ == "__main__":
    main()
