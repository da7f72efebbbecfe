# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Decision kernels of the density passes' schedule: how many passes a substep runs, decided on the device.

With ``fluid_density_tolerance`` or ``fluid_max_iterations`` > 1 the passes after a substep's (or an
iteration's) first stop once the mean compression they measure is within the tolerance. Each
decision is one block that sums the compression bins of the pass it follows
(:func:`take_compression`) and writes flags the next passes (or a conditional graph node) read.
"""

import warp as wp

from .density_constraint import COMPRESSION_BINS, COMPRESSION_SUMS, RATE_KEPT, RATE_READ
from .sph import FluidParams, SlotContent

# approximate division and square root in CUDA code (no effect on the CPU; see :mod:`.sph`)
wp.set_module_options({"fast_math": True})


@wp.func
def take_compression(bins: wp.array[float]):
    """Total compression and particle count of the compression bins (see :func:`~.density_constraint.density_passes`).

    Clears the bins for the next evaluation. Called by every thread of one block: the bins are summed
    as tiles (a tree over the block, where one thread's loop over them took about 10 us on an H100).
    """
    total = wp.tile_sum(wp.tile_load(bins, shape=COMPRESSION_BINS, offset=0))[0]
    count = wp.tile_sum(wp.tile_load(bins, shape=COMPRESSION_BINS, offset=COMPRESSION_BINS))[0]
    # (every thread has passed the sums, so every load is done)
    wp.tile_store(bins, wp.tile_zeros(shape=COMPRESSION_SUMS, dtype=float))
    return wp.vec2(total, count)


@wp.func
def compression_within_tolerance(sums: wp.vec2, tolerance: float, stop_uncompressed: int):
    """Whether a pass's mean compression (``sums`` from :func:`take_compression`) lets the passes stop.

    Nothing evaluated always stops. A tolerance of 0 stops only where nothing is compressed, and
    only with ``stop_uncompressed`` (the passes within an XPBD iteration); on the XPBD iterations
    0 means no early stop.
    """
    total = sums[0]
    count = sums[1]
    if count == 0.0:
        return True
    if tolerance > 0.0 or stop_uncompressed != 0:
        return total <= tolerance * count
    return False


@wp.kernel
def open_fluid_subpasses(
    forced: int,
    pairs: int,
    tail: int,
    # out
    loop_active: wp.array[wp.int32],
    loop_count: wp.array[wp.int32],
    tail_active: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Open an XPBD iteration's sub-passes (see :class:`SubPasses`).

    Its first ``forced`` passes correct whatever they measure; up to ``pairs`` pairs decided on the device may
    follow, and with ``tail`` a last, closing pass once every pair has corrected.
    """
    loop_active[0] = wp.where(pairs > 0, 1, 0)
    loop_count[0] = 0
    tail_active[0] = wp.where(pairs == 0, tail, 0)
    iterations_total[0] = iterations_total[0] + forced


@wp.kernel
def decide_fluid_pass_pair(
    params: wp.array[FluidParams],
    pairs: int,
    tail: int,
    # in/out
    bins: wp.array[float],
    loop_active: wp.array[wp.int32],
    correct: wp.array[wp.int32],
    loop_count: wp.array[wp.int32],
    tail_active: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Decide whether this pair of sub-passes corrects, from the compression its first pass measured.

    The pair corrects unless the mean compression is within the tolerance (or nothing is compressed), so
    an iteration stops only after an even count; the loop ends with that or after ``pairs`` pairs, and
    after the last pair (with ``tail``) the closing pass is opened. Reads and clears the pass's compression
    sums. Once the loop has ended (pairs launched outside a graph), nothing corrects. One block of
    ``COMPRESSION_BINS`` threads; the first writes the decision (every thread reads the flags before the
    sums, so before it writes them).
    """
    _, lane = wp.tid()
    if loop_active[0] == 0:
        if lane == 0:
            correct[0] = 0
        return
    sums = take_compression(bins)
    if lane != 0:
        return
    if compression_within_tolerance(sums, params[0].density_tolerance, 1):
        correct[0] = 0
        loop_active[0] = 0
        return
    correct[0] = 1
    loop_count[0] = loop_count[0] + 1
    iterations_total[0] = iterations_total[0] + 2
    if loop_count[0] >= pairs:
        loop_active[0] = 0
        tail_active[0] = tail


@wp.kernel
def open_fluid_substep_passes(
    passes: int,
    # in/out
    active: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Open a substep's density passes on the XPBD iterations: its first ``passes`` correct whatever they measure."""
    active[0] = 1
    iterations_total[0] = iterations_total[0] + passes


@wp.kernel
def decide_fluid_density_converged(
    params: wp.array[FluidParams],
    passes: int,
    stop_uncompressed: int,
    # in/out
    bins: wp.array[float],
    active: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Skip this and the substep's remaining density passes once the mean compression is within the tolerance.

    Launched before an odd pass from the third on (see :class:`IterationTolerance`): the decision holds for
    ``passes`` passes, this one and the next (one where this is the last), so a substep stops only after
    an even count; and before the closing pass of :class:`SubPasses`. ``stop_uncompressed`` as in
    :func:`compression_within_tolerance`. Reads and clears the compression sums of this pass's evaluation;
    counts the passes that go on to correct. One block of ``COMPRESSION_BINS`` threads, as
    :func:`decide_fluid_pass_pair`.
    """
    _, lane = wp.tid()
    if active[0] == 0:
        return
    sums = take_compression(bins)
    if lane != 0:
        return
    if compression_within_tolerance(sums, params[0].density_tolerance, stop_uncompressed):
        active[0] = 0
        return
    iterations_total[0] = iterations_total[0] + passes


# ---------------------------------------------------------------------------------------------------------------------
# the schedules, one per mode: each owns its device flags and launches its decisions


class FixedPasses:
    """One density pass per XPBD iteration, each correcting (no tolerance, ``fluid_max_iterations`` 1).

    The correction pass writes the positions (and velocities) SolverXPBD will apply, so the next
    iteration and the velocity pass gather nothing; on CUDA the next iteration's density pass runs
    beside upstream's application of the deltas and its next contacts.

    Args:
        fluid: The :class:`~.solver_fluid.FluidSolver` whose passes it schedules.
    """

    #: whether the passes measure the compression and decide on the device (a later pass may not correct)
    tolerance = False

    def __init__(self, fluid):
        self.fluid = fluid

    def active(self, first: bool) -> wp.array:
        """The flag this iteration's passes run under (``first``: the substep's first iteration)."""
        return self.fluid.always_active

    def surely_corrects(self, iteration: int) -> bool:
        """Whether the pass of XPBD iteration ``iteration`` (from 1) corrects whatever a decision says."""
        return True

    def decides(self) -> bool:
        """Whether this iteration's density pass measures the compression for a decision."""
        return False

    def decide(self, first: bool, active: wp.array, iterations: int) -> None:
        """Launch the decision on the iteration's density pass (none: every pass corrects)."""

    def run(self, first: bool, active: wp.array, particle_q, particle_deltas, apply, iterations: int) -> None:
        """The density pass and correction of one XPBD iteration (see :meth:`~.solver_fluid.FluidSolver.solve_density`)."""
        f = self.fluid
        if not f.evaluated_ahead:
            f.evaluate_constraint(
                active,
                track_compression=self.decides(),
                last=f.iteration == iterations,
                rate_pass=RATE_READ if first else RATE_KEPT,
            )
        f.evaluated_ahead = False
        self.decide(first, active, iterations)
        # (a pass that may be skipped writes no applied positions)
        predict = apply is not None and active is f.always_active
        # (a schedule that decides on the device does not know the last correction: a pass after the step stores)
        store = f.warm_start_on() and not self.tolerance and f.iteration == iterations
        # an odd count's last pass takes the closing step (calibration.stable_pass_bound)
        closing = f.iteration == f.closing_iteration
        f.correct(particle_deltas, active, particle_q if predict else None, apply, store_warm=store, closing=closing)
        f.warm_stored = f.warm_stored or store
        if predict:
            f.swap_slot_buffers()
            f.slot_content = SlotContent.APPLIED_WITH_VELOCITIES if apply[3] else SlotContent.APPLIED
            if f.iteration < iterations and self.surely_corrects(f.iteration + 1) and f.side_stream is not None:
                # the next iteration's density pass needs only these positions: it runs beside
                # upstream's application of the deltas and its next contacts
                with f.beside():
                    f.evaluate_constraint(active, last=f.iteration + 1 == iterations, rate_pass=RATE_KEPT)
                f.evaluated_ahead = True


class IterationTolerance(FixedPasses):
    """One density pass per XPBD iteration; they stop after an even count once the fluid meets the tolerance.

    ``fluid_density_tolerance`` > 0 with ``fluid_max_iterations`` 1: the substep's first two passes always
    correct; each odd pass from the third on measures the mean compression and skips itself and the rest
    of the substep's passes once it is within the tolerance. A substep stops only after an even count
    because an odd count at the full step keeps a negative share of the shortest waves, and still water
    hums (docs/validation.rst, "Odd pass counts"): the one odd count it may run, all of its
    ``iterations``, ends with the closing pass (:attr:`~.solver_fluid.FluidSolver.closing_iteration`).
    """

    tolerance = True

    def __init__(self, fluid):
        super().__init__(fluid)
        with wp.ScopedDevice(fluid.device):
            # cleared once a substep's density has converged
            self.substep_active = wp.ones(1, dtype=wp.int32)

    def surely_corrects(self, iteration: int) -> bool:
        return iteration <= 2

    def active(self, first: bool) -> wp.array:
        f = self.fluid
        return f.always_active if self.surely_corrects(f.iteration) else self.substep_active

    def decides(self) -> bool:
        return self.fluid.iteration >= 3 and self.fluid.iteration % 2 == 1

    def decide(self, first: bool, active: wp.array, iterations: int) -> None:
        f = self.fluid
        if first:
            wp.launch(
                open_fluid_substep_passes,
                dim=1,
                inputs=[min(2, iterations)],
                outputs=[self.substep_active, f.subiterations_total],
                device=f.device,
            )
        elif self.decides():
            wp.launch_tiled(
                decide_fluid_density_converged,
                dim=1,
                block_dim=COMPRESSION_BINS,
                inputs=[f.params, min(2, iterations - f.iteration + 1), 0],
                outputs=[f.compression_bins, active, f.subiterations_total],
                device=f.device,
            )


class SubPasses:
    """Up to ``fluid_max_iterations`` density passes per XPBD iteration, stopping after an even count within tolerance.

    Each pass's correction writes into the other slot buffer where the iteration's deltas so far put the
    particles, and the next pass goes on from there: the contacts' deltas too, which upstream solved once for
    the iteration before its passes (a pass that did not see them corrected their push out of a wall a
    second time, and still water hummed: docs/validation.rst, "Sub-passes"). An iteration's first two passes
    always correct; then pairs of passes follow while the mean compression the first of a pair measures is
    above ``fluid_density_tolerance``, so an iteration stops only after an even count (an odd count at the
    even count's step keeps a negative share of the shortest waves, and still water hums:
    docs/validation.rst, "Odd pass counts"). With an odd ``fluid_max_iterations`` a last pass, once every
    pair has corrected, closes with half the step. The count is decided on the device: inside a graph
    capture the pairs are a conditional while node; on a GPU outside one every allowed pair is launched and
    the pairs after the decision do nothing (no synchronisation); on the CPU the loop reads its flag and
    stops.
    """

    tolerance = True

    def __init__(self, fluid):
        self.fluid = fluid
        most = fluid.config.fluid_max_iterations
        #: passes of an iteration that always correct, pairs decided after them, and whether a closing pass may
        #: end it
        self.forced, self.pairs, self.tail = min(2, most), (most - 2) // 2, most % 2 == 1 and most > 2
        with wp.ScopedDevice(fluid.device):
            self.loop_active = wp.zeros(1, dtype=wp.int32)
            self.loop_count = wp.zeros(1, dtype=wp.int32)
            self.pass_corrects = wp.zeros(1, dtype=wp.int32)
            self.tail_active = wp.zeros(1, dtype=wp.int32)
        self._last_iteration = False

    def active(self, first: bool) -> wp.array:
        return self.fluid.always_active

    def run(self, first: bool, active: wp.array, particle_q, particle_deltas, apply, iterations: int) -> None:
        f = self.fluid
        self._last_iteration = f.iteration == iterations
        for k in range(self.forced):
            f.evaluate_constraint(
                f.always_active, last=self._last_iteration, rate_pass=RATE_READ if first and k == 0 else RATE_KEPT
            )
            f.correct(particle_deltas, f.always_active, particle_q, advance=True)
            f.swap_slot_buffers()
        wp.launch(
            open_fluid_subpasses,
            dim=1,
            inputs=[self.forced, self.pairs, int(self.tail)],
            outputs=[self.loop_active, self.loop_count, self.tail_active, f.subiterations_total],
            device=f.device,
        )
        if self.pairs > 0:
            if f.device.is_capturing or f.device.is_cpu:
                # a conditional while node in a graph; on the CPU the flag is read where it lies
                wp.capture_while(
                    self.loop_active, self._pass_pair, particle_q=particle_q, particle_deltas=particle_deltas
                )
            else:
                # no graph: launch every allowed pair (reading the flag would synchronise); the ones
                # after the decision do nothing
                for _ in range(self.pairs):
                    self._pass_pair(particle_q, particle_deltas)
        if self.tail:
            f.evaluate_constraint(
                self.tail_active, track_compression=True, last=self._last_iteration, rate_pass=RATE_KEPT
            )
            wp.launch_tiled(
                decide_fluid_density_converged,
                dim=1,
                block_dim=COMPRESSION_BINS,
                inputs=[f.params, 1, 1],
                outputs=[f.compression_bins, self.tail_active, f.subiterations_total],
                device=f.device,
            )
            # (nothing reads the slots' positions after an iteration's passes: the next gathers them again)
            f.correct(particle_deltas, self.tail_active, particle_q, advance=True, closing=True)

    def _pass_pair(self, particle_q: wp.array, particle_deltas: wp.array) -> None:
        # each pass's correction writes the moved positions into the other buffer, which the next pass
        # reads: the pair brings them back (a pair after the loop's decision to stop does nothing; the
        # positions after the loop are gathered again when needed)
        f = self.fluid
        start = f.current
        # (the first pass measures the walls and the compression where the last pass left the particles)
        f.evaluate_constraint(self.loop_active, track_compression=True, last=self._last_iteration, rate_pass=RATE_KEPT)
        wp.launch_tiled(
            decide_fluid_pass_pair,
            dim=1,
            block_dim=COMPRESSION_BINS,
            inputs=[f.params, self.pairs, int(self.tail)],
            outputs=[
                f.compression_bins,
                self.loop_active,
                self.pass_corrects,
                self.loop_count,
                self.tail_active,
                f.subiterations_total,
            ],
            device=f.device,
        )
        f.correct(particle_deltas, self.pass_corrects, particle_q, advance=True)
        f.current = 1 - start
        f.evaluate_constraint(self.pass_corrects, last=self._last_iteration, rate_pass=RATE_KEPT)
        f.correct(particle_deltas, self.pass_corrects, particle_q, advance=True)
        f.current = start


def density_schedule(fluid):
    """The schedule of ``fluid``'s configuration (fixed at construction)."""
    c = fluid.config
    if c.fluid_max_iterations > 1:
        return SubPasses(fluid)
    if c.fluid_density_tolerance > 0.0:
        return IterationTolerance(fluid)
    return FixedPasses(fluid)
