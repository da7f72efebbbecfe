# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Still water: the Jacobi step bound of the density solve and the non-affine velocity damping (CPU and CUDA)."""

import math
import unittest

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

from newton._src.solvers.xpbd.fluid.calibration import (
    CLOSING_PASS_SHARE,
    JACOBI_STEP_MARGIN,
    jacobi_spectral_radius,
    stable_pass_bound,
    stable_relaxation,
)
from newton._src.solvers.xpbd.fluid.config import DEFAULT_NONAFFINE_DAMPING
from newton._src.solvers.xpbd.fluid.velocity_passes import apply_fluid_viscosity, damping_every
from newton.examples.fluid.common import add_closed_box
from newton.tests.test_solver_xpbd_fluid import D, Sim, add_block, make_model, pool_with_box, still_level


def periodic_jacobi_radius(rest_distance: float, h: float, cells: int, kernel: str) -> float:
    """Largest eigenvalue of ``D^-1 J J^T`` of ``kernel``'s density constraint on a periodic cubic lattice, by brute force."""
    r = np.arange(cells) * rest_distance
    x = np.stack(np.meshgrid(r, r, r, indexing="ij"), axis=-1).reshape(-1, 3)
    n, size = len(x), cells * rest_distance
    offset = x[None, :, :] - x[:, None, :]
    offset -= size * np.round(offset / size)
    dist = np.linalg.norm(offset, axis=-1)
    near = (dist > 0.0) & (dist < h)
    # gradient of C_i with respect to x_j (j != i), up to the common factor of the kernel's slope: the spiky
    # kernel's (h - r)^2 beside poly6, the one kernel's own (1 - r/h)^1.5
    shape = (h - dist) ** 2 if kernel == "poly6" else np.maximum(1.0 - dist / h, 0.0) ** 1.5
    grad = np.where(near[..., None], offset / np.where(near, dist, 1.0)[..., None] * shape[..., None], 0.0)
    jac = grad.copy()
    jac[np.arange(n), np.arange(n)] = -grad.sum(axis=1)
    jac = jac.reshape(n, 3 * n)
    diagonal = np.einsum("ij,ij->i", jac, jac)
    return float(np.linalg.eigvalsh(jac @ jac.T / diagonal[0]).max())


def test_jacobi_radius_matches_brute_force(test, device):
    # a periodic lattice of 2S cells has exactly the wave vectors the S-sample Fourier scan visits
    for kernel in ("poly6", "one_kernel"):
        for ratio in (1.5, 1.8, 2.2):
            h = ratio * D
            test.assertAlmostEqual(
                jacobi_spectral_radius(D, h, samples=4, kernel=kernel),
                periodic_jacobi_radius(D, h, 8, kernel),
                places=6,
                msg=(kernel, ratio),
            )
        # with either kernel a plain Jacobi pass (relaxation 1) overshoots the lattice's shortest waves
        test.assertGreater(jacobi_spectral_radius(D, 1.8 * D, kernel=kernel), 2.0)
    # the one kernel's shortest waves are stiffer (2.71 against poly6's 2.43), so its step is shorter
    test.assertAlmostEqual(stable_relaxation(D, 1.8 * D, kernel="poly6"), 0.72, places=2)
    test.assertAlmostEqual(stable_relaxation(D, 1.8 * D, kernel="one_kernel"), 0.65, places=2)
    for kwargs, kernel in (({}, "one_kernel"), ({"fluid_density_kernel": "poly6"}, "poly6")):
        solver = Sim(make_model(device, lambda b: add_block(b, (3, 3, 3))), **kwargs).solver
        test.assertEqual(solver.fluid_density_kernel, kernel)
        test.assertAlmostEqual(solver.fluid_relaxation, stable_relaxation(D, 1.8 * D, kernel=kernel))
        test.assertEqual(solver.fluid_nonaffine_damping, DEFAULT_NONAFFINE_DAMPING)
        solver.fluid_relaxation = 1.0
        test.assertEqual(solver.fluid_relaxation, 1.0)
        solver.fluid_relaxation = None
        test.assertAlmostEqual(solver.fluid_relaxation, stable_relaxation(D, 1.8 * D, kernel=kernel))


def closing_kept(step: float, passes: int) -> float:
    """Error a mode of ``relaxation x eigenvalue`` = ``step`` keeps after a fixed count of ``passes`` at the default step."""
    if passes % 2:
        return (1.0 - step) ** (passes - 1) * (1.0 - CLOSING_PASS_SHARE * step)
    return (1.0 - step) ** passes


def test_stable_step_follows_the_pass_count(test, device):
    # a fixed count takes the even bound: its modes keep (1 - w mu)^n of their error, stable for w mu < 2, and
    # an odd count's last pass takes half the step
    for n in (1, 2, 3, 4, 5):
        test.assertEqual(stable_pass_bound(n, n), 2.0)
    # so no mode below the bound keeps a negative share (which flips its sign every substep: the hum)
    for n in (1, 3, 5):
        bound = stable_pass_bound(n, n)
        steps = np.linspace(0.0, bound, 401)
        test.assertGreaterEqual(min(closing_kept(s, n) for s in steps), 0.0)
        # without the closing pass the shortest wave at the default step (the margin of the bound) would keep a
        # negative share (below -1/3, unstable, for 1 and 3 passes)
        test.assertLess((1.0 - JACOBI_STEP_MARGIN * bound) ** n, 0.0 if n > 3 else -1.0 / 3.0)
    # a count decided on the device (a tolerance) may stop at any count in its range: the least bound over
    # them, its fewest odd count's, where (1 - w mu)^n reaches -1/3
    test.assertAlmostEqual(stable_pass_bound(1, 2), 4.0 / 3.0)
    test.assertAlmostEqual(stable_pass_bound(2, 8), 1.0 + 3.0 ** (-1.0 / 3.0))
    test.assertEqual(stable_pass_bound(4, 5), 1.0 + 3.0 ** (-1.0 / 5.0))
    for fewest, most in ((1, 2), (3, 4), (5, 9)):
        test.assertAlmostEqual((1.0 - stable_pass_bound(fewest, most)) ** fewest, -1.0 / 3.0)
    # (the default kernel's spectral radius: the one kernel's)
    radius = jacobi_spectral_radius(D, 1.8 * D, kernel="one_kernel")

    def fluid(**kwargs):
        return Sim(make_model(device, lambda b: add_block(b, (3, 3, 3))), **kwargs).solver._fluid

    for iterations, closing in ((1, 1), (2, 0), (3, 3), (4, 0)):
        f = fluid(iterations=iterations)
        test.assertAlmostEqual(f.default_relaxation, 0.875 * 2.0 / radius, places=5)
        test.assertEqual(f.closing_iteration, closing)
        p = f.params.numpy()[0]
        test.assertEqual(p["closing_relaxation"], np.float32(f.default_relaxation * CLOSING_PASS_SHARE))
    # a relaxation the user sets is used for every pass
    test.assertEqual(fluid(iterations=3, fluid_relaxation=0.5).params.numpy()[0]["closing_relaxation"], 0.5)
    # a tolerance on the XPBD iterations stops only after an even count, and all of an odd count closes; sub-passes
    # stop after an even count in each iteration, whose last pass closes an odd one: every schedule, the even bound
    for iterations, closing in ((2, 0), (3, 3), (5, 5)):
        tolerance = fluid(iterations=iterations, fluid_density_tolerance=0.01)
        test.assertAlmostEqual(tolerance.default_relaxation, 0.875 * 2.0 / radius, places=5)
        test.assertEqual(tolerance.closing_iteration, closing)
    for iterations, most in ((1, 4), (2, 4), (1, 3)):
        sub_passes = fluid(iterations=iterations, fluid_max_iterations=most, fluid_density_tolerance=0.01)
        test.assertAlmostEqual(sub_passes.default_relaxation, 0.875 * 2.0 / radius, places=5)
        test.assertEqual(sub_passes.closing_iteration, 0)
    # with a tolerance and one iteration the first pass, which always corrects, is the only one: a fixed count
    test.assertEqual(fluid(iterations=1, fluid_density_tolerance=0.01).closing_iteration, 1)


def velocity_pass(device, velocity, damping, viscosity=0.0, steps=1.0):
    """One velocity pass (a substep of ``steps`` damping reference steps) of an 8 x 8 x 8 block (jittered) whose
    particles move with ``velocity(x)``; returns (x, v before, v after)."""
    model = make_model(device, lambda b: add_block(b, (8, 8, 8), jitter=0.2 * D))
    sim = Sim(model, fluid_nonaffine_damping=damping, fluid_viscosity=viscosity)
    fluid = sim.solver._fluid
    q = sim.q()
    v = velocity(q)
    sim.state_0.particle_qd.assign(v.astype(np.float32))
    fluid.build_neighborhood(sim.state_0.particle_q)
    fluid.evaluate_constraint(fluid.always_active)
    slot_particle = fluid.search.slots.particle.numpy()
    sorted_v = np.zeros((fluid.fluid_count, 3), dtype=np.float32)
    sorted_v[slot_particle >= 0] = v[slot_particle[slot_particle >= 0]]
    fluid.sorted_v.assign(sorted_v)
    wp.launch(
        apply_fluid_viscosity,
        dim=fluid.fluid_count,
        # a clock that makes the damping due in this substep
        inputs=[fluid.params, fluid.search.slots, fluid.sorted_v, fluid.density, fluid.damping_clock, 1, steps],
        outputs=[sim.state_0.particle_qd, fluid.vorticity],
        device=device,
    )
    return q, v, sim.qd()


def test_nonaffine_damping_keeps_affine_motion(test, device):
    rng = np.random.default_rng(3)
    # translation, rotation, shear and expansion at once
    grad = rng.normal(0.0, 1.0, size=(3, 3))
    v0 = rng.normal(0.0, 1.0, size=3)
    q, v, after = velocity_pass(device, lambda x: v0 + (x - x.mean(axis=0)) @ grad.T, 1.0)
    # the fit reproduces the field up to its regulariser (a per mille of the gradient's part)
    test.assertLess(np.abs(after - v).max(), 2.0e-3 * np.abs(v).max())
    # Shepard viscosity of the same strength does not: it pulls the edges toward their inner neighbours
    _, _, blended = velocity_pass(device, lambda x: v0 + (x - x.mean(axis=0)) @ grad.T, 0.0, viscosity=1.0)
    test.assertGreater(np.abs(blended - v).max(), 20.0 * np.abs(after - v).max())


def test_nonaffine_damping_follows_the_substep(test, device):
    # a substep of two reference steps removes what two substeps of one would: 1 - (1 - 0.5)^2 = 0.75
    rng = np.random.default_rng(5)
    noise = rng.normal(0.0, 0.1, size=(512, 3))
    _, v, once = velocity_pass(device, lambda x: noise, 0.5)
    _, _, twice = velocity_pass(device, lambda x: noise, 0.5, steps=2.0)
    _, _, half = velocity_pass(device, lambda x: noise, 0.5, steps=0.5)
    removed_once = np.linalg.norm(v - once)
    test.assertAlmostEqual(np.linalg.norm(v - twice) / removed_once, 0.75 / 0.5, places=3)
    test.assertAlmostEqual(np.linalg.norm(v - half) / removed_once, (1.0 - 0.5**0.5) / 0.5, places=3)


def test_nonaffine_damping_removes_particle_noise(test, device):
    rng = np.random.default_rng(4)
    grad = rng.normal(0.0, 1.0, size=(3, 3))
    noise = rng.normal(0.0, 0.1, size=(512, 3))

    def field(x):
        return (x - x.mean(axis=0)) @ grad.T + noise

    q, v, after = velocity_pass(device, field, 0.5)
    smooth = (q - q.mean(axis=0)) @ grad.T
    # the particles whose whole kernel lies in the block (the surface's fit sees half a neighbourhood)
    inner = np.all(np.abs(q - q.mean(axis=0)) < 4.0 * D - 1.8 * D, axis=1)
    test.assertGreater(np.count_nonzero(inner), 20)
    before = np.linalg.norm(v - smooth, axis=1)[inner].mean()
    left = np.linalg.norm(after - smooth, axis=1)[inner].mean()
    # half the deviation from the affine field goes, give or take the noise the fit itself takes in
    test.assertLess(left, 0.75 * before)
    test.assertGreater(left, 0.4 * before)
    # without the damping the pass leaves the velocities as they are
    _, v_off, after_off = velocity_pass(device, field, 0.0)
    np.testing.assert_array_equal(after_off, v_off.astype(np.float32))


def test_nonaffine_damping_once_an_interval(test, device):
    # about every 1/120 s: every 4th substep of 8 a 60 Hz frame, each substep of 2
    test.assertEqual([damping_every(1.0 / (60.0 * s)) for s in (1, 2, 4, 8, 16)], [1, 1, 2, 4, 8])
    removed = {}
    for substeps in (8, 2):
        # spaced apart, so no density correction moves the particles: only the damping changes a velocity
        model = make_model(device, lambda b: add_block(b, (6, 6, 6), spacing=1.1 * D))
        sim = Sim(model, substeps=substeps, fluid_nonaffine_damping=0.5)
        noise = np.random.default_rng(6).normal(0.0, 0.01, size=(216, 3))
        sim.state_0.particle_qd.assign(noise.astype(np.float32))
        changes = []
        for _ in range(substeps):
            before = sim.qd()
            sim.solver.step(sim.state_0, sim.state_1, None, None, sim.dt)
            sim.state_0, sim.state_1 = sim.state_1, sim.state_0
            changes.append(np.linalg.norm(sim.qd() - before))
        due = [k for k, change in enumerate(changes) if change > 1.0e-3]
        test.assertEqual(due, [3, 7] if substeps == 8 else [0, 1])
        removed[substeps] = changes[due[0]]
    # either way the first damping stands for 1/120 s: 1 - (1 - 0.5)^4 of the deviation goes
    test.assertAlmostEqual(removed[8] / removed[2], 1.0, delta=0.01)


def still_column(device, frames, **solver_kwargs):
    """A 6 x 6 x 12 column (spacing 0.05 m) at rest in a closed frictionless box, 8 x 2 at 60 Hz; RMS speed per frame."""
    n, layers, d = 6, 12, 0.05

    def build(b):
        add_block(b, (n, n, layers), origin=(0.5 * d, 0.5 * d, 0.5 * d), spacing=d, mass=1000.0 * d**3, radius=0.5 * d)
        add_closed_box(b, n * d, 1.5 * layers * d)

    model = make_model(device, build, gravity=-9.81)
    model.soft_contact_mu = 0.0
    sim = Sim(model, substeps=8, contacts=True, fluid_rest_distance=d, **solver_kwargs)
    rms = []
    for _ in range(frames):
        sim.step()
        speed = np.linalg.norm(sim.qd(), axis=1)
        rms.append(math.sqrt(float(np.mean(speed * speed))))
    return np.asarray(rms), sim.q()


def test_still_column_comes_to_rest(test, device):
    rms, q = still_column(device, 180)
    test.assertTrue(np.isfinite(q).all())
    # after 2 s of settling: below a quarter of g times the substep (issue #23's bound for RMS speed)
    test.assertLess(rms[120:].mean(), 0.005)
    # without the step bound and the damping (the solver before them) the same column churns
    churn, _ = still_column(device, 180, fluid_relaxation=1.0, fluid_nonaffine_damping=0.0)
    test.assertGreater(churn[120:].mean(), 10.0 * rms[120:].mean())


def test_odd_pass_counts_come_to_rest(test, device):
    # an odd count's last pass takes half the step, so no mode keeps a negative share of its error (which
    # flips sign every substep): the column rests at 8 x 1 and 8 x 3 as at 8 x 2 (CPU, over 2-3 s: 0.0004 and
    # 0.0022 m/s)
    rest = {}
    for iterations in (1, 3):
        rms, q = still_column(device, 180, iterations=iterations)
        test.assertTrue(np.isfinite(q).all())
        test.assertLess(rms[120:].mean(), 0.005)
        rest[iterations] = rms[120:].mean()
    # every pass at the step that keeps the modes inside the linear bound (a relaxation set by hand has no
    # closing pass) hums: the step 3 passes took before (CPU 0.0099 m/s)
    # (the default kernel's spectral radius: the one kernel's)
    radius = jacobi_spectral_radius(D, 1.8 * D, kernel="one_kernel")
    hum, _ = still_column(device, 180, iterations=3, fluid_relaxation=0.875 * stable_pass_bound(3, 4) / radius)
    test.assertGreater(hum[120:].mean(), 2.0 * rest[3])


def test_subpasses_come_to_rest(test, device):
    # sub-passes in one XPBD iteration: each goes on from where the iteration's deltas so far put the
    # particles, the walls' contacts included, and an iteration stops only after an even count (or closes an
    # odd one). Reading its own moves alone, the second pass pushed the particles out of the walls a second
    # time and the column hummed (CPU, over 2-3 s: 0.036 m/s with two passes, 0.061 with up to four; now 0.0028)
    for kwargs in (
        {"fluid_max_iterations": 2},
        {"fluid_max_iterations": 3},
        {"fluid_max_iterations": 4, "fluid_density_tolerance": 0.005},
    ):
        rms, q = still_column(device, 180, iterations=1, **kwargs)
        test.assertTrue(np.isfinite(q).all())
        test.assertLess(rms[120:].mean(), 0.005, kwargs)


# the floating-box scene: spacing [m], pool half-width [m], pool depth [m], box half-height [m] (its half-width
# is 0.15 m), box density [kg/m^3]
BOX_SPACING, BOX_POOL_HALF, BOX_POOL_DEPTH, BOX_HALF_HEIGHT, BOX_DENSITY = 0.05, 0.4, 0.3, 0.1, 500.0


def floating_box_sim(device, offset=0.0, **solver_kwargs):
    """The scene of :func:`floating_box` at its start: the box dropped onto the settled-lattice pool, 8 x 2.

    ``offset`` [m] moves the box's start along x (a micrometre is enough for another outcome).
    """
    d, box = BOX_SPACING, BOX_HALF_HEIGHT
    model = pool_with_box(
        device,
        BOX_DENSITY,
        d,
        BOX_POOL_HALF,
        BOX_POOL_DEPTH,
        (0.15, 0.15, box),
        box_z=BOX_POOL_DEPTH + box,
        box_x=offset,
    )
    return Sim(model, substeps=8, contacts=True, fluid_rest_distance=d, **solver_kwargs)


def tilt_deg(body_q) -> float:
    """How far a body's up axis leans from the vertical [deg], from its pose ``(x, y, z, qx, qy, qz, qw)``."""
    qx, qy = body_q[3], body_q[4]
    return math.degrees(math.acos(min(1.0, 1.0 - 2.0 * (qx * qx + qy * qy))))


def draft_over_archimedes(q, body_q) -> float:
    """The box's draft over Archimedes' from the particle positions ``q`` and the box's pose ``body_q``.

    The still level is :func:`still_level` beside the box, as test_floating_box_draft_matches_archimedes reads it.
    """
    box = BOX_HALF_HEIGHT
    level = still_level(q, 0.15, BOX_SPACING)
    return float((level - (body_q[2] - box)) / (BOX_DENSITY / 1000.0 * 2.0 * box))


def floating_box(device, offset=0.0, **solver_kwargs):
    """A 500 kg/m^3 box 0.3 x 0.3 m wide and 4 spacings (0.2 m) tall on a 0.8 m pool 0.3 m deep at 0.05 m,
    8 x 2, no viscosity, 5 s, the box started ``offset`` [m] off centre.

    Upright it is stable: its metacentre lies 0.025 m above its centre of mass (B M = w^2 / (12 draft),
    K B = draft / 2, K G = height / 2). A cube of that density is not (-0.017 m): it tips over, as it
    should, and could not test coming to rest upright. Returns the box's largest tilt [deg], mean
    angular and vertical speed over the last second, and its draft over Archimedes' (the still level
    away from the box, as test_floating_box_draft_matches_archimedes).
    """
    sim = floating_box_sim(device, offset, **solver_kwargs)
    sim.step(240)
    tilt, spin, sink = [], [], []
    for _ in range(6):
        sim.step(10)
        body_q, body_qd = sim.state_0.body_q.numpy()[0], sim.state_0.body_qd.numpy()[0]
        tilt.append(tilt_deg(body_q))
        spin.append(float(np.linalg.norm(body_qd[3:])))
        sink.append(abs(float(body_qd[2])))
    return max(tilt), float(np.mean(spin)), float(np.mean(sink)), draft_over_archimedes(sim.q(), body_q)


def test_floating_box_comes_to_rest(test, device):
    # Issue #23 asks, after 5 s: tilt below 1 deg, angular speed below 0.02 rad/s, vertical speed below
    # 0.005 m/s, draft within 5 % of Archimedes'. The run is chaotic: a start moved by a micrometre, or a
    # GPU's summation order, gives another outcome, so it is read over starts (docs/validation.rst, "Floating
    # box"). With the default kernel (the one kernel), over 12 starts 0 to 11 mm off centre the vertical speed and
    # the draft met their bounds in all (CPU: at most 0.0006 m/s, -1.0 to +0.8 %; one H200: 0.0007 m/s, -1.7 to
    # +0.8 %), the angular speed in 12 on the CPU and 11 on the H200 (largest 0.0195 and 0.032 rad/s), the tilt in
    # 10 and 9 (largest 1.20 and 1.47 deg); poly6 leaned 3-9 deg off centre. One run is held to the bounds
    # where every start met them, and above the starts' envelope where they did not.
    tilt, spin, sink, draft = floating_box(device)
    test.assertLess(tilt, 2.0)
    test.assertLess(spin, 0.04)
    test.assertLess(sink, 0.005)
    test.assertAlmostEqual(draft, 1.0, delta=0.05)
    # with the kernel and the keywords before the stable step and the damping the box rocked and floated high
    # (CPU: 0.99 deg, 0.136 rad/s, 0.0048 m/s, +31 %)
    _, spin_before, _, draft_before = floating_box(
        device, fluid_density_kernel="poly6", fluid_relaxation=1.0, fluid_nonaffine_damping=0.0
    )
    test.assertGreater(spin_before, 0.05)
    test.assertGreater(abs(draft_before - 1.0), 0.1)


class TestFluidStillWater(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestFluidStillWater, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
