# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""What the benchmarks share: the solver's keywords as flags, and a frame of substeps (a CUDA graph on a GPU)."""

from __future__ import annotations

import argparse

import warp as wp

import newton
from newton._src.solvers.xpbd.fluid.calibration import DENSITY_KERNELS
from newton._src.solvers.xpbd.fluid.config import FLUID_KEYWORDS


class Frames:
    """Steps ``states[0]`` by one 60 Hz frame of ``substeps`` substeps per call.

    Args:
        solver: The solver.
        pipeline: The collision pipeline (``collide`` every substep), or ``None`` for a scene without contacts.
        contacts: Its contacts (``None`` without a pipeline).
        states: Two states; ``states[0]`` holds the current one after every call.
        substeps: Substeps per frame.
        device: The device; on CUDA with an even substep count (the states end where they started) the
            frame is captured once and replayed.
    """

    def __init__(self, solver, pipeline, contacts, states, substeps: int, device):
        self.solver, self.pipeline, self.contacts, self.states = solver, pipeline, contacts, states
        self.substeps, self.device = substeps, device
        self.dt = 1.0 / 60.0 / substeps
        self.graph = None

    def _substeps(self) -> None:
        s = self.states
        for _ in range(self.substeps):
            if self.pipeline is not None:
                self.pipeline.collide(s[0], self.contacts)
            self.solver.step(s[0], s[1], None, self.contacts, self.dt)
            s[0], s[1] = s[1], s[0]

    def __call__(self) -> None:
        if not self.device.is_cuda or self.substeps % 2:
            self._substeps()
            return
        if self.graph is None:
            with wp.ScopedCapture(self.device) as capture:
                self._substeps()
            self.graph = capture.graph
        wp.capture_launch(self.graph)


#: the solver's ``fluid_*`` keywords (and ``max_diffuse_particles``) with their defaults
SOLVER_KEYWORDS = FLUID_KEYWORDS
# keywords a scene sets from its spacing, not from a flag
_SCENE_KEYWORDS = ("fluid_rest_distance", "fluid_smoothing_length")
# the keywords that take one of a few names
_CHOICES = {"fluid_density_kernel": DENSITY_KERNELS}


def _dest(keyword: str) -> str:
    """The ``argparse`` destination of a solver keyword's flag: ``fluid_density_tolerance`` is ``density_tolerance``."""
    return keyword.removeprefix("fluid_")


def solver_flag(keyword: str) -> str:
    """The command-line flag of a solver keyword: ``fluid_density_tolerance`` is ``--density-tolerance``."""
    return "--" + _dest(keyword).replace("_", "-")


def add_solver_arguments(
    parser, defaults: dict | None = None, substeps: int = 8, iterations: int = 2, step_flags: bool = True
) -> None:
    """Every solver keyword as a flag named after it (:func:`solver_flag`), so the names match in every benchmark.

    A flag left unset passes nothing: the solver's default applies. Besides them: ``--substeps``,
    ``--iterations`` (unless ``step_flags`` is off), ``--smoothing-ratio`` (``fluid_smoothing_length`` over
    the scene's spacing), ``--device`` and ``--json``.

    Args:
        parser: The ``argparse.ArgumentParser`` to add them to.
        defaults: The benchmark's own defaults by keyword (for example ``{"fluid_cohesion": 1.0}``).
        substeps: Default substeps per 1/60 s frame.
        iterations: Default XPBD iterations per substep.
        step_flags: Whether to add ``--substeps`` and ``--iterations`` (a sweep over them adds its own).
    """
    defaults = defaults or {}
    unknown = set(defaults) - set(SOLVER_KEYWORDS)
    if unknown:
        raise ValueError(f"defaults names {sorted(unknown)}, which are not solver keywords")
    group = parser.add_argument_group("solver", "SolverXPBD's keywords (unset: the solver's default)")
    if step_flags:
        group.add_argument("--substeps", type=int, default=substeps, help="substeps per 1/60 s frame")
        group.add_argument("--iterations", type=int, default=iterations, help="XPBD iterations per substep")
    group.add_argument(
        "--smoothing-ratio",
        type=float,
        default=None,
        help="the smoothing length over the scene's spacing (sets fluid_smoothing_length)",
    )
    group.add_argument(
        "--soft-contact-relaxation",
        type=float,
        default=None,
        help="soft_contact_relaxation: upstream's relaxation of particle-shape contacts (its default 0.9)",
    )
    for name, default in SOLVER_KEYWORDS.items():
        if name in _SCENE_KEYWORDS:
            continue
        value = defaults.get(name)
        shown = f" (default {value})" if value is not None else ""
        if isinstance(default, bool):
            group.add_argument(
                solver_flag(name), action=argparse.BooleanOptionalAction, default=value, help=name + shown
            )
        elif name in _CHOICES:
            group.add_argument(solver_flag(name), choices=_CHOICES[name], default=value, help=name + shown)
        else:
            kind = int if isinstance(default, int) else float
            group.add_argument(solver_flag(name), type=kind, default=value, help=name + shown)
    parser.add_argument("--device", default=None)
    parser.add_argument("--json", default=None)


def solver_keywords(args, spacing: float, damping: bool = True, iterations: int | None = None) -> dict:
    """``SolverXPBD`` keywords from :func:`add_solver_arguments`' flags: the ones set, and the scene's spacing.

    Args:
        args: The parsed arguments.
        spacing: The scene's particle spacing [m] (``fluid_rest_distance``).
        damping: Whether to pass ``fluid_nonaffine_damping`` (a benchmark that settles with its own damping first
            sets it later).
        iterations: XPBD iterations per substep, for a sweep over them; default ``args.iterations``.
    """
    keywords = {"iterations": args.iterations if iterations is None else iterations, "fluid_rest_distance": spacing}
    if args.smoothing_ratio is not None:
        keywords["fluid_smoothing_length"] = args.smoothing_ratio * spacing
    if args.soft_contact_relaxation is not None:
        keywords["soft_contact_relaxation"] = args.soft_contact_relaxation
    for name in SOLVER_KEYWORDS:
        if name in _SCENE_KEYWORDS:
            continue
        value = getattr(args, _dest(name))
        if value is not None:
            keywords[name] = value
    if not damping:
        keywords.pop("fluid_nonaffine_damping", None)
    return keywords


def solver_record(solver) -> dict:
    """The solver's settings for a JSON record: its iterations and every fluid keyword's value in use."""
    return {
        "iterations": solver.iterations,
        "soft_contact_relaxation": solver.soft_contact_relaxation,
        **{name: getattr(solver, name) for name in SOLVER_KEYWORDS},
    }


def contact_frames(model, args, spacing: float, device, damping: bool = True) -> tuple:
    """The solver at ``args``' keywords and :class:`Frames` stepping ``model`` with contacts every substep.

    The collision pipeline finds particle-shape contacts within half a ``spacing`` [m] (room for two per
    particle). ``damping`` as in :func:`solver_keywords`. Returns ``(solver, frames)``;
    ``frames.states[0]`` holds the current state.
    """
    solver = newton.solvers.SolverXPBD(model, **solver_keywords(args, spacing, damping=damping))
    pipeline = newton.CollisionPipeline(
        model, soft_contact_max=2 * model.particle_count, soft_contact_gap=0.5 * spacing
    )
    states = [model.state(), model.state()]
    return solver, Frames(solver, pipeline, pipeline.contacts(), states, args.substeps, wp.get_device(device))


def run_on_device(run, args):
    """``run(args, device)`` on ``args.device`` with Warp's messages off; returns the device and its result."""
    wp.config.quiet = True
    device = wp.get_device(args.device)
    with wp.ScopedDevice(device):
        return device, run(args, device)
