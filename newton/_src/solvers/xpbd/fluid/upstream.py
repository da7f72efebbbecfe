# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The seam with upstream ``SolverXPBD``: the one module that names, wraps or reads upstream privates.

:data:`SEAM` lists every upstream name the fluid extension touches, what it does there, and the
upstream hook that would let us delete the entry. Two guards keep the assumptions honest:

- :func:`check_names` runs at activation (import): every name exists and the particle-contact
  kernel we swap in has upstream's launch signature. On failure nothing is patched.
- :func:`verify_behaviour` runs once per device, when the first solver with fluid is built: a
  three-particle step of the stock solver checks the semantics we rely on (where the predicted
  positions are, which buffer ``_apply_particle_deltas`` applies the deltas to and with which
  formula, that the particle-contact kernel is looked up at launch, that a model without a particle
  grid and radius skips particle contacts). On a mismatch the extension deactivates itself (stock
  ``SolverXPBD`` again) and the construction raises an error naming both newton versions.

With upstream hooks (after integration; once per iteration, given the buffer the deltas go to; after
the step; a pair filter for particle contacts) this module would shrink to a registration: the
wrapped ``integrate_particles``, ``_apply_particle_deltas`` and ``step``, the contact-kernel swap,
the grid and radius swap, and the reads of ``_particle_delta_counter``, ``particle_q_init`` and
``enable_restitution`` would all go (see the ``hook`` column of :data:`SEAM`).
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import inspect
from dataclasses import dataclass

import numpy as np
import warp as wp

from .contacts import solve_particle_particle_contacts_skip_fluid_pairs
from .density_constraint import ParticleApply, applied_particles

SUPPORTED_NEWTON_VERSION = "1.8.0"


@dataclass(frozen=True)
class SeamEntry:
    """One upstream name the extension touches."""

    owner: str  # "SolverXPBD", "solver module" (newton._src.solvers.xpbd.solver_xpbd) or "Model"
    name: str
    how: str  # "wrapped", "swapped while stepping" or "read"
    why: str
    hook: str  # the upstream hook that would remove the entry


SEAM = (
    SeamEntry(
        "SolverXPBD",
        "__init__",
        "wrapped",
        "takes the fluid_* keywords and builds the fluid solve",
        "an extension registry",
    ),
    SeamEntry(
        "SolverXPBD",
        "integrate_particles",
        "wrapped",
        "builds the fluid neighbourhood from the predicted positions",
        "after integration",
    ),
    SeamEntry(
        "SolverXPBD",
        "_apply_particle_deltas",
        "wrapped",
        "adds the density correction once per iteration, after the other particle constraints",
        "once per iteration, given the positions the deltas are applied to",
    ),
    SeamEntry(
        "SolverXPBD",
        "step",
        "wrapped",
        "particle contacts skip fluid pairs; afterwards continuous collision, viscosity, vorticity, recovery",
        "after the step, and a pair filter for particle contacts",
    ),
    SeamEntry(
        "SolverXPBD",
        "reset",
        "wrapped",
        "restores the fluid of the selected worlds and clears their solver state",
        "none needed (reset is public and meant to be extended)",
    ),
    SeamEntry(
        "SolverXPBD",
        "_particle_delta_counter",
        "read",
        "which of the two states holds the positions the deltas are applied to",
        "once per iteration, given the positions the deltas are applied to",
    ),
    SeamEntry(
        "SolverXPBD",
        "particle_q_init",
        "read",
        "the substep's start positions (velocity update, continuous collision's paths)",
        "once per iteration, given the positions the deltas are applied to",
    ),
    SeamEntry(
        "SolverXPBD",
        "enable_restitution",
        "read",
        "whether anything changes particle velocities after the iterations",
        "once per iteration, given the positions the deltas are applied to",
    ),
    SeamEntry(
        "solver module",
        "solve_particle_particle_contacts",
        "swapped while stepping",
        "fluid-fluid pairs are left to the density constraint",
        "a pair filter for particle contacts",
    ),
    SeamEntry(
        "Model",
        "particle_grid",
        "swapped while stepping",
        "None when every particle is fluid: no grid build, no contact query",
        "a pair filter for particle contacts",
    ),
    SeamEntry(
        "Model",
        "particle_max_radius",
        "swapped while stepping",
        "0 when every particle is fluid: no contact launch",
        "a pair filter for particle contacts",
    ),
)

# the solver methods replaced by activate(), in SEAM's order
_WRAPPED = tuple(e.name for e in SEAM if e.owner == "SolverXPBD" and e.how == "wrapped")


def solver_module(cls):
    """The module that defines the solver class ``cls`` (where upstream looks the particle-contact kernel up)."""
    return importlib.import_module(cls.__module__)


def _mismatch(what: str) -> RuntimeError:
    import newton  # noqa: PLC0415

    return RuntimeError(
        f"newton-fluid supports newton {SUPPORTED_NEWTON_VERSION}, found newton {newton.__version__}: {what}"
    )


def _kernel_signature(kernel) -> list[tuple[str, str]]:
    return [(a.label, wp.types.type_repr(a.type)) for a in kernel.adj.args]


def check_names(xpbd_module) -> None:
    """Raise ``RuntimeError`` naming both versions unless every upstream name of :data:`SEAM` is there.

    Instance attributes (``Model.*`` and the ones ``SolverXPBD`` sets in its constructor) are checked
    by :func:`verify_behaviour`; here the class and module names, and the swapped contact kernel's
    launch signature against upstream's.

    Args:
        xpbd_module: The ``newton._src.solvers.xpbd`` package.
    """
    cls = xpbd_module.SolverXPBD
    module = solver_module(cls)
    missing = [f"SolverXPBD.{n}" for n in _WRAPPED if not hasattr(cls, n)]
    if not hasattr(module, "solve_particle_particle_contacts"):
        missing.append("solver_module.solve_particle_particle_contacts")
    if missing:
        raise _mismatch(f"upstream name(s) {', '.join(missing)} missing")
    ours = _kernel_signature(solve_particle_particle_contacts_skip_fluid_pairs)
    theirs = _kernel_signature(module.solve_particle_particle_contacts)
    if ours != theirs:
        raise _mismatch(f"solve_particle_particle_contacts takes {theirs}, the fluid replacement takes {ours}")


def delta_positions(solver, state_in, state_out) -> wp.array:
    """The positions upstream's ``_apply_particle_deltas`` adds this iteration's deltas to.

    Upstream ping-pongs between the two states without gradients: the first call of a step reads
    ``state_out`` (the predicted positions) and writes ``state_in``, the next reads ``state_in``.
    """
    current = state_in.requires_grad or solver._particle_delta_counter == 0
    return state_out.particle_q if current else state_in.particle_q


def substep_start_positions(solver) -> wp.array | None:
    """The positions the current substep started from (upstream's copy), ``None`` before the first step."""
    return getattr(solver, "particle_q_init", None)


def velocities_final_after_iterations(solver) -> bool:
    """Whether the velocities upstream writes with the iterations' last deltas are the step's (no restitution pass)."""
    return not getattr(solver, "enable_restitution", True)


@contextlib.contextmanager
def fluid_particle_contacts(module, model, all_fluid: bool):
    """While a fluid solver steps: particle contacts skip fluid-fluid pairs, or are skipped when all particles are fluid."""
    saved = (module.solve_particle_particle_contacts, model.particle_grid, model.particle_max_radius)
    module.solve_particle_particle_contacts = solve_particle_particle_contacts_skip_fluid_pairs
    if all_fluid:
        # no pair is left for the contact kernel: skip upstream's hash-grid build and query
        model.particle_grid = None
        model.particle_max_radius = 0.0
    try:
        yield
    finally:
        module.solve_particle_particle_contacts, model.particle_grid, model.particle_max_radius = saved


@contextlib.contextmanager
def upstream_step_only(solver):
    """Inside: ``solver`` steps as upstream's ``SolverXPBD`` with no fluid solve and no particle contacts.

    For benchmarks that time the upstream part of a fluid step alone (it is what the all-fluid step runs).
    """
    saved = solver._fluid
    solver._fluid = None
    try:
        with fluid_particle_contacts(solver_module(type(solver)), solver.model, all_fluid=True):
            yield
    finally:
        solver._fluid = saved


# ---------------------------------------------------------------------------------------------------------------------
# the behaviour guard


def _probe_model(device, fluid_flag: int):
    """Three particles: an overlapping pair flagged fluid (pushed apart faster than the velocity bound) and a free one."""
    import newton  # noqa: PLC0415

    builder = newton.ModelBuilder()
    flags = int(newton.ParticleFlags.ACTIVE) | fluid_flag
    builder.add_particle((0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 1.0, radius=0.1, flags=flags)
    builder.add_particle((0.15, 0.0, 1.0), (0.0, 0.0, 0.0), 1.0, radius=0.1, flags=flags)
    builder.add_particle((2.0, 0.0, 1.0), (0.5, 0.0, 0.0), 1.0, radius=0.1)
    model = builder.finalize(device=device)
    model.particle_max_velocity = 1.0
    return model


def _applied_by_our_formula(x_start, x_pred, deltas, dt, v_max, device) -> tuple[np.ndarray, np.ndarray]:
    n = len(x_pred)
    apply = ParticleApply()
    apply.on = 1
    apply.x_pred, apply.x_start, apply.dt, apply.v_max = x_pred, x_start, dt, v_max
    apply.xm = wp.empty(n, dtype=wp.vec4, device=device)
    apply.v = wp.empty(n, dtype=wp.vec3, device=device)
    wp.launch(applied_particles, dim=n, inputs=[apply, deltas], device=device)
    return apply.xm.numpy()[:, :3], apply.v.numpy()


def verify_behaviour(stock: dict, device, fluid_flag: int) -> list[str]:
    """Step the stock solver on three particles and list every way it differs from what the seam assumes.

    Args:
        stock: The upstream ``SolverXPBD`` methods by name (``__init__``, ``integrate_particles``,
            ``_apply_particle_deltas``, ``step``).
        device: The device to step on.
        fluid_flag: The value of :attr:`~newton.ParticleFlags.FLUID`.

    Returns:
        list[str]: One line per failed expectation; empty when upstream behaves as assumed.
    """
    from newton._src.solvers.xpbd import SolverXPBD  # noqa: PLC0415

    module = solver_module(SolverXPBD)
    failures = []
    dt = 1.0 / 60.0
    tol = 1.0e-6

    class Probe(SolverXPBD):
        pass

    for name, fn in stock.items():
        setattr(Probe, name, fn)

    def integrate(self, model, state_in, state_out, dt):
        stock["integrate_particles"](self, model, state_in, state_out, dt)
        self.probe_predicted = state_out.particle_q.numpy().copy()

    def apply(self, model, state_in, state_out, particle_deltas, dt):
        x_pred = delta_positions(self, state_in, state_out)
        x_start = substep_start_positions(self)
        if x_start is None:
            failures.append("particle_q_init is not set when the particle deltas are applied")
            return stock["_apply_particle_deltas"](self, model, state_in, state_out, particle_deltas, dt)
        if self.probe_calls == 0 and not np.array_equal(x_pred.numpy(), self.probe_predicted):
            failures.append("the first _apply_particle_deltas of a step does not apply to the predicted positions")
        x, v = _applied_by_our_formula(x_start, x_pred, particle_deltas, dt, model.particle_max_velocity, model.device)
        self.probe_calls += 1
        new_q, new_qd = stock["_apply_particle_deltas"](self, model, state_in, state_out, particle_deltas, dt)
        if not (np.allclose(new_q.numpy(), x, atol=tol) and np.allclose(new_qd.numpy(), v, atol=tol * 1.0e3)):
            failures.append(
                "_apply_particle_deltas does not give x = x_pred + delta, "
                "v = (x - particle_q_init) / dt bounded to particle_max_velocity, from the buffer "
                "_particle_delta_counter names"
            )
        return new_q, new_qd

    Probe.integrate_particles = integrate
    Probe._apply_particle_deltas = apply

    def run(mode: str):
        model = _probe_model(device, fluid_flag)
        solver = Probe(model, iterations=2)
        solver.probe_calls = 0
        s0, s1 = model.state(), model.state()
        if mode == "stock":
            solver.step(s0, s1, None, None, dt)
        else:
            with fluid_particle_contacts(module, model, all_fluid=mode == "all fluid"):
                solver.step(s0, s1, None, None, dt)
        if solver.probe_calls != 2:
            failures.append(f"_apply_particle_deltas ran {solver.probe_calls} times in a step of 2 iterations")
        return solver.probe_predicted, s1.particle_q.numpy()

    try:
        predicted, stock_q = run("stock")
        _, skip_q = run("skip fluid pairs")
        _, none_q = run("all fluid")
    except Exception as e:
        # (nothing to compare with)
        return [*dict.fromkeys(failures), f"the probe step raised {e!r}"]
    free = predicted[2]
    if not np.allclose(free, [2.0 + 0.5 * dt, 0.0, 1.0 - 9.81 * dt * dt], atol=1.0e-5):
        failures.append(f"integrate_particles predicted {free.tolist()} for a free particle")
    pushed = np.linalg.norm(stock_q[1] - stock_q[0]) - np.linalg.norm(predicted[1] - predicted[0])
    if pushed <= 1.0e-4:
        failures.append("the stock step did not push an overlapping particle pair apart")
    if not np.allclose(skip_q[:2], predicted[:2], atol=tol):
        failures.append(
            "swapping solve_particle_particle_contacts did not change the particle contacts upstream solves"
        )
    if not np.allclose(skip_q[2], stock_q[2], atol=tol):
        failures.append("with solve_particle_particle_contacts swapped a non-fluid particle stepped differently")
    if not np.allclose(none_q[:2], predicted[:2], atol=tol):
        failures.append("a model without particle_grid and particle_max_radius still solved particle contacts")
    return list(dict.fromkeys(failures))


# ---------------------------------------------------------------------------------------------------------------------
# activation


_verified_devices: set[str] = set()


def activate(xpbd_module, fluid_kwargs: dict, fluid_doc: str, make_fluid, reset_fluid, additions: dict) -> None:
    """Extend ``xpbd_module.SolverXPBD`` in place (idempotent); raise before patching anything if :func:`check_names` fails.

    Args:
        xpbd_module: The ``newton._src.solvers.xpbd`` package.
        fluid_kwargs: The ``fluid_*`` constructor keywords and their defaults.
        fluid_doc: Docstring text appended to the constructor's for those keywords.
        make_fluid: ``make_fluid(solver, model, kwargs, tuning, verify)`` sets ``solver._fluid_config`` and ``solver._fluid``
            (``None`` without fluid particles) after upstream's constructor ran.
        reset_fluid: ``reset_fluid(solver, state, world_mask, flags, fluid_source)``, after upstream's reset.
        additions: New attributes (methods, properties) of ``SolverXPBD`` by name.
    """
    cls = xpbd_module.SolverXPBD
    if getattr(cls, "_fluid_extension", False):
        return
    check_names(xpbd_module)
    module = solver_module(cls)
    stock = {name: getattr(cls, name) for name in _WRAPPED}
    inherited = tuple(name for name in _WRAPPED if name not in vars(cls))
    upstream_init, upstream_integrate = stock["__init__"], stock["integrate_particles"]
    upstream_apply, upstream_step, upstream_reset = stock["_apply_particle_deltas"], stock["step"], stock["reset"]

    @functools.wraps(upstream_init)
    def __init__(self, model, *args, **kwargs):
        fluid = {k: kwargs.pop(k) for k in fluid_kwargs if k in kwargs}
        tuning = kwargs.pop("_fluid_tuning", None)  # private: see FluidTuning
        upstream_init(self, model, *args, **kwargs)
        make_fluid(self, model, fluid, tuning, lambda: _verify_once(cls, stock, model.device))

    def integrate_particles(self, model, state_in, state_out, dt):
        upstream_integrate(self, model, state_in, state_out, dt)
        if self._fluid is not None:
            self._fluid.build_neighborhood(
                state_out.particle_q, state_in.particle_q, state_out.particle_qd, state_in.body_q
            )

    def _apply_particle_deltas(self, model, state_in, state_out, particle_deltas, dt):
        if self._fluid is not None:
            x_start = substep_start_positions(self)
            apply = None
            if x_start is not None and not state_in.requires_grad:
                apply = (x_start, dt, model.particle_max_velocity, velocities_final_after_iterations(self))
            particle_q = delta_positions(self, state_in, state_out)
            self._fluid.solve_density(particle_q, particle_deltas, apply, self.iterations)
        return upstream_apply(self, model, state_in, state_out, particle_deltas, dt)

    @functools.wraps(upstream_step)
    def step(self, state_in, state_out, control, contacts, dt, **kwargs):
        if self._fluid is None:
            return upstream_step(self, state_in, state_out, control, contacts, dt, **kwargs)
        self._fluid.contacts = contacts
        self._fluid.relax_placement(state_in)
        all_fluid = self._fluid.fluid_count == self.model.particle_count
        with fluid_particle_contacts(module, self.model, all_fluid):
            upstream_step(self, state_in, state_out, control, contacts, dt, **kwargs)
        self._fluid.finish_step(state_out, dt, substep_start_positions(self))

    def _fluid_reset(self, state, world_mask, flags, fluid_source):
        upstream_reset(self, state, world_mask, flags)
        reset_fluid(self, state, world_mask, flags, fluid_source)

    sig = inspect.signature(upstream_init)
    extra = [inspect.Parameter(k, inspect.Parameter.KEYWORD_ONLY, default=v) for k, v in fluid_kwargs.items()]
    __init__.__signature__ = sig.replace(parameters=[*sig.parameters.values(), *extra])
    __init__.__doc__ = (upstream_init.__doc__ or "") + fluid_doc

    patched = {
        "__init__": __init__,
        "integrate_particles": integrate_particles,
        "_apply_particle_deltas": _apply_particle_deltas,
        "step": step,
        "_fluid_reset": _fluid_reset,
        **additions,
    }
    for name, value in patched.items():
        setattr(cls, name, value)
    cls._fluid_stock = stock
    cls._fluid_inherited = inherited
    cls._fluid_added = tuple(n for n in patched if n not in stock)
    cls._fluid_extension = True


def deactivate(cls) -> None:
    """Give ``cls`` back its stock methods and remove everything :func:`activate` added."""
    if not getattr(cls, "_fluid_extension", False):
        return
    for name in cls._fluid_added:
        delattr(cls, name)
    for name, fn in cls._fluid_stock.items():
        if name in cls._fluid_inherited:
            delattr(cls, name)
        else:
            setattr(cls, name, fn)
    del cls._fluid_stock, cls._fluid_added, cls._fluid_inherited
    cls._fluid_extension = False


def _verify_once(cls, stock: dict, device) -> None:
    """Run :func:`verify_behaviour` on ``device`` once per process; on a mismatch deactivate and raise."""
    key = str(device)
    if key in _verified_devices:
        return
    from ....geometry import ParticleFlags  # noqa: PLC0415

    failures = verify_behaviour(stock, device, int(ParticleFlags.FLUID))
    if failures:
        deactivate(cls)
        raise _mismatch(
            "; ".join(failures) + ". The fluid extension is now inactive: SolverXPBD works as stock, without fluid_*"
        )
    _verified_devices.add(key)
