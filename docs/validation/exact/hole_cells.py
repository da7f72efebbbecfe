# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Which of the coarse correction's cells around Torricelli's hole hold fluid, and which are taken as walls.

Runs ``benchmarks/torricelli.py``'s tank with ``fluid_density_kernel="one_kernel"``, ``fluid_coarse_correction=0.5``
and no non-affine damping for ``--seconds``, then prints the kinds of the cells whose centres lie within a cell of
the hole (F full, S free surface, O outside the fluid: a wall's or empty) with their potential [1e-4 m^2], slice by
slice along the jet, and the cells' edge (the box coarsens while the jet spreads the fluid's bounds). Takes
``torricelli.py``'s arguments. docs/archive/validation_notebook.md, "The one kernel with the correction on the
chart".

Usage: python docs/validation/exact/hole_cells.py [--coarse-cell 1] [--seconds 0.5] [--device cpu]
"""

import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
import newton  # noqa: E402
from benchmarks import torricelli  # noqa: E402
from benchmarks.frames import Frames, solver_keywords  # noqa: E402
from newton.examples.fluid.progress import track  # noqa: E402

PAIR = ["--density-kernel", "one_kernel", "--coarse-correction", "0.5", "--nonaffine-damping", "0"]


def main():
    wp.config.quiet = True
    args = torricelli.parser().parse_args(sys.argv[1:] + PAIR)
    device = wp.get_device(args.device)
    model, d, hole = torricelli.build(args, device)
    solver = newton.solvers.SolverXPBD(model, **solver_keywords(args, d))
    pipeline = newton.CollisionPipeline(model, soft_contact_max=6 * model.particle_count, soft_contact_gap=0.5 * d)
    states = [model.state(), model.state()]
    frame = Frames(solver, pipeline, pipeline.contacts(), states, args.substeps, device)
    for _ in track(range(round(60.0 * args.seconds)), "hole_cells", unit="frame"):
        frame()
    # (the correction's cells are the solver's own state: read here for the diagnosis only)
    c = solver._fluid.coarse
    row = 0 if c.boxes.dims.numpy()[0][0] else 1
    dims, corner = c.boxes.dims.numpy()[row], c.boxes.corner.numpy()[row]
    edge = c.base_cell * 2.0 ** c.boxes.level.numpy()[row]
    first = c.boxes.first.numpy()[row]
    count = int(np.prod(dims))
    kind = c.kind.numpy()[first : first + count].reshape(dims)
    phi = c.phi.numpy()[first : first + count].reshape(dims)
    centres = [(np.arange(dims[a]) + corner[a] + 0.5) * edge for a in range(3)]
    inner = hole["x_out"] - d
    y0 = 0.5 * (round(args.width / d) - args.hole) * d
    y1 = y0 + args.hole * d
    print(
        f"cells of {edge:.3f} m ({edge / d:.0f} spacings), box {dims}; the holed wall from x = {inner:.3f} to "
        f"{hole['x_out']:.3f} m, the hole y {y0:.3f}-{y1:.3f}, z {hole['z_low']:.3f}-{hole['z_high']:.3f} m"
    )
    xs = [i for i, x in enumerate(centres[0]) if inner - 2.0 * edge < x < hole["x_out"] + 2.0 * edge]
    ys = [j for j, y in enumerate(centres[1]) if y0 - edge < y < y1 + edge]
    zs = [k for k, z in enumerate(centres[2]) if hole["z_low"] - edge < z < hole["z_high"] + edge]
    print("y:" + "".join(f"{centres[1][j]:>9.3f}" for j in ys))
    for i in xs:
        print(f"x = {centres[0][i]:.3f}")
        for k in reversed(zs):
            cells = "".join(f"  {'OSF'[kind[i, j, k]]}{1e4 * phi[i, j, k]:+6.2f}" for j in ys)
            print(f"  z = {centres[2][k]:.3f}{cells}")


if __name__ == "__main__":
    main()
