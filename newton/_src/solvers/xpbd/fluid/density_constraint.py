# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The density constraint of position-based fluids: density, multiplier, correction, cohesion, warm start.

One Jacobi pass is ``compute_fluid_density_lambda`` (the density and the multiplier of the
unilateral constraint ``C_i = max(rho_i / rho0 - 1, 0)``, Macklin & Müller 2013, eq. 1-11) then
``apply_fluid_density_correction`` (``dx_i = 1/rho0 sum_j (lambda_i + lambda_j) grad W_ij``, eq. 12,
with Akinci's cohesion as a bias), over the fluid slots (:mod:`.sph`); both are compiled per kernel
choice by :func:`density_passes`.

The density is the poly6 sum and the correction moves along the spiky kernel's gradient, as Macklin &
Müller's; or, with ``fluid_density_kernel="one_kernel"``, both come from the one kernel ``(1 - r/h)^2.5``:
the correction is then the gradient of the constraint it corrects (docs/formulation.rst, "The density
kernel").

With ``fluid_compression_damping`` g > 0 the substep's first pass also reads how much the substep's motion
compresses each particle, ``dC_i = grad C_i . (x* - x0)`` summed over the pairs (``x*`` the predicted, ``x0``
the substep's start positions), and every pass of the substep drives ``C_i + g dC_i`` to zero instead of
``C_i``: the passes remove compressing motion as well as compression, in the modes they act on, so a long
wave's ring (which the passes hold as a soft spring) is damped in proportion (docs/formulation.rst,
"Compression damping").
"""

import dataclasses
import functools
from typing import Any

import warp as wp

from .sph import (
    FluidParams,
    FluidSlots,
    akinci_cohesion,
    neighbor_sum,
    one_kernel,
    one_kernel_slope,
    pair_direction,
    pair_share,
    poly6,
    poly6_slope,
    spiky_slope,
)
from .walls import fluid_wall_share

# approximate division and square root in CUDA code (no effect on the CPU; see :mod:`.sph`)
wp.set_module_options({"fast_math": True})

# bins of the compression sum of density sub-iterations: spreads the atomics over several addresses
COMPRESSION_BINS = wp.constant(64)


# a particle compressed by more than this (of rho/rho0 - 1) in a substep's last density pass is counted, and
# the peak kept, on the device until the next fluid_diagnostics reports it (healthy flows stay well below)
PEAK_COMPRESSION = wp.constant(0.1)


# the bins' compression sums, then their particle counts
COMPRESSION_SUMS = wp.constant(128)


# ParticleApply.on: the correction pass writes the position SolverXPBD will apply, or the position
# moved by the pass's correction (density sub-passes)
APPLY_AS_XPBD = wp.constant(1)


APPLY_ADVANCE = wp.constant(2)


@wp.func
def density_constraint_lambda(rho: float, grad_i: wp.vec3, grad_sq: float, p: FluidParams):
    """Jacobi multiplier of the unilateral density constraint ``C = max(rho / rho0 - 1, 0)``.

    With ``density_ramp`` d > 0 the multiplier is that of ``C^2 / (2 d)`` below d and of ``C - d / 2``
    above (continuous, and so is its slope): particles near rest density, which switch a constraint
    with a kink on and off from substep to substep, take it in gradually, and fluid at rest stops
    humming, for d / 2 more compression where it carries a load (docs/archive/validation_notebook.md, "Hydrostatics").
    """
    c = wp.max(rho * p.inv_rest_density - 1.0, 0.0)
    d = p.density_ramp
    if c < d:
        c = c * c / (2.0 * d)
    else:
        c = c - 0.5 * d
    return -c / (grad_sq + wp.dot(grad_i, grad_i) + p.epsilon)


@wp.func
def damped_constraint_lambda(rho: float, grad_i: wp.vec3, grad_sq: float, rate: float, p: FluidParams):
    """Jacobi multiplier of the active constraint driven to ``-rate`` (``g dC_i``) instead of zero.

    A particle below rest density stays free (the constraint is unilateral); one compressed is pushed at
    most to rest, never pulled (``C + rate`` is taken at least 0).
    """
    if rho * p.inv_rest_density <= 1.0:
        return 0.0
    lam = density_constraint_lambda(rho, grad_i, grad_sq, p)
    denominator = grad_sq + wp.dot(grad_i, grad_i) + p.epsilon
    return wp.min(lam - rate / denominator, 0.0)


# the density sum's terms: grad C_i w.r.t. x_j (0-2), m W_ij (3), |grad C_i w.r.t. x_j|^2 (4)
vec5 = wp.types.vector(length=5, dtype=float)


# the density sum's terms and the compression rate's (5), for the substep's first pass under the damping
vec6 = wp.types.vector(length=6, dtype=float)


@wp.struct
class DensityRateSlot:
    """What a neighbour's density and compression-rate terms need of slot ``i``."""

    x: wp.vec3  # position [m]
    particle: int  # particle index
    moved: wp.vec3  # its move in the substep up to the build, x* - x0 [m]
    moves: wp.array[wp.vec3]  # every slot's move up to the build, in slot order (the build gathers them) [m]


# kinds of density pass under fluid_compression_damping: the substep's first (reads the motion's compression),
# a later one of the substep (drives to what the first read), or one outside a step (no damping)
RATE_NONE = wp.constant(0)
RATE_READ = wp.constant(1)
RATE_KEPT = wp.constant(2)


@wp.struct
class DensitySlot:
    """What a neighbour's density term needs of slot ``i``."""

    x: wp.vec3  # position [m]
    particle: int  # particle index


@wp.func
def cohesion_weight(rel_i: float, rel_j: float, p: FluidParams):
    """Share of the cohesion a pair takes, from the pair's relative densities ``rho / rho0``.

    Full where the pair is under-dense by ``cohesion_gate`` or more, none at or above rest density:
    where the fluid is at rest density the density constraint holds it together, and cohesion
    there would only compress it (the unilateral constraint pushes back only once compressed).
    """
    if p.cohesion <= 0.0:
        return 0.0
    under = 1.0 - 0.5 * (rel_i + rel_j)
    return wp.clamp(under / p.cohesion_gate, 0.0, 1.0)


@wp.struct
class CorrectionSlot:
    """What a neighbour's correction term needs of slot ``i``."""

    xm: wp.vec4  # position [m] and mass [kg]
    lam: float  # multiplier
    rel: float  # relative density rho / rho0
    particle: int  # particle index
    lambda_rho: wp.array[wp.vec2]  # every slot's multiplier and relative density


@wp.struct
class WarmStartSlot:
    """What a neighbour's warm-start term needs of slot ``i``."""

    xm: wp.vec4  # position [m] and mass [kg]
    lam: float  # carried multiplier
    particle: int  # particle index
    warm_lambda: wp.array[float]  # every slot's carried multiplier


@wp.kernel
def gather_fluid_positions(
    slots: FluidSlots,
    active: wp.array[wp.int32],
    particle_q: wp.array[wp.vec3],
    particle_mass: wp.array[float],
):
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0 or active[0] == 0:
        return
    x = particle_q[pi]
    slots.xm[i] = wp.vec4(x[0], x[1], x[2], particle_mass[pi])


@wp.func
def relaxed_correction(dx: wp.vec3, relaxation: float, p: FluidParams):
    """A density correction scaled by ``relaxation`` and bounded to ``max_correction`` per pass."""
    dx *= relaxation
    dx_len = wp.length(dx)
    if dx_len > p.max_correction:
        dx *= p.max_correction / dx_len
    return dx


@wp.struct
class ParticleApply:
    """Where the correction pass writes each fluid particle's corrected position (besides its delta).

    ``on`` = 1 (``APPLY_AS_XPBD``): the position and velocity after ``SolverXPBD`` applies the iteration's
    deltas with its ``apply_particle_deltas`` (same formula: ``x = x_pred + delta``,
    ``v = (x - x_start) / dt``, ``v`` bounded to ``v_max`` and ``x`` moved back with it), in slot
    order, so the next iteration and the viscosity pass need not gather them. ``on`` = 2
    (``APPLY_ADVANCE``): for the next density sub-pass, the position the iteration's deltas so far give,
    ``x_pred + delta``, with the contacts' and every other constraint's of the iteration as well as the
    passes' (only ``x_pred`` and ``xm`` are used; no bound on the speed). 0: nothing.
    """

    on: int
    x_pred: wp.array[wp.vec3]  # positions the deltas are applied to [m]
    x_start: wp.array[wp.vec3]  # positions at the start of the substep [m]
    dt: float  # [s]
    v_max: float  # [m/s]
    xm: wp.array[wp.vec4]  # output: the applied positions [m] and masses [kg], in slot order
    v: wp.array[wp.vec3]  # output: the applied velocities [m/s], in slot order


@wp.func
def applied_particle(apply: ParticleApply, pi: int, delta: wp.vec3):
    """Position and velocity of particle ``pi`` once ``SolverXPBD`` applies ``delta`` (see :class:`ParticleApply`)."""
    x0 = apply.x_start[pi]
    x = apply.x_pred[pi] + delta
    v = (x - x0) / apply.dt
    speed = wp.length(v)
    if speed > apply.v_max:
        v *= apply.v_max / speed
        x = x0 + v * apply.dt
    return x, v


@wp.kernel
def applied_particles(apply: ParticleApply, particle_deltas: wp.array[wp.vec3]):
    """:func:`applied_particle` of every particle, in particle order (the seam's check of upstream's formula)."""
    i = wp.tid()
    x, v = applied_particle(apply, i, particle_deltas[i])
    apply.xm[i] = wp.vec4(x[0], x[1], x[2], 0.0)
    apply.v[i] = v


@wp.kernel
def store_fluid_warm_start(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    lambda_sum: wp.array[float],
    # outputs
    particle_lambda: wp.array[float],
):
    """Keep ``warm_start`` times each particle's multipliers of this substep for the next one.

    For the tolerance modes, whose last correction is decided on the device; with fixed counts the
    last correction pass stores them itself. A particle left out of this substep's solve (inactive,
    non-finite) carries nothing: the sort set its value to 0.
    """
    i = wp.tid()
    p = params[0]
    if p.warm_start <= 0.0:
        return
    pi = slots.particle[i]
    if pi < 0:
        return
    particle_lambda[pi] = p.warm_start * lambda_sum[i]


@dataclasses.dataclass(frozen=True)
class DensityPasses:
    """The density constraint's passes compiled for one ``fluid_density_kernel`` (see :func:`density_passes`).

    Attributes:
        compute_lambda: The kernel of the density and the multipliers.
        compute_lambda_reading_rate: With the compression damping, that of the substep's first density pass,
            which also reads the motion's compression rate (else None).
        apply_correction: The kernel of the Jacobi correction.
        apply_warm_start: The kernel of the warm start's correction.
        pair_weight: ``wp.func`` ``W(r2, d, p)`` of the density sum, at ``r2 = |r|^2`` and ``d = h - |r|`` [1/m^3].
        pair_slope: ``wp.func`` ``dW/d|r| (d, p)`` the correction moves along [1/m^4].
        density_correction_sum: ``wp.func`` summing the correction and cohesion over a slot's neighbours
            (:class:`CorrectionSlot`), for other passes that move along the constraint's gradient.
        suffix: What the choice's kernel names end with ("" for ``"poly6"``; see :func:`named_variant`).
    """

    compute_lambda: Any
    compute_lambda_reading_rate: Any
    apply_correction: Any
    apply_warm_start: Any
    pair_weight: Any
    pair_slope: Any
    density_correction_sum: Any
    suffix: str


def named_variant(fn, suffix: str):
    """``fn`` renamed with ``suffix``: each kernel choice's functions and kernels get keys of their own."""
    fn.__name__ = fn.__qualname__ = fn.__name__ + suffix
    return fn


@functools.cache
def density_passes(kernel: str, damped: bool = False) -> DensityPasses:
    """The density passes with ``kernel``'s density and gradient (``"poly6"`` or ``"one_kernel"``) compiled in.

    ``"poly6"``: the poly6 sum moved along the spiky gradient (Macklin & Müller 2013); ``"one_kernel"``:
    ``c (1 - r/h)^2.5`` and its own gradient. The choice is made when the code is generated
    (``wp.static``), not per pair: a branch on it in the pair terms cost the 1M dam break 3.6 % of its frame
    with poly6 (one H200, ``bash benchmarks/gpu_session.sh OUT density-kernel``), and the kernels of a
    choice a scene does not make are not compiled. The ``"poly6"`` kernels keep their names. ``damped``
    compiles the compression damping's rate into the density pass (``fluid_compression_damping`` > 0);
    without it the pass reads nothing more than before.
    """
    one = kernel == "one_kernel"
    suffix = ("_one_kernel" if one else "") + ("_damped" if damped else "")

    def pair_weight(r2: float, d: float, p: FluidParams):
        if wp.static(one):
            return one_kernel(d / p.h, p)
        return poly6(r2, p)

    def pair_slope(d: float, p: FluidParams):
        if wp.static(one):
            return one_kernel_slope(d / p.h, p)
        return spiky_slope(d, p)

    def self_weight(p: FluidParams):
        """A particle's own ``W(0)`` [1/m^3]."""
        if wp.static(one):
            return p.one_kernel_scale
        return poly6(0.0, p)

    pair_weight = wp.func(named_variant(pair_weight, suffix))
    pair_slope = wp.func(named_variant(pair_slope, suffix))
    self_weight = wp.func(named_variant(self_weight, suffix))

    def pair_density_terms(
        r: wp.vec3, r2: float, dist: float, particle: int, slots: FluidSlots, j: int, p: FluidParams
    ):
        """A pair's ``(grad C_i w.r.t. x_j, m W_ij, its gradient squared)`` at ``r = x_i - x_j`` (``|r| = dist`` < ``h``).

        ``m`` is the reference mass, not ``m_j``: the constraint is on the number density, so that a
        particle's rest density is in proportion to its own mass and fluids of different density mix.
        """
        n = pair_direction(r, dist, particle, slots.particle, j, p)
        d = p.h - dist
        g = n * wp.static(pair_slope)(d, p) * (p.reference_mass * p.inv_rest_density)
        w = wp.static(pair_weight)(r2, d, p)
        return vec5(g[0], g[1], g[2], p.reference_mass * w, wp.dot(g, g))

    pair_density_terms = wp.func(named_variant(pair_density_terms, suffix))

    def density_term(slots: FluidSlots, j: int, me: DensitySlot, p: FluidParams):
        """Neighbour ``j``'s share of slot ``i``'s constraint (:func:`pair_density_terms`; zero beyond ``h``)."""
        xj4 = slots.xm[j]
        r = me.x - wp.vec3(xj4[0], xj4[1], xj4[2])
        r2 = wp.dot(r, r)
        if r2 >= p.h2:
            return vec5(0.0)
        return wp.static(pair_density_terms)(r, r2, wp.sqrt(r2), me.particle, slots, j, p)

    density_term = wp.func(named_variant(density_term, suffix))
    density_sum = neighbor_sum(density_term, pairwise=True)

    def density_slope(dist: float, d: float, p: FluidParams):
        """``dW/d|r|`` of the density's own kernel (poly6's is not the spiky slope the correction moves along)."""
        if wp.static(one):
            return one_kernel_slope(d / p.h, p)
        return poly6_slope(dist, p)

    density_slope = wp.func(named_variant(density_slope, suffix))

    def density_rate_term(slots: FluidSlots, j: int, me: DensityRateSlot, p: FluidParams):
        """:func:`density_term` and neighbour ``j``'s share of ``dC_i = sum_j m / rho0 W'(|r|) n . (moved_i - moved_j)``.

        One neighbour loop for both: the substep's first pass reads each pair once. The moves are in slot
        order, so a neighbour's is read beside its position.
        """
        xj4 = slots.xm[j]
        xj = wp.vec3(xj4[0], xj4[1], xj4[2])
        r = me.x - xj
        r2 = wp.dot(r, r)
        if r2 >= p.h2:
            return vec6(0.0)
        dist = wp.sqrt(r2)
        t = wp.static(pair_density_terms)(r, r2, dist, me.particle, slots, j, p)
        rate = float(0.0)
        if r2 > 0.0:
            slope = wp.static(density_slope)(dist, p.h - dist, p)
            rate = slope * p.reference_mass * p.inv_rest_density * wp.dot(r / dist, me.moved - me.moves[j])
        return vec6(t[0], t[1], t[2], t[3], t[4], rate)

    density_rate_term = wp.func(named_variant(density_rate_term, suffix))
    density_rate_sum = neighbor_sum(density_rate_term, pairwise=True)

    def correction_term(
        xi4: wp.vec4,
        lam_i: float,
        xj4: wp.vec4,
        lam_j: float,
        pi: int,
        sorted_particle: wp.array[wp.int32],
        j: int,
        p: FluidParams,
        cohesion: float,
    ):
        """Neighbour ``j``'s density correction (top) and its cohesion pull (bottom) on slot ``i``.

        The pull is weighted by ``cohesion`` (the pair's share, :func:`cohesion_weight`) and not yet scaled
        by the strength. It is evaluated for every pair while cohesion is on, also where the share is 0:
        a branch on the share diverges within a warp (measured 0.01 ms per frame slower at 100k, 0.05 ms at 1M).
        """
        r = wp.vec3(xi4[0] - xj4[0], xi4[1] - xj4[1], xi4[2] - xj4[2])
        r2 = wp.dot(r, r)
        if r2 >= p.h2:
            return wp.spatial_vector(wp.vec3(0.0), wp.vec3(0.0))
        dist = wp.sqrt(r2)
        n = pair_direction(r, dist, pi, sorted_particle, j, p)
        d = p.h - dist
        share = pair_share(xi4, xj4)
        dx = n * (wp.static(pair_slope)(d, p) * (lam_i + lam_j) * p.reference_mass * p.inv_rest_density * share)
        coh = wp.vec3(0.0)
        if p.cohesion > 0.0:
            coh = n * (-share * cohesion * akinci_cohesion(dist, p))
        return wp.spatial_vector(dx, coh)

    correction_term = wp.func(named_variant(correction_term, suffix))

    def density_correction_term(slots: FluidSlots, j: int, me: CorrectionSlot, p: FluidParams):
        """:func:`correction_term` of neighbour ``j`` with this iteration's multipliers and the pair's cohesion share."""
        lr = me.lambda_rho[j]
        c = cohesion_weight(me.rel, lr[1], p)
        return wp.static(correction_term)(me.xm, me.lam, slots.xm[j], lr[0], me.particle, slots.particle, j, p, c)

    density_correction_term = wp.func(named_variant(density_correction_term, suffix))
    density_correction_sum = neighbor_sum(density_correction_term)

    def warm_start_term(slots: FluidSlots, j: int, me: WarmStartSlot, p: FluidParams):
        """The density correction of neighbour ``j`` with the carried multipliers alone: no cohesion."""
        return wp.spatial_top(
            wp.static(correction_term)(
                me.xm, me.lam, slots.xm[j], me.warm_lambda[j], me.particle, slots.particle, j, p, 0.0
            )
        )

    warm_start_term = wp.func(named_variant(warm_start_term, suffix))
    warm_start_sum = neighbor_sum(warm_start_term)

    def lambda_pass(reads_rate: bool):
        """The density pass's kernel; ``reads_rate``: the damped substep's first, which also reads the rate.

        Two kernels rather than a branch on the pass: the later passes keep the registers of the undamped
        one, and only the first pays for the rate's loop.
        """

        def compute_fluid_density_lambda(
            params: wp.array[FluidParams],
            slots: FluidSlots,
            active: wp.array[wp.int32],
            wall_table: wp.array[float],
            wall_table_grad: wp.array[float],
            track_compression: int,
            track_peaks: int,
            rate_pass: int,
            moves: wp.array[wp.vec3],
            # outputs
            density: wp.array[float],
            lambda_rho: wp.array[wp.vec2],
            wall_grad: wp.array[wp.vec3],
            compression_bins: wp.array[float],
            peaks: wp.array[float],
            rate: wp.array[float],
        ):
            """Density and the Jacobi multiplier of the unilateral constraint C = max(rho/rho0 - 1, 0).

            The static walls listed for the slot add their share of ``rho / rho0`` (:func:`fluid_wall_share`);
            its gradient is kept in ``wall_grad`` for the correction. Does nothing while ``active[0]`` is 0.
            With ``track_compression``, also sums max(rho/rho0 - 1, 0) into ``compression_bins[0, B)`` and
            counts the particles in ``[B, 2B)`` (``B = COMPRESSION_BINS``, spreading the atomics). With
            ``track_peaks`` (a substep's last pass), counts the particles compressed by more than
            ``PEAK_COMPRESSION`` into ``peaks[0, B)`` and keeps their largest compression in ``peaks[B, 2B)``,
            until :meth:`~.solver_fluid.FluidSolver.diagnostics` reads and clears them. Compiled ``damped``, it
            drives the constraint to ``-rate`` for ``rate_pass`` ``RATE_KEPT`` (``RATE_NONE``: to 0); compiled
            ``reads_rate`` (the substep's first pass), it first sums ``g dC_i`` from ``moves`` (each slot's move
            from the substep's start to the build, in slot order) into ``rate``, whatever ``rate_pass``.
            """
            i = wp.tid()
            pi = slots.particle[i]
            if pi < 0 or active[0] == 0:
                return
            p = params[0]
            xi4 = slots.xm[i]
            xi = wp.vec3(xi4[0], xi4[1], xi4[2])
            rho = p.reference_mass * wp.static(self_weight)(p)
            # the sums start from the particle's own share
            if wp.static(reads_rate):
                # the substep's first pass reads the motion's compression in the density's neighbour loop
                moved = moves[i]
                me_rate = DensityRateSlot()
                me_rate.x = xi
                me_rate.particle = pi
                me_rate.moved = moved
                me_rate.moves = moves
                s = wp.static(density_rate_sum)(slots, i, me_rate, p, vec6(0.0, 0.0, 0.0, rho, 0.0, 0.0))
                t = vec5(s[0], s[1], s[2], s[3], s[4])
                moved_in = s[5]
            else:
                me = DensitySlot()
                me.x = xi
                me.particle = pi
                t = wp.static(density_sum)(slots, i, me, p, vec5(0.0, 0.0, 0.0, rho, 0.0))
            rho = t[3]
            grad_i = wp.vec3(t[0], t[1], t[2])
            grad_sq = t[4]
            # the walls do not move: their gradient only adds to the particle's own
            wall = fluid_wall_share(slots, i, xi, p, wall_table, wall_table_grad)
            wall_g = wp.vec3(wall[0], wall[1], wall[2])
            rho += wall[3] * p.rest_density
            grad_i += wall_g
            wall_grad[i] = wall_g
            density[i] = rho
            # the multiplier and the relative density, which the correction reads for each neighbour
            lam = float(0.0)
            if wp.static(reads_rate):
                g = p.compression_damping * (moved_in + wp.dot(wall_g, moved))
                rate[i] = g
                lam = damped_constraint_lambda(rho, grad_i, grad_sq, g, p)
            elif wp.static(damped):
                g = float(0.0)
                if rate_pass == RATE_KEPT:
                    g = rate[i]
                lam = damped_constraint_lambda(rho, grad_i, grad_sq, g, p)
            else:
                lam = density_constraint_lambda(rho, grad_i, grad_sq, p)
            lambda_rho[i] = wp.vec2(lam, rho * p.inv_rest_density)
            if track_compression != 0:
                b = i % COMPRESSION_BINS
                wp.atomic_add(compression_bins, b, wp.max(rho * p.inv_rest_density - 1.0, 0.0))
                wp.atomic_add(compression_bins, COMPRESSION_BINS + b, 1.0)
            if track_peaks != 0:
                c = rho * p.inv_rest_density - 1.0
                if c > PEAK_COMPRESSION:
                    b = i % COMPRESSION_BINS
                    wp.atomic_add(peaks, b, 1.0)
                    wp.atomic_max(peaks, COMPRESSION_BINS + b, c)

        name = suffix + ("_reading_rate" if reads_rate else "")
        return wp.kernel(named_variant(compute_fluid_density_lambda, name))

    def apply_fluid_density_correction(
        params: wp.array[FluidParams],
        slots: FluidSlots,
        active: wp.array[wp.int32],
        lambda_rho: wp.array[wp.vec2],
        particle_inv_mass: wp.array[float],
        wall_grad: wp.array[wp.vec3],
        apply: ParticleApply,
        store_warm: int,
        closing: int,
        # outputs
        particle_deltas: wp.array[wp.vec3],
        lambda_sum: wp.array[float],
        particle_lambda: wp.array[float],
    ):
        """Add the density correction and the cohesion bias of slot ``i`` to its particle's Jacobi delta.

        Each pair takes the share of the cohesion :func:`cohesion_weight` gives it.

        ``wall_grad`` is the walls' gradient of the density pass before it. With ``apply.on``, the
        corrected position goes to ``apply.xm`` (see :class:`ParticleApply`). With the warm start, the
        multiplier is added to the substep's sum ``lambda_sum``; with ``store_warm`` (the substep's last
        correction), ``warm_start`` times that sum is kept in ``particle_lambda`` for the next substep
        (as :func:`store_fluid_warm_start` does, without a pass of its own). ``closing``: the last pass of an
        odd count, which takes ``closing_relaxation``.
        """
        i = wp.tid()
        pi = slots.particle[i]
        if pi < 0 or active[0] == 0:
            return
        xi4 = slots.xm[i]
        p = params[0]
        if particle_inv_mass[pi] == 0.0:
            if store_warm != 0 and p.warm_start > 0.0:
                particle_lambda[pi] = p.warm_start * lambda_sum[i]
            if apply.on == APPLY_AS_XPBD:
                x, v = applied_particle(apply, pi, particle_deltas[pi])
                apply.xm[i] = wp.vec4(x[0], x[1], x[2], xi4[3])
                apply.v[i] = v
            elif apply.on == APPLY_ADVANCE:
                x = apply.x_pred[pi] + particle_deltas[pi]
                apply.xm[i] = wp.vec4(x[0], x[1], x[2], xi4[3])
            return
        lr_i = lambda_rho[i]
        lam_i = lr_i[0]
        rel_i = lr_i[1]
        wall_g = wall_grad[i]
        me = CorrectionSlot()
        me.xm = xi4
        me.lam = lam_i
        me.rel = rel_i
        me.particle = pi
        me.lambda_rho = lambda_rho
        acc = wp.static(density_correction_sum)(slots, i, me, p, wp.spatial_vector(wp.vec3(0.0), wp.vec3(0.0)))
        dx = wp.spatial_top(acc) + wall_g * lam_i
        coh = wp.spatial_bottom(acc)
        relaxation = p.relaxation
        if closing != 0:
            relaxation = p.closing_relaxation
        dx = relaxed_correction(dx, relaxation, p)
        if p.cohesion > 0.0:
            # the bias is bounded so a crowded neighbourhood cannot pull harder than one rest spacing allows
            coh *= p.cohesion
            coh_len = wp.length(coh)
            coh_max = 4.0 * p.cohesion
            if coh_len > coh_max:
                coh *= coh_max / coh_len
            dx += coh
        delta = particle_deltas[pi] + dx
        particle_deltas[pi] = delta
        if p.warm_start > 0.0:
            lam_sum = lambda_sum[i] + lam_i
            lambda_sum[i] = lam_sum
            if store_warm != 0:
                particle_lambda[pi] = p.warm_start * lam_sum
        if apply.on == APPLY_AS_XPBD:
            x, v = applied_particle(apply, pi, delta)
            apply.xm[i] = wp.vec4(x[0], x[1], x[2], xi4[3])
            apply.v[i] = v
        elif apply.on == APPLY_ADVANCE:
            x = apply.x_pred[pi] + delta
            apply.xm[i] = wp.vec4(x[0], x[1], x[2], xi4[3])

    def apply_fluid_warm_start(
        params: wp.array[FluidParams],
        slots: FluidSlots,
        active: wp.array[wp.int32],
        warm_lambda: wp.array[float],
        particle_inv_mass: wp.array[float],
        wall_table: wp.array[float],
        wall_table_grad: wp.array[float],
        # outputs
        particle_deltas: wp.array[wp.vec3],
        moved_xm: wp.array[wp.vec4],
        lambda_sum: wp.array[float],
    ):
        """Start the substep's density solve from the multipliers of the last one (warm start).

        Moves slot ``i`` by the correction of the carried multipliers ``warm_lambda`` (gathered into slot
        order by the sort, :meth:`~.neighbors.FluidNeighborSearch.carry_values`; as
        :func:`apply_fluid_density_correction` does with fresh ones, without cohesion) before the first
        density evaluation, writing the moved position to ``moved_xm`` (the other position buffer: the
        neighbours' positions are read from ``slots.xm`` meanwhile): a load the fluid carried last
        substep, like the weight of a deep column, is already held when the iterations start, which then
        only correct what changed. Starts the substep's sum of multipliers from the carried one.
        """
        i = wp.tid()
        pi = slots.particle[i]
        if pi < 0:
            return
        xi4 = slots.xm[i]
        lam_i = warm_lambda[i]
        lambda_sum[i] = lam_i
        p = params[0]
        if active[0] == 0 or p.warm_start <= 0.0 or particle_inv_mass[pi] == 0.0:
            moved_xm[i] = xi4
            return
        xi = wp.vec3(xi4[0], xi4[1], xi4[2])
        wall = fluid_wall_share(slots, i, xi, p, wall_table, wall_table_grad)
        me = WarmStartSlot()
        me.xm = xi4
        me.lam = lam_i
        me.particle = pi
        me.warm_lambda = warm_lambda
        dx = wp.static(warm_start_sum)(slots, i, me, p, wp.vec3(wall[0], wall[1], wall[2]) * lam_i)
        dx = relaxed_correction(dx, p.relaxation, p)
        particle_deltas[pi] = particle_deltas[pi] + dx
        moved_xm[i] = wp.vec4(xi[0] + dx[0], xi[1] + dx[1], xi[2] + dx[2], xi4[3])

    return DensityPasses(
        lambda_pass(False),
        lambda_pass(True) if damped else None,
        wp.kernel(named_variant(apply_fluid_density_correction, suffix)),
        wp.kernel(named_variant(apply_fluid_warm_start, suffix)),
        pair_weight,
        pair_slope,
        density_correction_sum,
        suffix,
    )
