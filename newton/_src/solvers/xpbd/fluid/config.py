# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The ``fluid_*`` keywords: defaults, validation (a ``ValueError`` naming argument, value and range), memory estimate."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from .calibration import DENSITY_KERNELS
from .walls import WALL_CONTACTS_PER_SLOT

# smoothing length h = DEFAULT_SMOOTHING_RATIO * rest distance unless given
DEFAULT_SMOOTHING_RATIO = 1.8


# share of the particle-scale (non-affine) velocity removed per NONAFFINE_DAMPING_STEP unless given (docs/archive/validation_notebook.md,
# "Still water")
DEFAULT_NONAFFINE_DAMPING = 0.1


# the time over which fluid_nonaffine_damping removes its share [s]: one substep of 8 at 60 Hz; a substep
# of dt removes 1 - (1 - share)^(dt / step), so the damping per second does not follow the substep count
NONAFFINE_DAMPING_STEP = 1.0 / 480.0


# the time from one non-affine damping to the next [s]: applied once in each such interval of substeps, it
# costs a quarter of its pass at 8 substeps a 60 Hz frame; the CPU's still columns are as calm as with it every
# substep, the 100k pool a little less, and the defaults' standing wave changes by under a point of period
# (docs/archive/validation_notebook.md, "The damping once in four substeps")
NONAFFINE_DAMPING_INTERVAL = 4.0 * NONAFFINE_DAMPING_STEP


# regulariser of the affine fit's position covariance, relative to the rest distance squared
AFFINE_REGULARIZER = 1.0e-3


# one iteration moves a particle by at most this fraction of the rest distance
MAX_CORRECTION_FRACTION = 0.5


# edge of a cell of the coarse density correction unless given [rest distances] (docs/validation.rst, "Still water")
DEFAULT_COARSE_CELL = 3.0


# largest fluid_warm_start: the carried sum includes what was carried, so under a steady load it is share / (1 -
# share) times what the passes add, and it keeps pushing after the load has gone; above a half (more than the
# passes' own) still water is churned (0.7: 0.022 m/s RMS in the 24-layer column, six times the defaults') and
# thrown apart (0.9: 0.81 m/s; docs/formulation.rst, "Warm start")
MAX_WARM_START = 0.5


# largest fluid_compression_damping: a substep's passes move a mode's error to p C* - (1 - p) g (C* - C0), which is
# stable for p > (2 g - 1) / (3 + 2 g); an even pass count reaches p = 0, so g must stay below a half
# (docs/formulation.rst, "Compression damping"; every schedule stops after an even count or closes an odd one,
# calibration.stable_pass_bound)
MAX_COMPRESSION_DAMPING = 0.4


# largest fluid_density_ramp: a ramp over 1 % compression would hold every loaded particle 0.5 % more compressed
MAX_DENSITY_RAMP = 0.01


# lambda regulariser relative to sum |grad C|^2 of the rest lattice (constraint softening ~1e-3)
EPSILON_RELATIVE = 1.0e-3


# cohesion 1 moves a surface particle by at most ~this fraction of the rest distance per iteration
COHESION_DISPLACEMENT = 0.0025


# neighbours stored per particle for fluid_max_neighbors=0, as a multiple of the rest-lattice count
FULL_NEIGHBOR_FACTOR = 4


# a pair under-dense by this fraction of the rest density takes the full cohesion, at rest density none
COHESION_GATE = 0.02


# zero of Akinci's cohesion spline, as a fraction of h: 2 (1-u)^3 u^3 = 1/64
AKINCI_ZERO = 0.5 * (1.0 - math.sqrt(1.0 - 4.0 * (1.0 / 128.0) ** (1.0 / 3.0)))


def real_in_range(
    name: str, value, lo: float, hi: float = math.inf, lo_open: bool = False, hi_open: bool = False
) -> float:
    """Return ``value`` as float, or raise ``ValueError`` naming the argument, the value and the valid range."""
    lb = "(" if lo_open else "["
    rb = ")" if hi_open or hi == math.inf else "]"
    valid = f"{lb}{lo:g}, {'inf' if hi == math.inf else f'{hi:g}'}{rb}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise ValueError(f"{name}={value!r} is invalid: expected a finite number in {valid}")
    v = float(value)
    if v < lo or (lo_open and v == lo) or v > hi or (hi_open and v == hi):
        raise ValueError(f"{name}={value!r} is out of range: expected a value in {valid}")
    return v


def count_in_range(name: str, value, hi: int, lo: int = 0) -> int:
    """Return ``value`` as int, or raise ``ValueError`` naming the argument, the value and the valid range."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not lo <= int(value) <= hi:
        raise ValueError(f"{name}={value!r} is invalid: expected an integer in [{lo}, {hi}]")
    return int(value)


@dataclass
class FluidConfig:
    """Validated fluid parameters of one solver (see :class:`~newton.solvers.SolverXPBD` for their meaning)."""

    fluid_rest_distance: float | None = None
    fluid_smoothing_length: float | None = None
    fluid_rest_density: float | None = None
    fluid_cohesion: float = 0.0
    fluid_viscosity: float = 0.0
    fluid_nonaffine_damping: float = DEFAULT_NONAFFINE_DAMPING
    fluid_vorticity: float = 0.0
    fluid_relaxation: float | None = None
    fluid_density_ramp: float = 0.0
    fluid_max_neighbors: int = 0
    fluid_density_tolerance: float = 0.0
    fluid_max_iterations: int = 1
    fluid_max_displacement: float = math.inf
    fluid_warm_start: float = 0.0
    max_diffuse_particles: int = 0
    fluid_continuous_collision: bool = True
    fluid_relax_overpacked: bool = True
    fluid_coarse_correction: float = 0.0
    fluid_coarse_cell: float = DEFAULT_COARSE_CELL
    fluid_density_kernel: str = "one_kernel"
    fluid_compression_damping: float = 0.0

    #: parameters that may change after construction (they live on the device)
    MUTABLE = (
        "fluid_rest_density",
        "fluid_cohesion",
        "fluid_viscosity",
        "fluid_nonaffine_damping",
        "fluid_vorticity",
        "fluid_relaxation",
        "fluid_density_ramp",
        "fluid_density_tolerance",
        "fluid_max_displacement",
        "fluid_warm_start",
    )

    def __post_init__(self):
        if self.fluid_rest_distance is not None:
            self.fluid_rest_distance = real_in_range("fluid_rest_distance", self.fluid_rest_distance, 0.0, lo_open=True)
            d = self.fluid_rest_distance
            if self.fluid_smoothing_length is None:
                self.fluid_smoothing_length = DEFAULT_SMOOTHING_RATIO * d
            self.fluid_smoothing_length = real_in_range(
                "fluid_smoothing_length", self.fluid_smoothing_length, d, 4.0 * d, lo_open=True
            )
        elif self.fluid_smoothing_length is not None:
            self.fluid_smoothing_length = real_in_range(
                "fluid_smoothing_length", self.fluid_smoothing_length, 0.0, lo_open=True
            )
        for name in self.MUTABLE:
            self.set(name, getattr(self, name))
        self.fluid_max_neighbors = count_in_range("fluid_max_neighbors", self.fluid_max_neighbors, 4096)
        self.fluid_max_iterations = count_in_range("fluid_max_iterations", self.fluid_max_iterations, 64, lo=1)
        self.max_diffuse_particles = count_in_range("max_diffuse_particles", self.max_diffuse_particles, 2**31 - 1)
        self.fluid_coarse_correction = real_in_range("fluid_coarse_correction", self.fluid_coarse_correction, 0.0, 1.0)
        self.fluid_coarse_cell = real_in_range("fluid_coarse_cell", self.fluid_coarse_cell, 1.0, 16.0)
        self.fluid_compression_damping = real_in_range(
            "fluid_compression_damping", self.fluid_compression_damping, 0.0, MAX_COMPRESSION_DAMPING
        )
        if not isinstance(self.fluid_density_kernel, str) or self.fluid_density_kernel not in DENSITY_KERNELS:
            raise ValueError(
                f"fluid_density_kernel={self.fluid_density_kernel!r} is invalid: expected one of "
                + ", ".join(repr(k) for k in DENSITY_KERNELS)
            )
        for name in ("fluid_continuous_collision", "fluid_relax_overpacked"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}={getattr(self, name)!r} is invalid: expected True or False")

    def set(self, name: str, value) -> None:
        """Validate and store one mutable parameter."""
        if name == "fluid_rest_density":
            v = None if value is None else real_in_range(name, value, 0.0, lo_open=True)
        elif name in ("fluid_cohesion", "fluid_viscosity", "fluid_nonaffine_damping"):
            v = real_in_range(name, value, 0.0, 1.0)
        elif name in ("fluid_vorticity", "fluid_density_tolerance"):
            v = real_in_range(name, value, 0.0)
        elif name == "fluid_max_displacement":
            # inf (no limit) is allowed here, unlike for the other parameters
            infinite = isinstance(value, numbers.Real) and not isinstance(value, bool) and value == math.inf
            v = math.inf if infinite else real_in_range(name, value, 0.0, lo_open=True)
        elif name == "fluid_warm_start":
            v = real_in_range(name, value, 0.0, MAX_WARM_START)
        elif name == "fluid_relaxation":
            # None: the solver's stable step for its kernel and pass count (FluidSolver.default_relaxation)
            v = None if value is None else real_in_range(name, value, 0.0, 2.0, lo_open=True)
        elif name == "fluid_density_ramp":
            v = real_in_range(name, value, 0.0, MAX_DENSITY_RAMP)
        else:
            raise AttributeError(f"{name} cannot be changed after the solver is created")
        setattr(self, name, v)


def fluid_memory_bytes(
    fluid_count: int, particle_count: int, neighbor_capacity: int, diffuse: int = 0, lanes: int = 1
) -> int:
    """Device memory the fluid solve allocates [bytes] (render particles, allocated on first use, excluded).

    Per fluid particle: the neighbour list (4 bytes a row, ``neighbor_capacity`` rows), the sort's keys,
    ranks, sorted keys, scattered and ordered values (20 bytes), the cell table (at least two entries a
    particle: count and first slot, 16 bytes), the gathered slot (24 bytes), the neighbour and candidate
    counts of each of the scan's ``lanes`` (8 bytes a lane), the static-wall planes (16 bytes each,
    ``WALL_CONTACTS_PER_SLOT``) and about 84 bytes of per-slot state; per model particle, two 4-byte
    maps; per diffuse particle, 28 bytes.
    """
    per_fluid = 4 * neighbor_capacity + 20 + 16 + 24 + 8 * lanes + 84 + 16 * WALL_CONTACTS_PER_SLOT
    return int(fluid_count * per_fluid + 12 * particle_count + 28 * diffuse)


def free_memory(device) -> int | None:
    """Free memory of ``device`` [bytes]: the CUDA device's, or the host's available memory; None if unknown."""
    if device.is_cuda:
        return int(device.free_memory)
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


@dataclass(frozen=True)
class FluidTuning:
    """How the fluid solve runs, where the choice does not change its results (beyond GPU rounding).

    For benchmarks and tests that compare implementations: pass it to ``SolverXPBD`` as the private
    keyword ``_fluid_tuning`` (it is not part of the public signature).

    Args:
        concurrent_passes: On a CUDA device, run the fluid passes that do not need upstream's work of
            the moment on a second stream beside it (the sort and scan beside the first iteration's
            contacts, the next density pass beside the deltas' application and the next contacts);
            False: one stream. Defaults to True.
        scan_lanes: Threads per particle of the full-neighbourhood scan, in {0, 1, 2, 3}; 0 chooses by
            the particle count and the device (:func:`~.neighbors.scan_lanes`). Ignored with
            ``fluid_max_neighbors`` > 0 (a capped scan runs one thread per particle). Defaults to 0.
    """

    concurrent_passes: bool = True
    scan_lanes: int = 0

    def __post_init__(self):
        if not isinstance(self.concurrent_passes, bool):
            raise ValueError(f"concurrent_passes={self.concurrent_passes!r} is invalid: expected True or False")
        count_in_range("scan_lanes", self.scan_lanes, 3)


#: the ``fluid_*`` keywords of ``SolverXPBD`` (and ``max_diffuse_particles``) with their defaults
FLUID_KEYWORDS = {name: field.default for name, field in FluidConfig.__dataclass_fields__.items()}
