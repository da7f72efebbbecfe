# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""A benchmark's frame: its substeps of collision and solver step, one captured CUDA graph per frame on a GPU."""

from __future__ import annotations

import warp as wp


class Frames:
    """Steps ``states[0]`` by one 60 Hz frame of ``substeps`` substeps per call.

    Args:
        solver: The solver.
        pipeline: The collision pipeline (``collide`` every substep).
        contacts: Its contacts.
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


def add_solver_arguments(parser, warm_start: float = 0.0, warm_start_help: str = "fluid_warm_start") -> None:
    """The arguments every exact-answer benchmark takes for the solver, the device and its JSON record."""
    parser.add_argument("--substeps", type=int, default=8)
    parser.add_argument("--iterations", type=int, default=2)
    parser.add_argument("--viscosity", type=float, default=0.0, help="fluid_viscosity")
    parser.add_argument(
        "--nonaffine-damping", type=float, default=None, help="fluid_nonaffine_damping (default: the solver's)"
    )
    parser.add_argument("--warm-start", type=float, default=warm_start, help=warm_start_help)
    parser.add_argument(
        "--smoothing-ratio", type=float, default=None, help="fluid_smoothing_length / spacing (default: the solver's)"
    )
    parser.add_argument("--device", default=None)
    parser.add_argument("--json", default=None)


def solver_keywords(args, spacing: float, damping: bool = True) -> dict:
    """``SolverXPBD`` keywords from :func:`add_solver_arguments`' arguments (``damping``: pass the damping too)."""
    keywords = {
        "iterations": args.iterations,
        "fluid_rest_distance": spacing,
        "fluid_viscosity": args.viscosity,
        "fluid_warm_start": args.warm_start,
    }
    if args.smoothing_ratio is not None:
        keywords["fluid_smoothing_length"] = args.smoothing_ratio * spacing
    if damping and args.nonaffine_damping is not None:
        keywords["fluid_nonaffine_damping"] = args.nonaffine_damping
    return keywords


def run_on_device(run, args):
    """``run(args, device)`` on ``args.device`` with Warp's messages off; returns the device and its result."""
    wp.config.quiet = True
    device = wp.get_device(args.device)
    with wp.ScopedDevice(device):
        return device, run(args, device)
