# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""``ModelBuilder.add_fluid_fill``: fluid on the rest lattice inside a mesh, or inside a container up to a level."""

import math
import unittest

import numpy as np
import warp as wp

import newton
from newton.examples.fluid.common import revolved_container

FLUID = int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID)

# a unit cube's corners and its 12 outward-wound triangles, the two of the top face (z = +0.5) last
CUBE_VERTICES = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
CUBE_FACES = np.array(
    [
        [0, 2, 3], [0, 3, 1],  # x = -0.5
        [4, 5, 7], [4, 7, 6],  # x = +0.5
        [0, 1, 5], [0, 5, 4],  # y = -0.5
        [2, 6, 7], [2, 7, 3],  # y = +0.5
        [0, 4, 6], [0, 6, 2],  # z = -0.5
        [1, 3, 7], [1, 7, 5],  # z = +0.5
    ]
)  # fmt: skip


def cube(open_top=False):
    faces = CUBE_FACES[:-2] if open_top else CUBE_FACES
    return newton.Mesh(CUBE_VERTICES, faces.ravel(), compute_inertia=False)


class TestFluidFill(unittest.TestCase):
    def test_closed_mesh_is_filled_on_the_lattice(self):
        builder = newton.ModelBuilder()
        n = builder.add_fluid_fill(cube(), 0.1)
        # centred lattice, centres at least half a spacing inside: 0, +-0.1, ..., +-0.4 on each axis
        self.assertEqual(n, 9**3)
        q = np.array(builder.particle_q)
        np.testing.assert_allclose(np.sort(np.unique(q[:, 0].round(6))), np.linspace(-0.4, 0.4, 9), atol=1e-6)
        np.testing.assert_allclose(builder.particle_mass, 1000.0 * 0.1**3)
        np.testing.assert_allclose(builder.particle_radius, 0.05)
        self.assertEqual(set(builder.particle_flags), {FLUID})

    def test_container_is_filled_to_the_level(self):
        radius, wall, spacing, level = 0.05, 0.008, 0.005, 0.068
        inner = np.stack([np.full(8, radius), np.linspace(wall, wall + 0.12, 8)], axis=1)
        cup = revolved_container(inner, wall, segments=64)
        turn = wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), 0.4)
        placement = wp.transform(wp.vec3(1.0, 2.0, 3.0), turn)
        builder = newton.ModelBuilder()
        n = builder.add_fluid_fill(cup, spacing, xform=placement, fill_height=level)
        q = np.array(builder.particle_q, dtype=np.float64)
        rotation = np.array(wp.quat_to_matrix(turn)).reshape(3, 3)
        local = (q - [1.0, 2.0, 3.0]) @ rotation
        # in the cavity: half a spacing from the wall (the polygon's flats lie inside the circle), from the
        # floor, and the top layer half a spacing below the level
        r = np.hypot(local[:, 0], local[:, 1])
        flat = radius * math.cos(math.pi / 64)
        self.assertLessEqual(r.max(), flat - 0.5 * spacing + 1e-6)
        layers = np.unique(local[:, 2].round(6))
        np.testing.assert_allclose(layers, np.arange(wall + 0.5 * spacing, level, spacing), atol=1e-6)
        # every lattice point of the disc in every layer: the count a cylinder of the cavity's radius holds
        axis = spacing * np.arange(-10, 11)
        disc = np.count_nonzero(np.hypot(*np.meshgrid(axis, axis)) <= flat - 0.5 * spacing)
        self.assertEqual(n, disc * len(layers))
        self.assertAlmostEqual(n * spacing**3 / (math.pi * radius**2 * (level - wall)), 0.9, delta=0.06)

    def test_open_surface_container(self):
        builder = newton.ModelBuilder()
        n = builder.add_fluid_fill(cube(open_top=True), 0.1, fill_height=0.2)
        q = np.array(builder.particle_q)
        # the bottom layer half a spacing above the floor, the top half a spacing below the level
        np.testing.assert_allclose(np.unique(q[:, 2].round(6)), [-0.45 + 0.1 * k for k in range(7)], atol=1e-6)
        self.assertEqual(n, 9 * 9 * 7)

    def test_each_world_gets_its_fill(self):
        world = newton.ModelBuilder()
        per_world = world.add_fluid_fill(cube(), 0.25)
        builder = newton.ModelBuilder()
        builder.replicate(world, 3)
        model = builder.finalize(device="cpu")
        np.testing.assert_array_equal(np.bincount(model.particle_world.numpy()), [per_world] * 3)

    def test_bad_fills_raise(self):
        builder = newton.ModelBuilder()
        with self.assertRaisesRegex(ValueError, r"mesh is not closed .* give fill_height"):
            builder.add_fluid_fill(cube(open_top=True), 0.1)
        with self.assertRaisesRegex(ValueError, r"fill_height=0.7 .* produced no particle"):
            builder.add_fluid_fill(cube(open_top=True), 0.1, fill_height=0.7)  # above the rim: it runs over
        with self.assertRaisesRegex(ValueError, r"fill_height=-1 is invalid: the mesh lies above it"):
            builder.add_fluid_fill(cube(open_top=True), 0.1, fill_height=-1.0)
        with self.assertRaisesRegex(ValueError, r"spacing=0.0 is invalid: expected a lattice spacing in \(0, inf\)"):
            builder.add_fluid_fill(cube(), 0.0)
        with self.assertRaisesRegex(ValueError, r"density=-1.0 is invalid"):
            builder.add_fluid_fill(cube(), 0.1, density=-1.0)
        with self.assertRaisesRegex(ValueError, r"spacing=2 produced no particle"):
            builder.add_fluid_fill(cube(), 2.0)
        self.assertEqual(builder.particle_count, 0)


if __name__ == "__main__":
    unittest.main(verbosity=2)
