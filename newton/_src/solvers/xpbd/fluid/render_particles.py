# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Render particles: smoothed positions and anisotropic ellipsoids for drawing a fluid surface.

After Yu & Turk, "Reconstructing surfaces of particle-based fluids using anisotropic kernels",
ACM TOG 32(1), 2013: each fluid particle gets the weighted mean ``x_bar`` of its neighbourhood
(weights ``w = 1 - (r/h)^3``, itself included) and the weighted covariance of the neighbours
about it. The drawn centre is ``(1 - s) x + s x_bar``; the ellipsoid axes are the covariance's
eigenvectors, and their radius scales the square roots of its eigenvalues normalised to a unit
product (so a uniform neighbourhood gives a sphere of scale 1, a sheet a flat disk, a strand a
needle), clamped to ``[anisotropy_min, anisotropy_max]`` and multiplied by ``anisotropy_scale``.
Particles with fewer than ``MIN_NEIGHBORS`` neighbours are drawn as spheres.

Nothing here feeds back into the simulation.
"""

import warp as wp

from .sph import FluidParams, FluidSlots, fluid_neighbor_layout, neighbor_sum

# below this many neighbours a covariance says little about the shape: draw a sphere
MIN_NEIGHBORS = 6


@wp.struct
class RenderSlot:
    """What a neighbour's weighted position and spread need of slot ``i``."""

    x: wp.vec3  # position [m]
    mean: wp.vec3  # weighted mean of the neighbourhood [m] (for the spread)


@wp.func
def neighbor_weight(slots: FluidSlots, j: int, me: RenderSlot, p: FluidParams):
    """Position (xyz) and weight ``1 - (r/h)^3`` (w, 0 beyond h) of neighbour ``j``."""
    xj4 = slots.xm[j]
    xj = wp.vec3(xj4[0], xj4[1], xj4[2])
    r = xj - me.x
    r2 = wp.dot(r, r)
    w = float(0.0)
    if r2 < p.h2:
        q = wp.sqrt(r2 / p.h2)
        w = 1.0 - q * q * q
    return wp.vec4(xj[0], xj[1], xj[2], w)


@wp.func
def weighted_position_term(slots: FluidSlots, j: int, me: RenderSlot, p: FluidParams):
    """Neighbour ``j``'s weighted position (xyz) and weight (w)."""
    n = neighbor_weight(slots, j, me, p)
    xw = wp.vec3(n[0], n[1], n[2]) * n[3]
    return wp.vec4(xw[0], xw[1], xw[2], n[3])


@wp.func
def spread_term(slots: FluidSlots, j: int, me: RenderSlot, p: FluidParams):
    """Neighbour ``j``'s weighted outer product of its offset from the mean."""
    n = neighbor_weight(slots, j, me, p)
    d = wp.vec3(n[0], n[1], n[2]) - me.mean
    return wp.outer(d, d) * n[3]


weighted_position_sum = neighbor_sum(weighted_position_term)


spread_sum = neighbor_sum(spread_term)


@wp.kernel
def reset_render_particles(
    particle_q: wp.array[wp.vec3],
    anisotropy_scale: float,
    # outputs
    render_positions: wp.array[wp.vec3],
    axis_1: wp.array[wp.vec4],
    axis_2: wp.array[wp.vec4],
    axis_3: wp.array[wp.vec4],
):
    """Every particle as itself, a sphere: the fluid pass then overwrites the fluid particles."""
    pi = wp.tid()
    render_positions[pi] = particle_q[pi]
    axis_1[pi] = wp.vec4(1.0, 0.0, 0.0, anisotropy_scale)
    axis_2[pi] = wp.vec4(0.0, 1.0, 0.0, anisotropy_scale)
    axis_3[pi] = wp.vec4(0.0, 0.0, 1.0, anisotropy_scale)


@wp.kernel
def compute_fluid_render_particles(
    params: wp.array[FluidParams],
    slots: FluidSlots,
    smoothing: float,
    anisotropy_scale: float,
    anisotropy_min: float,
    anisotropy_max: float,
    # outputs
    render_positions: wp.array[wp.vec3],
    axis_1: wp.array[wp.vec4],
    axis_2: wp.array[wp.vec4],
    axis_3: wp.array[wp.vec4],
):
    i = wp.tid()
    pi = slots.particle[i]
    if pi < 0:
        return
    p = params[0]
    h2 = p.h2
    xi4 = slots.xm[i]
    xi = wp.vec3(xi4[0], xi4[1], xi4[2])
    me = RenderSlot()
    me.x = xi
    # the particle itself at weight 1
    sums = weighted_position_sum(slots, i, me, p, wp.vec4(xi[0], xi[1], xi[2], 1.0))
    w_sum = sums[3]
    mean = wp.vec3(sums[0], sums[1], sums[2]) / w_sum
    render_positions[pi] = xi * (1.0 - smoothing) + mean * smoothing
    if fluid_neighbor_layout(slots, i)[2] < MIN_NEIGHBORS:
        return
    me.mean = mean
    d = xi - mean
    cov = spread_sum(slots, i, me, p, wp.outer(d, d)) / w_sum
    q, e = wp.eig3(cov)
    floor = 1.0e-6 * h2
    s0 = wp.sqrt(wp.max(e[0], floor))
    s1 = wp.sqrt(wp.max(e[1], floor))
    s2 = wp.sqrt(wp.max(e[2], floor))
    norm = 1.0 / wp.pow(s0 * s1 * s2, 1.0 / 3.0)
    s = wp.vec3(s0 * norm, s1 * norm, s2 * norm)
    # order the axes by decreasing radius: axis_1 is the longest
    a = int(0)
    c = int(2)
    for k in range(3):
        if s[k] > s[a]:
            a = k
        if s[k] < s[c]:
            c = k
    if a == c:
        c = 2 - a
    b = 3 - a - c
    ra = wp.clamp(s[a], anisotropy_min, anisotropy_max) * anisotropy_scale
    rb = wp.clamp(s[b], anisotropy_min, anisotropy_max) * anisotropy_scale
    rc = wp.clamp(s[c], anisotropy_min, anisotropy_max) * anisotropy_scale
    axis_1[pi] = wp.vec4(q[0, a], q[1, a], q[2, a], ra)
    axis_2[pi] = wp.vec4(q[0, b], q[1, b], q[2, b], rb)
    axis_3[pi] = wp.vec4(q[0, c], q[1, c], q[2, c], rc)
