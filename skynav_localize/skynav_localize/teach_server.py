# SPDX-License-Identifier: Apache-2.0
"""The Teach action server, /skynav/teach (docs/interfaces.md, "Driving: teach, follow, home"), hosted by the
localize node: the rclpy glue around a RouteTeacher (teaching, the logic).

A goal runs until it is canceled (the usual end, with success), until the odometry says `max_length` m were driven
(success), or until no usable view arrived for `teach_input_timeout` s of the node's time (sim time in the
simulator's in-process graph; the clock's jumps left out, SkynavNode.elapsed_ns: a goal sent before the first /clock
waits for it) with NO_INPUT, the map keeping what was stored. Its first feedback (0 snapshots) says
teaching has begun. The localize node hands it every view it takes and every /odom message (on_odometry). When the
goal ends the map is closed into one file and the nodes switch to it: the localize node itself and those of
`teach_map_nodes` (their `map` parameter is set through their parameter services: skynav_core.peers), before the
result is sent. One goal at a time: a second one ends at once with BUSY. A goal canceled before its execution began
ends at once, canceled, without a map (a client cancels a goal whose answer it did not get: skynav_core.goals).

A robot without wheel odometry still leaves its route's shape in the map: the node hands the server every
velocity command on /cmd_vel too (on_command: the operator's teleoperation while teaching), and the teacher dead
reckons from them (skynav_localize.teaching.CommandedMotion).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.action import ActionServer, CancelResponse
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future

from skynav_core.images import stamp_ns
from skynav_core.names import TEACH_ACTION
from skynav_core.namespaces import relative
from skynav_core.node import SkynavNode
from skynav_core.peers import NOT_FOUND, PeerParameters
from skynav_msgs.action import Teach

from .teaching import NoInput, RouteTeacher, TeachError

# Best effort matches any odometry publisher; a deep queue, as odometry comes at up to 100 Hz in bursts.
ODOM_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.BEST_EFFORT)
COMMAND_QOS = ODOM_QOS  # best effort takes any teleoperation's commands, reliable or not
INPUT_CHECK_PERIOD = 0.25  # s between checks for missing views
SWITCH_TIMEOUT = 5.0  # s a node gets to take the new map


@dataclass
class ActiveGoal:
    """The goal being taught."""

    handle: Any  # rclpy ServerGoalHandle
    teacher: RouteTeacher
    done: Future  # its result: 'canceled', 'max_length' or a TeachError
    last_view_ns: int  # the node's elapsed time (SkynavNode.elapsed_ns) at the last usable view (or the start)


def odometry_pose(message: Odometry) -> np.ndarray:
    """Return (x, y, z, qx, qy, qz, qw) of base_link in odom (m) from an Odometry message."""
    p, q = message.pose.pose.position, message.pose.pose.orientation
    return np.array([p.x, p.y, p.z, q.x, q.y, q.z, q.w])


def map_parameters(path: str) -> list[tuple[str, str]]:
    """Return the `map` settings, in order, that make a node (re)load the map at `path`: none first, so a rewritten
    file loads."""
    return [('map', ''), ('map', path)]


class TeachServer:
    """Serves /skynav/teach for a node that hands it every usable view (on_view)."""

    def __init__(self, node: SkynavNode) -> None:
        self.node = node
        self.active: ActiveGoal | None = None
        self.settings: dict[str, Any] = {}
        self.peers = PeerParameters(node)
        self.server = ActionServer(
            node, Teach, relative(TEACH_ACTION), execute_callback=self.execute, cancel_callback=self.on_cancel
        )
        node.create_timer(INPUT_CHECK_PERIOD, self.check_input)

    def configure(self, values: dict[str, Any]) -> None:
        """Take the node's teach_* parameters (ValueError if unusable)."""
        if not (values['teach_spacing'] > 0 and values['teach_view_change'] > 0 and values['teach_input_timeout'] > 0):
            raise ValueError('teach_spacing, teach_view_change and teach_input_timeout must be positive')
        if not values['odometry_tolerance'] >= 0:
            raise ValueError('odometry_tolerance must be at least 0')
        self.settings = values
        for name in values['teach_map_nodes']:
            if name:
                self.peers.client(name)  # found long before a teach ends

    # --- inputs -----------------------------------------------------------------------------------------------

    def on_view(self, stamp: int, coefficients: np.ndarray) -> None:
        """Offer one usable view (stamp in ns, SH coefficients) to the goal being taught, if any."""
        goal = self.active
        if goal is None or goal.done.done():
            return
        goal.last_view_ns = self.node.elapsed_ns()
        try:
            stored = goal.teacher.offer(stamp, coefficients)
        except ValueError as exc:
            self.node.reject('teach_degree', str(exc))
            return
        except TeachError as exc:
            goal.done.set_result(exc)
            return
        if stored:
            goal.handle.publish_feedback(
                Teach.Feedback(snapshots=goal.teacher.snapshots, route_length=goal.teacher.route_length)
            )
        if goal.teacher.finished:
            goal.done.set_result('max_length')

    def on_odometry(self, message: Odometry) -> None:
        """Take one odometry sample for the goal being taught (ignored without one)."""
        if self.active is not None:
            self.active.teacher.add_odometry(stamp_ns(message.header), odometry_pose(message))

    def on_command(self, message: TwistStamped) -> None:
        """Take one velocity command for the goal being taught (stamp 0, as some teleoperation sends: the node's
        time); a non-finite command is counted and ignored."""
        if self.active is None:
            return
        self.take_command(stamp_ns(message.header) or self.node.now_ns(), message.twist)

    def on_twist(self, message: Twist) -> None:
        """Take one unstamped velocity command (cmd_vel_stamped false) for the goal being taught, at the node's time."""
        if self.active is not None:
            self.take_command(self.node.now_ns(), message)

    def take_command(self, stamp: int, twist: Twist) -> None:
        """Hand the teacher a command stamped `stamp` (ns); a non-finite or old one is counted and ignored."""
        assert self.active is not None  # the callers look first
        if not self.active.teacher.add_command(stamp, twist.linear.x, twist.angular.z):
            self.node.reject('command', 'a /cmd_vel command is not finite or not newer than the last one')

    def check_input(self) -> None:
        """End the goal with NO_INPUT when no usable view arrived for teach_input_timeout s of the node's clock
        (its jumps left out: a goal sent before the first /clock waits for the clock)."""
        goal = self.active
        if goal is None or goal.done.done():
            return
        silence = (self.node.elapsed_ns() - goal.last_view_ns) * 1e-9
        if silence > self.settings['teach_input_timeout']:
            goal.done.set_result(NoInput(f'no usable view on /skyline/sh for {silence:.1f} s'))

    # --- the goal -------------------------------------------------------------------------------------------

    def on_cancel(self, goal_handle: Any) -> CancelResponse:
        """Accept a cancel: the goal finishes its map (the usual end of teaching)."""
        goal = self.active
        if goal is not None and goal.handle is goal_handle and not goal.done.done():
            goal.done.set_result('canceled')
        return CancelResponse.ACCEPT

    async def execute(self, goal_handle: Any) -> Teach.Result:
        """Teach one goal until it ends (see the module notes) and return its result."""
        request = goal_handle.request
        if self.active is not None:
            goal_handle.abort()
            return self.result('BUSY', f'another Teach goal is running (writing {self.active.teacher.path})')
        if goal_handle.is_cancel_requested:  # canceled before its execution began, when on_cancel found no goal
            goal_handle.canceled()
            return self.result('NONE', 'canceled before teaching began: no map was written')
        # <= 0: the node's default (spacing) or no limit (max_length); NaN is passed on, to be refused as BAD_GOAL
        spacing = request.spacing if not request.spacing <= 0 else self.settings['teach_spacing']
        max_length = request.max_length if not request.max_length <= 0 else 0.0
        try:
            teacher = RouteTeacher(
                request.map_path,
                request.map_name,
                spacing=spacing,
                max_length=max_length,
                overwrite=request.overwrite,
                change_per_metre=self.settings['teach_view_change'],
                odometry_tolerance_ns=int(self.settings['odometry_tolerance'] * 1e9),
            )
        except TeachError as exc:
            goal_handle.abort()
            return self.result(exc.code, str(exc))
        log = self.node.get_logger()
        log.info(f'teaching {teacher.path}: a snapshot every {spacing:g} m')
        self.active = ActiveGoal(goal_handle, teacher, Future(), self.node.elapsed_ns())
        goal_handle.publish_feedback(Teach.Feedback(snapshots=0, route_length=0.0))  # teaching has begun
        outcome = await self.active.done
        self.active = None
        error = outcome if isinstance(outcome, TeachError) else None
        try:
            path = teacher.finish()
        except TeachError as exc:
            error, path = exc, None
        length = f'{teacher.route_length:.2f} m by {teacher.length_source}'
        summary = f'{teacher.snapshots} snapshots, ' + ('route length unknown' if teacher.route_length <= 0 else length)
        if path is not None and error is None:
            await self.switch_maps(str(path))
        result = self.result(error.code if error else 'NONE', str(error) if error else '', teacher)
        if error is not None:
            log.error(f'teaching {teacher.path} ended with {error.code}: {error} ({summary})')
            goal_handle.abort()
        elif outcome == 'canceled':
            log.info(f'taught {teacher.path} (canceled, the usual end): {summary}')
            goal_handle.canceled()
        else:
            log.info(f'taught {teacher.path} ({max_length:g} m reached): {summary}')
            goal_handle.succeed()
        return result

    @staticmethod
    def result(code: str, message: str = '', teacher: RouteTeacher | None = None) -> Teach.Result:
        """Return a Teach result with the error code named `code` and the teacher's figures."""
        result = Teach.Result(error_code=getattr(Teach.Result, code), error_msg=message)
        if teacher is not None:
            result.snapshots, result.route_length = teacher.snapshots, teacher.route_length
        return result

    async def switch_maps(self, path: str) -> None:
        """Make this node and those of teach_map_nodes use the map at `path`; log those that did not."""
        results = self.node.set_parameters([Parameter(name, value=value) for name, value in map_parameters(path)])
        if not results[-1].successful:
            self.node.get_logger().error(f'cannot use the taught map {path}: {results[-1].reason}')
        settings = {name: map_parameters(path) for name in self.settings['teach_map_nodes'] if name}
        failures = await self.peers.set(settings, SWITCH_TIMEOUT, discovery=0.0, atomically=False)
        for name, reason in failures.items():
            if reason == NOT_FOUND:  # not found by now: not running
                self.node.get_logger().warning(f'node {name} is not running: it keeps its map')
            else:
                self.node.get_logger().error(f'node {name} did not take the taught map {path}: {reason}')

    def close(self) -> None:
        """Close the map of a goal still being taught (the node shuts down): it keeps every snapshot stored."""
        if self.active is not None:
            try:
                self.active.teacher.finish()
            except TeachError as exc:
                self.node.get_logger().error(str(exc))
