# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The screen-space fluid surface of ViewerGL, measured on rendered frames.

Runs headless through EGL (Mesa's llvmpipe on machines without a GPU; see README for the
packages); the resize test runs under Xvfb because an EGL pbuffer cannot be resized. Frames are
small so that software rasterisation stays quick. The viewer draws on the CPU device. The image
tests run twice: with the GLSL passes ("raster") and with the Warp kernels ("compute") for the
depth, thickness and smoothing passes.
"""

import ast
import os
import subprocess
import sys
import textwrap
import unittest

import newton.viewer
import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices
from scipy.ndimage import binary_dilation, binary_erosion

import newton

if not os.environ.get("DISPLAY"):
    # EGL without an X server; must be set before pyglet opens its first window
    import pyglet

    pyglet.options["headless"] = True

W, H = 256, 192
S = 0.02  # particle spacing [m]
R = 0.5 * S


def lattice(dims, origin, spacing=S):
    g = np.stack(np.meshgrid(*[np.arange(n) for n in dims], indexing="ij"), -1).reshape(-1, 3)
    return (g * spacing + np.asarray(origin)).astype(np.float32)


def ball(radius, center):
    n = int(radius / S) + 1
    p = lattice((2 * n + 1,) * 3, (-n * S,) * 3)
    return (p[np.linalg.norm(p, axis=1) <= radius] + np.asarray(center)).astype(np.float32)


class Scene:
    """A small ViewerGL with optional static boxes, for one test."""

    # where the fluid passes run in the tests that follow (set per test, see _in_mode)
    splatting = "raster"

    def __init__(self, boxes=(), ground=False, sky=True, size=(W, H)):
        self.viewer = newton.viewer.ViewerGL(width=size[0], height=size[1], headless=True)
        self.viewer.fluid_renderer.splatting = Scene.splatting
        builder = newton.ModelBuilder()
        if ground:
            builder.add_ground_plane()
        for center, half in boxes:
            builder.add_shape_box(
                -1, xform=wp.transform(wp.vec3(*center), wp.quat_identity()), hx=half[0], hy=half[1], hz=half[2]
            )
        self.model = builder.finalize(device="cpu")
        self.viewer.set_model(self.model)
        self.viewer.renderer.draw_sky = sky
        self.state = self.model.state()

    def frame(self, batches=(), repeat=1):
        """Draw ``batches`` (name, positions, kwargs); return the frame (top row first) and fluid depth (bottom row first)."""
        for _ in range(repeat):
            self.viewer.begin_frame(0.0)
            self.viewer.log_state(self.state)
            for name, positions, kwargs in batches:
                arr = None if positions is None else wp.array(positions, dtype=wp.vec3, device="cpu")
                self.viewer.log_fluid(name, arr, **kwargs)
            self.viewer.end_frame()
        image = self.viewer.get_frame().numpy().astype(np.float64)
        fluid = self.viewer.fluid_renderer
        if fluid.visible_batches():
            assert fluid.last_splatting == Scene.splatting, (fluid.last_splatting, Scene.splatting)
        depth = fluid.read_texture("depth") if fluid._targets is not None else None
        return image, depth

    def rays(self):
        """World-space origin and per-pixel unit-depth ray (eye z = -1) of the last frame, rows bottom-up."""
        r = self.viewer.renderer
        view = np.asarray(r._view_matrix, dtype=np.float64).reshape(4, 4).T
        proj = np.asarray(r._projection_matrix, dtype=np.float64).reshape(4, 4).T
        w, h = r._screen_width, r._screen_height
        x = (np.arange(w) + 0.5) / w * 2.0 - 1.0
        y = (np.arange(h) + 0.5) / h * 2.0 - 1.0
        xx, yy = np.meshgrid(x, y)
        d_eye = np.stack([xx / proj[0, 0], yy / proj[1, 1], -np.ones_like(xx)], -1)
        rot, trans = view[:3, :3], view[:3, 3]
        origin = -rot.T @ trans
        return origin, d_eye @ rot  # rows of d_eye times rot == rot.T @ d

    def close(self):
        self.viewer.close()


def test_flat_pool_depth_and_holes(test, device):
    scene = Scene()
    try:
        pool = lattice((30, 30, 3), (-0.3, -0.3, 0.0))
        scene.viewer.set_camera(wp.vec3(0.0, -0.55, 0.75), pitch=-55.0, yaw=90.0)
        # the default radius_scale (1.8) closes the channels a lattice of touching spheres leaves
        _, depth = scene.frame([("/pool", pool, {"radii": R})], repeat=2)
        origin, rays = scene.rays()
        plane = pool[:, 2].max() + 1.8 * R  # top of the top layer's drawn spheres
        t = (plane - origin[2]) / rays[..., 2]
        hit = origin + t[..., None] * rays
        lo, hi = pool[:, :2].min(0) + S, pool[:, :2].max(0) - S  # one spacing inside the footprint
        inside = np.all((hit[..., :2] > lo) & (hit[..., :2] < hi), axis=-1) & (t > 0)
        test.assertGreater(inside.sum(), 0.2 * W * H)
        z = depth[..., 0]
        test.assertEqual(int((z[inside] <= 0.0).sum()), 0, "holes in the pool's footprint")
        err = np.abs(z[inside] - t[inside])
        test.assertLess(err.mean(), 0.2 * S, f"mean depth error {err.mean():.5f} m")
        test.assertLess(np.percentile(err, 99), 0.5 * S, f"99th percentile depth error {np.percentile(err, 99):.5f} m")
    finally:
        scene.close()


def test_sphere_silhouette_iou(test, device):
    scene = Scene()
    try:
        radius, center = 0.16, np.array([0.0, 0.0, 0.3])
        scene.viewer.set_camera(wp.vec3(0.0, -1.2, 0.45), pitch=-7.0, yaw=90.0)
        particles = ball(radius, center)
        _, depth = scene.frame([("/ball", particles, {"radii": R})], repeat=2)
        origin, rays = scene.rays()
        unit = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
        oc = center - origin
        dist = np.linalg.norm(oc - (unit @ oc)[..., None] * unit, axis=-1)
        # the ball of particles of radius R: outermost centres plus R (the drawn spheres, 1.8 R, overlap
        # into the lattice and only reach beyond it at the outermost particles)
        disk = dist < np.linalg.norm(particles - center, axis=1).max() + R
        drawn = depth[..., 0] > 0.0
        iou = (disk & drawn).sum() / (disk | drawn).sum()
        test.assertGreater(iou, 0.93, f"IoU {iou:.3f}")
    finally:
        scene.close()


def test_box_in_front_occludes_fluid(test, device):
    pool = lattice((30, 20, 3), (-0.3, -0.2, 0.0))
    box = ((0.0, -0.35, 0.15), (0.08, 0.02, 0.15))
    masks, images = [], []
    for boxes in ((), (box,)):
        scene = Scene(boxes=boxes)
        try:
            scene.viewer.set_camera(wp.vec3(0.0, -0.9, 0.35), pitch=-20.0, yaw=90.0)
            images.append(scene.frame(repeat=2)[0])
            _, depth = scene.frame([("/pool", pool, {"radii": R})], repeat=2)
            masks.append(depth[..., 0] > 0.0)
        finally:
            scene.close()
    box_raw = np.any(np.abs(images[1] - images[0]) > 1.0, axis=-1)[::-1]  # bottom row first, like depth
    # pixels on the box's outline are partly box, partly behind it (multisampled edges)
    box_pixels = binary_erosion(box_raw)
    away = ~binary_dilation(box_raw, iterations=2)
    test.assertGreater((box_pixels & masks[0]).sum(), 500, "the box should cover part of the fluid")
    test.assertEqual(int((box_pixels & masks[1]).sum()), 0, "fluid drawn over the box in front of it")
    test.assertTrue(np.array_equal(masks[0] & away, masks[1] & away), "the box changed fluid away from it")


def test_beer_lambert_transmission(test, device):
    scene = Scene(sky=False)
    try:
        sigma = np.array([0.0, 6.0, 3.0])
        material = {
            "radii": R,
            "absorption": tuple(sigma),
            "color": (1.0, 1.0, 1.0, 0.0),
            "reflectance": 0.0,
            "specular_intensity": 0.0,
            "ior": 1.0,
        }
        thin = lattice((12, 24, 4), (-0.3, -0.24, 0.0))
        thick = lattice((12, 24, 8), (0.06, -0.24, 0.0))
        scene.viewer.set_camera(wp.vec3(0.0, -0.02, 1.2), pitch=-89.0, yaw=90.0)
        image, depth = scene.frame([("/thin", thin, material), ("/thick", thick, material)], repeat=2)
        background = np.asarray(scene.viewer.renderer.sky_upper) * 255.0
        linear = (image[::-1] / 255.0) ** 2.2 / (background / 255.0) ** 2.2
        origin, rays = scene.rays()
        absorbance = []
        for k, block in enumerate((thin, thick)):
            t = (block[:, 2].max() - origin[2]) / rays[..., 2]
            hit = origin + t[..., None] * rays
            lo, hi = block[:, :2].min(0) + 3 * S, block[:, :2].max(0) - 3 * S
            core = np.all((hit[..., :2] > lo) & (hit[..., :2] < hi), axis=-1) & (depth[..., 1] == k)
            test.assertGreater(core.sum(), 200)
            absorbance.append(-np.log(np.median(linear[core][:, 1:], axis=0)))
            thickness = len(block) * S**3 / np.prod(np.ptp(block[:, :2], axis=0) + S)  # volume per area [m]
            np.testing.assert_allclose(absorbance[-1], sigma[1:] * thickness, rtol=0.2)
        np.testing.assert_allclose(absorbance[1] / absorbance[0], 2.0, rtol=0.1)
    finally:
        scene.close()


def test_two_batches_materials_and_mutual_occlusion(test, device):
    scene = Scene()
    try:
        red = {"radii": R, "color": (0.9, 0.1, 0.05, 1.0), "reflectance": 0.0, "specular_intensity": 0.0}
        blue = {"radii": R, "color": (0.05, 0.1, 0.9, 1.0), "reflectance": 0.0, "specular_intensity": 0.0}
        front = ball(0.08, (-0.02, -0.1, 0.2))
        back = ball(0.12, (0.06, 0.1, 0.2))
        scene.viewer.set_camera(wp.vec3(0.0, -1.0, 0.2), pitch=0.0, yaw=90.0)
        image, depth = scene.frame([("/red", front, red), ("/blue", back, blue)], repeat=2)
        rgb = image[::-1]
        batch = np.where(depth[..., 0] > 0.0, np.rint(depth[..., 1]), -1)
        for index, (hi, lo) in ((0, (0, 2)), (1, (2, 0))):
            pixels = rgb[batch == index]
            test.assertGreater(len(pixels), 300)
            test.assertGreater(np.median(pixels[:, hi] - pixels[:, lo]), 20.0)
        # the red ball is in front: where both project, red wins
        origin, rays = scene.rays()
        unit = rays / np.linalg.norm(rays, axis=-1, keepdims=True)

        def covers(center, radius):
            oc = np.asarray(center) - origin
            return np.linalg.norm(oc - (unit @ oc)[..., None] * unit, axis=-1) < radius - 2 * S

        both = covers((-0.02, -0.1, 0.2), 0.08) & covers((0.06, 0.1, 0.2), 0.12)
        test.assertGreater(both.sum(), 100)
        test.assertTrue(np.all(batch[both] == 0))
    finally:
        scene.close()


def test_counts_change_and_removal(test, device):
    scene = Scene()
    try:
        scene.viewer.set_camera(wp.vec3(0.0, -0.8, 0.5), pitch=-30.0, yaw=90.0)
        areas = []
        for n in (4, 12, 2):
            _, depth = scene.frame([("/pool", lattice((n, n, 2), (-0.12, -0.12, 0.0)), {"radii": R})])
            areas.append(int((depth[..., 0] > 0).sum()))
        test.assertTrue(areas[0] < areas[1] and areas[2] < areas[0], areas)
        image_with, _ = scene.frame([("/pool", lattice((8, 8, 2), (-0.08, -0.08, 0.0)), {"radii": R})])
        image_none, _ = scene.frame([("/pool", None, {})])
        empty, _ = scene.frame()
        test.assertNotIn("/pool", scene.viewer.fluid_renderer.batches)
        test.assertTrue(np.array_equal(image_none, empty))
        test.assertFalse(np.array_equal(image_with, empty))
    finally:
        scene.close()


def test_surface_toggle_shows_particles(test, device):
    scene = Scene()
    try:
        scene.viewer.set_camera(wp.vec3(0.0, -0.8, 0.5), pitch=-30.0, yaw=90.0)
        pool = [("/pool", lattice((8, 8, 2), (-0.08, -0.08, 0.0)), {"radii": R, "color": (1.0, 0.2, 0.1)})]
        surface, _ = scene.frame(pool)
        test.assertFalse(scene.viewer.objects.get("/pool") is not None and not scene.viewer.objects["/pool"].hidden)
        scene.viewer.fluid_surface = False
        points, _ = scene.frame(pool)
        test.assertFalse(scene.viewer.objects["/pool"].hidden)
        test.assertEqual(scene.viewer.fluid_renderer.visible_batches(), [])
        test.assertFalse(np.array_equal(surface, points))
        scene.viewer.fluid_surface = True
        again, _ = scene.frame(pool)
        test.assertTrue(scene.viewer.objects["/pool"].hidden)
        test.assertTrue(np.array_equal(surface, again))
    finally:
        scene.close()


def test_diffuse_hook_sees_fluid_depth(test, device):
    scene = Scene()
    try:
        seen = []

        def hook(ctx):
            gl = scene.viewer.renderer.gl
            out = np.zeros((ctx.height, ctx.width, 2), dtype=np.float32)
            gl.glBindTexture(gl.GL_TEXTURE_2D, ctx.depth_texture)
            gl.glGetTexImage(gl.GL_TEXTURE_2D, 0, gl.GL_RG, gl.GL_FLOAT, out.ctypes.data)
            gl.glBindTexture(gl.GL_TEXTURE_2D, 0)
            seen.append(out)
            # paint a square through the hook: it must reach the captured frame
            gl.glEnable(gl.GL_SCISSOR_TEST)
            gl.glScissor(0, 0, 8, 8)
            gl.glClearColor(1.0, 0.0, 1.0, 1.0)
            gl.glClear(gl.GL_COLOR_BUFFER_BIT)
            gl.glDisable(gl.GL_SCISSOR_TEST)

        scene.viewer.fluid_renderer.diffuse_hooks.append(hook)
        scene.viewer.set_camera(wp.vec3(0.0, -0.8, 0.5), pitch=-30.0, yaw=90.0)
        image, depth = scene.frame([("/pool", lattice((8, 8, 2), (-0.08, -0.08, 0.0)), {"radii": R})])
        test.assertEqual(len(seen), 1)
        np.testing.assert_array_equal(seen[0], depth)
        test.assertTrue(np.all(image[-8:, :8] == (255.0, 0.0, 255.0)))
    finally:
        scene.close()


def test_diffuse_sprites(test, device):
    box = ((0.12, -0.25, 0.1), (0.05, 0.02, 0.1))
    scene = Scene(boxes=(box,))
    try:
        scene.viewer.set_camera(wp.vec3(0.0, -0.9, 0.3), pitch=-15.0, yaw=90.0)
        pool = ("/pool", lattice((16, 10, 5), (-0.15, -0.1, 0.0)), {"radii": R, "color": (0.2, 0.4, 0.9, 0.0)})
        # spray above the pool, a bubble inside it, one behind the box, one dead
        points = np.array([[-0.06, 0.0, 0.2], [-0.06, 0.0, 0.03], [0.12, 0.0, 0.1], [0.0, 0.0, 0.25]], np.float32)
        life = wp.array([1.0, 1.0, 1.0, 0.0], dtype=float, device="cpu")
        kinds = wp.array([0, 2, 0, 0], dtype=wp.int32, device="cpu")
        base, _ = scene.frame([pool], repeat=2)
        scene.viewer.begin_frame(0.0)
        scene.viewer.log_state(scene.state)
        scene.viewer.log_fluid(pool[0], wp.array(pool[1], dtype=wp.vec3, device="cpu"), **pool[2])
        scene.viewer.log_fluid_diffuse(
            "/foam",
            wp.array(points, dtype=wp.vec3, device="cpu"),
            lifetimes=life,
            kinds=kinds,
            radius=0.012,
            color=(1.0, 1.0, 1.0, 1.0),
        )
        scene.viewer.end_frame()
        image = scene.viewer.get_frame().numpy().astype(np.float64)
        origin, rays = scene.rays()
        frame = scene.viewer.fluid_renderer.frame
        view = np.asarray(frame.view_matrix, np.float64).reshape(4, 4).T
        proj = np.asarray(frame.projection_matrix, np.float64).reshape(4, 4).T

        def pixel(p):
            clip = proj @ view @ np.append(p, 1.0)
            ndc = clip[:2] / clip[3]
            x, y = (ndc * 0.5 + 0.5) * (W, H)
            return int(H - 1 - y), int(x)  # row in the top-down frame

        gain = [image[pixel(p)].sum() - base[pixel(p)].sum() for p in points]
        test.assertGreater(gain[0], 150.0, gain)  # spray in the open: bright
        test.assertGreater(gain[1], 5.0, gain)  # a bubble shows through the fluid,
        test.assertLess(gain[1], 0.6 * gain[0], gain)  # dimmed by it
        test.assertLess(abs(gain[2]), 3.0, gain)  # behind the box: hidden
        test.assertLess(abs(gain[3]), 3.0, gain)  # dead: not drawn
        # removal
        scene.viewer.log_fluid_diffuse("/foam", None)
        test.assertNotIn("/foam", scene.viewer.fluid_renderer.diffuse_batches)
    finally:
        scene.close()


def test_render_does_not_change_simulation(test, device):
    def simulate(render):
        builder = newton.ModelBuilder()
        builder.add_particle_grid(
            pos=wp.vec3(-0.05, -0.05, 0.5 * S),
            rot=wp.quat_identity(),
            vel=wp.vec3(0.0),
            dim_x=6,
            dim_y=6,
            dim_z=6,
            cell_x=S,
            cell_y=S,
            cell_z=S,
            mass=1000.0 * S**3,
            jitter=0.0,
            radius_mean=R,
            flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
        )
        builder.add_ground_plane()
        model = builder.finalize(device="cpu")
        solver = newton.solvers.SolverXPBD(model, iterations=2, fluid_rest_distance=S)
        s0, s1 = model.state(), model.state()
        pipeline = newton.CollisionPipeline(model, soft_contact_gap=R)
        contacts = pipeline.contacts()
        viewer = None
        if render:
            viewer = newton.viewer.ViewerGL(width=128, height=96, headless=True)
            viewer.fluid_renderer.splatting = Scene.splatting
            viewer.set_model(model)
        for _ in range(6):
            for _ in range(2):
                s0.clear_forces()
                pipeline.collide(s0, contacts)
                solver.step(s0, s1, None, contacts, 1.0 / 120.0)
                s0, s1 = s1, s0
            if viewer is not None:
                solver.update_render_particles(s0)
                viewer.begin_frame(0.0)
                viewer.log_state(s0)
                viewer.log_fluid(
                    "/fluid",
                    solver.render_positions,
                    radii=model.particle_radius,
                    anisotropy=solver.render_anisotropy,
                    anisotropy_secondary=solver.render_anisotropy_secondary,
                    anisotropy_tertiary=solver.render_anisotropy_tertiary,
                )
                viewer.end_frame()
        if viewer is not None:
            test.assertEqual(len(viewer.fluid_renderer.visible_batches()), 1)
            viewer.close()
        return s0.particle_q.numpy(), s0.particle_qd.numpy()

    plain, rendered = simulate(False), simulate(True)
    np.testing.assert_array_equal(plain[0], rendered[0])
    np.testing.assert_array_equal(plain[1], rendered[1])


def test_bad_material_raises(test, device):
    scene = Scene()
    try:
        positions = wp.array(lattice((2, 2, 2), (0.0, 0.0, 0.0)), dtype=wp.vec3, device="cpu")
        for viewer in (scene.viewer, newton.viewer.ViewerNull()):
            for kwargs, name in (
                ({"ior": 0.5}, "ior"),
                ({"reflectance": 1.5}, "reflectance"),
                ({"color": (2.0, 0.0, 0.0)}, "color"),
                ({"absorption": (-1.0, 0.0, 0.0)}, "absorption"),
                ({"blur_radius_world": -0.1}, "blur_radius_world"),
                ({"specular_power": 0.0}, "specular_power"),
                ({"radius_scale": 0.0}, "radius_scale"),
                ({"anisotropy": wp.zeros(8, dtype=wp.vec4, device="cpu")}, "anisotropy_secondary"),
            ):
                with test.assertRaisesRegex(ValueError, name):
                    viewer.log_fluid("/f", positions, radii=R, **kwargs)
            for kwargs, name in (
                ({"radius": 0.0}, "radius"),
                ({"color": (1.0, 1.0)}, "color"),
                ({"stretch_time": -1.0}, "stretch_time"),
                ({"fade_length": 0.0}, "fade_length"),
                ({"lifetimes": wp.zeros(2, dtype=float, device="cpu")}, "lifetimes"),
            ):
                with test.assertRaisesRegex(ValueError, name):
                    viewer.log_fluid_diffuse("/d", positions, **kwargs)
    finally:
        scene.close()


RESIZE_SCRIPT = textwrap.dedent(
    """
    import numpy as np, warp as wp, newton, newton.viewer
    v = newton.viewer.ViewerGL(width=200, height=150)  # a real (Xvfb) window: its events drive the resize
    v.fluid_renderer.splatting = SPLATTING
    v.set_model(newton.ModelBuilder().finalize(device="cpu"))
    v.set_camera(wp.vec3(0.0, -0.8, 0.5), pitch=-30.0, yaw=90.0)
    g = np.stack(np.meshgrid(*[np.arange(8)] * 3, indexing="ij"), -1).reshape(-1, 3) * 0.02 - 0.07
    pos = wp.array(g.astype(np.float32), dtype=wp.vec3, device="cpu")
    def frame():
        v.begin_frame(0.0); v.log_fluid("/f", pos, radii=0.01); v.end_frame()
        return v.get_frame().numpy(), v.fluid_renderer.read_texture("depth")
    a, da = frame()
    v.renderer.window.set_size(320, 240)
    for _ in range(3):
        b, db = frame()
    assert v.fluid_renderer.last_splatting == SPLATTING, v.fluid_renderer.last_splatting
    print("SIZES", repr((a.shape, da.shape, b.shape, db.shape, int((da[..., 0] > 0).sum()), int((db[..., 0] > 0).sum()))))
    v.close()
    """
)


def test_resize_keeps_working(test, device):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "PYGLET_HEADLESS")}
    script = RESIZE_SCRIPT.replace("SPLATTING", repr(Scene.splatting))
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 800x600x24", sys.executable, "-c", script]
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    test.assertEqual(out.returncode, 0, out.stderr[-3000:])
    line = next(x for x in out.stdout.splitlines() if x.startswith("SIZES"))
    sizes = ast.literal_eval(line.removeprefix("SIZES"))
    test.assertEqual(sizes[0][:2], (150, 200))
    test.assertEqual(sizes[2][:2], (240, 320))
    test.assertEqual(sizes[3][:2], (240, 320))
    test.assertGreater(sizes[5], 1.5 * sizes[4])  # the same fluid covers more pixels in the larger frame


def test_viewer_picks_fluid_particles(test, device):
    from newton._src.viewer.gl.fluid.picking import FluidPicking  # noqa: PLC0415

    scene = Scene(ground=True)  # no fluid: upstream's picking
    test.assertNotIsInstance(scene.viewer.picking, FluidPicking)
    builder = newton.ModelBuilder()
    builder.add_particle_grid(
        pos=wp.vec3(0.0),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0),
        dim_x=4,
        dim_y=4,
        dim_z=2,
        cell_x=S,
        cell_y=S,
        cell_z=S,
        mass=1000.0 * S**3,
        jitter=0.0,
        radius_mean=R,
        flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
    )
    model = builder.finalize(device="cpu")
    scene.viewer.set_model(model)
    test.assertIsInstance(scene.viewer.picking, FluidPicking)
    state = model.state()
    scene.viewer.picking.pick(state, (0.0, 0.0, 1.0), (0.0, 0.0, -1.0))
    q = state.particle_q.numpy()
    top = int(np.flatnonzero(np.all(np.abs(q - (0.0, 0.0, S)) < 1.0e-6, axis=1))[0])
    test.assertEqual(scene.viewer.picking.pick_particle, top)  # the top layer's particle at the origin
    state.clear_forces()
    scene.viewer.picking.update((0.1, 0.0, 1.0), (0.0, 0.0, -1.0))
    scene.viewer.apply_forces(state)
    test.assertGreater(state.particle_f.numpy()[top, 0], 0.0)


def test_compute_passes_match_raster(test, device):
    """The Warp passes draw what the GLSL passes draw: coverage, depth, batch, thickness, final image."""
    scene = Scene(boxes=(((0.05, -0.3, 0.3), (0.05, 0.05, 0.05)),))
    try:
        scene.viewer.set_camera(wp.vec3(0.0, -1.2, 0.45), pitch=-7.0, yaw=90.0)
        batches = []
        for name, radius, center, color in (
            ("/big", 0.16, (0.0, 0.0, 0.3), (0.2, 0.45, 0.9, 1.0)),
            ("/small", 0.08, (0.2, -0.1, 0.3), (0.9, 0.2, 0.1, 1.0)),
        ):
            positions = wp.array(ball(radius, np.asarray(center)), dtype=wp.vec3, device=device)
            batches.append((name, positions, {"radii": R, "color": color}))
        fluid = scene.viewer.fluid_renderer
        frames = {}
        for mode in ("raster", "compute"):
            fluid.splatting = mode
            for _ in range(2):
                scene.viewer.begin_frame(0.0)
                scene.viewer.log_state(scene.state)
                for name, positions, kwargs in batches:
                    scene.viewer.log_fluid(name, positions, **kwargs)
                scene.viewer.end_frame()
            test.assertEqual(fluid.last_splatting, mode)
            frames[mode] = (
                scene.viewer.get_frame().numpy().astype(np.float64),
                fluid.read_texture("depth"),
                fluid.read_texture("optical"),
            )
        (image_r, depth_r, optical_r), (image_c, depth_c, optical_c) = frames["raster"], frames["compute"]
        covered_r, covered_c = depth_r[..., 0] > 0.0, depth_c[..., 0] > 0.0
        test.assertGreater(covered_r.sum(), 0.05 * W * H)
        test.assertLessEqual(int((covered_r ^ covered_c).sum()), 2, "pixels covered by one path only")
        both = covered_r & covered_c
        test.assertLess(np.abs(depth_r[..., 0] - depth_c[..., 0])[both].max(), 1.0e-4)
        test.assertEqual(int((depth_r[..., 1] != depth_c[..., 1])[both].sum()), 0, "batch index differs")
        test.assertEqual(set(np.unique(depth_c[..., 1][covered_c])), {0.0, 1.0})
        # thickness: the raster path sums in half floats, and which full-resolution scene depth sample a
        # half-resolution pixel is tested against along the box's outline is the driver's choice
        off = np.abs(optical_r - optical_c).max(axis=-1) > 0.03 * optical_r.max()
        test.assertLess(off.mean(), 0.01, f"{int(off.sum())} half-resolution pixels differ in thickness")
        test.assertLess(np.abs(optical_r - optical_c).mean(), 0.002 * optical_r.max())
        # the final image: equal up to rounding but for those outline pixels
        diff = np.abs(image_r - image_c).max(axis=-1)
        test.assertLess(diff.mean(), 0.1)
        test.assertLess((diff > 2.0).mean(), 0.01, f"{int((diff > 2.0).sum())} pixels differ by more than 2 levels")
    finally:
        scene.close()


def test_splatting_mode(test, device):
    scene = Scene()
    try:
        fluid = scene.viewer.fluid_renderer
        with test.assertRaisesRegex(ValueError, "splatting='gpu'"):
            fluid.splatting = "gpu"
        fluid.splatting = "auto"
        # CPU arrays: auto draws with the raster passes
        scene.frame([("/f", lattice((4, 4, 4), (-0.03, -0.03, 0.0)), {"radii": R})])
        test.assertEqual(fluid.last_splatting, "raster")
    finally:
        scene.close()


def _in_mode(func, mode):
    def run(test, device):
        previous = Scene.splatting
        Scene.splatting = mode
        try:
            func(test, device)
        finally:
            Scene.splatting = previous

    return run


class TestFluidRenderGL(unittest.TestCase):
    pass


# tests whose pictures come from the depth, thickness and smoothing passes run with both implementations
_BOTH_MODES = {
    "test_flat_pool_depth_and_holes",
    "test_sphere_silhouette_iou",
    "test_box_in_front_occludes_fluid",
    "test_beer_lambert_transmission",
    "test_two_batches_materials_and_mutual_occlusion",
    "test_counts_change_and_removal",
    "test_diffuse_hook_sees_fluid_depth",
    "test_diffuse_sprites",
    "test_render_does_not_change_simulation",
    "test_resize_keeps_working",
}
_ALL_DEVICES = {"test_compute_passes_match_raster"}

for _name, _func in list(globals().items()):
    if _name.startswith("test_") and callable(_func):
        _devices = get_test_devices() if _name in _ALL_DEVICES else [wp.get_device("cpu")]
        add_function_test(TestFluidRenderGL, _name, _func, devices=_devices)
        if _name in _BOTH_MODES:
            add_function_test(TestFluidRenderGL, f"{_name}_compute", _in_mode(_func, "compute"), devices=_devices)
del _name, _func, _devices

if __name__ == "__main__":
    unittest.main(verbosity=2)
