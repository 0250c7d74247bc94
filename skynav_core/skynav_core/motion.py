# SPDX-License-Identifier: Apache-2.0
"""Planar motion of a ground robot: a pose on the ground plane moved along an arc, as a 3D pose, and the velocity
command that asks for it (geometry_msgs TwistStamped in base_link, or a bare Twist for a base that takes that)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .names import BASE_FRAME
from .rotations import wrap_angle

if TYPE_CHECKING:
    from geometry_msgs.msg import Twist, TwistStamped


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


def fill_twist(message: Twist, linear: float, angular: float) -> Twist:
    """Fill a Twist of a differential drive: forward speed (m/s) and turn rate (rad/s, left positive) in base_link,
    every other field 0; return it."""
    message.linear.x, message.linear.y, message.linear.z = float(linear), 0.0, 0.0
    message.angular.x, message.angular.y, message.angular.z = 0.0, 0.0, float(angular)
    return message


def fill_velocity_command(message: TwistStamped, stamp: int, linear: float, angular: float) -> TwistStamped:
    """Fill a /cmd_vel command: forward speed (m/s) and turn rate (rad/s, left positive) in base_link, stamped
    `stamp` (ns); return it."""
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(int(stamp), 1_000_000_000)
    message.header.frame_id = BASE_FRAME
    fill_twist(message.twist, linear, angular)
    return message
