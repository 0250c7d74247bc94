# SPDX-License-Identifier: Apache-2.0
"""FollowRoute and Home goals: their maps, which requests are refused, how each is driven (its controller, the other
nodes' goal context, its time limit), feedback and results.

A goal's time limit grows with the distance it drives: `goal_timeout` s plus `goal_time_factor` times the time the
distance takes at the goal's speed limit. A follow goal's distance is the route's between its start (the first
snapshot, when localization places the robot) and its end, from the map (RouteLength: the teach's odometry, else
its velocity commands, else the snapshots times the teach's spacing, else times UNKNOWN_SPACING); a Home goal's is
the parameter `home_distance`, the farthest homing is expected to drive.

No rclpy: the route node (skynav_route.node) serves the actions with these and drives with skynav_route.controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from skynav_core.maps import MapError, MapStore
from skynav_msgs.action import FollowRoute, Home

from .context import GoalContext
from .controller import LOCALIZING, LOST, Homer, RouteFollower, Step, TaughtRoute
from .parameters import limits

# how a goal ends besides the controller's REACHED and LOST
CANCELED, STALE, TIMED_OUT, SHUTDOWN, BLOCKED = 'canceled', 'stale', 'timeout', 'shutdown', 'blocked'
EMERGENCY = 'emergency stop'

Refusal = tuple[int, str]  # a Result error code and its text
MIN_SHAPE_LENGTH = 0.1  # m: a route shape by commands shorter than this had none (the robot was not driven by /cmd_vel)
# m between snapshots assumed for a goal's time limit when the map records no odometry, commands or spacing: ten
# times the default spacing of `skynav teach` and `skynav map build` (0.1 m), as the limit is a backstop that must not
# end a goal still driving (the watchdog and LOST stop a goal that cannot go on)
UNKNOWN_SPACING = 1.0
MAX_COMMAND_INTERVAL = 1.0  # s: the longest a command counts for in the distance driven without /odom
SPACING_META = 'spacing_m'  # map metadata: the teach's spacing (m), as `skynav teach` writes it


@dataclass(frozen=True)
class RouteLength:
    """Where a map's snapshots lie along its route (m from the first) and how that is known."""

    along: np.ndarray  # (N,) m from the first snapshot
    source: str  # how the distances were found, for the TIMEOUT text

    def between(self, first: int, last: int) -> float:
        """Return the route's length (m) from snapshot `first` to snapshot `last`."""
        return float(abs(self.along[last] - self.along[first]))


def _pose_steps(poses: np.ndarray | None) -> np.ndarray | None:
    """Return the distances (m) between consecutive poses (N, 7); None without poses, with a non-finite one, or when
    they never moved (MIN_SHAPE_LENGTH in all)."""
    if poses is None or len(poses) < 2:
        return None
    steps = np.linalg.norm(np.diff(np.asarray(poses, float)[:, :3], axis=0), axis=1)
    if not np.all(np.isfinite(steps)) or float(np.sum(steps)) < MIN_SHAPE_LENGTH:
        return None
    return steps


def route_length(
    count: int, odometry: np.ndarray | None, commanded: np.ndarray | None, meta: dict[str, str]
) -> RouteLength:
    """Return where the `count` snapshots of a map lie along its route: by the teach's odometry poses, else its poses
    by the velocity commands ((N, 7) each, None if the map has none), else the teach's spacing in the map's `meta`
    (SPACING_META), else UNKNOWN_SPACING apart."""
    for poses, source in ((odometry, "the teach's odometry"), (commanded, "the teach's velocity commands")):
        steps = _pose_steps(poses)
        if steps is not None and len(steps) == count - 1:
            return RouteLength(np.concatenate([[0.0], np.cumsum(steps)]), f'by {source}')
    try:
        spacing = float(meta.get(SPACING_META, 'nan'))
    except ValueError:
        spacing = math.nan
    if math.isfinite(spacing) and spacing > 0:
        source = f"snapshots {spacing:g} m apart (the teach's spacing)"
    else:
        spacing = UNKNOWN_SPACING
        source = f'snapshots taken as {spacing:g} m apart (the map records no odometry, commands or spacing)'
    return RouteLength(spacing * np.arange(max(count, 1), dtype=float), source)


@dataclass(frozen=True)
class TimeLimit:
    """A goal's time limit: `fixed` s plus `factor` times the time `distance` m takes at `speed` m/s."""

    fixed: float  # s (the parameter goal_timeout)
    factor: float  # (the parameter goal_time_factor)
    distance: float  # m the goal is to drive
    speed: float  # m/s, the goal's speed limit
    source: str  # how the distance was found

    @property
    def seconds(self) -> float:
        """Return the limit (s)."""
        return self.fixed + self.factor * self.distance / self.speed

    def describe(self) -> str:
        """Return the limit and how it was computed, for the TIMEOUT text."""
        return (
            f'{self.seconds:.1f} s: goal_timeout {self.fixed:g} s + goal_time_factor {self.factor:g} x '
            f'{self.distance:.1f} m ({self.source}) at {self.speed:g} m/s'
        )


def follow_time_limit(
    length: RouteLength, start_index: int, end: int, speed: float, fixed: float, factor: float
) -> TimeLimit:
    """Return the time limit of a follow goal from `start_index` (-1: wherever it is placed, at worst the first
    snapshot) to `end` at `speed` m/s."""
    distance = length.between(max(start_index, 0), end)
    return TimeLimit(
        fixed, factor, distance, speed, f'the route from snapshot {max(start_index, 0)} to {end}, {length.source}'
    )


def home_time_limit(home_distance: float, speed: float, fixed: float, factor: float) -> TimeLimit:
    """Return the time limit of a Home goal: it may drive `home_distance` m at `speed` m/s."""
    return TimeLimit(fixed, factor, home_distance, speed, 'home_distance')


def route_shape(odometry: np.ndarray | None, commanded: np.ndarray | None) -> tuple[TaughtRoute | None, str]:
    """Return the taught route's shape and what it comes from: the teach's odometry poses, else its poses by the
    velocity commands ((N, 7) each, None if the map has none), else nothing (None, 'nothing')."""
    route = TaughtRoute.from_poses(odometry) if odometry is not None else None
    if route is not None:
        return route, 'odometry'
    route = TaughtRoute.from_poses(commanded) if commanded is not None else None
    if route is not None and np.sum(np.linalg.norm(np.diff(route.positions, axis=0), axis=1)) >= MIN_SHAPE_LENGTH:
        return route, 'commands'
    return None, 'nothing'


def follow_end(request: FollowRoute.Goal, count: int) -> int:
    """Return the snapshot index a FollowRoute request ends at on a map of `count` snapshots (-1: the last)."""
    return count - 1 if request.end_index < 0 else int(request.end_index)


def follow_refusal(request: FollowRoute.Goal, count: int) -> Refusal | None:
    """Return why a FollowRoute request on a map of `count` snapshots is refused, or None to drive it."""
    codes, end = FollowRoute.Result, follow_end(request, count)
    if not math.isfinite(request.max_speed):
        return codes.BAD_GOAL, 'max_speed is not finite'
    if not (-1 <= request.start_index < count and 0 <= end < count):
        return codes.BAD_INDEX, f'the map has snapshots 0..{count - 1}: no such index'
    if request.start_index > end:
        return codes.BAD_INDEX, 'start_index lies beyond end_index'
    return None


def home_refusal(request: Home.Goal, count: int) -> Refusal | None:
    """Return why a Home request on a map of `count` snapshots is refused, or None to drive it."""
    codes = Home.Result
    if not math.isfinite(request.max_speed):
        return codes.BAD_GOAL, 'max_speed is not finite'
    if not 0 <= request.index < count:
        return codes.BAD_INDEX, f'no snapshot {request.index}: the map has snapshots 0..{count - 1}'
    return None


@dataclass(frozen=True)
class RouteMap:
    """A goal's map as the route node drives it: its snapshots, the route's shape and where they lie along it."""

    path: str
    count: int  # snapshots
    route: TaughtRoute | None  # the route's shape (route_shape); None: steering on the home vectors alone
    shape_source: str  # 'odometry', 'commands' or 'nothing'
    length: RouteLength

    def other_than(self, node_map: str) -> str:
        """Return this map's path if it is not `node_map` (the route node's own), else '' (GoalContext.map_path)."""
        return self.path if self.path != node_map else ''


def open_route_map(goal_map: str, node_map: str) -> RouteMap:
    """Return the map a goal drives on: the goal's `map_path`, else the route node's `map`; raise MapError."""
    path = goal_map or node_map
    if not path:
        raise MapError('no map: the goal names none and the route node has no `map` parameter')
    with MapStore.open(path) as store:
        count, odometry, commanded = len(store), store.odometry_poses(), store.commanded_poses()
        route, source = route_shape(odometry, commanded)
        length = route_length(count, odometry, commanded, store.meta)
    return RouteMap(str(path), count, route, source, length)


@dataclass(frozen=True)
class GoalPlan:
    """How one accepted goal is driven."""

    route_map: RouteMap
    controller: RouteFollower | Homer
    context: GoalContext  # what localize, compass and warping compare against meanwhile
    time_limit: TimeLimit
    end: int  # the snapshot it ends at (a Home goal's index)


def plan_follow(request: FollowRoute.Goal, route_map: RouteMap, values: dict, settings: Any) -> GoalPlan | Refusal:
    """Return how a FollowRoute request is driven with the route node's parameter `values` and controller
    `settings`, or why it is refused."""
    refusal = follow_refusal(request, route_map.count)
    if refusal is not None:
        return refusal
    end, goal_limits = follow_end(request, route_map.count), limits(values, request.max_speed)
    controller = RouteFollower(request.start_index, end, goal_limits, settings, route_map.route)
    context = GoalContext.follow(values['lookahead'], request.start_index, route_map.other_than(values['map']))
    time_limit = follow_time_limit(
        route_map.length,
        request.start_index,
        end,
        goal_limits.max_speed,
        values['goal_timeout'],
        values['goal_time_factor'],
    )
    return GoalPlan(route_map, controller, context, time_limit, end)


def plan_home(request: Home.Goal, route_map: RouteMap, values: dict, settings: Any) -> GoalPlan | Refusal:
    """Return how a Home request is driven with the route node's parameter `values` and controller `settings`, or
    why it is refused."""
    refusal = home_refusal(request, route_map.count)
    if refusal is not None:
        return refusal
    goal_limits = limits(values, request.max_speed)
    controller = Homer(request.index, goal_limits, settings)
    context = GoalContext.home(request.index, route_map.other_than(values['map']))
    time_limit = home_time_limit(
        values['home_distance'], goal_limits.max_speed, values['goal_timeout'], values['goal_time_factor']
    )
    return GoalPlan(route_map, controller, context, time_limit, request.index)


@dataclass
class ActiveGoal:
    """The goal being driven: its handle, how it is driven, how it ends and what it did so far."""

    kind: Any  # the action FollowRoute or Home
    handle: Any  # rclpy ServerGoalHandle
    plan: GoalPlan
    done: Any  # rclpy Future, given the outcome when the goal ends
    started: int | None = None  # ns of elapsed time (the node's, its clock's jumps left out) at the goal's start
    last_frame: int | None = None  # ns of elapsed time the last frame was processed (or the start)
    stop_reason: str | None = None  # why an emergency stop ended it
    driven: float = 0.0  # m
    reached_index: int = -1
    steps: int = 0
    confidence: float = 0.0

    def record(self, step: Step, odometry: float | None, stamp: int, previous: int, now: int) -> None:
        """Count one answered frame: `odometry` m driven since the last (None: by the commands), its `stamp` and
        the `previous` one's (ns; -1 none), `now` in elapsed ns."""
        self.last_frame = now
        self.started = now if self.started is None else self.started
        self.steps += 1
        self.confidence = step.confidence
        if odometry is not None:
            self.driven += odometry
        elif previous >= 0:
            self.driven += abs(step.command.linear) * min((stamp - previous) / 1e9, MAX_COMMAND_INTERVAL)
        self.reached_index = max(self.reached_index, step.matched_index)


def first_feedback(kind: Any) -> Any:
    """Return the feedback that tells a client the graph is set up for its goal, before any frame is answered."""
    if kind is FollowRoute:
        return FollowRoute.Feedback(matched_index=-1, target_index=-1, state=LOCALIZING)
    return Home.Feedback(confidence=0.0, steps=0)


def step_feedback(goal: ActiveGoal, step: Step) -> Any:
    """Return the feedback of one answered frame."""
    if goal.kind is FollowRoute:
        return FollowRoute.Feedback(
            matched_index=step.matched_index,
            target_index=step.target_index,
            progress=step.progress,
            confidence=step.confidence,
            state=step.state,
        )
    return Home.Feedback(confidence=step.confidence, steps=goal.steps)


def unplaced(matched: int, start_index: int) -> str | None:
    """Return the LOST text of a follow goal that never placed a view on the route (None if one was placed)."""
    if matched >= 0:
        return None
    text = 'lost: no view was placed on the route, the robot never moved'
    if start_index < 0:
        text += ' (where it stands at a known snapshot, give it as start_index: skynav follow --from I)'
    return text


def failure(
    outcome: str,
    codes: Any,
    input_timeout: float,
    time_limit: TimeLimit,
    lost: str | None = None,
    stop_reason: str | None = None,
) -> Refusal:
    """Return the Result error code and text of a goal that ended by `outcome` (not reached, not canceled); `lost`:
    the text of LOST if not the usual one, `stop_reason`: what engaged the emergency stop."""
    texts = {
        LOST: (codes.LOST, lost or 'lost: too many unaccepted or unsure frames in a row, recovery failed'),
        STALE: (codes.STALE_INPUT, f'no usable frame for {input_timeout} s'),
        TIMED_OUT: (codes.TIMEOUT, f'the goal ran longer than its time limit of {time_limit.describe()}'),
        SHUTDOWN: (codes.LOST, 'the route node shut down'),
        BLOCKED: (codes.BLOCKED, 'blocked: the bumper reported contact (skynav does not drive around objects)'),
        EMERGENCY: (codes.EMERGENCY_STOP, f'emergency stop: {stop_reason or EMERGENCY_INPUT}; the robot stopped'),
    }
    return texts[outcome]


EMERGENCY_INPUT = 'the emergency stop input is true'  # the reason of an emergency stop by its input


def emergency_refusal(reasons: str) -> str:
    """Return why a goal that comes while the emergency stop is engaged (for `reasons`) is refused."""
    return f'emergency stop engaged ({reasons}): no goal drives until it is released'
