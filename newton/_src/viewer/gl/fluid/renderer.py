# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Screen-space fluid surface for ViewerGL.

After van der Laan, Green & Sainz, "Screen space fluid rendering with curvature flow" (I3D 2009),
with ellipsoid splats after Yu & Turk (2013). Runs after the scene has been drawn and resolved
into RendererGL's frame buffer, at its size:

1. thickness: additive optical depth of enlarged ellipsoid splats, depth-tested against the scene;
2. depth: ray-cast ellipsoids into linear eye depth (RG32F, batch index in G) and the depth buffer;
3. smooth: separable depth-aware (bilateral) filter, width ``blur_radius_world`` [m];
4. shade: normals from depth, refraction of the scene behind, Beer-Lambert transmission, Schlick
   Fresnel reflection of the environment, specular highlight and the scene's shadow, written into
   the frame buffer with the fluid's depth;
5. diffuse hooks: callables drawing foam or spray against the fluid depth.

The frame buffer is then presented again, so ``viewer.get_frame()`` sees the composited image.
"""

from __future__ import annotations

import ctypes
import weakref
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from . import shaders
from .splat import FluidSplatter

# where passes 1-3 run: "raster" = the GLSL passes, "compute" = Warp kernels (splat.py),
# "auto" = compute when every batch is on one CUDA device shared with the GL context
SPLATTING_MODES = ("auto", "raster", "compute")

# when no absorption is given: the colour is what this thickness [m] of fluid transmits
COLOR_REFERENCE_THICKNESS = 0.1


@wp.kernel
def pack_fluid_instances(
    positions: wp.array[wp.vec3],
    radii: wp.array[float],
    radius: float,
    axis_1: wp.array[wp.vec4],
    axis_2: wp.array[wp.vec4],
    axis_3: wp.array[wp.vec4],
    has_axes: int,
    # outputs
    instances: wp.array2d[wp.vec4],
):
    """Four vec4 per particle for the GL instance buffer: centre and radius, then the three axes."""
    i = wp.tid()
    r = radius
    if radii.shape[0] > 0:
        r = radii[i]
    p = positions[i]
    instances[i, 0] = wp.vec4(p[0], p[1], p[2], r)
    if has_axes != 0:
        instances[i, 1] = axis_1[i]
        instances[i, 2] = axis_2[i]
        instances[i, 3] = axis_3[i]
    else:
        instances[i, 1] = wp.vec4(1.0, 0.0, 0.0, 1.0)
        instances[i, 2] = wp.vec4(0.0, 1.0, 0.0, 1.0)
        instances[i, 3] = wp.vec4(0.0, 0.0, 1.0, 1.0)


@wp.kernel
def pack_diffuse_instances(
    positions: wp.array[wp.vec3],
    velocities: wp.array[wp.vec3],
    lifetimes: wp.array[float],
    kinds: wp.array[wp.int32],
    radius: float,
    # outputs
    instances: wp.array2d[wp.vec4],
):
    """Two vec4 per diffuse particle: centre and radius (0: not drawn), velocity and kind."""
    i = wp.tid()
    r = radius
    if lifetimes.shape[0] > 0:
        if lifetimes[i] <= 0.0:
            r = 0.0
    kind = float(1.0)
    if kinds.shape[0] > 0:
        kind = float(kinds[i])
        if kinds[i] < 0:
            r = 0.0
    v = wp.vec3(0.0)
    if velocities.shape[0] > 0:
        v = velocities[i]
    p = positions[i]
    instances[i, 0] = wp.vec4(p[0], p[1], p[2], r)
    instances[i, 1] = wp.vec4(v[0], v[1], v[2], kind)


@dataclass
class DiffuseMaterial:
    """Look of one batch of diffuse particles; see ``log_fluid_diffuse``."""

    color: tuple = (1.0, 1.0, 1.0, 0.8)
    stretch_time: float = 1.0 / 60.0
    fade_length: float = 0.05


@dataclass
class FluidMaterial:
    """Look of one fluid batch; see :func:`log_fluid` for the meaning and units of each field."""

    color: tuple = (0.2, 0.45, 0.9, 1.0)
    absorption: tuple | None = None
    ior: float = 1.333
    reflectance: float = 0.02
    specular_intensity: float = 0.6
    specular_power: float = 200.0
    blur_radius_world: float | None = None
    radius_scale: float = 1.8

    def absorption_coefficients(self) -> tuple:
        """sigma_a per channel [1/m]."""
        if self.absorption is not None:
            return tuple(float(a) for a in self.absorption)
        rgb = np.clip(np.asarray(self.color[:3], dtype=np.float64), 1.0e-3, 1.0)
        return tuple(float(a) for a in -np.log(rgb) / COLOR_REFERENCE_THICKNESS)


@dataclass
class FluidBatchGL:
    """GL instance buffer and material of one named fluid batch."""

    material: FluidMaterial
    count: int = 0
    capacity: int = 0
    vbo: int = 0
    vao: int = 0
    mean_radius: float = 0.0
    hidden: bool = False
    vec4_per_instance: int = 4
    packed: wp.array | None = None
    registered: object = None
    # the GL instance buffer holds the latest packed data (only the raster passes read it)
    uploaded: bool = False
    extra: dict = field(default_factory=dict)


class FluidRendererGL:
    """Owns the fluid batches of one ViewerGL and draws them after the scene."""

    def __init__(self, frame):
        #: the upstream renderer's frame, camera and lights (:class:`~.upstream.UpstreamFrame`)
        self.frame = frame
        self.batches: dict[str, FluidBatchGL] = {}
        self.diffuse_batches: dict[str, FluidBatchGL] = {}
        self.diffuse_hooks: list = []
        self.size = (0, 0)
        self._programs = None
        self._targets = None
        self._quad_vbo = None
        self._empty_vao = None
        self._cuda_interop = True
        self._splatting = "auto"
        self._splatter = None
        self.last_timings_ms: dict[str, float] = {}
        self.last_splatting = None
        self.measure_timings = False

    @property
    def splatting(self) -> str:
        """Where the depth, thickness and smoothing passes run: ``"auto"`` (default), ``"raster"`` or ``"compute"``.

        ``"raster"`` draws them with GLSL shaders; ``"compute"`` runs the same passes as Warp kernels on the
        batches' device and copies the results into the textures the shading pass reads (through CUDA-GL
        shared buffers when the GL context is on that GPU, through the host otherwise); ``"auto"`` picks
        compute when every visible batch is on one CUDA device shared with the GL context, raster
        otherwise. Both give the same image up to rounding (tested).
        """
        return self._splatting

    @splatting.setter
    def splatting(self, value: str) -> None:
        if value not in SPLATTING_MODES:
            raise ValueError(f"splatting={value!r}: expected one of {', '.join(map(repr, SPLATTING_MODES))}")
        self._splatting = value

    @property
    def cuda_interop(self) -> bool:
        """Whether CUDA batches reach GL through CUDA-GL shared buffers (``False`` once sharing failed on this
        context: they go through the host from then on)."""
        return self._cuda_interop

    # ------------------------------------------------------------------ batches
    def set_batch(self, name, positions, radii, material, anisotropy, hidden):
        gl = self.frame.gl
        self.frame.make_current()
        batch = self.batches.get(name)
        if batch is None:
            if len(self.batches) >= shaders.MAX_BATCHES:
                raise ValueError(
                    f"name={name!r} would be fluid batch {len(self.batches) + 1}: expected at most "
                    f"{shaders.MAX_BATCHES} batches in one viewer"
                )
            batch = FluidBatchGL(material=material)
            self.batches[name] = batch
        if not self._prepare(gl, batch, material, hidden, positions):
            return
        n, device = batch.count, positions.device
        scalar = isinstance(radii, float)
        if scalar:
            batch.mean_radius = radii
        elif batch.extra.get("radii_key") != (id(radii), n):
            # the default blur width follows the radius: read it once per radii array, not per frame
            batch.extra["radii_key"] = (id(radii), n)
            batch.mean_radius = float(np.mean(radii.numpy()[:n]))
        none_f, none_v = _absent(float, device), _absent(wp.vec4, device)
        axes = anisotropy if anisotropy is not None else (none_v, none_v, none_v)
        wp.launch(
            pack_fluid_instances,
            dim=n,
            inputs=[
                positions,
                none_f if scalar else radii,
                radii if scalar else 0.0,
                *axes,
                int(anisotropy is not None),
            ],
            outputs=[batch.packed],
            device=device,
        )
        # uploaded when a raster pass needs it: the compute passes read the packed array itself
        batch.uploaded = False

    def set_diffuse_batch(self, name, positions, velocities, lifetimes, kinds, radius, material, hidden):
        gl = self.frame.gl
        self.frame.make_current()
        batch = self.diffuse_batches.get(name)
        if batch is None:
            batch = FluidBatchGL(material=material, vec4_per_instance=2)
            self.diffuse_batches[name] = batch
        if not self._prepare(gl, batch, material, hidden, positions):
            return
        n, device = batch.count, positions.device
        none_v, none_f, none_i = _absent(wp.vec3, device), _absent(float, device), _absent(wp.int32, device)
        wp.launch(
            pack_diffuse_instances,
            dim=n,
            inputs=[
                positions,
                none_v if velocities is None else velocities,
                none_f if lifetimes is None else lifetimes,
                none_i if kinds is None else kinds,
                float(radius),
            ],
            outputs=[batch.packed],
            device=device,
        )
        self._upload(gl, batch, n)

    def _prepare(self, gl, batch, material, hidden, positions) -> bool:
        """Update a batch's material and count, grow its buffers; False when there is nothing to draw."""
        batch.material = material
        batch.hidden = hidden
        n = len(positions)
        batch.count = n
        if n == 0:
            return False
        self._ensure_common(gl)
        if n > batch.capacity:
            self._allocate_batch(gl, batch, max(n, 2 * batch.capacity, 256))
        if batch.packed is None or batch.packed.device != positions.device:
            batch.packed = wp.empty((batch.capacity, batch.vec4_per_instance), dtype=wp.vec4, device=positions.device)
        return True

    def remove_diffuse_batch(self, name):
        self._release_batch(self.diffuse_batches.pop(name, None))

    def hide_batch(self, name):
        if name in self.batches:
            self.batches[name].hidden = True

    def remove_batch(self, name):
        self._release_batch(self.batches.pop(name, None))

    def _release_batch(self, batch):
        if batch is not None and batch.vbo:
            gl = self.frame.gl
            self.frame.make_current()
            batch.registered = None
            gl.glDeleteBuffers(1, ctypes.byref(gl.GLuint(batch.vbo)))
            gl.glDeleteVertexArrays(1, ctypes.byref(gl.GLuint(batch.vao)))

    def _allocate_batch(self, gl, batch, capacity):
        if not batch.vbo:
            ids = (gl.GLuint * 1)()
            gl.glGenBuffers(1, ids)
            batch.vbo = int(ids[0])
            gl.glGenVertexArrays(1, ids)
            batch.vao = int(ids[0])
            gl.glBindVertexArray(batch.vao)
            gl.glBindBuffer(gl.GL_ARRAY_BUFFER, self._quad_vbo)
            gl.glEnableVertexAttribArray(0)
            gl.glVertexAttribPointer(0, 2, gl.GL_FLOAT, gl.GL_FALSE, 8, ctypes.c_void_p(0))
            gl.glBindBuffer(gl.GL_ARRAY_BUFFER, batch.vbo)
            stride = 16 * batch.vec4_per_instance
            for k in range(batch.vec4_per_instance):
                gl.glEnableVertexAttribArray(1 + k)
                gl.glVertexAttribPointer(1 + k, 4, gl.GL_FLOAT, gl.GL_FALSE, stride, ctypes.c_void_p(16 * k))
                gl.glVertexAttribDivisor(1 + k, 1)
            gl.glBindVertexArray(0)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, batch.vbo)
        gl.glBufferData(gl.GL_ARRAY_BUFFER, capacity * 16 * batch.vec4_per_instance, None, gl.GL_DYNAMIC_DRAW)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, 0)
        batch.capacity = capacity
        batch.registered = None
        batch.packed = None

    def _upload(self, gl, batch, n):
        batch.uploaded = True
        packed = batch.packed
        if packed.device.is_cuda and self._cuda_interop:
            try:
                if batch.registered is None:
                    batch.registered = wp.RegisteredGLBuffer(
                        batch.vbo, packed.device, flags=wp.RegisteredGLBuffer.WRITE_DISCARD
                    )
                mapped = batch.registered.map(dtype=wp.vec4, shape=(batch.capacity, batch.vec4_per_instance))
                wp.copy(mapped, packed, count=batch.vec4_per_instance * n)
                batch.registered.unmap()
                return
            except Exception:
                # no CUDA-GL interop on this context (e.g. a Mesa context beside a CUDA device)
                self._cuda_interop = False
                batch.registered = None
        host = np.ascontiguousarray(packed.numpy()[:n], dtype=np.float32)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, batch.vbo)
        gl.glBufferSubData(gl.GL_ARRAY_BUFFER, 0, host.nbytes, host.ctypes.data)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, 0)

    # ------------------------------------------------------------------ resources
    def _ensure_common(self, gl):
        if self._programs is not None:
            return
        from pyglet.graphics.shader import Shader, ShaderProgram  # noqa: PLC0415

        def program(vs, fs):
            return ShaderProgram(Shader(vs, "vertex"), Shader(fs, "fragment"))

        self._programs = {
            "thickness": program(shaders.ELLIPSOID_VERTEX, shaders.THICKNESS_FRAGMENT),
            "depth": program(shaders.ELLIPSOID_VERTEX, shaders.DEPTH_FRAGMENT),
            "filter": program(shaders.FULLSCREEN_VERTEX, shaders.FILTER_FRAGMENT),
            "optical_filter": program(shaders.FULLSCREEN_VERTEX, shaders.OPTICAL_FILTER_FRAGMENT),
            "shade": program(shaders.FULLSCREEN_VERTEX, shaders.SHADE_FRAGMENT),
            "diffuse": program(shaders.DIFFUSE_VERTEX, shaders.DIFFUSE_FRAGMENT),
            "depth_copy": program(shaders.FULLSCREEN_VERTEX, shaders.DEPTH_COPY_FRAGMENT),
        }
        quad = np.array([-1.0, -1.0, 1.0, -1.0, -1.0, 1.0, 1.0, 1.0], dtype=np.float32)
        ids = (gl.GLuint * 1)()
        gl.glGenBuffers(1, ids)
        self._quad_vbo = int(ids[0])
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, self._quad_vbo)
        gl.glBufferData(gl.GL_ARRAY_BUFFER, quad.nbytes, quad.ctypes.data, gl.GL_STATIC_DRAW)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, 0)
        gl.glGenVertexArrays(1, ids)
        self._empty_vao = int(ids[0])

    def _ensure_targets(self, gl, width, height):
        if self._targets is not None and self.size == (width, height):
            return
        self._release_targets(gl)
        full, half = (width, height), _half_size(width, height)
        nearest, linear = gl.GL_NEAREST, gl.GL_LINEAR
        depth32 = (gl.GL_DEPTH_COMPONENT32, gl.GL_DEPTH_COMPONENT, gl.GL_FLOAT)
        make = self._make_texture
        t = {
            "depth": make(gl, gl.GL_RG32F, gl.GL_RG, gl.GL_FLOAT, full, nearest),
            "depth_blur": make(gl, gl.GL_RG32F, gl.GL_RG, gl.GL_FLOAT, full, nearest),
            # thickness varies slowly and is blurred anyway: half resolution, read with linear filtering
            "optical": make(gl, gl.GL_RGBA16F, gl.GL_RGBA, gl.GL_FLOAT, half, linear),
            "optical_blur": make(gl, gl.GL_RGBA16F, gl.GL_RGBA, gl.GL_FLOAT, half, nearest),
            "zbuffer_half": make(gl, *depth32, half, nearest),
            "scene_depth": make(gl, *depth32, full, nearest),
            "scene_color": make(gl, gl.GL_RGB8, gl.GL_RGB, gl.GL_UNSIGNED_BYTE, full, linear),
            "zbuffer": make(gl, *depth32, full, nearest),
        }
        framebuffer = self._make_framebuffer
        t["fbo_depth"] = framebuffer(gl, t["depth"], t["zbuffer"])
        t["fbo_optical"] = framebuffer(gl, t["optical"], t["zbuffer_half"])
        t["fbo_blur"] = framebuffer(gl, t["depth_blur"])
        t["fbo_depth_only"] = framebuffer(gl, t["depth"])
        t["fbo_scene"] = framebuffer(gl, t["scene_color"], t["scene_depth"])
        t["fbo_optical_blur"] = framebuffer(gl, t["optical_blur"])
        t["fbo_optical_only"] = framebuffer(gl, t["optical"])
        self._targets = t
        self.size = (width, height)

    @staticmethod
    def _make_texture(gl, internal, fmt, kind, size, filtering):
        ids = (gl.GLuint * 1)()
        gl.glGenTextures(1, ids)
        gl.glBindTexture(gl.GL_TEXTURE_2D, ids[0])
        gl.glTexImage2D(gl.GL_TEXTURE_2D, 0, internal, size[0], size[1], 0, fmt, kind, None)
        gl.glTexParameteri(gl.GL_TEXTURE_2D, gl.GL_TEXTURE_MIN_FILTER, filtering)
        gl.glTexParameteri(gl.GL_TEXTURE_2D, gl.GL_TEXTURE_MAG_FILTER, filtering)
        gl.glTexParameteri(gl.GL_TEXTURE_2D, gl.GL_TEXTURE_WRAP_S, gl.GL_CLAMP_TO_EDGE)
        gl.glTexParameteri(gl.GL_TEXTURE_2D, gl.GL_TEXTURE_WRAP_T, gl.GL_CLAMP_TO_EDGE)
        gl.glBindTexture(gl.GL_TEXTURE_2D, 0)
        return int(ids[0])

    @staticmethod
    def _make_framebuffer(gl, color, depth=None):
        ids = (gl.GLuint * 1)()
        gl.glGenFramebuffers(1, ids)
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, ids[0])
        gl.glFramebufferTexture2D(gl.GL_FRAMEBUFFER, gl.GL_COLOR_ATTACHMENT0, gl.GL_TEXTURE_2D, color, 0)
        if depth is not None:
            gl.glFramebufferTexture2D(gl.GL_FRAMEBUFFER, gl.GL_DEPTH_ATTACHMENT, gl.GL_TEXTURE_2D, depth, 0)
        status = gl.glCheckFramebufferStatus(gl.GL_FRAMEBUFFER)
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, 0)
        if status != gl.GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError(f"fluid render target incomplete (status 0x{status:x})")
        return int(ids[0])

    def _release_targets(self, gl):
        if self._targets is None:
            return
        for key, obj in self._targets.items():
            ref = ctypes.byref(gl.GLuint(obj))
            if key.startswith("fbo"):
                gl.glDeleteFramebuffers(1, ref)
            else:
                gl.glDeleteTextures(1, ref)
        self._targets = None

    def release(self):
        """Free every GL object of the fluid renderer (the viewer's context must be current)."""
        gl = self.frame.gl
        for name in list(self.batches):
            self.remove_batch(name)
        for name in list(self.diffuse_batches):
            self.remove_diffuse_batch(name)
        self._release_targets(gl)
        if self._splatter is not None:
            self._splatter.release()
            self._splatter = None
        if self._programs is not None:
            for p in self._programs.values():
                p.delete()
            self._programs = None

    def read_texture(self, which: str) -> np.ndarray:
        """Read one internal target back (testing aid): ``"depth"`` (smoothed linear depth [m] and batch
        index, 0 depth where there is no fluid) or ``"optical"`` (absorbance per channel and thickness [m],
        at half the frame's resolution).

        Rows are bottom-up, as OpenGL stores them.
        """
        gl = self.frame.gl
        self.frame.make_current()
        if self._targets is None:
            raise RuntimeError("no fluid has been rendered yet")
        w, h = self.size
        channels = {"depth": (gl.GL_RG, 2), "optical": (gl.GL_RGBA, 4)}[which]
        out = np.zeros((h, w, channels[1]), dtype=np.float32)
        gl.glBindTexture(gl.GL_TEXTURE_2D, self._targets[which])
        gl.glGetTexImage(gl.GL_TEXTURE_2D, 0, channels[0], gl.GL_FLOAT, out.ctypes.data)
        gl.glBindTexture(gl.GL_TEXTURE_2D, 0)
        return out

    # ------------------------------------------------------------------ passes
    def visible_batches(self):
        return [(i, b) for i, b in enumerate(self.batches.values()) if not b.hidden and b.count > 0]

    def visible_diffuse_batches(self):
        return [b for b in self.diffuse_batches.values() if not b.hidden and b.count > 0]

    def has_work(self):
        return bool(self.visible_batches() or self.visible_diffuse_batches())

    def render(self):
        """Composite the fluid into the renderer's frame buffer and present it again."""
        batches = self.visible_batches()
        if not self.has_work():
            return
        frame = self.frame
        gl = frame.gl
        width, height = frame.size
        if width <= 0 or height <= 0:
            return
        self._ensure_common(gl)
        self._ensure_targets(gl, width, height)
        t = self._targets
        view = frame.view_matrix
        proj = frame.projection_matrix
        focal_px = float(proj[5]) * 0.5 * height

        timer = _PassTimer(gl, self.measure_timings)
        gl.glViewport(0, 0, width, height)
        gl.glDisable(gl.GL_BLEND)
        gl.glDisable(gl.GL_CULL_FACE)

        compute = bool(batches) and self._use_compute(batches)
        self.last_splatting = ("compute" if compute else "raster") if batches else None
        # the scene's colour (read by the shading pass) and depth (occludes the fluid; in compute mode
        # a float copy of it is made for the kernels, which the later passes read instead)
        gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, frame.fbo)
        gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, t["fbo_scene"])
        bits = gl.GL_COLOR_BUFFER_BIT if compute else gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT
        gl.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, bits, gl.GL_NEAREST)
        if not compute:
            # the raster passes test against the scene in their own depth buffers
            gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, t["fbo_depth"])
            gl.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, gl.GL_DEPTH_BUFFER_BIT, gl.GL_NEAREST)
            half = _half_size(width, height)
            gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, t["fbo_optical"])
            gl.glBlitFramebuffer(0, 0, width, height, 0, 0, half[0], half[1], gl.GL_DEPTH_BUFFER_BIT, gl.GL_NEAREST)
        timer.mark("copy_scene")

        if batches:
            self._draw_surface(gl, batches, view, proj, focal_px, width, height, timer, compute)
        else:
            # only diffuse particles: no fluid surface in front of them
            gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, t["fbo_depth_only"])
            gl.glClearColor(0.0, 0.0, 0.0, 0.0)
            gl.glClear(gl.GL_COLOR_BUFFER_BIT)

        # 5. diffuse particles (spray, foam, bubbles), then the hooks, against the fluid depth
        diffuse = self.visible_diffuse_batches()
        if diffuse:
            self._draw_diffuse(gl, diffuse, view, proj)
            timer.mark("diffuse")
        if self.diffuse_hooks:
            context = FluidFrameContext(
                depth_texture=t["depth"], width=width, height=height, view=view.copy(), projection=proj.copy()
            )
            for hook in self.diffuse_hooks:
                gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, frame.fbo)
                hook(context)
            timer.mark("hooks")

        gl.glBindVertexArray(0)
        self._present(gl, width, height)
        timer.mark("present")
        self.last_timings_ms = timer.finish()
        if compute and self.measure_timings:
            self.last_timings_ms.update({f"cuda_{k}": v for k, v in self._splatter.timings_ms.items()})

    def _scene_depth_texture(self):
        """The scene's depth as this frame's later passes read it: the float copy made for the compute
        passes (the depth blit is skipped then), the blitted depth otherwise."""
        if self.last_splatting == "compute":
            return self._targets["scene_depth_copy"]
        return self._targets["scene_depth"]

    def _use_compute(self, batches) -> bool:
        """Whether passes 1-3 run as Warp kernels this frame (see :attr:`splatting`)."""
        if self._splatting == "raster":
            return False
        devices = {str(b.packed.device) for _, b in batches}
        if len(devices) != 1:
            return False  # the kernels need every batch on one device
        if self._splatting == "compute":
            return True
        return batches[0][1].packed.device.is_cuda and self._cuda_interop

    def _splat_compute(self, gl, batches, view, proj, focal_px, width, height, blur, timer):
        """Passes 1-3 as Warp kernels, results in the ``depth`` and ``optical`` textures."""
        device = batches[0][1].packed.device
        size, half = (width, height), _half_size(width, height)
        s = self._splatter
        if s is None or s.size != size or s.device != device:
            if s is not None:
                s.release()
            s = FluidSplatter(gl, device, size, half, interop=self._cuda_interop)
            self._splatter = s
            if device.is_cuda and not s.interop:
                # this GL context cannot share buffers with the device: auto mode draws with GL
                self._cuda_interop = False
        t = self._targets
        if "fbo_scene_depth_copy" not in t:
            t["scene_depth_copy"] = self._make_texture(gl, gl.GL_R32F, gl.GL_RED, gl.GL_FLOAT, size, gl.GL_NEAREST)
            t["fbo_scene_depth_copy"] = self._make_framebuffer(gl, t["scene_depth_copy"])
        # the scene's depth as a float colour, which the splatter reads back and the shading and
        # diffuse passes sample
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, t["fbo_scene_depth_copy"])
        gl.glDisable(gl.GL_DEPTH_TEST)
        prog = self._programs["depth_copy"]
        prog.use()
        gl.glActiveTexture(gl.GL_TEXTURE0)
        gl.glBindTexture(gl.GL_TEXTURE_2D, _gl_name(self.frame.depth_texture))
        gl.glUniform1i(_loc(gl, prog, "scene_depth_tex"), 0)
        gl.glBindVertexArray(self._empty_vao)
        gl.glDrawArrays(gl.GL_TRIANGLES, 0, 3)
        gl.glBindVertexArray(0)
        gl.glBindTexture(gl.GL_TEXTURE_2D, 0)
        prog.stop()
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, 0)
        timer.mark("scene_depth_copy")
        s.run(batches, view, proj, focal_px, blur, t["fbo_scene_depth_copy"], t["depth"], t["optical"], timer)

    def _draw_surface(self, gl, batches, view, proj, focal_px, width, height, timer, compute):
        """Passes 1-4: thickness, depth, smoothing and shading of the fluid batches."""
        blur = np.zeros(shaders.MAX_BATCHES, dtype=np.float32)
        for index, batch in batches:
            blur[index] = self._blur_radius(batch)
        if compute:
            self._splat_compute(gl, batches, view, proj, focal_px, width, height, blur, timer)
        else:
            self._splat_raster(gl, batches, view, proj, focal_px, width, height, blur, timer)

        # 4. shade into the frame buffer, with the fluid's depth
        gl.glViewport(0, 0, width, height)
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, self.frame.fbo)
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_ALWAYS)
        gl.glDepthMask(gl.GL_TRUE)
        prog = self._programs["shade"]
        prog.use()
        self._set_shading(gl, prog, batches, view, proj, width, height)
        gl.glBindVertexArray(self._empty_vao)
        gl.glDrawArrays(gl.GL_TRIANGLES, 0, 3)
        prog.stop()
        _unbind_textures(gl, 6)
        gl.glDepthFunc(gl.GL_LESS)
        timer.mark("shade")

    def _splat_raster(self, gl, batches, view, proj, focal_px, width, height, blur, timer):
        """Passes 1-3 with GLSL: thickness, depth and smoothing into the ``depth`` and ``optical`` textures."""
        t = self._targets
        half = _half_size(width, height)
        for _, batch in batches:
            if not batch.uploaded:
                self._upload(gl, batch, batch.count)
        # 1. thickness: additive, tested against the scene only, at half resolution
        gl.glViewport(0, 0, half[0], half[1])
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, t["fbo_optical"])
        gl.glClearColor(0.0, 0.0, 0.0, 0.0)
        gl.glClear(gl.GL_COLOR_BUFFER_BIT)
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_LESS)
        gl.glDepthMask(gl.GL_FALSE)
        gl.glEnable(gl.GL_BLEND)
        gl.glBlendFunc(gl.GL_ONE, gl.GL_ONE)
        prog = self._programs["thickness"]
        prog.use()
        self._set_camera(gl, prog, view, proj)
        _uniform1f(gl, prog, "splat_scale", shaders.THICKNESS_SPLAT_SCALE)
        for _, batch in batches:
            _uniform1f(gl, prog, "radius_scale", batch.material.radius_scale)
            gl.glUniform3f(_loc(gl, prog, "absorption"), *batch.material.absorption_coefficients())
            self._draw_batch(gl, batch)
        prog.stop()
        gl.glDisable(gl.GL_BLEND)
        timer.mark("thickness")

        # 2. depth: nearest ellipsoid surface, written to the depth buffer too
        gl.glViewport(0, 0, width, height)
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, t["fbo_depth"])
        gl.glClear(gl.GL_COLOR_BUFFER_BIT)
        gl.glDepthMask(gl.GL_TRUE)
        prog = self._programs["depth"]
        prog.use()
        self._set_camera(gl, prog, view, proj)
        _uniform1f(gl, prog, "splat_scale", 1.0)
        for index, batch in batches:
            _uniform1f(gl, prog, "radius_scale", batch.material.radius_scale)
            _uniform1f(gl, prog, "batch_index", float(index))
            self._draw_batch(gl, batch)
        prog.stop()
        gl.glDisable(gl.GL_DEPTH_TEST)
        timer.mark("depth")

        # 3. smooth: horizontal into depth_blur, vertical back into depth
        gl.glBindVertexArray(self._empty_vao)
        self._separable(gl, "filter", ("depth", "fbo_blur", "depth_blur", "fbo_depth_only"), focal_px, blur)
        # the thickness is filtered at its half resolution, with the full-resolution depth beside it
        gl.glViewport(0, 0, half[0], half[1])
        gl.glActiveTexture(gl.GL_TEXTURE1)
        gl.glBindTexture(gl.GL_TEXTURE_2D, t["depth"])
        self._separable(
            gl,
            "optical_filter",
            ("optical", "fbo_optical_blur", "optical_blur", "fbo_optical_only"),
            focal_px * half[1] / height,
            blur,
            depth_step=2,
        )
        gl.glViewport(0, 0, width, height)
        timer.mark("smooth")

    def _separable(self, gl, program, chain, focal_px, blur, depth_step=None):
        """Horizontal then vertical pass of a filter: ``chain`` = (source, fbo of the middle texture,
        middle texture, fbo of the result); the source is sampled from unit 0, the depth from unit 1."""
        t = self._targets
        prog = self._programs[program]
        prog.use()
        _uniform1f(gl, prog, "focal_px", focal_px)
        gl.glUniform1i(_loc(gl, prog, "max_radius_px"), shaders.MAX_FILTER_RADIUS_PX)
        gl.glUniform1fv(_loc(gl, prog, "blur_radius"), shaders.MAX_BATCHES, _floats(blur))
        if depth_step is None:
            gl.glUniform1i(_loc(gl, prog, "depth_tex"), 0)
        else:
            gl.glUniform1i(_loc(gl, prog, "optical_tex"), 0)
            gl.glUniform1i(_loc(gl, prog, "depth_tex"), 1)
            gl.glUniform1i(_loc(gl, prog, "depth_step"), depth_step)
        gl.glActiveTexture(gl.GL_TEXTURE0)
        source, middle_fbo, middle, target_fbo = chain
        for texture, fbo, direction in ((source, middle_fbo, (1.0, 0.0)), (middle, target_fbo, (0.0, 1.0))):
            gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, t[fbo])
            gl.glBindTexture(gl.GL_TEXTURE_2D, t[texture])
            gl.glUniform2f(_loc(gl, prog, "direction"), *direction)
            gl.glDrawArrays(gl.GL_TRIANGLES, 0, 3)
        prog.stop()

    def _draw_diffuse(self, gl, diffuse, view, proj):
        """Velocity-stretched sprites of the diffuse batches, blended into the frame buffer."""
        t = self._targets
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, self.frame.fbo)
        gl.glDisable(gl.GL_DEPTH_TEST)
        gl.glDepthMask(gl.GL_FALSE)
        gl.glEnable(gl.GL_BLEND)
        gl.glBlendFunc(gl.GL_ONE, gl.GL_ONE_MINUS_SRC_ALPHA)
        prog = self._programs["diffuse"]
        prog.use()
        self._set_camera(gl, prog, view, proj)
        for unit, (uniform, texture) in enumerate(
            (("fluid_depth_tex", t["depth"]), ("scene_depth_tex", self._scene_depth_texture()))
        ):
            gl.glActiveTexture(gl.GL_TEXTURE0 + unit)
            gl.glBindTexture(gl.GL_TEXTURE_2D, texture)
            gl.glUniform1i(_loc(gl, prog, uniform), unit)
        for batch in diffuse:
            m = batch.material
            gl.glUniform4f(_loc(gl, prog, "color"), *m.color)
            _uniform1f(gl, prog, "stretch_time", m.stretch_time)
            _uniform1f(gl, prog, "fade_length", m.fade_length)
            self._draw_batch(gl, batch)
        prog.stop()
        _unbind_textures(gl, 2)
        gl.glDisable(gl.GL_BLEND)
        gl.glDepthMask(gl.GL_TRUE)

    def _blur_radius(self, batch):
        m = batch.material
        if m.blur_radius_world is not None:
            return float(m.blur_radius_world)
        if batch.mean_radius is not None:
            return 1.0 * batch.mean_radius * m.radius_scale
        return 0.0

    def _draw_batch(self, gl, batch):
        gl.glBindVertexArray(batch.vao)
        gl.glDrawArraysInstanced(gl.GL_TRIANGLE_STRIP, 0, 4, batch.count)
        gl.glBindVertexArray(0)

    @staticmethod
    def _set_camera(gl, prog, view, proj):
        gl.glUniformMatrix4fv(
            _loc(gl, prog, "view"), 1, gl.GL_FALSE, view.ctypes.data_as(ctypes.POINTER(ctypes.c_float))
        )
        gl.glUniformMatrix4fv(
            _loc(gl, prog, "projection"), 1, gl.GL_FALSE, proj.ctypes.data_as(ctypes.POINTER(ctypes.c_float))
        )

    def _set_shading(self, gl, prog, batches, view, proj, width, height):
        frame = self.frame
        self._set_camera(gl, prog, view, proj)
        n = shaders.MAX_BATCHES
        color = np.zeros((n, 4), dtype=np.float32)
        ior = np.ones(n, dtype=np.float32)
        f0 = np.zeros(n, dtype=np.float32)
        spec = np.zeros(n, dtype=np.float32)
        power = np.ones(n, dtype=np.float32)
        for index, batch in batches:
            m = batch.material
            color[index] = m.color
            ior[index], f0[index] = m.ior, m.reflectance
            spec[index], power[index] = m.specular_intensity, m.specular_power

        gl.glUniform4fv(_loc(gl, prog, "base_color"), n, _floats(color))
        gl.glUniform1fv(_loc(gl, prog, "ior"), n, _floats(ior))
        gl.glUniform1fv(_loc(gl, prog, "reflectance"), n, _floats(f0))
        gl.glUniform1fv(_loc(gl, prog, "specular_intensity"), n, _floats(spec))
        gl.glUniform1fv(_loc(gl, prog, "specular_power"), n, _floats(power))
        light = frame.light_space_matrix
        gl.glUniformMatrix4fv(_loc(gl, prog, "light_space"), 1, gl.GL_FALSE, _floats(light))
        sun = frame.sun_direction
        view_rot = view.reshape(4, 4).T[:3, :3]
        sun_eye = view_rot @ (sun / np.linalg.norm(sun))
        gl.glUniform3f(_loc(gl, prog, "sun_dir_eye"), *(float(x) for x in sun_eye))
        sky_upper, sky_lower = frame.sky
        gl.glUniform3f(_loc(gl, prog, "sky_upper"), *(float(x) for x in sky_upper))
        gl.glUniform3f(_loc(gl, prog, "sky_lower"), *(float(x) for x in sky_lower))
        gl.glUniform1i(_loc(gl, prog, "up_axis"), frame.up_axis)
        gl.glUniform2f(_loc(gl, prog, "inv_size"), 1.0 / width, 1.0 / height)
        _uniform1f(gl, prog, "env_intensity", frame.env_intensity)
        t = self._targets
        env = frame.env_texture
        shadow = frame.shadow_texture
        units = (
            ("depth_tex", t["depth"]),
            ("optical_tex", t["optical"]),
            ("scene_tex", t["scene_color"]),
            ("env_tex", _gl_name(env) if env is not None else 0),
            ("shadow_tex", _gl_name(shadow) if shadow is not None else 0),
            ("scene_depth_tex", self._scene_depth_texture()),
        )
        for unit, (uniform, texture) in enumerate(units):
            gl.glActiveTexture(gl.GL_TEXTURE0 + unit)
            gl.glBindTexture(gl.GL_TEXTURE_2D, texture)
            gl.glUniform1i(_loc(gl, prog, uniform), unit)
        gl.glUniform1i(_loc(gl, prog, "has_env"), int(env is not None))
        gl.glUniform1i(_loc(gl, prog, "has_shadow"), int(shadow is not None))

    def _present(self, gl, width, height):
        """Draw the composited frame texture to the window again (what RendererGL.render ended with)."""
        self.frame.present(width, height)


@dataclass
class FluidFrameContext:
    """What a diffuse-particle hook gets: the smoothed fluid depth and the camera of this frame.

    Attributes:
        depth_texture: GL texture id, RG32F: linear eye depth [m] of the fluid surface (0: none), batch index.
        width: Frame width [px].
        height: Frame height [px].
        view: View matrix, 16 floats, column-major.
        projection: Projection matrix, 16 floats, column-major.
    """

    depth_texture: int
    width: int
    height: int
    view: np.ndarray
    projection: np.ndarray


class _PassTimer:
    """GPU time of each pass from GL timestamp queries; off (free) unless asked for.

    Reading the results waits for the frame's GPU work, so only frames that measure pay for it.
    """

    def __init__(self, gl, enabled):
        self._gl, self.enabled = gl, enabled
        self._names = []
        self._queries = []
        if enabled:
            self._stamp()

    def _stamp(self):
        gl = self._gl
        query = gl.GLuint()
        gl.glGenQueries(1, ctypes.byref(query))
        gl.glQueryCounter(query, gl.GL_TIMESTAMP)
        self._queries.append(query)

    def mark(self, name):
        if self.enabled:
            self._stamp()
            self._names.append(name)

    def finish(self):
        if not self.enabled:
            return {}
        gl = self._gl
        stamps = []
        for query in self._queries:
            value = ctypes.c_uint64()
            gl.glGetQueryObjectui64v(query, gl.GL_QUERY_RESULT, ctypes.byref(value))
            stamps.append(value.value)
            gl.glDeleteQueries(1, ctypes.byref(query))
        return {name: 1.0e-6 * (stamps[k + 1] - stamps[k]) for k, name in enumerate(self._names)}


def _gl_name(obj) -> int:
    """A GL object name held by upstream as an int or a ``GLuint``."""
    return int(getattr(obj, "value", obj))


def _half_size(width, height):
    return (width + 1) // 2, (height + 1) // 2


def _floats(array):
    return array.ctypes.data_as(ctypes.POINTER(ctypes.c_float))


_ABSENT = {}


def _absent(dtype, device):
    """An empty array standing for an argument that was not given (made once per type and device, not per frame)."""
    key = (dtype, str(device))
    if key not in _ABSENT:
        _ABSENT[key] = wp.empty(0, dtype=dtype, device=device)
    return _ABSENT[key]


# uniform locations per program object (GL names are reused across contexts, objects are not)
_LOCATIONS = weakref.WeakKeyDictionary()


def _loc(gl, prog, name):
    """Uniform location, looked up once per program (every pass sets its uniforms each frame)."""
    locations = _LOCATIONS.setdefault(prog, {})
    if name not in locations:
        locations[name] = gl.glGetUniformLocation(prog.id, name.encode())
    return locations[name]


def _uniform1f(gl, prog, name, value):
    gl.glUniform1f(_loc(gl, prog, name), float(value))


def _unbind_textures(gl, units: int):
    """Unbind the 2D textures of units ``0 .. units - 1`` a pass used, leaving unit 0 active."""
    for unit in range(units):
        gl.glActiveTexture(gl.GL_TEXTURE0 + unit)
        gl.glBindTexture(gl.GL_TEXTURE_2D, 0)
    gl.glActiveTexture(gl.GL_TEXTURE0)
