# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""An exclusive prefix sum of ``int32`` counts that allocates nothing when it runs.

``wp.utils.array_scan`` takes its temporary storage from the device's allocator at every call, so it
cannot run inside a CUDA conditional node (a graph's ``capture_while`` or ``capture_if`` body may not
allocate). :class:`ExclusiveScan` keeps its own storage, made at construction for one array length:
tiles of :data:`SCAN_TILE` counts are summed within a block, the tiles' totals are summed the same
way level by level until one tile holds them all, and each level's offsets are then added back
down. ``offsets[i] = sum(counts[:i])``.
"""

import warp as wp

#: counts summed by one block
SCAN_TILE = 1024
SCAN_BLOCK_DIM = 256


@wp.kernel
def scan_count_tiles(
    counts: wp.array[wp.int32],
    # outputs
    offsets: wp.array[wp.int32],
    tile_totals: wp.array[wp.int32],
):
    """``offsets`` of each tile's counts within the tile, and each tile's total."""
    block = wp.tid()
    start = block * SCAN_TILE
    c = wp.tile_load(counts, shape=SCAN_TILE, offset=start)
    # (counts past the end read as zero and their offsets are not stored)
    wp.tile_store(offsets, wp.tile_scan_inclusive(c) - c, offset=start)
    wp.tile_store(tile_totals, wp.tile_sum(c), offset=block)


@wp.kernel
def add_tile_offsets(
    tile_offsets: wp.array[wp.int32],
    # outputs
    offsets: wp.array[wp.int32],
):
    """Each offset plus the counts of the tiles before its own."""
    i = wp.tid()
    offsets[i] = offsets[i] + tile_offsets[i // SCAN_TILE]


class ExclusiveScan:
    """``offsets[i] = sum(counts[:i])`` over arrays of one length, with no allocation at :meth:`run`.

    Args:
        length: Length of the count and offset arrays (>= 1).
        device: Device of the arrays.
    """

    def __init__(self, length: int, device):
        self.length = int(length)
        #: the counts summed at each level above the first: the tiles' totals, then their tiles' totals, ...
        self.levels = []
        n = self.length
        with wp.ScopedDevice(device):
            while True:
                n = (n + SCAN_TILE - 1) // SCAN_TILE
                self.levels.append(wp.zeros(n, dtype=wp.int32))
                if n == 1:
                    break

    def run(self, counts: wp.array, offsets: wp.array) -> None:
        """Write the exclusive prefix sum of ``counts`` to ``offsets`` (both of the constructed length)."""
        device, levels = offsets.device, self.levels
        # up: each level's offsets within its tiles, and the tiles' totals as the next level (summed in place;
        # the last level, one entry, is the grand total)
        for k, totals in enumerate(levels):
            values, sums = (counts, offsets) if k == 0 else (levels[k - 1], levels[k - 1])
            wp.launch_tiled(
                scan_count_tiles,
                dim=[totals.shape[0]],
                inputs=[values],
                outputs=[sums, totals],
                block_dim=SCAN_BLOCK_DIM,
                device=device,
            )
        # down: the level below the grand total is one tile, complete; every level under it adds its
        # tiles' offsets from the level above
        for k in range(len(levels) - 3, -1, -1):
            wp.launch(
                add_tile_offsets, dim=levels[k].shape[0], inputs=[levels[k + 1]], outputs=[levels[k]], device=device
            )
        if len(levels) > 1:
            wp.launch(add_tile_offsets, dim=self.length, inputs=[levels[0]], outputs=[offsets], device=device)
