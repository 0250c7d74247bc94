# SPDX-License-Identifier: Apache-2.0
"""A lawn mower standing on the terrain: its base pose from the ground under its wheels, and its camera's pose.

base_link (REP-103: x forward, y left, z up) sits on the plane fitted through
the terrain under the four wheels, so the robot tilts as the ground does.
camera_link sits CAMERA_HEIGHT above base_link, the fish-eye looking up along
its +z; its axes are base_link's, or turned against them by a mount (the
rotation of camera_link in base_link, skynav_core.mount): the camera's
orientation in map is the base's times the mount.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from skynav_core.rotations import as_matrix

from .render import CameraPose
from .terrain import Terrain

WHEELBASE = 0.45  # m, front to rear axle
TRACK = 0.40  # m, left to right wheel
CAMERA_HEIGHT = 0.30  # m, camera_link above base_link


def base_pose(terrain: Terrain, x: float, y: float, heading: float) -> tuple[np.ndarray, Rotation]:
    """Return position and orientation of base_link for a robot at (x, y) facing `heading` (rad from +x)."""
    forward = np.array([np.cos(heading), np.sin(heading)])
    left = np.array([-forward[1], forward[0]])
    wheels = np.array([[x, y]]) + np.array(
        [sx * WHEELBASE / 2 * forward + sy * TRACK / 2 * left for sx in (-1, 1) for sy in (-1, 1)]
    )
    heights = terrain.height(wheels[:, 0], wheels[:, 1])
    # Least-squares plane z = a + b x + c y through the wheel contacts.
    design = np.column_stack([np.ones(4), wheels])
    a, b, c = np.linalg.lstsq(design, heights, rcond=None)[0]
    up = np.array([-b, -c, 1.0]) / np.hypot(np.hypot(b, c), 1.0)
    ahead = np.array([forward[0], forward[1], 0.0])
    ahead -= (ahead @ up) * up
    ahead /= np.linalg.norm(ahead)
    rotation = Rotation.from_matrix(np.column_stack([ahead, np.cross(up, ahead), up]))
    return np.array([x, y, a + b * x + c * y]), rotation


def camera_pose(
    terrain: Terrain,
    x: float,
    y: float,
    heading: float,
    jitter: Rotation | None = None,
    mount: Rotation | None = None,
) -> CameraPose:
    """Return the camera_link pose of a robot at (x, y) facing `heading`, optionally shaken by `jitter` (a bump
    under the wheels), its camera turned on it by `mount` (camera_link in base_link; None: the base's axes)."""
    position, rotation = base_pose(terrain, x, y, heading)
    if jitter is not None:
        rotation = rotation * jitter
    orientation = rotation * mount if mount is not None else rotation
    return CameraPose(position + rotation.apply([0.0, 0.0, CAMERA_HEIGHT]), orientation)


def base_positions(camera_poses: np.ndarray, mount: np.ndarray | None = None) -> np.ndarray:
    """Return the ground positions (N, 2) of base_link (m, map) of camera_link poses (N, 7) (x, y, z, qx, qy, qz, qw)
    of a camera CAMERA_HEIGHT above base_link, turned on it by `mount` (3, 3; None: the base's axes)."""
    poses = np.asarray(camera_poses, float)
    bases = as_matrix(poses[:, 3:]) if mount is None else as_matrix(poses[:, 3:]) @ np.asarray(mount, float).T
    return poses[:, :2] - CAMERA_HEIGHT * bases[:, :2, 2]


def bump(rng: np.random.Generator, most: float) -> Rotation | None:
    """Return the extra tilt of a bump under the wheels: up to `most` degrees about a random horizontal axis of
    base_link, uniform over that cap of up directions; None (and no random draw) for 0."""
    if most <= 0:
        return None
    axis_angle = rng.uniform(0, 2 * np.pi)
    angle = np.radians(most) * np.sqrt(rng.uniform())
    return Rotation.from_rotvec(angle * np.array([np.cos(axis_angle), np.sin(axis_angle), 0.0]))
