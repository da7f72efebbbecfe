# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The density a rest lattice reads beside a static box's convex edges, its flat faces and a tank's corners.

A wall lends a fluid particle the density of a rest lattice continued beyond the plane of its contact
(:mod:`newton._src.solvers.xpbd.fluid.walls`). Beside a flat face or in a concave corner the solid fills
that half-space; by a convex edge it fills only a wedge of it, and the rest is water whose particles the
sum counts already. This places a rest lattice (spacing 0.05 m, no gravity) in a square tank around a
static box standing on the floor, its faces half a spacing from the nearest particle centres, steps one
substep of one pass, and prints for each group of particles the density that pass read over the rest density
(walls included), and how far the group moves in a frame of 8 substeps x 2 iterations. Run from the
repository root: ``python docs/validation/walls/edge_density.py [--device cpu] [--json F]``.
"""

import argparse
import json
import sys

import numpy as np
import warp as wp

sys.path.insert(0, ".")
import newton  # noqa: E402
from newton.examples.fluid.common import add_tank  # noqa: E402
from newton.tests.test_solver_xpbd_fluid import Sim  # noqa: E402

D, HALF, DEPTH = 0.05, 0.4, 0.45
# the obstacle: |x| <= 0.15, |y| <= 0.2, 0 <= z <= 0.3 [m]
BOX = np.array([0.15, 0.2, 0.3])


def scene(device):
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    n = int(round(2.0 * HALF / D))
    r = -HALF + (np.arange(n) + 0.5) * D
    z = (np.arange(int(round(DEPTH / D))) + 0.5) * D
    x = np.stack(np.meshgrid(r, r, z, indexing="ij"), axis=-1).reshape(-1, 3)
    outside = ~((np.abs(x[:, 0]) < BOX[0]) & (np.abs(x[:, 1]) < BOX[1]) & (x[:, 2] < BOX[2]))
    for p in x[outside]:
        builder.add_particle(
            wp.vec3(*p),
            wp.vec3(0.0),
            1000.0 * D**3,
            radius=0.5 * D,
            flags=newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID,
        )
    cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
    builder.add_ground_plane(cfg=cfg)
    add_tank(builder, HALF, HALF, 1.0, 0.05)
    builder.add_shape_box(
        -1,
        xform=wp.transform(wp.vec3(0.0, 0.0, 0.5 * BOX[2]), wp.quat_identity()),
        hx=BOX[0],
        hy=BOX[1],
        hz=0.5 * BOX[2],
        cfg=cfg,
    )
    return builder.finalize(device=device)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    wp.config.quiet = True
    # one substep of one pass: the density of the lattice as placed
    sim = Sim(scene(args.device), substeps=1, fps=6000.0, contacts=True, fluid_rest_distance=D, iterations=1)
    q0 = sim.q()
    sim.step(1)
    # what the last density pass of the step read, walls included (fluid_diagnostics reads the fluid alone)
    fluid = sim.solver._fluid
    slot_particle = fluid.search.slots.particle.numpy()
    listed = slot_particle >= 0
    rho = np.zeros(sim.model.particle_count)
    rho[slot_particle[listed]] = fluid.density.numpy()[listed] / fluid.rest_density
    q = q0
    # and how far the lattice moves in a frame of 8 x 2 substeps
    moved = Sim(scene(args.device), substeps=8, contacts=True, fluid_rest_distance=D)
    moved.step(1)
    shift = np.linalg.norm(moved.q() - q0, axis=1) / D
    ax, ay, z = np.abs(q[:, 0]), np.abs(q[:, 1]), q[:, 2]
    first = 0.5 * D + 0.01  # within the first layer from a face
    # beside the obstacle's side faces (x), away from its edges and from the floor and the surface
    face = (ax > BOX[0]) & (ax < BOX[0] + first) & (ay < BOX[1] - 2.0 * D) & (z > 2.0 * D) & (z < BOX[2] - 2.0 * D)
    # beside the top face, away from its edges
    top = (z > BOX[2]) & (z < BOX[2] + first) & (ax < BOX[0] - 2.0 * D) & (ay < BOX[1] - 2.0 * D)
    # the diagonal site by the top's long edges (x), and the first layer beside it on either face
    near_edge_x = (ax > BOX[0]) & (ax < BOX[0] + first) & (ay < BOX[1] - 2.0 * D)
    edge_diag = near_edge_x & (z > BOX[2]) & (z < BOX[2] + first)
    edge_side = near_edge_x & (z < BOX[2]) & (z > BOX[2] - first)
    edge_top = (ax < BOX[0]) & (ax > BOX[0] - first) & (ay < BOX[1] - 2.0 * D) & (z > BOX[2]) & (z < BOX[2] + first)
    interior = (np.abs(ax - 0.275) < 0.01) & (ay < 0.1) & (np.abs(z - 0.225) < 0.01)
    corner = (ax > HALF - first) & (ay < 0.1) & (z < first)  # the tank's wall meets its floor
    upright = (ax > HALF - first) & (ay > HALF - first) & (np.abs(z - 0.225) < 0.03)  # two of its walls meet
    groups = {
        "interior": interior,
        "beside a side face": face,
        "on the top face": top,
        "convex edge, diagonal": edge_diag,
        "convex edge, beside the side face": edge_side,
        "convex edge, on the top face": edge_top,
        "concave corner (tank wall and floor)": corner,
        "concave corner (two tank walls)": upright,
    }
    record = {"device": args.device, "spacing_m": D, "particles": int(len(q)), "groups": {}}
    for name, sel in groups.items():
        values = rho[sel]
        record["groups"][name] = {
            "count": int(sel.sum()),
            "mean": float(values.mean()),
            "max": float(values.max()),
            "moved_in_a_frame_d": float(shift[sel].mean()),
        }
        print(
            f"{name:38s} {sel.sum():3d} particles: density / rest {values.mean():.4f} (max {values.max():.4f}),"
            f" moved {shift[sel].mean():.4f} d in a frame"
        )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
