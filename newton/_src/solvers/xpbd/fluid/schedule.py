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
def decide_after_first_fluid_pass(
    params: wp.array[FluidParams],
    more: int,
    # in/out
    bins: wp.array[float],
    go_on: wp.array[wp.int32],
    loop_count: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Whether sub-passes follow an XPBD iteration's first density pass, which always corrects.

    The first pass corrects whatever the tolerance says: the mean counts the under-dense surface as 0,
    so a small or splashing fluid meets any tolerance while some of its particles are compressed.
    Passes follow while its mean compression, measured before its correction, is not within the
    tolerance (the rule of the later passes' decisions: :func:`compression_within_tolerance`) and
    ``more`` passes are allowed. Counts the first pass, opens the loop's count, and reads and clears the
    pass's compression sums. One block of ``COMPRESSION_BINS`` threads.
    """
    _, lane = wp.tid()
    sums = take_compression(bins)
    if lane != 0:
        return
    iterations_total[0] = iterations_total[0] + 1
    loop_count[0] = 0
    if more > 0 and not compression_within_tolerance(sums, params[0].density_tolerance, 1):
        go_on[0] = 1
    else:
        go_on[0] = 0


@wp.kernel
def decide_fluid_subiteration(
    params: wp.array[FluidParams],
    max_iterations: int,
    # in/out
    bins: wp.array[float],
    loop_active: wp.array[wp.int32],
    correct: wp.array[wp.int32],
    loop_count: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Decide whether this density pass (after the iteration's first) corrects and whether another one follows.

    It corrects unless the mean compression it measured is within the tolerance (or nothing is
    compressed); the loop ends with that or after ``max_iterations`` corrections in the loop. Reads and clears
    the pass's compression sums. Once the loop has ended (passes launched outside a graph), nothing
    corrects. One block of ``COMPRESSION_BINS`` threads; the first writes the decision (every thread
    reads the flags before the sums, so before it writes them).
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
    iterations_total[0] = iterations_total[0] + 1
    if loop_count[0] >= max_iterations:
        loop_active[0] = 0


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
    # in/out
    bins: wp.array[float],
    active: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Skip this and the substep's remaining density passes once the mean compression is within the tolerance.

    Launched before an odd pass from the third on (see :class:`IterationTolerance`): the decision holds for
    ``passes`` passes, this one and the next (one where this is the last), so a substep stops only after
    an even count. Reads and clears the compression sums of this pass's evaluation; counts the passes
    that go on to correct. One block of ``COMPRESSION_BINS`` threads, as :func:`decide_fluid_subiteration`.
    """
    _, lane = wp.tid()
    if active[0] == 0:
        return
    sums = take_compression(bins)
    if lane != 0:
        return
    if compression_within_tolerance(sums, params[0].density_tolerance, 0):
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
                inputs=[f.params, min(2, iterations - f.iteration + 1)],
                outputs=[f.compression_bins, active, f.subiterations_total],
                device=f.device,
            )


class SubPasses:
    """Up to ``fluid_max_iterations`` density passes per XPBD iteration, stopping once the fluid meets the tolerance.

    The iteration's first pass corrects and writes its moved positions into the other slot buffer,
    where the loop's passes go on while the mean compression they measure is above
    ``fluid_density_tolerance``. The count is decided on the device: inside a graph capture the loop is
    a conditional while node; on a GPU outside one every allowed pass is launched and the passes after
    the decision do nothing (no synchronisation); on the CPU the loop reads its flag and stops.
    """

    tolerance = True

    def __init__(self, fluid):
        self.fluid = fluid
        with wp.ScopedDevice(fluid.device):
            self.loop_active = wp.zeros(1, dtype=wp.int32)
            self.loop_count = wp.zeros(1, dtype=wp.int32)
            self.pass_corrects = wp.zeros(1, dtype=wp.int32)
        self._last_iteration = False

    def active(self, first: bool) -> wp.array:
        return self.fluid.always_active

    def run(self, first: bool, active: wp.array, particle_q, particle_deltas, apply, iterations: int) -> None:
        f = self.fluid
        more = f.config.fluid_max_iterations - 1
        self._last_iteration = f.iteration == iterations
        f.evaluate_constraint(
            f.always_active,
            track_compression=True,
            last=self._last_iteration,
            rate_pass=RATE_READ if first else RATE_KEPT,
        )
        wp.launch_tiled(
            decide_after_first_fluid_pass,
            dim=1,
            block_dim=COMPRESSION_BINS,
            inputs=[f.params, more],
            outputs=[f.compression_bins, self.loop_active, self.loop_count, f.subiterations_total],
            device=f.device,
        )
        f.correct(particle_deltas, f.always_active, advance=True)
        f.swap_slot_buffers()
        if f.device.is_capturing or f.device.is_cpu:
            # a conditional while node in a graph; on the CPU the flag is read where it lies
            wp.capture_while(self.loop_active, self._pass_pair, particle_deltas=particle_deltas)
        else:
            # no graph: launch every allowed pass (reading the flag would synchronise); the ones
            # after the decision do nothing
            for _ in range(f.config.fluid_max_iterations // 2):
                self._pass_pair(particle_deltas)

    def _pass_pair(self, particle_deltas: wp.array) -> None:
        # each pass's correction writes the moved positions into the other buffer, which the next pass
        # reads: two passes per trip of the loop bring them back (a second pass after the loop's
        # decision to stop does nothing; the positions after the loop are gathered again when needed)
        f = self.fluid
        start = f.current
        for source in (start, 1 - start):
            f.current = source
            self._pass(particle_deltas)
        f.current = start

    def _pass(self, particle_deltas: wp.array) -> None:
        f = self.fluid
        # (the density pass measures the walls where the last pass left the particles)
        f.evaluate_constraint(self.loop_active, track_compression=True, last=self._last_iteration, rate_pass=RATE_KEPT)
        wp.launch_tiled(
            decide_fluid_subiteration,
            dim=1,
            block_dim=COMPRESSION_BINS,
            inputs=[f.params, f.config.fluid_max_iterations - 1],
            outputs=[f.compression_bins, self.loop_active, self.pass_corrects, self.loop_count, f.subiterations_total],
            device=f.device,
        )
        f.correct(particle_deltas, self.pass_corrects, advance=True)


def density_schedule(fluid):
    """The schedule of ``fluid``'s configuration (fixed at construction)."""
    c = fluid.config
    if c.fluid_max_iterations > 1:
        return SubPasses(fluid)
    if c.fluid_density_tolerance > 0.0:
        return IterationTolerance(fluid)
    return FixedPasses(fluid)
