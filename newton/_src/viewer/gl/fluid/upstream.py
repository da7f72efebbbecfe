# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The seam with upstream's viewers: the one module of the viewer extension that names an upstream private.

:data:`CLASS_NAMES` are checked when the extension activates (on a miss nothing is patched and the
error names both newton versions); :data:`RENDERER_NAMES` when the first fluid frame is drawn
(``RendererGL`` sets them in its constructor) and :data:`FRAME_NAMES` after ``RendererGL.render`` ran
(it sets them there). Everything the fluid renderer needs from ``RendererGL`` goes through
:class:`UpstreamFrame`, and the body pick's state through :func:`body_pick_distance` and
:func:`body_pick_state`.

With upstream hooks (a compositing pass after the scene with the frame's framebuffer, depth
texture, camera matrices and lights; a present call; a ``qualified_name`` / ``prim_path`` API; the
body pick's hit distance) the private reads here would go, and the ``RendererGL.render`` wrapper with
them.
"""

from __future__ import annotations

import numpy as np

SUPPORTED_NEWTON = "1.8.0"

# upstream names the extension relies on: class attributes checked at activation
CLASS_NAMES = {
    "ViewerBase": ("log_points", "_qualify"),
    "ViewerGL": ("log_points", "_qualify", "set_model"),
    "RendererGL": ("render", "_make_current", "gl"),
    "ViewerUSD": ("log_mesh", "_get_path", "_qualify"),
    "ViewerRerun": ("log_mesh",),
    "ViewerViser": ("log_mesh",),
    "Picking": ("pick", "release", "update", "apply_force", "is_picking", "pick_target", "pick_point"),
}
# the viewers that draw log_fluid as an extracted surface mesh
MESH_VIEWERS = ("ViewerUSD", "ViewerRerun", "ViewerViser")
# RendererGL instance attributes, set by its constructor
RENDERER_NAMES = (
    "_frame_fbo",
    "_frame_texture",
    "_frame_depth_texture",
    "_frame_shader",
    "_frame_vao",
    "_frame_indices",
    "_light_space_matrix",
    "_sun_direction",
    "_env_texture",
    "_shadow_texture",
    "_screen_width",
    "_screen_height",
)
# set by RendererGL.render itself, so checked after it ran
FRAME_NAMES = ("_view_matrix", "_projection_matrix", "camera")
# other upstream instance privates read here
OTHER_PRIVATES = ("_visible_worlds_mask", "_min_dist", "_pick_state", "_env_intensity")


def upstream_error(missing) -> RuntimeError:
    import newton  # noqa: PLC0415

    return RuntimeError(
        f"newton-fluid's viewer extension supports newton {SUPPORTED_NEWTON}, found newton {newton.__version__}: "
        f"missing {', '.join(missing)}"
    )


def upstream_classes(viewer_module) -> dict:
    from newton._src.viewer.gl.opengl import RendererGL  # noqa: PLC0415
    from newton._src.viewer.picking import Picking  # noqa: PLC0415

    classes = {name: getattr(viewer_module, name) for name in ("ViewerBase", "ViewerGL", *MESH_VIEWERS)}
    classes["RendererGL"] = RendererGL
    classes["Picking"] = Picking
    return classes


def check_upstream(viewer_module) -> None:
    """Raise ``RuntimeError`` naming the versions if an upstream viewer name we extend is missing."""
    classes = upstream_classes(viewer_module)
    missing = [f"{c}.{n}" for c, names in CLASS_NAMES.items() for n in names if not hasattr(classes[c], n)]
    if missing:
        raise upstream_error(missing)


def qualified_name(viewer, name: str) -> str:
    """The name ``viewer`` files a logged batch under (its world and path prefixes applied)."""
    return viewer._qualify(name)


def usd_prim_path(viewer, name: str) -> str:
    """The USD prim path ``ViewerUSD`` writes the batch ``name`` to."""
    return viewer._get_path(viewer._qualify(name))


def visible_worlds_mask(viewer):
    """The viewer's mask of drawn worlds, as its own picking is given it."""
    return viewer._visible_worlds_mask


def body_pick_distance(picking) -> float:
    """Distance [m] along the ray of the body the last pick hit (synchronises)."""
    return float(picking._min_dist.numpy()[0])


def body_pick_state(picking):
    """The body pick's device state (stiffness, damping), read by the fluid pick's force kernel."""
    return picking._pick_state


class UpstreamFrame:
    """What the fluid renderer reads from ``RendererGL``: its frame buffer, camera, lights, and the present pass.

    Args:
        renderer: The viewer's ``RendererGL``; raises ``RuntimeError`` naming the versions if it lacks a name.
    """

    def __init__(self, renderer):
        missing = [n for n in RENDERER_NAMES if not hasattr(renderer, n)]
        if missing:
            raise upstream_error([f"RendererGL.{n}" for n in missing])
        self.renderer = renderer

    @property
    def gl(self):
        """The ``pyglet.gl`` module the renderer draws with."""
        return self.renderer.gl

    def make_current(self) -> None:
        """Make the renderer's GL context current."""
        self.renderer._make_current()

    def check_frame(self) -> None:
        """Raise ``RuntimeError`` if ``RendererGL.render`` did not leave the camera we read."""
        missing = [n for n in FRAME_NAMES if not hasattr(self.renderer, n)]
        if missing:
            raise upstream_error([f"RendererGL.{n}" for n in missing])

    @property
    def size(self) -> tuple[int, int]:
        """The frame buffer's width and height [px]."""
        return int(self.renderer._screen_width), int(self.renderer._screen_height)

    @property
    def fbo(self):
        """The frame buffer object the scene was drawn into (colour and depth)."""
        return self.renderer._frame_fbo

    @property
    def depth_texture(self):
        """The scene's depth texture."""
        return self.renderer._frame_depth_texture

    @property
    def view_matrix(self) -> np.ndarray:
        """This frame's view matrix (16 floats, column-major)."""
        return np.asarray(self.renderer._view_matrix, dtype=np.float32).reshape(16)

    @property
    def projection_matrix(self) -> np.ndarray:
        """This frame's projection matrix (16 floats, column-major)."""
        return np.asarray(self.renderer._projection_matrix, dtype=np.float32).reshape(16)

    @property
    def up_axis(self) -> int:
        return int(getattr(self.renderer.camera, "up_axis", 2))

    @property
    def light_space_matrix(self) -> np.ndarray:
        """The shadow map's light-space matrix (16 floats, column-major)."""
        return np.asarray(self.renderer._light_space_matrix, dtype=np.float32).reshape(16)

    @property
    def sun_direction(self) -> np.ndarray:
        """Direction toward the sun (world space, not normalised)."""
        sun = self.renderer._sun_direction
        return np.asarray(sun if sun is not None else (0.2, -0.3, 0.8), dtype=np.float64)

    @property
    def sky(self) -> tuple:
        """The sky's upper and lower colours."""
        return self.renderer.sky_upper, self.renderer.sky_lower

    @property
    def env_intensity(self) -> float:
        return float(getattr(self.renderer, "_env_intensity", 1.0))

    @property
    def env_texture(self):
        """The environment map texture, or ``None``."""
        return self.renderer._env_texture

    @property
    def shadow_texture(self):
        """The shadow map texture while shadows are drawn, else ``None``."""
        return self.renderer._shadow_texture if self.renderer.draw_shadows else None

    def present(self, width: int, height: int) -> None:
        """Draw the frame texture to the window again (what ``RendererGL.render`` ended with)."""
        r, gl = self.renderer, self.renderer.gl
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, 0)
        gl.glViewport(0, 0, width, height)
        gl.glDisable(gl.GL_DEPTH_TEST)
        with r._frame_shader:
            gl.glActiveTexture(gl.GL_TEXTURE0)
            gl.glBindTexture(gl.GL_TEXTURE_2D, r._frame_texture)
            r._frame_shader.update(0)
            gl.glBindVertexArray(r._frame_vao)
            gl.glDrawElements(gl.GL_TRIANGLES, len(r._frame_indices), gl.GL_UNSIGNED_INT, None)
            gl.glBindVertexArray(0)
            gl.glBindTexture(gl.GL_TEXTURE_2D, 0)
        gl.glEnable(gl.GL_DEPTH_TEST)


def activate(viewer_module, base_methods: dict, mesh_methods: dict, gl_methods: dict, fluid_surface_doc: dict) -> None:
    """Extend the viewers of ``viewer_module`` (``newton._src.viewer``) in place; idempotent.

    Args:
        viewer_module: The ``newton._src.viewer`` package.
        base_methods: Attributes added to ``ViewerBase`` (the point fallback every viewer inherits).
        mesh_methods: Attributes set on each of :data:`MESH_VIEWERS` (the extracted surface mesh).
        gl_methods: Attributes set on ``ViewerGL`` (the screen-space surface).
        fluid_surface_doc: The ``fluid_surface`` property's docstring per viewer kind (``"mesh"``, ``"gl"``).
    """
    check_upstream(viewer_module)
    classes = upstream_classes(viewer_module)
    base = classes["ViewerBase"]
    if not hasattr(base, "log_fluid"):
        for name, value in base_methods.items():
            setattr(base, name, value)
    for mesh_name in MESH_VIEWERS:
        mesh_viewer = classes[mesh_name]
        if "_fluid_draw" not in vars(mesh_viewer):
            for name, value in mesh_methods.items():
                setattr(mesh_viewer, name, value)
            mesh_viewer.fluid_surface = property(_fluid_surface_get, _fluid_surface_set, doc=fluid_surface_doc["mesh"])
    gl_viewer = classes["ViewerGL"]
    if getattr(gl_viewer, "_newton_fluid_gl", False):
        return
    gl_viewer._newton_fluid_gl = True
    for name, value in gl_methods.items():
        setattr(gl_viewer, name, value)
    gl_viewer.fluid_surface = property(_fluid_surface_get, _fluid_surface_set, doc=fluid_surface_doc["gl"])
    upstream_set_model = gl_viewer.set_model

    def set_model(self, model, *args, **kwargs):
        upstream_set_model(self, model, *args, **kwargs)
        # fluid particles can be picked too: the same picking, extended
        if model is not None and getattr(self, "picking", None) is not None and model.particle_count:
            from newton._src.geometry.flags import ParticleFlags  # noqa: PLC0415

            from .picking import FluidPicking  # noqa: PLC0415

            if np.any(model.particle_flags.numpy() & int(ParticleFlags.FLUID)):
                self.picking = FluidPicking(
                    model, world_offsets=self.world_offsets, visible_worlds_mask=visible_worlds_mask(self)
                )

    set_model.__doc__ = upstream_set_model.__doc__
    set_model.__wrapped__ = upstream_set_model
    gl_viewer.set_model = set_model

    renderer_cls = classes["RendererGL"]
    upstream_render = renderer_cls.render

    def render(self, *args, **kwargs):
        upstream_render(self, *args, **kwargs)
        fluid = getattr(self, "_newton_fluid", None)
        if fluid is not None and fluid.has_work():
            fluid.frame.check_frame()
            fluid.render()
            if self.draw_fps:
                # leave the state upstream's render leaves for the UI overlay
                self.gl.glClear(self.gl.GL_DEPTH_BUFFER_BIT)
                self.gl.glBlendFunc(self.gl.GL_SRC_ALPHA, self.gl.GL_ONE_MINUS_SRC_ALPHA)
                self.gl.glEnable(self.gl.GL_BLEND)

    render.__doc__ = upstream_render.__doc__
    render.__wrapped__ = upstream_render
    renderer_cls.render = render


def fluid_renderer_of(viewer):
    """The :class:`~.renderer.FluidRendererGL` of a ViewerGL (created on first use, kept on its ``RendererGL``)."""
    renderer = viewer.renderer
    fluid = getattr(renderer, "_newton_fluid", None)
    if fluid is None:
        from .renderer import FluidRendererGL  # noqa: PLC0415

        fluid = FluidRendererGL(UpstreamFrame(renderer))
        renderer._newton_fluid = fluid
    return fluid


def _fluid_surface_get(self) -> bool:
    return getattr(self, "_newton_fluid_surface", True)


def _fluid_surface_set(self, value: bool) -> None:
    self._newton_fluid_surface = bool(value)
