# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The fluid part of a :class:`~newton.solvers.SolverXPBD`: configuration, buffers and the per-substep passes.

:class:`FluidConfig` validates the ``fluid_*`` keywords. :class:`FluidSolver` owns every device
buffer of the fluid solve (allocated once, at construction) and is driven from three points of
the upstream step (see :mod:`newton._src.solvers.xpbd.fluid`): after prediction
(:meth:`FluidSolver.build_neighborhood`), once per iteration before the particle deltas are
applied (:meth:`FluidSolver.solve_density`) and after the step (:meth:`FluidSolver.finish_step`).
"""

from __future__ import annotations

import contextlib
import math
import numbers
import warnings
from dataclasses import dataclass

import numpy as np
import warp as wp

from ....geometry import ParticleFlags
from .continuous_collision import ContinuousCollision, still_shapes
from .diffuse import (
    DIFFUSE_BLOCK_DIM,
    DIFFUSE_DEAD,
    DiffuseBuffers,
    advect_diffuse_particles,
    emit_diffuse_particles,
)
from .kernels import (
    APPLY_ADVANCE,
    APPLY_AS_XPBD,
    COMPRESSION_BINS,
    COMPRESSION_SUMS,
    MAX_DISPLACEMENT_OFF,
    PEAK_COMPRESSION,
    WALL_CONTACTS_PER_SLOT,
    FluidParams,
    FluidSlots,
    FluidWallContacts,
    ParticleApply,
    apply_fluid_density_correction,
    apply_fluid_viscosity,
    apply_fluid_warm_start,
    compute_fluid_density_lambda,
    confine_vorticity_and_recover,
    decide_after_first_fluid_pass,
    decide_fluid_density_converged,
    decide_fluid_subiteration,
    gather_fluid_positions,
    gather_fluid_state,
    recover_nonfinite_fluid,
    store_fluid_warm_start,
)
from .neighbors import FluidNeighborSearch, neighbor_list_layout
from .render_particles import compute_fluid_render_particles, reset_render_particles
from .reset import reset_diffuse_worlds, reset_fluid_worlds

# smoothing length h = DEFAULT_SMOOTHING_RATIO * rest distance unless given
DEFAULT_SMOOTHING_RATIO = 1.8
# share of the particle-scale (non-affine) velocity removed per NONAFFINE_DAMPING_STEP unless given (docs/validation.md,
# "Still water")
DEFAULT_NONAFFINE_DAMPING = 0.1
# the time over which fluid_nonaffine_damping removes its share [s]: one substep of 8 at 60 Hz; a substep
# of dt removes 1 - (1 - share)^(dt / step), so the damping per second does not follow the substep count
NONAFFINE_DAMPING_STEP = 1.0 / 480.0
# share of the stable step (stable_pass_bound) the default relaxation takes on the rest lattice
JACOBI_STEP_MARGIN = 0.875
# regulariser of the affine fit's position covariance, relative to the rest distance squared
AFFINE_REGULARIZER = 1.0e-3
# one iteration moves a particle by at most this fraction of the rest distance
MAX_CORRECTION_FRACTION = 0.5
# largest fluid_density_ramp: a ramp over 1 % compression would hold every loaded particle 0.5 % more compressed
MAX_DENSITY_RAMP = 0.01
# lambda regulariser relative to sum |grad C|^2 of the rest lattice (constraint softening ~1e-3)
EPSILON_RELATIVE = 1.0e-3
# cohesion 1 moves a surface particle by at most ~this fraction of the rest distance per iteration
COHESION_DISPLACEMENT = 0.0025
# neighbours stored per particle for fluid_max_neighbors=0, as a multiple of the rest-lattice count
FULL_NEIGHBOR_FACTOR = 4
# samples of the wall density tables over [0, h]
WALL_TABLE_SIZE = 64
# a pair under-dense by this fraction of the rest density takes the full cohesion, at rest density none
COHESION_GATE = 0.02
# zero of Akinci's cohesion spline, as a fraction of h: 2 (1-u)^3 u^3 = 1/64
AKINCI_ZERO = 0.5 * (1.0 - math.sqrt(1.0 - 4.0 * (1.0 / 128.0) ** (1.0 / 3.0)))
# on a CUDA device, run the fluid passes that do not need upstream's work of the moment on a second
# stream beside it (the sort and scan beside the first iteration's contacts, the next density pass
# beside the deltas' application and the next contacts); False: one stream
CONCURRENT_PASSES = True


def _real(name: str, value, lo: float, hi: float = math.inf, lo_open: bool = False, hi_open: bool = False) -> float:
    """Return ``value`` as float, or raise ``ValueError`` naming the argument, the value and the valid range."""
    lb = "(" if lo_open else "["
    rb = ")" if hi_open or hi == math.inf else "]"
    valid = f"{lb}{lo:g}, {'inf' if hi == math.inf else f'{hi:g}'}{rb}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise ValueError(f"{name}={value!r} is invalid: expected a finite number in {valid}")
    v = float(value)
    if v < lo or (lo_open and v == lo) or v > hi or (hi_open and v == hi):
        raise ValueError(f"{name}={value!r} is out of range: expected a value in {valid}")
    return v


def _count(name: str, value, hi: int, lo: int = 0) -> int:
    """Return ``value`` as int, or raise ``ValueError`` naming the argument, the value and the valid range."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not lo <= int(value) <= hi:
        raise ValueError(f"{name}={value!r} is invalid: expected an integer in [{lo}, {hi}]")
    return int(value)


@dataclass
class FluidConfig:
    """Validated fluid parameters of one solver (see :class:`~newton.solvers.SolverXPBD` for their meaning)."""

    fluid_rest_distance: float | None = None
    fluid_smoothing_length: float | None = None
    fluid_rest_density: float | None = None
    fluid_cohesion: float = 0.0
    fluid_viscosity: float = 0.0
    fluid_nonaffine_damping: float = DEFAULT_NONAFFINE_DAMPING
    fluid_vorticity: float = 0.0
    fluid_relaxation: float | None = None
    fluid_density_ramp: float = 0.0
    fluid_max_neighbors: int = 0
    fluid_density_tolerance: float = 0.0
    fluid_max_iterations: int = 1
    fluid_max_displacement: float = math.inf
    fluid_warm_start: float = 0.0
    max_diffuse_particles: int = 0
    fluid_continuous_collision: bool = True

    #: parameters that may change after construction (they live on the device)
    MUTABLE = (
        "fluid_rest_density",
        "fluid_cohesion",
        "fluid_viscosity",
        "fluid_nonaffine_damping",
        "fluid_vorticity",
        "fluid_relaxation",
        "fluid_density_ramp",
        "fluid_density_tolerance",
        "fluid_max_displacement",
        "fluid_warm_start",
    )

    def __post_init__(self):
        if self.fluid_rest_distance is not None:
            self.fluid_rest_distance = _real("fluid_rest_distance", self.fluid_rest_distance, 0.0, lo_open=True)
            d = self.fluid_rest_distance
            if self.fluid_smoothing_length is None:
                self.fluid_smoothing_length = DEFAULT_SMOOTHING_RATIO * d
            self.fluid_smoothing_length = _real(
                "fluid_smoothing_length", self.fluid_smoothing_length, d, 4.0 * d, lo_open=True
            )
        elif self.fluid_smoothing_length is not None:
            self.fluid_smoothing_length = _real(
                "fluid_smoothing_length", self.fluid_smoothing_length, 0.0, lo_open=True
            )
        for name in self.MUTABLE:
            self.set(name, getattr(self, name))
        self.fluid_max_neighbors = _count("fluid_max_neighbors", self.fluid_max_neighbors, 4096)
        self.fluid_max_iterations = _count("fluid_max_iterations", self.fluid_max_iterations, 64, lo=1)
        self.max_diffuse_particles = _count("max_diffuse_particles", self.max_diffuse_particles, 2**31 - 1)
        if not isinstance(self.fluid_continuous_collision, bool):
            raise ValueError(
                f"fluid_continuous_collision={self.fluid_continuous_collision!r} is invalid: expected True or False"
            )

    def set(self, name: str, value) -> None:
        """Validate and store one mutable parameter."""
        if name == "fluid_rest_density":
            v = None if value is None else _real(name, value, 0.0, lo_open=True)
        elif name in ("fluid_cohesion", "fluid_viscosity", "fluid_nonaffine_damping"):
            v = _real(name, value, 0.0, 1.0)
        elif name in ("fluid_vorticity", "fluid_density_tolerance"):
            v = _real(name, value, 0.0)
        elif name == "fluid_max_displacement":
            # inf (no limit) is allowed here, unlike for the other parameters
            infinite = isinstance(value, numbers.Real) and not isinstance(value, bool) and value == math.inf
            v = math.inf if infinite else _real(name, value, 0.0, lo_open=True)
        elif name == "fluid_warm_start":
            v = _real(name, value, 0.0, 1.0, hi_open=True)
        elif name == "fluid_relaxation":
            # None: the solver's stable step for its kernel and pass count (FluidSolver.default_relaxation)
            v = None if value is None else _real(name, value, 0.0, 2.0, lo_open=True)
        elif name == "fluid_density_ramp":
            v = _real(name, value, 0.0, MAX_DENSITY_RAMP)
        else:
            raise AttributeError(f"{name} cannot be changed after the solver is created")
        setattr(self, name, v)


def fluid_memory_bytes(
    fluid_count: int, particle_count: int, neighbor_capacity: int, diffuse: int = 0, lanes: int = 1
) -> int:
    """Device memory the fluid solve allocates [bytes] (render particles, allocated on first use, excluded).

    Per fluid particle: the neighbour list (4 bytes a row, ``neighbor_capacity`` rows), the sort's keys,
    ranks, sorted keys, scattered and ordered values (20 bytes), the cell table (at least two entries a
    particle: count and first slot, 16 bytes), the gathered slot (24 bytes), the neighbour and candidate
    counts of each of the scan's ``lanes`` (8 bytes a lane), the static-wall planes (16 bytes each,
    ``WALL_CONTACTS_PER_SLOT``) and about 84 bytes of per-slot state; per model particle, two 4-byte
    maps; per diffuse particle, 28 bytes.
    """
    per_fluid = 4 * neighbor_capacity + 20 + 16 + 24 + 8 * lanes + 84 + 16 * WALL_CONTACTS_PER_SLOT
    return int(fluid_count * per_fluid + 12 * particle_count + 28 * diffuse)


def free_memory(device) -> int | None:
    """Free memory of ``device`` [bytes]: the CUDA device's, or the host's available memory; None if unknown."""
    if device.is_cuda:
        return int(device.free_memory)
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def rest_lattice(rest_distance: float, h: float) -> np.ndarray:
    """Offsets [m] of the cubic lattice points with spacing ``rest_distance`` within ``h`` of the origin (origin included)."""
    n = int(math.ceil(h / rest_distance))
    r = np.arange(-n, n + 1, dtype=np.float64) * rest_distance
    grid = np.stack(np.meshgrid(r, r, r, indexing="ij"), axis=-1).reshape(-1, 3)
    return grid[np.einsum("ij,ij->i", grid, grid) < h * h]


def jacobi_spectral_radius(rest_distance: float, h: float, samples: int = 24) -> float:
    """Largest eigenvalue of one Jacobi pass of the density constraint on the rest lattice.

    A pass moves the particles by ``-J^T D^-1 C`` (``J`` the constraint gradients, ``D`` the diagonal of
    ``J J^T``), so the constraint error ``C`` goes to ``(I - J J^T D^-1) C``. On the cubic lattice the
    operator is translation invariant: a displacement wave ``u e^(i k.x)`` changes ``C`` by
    ``b(k) . u`` with ``b(k) = sum_j grad W(r_j) sin(k . r_j)`` (up to a phase), so the eigenvalue at wave
    vector ``k`` is ``|b(k)|^2 / sum_j |grad W(r_j)|^2``. Sampled over the Brillouin zone (the largest sits
    at its edge): 2.43 at the default h = 1.8 d. Above 2 a pass overshoots those modes, and two passes
    amplify them: the lattice's shortest waves grow every substep.
    """
    lattice = rest_lattice(rest_distance, h)
    r = np.sqrt(np.einsum("ij,ij->i", lattice, lattice))
    keep = r > 0.0
    offsets, r = lattice[keep], r[keep]
    grad = offsets / r[:, None] * ((h - r) ** 2)[:, None]
    k = (np.arange(samples + 1) / samples) * (math.pi / rest_distance)
    waves = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3)
    b = np.sin(waves @ offsets.T) @ grad
    return float(np.einsum("ij,ij->i", b, b).max() / np.einsum("ij,ij->", grad, grad))


def stable_pass_bound(fewest: int, most: int) -> float:
    """Largest ``relaxation x eigenvalue`` for which any substep of ``fewest`` to ``most`` Jacobi passes is stable.

    After ``k`` passes a mode of eigenvalue ``mu`` keeps ``p = (1 - w mu)^k`` of its error, and the
    substep turns the correction into velocity: ``x' = p (x + v dt)``, ``v' = (x' - x) / dt``, whose
    eigenvalues solve ``z^2 - 2 p z + p = 0``. They stay inside the unit circle for ``-1/3 < p < 1``: for an
    even ``k`` while ``w mu < 2``, for an odd one while ``w mu < 1 + 3^(-1/k)`` (4/3 for one pass). The
    bound is the least over the counts a substep may run.
    """
    odd = fewest if fewest % 2 else fewest + 1
    return 1.0 + 3.0 ** (-1.0 / odd) if odd <= most else 2.0


def stable_relaxation(rest_distance: float, h: float, fewest: int = 2, most: int = 2) -> float:
    """Default ``fluid_relaxation``: a step that keeps every mode of the rest lattice stable, at most 1.

    ``JACOBI_STEP_MARGIN`` of :func:`stable_pass_bound` over :func:`jacobi_spectral_radius`: 0.72 at
    h = 1.8 d for two passes a substep, 0.48 for one. A disordered neighbourhood's spectral radius is
    close to the lattice's (2.45 measured in a settled column against 2.43), within the margin.
    """
    bound = stable_pass_bound(fewest, most)
    return min(1.0, JACOBI_STEP_MARGIN * bound / jacobi_spectral_radius(rest_distance, h))


def poly6_np(r2: np.ndarray, h: float) -> np.ndarray:
    return 315.0 / (64.0 * math.pi * h**9) * np.maximum(h * h - r2, 0.0) ** 3


def wall_density_tables(rest_distance: float, h: float, mass: float, size: int = WALL_TABLE_SIZE):
    """Poly6 density [kg/m^3] of a lattice at rest continued beyond a plane wall, and its derivative.

    For a particle whose centre is ``delta`` from the wall (``delta`` sampled uniformly on
    ``[0, h]``), the ghost lattice has layers at ``delta + d/2 + k d`` behind the wall: exactly
    the layers a lattice would have if the fluid went on, when the particle touches the wall
    (``delta = d/2``). The density is tapered to zero between ``0.75 d`` and ``d`` (where it is
    below 5 % and 1 % of the lattice density) so that it vanishes before particle-shape contacts
    end, at ``radius + soft_contact_gap``: with a gap of at least the radius it never jumps.

    Returns:
        tuple: densities and their derivatives against ``delta`` [kg/m^4], each of ``size`` samples.
    """
    d = rest_distance
    n = int(math.ceil(h / d))
    ab = np.arange(-n, n + 1) * d
    plane = (ab[:, None] ** 2 + ab[None, :] ** 2).reshape(-1)
    k = 315.0 / (64.0 * math.pi * h**9)
    deltas = np.linspace(0.0, h, size)
    rho = np.zeros(size)
    grad = np.zeros(size)
    for i, delta in enumerate(deltas):
        z = delta + 0.5 * d + np.arange(n + 1) * d
        q = np.maximum(h * h - plane[None, :] - z[:, None] ** 2, 0.0)
        rho[i] = mass * k * (q**3).sum()
        # d/d(delta) of (h^2 - r^2)^3 with dr^2/d(delta) = 2 z
        grad[i] = mass * k * (-6.0 * z[:, None] * q**2).sum()
    t = np.clip((deltas - 0.75 * d) / (0.25 * d), 0.0, 1.0)
    window = 1.0 - t * t * (3.0 - 2.0 * t)
    dwindow = np.where((t > 0.0) & (t < 1.0), -6.0 * t * (1.0 - t) / (0.25 * d), 0.0)
    return rho * window, grad * window + rho * dwindow


class FluidSolver:
    """Buffers and passes of the fluid solve for the fluid particles of ``model``.

    Args:
        model: The model; its particles flagged :attr:`~newton.ParticleFlags.FLUID` are the fluid.
        config: Validated parameters; ``fluid_rest_distance`` must be set.
        fluid_particle: Indices of the fluid particles (host array).
        iterations: XPBD iterations of the solver's substep (one density pass each, or more), >= 1; sets
            the default relaxation (:func:`stable_relaxation`).
    """

    def __init__(self, model, config: FluidConfig, fluid_particle: np.ndarray, iterations: int):
        self.model = model
        self.config = config
        self.device = model.device
        self.fluid_count = len(fluid_particle)
        d = config.fluid_rest_distance
        h = config.fluid_smoothing_length
        masses = model.particle_mass.numpy()[fluid_particle]
        self.mean_mass = float(masses.mean())
        lattice = rest_lattice(d, h)
        self.rest_lattice_neighbors = len(lattice) - 1
        r2 = np.einsum("ij,ij->i", lattice, lattice)
        #: rest density of a regular lattice at the rest distance under the poly6 sum [kg/m^3]
        self.lattice_density = float(self.mean_mass * poly6_np(r2, h).sum())
        # sum |grad C|^2 of a lattice particle at rest (the self term vanishes by symmetry)
        r = np.sqrt(r2[r2 > 0.0])
        grad = 45.0 / (math.pi * h**6) * (h - r) ** 2 * (self.mean_mass / self.lattice_density)
        self.rest_grad_sq = float((grad * grad).sum())
        # the density passes a substep may run: one per iteration, or with a tolerance any count from
        # one (the XPBD iterations stop) or ``iterations`` (sub-passes) up to the most allowed
        if config.fluid_max_iterations > 1:
            fewest, most = iterations, iterations * config.fluid_max_iterations
        elif config.fluid_density_tolerance > 0.0:
            fewest, most = 1, iterations
        else:
            fewest, most = iterations, iterations
        #: the relaxation in use while ``fluid_relaxation`` is None (see :func:`stable_relaxation`)
        self.default_relaxation = stable_relaxation(d, h, fewest, most)

        if config.fluid_max_neighbors > 0:
            capacity, capped = config.fluid_max_neighbors, True
        else:
            capacity, capped = FULL_NEIGHBOR_FACTOR * self.rest_lattice_neighbors, False
        lanes, lane_capacity = neighbor_list_layout(
            capacity, capped, device=self.device, particle_count=self.fluid_count
        )
        need = fluid_memory_bytes(
            self.fluid_count, model.particle_count, lanes * lane_capacity, config.max_diffuse_particles, lanes
        )
        free = free_memory(self.device)
        if free is not None and need > free:
            raise MemoryError(
                f"the fluid solve of {self.fluid_count} particles needs about {need / 2**30:.2f} GiB on "
                f"{self.device}, and {free / 2**30:.2f} GiB are free: use fewer particles, or a smaller "
                f"fluid_max_neighbors (now {capacity} neighbour slots per particle)"
            )
        with wp.ScopedDevice(self.device):
            self.fluid_particle = wp.array(fluid_particle.astype(np.int32), dtype=wp.int32)
            worlds = model.particle_world.numpy()[fluid_particle]
            world_count = int(worlds.max()) + 1 if len(worlds) else 0
            self.search = FluidNeighborSearch(
                self.fluid_particle, model.particle_count, world_count, h, capacity, capped
            )
            n = self.fluid_count
            self.params = wp.zeros(1, dtype=FluidParams)
            self.density = wp.zeros(n, dtype=float)
            #: multiplier (x) and relative density rho / rho0 (y) of each slot, from the last density pass
            self.lambda_rho = wp.zeros(n, dtype=wp.vec2)
            self.sorted_v = wp.zeros(n, dtype=wp.vec3)
            # the slots again, with a second position buffer: a correction pass that knows how
            # SolverXPBD applies its deltas writes the applied positions there for the next pass
            self.xm_applied = wp.zeros(n, dtype=wp.vec4)
            self.vorticity = wp.zeros(n, dtype=wp.vec3)
            # the warm-start passes exist only on a solver created with it (a scene without it pays nothing)
            self.warm_start_mode = config.fluid_warm_start > 0.0
            # warm start: multipliers carried per particle between substeps, their slot-order copy
            # (gathered by the sort) and the substep's running sum per slot
            warm = self.warm_start_mode
            self.particle_lambda = wp.zeros(model.particle_count if warm else 0, dtype=float)
            self.warm_lambda = wp.zeros(n if warm else 0, dtype=float)
            self.lambda_sum = wp.zeros(n if warm else 0, dtype=float)
            if warm:
                self.search.carry_values(self.particle_lambda, self.warm_lambda)
            # state of the density sub-iteration loop: an "always on" flag for the single pass,
            # and the loop's flag, correction count, compression bins and a total for diagnostics
            self._always_active = wp.ones(1, dtype=wp.int32)
            # tolerance mode with one pass per iteration: cleared once a substep's density has converged
            self._substep_active = wp.ones(1, dtype=wp.int32)
            self.tolerance_mode = config.fluid_max_iterations > 1 or config.fluid_density_tolerance > 0.0
            self._loop_active = wp.zeros(1, dtype=wp.int32)
            self._loop_count = wp.zeros(1, dtype=wp.int32)
            self._pass_corrects = wp.zeros(1, dtype=wp.int32)
            self._compression_bins = wp.zeros(COMPRESSION_SUMS, dtype=float)
            # particles past PEAK_COMPRESSION in a substep's last density pass, and their peak, per bin:
            # kept on the device between two diagnostics calls (see compute_fluid_density_lambda)
            self._peaks = wp.zeros(2 * COMPRESSION_BINS, dtype=float)
            self.subiterations_total = wp.zeros(1, dtype=wp.int32)
            # gradient of the static walls' share of rho / rho0 per slot, from the density pass to the correction
            self.wall_grad = wp.zeros(n, dtype=wp.vec3)
            wall_rho, wall_drho = wall_density_tables(d, h, self.mean_mass)
            self.wall_table = wp.array(wall_rho / self.lattice_density, dtype=float)
            self.wall_table_grad = wp.array(wall_drho / self.lattice_density, dtype=float)
            self.last_finite_q = wp.array(model.particle_q.numpy()[fluid_particle], dtype=wp.vec3)
            self.nonfinite_count = wp.zeros(1, dtype=wp.int32)
            self.fast_count = wp.zeros(1, dtype=wp.int32)
            self._fast_reported = 0
            self._nonfinite_reported = 0
            self._compression_reported = False
            #: density of every particle at the state of the last :meth:`diagnostics` call [kg/m^3] (0 for non-fluid)
            self.particle_density = wp.zeros(model.particle_count, dtype=float)
            self._summary = wp.zeros(_SUMMARY_SIZE, dtype=float)
            # stands in for the reset mask when every world is reset (the kernel then reads none)
            self._no_mask = wp.zeros(1, dtype=wp.bool)
        other = FluidSlots()
        for field in ("particle", "neighbors", "neighbor_count", "capacity", "lanes", "lane_capacity"):
            setattr(other, field, getattr(self.search.slots, field))
        other.wall_count = self.search.wall_count
        other.wall_plane = self.search.wall_plane
        other.xm = self.xm_applied
        #: the slot views of the two position buffers; ``_current`` is the one holding the positions
        self._slot_views = (self.search.slots, other)
        self._apply_off = ParticleApply()
        self._apply_off.on = 0
        # a density sub-pass reading one position buffer writes its moved positions into the other
        self._apply_advance = []
        for target in (1, 0):
            advance = ParticleApply()
            advance.on = APPLY_ADVANCE
            advance.xm = self._slot_views[target].xm
            self._apply_advance.append(advance)
        self._current = 0
        self._iteration = 0
        self._last_iteration = False
        self._warm_stored = False
        # the current slots hold the particles' positions (and sorted_v their velocities) as SolverXPBD
        # last applied them, so no gather is needed
        self._positions_applied = False
        self._velocities_applied = False
        self._slots_hold_positions = False
        self.diffuse = None
        if config.max_diffuse_particles > 0:
            c = config.max_diffuse_particles
            with wp.ScopedDevice(self.device):
                self.diffuse = DiffuseBuffers()
                self.diffuse.position = wp.zeros(c, dtype=wp.vec3)
                self.diffuse.velocity = wp.zeros(c, dtype=wp.vec3)
                self.diffuse.lifetime = wp.zeros(c, dtype=float)
                self.diffuse.kind = wp.full(c, DIFFUSE_DEAD, dtype=wp.int32)
                self.diffuse.world = wp.full(c, -1, dtype=wp.int32)
                self.diffuse.counters = wp.zeros(3, dtype=wp.int32)
        # render particles, allocated by the first update_render_particles()
        self.render_positions = None
        self.render_anisotropy = None
        self.render_anisotropy_secondary = None
        self.render_anisotropy_tertiary = None
        #: particle-shape contacts of the step in progress (set by the solver), for the wall density
        self.contacts = None
        # static shapes and those of kinematic bodies lend density (see list_wall_contact)
        self._has_walls = bool(model.shape_count) and bool(still_shapes(model).any())
        with wp.ScopedDevice(self.device):
            self._no_bodies = wp.zeros(1, dtype=wp.transform)
            self._no_body_flags = wp.zeros(1, dtype=wp.int32)
        # the fluid's paths kept out of static and kinematic shapes (None: off, or no such shape)
        self.continuous_collision = ContinuousCollision.build(model) if config.fluid_continuous_collision else None
        # the second stream (see CONCURRENT_PASSES), and whether work on it has not been joined yet
        self._side_stream = wp.Stream(self.device) if self.device.is_cuda and CONCURRENT_PASSES else None
        self._side_pending = False
        # the density pass of the next iteration ran ahead on the second stream
        self._evaluated_ahead = False
        self.update_params()

    @property
    def rest_density(self) -> float:
        """Rest density in use [kg/m^3]: the configured one, else the calibrated lattice density."""
        rho0 = self.config.fluid_rest_density
        return self.lattice_density if rho0 is None else rho0

    def update_params(self) -> None:
        """Copy the current configuration to the device (the next step, or graph replay, uses it)."""
        c = self.config
        d, h = c.fluid_rest_distance, c.fluid_smoothing_length
        p = FluidParams()
        p.h = h
        p.h2 = h * h
        p.poly6 = 315.0 / (64.0 * math.pi * h**9)
        p.spiky_grad = -45.0 / (math.pi * h**6)
        p.rest_density = self.rest_density
        p.inv_rest_density = 1.0 / self.rest_density
        p.reference_mass = self.mean_mass
        p.rest_distance = d
        # the gradients scale with m/rho0, so does their rest norm
        scale = self.lattice_density / self.rest_density
        p.epsilon = EPSILON_RELATIVE * self.rest_grad_sq * scale * scale
        p.relaxation = self.default_relaxation if c.fluid_relaxation is None else c.fluid_relaxation
        p.density_ramp = c.fluid_density_ramp
        p.max_correction = MAX_CORRECTION_FRACTION * d
        p.max_displacement = min(c.fluid_max_displacement * d, MAX_DISPLACEMENT_OFF)
        p.cohesion = c.fluid_cohesion * COHESION_DISPLACEMENT * d
        p.cohesion_u0 = AKINCI_ZERO
        p.cohesion_in = AKINCI_ZERO / d
        p.cohesion_out = (1.0 - AKINCI_ZERO) / (h - d)
        p.cohesion_gate = COHESION_GATE
        p.viscosity = c.fluid_viscosity
        p.nonaffine_damping = c.fluid_nonaffine_damping
        p.affine_regularizer = AFFINE_REGULARIZER * d * d
        p.vorticity = c.fluid_vorticity
        p.density_tolerance = c.fluid_density_tolerance
        p.warm_start = c.fluid_warm_start
        p.wall_scale = self.lattice_density / self.rest_density
        p.wall_table_step = h / (WALL_TABLE_SIZE - 1)
        self.params.assign(wp.array([p], dtype=FluidParams, device="cpu"))

    # --- passes inside the upstream step ---------------------------------------------------------

    @property
    def iteration_tolerance(self) -> bool:
        """Whether the tolerance stops the substep's XPBD iterations' density passes (one pass per iteration)."""
        return self.config.fluid_max_iterations == 1 and self.tolerance_mode

    def check_change(self, name: str, value) -> None:
        """Refuse to switch the tolerance mode or the warm start on after construction (their passes are not launched)."""
        if name == "fluid_warm_start" and not self.warm_start_mode and value != 0.0:
            raise ValueError(
                f"fluid_warm_start={value!r} cannot be set on a solver created without it: create the solver "
                "with fluid_warm_start in (0, 1)"
            )
        if name == "fluid_density_tolerance" and not self.tolerance_mode and value != 0.0:
            raise ValueError(
                f"fluid_density_tolerance={value!r} cannot be set on a solver created without it (and with "
                "fluid_max_iterations 1): create the solver with fluid_density_tolerance > 0"
            )

    @contextlib.contextmanager
    def _beside(self):
        """Launches inside go to the second stream, after everything launched so far on the current one.

        They run beside what the current stream does next, until :meth:`_join`. Without a second
        stream (CPU, or ``CONCURRENT_PASSES`` off) they go to the current stream.
        """
        if self._side_stream is None:
            yield
            return
        with wp.ScopedStream(self._side_stream, sync_enter=True):
            yield
        self._side_pending = True

    def _join(self) -> None:
        """Make the current stream wait for the work launched by :meth:`_beside` (in a graph: an edge)."""
        if self._side_pending:
            self.device.stream.wait_stream(self._side_stream)
            self._side_pending = False

    def build_neighborhood(self, particle_q: wp.array, particle_q_start=None, particle_qd=None, body_q=None) -> None:
        """Sort the fluid at ``particle_q`` and list its neighbours.

        After prediction (``particle_q_start`` and ``particle_qd`` given) each fluid particle's travel
        is first limited to ``fluid_max_displacement`` rest distances, in the same pass, and the
        static walls of the step's contacts are listed for each slot by the same launch as the
        neighbours (a build for diagnostics or rendering lists no walls: the contacts belong to a step).
        In a step, the sort and the scan run beside upstream's work up to the first density pass
        (particle-shape contacts, which only read the positions): :meth:`_beside`.
        """
        self._join()
        m, contacts = self.model, self.contacts
        walls = None
        if particle_q_start is not None and self._has_walls and contacts is not None:
            walls = FluidWallContacts()
            walls.count = contacts.soft_contact_count
            walls.particle = contacts.soft_contact_particle
            walls.shape = contacts.soft_contact_shape
            walls.point = contacts.soft_contact_body_pos
            walls.normal = contacts.soft_contact_normal
            walls.contact_max = contacts.soft_contact_max
            walls.shape_body = m.shape_body
            walls.body_q = body_q if body_q is not None and m.body_count else self._no_bodies
            walls.body_flags = m.body_flags if m.body_count else self._no_body_flags
        s = self.search
        # (the travel limit writes the positions upstream goes on with: not beside it)
        s.compute_keys(particle_q, m.particle_flags, m.particle_world, self.params, particle_q_start, particle_qd)
        with self._beside() if particle_q_start is not None else contextlib.nullcontext():
            s.sort(particle_q, m.particle_mass, m.particle_world)
            s.scan(walls)
        # the build gathered these positions into slot order: the first iteration uses them as they are
        self._slots_hold_positions = True
        self._iteration = 0
        self._warm_stored = False
        self._current = 0
        self._positions_applied = False
        self._velocities_applied = False
        self._evaluated_ahead = False

    @property
    def slots(self) -> FluidSlots:
        """The slots with the current position buffer (see :meth:`solve_density`)."""
        return self._slot_views[self._current]

    def solve_density(
        self, particle_q: wp.array, particle_deltas: wp.array, apply: tuple | None = None, iterations: int = 0
    ) -> None:
        """The density constraint of one XPBD iteration: add its correction to ``particle_deltas``.

        ``apply`` = ``(x_start, dt, v_max, velocities)`` says how ``SolverXPBD`` applies the deltas
        after this call (:class:`~.kernels.ParticleApply`; ``x_start`` the substep's start positions).
        With it, and one density pass per iteration that is sure to correct (no tolerance, or the
        substep's first), the correction pass also writes every fluid particle's applied position in
        slot order (and, with ``velocities``, its velocity: false where something changes the
        velocities after the iterations), so the next iteration and the viscosity pass gather nothing:
        two launches less per substep.

        With ``fluid_max_iterations`` 1 this is one Jacobi pass (with a tolerance set at construction,
        skipped once the substep's mean compression has met it; the substep's first pass always
        corrects). Otherwise up to that many passes run on the gathered positions, each starting where
        the last one left them; the first always corrects, and the ones after it stop early once the
        mean compression is at most ``fluid_density_tolerance`` (if above 0); each pass
        measures the walls again where the last one left the particles. The count is decided on the
        device: inside a graph capture the loop is a conditional while node; on a GPU outside one
        every allowed pass is launched and the passes after the decision do nothing (no
        synchronisation); on the CPU the loop reads its flag and stops. With ``fluid_warm_start``, the
        substep's first iteration first moves the fluid by the multipliers carried from the last one,
        and with fixed counts the correction of iteration ``iterations`` (the substep's last; 0:
        unknown) keeps the multipliers for the next substep (else a pass after the step does).
        """
        self._join()
        m, n = self.model, self.fluid_count
        # the substep's first iteration starts from the positions the build gathered; its first density
        # pass always corrects (see decide_after_first_fluid_pass), and with the tolerance on the XPBD
        # iterations a converged substep skips the rest of its passes
        first = self._slots_hold_positions
        active = self._substep_active if self.iteration_tolerance and not first else self._always_active
        if not self._slots_hold_positions and not self._positions_applied:
            wp.launch(
                gather_fluid_positions,
                dim=n,
                inputs=[self.slots, active, particle_q, m.particle_mass],
                device=self.device,
            )
        self._iteration += 1
        if self._slots_hold_positions and self._warm_start_on():
            self._warm_start(particle_deltas, active)
        # after this iteration's correction, the slots' positions are out of date (unless it writes the applied ones)
        self._slots_hold_positions = False
        self._positions_applied = False
        self._velocities_applied = False
        if self.config.fluid_max_iterations == 1:
            if not self._evaluated_ahead:
                self._evaluate_constraint(
                    active, track_compression=self.iteration_tolerance, last=self._iteration == iterations
                )
            self._evaluated_ahead = False
            if self.iteration_tolerance:
                if first:
                    # corrects below whatever it measured; decides whether the later iterations do
                    self._decide_after_first_pass(self._substep_active, 1, stop_uncompressed=False)
                else:
                    wp.launch_tiled(
                        decide_fluid_density_converged,
                        dim=1,
                        block_dim=COMPRESSION_BINS,
                        inputs=[self.params],
                        outputs=[self._compression_bins, active, self.subiterations_total],
                        device=self.device,
                    )
            # (a pass that may be skipped writes no applied positions)
            predict = apply is not None and active is self._always_active
            # (the tolerance modes decide the last correction on the device: a pass after the step stores)
            store = self._warm_start_on() and not self.tolerance_mode and self._iteration == iterations
            self._correct(particle_deltas, active, particle_q if predict else None, apply, store_warm=store)
            self._warm_stored = self._warm_stored or store
            if predict:
                self._current = 1 - self._current
                self._positions_applied = True
                self._velocities_applied = bool(apply[3])
                if not self.iteration_tolerance and self._iteration < iterations and self._side_stream is not None:
                    # the next iteration's density pass needs only these positions: it runs beside
                    # upstream's application of the deltas and its next contacts
                    with self._beside():
                        self._evaluate_constraint(active, last=self._iteration + 1 == iterations)
                    self._evaluated_ahead = True
            return
        # the iteration's first pass corrects; it writes its moved positions into the other position
        # buffer, where the loop's passes go on (while it measured the mean compression above the tolerance)
        self._last_iteration = self._iteration == iterations
        self._evaluate_constraint(self._always_active, track_compression=True, last=self._last_iteration)
        self._decide_after_first_pass(self._loop_active, self.config.fluid_max_iterations - 1, stop_uncompressed=True)
        self._correct(particle_deltas, self._always_active, advance=True)
        self._current = 1 - self._current
        if self.device.is_capturing or self.device.is_cpu:
            # a conditional while node in a graph; on the CPU the flag is read where it lies
            wp.capture_while(self._loop_active, self._density_subiteration_pair, particle_deltas=particle_deltas)
        else:
            # no graph: launch every allowed pass (reading the flag would synchronise); the ones
            # after the decision do nothing
            for _ in range(self.config.fluid_max_iterations // 2):
                self._density_subiteration_pair(particle_deltas)

    def _decide_after_first_pass(self, go_on: wp.array, more: int, stop_uncompressed: bool) -> None:
        wp.launch_tiled(
            decide_after_first_fluid_pass,
            dim=1,
            block_dim=COMPRESSION_BINS,
            inputs=[self.params, more, int(stop_uncompressed)],
            outputs=[self._compression_bins, go_on, self._loop_count, self.subiterations_total],
            device=self.device,
        )

    def _density_subiteration_pair(self, particle_deltas: wp.array) -> None:
        # each pass's correction writes the moved positions into the other buffer, which the next pass
        # reads: two passes per trip of the loop bring them back (a second pass after the loop's
        # decision to stop does nothing; the positions after the loop are gathered again when needed)
        start = self._current
        for source in (start, 1 - start):
            self._current = source
            self._density_subiteration(particle_deltas)
        self._current = start

    def _density_subiteration(self, particle_deltas: wp.array) -> None:
        # (the density pass measures the walls where the last pass left the particles)
        self._evaluate_constraint(self._loop_active, track_compression=True, last=self._last_iteration)
        wp.launch_tiled(
            decide_fluid_subiteration,
            dim=1,
            block_dim=COMPRESSION_BINS,
            inputs=[self.params, self.config.fluid_max_iterations - 1],
            outputs=[
                self._compression_bins,
                self._loop_active,
                self._pass_corrects,
                self._loop_count,
                self.subiterations_total,
            ],
            device=self.device,
        )
        self._correct(particle_deltas, self._pass_corrects, advance=True)

    def _warm_start_on(self) -> bool:
        # in a graph the passes are captured and check the parameter on the device (so it may change)
        return self.warm_start_mode and (self.device.is_capturing or self.config.fluid_warm_start > 0.0)

    def _warm_start(self, particle_deltas: wp.array, active: wp.array) -> None:
        """Move the fluid by the multipliers carried from the last substep before its first evaluation.

        The sort gathered them into slot order; the moved positions go to the other position buffer.
        """
        m, n = self.model, self.fluid_count
        wp.launch(
            apply_fluid_warm_start,
            dim=n,
            inputs=[
                self.params,
                self.slots,
                active,
                self.warm_lambda,
                m.particle_inv_mass,
                self.wall_table,
                self.wall_table_grad,
            ],
            outputs=[particle_deltas, self._slot_views[1 - self._current].xm, self.lambda_sum],
            device=self.device,
        )
        self._current = 1 - self._current

    def _correct(
        self,
        particle_deltas: wp.array,
        active: wp.array,
        x_pred: wp.array | None = None,
        apply: tuple | None = None,
        advance: bool = False,
        store_warm: bool = False,
    ) -> None:
        m = self.model
        applied = self._apply_off
        # the corrected positions go to the other position buffer (this pass reads the current one)
        if advance:
            applied = self._apply_advance[self._current]
        elif x_pred is not None:
            applied = ParticleApply()
            applied.on = APPLY_AS_XPBD
            applied.x_pred = x_pred
            applied.x_start, applied.dt, applied.v_max = apply[0], float(apply[1]), float(apply[2])
            applied.xm = self._slot_views[1 - self._current].xm
            applied.v = self.sorted_v
        wp.launch(
            apply_fluid_density_correction,
            dim=self.fluid_count,
            inputs=[
                self.params,
                self.slots,
                active,
                self.lambda_rho,
                m.particle_inv_mass,
                self.wall_grad,
                applied,
                int(store_warm),
            ],
            outputs=[particle_deltas, self.lambda_sum, self.particle_lambda],
            device=self.device,
        )

    def _evaluate_constraint(self, active: wp.array, track_compression: bool = False, last: bool = False) -> None:
        """Density and multipliers at the positions gathered in ``slots.xm`` (while ``active[0]`` is set).

        ``last``: a pass of the substep's last XPBD iteration, whose compression peaks are kept for the
        next report.
        """
        wp.launch(
            compute_fluid_density_lambda,
            dim=self.fluid_count,
            inputs=[
                self.params,
                self.slots,
                active,
                self.wall_table,
                self.wall_table_grad,
                int(track_compression),
                int(last),
            ],
            outputs=[self.density, self.lambda_rho, self.wall_grad, self._compression_bins, self._peaks],
            device=self.device,
        )

    def finish_step(self, state_out, dt: float, particle_q_start: wp.array | None = None) -> None:
        """Continuous collision, viscosity, vorticity confinement and non-finite recovery on the step's result.

        With ``particle_q_start`` (the positions the substep started from), each fluid particle's path is
        first kept out of the static and kinematic shapes (:mod:`.continuous_collision`).

        Outside a graph capture the optional passes are not launched while their parameter is 0.
        Inside one they are captured and check the parameter on the device, so that switching them on
        or off later needs no re-capture: a pass that is off then costs its launch (about 2 us a
        kernel on an H100), less than a conditional node would (about 5 us, docs/performance.md).
        The vorticity pass, the last, also recovers the non-finite particles (a pass of its own where
        the vorticity pass is not launched).
        """
        self._join()
        c = self.config
        if self.continuous_collision is not None and particle_q_start is not None:
            self.continuous_collision.apply(
                self.fluid_particle,
                self.search.slot_of_particle,
                self.slots.xm,
                self.sorted_v,
                particle_q_start,
                state_out,
                dt,
            )
        if self._warm_start_on() and not self._warm_stored:
            wp.launch(
                store_fluid_warm_start,
                dim=self.fluid_count,
                inputs=[self.params, self.search.slots, self.lambda_sum],
                outputs=[self.particle_lambda],
                device=self.device,
            )
        self._warm_stored = False
        if self.device.is_capturing:
            self._velocity_pass(state_out, dt)
            self._vorticity_pass(state_out, dt)
        else:
            if c.fluid_viscosity > 0.0 or c.fluid_nonaffine_damping > 0.0 or c.fluid_vorticity > 0.0:
                self._velocity_pass(state_out, dt)
            if c.fluid_vorticity > 0.0:
                self._vorticity_pass(state_out, dt)
            else:
                # (the vorticity pass recovers the non-finite particles where it runs)
                wp.launch(
                    recover_nonfinite_fluid,
                    dim=self.fluid_count,
                    inputs=[self.params, self.fluid_particle, self.model.particle_flags, dt],
                    outputs=self._recovery_outputs(state_out),
                    device=self.device,
                )
        if self.diffuse is not None:
            self._diffuse_pass(state_out, dt)

    def _recovery_outputs(self, state_out) -> list:
        """The arrays :func:`~.kernels.recover_fluid_particle` updates, for the kernels that call it."""
        return [state_out.particle_q, state_out.particle_qd, self.last_finite_q, self.nonfinite_count, self.fast_count]

    def _diffuse_pass(self, state_out, dt: float) -> None:
        """Let the fluid emit diffuse particles, then advect them all (new ones leave shapes at once)."""
        s, m, b = self.search, self.model, self.diffuse
        body_q = state_out.body_q if state_out.body_q is not None else self._no_bodies
        # the step's result in slot order (after the viscosity and vorticity passes changed the velocities)
        wp.launch(
            gather_fluid_state,
            dim=self.fluid_count,
            inputs=[self.params, s.slots, state_out.particle_q, state_out.particle_qd, m.particle_mass, 0],
            outputs=[self.sorted_v],
            device=self.device,
        )
        wp.launch(
            emit_diffuse_particles,
            dim=self.fluid_count,
            inputs=[self.params, s.slots, self.sorted_v, self.density, m.particle_world, dt, b.position.shape[0]],
            outputs=[b],
            device=self.device,
        )
        wp.launch_tiled(
            advect_diffuse_particles,
            dim=[b.position.shape[0]],
            block_dim=DIFFUSE_BLOCK_DIM,
            inputs=[
                self.params,
                s.cell_offset,
                s.sorted_xm,
                self.sorted_v,
                s.sorted_world,
                s.inv_cell,
                s.cell_bits,
                s.mask,
                m.gravity,
                m.shape_type,
                m.shape_scale,
                m.shape_transform,
                m.shape_body,
                m.shape_world,
                body_q,
                m.shape_count,
                dt,
            ],
            outputs=[b],
            device=self.device,
        )

    def _velocity_pass(self, state_out, dt: float) -> None:
        """Viscosity, the non-affine damping of a substep of ``dt`` and the vorticity estimate (one neighbour loop)."""
        m, n = self.model, self.fluid_count
        if not self._velocities_applied:
            wp.launch(
                gather_fluid_state,
                dim=n,
                inputs=[self.params, self.slots, state_out.particle_q, state_out.particle_qd, m.particle_mass, 1],
                outputs=[self.sorted_v],
                device=self.device,
            )
        wp.launch(
            apply_fluid_viscosity,
            dim=n,
            inputs=[self.params, self.slots, self.sorted_v, self.density, dt / NONAFFINE_DAMPING_STEP],
            outputs=[state_out.particle_qd, self.vorticity],
            device=self.device,
        )

    def _vorticity_pass(self, state_out, dt: float) -> None:
        """Vorticity confinement (while on) and the non-finite recovery, in one pass."""
        wp.launch(
            confine_vorticity_and_recover,
            dim=self.fluid_count,
            inputs=[
                self.params,
                self.slots,
                self.density,
                self.vorticity,
                self.search.values,
                self.fluid_particle,
                self.model.particle_flags,
                dt,
            ],
            outputs=self._recovery_outputs(state_out),
            device=self.device,
        )

    # --- render particles ------------------------------------------------------------------------

    def update_render_particles(
        self, state, smoothing: float, anisotropy_scale: float, anisotropy_min: float, anisotropy_max: float
    ) -> None:
        """Smoothed positions and ellipsoid axes of every particle at ``state`` (see :mod:`.render_particles`)."""
        smoothing = _real("smoothing", smoothing, 0.0, 1.0)
        anisotropy_scale = _real("anisotropy_scale", anisotropy_scale, 0.0, lo_open=True)
        anisotropy_min = _real("anisotropy_min", anisotropy_min, 0.0, 1.0, lo_open=True)
        anisotropy_max = _real("anisotropy_max", anisotropy_max, 1.0)
        if self.render_positions is None:
            with wp.ScopedDevice(self.device):
                n = self.model.particle_count
                self.render_positions = wp.zeros(n, dtype=wp.vec3)
                self.render_anisotropy = wp.zeros(n, dtype=wp.vec4)
                self.render_anisotropy_secondary = wp.zeros(n, dtype=wp.vec4)
                self.render_anisotropy_tertiary = wp.zeros(n, dtype=wp.vec4)
        axes = [self.render_anisotropy, self.render_anisotropy_secondary, self.render_anisotropy_tertiary]
        wp.launch(
            reset_render_particles,
            dim=self.model.particle_count,
            inputs=[state.particle_q, anisotropy_scale],
            outputs=[self.render_positions, *axes],
            device=self.device,
        )
        # the scratch of the neighbourhood is rebuilt by the next step, so using it here changes nothing
        self.build_neighborhood(state.particle_q)
        self._slots_hold_positions = False
        wp.launch(
            compute_fluid_render_particles,
            dim=self.fluid_count,
            inputs=[self.params, self.search.slots, smoothing, anisotropy_scale, anisotropy_min, anisotropy_max],
            outputs=[self.render_positions, *axes],
            device=self.device,
        )

    # --- reset -------------------------------------------------------------------------------------

    def reset(self, state, world_mask: wp.array | None, restore_q: bool, restore_qd: bool, source=None) -> None:
        """Restore the fluid of the worlds ``world_mask`` selects and clear their carried solver state.

        Args:
            state: The state whose fluid particles are restored (in place).
            world_mask: Validated mask of ``world_count + 1`` booleans, or ``None`` for every world.
            restore_q: Whether positions are restored from ``source``.
            restore_qd: Whether velocities are restored from ``source``.
            source: A state to take the particles from; ``None``: the model's initial particles.
        """
        m = self.model
        src_q = m.particle_q if source is None else source.particle_q
        src_qd = m.particle_qd if source is None else source.particle_qd
        use_mask = int(world_mask is not None)
        mask = world_mask if world_mask is not None else self._no_mask
        wp.launch(
            reset_fluid_worlds,
            dim=self.fluid_count,
            inputs=[
                self.fluid_particle,
                m.particle_world,
                mask,
                m.world_count,
                use_mask,
                src_q,
                src_qd,
                int(restore_q),
                int(restore_qd),
            ],
            outputs=[state.particle_q, state.particle_qd, self.last_finite_q, self.particle_lambda],
            device=self.device,
        )
        if self.diffuse is not None:
            b = self.diffuse
            wp.launch(
                reset_diffuse_worlds,
                dim=len(b.kind),
                inputs=[mask, m.world_count, use_mask, b.world, int(DIFFUSE_DEAD)],
                outputs=[b.lifetime, b.kind],
                device=self.device,
            )

    # --- diagnostics -------------------------------------------------------------------------------

    def _report_fast_particles(self) -> int:
        """Particle substeps that ended faster than one rest distance per substep; warns when they grew since last."""
        count = int(self.fast_count.numpy()[0])
        if count > self._fast_reported:
            limit = self.config.fluid_max_displacement
            if math.isfinite(limit):
                action = f"they were slowed to fluid_max_displacement={limit:g} rest distances per substep"
            elif self.continuous_collision is not None:
                action = (
                    "continuous collision kept them out of static and kinematic shapes; past that a particle "
                    "can cross a dynamic body before its contact is found (fluid_max_displacement=1 prevents it)"
                )
            else:
                action = "past that a particle can cross a thin wall (fluid_max_displacement=1 prevents it)"
            warnings.warn(
                f"{count - self._fast_reported} fluid particle substeps since the last report travelled more than "
                f"one rest distance: the substep is too long for the flow's speed (use more substeps); {action}",
                RuntimeWarning,
                stacklevel=3,
            )
        self._fast_reported = count
        return count

    def _report_peaks(self) -> tuple[int, float]:
        """Particle substeps compressed past ``PEAK_COMPRESSION`` since the last report, and their peak; warns."""
        v = self._peaks.numpy()
        count, peak = int(v[:COMPRESSION_BINS].sum()), float(v[COMPRESSION_BINS:].max())
        if count:
            warnings.warn(
                f"{count} fluid particle substeps since the last report ended their density solve past "
                f"{100.0 * PEAK_COMPRESSION:.0f} % compression (peak {100.0 * peak:.0f} %): the fluid was packed too tightly "
                "(an overlapping start) or hit harder than its iterations and substeps hold (use more of "
                "either, or a fluid_density_tolerance with fluid_max_iterations > 1)",
                RuntimeWarning,
                stacklevel=3,
            )
            self._peaks.zero_()
        return count, peak

    def _report_recoveries(self) -> int:
        """Fluid particles recovered from non-finite values in all; warns when the count grew since the last report."""
        count = int(self.nonfinite_count.numpy()[0])
        if count > self._nonfinite_reported:
            warnings.warn(
                f"{count - self._nonfinite_reported} fluid particles since the last report had a non-finite "
                "position or velocity and were put back at rest where they last were finite",
                RuntimeWarning,
                stacklevel=3,
            )
        self._nonfinite_reported = count
        return count

    def _report_dropped_contacts(self) -> int:
        """Particle-shape contacts the last collision found beyond its buffer (dropped); warns when there were any."""
        c = self.contacts
        if c is None or getattr(c, "soft_contact_count", None) is None:
            return 0
        found, room = int(c.soft_contact_count.numpy()[0]), int(c.soft_contact_max)
        if found <= room:
            return 0
        warnings.warn(
            f"the last collision found {found} particle-shape contacts and its buffer holds {room}: "
            f"{found - room} were dropped, and with them walls (fluid passes through them and misses their "
            f"density); create the CollisionPipeline with soft_contact_max >= {found}",
            RuntimeWarning,
            stacklevel=3,
        )
        return found - room

    def _report_compression(self, mean: float, peak: float) -> None:
        """Warn when the mean compression rises past ``COMPRESSION_WARNING`` (once, until it falls below again)."""
        over = mean > COMPRESSION_WARNING
        if over and not self._compression_reported:
            warnings.warn(
                f"the fluid is compressed by {100.0 * mean:.1f} % on average (max {100.0 * peak:.0f} %): more "
                "than the density solve holds (packed too tightly, or too deep for its iterations). A fluid H "
                "deep is compressed by about g H / c^2 at the bottom, "
                "with c = iterations x rest distance / substep duration: use more iterations or substeps, or a "
                "fluid_density_tolerance with fluid_max_iterations > 1, which adds passes where the fluid needs them "
                "(past about 10 % a deep column in a closed tank collapses and throws particles out)",
                RuntimeWarning,
                stacklevel=3,
            )
        self._compression_reported = over

    def diagnostics(self, state) -> dict:
        """Density and neighbourhood statistics of the fluid at ``state`` (synchronises; not for the hot loop)."""
        s, n = self.search, self.fluid_count
        self.build_neighborhood(state.particle_q)
        # the statistics are of the fluid's own kernel sum (the build cleared the slots' walls)
        self._evaluate_constraint(self._always_active)
        self._slots_hold_positions = False
        self._summary.assign(np.array(_SUMMARY_INIT, dtype=np.float32))
        wp.launch(
            summarize_fluid_density,
            dim=n,
            inputs=[self.params, s.slots, self.density, s.candidate_count],
            outputs=[self.particle_density, self._summary],
            device=self.device,
        )
        v = self._summary.numpy().astype(np.float64)
        active = int(v[0])
        # with no active particle every sum is 0, and so is every reported value
        per = 1.0 / active if active else 0.0
        some = float(active > 0)
        self._report_compression(float(v[3] * per), float(v[4] * some))
        compressed, peak = self._report_peaks()
        dropped = self._report_dropped_contacts()
        return {
            "active_particles": active,
            "rest_density": self.rest_density,
            "mean_abs_density_error": float(v[1] * per),
            "max_abs_density_error": float(v[2] * some),
            "mean_compression": float(v[3] * per),
            "max_compression": float(v[4] * some),
            "neighbors_min": int(v[5] * some),
            "neighbors_mean": float(v[6] * per),
            "neighbors_max": int(v[7] * some),
            "neighbor_overflow": int(v[8]),
            "candidates_mean": float(v[9] * per),
            "nonfinite_recovered": self._report_recoveries(),
            "compressed_particle_substeps": compressed,
            "peak_compression": peak,
            "fast_particle_substeps": self._report_fast_particles(),
            "density_subiterations": int(self.subiterations_total.numpy()[0]),
            "soft_contacts_dropped": dropped,
            "shape_entries_stopped": self._stopped_entries(),
        }

    def _stopped_entries(self) -> int:
        cc = self.continuous_collision
        return 0 if cc is None else int(cc.stopped_count.numpy()[0])


#: mean compression max(rho/rho0 - 1, 0) above which :meth:`FluidSolver.diagnostics` warns that the density
#: solve does not hold the fluid (healthy runs stay below 3 %, docs/validation.md "Where the method fails")
COMPRESSION_WARNING = 0.05

# summary slots: count, sum|e|, max|e|, sum compression, max compression, nbr min, nbr sum, nbr max,
# overflowing particles, candidate sum
_SUMMARY_SIZE = 10
_SUMMARY_INIT = [0.0, 0.0, 0.0, 0.0, 0.0, 3.0e38, 0.0, 0.0, 0.0, 0.0]


@wp.kernel
def summarize_fluid_density(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    density: wp.array[float],
    candidate_count: wp.array[wp.int32],
    # outputs
    particle_density: wp.array[float],
    summary: wp.array[float],
):
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0:
        return
    rho = density[i]
    # the sums count neighbours at the reference mass; a particle's own density scales with its mass
    particle_density[pi] = rho * slots.xm[i][3] / params[0].reference_mass
    e = rho * params[0].inv_rest_density - 1.0
    n = slots.particle.shape[0]
    found = int(0)
    candidates = int(0)
    overflow = int(0)
    for lane in range(slots.lanes):
        c = slots.neighbor_count[lane * n + i]
        found += c
        candidates += candidate_count[lane * n + i]
        if c > slots.lane_capacity:
            overflow = 1
    nb = float(found)
    wp.atomic_add(summary, 0, 1.0)
    wp.atomic_add(summary, 1, wp.abs(e))
    wp.atomic_max(summary, 2, wp.abs(e))
    wp.atomic_add(summary, 3, wp.max(e, 0.0))
    wp.atomic_max(summary, 4, wp.max(e, 0.0))
    wp.atomic_min(summary, 5, nb)
    wp.atomic_add(summary, 6, nb)
    wp.atomic_max(summary, 7, nb)
    if overflow != 0:
        wp.atomic_add(summary, 8, 1.0)
    wp.atomic_add(summary, 9, float(candidates))


def find_fluid_particles(model) -> np.ndarray:
    """Indices of the particles of ``model`` flagged :attr:`~newton.ParticleFlags.FLUID`."""
    if not model.particle_count:
        return np.zeros(0, dtype=np.int32)
    flags = model.particle_flags.numpy()
    return np.flatnonzero(flags & int(ParticleFlags.FLUID)).astype(np.int32)
