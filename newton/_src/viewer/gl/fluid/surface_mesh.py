# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The fluid as a triangle mesh, for the viewers that draw meshes but not ViewerGL's screen-space surface.

``ViewerUSD``, ``ViewerRerun`` and ``ViewerViser`` draw each ``log_fluid`` batch as the isosurface
that Newton's particle-surface extractor (:class:`newton.geometry.ParticleSurface`: Yu & Turk's
anisotropic kernels and marching cubes) builds around the batch's positions, usually the solver's
render particles. The mesh's topology changes every frame, so it is logged as a dynamic mesh (in
USD, time-sampled points, faces and normals on one ``Mesh`` prim per batch). ``viewer.fluid_surface
= False`` draws points instead, as in every other viewer.

The extractor is set up for the solver's render particles (``update_render_particles`` at its
default smoothing of 0.5), so that the surface lies where the fluid's mass ends: voxels of ``r``
(the particle radius, as given: ``radius_scale`` sizes ViewerGL's ellipsoids and the points, not the
volume), ``kernel_radius = 3 r``, no smoothing of its own (the render particles are smoothed
already), and the iso-level at which the flat face of a lattice block lies half a spacing (``r``)
beyond its outermost centres. The mesh then encloses the volume the particles stand for (N cubes of
edge 2 r): 98 % for a 12 x 12 x 6 block. Raw simulated positions give a surface about 0.2 spacings
further out. The kernels are round: the extractor takes no anisotropy from outside (the ``anisotropy``
arrays of ``log_fluid`` shape ViewerGL's ellipsoids only), and its own (WPCA) needs more neighbours
than a kernel of 1.5 spacings holds; the smoothed centres already flatten the sheets. USD also gets a
``UsdPreviewSurface`` material with the batch's colour, opacity and index of refraction, and the
absorption coefficients [1/m] as the custom input ``inputs:absorption`` a renderer can read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from .renderer import COLOR_REFERENCE_THICKNESS, FluidMaterial
from .upstream import usd_prim_path

# voxel edge, extraction kernel radius and the kernels' scale, per particle radius (see the module's docstring)
VOXEL_PER_RADIUS = 1.0
KERNEL_RADIUS_PER_RADIUS = 3.0
# with those, the render particles of a lattice block put its flat faces 0.48 rest distances beyond its
# outer centres at this level (measured: 0.55 at the extractor's default of 0.25, 0.44 at 0.35)
ISO_LEVEL = 0.3
# smallest opacity given to a mesh viewer, so that clear water still shows
MIN_OPACITY = 0.2
# water is smooth
ROUGHNESS = 0.05


def mesh_opacity(material: FluidMaterial) -> float:
    """Opacity of the surface mesh: the light absorbed by the colour's reference thickness of fluid, at least ``MIN_OPACITY``."""
    sigma = np.asarray(material.absorption_coefficients(), dtype=np.float64)
    transmitted = float(np.mean(np.exp(-COLOR_REFERENCE_THICKNESS * sigma)))
    return float(np.clip(1.0 - transmitted, MIN_OPACITY, 1.0))


@dataclass
class _Batch:
    """One batch's extraction context (it keeps its buffers between frames) and the radius it was sized for."""

    key: tuple  # (radius rounded, device): a new context when it changes
    surface: object  # newton.geometry.ParticleSurface
    radius: float = 0.0  # [m]
    source: tuple | None = None  # (pointer, length) of the radii array the radius was read from


class FluidSurfaceMeshes:
    """The extraction contexts of one viewer, one per batch."""

    def __init__(self):
        self._batches = {}
        #: batches with a mesh logged (and visible) in the viewer
        self.shown = set()

    def extract(self, name: str, positions: wp.array, radii):
        """The surface mesh of ``positions`` as ``(vertices, indices, normals)``; all ``None`` when there is none.

        Args:
            name: The batch.
            positions: Particle (or render) positions [m].
            radii: Per-particle radii [m] (``wp.array`` of float) or one radius.
        """
        from newton.geometry import ParticleSurface  # noqa: PLC0415

        n = len(positions)
        if n == 0:
            return None, None, None
        device = positions.device
        if radii is None:
            radii = 0.1
        batch = self._batches.get(name)
        if isinstance(radii, (int, float)):
            radius, source = float(radii), None
            radii_array = wp.full(n, radius, dtype=float, device=device)
        else:
            radii_array, source = radii[:n], (radii.ptr, n)
            # the median radius sizes the voxels: read from the device only for another radii array (radii
            # edited in place keep the voxel size they were first read with)
            same = batch is not None and batch.source == source
            radius = batch.radius if same else float(np.median(radii_array.numpy()))
        if not (math.isfinite(radius) and radius > 0.0):
            raise ValueError(f"radii={radii!r} is invalid: expected radii in (0, inf) [m]")
        key = (round(radius, 9), str(device))
        if batch is None or batch.key != key:
            surface = ParticleSurface(
                VOXEL_PER_RADIUS * radius,
                kernel_radius=KERNEL_RADIUS_PER_RADIUS * radius,
                threshold=ISO_LEVEL,
                smooth_lambda=0.0,
                device=device,
            )
            batch = _Batch(key, surface)
            self._batches[name] = batch
        batch.radius, batch.source = radius, source
        return batch.surface.extract(positions, radii_array, compute_normals=True).to_arrays()


def surface_meshes(viewer) -> FluidSurfaceMeshes:
    """The :class:`FluidSurfaceMeshes` of ``viewer`` (created on first use)."""
    meshes = getattr(viewer, "_newton_fluid_meshes", None)
    if meshes is None:
        meshes = FluidSurfaceMeshes()
        viewer._newton_fluid_meshes = meshes
    return meshes


def draw_surface_mesh(viewer, name, positions, radii, material, hidden) -> bool:
    """Log the batch's surface as a dynamic mesh through ``viewer.log_mesh``; False when it has no surface."""
    meshes = surface_meshes(viewer)
    vertices, indices, normals = meshes.extract(name, positions, radii)
    if vertices is None:
        return False
    meshes.shown.add(name)
    usd = hasattr(viewer, "stage")
    # (USD gets its own material below; the other viewers take the colour and opacity as they are)
    viewer.log_mesh(
        name,
        vertices,
        indices,
        normals,
        hidden=hidden,
        backface_culling=False,
        color=None if usd else tuple(material.color[:3]),
        roughness=None if usd else ROUGHNESS,
        dynamic=True,
        opacity=None if usd else mesh_opacity(material),
    )
    if usd:
        bind_usd_water_material(viewer, name, material)
    return True


def bind_usd_water_material(viewer, name: str, material) -> None:
    """Bind a ``UsdPreviewSurface`` with the batch's colour, opacity, IOR and absorption to its mesh prim."""
    from pxr import Gf, Sdf, UsdShade  # noqa: PLC0415

    stage = viewer.stage
    mesh_path = usd_prim_path(viewer, name)
    prim = stage.GetPrimAtPath(mesh_path)
    material_path = f"{mesh_path}_material"
    if not stage.GetPrimAtPath(material_path):
        usd_material = UsdShade.Material.Define(stage, material_path)
        shader = UsdShade.Shader.Define(stage, f"{material_path}/PreviewSurface")
        shader.CreateIdAttr("UsdPreviewSurface")
        usd_material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
        UsdShade.MaterialBindingAPI.Apply(prim)
        UsdShade.MaterialBindingAPI(prim).Bind(usd_material)
    shader = UsdShade.Shader(stage.GetPrimAtPath(f"{material_path}/PreviewSurface"))
    rgb = Gf.Vec3f(*(float(c) for c in material.color[:3]))
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(rgb)
    shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(mesh_opacity(material))
    shader.CreateInput("ior", Sdf.ValueTypeNames.Float).Set(float(material.ior))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(ROUGHNESS)
    shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    absorption = Gf.Vec3f(*material.absorption_coefficients())
    shader.CreateInput("absorption", Sdf.ValueTypeNames.Float3).Set(absorption)


def hide_surface_mesh(viewer, name: str) -> None:
    """Hide the batch's mesh from this frame on, where one was logged (as one degenerate, hidden triangle)."""
    meshes = surface_meshes(viewer)
    if name not in meshes.shown:
        return
    meshes.shown.discard(name)
    device = getattr(viewer, "device", None)
    points = wp.zeros(3, dtype=wp.vec3, device=device)
    viewer.log_mesh(name, points, wp.array([0, 1, 2], dtype=wp.int32, device=device), hidden=True, dynamic=True)
