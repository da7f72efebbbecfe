# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch: the ``fluid_xpbd_foam`` example with and without its particle speed clamp; where spray and water go.

Runs the example headless at ``--particle-count`` for ``--frames`` frames, with ``model.particle_max_velocity`` as
the example set it until 2026-11-30 (``--clamp``: a quarter of a spacing a substep) or without, and
``--wall-height`` and ``--pool-depth`` for the basin's walls and its water [m] (0.6 and 0.06 until 2026-11-30).
Reads every frame back and prints one JSON line: the fastest and highest fluid particle and diffuse particle seen,
the most diffuse and water particles outside the basin's footprint at once, where the first diffuse particle outside
was (position, velocity, kind), what the example's ``test_final`` said, and the fluid's mean density error at the
end. docs/archive/validation_notebook.md, "The foam example's clamp".

Usage: python docs/archive/scratch/foam_clamp.py [--clamp] [--particle-count 4000] [--frames 120] [--wall-height 0.6]
[--pool-depth 0.06]
"""

import argparse
import json

import newton.viewer
import numpy as np
import warp as wp

import newton
from newton._src.solvers.xpbd.fluid.diffuse import DIFFUSE_DEAD
from newton.examples.fluid import example_fluid_xpbd_foam as foam


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clamp", action="store_true", help="keep the example's speed clamp")
    parser.add_argument("--particle-count", type=int, default=4000)
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--wall-height", type=float, default=foam.WALL_HEIGHT)
    parser.add_argument("--pool-depth", type=float, default=foam.POOL_DEPTH)
    parser.add_argument("--device", default=None)
    a = parser.parse_args()
    foam.WALL_HEIGHT = a.wall_height
    foam.POOL_DEPTH = a.pool_depth
    example_args = foam.Example.create_parser().parse_args(
        ["--particle-count", str(a.particle_count), "--viewer", "null", "--num-frames", str(a.frames)]
    )
    with wp.ScopedDevice(a.device):
        if a.clamp:
            # set before the example captures its step in a graph, which takes the value as it is then
            setup = foam.Example.setup_simulation

            def clamped(self):
                self.model.particle_max_velocity = 0.25 * self.spacing / self.sim_dt
                setup(self)

            foam.Example.setup_simulation = clamped
        ex = foam.Example(newton.viewer.ViewerNull(num_frames=a.frames), example_args)
        half = foam.BASIN_HALF
        g = 9.81
        # the fluid's energy per unit mass (kinetic and potential, equal masses) against its start's
        energy0 = float(np.mean(g * ex.state_0.particle_q.numpy()[:, 2]))
        s_energy = {"energy_max_over_start": 0.0, "energy_max_frame": 0}
        s = {"fluid_speed": 0.0, "fluid_z": 0.0, "diffuse_speed": 0.0, "diffuse_z": 0.0, "diffuse_out": 0}
        s.update(water_out=0, first_out=None)
        for frame in range(a.frames):
            ex.step()
            q = ex.state_0.particle_q.numpy()
            v = ex.state_0.particle_qd.numpy()
            kinds = ex.solver.diffuse_kinds.numpy()
            live = kinds != DIFFUSE_DEAD
            p = ex.solver.diffuse_positions.numpy()[live]
            vd = ex.solver.diffuse_velocities.numpy()[live]
            s["fluid_speed"] = max(s["fluid_speed"], float(np.linalg.norm(v, axis=1).max()))
            energy = float(np.mean(0.5 * np.sum(v * v, axis=1) + g * q[:, 2])) / energy0
            if energy > s_energy["energy_max_over_start"]:
                s_energy.update(energy_max_over_start=energy, energy_max_frame=frame + 1)
            if frame + 1 in (15, 30, 45, 60, 75, 90, 120):
                s_energy[f"energy_over_start_frame_{frame + 1}"] = round(energy, 4)
            s["fluid_z"] = max(s["fluid_z"], float(q[:, 2].max()))
            water_out = np.any(np.abs(q[:, :2]) > half + 0.25 * ex.spacing, axis=1)
            s["water_out"] = max(s["water_out"], int(water_out.sum()))
            if len(p) == 0:
                continue
            s["diffuse_speed"] = max(s["diffuse_speed"], float(np.linalg.norm(vd, axis=1).max()))
            s["diffuse_z"] = max(s["diffuse_z"], float(p[:, 2].max()))
            out = np.any(np.abs(p[:, :2]) > half + 1.0e-3, axis=1)
            s["diffuse_out"] = max(s["diffuse_out"], int(out.sum()))
            if out.any() and s["first_out"] is None:
                i = np.flatnonzero(out)[:3]
                s["first_out"] = {
                    "frame": frame + 1,
                    "position": p[i].round(3).tolist(),
                    "velocity": vd[i].round(2).tolist(),
                    "kind": kinds[live][i].tolist(),
                }
        try:
            ex.test_final()
            s["test_final"] = "passed"
        except AssertionError as e:
            s["test_final"] = f"failed: {e}"[:300]
        # read after test_final, whose own report must see the run's counts; the mean error is of the state now
        s["mean_abs_density_error"] = ex.solver.fluid_diagnostics(ex.state_0)["mean_abs_density_error"]
    s.update(s_energy)
    s.update(
        clamp=a.clamp,
        particles=ex.model.particle_count,
        frames=a.frames,
        wall_height=a.wall_height,
        pool_depth=a.pool_depth,
        spacing=ex.spacing,
    )
    print(json.dumps(s))


if __name__ == "__main__":
    main()
