# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Fill a mesh with fluid particles on the rest lattice: ``ModelBuilder.add_fluid_fill``.

Two kinds of fill, decided by ``fill_height``:

- **the mesh is the water** (``fill_height=None``): lattice points inside a closed mesh (by the
  winding number) whose particle lies inside it, the centre at least half a spacing from the surface;
- **the mesh holds the water** (a cup, a tank, a bowl: ``fill_height`` given): the lattice points
  below ``fill_height`` (along the mesh frame's z axis) that lie in the container's cavity. The
  cavity is what a flood from the sides and the bottom of the lattice cannot reach through
  the free points, the container's walls (points within half a spacing of the surface, or inside a
  closed mesh) blocking it, with the fill height as a lid. A fill line more than a spacing above
  the rim lets the flood in and fills nothing. Open (non-closed) container surfaces work as walls too.

The points are found at build time on the CPU (one Warp launch of mesh queries, then a flood fill
in numpy), placed by ``xform`` and added with :meth:`~newton.ModelBuilder.add_particles` to the
builder's current world.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..geometry.flags import ParticleFlags

# a lattice point is a wall point when its centre lies closer than this many spacings to the surface
WALL_CLEARANCE = 0.5


@wp.kernel
def classify_lattice_points(
    mesh: wp.uint64,
    points: wp.array[wp.vec3],
    max_dist: float,
    # outputs
    distance: wp.array[float],
    inside: wp.array[wp.int32],
):
    i = wp.tid()
    p = points[i]
    q = wp.mesh_query_point_no_sign(mesh, p, max_dist)
    d = max_dist
    if q.result:
        d = wp.length(p - wp.mesh_eval_position(mesh, q.face, q.u, q.v))
    distance[i] = d
    s = wp.mesh_query_point_sign_winding_number(mesh, p, max_dist)
    inside[i] = int(s.result and s.sign < 0.0)


def _grow(cells: np.ndarray) -> np.ndarray:
    """``cells`` and their 6 face neighbours."""
    grown = cells.copy()
    grown[1:] |= cells[:-1]
    grown[:-1] |= cells[1:]
    grown[:, 1:] |= cells[:, :-1]
    grown[:, :-1] |= cells[:, 1:]
    grown[:, :, 1:] |= cells[:, :, :-1]
    grown[:, :, :-1] |= cells[:, :, 1:]
    return grown


def _flood_from_sides_and_bottom(free: np.ndarray) -> np.ndarray:
    """Free cells a 6-connected flood reaches from the x, y and bottom z faces of the grid."""
    reached = np.zeros_like(free)
    for face in (np.s_[0, :, :], np.s_[-1, :, :], np.s_[:, 0, :], np.s_[:, -1, :], np.s_[:, :, 0]):
        reached[face] = free[face]
    while True:
        grown = _grow(reached) & free
        if np.array_equal(grown, reached):
            return reached
        reached = grown


def fluid_fill_points(mesh, spacing: float, fill_height: float | None = None, scale=(1.0, 1.0, 1.0)) -> np.ndarray:
    """Lattice points [m] of a fill, in the mesh's frame (see the module notes); shape (N, 3).

    Args:
        mesh: :class:`newton.Mesh` to fill or fill inside.
        spacing: Lattice spacing [m], > 0.
        fill_height: Water level in the mesh frame [m], or ``None`` to fill the closed mesh itself.
        scale: Scale of the mesh vertices.

    Raises:
        ValueError: A non-closed mesh without ``fill_height``, or a fill that produces no point.
    """
    if not (spacing > 0.0 and np.isfinite(spacing)):
        raise ValueError(f"spacing={spacing!r} is invalid: expected a lattice spacing in (0, inf) [m]")
    if fill_height is not None and not np.isfinite(fill_height):
        raise ValueError(f"fill_height={fill_height!r} is invalid: expected a finite height [m] or None")
    closed = bool(mesh.is_watertight)
    if fill_height is None and not closed:
        raise ValueError(
            "mesh is not closed (watertight): the fill without fill_height needs a closed mesh to fill; "
            "give fill_height to fill an open container up to a level"
        )
    vertices = np.asarray(mesh.vertices, dtype=np.float64) * np.asarray(scale, dtype=np.float64)
    triangles = np.asarray(mesh.indices, dtype=np.int32).reshape(-1, 3)
    if closed:
        # the winding number reads a closed mesh wound inward as all outside: turn it outward
        a, b, c = (vertices[triangles[:, k]] for k in range(3))
        if np.einsum("ij,ij->i", a, np.cross(b, c)).sum() < 0.0:
            triangles = triangles[:, ::-1]
    # two spacings around the mesh: the outermost lattice points are free, so the flood goes around it
    lo, hi = vertices.min(axis=0) - 2.0 * spacing, vertices.max(axis=0) + 2.0 * spacing
    if fill_height is not None:
        # the top layer's particles lie below the water level (above the mesh too: a level over the rim
        # must let the flood in)
        hi[2] = fill_height - 0.5 * spacing
        if hi[2] < lo[2]:
            raise ValueError(
                f"fill_height={fill_height:g} is invalid: the mesh lies above it (its lowest point is at "
                f"{vertices[:, 2].min():g} m in its frame); expected a level inside the container"
            )
    # the lattice is centred on the mesh (a symmetric container fills symmetrically); a container's
    # top layer lies half a spacing below the water level
    centre = 0.5 * (lo + hi)
    if fill_height is not None:
        centre[2] = fill_height - 0.5 * spacing
    axes = []
    for k in range(3):
        first, last = np.floor((lo[k] - centre[k]) / spacing), np.ceil((hi[k] - centre[k]) / spacing)
        axis = centre[k] + spacing * np.arange(first, last + 1.0)
        axes.append(axis[(axis >= lo[k] - 1.0e-9 * spacing) & (axis <= hi[k] + 1.0e-9 * spacing)])
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    points = grid.reshape(-1, 3)
    device = wp.get_device("cpu")
    with wp.ScopedDevice(device):
        query = wp.Mesh(
            points=wp.array(vertices.astype(np.float32), dtype=wp.vec3),
            indices=wp.array(np.ascontiguousarray(triangles).ravel(), dtype=wp.int32),
            support_winding_number=True,
        )
        distance = wp.zeros(len(points), dtype=float)
        inside = wp.zeros(len(points), dtype=wp.int32)
        max_dist = float(np.linalg.norm(hi - lo)) + spacing
        wp.launch(
            classify_lattice_points,
            dim=len(points),
            inputs=[query.id, wp.array(points.astype(np.float32), dtype=wp.vec3), max_dist],
            outputs=[distance, inside],
        )
    distance = distance.numpy().reshape(grid.shape[:3])
    inside = (inside.numpy() != 0).reshape(grid.shape[:3]) & closed
    # a particle may sit exactly at the clearance (a wall the lattice meets there keeps its layer despite
    # float32 rounding), and for the flood such a point is wall: every lattice line crossing the surface
    # then has a wall point, so the flood cannot slip through between two points at the clearance
    clear = distance >= (WALL_CLEARANCE - 1.0e-3) * spacing
    if fill_height is None:
        keep = inside & clear
    else:
        free = (distance >= (WALL_CLEARANCE + 1.0e-3) * spacing) & ~inside
        outside = _flood_from_sides_and_bottom(free)
        # the points at the clearance on the outer side belong to the outside
        outside |= _grow(outside) & clear & ~inside
        keep = clear & ~inside & ~outside
    if not keep.any():
        what = "the closed mesh" if fill_height is None else f"the container below fill_height={fill_height:g}"
        raise ValueError(
            f"the fill of {what} at spacing={spacing:g} produced no particle: the volume is thinner than the "
            "spacing, or (with fill_height) the container is open below the fill line or the line is above its rim"
        )
    return grid[keep]


def add_fluid_fill(
    self,
    mesh,
    spacing: float,
    *,
    xform=None,
    scale=(1.0, 1.0, 1.0),
    fill_height: float | None = None,
    velocity=(0.0, 0.0, 0.0),
    density: float = 1000.0,
    flags: int | None = None,
) -> int:
    """Add fluid particles on a cubic lattice inside a mesh, or inside a container mesh up to a level.

    Without ``fill_height`` the closed ``mesh`` is the water's shape: particles fill it, their centres
    at least half a spacing inside its surface. With ``fill_height`` the mesh is a container (a cup, a
    tank; closed walls or an open surface) and the particles fill its cavity up to that level along
    the mesh frame's z axis (:mod:`newton._src.sim.fluid_fill`). The particles go to the
    builder's current world, with radius ``spacing / 2`` and mass ``density * spacing^3``; pass the
    same ``spacing`` as ``fluid_rest_distance`` to :class:`~newton.solvers.SolverXPBD`.

    Args:
        mesh: :class:`newton.Mesh` to fill or to fill inside.
        spacing: Lattice spacing [m], > 0.
        xform: Placement of the mesh frame in the world (``wp.transform``; for a container on a body, the
            body's pose times the shape's transform). Defaults to the identity.
        scale: Scale of the mesh vertices, as :meth:`add_shape_mesh` takes it. Defaults to 1.
        fill_height: Water level in the mesh frame [m], or ``None`` to fill the closed mesh. Defaults to None.
        velocity: Initial velocity of every particle [m/s]. Defaults to 0.
        density: Rest density of the fluid [kg/m^3], > 0. Defaults to 1000.
        flags: Particle flags. Defaults to ``ACTIVE | FLUID``.

    Returns:
        int: The number of particles added.

    Raises:
        ValueError: A bad argument, a non-closed mesh without ``fill_height``, or a fill with no particle.
    """
    if not (density > 0.0 and np.isfinite(density)):
        raise ValueError(f"density={density!r} is invalid: expected a rest density in (0, inf) [kg/m^3]")
    local = fluid_fill_points(mesh, spacing, fill_height, scale)
    if xform is None:
        world = local
    else:
        t = np.array(wp.transform_get_translation(xform), dtype=np.float64)
        rotation = np.array(wp.quat_to_matrix(wp.transform_get_rotation(xform)), dtype=np.float64).reshape(3, 3)
        world = local @ rotation.T + t
    if flags is None:
        flags = int(ParticleFlags.ACTIVE | ParticleFlags.FLUID)
    n = len(world)
    self.add_particles(
        pos=[wp.vec3(*p) for p in world],
        vel=[wp.vec3(*velocity)] * n,
        mass=[density * spacing**3] * n,
        radius=[0.5 * spacing] * n,
        flags=[int(flags)] * n,
    )
    return n


def activate(builder_module) -> None:
    """Add :func:`add_fluid_fill` to ``ModelBuilder`` (run when ``newton._src.sim.builder`` is imported)."""
    builder_module.ModelBuilder.add_fluid_fill = add_fluid_fill
