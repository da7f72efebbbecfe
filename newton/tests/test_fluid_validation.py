# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Validation: the dam-break surge front of Koshizuka & Oka (1996), coarse, and a water column at rest.

Runs ``benchmarks/validate_dam_break.py`` (part of the source checkout) at 20 particles across
the column width with the solver's defaults (2 iterations, 8 substeps, no cohesion, no viscosity,
no speed clamp, frictionless floor). At that setting the front was measured 4 % behind to 17 %
ahead of the experiment (docs/archive/validation_notebook.md); the bounds here catch a front that is held back
(e.g. by a speed clamp) or runs away, not the last few percent.

Runs ``benchmarks/hydrostatic_drift.py`` with ``fluid_density_ramp=0.001`` for the issue's
hydrostatic target: a settled column drifts less than 0.05 spacings over 5 s.

Runs ``benchmarks/sloshing.py``, ``benchmarks/torricelli.py`` and ``benchmarks/hydrostatic_pressure.py``
small, against exact answers: the first standing wave's period against linear theory, the jet of a
draining tank against Torricelli's speed, and the pressure in a settled column against rho g (H - z)
(docs/archive/validation_notebook.md "Exact answers").
"""

import argparse
import contextlib
import importlib
import io
import json
import sys
import unittest
import warnings
from pathlib import Path

import numpy as np
from newton.tests.unittest_utils import add_function_test, get_test_devices

BENCHMARK = Path(__file__).resolve().parents[2] / "benchmarks" / "validate_dam_break.py"
HYDROSTATIC = BENCHMARK.parent / "hydrostatic_drift.py"
SLOSHING = BENCHMARK.parent / "sloshing.py"
TORRICELLI = BENCHMARK.parent / "torricelli.py"
PRESSURE = BENCHMARK.parent / "hydrostatic_pressure.py"


def load_benchmark(path=BENCHMARK):
    """The module of the benchmark at ``path``, imported as the case of the ``benchmarks`` package it is."""
    root = str(path.parents[1])
    sys.path.insert(0, root)
    try:
        return importlib.import_module(f"benchmarks.{path.stem}")
    finally:
        sys.path.remove(root)


def surge_args(bench, iterations: int) -> argparse.Namespace:
    """``validate_dam_break.run``'s settings: 4 layers deep, 8 substeps, no cohesion, viscosity, clamp or friction."""
    parser = argparse.ArgumentParser()
    bench.add_solver_arguments(parser)  # the solver's keywords as the benchmark's flags, unset: its defaults
    args = parser.parse_args(["--substeps", "8", "--iterations", str(iterations)])
    args.depth, args.speed_clamp, args.floor_friction, args.settle = 4, 0.0, 0.0, 0.0
    return args


def test_surge_front_matches_experiment(test, device):
    if not BENCHMARK.is_file():
        test.skipTest("benchmarks/ is part of the source checkout, not of the installed wheel")
    bench = load_benchmark()
    data = json.loads(bench.DATA.read_text())
    points = np.asarray(data["points"])
    args = surge_args(bench, iterations=2)
    # 40 layers for 2 iterations: g H / c^2 = 5.8 % (c = 2 x spacing / substep), beyond the 3 % the
    # solve holds, so the collapse compresses the bottom past 10 % in some substeps, and the run says so
    with test.assertWarnsRegex(RuntimeWarning, "past 10 % compression"):
        result = bench.run(20, args, points, device)
    error = np.asarray(result["relative_error"])
    test.assertLess(np.abs(error).max(), 0.25, error)
    test.assertLess(np.abs(error).mean(), 0.12, error)
    # the front advances monotonically, and faster than the column's own creep
    z = np.asarray(result["Z_simulated"])
    test.assertTrue(np.all(np.diff(z) >= 0.0), z)
    test.assertGreater(z[-1], 3.0)


def test_converged_surge_front_within_bound(test, device):
    # The surge front is a reported figure, not a target (issue #27): with 4 iterations it has converged
    # (20 / 30 / 40 per L within 1.2 % of each other) and runs ahead of the experiment: here (20 per L, 4
    # particles deep, CPU) by up to 16.3 % (18.6 % 6 deep), the gate's lift and the floor's boundary layer
    # being what the model leaves out (docs/archive/validation_notebook.md). The bound it is held to: every point within 20 %.
    if not BENCHMARK.is_file():
        test.skipTest("benchmarks/ is part of the source checkout, not of the installed wheel")
    bench = load_benchmark()
    points = np.asarray(json.loads(bench.DATA.read_text())["points"])
    args = surge_args(bench, iterations=4)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = bench.run(20, args, points, device)
    for w in caught:
        test.assertRegex(str(w.message), "past 10 % compression")
    error = np.asarray(result["relative_error"])
    test.assertLess(np.abs(error).max(), 0.20, error)
    # it runs ahead (the lead the bound allows), not behind
    test.assertGreater(error[-3:].min(), 0.0, error)


def test_settled_column_stays_at_rest(test, device):
    # 6 x 6 x 10 particles in a walled tank, 8 substeps x 2 iterations, viscosity 0.05: after 8 s of settling
    # the mean displacement over the next 5 s. Measured 0.041 spacings (CPU, the default stable step and
    # non-affine damping; 0.023 with a step of 1 and no damping, whose column hummed instead) with the ramp;
    # without it the settled packing keeps slipping (0.046-0.097 in the runs of docs/archive/validation_notebook.md)
    if not HYDROSTATIC.is_file():
        test.skipTest("benchmarks/ is part of the source checkout, not of the installed wheel")
    bench = load_benchmark(HYDROSTATIC)
    with contextlib.redirect_stdout(io.StringIO()):  # its table
        result = bench.main(["--density-ramp", "0.001", "--settle", "8", "--device", str(device)])
    last = result["rows"][-1]
    test.assertEqual(last["t_after_settling_s"], 5)
    test.assertLess(last["mean_spacings"], 0.05, last)
    test.assertEqual(last["outside_tank"], 0)
    test.assertLess(last["max_compression"], 0.01)


def run_benchmark(test, path, argv: list[str], device, keep: tuple[str, ...] = ()) -> dict:
    if not path.is_file():
        test.skipTest("benchmarks/ is part of the source checkout, not of the installed wheel")
    bench = load_benchmark(path)
    with contextlib.redirect_stdout(io.StringIO()):  # its table
        record = bench.main([*argv, "--device", str(device)])
    # the scalars (and the lists in ``keep``) only: failure messages without the sampled signals
    return {k: v for k, v in record.items() if k in keep or not isinstance(v, list)}


def test_standing_wave_period(test, device):
    # 20 particles per tank length, h / L = 0.5, 4 across (800 particles a tank), a / h = 0.2, 32 substeps x 2
    # iterations without the non-affine damping, read over 16 starts a micrometre apart (isolated worlds of one
    # model). One start's period scatters with its settled start by about 3 % (standard deviation): settled 1-3 s,
    # one start read -1.7 to +7.7 %, so a single reading would fail the bound on a change that only moves the start.
    # Measured (CPU, 2026-11-30) at the defaults, the one kernel: -3.6 +- 0.3 % (linear theory 0.836 s; one start's
    # standard deviation 1.3 %), 41 % of the amplitude kept per period; with poly6, the default before, +3.4 +- 0.8 %
    # (3.2 %), 45 % (docs/validation/sloshing/sloshing_starts_16_amplitude_0.2_32x2_{one_kernel_default,poly6}_
    # 2026-11-30_cpu.json). At 8 substeps
    # the first mode runs near the shallow-water period (-17 to -22 %) and at a / h = 0.1 the tank's own motion moves
    # its crossings by a few percent, which is why this test takes 32 substeps and a / h = 0.2; the 90 % kept
    # per period is not met (open).
    r = run_benchmark(
        test,
        SLOSHING,
        ["--substeps", "32", "--nonaffine-damping", "0", "--amplitude", "0.2", "--periods", "3", "--settle", "1"]
        + ["--starts", "16", "--energy"],
        device,
        keep=("energy", "per_start"),
    )
    test.assertEqual(r["period_error_unread"], 0, r)
    test.assertGreaterEqual(min(start["periods_measured"] for start in r["per_start"]), 2.0, r)
    # half a period in, the mode's velocity field holds part of the energy the wave started with, not more
    # (measured 0.31 on the CPU: the rest went into particle-scale motion, docs/archive/validation_notebook.md)
    half = r["energy"][1]["mode_kinetic_J"] / r["wave_energy_J"]
    test.assertGreater(half, 0.05, r["energy"])
    test.assertLess(half, 1.05, r["energy"])
    test.assertLess(abs(r["period_error_mean"]), 0.05, r)
    # the first extreme of the centre of mass: the mode was set up in every tank, not a tank that barely moves
    for start in r["per_start"]:
        test.assertGreater(start["first_extreme_m"], 0.5 * r["theory_first_extreme_m"], start)
        test.assertLess(start["first_extreme_m"], 1.1 * r["theory_first_extreme_m"], start)
    test.assertGreater(r["amplitude_kept_per_period_mean"], 0.3, r)


def test_corrected_standing_wave_period(test, device):
    # the one kernel with the coarse correction (20 per L, h / L 0.5, 4 across, 800 particles, 8 x 2, the default
    # damping, a / h = 0.1, settled 1 s). The correction carries much of the wave's restoring pressure, so where its
    # free surface sits sets the period: at the fluid's top (from the surface cells' fill) the wave runs 8.6 % fast on
    # the CPU (12 % on an H200, 8 across; the kernel's shear stiffness), at the surface cells' centres 22.5 % slow
    # (docs/archive/patches/coarse_surface_at_cell_centres.patch; 25-30 % over 64 starts on an H200)
    r = run_benchmark(
        test,
        SLOSHING,
        ["--density-kernel", "one_kernel", "--coarse-correction", "0.5", "--periods", "3", "--settle", "1"],
        device,
    )
    test.assertGreaterEqual(r["periods_measured"], 2.0, r)
    test.assertLess(r["period_error"], 0.0, r)
    test.assertGreater(r["period_error"], -0.15, r)
    test.assertGreater(r["amplitude_kept_per_period"], 0.35, r)


def test_standing_wave_over_starts(test, device):
    # --starts N runs N tanks as isolated worlds of one model, world w's lattice moved by up to w x 1e-6
    # spacings: the wave's reading scatters from start to start by more than the 2 % (archive,
    # "The density kernel in the solver"), so its period is read as a mean over starts. World 0 starts on
    # the unmoved lattice: on the CPU its run is bitwise the run of a model that holds it alone.
    argv = ["--amplitude", "0.2", "--periods", "2", "--settle", "0.5"]
    alone = run_benchmark(test, SLOSHING, argv, device, keep=("signal_m",))
    r = run_benchmark(test, SLOSHING, [*argv, "--starts", "3"], device, keep=("signal_m", "per_start"))
    signal, first = np.asarray(r["signal_m"]), np.asarray(alone["signal_m"])
    test.assertEqual(signal.shape, (len(first), 3))
    if device.is_cpu:
        np.testing.assert_array_equal(signal[:, 0], first)
    # the moved starts are other runs (a flow this short and damped still tells them apart)
    test.assertGreater(np.abs(signal[:, 1] - signal[:, 0]).max(), 0.0)
    test.assertGreater(np.abs(signal[:, 2] - signal[:, 1]).max(), 0.0)
    for start in r["per_start"]:
        test.assertGreater(start["first_extreme_m"], 0.5 * r["theory_first_extreme_m"], start)
        test.assertLess(start["first_extreme_m"], 1.1 * r["theory_first_extreme_m"], start)
    errors = [start["period_error"] for start in r["per_start"]]
    test.assertAlmostEqual(r["period_error_mean"], float(np.mean(errors)), places=12)
    test.assertAlmostEqual(r["period_error_se"], float(np.std(errors, ddof=1) / np.sqrt(3.0)), places=12)
    test.assertEqual(r["starts"], 3)
    with test.assertRaisesRegex(ValueError, "--starts is 0"):
        run_benchmark(test, SLOSHING, [*argv, "--starts", "0"], device)


def test_torricelli_jet_speed(test, device):
    # a 0.2 x 0.12 m tank filled 0.3 m high (spacing 0.02 m, 900 particles), a hole of 4 x 4 spacings 4
    # spacings above the floor, 8 substeps x 2 iterations, 1 s. Measured (CPU): the jet past the vena
    # contracta at 0.92 of sqrt(2 g H) (frames from 0.83 to 1.12) without the non-affine damping; with the
    # default 0.1 per substep the damping takes the jet's shear layer and it leaves at 0.75 or less.
    argv = ["--length", "0.2", "--width", "0.12", "--height", "0.3", "--seconds", "1.0"]
    undamped = run_benchmark(test, TORRICELLI, [*argv, "--nonaffine-damping", "0"], device)
    test.assertTrue(undamped["all_finite"])
    test.assertGreater(undamped["speed_samples"], 20, undamped)
    test.assertLess(abs(undamped["jet_speed_ratio_mean"] - 1.0), 0.1, undamped)
    test.assertGreater(undamped["drained_fraction"], 0.1, undamped)
    # the damped jet lands on the ground with a splash some substeps of which end past 10 % compression
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        damped = run_benchmark(test, TORRICELLI, argv, device)
    for w in caught:
        test.assertRegex(str(w.message), "past 10 % compression")
    test.assertLess(damped["jet_speed_ratio_mean"], undamped["jet_speed_ratio_mean"], damped)


def test_hydrostatic_pressure(test, device):
    # 8 x 8 x 16 particles (spacing 0.05 m) settled in a closed box, 8 substeps x 2 iterations, the
    # default keywords; the pressure the density multipliers imply, averaged over 1 s. Measured (CPU):
    # the floor force 0.9 % above the weight, the side wall's 1.0 % below rho g H^2 W / 2, the pressure
    # gradient 2.9 % steep; single layers next to the floor alternate by up to 14 %, an alternation that
    # exerts no force: through a [1,2,1] filter over the layers, every layer from the second up is within
    # 2.6 %; the mean over the layers below the top two is 1.2 % low.
    r = run_benchmark(test, PRESSURE, [], device)
    test.assertLess(abs(r["floor_force_error"]), 0.02, r)
    test.assertLess(abs(r["side_force_error"]), 0.05, r)
    test.assertLess(abs(r["pressure_gradient_error"]), 0.05, r)
    test.assertLess(abs(r["pressure_error_mean"]), 0.05, r)
    test.assertLess(r["pressure_error_max_filtered"], 0.05, r)
    # the walls' ghost density carries most of the load, the particle-shape contacts the rest
    test.assertGreater(r["floor_ghost_force_share"], 0.5, r)
    test.assertLess(r["floor_ghost_force_share"], 1.0, r)
    test.assertEqual(r["coarse_pressure_share"], 0.0, r)


def test_hydrostatic_pressure_reads_the_kernel_and_the_correction(test, device):
    # The column of test_hydrostatic_pressure with fluid_density_kernel="one_kernel", whose multipliers move the
    # particles along that kernel's own gradient. Measured (CPU): the floor force 0.5 % below the weight, every
    # filtered layer within 3.6 %; read with the spiky gradient and poly6's rest density, as the read-out did
    # before it knew the kernel, every pressure is 14 % high.
    alone = run_benchmark(test, PRESSURE, ["--density-kernel", "one_kernel"], device)
    test.assertLess(abs(alone["floor_force_error"]), 0.02, alone)
    test.assertLess(alone["pressure_error_max_filtered"], 0.05, alone)
    # With fluid_coarse_correction=0.5 as well, the correction's potential carries most of the pressure (CPU:
    # 0.93 of it; the multipliers alone would read the floor 91 % low). Its gradient is rho g within 2.6 %; the
    # floor force reads 6 % high: the line through the potential's layers reaches zero 0.3 spacings above the
    # level (where the cells' fill puts the surface) and the clamped multipliers add 0.2 spacings of pressure.
    pair = run_benchmark(test, PRESSURE, ["--density-kernel", "one_kernel", "--coarse-correction", "0.5"], device)
    test.assertGreater(pair["coarse_pressure_share"], 0.5, pair)
    test.assertLess(abs(pair["pressure_gradient_error"]), 0.05, pair)
    test.assertLess(abs(pair["floor_force_error"]), 0.1, pair)


class TestFluidValidation(unittest.TestCase):
    def test_wave_period_read_past_an_offset(self):
        # a decaying wave whose centre of mass settles 0.3 mm off zero, as the CPU's 20 per L wave did with the
        # damping every substep (docs/validation.rst, "Still water and floating bodies"): the offset moves the zero
        # crossings (the halves alternate long and short, and the count read differs), not the extremes
        if not SLOSHING.is_file():
            self.skipTest("benchmarks/ is part of the source checkout, not of the installed wheel")
        sloshing = load_benchmark(SLOSHING)
        # (a decaying sine's extremes and crossings are both half a period apart)
        period, decay, amplitude = 0.64, 1.0, 0.007  # [s], [1/s], [m]
        t = np.arange(541) / 60.0
        wave = -amplitude * np.exp(-decay * t) * np.sin(2.0 * np.pi * t / period)
        clean = sloshing.analyse(t, wave, periods=3)
        off = sloshing.analyse(t, wave - 0.0003 * (1.0 - np.exp(-2.0 * t)), periods=3)
        for r in (clean, off):
            self.assertAlmostEqual(r["period_from_extremes_s"], period, delta=0.01 * period)
        self.assertAlmostEqual(clean["period_s"], period, delta=0.005 * period)
        self.assertGreater(abs(off["period_s"] - period), 0.02 * period, off)
        self.assertLess(abs(off["period_from_extremes_s"] - period), abs(off["period_s"] - period) / 3.0, off)


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestFluidValidation, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
