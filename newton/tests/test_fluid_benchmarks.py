# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The benchmark tool: ``python -m benchmarks <case>`` finds every case, and the solver's keywords have one flag name."""

import argparse
import contextlib
import importlib
import io
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

import warp as wp
from newton.tests.unittest_utils import add_function_test

ROOT = Path(__file__).resolve().parents[2]
HAS_BENCHMARKS = (ROOT / "benchmarks" / "__main__.py").is_file()


class _Parsed(Exception):
    def __init__(self, parser):
        super().__init__()
        self.parser = parser


def case_parser(name: str) -> argparse.ArgumentParser:
    """The argument parser a case's ``main`` builds (caught as it parses, before the case runs)."""
    module = importlib.import_module(f"benchmarks.{name}")
    original = argparse.ArgumentParser.parse_args

    def catch(self, *args, **kwargs):
        raise _Parsed(self)

    argparse.ArgumentParser.parse_args = catch
    try:
        module.main([])
    except _Parsed as parsed:
        return parsed.parser
    finally:
        argparse.ArgumentParser.parse_args = original
    raise AssertionError(f"benchmarks.{name}.main parsed no arguments")


def test_every_case_listed_and_parsed(test, device):
    if not HAS_BENCHMARKS:
        test.skipTest("benchmarks/ is part of the source checkout, not of the installed wheel")
    out = subprocess.run(
        [sys.executable, "-m", "benchmarks", "--list"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    test.assertEqual(out.returncode, 0, out.stderr)
    sys.path.insert(0, str(ROOT))
    try:
        from benchmarks import ALIASES, HELPERS  # noqa: PLC0415
        from benchmarks.__main__ import cases  # noqa: PLC0415
        from benchmarks.frames import SOLVER_KEYWORDS, solver_flag  # noqa: PLC0415

        files = sorted(p.stem for p in (ROOT / "benchmarks").glob("*.py") if not p.stem.startswith("_"))
        test.assertEqual(cases(), [f for f in files if f not in HELPERS])
        for alias, name in ALIASES.items():
            test.assertIn(name, cases(), alias)
        for name in cases():
            test.assertIn(name, out.stdout)
            with contextlib.redirect_stdout(io.StringIO()):
                parser = case_parser(name)
            # a flag that sets a solver keyword is named after it (its help names the keyword first)
            for action in parser._actions:
                words = (action.help or "").split()
                keyword = words[0] if words else None
                if keyword in SOLVER_KEYWORDS:
                    with test.subTest(case=name, keyword=keyword):
                        test.assertIn(solver_flag(keyword), action.option_strings)
    finally:
        sys.path.remove(str(ROOT))


def test_unknown_case_is_refused(test, device):
    if not HAS_BENCHMARKS:
        test.skipTest("benchmarks/ is part of the source checkout, not of the installed wheel")
    out = subprocess.run(
        [sys.executable, "-m", "benchmarks", "dam_brake"], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    test.assertEqual(out.returncode, 2)
    test.assertIn("unknown case 'dam_brake'", out.stderr)
    test.assertIn("dam_break (perf)", out.stderr)


def test_every_case_writes_the_same_record(test, device):
    """Each case writes its JSON through run_record.write_record, which refuses a run without the particle
    count, substeps, iterations and density error (a small case's record carries them on every row), and
    none reads the solver's private state."""
    if not HAS_BENCHMARKS:
        test.skipTest("benchmarks/ is part of the source checkout, not of the installed wheel")
    sys.path.insert(0, str(ROOT))
    try:
        from benchmarks import inactive_pool  # noqa: PLC0415
        from benchmarks.__main__ import cases  # noqa: PLC0415
        from benchmarks.run_record import RUN_FIELDS, write_record  # noqa: PLC0415

        for name in cases():
            with test.subTest(case=name):
                source = (ROOT / "benchmarks" / f"{name}.py").read_text()
                test.assertIn("write_record(", source)
                # and reads the solver and renderer through their public attributes
                test.assertNotRegex(source, r"\._fluid\b|\._cuda_interop\b")
                # a case that makes its own solver takes every keyword as a flag from the solver's table
                if re.search(r"SolverXPBD\(|build_plain\(|\bbuild\(per_l", source):
                    test.assertIn("add_solver_arguments(", source)
        cpu = wp.get_device("cpu")
        with test.assertRaisesRegex(ValueError, r"'x': the record lacks \['substeps', 'iterations', 'mean_abs"):
            write_record("x", cpu, {"particles": 10, "max_compression": 0.0}, None)
        rows = [{"particles": 10, "mean_abs_density_error": 0.0, "max_compression": 0.0}, {"particles": 10}]
        with test.assertRaisesRegex(ValueError, r"'x': the record row 1 lacks \['mean_abs_density_error'"):
            write_record("x", cpu, {"substeps": 8, "iterations": 2}, None, rows=rows)
        write_record("x", cpu, {"substeps": 8, "iterations": 2}, None, rows=rows[:1])  # shared settings count
        write_record("x", cpu, {"particles": 10}, None, fluid_step=False)
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "pool.json")
            with contextlib.redirect_stdout(io.StringIO()):
                inactive_pool.main(
                    ["--active", "343", "--pool", "100", "--repeats", "2", "--device", "cpu", "--json", path]
                )
            with open(path) as f:
                record = json.load(f)
        test.assertEqual(record["benchmark"], "inactive_pool")
        test.assertEqual(record["device"], "cpu")
        test.assertEqual([r["inactive"] for r in record["rows"]], [0, 100])
        for row in record["rows"]:
            for field in RUN_FIELDS:
                test.assertIn(field, row)
            test.assertEqual(row["active"], 343)
            test.assertTrue(math.isfinite(row["ms_per_substep"]))
    finally:
        sys.path.remove(str(ROOT))


@contextlib.contextmanager
def benchmark_module(test, name: str):
    """``benchmarks.<name>`` imported from the source checkout (the test skips without one)."""
    if not HAS_BENCHMARKS:
        test.skipTest("benchmarks/ is part of the source checkout, not of the installed wheel")
    sys.path.insert(0, str(ROOT))
    try:
        yield importlib.import_module(f"benchmarks.{name}")
    finally:
        sys.path.remove(str(ROOT))


def test_rest_column_splits_speed_by_scale(test, device):
    # rest_column's split of the RMS speed: a lattice of 8^3 particles in cells of 4 x 4 x 4
    import numpy as np  # noqa: PLC0415

    with benchmark_module(test, "rest_column") as rest_column:
        g = (np.arange(8) + 0.5) * 0.1
        q = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
        cell = 0.4
        # the fluid moving together
        v = np.tile([0.3, 0.0, -0.4], (len(q), 1))
        np.testing.assert_allclose(rest_column.velocity_scales(q, v, cell), (0.5, 0.0, 0.0), atol=1e-12)
        # cells moving against each other, each one rigidly: a long wave
        v = np.zeros_like(q)
        v[:, 2] = np.where(q[:, 0] < cell, 0.2, -0.2)
        np.testing.assert_allclose(rest_column.velocity_scales(q, v, cell), (0.0, 0.2, 0.0), atol=1e-12)
        # neighbours moving against each other: particle scale
        v = np.zeros_like(q)
        v[:, 1] = 0.1 * (-1.0) ** np.arange(len(q))
        np.testing.assert_allclose(rest_column.velocity_scales(q, v, cell), (0.0, 0.0, 0.1), atol=1e-12)


def test_rest_column_reads_the_surface(test, device):
    # the surface's span: the top particle of each column of cells two spacings wide, whichever particles they are
    import numpy as np  # noqa: PLC0415

    with benchmark_module(test, "rest_column") as rest_column:
        span = rest_column.surface_span
        d = 0.05
        g = (np.arange(6) + 0.5) * d
        q = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
        test.assertAlmostEqual(span(q, d), 0.0, places=9)
        # a top particle sunk into a hollow: its cell's neighbours still stand at the top
        top = np.flatnonzero(np.isclose(q[:, 2], g[-1]))
        sunk = q.copy()
        sunk[top[0], 2] -= 0.7 * d
        test.assertAlmostEqual(span(sunk, d), 0.0, places=9)
        # a particle raised half a spacing, and a whole cell's top layer gone
        raised = q.copy()
        raised[top[0], 2] += 0.5 * d
        test.assertAlmostEqual(span(raised, d), 0.5, places=6)
        cell = (q[:, 0] < 2 * d) & (q[:, 1] < 2 * d) & np.isclose(q[:, 2], g[-1])
        test.assertAlmostEqual(span(q[~cell], d), 1.0, places=6)


def test_rest_column_offset_moves_the_start(test, device):
    # rest_column --offset: another draw of the same still water, the column's start moved along x alone
    import numpy as np  # noqa: PLC0415

    with benchmark_module(test, "rest_column") as rest_column:
        at_rest = rest_column.build(3, 2, device).particle_q.numpy()
        moved = rest_column.build(3, 2, device, offset=0.02).particle_q.numpy()
        np.testing.assert_allclose(moved[:, 0] - at_rest[:, 0], 0.02 * rest_column.SPACING, rtol=1e-4)
        np.testing.assert_array_equal(moved[:, 1:], at_rest[:, 1:])
        test.assertIn("--offset", case_parser("rest_column").format_help())


def test_rest_column_windows_read_as_separate_runs(test, device):
    # rest_column --settle S1 S2: one run measured over each window; measuring leaves the state as it is, so the
    # second window reads bitwise what a run measured from S2 alone reads (CPU)
    with benchmark_module(test, "rest_column") as rest_column:
        small = ["--n", "3", "--layers", "4", "--measure", "0.05", "--device", "cpu"]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            both = rest_column.main([*small, "--settle", "0.05", "0.1"])
            alone = rest_column.main([*small, "--settle", "0.1"])
        test.assertEqual([w["settle_s"] for w in both["windows"]], [0.05, 0.1])
        test.assertEqual(both["rms_speed_m_s"], both["windows"][0]["rms_speed_m_s"])
        test.assertNotIn("windows", alone)
        for key in (
            "rms_speed_m_s",
            "max_speed_m_s",
            "max_displacement_spacings",
            "energy_end_J_kg",
            "max_compression",
        ):
            test.assertEqual(both["windows"][1][key], alone[key], key)
        test.assertNotEqual(both["windows"][0]["energy_end_J_kg"], alone["energy_end_J_kg"])
        # windows that overlap are refused, naming the flag
        err = io.StringIO()
        with contextlib.redirect_stderr(err), test.assertRaises(SystemExit):
            rest_column.main([*small, "--settle", "0.1", "0.12"])
        test.assertIn("--settle 0.1 0.12", err.getvalue())


def test_floating_box_reads_its_rest(test, device):
    # floating_box's issue #23 item 2 readings: the tilt from the pose, the box's start moved off centre per start,
    # and per run the four readings and whether all are within the bounds
    import numpy as np  # noqa: PLC0415
    import warp as wp  # noqa: PLC0415

    with benchmark_module(test, "floating_box") as floating_box:
        q = wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), math.radians(10.0))
        test.assertAlmostEqual(floating_box.tilt_deg(np.array([0.0, 0.0, 0.0, *q])), 10.0, places=3)
        test.assertAlmostEqual(floating_box.tilt_deg(np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])), 0.0)
        centred = floating_box.build(0.1, 500.0, device, depth=0.2).body_q.numpy()[0]
        moved = floating_box.build(0.1, 500.0, device, depth=0.2, box_x=0.02).body_q.numpy()[0]
        test.assertAlmostEqual(float(moved[0] - centred[0]), 0.02, places=6)
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "box.json")
            argv = ["--spacings", "0.1", "--densities", "500", "--pool-half", "0.5", "--depth", "0.2"]
            argv += ["--seconds", "0.1", "--average", "0.05", "--starts", "2", "--offset", "0.01"]
            with contextlib.redirect_stdout(io.StringIO()) as out:
                floating_box.main([*argv, "--device", "cpu", "--json", path])
            with open(path) as f:
                record = json.load(f)
        test.assertEqual([r["box_start_x_m"] for r in record["rows"]], [0.0, 0.01])
        for row in record["rows"]:
            readings = [row[k] for k in ("tilt_max_deg", "angular_speed_rad_s", "vertical_speed_m_s")]
            test.assertTrue(all(math.isfinite(v) and v >= 0.0 for v in readings), row)
            within = all(row[k] < b for k, b in floating_box.REST_BOUNDS.items() if k != "draft_error")
            within = within and abs(row["draft_relative_error"]) < floating_box.REST_BOUNDS["draft_error"]
            test.assertEqual(row["rest_bounds_met"], within, row)
        test.assertIn("of 2 runs", out.getvalue())


class TestFluidBenchmarks(unittest.TestCase):
    pass


for _name, _func in [(n, f) for n, f in globals().items() if n.startswith("test_") and callable(f)]:
    add_function_test(TestFluidBenchmarks, _name, _func, devices=["cpu"])

if __name__ == "__main__":
    unittest.main(verbosity=2)
