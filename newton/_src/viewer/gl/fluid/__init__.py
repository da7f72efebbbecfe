# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""``viewer.log_fluid`` and ``viewer.log_fluid_diffuse``: a fluid surface and foam sprites in ViewerGL,
a surface mesh in the USD, Rerun and Viser viewers, points in the batch colour everywhere else.

:func:`activate` hands :mod:`.upstream`, the one module of the viewer extension that touches upstream
names, what to add: ``log_fluid`` on ``ViewerBase`` (the point fallback every viewer inherits), its
drawing on ``ViewerGL`` with the screen-space surface of :mod:`.renderer` and on ``ViewerUSD`` (and so
``ViewerRTX``), ``ViewerRerun`` and ``ViewerViser`` with the extracted mesh of :mod:`.surface_mesh`,
the ``fluid_surface`` toggle and the ``ViewerGL.fluid_renderer`` accessor.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from . import upstream
from .renderer import DiffuseMaterial, FluidMaterial


def _check_material(
    radius_scale, color, absorption, ior, reflectance, specular_intensity, specular_power, blur_radius_world
):
    def bad(name, value, valid):
        return ValueError(f"{name}={value!r} is out of range: expected {valid}")

    if not (isinstance(radius_scale, (int, float)) and math.isfinite(radius_scale) and radius_scale > 0.0):
        raise bad("radius_scale", radius_scale, "a value in (0, inf)")
    c = np.asarray(color, dtype=np.float64).ravel()
    if c.size not in (3, 4) or not np.all(np.isfinite(c)) or np.any(c < 0.0) or np.any(c > 1.0):
        raise bad("color", color, "3 or 4 values (RGB or RGBA) in [0, 1]")
    if absorption is not None:
        a = np.asarray(absorption, dtype=np.float64).ravel()
        if a.size != 3 or not np.all(np.isfinite(a)) or np.any(a < 0.0):
            raise bad("absorption", absorption, "None or 3 values in [0, inf) [1/m]")
    if not (math.isfinite(ior) and 1.0 <= ior <= 3.0):
        raise bad("ior", ior, "a value in [1, 3]")
    if not (0.0 <= reflectance <= 1.0):
        raise bad("reflectance", reflectance, "a value in [0, 1]")
    if not (math.isfinite(specular_intensity) and specular_intensity >= 0.0):
        raise bad("specular_intensity", specular_intensity, "a value in [0, inf)")
    if not (math.isfinite(specular_power) and specular_power >= 1.0):
        raise bad("specular_power", specular_power, "a value in [1, inf)")
    if blur_radius_world is not None and not (math.isfinite(blur_radius_world) and blur_radius_world >= 0.0):
        raise bad("blur_radius_world", blur_radius_world, "None or a value in [0, inf) [m]")
    rgba = tuple(float(x) for x in c) + ((1.0,) if c.size == 3 else ())
    return rgba


def _check_axes(positions, anisotropy, anisotropy_secondary, anisotropy_tertiary):
    axes = (anisotropy, anisotropy_secondary, anisotropy_tertiary)
    if all(a is None for a in axes):
        return None
    names = ("anisotropy", "anisotropy_secondary", "anisotropy_tertiary")
    for name, a in zip(names, axes, strict=True):
        if a is None or a.dtype != wp.vec4 or len(a) < len(positions):
            raise ValueError(
                f"{name}={a!r} is invalid: expected the three anisotropy arrays together, each a wp.vec4 array "
                f"with at least {len(positions)} entries (one per position)"
            )
    return axes


def log_fluid(
    self,
    name: str,
    positions: wp.array | None,
    radii: wp.array | float | None = None,
    *,
    radius_scale: float = 1.8,
    color: tuple = (0.2, 0.45, 0.9, 1.0),
    absorption: tuple | None = None,
    ior: float = 1.333,
    reflectance: float = 0.02,
    specular_intensity: float = 0.6,
    specular_power: float = 200.0,
    blur_radius_world: float | None = None,
    anisotropy: wp.array | None = None,
    anisotropy_secondary: wp.array | None = None,
    anisotropy_tertiary: wp.array | None = None,
    hidden: bool = False,
) -> None:
    """Log a batch of fluid particles.

    ViewerGL draws each batch as a screen-space liquid surface (ray-cast ellipsoids, smoothed
    depth, refraction, Beer-Lambert absorption, Fresnel reflection), with the batches of a frame
    occluding each other and the scene correctly. ViewerUSD (and ViewerRTX), ViewerRerun and
    ViewerViser draw it as a triangle mesh extracted by :class:`newton.geometry.ParticleSurface`
    (in USD a time-sampled ``Mesh`` prim per batch with a ``UsdPreviewSurface`` carrying colour,
    opacity, ``ior`` and ``absorption``; see :mod:`newton._src.viewer.gl.fluid.surface_mesh`). With
    ``viewer.fluid_surface = False``, and in every other viewer, the particles are drawn as points in
    the batch colour.

    Args:
        name: Unique path of the batch; logging the same name again replaces it (the particle
            count may change between frames).
        positions: Particle (or render) positions [m], ``wp.array`` of ``wp.vec3``; ``None`` removes the batch.
        radii: Per-particle radii [m] (``wp.array`` of float) or one radius for all; ``None``: 0.1 m.
            A particle of radius r stands for a cube of fluid of edge 2r (Newton's particle
            spacing), which calibrates the thickness.
        radius_scale: Multiplier of ``radii`` for the drawn ellipsoids and points [dimensionless], in (0, inf)
            (an extracted surface mesh takes ``radii`` as they are: they set the fluid's volume).
        color: RGB or RGBA in [0, 1]: the colour the fluid scatters toward the eye, weighted by alpha
            (0: clear, 1: milky); also the transmitted tint when ``absorption`` is None.
        absorption: Absorption coefficients sigma_a [1/m] per channel for Beer-Lambert transmission
            ``T = exp(-sigma_a * thickness)``; ``None``: ``-ln(color.rgb) / 0.1``, i.e. 0.1 m of fluid
            transmits ``color.rgb``.
        ior: Index of refraction in [1, 3] (bends the view of the scene behind).
        reflectance: Fresnel reflectance at normal incidence F0 in [0, 1] (Schlick).
        specular_intensity: Strength of the sun's highlight, in [0, inf).
        specular_power: Blinn-Phong exponent of the highlight, in [1, inf).
        blur_radius_world: Width of the surface smoothing filter [m], in [0, inf); ``None``: the drawn
            particle radius.
        anisotropy: Longest ellipsoid axis per particle, ``wp.vec4`` (unit direction xyz, radius
            scale w), e.g. ``solver.render_anisotropy``; give all three axes or none (spheres).
        anisotropy_secondary: Middle axis, same layout.
        anisotropy_tertiary: Shortest axis, same layout.
        hidden: Whether the batch is hidden.

    Raises:
        ValueError: An argument is out of its range (the message names it, its value and the range).
    """
    if positions is None:
        self._fluid_remove(name)
        return
    rgba = _check_material(
        radius_scale, color, absorption, ior, reflectance, specular_intensity, specular_power, blur_radius_world
    )
    axes = _check_axes(positions, anisotropy, anisotropy_secondary, anisotropy_tertiary)
    material = FluidMaterial(
        color=rgba,
        absorption=None if absorption is None else tuple(float(a) for a in absorption),
        ior=float(ior),
        reflectance=float(reflectance),
        specular_intensity=float(specular_intensity),
        specular_power=float(specular_power),
        blur_radius_world=None if blur_radius_world is None else float(blur_radius_world),
        radius_scale=float(radius_scale),
    )
    self._fluid_draw(name, positions, radii, material, axes, hidden)


def _fluid_remove(self, name):
    """Every viewer but ViewerGL: hide the points of a removed batch."""
    self.log_points(name, None, hidden=True)


def _fluid_draw(self, name, positions, radii, material, axes, hidden):
    """Every viewer but ViewerGL: the particles as points in the batch colour."""
    _log_fluid_points(self, name, positions, radii, material.radius_scale, material.color, hidden)


def _log_fluid_points(viewer, name, positions, radii, radius_scale, color, hidden):
    if radii is None:
        radii = 0.1
    if isinstance(radii, (int, float)):
        radii = float(radii) * radius_scale
    elif radius_scale != 1.0:
        radii = wp.array(radii.numpy()[: len(positions)] * radius_scale, dtype=wp.float32, device=radii.device)
    rgb = wp.vec3(*(float(c) for c in np.asarray(color, dtype=np.float32)[:3]))
    # one colour per point: not every viewer's log_points takes a single RGB triple
    colors = wp.full(len(positions), rgb, dtype=wp.vec3, device=positions.device)
    viewer.log_points(name, positions, radii=radii, colors=colors, hidden=hidden)


def _fluid_draw_mesh(self, name, positions, radii, material, axes, hidden):
    """ViewerUSD, ViewerRerun, ViewerViser: the extracted surface as a dynamic mesh (points when switched off)."""
    from .surface_mesh import draw_surface_mesh, hide_surface_mesh  # noqa: PLC0415

    if self.fluid_surface:
        if not draw_surface_mesh(self, name, positions, radii, material, hidden):
            # no surface this frame (every particle apart from the rest): hide the last one
            hide_surface_mesh(self, name)
        return
    hide_surface_mesh(self, name)
    _log_fluid_points(self, name + "_points", positions, radii, material.radius_scale, material.color, hidden)


def _fluid_remove_mesh(self, name):
    from .surface_mesh import hide_surface_mesh  # noqa: PLC0415

    hide_surface_mesh(self, name)
    self.log_points(name + "_points", None, hidden=True)


def _fluid_remove_gl(self, name):
    fluid_renderer(self).remove_batch(upstream.qualified_name(self, name))
    self.log_points(name, None, hidden=True)


def _fluid_draw_gl(self, name, positions, radii, material, axes, hidden):
    qualified = upstream.qualified_name(self, name)
    fluid = fluid_renderer(self)
    if not self.fluid_surface:
        fluid.hide_batch(qualified)
        _log_fluid_points(self, name, positions, radii, material.radius_scale, material.color, hidden)
        return
    if qualified in self.objects:
        self.objects[qualified].hidden = True
    if radii is None:
        radii = 0.1
    if isinstance(radii, (int, float)):
        radii = float(radii)
    elif radii.dtype != wp.float32 or len(radii) < len(positions):
        raise ValueError(
            f"radii={radii!r} is invalid: expected a float, or a float32 array with one radius per position"
        )
    fluid.set_batch(qualified, positions, radii, material, axes, hidden)


@wp.kernel
def _diffuse_point_radii(lifetimes: wp.array[float], kinds: wp.array[wp.int32], radius: float, radii: wp.array[float]):
    i = wp.tid()
    r = radius
    if lifetimes.shape[0] > 0:
        if lifetimes[i] <= 0.0:
            r = 0.0
    if kinds.shape[0] > 0:
        if kinds[i] < 0:
            r = 0.0
    radii[i] = r


def _check_diffuse(positions, velocities, lifetimes, kinds, radius, color, stretch_time, fade_length):
    def bad(name, value, valid):
        return ValueError(f"{name}={value!r} is out of range: expected {valid}")

    if not (math.isfinite(radius) and radius > 0.0):
        raise bad("radius", radius, "a value in (0, inf) [m]")
    c = np.asarray(color, dtype=np.float64).ravel()
    if c.size not in (3, 4) or not np.all(np.isfinite(c)) or np.any(c < 0.0) or np.any(c > 1.0):
        raise bad("color", color, "3 or 4 values (RGB or RGBA) in [0, 1]")
    if not (math.isfinite(stretch_time) and stretch_time >= 0.0):
        raise bad("stretch_time", stretch_time, "a value in [0, inf) [s]")
    if not (math.isfinite(fade_length) and fade_length > 0.0):
        raise bad("fade_length", fade_length, "a value in (0, inf) [m]")
    for name, a, dtype in (
        ("velocities", velocities, wp.vec3),
        ("lifetimes", lifetimes, wp.float32),
        ("kinds", kinds, wp.int32),
    ):
        if a is not None and (a.dtype != dtype or len(a) < len(positions)):
            raise ValueError(
                f"{name}={a!r} is invalid: expected None or a {dtype.__name__} array with at least {len(positions)} entries"
            )
    return tuple(float(x) for x in c) + ((1.0,) if c.size == 3 else ())


def log_fluid_diffuse(
    self,
    name: str,
    positions: wp.array | None,
    velocities: wp.array | None = None,
    lifetimes: wp.array | None = None,
    kinds: wp.array | None = None,
    *,
    radius: float = 0.005,
    color: tuple = (1.0, 1.0, 1.0, 0.8),
    stretch_time: float = 1.0 / 60.0,
    fade_length: float = 0.05,
    hidden: bool = False,
) -> None:
    """Log a batch of diffuse particles (spray, foam, bubbles), e.g. ``solver.diffuse_positions``.

    ViewerGL draws each live particle as a soft sprite stretched along its screen-space motion,
    composited with the fluid surface: a particle behind the surface fades with the depth of fluid
    in front of it (bubbles show faintly through water), one behind scene geometry is hidden. Every
    other viewer draws the live particles as points in ``color``.

    Args:
        name: Unique path of the batch; ``positions=None`` removes it.
        positions: Positions [m], ``wp.array`` of ``wp.vec3``.
        velocities: Velocities [m/s] (``wp.vec3``) for the motion stretch, e.g. ``solver.diffuse_velocities``.
        lifetimes: Remaining lifetimes [s]; entries <= 0 are not drawn (``solver.diffuse_lifetimes``).
        kinds: Kinds (int32; negative: not drawn; 2: bubble, drawn darker), e.g. ``solver.diffuse_kinds``.
        radius: Sprite radius [m], in (0, inf).
        color: RGB or RGBA in [0, 1]; alpha is the opacity of a sprite's centre.
        stretch_time: The sprite spans the distance moved in this time [s], in [0, inf).
        fade_length: Depth of fluid [m] in front of a particle that dims it by 1/e, in (0, inf).
        hidden: Whether the batch is hidden.

    Raises:
        ValueError: An argument is out of its range (the message names it, its value and the range).
    """
    if positions is None:
        self._fluid_remove_diffuse(name)
        return
    rgba = _check_diffuse(positions, velocities, lifetimes, kinds, radius, color, stretch_time, fade_length)
    material = DiffuseMaterial(color=rgba, stretch_time=float(stretch_time), fade_length=float(fade_length))
    self._fluid_draw_diffuse(name, positions, velocities, lifetimes, kinds, float(radius), material, hidden)


def _fluid_remove_diffuse(self, name):
    self.log_points(name, None, hidden=True)


def _fluid_draw_diffuse(self, name, positions, velocities, lifetimes, kinds, radius, material, hidden):
    """Every viewer but ViewerGL: the live particles as points."""
    _log_diffuse_points(self, name, positions, lifetimes, kinds, radius, material.color, hidden)


def _log_diffuse_points(viewer, name, positions, lifetimes, kinds, radius, rgba, hidden):
    device = positions.device
    radii = wp.empty(len(positions), dtype=float, device=device)
    wp.launch(
        _diffuse_point_radii,
        dim=len(positions),
        inputs=[
            lifetimes if lifetimes is not None else wp.empty(0, dtype=float, device=device),
            kinds if kinds is not None else wp.empty(0, dtype=wp.int32, device=device),
            float(radius),
        ],
        outputs=[radii],
        device=device,
    )
    colors = wp.full(len(positions), wp.vec3(*rgba[:3]), dtype=wp.vec3, device=device)
    viewer.log_points(name, positions, radii=radii, colors=colors, hidden=hidden)


def _fluid_remove_diffuse_gl(self, name):
    fluid_renderer(self).remove_diffuse_batch(upstream.qualified_name(self, name))
    self.log_points(name, None, hidden=True)


def _fluid_draw_diffuse_gl(self, name, positions, velocities, lifetimes, kinds, radius, material, hidden):
    qualified = upstream.qualified_name(self, name)
    fluid = fluid_renderer(self)
    if not self.fluid_surface:
        if qualified in fluid.diffuse_batches:
            fluid.diffuse_batches[qualified].hidden = True
        _log_diffuse_points(self, name, positions, lifetimes, kinds, radius, material.color, hidden)
        return
    if qualified in self.objects:
        self.objects[qualified].hidden = True
    fluid.set_diffuse_batch(qualified, positions, velocities, lifetimes, kinds, radius, material, hidden)


def fluid_renderer(self):
    """The :class:`~newton._src.viewer.gl.fluid.renderer.FluidRendererGL` of this ViewerGL (created on first use)."""
    return upstream.fluid_renderer_of(self)


def activate(viewer_module) -> None:
    """Extend the viewers of ``viewer_module`` (``newton._src.viewer``) through :mod:`.upstream`; idempotent."""
    upstream.activate(
        viewer_module,
        base_methods={
            "log_fluid": log_fluid,
            "_fluid_draw": _fluid_draw,
            "_fluid_remove": _fluid_remove,
            "log_fluid_diffuse": log_fluid_diffuse,
            "_fluid_draw_diffuse": _fluid_draw_diffuse,
            "_fluid_remove_diffuse": _fluid_remove_diffuse,
        },
        mesh_methods={"_fluid_draw": _fluid_draw_mesh, "_fluid_remove": _fluid_remove_mesh},
        gl_methods={
            "_fluid_draw": _fluid_draw_gl,
            "_fluid_remove": _fluid_remove_gl,
            "_fluid_draw_diffuse": _fluid_draw_diffuse_gl,
            "_fluid_remove_diffuse": _fluid_remove_diffuse_gl,
            "fluid_renderer": property(fluid_renderer),
        },
        fluid_surface_doc={
            "mesh": "Draw ``log_fluid`` batches as an extracted surface mesh (True, default) or as points (False).",
            "gl": "Draw ``log_fluid`` batches as a liquid surface (True, default) or as raw particles (False).",
        },
    )
