# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Physics of the position-based fluid in SolverXPBD (small scenes; CPU always, CUDA when present)."""

import unittest
import warnings

import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton
from newton._src.solvers.xpbd.fluid.calibration import wall_density_tables
from newton._src.solvers.xpbd.fluid.config import FULL_NEIGHBOR_FACTOR, FluidTuning
from newton._src.solvers.xpbd.fluid.density_constraint import density_constraint_lambda
from newton._src.solvers.xpbd.fluid.neighbors import FluidNeighborSearch
from newton._src.solvers.xpbd.fluid.prefix_sum import SCAN_TILE, ExclusiveScan
from newton._src.solvers.xpbd.fluid.sph import (
    FluidParams,
    FluidSlots,
    SlotContent,
    fluid_neighbor,
    fluid_neighbor_layout,
)
from newton._src.solvers.xpbd.fluid.walls import WALL_CONTACTS_PER_SLOT, fluid_wall_share
from newton.examples.fluid.common import add_tank

FLUID = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)
D = 0.1  # rest distance [m]
MASS = 1000.0 * D**3


def add_block(
    builder, dims, origin=(0.0, 0.0, 0.0), spacing=D, vel=(0.0, 0.0, 0.0), jitter=0.0, mass=MASS, radius=0.5 * D
):
    builder.add_particle_grid(
        pos=wp.vec3(*origin),
        rot=wp.quat_identity(),
        vel=wp.vec3(*vel),
        dim_x=dims[0],
        dim_y=dims[1],
        dim_z=dims[2],
        cell_x=spacing,
        cell_y=spacing,
        cell_z=spacing,
        mass=mass,
        jitter=jitter,
        radius_mean=radius,
        flags=FLUID,
    )


def make_model(device, build, gravity=0.0):
    gravity = (0.0, 0.0, gravity)
    builder = newton.ModelBuilder(gravity=gravity)
    build(builder)
    return builder.finalize(device=device)


class Sim:
    """A model, two states, an optional collision pipeline and a fluid solver."""

    def __init__(self, model, substeps=4, fps=60.0, contacts=False, **solver_kwargs):
        solver_kwargs.setdefault("iterations", 2)
        solver_kwargs.setdefault("fluid_rest_distance", D)
        self.model = model
        self.solver = newton.solvers.SolverXPBD(model, **solver_kwargs)
        self.state_0, self.state_1 = model.state(), model.state()
        # contacts out to one diameter from the surface, so fluid particles see the walls' density
        gap = 0.5 * solver_kwargs["fluid_rest_distance"]
        self.collision = newton.CollisionPipeline(model, soft_contact_gap=gap) if contacts else None
        self.contacts = self.collision.contacts() if contacts else None
        self.dt = 1.0 / fps / substeps
        self.substeps = substeps

    def step(self, frames=1):
        for _ in range(frames * self.substeps):
            self.state_0.clear_forces()
            if self.collision is not None:
                self.collision.collide(self.state_0, self.contacts)
            self.solver.step(self.state_0, self.state_1, None, self.contacts, self.dt)
            self.state_0, self.state_1 = self.state_1, self.state_0

    def q(self):
        return self.state_0.particle_q.numpy().astype(np.float64)

    def qd(self):
        return self.state_0.particle_qd.numpy().astype(np.float64)


def test_rest_lattice_stays_at_rest(test, device):
    model = make_model(device, lambda b: add_block(b, (7, 7, 7)))
    sim = Sim(model)
    q0 = sim.q()
    stats = sim.solver.fluid_diagnostics(sim.state_0)
    rho = sim.solver.fluid_density.numpy()
    interior = np.all(np.abs(q0 - q0.mean(axis=0)) < 2.0 * D + 1.0e-6, axis=1)  # full kernel support
    test.assertEqual(np.count_nonzero(interior), 125)
    np.testing.assert_allclose(rho[interior] / stats["rest_density"], 1.0, atol=1.0e-3)
    sim.step(30)
    test.assertLess(np.abs(sim.q() - q0).max(), 1.0e-4 * D)
    test.assertLess(np.abs(sim.qd()).max(), 1.0e-4)


def test_column_settles_above_ground(test, device):
    def build(b):
        add_block(b, (4, 4, 12), origin=(0.5 * D, 0.5 * D, 0.5 * D), jitter=0.05 * D)
        b.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
        for c, h in (((-0.05, 0.2, 1.0), (0.05, 0.3, 1.0)), ((0.45, 0.2, 1.0), (0.05, 0.3, 1.0))):
            b.add_shape_box(-1, xform=wp.transform(wp.vec3(*c), wp.quat_identity()), hx=h[0], hy=h[1], hz=h[2], cfg=cfg)
        for c, h in (((0.2, -0.05, 1.0), (0.3, 0.05, 1.0)), ((0.2, 0.45, 1.0), (0.3, 0.05, 1.0))):
            b.add_shape_box(-1, xform=wp.transform(wp.vec3(*c), wp.quat_identity()), hx=h[0], hy=h[1], hz=h[2], cfg=cfg)

    model = make_model(device, build, gravity=-9.81)
    model.soft_contact_mu = 0.0
    sim = Sim(model, substeps=8, contacts=True, fluid_viscosity=0.05)
    lowest = np.inf
    for _ in range(60):
        sim.step()
        q = sim.q()
        lowest = min(lowest, q[:, 2].min())
        test.assertTrue(np.isfinite(q).all())
    # the column stays in its 4 x 4 footprint, so it only compacts; it neither explodes nor sinks
    test.assertGreater(lowest, 0.25 * D)
    test.assertLess(np.abs(sim.qd()).max(), 0.5)
    # the walls lend the density of the fluid missing behind them, so even this narrow column keeps
    # its height (initial top: 11.5 spacings plus jitter) instead of compacting against them
    test.assertLess(sim.q()[:, 2].max(), 12.0 * D)
    test.assertGreater(sim.q()[:, 2].max(), 11.0 * D)
    stats = sim.solver.fluid_diagnostics(sim.state_0)
    test.assertLess(stats["max_compression"], 0.06)


def add_walled_column(b):
    """A 6 x 6 x 10 column in a frictionless tank of its own width."""
    add_block(b, (6, 6, 10), origin=(0.5 * D, 0.5 * D, 0.5 * D))
    cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
    b.add_ground_plane(cfg=cfg)
    for c, h in (
        ((-0.05, 0.3, 1.0), (0.05, 0.4, 1.0)),
        ((0.65, 0.3, 1.0), (0.05, 0.4, 1.0)),
        ((0.3, -0.05, 1.0), (0.4, 0.05, 1.0)),
        ((0.3, 0.65, 1.0), (0.4, 0.05, 1.0)),
    ):
        b.add_shape_box(-1, xform=wp.transform(wp.vec3(*c), wp.quat_identity()), hx=h[0], hy=h[1], hz=h[2], cfg=cfg)


def test_applied_positions_match_a_gather(test, device):
    # the correction pass writes each particle's position and velocity as SolverXPBD then applies
    # them, so the next iteration and the viscosity pass gather nothing: the slots must hold what a
    # gather would (bitwise on the CPU; on CUDA the fluid code's fast math rounds the velocity clamp
    # differently), and a run with it must follow one without
    def build(b):
        add_walled_column(b)
        add_block(b, (3, 3, 2), origin=(0.25, 0.25, 1.3), vel=(0.0, 0.0, -3.0))  # fast: the clamp acts

    runs = []
    for viscosity, applied in ((0.0, True), (0.0, False), (0.1, True), (0.1, False)):
        model = make_model(device, build, gravity=-9.81)
        model.soft_contact_mu = 0.0
        model.particle_max_velocity = 2.0
        # viscosity 0: no velocity pass at all (the non-affine damping off too), so the slots' velocities are the step's
        sim = Sim(
            model,
            substeps=2,
            contacts=True,
            fluid_viscosity=viscosity,
            fluid_nonaffine_damping=viscosity,
            fluid_cohesion=0.5,
        )
        fluid = sim.solver._fluid
        if not applied:
            solve = fluid.solve_density
            fluid.solve_density = lambda q, deltas, apply=None, iterations=0, solve=solve: solve(
                q, deltas, None, iterations
            )
        sim.step(6)
        expected = SlotContent.APPLIED_WITH_VELOCITIES if applied else SlotContent.STALE
        test.assertIs(fluid.slot_content, expected)
        runs.append((sim.q(), sim.qd()))
        if applied and viscosity == 0.0:
            particle = fluid.slots.particle.numpy()
            inside = particle >= 0
            xm = fluid.slots.xm.numpy()[inside]
            v = fluid.sorted_v.numpy()[inside]
            q = sim.state_0.particle_q.numpy()[particle[inside]]
            qd = sim.state_0.particle_qd.numpy()[particle[inside]]
            test.assertGreater(np.abs(qd).max(), 1.9)  # the clamp acted
            if wp.get_device(device).is_cpu:
                np.testing.assert_array_equal(xm[:, :3], q)
                np.testing.assert_array_equal(v, qd)
            else:
                np.testing.assert_allclose(xm[:, :3], q, rtol=0.0, atol=1.0e-6)
                np.testing.assert_allclose(v, qd, rtol=0.0, atol=1.0e-4)
    for with_it, without in (runs[0:2], runs[2:4]):
        if wp.get_device(device).is_cpu:
            np.testing.assert_array_equal(with_it[0], without[0])
            np.testing.assert_array_equal(with_it[1], without[1])
        else:
            np.testing.assert_allclose(with_it[0], without[0], rtol=0.0, atol=1.0e-4)
            np.testing.assert_allclose(with_it[1], without[1], rtol=0.0, atol=1.0e-2)


def test_hydrostatic_column_stays_at_rest(test, device):
    model = make_model(device, add_walled_column, gravity=-9.81)
    model.soft_contact_mu = 0.0
    sim = Sim(model, substeps=8, contacts=True, fluid_viscosity=0.05)
    sim.step(60)
    settled = sim.q()
    sim.step(180)
    q = sim.q()
    # at rest: slow creep only (measured on CPU: mean 0.09, max 0.7 spacing over 3 s, the max at the surface);
    # a surface particle may hop now and then (seen up to 0.055 m/s on an H100, where atomics make runs
    # differ), so the bulk is judged by its RMS speed and the hop by a looser bound. The settled packing
    # also slips now and then as a whole (RMS speed above 0.01 m/s in 3 of 19 H100 runs; 0.029 m/s,
    # max 0.115 m/s, on the CPU after 17 s; docs/archive/validation_notebook.md), while a column that does not settle
    # (no viscosity) has an RMS speed of 0.24 m/s and a max of 0.93 m/s here: the bounds lie between
    speed = np.linalg.norm(sim.qd(), axis=1)
    test.assertLess(np.sqrt(np.mean(speed**2)), 0.05)
    test.assertLess(speed.max(), 0.3)
    test.assertLess(np.linalg.norm(q - settled, axis=1).mean(), 0.2 * D)
    # nearly incompressible, with the weight of the column carried by a compression that grows with depth
    fluid = sim.solver._fluid
    slot_particle = fluid.search.sorted_particle.numpy()
    rho = fluid.density.numpy() / fluid.rest_density
    lam = fluid.lambda_rho.numpy()[:, 0]
    layer = np.floor(q[slot_particle, 2] / D).astype(int)
    rho_layers = np.array([rho[layer == k].mean() for k in range(9)])
    lam_layers = np.array([lam[layer == k].mean() for k in range(9)])
    test.assertLess(np.abs(rho_layers - 1.0).max(), 0.005)
    test.assertGreater(rho_layers[:3].mean(), rho_layers[5:8].mean())
    test.assertLess(lam_layers[:3].mean(), 2.0 * lam_layers[5:8].mean())  # multipliers are <= 0


@wp.kernel
def evaluate_density_lambda(params: wp.array[FluidParams], rho: wp.array[float], out: wp.array[float]):
    i = wp.tid()
    out[i] = density_constraint_lambda(rho[i], wp.vec3(0.0), 1.0, params[0])


def test_density_ramp_is_smooth(test, device):
    # lambda is -psi(c) / (1 + epsilon) with the ramp psi: c^2 / (2 d) below d, c - d / 2 above, 0 below rest
    sim = Sim(make_model(device, lambda b: add_block(b, (2, 2, 2))))
    fluid = sim.solver._fluid
    d = 0.002
    c = np.linspace(-0.01, 0.01, 2001)
    rho = wp.array((1.0 + c) * fluid.rest_density, dtype=float, device=device)

    def psi():
        out = wp.zeros(len(c), dtype=float, device=device)
        wp.launch(evaluate_density_lambda, dim=len(c), inputs=[fluid.params, rho], outputs=[out], device=device)
        epsilon = float(fluid.params.numpy()[0]["epsilon"])
        return -out.numpy() * (1.0 + epsilon)

    off = psi()
    np.testing.assert_allclose(off, np.maximum(c, 0.0), atol=1.0e-6)
    sim.solver.fluid_density_ramp = d  # on the device: no new solver, no new graph
    ramp = psi()
    np.testing.assert_allclose(ramp, np.where(c < d, np.maximum(c, 0.0) ** 2 / (2.0 * d), c - 0.5 * d), atol=1.0e-6)
    # continuous with its slope at both ends of the ramp (samples 1e-5 apart; float32 rounding ~2e-7 in
    # the second difference), where the plain constraint's slope jumps from 0 to 1 at rest density
    test.assertLess(np.abs(np.diff(ramp)).max(), 1.05e-5)
    test.assertLess(np.abs(np.diff(ramp, 2)).max(), 1.0e-6)
    test.assertGreater(np.abs(np.diff(off, 2)).max(), 5.0e-6)


def test_cohesion_leaves_a_resting_column_quiet(test, device):
    # where the fluid is at rest density the density constraint holds it: a cohesive pull there only
    # compresses it and fights the constraint every substep (without the gate, on the CPU: RMS speed
    # 0.07-0.10 m/s and max compression 1.3-2.1 % over these samples; with it 0.017-0.021 m/s, still
    # settling, and 0.3 %, as without cohesion)
    model = make_model(device, add_walled_column, gravity=-9.81)
    model.soft_contact_mu = 0.0
    sim = Sim(model, substeps=8, contacts=True, fluid_viscosity=0.05, fluid_cohesion=1.0)
    sim.step(90)
    speeds, compression = [], []
    for _ in range(6):
        sim.step(5)
        speeds.append(np.sqrt(np.mean(np.sum(sim.qd() ** 2, axis=1))))
        compression.append(sim.solver.fluid_diagnostics(sim.state_0)["max_compression"])
    test.assertLess(np.mean(speeds), 0.05)
    test.assertLess(max(compression), 0.007)
    test.assertGreater(sim.q()[:, 2].max(), 0.85)  # standing, not fallen apart


def test_free_fall_matches_analytic(test, device):
    model = make_model(device, lambda b: add_block(b, (3, 3, 3), origin=(0.0, 0.0, 3.0)), gravity=-9.81)
    sim = Sim(model, substeps=4)
    q0 = sim.q()
    n = 40 * sim.substeps
    sim.step(40)
    # semi-implicit Euler from rest: z_n = z_0 - g dt^2 n (n + 1) / 2
    drop = 9.81 * sim.dt**2 * n * (n + 1) / 2.0
    # float32 positions: velocities from position differences carry ~ulp(z)/dt of rounding per substep
    np.testing.assert_allclose(sim.q()[:, 2], q0[:, 2] - drop, atol=1.0e-3 * drop)
    np.testing.assert_allclose(sim.q()[:, :2], q0[:, :2], atol=1.0e-5)
    np.testing.assert_allclose(sim.qd()[:, 2], -9.81 * n * sim.dt, rtol=1.0e-3)


def test_density_solve_conserves_momentum(test, device):
    rng = np.random.default_rng(3)
    model = make_model(device, lambda b: add_block(b, (6, 6, 6), spacing=0.95 * D, jitter=0.1 * D))
    v = rng.normal(0.0, 0.2, size=(model.particle_count, 3)).astype(np.float32)
    # the density solve's own momentum: the velocity pass (viscosity, non-affine damping) blends each velocity
    # with weights normalised per particle and keeps momentum only approximately
    sim = Sim(model, fluid_nonaffine_damping=0.0)
    sim.state_0.particle_qd.assign(v)
    p0 = v.astype(np.float64).sum(axis=0) * MASS
    q0 = sim.q()
    sim.step(10)
    test.assertGreater(np.abs(sim.q() - q0 - 10.0 / 60.0 * v).max(), 0.1 * D)  # the solve did move particles
    # (corrections below the per-iteration bound: beyond it, the bound trades momentum for stability)
    np.testing.assert_allclose(sim.qd().sum(axis=0) * MASS, p0, atol=1.0e-5 * np.abs(v).sum() * MASS)


def test_two_densities_rest_and_stratify(test, device):
    heavy_mass = 3.0 * MASS

    def build_lattice(b):
        add_block(b, (7, 7, 7))
        b.particle_mass[len(b.particle_mass) // 2 :] = [heavy_mass] * (len(b.particle_mass) - len(b.particle_mass) // 2)

    # a lattice of two particle masses is at the rest density of each: no pressure at the interface
    sim = Sim(make_model(device, build_lattice))
    q0 = sim.q()
    sim.step(20)
    test.assertLess(np.abs(sim.q() - q0).max(), 1.0e-4 * D)
    stats = sim.solver.fluid_diagnostics(sim.state_0)
    rho = sim.solver.fluid_density.numpy()
    masses = sim.model.particle_mass.numpy().astype(np.float64)
    interior = np.all(np.abs(q0 - q0.mean(axis=0)) < 2.0 * D + 1.0e-6, axis=1)
    # each particle at its own rest density: the reference one times its mass over the mean mass
    expected = stats["rest_density"] * masses / masses.mean()
    test.assertGreater(np.ptp(expected[interior]), 0.9 * expected.mean())
    np.testing.assert_allclose(rho[interior], expected[interior], rtol=1.0e-3)
    test.assertLess(stats["mean_compression"], 1.0e-4)

    # lock exchange: a heavy column beside a light one of the same height slumps under it
    def build_columns(b):
        add_block(b, (2, 5, 8), origin=(0.5 * D, 0.5 * D, 0.5 * D))
        add_block(b, (3, 5, 8), origin=(2.5 * D, 0.5 * D, 0.5 * D))
        b.particle_mass[:80] = [heavy_mass] * 80
        b.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
        for c, h in (((-0.05, 0.25, 1.0), (0.05, 0.35, 1.0)), ((0.55, 0.25, 1.0), (0.05, 0.35, 1.0))):
            b.add_shape_box(-1, xform=wp.transform(wp.vec3(*c), wp.quat_identity()), hx=h[0], hy=h[1], hz=h[2], cfg=cfg)
        for c, h in (((0.25, -0.05, 1.0), (0.35, 0.05, 1.0)), ((0.25, 0.55, 1.0), (0.35, 0.05, 1.0))):
            b.add_shape_box(-1, xform=wp.transform(wp.vec3(*c), wp.quat_identity()), hx=h[0], hy=h[1], hz=h[2], cfg=cfg)

    model = make_model(device, build_columns, gravity=-9.81)
    model.soft_contact_mu = 0.0
    heavy = model.particle_mass.numpy() > 2.0 * MASS
    sim = Sim(model, substeps=8, contacts=True, fluid_viscosity=0.05)
    sim.step(60)
    q = sim.q()
    test.assertTrue(np.isfinite(q).all())
    # both columns started with their centres at the same height; the heavy one ends below
    test.assertLess(q[heavy, 2].mean() - q[~heavy, 2].mean(), -0.2)
    test.assertTrue(np.all(np.abs(q[:, :2] - 0.25) < 0.3) and q[:, 2].min() > 0.0)


def replicate_blocks(device, worlds, velocities):
    """A fluid block per world, all worlds at the same place, world ``w`` thrown with ``velocities[w]``."""
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    for w in range(worlds):
        block = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
        add_block(block, (5, 5, 5), origin=(0.0, 0.0, 0.05), vel=velocities[w], jitter=0.1 * D)
        builder.add_world(block)
    builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model


def test_worlds_are_isolated(test, device):
    velocities = [(0.5, 0.0, 0.0), (0.5, 0.0, 0.0), (-1.0, 0.3, 0.0)]
    three = Sim(replicate_blocks(device, 3, velocities), contacts=True)
    alone = Sim(replicate_blocks(device, 1, velocities), contacts=True)
    three.step(20)
    alone.step(20)
    q3 = three.q().reshape(3, -1, 3)
    np.testing.assert_allclose(q3[0], q3[1], atol=1.0e-6)  # identical worlds, identical results
    np.testing.assert_allclose(q3[0], alone.q(), atol=1.0e-5)  # the others change nothing
    test.assertGreater(np.abs(q3[2] - q3[0]).max(), 0.1)  # and world 2 did its own thing


def test_overlapping_worlds_cost_one_world(test, device):
    v = [(0.0, 0.0, 0.0)] * 8
    one = Sim(replicate_blocks(device, 1, v))
    eight = Sim(replicate_blocks(device, 8, v))
    s1 = one.solver.fluid_diagnostics(one.state_0)
    s8 = eight.solver.fluid_diagnostics(eight.state_0)
    test.assertEqual(s8["active_particles"], 8 * s1["active_particles"])
    test.assertAlmostEqual(s8["neighbors_mean"], s1["neighbors_mean"], places=5)
    # candidates examined per particle: hash collisions between worlds may add a few, never a world's worth
    test.assertLess(s8["candidates_mean"], 1.1 * s1["candidates_mean"])


def test_cohesion_holds_droplet_and_leaves_isolated_particle(test, device):
    def build(b):
        add_block(b, (4, 4, 4), spacing=1.05 * D)
        b.add_particle(pos=wp.vec3(5.0, 0.0, 0.0), vel=wp.vec3(0.0), mass=MASS, radius=0.5 * D, flags=FLUID)

    spreads = {}
    for cohesion in (0.0, 1.0):
        model = make_model(device, build)
        rng = np.random.default_rng(0)
        q0 = model.particle_q.numpy()
        centre = q0[:64].mean(axis=0)
        v = np.zeros_like(q0)
        v[:64] = (q0[:64] - centre) * 1.5 + rng.normal(0.0, 0.05, size=(64, 3))  # the droplet flies apart
        sim = Sim(model, fluid_cohesion=cohesion)
        sim.state_0.particle_qd.assign(v.astype(np.float32))
        sim.step(60)
        q = sim.q()
        spreads[cohesion] = np.linalg.norm(q[:64] - q[:64].mean(axis=0), axis=1).max()
        np.testing.assert_array_equal(q[64], q0[64])  # isolated particle: no neighbour, no motion
    test.assertLess(spreads[1.0], 0.6 * spreads[0.0])
    test.assertLess(spreads[1.0], 5.0 * D)


def test_viscosity_lowers_relative_velocity(test, device):
    rng = np.random.default_rng(1)
    spread = {}
    for nu in (0.0, 0.3):
        model = make_model(device, lambda b: add_block(b, (6, 6, 6)))
        sim = Sim(model, fluid_viscosity=nu)
        sim.state_0.particle_qd.assign(rng.normal(0.0, 0.1, size=(model.particle_count, 3)).astype(np.float32))
        rng = np.random.default_rng(1)
        sim.step(5)
        qd = sim.qd()
        spread[nu] = np.linalg.norm(qd - qd.mean(axis=0), axis=1).mean()
    test.assertLess(spread[0.3], 0.5 * spread[0.0])


def swirl_energy(q, qd):
    r = q - q.mean(axis=0)
    omega_z = (r[:, 0] * qd[:, 1] - r[:, 1] * qd[:, 0]) / np.maximum(r[:, 0] ** 2 + r[:, 1] ** 2, 1.0e-9)
    return float(np.sum(qd * qd)), float(np.mean(np.abs(omega_z)))


def test_vorticity_confinement_adds_rotational_energy(test, device):
    energy = {}
    for eps in (0.0, 0.5):
        model = make_model(device, lambda b: add_block(b, (8, 8, 4), origin=(-0.35, -0.35, 0.0)))
        q = model.particle_q.numpy()
        rng = np.random.default_rng(2)
        # small random eddies on top of a slow swirl
        v = np.stack([-q[:, 1], q[:, 0], np.zeros(len(q))], axis=1) * 0.5 + rng.normal(0.0, 0.05, q.shape)
        sim = Sim(model, fluid_vorticity=eps, fluid_viscosity=0.01)
        sim.state_0.particle_qd.assign(v.astype(np.float32))
        sim.step(10)
        energy[eps] = swirl_energy(sim.q(), sim.qd())[0]
    test.assertGreater(energy[0.5], 1.05 * energy[0.0])


def brute_force_neighbors(q, h):
    d2 = np.sum((q[:, None, :] - q[None, :, :]) ** 2, axis=-1)
    return (d2 < h * h).sum(axis=1) - 1


def test_neighbor_cap(test, device):
    model = make_model(device, lambda b: add_block(b, (6, 6, 6), spacing=0.7 * D, jitter=0.1 * D))
    full = Sim(model)
    # packed at 0.7 spacings: about three times the rest density, and the diagnostics say so
    with test.assertWarnsRegex(RuntimeWarning, "compressed by"):
        stats = full.solver.fluid_diagnostics(full.state_0)
    expected = brute_force_neighbors(model.particle_q.numpy().astype(np.float64), full.solver.fluid_smoothing_length)
    test.assertAlmostEqual(stats["neighbors_mean"], expected.mean(), places=4)
    test.assertEqual(stats["neighbors_max"], expected.max())
    test.assertEqual(stats["neighbor_overflow"], 0)
    capped = Sim(model, fluid_max_neighbors=12)
    cstats = capped.solver.fluid_diagnostics(capped.state_0)
    test.assertEqual(cstats["neighbors_max"], 12)
    test.assertLess(cstats["candidates_mean"], 0.75 * stats["candidates_mean"])  # the scan stopped early
    capped.step(3)
    test.assertTrue(np.isfinite(capped.q()).all())


def test_sort_orders_each_cell_by_fluid_index(test, device):
    # the scatter's atomic ranks arrive in any order on a GPU; the build puts each cell's slots in
    # fluid-index order so that a run does not depend on them (and leaves the cell counts zero)
    rng = np.random.default_rng(7)

    def build(b):
        for x in rng.uniform(0.0, 0.6, size=(400, 3)):
            b.add_particle(pos=wp.vec3(*x), vel=wp.vec3(0.0), mass=MASS, radius=0.5 * D, flags=FLUID)
        for _ in range(40):  # one crowded cell
            b.add_particle(pos=wp.vec3(0.05, 0.05, 0.05), vel=wp.vec3(0.0), mass=MASS, radius=0.5 * D, flags=FLUID)
        for x in rng.uniform(0.0, 0.6, size=(30, 3)):  # inactive: left out, last
            b.add_particle(
                pos=wp.vec3(*x), vel=wp.vec3(0.0), mass=MASS, radius=0.5 * D, flags=int(newton.ParticleFlags.FLUID)
            )

    solver = Sim(make_model(device, build)).solver
    search = solver._fluid.search
    for _ in range(2):
        search.build(
            *(getattr(solver.model, a) for a in ("particle_q", "particle_mass", "particle_flags", "particle_world")),
            solver._fluid.params,
        )
        keys, values = search.keys.numpy(), search.values.numpy()
        test.assertEqual(sorted(values.tolist()), list(range(len(values))))
        test.assertTrue(np.all(np.diff(keys) >= 0))
        inside = keys <= search.mask
        test.assertEqual(np.count_nonzero(~inside), 30)
        same_cell = (keys[1:] == keys[:-1]) & inside[1:]
        test.assertTrue(np.all(np.diff(values)[same_cell] > 0))
        test.assertGreaterEqual(np.bincount(keys[inside]).max(), 40)
        test.assertEqual(np.count_nonzero(search.cell_count.numpy()), 0)


def test_prefix_sum_matches_cumsum(test, device):
    # one tile, one past it, and three levels of tiles (a table of 2^20 entries and more, as 500k fluid
    # particles make); the counts as the sort's cells hold them, many zeros
    rng = np.random.default_rng(3)
    for n in (1, SCAN_TILE - 1, SCAN_TILE + 1, 37 * SCAN_TILE + 5, SCAN_TILE * SCAN_TILE + 9):
        with test.subTest(n=n):
            counts = (rng.integers(0, 3, n) * (rng.random(n) < 0.3)).astype(np.int32)
            offsets = wp.full(n, -7, dtype=wp.int32, device=device)
            scan = ExclusiveScan(n, device)
            for _ in range(2):  # its storage is reused
                scan.run(wp.array(counts, dtype=wp.int32, device=device), offsets)
                np.testing.assert_array_equal(offsets.numpy(), np.cumsum(counts) - counts)


def test_allocation_free_sort_sorts_as_array_scan(test, device):
    # the sort in a conditional node's body takes its offsets from ExclusiveScan: the same slots
    rng = np.random.default_rng(5)
    q = rng.uniform(0.0, 0.4, size=(700, 3)).astype(np.float32)
    n = len(q)
    args = (
        wp.array(q, dtype=wp.vec3, device=device),
        wp.full(n, MASS, dtype=float, device=device),
        wp.full(n, int(FLUID), dtype=wp.int32, device=device),
        wp.zeros(n, dtype=wp.int32, device=device),
    )
    params = wp.zeros(1, dtype=FluidParams, device=device)
    built = []
    for allocation_free in (False, True):
        search = FluidNeighborSearch(
            wp.array(np.arange(n, dtype=np.int32), dtype=wp.int32, device=device), n, 1, 1.8 * D, 120, False
        )
        search.compute_keys(args[0], args[2], args[3], params)
        search.sort(args[0], args[1], args[3], allocation_free=allocation_free)
        built.append([a.numpy() for a in (search.cell_offset, search.keys, search.values, search.sorted_particle)])
    for a, b in zip(*built, strict=True):
        np.testing.assert_array_equal(a, b)
    test.assertGreater(built[0][0].max(), 0)


@wp.kernel
def read_neighbor_lists(slots: FluidSlots, out: wp.array2d[wp.int32], count: wp.array[wp.int32]):
    i = wp.tid()
    layout = fluid_neighbor_layout(slots, i)
    count[i] = layout[2]
    for k in range(wp.min(layout[2], out.shape[1])):
        out[i, k] = fluid_neighbor(slots, i, k, layout)


def test_scan_lanes_list_the_same_neighbors(test, device):
    # one to three threads per particle each list a part of the 27 cells: read lane after lane, the
    # lists must be those of one thread (same neighbours, same order, so the same sums), and exact
    rng = np.random.default_rng(11)
    q = np.vstack([rng.uniform(0.0, 0.6, size=(300, 3)), np.full((12, 3), 0.21)]).astype(np.float32)
    n = len(q)
    h = 1.8 * D
    particle_q = wp.array(q, dtype=wp.vec3, device=device)
    mass = wp.full(n, MASS, dtype=float, device=device)
    flags = wp.full(n, int(FLUID), dtype=wp.int32, device=device)
    world = wp.zeros(n, dtype=wp.int32, device=device)
    params = wp.zeros(1, dtype=FluidParams, device=device)
    lists = {}
    for lanes in (1, 2, 3):
        search = FluidNeighborSearch(
            wp.array(np.arange(n, dtype=np.int32), dtype=wp.int32, device=device), n, 1, h, 120, False, lanes=lanes
        )
        test.assertEqual(search.lanes, lanes)
        search.build(particle_q, mass, flags, world, params)
        out = wp.full((n, 120), -1, dtype=wp.int32, device=device)
        count = wp.zeros(n, dtype=wp.int32, device=device)
        wp.launch(read_neighbor_lists, dim=n, inputs=[search.slots], outputs=[out, count], device=device)
        lists[lanes] = (out.numpy(), count.numpy(), search.sorted_particle.numpy())
    out, count, particle = lists[1]
    for lanes in (2, 3):
        np.testing.assert_array_equal(lists[lanes][0], out)
        np.testing.assert_array_equal(lists[lanes][1], count)
    d2 = np.sum((q[:, None, :].astype(np.float64) - q[None, :, :]) ** 2, axis=-1)
    # (pairs within float rounding of h may go either way)
    for i in range(n):
        found = set(particle[out[i, : count[i]]].tolist())
        test.assertEqual(len(found), count[i])
        row = d2[particle[i]]
        inside = {j for j in np.flatnonzero(row < h * h * (1.0 - 1.0e-5)) if j != particle[i]}
        near = {j for j in np.flatnonzero(row < h * h * (1.0 + 1.0e-5)) if j != particle[i]}
        test.assertTrue(inside <= found <= near)
    test.assertGreater(count.max(), 30)
    # a block at 0.7 spacings (about 3x the rest neighbours) fits the lanes' rows as it fits one
    # lane's: one-sided neighbourhoods at its faces put most of a list in one lane
    block = make_model(device, lambda b: add_block(b, (6, 6, 6), spacing=0.7 * D, jitter=0.1 * D))
    fluid = Sim(block).solver._fluid
    m = block.particle_count
    for lanes in (1, 2, 3):
        search = FluidNeighborSearch(
            wp.array(np.arange(m, dtype=np.int32), dtype=wp.int32, device=device),
            m,
            1,
            h,
            FULL_NEIGHBOR_FACTOR * fluid.rest_lattice_neighbors,
            False,
            lanes=lanes,
        )
        search.build(block.particle_q, block.particle_mass, block.particle_flags, block.particle_world, params)
        found = search.neighbor_count.numpy().reshape(lanes, m)
        test.assertLessEqual(found.max(), search.lane_capacity)
        test.assertGreater(found.sum(axis=0).max(), 70)
    with test.assertRaises(ValueError):
        FluidNeighborSearch(wp.zeros(4, dtype=wp.int32, device=device), 4, 1, h, 8, True, lanes=2)


def test_coincident_particles_separate_deterministically(test, device):
    def build(b):
        for _ in range(4):
            b.add_particle(pos=wp.vec3(0.0, 0.0, 1.0), vel=wp.vec3(0.0), mass=MASS, radius=0.5 * D, flags=FLUID)

    for kernel in ("one_kernel", "poly6"):
        results, first = [], None
        for _ in range(2):
            # the density solve's symmetric push alone (see test_density_solve_conserves_momentum)
            sim = Sim(make_model(device, build), fluid_nonaffine_damping=0.0, fluid_density_kernel=kernel)
            sim.step(1)
            first = sim.q().mean(axis=0)
            sim.step(4)
            results.append(sim.q())
        q = results[0]
        test.assertTrue(np.isfinite(q).all())
        d = np.linalg.norm(q[:, None] - q[None, :], axis=-1)[np.triu_indices(4, 1)]
        test.assertGreater(d.min(), 0.2 * D, msg=kernel)
        np.testing.assert_array_equal(results[0], results[1])
        # the placement's relaxation moves positions only: no momentum, the cloud stays where it was put apart
        np.testing.assert_allclose(sim.qd().mean(axis=0), 0.0, atol=1.0e-5, err_msg=kernel)
        np.testing.assert_allclose(q.mean(axis=0), first, atol=1.0e-6, err_msg=kernel)
        if kernel == "poly6":
            # its pushes stay within the bound of one pass's move: symmetric, the centre kept
            np.testing.assert_allclose(q.mean(axis=0), (0.0, 0.0, 1.0), atol=1.0e-6)
        else:
            # the one kernel's first push passes the bound, which shortens each particle's move by its own
            # factor (relaxed_correction): the centre shifts by 0.07 spacings (CPU), in position only
            test.assertLess(np.linalg.norm(q.mean(axis=0) - (0.0, 0.0, 1.0)), 0.1 * D)


def still_level(q, box_half, spacing):
    """The still water level [m] of a pool, read more than two spacings beside a box of half-width ``box_half``.

    The 99th percentile of those particles' heights plus a radius: the surface away from the water the box
    displaces and its wake.
    """
    far = (np.abs(q[:, 0]) > box_half + 2.0 * spacing) | (np.abs(q[:, 1]) > box_half + 2.0 * spacing)
    return float(np.percentile(q[far, 2], 99) + 0.5 * spacing)


def pool_with_box(
    device, box_density, spacing=D, half=0.5, depth=0.5, box_half=(0.15, 0.15, 0.1), box_z=0.75, box_x=0.0
):
    """Water ``depth`` [m] deep at ``spacing`` in a frictionless square pool of half-width ``half``, and a box above."""
    builder = newton.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    # as many columns as fit between the walls (benchmarks/floating_box.py: rounding up starts some inside them)
    n, d = int(2.0 * half / spacing + 1.0e-3), spacing
    origin = (-half + 0.5 * d, -half + 0.5 * d, 0.5 * d)
    add_block(builder, (n, n, int(round(depth / d))), origin, spacing=d, mass=1000.0 * d**3, radius=0.5 * d)
    builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    add_tank(builder, half, half, 1.0, 0.05)
    body = builder.add_body(xform=wp.transform(wp.vec3(box_x, 0.0, box_z), wp.quat_identity()))
    box_cfg = newton.ModelBuilder.ShapeConfig(mu=0.0, density=box_density)
    builder.add_shape_box(body, hx=box_half[0], hy=box_half[1], hz=box_half[2], cfg=box_cfg)
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    return model


def test_two_way_coupling_floats_and_sinks(test, device):
    heights, inside = {}, {}
    for density in (300.0, 3000.0):
        model = pool_with_box(device, density)
        sim = Sim(model, substeps=8, contacts=True, fluid_viscosity=0.1)
        # 3 s: the water's non-affine damping slows the flow around a moving box (1.5 s left the heavy box
        # at 0.34 m, still sinking)
        sim.step(180)
        q = sim.q()
        test.assertTrue(np.isfinite(q).all())
        heights[density] = sim.state_0.body_q.numpy()[0, 2]
        # the box pushed the water out of its way: no particle centre inside it
        local = np.abs(q - sim.state_0.body_q.numpy()[0, :3])
        inside[density] = np.count_nonzero(np.all(local < np.array([0.15, 0.15, 0.1]), axis=1))
    # the water pushes the light box up: it floats with its centre near the surface (water top ~0.43 m)
    test.assertGreater(heights[300.0], 0.4)
    # the heavy box sinks through the water toward the floor (a layer or two of water stays under it)
    test.assertLess(heights[3000.0], 0.3)
    test.assertEqual(inside, {300.0: 0, 3000.0: 0})


def test_floating_box_draft_matches_archimedes(test, device):
    # a box at rest in a pool sinks until it displaces its own mass of water: draft = rho_box / rho_water x
    # height. At half the spacing of the pool above (the box 4 spacings tall) the two-way coupling resolves it
    # within a few percent (benchmarks/floating_box.py maps it by resolution; at 2 spacings the box rides on
    # the top layer of particles)
    d, half, depth, box = 0.5 * D, 0.3, 0.3, 0.1
    drafts = {}
    for density in (250.0, 750.0):
        model = pool_with_box(device, density, d, half, depth, (box, box, box), box_z=depth + box)
        sim = Sim(model, substeps=8, contacts=True, fluid_rest_distance=d, fluid_viscosity=0.1)
        # the box settles within 3 s (the water's non-affine damping slows the flow around it: after 1.5 s
        # the light box was still sinking, 20 % short of its draft)
        sim.step(180)
        heights = []
        for _ in range(30):
            sim.step(1)
            heights.append(sim.state_0.body_q.numpy()[0, 2])
        q = sim.q()
        test.assertTrue(np.isfinite(q).all())
        # the still level away from the box (raised by the water it displaced), and the box at rest on it
        level = still_level(q, box, d)
        test.assertLess(np.ptp(heights), 0.25 * d)
        drafts[density] = level - (np.mean(heights) - box)
    # measured on the CPU (2026-11-30) at the defaults (the one kernel): 0.0487 and 0.1521 m against 0.05 and 0.15
    # (-2.5 %, +1.4 %); with the box started 1e-4, 2e-4 and 1e-3 m off centre 1.06, 1.06 and 1.14 of Archimedes'
    # for the light box (2 spacings deep: a reading by the bound) and 0.99-1.02 for the heavy one. With poly6, the
    # default before, -0.3 % and -11 %, the heavy box 0.85-0.86 with the pool moved by 1e-4 and 2e-4 m
    # (docs/archive/validation_notebook.md, "The floor's pump")
    for density, draft in drafts.items():
        test.assertAlmostEqual(draft / (density / 1000.0 * 2.0 * box), 1.0, delta=0.15)


def test_kinematic_walls_lend_density_like_static_ones(test, device):
    """A tank on a kinematic body (placed through its pose) holds the fluid exactly as the same static tank."""

    def build(b, body_pose):
        add_block(b, (5, 5, 6), origin=(-0.2, -0.2, 0.05))
        b.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0, density=0.0, has_shape_collision=False)
        body = -1
        if body_pose is not None:
            body = b.add_body(xform=wp.transform(body_pose, wp.quat_identity()), is_kinematic=True)
        for center, half in (((-0.3, 0, 0.5), (0.05, 0.35, 0.5)), ((0.3, 0, 0.5), (0.05, 0.35, 0.5)),
                             ((0, -0.3, 0.5), (0.25, 0.05, 0.5)), ((0, 0.3, 0.5), (0.25, 0.05, 0.5))):  # fmt: skip
            local = np.array(center) - (np.zeros(3) if body_pose is None else np.array(body_pose))
            b.add_shape_box(body, xform=wp.transform(wp.vec3(*local), wp.quat_identity()), hx=half[0], hy=half[1],
                            hz=half[2], cfg=cfg)  # fmt: skip

    runs = {}
    for name, pose in (("static", None), ("kinematic", (0.4, -0.2, 0.1))):
        model = make_model(device, lambda b, pose=pose: build(b, pose), gravity=-9.81)
        model.soft_contact_mu = 0.0
        sim = Sim(model, contacts=True)
        sim.step(10)
        runs[name] = sim.q()[: 5 * 5 * 6]
    # the walls moved the fluid (it is not just falling freely) ...
    test.assertGreater(np.abs(runs["static"][:, :2]).max(), 0.2 - 1.0e-3)
    # ... and the kinematic tank, its shapes placed by the body's pose, held it the same way
    # (within float rounding: the contacts come in another order; without the kinematic walls' density
    # the fluid ends up to 0.15 m elsewhere)
    np.testing.assert_allclose(runs["kinematic"], runs["static"], atol=1.0e-3)


def test_dropped_wall_contacts_are_reported(test, device):
    """A collision buffer too small for the particles at the walls: the diagnostics say how many were dropped."""

    def build(b):
        add_block(b, (6, 6, 3), origin=(0.05, 0.05, 0.05))
        b.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))

    model = make_model(device, build, gravity=-9.81)
    for room, expect_warning in ((10, True), (4 * model.particle_count, False)):
        sim = Sim(model)
        sim.collision = newton.CollisionPipeline(model, soft_contact_max=room, soft_contact_gap=0.5 * D)
        sim.contacts = sim.collision.contacts()
        sim.step(1)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            stats = sim.solver.fluid_diagnostics(sim.state_0)
        dropped = [w for w in caught if "particle-shape contacts" in str(w.message)]
        # the bottom layer, 36 particles, touches the ground
        test.assertEqual(stats["soft_contacts_dropped"], 36 - 10 if expect_warning else 0)
        test.assertEqual(len(dropped), int(expect_warning))
        if expect_warning:
            test.assertIn("soft_contact_max >= 36", str(dropped[0].message))


def test_nonfinite_particles_recovered_and_counted(test, device):
    # with vorticity confinement on, its pass (the substep's last) does the recovery
    for vorticity in (0.0, 0.5):
        model = make_model(device, lambda b: add_block(b, (4, 4, 4), origin=(0.0, 0.0, 1.0)), gravity=-9.81)
        sim = Sim(model, substeps=1, fluid_vorticity=vorticity)
        sim.step(3)
        reference = Sim(
            make_model(device, lambda b: add_block(b, (4, 4, 4), origin=(0.0, 0.0, 1.0)), gravity=-9.81),
            substeps=1,
            fluid_vorticity=vorticity,
        )
        reference.step(3)
        before = sim.q()
        q = before.astype(np.float32)
        q[5] = np.nan
        qd = sim.qd().astype(np.float32)
        qd[9] = np.inf
        sim.state_0.particle_q.assign(q)
        sim.state_0.particle_qd.assign(qd)
        sim.step(1)
        q_after = sim.q()
        test.assertTrue(np.isfinite(q_after).all() and np.isfinite(sim.qd()).all())
        test.assertEqual(sim.solver.fluid_nonfinite_count.numpy()[0], 2)
        np.testing.assert_allclose(q_after[5], before[5], atol=1.0e-6)  # restored to its last finite position
        np.testing.assert_array_equal(sim.qd()[5], 0.0)
        with test.assertWarnsRegex(RuntimeWarning, "^2 fluid particles since the last report had a non-finite"):
            test.assertEqual(sim.solver.fluid_diagnostics(sim.state_0)["nonfinite_recovered"], 2)
        # once: the next report has no new recovery
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            test.assertEqual(sim.solver.fluid_diagnostics(sim.state_0)["nonfinite_recovered"], 2)
        # everything else continued as if nothing happened
        reference.step(1)
        others = np.setdiff1d(np.arange(model.particle_count), [5, 9])
        far = others[np.linalg.norm(before[others] - before[5], axis=1) > 2.0 * D]
        far = far[np.linalg.norm(before[far] - before[9], axis=1) > 2.0 * D]
        test.assertGreater(len(far), 0)
        np.testing.assert_allclose(q_after[far], reference.q()[far], atol=1.0e-6)


def test_parameters_change_captured_graph(test, device):
    """Parameter changes reach a captured graph, including switching a pass on from 0 and off again."""
    rng = np.random.default_rng(4)
    model = make_model(device, lambda b: add_block(b, (6, 6, 6)))
    v = rng.normal(0.0, 0.2, size=(model.particle_count, 3)).astype(np.float32)
    sim = Sim(model, fluid_viscosity=0.0)
    with wp.ScopedCapture(device=device) as capture:
        sim.step(1)  # an even number of substeps: state_0 is the graph's input and output

    def replay(name, value, velocities):
        """Set one parameter, restart from the initial positions at ``velocities``, replay the graph."""
        setattr(sim.solver, name, value)
        sim.state_0.particle_q.assign(model.particle_q)
        sim.state_0.particle_qd.assign(velocities)
        wp.capture_launch(capture.graph)

    spread = {}
    for nu in (0.0, 0.8, 0.0):
        replay("fluid_viscosity", nu, v)
        qd = sim.qd()
        spread.setdefault(nu, []).append(np.linalg.norm(qd - qd.mean(axis=0), axis=1).mean())
    test.assertLess(spread[0.8][0], 0.5 * spread[0.0][0])
    test.assertAlmostEqual(spread[0.0][0], spread[0.0][1], places=6)
    # vorticity confinement, switched on from 0 and off again: the captured pass reads the value on the device
    vorticity = {}
    for eps in (0.0, 2.0, 0.0):
        replay("fluid_vorticity", eps, v)
        vorticity.setdefault(eps, []).append(sim.qd())
    test.assertGreater(np.abs(vorticity[2.0][0] - vorticity[0.0][0]).max(), 1.0e-3)
    np.testing.assert_array_equal(vorticity[0.0][0], vorticity[0.0][1])
    sim.solver.fluid_vorticity = 0.0
    # the displacement limit, on, then off again, in the same graph
    sim.solver.fluid_viscosity = 0.0
    fast = np.tile([5.0, 0.0, 0.0], (model.particle_count, 1)).astype(np.float32)
    travel = {}
    for limit in (0.05, float("inf")):
        replay("fluid_max_displacement", limit, fast)
        travel[limit] = float(np.mean(sim.q()[:, 0] - model.particle_q.numpy()[:, 0]))
    # 4 substeps of 1/240 s at 5 m/s: 0.083 m free, 4 x 0.05 spacings limited
    test.assertAlmostEqual(travel[float("inf")], 5.0 / 60.0, delta=0.01)
    test.assertAlmostEqual(travel[0.05], 4 * 0.05 * D, delta=0.002)
    # the same step without a graph agrees with the replay
    eager = Sim(make_model(device, lambda b: add_block(b, (6, 6, 6))), fluid_viscosity=0.8)
    eager.state_0.particle_qd.assign(v)
    eager.step(1)
    qd = eager.qd()
    test.assertAlmostEqual(np.linalg.norm(qd - qd.mean(axis=0), axis=1).mean(), spread[0.8][0], places=5)


def reported(test, sim):
    """The diagnostics of an over-packed start: they warn that it was packed too tightly exactly when they count it."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        stats = sim.solver.fluid_diagnostics(sim.state_0)
    packed = [str(w.message) for w in caught if "packed too tightly" in str(w.message)]
    test.assertEqual(len(packed), int(stats["compressed_particle_substeps"] > 0), packed)
    test.assertEqual(len(caught), len(packed), [str(w.message) for w in caught])
    return stats


def compressed_block(device):
    """A block at 0.9 of the rest spacing: a load for the density passes (stepped with ``fluid_relax_overpacked=False``)."""
    return make_model(device, lambda b: add_block(b, (6, 6, 6), spacing=0.9 * D, jitter=0.05 * D))


def test_density_subiterations_and_tolerance(test, device):
    results = {}
    for name, kwargs in (
        ("single", {}),
        ("two", {"fluid_max_iterations": 2}),
        ("fixed", {"fluid_max_iterations": 3}),
        ("loose", {"fluid_max_iterations": 3, "fluid_density_tolerance": 1.0}),
        # half the mean compression two passes leave: reachable, not by the first two passes
        ("tolerance", {"fluid_max_iterations": 8}),
    ):
        if name == "tolerance":
            kwargs["fluid_density_tolerance"] = 0.5 * results["two"][0]["mean_compression"]
        model = compressed_block(device)
        # one step for all (the default follows the pass counts a mode may run, which differ here)
        sim = Sim(model, substeps=1, iterations=1, fluid_relaxation=0.5, fluid_relax_overpacked=False, **kwargs)
        q0 = sim.q()
        sim.step(1)  # one substep of one XPBD iteration: the density passes alone
        stats = reported(test, sim)
        results[name] = (stats, np.abs(sim.q() - q0).max())
    single, two, fixed, loose, tolerance = (results[k][0] for k in ("single", "two", "fixed", "loose", "tolerance"))
    # three passes, each from where the last left the particles: less compression than one pass
    test.assertEqual(fixed["density_subiterations"], 3)
    test.assertLess(fixed["mean_compression"], 0.7 * single["mean_compression"])
    # packed at 0.9 spacings (37 % over the rest density): one pass leaves particles past 10 %, reported
    test.assertGreater(single["compressed_particle_substeps"], 0)
    # a tolerance above the compression: the first two passes still correct (a mean met by a mostly
    # under-dense fluid must not leave its compressed particles unsolved, and an odd count hums), the
    # third, which would close an odd count, does not
    test.assertEqual(two["density_subiterations"], 2)
    test.assertEqual(loose["density_subiterations"], 2)
    test.assertGreater(results["loose"][1], 0.01 * D)
    test.assertAlmostEqual(results["loose"][1], results["two"][1], delta=1.0e-6)
    test.assertAlmostEqual(loose["mean_compression"], two["mean_compression"], delta=1.0e-6)
    # a reachable tolerance: stops early, within it, after an even count
    test.assertGreater(tolerance["density_subiterations"], 2)
    test.assertLess(tolerance["density_subiterations"], 8)
    test.assertEqual(tolerance["density_subiterations"] % 2, 0)
    test.assertLess(tolerance["mean_compression"], 0.5 * two["mean_compression"])


def test_density_subpasses_match_xpbd_iterations(test, device):
    # without contacts an XPBD iteration applies the density pass's correction and nothing else, so
    # n passes within one iteration, each reading the positions the last one wrote (the two position
    # buffers in turn), must move the fluid as n iterations of one pass do; an odd and an even count, at the
    # default step both take (the odd count's last pass closes with half of it in both)
    for n in (3, 4):
        runs = []
        for kwargs in ({"iterations": n}, {"iterations": 1, "fluid_max_iterations": n}):
            sim = Sim(compressed_block(device), substeps=2, **kwargs, fluid_relax_overpacked=False)
            sim.step(1)
            runs.append(sim.q())
        test.assertGreater(np.abs(runs[0] - compressed_block(device).particle_q.numpy()).max(), 0.05 * D)
        np.testing.assert_allclose(runs[1], runs[0], atol=1.0e-5 * D)


def test_density_subiterations_in_captured_graph(test, device):
    kwargs = {"fluid_max_iterations": 4, "fluid_density_tolerance": 0.01}
    eager = Sim(compressed_block(device), **kwargs, fluid_relax_overpacked=False)
    eager.step(1)
    model = compressed_block(device)
    sim = Sim(model, **kwargs, fluid_relax_overpacked=False)
    with wp.ScopedCapture(device=device) as capture:
        sim.step(1)
    sim.state_0.particle_q.assign(model.particle_q)
    sim.state_0.particle_qd.zero_()
    wp.capture_launch(capture.graph)
    np.testing.assert_allclose(sim.q(), eager.q(), atol=1.0e-5)
    test.assertEqual(
        int(sim.solver._fluid.subiterations_total.numpy()[0]),
        int(eager.solver._fluid.subiterations_total.numpy()[0]),
    )


def test_density_subiterations_see_the_walls_move(test, device):
    # a compressed block on the floor expands; passes within one XPBD iteration (no contact solve
    # between them) must measure the floor's ghost density where the last pass left the particles
    def build(b):
        add_block(b, (6, 6, 5), origin=(0.0, 0.0, 0.45 * D), spacing=0.9 * D)
        b.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))

    model = make_model(device, build)
    model.soft_contact_mu = 0.0
    # (a full Jacobi step: the test is of the walls' measurement, which the stable default's smaller
    # step, 0.48 for one pass, would leave with more compression to show)
    sim = Sim(
        model,
        substeps=1,
        iterations=1,
        contacts=True,
        fluid_max_iterations=4,
        fluid_relaxation=1.0,
        fluid_relax_overpacked=False,
    )
    sim.step(1)
    stats = reported(test, sim)
    test.assertEqual(stats["density_subiterations"], 4)
    q = sim.q()
    h = sim.solver.fluid_smoothing_length
    # the floor's share of the density: the solver's ghost lattice (of its density kernel), by distance from the floor
    wall_rho, _ = wall_density_tables(D, h, MASS, kernel=sim.solver.fluid_density_kernel)
    wall = np.interp(np.clip(q[:, 2], 0.0, h), np.linspace(0.0, h, len(wall_rho)), wall_rho)
    compression = (sim.solver.fluid_density.numpy() + wall) / stats["rest_density"] - 1.0
    bottom = q[:, 2] < 0.85 * D
    test.assertEqual(np.count_nonzero(bottom), 36)
    # measured once per iteration, the floor's share went stale: one pass pushed the bottom layer to
    # 0.1 spacings above the floor, 18 % compressed, and the next found the fluid alone uncompressed
    test.assertGreater(q[:, 2].min(), 0.2 * D)
    test.assertLess(compression[bottom].max(), 0.02)


@wp.kernel
def evaluate_wall_share(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    wall_table: wp.array[float],
    wall_table_grad: wp.array[float],
    share: wp.array[wp.vec4],
):
    i = wp.tid()
    x4 = slots.xm[i]
    x = wp.vec3(x4[0], x4[1], x4[2])
    share[i] = fluid_wall_share(slots, i, x, params[0], wall_table, wall_table_grad)


def test_wall_density_does_not_depend_on_contact_order(test, device):
    # contacts are found in any order on a GPU; a particle by three or more walls must get the same
    # (bitwise) ghost density whatever the order its planes were listed in
    fluid = Sim(make_model(device, lambda b: add_block(b, (2, 2, 2)))).solver._fluid
    rng = np.random.default_rng(3)
    n = 64
    x = rng.uniform(0.3 * D, 0.9 * D, size=(n, 3))
    diagonal = np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0)
    planes = np.array(
        [[0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.01], [*diagonal, 0.3 * D]], dtype=np.float32
    )
    test.assertEqual(WALL_CONTACTS_PER_SLOT, len(planes))

    def shares(lists):
        # lists[i]: the planes listed for slot i, in listing order
        slots = FluidSlots()
        slots.particle = wp.array(np.arange(n, dtype=np.int32), dtype=wp.int32, device=device)
        slots.xm = wp.array(np.hstack([x, np.full((n, 1), MASS)]).astype(np.float32), dtype=wp.vec4, device=device)
        slots.neighbors = wp.zeros(n, dtype=wp.int32, device=device)
        slots.neighbor_count = wp.zeros(n, dtype=wp.int32, device=device)
        slots.capacity = 1
        slots.lanes = 1
        slots.lane_capacity = 1
        plane = np.zeros((WALL_CONTACTS_PER_SLOT, n, 4), dtype=np.float32)
        for i, listed in enumerate(lists):
            plane[: len(listed), i] = listed
        slots.wall_count = wp.array([len(listed) for listed in lists], dtype=wp.int32, device=device)
        slots.wall_plane = wp.array(plane.reshape(-1, 4), dtype=wp.vec4, device=device)
        out = wp.zeros(n, dtype=wp.vec4, device=device)
        wp.launch(
            evaluate_wall_share,
            dim=n,
            inputs=[fluid.params, slots, fluid.wall_table, fluid.wall_table_grad],
            outputs=[out],
            device=device,
        )
        return out.numpy()

    reference = shares([planes] * n)
    single = [shares([planes[k : k + 1]] * n) for k in range(len(planes))]
    # the share is the walls' shares added up (and not nothing: the particles are within h of the walls)
    np.testing.assert_allclose(reference, sum(single), rtol=1.0e-5, atol=1.0e-7)
    test.assertGreater(reference[:, 3].min(), 0.0)
    for _ in range(12):
        lists = [planes[rng.permutation(len(planes))] for _ in range(n)]
        np.testing.assert_array_equal(shares(lists), reference)
    # a plane listed twice (two shapes, one surface) counts twice, in either place
    twice = shares([planes[[0, 1, 0]]] * n)
    np.testing.assert_array_equal(shares([planes[[0, 0, 1]]] * n), twice)
    np.testing.assert_allclose(twice, 2.0 * single[0] + single[1], rtol=1.0e-5, atol=1.0e-7)


def test_tolerance_stops_xpbd_iterations(test, device):
    # one density pass per XPBD iteration: the tolerance skips the substep's remaining passes, after an even count
    results = {}
    for name, kwargs in (
        ("fixed", {"iterations": 6}),
        ("two", {"iterations": 2}),
        ("five", {"iterations": 5}),
        ("loose", {"iterations": 6, "fluid_density_tolerance": 1.0}),
        ("tolerance", {"iterations": 6, "fluid_density_tolerance": 0.002}),
        ("unmet", {"iterations": 5, "fluid_density_tolerance": 1.0e-9}),
    ):
        model = compressed_block(device)
        # the default step (every schedule here takes the even bound; an odd count closes with half of it)
        sim = Sim(model, substeps=1, fluid_relax_overpacked=False, **kwargs)
        q0 = sim.q()
        sim.step(1)
        results[name] = (reported(test, sim), np.abs(sim.q() - q0).max(), sim.q())
    fixed, loose, tolerance, unmet = (results[k][0] for k in ("fixed", "loose", "tolerance", "unmet"))
    # the substep's first two passes always correct: a tolerance above the compression leaves two iterations
    test.assertEqual(loose["density_subiterations"], 2)
    test.assertGreater(results["loose"][1], 0.01 * D)
    test.assertAlmostEqual(results["loose"][1], results["two"][1], delta=1.0e-6)
    test.assertAlmostEqual(loose["mean_compression"], results["two"][0]["mean_compression"], delta=1.0e-6)
    test.assertGreater(tolerance["density_subiterations"], 2)
    test.assertLess(tolerance["density_subiterations"], 6)
    test.assertEqual(tolerance["density_subiterations"] % 2, 0)
    test.assertLess(tolerance["mean_compression"], 0.002)
    test.assertLess(fixed["mean_compression"], tolerance["mean_compression"])
    # a tolerance never met runs every pass of an odd count, and its last closes as the fixed count's does
    test.assertEqual(unmet["density_subiterations"], 5)
    # (on a GPU the fixed count computes the applied positions in its own correction pass, the tolerance mode
    # only in its first two: they differ in rounding; a last pass at the full step moves them up to 1.5e-3 D)
    exact = wp.get_device(device).is_cpu
    np.testing.assert_allclose(results["unmet"][2], results["five"][2], atol=1.0e-6 if exact else 3.0e-4 * D)
    # the next substep starts solving again: compressed anew, it takes as many passes again
    model = compressed_block(device)
    sim = Sim(model, substeps=1, iterations=6, fluid_density_tolerance=0.002, fluid_relax_overpacked=False)
    sim.step(1)
    sim.state_0.particle_q.assign(model.particle_q)
    sim.state_0.particle_qd.zero_()
    sim.step(1)
    passes = reported(test, sim)["density_subiterations"]
    test.assertEqual(passes, 2 * tolerance["density_subiterations"])
    # it is decided on the device, so a captured graph replays the same result
    kwargs = {"iterations": 6, "fluid_density_tolerance": 0.02}
    eager = Sim(compressed_block(device), **kwargs, fluid_relax_overpacked=False)
    eager.step(1)
    model = compressed_block(device)
    graph_sim = Sim(model, **kwargs, fluid_relax_overpacked=False)
    if device.is_cuda:
        with wp.ScopedCapture(device=device) as capture:
            graph_sim.step(1)
        graph_sim.state_0.particle_q.assign(model.particle_q)
        graph_sim.state_0.particle_qd.zero_()
        graph_sim.solver._fluid.subiterations_total.zero_()
        wp.capture_launch(capture.graph)
    else:
        graph_sim.step(1)
    np.testing.assert_allclose(graph_sim.q(), eager.q(), atol=1.0e-5)
    # switched on later it would need launches the solver was built without: refused, clearly
    plain = Sim(compressed_block(device), iterations=2, fluid_relax_overpacked=False)
    with test.assertRaisesRegex(ValueError, "fluid_density_tolerance=0.01"):
        plain.solver.fluid_density_tolerance = 0.01
    sim.solver.fluid_density_tolerance = 0.05  # a solver created with it may change it
    # changed to 0, the XPBD iterations do not stop early, even where nothing is compressed (their
    # passes still apply cohesion): every iteration's pass corrects
    sparse = Sim(
        make_model(device, lambda b: add_block(b, (4, 4, 4), spacing=1.1 * D)),
        substeps=1,
        iterations=4,
        fluid_density_tolerance=0.02,
    )
    sparse.solver.fluid_density_tolerance = 0.0
    sparse.step(1)
    test.assertEqual(sparse.solver.fluid_diagnostics(sparse.state_0)["max_compression"], 0.0)
    test.assertEqual(sparse.solver.fluid_diagnostics(sparse.state_0)["density_subiterations"], 4)


def warm_start_column(device, warm_start):
    """A walled 6 x 6 x 24 column on the floor, 4 substeps x 2 iterations, after 2/3 s of settling.

    Returns the solver's mean and max compression averaged over the next 1/3 s (single samples
    vary from run to run on a GPU) and the last positions.
    """
    height, half = 24 * D, 3 * D

    def build(b):
        add_block(b, (6, 6, 24), origin=(0.5 * D, 0.5 * D, 0.5 * D), jitter=0.05 * D)
        cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
        b.add_ground_plane(cfg=cfg)
        for c, h in (
            ((-0.05, half), (0.05, half + 0.1)),
            ((2 * half + 0.05, half), (0.05, half + 0.1)),
            ((half, -0.05), (half + 0.1, 0.05)),
            ((half, 2 * half + 0.05), (half + 0.1, 0.05)),
        ):
            xform = wp.transform(wp.vec3(c[0], c[1], height), wp.quat_identity())
            b.add_shape_box(-1, xform=xform, hx=h[0], hy=h[1], hz=height, cfg=cfg)

    model = make_model(device, build, gravity=-9.81)
    model.soft_contact_mu = 0.0
    sim = Sim(model, substeps=4, contacts=True, fluid_viscosity=0.05, fluid_warm_start=warm_start)
    sim.step(40)
    mean, peak = [], []
    for _ in range(10):
        sim.step(2)
        stats = sim.solver.fluid_diagnostics(sim.state_0)
        mean.append(stats["mean_compression"])
        peak.append(stats["max_compression"])
    return sim, float(np.mean(mean)), float(np.mean(peak))


def test_warm_start_holds_a_column_with_less_compression(test, device):
    sim_cold, mean_cold, peak_cold = warm_start_column(device, 0.0)
    sim, mean_warm, peak_warm = warm_start_column(device, 0.5)
    # the column's weight is partly held by the carried multipliers instead of by compression
    # (CPU and H100: mean 0.20 -> 0.16 %, max 2.4 -> 1.9 %; the maximum varies more between GPU runs)
    test.assertLess(mean_warm, 0.9 * mean_cold)
    test.assertLess(peak_warm, peak_cold)
    # ... without lifting it: the top stays within a fifth of a spacing, nothing leaves the tank
    q_cold, q_warm = sim_cold.q(), sim.q()
    test.assertTrue(np.isfinite(q_warm).all())
    test.assertLess(abs(q_warm[:, 2].max() - q_cold[:, 2].max()), 0.2 * D)
    test.assertGreater(q_warm[:, 2].min(), 0.25 * D)
    test.assertLess(np.abs(q_warm[:, :2] - 0.3).max(), 0.3 + 1.0e-3)
    # created without it the passes do not exist: switching it on later is refused, clearly
    plain = Sim(make_model(device, lambda b: add_block(b, (3, 3, 3))))
    with test.assertRaisesRegex(ValueError, "fluid_warm_start=0.5"):
        plain.solver.fluid_warm_start = 0.5
    sim.solver.fluid_warm_start = 0.0  # a solver created with it may change it, to 0 too
    sim.solver.fluid_warm_start = 0.3


def test_warm_start_change_takes_effect(test, device):
    """Changed after construction (and after capture on CUDA), the warm start acts on the next step."""

    def block():
        return make_model(device, lambda b: add_block(b, (6, 6, 6), spacing=0.9 * D), gravity=-9.81)

    model = block()
    sim = Sim(model, fluid_warm_start=0.5, fluid_relax_overpacked=False)
    capture = None
    if device.is_cuda:
        with wp.ScopedCapture(device=device) as capture:
            sim.step(1)
    result = {}
    for gamma in (0.5, 0.0, 0.5):
        sim.solver.fluid_warm_start = gamma
        sim.solver.fluid_warm_start_multipliers.zero_()
        sim.state_0.particle_q.assign(model.particle_q)
        sim.state_0.particle_qd.zero_()
        if capture is not None:
            wp.capture_launch(capture.graph)
        else:
            sim.step(1)
        result.setdefault(gamma, []).append(sim.q())
    # the multipliers carried from the first substeps push the compressed block further apart
    test.assertGreater(np.abs(result[0.5][0] - result[0.0][0]).max(), 1.0e-4)
    np.testing.assert_allclose(result[0.5][0], result[0.5][1], atol=1.0e-6)
    eager = Sim(block(), fluid_warm_start=0.5, fluid_relax_overpacked=False)
    eager.step(1)
    np.testing.assert_allclose(eager.q(), result[0.5][0], atol=1.0e-5)


def test_warm_start_kept_by_the_last_correction(test, device):
    """The multipliers carried to the next substep: kept by the last correction pass with fixed counts,
    by a pass after the step in the tolerance modes (the same values), and none for a left-out particle."""

    def run(**kwargs):
        model = make_model(device, lambda b: add_block(b, (6, 6, 6), spacing=0.9 * D, jitter=0.05 * D), gravity=-9.81)
        flags = model.particle_flags.numpy()
        flags[0] = int(newton.ParticleFlags.FLUID)  # inactive: left out of the solve
        model.particle_flags.assign(flags)
        # one step for both (the default for a tolerance that may stop after one pass is smaller)
        sim = Sim(model, fluid_warm_start=0.5, fluid_relaxation=0.5, **kwargs, fluid_relax_overpacked=False)
        sim.solver.fluid_warm_start_multipliers.fill_(3.0)
        sim.step(2)
        return sim.q(), sim.solver.fluid_warm_start_multipliers.numpy()

    q_fixed, lam_fixed = run()
    # a tolerance no substep meets runs every iteration, as the fixed count does
    q_tol, lam_tol = run(fluid_density_tolerance=1.0e-9)
    test.assertEqual(lam_fixed[0], 0.0)
    test.assertEqual(lam_tol[0], 0.0)
    test.assertGreater(np.count_nonzero(lam_fixed), 50)  # the compressed block carries multipliers
    # Bitwise on the CPU but for the last float bits. On a GPU the two runs differ in rounding (the fixed count's
    # correction pass computes the applied positions and velocities in our fast-math module where the tolerance
    # mode takes upstream's, and the sums' order differs), and the packed block amplifies it over 8 substeps
    # (H100, 2026-11-26: multipliers of up to 0.0117 at most 3.0e-4 apart, positions up to 0.017 m = 0.17
    # spacing). So there the multipliers are held to 5 % of the largest and the positions to a quarter
    # spacing: a last correction that kept no multipliers, or kept them twice, is off by the whole multiplier.
    exact = wp.get_device(device).is_cpu
    gpu_atol = 0.05 * float(np.abs(lam_fixed).max())
    np.testing.assert_allclose(lam_fixed, lam_tol, rtol=1.0e-5, atol=1.0e-9 if exact else gpu_atol)
    np.testing.assert_allclose(q_fixed, q_tol, atol=1.0e-6 if exact else 0.25 * D)


def test_warm_start_multipliers_checkpoint(test, device):
    """With warm start, the carried multipliers are state: restored with positions and velocities, a run
    continues as it did; restored without them, it does not. Without warm start there are none."""

    def block():
        return make_model(device, lambda b: add_block(b, (6, 6, 6), spacing=0.9 * D), gravity=-9.81)

    test.assertIsNone(Sim(block()).solver.fluid_warm_start_multipliers)
    sim = Sim(block(), fluid_warm_start=0.5, fluid_relax_overpacked=False)
    sim.step(1)
    lam = sim.solver.fluid_warm_start_multipliers
    test.assertEqual(lam.shape, (sim.model.particle_count,))
    test.assertGreater(np.count_nonzero(lam.numpy()), 50)  # the compressed block carries multipliers
    saved = (wp.clone(sim.state_0.particle_q), wp.clone(sim.state_0.particle_qd), wp.clone(lam))
    sim.step(1)
    q_on = sim.q()

    def resume(multipliers):
        sim.state_0.particle_q.assign(saved[0])
        sim.state_0.particle_qd.assign(saved[1])
        lam.assign(multipliers)
        sim.step(1)
        return sim.q()

    q_restored = resume(saved[2])
    q_cold = resume(wp.zeros_like(saved[2]))
    if wp.get_device(device).is_cpu:
        np.testing.assert_array_equal(q_restored, q_on)
    else:
        np.testing.assert_allclose(q_restored, q_on, atol=1.0e-5)
    test.assertGreater(np.abs(q_cold - q_on).max(), 1.0e-4)


def test_no_fluid_adds_no_work(test, device):
    builder = newton.ModelBuilder()
    builder.add_particle(pos=wp.vec3(0.0, 0.0, 1.0), vel=wp.vec3(0.0), mass=1.0, radius=0.1)
    model = builder.finalize(device=device)
    solver = newton.solvers.SolverXPBD(model)
    test.assertIsNone(solver._fluid)
    test.assertEqual(solver.fluid_diagnostics(model.state()), {})
    s0, s1 = model.state(), model.state()
    solver.step(s0, s1, None, None, 0.01)
    test.assertAlmostEqual(float(s1.particle_q.numpy()[0, 2]), 1.0 - 9.81 * 0.01 * 0.01, places=5)


def test_fluid_collides_with_granular_particles(test, device):
    def build(b):
        add_block(b, (3, 3, 3), origin=(0.0, 0.0, 0.05))
        # a granular (non-fluid) particle dropped onto the fluid block
        b.add_particle(pos=wp.vec3(0.1, 0.1, 0.5), vel=wp.vec3(0.0, 0.0, -1.0), mass=MASS, radius=0.5 * D)
        b.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))

    model = make_model(device, build, gravity=-9.81)
    sim = Sim(model, substeps=8, contacts=True)
    sim.step(30)
    q = sim.q()
    fluid_top = q[:27, 2].max()
    test.assertGreater(q[27, 2], fluid_top - 0.5 * D)  # rests on the fluid, not inside it
    test.assertGreater(np.linalg.norm(q[:27] - q[27], axis=1).min(), 0.8 * D)


def test_non_fluid_particles_step_as_without_fluid(test, device):
    # granular particles (friction and cohesion between them, touching from the start) falling on a cloth
    # over the ground step as stock Newton steps them, whether or not the model also holds fluid
    # elsewhere: the fluid's contact kernel skips only fluid-fluid pairs and applies upstream's law to
    # every other pair. Bitwise on the CPU over 40 substeps; on CUDA the atomics may reorder sums, and
    # a granular pile amplifies that rounding within a few dozen substeps, so there 3 substeps, within it
    def build(b, fluid):
        b.add_cloth_grid(
            pos=wp.vec3(-0.3, -0.3, 0.2),
            rot=wp.quat_identity(),
            vel=wp.vec3(0.0),
            dim_x=6,
            dim_y=6,
            cell_x=0.1,
            cell_y=0.1,
            mass=0.05,
            fix_left=True,
            fix_right=True,
            particle_radius=0.5 * D,
        )
        add_block(b, (3, 3, 3), origin=(-0.1, -0.1, 0.45), vel=(0.3, 0.0, -1.0), jitter=0.01)
        granular = b.particle_count
        for k in range(granular - 27, granular):
            b.particle_flags[k] &= ~int(newton.ParticleFlags.FLUID)
        if fluid:
            # a fluid block far from the rest (after it: the other particles keep their indices)
            add_block(b, (3, 3, 3), origin=(3.0, 3.0, 0.05))
        b.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.5))

    runs = []
    for fluid in (False, True):
        model = make_model(device, lambda b, fluid=fluid: build(b, fluid), gravity=-9.81)
        model.particle_mu = 0.6
        model.particle_cohesion = 0.02
        solver_kwargs = {"fluid_rest_distance": D} if fluid else {}
        solver = newton.solvers.SolverXPBD(model, iterations=2, **solver_kwargs)
        test.assertEqual(solver._fluid is not None, fluid)
        pipeline = newton.CollisionPipeline(model, soft_contact_gap=0.5 * D)
        contacts = pipeline.contacts()
        state_0, state_1 = model.state(), model.state()
        for _ in range(3 if wp.get_device(device).is_cuda else 40):
            pipeline.collide(state_0, contacts)
            solver.step(state_0, state_1, None, contacts, 1.0 / 240.0)
            state_0, state_1 = state_1, state_0
        n = 36 + 27
        runs.append((state_0.particle_q.numpy()[:n], state_0.particle_qd.numpy()[:n]))
    (q0, v0), (q1, v1) = runs
    test.assertTrue(np.isfinite(q0).all())
    if wp.get_device(device).is_cuda:
        np.testing.assert_allclose(q1, q0, rtol=0.0, atol=1.0e-6)
        np.testing.assert_allclose(v1, v0, rtol=0.0, atol=1.0e-4)
    else:
        # the granular block landed on the cloth and pressed into it
        test.assertLess(q0[36:, 2].min(), 0.3)
        np.testing.assert_array_equal(q1, q0)
        np.testing.assert_array_equal(v1, v0)


def test_concurrent_passes_match_one_stream(test, device):
    # on CUDA the sort and scan run on a second stream beside upstream's first contacts, and each next
    # density pass beside the application of the deltas and the next contacts, joined before anything
    # reads them: the results must be those of one stream, eagerly and replayed from a graph (the walls
    # are listed with atomics, so their order, and the last bits of a sum, may differ between runs).
    # On the CPU there is one stream either way, and the results are the same bitwise
    device = wp.get_device(device)

    def build(b):
        add_walled_column(b)
        add_block(b, (3, 3, 2), origin=(0.25, 0.25, 1.3), vel=(0.0, 0.0, -3.0))

    modes = {
        "fixed": {"iterations": 3},
        "vorticity": {"iterations": 2, "fluid_vorticity": 0.5},
        "warm start": {"iterations": 3, "fluid_warm_start": 0.5},
        "compression damping": {"iterations": 3, "fluid_compression_damping": 0.4},
        "compression damping, warm start": {"iterations": 2, "fluid_compression_damping": 0.4, "fluid_warm_start": 0.5},
        "tolerance": {"iterations": 3, "fluid_density_tolerance": 0.002},
        "sub-passes": {"iterations": 2, "fluid_max_iterations": 4, "fluid_density_tolerance": 0.002},
    }
    for name, kwargs in modes.items():
        runs = {}
        for concurrent in (True, False):
            model = make_model(device, build, gravity=-9.81)
            model.soft_contact_mu = 0.0
            tuning = FluidTuning(concurrent_passes=concurrent)
            sim = Sim(model, substeps=4, contacts=True, fluid_viscosity=0.05, _fluid_tuning=tuning, **kwargs)
            test.assertEqual(sim.solver._fluid.side_stream is not None, concurrent and device.is_cuda)
            sim.step(3)
            eager = sim.q()
            if device.is_cuda:
                with wp.ScopedCapture(device=device) as capture:
                    sim.step(1)  # an even number of substeps: state_0 is the graph's input and output
                for _ in range(4):
                    wp.capture_launch(capture.graph)
            else:
                sim.step(5)
            runs[concurrent] = (eager, sim.q(), sim.qd())
        with test.subTest(mode=name):
            # the block falls into the column meanwhile
            test.assertGreater(np.abs(runs[False][1] - runs[False][0]).max(), D)
            test.assertTrue(all(np.isfinite(a).all() for a in runs[True]))
            for a, b, atol in zip(runs[True], runs[False], (1.0e-3 * D, 1.0e-3 * D, 1.0e-2), strict=True):
                if device.is_cuda:
                    np.testing.assert_allclose(a, b, rtol=0.0, atol=atol)
                else:
                    np.testing.assert_array_equal(a, b)


class TestSolverXPBDFluid(unittest.TestCase):
    pass


devices = get_test_devices()
for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        add_function_test(TestSolverXPBDFluid, _name, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
