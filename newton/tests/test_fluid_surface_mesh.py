# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""``log_fluid`` in the USD, Rerun and Viser viewers: the fluid as an extracted surface mesh."""

import os
import tempfile
import unittest

import newton.viewer
import numpy as np
import warp as wp
from newton.tests.unittest_utils import add_function_test, get_test_devices

import newton
from newton.examples.fluid.common import WATER, add_tank
from newton.tests.test_fluid_extension import _free_port
from newton.tests.test_solver_xpbd_fluid import add_block

SPACING = 0.05  # [m]
POOL = (8, 8, 5)  # particles


def settled_pool(device):
    """A pool of ``POOL`` particles settled for 1 s in a tank that fits it, its solver and state."""
    d = SPACING
    builder = newton.ModelBuilder()
    add_block(builder, POOL, (0.5 * d, 0.5 * d, 0.5 * d), spacing=d, mass=1000.0 * d**3, radius=0.5 * d)
    builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.0))
    half = 0.5 * POOL[0] * d
    add_tank(builder, half, half, 0.5, 0.05, center=(half, half))
    model = builder.finalize(device=device)
    model.soft_contact_mu = 0.0
    solver = newton.solvers.SolverXPBD(model, iterations=2, fluid_rest_distance=d, fluid_viscosity=0.1)
    pipeline = newton.CollisionPipeline(model, soft_contact_max=model.particle_count, soft_contact_gap=0.5 * d)
    contacts = pipeline.contacts()
    state_0, state_1 = model.state(), model.state()
    substeps = 4
    for _ in range(60 * substeps):
        pipeline.collide(state_0, contacts)
        solver.step(state_0, state_1, None, contacts, 1.0 / 60.0 / substeps)
        state_0, state_1 = state_1, state_0
    return model, solver, state_0


def mesh_volume(points: np.ndarray, faces: np.ndarray) -> float:
    """Enclosed volume [m^3] of a closed, outward-wound triangle mesh (divergence theorem)."""
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def open_edges(faces: np.ndarray) -> int:
    """Edges not shared by exactly two triangles (0 for a closed surface)."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, count = np.unique(edges, axis=0, return_counts=True)
    return int(np.count_nonzero(count != 2))


def test_usd_writes_a_closed_surface_of_the_pool_volume(test, device):
    from pxr import Usd, UsdGeom, UsdShade  # noqa: PLC0415

    model, solver, state = settled_pool(device)
    frames = 3
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "pool.usda")
        viewer = newton.viewer.ViewerUSD(path, num_frames=frames)
        viewer.set_model(model)
        for frame in range(frames):
            solver.update_render_particles(state)
            viewer.begin_frame(frame / 60.0)
            viewer.log_state(state)
            viewer.log_fluid(
                "/water",
                solver.render_positions,
                radii=model.particle_radius,
                anisotropy=solver.render_anisotropy,
                anisotropy_secondary=solver.render_anisotropy_secondary,
                anisotropy_tertiary=solver.render_anisotropy_tertiary,
                ior=1.333,
                **WATER,
            )
            viewer.end_frame()
        viewer.close()

        stage = Usd.Stage.Open(path)
        prims = [p for p in stage.Traverse() if p.GetName() == "water"]
        test.assertEqual(len(prims), 1, [str(p.GetPath()) for p in stage.Traverse()])
        test.assertTrue(prims[0].IsA(UsdGeom.Mesh))
        mesh = UsdGeom.Mesh(prims[0])
        test.assertEqual(mesh.GetPointsAttr().GetTimeSamples(), [float(k) for k in range(frames)])
        points = np.asarray(mesh.GetPointsAttr().Get(frames - 1), dtype=np.float64)
        faces = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(frames - 1)).reshape(-1, 3)
        test.assertTrue(set(np.asarray(mesh.GetFaceVertexCountsAttr().Get(frames - 1))) == {3})
        test.assertEqual(open_edges(faces), 0)
        rest_volume = model.particle_count * SPACING**3
        test.assertLess(abs(mesh_volume(points, faces) / rest_volume - 1.0), 0.10)

        material, _ = UsdShade.MaterialBindingAPI(prims[0]).ComputeBoundMaterial()
        test.assertTrue(material)
        shader = material.ComputeSurfaceSource()[0]
        test.assertEqual(shader.GetIdAttr().Get(), "UsdPreviewSurface")
        test.assertAlmostEqual(shader.GetInput("ior").Get(), 1.333, places=5)
        np.testing.assert_allclose(shader.GetInput("diffuseColor").Get(), WATER["color"][:3], rtol=1.0e-6)
        np.testing.assert_allclose(shader.GetInput("absorption").Get(), WATER["absorption"], rtol=1.0e-6)
        test.assertGreater(shader.GetInput("opacity").Get(), 0.0)
        test.assertLess(shader.GetInput("opacity").Get(), 1.0)


def test_surface_off_draws_points(test, device):
    from pxr import Usd, UsdGeom  # noqa: PLC0415

    positions = wp.array(np.random.default_rng(1).random((50, 3)) * 0.2, dtype=wp.vec3, device=device)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "points.usda")
        viewer = newton.viewer.ViewerUSD(path, num_frames=2)
        viewer.begin_frame(0.0)
        viewer.log_fluid("/water", positions, radii=0.03)
        viewer.end_frame()
        viewer.fluid_surface = False
        viewer.begin_frame(1.0 / 60.0)
        viewer.log_fluid("/water", positions, radii=0.03, color=(0.9, 0.3, 0.1))
        viewer.end_frame()
        viewer.close()
        stage = Usd.Stage.Open(path)
        mesh = UsdGeom.Mesh(next(p for p in stage.Traverse() if p.GetName() == "water"))
        test.assertEqual(mesh.GetVisibilityAttr().Get(0), UsdGeom.Tokens.inherited)
        test.assertEqual(mesh.GetVisibilityAttr().Get(1), UsdGeom.Tokens.invisible)
        points = [p for p in stage.Traverse() if p.GetName() == "water_points"]
        test.assertEqual(len(points), 1)
        colors = UsdGeom.Gprim(points[0]).GetDisplayColorAttr().Get(Usd.TimeCode(1))
        np.testing.assert_allclose(np.asarray(colors)[0], (0.9, 0.3, 0.1), atol=1.0e-6)


def test_mesh_viewers_log_the_surface(test, device):
    """Rerun and Viser get the surface through their own log_mesh, as a closed dynamic mesh."""
    model, solver, state = settled_pool(device)
    viewers = {
        "rerun": lambda: newton.viewer.ViewerRerun(web_port=_free_port(), grpc_port=_free_port()),
        "viser": lambda: newton.viewer.ViewerViser(host="127.0.0.1", port=_free_port(), verbose=False),
    }
    for kind, make in viewers.items():
        with test.subTest(viewer=kind):
            viewer = make()
            calls = []
            upstream_log_mesh = viewer.log_mesh

            def log_mesh(name, points, indices, normals=None, _log=upstream_log_mesh, _calls=calls, **kwargs):
                _calls.append((name, points.numpy(), indices.numpy(), kwargs))
                _log(name, points, indices, normals, **kwargs)

            viewer.log_mesh = log_mesh
            solver.update_render_particles(state)
            viewer.begin_frame(0.0)
            viewer.log_fluid("/water", solver.render_positions, radii=model.particle_radius, **WATER)
            viewer.end_frame()
            viewer.close()
            name, points, indices, kwargs = calls[-1]
            test.assertEqual(name, "/water")
            test.assertTrue(kwargs["dynamic"])
            faces = indices.reshape(-1, 3)
            test.assertEqual(open_edges(faces), 0)
            volume = mesh_volume(points.astype(np.float64), faces)
            test.assertLess(abs(volume / (model.particle_count * SPACING**3) - 1.0), 0.10)
            np.testing.assert_allclose(kwargs["color"], WATER["color"][:3])
            test.assertTrue(0.0 < kwargs["opacity"] < 1.0)


class TestFluidSurfaceMesh(unittest.TestCase):
    pass


devices = get_test_devices()
# the web viewers' test runs their servers once (on the CPU), and they print their addresses
add_function_test(
    TestFluidSurfaceMesh,
    "test_mesh_viewers_log_the_surface",
    test_mesh_viewers_log_the_surface,
    devices=[wp.get_device("cpu")],
    check_output=False,
)
for _func in (test_usd_writes_a_closed_surface_of_the_pool_volume, test_surface_off_draws_points):
    add_function_test(TestFluidSurfaceMesh, _func.__name__, _func, devices=devices)

if __name__ == "__main__":
    unittest.main(verbosity=2)
