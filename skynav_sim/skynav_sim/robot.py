# SPDX-License-Identifier: Apache-2.0
"""A lawn mower standing on the terrain: its base pose from the ground under its wheels, and its camera's pose.

base_link (REP-103: x forward, y left, z up) sits on the plane fitted through
the terrain under the four wheels, so the robot tilts as the ground does.
camera_link has the same axes (the fish-eye looks up along +z) and is mounted
CAMERA_HEIGHT above base_link.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

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


def camera_pose(terrain: Terrain, x: float, y: float, heading: float, jitter: Rotation | None = None) -> CameraPose:
    """Return the camera_link pose of a robot at (x, y) facing `heading`, optionally shaken by `jitter`."""
    position, rotation = base_pose(terrain, x, y, heading)
    if jitter is not None:
        rotation = rotation * jitter
    return CameraPose(position + rotation.apply([0.0, 0.0, CAMERA_HEIGHT]), rotation)


def bump(rng: np.random.Generator, most: float) -> Rotation | None:
    """Return the extra tilt of a bump under the wheels: up to `most` degrees about a random horizontal axis of
    base_link, uniform over that cap of up directions; None (and no random draw) for 0."""
    if most <= 0:
        return None
    axis_angle = rng.uniform(0, 2 * np.pi)
    angle = np.radians(most) * np.sqrt(rng.uniform())
    return Rotation.from_rotvec(angle * np.array([np.cos(axis_angle), np.sin(axis_angle), 0.0]))
