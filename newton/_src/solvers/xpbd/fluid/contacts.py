# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Upstream's particle-particle contacts with the fluid-fluid pairs left out (swapped in by :mod:`.upstream`)."""

import warp as wp

from ....geometry import ParticleFlags

# approximate division and square root in CUDA code (no effect on the CPU; see :mod:`.sph`)
wp.set_module_options({"fast_math": True})


@wp.kernel
def solve_particle_particle_contacts_skip_fluid_pairs(
    grid: wp.uint64,
    particle_x: wp.array[wp.vec3],
    particle_v: wp.array[wp.vec3],
    particle_invmass: wp.array[float],
    particle_radius: wp.array[float],
    particle_flags: wp.array[wp.int32],
    k_mu: float,
    k_cohesion: float,
    max_radius: float,
    dt: float,
    relaxation: float,
    # outputs
    deltas: wp.array[wp.vec3],
):
    """Particle contacts for models with fluid: a pair of two fluid particles is left to the density constraint.

    Same launch signature as upstream's particle-contact kernel (:mod:`.upstream` checks it and swaps
    this one in only while a fluid solver steps), and for every other pair upstream's contact law
    in upstream's order of operations, so that granular particles and cloth step bitwise as without
    fluid. For a pair at distance ``d`` with gap ``e = d - r_i - r_j <= k_cohesion``, normal ``n`` and
    tangential relative velocity ``v_t``, particle ``i`` moves by

        w_i * relaxation * sum_j (normalize(v_t) * max(mu * e, -|v_t| dt) - n * e) / (w_i + w_j)

    (inside the cohesion band, ``e > 0``, the friction term is upstream's too).
    """
    tid = wp.tid()
    i = wp.hash_grid_point_id(grid, tid)
    if i == -1:
        return
    flags_i = particle_flags[i]
    if (flags_i & ParticleFlags.ACTIVE) == 0:
        return
    fluid_i = (flags_i & ParticleFlags.FLUID) != 0
    proxy_i = (flags_i & ParticleFlags.PROXY) != 0
    xi = particle_x[i]
    vi = particle_v[i]
    ri = particle_radius[i]
    wi = particle_invmass[i]
    correction = wp.vec3(0.0)
    query = wp.hash_grid_query(grid, xi, ri + max_radius + k_cohesion)
    j = int(0)
    while wp.hash_grid_query_next(query, j):
        if j == i:
            continue
        flags_j = particle_flags[j]
        if (flags_j & ParticleFlags.ACTIVE) == 0:
            continue
        if fluid_i and (flags_j & ParticleFlags.FLUID) != 0:
            continue
        if proxy_i and ((flags_j & ParticleFlags.PROXY) != 0 or particle_invmass[j] <= 0.0):
            continue
        offset = xi - particle_x[j]
        dist = wp.length(offset)
        gap = dist - ri - particle_radius[j]
        w_sum = wi + particle_invmass[j]
        if gap <= k_cohesion and w_sum > 0.0 and dist > 0.0:
            n = offset / dist
            v_rel = vi - particle_v[j]
            normal = n * gap
            v_t = v_rel - n * wp.dot(n, v_rel)
            friction = wp.normalize(v_t) * wp.max(k_mu * gap, -wp.length(v_t) * dt)
            correction += (friction - normal) / w_sum
    wp.atomic_add(deltas, i, correction * wi * relaxation)
