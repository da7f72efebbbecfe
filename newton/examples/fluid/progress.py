# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Progress of long fluid runs (examples, captures, benchmarks): a tqdm bar and a one-line summary.

On a terminal the bar updates in place; when the output is a file or a pipe it prints a line every
few seconds instead. Frames done / total, frames per second and the time left come from tqdm; the
fluid's mean density error is read from the solver at each refresh (``fluid_diagnostics``, which
synchronises with the device, so it is read only as often as the line is redrawn, never per step).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from tqdm import tqdm

# seconds between redraws (and density reads) on a terminal, and between printed lines otherwise
TERMINAL_INTERVAL = 1.0
LOG_INTERVAL = 5.0


class _LineStream:
    """A file-like target that turns tqdm's in-place redraws into one line each (for logs and pipes)."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text: str) -> None:
        line = text.replace("\r", "").strip("\n")
        if line.strip():
            self._stream.write(line + "\n")

    def flush(self) -> None:
        self._stream.flush()


def _is_terminal(stream) -> bool:
    isatty = getattr(stream, "isatty", None)
    return bool(isatty and isatty())


class FluidProgress:
    """A progress line for ``total`` frames of a fluid run, and a summary line when it closes.

    Args:
        total: Frames the run will take (``None``: unknown, no time left is shown).
        description: What runs (the example or benchmark name), shown before the bar.
        solver: A :class:`~newton.solvers.SolverXPBD` with fluid, whose density error is shown; ``None``: not shown.
        state: Callable returning the state to measure (the example's current ``state_0``).
        particles: Particle count named in the summary.
        quiet: Print nothing at all.
        unit: What is counted (``"frame"``; a benchmark's sweep counts ``"run"``).
        stream: Where the bar goes (default ``sys.stderr``); the summary goes to ``sys.stdout``.
    """

    def __init__(
        self,
        total: int | None,
        description: str,
        solver=None,
        state=None,
        particles: int | None = None,
        quiet: bool = False,
        unit: str = "frame",
        stream=None,
    ):
        self.description = description
        self.solver = solver
        self.state = state
        self.particles = particles
        self.quiet = quiet
        self.unit = unit
        self.frames = 0
        self.density_error = None
        self._start = time.perf_counter()
        self._last_read = -np.inf
        self._bar = None
        if quiet:
            return
        stream = sys.stderr if stream is None else stream
        terminal = _is_terminal(stream)
        self._interval = TERMINAL_INTERVAL if terminal else LOG_INTERVAL
        self._bar = tqdm(
            total=total,
            desc=description,
            unit=unit,
            file=stream if terminal else _LineStream(stream),
            mininterval=self._interval,
            maxinterval=self._interval if terminal else 1.0e9,
            dynamic_ncols=terminal,
            ncols=None if terminal else 120,
            leave=True,
        )

    def _read_density(self) -> None:
        if self.solver is None or self.state is None:
            return
        stats = self.solver.fluid_diagnostics(self.state())
        if stats:
            self.density_error = stats["mean_abs_density_error"]
            self._bar.set_postfix_str(f"density error {100.0 * self.density_error:.2f} %", refresh=False)

    def update(self, frames: int = 1) -> None:
        """Count ``frames`` more frames done (reads the density error only when the line is redrawn)."""
        self.frames += frames
        if self._bar is None:
            return
        now = time.perf_counter()
        if now - self._last_read >= self._interval:
            self._last_read = now
            self._read_density()
        self._bar.update(frames)

    def close(self) -> str:
        """End the bar and print the one-line summary (unless quiet); returns the summary."""
        wall = time.perf_counter() - self._start
        if self.solver is not None and self.state is not None:
            stats = self.solver.fluid_diagnostics(self.state())
            if stats:
                self.density_error = stats["mean_abs_density_error"]
        rate = self.frames / wall if wall > 0.0 else 0.0
        unit = self.unit
        parts = [f"{self.description}: {self.frames} {unit}s in {wall:.1f} s ({rate:.2f} {unit}s/s)"]
        if self.particles is not None:
            parts.append(f"{self.particles:,} particles")
        if self.density_error is not None:
            parts.append(f"mean density error {100.0 * self.density_error:.2f} %")
        lost = self.lost_particles()
        if lost is not None:
            parts.append(f"{lost} particles lost")
        summary = ", ".join(parts)
        if self._bar is not None:
            self._bar.close()
            self._bar = None
            print(summary, flush=True)
        return summary

    def lost_particles(self) -> int | None:
        """Fluid particles that ended inactive or with a non-finite position (``None`` without a solver)."""
        if self.solver is None or self.state is None:
            return None
        import newton  # noqa: PLC0415

        model = self.solver.model
        flags = model.particle_flags.numpy()
        fluid = (flags & int(newton.ParticleFlags.FLUID)) != 0
        q = self.state().particle_q.numpy()
        gone = ((flags & int(newton.ParticleFlags.ACTIVE)) == 0) | ~np.isfinite(q).all(axis=1)
        return int(np.count_nonzero(fluid & gone))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def track(iterable, description: str, total: int | None = None, quiet: bool = False, unit: str = "run"):
    """Iterate over ``iterable`` with a progress line and a closing summary (for benchmark loops)."""
    if total is None and hasattr(iterable, "__len__"):
        total = len(iterable)
    progress = FluidProgress(total, description, quiet=quiet, unit=unit)
    try:
        for item in iterable:
            yield item
            progress.update()
    finally:
        progress.close()
