# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""A heightfield as a solid for the fluid: where a path enters it, and how far a point is from its surface.

A heightfield (:class:`newton.Heightfield`) is a grid of elevations over ``[-hx, hx] x [-hy, hy]`` in
its shape's frame, each cell split along its diagonal into two triangles (the split upstream's
contacts use: the lower-right one where the cell's fractions satisfy ``fx >= fy``). As upstream's
contacts treat it, it is solid below its surface inside that footprint, to any depth, and nothing
outside it. The surface over one triangle is a plane ``z = c + gx x + gy y``, so along a straight
path the height above it is linear in the path's parameter within each triangle: the path is walked
cell by cell (the cells its ground track crosses, in order) and the first triangle where that height
turns negative gives the entry.
"""

import warp as wp

from ....utils.heightfield import HeightfieldData


@wp.func
def _elevation(hf: HeightfieldData, elevation: wp.array[wp.float32], row: int, col: int):
    """Height [m] of grid point (``row``, ``col``) in the shape's frame."""
    return hf.min_z + elevation[hf.data_offset + row * hf.ncol + col] * (hf.max_z - hf.min_z)


@wp.func
def triangle_plane(hf: HeightfieldData, elevation: wp.array[wp.float32], row: int, col: int, upper: bool):
    """The surface over one triangle of cell (``row``, ``col``) as ``z = c + gx x + gy y``: ``vec3(c, gx, gy)``.

    ``upper``: the triangle (p00, p11, p01) where ``fx < fy``; else (p00, p10, p11).
    """
    dx = 2.0 * hf.hx / float(hf.ncol - 1)
    dy = 2.0 * hf.hy / float(hf.nrow - 1)
    h00 = _elevation(hf, elevation, row, col)
    h10 = _elevation(hf, elevation, row, col + 1)
    h01 = _elevation(hf, elevation, row + 1, col)
    h11 = _elevation(hf, elevation, row + 1, col + 1)
    gx = (h10 - h00) / dx
    gy = (h11 - h10) / dy
    if upper:
        gx = (h11 - h01) / dx
        gy = (h01 - h00) / dy
    x0 = -hf.hx + float(col) * dx
    y0 = -hf.hy + float(row) * dy
    return wp.vec3(h00 - gx * x0 - gy * y0, gx, gy)


@wp.func
def _height_above(plane: wp.vec3, p: wp.vec3):
    """``z`` of ``p`` above the plane ``z = c + gx x + gy y`` (vertical, not normal, distance)."""
    return p[2] - (plane[0] + plane[1] * p[0] + plane[2] * p[1])


@wp.func
def _plane_normal(plane: wp.vec3):
    return wp.normalize(wp.vec3(-plane[1], -plane[2], 1.0))


@wp.func
def _cell_of(hf: HeightfieldData, p: wp.vec3):
    """Cell (column, row) holding the ground point of ``p``, and its fractions (clamped to the grid)."""
    u = (p[0] + hf.hx) * float(hf.ncol - 1) / (2.0 * hf.hx)
    v = (p[1] + hf.hy) * float(hf.nrow - 1) / (2.0 * hf.hy)
    col = wp.clamp(int(wp.floor(u)), 0, hf.ncol - 2)
    row = wp.clamp(int(wp.floor(v)), 0, hf.nrow - 2)
    return col, row, u - float(col), v - float(row)


@wp.func
def heightfield_distance(hf: HeightfieldData, elevation: wp.array[wp.float32], p: wp.vec3):
    """Signed distance [m] of local ``p`` to the plane of the surface triangle above or below it (xyz: its upward
    normal, w: the distance, negative below); a point outside the footprint reads as far away (1e10 m)."""
    if hf.nrow <= 1 or hf.ncol <= 1 or wp.abs(p[0]) > hf.hx or wp.abs(p[1]) > hf.hy:
        return wp.vec4(0.0, 0.0, 1.0, 1.0e10)
    col, row, fx, fy = _cell_of(hf, p)
    plane = triangle_plane(hf, elevation, row, col, fx < fy)
    n = _plane_normal(plane)
    d = _height_above(plane, p) * n[2]
    return wp.vec4(n[0], n[1], n[2], d)


@wp.func
def heightfield_entry(hf: HeightfieldData, elevation: wp.array[wp.float32], a: wp.vec3, d: wp.vec3):
    """Where the path ``a + t d``, ``t`` in [0, 1], first goes below the surface from above it (``w``; 2: it does
    not, nor from a start already below), and the outward normal there (``xyz``), in the shape's frame.

    A path that comes in through the footprint's side below the surface enters there, with the side's
    normal (the solid has a wall where its footprint ends).
    """
    none = wp.vec4(0.0, 0.0, 1.0, 2.0)
    if hf.nrow <= 1 or hf.ncol <= 1:
        return none
    top = wp.max(hf.min_z, hf.max_z)
    if wp.min(a[2], a[2] + d[2]) >= top:
        return none
    # the part of the path over the footprint, and the side it comes in through
    t0 = float(0.0)
    t1 = float(1.0)
    side = wp.vec3(0.0, 0.0, 1.0)
    for k in range(2):
        half = wp.where(k == 0, hf.hx, hf.hy)
        if wp.abs(d[k]) < 1.0e-30:
            if wp.abs(a[k]) > half:
                return none
        else:
            near = (-wp.sign(d[k]) * half - a[k]) / d[k]
            far = (wp.sign(d[k]) * half - a[k]) / d[k]
            if near > t0:
                t0 = near
                side = wp.vec3(0.0, 0.0, 0.0)
                side[k] = -wp.sign(d[k])
            t1 = wp.min(t1, far)
    if t0 > t1:
        return none
    # grid coordinates along the path: u = u0 + t du (columns), v = v0 + t dv (rows)
    su = float(hf.ncol - 1) / (2.0 * hf.hx)
    sv = float(hf.nrow - 1) / (2.0 * hf.hy)
    u0 = (a[0] + hf.hx) * su
    v0 = (a[1] + hf.hy) * sv
    du = d[0] * su
    dv = d[1] * sv
    col, row, fx, fy = _cell_of(hf, a + t0 * d)
    ts = t0
    first = bool(True)
    # (every cell the ground track crosses: at most one per grid line, and a path crosses each line once)
    for _step in range(hf.ncol + hf.nrow):
        next_u = float(1.0e30)
        if du > 0.0:
            next_u = (float(col + 1) - u0) / du
        elif du < 0.0:
            next_u = (float(col) - u0) / du
        next_v = float(1.0e30)
        if dv > 0.0:
            next_v = (float(row + 1) - v0) / dv
        elif dv < 0.0:
            next_v = (float(row) - v0) / dv
        te = wp.min(t1, wp.min(next_u, next_v))
        # the cell's diagonal fx = fy splits [ts, te] where e(t) = (u - col) - (v - row) changes sign
        e0 = (u0 - float(col)) - (v0 - float(row))
        de = du - dv
        cut = te
        if de != 0.0:
            cut = wp.clamp(-e0 / de, ts, te)
        for part in range(2):
            s0 = wp.where(part == 0, ts, cut)
            s1 = wp.where(part == 0, cut, te)
            if part == 0 or s1 > s0:
                mid = 0.5 * (s0 + s1)
                plane = triangle_plane(hf, elevation, row, col, e0 + mid * de < 0.0)
                g0 = _height_above(plane, a + s0 * d)
                g1 = _height_above(plane, a + s1 * d)
                if g0 < 0.0 and first:
                    if t0 <= 0.0:
                        # it starts below (upstream's contact pushes it out)
                        return none
                    return wp.vec4(side[0], side[1], side[2], t0)
                first = False
                if g0 < 0.0 or g1 < 0.0:
                    # (below at s0 only by the rounding of the last triangle's height, which was not)
                    t = s0
                    if g0 > 0.0:
                        t = s0 + (s1 - s0) * g0 / (g0 - g1)
                    n = _plane_normal(plane)
                    return wp.vec4(n[0], n[1], n[2], t)
        if te >= t1:
            return none
        if next_u <= next_v:
            col += wp.where(du > 0.0, 1, -1)
        else:
            row += wp.where(dv > 0.0, 1, -1)
        if col < 0 or col > hf.ncol - 2 or row < 0 or row > hf.nrow - 2:
            return none
        ts = te
    return none
