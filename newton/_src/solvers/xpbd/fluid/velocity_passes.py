# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The velocity passes after the step: viscosity, the non-affine damping, vorticity confinement, recovery.

:func:`apply_fluid_viscosity` blends each fluid particle's velocity toward its neighbourhood
(XSPH) and removes a share of its deviation from the affine velocity field fitted to the
neighbourhood, the latter once in each interval of about ``NONAFFINE_DAMPING_INTERVAL``
(:func:`damping_every`); :func:`confine_vorticity_and_recover` adds vorticity confinement (Fedkiw et al. 2001)
and, as the substep's last pass, recovers particles whose state went non-finite.
"""

import warp as wp

from ....geometry import ParticleFlags
from .config import NONAFFINE_DAMPING_INTERVAL, NONAFFINE_DAMPING_STEP
from .sph import FluidParams, FluidSlots, fluid_neighbor, fluid_neighbor_layout, neighbor_sum, poly6, spiky_gradient

# approximate division and square root in CUDA code (no effect on the CPU; see :mod:`.sph`)
wp.set_module_options({"fast_math": True})


def damping_every(dt: float) -> int:
    """Substeps of ``dt`` [s] from one non-affine damping to the next: the count nearest ``NONAFFINE_DAMPING_INTERVAL``, at least 1."""
    return max(1, round(NONAFFINE_DAMPING_INTERVAL / dt))


def damping_steps(dt: float) -> float:
    """Reference steps (``NONAFFINE_DAMPING_STEP``) that one damping of substeps of ``dt`` [s] stands for."""
    return damping_every(dt) * dt / NONAFFINE_DAMPING_STEP


@wp.func
def damping_due(clock: wp.array[wp.int32], every: int):
    """Whether this substep applies the non-affine damping: the last of each ``every`` substeps."""
    return clock[0] % every == every - 1


@wp.func
def velocity_pass_on(p: FluidParams, due: bool):
    """Whether the velocity pass runs: for viscosity, the vorticity estimate of confinement, or a damping that is ``due``."""
    return p.viscosity > 0.0 or p.vorticity > 0.0 or (p.nonaffine_damping > 0.0 and due)


@wp.kernel
def advance_damping_clock(every: int, clock: wp.array[wp.int32]):
    """Count the substep toward the next non-affine damping (on the device, so that a captured step keeps count)."""
    clock[0] = (clock[0] + 1) % every


@wp.kernel
def gather_fluid_state(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    particle_mass: wp.array[float],
    for_velocity_pass: int,
    clock: wp.array[wp.int32],
    damping_every: int,
    # outputs
    sorted_v: wp.array[wp.vec3],
):
    """Gather positions, masses and velocities into slot order (for the velocity pass: only if it runs).

    ``clock`` and ``damping_every`` say whether the damping is due (:func:`damping_due`); read only for the velocity pass.
    """
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0:
        return
    if for_velocity_pass != 0 and not velocity_pass_on(params[0], damping_due(clock, damping_every)):
        return
    x = particle_q[pi]
    slots.xm[i] = wp.vec4(x[0], x[1], x[2], particle_mass[pi])
    sorted_v[i] = particle_qd[pi]


@wp.func
def affine_velocity_at_particle(s0: float, sx: wp.vec3, sv: wp.vec3, sxx: wp.mat33, svx: wp.mat33, p: FluidParams):
    """Velocity at the particle of the affine field ``v(x) = v_bar + A (x - x_bar)`` fitted to its neighbourhood.

    The moments are weighted sums over the neighbourhood (the particle included) of 1, the offsets
    ``r_j = x_j - x_i``, the velocities, ``r_j r_j^T`` and ``v_j r_j^T``. ``A`` is the weighted
    least-squares velocity gradient ``C_vx (C_xx + eps I)^-1`` (moving least squares of first order),
    so the field reproduces any uniform, rotating, shearing or expanding motion exactly; ``eps`` keeps a
    flat or thin neighbourhood (a surface, a filament) from amplifying noise.
    """
    inv = 1.0 / s0
    x_bar = sx * inv
    v_bar = sv * inv
    c_xx = sxx * inv - wp.outer(x_bar, x_bar) + wp.identity(n=3, dtype=float) * p.affine_regularizer
    c_vx = svx * inv - wp.outer(v_bar, x_bar)
    grad_v = c_vx * wp.inverse(c_xx)
    # the particle sits at r = 0
    return v_bar - grad_v * x_bar


@wp.kernel
def apply_fluid_viscosity(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    sorted_v: wp.array[wp.vec3],
    density: wp.array[float],
    clock: wp.array[wp.int32],
    damping_every: int,
    damping_steps: float,
    # outputs
    particle_qd: wp.array[wp.vec3],
    vorticity: wp.array[wp.vec3],
):
    """The substep's velocity pass: XSPH viscosity, non-affine damping and the vorticity estimate, in one loop.

    Viscosity blends each velocity toward the mass- and density-weighted (Shepard) neighbourhood
    velocity: ``v_i <- v_i + nu (sum_j V_j W_ij v_j / sum_j V_j W_ij - v_i)`` with ``V_j = m_j / rho_j``,
    the sums including ``j = i``. The non-affine damping removes the share ``beta`` of the velocity's
    deviation from the affine field fitted to the neighbourhood with the same weights
    (:func:`affine_velocity_at_particle`): ``v_i <- v_i + beta (v_aff(x_i) - v_i)``. It is applied on the
    last of each ``damping_every`` substeps (:func:`damping_due` of ``clock``), which stand for
    ``damping_steps`` reference steps (``NONAFFINE_DAMPING_STEP``), with ``beta = 1 - (1 - damping)^steps``:
    the damping per second follows neither the substep count nor how often it is applied. Motion the kernel
    resolves (translation, rotation, shear, expansion across ``h``) is left alone; what goes is the
    particle-scale jitter no smooth field carries. Both act on the velocities of the step's result.
    With vorticity confinement on, the same loop also estimates the vorticity
    ``omega_i = sum_j V_j (v_j - v_i) x grad W_ij`` for the confinement pass.
    """
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0:
        return
    p = params[0]
    # checked here rather than by a conditional graph node, which costs more than this launch
    due = damping_due(clock, damping_every)
    if not velocity_pass_on(p, due):
        return
    compute_vorticity = p.vorticity > 0.0
    fit_affine = p.nonaffine_damping > 0.0 and due
    xi4 = slots.xm[i]
    xi = wp.vec3(xi4[0], xi4[1], xi4[2])
    vi = sorted_v[i]
    w_self = xi4[3] / wp.max(density[i], 1.0e-6) * poly6(0.0, p)
    num = vi * w_self
    den = w_self
    sx = wp.vec3(0.0)
    sxx = wp.mat33(0.0)
    svx = wp.mat33(0.0)
    omega = wp.vec3(0.0)
    # six moments at once, one neighbour per trip (two per trip gained nothing at 100k and lost at 1M:
    # docs/archive/performance_notebook.md): written out rather than a neighbor_sum of a 28-float term
    layout = fluid_neighbor_layout(slots, i)
    count = layout[2]
    for k in range(count):
        j = fluid_neighbor(slots, i, k, layout)
        xj4 = slots.xm[j]
        r = xi - wp.vec3(xj4[0], xj4[1], xj4[2])
        r2 = wp.dot(r, r)
        if r2 < p.h2:
            vol_j = xj4[3] / wp.max(density[j], 1.0e-6)
            w = vol_j * poly6(r2, p)
            vj = sorted_v[j]
            num += vj * w
            den += w
            if fit_affine:
                # offsets from the particle to its neighbour
                sx -= r * w
                sxx += wp.outer(r, r) * w
                svx -= wp.outer(vj, r) * w
            if compute_vorticity:
                omega += wp.cross(vj - vi, spiky_gradient(r, r2, pi, slots.particle, j, p)) * vol_j
    v = vi
    if p.viscosity > 0.0:
        v += (num / den - vi) * p.viscosity
    if fit_affine:
        # (exact at the reference step, where fast math's power would round)
        beta = p.nonaffine_damping
        if damping_steps != 1.0:
            beta = 1.0 - wp.pow(1.0 - beta, damping_steps)
        v += (affine_velocity_at_particle(den, sx, num, sxx, svx, p) - vi) * beta
    if p.viscosity > 0.0 or fit_affine:
        particle_qd[pi] = v
    if compute_vorticity:
        vorticity[i] = omega


@wp.struct
class VorticitySlot:
    """What a neighbour's share of the vorticity-magnitude gradient needs of slot ``i``."""

    x: wp.vec3  # position [m]
    particle: int  # particle index
    density: wp.array[float]  # every slot's density [kg/m^3]
    vorticity: wp.array[wp.vec3]  # every slot's vorticity [1/s]


@wp.func
def vorticity_gradient_term(slots: FluidSlots, j: int, me: VorticitySlot, p: FluidParams):
    """Neighbour ``j``'s share of ``eta = sum_j V_j |omega_j| grad W_ij`` (zero beyond ``h``)."""
    xj4 = slots.xm[j]
    r = me.x - wp.vec3(xj4[0], xj4[1], xj4[2])
    r2 = wp.dot(r, r)
    if r2 >= p.h2:
        return wp.vec3(0.0)
    vol_j = xj4[3] / wp.max(me.density[j], 1.0e-6)
    return spiky_gradient(r, r2, me.particle, slots.particle, j, p) * (vol_j * wp.length(me.vorticity[j]))


vorticity_gradient_sum = neighbor_sum(vorticity_gradient_term)


@wp.func
def recover_fluid_particle(
    k: int,
    pi: int,
    particle_flags: wp.array[wp.int32],
    rest_distance: float,
    dt: float,
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    last_finite_q: wp.array[wp.vec3],
    nonfinite_count: wp.array[wp.int32],
    fast_count: wp.array[wp.int32],
):
    """Restore fluid particle ``k`` (particle ``pi``) to its last finite position at rest if it is not finite.

    Counts the recovered particles, and the particles that would travel more than one rest distance
    in the next substep: past that a particle can cross a thin wall before its contact is found.
    """
    if (particle_flags[pi] & ParticleFlags.ACTIVE) == 0:
        return
    x = particle_q[pi]
    v = particle_qd[pi]
    if wp.isfinite(x) and wp.isfinite(v):
        last_finite_q[k] = x
        if wp.length(v) * dt > rest_distance:
            wp.atomic_add(fast_count, 0, 1)
    else:
        particle_q[pi] = last_finite_q[k]
        particle_qd[pi] = wp.vec3(0.0)
        wp.atomic_add(nonfinite_count, 0, 1)


@wp.kernel
def confine_vorticity_and_recover(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    density: wp.array[float],
    vorticity: wp.array[wp.vec3],
    slot_fluid: wp.array[wp.int32],
    fluid_particle: wp.array[wp.int32],
    particle_flags: wp.array[wp.int32],
    dt: float,
    # in/out
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    last_finite_q: wp.array[wp.vec3],
    nonfinite_count: wp.array[wp.int32],
    fast_count: wp.array[wp.int32],
):
    """Vorticity confinement, then the non-finite recovery of the slot's particle (the substep's last pass).

    Confinement: ``v_i += dt * eps * (N x omega_i)`` with ``N`` the normalised gradient of ``|omega|``.
    Then :func:`recover_fluid_particle` for the particle of every slot, the left-out ones included
    (``slot_fluid``: the fluid index of each slot), so the recovery costs no pass of its own.
    """
    i = wp.tid()
    pi = slots.particle[i]
    p = params[0]
    if pi >= 0 and p.vorticity > 0.0:
        xi4 = slots.xm[i]
        xi = wp.vec3(xi4[0], xi4[1], xi4[2])
        me = VorticitySlot()
        me.x = xi
        me.particle = pi
        me.density = density
        me.vorticity = vorticity
        eta = vorticity_gradient_sum(slots, i, me, p, wp.vec3(0.0))
        # grad W points from j to i, so -eta points toward larger |omega|
        eta_len = wp.length(eta)
        if eta_len > 1.0e-9:
            n = -eta / eta_len
            particle_qd[pi] = particle_qd[pi] + wp.cross(n, vorticity[i]) * (p.vorticity * dt)
    f = slot_fluid[i]
    recover_fluid_particle(
        f,
        fluid_particle[f],
        particle_flags,
        p.rest_distance,
        dt,
        particle_q,
        particle_qd,
        last_finite_q,
        nonfinite_count,
        fast_count,
    )


@wp.kernel
def recover_nonfinite_fluid(
    params: wp.array[FluidParams],
    fluid_particle: wp.array[wp.int32],
    particle_flags: wp.array[wp.int32],
    dt: float,
    # in/out
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    last_finite_q: wp.array[wp.vec3],
    nonfinite_count: wp.array[wp.int32],
    fast_count: wp.array[wp.int32],
):
    """:func:`recover_fluid_particle` for every fluid particle (where the substep ends without the vorticity pass)."""
    k = wp.tid()
    recover_fluid_particle(
        k,
        fluid_particle[k],
        particle_flags,
        params[0].rest_distance,
        dt,
        particle_q,
        particle_qd,
        last_finite_q,
        nonfinite_count,
        fast_count,
    )
