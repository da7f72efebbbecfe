# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The compression damping (``fluid_compression_damping``): its stable step, its cost when off, a deep column's ring, the warm start (CPU and CUDA)."""

import math
import unittest

import numpy as np
from newton.tests.unittest_utils import add_function_test, get_test_devices

from newton._src.solvers.xpbd.fluid.calibration import stable_pass_bound
from newton.tests.test_fluid_coarse_correction import column
from newton.tests.test_fluid_still_water import closing_kept


def substep_radius(kept: float, damping: float) -> float:
    """Spectral radius of the substep ``x' = p x* - (1 - p) g (x* - x)``, ``x* = 2 x - x_prev``, of a mode kept ``p``."""
    a = kept - (1.0 - kept) * damping
    step = np.array([[2.0 * a + (1.0 - kept) * damping, -a], [1.0, 0.0]])
    return float(np.abs(np.linalg.eigvals(step)).max())


def test_stable_step_with_damping(test, device):
    # a fixed count keeps the even bound with the damping: an odd one's last pass takes half the step, so every
    # mode keeps p >= 0 of its error, inside the damped substep's stable range (2 g - 1) / (3 + 2 g) < p < 1
    for damping in (0.0, 0.2, 0.4):
        for passes in (1, 2, 3):
            test.assertEqual(stable_pass_bound(passes, passes, damping), 2.0)
            steps = np.linspace(0.0, 0.999 * 2.0, 400)[1:]
            inside = max(substep_radius(closing_kept(s, passes), damping) for s in steps)
            test.assertLess(inside, 1.0 + 1.0e-9, msg=f"g {damping}, {passes} passes")
        # a count decided on the device: its fewest odd count's bound is where the substep's least stable mode
        # reaches the unit circle; below it every count of the range stays inside, just above it one leaves
        for fewest, most in ((1, 2), (1, 3), (3, 4)):
            bound = stable_pass_bound(fewest, most, damping)
            steps = np.linspace(0.0, 0.999 * bound, 400)[1:]
            for passes in range(fewest, most + 1):
                inside = max(substep_radius((1.0 - s) ** passes, damping) for s in steps)
                test.assertLess(inside, 1.0 + 1.0e-9, msg=f"g {damping}, {passes} of {fewest}-{most} passes")
            test.assertGreater(substep_radius((1.0 - 1.01 * bound) ** fewest, damping), 1.0)
    # there the damping narrows the step: one to two passes 4/3 undamped, 1.05 at 0.4
    test.assertEqual(stable_pass_bound(1, 2), 1.0 + 3.0**-1.0)
    test.assertLess(stable_pass_bound(1, 2, 0.4), 1.06)
    test.assertLess(stable_pass_bound(1, 3, 0.4), stable_pass_bound(1, 3))


def test_off_compiles_nothing(test, device):
    # nothing is paid for the damping a scene does not use: no rate or start buffer, the undamped passes
    off = column(device, n=2, layers=2).solver._fluid
    test.assertEqual(off.compression_rate.shape[0], 0)
    test.assertEqual(off.sorted_moved.shape[0], 0)
    test.assertFalse(off.passes.suffix.endswith("_damped"))
    on = column(device, n=2, layers=2, fluid_compression_damping=0.4).solver._fluid
    test.assertEqual(on.compression_rate.shape[0], on.fluid_count)
    test.assertEqual(on.sorted_moved.shape[0], on.fluid_count)
    test.assertTrue(on.passes.suffix.endswith("_damped"))
    test.assertEqual(on.config.fluid_compression_damping, 0.4)


def column_motion(device, **solver_kwargs) -> tuple[float, float, float, bool]:
    """RMS speed and the whole column's vertical speed over 2-3 s, and the largest compression, of a 4 x 4 x 40 one-kernel column."""
    sim = column(device, n=4, layers=40, fluid_density_kernel="one_kernel", **solver_kwargs)
    sim.step(120)
    squares, whole = [], []
    for _ in range(60):
        sim.step()
        v = sim.qd()
        squares.append(float(np.mean(np.sum(v * v, axis=1))))
        whole.append(float(v[:, 2].mean()))
    compression = sim.solver.fluid_diagnostics(sim.state_0)["max_compression"]
    finite = bool(np.isfinite(sim.q()).all())
    return math.sqrt(float(np.mean(squares))), math.sqrt(float(np.mean(np.square(whole)))), compression, finite


def test_damping_rings_a_deep_column_down(test, device):
    # the one kernel's deep column rings as a whole after its start (the passes hold its weight as a soft spring,
    # PBF's own damping of it about kappa / 2 dt a second); the damping adds g times that, the load held as before
    # (CPU: 0.0132 m/s undamped, 0.0072 at 0.4; largest compression 1.41 and 1.43 %)
    _, ring, compression, finite = column_motion(device)
    _, damped, damped_compression, damped_finite = column_motion(device, fluid_compression_damping=0.4)
    test.assertTrue(finite and damped_finite)
    test.assertGreater(ring, 0.005)
    test.assertLess(damped, 0.7 * ring)
    test.assertLess(abs(damped_compression - compression), 0.05 * compression)


def test_warm_start_move_is_not_read_as_motion(test, device):
    # the first pass reads each particle's move up to the substep's neighbour build, which the sort gathers; the warm
    # start's move after it is a correction, not motion. Read as motion (from the positions the pass sees), the pair
    # churned the column (CPU: 0.073 m/s RMS, against 0.0052 with the warm start alone and 0.0020 with the pair now)
    warm, _, warm_compression, warm_finite = column_motion(device, fluid_warm_start=0.5)
    pair, _, pair_compression, pair_finite = column_motion(device, fluid_warm_start=0.5, fluid_compression_damping=0.4)
    test.assertTrue(warm_finite and pair_finite)
    test.assertLess(pair, 0.7 * warm)
    test.assertLess(abs(pair_compression - warm_compression), 0.05 * warm_compression)


class TestFluidCompressionDamping(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestFluidCompressionDamping, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
