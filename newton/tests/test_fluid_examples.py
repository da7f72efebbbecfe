# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The fluid examples at reduced particle counts, with their ``test_final``, and the README's listings."""

import importlib
import re
import unittest
from pathlib import Path

import newton.viewer
import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton
import newton.examples

# example name -> (command-line arguments, frames)
EXAMPLES = {
    "fluid_xpbd_dam_break": (["--particle-count", "3000"], 90),
    "fluid_xpbd_foam": (["--particle-count", "4000"], 120),
    "fluid_xpbd_multiworld": (["--world-count", "8", "--particle-count", "3000"], 60),
    "fluid_xpbd_interactive_tank": (["--particle-count", "3000"], 100),
    "fluid_xpbd_multi_fluid_tank": (["--particle-count", "3000"], 300),
    "fluid_xpbd_sdf_container": (["--particle-count", "3000"], 240),
    "fluid_xpbd_wave_pool": (["--particle-count", "4500"], 240),
    "fluid_xpbd_cup_transfer": (["--world-count", "2", "--particle-count", "1000"], 540),
    "fluid_xpbd_archimedes_screw": (["--particle-count", "6000"], 240),
    "fluid_xpbd_pouring": (["--world-count", "2", "--particle-count", "400"], 240),
}


def run_example(test, device, name):
    args_list, frames = EXAMPLES[name]
    module = importlib.import_module(
        newton.examples.get_examples().get(name) or f"newton.examples.fluid.example_{name}"
    )
    parser = module.Example.create_parser()
    args = parser.parse_args([*args_list, "--viewer", "null", "--test", "--num-frames", str(frames)])
    with wp.ScopedDevice(device):
        example = module.Example(newton.viewer.ViewerNull(num_frames=frames), args)
        # issue #23 item 2: no example holds its fluid calm with a particle speed clamp
        test.assertEqual(example.model.particle_max_velocity, newton.ModelBuilder().particle_max_velocity, name)
        newton.examples.run(example, args)  # runs test_final and the finiteness checks


def readme_listings():
    readme = Path(__file__).resolve().parents[2] / "README.md"
    if not readme.is_file():
        return None
    return re.findall(r"```python\n(.*?)```", readme.read_text(encoding="utf-8"), flags=re.S)


def test_readme_listings_run(test, device):
    listings = readme_listings()
    if listings is None:
        test.skipTest("README.md is part of the source checkout, not of the installed wheel")
    test.assertEqual(len(listings), 2)
    namespace = {}
    with wp.ScopedDevice(device):
        for code in listings:
            exec(compile(code, "README.md", "exec"), namespace)
    stats = namespace["stats"]
    test.assertEqual(stats["active_particles"], 1000)
    test.assertLess(stats["max_compression"], 0.1)
    test.assertEqual(namespace["solver"].fluid_viscosity, 0.2)
    test.assertEqual(namespace["density"].shape, (1000,))


def test_capture_writes_video_and_sidecar(test, device):
    import json  # noqa: PLC0415
    import tempfile  # noqa: PLC0415

    import imageio.v3 as iio  # noqa: PLC0415

    from newton.examples.fluid import capture  # noqa: PLC0415
    from newton.examples.fluid.example_fluid_xpbd_dam_break import Example  # noqa: PLC0415

    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "dam.mp4")
        args = Example.create_parser().parse_args(
            [
                "--particle-count",
                "2000",
                "--num-frames",
                "8",
                "--capture",
                path,
                "--capture-size",
                "320",
                "180",
                "--capture-still",
                str(Path(tmp) / "still.png"),
            ]
        )
        with wp.ScopedDevice(device):
            sidecar = capture.capture(Example, args, "fluid_xpbd_dam_break")
        frames = iio.imread(path)
        test.assertEqual(frames.shape, (4, 180, 320, 3))  # 8 frames at 60 Hz -> 4 at 30 fps
        # the fluid is in the picture: the frames differ from one another as it falls
        test.assertGreater(abs(frames[-1].astype(float) - frames[0].astype(float)).mean(), 0.05)
        still = iio.imread(Path(tmp) / "still.png")
        test.assertEqual(still.shape[:2], (180, 320))
        # the still is the last frame (the video's is the same picture through H.264)
        test.assertLess(abs(still[..., :3].astype(float) - frames[-1].astype(float)).mean(), 8.0)
        on_disk = json.loads(Path(path + ".json").read_text())
        test.assertEqual(on_disk, json.loads(json.dumps(sidecar)))
        for key, value in (
            ("scene", "fluid_xpbd_dam_break"),
            ("frames_simulated", 8),
            ("frames_written", 4),
            ("output_fps", 30.0),
            ("substeps", 8),
            ("iterations", 2),
            ("resolution", [320, 180]),
        ):
            test.assertEqual(on_disk[key], value, key)
        test.assertGreater(on_disk["particles"], 1500)
        for key in ("wall_time_s", "simulated_time_s", "device", "newton", "warp"):
            test.assertIn(key, on_disk)
        test.assertLess(on_disk["max_compression"], 0.2)
        test.assertGreater(on_disk["mean_abs_density_error"], 0.0)


def test_still_without_video(test, device):
    import json  # noqa: PLC0415
    import tempfile  # noqa: PLC0415

    import imageio.v3 as iio  # noqa: PLC0415

    from newton.examples.fluid import capture  # noqa: PLC0415
    from newton.examples.fluid.example_fluid_xpbd_dam_break import Example  # noqa: PLC0415

    with tempfile.TemporaryDirectory() as tmp:
        still = str(Path(tmp) / "still.png")
        common = ["--particle-count", "2000", "--num-frames", "6", "--capture-size", "160", "96"]
        args = Example.create_parser().parse_args([*common, "--capture-still", still, "--still-frame", "3"])
        rendered = []
        upstream_render = Example.render

        class Counted(Example):
            def render(self):
                rendered.append(self.sim_time)
                upstream_render(self)

        with wp.ScopedDevice(device):
            sidecar = capture.capture(Counted, args, "fluid_xpbd_dam_break")
        test.assertEqual(sorted(p.name for p in Path(tmp).iterdir()), ["still.png", "still.png.json"])
        test.assertEqual(iio.imread(still).shape[:2], (96, 160))
        # only the still's frame was rendered, after the third step
        np.testing.assert_allclose(rendered, [3.0 / 60.0])
        on_disk = json.loads(Path(still + ".json").read_text())
        test.assertEqual(on_disk, json.loads(json.dumps(sidecar)))
        test.assertEqual((on_disk["video"], on_disk["still_frame"], on_disk["frames_written"]), (None, 3, 0))
        for bad, message in ((["--still-frame", "7"], "still_frame=7"), (["--still-frame", "0"], "still_frame=0")):
            args = Example.create_parser().parse_args([*common, "--capture-still", still, *bad])
            with test.assertRaisesRegex(ValueError, message):
                capture.capture(Example, args, "fluid_xpbd_dam_break")


def test_run_shows_progress_and_summary(test, device):
    """The README's first command, small: a progress line on stderr, one summary line; --quiet prints neither."""
    import subprocess  # noqa: PLC0415
    import sys  # noqa: PLC0415

    command = [sys.executable, "-m", "newton.examples", "fluid_xpbd_dam_break", "--viewer", "null"]
    command += ["--num-frames", "12", "--device", "cpu"]
    result = subprocess.run(command, capture_output=True, text=True, timeout=600, check=True)
    out = result.stdout.strip().splitlines()
    test.assertIn("running on the CPU: 5,000 particles by default (100,000 on a GPU)", result.stdout)
    summary = out[-1]
    test.assertRegex(summary, r"^fluid_xpbd_dam_break: 12 frames in [0-9.]+ s \([0-9.]+ frames/s\), 5,148 particles, ")
    test.assertRegex(summary, r"mean density error [0-9.]+ %, 0 particles lost$")
    # not a terminal: whole lines, the last one at 12/12
    test.assertRegex(result.stderr, r"fluid_xpbd_dam_break: 100%.*12/12 .*density error [0-9.]+ %")
    test.assertNotIn("\r", result.stderr)
    quiet = subprocess.run(
        [*command, "--quiet", "--particle-count", "1000"], capture_output=True, text=True, timeout=600
    )
    test.assertEqual(quiet.returncode, 0, quiet.stderr[-2000:])
    test.assertEqual(quiet.stdout.strip(), "")
    test.assertNotIn("frames/s", quiet.stderr)


def test_readme_commands_and_flags_exist(test, device):
    """Every example command and every example flag the README names exists (and every viewer it names)."""
    readme_path = Path(__file__).resolve().parents[2] / "README.md"
    if not readme_path.is_file():
        test.skipTest("README.md is part of the source checkout, not of the installed wheel")
    readme = readme_path.read_text(encoding="utf-8")
    # inline code outside the fenced listings, and the indented command lines
    spans = re.findall(r"`([^`\n]+)`", re.sub(r"```.*?```", "", readme, flags=re.S))
    commands = [c for c in spans if "newton.examples " in c]
    commands += [line.strip() for line in readme.splitlines() if line.startswith("    ") and "newton.examples " in line]
    test.assertGreaterEqual(len(commands), 2)
    flag = r"(--[a-z][a-z-]*)(?:\s+([^\s-]\S*))?"
    flags = []
    for command in commands:
        words = command.split("newton.examples ", 1)[1].split()
        if not words[0].startswith(("<", "-")):
            test.assertIn(words[0], EXAMPLES, command)
        flags += re.findall(flag, " ".join(words))
    flags += [f for c in spans if c.startswith("--") for f in re.findall(flag, c)]
    test.assertGreater(len(flags), 8)
    for name in EXAMPLES:
        parser = importlib.import_module(f"newton.examples.fluid.example_{name}").Example.create_parser()
        options = {o: a for a in parser._actions for o in a.option_strings}
        for flag, value in flags:
            test.assertIn(flag, options, f"{name}: README names {flag}")
            if flag == "--viewer" and value:
                test.assertIn(value, options[flag].choices, f"{name}: README names --viewer {value}")


def test_every_example_is_tested_and_listed(test, device):
    package = importlib.import_module("newton.examples.fluid")
    here = Path(next(iter(package.__path__)))
    modules = sorted(p.stem.removeprefix("example_") for p in here.glob("example_fluid_xpbd_*.py"))
    test.assertEqual(len(modules), 10)
    test.assertEqual(sorted(EXAMPLES), modules)
    listings = readme_listings()
    if listings is None:
        test.skipTest("README.md is part of the source checkout, not of the installed wheel")
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    for name in modules:
        test.assertIn(f"`{name}`", readme)


class TestFluidExamples(unittest.TestCase):
    pass


devices = get_test_devices()
for _example in EXAMPLES:
    add_function_test(
        TestFluidExamples,
        f"test_{_example}",
        lambda test, device, n=_example: run_example(test, device, n),
        devices=devices,
    )
add_function_test(
    TestFluidExamples,
    "test_capture_writes_video_and_sidecar",
    test_capture_writes_video_and_sidecar,
    devices=[wp.get_device("cpu")],
    check_output=False,
)
for _test in (test_still_without_video, test_run_shows_progress_and_summary, test_readme_commands_and_flags_exist):
    add_function_test(TestFluidExamples, _test.__name__, _test, devices=[wp.get_device("cpu")], check_output=False)
add_function_test(
    TestFluidExamples, "test_readme_listings_run", test_readme_listings_run, devices=devices, check_output=False
)
add_function_test(
    TestFluidExamples,
    "test_every_example_is_tested_and_listed",
    test_every_example_is_tested_and_listed,
    devices=[wp.get_device("cpu")],
)

if __name__ == "__main__":
    unittest.main(verbosity=2)
