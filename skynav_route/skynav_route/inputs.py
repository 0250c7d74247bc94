# SPDX-License-Identifier: Apache-2.0
"""One camera frame's messages as the controller sees them: a View in base_link; and how far an IMU says the robot
leans (imu_tilt).

The stages' messages stay in camera_link (docs/interfaces.md); the controller steers in base_link. With the mount M
(camera_link's rotation in base_link, skynav_core.mount) the home vector d becomes M d and the compass rotation R
(d_snapshot = R d_current between two camera_links) becomes M R M^T between the two base_links, so the heading's
twist (yaw), the route's direction (the first row of R) and every ground angle the controller takes are the
robot's, however the camera is turned on it. The compass's `confident` and `confidence` go with its rotation (the
controller steers on a non-confident one only where it agrees with its other inputs). No rclpy: messages are read
by their fields.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from skynav_core.mount import direction_to_base, rotation_to_base
from skynav_core.rotations import as_matrix

from .controller import View

# s by the IMU's stamps that a lean over max_tilt_deg must last before it stops the robot (a jolt is shorter)
TILT_HOLD = 0.2


def compass_rotation(estimate: Any) -> np.ndarray | None:
    """Return a CompassEstimate's rotation (3, 3) in camera_link; None unless its quaternion is finite and not 0."""
    q = estimate.rotation
    quaternion = np.array([q.x, q.y, q.z, q.w], float)
    norm = float(np.linalg.norm(quaternion))
    if not (np.isfinite(norm) and norm > 0):
        return None
    return as_matrix(quaternion / norm)


def home_direction(vector: Any) -> np.ndarray | None:
    """Return a HomeVector's unit direction (3,) in camera_link; None unless it and its residual are finite and it is
    not 0."""
    d = np.array([vector.direction.x, vector.direction.y, vector.direction.z], float)
    norm = float(np.linalg.norm(d))
    if not (np.isfinite(norm) and norm > 0 and np.isfinite(vector.residual)):
        return None
    return d / norm


def frame_view(stamp: int, match: Any, compass: Any, home: Any, mount: np.ndarray) -> View:
    """Return the View of the frame stamped `stamp` (ns) from its PlaceMatch, CompassEstimate and HomeVector (None
    where missing), the compass rotation and home vector turned into base_link by the mount (3, 3)."""
    view = View(stamp)
    if match is not None:
        view.match_index, view.match_accepted = int(match.index), bool(match.accepted)
    rotation = compass_rotation(compass) if compass is not None else None
    if rotation is not None:
        view.rotation, view.rotation_index = rotation_to_base(mount, rotation), int(compass.snapshot_index)
        view.rotation_confident, view.rotation_confidence = bool(compass.confident), float(compass.confidence)
    direction = home_direction(home) if home is not None else None
    if direction is not None:
        view.home_direction, view.home_residual = direction_to_base(mount, direction), float(home.residual)
        view.home_index = int(home.snapshot_index)
    return view


def imu_tilt(imu: Any, base_rotation: np.ndarray) -> float | None:
    """Return how far (rad) base_link's z axis leans from the vertical by a sensor_msgs/Imu: by its orientation when
    it gives one (REP-145: orientation_covariance[0] is -1 when it does not), else by the direction of its linear
    acceleration (at rest the reaction to gravity, up). `base_rotation` (3, 3) is the IMU frame's rotation in
    base_link. None when neither is finite and non-zero."""
    up = None
    q = imu.orientation
    quaternion = np.array([q.x, q.y, q.z, q.w], float)
    norm = float(np.linalg.norm(quaternion))
    if imu.orientation_covariance[0] != -1.0 and np.isfinite(norm) and norm > 0:
        up = as_matrix(quaternion / norm).T[:, 2]  # the world's up in the IMU's frame
    else:
        a = imu.linear_acceleration
        acceleration = np.array([a.x, a.y, a.z], float)
        norm = float(np.linalg.norm(acceleration))
        if np.isfinite(norm) and norm > 0:
            up = acceleration / norm
    if up is None:
        return None
    return float(np.arccos(np.clip((np.asarray(base_rotation, float) @ up)[2], -1.0, 1.0)))
