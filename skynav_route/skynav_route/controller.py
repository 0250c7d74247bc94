# SPDX-License-Identifier: Apache-2.0
"""The route controller's core: from one camera frame's place match, compass and home vector to a velocity command.

Pure numpy, no ROS: the node (skynav_route.node) turns messages into `View`s and `Command`s into /cmd_vel.

Every direction and rotation is in base_link (x forward, y left, z up): the node turns the stages' camera_link
home vector and compass rotation into it by the camera's mount (skynav_route.inputs), so a camera mounted turned or
tilted steers like one on the robot's axes. A direction's *ground angle* is its azimuth atan2(y, x) in the robot's
x-y plane (rad, left positive).

Route following (`RouteFollower`): where am I, and which way does the route run there? The robot's heading in the
teach's odometry frame is known closely: the compass rotation R (d_snapshot = R d_current) against the matched
snapshot twists about z by `yaw(R)` from the heading that snapshot was taught with (`TaughtRoute`: the teach's
odometry poses). Its ground position in that frame is kept by `RoutePosition`, a Kalman filter of two states:
from frame to frame it is carried on by the distance driven (odometry, else the last command) along that heading;
each accepted place match puts the robot level with its snapshot along the route (`match_noise`); each home vector
to a snapshot a few places ahead puts that snapshot on the line of sight (`bearing_noise`, weighted by the
vector's confidence 1 - residual). One home vector is a noisy and, over metres, biased ruler (its bearing is off
by tens of degrees where the scene is poor); the filter averages it over metres of driving against the odometry
(`odometry_drift`, `odometry_noise`). The nearest point of the route's polyline to that position gives the
*cross-track offset* (m, left positive) and the route's direction there, so that a match a few decimetres ahead
on a bend bends neither. The steering law is Stanley's in spirit: head along the route, turned towards it by
atan(offset / `approach`), the route's curvature over `route_lead` snapshots fed forward, with a proportional
turn-rate law and the speed falling as cos(error). *Point turns* (a lawn's lane ends, where the teach turned in
place: `TaughtRoute.point_turns`) are driven as taught: the robot slows to arrive on the corner at rest (no more
than sqrt(2 a d) at d m before it), feels no curvature forward across it (so it cuts no corner) and turns there in
place while its heading error exceeds IN_PLACE_ERROR, then drives the next leg. A map without the teach's odometry
(built from a recording without /odom) has no shape to place the robot on: there the robot steers along the sum
of the route's direction (the snapshot's forward axis R^T e_x, the first row of R, in the current view) and the
home vector weighted by `homing_gain` times its confidence.

Homing (`Homer`): turn towards the home vector and drive; slow down by half whenever it points behind (home was
passed); arrived when the home vector stays unsure for `arrived_frames` frames in a row (the views agree: nothing
is left to home on). A frame whose home vector the warping node refused (it publishes none whose direction the
views do not determine: at the snapshot, or too close to tell) is unsure too, as long as home vectors come at all
(`View.home_expected`; without any, the frames are missing and the goal ends LOST). Near home the vectors become
unsure a little early (within the warping's shortest step:
0.05-0.3 m in the synthetic garden and park), so on those frames the robot keeps its last confident course straight
on (it never steers on an unsure vector) for `arrive_creep` m (by odometry, else by its commands) and then stops.

A compass rotation not marked `confident` (an ambiguous yaw: CompassEstimate.confident) is steered on only where
it agrees, within COMPASS_AGREEMENT_DEG, with the heading the controller predicts (its last heading turned by its
last command's turn rate) or with the heading the home vector implies (its bearing against the line of sight to
its snapshot; without the route's shape: the route's direction against the home vector). A rotation that agrees
with neither is not turned on: the frame is unsure, as one without a compass (no turn, `recover_speed`), and the
feedback's confidence is 0; a non-confident rotation that agrees is used, the feedback's confidence then at most
the compass's own.

Safety: a frame without the inputs to steer on is *unsure*. Unsure frames first make the robot creep straight on
(recovering); after `lost_frames` of them in a row (or `recover_distance` m of odometry) the goal ends LOST with a
zero command. Every ending gives a zero command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from skynav_core.rotations import wrap_angle, yaw

# states of the FollowRoute feedback (docs/interfaces.md)
LOCALIZING, FOLLOWING, RECOVERING, STOPPING = 'localizing', 'following', 'recovering', 'stopping'
# outcomes of a step: '' goes on, the others end the goal
GOING, REACHED, LOST = '', 'reached', 'lost'
#: snapshots: a Homer that has had no home vector yet takes frames without one as a refusal near home (arriving) only
#: where the frame's accepted place match lies within this many snapshots of its own (some 0.3 m at 0.1 m spacing)
ARRIVAL_MATCH_SNAPSHOTS = 3
MAX_FRAME_GAP = 1.0  # s: a longer gap between frames counts as this much for the acceleration limits
START_ALONG_SIGMA = 0.5  # m: standard deviation of the position along the route when the first match places the robot
START_OFFSET_SIGMA = 0.3  # m: ...and across it
MIN_SIGHT = 0.3  # m: a home vector's line of sight is trusted no better than one to a snapshot this far away
GATE_SIGMAS = 3.0  # a home vector whose line of sight is further than this many standard deviations is ignored
LOCATE_WINDOW = 10  # snapshots either side of the last nearest one where the nearest point of the route is sought
# deg: a compass yaw not marked confident is steered on only within this of the predicted or the home vector's heading
COMPASS_AGREEMENT_DEG = 20.0
POINT_TURN_STEP = math.radians(20.0)  # rad: two snapshots turned this much or more from each other...
POINT_TURN_RADIUS = 0.15  # m: ...on a tighter radius than this are a point turn (the teach turned where it stood)
IN_PLACE_ERROR = math.radians(30.0)  # rad: at a point turn, a heading error beyond this is turned away in place
CORNER_LOOKAHEAD = 30  # snapshots ahead (3 m at 0.1 m spacing) where the next point turn is sought
TIES = 1e-6  # m: nearest points of the route closer than this to each other are the same point (a corner)


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
    approach: float = 1.0  # m: route following turns towards the route by atan(cross-track offset / approach)
    bearing_noise: float = 1.0  # rad: standard deviation of a fully confident home vector's bearing
    match_noise: float = 0.6  # m: standard deviation of an accepted place match's position along the route
    odometry_drift: float = 0.01  # m: growth of the position's standard deviation per square-root metre driven
    odometry_noise: float = 0.05  # standard deviation of the distance driven, as a share of it
    route_lead: int = 3  # snapshots ahead of the matched one over which the route's curvature is felt forward
    homing_gain: float = 2.0  # without the route's shape: weight of a fully confident home vector against its direction
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
    rotation: np.ndarray | None = None  # (3, 3) compass R against `rotation_index` in base_link: d_snap = R d_current
    rotation_index: int = -1
    rotation_confident: bool = True  # CompassEstimate.confident: False, the yaw may be a guess
    rotation_confidence: float = 1.0  # CompassEstimate.confidence (0..1)
    home_direction: np.ndarray | None = None  # (3,) unit home vector in base_link
    home_residual: float = 1.0
    home_index: int = -1
    # whether home vectors come at all (something publishes them): a frame without one then had its vector refused by
    # the warping node (a direction the views do not determine: at the snapshot, or too close to tell)
    home_expected: bool = False
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

    def travelled(self, view: View) -> float:
        """Return the distance (m) driven since the last command's frame: odometry, else that command's speed."""
        if view.odometry is not None:
            return view.odometry
        dt = 0.0 if self.stamp is None else min(max((view.stamp - self.stamp) / 1e9, 0.0), MAX_FRAME_GAP)
        return self.command.linear * dt

    def stop(self, stamp: int) -> Command:
        """Return a zero command (a stop is never rate-limited) and remember it."""
        self.command, self.stamp = Command(), stamp
        return Command()


@dataclass(frozen=True)
class TaughtRoute:
    """The taught route's shape: each snapshot's ground position (m) and heading (rad) in the teach's odometry frame."""

    positions: np.ndarray  # (N, 2)
    headings: np.ndarray  # (N,)

    @classmethod
    def from_poses(cls, poses: np.ndarray) -> TaughtRoute | None:
        """Return the route of (N, 7) poses (x, y, z, qx, qy, qz, qw) of base_link; None without two usable poses.

        A snapshot without a pose (NaN, or a zero quaternion: one stored before the first /odom sample, say) takes
        its position interpolated along the snapshot index between its neighbours' and the nearest one's heading.
        """
        poses = np.asarray(poses, float)
        if poses.ndim != 2 or poses.shape[1] != 7:
            return None
        usable = np.all(np.isfinite(poses), axis=1) & (np.linalg.norm(np.nan_to_num(poses[:, 3:]), axis=1) > 0)
        known = np.flatnonzero(usable)
        if len(known) < 2:
            return None
        index = np.arange(len(poses))
        positions = np.column_stack([np.interp(index, known, poses[known, axis]) for axis in (0, 1)])
        x, y, z, w = poses[known, 3:].T
        headings = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        # each snapshot takes the heading of the nearest one with a pose (its own, where it has one)
        after = np.clip(np.searchsorted(known, index), 1, len(known) - 1)
        nearer = np.where(index - known[after - 1] <= known[after] - index, after - 1, after)
        return cls(positions, headings[nearer])

    def __len__(self) -> int:
        return len(self.headings)

    @cached_property
    def along(self) -> np.ndarray:
        """Return each snapshot's distance (m) along the route from the first."""
        return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(self.positions, axis=0), axis=1))])

    @cached_property
    def point_turns(self) -> np.ndarray:
        """Return the point turns (corners where the teach turned in place) as (K, 2) snapshot indices: where each
        begins and ends. A point turn is a run of snapshots each turned by POINT_TURN_STEP or more from the last on
        a radius under POINT_TURN_RADIUS m."""
        steps = np.linalg.norm(np.diff(self.positions, axis=0), axis=1)
        turns = np.abs(wrap_angle(np.diff(self.headings)))
        sharp = np.r_[False, (turns >= POINT_TURN_STEP) & (steps < POINT_TURN_RADIUS * turns), False]
        edges = np.flatnonzero(np.diff(sharp.astype(np.int8)))  # run k of sharp steps: edges[2k]..edges[2k+1]-1
        return edges.reshape(-1, 2)

    def in_point_turn(self, along: float) -> bool:
        """Return whether fractional snapshot index `along` lies within a point turn or on the chord that leaves it."""
        turns = self.point_turns
        k = int(np.searchsorted(turns[:, 0], along, side='right')) - 1  # the last turn that begins at or before it
        return bool(k >= 0 and along < turns[k, 1] + 1)

    def corner_ahead(self, along: float, within: int = CORNER_LOOKAHEAD) -> tuple[int, float] | None:
        """Return the snapshot where the first point turn after fractional snapshot index `along` begins (within
        `within` snapshots) and its distance (m) along the route; None if there is none."""
        starts = self.point_turns[:, 0]
        k = int(np.searchsorted(starts, along, side='right'))
        if k == len(starts) or starts[k] > along + within:
            return None
        before = min(max(int(along), 0), len(self) - 1)  # the place's chord: no work over the whole route per frame
        after = min(before + 1, len(self) - 1)
        here = float(self.along[before] + (along - before) * (self.along[after] - self.along[before]))
        return int(starts[k]), max(float(self.along[starts[k]]) - here, 0.0)

    def curvature(self, origin: int, span: int) -> float:
        """Return the route's mean curvature (1/m, left positive) over `span` snapshots from `origin` on (0 if none)."""
        index = min(origin + max(span, 1), len(self) - 1)
        length = float(self.along[index] - self.along[origin])
        return self.turn(origin, index) / length if length > 1e-9 else 0.0

    def turn(self, origin: int, index: int) -> float:
        """Return how far (rad, left positive) the route's heading at snapshot `index` is turned from `origin`'s."""
        index = min(max(index, 0), len(self) - 1)
        return wrap_angle(float(self.headings[index] - self.headings[origin]))


@dataclass(frozen=True)
class Placement:
    """Where a ground position lies against the taught route: the nearest point of the route and the offset from it."""

    along: float  # the nearest point, as a fractional snapshot index
    offset: float  # m: the signed distance from the route (left positive)
    heading: float  # rad: the route's direction at the nearest point, in the teach's odometry frame


def locate(route: TaughtRoute, position: np.ndarray, near: int) -> Placement:
    """Return where a ground position (m, the teach's odometry frame) lies against the route's polyline, sought
    within LOCATE_WINDOW snapshots of snapshot `near` (so that a route passing close to itself is never confused)."""
    lo = min(max(near - LOCATE_WINDOW, 0), len(route) - 2)
    hi = min(max(near + LOCATE_WINDOW, lo + 1), len(route) - 1)
    start, end = route.positions[lo:hi], route.positions[lo + 1 : hi + 1]
    chord = end - start
    length2 = np.einsum('ij,ij->i', chord, chord)
    share = np.clip(np.einsum('ij,ij->i', position - start, chord) / np.maximum(length2, 1e-12), 0.0, 1.0)
    nearest = start + share[:, None] * chord
    distance = np.linalg.norm(position - nearest, axis=1)
    # at a corner several chords meet in one nearest point: the last of them, the way the route goes on from there
    k = int(np.flatnonzero(distance <= distance.min() + TIES)[-1])
    if length2[k] > 1e-12:
        heading = math.atan2(chord[k, 1], chord[k, 0])
    else:  # the teach stood still between two snapshots: its own heading there
        heading = float(route.headings[lo + k])
    away = position - nearest[k]
    offset = math.cos(heading) * away[1] - math.sin(heading) * away[0]
    return Placement(lo + k + float(share[k]), float(offset), heading)


def ground_direction(angle: float) -> np.ndarray:
    """Return the unit (x, y) vector at ground angle `angle` (rad)."""
    return np.array([math.cos(angle), math.sin(angle)])


@dataclass
class RoutePosition:
    """The robot's ground position (m) in the teach's odometry frame: a Kalman filter of two states.

    The robot's heading in that frame is known from the compass (a snapshot's taught heading plus the compass's
    twist), so each observation is one line the position lies on: a place match puts the robot level with its
    snapshot along the route, a home vector puts its snapshot on the line of sight. Predict: the position moves
    by the distance driven along the heading; its covariance grows by `drift`^2 per metre in every direction and
    by (`scale_noise` * distance)^2 along the heading (wheel slip, odometry's scale).
    """

    position: np.ndarray  # (2,) m
    covariance: np.ndarray  # (2, 2) m^2
    drift: float
    scale_noise: float

    @classmethod
    def at_snapshot(cls, route: TaughtRoute, index: int, drift: float, scale_noise: float) -> RoutePosition:
        """Return a robot placed at snapshot `index` (standard deviations: START_ALONG_SIGMA, START_OFFSET_SIGMA)."""
        along, across = ground_direction(route.headings[index]), ground_direction(route.headings[index] + math.pi / 2)
        covariance = START_ALONG_SIGMA**2 * np.outer(along, along) + START_OFFSET_SIGMA**2 * np.outer(across, across)
        return cls(route.positions[index].copy(), covariance, drift, scale_noise)

    def predict(self, distance: float, heading: float) -> None:
        """Move the position by `distance` m driven at `heading` (rad, the teach's odometry frame)."""
        forward = ground_direction(heading)
        self.position = self.position + distance * forward
        self.covariance = (
            self.covariance
            + self.drift**2 * abs(distance) * np.eye(2)
            + (self.scale_noise * distance) ** 2 * np.outer(forward, forward)
        )

    def correct(self, normal: np.ndarray, value: float, sigma: float, gate: bool = True) -> bool:
        """Pull the position towards the line normal . position = value (m, standard deviation `sigma` m); False if
        `gate` and the line lies further than GATE_SIGMAS standard deviations from the estimate."""
        if not (math.isfinite(value) and math.isfinite(sigma) and sigma > 0):
            return False
        innovation = value - float(normal @ self.position)
        spread = float(normal @ self.covariance @ normal) + sigma**2
        if gate and innovation**2 > GATE_SIGMAS**2 * spread:
            return False
        gain = self.covariance @ normal / spread
        self.position = self.position + gain * innovation
        self.covariance = self.covariance - np.outer(gain, normal @ self.covariance)
        return True

    def observe_match(self, route: TaughtRoute, index: int, sigma: float) -> None:
        """Take a place match at snapshot `index`: the robot is level with it along the route (within `sigma` m)."""
        along = ground_direction(route.headings[index])
        self.correct(along, float(along @ route.positions[index]), sigma, gate=False)

    def observe_home(self, route: TaughtRoute, index: int, bearing: float, sigma: float, confidence: float) -> bool:
        """Take a home vector to snapshot `index` at `bearing` (rad, the teach's odometry frame): the snapshot lies on
        the line of sight, to within `sigma` rad times its distance over the root of `confidence` in (0, 1]; False
        if it was not taken (no confidence, the snapshot behind the line of sight, or gated out)."""
        sight = route.positions[index] - self.position
        if confidence <= 0 or float(sight @ ground_direction(bearing)) <= 0:
            return False
        normal = ground_direction(bearing + math.pi / 2)
        distance = max(float(np.linalg.norm(sight)), MIN_SIGHT)
        return self.correct(normal, float(normal @ route.positions[index]), sigma * distance / math.sqrt(confidence))


class RouteFollower:
    """Drives along a taught route from `start_index` (or wherever the robot is matched) to `end_index`."""

    def __init__(
        self, start_index: int, end_index: int, limits: Limits, settings: Settings, route: TaughtRoute | None = None
    ) -> None:
        """Follow snapshots start_index..end_index (start -1: the first accepted match places the robot) of a route
        whose shape is `route` (None: unknown)."""
        self.start_index, self.end_index = start_index, end_index
        self.limits, self.settings, self.route = limits, settings, route
        self.position: RoutePosition | None = None  # where the robot is, once it was placed and had a compass
        self.heading = 0.0  # rad: its last heading by the compass, in the teach's odometry frame
        self.nearest = 0  # the snapshot nearest to it
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
        if matched and view.rotation is not None and self._rotation_usable(view):
            self.unsure, self.recovered_distance, self.state = 0, 0.0, FOLLOWING
            desired = self._steer(view, confidence)
            return self._answer(self._motion.limited(desired, view.stamp, self.limits), view)
        # unsure: creep straight on for a while, as a driver would, then give up
        self.unsure += 1
        self.recovered_distance += view.odometry or 0.0
        if self.position is not None:  # the robot creeps straight on: carry its position on along its last heading
            self.position.predict(self._motion.travelled(view), self.heading)
        if self.unsure > self.settings.lost_frames or self.recovered_distance > self.settings.recover_distance:
            self.state = STOPPING
            return self._answer(self._motion.stop(view.stamp), view, LOST)
        self.state = RECOVERING
        desired = Command(self.settings.recover_speed * self.limits.max_speed, 0.0)
        return self._answer(self._motion.limited(desired, view.stamp, self.limits), view)

    def _rotation_usable(self, view: View) -> bool:
        """Return whether the frame's compass rotation may be steered on: confident, or agreeing within
        COMPASS_AGREEMENT_DEG with the predicted heading or with the home vector's."""
        if view.rotation_confident:
            return True
        assert view.rotation is not None
        bound = math.radians(COMPASS_AGREEMENT_DEG)
        home = view.home_direction
        home_usable = home is not None and view.home_residual <= self.settings.unsure_residual
        route, origin = self.route, view.rotation_index
        if route is None or len(route) < 2 or not 0 <= origin < len(route):
            # without the route's shape: the route's direction here against the home vector to a snapshot ahead
            if not home_usable:
                return False
            assert home is not None
            return abs(wrap_angle(ground_angle(route_direction(view.rotation)) - ground_angle(home))) <= bound
        heading = float(route.headings[origin] + yaw(view.rotation))  # by this compass, the teach's odometry frame
        if self.position is not None:  # the heading predicted from the last one and the last command's turn
            dt = (
                0.0
                if self._motion.stamp is None
                else min(max((view.stamp - self._motion.stamp) / 1e9, 0.0), MAX_FRAME_GAP)
            )
            if abs(wrap_angle(heading - (self.heading + self._motion.command.angular * dt))) <= bound:
                return True
        if home_usable and 0 <= view.home_index < len(route):
            assert home is not None
            here = self.position.position if self.position is not None else route.positions[origin]
            sight = route.positions[view.home_index] - here
            if float(np.linalg.norm(sight)) >= MIN_SIGHT:  # the heading under which the home vector sees its snapshot
                implied = math.atan2(sight[1], sight[0]) - ground_angle(home)
                return abs(wrap_angle(heading - implied)) <= bound
        return False

    def _steer(self, view: View, confidence: float) -> Command:
        """Return the command of a frame with a compass estimate: by the cross-track offset where the route's shape
        is known, else along the route's direction pulled towards the home vector."""
        assert view.rotation is not None
        origin = view.rotation_index
        if self.route is None or len(self.route) < 2 or not 0 <= origin < len(self.route):
            direction = route_direction(view.rotation)
            angle = steering_angle(direction, view.home_direction, confidence, self.settings.homing_gain)
            return pursue(angle, self.limits.max_speed, self.limits, self.settings)
        settings, route = self.settings, self.route
        heading = self.heading = float(route.headings[origin] + yaw(view.rotation))  # the teach's odometry frame
        if self.position is None:
            self.position = RoutePosition.at_snapshot(route, origin, settings.odometry_drift, settings.odometry_noise)
            self.nearest = origin
        else:
            self.position.predict(self._motion.travelled(view), heading)
        if 0 <= view.match_index < len(route):
            self.position.observe_match(route, view.match_index, settings.match_noise)
        if view.home_direction is not None and 0 <= view.home_index < len(route):
            bearing = heading + ground_angle(view.home_direction)
            self.position.observe_home(route, view.home_index, bearing, settings.bearing_noise, confidence)
        place = locate(route, self.position.position, self.nearest)
        self.nearest = round(place.along)
        relative = wrap_angle(heading - place.heading)  # the robot's heading from the route's (rad)
        error = wrap_angle(-math.atan2(place.offset, settings.approach) - relative)
        command = pursue(error, self.limits.max_speed, self.limits, settings)
        if abs(error) > IN_PLACE_ERROR and route.in_point_turn(place.along):  # the route turns here: so does the robot
            command.linear = 0.0
        lead, corner = settings.route_lead, route.corner_ahead(place.along)
        if corner is not None:
            # a point turn ahead: arrive there slow enough to stop on it, and feel no curvature forward across it (the
            # robot turns where the route does, in place, rather than cutting the corner)
            lead = min(lead, corner[0] - int(place.along))
            command.linear = min(command.linear, math.sqrt(2 * self.limits.max_acceleration * corner[1]))
        if lead > 0:
            command.angular += command.linear * route.curvature(int(place.along), lead)
        return command

    def _answer(self, command: Command, view: View, outcome: str = GOING) -> Step:
        sure = view.home_direction is not None and not self.unsure
        confidence = float(np.clip(1.0 - view.home_residual, 0.0, 1.0)) if sure else 0.0
        if sure and view.rotation is not None and not view.rotation_confident:  # steered on an agreeing guess
            compass = view.rotation_confidence if math.isfinite(view.rotation_confidence) else 0.0
            confidence = min(confidence, max(0.0, compass))
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
        self.heard = False  # whether a home vector to this snapshot has come during the goal
        self._motion = _Motion()

    def _refusal_credible(self, view: View) -> bool:
        """Return whether a frame without a home vector may be a refusal near home: home vectors to this snapshot
        came before (the warping node serves this goal), or the frame's accepted place match lies within
        ARRIVAL_MATCH_SNAPSHOTS of it. A warping node that rejects every view (a wrong SH degree, say) is otherwise
        silent in the same way, and would let the robot report arriving where it stands."""
        near = view.match_accepted and abs(view.match_index - self.index) <= ARRIVAL_MATCH_SNAPSHOTS
        return self.heard or near

    def step(self, view: View) -> Step:
        """Return the command for one frame."""
        if view.home_direction is None and view.home_expected and self._refusal_credible(view):
            # the warping node refused this frame's home vector: the views do not determine a direction (at the
            # snapshot, or too close to tell), as an unsure vector says
            self.missing = 0
            return self._unsure(view, 0.0)
        if view.home_direction is None or view.home_index != self.index:
            self.missing += 1
            outcome = LOST if self.missing > self.settings.lost_frames else GOING
            return Step(self._motion.stop(view.stamp), RECOVERING if not outcome else STOPPING, outcome)
        self.missing, self.heard = 0, True
        confidence = float(np.clip(1.0 - view.home_residual, 0.0, 1.0))
        if view.home_residual > self.settings.unsure_residual:
            return self._unsure(view, confidence)
        self.unsure, self.crept = 0, 0.0
        error = ground_angle(view.home_direction)
        if self.driving and abs(error) > math.pi / 2:  # it points back: home was passed
            self.speed_share = max(self.speed_share / 2, self.settings.min_speed_share)
            self.driving = False
        desired = pursue(error, self.speed_share * self.limits.max_speed, self.limits, self.settings)
        command = self._motion.limited(desired, view.stamp, self.limits)
        self.driving = self.driving or command.linear > 0.0
        return Step(command, FOLLOWING, confidence=confidence)

    def _unsure(self, view: View, confidence: float) -> Step:
        """Return the command of a frame without a confident home vector: arrived after `arrived_frames` of them in a
        row (once crept `arrive_creep` m, if the robot drove), until then straight on along the last course."""
        self.unsure += 1
        if self.unsure > 1:  # travel since the first unsure frame: odometry, else the last command
            self.crept += self._motion.travelled(view)
        crept_enough = self.crept >= self.settings.arrive_creep or not self.driving
        if self.unsure >= self.settings.arrived_frames and crept_enough:
            return Step(self._motion.stop(view.stamp), STOPPING, REACHED, confidence=confidence)
        # unsure near home: keep the last confident course straight on (never steer on a guess), then stop
        desired = Command(self.speed_share * self.limits.max_speed if self.driving else 0.0, 0.0)
        return Step(self._motion.limited(desired, view.stamp, self.limits), RECOVERING, confidence=confidence)
