# SPDX-License-Identifier: Apache-2.0
"""The route controller's core: from one camera frame's place match, compass and home vector to a velocity command.

Pure numpy, no ROS: the node (skynav_route.node) turns messages into `View`s and `Command`s into /cmd_vel.

Every direction is in base_link (= camera_link's axes: x forward, y left, z up). A direction's *ground angle* is
its azimuth atan2(y, x) in the robot's x-y plane (rad, left positive).

Route following (`RouteFollower`): where am I (the accepted place match, never moving backwards along the route),
which way does the route run here (the compass rotation R, d_snapshot = R d_current, carries the snapshot's
forward axis e_x into the current view as R^T e_x, the first row of R: that was the driving direction when the
snapshot was taught), and how far off am I (the home vector to a snapshot a few places ahead pulls the robot back,
weighted by its confidence 1 - residual). The steering direction is the sum of the two unit ground directions;
a proportional turn-rate law on its ground angle (pure pursuit in spirit) with speed falling as cos(error).

Homing (`Homer`): turn towards the home vector and drive; slow down by half whenever it points behind (home was
passed); arrived when the home vector stays unsure for `arrived_frames` frames in a row (the views agree: nothing
is left to home on). Near home the vectors become unsure a few decimetres early (0.3-0.4 m in the synthetic park),
so on those frames the robot keeps its last confident course straight on (it never steers on an unsure vector)
for `arrive_creep` m (by odometry, else by its commands) and then stops.

Safety: a frame without the inputs to steer on is *unsure*. Unsure frames first make the robot creep straight on
(recovering); after `lost_frames` of them in a row (or `recover_distance` m of odometry) the goal ends LOST with a
zero command. Every ending gives a zero command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

# states of the FollowRoute feedback (docs/interfaces.md)
LOCALIZING, FOLLOWING, RECOVERING, STOPPING = 'localizing', 'following', 'recovering', 'stopping'
# outcomes of a step: '' goes on, the others end the goal
GOING, REACHED, LOST = '', 'reached', 'lost'
MAX_FRAME_GAP = 1.0  # s: a longer gap between frames counts as this much for the acceleration limits


@dataclass(frozen=True)
class Limits:
    """How fast the robot may go: speed (m/s), acceleration (m/s^2), turn rate (rad/s), turn acceleration (rad/s^2)."""

    max_speed: float = 0.3
    max_acceleration: float = 0.5
    max_turn_rate: float = 1.0
    max_turn_acceleration: float = 4.0


@dataclass(frozen=True)
class Settings:
    """The steering law's gains and the thresholds of the controller's states."""

    heading_gain: float = 1.5  # rad/s of turn rate per rad of heading error
    homing_gain: float = 2.0  # weight of a fully confident home vector against the route direction
    unsure_residual: float = 0.97  # HomeVector.residual above this: no confident direction
    arrived_frames: int = 3  # homing: consecutive unsure home vectors that mean "arrived"...
    arrive_creep: float = 0.25  # m: ...once the robot has crept this far straight on through them (if it drove)
    lost_frames: int = 10  # consecutive unsure frames (after recovering) that end a goal LOST
    recover_speed: float = 0.3  # share of the speed limit at which the robot creeps on while recovering
    recover_distance: float = 1.0  # m of odometry driven while recovering that end a goal LOST
    min_speed_share: float = 0.125  # homing: the speed is halved on each overshoot, down to this share
    end_margin: int = 1  # route following: reached when the match is this close to the end index
    max_jump: int = 8  # route following: accepted matches further ahead than this are not believed at once


@dataclass
class Command:
    """A velocity command in base_link: forward speed (m/s) and turn rate (rad/s, left positive)."""

    linear: float = 0.0
    angular: float = 0.0

    @property
    def is_zero(self) -> bool:
        """Return whether the command stands the robot still."""
        return self.linear == 0.0 and self.angular == 0.0


@dataclass
class View:
    """What the controller knows of one camera frame (stamp in ns); None where an input is missing."""

    stamp: int
    match_index: int = -1  # PlaceMatch.index of this frame
    match_accepted: bool = False
    rotation: np.ndarray | None = None  # (3, 3) compass R against `rotation_index`, d_snapshot = R d_current
    rotation_index: int = -1
    home_direction: np.ndarray | None = None  # (3,) unit home vector in base_link
    home_residual: float = 1.0
    home_index: int = -1
    odometry: float | None = None  # m driven since the previous frame, by /odom (None without odometry)


@dataclass
class Step:
    """The controller's answer to one frame: the command, its state, and whether the goal ends."""

    command: Command
    state: str
    outcome: str = GOING
    matched_index: int = -1
    target_index: int = -1
    progress: float = 0.0  # 0..1
    confidence: float = 0.0  # 0..1


def ground_angle(direction: np.ndarray) -> float:
    """Return the azimuth (rad, left positive) of a base_link direction in the robot's x-y plane."""
    return float(math.atan2(direction[1], direction[0]))


def route_direction(rotation: np.ndarray) -> np.ndarray:
    """Return the route's driving direction at a snapshot in the current base_link: R^T e_x, the first row of R."""
    return np.asarray(rotation, float)[0]


def ground_unit(direction: np.ndarray) -> np.ndarray:
    """Return a base_link direction projected on the robot's x-y plane, as a unit (x, y) (x if it is vertical)."""
    flat = np.asarray(direction, float)[:2]
    norm = float(np.linalg.norm(flat))
    return flat / norm if norm > 1e-9 else np.array([1.0, 0.0])


def steering_angle(route: np.ndarray, home: np.ndarray | None, confidence: float, homing_gain: float) -> float:
    """Return the ground angle (rad) to steer along: the route direction pulled towards the home vector."""
    steer = ground_unit(route)
    if home is not None:
        steer = steer + homing_gain * max(0.0, min(1.0, confidence)) * ground_unit(home)
    return float(math.atan2(steer[1], steer[0]))


def pursue(error: float, speed: float, limits: Limits, settings: Settings) -> Command:
    """Return the command that turns a heading error (rad) away: turn rate proportional, speed falling as cos."""
    angular = float(np.clip(settings.heading_gain * error, -limits.max_turn_rate, limits.max_turn_rate))
    return Command(speed * max(0.0, math.cos(error)), angular)


def limit(desired: Command, previous: Command, dt: float, limits: Limits) -> Command:
    """Return `desired` within the speed, turn-rate and acceleration limits, `dt` s after `previous`."""
    dt = min(max(dt, 0.0), MAX_FRAME_GAP)
    linear = float(np.clip(desired.linear, -limits.max_speed, limits.max_speed))
    angular = float(np.clip(desired.angular, -limits.max_turn_rate, limits.max_turn_rate))
    step_linear, step_angular = limits.max_acceleration * dt, limits.max_turn_acceleration * dt
    linear = float(np.clip(linear, previous.linear - step_linear, previous.linear + step_linear))
    angular = float(np.clip(angular, previous.angular - step_angular, previous.angular + step_angular))
    return Command(linear, angular)


@dataclass
class _Motion:
    """The last command and the stamp it answered, for the acceleration limits."""

    command: Command = field(default_factory=Command)
    stamp: int | None = None

    def limited(self, desired: Command, stamp: int, limits: Limits) -> Command:
        """Return `desired` limited against the previous command and remember it."""
        dt = 0.0 if self.stamp is None else (stamp - self.stamp) / 1e9
        command = limit(desired, self.command, dt, limits)
        self.command, self.stamp = command, stamp
        return command

    def stop(self, stamp: int) -> Command:
        """Return a zero command (a stop is never rate-limited) and remember it."""
        self.command, self.stamp = Command(), stamp
        return Command()


class RouteFollower:
    """Drives along a taught route from `start_index` (or wherever the robot is matched) to `end_index`."""

    def __init__(self, start_index: int, end_index: int, limits: Limits, settings: Settings) -> None:
        """Follow snapshots start_index..end_index (start -1: the first accepted match places the robot)."""
        self.start_index, self.end_index = start_index, end_index
        self.limits, self.settings = limits, settings
        self.matched = -1  # furthest snapshot believed passed
        self.unsure = 0
        self.recovered_distance = 0.0
        self.state = LOCALIZING
        self._motion = _Motion()

    def progress(self) -> float:
        """Return how far along start..end the robot is believed (0..1)."""
        start = max(self.start_index, 0)
        if self.matched < 0 or self.end_index <= start:
            return 0.0 if self.matched < 0 else 1.0
        return float(np.clip((self.matched - start) / (self.end_index - start), 0.0, 1.0))

    def _take_match(self, view: View) -> bool:
        """Move the believed place on with an accepted match that is plausible; return whether it was taken."""
        if not view.match_accepted or view.match_index < 0:
            return False
        if self.matched < 0:
            near_start = self.start_index < 0 or abs(view.match_index - self.start_index) <= self.settings.max_jump
            if near_start and view.match_index <= self.end_index:
                self.matched = view.match_index
                return True
            return False
        if self.matched - self.settings.max_jump <= view.match_index <= self.matched + self.settings.max_jump:
            self.matched = max(self.matched, view.match_index)  # never backwards along the route
            return True
        return False

    def step(self, view: View) -> Step:
        """Return the command for one frame."""
        matched = self._take_match(view)
        if self.matched >= 0 and self.matched >= self.end_index - self.settings.end_margin:
            self.state = STOPPING
            return self._answer(self._motion.stop(view.stamp), view, REACHED)
        confidence = float(np.clip(1.0 - view.home_residual, 0.0, 1.0)) if view.home_direction is not None else 0.0
        if self.matched < 0:  # not placed on the route yet: stand still and look
            self.unsure += 1
            self.state = LOCALIZING
            if self.unsure > self.settings.lost_frames:
                return self._answer(self._motion.stop(view.stamp), view, LOST)
            return self._answer(self._motion.stop(view.stamp), view)
        if matched and view.rotation is not None:
            self.unsure, self.recovered_distance, self.state = 0, 0.0, FOLLOWING
            angle = steering_angle(
                route_direction(view.rotation), view.home_direction, confidence, self.settings.homing_gain
            )
            desired = pursue(angle, self.limits.max_speed, self.limits, self.settings)
            return self._answer(self._motion.limited(desired, view.stamp, self.limits), view)
        # unsure: creep straight on for a while, as a driver would, then give up
        self.unsure += 1
        self.recovered_distance += view.odometry or 0.0
        if self.unsure > self.settings.lost_frames or self.recovered_distance > self.settings.recover_distance:
            self.state = STOPPING
            return self._answer(self._motion.stop(view.stamp), view, LOST)
        self.state = RECOVERING
        desired = Command(self.settings.recover_speed * self.limits.max_speed, 0.0)
        return self._answer(self._motion.limited(desired, view.stamp, self.limits), view)

    def _answer(self, command: Command, view: View, outcome: str = GOING) -> Step:
        sure = view.home_direction is not None and not self.unsure
        confidence = float(np.clip(1.0 - view.home_residual, 0.0, 1.0)) if sure else 0.0
        progress = 1.0 if outcome == REACHED else self.progress()
        return Step(command, self.state, outcome, self.matched, view.home_index, progress, float(confidence))


class Homer:
    """Drives to the place of one snapshot by its home vectors."""

    def __init__(self, index: int, limits: Limits, settings: Settings) -> None:
        """Home to snapshot `index`."""
        self.index, self.limits, self.settings = index, limits, settings
        self.speed_share = 1.0
        self.unsure = 0  # consecutive unsure home vectors (the views agree: arrived)
        self.crept = 0.0  # m driven straight on through them
        self.missing = 0  # consecutive frames without a home vector to this snapshot
        self.driving = False  # whether the robot has driven towards home yet (overshoot needs that)
        self._motion = _Motion()

    def step(self, view: View) -> Step:
        """Return the command for one frame."""
        if view.home_direction is None or view.home_index != self.index:
            self.missing += 1
            outcome = LOST if self.missing > self.settings.lost_frames else GOING
            return Step(self._motion.stop(view.stamp), RECOVERING if not outcome else STOPPING, outcome)
        self.missing = 0
        confidence = float(np.clip(1.0 - view.home_residual, 0.0, 1.0))
        if view.home_residual > self.settings.unsure_residual:
            self.unsure += 1
            if self.unsure > 1:  # travel since the first unsure frame: odometry, else the last command
                dt = (view.stamp - self._motion.stamp) / 1e9 if self._motion.stamp is not None else 0.0
                self.crept += view.odometry if view.odometry is not None else self._motion.command.linear * dt
            crept_enough = self.crept >= self.settings.arrive_creep or not self.driving
            if self.unsure >= self.settings.arrived_frames and crept_enough:
                return Step(self._motion.stop(view.stamp), STOPPING, REACHED, confidence=confidence)
            # unsure near home: keep the last confident course straight on (never steer on a guess), then stop
            desired = Command(self.speed_share * self.limits.max_speed if self.driving else 0.0, 0.0)
            return Step(self._motion.limited(desired, view.stamp, self.limits), RECOVERING, confidence=confidence)
        self.unsure, self.crept = 0, 0.0
        error = ground_angle(view.home_direction)
        if self.driving and abs(error) > math.pi / 2:  # it points back: home was passed
            self.speed_share = max(self.speed_share / 2, self.settings.min_speed_share)
            self.driving = False
        desired = pursue(error, self.speed_share * self.limits.max_speed, self.limits, self.settings)
        command = self._motion.limited(desired, view.stamp, self.limits)
        self.driving = self.driving or command.linear > 0.0
        return Step(command, FOLLOWING, confidence=confidence)
