# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The coarse density correction (``fluid_coarse_correction``): its cells, its load, its worlds (CPU and CUDA)."""

import unittest
import unittest.mock
import warnings

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton
from newton._src.solvers.xpbd.fluid import coarse_correction
from newton._src.solvers.xpbd.fluid.coarse_correction import CELL_FULL, CELL_OUTSIDE, CELL_SURFACE
from newton.examples.fluid.common import add_closed_box
from newton.tests.test_fluid_still_water import floating_box_sim
from newton.tests.test_solver_xpbd_fluid import Sim, add_block, make_model

SPACING = 0.05  # [m]


def column(device, n=6, layers=24, worlds=1, **solver_kwargs):
    """An ``n`` x ``n`` x ``layers`` column at rest in a closed frictionless box per world (worlds at one place), 8 x 2."""
    d = SPACING

    def build(b, depth=layers):
        add_block(b, (n, n, depth), origin=(0.5 * d, 0.5 * d, 0.5 * d), spacing=d, mass=1000.0 * d**3, radius=0.5 * d)
        add_closed_box(b, n * d, 1.5 * layers * d)

    if worlds == 1:
        model = make_model(device, build, gravity=-9.81)
    else:
        builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
        for w in range(worlds):
            world = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
            # the worlds differ: each is a column of its own depth
            build(world, layers - 4 * w)
            builder.add_world(world)
        model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return Sim(model, substeps=8, contacts=True, fluid_rest_distance=d, **solver_kwargs)


def max_compression(sim) -> float:
    return sim.solver.fluid_diagnostics(sim.state_0)["max_compression"]


def test_coarse_correction_is_validated_and_off_by_default(test, device):
    for name, value in (
        ("fluid_coarse_correction", -0.1),
        ("fluid_coarse_correction", 1.5),
        ("fluid_coarse_correction", float("nan")),
        ("fluid_coarse_cell", 0.5),
        ("fluid_coarse_cell", 17.0),
    ):
        with test.assertRaisesRegex(ValueError, f"{name}={value!r}"):
            column(device, n=2, layers=2, **{name: value})
    # off: no cells, no launches
    test.assertIsNone(column(device, n=2, layers=2).solver._fluid.coarse)
    on = column(device, n=2, layers=2, fluid_coarse_correction=0.5).solver
    test.assertEqual(on.fluid_coarse_correction, 0.5)
    test.assertEqual(on.fluid_coarse_cell, 3.0)
    with test.assertRaises(AttributeError):
        on.fluid_coarse_correction = 0.2


def test_coarse_correction_carries_a_deep_load(test, device):
    """The load the density passes leave compressed at the bottom of a deep column is carried by the cells."""
    plain = column(device)
    coarse = column(device, fluid_coarse_correction=0.5)
    for sim in (plain, coarse):
        sim.step(60)
        test.assertTrue(np.isfinite(sim.q()).all())
    compressed, corrected = max_compression(plain), max_compression(coarse)
    # 24 layers at 8 x 2 leave the bottom about 0.5 % compressed; the correction removes most of it
    test.assertGreater(compressed, 0.002)
    test.assertLess(corrected, 0.25 * compressed)
    # the column stands: nothing thrown up or lost
    q = coarse.q()
    test.assertLess(q[:, 2].max(), (24 + 3) * SPACING)
    test.assertGreater(q[:, 2].min(), 0.0)


def test_coarse_cells_know_surface_walls_and_fluid(test, device):
    """The cells' kinds in a settled column: walls and air hold no fluid, the top layer is the free surface."""
    sim = column(device, n=6, layers=12, fluid_coarse_correction=0.5)
    sim.step(30)
    c = sim.solver._fluid.coarse
    row = 0 if c.boxes.dims.numpy()[0][0] else 1
    dims = c.boxes.dims.numpy()[row]
    first = c.row_first.numpy()[row]
    kind = c.kind.numpy()[first : first + int(np.prod(dims))].reshape(dims)
    phi = c.phi.numpy()[first : first + int(np.prod(dims))].reshape(dims)
    # the box over 6 x 6 x 12 spacings is 2 x 2 x 4 cells of 3, with one to spare on every side
    np.testing.assert_array_equal(dims, (4, 4, 6))
    np.testing.assert_array_equal(c.boxes.corner.numpy()[row], (-1, -1, -1))
    # the spare cells are the walls' and the floor's (their particles' walls have the centres behind them)
    test.assertTrue((kind[0] == CELL_OUTSIDE).all() and (kind[-1] == CELL_OUTSIDE).all())
    test.assertTrue((kind[:, :, 0] == CELL_OUTSIDE).all())
    # inside: full below the cell the top layer is in (which the fluid fills only to 0.6 m, 7/8 of its room),
    # the free surface from there up; the cells by the walls are full in the room the walls leave them
    test.assertTrue((kind[1:3, 1:3, 1:4] == CELL_FULL).all())
    test.assertTrue((kind[1:3, 1:3, 4:6] == CELL_SURFACE).all())
    # the potential's zero is where the fluid's top is, half a spacing above its highest particle: about 1.5
    # cells above the last full centre (0.375 m), read from the top cell's fill (CPU: 1.59 against 1.55; at its
    # centre, 1 cell, before, and 1.42 with the fill's linear reading 0.5 + fill)
    source = c.source.numpy()[first : first + int(np.prod(dims))].reshape(dims)
    top = sim.q()[:, 2].max() + 0.5 * SPACING
    np.testing.assert_allclose(source[1:3, 1:3, 4], (top - 0.375) / 0.15, atol=0.1)
    # the potential is a pressure's: zero at the surface, deepest at the floor
    test.assertTrue((phi[1:3, 1:3, 1] < phi[1:3, 1:3, 3]).all())
    test.assertTrue((phi[1:3, 1:3, 3] < 0.0).all())


def test_coarse_potential_is_read_at_the_particles(test, device):
    """``fluid_coarse_potential``: the cells' potential at each fluid particle, from the cells with fluid around it."""
    test.assertIsNone(column(device, n=2, layers=2).solver.fluid_coarse_potential(None))
    sim = column(device, n=6, layers=12, fluid_coarse_correction=0.5)
    sim.step(30)
    potential = sim.solver.fluid_coarse_potential(sim.state_0)
    test.assertEqual(potential.shape[0], sim.model.particle_count)
    test.assertEqual(potential.device, sim.model.device)
    # the reference: the 8 cell centres around each particle, weighted trilinearly, cells without fluid left out
    c = sim.solver._fluid.coarse
    row = 0 if c.boxes.dims.numpy()[0][0] else 1
    dims, corner = c.boxes.dims.numpy()[row], c.boxes.corner.numpy()[row]
    edge = c.base_cell * 2.0 ** c.boxes.level.numpy()[row]
    first = c.boxes.first.numpy()[row]
    kind, phi = c.kind.numpy(), c.phi.numpy().astype(np.float64)
    s = sim.q() / edge - corner - 0.5
    low = np.floor(s).astype(int)
    total, value = np.zeros(len(s)), np.zeros(len(s))
    for bits in range(8):
        o = np.array([(bits >> axis) & 1 for axis in range(3)])
        ijk = np.clip(low + o, 0, dims - 1)
        w = np.prod(np.where(o == 1, s - low, 1.0 - (s - low)), axis=1)
        cell = first + (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
        fluid = kind[cell] != CELL_OUTSIDE
        total += np.where(fluid, w, 0.0)
        value += np.where(fluid, w * phi[cell], 0.0)
    np.testing.assert_allclose(potential.numpy(), value / total, rtol=1e-4, atol=1e-9)
    # a pressure's potential: below zero in the loaded column, deeper toward the floor
    read = potential.numpy()
    z = sim.q()[:, 2]
    test.assertLess(read.max(), 1e-12)
    test.assertLess(read[z < 0.2].mean(), read[(z > 0.3) & (z < 0.45)].mean())


def test_coarse_cells_are_per_world(test, device):
    """Worlds at one place have cells of their own: a world steps as it does alone."""
    together = column(device, n=4, layers=16, worlds=2, fluid_coarse_correction=0.5)
    alone = column(device, n=4, layers=16, worlds=1, fluid_coarse_correction=0.5)
    together.step(10)
    alone.step(10)
    world = together.model.particle_world.numpy()
    q = together.q()[world == 0]
    # (the neighbour search orders a world's particles differently beside another world, so a cell's sums are added
    # in another order: the free surface's distance, read from them, differs in its last bits, and after 10 steps
    # positions by up to 8e-7 m on the CPU; a world that saw the other's fluid would move by spacings)
    np.testing.assert_allclose(q, alone.q(), atol=1.0e-4 if device.is_cuda else 1.0e-5)
    # the other world moved: its column differs
    test.assertGreater(np.abs(together.q()[world == 1][:, 2].max() - q[:, 2].max()), 3.0 * SPACING)


def test_coarse_potential_is_reset_with_its_world(test, device):
    """A reset world starts its potential from zero again: its next frame is a new solver's first."""
    sim = column(device, n=4, layers=16, worlds=2, fluid_coarse_correction=0.5)
    sim.step(20)
    mask = np.zeros(3, dtype=bool)
    mask[0] = True
    sim.solver.reset(sim.state_0, wp.array(mask, dtype=wp.bool, device=device))
    sim.step(1)
    fresh = column(device, n=4, layers=16, worlds=2, fluid_coarse_correction=0.5)
    fresh.step(1)
    world = sim.model.particle_world.numpy()
    if device.is_cuda:
        np.testing.assert_allclose(sim.q()[world == 0], fresh.q()[world == 0], atol=1.0e-4)
    else:
        np.testing.assert_array_equal(sim.q()[world == 0], fresh.q()[world == 0])
    # the world not reset went on
    test.assertGreater(np.abs(sim.q()[world == 1] - fresh.q()[world == 1]).max(), 0.1 * SPACING)


def test_coarse_correction_in_a_full_closed_box(test, device):
    """Fluid filling a closed box leaves no free surface: the screened potential stays bounded."""
    d = SPACING

    def build(b):
        add_block(b, (4, 4, 4), origin=(0.5 * d, 0.5 * d, 0.5 * d), spacing=d, mass=1000.0 * d**3, radius=0.5 * d)
        add_closed_box(b, 4 * d, 4 * d)

    model = make_model(device, build, gravity=-9.81)
    model.soft_contact_mu = 0.0
    sim = Sim(model, substeps=8, contacts=True, fluid_rest_distance=d, fluid_coarse_correction=1.0)
    sim.step(60)
    q, v = sim.q(), sim.qd()
    test.assertTrue(np.isfinite(q).all() and np.isfinite(v).all())
    test.assertTrue(((q > 0.0) & (q < 4 * d)).all())
    test.assertLess(np.abs(v).max(), 0.5)


def test_coarse_correction_warns_about_dynamic_bodies(test, device):
    """A scene with a floating body warns (the cells do not hold it); one with static walls only does not."""
    with test.assertWarnsRegex(RuntimeWarning, "fluid_coarse_correction with 1 shapes of dynamic bodies"):
        floating_box_sim(device, fluid_coarse_correction=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        column(device, n=2, layers=2, fluid_coarse_correction=0.5)


def test_coarse_correction_step_is_captured(test, device):
    """The step with the correction, captured in a CUDA graph, replays the eager step."""
    eager = column(device, n=4, layers=12, fluid_coarse_correction=0.5)
    graph = column(device, n=4, layers=12, fluid_coarse_correction=0.5)
    with wp.ScopedCapture(device=device) as capture:
        graph.step(1)
    for _ in range(10):
        wp.capture_launch(capture.graph)
        eager.step(1)
    np.testing.assert_allclose(graph.q(), eager.q(), atol=1.0e-4)


def test_coarse_bounds_do_not_depend_on_the_bins(test, device):
    """A world's fluid bounds reduced from one bin give the boxes and the step that eight bins give."""
    runs = []
    for bins in (coarse_correction.BINS_PER_WORLD, 1):
        with unittest.mock.patch.object(coarse_correction, "BINS_PER_WORLD", bins):
            sim = column(device, n=4, layers=16, worlds=2, fluid_coarse_correction=0.5)
        c = sim.solver._fluid.coarse
        # (256 and 192 particles: 8 and 6 bins of 32, or one each)
        test.assertEqual(c.bin_count.numpy()[:2].tolist(), [8, 6] if bins > 1 else [1, 1])
        sim.step(5)
        runs.append((c.boxes.corner.numpy(), c.boxes.dims.numpy(), sim.q()))
    (corner, dims, q), (corner_one, dims_one, q_one) = runs
    np.testing.assert_array_equal(corner, corner_one)
    np.testing.assert_array_equal(dims, dims_one)
    test.assertTrue((dims[:2] > 0).all())
    if device.is_cuda:
        np.testing.assert_allclose(q, q_one, atol=1.0e-4)
    else:
        np.testing.assert_array_equal(q, q_one)


def red_black_reference(phi, kind, source, h, sweeps):
    """Red-black over-relaxed Gauss-Seidel of ``lap phi - phi / L^2 = source`` on the full cells (NumPy, float64).

    ``phi`` is 0 at a free surface ``source`` cells (of a free-surface cell) from the full centre: the face to it
    weighs ``1 / theta``."""
    phi = phi.astype(np.float64).copy()
    screening = 1.0 / coarse_correction.SCREENING_CELLS**2
    omega = coarse_correction.OMEGA
    for _ in range(sweeps):
        for colour in (0, 1):
            for i, j, k in zip(*np.nonzero(kind == CELL_FULL), strict=True):
                if (i + j + k) % 2 != colour:
                    continue
                total, faces = 0.0, 0.0
                for o in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)):
                    a, b, c = i + o[0], j + o[1], k + o[2]
                    inside = 0 <= a < kind.shape[0] and 0 <= b < kind.shape[1] and 0 <= c < kind.shape[2]
                    if inside and kind[a, b, c] == CELL_FULL:
                        total += phi[a, b, c]
                        faces += 1.0
                    elif inside and kind[a, b, c] == CELL_SURFACE:
                        faces += 1.0 / source[a, b, c]
                solved = (total - h * h * source[i, j, k]) / (faces + screening)
                phi[i, j, k] = (1.0 - omega) * phi[i, j, k] + omega * solved
    return phi


def test_coarse_sweeps_are_red_black_gauss_seidel(test, device):
    """The sweeps relax the screened Poisson equation of the full cells as red-black over-relaxed Gauss-Seidel."""
    rng = np.random.default_rng(7)
    dims = (5, 4, 6)
    kind = rng.choice([CELL_FULL, CELL_FULL, CELL_FULL, CELL_SURFACE, CELL_OUTSIDE], size=dims).astype(np.int32)
    # a full cell's source; a free-surface cell's distance from the full centres to the surface [cells]
    source = np.where(kind == CELL_FULL, rng.uniform(0.0, 0.02, dims), rng.uniform(0.25, 1.75, dims))
    phi = np.where(kind == CELL_FULL, rng.uniform(-0.01, 0.0, dims), 0.0)
    h = 0.15
    boxes = coarse_correction.CoarseBoxes()
    boxes.first = wp.zeros(1, dtype=wp.int32, device=device)
    boxes.corner = wp.zeros(1, dtype=wp.vec3i, device=device)
    boxes.dims = wp.array([dims], dtype=wp.vec3i, device=device)
    boxes.level = wp.zeros(1, dtype=wp.int32, device=device)
    boxes.base_cell = h
    n = kind.size
    cell_row = wp.zeros(n, dtype=wp.int32, device=device)
    kind_d = wp.array(kind.ravel(), dtype=wp.int32, device=device)
    source_d = wp.array(source.ravel(), dtype=float, device=device)
    phi_d = wp.array(phi.ravel(), dtype=float, device=device)
    sweeps = 4
    for _ in range(sweeps):
        for colour in (0, 1):
            wp.launch(
                coarse_correction.relax_coarse_potential,
                dim=n,
                inputs=[cell_row, boxes, kind_d, source_d, colour],
                outputs=[phi_d],
                device=device,
            )
    result = phi_d.numpy().reshape(dims)
    expected = red_black_reference(phi, kind, source, h, sweeps)
    test.assertGreater(np.abs(expected - phi).max(), 1.0e-4)
    np.testing.assert_allclose(result, expected, rtol=1.0e-5, atol=1.0e-8)


class TestFluidCoarseCorrection(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(
            TestFluidCoarseCorrection,
            _name,
            _func,
            devices=devices,
        )


if __name__ == "__main__":
    unittest.main(verbosity=2)
