# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Passes 1-3 of the fluid surface (depth, thickness, smoothing) as Warp kernels.

The same images as the GLSL passes in :mod:`.shaders` (same ray-cast ellipsoids, same pixel
centres, same filters), computed on the compute units instead of the raster pipeline: on an
H100 the graphics pipeline runs on two of its TPCs while Warp kernels use all 132 SMs. The
results land in the GL textures the shading pass reads, through pixel buffers shared with CUDA
when the context allows it and through the host otherwise.

Depth is resolved with one 64-bit atomic minimum per covered pixel whose key holds the linear
depth in steps of ``1 / DEPTH_KEY_SCALE`` metres and the batch index in its low four bits, so
the nearest surface of all batches and the batch it belongs to are found in one pass.
"""

from __future__ import annotations

import ctypes
from typing import Any

import numpy as np
import warp as wp

from . import shaders

# depth keys count 0.1 um steps: int64 keys hold depths up to 5e10 m
DEPTH_KEY_SCALE = 1.0e7
BATCH_SLOTS = 16
EMPTY_DEPTH_KEY = 2**62
# threads sharing the pixels of one particle on CUDA (one on the CPU, where threads are not free)
CUDA_LANES = 8

assert shaders.MAX_BATCHES <= BATCH_SLOTS


@wp.struct
class SplatView:
    """Camera and target of one splat pass."""

    view: wp.mat44
    projection: wp.mat44
    # pixels of the target being written
    width: int
    height: int
    # pixels of the scene depth it is tested against
    scene_width: int
    scene_height: int
    near: float


@wp.func
def projected_interval(row: wp.vec4, row_w: wp.vec4):
    """NDC interval of one clip coordinate over the unit sphere mapped by the splat transform."""
    qw = wp.vec4(row_w[0], row_w[1], row_w[2], -row_w[3])
    qr = wp.vec4(row[0], row[1], row[2], -row[3])
    a = wp.dot(row, qw)
    b = wp.dot(row_w, qw)
    c = wp.dot(row, qr)
    h = wp.sqrt(wp.max(a * a - b * c, 0.0))
    x0 = (a - h) / b
    x1 = (a + h) / b
    return wp.min(x0, x1), wp.max(x0, x1)


@wp.func
def pixel_span(lo: float, hi: float, size: int):
    """First and last pixel whose centre lies in the NDC interval [lo, hi]."""
    first = int(wp.ceil((lo + 1.0) * 0.5 * float(size) - 0.5))
    last = int(wp.floor((hi + 1.0) * 0.5 * float(size) - 0.5))
    return wp.max(first, 0), wp.min(last, size - 1)


@wp.func
def ellipsoid_to_unit(instance: wp.array2d[wp.vec4], i: int, cam: SplatView, scale: float):
    """Eye-space centre, map onto the unit sphere, bounding radius [m] and volume share of particle i."""
    cr = instance[i, 0]
    r = cr[3] * scale
    a1 = instance[i, 1]
    a2 = instance[i, 2]
    a3 = instance[i, 3]
    s = wp.vec3(r * wp.max(a1[3], 1.0e-3), r * wp.max(a2[3], 1.0e-3), r * wp.max(a3[3], 1.0e-3))
    rot = wp.mat33(
        cam.view[0, 0],
        cam.view[0, 1],
        cam.view[0, 2],
        cam.view[1, 0],
        cam.view[1, 1],
        cam.view[1, 2],
        cam.view[2, 0],
        cam.view[2, 1],
        cam.view[2, 2],
    )
    e1 = wp.normalize(rot * wp.vec3(a1[0], a1[1], a1[2]))
    e2 = wp.normalize(rot * wp.vec3(a2[0], a2[1], a2[2]))
    e3 = wp.normalize(rot * wp.vec3(a3[0], a3[1], a3[2]))
    to_unit = wp.matrix_from_rows(e1 / s[0], e2 / s[1], e3 / s[2])
    c4 = cam.view * wp.vec4(cr[0], cr[1], cr[2], 1.0)
    c = wp.vec3(c4[0], c4[1], c4[2])
    bound = wp.max(s[0], wp.max(s[1], s[2]))
    # a particle of radius r stands for a cube of fluid of edge 2r (see THICKNESS_FRAGMENT)
    base = cr[3]
    share = 8.0 * base * base * base / (4.18879020479 * s[0] * s[1] * s[2])
    t = cam.projection * wp.matrix_from_cols(
        wp.vec4(e1[0] * s[0], e1[1] * s[0], e1[2] * s[0], 0.0),
        wp.vec4(e2[0] * s[1], e2[1] * s[1], e2[2] * s[1], 0.0),
        wp.vec4(e3[0] * s[2], e3[1] * s[2], e3[2] * s[2], 0.0),
        wp.vec4(c[0], c[1], c[2], 1.0),
    )
    return c, to_unit, bound, share, t


@wp.func
def pixel_ray(x: int, y: int, cam: SplatView):
    """Eye-space ray through a pixel centre, scaled to eye z = -1."""
    ndc_x = (float(x) + 0.5) / float(cam.width) * 2.0 - 1.0
    ndc_y = (float(y) + 0.5) / float(cam.height) * 2.0 - 1.0
    return wp.vec3(ndc_x / cam.projection[0, 0], ndc_y / cam.projection[1, 1], -1.0)


@wp.func
def window_depth(p: wp.vec3, cam: SplatView):
    clip = cam.projection * wp.vec4(p[0], p[1], p[2], 1.0)
    return clip[2] / clip[3] * 0.5 + 0.5


@wp.func
def scene_depth_at(scene_depth: wp.array2d[float], x: int, y: int, cam: SplatView):
    """Window depth of the scene at the target pixel (x, y), nearest sample when sizes differ."""
    sx = wp.min(int((float(x) + 0.5) * float(cam.scene_width) / float(cam.width)), cam.scene_width - 1)
    sy = wp.min(int((float(y) + 0.5) * float(cam.scene_height) / float(cam.height)), cam.scene_height - 1)
    return scene_depth[sy, sx]


@wp.func
def splat_footprint(instances: wp.array2d[wp.vec4], i: int, cam: SplatView, scale: float):
    """Ray-cast set-up of particle i and the pixel rectangle it covers (count 0: nothing to draw).

    Returns the map onto the unit sphere, the centre in those units, |centre|^2 - 1 there, the volume
    share, the rectangle's first pixel, its width and its pixel count.
    """
    c, to_unit, bound, share, t = ellipsoid_to_unit(instances, i, cam, scale)
    mc = to_unit * c
    qc = wp.dot(mc, mc) - 1.0
    # reaching the near plane: dropped, as the raster pass drops it
    if -(c[2] + bound) <= cam.near:
        return to_unit, mc, qc, share, 0, 0, 0, 0
    row_w = wp.vec4(t[3, 0], t[3, 1], t[3, 2], t[3, 3])
    bx0, bx1 = projected_interval(wp.vec4(t[0, 0], t[0, 1], t[0, 2], t[0, 3]), row_w)
    by0, by1 = projected_interval(wp.vec4(t[1, 0], t[1, 1], t[1, 2], t[1, 3]), row_w)
    x0, x1 = pixel_span(bx0, bx1, cam.width)
    y0, y1 = pixel_span(by0, by1, cam.height)
    nx = x1 - x0 + 1
    if nx <= 0 or y1 < y0:
        return to_unit, mc, qc, share, 0, 0, 0, 0
    return to_unit, mc, qc, share, x0, y0, nx, nx * (y1 - y0 + 1)


@wp.func
def footprint_pixel(k: int, x0: int, y0: int, nx: int):
    """Pixel k of a footprint rectangle of width nx starting at (x0, y0), row by row."""
    row = k // nx
    return x0 + k - row * nx, y0 + row


@wp.func
def hit_ellipsoid(to_unit: wp.mat33, mc: wp.vec3, qc: float, ray: wp.vec3):
    """Entry and exit parameter of the ray t * ray through the ellipsoid (entry <= 0: no hit in front).

    The ray-cast of ``_ELLIPSOID_HIT`` in shaders.py, with the centre terms of splat_footprint.
    """
    a = to_unit * ray
    qa = wp.dot(a, a)
    qb = -wp.dot(a, mc)
    disc = qb * qb - qa * qc
    if disc < 0.0:
        return -1.0, -1.0
    root = wp.sqrt(disc)
    return (-qb - root) / qa, (-qb + root) / qa


@wp.kernel
def splat_fluid_depth(
    instances: wp.array2d[wp.vec4],
    cam: SplatView,
    radius_scale: float,
    batch: int,
    lanes: int,
    scene_depth: wp.array2d[float],
    # outputs
    depth_keys: wp.array2d[wp.int64],
):
    """Nearest ray-cast ellipsoid surface per pixel, tested against the scene (pass 1)."""
    tid = wp.tid()
    i = tid // lanes
    to_unit, mc, qc, share, x0, y0, nx, count = splat_footprint(instances, i, cam, radius_scale)
    for k in range(tid - i * lanes, count, lanes):
        x, y = footprint_pixel(k, x0, y0, nx)
        ray = pixel_ray(x, y, cam)
        t0, t1 = hit_ellipsoid(to_unit, mc, qc, ray)
        if t0 <= 0.0:
            continue
        key = wp.int64(t0 * DEPTH_KEY_SCALE) * wp.int64(BATCH_SLOTS) + wp.int64(batch)
        # most covered pixels already hold a nearer surface: read before paying for the atomic
        if key >= depth_keys[y, x]:
            continue
        if window_depth(t0 * ray, cam) >= scene_depth_at(scene_depth, x, y, cam):
            continue
        wp.atomic_min(depth_keys, y, x, key)


@wp.kernel
def splat_fluid_thickness(
    instances: wp.array2d[wp.vec4],
    cam: SplatView,
    radius_scale: float,
    splat_scale: float,
    absorption: wp.vec3,
    lanes: int,
    scene_depth: wp.array2d[float],
    # outputs
    optical: wp.array2d[wp.vec4],
):
    """Additive absorbance and thickness [m] of enlarged splats in front of the scene (pass 2)."""
    tid = wp.tid()
    i = tid // lanes
    to_unit, mc, qc, share, x0, y0, nx, count = splat_footprint(instances, i, cam, radius_scale * splat_scale)
    for k in range(tid - i * lanes, count, lanes):
        x, y = footprint_pixel(k, x0, y0, nx)
        ray = pixel_ray(x, y, cam)
        t0, t1 = hit_ellipsoid(to_unit, mc, qc, ray)
        if t0 <= 0.0:
            continue
        if window_depth(t0 * ray, cam) >= scene_depth_at(scene_depth, x, y, cam):
            continue
        chord = (t1 - t0) * wp.length(ray) * share
        wp.atomic_add(
            optical, y, x, wp.vec4(absorption[0] * chord, absorption[1] * chord, absorption[2] * chord, chord)
        )


@wp.kernel
def resolve_fluid_depth(depth_keys: wp.array2d[wp.int64], depth: wp.array2d[wp.vec2]):
    """Depth key to (linear depth [m], batch index); (0, 0) where no fluid was hit."""
    y, x = wp.tid()
    key = depth_keys[y, x]
    if key >= wp.int64(EMPTY_DEPTH_KEY):
        depth[y, x] = wp.vec2(0.0, 0.0)
        return
    slots = wp.int64(BATCH_SLOTS)
    depth[y, x] = wp.vec2(float(key // slots) / DEPTH_KEY_SCALE, float(key % slots))


@wp.kernel
def filter_fluid_depth(
    source: wp.array2d[wp.vec2],
    dx: int,
    dy: int,
    focal_px: float,
    max_radius_px: int,
    blur_radius: wp.array[float],
    # outputs
    target: wp.array2d[wp.vec2],
):
    """One direction of the depth-aware filter of FILTER_FRAGMENT (pass 3)."""
    y, x = wp.tid()
    center = source[y, x]
    target[y, x] = center
    if center[0] <= 0.0:
        return
    batch = int(center[1] + 0.5)
    world = blur_radius[batch]
    sigma_px = world * focal_px / center[0]
    if world <= 0.0 or sigma_px < 0.5:
        return
    radius = wp.min(int(wp.ceil(2.0 * sigma_px)), max_radius_px)
    inv_2s2 = 0.5 / (sigma_px * sigma_px)
    # keeps apart only surfaces that overlap on screen (see FILTER_FRAGMENT)
    band = 4.0 * world
    inv_2r2 = 0.5 / (band * band)
    h = source.shape[0]
    w = source.shape[1]
    total = float(0.0)
    weight = float(0.0)
    for k in range(-radius, radius + 1):
        qx = wp.clamp(x + k * dx, 0, w - 1)
        qy = wp.clamp(y + k * dy, 0, h - 1)
        s = source[qy, qx]
        if s[0] <= 0.0 or int(s[1] + 0.5) != batch:
            continue
        dz = s[0] - center[0]
        wk = wp.exp(-float(k * k) * inv_2s2 - dz * dz * inv_2r2)
        total += wk * s[0]
        weight += wk
    target[y, x] = wp.vec2(total / weight, center[1])


@wp.kernel
def filter_fluid_optical(
    source: wp.array2d[wp.vec4],
    depth: wp.array2d[wp.vec2],
    depth_step: int,
    dx: int,
    dy: int,
    focal_px: float,
    max_radius_px: int,
    blur_radius: wp.array[float],
    # outputs
    target: wp.array2d[Any],
):
    """One direction of the Gaussian of OPTICAL_FILTER_FRAGMENT, width from the depth beside it.

    ``target`` holds vec4 or, for the texture upload, vec4h (the texture's own half-float format).
    """
    y, x = wp.tid()
    center = source[y, x]
    target[y, x] = target.dtype(center)
    d = depth[wp.min(y * depth_step, depth.shape[0] - 1), wp.min(x * depth_step, depth.shape[1] - 1)]
    if d[0] <= 0.0:
        return
    sigma_px = blur_radius[int(d[1] + 0.5)] * focal_px / d[0]
    if sigma_px < 0.5:
        return
    radius = wp.min(int(wp.ceil(2.0 * sigma_px)), max_radius_px)
    inv_2s2 = 0.5 / (sigma_px * sigma_px)
    h = source.shape[0]
    w = source.shape[1]
    total = wp.vec4(0.0)
    weight = float(0.0)
    for k in range(-radius, radius + 1):
        qx = wp.clamp(x + k * dx, 0, w - 1)
        qy = wp.clamp(y + k * dy, 0, h - 1)
        wk = wp.exp(-float(k * k) * inv_2s2)
        total += wk * source[qy, qx]
        weight += wk
    target[y, x] = target.dtype(total / weight)


def _matrix(flat):
    """GL's column-major 16 floats as a Warp matrix."""
    return wp.mat44(*np.asarray(flat, dtype=np.float32).reshape(4, 4).T.flatten())


class FluidSplatter:
    """Buffers and GL transfers of the compute passes for one frame size and device.

    With CUDA-GL interop one GL pixel buffer holds the three images that cross between the APIs (the
    scene's depth coming in, the fluid's depth and optical depth going out), so a frame maps and unmaps
    it once; each map is a synchronisation point between GL and CUDA.

    Args:
        gl: pyglet's GL module.
        device: Warp device of the fluid batches.
        size: Frame (width, height) [px].
        half: Size of the thickness target (width, height) [px].
        interop: Share pixel buffers between GL and CUDA (False: through the host).
    """

    def __init__(self, gl, device, size, half, interop):
        self.gl = gl
        self.device = device
        self.size = size
        self.half = half
        self.interop = bool(interop and device.is_cuda)
        w, h = size
        hw, hh = half
        self.lanes = CUDA_LANES if device.is_cuda else 1
        self.depth_keys = wp.empty((h, w), dtype=wp.int64, device=device)
        self.depth = wp.empty((h, w), dtype=wp.vec2, device=device)
        self.depth_middle = wp.empty((h, w), dtype=wp.vec2, device=device)
        self.optical = wp.empty((hh, hw), dtype=wp.vec4, device=device)
        self.optical_middle = wp.empty((hh, hw), dtype=wp.vec4, device=device)
        self.blur = wp.zeros(shaders.MAX_BATCHES, dtype=float, device=device)
        self._blur_host = np.zeros(shaders.MAX_BATCHES, dtype=np.float32)
        # byte offsets of the scene depth, fluid depth and optical images in the shared buffer
        self._layout = (0, 4 * w * h, 12 * w * h)
        self._nbytes = 12 * w * h + 8 * hw * hh
        self._pbo = 0
        self._registered = None
        self.timings_ms: dict[str, float] = {}
        if self.interop:
            try:
                ids = (gl.GLuint * 1)()
                gl.glGenBuffers(1, ids)
                self._pbo = int(ids[0])
                gl.glBindBuffer(gl.GL_PIXEL_PACK_BUFFER, self._pbo)
                gl.glBufferData(gl.GL_PIXEL_PACK_BUFFER, self._nbytes, None, gl.GL_STREAM_COPY)
                gl.glBindBuffer(gl.GL_PIXEL_PACK_BUFFER, 0)
                self._registered = wp.RegisteredGLBuffer(self._pbo, device, flags=wp.RegisteredGLBuffer.NONE)
            except Exception:
                # no CUDA-GL interop on this context: go through the host
                self.release()
                self.interop = False
        if not self.interop:
            self.scene_depth = wp.empty((h, w), dtype=float, device=device)
            self.depth_out = wp.empty((h, w), dtype=wp.vec2, device=device)
            self.optical_out = wp.empty((hh, hw), dtype=wp.vec4h, device=device)

    def release(self):
        self._registered = None
        if self._pbo:
            self.gl.glDeleteBuffers(1, ctypes.byref(self.gl.GLuint(self._pbo)))
        self._pbo = 0

    def _map(self):
        """The three images as Warp arrays over the mapped shared buffer."""
        w, h = self.size
        hw, hh = self.half
        base = self._registered.map(dtype=wp.uint8, shape=(self._nbytes,)).ptr
        return tuple(
            wp.array(ptr=base + offset, dtype=dtype, shape=shape, device=self.device)
            for offset, dtype, shape in zip(
                self._layout, (float, wp.vec2, wp.vec4h), ((h, w), (h, w), (hh, hw)), strict=True
            )
        )

    def run(self, batches, view, proj, focal_px, blur, scene_fbo, depth_texture, optical_texture, timer):
        """Passes 1-3 for ``batches`` [(index, FluidBatchGL)], written into the two GL textures.

        ``scene_fbo`` holds the scene's window depth in a one-channel float colour attachment.
        ``timer`` marks the GL side: ``scene_depth_readback``, ``compute`` (up to the end of the CUDA
        work, waits for the host included) and ``texture_upload``; with ``timer.enabled`` the CUDA
        kernels are also timed with events into :attr:`timings_ms`.
        """
        measure = timer.enabled
        gl = self.gl
        w, h = self.size
        hw, hh = self.half
        device = self.device
        events = []

        def mark(name):
            if measure and device.is_cuda:
                event = wp.Event(device, enable_timing=True)
                wp.record_event(event)
                events.append((name, event))

        # the scene's depth, which hides the fluid behind it
        gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, scene_fbo)
        gl.glPixelStorei(gl.GL_PACK_ALIGNMENT, 4)
        if self.interop:
            gl.glBindBuffer(gl.GL_PIXEL_PACK_BUFFER, self._pbo)
            gl.glReadPixels(0, 0, w, h, gl.GL_RED, gl.GL_FLOAT, ctypes.c_void_p(self._layout[0]))
            gl.glBindBuffer(gl.GL_PIXEL_PACK_BUFFER, 0)
        else:
            host = np.empty((h, w), dtype=np.float32)
            gl.glReadPixels(0, 0, w, h, gl.GL_RED, gl.GL_FLOAT, host.ctypes.data)
            self.scene_depth.assign(host)
        gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, 0)
        timer.mark("scene_depth_readback")
        if self.interop:
            scene, depth_out, optical_out = self._map()
        else:
            scene, depth_out, optical_out = self.scene_depth, self.depth_out, self.optical_out

        with wp.ScopedDevice(device):
            mark("start")
            if not np.array_equal(self._blur_host, blur):
                self._blur_host[:] = blur
                self.blur.assign(self._blur_host)
            near = float(proj[14] / (proj[10] - 1.0))
            full = SplatView()
            full.view, full.projection = _matrix(view), _matrix(proj)
            full.width, full.height, full.scene_width, full.scene_height, full.near = w, h, w, h, near
            half = SplatView()
            half.view, half.projection = full.view, full.projection
            half.width, half.height, half.scene_width, half.scene_height, half.near = hw, hh, w, h, near

            self.depth_keys.fill_(EMPTY_DEPTH_KEY)
            for index, batch in batches:
                wp.launch(
                    splat_fluid_depth,
                    dim=batch.count * self.lanes,
                    inputs=[batch.packed, full, batch.material.radius_scale, index, self.lanes, scene],
                    outputs=[self.depth_keys],
                )
            wp.launch(resolve_fluid_depth, dim=(h, w), inputs=[self.depth_keys], outputs=[self.depth])
            mark("depth")
            self.optical.zero_()
            for _, batch in batches:
                wp.launch(
                    splat_fluid_thickness,
                    dim=batch.count * self.lanes,
                    inputs=[
                        batch.packed,
                        half,
                        batch.material.radius_scale,
                        shaders.THICKNESS_SPLAT_SCALE,
                        wp.vec3(*batch.material.absorption_coefficients()),
                        self.lanes,
                        scene,
                    ],
                    outputs=[self.optical],
                )
            mark("thickness")
            for source, dx, dy, target in ((self.depth, 1, 0, self.depth_middle), (self.depth_middle, 0, 1, depth_out)):
                wp.launch(
                    filter_fluid_depth,
                    dim=(h, w),
                    inputs=[source, dx, dy, focal_px, shaders.MAX_FILTER_RADIUS_PX, self.blur],
                    outputs=[target],
                )
            half_focal = focal_px * hh / h
            for source, dx, dy, target in (
                (self.optical, 1, 0, self.optical_middle),
                (self.optical_middle, 0, 1, optical_out),
            ):
                wp.launch(
                    filter_fluid_optical,
                    dim=(hh, hw),
                    inputs=[source, depth_out, 2, dx, dy, half_focal, shaders.MAX_FILTER_RADIUS_PX, self.blur],
                    outputs=[target],
                )
            mark("smooth")

        gl.glPixelStorei(gl.GL_UNPACK_ALIGNMENT, 4)
        uploads = (
            (depth_texture, gl.GL_RG, gl.GL_FLOAT, (w, h)),
            (optical_texture, gl.GL_RGBA, gl.GL_HALF_FLOAT, (hw, hh)),
        )
        if self.interop:
            self._registered.unmap()
            timer.mark("compute")
            gl.glBindBuffer(gl.GL_PIXEL_UNPACK_BUFFER, self._pbo)
            for (texture, fmt, kind, size), offset in zip(uploads, self._layout[1:], strict=True):
                gl.glBindTexture(gl.GL_TEXTURE_2D, texture)
                gl.glTexSubImage2D(gl.GL_TEXTURE_2D, 0, 0, 0, *size, fmt, kind, ctypes.c_void_p(offset))
            gl.glBindBuffer(gl.GL_PIXEL_UNPACK_BUFFER, 0)
        else:
            hosts = [np.ascontiguousarray(a.numpy()) for a in (depth_out, optical_out)]
            timer.mark("compute")
            for (texture, fmt, kind, size), host in zip(uploads, hosts, strict=True):
                gl.glBindTexture(gl.GL_TEXTURE_2D, texture)
                gl.glTexSubImage2D(gl.GL_TEXTURE_2D, 0, 0, 0, *size, fmt, kind, host.ctypes.data)
        gl.glBindTexture(gl.GL_TEXTURE_2D, 0)
        timer.mark("texture_upload")

        self.timings_ms = {}
        if events:
            wp.synchronize_device(device)
            for (_, start), (name, end) in zip(events[:-1], events[1:], strict=True):
                self.timings_ms[name] = wp.get_event_elapsed_time(start, end)
