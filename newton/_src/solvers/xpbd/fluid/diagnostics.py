# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The fluid's statistics at a state, and the warnings of what happened between two reports."""

from __future__ import annotations

import math
import warnings

import numpy as np
import warp as wp

from .density_constraint import COMPRESSION_BINS, PEAK_COMPRESSION
from .placement import EAGER_RELAXATION_ROUNDS, PLACEMENT_COMPRESSION, PLACEMENT_TOLERANCE, RELAXATION_ROUNDS
from .sph import FluidParams, FluidSlots

#: mean compression max(rho/rho0 - 1, 0) above which :meth:`FluidSolver.diagnostics` warns that the density
#: solve does not hold the fluid (healthy runs stay below 3 %, docs/archive/validation_notebook.md "Where the method fails")
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


class FluidReports:
    """Device counters of what happened to the fluid between two reports, and the warnings that report them.

    The kernels count on the device (no synchronisation in the step); :meth:`FluidSolver.diagnostics
    <.solver_fluid.FluidSolver.diagnostics>` reads them, warns once per growth, and clears what is per
    report. Allocates on the current device.

    Args:
        particle_count: Particles of the model (the size of :attr:`particle_density`).
    """

    def __init__(self, particle_count: int):
        #: fluid particles recovered from non-finite values, in all (one int32)
        self.nonfinite_count = wp.zeros(1, dtype=wp.int32)
        #: particle substeps that ended faster than one rest distance per substep, in all (one int32)
        self.fast_count = wp.zeros(1, dtype=wp.int32)
        #: particles past PEAK_COMPRESSION in a substep's last density pass, and their peak, per bin
        #: (see :func:`~.density_constraint.density_passes`)
        self.peaks = wp.zeros(2 * COMPRESSION_BINS, dtype=float)
        #: density of every particle at the state of the last summary [kg/m^3] (0 for non-fluid)
        self.particle_density = wp.zeros(particle_count, dtype=float)
        self.summary = wp.zeros(_SUMMARY_SIZE, dtype=float)
        #: fluid particles placed past PLACEMENT_COMPRESSION (0), their largest compression (1) and the worlds
        #: left packed by the relaxation's last round (2), since the last report (see :mod:`.placement`)
        self.overpacked = wp.zeros(3, dtype=float)
        self._fast_reported = 0
        self._nonfinite_reported = 0
        self._compression_reported = False

    def summarize(self, params, slots, density, candidate_count) -> np.ndarray:
        """The :data:`_SUMMARY_SIZE` sums of :func:`summarize_fluid_density` over the slots (synchronises)."""
        self.summary.assign(np.array(_SUMMARY_INIT, dtype=np.float32))
        wp.launch(
            summarize_fluid_density,
            dim=slots.particle.shape[0],
            inputs=[params, slots, density, candidate_count],
            outputs=[self.particle_density, self.summary],
            device=self.summary.device,
        )
        return self.summary.numpy().astype(np.float64)

    def report_fast_particles(self, max_displacement: float, continuous_collision: bool) -> int:
        """Particle substeps that ended faster than one rest distance per substep; warns when they grew since last."""
        count = int(self.fast_count.numpy()[0])
        if count > self._fast_reported:
            limit = max_displacement
            if math.isfinite(limit):
                action = f"they were slowed to fluid_max_displacement={limit:g} rest distances per substep"
            elif continuous_collision:
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

    def report_peaks(self) -> tuple[int, float]:
        """Particle substeps compressed past ``PEAK_COMPRESSION`` since the last report, and their peak; warns."""
        v = self.peaks.numpy()
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
            self.peaks.zero_()
        return count, peak

    def report_overpacked(self) -> int:
        """Fluid particles placed over-packed since the last report, which the step moved apart; warns."""
        v = self.overpacked.numpy()
        count, peak, unfinished = int(v[0]), float(v[1]), int(v[2])
        if count:
            outcome = (
                f"to within {100.0 * PLACEMENT_TOLERANCE:.0f} % of rest density"
                if unfinished == 0
                else f"but {unfinished} world(s) were still packed past {100.0 * PLACEMENT_TOLERANCE:.0f} % after "
                f"its rounds ({RELAXATION_ROUNDS}; {EAGER_RELAXATION_ROUNDS} in a CUDA step without a graph where the "
                "driver has no conditional graph nodes; the rest springs apart with velocity)"
            )
            warnings.warn(
                f"{count} fluid particles were placed more than {100.0 * PLACEMENT_COMPRESSION:.0f} % above rest "
                f"density (peak {100.0 * peak:.0f} %: an over-packed start, closer than the rest spacing or "
                "overlapping): the step after their placement moved their worlds' fluid apart, positions only "
                f"(no velocity), {outcome}",
                RuntimeWarning,
                stacklevel=3,
            )
            self.overpacked.zero_()
        return count

    def report_recoveries(self) -> int:
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

    def report_dropped_contacts(self, contacts) -> int:
        """Particle-shape contacts the last collision found beyond its buffer (dropped); warns when there were any."""
        c = contacts
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

    def report_compression(self, mean: float, peak: float) -> None:
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
