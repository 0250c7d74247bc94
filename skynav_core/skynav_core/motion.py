# SPDX-License-Identifier: Apache-2.0
"""Planar motion of a ground robot: a pose on the ground plane moved along an arc, and as a 3D pose."""

from __future__ import annotations

import math

import numpy as np

from .rotations import wrap_angle


def arc(x: float, y: float, heading: float, distance: float, turn: float) -> tuple[float, float, float]:
    """Return the pose (x, y in m, heading in rad, wrapped) after driving `distance` (m) along an arc that turns by
    `turn` (rad, left positive) from (x, y, heading)."""
    if abs(turn) < 1e-9:
        dx, dy = distance, 0.0
    else:  # exact arc of radius distance / turn
        radius = distance / turn
        dx, dy = radius * math.sin(turn), radius * (1.0 - math.cos(turn))
    c, s = math.cos(heading), math.sin(heading)
    return x + c * dx - s * dy, y + s * dx + c * dy, wrap_angle(heading + turn)


def ground_pose(x: float, y: float, heading: float) -> np.ndarray:
    """Return (x, y, 0, qx, qy, qz, qw) of a pose on the ground plane (m; heading in rad about z, left positive)."""
    return np.array([x, y, 0.0, 0.0, 0.0, math.sin(heading / 2), math.cos(heading / 2)])
