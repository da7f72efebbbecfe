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
    TestFluidExamples, "test_readme_listings_run", test_readme_listings_run, devices=devices, check_output=False
)

if __name__ == "__main__":
    unittest.main(verbosity=2)
