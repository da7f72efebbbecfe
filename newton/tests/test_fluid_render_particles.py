# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Render particles: smoothed centres and anisotropic ellipsoids (SolverXPBD.update_render_particles)."""

import unittest

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton

FLUID = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)
D = 0.1


def build_model(device, blocks, extra=()):
    """Fluid lattice blocks ``(dims, origin)`` plus extra particles ``(pos, flags)``."""
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    for dims, origin in blocks:
        builder.add_particle_grid(
            pos=wp.vec3(*origin),
            rot=wp.quat_identity(),
            vel=wp.vec3(0.0),
            dim_x=dims[0],
            dim_y=dims[1],
            dim_z=dims[2],
            cell_x=D,
            cell_y=D,
            cell_z=D,
            mass=1000.0 * D**3,
            jitter=0.0,
            radius_mean=0.5 * D,
            flags=FLUID,
        )
    for pos, flags in extra:
        builder.add_particle(pos=wp.vec3(*pos), vel=wp.vec3(0.0), mass=1.0, radius=0.5 * D, flags=flags)
    return builder.finalize(device=device)


def render(device, model, **kwargs):
    solver = newton.solvers.SolverXPBD(model, fluid_rest_distance=D)
    state = model.state()
    solver.update_render_particles(state, **kwargs)
    return (
        solver.render_positions.numpy(),
        solver.render_anisotropy.numpy(),
        solver.render_anisotropy_secondary.numpy(),
        solver.render_anisotropy_tertiary.numpy(),
    )


def test_interior_particles_are_round(test, device):
    model = build_model(device, [((7, 7, 7), (0.0, 0.0, 0.0))])
    pos, a1, a2, a3 = render(device, model, smoothing=0.5, anisotropy_scale=1.5)
    q = model.particle_q.numpy()
    interior = np.all(np.abs(q - q.mean(axis=0)) < 1.5 * D + 1.0e-6, axis=1)
    test.assertGreater(np.count_nonzero(interior), 0)
    for a in (a1, a2, a3):
        np.testing.assert_allclose(a[interior, 3], 1.5, atol=0.02)
        np.testing.assert_allclose(np.linalg.norm(a[:, :3], axis=1), 1.0, atol=1.0e-4)
    np.testing.assert_allclose(pos[interior], q[interior], atol=1.0e-5)  # symmetric: no shift
    # the smoothed surface moves toward the inside
    corner = np.argmax(np.linalg.norm(q - q.mean(axis=0), axis=1))
    inward = (q.mean(axis=0) - q[corner]) / np.linalg.norm(q.mean(axis=0) - q[corner])
    test.assertGreater(np.dot(pos[corner] - q[corner], inward), 0.01 * D)


def test_sheet_is_flat_and_strand_is_long(test, device):
    sheet = build_model(device, [((8, 8, 1), (0.0, 0.0, 0.0))])
    _, a1, a2, a3 = render(device, sheet, anisotropy_min=0.2, anisotropy_max=3.0)
    q = sheet.particle_q.numpy()
    inner = np.all(np.abs(q[:, :2] - q[:, :2].mean(axis=0)) < 2.0 * D, axis=1)
    np.testing.assert_allclose(np.abs(a3[inner, 2]), 1.0, atol=1.0e-3)  # shortest axis = sheet normal
    np.testing.assert_allclose(a3[inner, 3], 0.2, atol=1.0e-5)  # clamped at the minimum
    test.assertTrue(np.all(a1[inner, 3] > 1.0) and np.all(a2[inner, 3] > 1.0))

    strand = build_model(device, [((12, 2, 2), (0.0, 0.0, 0.0))])
    _, a1, a2, a3 = render(device, strand)
    q = strand.particle_q.numpy()
    inner = np.abs(q[:, 0] - q[:, 0].mean()) < 3.0 * D
    np.testing.assert_allclose(np.abs(a1[inner, 0]), 1.0, atol=1.0e-3)  # longest axis along the strand
    test.assertTrue(np.all(a1[inner, 3] > 1.2))
    test.assertTrue(np.all(a3[inner, 3] < 1.0))


def test_isolated_and_non_fluid_particles_stay_round(test, device):
    model = build_model(
        device,
        [((4, 4, 4), (0.0, 0.0, 0.0))],
        extra=[((3.0, 0.0, 0.0), FLUID), ((-3.0, 0.0, 0.0), int(newton.ParticleFlags.ACTIVE))],
    )
    pos, a1, a2, a3 = render(device, model, anisotropy_scale=0.8)
    q = model.particle_q.numpy()
    for i in (64, 65):
        np.testing.assert_array_equal(pos[i], q[i])
        for a in (a1, a2, a3):
            test.assertAlmostEqual(float(a[i, 3]), 0.8, places=6)


def test_render_state_does_not_change_simulation(test, device):
    rng = np.random.default_rng(5)
    results = []
    for draw in (False, True):
        model = build_model(device, [((6, 6, 6), (0.0, 0.0, 0.0))])
        model.particle_q.assign(model.particle_q.numpy() + rng.normal(0.0, 0.05 * D, (216, 3)).astype(np.float32))
        rng = np.random.default_rng(5)
        solver = newton.solvers.SolverXPBD(model, fluid_rest_distance=1.1 * D, fluid_viscosity=0.1)
        s0, s1 = model.state(), model.state()
        for _ in range(12):
            solver.step(s0, s1, None, None, 1.0 / 240.0)
            s0, s1 = s1, s0
            if draw:
                solver.update_render_particles(s0)
        results.append((s0.particle_q.numpy(), s0.particle_qd.numpy()))
    np.testing.assert_array_equal(results[0][0], results[1][0])
    np.testing.assert_array_equal(results[0][1], results[1][1])
    test.assertGreater(np.abs(results[0][0] - model.particle_q.numpy()).max(), 1.0e-4)  # it did move


def test_render_bad_arguments(test, device):
    model = build_model(device, [((3, 3, 3), (0.0, 0.0, 0.0))])
    solver = newton.solvers.SolverXPBD(model, fluid_rest_distance=D)
    state = model.state()
    for name, value in (
        ("smoothing", 1.5),
        ("anisotropy_scale", 0.0),
        ("anisotropy_min", 0.0),
        ("anisotropy_max", 0.5),
    ):
        with test.assertRaisesRegex(ValueError, f"{name}={value!r}"):
            solver.update_render_particles(state, **{name: value})
    plain = newton.solvers.SolverXPBD(newton.ModelBuilder().finalize(device=device))
    with test.assertRaisesRegex(ValueError, "fluid"):
        plain.update_render_particles(state)
    test.assertIsNone(plain.render_positions)


class TestFluidRenderParticles(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestFluidRenderParticles, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
