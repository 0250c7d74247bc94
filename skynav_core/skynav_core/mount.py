# SPDX-License-Identifier: Apache-2.0
"""The camera's mount on the robot: the rotation of camera_link in base_link, and camera_link's directions and
rotations turned into base_link.

docs/interfaces.md ("Cameras as robots have them", Mounting): camera_link may be turned against base_link by any
rotation. The *mount* M is camera_link's orientation in base_link, the rotation of the transform base_link ->
camera_link as /tf_static and a URDF give it (its columns are camera_link's axes in base_link). A direction d of
camera_link is M d in base_link; a rotation R between two views' camera_link (d_snapshot = R d_current) is
M R M^T between the two base_links. Where the camera sits on the robot (the translation) changes no direction and
no rotation, so it is left out.

The mount comes from the parameter `camera_mount_rpy_deg` (roll, pitch, yaw in degrees, fixed axes X, Y, Z as
REP-103's and URDF's RPY; `mount_from_rpy_deg`) or from /tf_static (`StaticTransforms`: every fixed transform
heard, so a chain base_link -> ... -> camera_link of a URDF gives the mount too). No rclpy: messages are read by
their fields (tf2_msgs/TFMessage, geometry_msgs/TransformStamped).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .names import BASE_FRAME, CAMERA_FRAME
from .rotations import as_matrix, rpy_angles, rpy_matrix

# tf2 refuses a transform whose quaternion's squared norm is further than this from 1 (BufferCore::setTransform)
QUATERNION_TOLERANCE = 0.01


def mount_from_rpy_deg(value: Any) -> np.ndarray:
    """Return the mount M (3, 3) of a camera_mount_rpy_deg value: roll, pitch, yaw in degrees (fixed axes X, Y, Z);
    ValueError, in one line, for anything but three finite numbers."""
    if isinstance(value, str | bytes) or not isinstance(value, Sequence | np.ndarray):
        raise ValueError(f'camera_mount_rpy_deg must be [roll, pitch, yaw] in degrees, got {value!r}')
    if len(value) != 3 or any(isinstance(v, bool) or not isinstance(v, int | float | np.number) for v in value):
        raise ValueError(f'camera_mount_rpy_deg must be three numbers [roll, pitch, yaw] in degrees, got {list(value)}')
    angles = [float(v) for v in value]
    if not all(math.isfinite(v) for v in angles):
        raise ValueError(f'camera_mount_rpy_deg must be finite, got {angles}')
    return rpy_matrix(*np.radians(angles))


def mount_rpy_deg(mount: np.ndarray) -> tuple[float, float, float]:
    """Return a mount's roll, pitch and yaw in degrees (fixed axes X, Y, Z), as camera_mount_rpy_deg gives them."""
    roll, pitch, yaw = rpy_angles(mount)
    return float(np.degrees(roll)), float(np.degrees(pitch)), float(np.degrees(yaw))


def describe(mount: np.ndarray) -> str:
    """Return a mount in words for a log line: its roll, pitch and yaw in degrees."""
    roll, pitch, yaw = mount_rpy_deg(mount)
    return f'roll {roll:.1f}, pitch {pitch:.1f}, yaw {yaw:.1f} deg'


def direction_to_base(mount: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Return camera_link directions (..., 3) in base_link: M d."""
    return np.asarray(directions, float) @ np.asarray(mount, float).T


def rotation_to_base(mount: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Return rotations (..., 3, 3) between two views' camera_link (d_snapshot = R d_current) as the same rotation
    between their base_links: M R M^T."""
    m = np.asarray(mount, float)
    return m @ np.asarray(rotations, float) @ m.T


def frame_name(frame_id: str) -> str:
    """Return a tf frame id as tf2 keys it: without a leading '/'."""
    return frame_id.lstrip('/')


def transform_rotation(transform: Any) -> np.ndarray:
    """Return the rotation (3, 3) of a geometry_msgs/TransformStamped (its child frame's orientation in its parent);
    ValueError for a quaternion that is not finite or not of unit length (as tf2 refuses it)."""
    q = transform.transform.rotation
    quaternion = np.array([q.x, q.y, q.z, q.w], float)
    if not np.all(np.isfinite(quaternion)):
        raise ValueError('its rotation is not finite')
    if abs(float(quaternion @ quaternion) - 1.0) > QUATERNION_TOLERANCE:
        raise ValueError(f'its rotation quaternion is not of unit length (norm {np.linalg.norm(quaternion):.3f})')
    return as_matrix(quaternion / np.linalg.norm(quaternion))


class StaticTransforms:
    """The fixed transforms heard on /tf_static: per child frame its parent and rotation, the latest of each (as
    tf2's buffer keeps them), and the rotation between any two frames of one tree."""

    def __init__(self) -> None:
        self.links: dict[str, tuple[str, np.ndarray]] = {}  # child frame -> (parent frame, child's rotation in it)

    def add(self, message: Any) -> list[str]:
        """Take every usable transform of a tf2_msgs/TFMessage; return one line per transform refused."""
        problems = []
        for transform in message.transforms:
            parent, child = frame_name(transform.header.frame_id), frame_name(transform.child_frame_id)
            if not parent or not child or parent == child:
                problems.append(f'a transform from {parent!r} to {child!r} links no two frames')
                continue
            try:
                self.links[child] = (parent, transform_rotation(transform))
            except ValueError as exc:
                problems.append(f'the transform {parent} -> {child} is refused: {exc}')
        return problems

    def _in_root(self, frame: str) -> tuple[str, np.ndarray]:
        """Return the root of `frame`'s tree and the frame's rotation in it; ValueError if its parents loop."""
        rotation, seen = np.eye(3), [frame]
        while frame in self.links:
            frame, link = self.links[frame]
            rotation = link @ rotation
            if frame in seen:
                raise ValueError(f'the transforms on /tf_static loop: {" -> ".join([*seen, frame])}')
            seen.append(frame)
        return frame, rotation

    def rotation(self, parent: str, child: str) -> np.ndarray | None:
        """Return the rotation (3, 3) of frame `child` in frame `parent` through the transforms heard (any chain
        between them); None while they are not linked; ValueError if the transforms loop."""
        if parent == child:
            return np.eye(3)
        parent_root, parent_rotation = self._in_root(parent)
        child_root, child_rotation = self._in_root(child)
        if parent_root != child_root:
            return None
        return parent_rotation.T @ child_rotation

    def mount(self) -> np.ndarray | None:
        """Return the mount (camera_link in base_link) the transforms heard give; None while they give none."""
        return self.rotation(BASE_FRAME, CAMERA_FRAME)
