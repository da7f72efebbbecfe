# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Position-based fluids inside :class:`~newton.solvers.SolverXPBD`: what the extension adds to it.

:func:`activate` runs when ``newton._src.solvers.xpbd`` is imported (through the startup hook, or when
this module is imported directly) and hands :mod:`.upstream`, the one module that touches upstream
names, what to add to ``SolverXPBD``:

- the ``fluid_*`` constructor keywords and matching properties;
- :meth:`reset` (restore the fluid of the selected worlds and clear their carried solver state);
- :meth:`fluid_diagnostics`, :meth:`fluid_coarse_potential` and :meth:`update_render_particles`, the render and
  diffuse arrays.

Solvers whose model has no fluid particle run upstream's step unchanged.
"""

from __future__ import annotations

import importlib

from . import upstream
from .config import FLUID_KEYWORDS, FluidConfig, FluidTuning
from .solver_fluid import FluidSolver, find_fluid_particles

SUPPORTED_NEWTON_VERSION = upstream.SUPPORTED_NEWTON_VERSION


def _make_property(name: str, mutable: bool):
    def fget(self):
        value = getattr(self._fluid_config, name)
        if value is None and name == "fluid_relaxation" and self._fluid is not None:
            return self._fluid.default_relaxation
        return value

    def fset(self, value):
        if self._fluid is not None:
            self._fluid.check_change(name, value)
        self._fluid_config.set(name, value)
        if self._fluid is not None:
            self._fluid.update_params()

    doc = f"``{name}`` of the fluid solve (see the constructor)."
    return property(fget, fset if mutable else None, doc=doc)


def _render_property(name: str):
    return property(
        lambda self: None if self._fluid is None else getattr(self._fluid, name),
        doc=f"Result of :meth:`update_render_particles` (``None`` before the first call): see there for ``{name}``.",
    )


def _diffuse(solver):
    return None if solver._fluid is None else solver._fluid.diffuse


def _warm_start_multipliers(solver):
    fluid = solver._fluid
    if fluid is None or fluid.particle_lambda.shape[0] == 0:
        return None
    return fluid.particle_lambda


def fluid_coarse_potential(self, state):
    """The coarse density correction's potential [m^2] at each particle of ``state``, from the last substep.

    Each substep moves a fluid particle by ``fluid_coarse_correction`` times the potential's gradient, so the
    pressure that move stands for is ``-(m / d^3) fluid_coarse_correction phi / dt^2`` (``d`` the rest distance,
    ``dt`` the substep; zero at the free surface, as ``phi`` is). Read from the cells with fluid around each
    particle as the move reads their gradients. Allocates its result and launches one kernel: call it when you
    need the numbers, not in the hot loop.

    Args:
        state: The state whose particle positions the potential is read at (the one the last step wrote).

    Returns:
        ``wp.array`` of ``particle_count`` floats (0 for particles not fluid), or ``None`` without fluid or
        without ``fluid_coarse_correction``.
    """
    fluid = self._fluid
    if fluid is None or fluid.coarse is None:
        return None
    return fluid.coarse.potential_at(fluid.fluid_particle, state.particle_q)


def _diffuse_property(field: str, doc: str):
    return property(
        lambda self: None if _diffuse(self) is None else getattr(_diffuse(self), field),
        doc=f"Diffuse (spray, foam, bubble) particles' {doc}: a ``wp.array`` of ``max_diffuse_particles`` "
        "entries, updated every substep; ``None`` when ``max_diffuse_particles`` is 0.",
    )


def fluid_diagnostics(self, state) -> dict:
    """Density and neighbourhood statistics of the fluid at ``state``.

    Recomputes the neighbourhood and the density at ``state.particle_q`` (so it reads the
    result of the last step, not a value from inside it) and synchronises with the device: call it
    when you need the numbers, not in the hot loop. Also fills :attr:`fluid_density`. Warns
    (``RuntimeWarning``) when the mean compression exceeds 5 %, more than the density solve holds
    (a fluid too deep for its iterations and substeps), once until it falls below again. What
    happened between two calls is kept on the device and reported at the next one, however short
    it lasted: fluid placed over-packed (relaxed by the step after its placement), particle substeps
    that ended their density solve more than 10 % compressed (an impact harder than the iterations
    hold), substeps faster than one rest distance, and particles recovered from non-finite values
    each warn once with their count.

    Args:
        state: The state to measure, usually the ``state_out`` of the last step.

    Returns:
        dict: ``active_particles``, ``rest_density`` [kg/m^3], ``mean_abs_density_error`` and
        ``max_abs_density_error`` (of rho/rho0 - 1 over all fluid particles, surface included),
        ``mean_compression`` and ``max_compression`` (of max(rho/rho0 - 1, 0)), ``neighbors_min``,
        ``neighbors_mean``, ``neighbors_max``, ``neighbor_overflow`` (particles with more neighbours
        than are stored), ``candidates_mean`` (particles examined per neighbourhood search) and
        ``nonfinite_recovered`` (total count of recovered non-finite particles),
        ``compressed_particle_substeps`` and ``peak_compression`` (particle substeps whose last density
        pass found them more than 10 % compressed since the last call, and the largest such compression),
        ``density_subiterations`` (total density passes that corrected, with ``fluid_max_iterations`` > 1
        or a ``fluid_density_tolerance`` set at construction),
        ``fast_particle_substeps`` (particle substeps that ended with a velocity carrying the particle more
        than one rest distance in a substep; a ``RuntimeWarning`` says when it grew since the last call),
        ``soft_contacts_dropped`` (particle-shape contacts the last step's collision found beyond the
        ``Contacts`` buffer's ``soft_contact_max``, so dropped with the walls they stand for; warns),
        ``shape_entries_stopped`` (particle substeps whose path continuous collision stopped at a static or
        kinematic shape, in all), ``overpacked_placed`` (fluid particles placed more than 10 % above rest
        density or with a centre inside a shape since the last call, which the step after their
        placement moved apart, positions only; warns).
        Empty for a model without fluid.
    """
    if self._fluid is None:
        return {}
    return self._fluid.diagnostics(state)


def reset(self, state, world_mask=None, flags=None, *, fluid_source=None) -> None:
    """Reset the selected worlds: upstream's reset, then their fluid restored and its history cleared.

    Upstream's :meth:`SolverXPBD.reset` runs first (it validates ``world_mask`` and resets tendon
    state). Then, for the fluid particles of the selected worlds, positions (with
    :attr:`~newton.StateFlags.PARTICLE_Q` in ``flags``) and velocities (with
    :attr:`~newton.StateFlags.PARTICLE_QD`) are restored from ``fluid_source``, and the solver state they
    carry between steps is cleared: warm-start multipliers, the last finite positions that a
    non-finite recovery falls back to, and the worlds' diffuse particles. A world reset with its
    initial particles then replays bitwise as a fresh start (CPU); every other world's particles and
    solver state are left untouched. Non-fluid particles, bodies and joints are not restored here.
    The whole-model counters (``fluid_nonfinite_count``, ``fluid_fast_count``, the compression peaks
    that :meth:`fluid_diagnostics` reports) keep counting. Device work only, no allocation or
    synchronisation: it can be captured in a CUDA graph, and the mask's contents may change between
    replays. Positions restored from a ``fluid_source`` (or from initial particles that were placed
    over-packed) are checked by the next :meth:`step`: a restored world whose fluid is more than 10 %
    above rest density, or with a centre inside a shape, is first moved apart, positions only
    (see :doc:`formulation`, "Over-packed placements"). In a CUDA graph that check runs only when the
    mask selected a world (6.8 ms at 100k particles on an H200 where nothing is packed) and relaxes for
    as many rounds as the packing needs. A CUDA step without a graph does the same by launching a graph
    of the check and the rounds that the solver captured once: at construction if the initial fluid was
    over-packed, else at the first reset outside a capture that asks for a check (that reset allocates
    a copy of the positions and of the body poses for it; later ones reuse them).

    Args:
        state: The state to reset (modified in place), the one the next :meth:`step` reads.
        world_mask: ``wp.array`` of ``world_count + 1`` bools on the model's device (the last entry selects
            the global world -1), as :meth:`newton.solvers.SolverBase.reset` takes it; ``None`` resets all.
        flags: :class:`~newton.StateFlags` bits saying what to restore; ``None`` restores positions and
            velocities. Without ``PARTICLE_Q`` and ``PARTICLE_QD`` the fluid is left as it is.
        fluid_source: A :class:`~newton.State` of this model to take the particles from (only those of the
            selected worlds are read); ``None`` takes the model's initial ``particle_q`` and ``particle_qd``.
    """
    return self._fluid_reset(state, world_mask, flags, fluid_source)


def update_render_particles(
    self,
    state,
    smoothing: float = 0.5,
    anisotropy_scale: float = 1.0,
    anisotropy_min: float = 0.25,
    anisotropy_max: float = 2.0,
) -> None:
    """Compute render positions and anisotropic ellipsoids of the particles at ``state`` for drawing.

    Fluid particles get a smoothed centre and three ellipsoid axes from the weighted covariance of
    their neighbourhood (Yu & Turk 2013): flat in sheets, long in strands, round inside. Other
    particles keep their position with round axes. The results, each a ``wp.array`` of
    ``particle_count`` on the model's device, are

    - :attr:`render_positions` (``wp.vec3`` [m]): ``(1 - smoothing) x + smoothing x_bar``;
    - :attr:`render_anisotropy`, :attr:`render_anisotropy_secondary`, :attr:`render_anisotropy_tertiary`
      (``wp.vec4``): the longest, middle and shortest axis, ``xyz`` a unit direction in world space and
      ``w`` the radius scale along it (multiply the particle's drawn radius by it).

    Nothing here changes the next simulation step; no host synchronisation, so it can be captured.

    Args:
        state: The state to draw.
        smoothing: Blend from the simulated position toward the neighbourhood mean, in [0, 1].
        anisotropy_scale: Multiplier of all three radius scales, > 0.
        anisotropy_min: Smallest radius scale before ``anisotropy_scale``, in (0, 1].
        anisotropy_max: Largest radius scale before ``anisotropy_scale``, >= 1.
    """
    if self._fluid is None:
        raise ValueError("update_render_particles needs a model with fluid particles (ParticleFlags.FLUID)")
    self._fluid.update_render_particles(state, smoothing, anisotropy_scale, anisotropy_min, anisotropy_max)


def _make_fluid(solver, model, fluid_kwargs: dict, tuning, verify_upstream) -> None:
    """After upstream's constructor: validate the keywords and, for a model with fluid, build its solve."""
    if tuning is not None and not isinstance(tuning, FluidTuning):
        raise ValueError(f"_fluid_tuning={tuning!r} is invalid: expected a FluidTuning or None")
    config = FluidConfig(**fluid_kwargs)
    solver._fluid_config = config
    solver._fluid = None
    fluid_particle = find_fluid_particles(model)
    if len(fluid_particle):
        if config.fluid_rest_distance is None:
            raise ValueError(
                f"fluid_rest_distance=None is invalid: the model has {len(fluid_particle)} fluid particles, "
                "expected a particle spacing in (0, inf) [m]"
            )
        verify_upstream()
        solver._fluid = FluidSolver(model, config, fluid_particle, solver.iterations, tuning)


def _reset_fluid(solver, state, world_mask, flags, fluid_source) -> None:
    """After upstream's reset: restore the fluid of the selected worlds (see :func:`reset`)."""
    if solver._fluid is None:
        if fluid_source is not None:
            raise ValueError("fluid_source is given, but the model has no fluid particles to restore")
        return
    from ....sim import StateFlags  # noqa: PLC0415

    bits = int(StateFlags.PARTICLE_Q | StateFlags.PARTICLE_QD) if flags is None else int(flags)
    restore_q, restore_qd = bool(bits & StateFlags.PARTICLE_Q), bool(bits & StateFlags.PARTICLE_QD)
    if not (restore_q or restore_qd):
        return
    model = solver.model
    if fluid_source is not None:
        q = getattr(fluid_source, "particle_q", None)
        if q is None or q.shape[0] != model.particle_count or q.device != model.device:
            found = "no particle_q" if q is None else f"{q.shape[0]} particles on {q.device}"
            raise ValueError(
                f"fluid_source has {found}: expected a State of this model "
                f"({model.particle_count} particles on {model.device})"
            )
    # upstream validated the mask (shape world_count + 1, bool, on the model's device)
    solver._fluid.reset(state, world_mask, restore_q, restore_qd, fluid_source)


def _additions() -> dict:
    """The attributes the extension adds to ``SolverXPBD``: public methods and properties."""
    added = {
        "reset": reset,
        "fluid_diagnostics": fluid_diagnostics,
        "fluid_coarse_potential": fluid_coarse_potential,
        "update_render_particles": update_render_particles,
    }
    for name in (
        "render_positions",
        "render_anisotropy",
        "render_anisotropy_secondary",
        "render_anisotropy_tertiary",
    ):
        added[name] = _render_property(name)
    for name, field, doc in (
        ("diffuse_positions", "position", "positions [m] (``wp.vec3``)"),
        ("diffuse_velocities", "velocity", "velocities [m/s] (``wp.vec3``)"),
        ("diffuse_lifetimes", "lifetime", "remaining lifetimes [s] (float; <= 0: a dead entry)"),
        ("diffuse_kinds", "kind", "kinds (int32: 0 spray, 1 foam, 2 bubble, -1 dead)"),
    ):
        added[name] = _diffuse_property(field, doc)
    added["diffuse_emitted_count"] = property(
        lambda self: None if _diffuse(self) is None else _diffuse(self).counters[1:2],
        doc="Device counter (``wp.array`` of one int32) of diffuse particles emitted so far, or ``None`` when "
        "``max_diffuse_particles`` is 0.",
    )
    added["fluid_density"] = property(
        lambda self: None if self._fluid is None else self._fluid.particle_density,
        doc="Per-particle density [kg/m^3] at the state of the last :meth:`fluid_diagnostics` call "
        "(``wp.array`` of ``particle_count``; 0 for non-fluid particles), or ``None`` without fluid.",
    )
    added["fluid_warm_start_multipliers"] = property(
        _warm_start_multipliers,
        doc="Per-particle density multipliers the next substep starts from: ``fluid_warm_start`` times each "
        "fluid particle's multipliers summed over the last substep (``wp.array`` of ``particle_count``, float; 0 "
        "for non-fluid particles), or ``None`` without fluid or warm start. Part of the solver's state: saved "
        "and restored with a State, a run continues bitwise. The pressure they imply is in docs/validation.rst.",
    )
    added["fluid_nonfinite_count"] = property(
        lambda self: None if self._fluid is None else self._fluid.nonfinite_count,
        doc="Device counter (``wp.array`` of one int32) of fluid particles recovered from non-finite values.",
    )
    added["fluid_fast_count"] = property(
        lambda self: None if self._fluid is None else self._fluid.fast_count,
        doc="Device counter (``wp.array`` of one int32) of fluid particle substeps that ended with a velocity "
        "that carries the particle more than one rest distance in a substep.",
    )
    for name in FLUID_KEYWORDS:
        added[name] = _make_property(name, name in FluidConfig.MUTABLE)
    return added


def activate(xpbd_module) -> None:
    """Extend ``xpbd_module.SolverXPBD`` (``newton._src.solvers.xpbd``) in place through :mod:`.upstream`; idempotent."""
    upstream.activate(xpbd_module, FLUID_KEYWORDS, _FLUID_DOC, _make_fluid, _reset_fluid, _additions())


_FLUID_DOC = """
        Fluid keywords (newton-fluid), for particles flagged :attr:`~newton.ParticleFlags.FLUID`; the README's
        parameter table and docs/validation.rst say what each setting does to the flow:
            fluid_rest_distance: Rest spacing of the fluid particles [m], > 0. Required when fluid particles exist.
            fluid_smoothing_length: Kernel support radius h [m], in (rest distance, 4 x rest distance].
                Defaults to 1.8 x ``fluid_rest_distance``.
            fluid_rest_density: Rest density of a particle of the mean fluid mass [kg/m^3], > 0 (one of mass ``m``
                has ``m / mean`` times it). Defaults to the density kernel's sum on the cubic lattice at the rest distance.
            fluid_cohesion: Strength of the Akinci pair cohesion of under-dense pairs [dimensionless], in [0, 1].
                Defaults to 0.
            fluid_viscosity: Blend toward the neighbourhood velocity per substep [dimensionless], in [0, 1].
                Defaults to 0.
            fluid_nonaffine_damping: Share of each particle's deviation from its neighbourhood's affine velocity
                field removed per 1/480 s [dimensionless], in [0, 1]; 0 is off. Defaults to 0.1.
            fluid_vorticity: Vorticity confinement strength [m/s], >= 0; 0 is off. Defaults to 0.
            fluid_relaxation: Scale of each Jacobi density correction [dimensionless], in (0, 2]. Defaults to None:
                the largest step stable for the kernel and the pass count (the property reads the value in use; an
                odd fixed count's last pass takes half of it).
            fluid_density_ramp: Compression (of rho/rho0 - 1) over which the density constraint ramps in
                [dimensionless], in [0, 0.01]. Defaults to 0.
            fluid_max_neighbors: Neighbours kept per particle, in [0, 4096]; 0 keeps the whole neighbourhood.
                Defaults to 0.
            fluid_density_tolerance: Mean compression (of max(rho/rho0 - 1, 0)) at which the density passes stop
                [dimensionless], >= 0: with ``fluid_max_iterations`` 1 a substep's after its first two, at an even
                count; with more, each XPBD iteration's after its first two, at an even count. 0 is off, and only
                a solver created with a value > 0 can change it later. Defaults to 0.
            fluid_max_iterations: Density passes per XPBD iteration, in [1, 64]; above 1 they stop at
                ``fluid_density_tolerance``. Defaults to 1.
            fluid_max_displacement: Longest travel of a fluid particle in one substep [rest distances], > 0 or
                ``inf`` (no limit). Defaults to ``inf``.
            fluid_warm_start: Share of a substep's summed density multipliers the next substep starts from
                [dimensionless], in [0, 0.5]; 0 is off, and only a solver created with a value > 0 can change it
                later. Defaults to 0.
            max_diffuse_particles: Capacity of the diffuse (spray, foam, bubble) particle buffer, >= 0; 0 is off.
                Defaults to 0.
            fluid_continuous_collision: Whether each fluid particle's path is kept out of static and kinematic
                shapes (bool), set at construction. Defaults to True.
            fluid_relax_overpacked: Whether the step after a placement moves fluid placed over-packed (more
                than 10 % above rest density) or with a centre inside a shape apart, positions only
                (bool), set at construction; False steps such a start as it is. Defaults to True.
            fluid_coarse_correction: Share of the coarse density correction's move applied each substep
                [dimensionless], in [0, 1], set at construction; 0 is off. After the density passes, the compression
                they leave is relaxed on cells of ``fluid_coarse_cell`` rest distances and the fluid moved by the
                potential's gradient: the long waves a few passes cannot converge (a deep column's ring). 0.5 is the
                measured choice. Defaults to 0.
            fluid_coarse_cell: Edge of the coarse correction's cells [rest distances], in [1, 16], set at
                construction. Defaults to 3.
            fluid_density_kernel: The density constraint's kernel (str), set at construction: ``"one_kernel"``
                sums ``(1 - r/h)^2.5``, normalised so the rest lattice reads ``m / d^3``, and moves along its own
                gradient: still water comes to rest (a deep column once its start's ring has died down);
                ``"poly6"`` sums the poly6 kernel and moves along the spiky kernel's gradient (Macklin & Müller
                2013), a few percent faster, its deep still water never at rest. Defaults to ``"one_kernel"``.
            fluid_compression_damping: Share of the compression a substep's motion adds that its density passes
                also remove [dimensionless], in [0, 0.4], set at construction; 0 is off. Damps a deep column's ring
                as strongly as the passes act on it; a load at rest is held as before. Defaults to 0.
"""


def _self_activate() -> None:
    """Activate when imported without the startup hook (e.g. ``python -S``); a no-op when already active."""
    import os  # noqa: PLC0415

    if os.environ.get("NEWTON_FLUID_DISABLE"):
        return
    flags = importlib.import_module("newton._src.geometry.flags")
    if not hasattr(flags.ParticleFlags, "FLUID"):
        import _newton_fluid_hook  # noqa: PLC0415

        _newton_fluid_hook._activate_flags(flags)
    activate(importlib.import_module("newton._src.solvers.xpbd"))


_self_activate()
