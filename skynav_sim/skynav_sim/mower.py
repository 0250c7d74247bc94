# SPDX-License-Identifier: Apache-2.0
"""A simulated differential-drive mower: integrates velocity commands on the terrain, with wheel slip and odometry.

The mower obeys (forward speed m/s, turn rate rad/s) commands like a robot's base: the wheels turn as commanded,
the ground moves the robot a little less (slip: each step loses a random share of up to `slip` of its forward
travel and its turn is off by a random share of up to `slip`), and the wheel odometry integrates what the wheels
did, with its own noise (`odometry_noise`, a share of each step's travel and turn), so it drifts as real
odometry does. Positions (x, y) and headings are in the world's map frame (m, rad); odometry is in its own frame
`odom`, which starts where the mower starts. An obstacle stops the mower where it is (blocked): its body touches an
object, or it crossed the yard's boundary wire (World.collides; routes are planned with more room to spare).

Pure numpy: the simulation's node (skynav_sim.closed_loop) publishes what it says.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skynav_core.motion import arc

from .world import World


@dataclass
class Pose2D:
    """A planar pose: position (m) and heading (rad, from +x towards +y)."""

    x: float = 0.0
    y: float = 0.0
    heading: float = 0.0

    def moved(self, distance: float, turn: float) -> Pose2D:
        """Return the pose after driving `distance` (m) along an arc that turns by `turn` (rad)."""
        return Pose2D(*arc(self.x, self.y, self.heading, distance, turn))

    @property
    def position(self) -> np.ndarray:
        """Return (x, y) in m."""
        return np.array([self.x, self.y])


class Mower:
    """The mower's true pose in the world and its wheel odometry."""

    def __init__(
        self,
        world: World,
        start: Pose2D,
        rng: np.random.Generator,
        slip: float = 0.05,
        odometry_noise: float = 0.02,
    ) -> None:
        """Place the mower at `start` (map); slip and odometry_noise are shares (0..1) of each step's motion."""
        if not (0.0 <= slip < 1.0 and 0.0 <= odometry_noise < 1.0):
            raise ValueError('slip and odometry noise must be shares within 0..1')
        self.world, self.rng = world, rng
        self.slip, self.odometry_noise = slip, odometry_noise
        self.pose = start
        self.odometry = Pose2D()
        self.blocked = False

    def drive(self, linear: float, angular: float, dt: float) -> None:
        """Obey a command (m/s, rad/s) for `dt` s: move the true pose with slip and the odometry with its noise."""
        distance, turn = linear * dt, angular * dt
        slip = self.rng.uniform(0.0, self.slip, 2) if self.slip > 0 else np.zeros(2)
        noise = self.rng.normal(0.0, self.odometry_noise, 2) if self.odometry_noise > 0 else np.zeros(2)
        true = self.pose.moved(distance * (1.0 - slip[0]), turn * (1.0 + (slip[1] - self.slip / 2)))
        self.blocked = self.world.collides(true.x, true.y)
        if self.blocked:  # the bumper: it stays where it is, and so do the wheels
            return
        self.pose = true
        self.odometry = self.odometry.moved(distance * (1.0 + noise[0]), turn * (1.0 + noise[1]))
