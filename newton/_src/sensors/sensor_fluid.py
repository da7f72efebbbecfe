# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Fluid sensor: per-world fluid counts inside regions, centroid, mean velocity and spill, on the device.

A training loop over many worlds asks of each world's water what a task needs (how much is still
in the cup, how much reached the target, where it is, how fast it moves, how much is lost) without
reading particles back. :class:`SensorFluid` answers in fixed-size device arrays, from one launch
over the fluid particles of every world and one over the worlds and regions, with no allocation or
host synchronisation, so it can sit in a captured graph beside the step.

Regions are shapes of the model (usually sites, :meth:`~newton.ModelBuilder.add_site`) of type box,
sphere or cylinder, on a body (they move with it) or static. A region counts the fluid of its own
world (a region of the global world -1 counts every world's fluid).
"""

from __future__ import annotations

import re

import numpy as np
import warp as wp

from ..geometry import GeoType, ParticleFlags
from ..sim.model import Model
from ..sim.state import State
from ..utils.selection import match_labels

_REGION_TYPES = {int(GeoType.BOX): "box", int(GeoType.SPHERE): "sphere", int(GeoType.CYLINDER): "cylinder"}


@wp.func
def inside_region(x: wp.vec3, frame: wp.transform, geo_type: int, scale: wp.vec3):
    """Whether the world point ``x`` lies in a box (half extents ``scale``), sphere (radius ``scale[0]``)
    or z-axis cylinder (radius ``scale[0]``, half height ``scale[1]``) placed at ``frame``."""
    p = wp.transform_point(wp.transform_inverse(frame), x)
    if geo_type == int(GeoType.BOX):
        return wp.abs(p[0]) <= scale[0] and wp.abs(p[1]) <= scale[1] and wp.abs(p[2]) <= scale[2]
    if geo_type == int(GeoType.SPHERE):
        return wp.dot(p, p) <= scale[0] * scale[0]
    return p[0] * p[0] + p[1] * p[1] <= scale[0] * scale[0] and wp.abs(p[2]) <= scale[1]


@wp.func
def region_frame(
    shape: int, shape_body: wp.array[wp.int32], shape_transform: wp.array[wp.transform], body_q: wp.array[wp.transform]
):
    body = shape_body[shape]
    if body >= 0:
        return wp.transform_multiply(body_q[body], shape_transform[shape])
    return shape_transform[shape]


@wp.kernel
def accumulate_fluid_regions(
    fluid_particle: wp.array[wp.int32],
    particle_world: wp.array[wp.int32],
    particle_flags: wp.array[wp.int32],
    particle_q: wp.array[wp.vec3],
    particle_qd: wp.array[wp.vec3],
    world_count: int,
    region_start: wp.array[wp.int32],
    region_shape: wp.array[wp.int32],
    shape_type: wp.array[wp.int32],
    shape_scale: wp.array[wp.vec3],
    shape_body: wp.array[wp.int32],
    shape_transform: wp.array[wp.transform],
    body_q: wp.array[wp.transform],
    # outputs (zeroed before): counts, and the sums that finish_fluid_regions turns into means
    fluid_count: wp.array[wp.int32],
    position_sum: wp.array[wp.vec3],
    velocity_sum: wp.array[wp.vec3],
    spilled_count: wp.array[wp.int32],
    region_count: wp.array[wp.int32],
):
    k = wp.tid()
    pi = fluid_particle[k]
    if (particle_flags[pi] & int(ParticleFlags.ACTIVE)) == 0:
        return
    x, v = particle_q[pi], particle_qd[pi]
    if not (wp.isfinite(x) and wp.isfinite(v)):
        return
    w = particle_world[pi]
    # the global world -1 is the last row
    row = world_count
    if w >= 0 and w < world_count:
        row = w
    inside = int(0)
    # the regions of the particle's world, then the global ones (which see every world)
    for bucket in range(2):
        b = row
        if bucket == 1:
            b = world_count
        if bucket == 0 or row != world_count:
            for r in range(region_start[b], region_start[b + 1]):
                s = region_shape[r]
                frame = region_frame(s, shape_body, shape_transform, body_q)
                if inside_region(x, frame, shape_type[s], shape_scale[s]):
                    wp.atomic_add(region_count, r, 1)
                    inside = 1
    wp.atomic_add(fluid_count, row, 1)
    wp.atomic_add(position_sum, row, x)
    wp.atomic_add(velocity_sum, row, v)
    if inside == 0:
        wp.atomic_add(spilled_count, row, 1)


@wp.kernel
def finish_fluid_regions(
    world_count: int,
    region_row: wp.array[wp.int32],
    fluid_count: wp.array[wp.int32],
    region_count: wp.array[wp.int32],
    # in: sums, out: means (in place)
    centroid: wp.array[wp.vec3],
    mean_velocity: wp.array[wp.vec3],
    # outputs
    region_fraction: wp.array[float],
):
    i = wp.tid()
    if i < region_count.shape[0]:
        # a world's region's share is of its world's fluid; a global region's, of all fluid
        row = region_row[i]
        total = int(0)
        if row == world_count:
            for w in range(world_count + 1):
                total += fluid_count[w]
        else:
            total = fluid_count[row]
        region_fraction[i] = float(region_count[i]) / float(wp.max(total, 1))
    if i <= world_count:
        inv = 1.0 / float(wp.max(fluid_count[i], 1))
        centroid[i] = centroid[i] * inv
        mean_velocity[i] = mean_velocity[i] * inv


class SensorFluid:
    """Per-world measurements of the fluid, on the device.

    For every world (plus a last row for the global world -1): the count of active fluid particles,
    their centroid and mean velocity, and how many lie in none of the regions their world sees
    (spilled); for every region: the count of fluid particles inside it and their share of the
    fluid it sees. Regions are shapes of type box, sphere or cylinder (usually sites added with
    :meth:`~newton.ModelBuilder.add_site`, ``type`` and ``scale`` setting the volume: box half
    extents; sphere radius; cylinder radius and half height along the local z axis), on a body or
    static; a region counts the fluid of its own world, and a region of the global world -1 the
    fluid of every world. Particles that are inactive or non-finite are not counted.

    :meth:`update` is five memsets and two kernel launches for all worlds, with no
    allocation or host synchronisation: it can be captured in a CUDA graph. The counts are exact;
    centroids and velocities are float sums whose order (and so last bits) may vary on CUDA.

    Example:

        .. code-block:: python

            world = newton.ModelBuilder()
            cup = world.add_body(...)
            # the cup's inside, in the cup's frame: 4 cm radius, 5 cm above its base
            world.add_site(cup, xform=wp.transform((0, 0, 0.05), wp.quat_identity()),
                           type=newton.GeoType.CYLINDER, scale=(0.04, 0.05, 0.0), label="cup_inside")
            ...
            builder.replicate(world, 1024)
            model = builder.finalize()
            sensor = newton.sensors.SensorFluid(model, regions="*cup_inside")
            sensor.update(state)  # after each step; inside a captured graph too
            kept = sensor.region_fraction  # (1024,): the share of each world's water in its cup
    """

    fluid_count: wp.array[wp.int32]
    """Active, finite fluid particles per world, shape ``(world_count + 1,)`` (last: world -1)."""
    centroid: wp.array[wp.vec3]
    """Mean fluid particle position per world [m], shape ``(world_count + 1,)``; 0 for a world without fluid."""
    mean_velocity: wp.array[wp.vec3]
    """Mean fluid particle velocity per world [m/s], shape ``(world_count + 1,)``."""
    spilled_count: wp.array[wp.int32]
    """Fluid particles per world in none of the regions the world sees, shape ``(world_count + 1,)``."""
    region_count: wp.array[wp.int32]
    """Fluid particles inside each region, shape ``(region_count,)``, in the order of :attr:`region_shapes`."""
    region_fraction: wp.array[float]
    """:attr:`region_count` over the fluid the region sees (its world's, or all for a global region)."""
    region_shapes: list[int]
    """Shape index of each region, ordered by world (the global world's last), then by shape index."""
    region_world: wp.array[wp.int32]
    """World of each region (-1: global), shape ``(region_count,)``."""

    def __init__(self, model: Model, regions: str | list[str] | re.Pattern[str] | list[int] | None = None):
        """Create the sensor and its output arrays on the model's device.

        Args:
            model: The model; its particles flagged :attr:`~newton.ParticleFlags.FLUID` are measured.
            regions: Shapes to count fluid in: a glob pattern or list of patterns matched against the
                shape labels, a compiled regular expression (full match), or shape indices; each of type
                box, sphere or cylinder. ``None``: no regions (every particle counts as spilled).
        """
        self.model = model
        flags = model.particle_flags.numpy() if model.particle_count else np.zeros(0, dtype=np.int32)
        fluid = np.flatnonzero((flags & int(ParticleFlags.FLUID)) != 0).astype(np.int32)
        if len(fluid) == 0:
            raise ValueError("SensorFluid needs a model with fluid particles (ParticleFlags.FLUID), found none")
        shapes = [] if regions is None else list(match_labels(model.shape_label, regions))
        if regions is not None and not shapes:
            raise ValueError(f"regions={regions!r} matches no shape label; expected shape labels or indices")
        types = model.shape_type.numpy() if model.shape_count else np.zeros(0, dtype=np.int32)
        shape_world = model.shape_world.numpy() if model.shape_count else np.zeros(0, dtype=np.int32)
        for s in shapes:
            if not 0 <= s < model.shape_count:
                raise ValueError(f"regions has shape index {s}, expected an index in [0, {model.shape_count})")
            if int(types[s]) not in _REGION_TYPES:
                raise ValueError(
                    f"regions has shape {s} ({model.shape_label[s]!r}) of type {GeoType(int(types[s])).name}, "
                    f"expected one of {', '.join(sorted(_REGION_TYPES.values()))}"
                )
        world_count = int(model.world_count)
        rows = world_count + 1
        # regions bucketed by world, the global world -1 last
        row_of = {s: (int(shape_world[s]) if 0 <= shape_world[s] < world_count else world_count) for s in shapes}
        ordered = sorted(shapes, key=lambda s: (row_of[s], s))
        start = np.zeros(rows + 1, dtype=np.int32)
        for s in ordered:
            start[row_of[s] + 1] += 1
        start = np.cumsum(start).astype(np.int32)
        self.region_shapes = ordered
        device = model.device
        with wp.ScopedDevice(device):
            self._fluid_particle = wp.array(fluid, dtype=wp.int32)
            self._region_start = wp.array(start, dtype=wp.int32)
            self._region_shape = wp.array(np.array(ordered, dtype=np.int32), dtype=wp.int32)
            self._region_row = wp.array(np.array([row_of[s] for s in ordered], dtype=np.int32), dtype=wp.int32)
            self.region_world = wp.array(
                np.array([row_of[s] if row_of[s] < world_count else -1 for s in ordered], dtype=np.int32),
                dtype=wp.int32,
            )
            self.fluid_count = wp.zeros(rows, dtype=wp.int32)
            self.centroid = wp.zeros(rows, dtype=wp.vec3)
            self.mean_velocity = wp.zeros(rows, dtype=wp.vec3)
            self.spilled_count = wp.zeros(rows, dtype=wp.int32)
            self.region_count = wp.zeros(len(ordered), dtype=wp.int32)
            self.region_fraction = wp.zeros(len(ordered), dtype=float)
            self._no_bodies = wp.zeros(1, dtype=wp.transform)

    def update(self, state: State) -> None:
        """Measure the fluid at ``state`` into the output arrays (device work only).

        Args:
            state: The state to measure; its ``body_q`` places the regions on bodies.
        """
        m = self.model
        for out in (self.fluid_count, self.centroid, self.mean_velocity, self.spilled_count, self.region_count):
            out.zero_()
        body_q = state.body_q if state.body_q is not None else self._no_bodies
        wp.launch(
            accumulate_fluid_regions,
            dim=len(self._fluid_particle),
            inputs=[
                self._fluid_particle,
                m.particle_world,
                m.particle_flags,
                state.particle_q,
                state.particle_qd,
                int(m.world_count),
                self._region_start,
                self._region_shape,
                m.shape_type,
                m.shape_scale,
                m.shape_body,
                m.shape_transform,
                body_q,
            ],
            outputs=[self.fluid_count, self.centroid, self.mean_velocity, self.spilled_count, self.region_count],
            device=m.device,
        )
        wp.launch(
            finish_fluid_regions,
            dim=max(int(m.world_count) + 1, len(self.region_shapes)),
            inputs=[int(m.world_count), self._region_row, self.fluid_count, self.region_count],
            outputs=[self.centroid, self.mean_velocity, self.region_fraction],
            device=m.device,
        )


def activate(sensors_module) -> None:
    """Add :class:`SensorFluid` to ``newton.sensors``; idempotent."""
    sensors_module.SensorFluid = SensorFluid
    if "SensorFluid" not in sensors_module.__all__:
        sensors_module.__all__.append("SensorFluid")
