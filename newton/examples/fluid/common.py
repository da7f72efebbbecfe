# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""What the fluid examples share: a tank of four walls, the frame loop, and drawing the water."""

from __future__ import annotations

import numpy as np
import warp as wp

import newton
import newton.examples
from newton.examples.fluid.capture import add_capture_arguments

WATER = {"color": (0.2, 0.45, 0.9, 0.3), "absorption": (4.0, 1.2, 0.5)}


def add_closed_box(
    builder: newton.ModelBuilder, edge: float, height: float, thickness: float = 0.1, width: float | None = None
) -> None:
    """Six frictionless walls closing ``[0, edge] x [0, width] x [0, height]`` [m] (floor and lid included).

    ``width`` defaults to ``edge`` (a square floor). Each wall reaches over the ones it meets to their
    outer faces, so no joint opens between them (see :func:`add_tank`). The still-water column of
    ``benchmarks/rest_column.py`` and the tank of ``benchmarks/sloshing.py`` stand in it.
    """
    width = edge if width is None else width
    t, hx, hy, mid = thickness, 0.5 * edge, 0.5 * width, 0.5 * height
    cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
    for center, extent in (
        ((hx, hy, -t), (hx + 2 * t, hy + 2 * t, t)),
        ((hx, hy, height + t), (hx + 2 * t, hy + 2 * t, t)),
        ((-t, hy, mid), (t, hy + 2 * t, mid + 2 * t)),
        ((edge + t, hy, mid), (t, hy + 2 * t, mid + 2 * t)),
        ((hx, -t, mid), (hx + 2 * t, t, mid + 2 * t)),
        ((hx, width + t, mid), (hx + 2 * t, t, mid + 2 * t)),
    ):
        xform = wp.transform(wp.vec3(*center), wp.quat_identity())
        builder.add_shape_box(-1, xform=xform, hx=extent[0], hy=extent[1], hz=extent[2], cfg=cfg)


def add_water_lattice(
    builder: newton.ModelBuilder, spacing: float, counts: tuple[int, int, int], jitter: float = 0.0
) -> None:
    """Fluid particles on the rest lattice filling ``[0, nx d] x [0, ny d] x [0, nz d]`` from the origin.

    Spacing ``d`` [m], mass ``1000 d^3`` [kg] (water), radius ``d / 2``; ``jitter`` [m] is the width of
    upstream's uniform random offset per coordinate (0: none).
    """
    d = spacing
    builder.add_particle_grid(
        pos=wp.vec3(0.5 * d, 0.5 * d, 0.5 * d),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0),
        dim_x=counts[0],
        dim_y=counts[1],
        dim_z=counts[2],
        cell_x=d,
        cell_y=d,
        cell_z=d,
        mass=1000.0 * d**3,
        jitter=jitter,
        radius_mean=0.5 * d,
        flags=int(newton.ParticleFlags.ACTIVE | newton.ParticleFlags.FLUID),
    )


def add_tank(
    builder: newton.ModelBuilder,
    half_x: float,
    half_y: float,
    height: float,
    thickness: float,
    center: tuple[float, float] = (0.0, 0.0),
) -> None:
    """Four frictionless walls around ``|x - cx| <= half_x``, ``|y - cy| <= half_y`` [m] (``center = (cx, cy)``).

    The front (-y) wall collides but is not drawn, like the glass of a real tank, so a camera in
    front sees in. The walls that collide reach through the two they meet to their outer faces and
    ``2 thickness`` below z = 0 (into a ground plane there): a particle pressed into a wall takes the
    nearest face of every box it is in, and an end or bottom face flush with the next wall's inner
    face or with the floor would push it out through the joint. What is drawn are boxes that meet
    without overlapping (overlapping boxes of the same height would show their shared top face).
    """
    t = thickness
    walls = (
        ((-half_x - t, 0.0), (t, half_y + 2.0 * t), t),
        ((half_x + t, 0.0), (t, half_y + 2.0 * t), t),
        ((0.0, -half_y - t), (half_x, t), half_x + 2.0 * t),
        ((0.0, half_y + t), (half_x, t), half_x + 2.0 * t),
    )
    collide = newton.ModelBuilder.ShapeConfig(mu=0.0, is_visible=False)
    draw = newton.ModelBuilder.ShapeConfig(has_shape_collision=False, has_particle_collision=False)

    def add(k, drawn):
        (x, y), (hx, hy), collide_hx = walls[k]
        x, y = center[0] + x, center[1] + y
        if drawn:
            xform = wp.transform(wp.vec3(x, y, 0.5 * height), wp.quat_identity())
            builder.add_shape_box(-1, xform=xform, hx=hx, hy=hy, hz=0.5 * height, cfg=draw)
        else:
            xform = wp.transform(wp.vec3(x, y, 0.5 * height - t), wp.quat_identity())
            builder.add_shape_box(-1, xform=xform, hx=collide_hx, hy=hy, hz=0.5 * height + t, cfg=collide)

    # the drawn walls first, in the order (and so the viewer's colours) of the single boxes before them
    for k in range(4):
        add(k, drawn=k != 2)
    for k in (0, 1, 3):
        add(k, drawn=False)


def add_closed_tank(builder: newton.ModelBuilder, edge: float, thickness: float) -> None:
    """Six frictionless walls, lid included, ``thickness`` [m] thick around the cube ``[0, edge]^3`` [m]."""
    cfg = newton.ModelBuilder.ShapeConfig(mu=0.0)
    t = 0.5 * thickness
    c, hw = 0.5 * edge, 0.5 * edge + thickness
    for center, half in (
        ((c, c, -t), (hw, hw, t)),
        ((c, c, edge + t), (hw, hw, t)),
        ((-t, c, c), (t, hw, hw)),
        ((edge + t, c, c), (t, hw, hw)),
        ((c, -t, c), (hw, t, hw)),
        ((c, edge + t, c), (hw, t, hw)),
    ):
        xform = wp.transform(wp.vec3(*center), wp.quat_identity())
        builder.add_shape_box(-1, xform=xform, hx=half[0], hy=half[1], hz=half[2], cfg=cfg)


class FluidExample:
    """Frame loop of a fluid example: ``sim_substeps`` collision + XPBD substeps per frame at ``fps``.

    A subclass builds ``self.model``, ``self.solver`` and ``self.spacing`` and then calls
    :meth:`setup_simulation`; on CUDA the whole frame is one captured graph.
    """

    fps = 60
    sim_substeps = 8
    #: substeps between two runs of the collision pipeline (``--collide-every``)
    collide_every = 1
    #: default of ``--particle-count`` on a GPU
    default_particle_count = 100_000
    #: default of ``--particle-count`` on a CPU (a few frames per second on two cores)
    cpu_particle_count = 5_000
    #: what ``--particle-count`` counts
    particle_count_help = "Approximate fluid particle count"

    def __init__(self, viewer, args=None):
        self.viewer = viewer
        k = getattr(args, "collide_every", 1) or 1
        if not 1 <= k <= self.sim_substeps:
            raise ValueError(
                f"collide_every={k!r} is invalid: expected substeps between collisions in [1, {self.sim_substeps}]"
            )
        self.collide_every = k
        self.frame_dt = 1.0 / self.fps
        self.sim_dt = self.frame_dt / self.sim_substeps
        self.sim_time = 0.0

    def setup_simulation(self) -> None:
        self.state_0 = self.model.state()
        self.state_1 = self.model.state()
        # contacts reach one diameter from a surface, so particles near walls see the walls' density; found
        # every collide_every substeps, they reach as far again as a particle may travel in the others.
        # Room for two per particle (in a corner a particle touches up to three walls) and per collision
        # interval: a full buffer drops contacts, and with them walls
        travel = min(self.model.particle_max_velocity * self.sim_dt, self.spacing)
        self.collision = newton.CollisionPipeline(
            self.model,
            soft_contact_max=2 * self.model.particle_count * self.collide_every,
            soft_contact_gap=0.5 * self.spacing + (self.collide_every - 1) * travel,
        )
        self.contacts = self.collision.contacts()
        self.viewer.set_model(self.model)
        self.capture()

    def capture(self):
        self.graph = None
        if wp.get_device().is_cuda:
            with wp.ScopedCapture() as capture:
                self.simulate()
            self.graph = capture.graph

    def prescribe(self, state: newton.State) -> None:
        """Set scripted (kinematic) body poses in ``state`` before a substep; nothing by default."""

    def simulate(self):
        for substep in range(self.sim_substeps):
            self.state_0.clear_forces()
            self.prescribe(self.state_0)
            # mouse picking and wind of the GL viewer
            self.viewer.apply_forces(self.state_0)
            if substep % self.collide_every == 0:
                self.collision.collide(self.state_0, self.contacts)
            self.solver.step(self.state_0, self.state_1, None, self.contacts, self.sim_dt)
            self.state_0, self.state_1 = self.state_1, self.state_0

    def step(self):
        if self.graph:
            wp.capture_launch(self.graph)
        else:
            self.simulate()
        self.sim_time += self.frame_dt

    @classmethod
    def create_parser(cls):
        """Newton's example arguments, the capture arguments and ``--particle-count``.

        ``--particle-count`` defaults to ``None``: the entry point chooses ``default_particle_count`` on a GPU
        and ``cpu_particle_count`` on a CPU (:func:`~newton.examples.fluid.capture.choose_particle_count`).
        """
        parser = newton.examples.create_parser()
        add_capture_arguments(parser)
        parser.add_argument(
            "--particle-count",
            type=int,
            default=None,
            help=f"{cls.particle_count_help}; default {cls.default_particle_count:,} on a GPU, "
            f"{cls.cpu_particle_count:,} on a CPU.",
        )
        parser.add_argument(
            "--collide-every",
            type=int,
            default=1,
            metavar="K",
            help="Find particle-shape contacts every K substeps (reaching as far as particles travel in between); "
            "1: every substep.",
        )
        return parser

    def viscosity_gui(self, ui) -> None:
        """A viscosity slider (assign to ``gui``); device parameters, so a captured graph picks up new values."""
        changed, value = ui.slider_float("viscosity", self.solver.fluid_viscosity, 0.0, 1.0)
        if changed:
            self.solver.fluid_viscosity = value

    def render(self):
        self.solver.update_render_particles(self.state_0)
        self.viewer.begin_frame(self.sim_time)
        self.viewer.log_state(self.state_0)
        self.log_fluids()
        self.viewer.end_frame()

    def log_fluids(self) -> None:
        """Draw this frame's fluid batches (by default, the water from the render particles)."""
        self.log_water()

    def log_water(
        self, name: str = "/water", positions: wp.array | None = None, particles: slice | None = None, **material
    ) -> None:
        """Draw the fluid from the solver's render particles (after ``update_render_particles``;
        ``positions`` replaces their centres, ``particles`` selects a contiguous range of particles)."""
        s = self.solver
        arrays = [
            s.render_positions if positions is None else positions,
            self.model.particle_radius,
            s.render_anisotropy,
            s.render_anisotropy_secondary,
            s.render_anisotropy_tertiary,
        ]
        if particles is not None:
            arrays = [a[particles] for a in arrays]
        self.viewer.log_fluid(
            name,
            arrays[0],
            radii=arrays[1],
            radius_scale=1.3,
            anisotropy=arrays[2],
            anisotropy_secondary=arrays[3],
            anisotropy_tertiary=arrays[4],
            **{**WATER, **material},
        )

    def log_water_by_world(self) -> None:
        """Draw the water of worlds that share one place side by side, at ``viewer.world_offsets``."""
        if getattr(self, "_shown", None) is None:
            self._shown = wp.empty(self.model.particle_count, dtype=wp.vec3, device=self.model.device)
        wp.launch(
            offset_by_world,
            dim=self.model.particle_count,
            inputs=[self.solver.render_positions, self.model.particle_world, self.viewer.world_offsets],
            outputs=[self._shown],
            device=self.model.device,
        )
        self.log_water(positions=self._shown)

    def log_foam(self, radius: float, **material) -> None:
        """Draw the solver's diffuse particles."""
        s = self.solver
        self.viewer.log_fluid_diffuse(
            "/foam",
            s.diffuse_positions,
            s.diffuse_velocities,
            s.diffuse_lifetimes,
            s.diffuse_kinds,
            radius=radius,
            **material,
        )


@wp.kernel
def offset_by_world(
    positions: wp.array[wp.vec3],
    particle_world: wp.array[wp.int32],
    world_offsets: wp.array[wp.vec3],
    # outputs
    shown: wp.array[wp.vec3],
):
    """Draw isolated worlds that share one place side by side: each particle moved by its world's offset."""
    i = wp.tid()
    w = particle_world[i]
    offset = wp.vec3(0.0)
    if w >= 0 and w < world_offsets.shape[0]:
        offset = world_offsets[w]
    shown[i] = positions[i] + offset


@wp.kernel
def advance_clock(clock: wp.array[float], dt: float):
    """Add ``dt`` [s] to a device-side clock (so captured graphs see the time advance)."""
    clock[0] = clock[0] + dt


def revolved_profile(profile: np.ndarray, segments: int = 48) -> newton.Mesh:
    """A watertight mesh: a closed polygon of the (r, z) half plane revolved about z.

    Args:
        profile: Vertices (radius, height) [m], shape (K, 2), counter-clockwise with r to the
            right and z up (so the surface is wound outward); vertices on the axis (r = 0) close
            the surface there.
        segments: Facets around the axis.
    """
    angles = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    vertices, rings = [], []
    for r, z in profile:
        if r == 0.0:
            rings.append([len(vertices)] * segments)
            vertices.append((0.0, 0.0, z))
        else:
            rings.append(list(range(len(vertices), len(vertices) + segments)))
            vertices.extend((r * np.cos(a), r * np.sin(a), z) for a in angles)
    indices = []
    closed = rings if profile[0][0] == 0.0 and profile[-1][0] == 0.0 else [*rings, rings[0]]
    for lower, upper in zip(closed[:-1], closed[1:], strict=True):
        for k in range(segments):
            k1 = (k + 1) % segments
            a, b, c, e = lower[k], lower[k1], upper[k1], upper[k]
            # degenerate triangles at the axis are skipped
            if a != b:
                indices.extend((a, b, c))
            if c != e:
                indices.extend((a, c, e))
    return newton.Mesh(np.asarray(vertices, dtype=np.float32), np.asarray(indices, dtype=np.int32))


def revolved_container(inner: np.ndarray, thickness: float, segments: int = 48) -> newton.Mesh:
    """A watertight container mesh: the inner wall profile revolved about z, with a wall of ``thickness``.

    Args:
        inner: Inner wall profile, shape (K, 2): radius and height [m] from the inner floor
            (height ``thickness``) up to the rim, heights increasing.
        thickness: Wall and floor thickness [m].
        segments: Facets around the axis.

    Returns:
        newton.Mesh: closed, outward-wound surface (floor, outer wall, rim, inner wall, inner floor),
        so particle contacts get a signed distance with the inside of the wall negative.
    """
    inner = np.asarray(inner, dtype=np.float64)
    outer = inner + np.array([thickness, 0.0])
    outer[0, 1] = 0.0  # the outer wall starts at the ground
    # axis at the bottom, out along the floor, up the outside, over the rim, down the inside, to the axis
    profile = np.vstack([[[0.0, 0.0]], outer, inner[::-1], [[0.0, inner[0, 1]]]])
    return revolved_profile(profile, segments)
