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
from types import SimpleNamespace

import numpy as np
import warp as wp

from ....geometry import ParticleFlags
from .calibration import (
    CLOSING_PASS_SHARE,
    ONE_KERNEL_EXPONENT,
    WALL_TABLE_SIZE,
    lattice_density,
    one_kernel_scale,
    rest_gradient_sq,
    rest_lattice,
    stable_relaxation,
    wall_density_tables,
)
from .config import (
    AFFINE_REGULARIZER,
    AKINCI_ZERO,
    COHESION_DISPLACEMENT,
    COHESION_GATE,
    EPSILON_RELATIVE,
    FULL_NEIGHBOR_FACTOR,
    MAX_CORRECTION_FRACTION,
    FluidConfig,
    FluidTuning,
    fluid_memory_bytes,
    free_memory,
    real_in_range,
)
from .continuous_collision import GUARD_ROUNDS, ContinuousCollision, GuardedShapes, still_shapes
from .density_constraint import (
    APPLY_ADVANCE,
    APPLY_AS_XPBD,
    COMPRESSION_SUMS,
    RATE_NONE,
    RATE_READ,
    ParticleApply,
    density_passes,
    gather_fluid_positions,
    store_fluid_warm_start,
)
from .diagnostics import FluidReports
from .diffuse import (
    DIFFUSE_BLOCK_DIM,
    DIFFUSE_DEAD,
    DiffuseBuffers,
    advect_diffuse_particles,
    emit_diffuse_particles,
)
from .neighbors import FluidNeighborSearch, neighbor_list_layout
from .placement import (
    EAGER_RELAXATION_ROUNDS,
    RELAXATION_PASSES,
    RELAXATION_ROUNDS,
    clear_placement,
    find_overpacked_worlds,
    find_packed_slots,
    keep_packed_worlds_relaxing,
    list_shape_walls,
    mark_placed_worlds,
    refresh_relaxed_contacts,
    relaxation_kernel,
)
from .render_particles import compute_fluid_render_particles, reset_render_particles
from .reset import reset_diffuse_worlds, reset_fluid_worlds
from .schedule import density_schedule
from .sph import MAX_DISPLACEMENT_OFF, FluidParams, FluidSlots, SlotContent
from .velocity_passes import (
    advance_damping_clock,
    apply_fluid_viscosity,
    confine_vorticity_and_recover,
    damping_every,
    damping_steps,
    gather_fluid_state,
    recover_nonfinite_fluid,
)
from .walls import FluidWallContacts


class FluidSolver:
    """Buffers and passes of the fluid solve for the fluid particles of ``model``.

    Args:
        model: The model; its particles flagged :attr:`~newton.ParticleFlags.FLUID` are the fluid.
        config: Validated parameters; ``fluid_rest_distance`` must be set.
        fluid_particle: Indices of the fluid particles (host array).
        iterations: XPBD iterations of the solver's substep (one density pass each, or more), >= 1; sets
            the default relaxation (:func:`stable_relaxation`).
        tuning: Implementation choices that leave the results unchanged; ``None``: the defaults.
    """

    def __init__(
        self,
        model,
        config: FluidConfig,
        fluid_particle: np.ndarray,
        iterations: int,
        tuning: FluidTuning | None = None,
    ):
        self.model = model
        self.config = config
        self.tuning = FluidTuning() if tuning is None else tuning
        self.device = model.device
        self.fluid_count = len(fluid_particle)
        d = config.fluid_rest_distance
        h = config.fluid_smoothing_length
        masses = model.particle_mass.numpy()[fluid_particle]
        self.mean_mass = float(masses.mean())
        kernel = config.fluid_density_kernel
        #: the density constraint's passes compiled for the kernel
        self.passes = density_passes(kernel, damped=config.fluid_compression_damping > 0.0)
        self.rest_lattice_neighbors = len(rest_lattice(d, h)) - 1
        #: rest density of a regular lattice at the rest distance under the density kernel's sum [kg/m^3]
        self.lattice_density = lattice_density(d, h, self.mean_mass, kernel)
        # sum |grad C|^2 of a lattice particle at rest, grad C = m / rho0 grad W
        self.rest_grad_sq = rest_gradient_sq(d, h, self.mean_mass / self.lattice_density, kernel)
        # every count of density passes a substep runs is even or ends with a pass at the closing step (an odd
        # fixed count's last, all of an odd count of XPBD iterations under a tolerance, an iteration's last
        # sub-pass: schedule.py), so every schedule takes the even count's bound (calibration.stable_pass_bound)
        #: the relaxation in use while ``fluid_relaxation`` is None (see :func:`stable_relaxation`)
        self.default_relaxation = stable_relaxation(d, h, kernel=kernel, damping=config.fluid_compression_damping)
        #: the XPBD iteration whose pass takes the closing step: the last of an odd count of one pass each, else
        #: none (0)
        self.closing_iteration = iterations if config.fluid_max_iterations == 1 and iterations % 2 == 1 else 0

        if config.fluid_max_neighbors > 0:
            capacity, capped = config.fluid_max_neighbors, True
        else:
            capacity, capped = FULL_NEIGHBOR_FACTOR * self.rest_lattice_neighbors, False
        forced_lanes = self.tuning.scan_lanes if self.tuning.scan_lanes and not capped else None
        lanes, lane_capacity = neighbor_list_layout(
            capacity, capped, forced_lanes, device=self.device, particle_count=self.fluid_count
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
            #: the coarse density correction (None: off; a scene without it allocates and launches nothing)
            self.coarse = None
            if config.fluid_coarse_correction > 0.0:
                # (imported here: a solver without it loads none of its kernels)
                from .coarse_correction import CoarseCorrection, warn_about_dynamic_shapes  # noqa: PLC0415

                warn_about_dynamic_shapes(model)
                rows = np.where(worlds >= 0, worlds, int(model.world_count))
                self.coarse = CoarseCorrection(
                    rows, model.world_count, d, config.fluid_coarse_cell, config.fluid_coarse_correction, self.device
                )
            self.search = FluidNeighborSearch(
                self.fluid_particle, model.particle_count, world_count, h, capacity, capped, forced_lanes
            )
            n = self.fluid_count
            self.params = wp.zeros(1, dtype=FluidParams)
            self.density = wp.zeros(n, dtype=float)
            #: multiplier (x) and relative density rho / rho0 (y) of each slot, from the last density pass
            self.lambda_rho = wp.zeros(n, dtype=wp.vec2)
            self.sorted_v = wp.zeros(n, dtype=wp.vec3)
            #: substeps since the last non-affine damping (:func:`.velocity_passes.damping_due`)
            self.damping_clock = wp.zeros(1, dtype=wp.int32)
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
            #: g dC of each slot, read by the substep's first density pass (fluid_compression_damping)
            self.compression_rate = wp.zeros(n if config.fluid_compression_damping > 0.0 else 0, dtype=float)
            #: each slot's move from the current substep's start to its build (its first density pass reads them)
            self.sorted_moved = wp.zeros(n if config.fluid_compression_damping > 0.0 else 0, dtype=wp.vec3)
            self.search.gather_moves(self.sorted_moved)
            self.warm_lambda = wp.zeros(n if warm else 0, dtype=float)
            self.lambda_sum = wp.zeros(n if warm else 0, dtype=float)
            if warm:
                self.search.carry_values(self.particle_lambda, self.warm_lambda)
            # the flag of the passes that always run; the compression sums the schedules decide on, and the
            # total of the passes that corrected (for the diagnostics)
            self.always_active = wp.ones(1, dtype=wp.int32)
            self.tolerance_mode = config.fluid_max_iterations > 1 or config.fluid_density_tolerance > 0.0
            self.compression_bins = wp.zeros(COMPRESSION_SUMS, dtype=float)
            # particles past PEAK_COMPRESSION in a substep's last density pass, and their peak, per bin:
            # kept on the device between two diagnostics calls (see density_constraint.density_passes)
            self.subiterations_total = wp.zeros(1, dtype=wp.int32)
            # gradient of the static walls' share of rho / rho0 per slot, from the density pass to the correction
            self.wall_grad = wp.zeros(n, dtype=wp.vec3)
            wall_rho, wall_drho = wall_density_tables(d, h, self.mean_mass, kernel=kernel)
            self.wall_table = wp.array(wall_rho / self.lattice_density, dtype=float)
            self.wall_table_grad = wp.array(wall_drho / self.lattice_density, dtype=float)
            self.last_finite_q = wp.array(model.particle_q.numpy()[fluid_particle], dtype=wp.vec3)
            #: device counters of what happened between two diagnostics calls, and the warnings that report it
            self.reports = FluidReports(model.particle_count)
            self.nonfinite_count = self.reports.nonfinite_count
            self.fast_count = self.reports.fast_count
            #: density of every particle at the state of the last :meth:`diagnostics` call [kg/m^3] (0 for non-fluid)
            self.particle_density = self.reports.particle_density
            # stands in for the reset mask when every world is reset (the kernel then reads none)
            self._no_mask = wp.zeros(1, dtype=wp.bool)
        other = FluidSlots()
        for field in ("particle", "neighbors", "neighbor_count", "capacity", "lanes", "lane_capacity"):
            setattr(other, field, getattr(self.search.slots, field))
        other.wall_count = self.search.wall_count
        other.wall_plane = self.search.wall_plane
        other.xm = self.xm_applied
        #: the slot views of the two position buffers; ``current`` is the one holding the positions
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
        self.current = 0
        self.iteration = 0
        self.warm_stored = False
        #: what the current slot buffer holds (see SlotContent)
        self.slot_content = SlotContent.STALE
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
        # over-packed placements (see :mod:`.placement`): per world (the global world last) whether a
        # placement touched it since the last step and whether it relaxes; the guard of their moves
        with wp.ScopedDevice(self.device):
            rows = int(model.world_count) + 1
            self.placed = wp.ones(rows, dtype=wp.int32)
            self.any_placed = wp.ones(1, dtype=wp.int32)
            self.relaxing = wp.zeros(rows, dtype=wp.int32)
            self.any_relaxing = wp.zeros(1, dtype=wp.int32)
            self.placement_packed = wp.zeros(rows, dtype=wp.int32)
            self.placement_rounds_left = wp.zeros(1, dtype=wp.int32)
        # (every shape that collides with particles, dynamic bodies' held where they are: fluid placed in a
        # body is moved out of it, positions only, rather than thrown out by its contacts; diffuse particles
        # are pushed out of the same shapes)
        needs_shapes = config.fluid_relax_overpacked or self.diffuse is not None
        self.shape_guard = ContinuousCollision.build(model, dynamic=True) if needs_shapes else None
        self.placement_guard = self.shape_guard if config.fluid_relax_overpacked else None
        # the second stream (see FluidTuning.concurrent_passes), and whether work on it has not been joined yet
        concurrent = self.device.is_cuda and self.tuning.concurrent_passes
        self.side_stream = wp.Stream(self.device) if concurrent else None
        self._side_pending = False
        # the density pass of the next iteration ran ahead on the second stream
        self.evaluated_ahead = False
        #: how many density passes an iteration runs, and who decides (:mod:`.schedule`)
        self.schedule = density_schedule(self)
        self.update_params()
        #: whether the model's initial fluid is over-packed (a reset that restores it relaxes it again)
        self.initial_overpacked = config.fluid_relax_overpacked and self._find_overpacked(model.particle_q)
        #: whether the next step checks the placed worlds (and relaxes the over-packed ones)
        self.placement_pending = self.initial_overpacked
        # the check and the rounds captured for CUDA steps outside a graph, with the copies they work on
        # (:meth:`_capture_eager_relaxation`)
        self.eager_relaxation = None
        if self.placement_pending:
            self._capture_eager_relaxation()

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
        p.one_kernel_scale = one_kernel_scale(d, h)
        p.one_kernel_slope = ONE_KERNEL_EXPONENT * p.one_kernel_scale / h
        p.rest_density = self.rest_density
        p.inv_rest_density = 1.0 / self.rest_density
        p.reference_mass = self.mean_mass
        p.rest_distance = d
        # the gradients scale with m/rho0, so does their rest norm
        scale = self.lattice_density / self.rest_density
        p.epsilon = EPSILON_RELATIVE * self.rest_grad_sq * scale * scale
        p.relaxation = self.default_relaxation if c.fluid_relaxation is None else c.fluid_relaxation
        # the default step lets an odd count's last pass correct the shortest wave at most fully; a relaxation
        # the user sets is used for every pass
        p.closing_relaxation = p.relaxation * CLOSING_PASS_SHARE if c.fluid_relaxation is None else p.relaxation
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
        p.compression_damping = c.fluid_compression_damping
        p.wall_scale = self.lattice_density / self.rest_density
        p.wall_table_step = h / (WALL_TABLE_SIZE - 1)
        self.params.assign(wp.array([p], dtype=FluidParams, device="cpu"))

    # --- passes inside the upstream step ---------------------------------------------------------

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
    def beside(self):
        """Launches inside go to the second stream, after everything launched so far on the current one.

        They run beside what the current stream does next, until :meth:`_join`. Without a second
        stream (CPU, or ``FluidTuning.concurrent_passes`` off) they go to the current stream.
        """
        if self.side_stream is None:
            yield
            return
        with wp.ScopedStream(self.side_stream, sync_enter=True):
            yield
        self._side_pending = True

    def _join(self) -> None:
        """Make the current stream wait for the work launched by :meth:`beside` (in a graph: an edge)."""
        if self._side_pending:
            self.device.stream.wait_stream(self.side_stream)
            self._side_pending = False

    def build_neighborhood(
        self, particle_q: wp.array, particle_q_start=None, particle_qd=None, body_q=None, allocation_free: bool = False
    ) -> None:
        """Sort the fluid at ``particle_q`` and list its neighbours.

        After prediction (``particle_q_start`` and ``particle_qd`` given) each fluid particle's travel
        is first limited to ``fluid_max_displacement`` rest distances, in the same pass, and the
        static walls of the step's contacts are listed for each slot by the same launch as the
        neighbours (a build for diagnostics or rendering lists no walls: the contacts belong to a step).
        In a step, the sort and the scan run beside upstream's work up to the first density pass
        (particle-shape contacts, which only read the positions): :meth:`beside`. With
        ``allocation_free`` the sort's prefix sum allocates nothing (the relaxation's builds, which run in
        the bodies of conditional nodes).
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
        with self.beside() if particle_q_start is not None else contextlib.nullcontext():
            s.sort(
                particle_q,
                m.particle_mass,
                m.particle_world,
                allocation_free=allocation_free,
                particle_q_start=particle_q_start,
            )
            s.scan(walls)
        # the build gathered these positions into slot order: the first iteration uses them as they are
        self.slot_content = SlotContent.BUILT
        self.iteration = 0
        self.warm_stored = False
        self.current = 0
        self.evaluated_ahead = False

    @property
    def slots(self) -> FluidSlots:
        """The slots with the current position buffer (see :meth:`solve_density`)."""
        return self._slot_views[self.current]

    def solve_density(
        self, particle_q: wp.array, particle_deltas: wp.array, apply: tuple | None = None, iterations: int = 0
    ) -> None:
        """The density constraint of one XPBD iteration: add its correction to ``particle_deltas``.

        ``apply`` = ``(x_start, dt, v_max, velocities)`` says how ``SolverXPBD`` applies the deltas
        after this call (:class:`~.density_constraint.ParticleApply`; ``x_start`` the substep's start positions).
        With it, and one density pass per iteration that is sure to correct (no tolerance, or the
        substep's first), the correction pass also writes every fluid particle's applied position in
        slot order (and, with ``velocities``, its velocity: false where something changes the
        velocities after the iterations), so the next iteration and the viscosity pass gather nothing:
        two launches less per substep.

        How many passes an iteration runs, and who decides, is :attr:`schedule`'s:
        :class:`~.schedule.FixedPasses` (one correcting pass), :class:`~.schedule.IterationTolerance`
        (one pass, skipped once the substep met ``fluid_density_tolerance`` after an even count) or
        :class:`~.schedule.SubPasses` (up to ``fluid_max_iterations`` passes, decided on the device). With
        ``fluid_warm_start``, the substep's first iteration first moves the fluid by the multipliers
        carried from the last one, and with fixed counts the correction of iteration ``iterations`` (the
        substep's last; 0: unknown) keeps the multipliers for the next substep (else a pass after the
        step does).
        """
        self._join()
        m, n = self.model, self.fluid_count
        # the substep's first iteration starts from the positions the build gathered; its first density
        # pass always corrects, and with the tolerance on the XPBD iterations a converged substep skips the
        # rest of its passes
        first = self.slot_content is SlotContent.BUILT
        self.iteration += 1
        active = self.schedule.active(first)
        if self.slot_content is SlotContent.STALE:
            wp.launch(
                gather_fluid_positions,
                dim=n,
                inputs=[self.slots, active, particle_q, m.particle_mass],
                device=self.device,
            )
        if first and self.warm_start_on():
            self._warm_start(particle_deltas, active)
        # after this iteration's correction, the slots' positions are out of date (unless it writes the applied ones)
        self.slot_content = SlotContent.STALE
        self.schedule.run(first, active, particle_q, particle_deltas, apply, iterations)

    def swap_slot_buffers(self) -> None:
        """Make the other position buffer the current one (a correction wrote the moved positions there)."""
        self.current = 1 - self.current

    def warm_start_on(self) -> bool:
        # in a graph the passes are captured and check the parameter on the device (so it may change)
        return self.warm_start_mode and (self.device.is_capturing or self.config.fluid_warm_start > 0.0)

    def _warm_start(self, particle_deltas: wp.array, active: wp.array) -> None:
        """Move the fluid by the multipliers carried from the last substep before its first evaluation.

        The sort gathered them into slot order; the moved positions go to the other position buffer.
        """
        m, n = self.model, self.fluid_count
        wp.launch(
            self.passes.apply_warm_start,
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
            outputs=[particle_deltas, self._slot_views[1 - self.current].xm, self.lambda_sum],
            device=self.device,
        )
        self.current = 1 - self.current

    def correct(
        self,
        particle_deltas: wp.array,
        active: wp.array,
        x_pred: wp.array | None = None,
        apply: tuple | None = None,
        advance: bool = False,
        store_warm: bool = False,
        closing: bool = False,
    ) -> None:
        """The correction pass of the last :meth:`evaluate_constraint`'s multipliers (while ``active[0]`` is set).

        ``x_pred``: the positions ``SolverXPBD`` adds this iteration's deltas to. With ``apply`` (see
        :meth:`solve_density`) the pass also writes where ``SolverXPBD`` will put each particle; with
        ``advance`` (a density sub-pass, :class:`~.schedule.SubPasses`) where the iteration's deltas so far put
        it, ``x_pred + delta``, for the next sub-pass. ``store_warm`` keeps the multipliers for the next
        substep's warm start; ``closing`` takes the closing step (an odd count's last pass).
        """
        m = self.model
        applied = self._apply_off
        # the corrected positions go to the other position buffer (this pass reads the current one)
        if advance:
            applied = self._apply_advance[self.current]
            applied.x_pred = x_pred
        elif x_pred is not None:
            applied = ParticleApply()
            applied.on = APPLY_AS_XPBD
            applied.x_pred = x_pred
            applied.x_start, applied.dt, applied.v_max = apply[0], float(apply[1]), float(apply[2])
            applied.xm = self._slot_views[1 - self.current].xm
            applied.v = self.sorted_v
        wp.launch(
            self.passes.apply_correction,
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
                int(closing),
            ],
            outputs=[particle_deltas, self.lambda_sum, self.particle_lambda],
            device=self.device,
        )

    def evaluate_constraint(
        self, active: wp.array, track_compression: bool = False, last: bool = False, rate_pass: int = RATE_NONE
    ) -> None:
        """Density and multipliers at the positions gathered in ``slots.xm`` (while ``active[0]`` is set).

        ``last``: a pass of the substep's last XPBD iteration, whose compression peaks are kept for the
        next report. ``rate_pass`` (with ``fluid_compression_damping``): ``RATE_READ`` for the substep's
        first pass, which reads how much the substep's motion compresses each particle, ``RATE_KEPT`` for its
        later passes, ``RATE_NONE`` outside a step's passes.
        """
        reads = rate_pass == RATE_READ and self.passes.compute_lambda_reading_rate is not None
        wp.launch(
            self.passes.compute_lambda_reading_rate if reads else self.passes.compute_lambda,
            dim=self.fluid_count,
            inputs=[
                self.params,
                self.slots,
                active,
                self.wall_table,
                self.wall_table_grad,
                int(track_compression),
                int(last),
                rate_pass,
                self.sorted_moved,
            ],
            outputs=[
                self.density,
                self.lambda_rho,
                self.wall_grad,
                self.compression_bins,
                self.reports.peaks,
                self.compression_rate,
            ],
            device=self.device,
        )

    def finish_step(self, state_out, dt: float, particle_q_start: wp.array | None = None) -> None:
        """Continuous collision, viscosity, vorticity confinement and non-finite recovery on the step's result.

        With ``particle_q_start`` (the positions the substep started from), each fluid particle's path is
        first kept out of the static and kinematic shapes (:mod:`.continuous_collision`).

        Outside a graph capture the optional passes are not launched while their parameter is 0.
        Inside one they are captured and check the parameter on the device, so that switching them on
        or off later needs no re-capture: a pass that is off then costs its launch (about 2 us a
        kernel on an H100), less than a conditional node would (about 5 us, docs/archive/performance_notebook.md).
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
        if self.warm_start_on() and not self.warm_stored:
            wp.launch(
                store_fluid_warm_start,
                dim=self.fluid_count,
                inputs=[self.params, self.search.slots, self.lambda_sum],
                outputs=[self.particle_lambda],
                device=self.device,
            )
        self.warm_stored = False
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
        if self.coarse is not None:
            self.coarse.apply(
                self.fluid_particle,
                self.search.slot_of_particle,
                self.search.sorted_particle,
                self.search.sorted_world,
                self.search.wall_count,
                self.search.wall_plane,
                self.density,
                self.rest_density,
                state_out,
                dt,
            )
        if self.diffuse is not None:
            self._diffuse_pass(state_out, dt)

    def _recovery_outputs(self, state_out) -> list:
        """The arrays :func:`~.velocity_passes.recover_fluid_particle` updates, for the kernels that call it."""
        return [state_out.particle_q, state_out.particle_qd, self.last_finite_q, self.nonfinite_count, self.fast_count]

    def _diffuse_pass(self, state_out, dt: float) -> None:
        """Let the fluid emit diffuse particles, then advect them all (new ones leave shapes at once)."""
        s, m, b = self.search, self.model, self.diffuse
        shapes = GuardedShapes()
        if self.shape_guard is not None:
            self.shape_guard.hold(state_out.body_q, state_out.body_qd)
            shapes = self.shape_guard.shapes
        # the step's result in slot order (after the viscosity and vorticity passes changed the velocities)
        wp.launch(
            gather_fluid_state,
            dim=self.fluid_count,
            inputs=[
                self.params,
                s.slots,
                state_out.particle_q,
                state_out.particle_qd,
                m.particle_mass,
                0,
                self.damping_clock,
                1,
            ],
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
                shapes,
                int(self.shape_guard is not None),
                dt,
            ],
            outputs=[b],
            device=self.device,
        )

    def _velocity_pass(self, state_out, dt: float) -> None:
        """Viscosity, the non-affine damping when due after substeps of ``dt`` and the vorticity estimate (one neighbour loop)."""
        m, n = self.model, self.fluid_count
        every = damping_every(dt)
        if self.slot_content is not SlotContent.APPLIED_WITH_VELOCITIES:
            wp.launch(
                gather_fluid_state,
                dim=n,
                inputs=[
                    self.params,
                    self.slots,
                    state_out.particle_q,
                    state_out.particle_qd,
                    m.particle_mass,
                    1,
                    self.damping_clock,
                    every,
                ],
                outputs=[self.sorted_v],
                device=self.device,
            )
        wp.launch(
            apply_fluid_viscosity,
            dim=n,
            inputs=[self.params, self.slots, self.sorted_v, self.density, self.damping_clock, every, damping_steps(dt)],
            outputs=[state_out.particle_qd, self.vorticity],
            device=self.device,
        )
        wp.launch(advance_damping_clock, dim=1, inputs=[every], outputs=[self.damping_clock], device=self.device)

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

    # --- over-packed placements --------------------------------------------------------------------

    def _find_overpacked(self, particle_q: wp.array) -> bool:
        """Whether any placed world's fluid at ``particle_q`` is over-packed (synchronises; for the constructor)."""
        m = self.model
        shapes = self._hold_placement_guard(m.body_q, m.body_qd)
        self.build_neighborhood(particle_q)
        self._check_placed_worlds(shapes, RELAXATION_ROUNDS)
        self.slot_content = SlotContent.STALE
        found = bool(self.any_relaxing.numpy()[0])
        # the step finds them again and counts them for the report; without them no world waits for a check
        self.relaxing.zero_()
        self.any_relaxing.zero_()
        self.reports.overpacked.zero_()
        if not found:
            self.placed.zero_()
            self.any_placed.zero_()
        return found

    def _hold_placement_guard(self, body_q, body_qd) -> GuardedShapes:
        """The shapes the relaxation keeps the fluid out of, where ``body_q`` has them (an empty set without any)."""
        guard = self.placement_guard
        if guard is None:
            return GuardedShapes()
        guard.hold(body_q, body_qd)
        return guard.shapes

    def _list_shape_walls(self, shapes: GuardedShapes, listed: wp.array, any_listed: wp.array) -> None:
        if self.placement_guard is None:
            return
        m = self.model
        wp.launch(
            list_shape_walls,
            dim=self.fluid_count,
            inputs=[self.params, self.slots, m.particle_world, int(m.world_count), listed, any_listed, shapes],
            device=self.device,
        )

    def _check_placed_worlds(self, shapes: GuardedShapes, rounds: int) -> None:
        """After a build: mark the placed worlds whose fluid is over-packed or inside a shape as relaxing (for
        at most ``rounds`` rounds)."""
        # (the fluid's own sum: a lattice at rest reads rest density however close to a wall it was placed)
        self.evaluate_constraint(self.always_active)
        self._list_shape_walls(shapes, self.placed, self.always_active)
        m = self.model
        wp.launch(
            find_overpacked_worlds,
            dim=self.fluid_count,
            inputs=[
                self.search.slots,
                self.lambda_rho,
                m.particle_world,
                int(m.world_count),
                self.placed,
                self.search.values,
                rounds,
            ],
            outputs=[
                self.relaxing,
                self.any_relaxing,
                self.placement_rounds_left,
                self.reports.overpacked,
                self.last_finite_q,
            ],
            device=self.device,
        )

    def relax_placement(self, state) -> None:
        """Move the over-packed fluid of the worlds placed since the last step apart, positions only (:mod:`.placement`).

        Nothing (no launch) unless the construction found the initial fluid over-packed or a reset
        restored positions since the last step. In a CUDA graph and on the CPU the check runs only if
        a world was placed, and the rounds are a conditional loop that stops at the last relaxing
        world. A CUDA step without a graph launches the same nodes, captured once beforehand
        (:meth:`_capture_eager_relaxation`), on copies of the positions and body poses; where the
        driver has no conditional nodes it launches every round of :data:`EAGER_RELAXATION_ROUNDS` (no
        synchronisation): those after the last world stopped return at once, but for their neighbour
        builds.
        """
        if not self.placement_pending:
            return
        self.placement_pending = False
        self._join()
        if self.eager_relaxation is not None and not self.device.is_capturing:
            # (the captured graph holds the shapes where its copies of the body poses have them)
            copies, graph = self.eager_relaxation
            wp.copy(copies.particle_q, state.particle_q)
            if copies.body_q is not None and state.body_q is not None:
                wp.copy(copies.body_q, state.body_q)
                wp.copy(copies.body_qd, state.body_qd)
            wp.capture_launch(graph)
            wp.copy(state.particle_q, copies.particle_q)
            self._finish_placement(state)
        elif self.device.is_capturing or self.device.is_cpu:
            self._relaxation_nodes(state)
            wp.capture_if(self.any_placed, self._finish_placement, state=state)
        else:
            shapes = self._hold_placement_guard(state.body_q, state.body_qd)
            self._check_placement(state, shapes, EAGER_RELAXATION_ROUNDS)
            for _ in range(EAGER_RELAXATION_ROUNDS):
                self._relaxation_round(state, shapes)
            self._finish_placement(state)
        self.slot_content = SlotContent.STALE

    def _relaxation_nodes(self, state) -> None:
        """The check (if a world was placed) and the conditional loop of rounds, as conditional nodes on ``state``.

        Conditional bodies may not allocate: their neighbour builds sort with the allocation-free sum.
        """
        shapes = self._hold_placement_guard(state.body_q, state.body_qd)
        wp.capture_if(self.any_placed, self._check_placement, state=state, shapes=shapes, rounds=RELAXATION_ROUNDS)
        wp.capture_while(self.any_relaxing, self._relaxation_round, state=state, shapes=shapes)

    def _check_placement(self, state, shapes: GuardedShapes, rounds: int) -> None:
        """Check the placed worlds and run the first round of the relaxation on the check's neighbour build."""
        self.build_neighborhood(state.particle_q, allocation_free=True)
        # (lists the walls of every placed world, the relaxing ones among them)
        self._check_placed_worlds(shapes, rounds)
        self._relaxation_round(state, shapes, first=True)

    def _finish_placement(self, state) -> None:
        """The step's contacts of the moved particles found again; the placement forgotten."""
        m = self.model
        c = self.contacts
        if c is not None and getattr(c, "soft_contact_count", None) is not None and c.soft_contact_max:
            wp.launch(
                refresh_relaxed_contacts,
                dim=c.soft_contact_max,
                inputs=[
                    c.soft_contact_count,
                    c.soft_contact_particle,
                    c.soft_contact_shape,
                    c.soft_contact_max,
                    m.particle_flags,
                    m.particle_world,
                    state.particle_q,
                    int(m.world_count),
                    self.placed,
                    self.placement_guard.shapes if self.placement_guard is not None else GuardedShapes(),
                    int(self.placement_guard is not None),
                    m.shape_transform,
                    m.shape_body,
                    state.body_q if state.body_q is not None else self._no_bodies,
                ],
                outputs=[c.soft_contact_body_pos, c.soft_contact_normal],
                device=self.device,
            )
        wp.launch(
            clear_placement,
            dim=self.placed.shape[0],
            outputs=[self.placed, self.any_placed, self.relaxing, self.any_relaxing],
            device=self.device,
        )

    def _capture_eager_relaxation(self) -> None:
        """Capture the check and the rounds of the relaxation once, with their conditional nodes, for CUDA steps
        outside a graph.

        Such a step cannot read the flags that end the rounds without synchronising; launching this graph, it
        runs them as a graph step does, up to :data:`RELAXATION_ROUNDS`, stopping at the last relaxing world.
        A graph binds its arrays, so it works on copies of the positions and body poses that the step makes
        before the launch and copies back after it. Captured at construction or at a reset that asks for a
        check (not inside ``step``), once; nothing on the CPU, inside another capture (that step captures the
        conditional nodes itself) or where the CUDA driver has no conditional nodes (the step then launches
        :data:`EAGER_RELAXATION_ROUNDS` rounds).
        """
        d = self.device
        if self.eager_relaxation is not None or not d.is_cuda or d.is_capturing:
            return
        if not wp.is_conditional_graph_supported():
            return
        m = self.model
        bodies = m.body_count > 0 and m.body_q is not None
        copies = SimpleNamespace(
            particle_q=wp.empty_like(m.particle_q),
            body_q=wp.empty_like(m.body_q) if bodies else None,
            body_qd=wp.empty_like(m.body_qd) if bodies else None,
        )
        # (the modules of the check and the rounds, loaded before the capture rather than during it)
        for name in ("placement", "neighbors", "prefix_sum", "density_constraint", "continuous_collision", "walls"):
            wp.load_module(f"{__package__}.{name}", device=d)
        self._join()
        with wp.ScopedCapture(device=d, force_module_load=False) as capture:
            self._relaxation_nodes(copies)
        self.slot_content = SlotContent.STALE
        self.eager_relaxation = (copies, capture.graph)

    def _relaxation_round(self, state, shapes: GuardedShapes, first: bool = False) -> None:
        """One round of the relaxation: a neighbour build (but in the first), the check that stops relaxed worlds, passes."""
        m = self.model
        rows = int(m.world_count)
        if not first:
            self.build_neighborhood(state.particle_q, allocation_free=True)
            self._list_shape_walls(shapes, self.relaxing, self.any_relaxing)
        self.evaluate_constraint(self.any_relaxing)
        wp.launch(
            find_packed_slots,
            dim=self.fluid_count,
            inputs=[self.slots, self.lambda_rho, m.particle_world, rows, self.relaxing, self.any_relaxing],
            outputs=[self.placement_packed],
            device=self.device,
        )
        wp.launch(
            keep_packed_worlds_relaxing,
            dim=1,
            inputs=[self.placement_packed],
            outputs=[self.relaxing, self.any_relaxing, self.placement_rounds_left, self.reports.overpacked],
            device=self.device,
        )
        for k in range(RELAXATION_PASSES):
            if k > 0:
                self.evaluate_constraint(self.any_relaxing)
            wp.launch(
                relaxation_kernel(self.config.fluid_density_kernel),
                dim=self.fluid_count,
                inputs=[
                    self.params,
                    self.slots,
                    self.lambda_rho,
                    self.wall_grad,
                    self.fluid_particle,
                    self.search.slot_of_particle,
                    m.particle_flags,
                    m.particle_world,
                    m.particle_radius,
                    m.particle_inv_mass,
                    rows,
                    self.relaxing,
                    self.any_relaxing,
                    shapes,
                    int(self.placement_guard is not None),
                    GUARD_ROUNDS,
                ],
                outputs=[state.particle_q, self.last_finite_q, self._slot_views[1 - self.current].xm],
                device=self.device,
            )
            self.swap_slot_buffers()

    # --- render particles ------------------------------------------------------------------------

    def update_render_particles(
        self, state, smoothing: float, anisotropy_scale: float, anisotropy_min: float, anisotropy_max: float
    ) -> None:
        """Smoothed positions and ellipsoid axes of every particle at ``state`` (see :mod:`.render_particles`)."""
        smoothing = real_in_range("smoothing", smoothing, 0.0, 1.0)
        anisotropy_scale = real_in_range("anisotropy_scale", anisotropy_scale, 0.0, lo_open=True)
        anisotropy_min = real_in_range("anisotropy_min", anisotropy_min, 0.0, 1.0, lo_open=True)
        anisotropy_max = real_in_range("anisotropy_max", anisotropy_max, 1.0)
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
        self.slot_content = SlotContent.STALE
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
        if restore_q and self.config.fluid_relax_overpacked and (source is not None or self.initial_overpacked):
            # the restored worlds are checked for an over-packed placement at the next step
            wp.launch(
                mark_placed_worlds,
                dim=self.placed.shape[0],
                inputs=[mask, use_mask],
                outputs=[self.placed, self.any_placed],
                device=self.device,
            )
            self.placement_pending = True
            self._capture_eager_relaxation()
        if self.coarse is not None:
            self.coarse.forget(mask, use_mask)
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

    def diagnostics(self, state) -> dict:
        """Density and neighbourhood statistics of the fluid at ``state`` (synchronises; not for the hot loop)."""
        s = self.search
        self.build_neighborhood(state.particle_q)
        # the statistics are of the fluid's own kernel sum (the build cleared the slots' walls)
        self.evaluate_constraint(self.always_active)
        self.slot_content = SlotContent.STALE
        v = self.reports.summarize(self.params, s.slots, self.density, s.candidate_count)
        active = int(v[0])
        # with no active particle every sum is 0, and so is every reported value
        per = 1.0 / active if active else 0.0
        some = float(active > 0)
        r = self.reports
        r.report_compression(float(v[3] * per), float(v[4] * some))
        compressed, peak = r.report_peaks()
        dropped = r.report_dropped_contacts(self.contacts)
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
            "nonfinite_recovered": r.report_recoveries(),
            "compressed_particle_substeps": compressed,
            "peak_compression": peak,
            "fast_particle_substeps": r.report_fast_particles(
                self.config.fluid_max_displacement, self.continuous_collision is not None
            ),
            "density_subiterations": int(self.subiterations_total.numpy()[0]),
            "soft_contacts_dropped": dropped,
            "shape_entries_stopped": self._stopped_entries(),
            "overpacked_placed": r.report_overpacked(),
        }

    def _stopped_entries(self) -> int:
        cc = self.continuous_collision
        return 0 if cc is None else int(cc.stopped_count.numpy()[0])


def find_fluid_particles(model) -> np.ndarray:
    """Indices of the particles of ``model`` flagged :attr:`~newton.ParticleFlags.FLUID`."""
    if not model.particle_count:
        return np.zeros(0, dtype=np.int32)
    flags = model.particle_flags.numpy()
    return np.flatnonzero(flags & int(ParticleFlags.FLUID)).astype(np.int32)
