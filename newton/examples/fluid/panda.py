# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""A kinematic Franka Emika Panda built from its published kinematic parameters (no assets, no network).

The joint frames follow the modified (Craig) Denavit-Hartenberg parameters that Franka Emika
publishes for the Panda in "Robot and interface specifications" (Franka Control Interface
documentation): per joint ``(a_{i-1}, d_i, alpha_{i-1})``, then the flange 0.107 m along the last
joint's axis. Links are drawn as capsules between consecutive joint origins; the arm is a chain
of kinematic links, posed by forward kinematics from scripted joint angles.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

import newton

# (a_{i-1} [m], d_i [m], alpha_{i-1} [rad]) of joints 1..7 (Franka Emika, modified DH)
PANDA_DH = (
    (0.0, 0.333, 0.0),
    (0.0, 0.0, -math.pi / 2),
    (0.0, 0.316, math.pi / 2),
    (0.0825, 0.0, math.pi / 2),
    (-0.0825, 0.384, -math.pi / 2),
    (0.0, 0.0, math.pi / 2),
    (0.088, 0.0, math.pi / 2),
)
FLANGE_D = 0.107  # flange offset along joint 7's axis [m]
HAND_LENGTH = 0.1034  # flange to the fingertips' centre (Franka Hand) [m]
#: joint position limits [rad], lower and upper, and velocity limits [rad/s] (Franka Emika, "Robot and
#: interface specifications")
JOINT_LOWER = (-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973)
JOINT_UPPER = (2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973)
JOINT_SPEED = (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61)
#: joint angles of Franka's "ready" pose [rad]: flange pointing down in front of the base
READY = (0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4)


def _joint_frame(a: float, d: float, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """Parent-side frame of a joint (position, rotation matrix) in the previous link's frame."""
    c, s = math.cos(alpha), math.sin(alpha)
    rot = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return rot @ np.array([a, 0.0, d]), rot


def forward_kinematics(q) -> list[np.ndarray]:
    """4x4 world transforms of links 1..7 and of the flange for joint angles ``q`` [rad] (base at the origin)."""
    frames, t = [], np.eye(4)
    for (a, d, alpha), angle in zip(PANDA_DH, q, strict=True):
        p, r = _joint_frame(a, d, alpha)
        c, s = math.cos(angle), math.sin(angle)
        joint = np.eye(4)
        joint[:3, :3] = r @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        joint[:3, 3] = p
        t = t @ joint
        frames.append(t)
    flange = np.eye(4)
    flange[2, 3] = FLANGE_D
    frames.append(t @ flange)
    return frames


def _quat_from_matrix(r: np.ndarray) -> wp.quat:
    return wp.quat_from_matrix(wp.mat33(*r.ravel().tolist()))


def joint_frames() -> list[wp.transform]:
    """Parent-side frames of joints 1..7 in the previous link's frame (base: world)."""
    frames = []
    for a, d, alpha in PANDA_DH:
        p, r = _joint_frame(a, d, alpha)
        frames.append(wp.transform(wp.vec3(*p), _quat_from_matrix(r)))
    return frames


def add_panda(builder: newton.ModelBuilder, link_radius: float = 0.045) -> list[int]:
    """Add the Panda's base and links 1..7 as kinematic bodies (posed by :func:`pose_panda`).

    Each link is a root body with the pose forward kinematics gives it, so the arm moves exactly
    along the scripted path and pushes the fluid without being pushed back.

    Returns:
        list[int]: body indices of the base and links 1..7 (link ``i`` at entry ``i``).
    """
    # massless shapes: the kinematic links' frames are their centres of mass; scripted links need no
    # rigid contacts with each other, only with the fluid
    cfg = newton.ModelBuilder.ShapeConfig(mu=0.0, density=0.0, has_shape_collision=False)
    base = builder.add_body(is_kinematic=True, label="panda_link0")
    builder.add_shape_capsule(
        base,
        xform=wp.transform(wp.vec3(0.0, 0.0, 0.5 * PANDA_DH[0][1]), wp.quat_identity()),
        radius=1.3 * link_radius,
        half_height=0.5 * PANDA_DH[0][1] - 1.3 * link_radius,
        cfg=cfg,
    )
    bodies = [base]
    for i in range(len(PANDA_DH)):
        link = builder.add_body(is_kinematic=True, label=f"panda_link{i + 1}")
        # a capsule from this joint to the next one (or to the flange)
        if i + 1 < len(PANDA_DH):
            offset, _ = _joint_frame(*PANDA_DH[i + 1])
        else:
            offset = np.array([0.0, 0.0, FLANGE_D])
        length = float(np.linalg.norm(offset))
        if length > 1.0e-6:
            axis = offset / length
            # rotate the capsule's z axis onto the segment
            v = np.cross((0.0, 0.0, 1.0), axis)
            if np.linalg.norm(v) < 1.0e-9:
                rot = wp.quat_identity() if axis[2] > 0 else wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), math.pi)
            else:
                rot = wp.quat_from_axis_angle(wp.vec3(*(v / np.linalg.norm(v))), math.acos(float(axis[2])))
            builder.add_shape_capsule(
                link,
                xform=wp.transform(wp.vec3(*(0.5 * offset)), rot),
                radius=link_radius,
                half_height=max(0.5 * length - link_radius, 0.25 * length),
                cfg=cfg,
            )
        else:
            builder.add_shape_sphere(link, radius=link_radius, cfg=cfg)
        bodies.append(link)
    return bodies


@wp.func
def path_angle(t: float, times: wp.array[float], angles: wp.array2d[float], j: int):
    """Joint ``j``'s angle [rad] on a keyframe path at time ``t`` [s]: smoothstep between keyframes (rest at each)."""
    n = times.shape[0]
    if t <= times[0]:
        return angles[0, j]
    for k in range(n - 1):
        if t < times[k + 1]:
            u = (t - times[k]) / (times[k + 1] - times[k])
            u = u * u * (3.0 - 2.0 * u)
            return angles[k, j] + u * (angles[k + 1, j] - angles[k, j])
    return angles[n - 1, j]


@wp.func
def link_pose(q: wp.array2d[float], w: int, link: int, frames: wp.array[wp.transform]):
    """World pose of ``link`` (0: base) of world ``w``'s arm at the joint angles ``q[w]`` [rad]."""
    x = wp.transform_identity()
    for j in range(link):
        x = x * frames[j] * wp.transform(wp.vec3(0.0), wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), q[w, j]))
    return x


@wp.kernel
def pose_panda(
    q_start: wp.array2d[float],
    q_end: wp.array2d[float],
    dt: float,
    bodies: wp.array2d[wp.int32],
    frames: wp.array[wp.transform],
    body_q: wp.array[wp.transform],
    body_qd: wp.array[wp.spatial_vector],
):
    """Pose link ``l`` of world ``w``'s arm at ``q_end``, with the velocity that takes it there from ``q_start`` in ``dt``."""
    w, link = wp.tid()
    x0 = link_pose(q_start, w, link, frames)
    x1 = link_pose(q_end, w, link, frames)
    dq = wp.transform_get_rotation(x1) * wp.quat_inverse(wp.transform_get_rotation(x0))
    axis = wp.vec3(0.0)
    angle = float(0.0)
    wp.quat_to_axis_angle(dq, axis, angle)
    if angle > wp.pi:
        angle -= 2.0 * wp.pi
    b = bodies[w, link]
    body_q[b] = x1
    body_qd[b] = wp.spatial_vector(
        (wp.transform_get_translation(x1) - wp.transform_get_translation(x0)) / dt, axis * (angle / dt)
    )


def flange_down_q6(q1: float, q2: float, q4: float, q7: float) -> float:
    """Joint 6 angle [rad] that points the flange straight down, with joints 3 and 5 at zero."""

    # joints 2, 4 and 6 then turn about parallel axes, so the flange's pitch is linear in q6: solve it
    def pitch_error(q6):
        z = forward_kinematics((q1, q2, 0.0, q4, 0.0, q6, q7))[-1][:3, 2]
        return z

    q6 = READY[5] + (q2 - READY[1]) - (q4 - READY[3])
    for _ in range(20):
        z0 = pitch_error(q6)
        if np.linalg.norm(z0 + np.array([0.0, 0.0, 1.0])) < 1.0e-12:
            break
        eps = 1.0e-6
        # Newton step on the flange axis' horizontal component along the arm's plane
        plane = np.array([math.cos(q1), math.sin(q1), 0.0])
        f0 = float(z0 @ plane)
        f1 = float(pitch_error(q6 + eps) @ plane)
        q6 -= f0 * eps / (f1 - f0)
    return q6
