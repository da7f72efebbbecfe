# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Decision kernels of the density passes' schedule: how many passes a substep runs, decided on the device.

With ``fluid_density_tolerance`` or ``fluid_max_iterations`` > 1 the passes after a substep's (or an
iteration's) first stop once the mean compression they measure is within the tolerance. Each
decision is one block that sums the compression bins of the pass it follows
(:func:`take_compression`) and writes flags the next passes (or a conditional graph node) read.
"""

import warp as wp

from .density_constraint import COMPRESSION_BINS, COMPRESSION_SUMS
from .sph import FluidParams

# approximate division and square root in CUDA code (no effect on the CPU; see :mod:`.sph`)
wp.set_module_options({"fast_math": True})


@wp.func
def take_compression(bins: wp.array[float]):
    """Total compression and particle count of the compression bins (see :func:`compute_fluid_density_lambda`).

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
    stop_uncompressed: int,
    # in/out
    bins: wp.array[float],
    go_on: wp.array[wp.int32],
    loop_count: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Whether density passes follow the first one, which always corrects, from the compression it measured.

    The first pass of a substep (of each XPBD iteration with sub-passes) corrects whatever the
    tolerance says: the mean counts the under-dense surface as 0, so a small or splashing fluid meets
    any tolerance while some of its particles are compressed. Passes follow while its mean
    compression, measured before its correction, is not within the tolerance (the rule of the later
    passes' decisions: :func:`compression_within_tolerance`) and ``more`` passes are allowed. Counts the first pass, opens the loop's count, and
    reads and clears the pass's compression sums. One block of ``COMPRESSION_BINS`` threads.
    """
    _, lane = wp.tid()
    sums = take_compression(bins)
    if lane != 0:
        return
    iterations_total[0] = iterations_total[0] + 1
    loop_count[0] = 0
    if more > 0 and not compression_within_tolerance(sums, params[0].density_tolerance, stop_uncompressed):
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
def decide_fluid_density_converged(
    params: wp.array[FluidParams],
    # in/out
    bins: wp.array[float],
    active: wp.array[wp.int32],
    iterations_total: wp.array[wp.int32],
):
    """Skip this and the substep's remaining density passes once the mean compression is within the tolerance.

    Not launched for the substep's first pass (see :func:`decide_after_first_fluid_pass`). Reads and clears the compression sums of this pass's evaluation; counts the passes that go on
    to correct. One block of ``COMPRESSION_BINS`` threads, as :func:`decide_fluid_subiteration`.
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
    iterations_total[0] = iterations_total[0] + 1
