# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Fluid neighbourhood search: sort fluid particles by (world, cell) and build per-slot neighbour lists.

Once per substep, after prediction:

1. every fluid particle gets a key: its world's block of a table of ``2^bits`` entries, and in it
   the Morton code of its cell (cell edge = smoothing length ``h``); inactive or non-finite
   particles get the sentinel ``2^bits`` and sort last;
2. the keys are counting-sorted: particles are counted per table entry as their keys are computed
   (an atomic add, whose return value is the particle's rank in its entry), a prefix sum over
   the table gives each entry's first slot, every particle goes to its entry's first slot plus
   its rank (clearing its entry's count for the next build, so the table needs no clearing pass),
   and each entry's slots (but the left-out particles') are then put in fluid-index order (the
   ranks arrive in any order on a GPU), so particles of one cell of one world are contiguous and
   the order is the same on every run; an entry's slots run from its first slot to the next
   entry's (:func:`fluid_cell_range`; an empty entry has none);
3. positions, masses and worlds are gathered into slot order (by the pass that orders the
   entries); each slot then scans the 27 cells around it and keeps the slots of the same world
   closer than ``h``, in up to three threads that each list a share of the cells
   (:func:`scan_lanes`).

Because every world has its own block of the table, worlds that overlap in space (``replicate``
with no spacing) never share an entry: each particle only scans candidates of its own world.
A world's block has at least 2^6 entries, so the Morton code wraps after at least 4 cells on
every axis: the 27 scanned cells always have distinct entries (no neighbour is listed twice),
and a particle of an aliased cell lies at least 3 h away and fails the distance test. So
the scan needs neither a world nor a cell check per candidate.

The counting sort replaced Warp's radix sort: at 100k particles on an H100 the radix sort of the
19-bit keys took 52 us per substep (about 36 us of it fixed cost; ``benchmarks/radix_sort.py``),
and the counting sort (three launches and a prefix sum) makes a frame of the 100k dam break
0.15 ms faster, 2.80 against 2.95 ms (docs/archive/performance_notebook.md).

The CUDA code compiles with fast math (approximate division and square root; Warp ignores the
option on the CPU): the fluid passes' time at up to a few hundred thousand particles is one
thread's chain of dependent steps, and exact divisions and roots lengthen it (docs/archive/performance_notebook.md,
"The floor").
"""

import numpy as np
import warp as wp

from ....geometry import ParticleFlags
from .prefix_sum import ExclusiveScan
from .sph import MAX_DISPLACEMENT_OFF, FluidParams, FluidSlots
from .walls import WALL_CONTACTS_PER_SLOT, FluidWallContacts, list_wall_contact

# approximate division and square root in CUDA code (no effect on the CPU; see the module notes)
wp.set_module_options({"fast_math": True})

# sentinel world index of a slot with no particle; real world indices are >= -1
_NO_WORLD = -2
# threads per particle in the scan of the full neighbourhood (each lists a part of the 27 cells);
# threads an SM of a CUDA device keeps resident (2048 on every architecture Warp supports)
_THREADS_PER_SM = 2048


@wp.func
def spread_bits_by_3(v: int):
    """Spread the low 10 bits of ``v`` so that bit k lands on bit 3k."""
    x = wp.uint32(v) & wp.uint32(0x3FF)
    x = (x | (x << wp.uint32(16))) & wp.uint32(0x030000FF)
    x = (x | (x << wp.uint32(8))) & wp.uint32(0x0300F00F)
    x = (x | (x << wp.uint32(4))) & wp.uint32(0x030C30C3)
    x = (x | (x << wp.uint32(2))) & wp.uint32(0x09249249)
    return x


@wp.func
def fluid_cell_hash(cx: int, cy: int, cz: int, world: int, cell_bits: int):
    """Table entry of a cell: the world's block of the table, then the cell's Morton code in it.

    Each world (``-1``, the global one, included) owns ``2^cell_bits`` consecutive entries, so
    worlds never share an entry and the sort groups particles by world. Morton order keeps cells
    that are close in space close in the sorted arrays, so neighbour reads of one warp share cache
    lines. The code wraps periodically within a world's block; cells that alias are at least 4
    cells apart on some axis, so the distance test of the neighbour scan tells them apart.
    """
    code = spread_bits_by_3(cx) | (spread_bits_by_3(cy) << wp.uint32(1)) | (spread_bits_by_3(cz) << wp.uint32(2))
    cell = wp.int32(code & wp.uint32((1 << cell_bits) - 1))
    return ((world + 1) << cell_bits) | cell


@wp.func
def fluid_cell(x: wp.vec3, inv_cell: float):
    return wp.vec3i(
        wp.int32(wp.floor(x[0] * inv_cell)), wp.int32(wp.floor(x[1] * inv_cell)), wp.int32(wp.floor(x[2] * inv_cell))
    )


@wp.func
def fluid_cell_range(cell_offset: wp.array[wp.int32], key: int):
    """First slot and end of the slots of table entry ``key`` (``key <= mask``; exact for every entry)."""
    return cell_offset[key], cell_offset[key + 1]


@wp.kernel
def compute_fluid_cell_keys(
    fluid_particle: wp.array[wp.int32],
    particle_flags: wp.array[wp.int32],
    particle_world: wp.array[wp.int32],
    params: wp.array[FluidParams],
    particle_q_start: wp.array[wp.vec3],
    limit_travel: int,
    inv_cell: float,
    cell_bits: int,
    mask: int,
    # in/out
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    # outputs
    keys: wp.array[wp.int32],
    cell_count: wp.array[wp.int32],
    rank: wp.array[wp.int32],
):
    """Table entry of each fluid particle's cell, counted per entry (``rank``: the particle's place among them).

    ``cell_count`` must be zero on entry (the scatter of the last build cleared what it counted).

    With ``limit_travel``, first shorten the particle's travel from ``particle_q_start`` to
    ``params[0].max_displacement`` (its velocity by the same factor): done here rather than in a pass of
    its own, the limit costs no graph node of its own, and nothing while it is off.
    """
    k = wp.tid()
    pi = fluid_particle[k]
    active = (particle_flags[pi] & ParticleFlags.ACTIVE) != 0
    x = particle_q[pi]
    if active and limit_travel != 0:
        limit = params[0].max_displacement
        if limit < MAX_DISPLACEMENT_OFF:
            x0 = particle_q_start[pi]
            d = x - x0
            travel = wp.length(d)
            if travel > limit:
                scale = limit / travel
                x = x0 + d * scale
                particle_q[pi] = x
                particle_qd[pi] = particle_qd[pi] * scale
    key = mask + 1
    # a cell index must fit in int32; farther particles are left out of the fluid solve this substep
    if active and wp.isfinite(x) and wp.length(x) * inv_cell < 1.0e9:
        c = fluid_cell(x, inv_cell)
        key = fluid_cell_hash(c[0], c[1], c[2], particle_world[pi], cell_bits)
    keys[k] = key
    rank[k] = wp.atomic_add(cell_count, key, 1)


@wp.kernel
def scatter_fluid_cell_keys(
    cell_keys: wp.array[wp.int32],
    cell_offset: wp.array[wp.int32],
    rank: wp.array[wp.int32],
    # outputs
    keys: wp.array[wp.int32],
    scattered: wp.array[wp.int32],
    cell_count: wp.array[wp.int32],
):
    """Put every particle in its slot, and clear the counts for the next build (all have been used)."""
    k = wp.tid()
    key = cell_keys[k]
    slot = cell_offset[key] + rank[k]
    keys[slot] = key
    scattered[slot] = k
    cell_count[key] = 0


@wp.kernel
def order_fluid_cells(
    keys: wp.array[wp.int32],
    scattered: wp.array[wp.int32],
    cell_offset: wp.array[wp.int32],
    fluid_particle: wp.array[wp.int32],
    particle_q: wp.array[wp.vec3],
    particle_mass: wp.array[float],
    particle_world: wp.array[wp.int32],
    mask: int,
    particle_start: wp.array[wp.vec3],
    # in/out
    carry: wp.array[float],
    # outputs
    values: wp.array[wp.int32],
    sorted_particle: wp.array[wp.int32],
    sorted_xm: wp.array[wp.vec4],
    sorted_world: wp.array[wp.int32],
    slot_of_particle: wp.array[wp.int32],
    wall_count: wp.array[wp.int32],
    carried: wp.array[float],
    sorted_moved: wp.array[wp.vec3],
):
    """Put each cell's slots in fluid-index order and gather the particles into them.

    The atomic ranks of the scatter arrive in any order: each slot counts the fluid indices of its
    cell below its own and moves its particle to that place, all slots at once, each reading its
    cell's few indices; the place is the particle's slot, so the gather of its position, mass and
    world happens here (no pass of its own). The slot's wall list, which belongs to the last order,
    is cleared. The left-out particles' entry is not ordered: they take no part in the solve, and a
    large pool of them (a scene that keeps inactive fluid particles in reserve) would cost time
    quadratic in its size.

    A value each particle carries from the last substep (``carry``, per particle; empty: none) is
    gathered into ``carried`` with the rest; a left-out particle's is set to 0 (it carries nothing).
    Where ``sorted_moved`` is not empty, each slot's particle's move from ``particle_start`` to ``particle_q``
    is gathered there.
    """
    i = wp.tid()
    key = keys[i]
    v = scattered[i]
    place = i
    if key <= mask:
        start, end = fluid_cell_range(cell_offset, key)
        place = start
        for a in range(start, end):
            if scattered[a] < v:
                place += 1
    values[place] = v
    wall_count[place] = 0
    pi = fluid_particle[v]
    if key > mask:
        sorted_particle[place] = -1
        sorted_world[place] = _NO_WORLD
        slot_of_particle[pi] = -1
        if carry.shape[0] > 0:
            carry[pi] = 0.0
        return
    x = particle_q[pi]
    sorted_particle[place] = pi
    slot_of_particle[pi] = place
    sorted_xm[place] = wp.vec4(x[0], x[1], x[2], particle_mass[pi])
    sorted_world[place] = particle_world[pi]
    if carry.shape[0] > 0:
        carried[place] = carry[pi]
    if sorted_moved.shape[0] > 0:
        sorted_moved[place] = x - particle_start[pi]


@wp.kernel
def build_fluid_neighbor_lists(
    sorted_xm: wp.array[wp.vec4],
    sorted_world: wp.array[wp.int32],
    cell_offset: wp.array[wp.int32],
    h: float,
    inv_cell: float,
    cell_bits: int,
    lanes: int,
    lane_capacity: int,
    stop_at: int,
    walls: FluidWallContacts,
    slot_of_particle: wp.array[wp.int32],
    # outputs
    neighbors: wp.array[wp.int32],
    neighbor_count: wp.array[wp.int32],
    candidate_count: wp.array[wp.int32],
    slots: FluidSlots,
):
    """List the slots within ``h`` of each slot (same world), stored transposed, and the walls of ``walls``.

    With ``lanes`` threads per slot, thread ``tid = lane * n + i`` scans its share of the 27 cells
    around slot ``i`` (in the order ``dz, dy, dx``, lane 0 the first share; with two lanes, each
    takes the slots of the own cell on its side of ``i``) and stores its finds in
    rows ``[lane, lane + 1) * lane_capacity`` of the list; so the lanes need neither atomics nor a
    prefix sum, and read one after the other the lists hold the neighbours in the order of one
    thread's scan. ``neighbor_count[lane * n + i]`` receives the number the lane found, which exceeds
    ``lane_capacity`` when its rows overflowed (only the first ``lane_capacity`` are stored). A lane
    stops once ``stop_at`` neighbours are found (used with one lane). (Evaluating the density here as
    well was measured slower on an H100 than a separate pass: the scan's loop is divergent and the
    extra registers cost occupancy.)

    Thread ``t`` also lists contact ``t`` of ``walls`` as a static wall of its particle's slot
    (:func:`~.walls.list_wall_contact`): a launch of its own would cost more than these threads at
    the sizes where a frame's time is latency (docs/archive/performance_notebook.md, "The floor"). Launched with
    ``max(lanes * n, walls.contact_max)`` threads.
    """
    tid = wp.tid()
    list_wall_contact(tid, walls, slot_of_particle, slots)
    slot_count = sorted_world.shape[0]
    if tid >= lanes * slot_count:
        return
    lane = tid // slot_count
    i = tid - lane * slot_count
    world = sorted_world[i]
    if world == _NO_WORLD:
        neighbor_count[tid] = 0
        candidate_count[tid] = 0
        return
    # this lane's share of the 27 cells in scan order, in half cells: [first, last) of 54. Only the
    # particle's own cell (the 14th) can be split, at the particle's own slot: two lanes then each
    # take 13 cells and half of the own cell (its slots are in fluid-index order, so no neighbour
    # is listed twice or left out)
    first = (54 * lane) // lanes
    last = (54 * (lane + 1)) // lanes
    row0 = lane * lane_capacity
    h2 = h * h
    xi4 = sorted_xm[i]
    xi = wp.vec3(xi4[0], xi4[1], xi4[2])
    ci = fluid_cell(xi, inv_cell)
    # distance from x_i to the lower and upper faces of its cell, per axis
    lo = wp.vec3(xi[0] - float(ci[0]) * h, xi[1] - float(ci[1]) * h, xi[2] - float(ci[2]) * h)
    hi = wp.vec3(h, h, h) - lo
    count = int(0)
    candidates = int(0)
    for dz in range(-1, 2):
        for dy in range(-1, 2):
            for dx in range(-1, 2):
                cell = (dz + 1) * 9 + (dy + 1) * 3 + dx + 1
                lower = 2 * cell >= first and 2 * cell < last
                upper = 2 * cell + 1 >= first and 2 * cell + 1 < last
                if not (lower or upper) or count >= stop_at:
                    continue
                # skip a cell whose box is farther than h (about a quarter of the 27, corners mostly)
                gap = wp.vec3(
                    wp.where(dx < 0, lo[0], wp.where(dx > 0, hi[0], 0.0)),
                    wp.where(dy < 0, lo[1], wp.where(dy > 0, hi[1], 0.0)),
                    wp.where(dz < 0, lo[2], wp.where(dz > 0, hi[2], 0.0)),
                )
                if wp.dot(gap, gap) >= h2:
                    continue
                key = fluid_cell_hash(ci[0] + dx, ci[1] + dy, ci[2] + dz, world, cell_bits)
                start, end = fluid_cell_range(cell_offset, key)
                if not upper:
                    end = wp.min(end, i)
                if not lower:
                    start = wp.max(start, i + 1)
                for j in range(start, end):
                    if count >= stop_at:
                        break
                    candidates += 1
                    xj4 = sorted_xm[j]
                    r = xi - wp.vec3(xj4[0], xj4[1], xj4[2])
                    if j == i or wp.dot(r, r) >= h2:
                        continue
                    if count < lane_capacity:
                        neighbors[(row0 + count) * slot_count + i] = j
                    count += 1
    neighbor_count[tid] = count
    candidate_count[tid] = candidates


def scan_lanes(device, particle_count: int) -> int:
    """Threads per particle for the full-neighbourhood scan of ``particle_count`` particles on ``device``.

    Up to a few hundred thousand particles the scan's time is the length of one thread's loop (its
    candidates one after the other), not the GPU's throughput: on an H100, 1,000 particles took
    41 us a scan and 100,000 66 us. Splitting the 27 cells among threads shortens that loop where
    one thread per particle leaves most of the GPU idle. Measured on an H100 (docs/archive/performance_notebook.md),
    ms per frame of the dam break with 1 / 2 / 3 lanes: 100k 2.60 / 2.52 / 2.48 (2 / 3 lanes with fast
    math 2.35 / 2.31); 300k (1.1 waves of resident threads) 5.80 / 5.85 / 5.92; 500k 8.80 / 8.80;
    1M 1 lane 17.5, 3 lanes 19.2 (17.8 with fast math). So: 3
    lanes up to half a wave of resident threads, 2 up to one wave, else 1; one on the CPU, where
    the threads run one after the other anyway.
    """
    device = wp.get_device(device)
    if not device.is_cuda:
        return 1
    wave = device.sm_count * _THREADS_PER_SM
    if 2 * particle_count <= wave:
        return 3
    if particle_count <= wave:
        return 2
    return 1


def neighbor_list_layout(
    capacity: int, capped: bool, lanes: int | None = None, device=None, particle_count: int = 0
) -> tuple[int, int]:
    """Scan lanes and list rows per lane for ``capacity`` neighbours per particle (see :class:`FluidNeighborSearch`).

    A lane's cells hold more than its share of the neighbours where the neighbourhood is one-sided
    (a surface, a corner): with two lanes up to three quarters of them were measured in one lane,
    with three (a layer of 9 cells each) over half. So with several lanes every lane has rows for
    three quarters of ``capacity``: the lists take 1.5 (2 lanes) or 2.25 (3 lanes) times the memory
    of one lane's, which :func:`scan_lanes` only picks for up to one wave of resident threads' worth
    of particles.
    """
    if lanes is None:
        lanes = 1 if capped else scan_lanes(device, particle_count)
    if lanes not in (1, 2, 3) or (capped and lanes != 1):
        raise ValueError(f"lanes={lanes!r} is invalid: expected 1, 2 or 3 (1 with a capped scan)")
    if lanes == 1:
        return 1, int(capacity)
    return int(lanes), -(-3 * int(capacity) // 4)


class FluidNeighborSearch:
    """Preallocated sort and neighbour-list buffers for ``fluid_count`` particles.

    Args:
        fluid_particle: Particle indices of the fluid particles, shape ``(fluid_count,)``.
        particle_count: Number of particles of the model.
        world_count: Number of worlds (world indices of fluid particles are in ``[-1, world_count)``).
        smoothing_length: Kernel support radius ``h`` [m]; also the cell edge.
        capacity: Neighbours stored per particle (with several lanes, more list rows:
            :func:`neighbor_list_layout`).
        capped: If ``True`` the scan stops at ``capacity`` neighbours (bounded work) and runs one
            thread per particle, so the first ``capacity`` in scan order are kept; otherwise it
            counts the whole neighbourhood with :func:`scan_lanes` threads per particle and reports
            overflow through :attr:`neighbor_count`.
        lanes: Threads per particle of the scan, 1 to 3, instead of the choice above (the lists
            hold the same neighbours in the same order either way).
    """

    def __init__(
        self,
        fluid_particle: wp.array,
        particle_count: int,
        world_count: int,
        smoothing_length: float,
        capacity: int,
        capped: bool,
        lanes: int | None = None,
    ):
        device = fluid_particle.device
        n = fluid_particle.shape[0]
        self.fluid_particle = fluid_particle
        self.slot_count = n
        self.smoothing_length = float(smoothing_length)
        self.inv_cell = 1.0 / self.smoothing_length
        self.lanes, self.lane_capacity = neighbor_list_layout(capacity, capped, lanes, device, n)
        self.capacity = self.lanes * self.lane_capacity
        self.stop_at = self.capacity if capped else np.iinfo(np.int32).max
        # world -1 and worlds 0..world_count-1 each own a block of at least 2^6 entries
        world_bits = int(np.ceil(np.log2(world_count + 1)))
        self.table_bits = max(world_bits + 6, int(np.ceil(np.log2(max(2 * n, 2)))))
        if self.table_bits > 30:
            raise ValueError(f"fluid neighbour table of 2^{self.table_bits} entries exceeds 2^30: too many worlds")
        self.cell_bits = self.table_bits - world_bits
        self.mask = (1 << self.table_bits) - 1
        with wp.ScopedDevice(device):
            #: table entry of each fluid particle (unsorted), and its rank among the entry's particles
            self.cell_keys = wp.zeros(n, dtype=wp.int32)
            self.rank = wp.zeros(n, dtype=wp.int32)
            #: sorted table entries of the slots, and the fluid index of each slot
            self.keys = wp.zeros(n, dtype=wp.int32)
            self.values = wp.zeros(n, dtype=wp.int32)
            # fluid index of each slot as scattered, before each cell is put in order
            self.scattered = wp.zeros(n, dtype=wp.int32)
            # particles per table entry (the last entry: left-out particles) and their first slot;
            # the counts are zero between builds
            self.cell_count = wp.zeros(self.mask + 2, dtype=wp.int32)
            self.cell_offset = wp.zeros(self.mask + 2, dtype=wp.int32)
            self.prefix_sum = ExclusiveScan(self.mask + 2, device)
            self.sorted_particle = wp.full(n, -1, dtype=wp.int32)
            self.sorted_xm = wp.zeros(n, dtype=wp.vec4)
            self.sorted_world = wp.full(n, _NO_WORLD, dtype=wp.int32)
            #: slot of every particle in this build, -1 for non-fluid and left-out particles
            self.slot_of_particle = wp.full(particle_count, -1, dtype=wp.int32)
            self.neighbors = wp.zeros(self.capacity * n, dtype=wp.int32)
            #: neighbours found for each slot by each lane of the scan, ``[lane * n + slot]``
            self.neighbor_count = wp.zeros(self.lanes * n, dtype=wp.int32)
            self.candidate_count = wp.zeros(self.lanes * n, dtype=wp.int32)
            #: static-wall planes of each slot, listed by the solver after a build (which clears the counts)
            self.wall_count = wp.zeros(n, dtype=wp.int32)
            self.wall_plane = wp.zeros(WALL_CONTACTS_PER_SLOT * n, dtype=wp.vec4)
        #: the slot arrays as one kernel argument
        self.slots = FluidSlots()
        self.slots.particle = self.sorted_particle
        self.slots.xm = self.sorted_xm
        self.slots.neighbors = self.neighbors
        self.slots.neighbor_count = self.neighbor_count
        self.slots.capacity = self.capacity
        self.slots.lanes = self.lanes
        self.slots.lane_capacity = self.lane_capacity
        self.slots.wall_count = self.wall_count
        self.slots.wall_plane = self.wall_plane
        #: no contacts: a build that lists no walls
        self.no_walls = FluidWallContacts()
        self.no_walls.count = wp.zeros(1, dtype=int, device=device)
        self.no_walls.contact_max = 0
        # a value per particle that the sort gathers into slot order (see :meth:`carry_values`)
        self.carry = wp.zeros(0, dtype=float, device=device)
        self.carried = self.carry
        # each slot's travel in the build's step so far (see :meth:`gather_moves`)
        self.sorted_moved = wp.zeros(0, dtype=wp.vec3, device=device)

    def carry_values(self, per_particle: wp.array, per_slot: wp.array) -> None:
        """Let every build gather ``per_particle`` (one float per particle) into ``per_slot`` (slot order).

        The sort's gather does it, so a value carried between substeps (the warm start's multipliers)
        costs no pass of its own; a particle left out of the build has its value set to 0.
        """
        self.carry = per_particle
        self.carried = per_slot

    def gather_moves(self, per_slot: wp.array) -> None:
        """Let every build gather each slot's move ``particle_q - particle_q_start`` into ``per_slot`` (a ``vec3`` a slot).

        A build without ``particle_q_start`` gathers no travel (zero). Gathered by the sort, a neighbour's move is
        read beside its position, not through its particle index, and stays what the build saw after later passes
        (the warm start's) have moved the slots' positions.
        """
        self.sorted_moved = per_slot

    def build(
        self,
        particle_q: wp.array,
        particle_mass: wp.array,
        particle_flags: wp.array,
        particle_world: wp.array,
        params: wp.array,
        particle_q_start: wp.array | None = None,
        particle_qd: wp.array | None = None,
        walls=None,
    ):
        """Sort the fluid particles at ``particle_q`` and rebuild all neighbour lists (no allocation, no sync).

        With ``particle_q_start`` (and ``particle_qd``), each fluid particle's travel from there is first
        limited to ``params[0].max_displacement`` in place (see :func:`compute_fluid_cell_keys`).
        Afterwards :attr:`sorted_xm` holds the positions and masses at ``particle_q`` in slot order.
        With ``walls`` (:class:`~.walls.FluidWallContacts`), the slots' static walls are listed from those
        contacts in the same launch as the neighbours (else the slots have none).
        """
        self.compute_keys(particle_q, particle_flags, particle_world, params, particle_q_start, particle_qd)
        self.sort(particle_q, particle_mass, particle_world, particle_q_start=particle_q_start)
        self.scan(walls)

    def compute_keys(
        self,
        particle_q: wp.array,
        particle_flags: wp.array,
        particle_world: wp.array,
        params: wp.array,
        particle_q_start: wp.array | None = None,
        particle_qd: wp.array | None = None,
    ) -> None:
        """Table entry of every fluid particle, counted per entry for :meth:`sort` (part of :meth:`build`)."""
        limit = particle_q_start is not None
        wp.launch(
            compute_fluid_cell_keys,
            dim=self.slot_count,
            inputs=[
                self.fluid_particle,
                particle_flags,
                particle_world,
                params,
                particle_q_start if limit else particle_q,
                int(limit),
                self.inv_cell,
                self.cell_bits,
                self.mask,
            ],
            outputs=[particle_q, particle_qd if limit else particle_q, self.cell_keys, self.cell_count, self.rank],
            device=particle_q.device,
        )

    def sort(
        self,
        particle_q: wp.array,
        particle_mass: wp.array,
        particle_world: wp.array,
        allocation_free: bool = False,
        particle_q_start: wp.array | None = None,
    ) -> None:
        """Counting-sort the fluid particles by their table entry and gather them (part of :meth:`build`).

        Reads :attr:`cell_keys` and the counts and ranks the key pass made; writes the sorted keys to
        :attr:`keys`, the fluid index of each slot to :attr:`values` and the slots' particles,
        positions (at ``particle_q``), masses and worlds, and leaves the counts zero. Entry
        ``mask + 1`` holds the left-out particles, which sort last (see the module notes). With
        ``allocation_free`` the entries' offsets come from :class:`~.prefix_sum.ExclusiveScan` (for the body
        of a CUDA conditional node, which may not allocate as ``wp.utils.array_scan`` does). The moves from
        ``particle_q_start`` (else none) go to :attr:`sorted_moved` where it is kept.
        """
        n = self.slot_count
        device = self.keys.device
        if allocation_free:
            self.prefix_sum.run(self.cell_count, self.cell_offset)
        else:
            wp.utils.array_scan(self.cell_count, self.cell_offset, inclusive=False)
        wp.launch(
            scatter_fluid_cell_keys,
            dim=n,
            inputs=[self.cell_keys, self.cell_offset, self.rank],
            outputs=[self.keys, self.scattered, self.cell_count],
            device=device,
        )
        wp.launch(
            order_fluid_cells,
            dim=n,
            inputs=[
                self.keys,
                self.scattered,
                self.cell_offset,
                self.fluid_particle,
                particle_q,
                particle_mass,
                particle_world,
                self.mask,
                particle_q if particle_q_start is None else particle_q_start,
                self.carry,
            ],
            outputs=[
                self.values,
                self.sorted_particle,
                self.sorted_xm,
                self.sorted_world,
                self.slot_of_particle,
                self.wall_count,
                self.carried,
                self.sorted_moved,
            ],
            device=device,
        )

    def scan(self, walls=None) -> None:
        """Rebuild the slots' neighbour lists as last sorted and gathered, and list their walls (see :meth:`build`)."""
        if walls is None:
            walls = self.no_walls
        wp.launch(
            build_fluid_neighbor_lists,
            dim=max(self.lanes * self.slot_count, walls.contact_max),
            inputs=[
                self.sorted_xm,
                self.sorted_world,
                self.cell_offset,
                self.smoothing_length,
                self.inv_cell,
                self.cell_bits,
                self.lanes,
                self.lane_capacity,
                self.stop_at,
                walls,
                self.slot_of_particle,
            ],
            outputs=[self.neighbors, self.neighbor_count, self.candidate_count, self.slots],
            device=self.sorted_xm.device,
        )
