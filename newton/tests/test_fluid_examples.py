# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The fluid examples at reduced particle counts, with their ``test_final``, and the README's listings."""

import importlib
import re
import unittest
from pathlib import Path

import newton.viewer
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
    "fluid_xpbd_cup_transfer": (["--particle-count", "2000"], 540),
    "fluid_xpbd_archimedes_screw": (["--particle-count", "6000"], 240),
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


def test_every_example_is_tested_and_listed(test, device):
    package = importlib.import_module("newton.examples.fluid")
    here = Path(next(iter(package.__path__)))
    modules = sorted(p.stem.removeprefix("example_") for p in here.glob("example_fluid_xpbd_*.py"))
    test.assertEqual(len(modules), 9)
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
