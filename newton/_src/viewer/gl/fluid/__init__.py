# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""``viewer.log_fluid``: fluid particles for every viewer.

This version draws every fluid batch as points in the batch colour on all viewers (the
screen-space surface of ViewerGL is a later addition); the call signature is the final one, so
scenes written against it keep working.
"""

from __future__ import annotations

import numpy as np
import warp as wp


def log_fluid(
    self,
    name: str,
    positions: wp.array | None,
    radii: wp.array | float | None = None,
    *,
    radius_scale: float = 1.8,
    color: tuple = (0.2, 0.45, 0.9, 1.0),
    hidden: bool = False,
    **surface,
) -> None:
    """Log a batch of fluid particles.

    Args:
        name: Unique path of the batch; logging the same name again replaces it.
        positions: Particle (or render) positions [m], ``wp.array`` of ``wp.vec3``; ``None`` removes the batch.
        radii: Per-particle radii [m] (``wp.array`` of float) or one radius for all; ``None`` uses the
            viewer's default point size.
        radius_scale: Multiplier of ``radii`` for drawing [dimensionless], > 0.
        color: Batch colour, RGB or RGBA in [0, 1].
        hidden: Whether the batch is hidden.
        **surface: Surface-shading options of the screen-space renderer (``absorption``, ``ior``,
            ``reflectance``, ``specular_intensity``, ``specular_power``, ``blur_radius_world``,
            ``anisotropy``, ...); the point fallback ignores them.
    """
    if positions is None:
        # an empty batch hides what was logged under this name before
        self.log_points(name, None, hidden=True)
        return
    if not (radius_scale > 0.0):
        raise ValueError(f"radius_scale={radius_scale!r} is out of range: expected a value in (0, inf)")
    if isinstance(radii, (int, float)):
        radii = float(radii) * radius_scale
    elif radii is not None and radius_scale != 1.0:
        radii = wp.array(radii.numpy() * radius_scale, dtype=wp.float32, device=radii.device)
    rgb = tuple(float(c) for c in np.asarray(color, dtype=np.float32)[:3])
    self.log_points(name, positions, radii=radii, colors=rgb, hidden=hidden)


def activate(viewer_module) -> None:
    """Add ``log_fluid`` to the viewer base class of ``viewer_module`` (``newton._src.viewer``); idempotent."""
    if not hasattr(viewer_module.ViewerBase, "log_fluid"):
        viewer_module.ViewerBase.log_fluid = log_fluid
