# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Dam-break surge front against the experiment of Koshizuka & Oka (1996).

A water column of width L and height 2L (L = 0.146 m) stands against the -x wall of a tank on a
dry, frictionless floor; the tank is ``--depth`` particle layers deep in y between frictionless
walls (a slice of the 2D experiment). After release, the surge front (the 99.9th percentile of x
over the particles within two spacings of the floor, measured from the wall behind the column)
is compared with the measured front at each data point of
``benchmarks/data/dam_break_koshizuka_oka_1996.json`` (the measured data, with its source) (T = t sqrt(2g/L), Z = front / L), at each
resolution of ``--resolutions`` (particles across L). Prints a table and writes JSON: the
relative error at every point, and the machine, device, particle count, substeps and iterations.

The column starts as a lattice at rest distance, unloaded; with ``--settle S`` it first settles
for S seconds behind a frictionless gate at its front face (so it starts, as in the experiment,
at rest under its own weight) and is released at T = 0 (the gate gone at once).

Usage::

    python -m benchmarks validate_dam_break [--resolutions 20 30 40] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
import warp as wp

import newton
from newton.examples.fluid.common import add_water_lattice
from newton.examples.fluid.progress import track

from .frames import add_solver_arguments, solver_keywords, solver_record
from .run_record import write_record

DATA = Path(__file__).resolve().parent / "data" / "dam_break_koshizuka_oka_1996.json"
L = 0.146  # column width [m] (Koshizuka & Oka's, after Martin & Moyce)
G = 9.81


def surge_front(q: np.ndarray, d: float) -> float:
    """Front position [m]: the 99.9th percentile of x within two spacings of the floor, plus half a spacing.

    ``q`` is measured from the column's back face (x) and the floor (z).
    """
    low = q[q[:, 2] < 2.0 * d]
    return float(np.percentile(low[:, 0], 99.9) + 0.5 * d) if len(low) else 0.0


def build(
    per_l: int,
    depth_layers: int,
    args,
    device,
    height: float = 2.5 * L,
    wall_gap: float = 0.0,
    gate: bool = False,
    **solver_kwargs,
):
    """The tank and column of Koshizuka & Oka at ``per_l`` particles across L: (model, solver, pipeline, dt).

    ``args`` supplies ``substeps``, ``speed_clamp`` and ``floor_friction``; ``solver_kwargs`` (``iterations``
    and ``fluid_*`` keywords) go to the solver, at its defaults otherwise. The column's back face is at
    x = 0 and its bottom at z = 0; the floor and the walls are ``wall_gap`` [m] beyond the column's faces
    (and the far wall that far beyond 5L). With ``gate``, a frictionless wall stands at the column's
    front face.
    """
    d = L / per_l
    builder = newton.ModelBuilder()
    add_water_lattice(builder, d, (per_l, depth_layers, 2 * per_l))
    cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
    # XPBD's particle-shape friction is the mean of model.soft_contact_mu (0 below) and the shape's mu:
    # the floor's 2 f gives the floor friction f, the walls' 0 frictionless walls
    builder.add_ground_plane(height=-wall_gap, cfg=newton.ModelBuilder.ShapeConfig(mu=2.0 * args.floor_friction))
    t = 0.05
    g = wall_gap
    width = depth_layers * d
    length = 5.0 * L
    # every wall reaches through the walls it meets to their outer faces, and 2t into the floor: a box's
    # nearest face pushes a particle pressed into it, so a face flush with a neighbour's inner face or with
    # the floor would push particles pressed into the joint out through it
    zc, hz = 0.5 * (height - g - 2 * t), 0.5 * (height + g + 2 * t)
    walls = [
        ((-t - g, 0.5 * width, zc), (t, 0.5 * width + 2 * t + g, hz)),
        ((length + t + g, 0.5 * width, zc), (t, 0.5 * width + 2 * t + g, hz)),
        ((0.5 * length, -t - g, zc), (0.5 * length + g + 2 * t, t, hz)),
        ((0.5 * length, width + t + g, zc), (0.5 * length + g + 2 * t, t, hz)),
    ]
    if gate:
        walls.append(((L + t + g, 0.5 * width, zc), (t, 0.5 * width + g + 2 * t, hz)))
    for center, half in walls:
        builder.add_shape_box(
            -1, xform=wp.transform(wp.vec3(*center), wp.quat_identity()), hx=half[0], hy=half[1], hz=half[2], cfg=cfg
        )
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    dt = 1.0 / (60.0 * args.substeps)
    if args.speed_clamp > 0.0:
        model.particle_max_velocity = args.speed_clamp * 0.5 * d / dt
    solver = newton.solvers.SolverXPBD(model, **{"fluid_rest_distance": d, **solver_kwargs})
    pipeline = newton.CollisionPipeline(model, soft_contact_max=model.particle_count, soft_contact_gap=0.5 * d)
    return model, solver, pipeline, dt


def build_plain(per_l: int, depth_layers: int, substeps: int, device, height: float = 4.0 * L, **kwargs):
    """The column in a tank ``height`` tall (default 4L) with nothing but the density solve at the solver's
    defaults (no cohesion, viscosity, speed clamp or friction) unless ``kwargs`` set keywords.

    The scene of the speed-accuracy sweep, the reference comparison and the column-depth map;
    ``kwargs`` (``iterations``, ``fluid_*``: :func:`~.frames.solver_keywords`; ``gate``, ``wall_gap``) go
    to :func:`build`.
    """
    cfg = argparse.Namespace(substeps=substeps, speed_clamp=0.0, floor_friction=0.0)
    return build(per_l, depth_layers, cfg, device, height=height, **kwargs)


class Stepper:
    """The two states and the contacts of a scene from :func:`build`, stepped forward to given times."""

    def __init__(self, model, solver, pipeline, dt: float):
        self.solver, self.pipeline, self.dt = solver, pipeline, dt
        self.state, self._next = model.state(), model.state()
        self.contacts = pipeline.contacts()
        self.time, self.steps = 0.0, 0

    def advance_to(self, t: float):
        """Step until the simulated time is within half a substep of ``t`` [s]; return the current state."""
        while self.time < t - 0.5 * self.dt:
            self.state.clear_forces()
            self.pipeline.collide(self.state, self.contacts)
            self.solver.step(self.state, self._next, None, self.contacts, self.dt)
            self.state, self._next = self._next, self.state
            self.time += self.dt
            self.steps += 1
        return self.state


def run(per_l: int, args, points: np.ndarray, device) -> dict:
    d = L / per_l
    kwargs = solver_keywords(args, d)
    model, solver, pipeline, dt = build(per_l, args.depth, args, device, **kwargs)
    stepper = Stepper(model, solver, pipeline, dt)
    if args.settle > 0.0:
        # the same column settled behind the gate, then released at rest
        settling = Stepper(*build(per_l, args.depth, args, device, gate=True, **kwargs))
        stepper.state.particle_q.assign(settling.advance_to(args.settle).particle_q)
        stepper.state.particle_qd.zero_()
    t_scale = math.sqrt(L / (2.0 * G))  # t = T * t_scale
    times = points[:, 0] * t_scale
    fronts = np.asarray([surge_front(stepper.advance_to(t).particle_q.numpy(), d) / L for t in times])
    stats = solver.fluid_diagnostics(stepper.state)
    error = (fronts - points[:, 1]) / points[:, 1]
    return {
        "particles_per_L": per_l,
        "spacing_m": d,
        "particles": int(model.particle_count),
        "T": points[:, 0].tolist(),
        "Z_experiment": points[:, 1].tolist(),
        "Z_simulated": fronts.tolist(),
        "relative_error": error.tolist(),
        "max_abs_relative_error": float(np.abs(error).max()),
        "mean_abs_relative_error": float(np.abs(error).mean()),
        # the solver's density measure at the last data point (walls not counted)
        "mean_abs_density_error": stats["mean_abs_density_error"],
        "max_compression": stats["max_compression"],
        # density passes that corrected per substep after the release (tolerance mode)
        "density_passes_per_substep": stats["density_subiterations"] / max(stepper.steps, 1),
        **solver_record(solver),
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--resolutions", type=int, nargs="+", default=[20, 30, 40], help="particles across L")
    parser.add_argument("--depth", type=int, default=6, help="particle layers in y")
    parser.add_argument("--speed-clamp", type=float, default=0.0, help="max displacement per substep [radii]; 0: off")
    parser.add_argument("--floor-friction", type=float, default=0.0, help="Coulomb friction of the floor (walls: 0)")
    parser.add_argument(
        "--settle",
        type=float,
        default=0.0,
        help="settle the column behind a gate this long first [s]; 0: lattice start",
    )
    add_solver_arguments(parser)
    parser.add_argument("--data", default=str(DATA))
    args = parser.parse_args(argv)

    data = json.loads(Path(args.data).read_text())
    points = np.asarray(data["points"], dtype=np.float64)
    wp.init()
    device = wp.get_device(args.device)
    runs = [run(n, args, points, device) for n in track(args.resolutions, "validate_dam_break")]
    print(f"{'T':>6} {'Z exp':>7} " + " ".join(f"{'Z @' + str(r['particles_per_L']):>9} {'err':>7}" for r in runs))
    for k, (t_value, z_exp) in enumerate(points):
        cells = " ".join(f"{r['Z_simulated'][k]:9.3f} {100 * r['relative_error'][k]:6.1f}%" for r in runs)
        print(f"{t_value:6.3f} {z_exp:7.3f} {cells}")
    for r in runs:
        print(
            f"{r['particles_per_L']:>3} per L ({r['particles']} particles): max |error| "
            f"{100 * r['max_abs_relative_error']:.1f} %, mean {100 * r['mean_abs_relative_error']:.1f} %; "
            f"density at the end: mean|e| {100 * r['mean_abs_density_error']:.2f} %, max compression "
            f"{100 * r['max_compression']:.2f} %"
        )
    result = {
        "reference": data["source"],
        "L_m": L,
        "depth_layers": args.depth,
        "substeps": args.substeps,
        "speed_clamp_radii_per_substep": args.speed_clamp,
        "floor_friction": args.floor_friction,
        "settle_s": args.settle,
    }
    return write_record("validate_dam_break", device, result, args.json, rows=runs)


if __name__ == "__main__":
    main(sys.argv[1:])
