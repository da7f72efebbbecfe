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
