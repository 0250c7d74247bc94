# SPDX-License-Identifier: Apache-2.0
"""The route node: serves /skynav/follow_route and /skynav/home and drives the robot through /cmd_vel.

Subscribes /skyline/sh (the frame clock), /localization/match, /compass/orientation, /homing/home_vector and, when a
robot has them, /odom, /bumper (std_msgs/Bool, true on contact: the goal stops and aborts with BLOCKED, as skynav
does not drive around objects), /emergency_stop (std_msgs/Bool, skynav_route.safety) and /tf_static (base_link ->
camera_link, over the parameter camera_mount_rpy_deg: the compass rotation and home vector are turned into
base_link, skynav_route.inputs); publishes /cmd_vel (geometry_msgs/TwistStamped in base_link; a bare
geometry_msgs/Twist with `cmd_vel_stamped` false, for bases that take that) as docs/interfaces.md ("Driving", "On a
robot") says: while a goal is active, exactly one command per camera frame it processes, stamped with that frame's
stamp; a zero command whenever it stops (goal reached, canceled, aborted, lost, blocked, emergency stop, stale
inputs, shutdown); nothing while idle. It never reads /ground_truth/*. Every name is relative to the node's
namespace (`-r __ns:=/robot1` serves /robot1/skynav/follow_route and publishes /robot1/cmd_vel); /cmd_vel is
remapped as any topic (`-r cmd_vel:=/base/cmd_vel`).

A frame is processed when its home vector comes, or, when none comes, once a view `frame_wait` s newer arrives
(skynav_route.frames); the command comes from skynav_route.controller. The emergency stop, the IMU's tilt and the
bumper stop a goal whatever it commands (skynav_route.safety). For each goal the node sets the compass, warping and
localize nodes' parameters (skynav_route.peers).

The watchdog (a timer live, /clock in the in-process graph) stops the robot and aborts with STALE_INPUT when no
frame was processed for `input_timeout` s, and with TIMEOUT when the goal ran longer than its time limit:
`goal_timeout` s plus `goal_time_factor` times the time its distance takes at its speed limit (skynav_route.goals:
the route's length from the map, `home_distance` for a Home goal). Both measure `elapsed_ns()`, the time passed on
the node's clock with its jumps left out, so a clock that starts late (sim time before the first /clock) or jumps
(a recording replayed with its own clock) fires neither (frame inputs whose stamps jump back restart the frames'
time: skynav_route.frames). A goal canceled before its execution began never drives (a client cancels a goal whose
answer it did not get: skynav_core.goals).
"""

from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.action import ActionServer, CancelResponse
from rclpy.task import Future
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu
from std_msgs.msg import Bool

from skynav_core.actions import error_name
from skynav_core.maps import MapError, MapStore
from skynav_core.motion import fill_twist, fill_velocity_command
from skynav_core.mount import frame_name
from skynav_core.names import (
    BASE_FRAME,
    BUMPER,
    CLOCK,
    CMD_VEL,
    COMPASS_ORIENTATION,
    EMERGENCY_STOP,
    FOLLOW_ROUTE_ACTION,
    HOME_ACTION,
    HOME_VECTOR,
    IMU,
    LOCALIZATION_MATCH,
    ODOM,
    ROUTE_NODE,
    SKYLINE_SH,
    TF_STATIC,
)
from skynav_core.namespaces import relative
from skynav_core.node import SkynavNode
from skynav_core.ros import run_node
from skynav_core.route_progress import ProgressError, RouteProgress, now, write_progress
from skynav_msgs.action import FollowRoute, Home
from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch, ShCoefficients

from . import goals
from .controller import REACHED, Command, Homer, RouteFollower, TaughtRoute
from .frames import Frames
from .goals import BLOCKED, CANCELED, EMERGENCY, SHUTDOWN, STALE, TIMED_OUT, ActiveGoal, TimeLimit
from .parameters import PARAMETERS, check, limits, settings
from .peers import Peers
from .safety import Safety

WATCHDOG_PERIOD = 0.1  # s of the node's clock
LAST_WORD_WAIT = 1.0  # s the zero command at shutdown may take to be acknowledged before the publisher goes


def twist(stamp: int, command: Command, stamped: bool = True) -> TwistStamped | Twist:
    """Return a velocity command in base_link: a TwistStamped stamped `stamp` (ns), or a bare Twist."""
    if stamped:
        return fill_velocity_command(TwistStamped(), stamp, command.linear, command.angular)
    return fill_twist(Twist(), command.linear, command.angular)


class RouteNode(SkynavNode):
    """Drives the robot along a taught route or home to a snapshot."""

    PARAMETERS = PARAMETERS
    INPUT_TOPICS = (
        SKYLINE_SH,
        LOCALIZATION_MATCH,
        COMPASS_ORIENTATION,
        HOME_VECTOR,
        ODOM,
        BUMPER,
        EMERGENCY_STOP,
        IMU,
        TF_STATIC,
    )
    values: dict[str, Any]  # the parameter values taken (configure)
    stamped: bool  # /cmd_vel is a TwistStamped (cmd_vel_stamped, read at start-up)

    def __init__(self, **kwargs) -> None:
        super().__init__(ROUTE_NODE, **kwargs)
        self.declare_table(PARAMETERS)
        self.active: ActiveGoal | None = None
        self.frames = Frames(self.stamp_jumped, self.reject)
        self.safety = Safety(self.get_logger(), lambda: self.active is not None, self.stop_emergency)
        self.peers = Peers(self)
        self.progress_unsaved = 0  # follow goals whose progress record could not be written beside the map
        frames = self.frames
        self.input(SKYLINE_SH, ShCoefficients, self.on_view)
        self.input(LOCALIZATION_MATCH, PlaceMatch, lambda m: frames.keep(LOCALIZATION_MATCH, frames.matches, m))
        self.input(COMPASS_ORIENTATION, CompassEstimate, lambda m: frames.keep(COMPASS_ORIENTATION, frames.compass, m))
        self.input(HOME_VECTOR, HomeVector, self.on_home_vector)
        self.input(ODOM, Odometry, frames.on_odom)
        self.input(BUMPER, Bool, self.on_bumper)
        self.input(EMERGENCY_STOP, Bool, lambda m: self.safety.on_emergency_stop(bool(m.data)))
        self.input(IMU, Imu, self.on_imu)
        self.listen_for_mount()
        self.servers = [
            ActionServer(self, kind, relative(name), execute_callback=execute, cancel_callback=self.on_cancel)
            for kind, name, execute in (
                (FollowRoute, FOLLOW_ROUTE_ACTION, self.execute_follow),
                (Home, HOME_ACTION, self.execute_home),
            )
        ]
        self.watchdog_timer = None
        if self.router is None:  # it ticks only while a goal runs: no wake-up of the executor for nothing
            self.watchdog_timer = self.create_timer(WATCHDOG_PERIOD, self.watchdog)
            self.watchdog_timer.cancel()
        else:
            self.input(CLOCK, Clock, lambda _: self.watchdog())
        self.start()
        self.stamped = bool(self.values['cmd_vel_stamped'])  # the message type is the publisher's, fixed at start
        self.output(CMD_VEL, TwistStamped if self.stamped else Twist)

    def configure(self, values: dict) -> None:
        """Take the limits and thresholds (ValueError if unusable)."""
        check(values)
        if 'stamped' in vars(self) and bool(values['cmd_vel_stamped']) != self.stamped:
            raise ValueError('cmd_vel_stamped is read at start-up only: restart the node to change it')
        self.values, self.settings = values, settings(values)

    @property
    def emergency_stops(self) -> int:
        """Return how often the emergency stop was engaged."""
        return self.safety.stops

    # --- inputs ---------------------------------------------------------------------------------

    def reset_time(self) -> None:
        """Forget the frames kept by stamp and the last frame answered: the frames' time restarted."""
        super().reset_time()
        self.frames.reset()

    def on_bumper(self, message: Bool) -> None:
        """Remember whether the bumper is in contact; contact stops the active goal (BLOCKED)."""
        self.safety.bumped = bool(message.data)
        if self.safety.bumped and self.active is not None:
            self.stop_blocked()

    def on_imu(self, message: Imu) -> None:
        """Take an IMU reading for the tilt stop (skynav_route.safety), its frame in base_link by /tf_static."""
        if self.values['max_tilt_deg'] <= 0:
            return
        try:
            rotation = self.static_transforms.rotation(BASE_FRAME, frame_name(message.header.frame_id) or BASE_FRAME)
        except ValueError:  # the transforms loop: rejected where they came in
            rotation = None
        if not self.safety.on_imu(message, rotation, self.values['max_tilt_deg']):
            self.reject('non_finite', f'an {IMU} message has no usable orientation nor acceleration')

    def on_home_vector(self, message: HomeVector) -> None:
        """Process the frame of a home vector (warping is the last stage); one for a frame done already is late."""
        stamp = self.frames.home_vector(message)
        if stamp is not None:
            self.process(stamp)

    def on_view(self, message: ShCoefficients) -> None:
        """Process the frames before this view that got no home vector (in-process: this one too)."""
        wait = 0 if self.router is not None else int(self.values['frame_wait'] * 1e9)
        stamp = self.frames.due(message, wait, self.router is not None)
        if stamp is not None:
            self.process(stamp)

    # --- driving --------------------------------------------------------------------------------

    def home_vectors_come(self) -> bool:
        """Return whether some node publishes home vectors (live: a publisher of the topic; in process: a node of the
        graph): a frame without one then had its vector refused by the warping node (the views do not determine a
        direction), which the Homer takes as unsure, not as missing."""
        if self.router is None:
            return self.count_publishers(self.live_name(HOME_VECTOR)) > 0
        nodes = getattr(self.router, 'nodes', ())
        return any(node is not self and node.publishes(HOME_VECTOR) for node in nodes)

    def process(self, stamp: int) -> None:
        """Answer one camera frame with one command while a goal is active; nothing while idle."""
        previous = self.frames.answer(stamp)
        goal = self.active
        if previous is None or goal is None:
            return
        if self.safety.engaged:  # engaged (a goal never starts while it is: this is a second guard)
            self.stop_emergency(stamp)
            return
        if self.safety.bumped:  # pressed since before the goal began
            self.stop_blocked(stamp)
            return
        with self.processing(stamp):
            view = self.frames.view(stamp, self.mount, self.home_vectors_come())
            step = goal.controller.step(view)
            goal.last_frame = self.elapsed_ns()
            goal.started = goal.last_frame if goal.started is None else goal.started
            goal.steps += 1
            goal.confidence = step.confidence
            if view.odometry is not None:
                goal.driven += view.odometry
            elif previous >= 0:
                goal.driven += abs(step.command.linear) * min((stamp - previous) / 1e9, 1.0)
            goal.reached_index = max(goal.reached_index, step.matched_index)
        self.emit(CMD_VEL, twist(stamp, step.command, self.stamped))
        goal.handle.publish_feedback(goals.step_feedback(goal, step))
        if step.outcome:
            self.finish(step.outcome, stopped=True)

    def stop(self, stamp: int | None = None) -> None:
        """Publish a zero command (stamped with the node's time unless a frame's stamp is given)."""
        self.emit(CMD_VEL, twist(self.now_ns() if stamp is None else stamp, Command(), self.stamped))

    def stop_blocked(self, stamp: int | None = None) -> None:
        """Stop the robot on bumper contact and end the goal with BLOCKED (the zero command stamped as stop's)."""
        self.get_logger().warning('the bumper reports contact: the robot stops and the goal aborts (BLOCKED)')
        self.stop(stamp)
        self.finish(BLOCKED, stopped=True)

    def stop_emergency(self, stamp: int | None = None) -> None:
        """Stop the robot on the emergency stop and end the goal with EMERGENCY_STOP (the zero command as stop's)."""
        if self.active is not None:
            self.active.stop_reason = self.safety.reason()
        self.stop(stamp)
        self.finish(EMERGENCY, stopped=True)

    def finish(self, outcome: str, stopped: bool = False) -> None:
        """End the active goal: stop the robot (unless the last command was a stop) and wake its execution."""
        goal, self.active = self.active, None
        if goal is None:
            return
        if self.watchdog_timer is not None:
            self.watchdog_timer.cancel()
        if not stopped:
            self.stop()
        if not goal.done.done():
            goal.done.set_result(outcome)

    def watchdog(self) -> None:
        """Stop the robot when no frame came for input_timeout s (STALE_INPUT) or the goal ran longer than its time
        limit (TIMEOUT), both in elapsed time (the clock's jumps left out)."""
        goal = self.active
        if goal is None:
            return
        now = self.elapsed_ns()
        if goal.started is None or goal.last_frame is None:
            goal.started = goal.last_frame = now
        if now - goal.started > goal.time_limit.seconds * 1e9:
            self.finish(TIMED_OUT)
        elif now - goal.last_frame > self.values['input_timeout'] * 1e9:
            self.finish(STALE)

    def on_cancel(self, handle: Any) -> CancelResponse:
        """Accept a cancel: stop at once."""
        if self.active is not None and self.active.handle.goal_id == handle.goal_id:
            self.finish(CANCELED)
        return CancelResponse.ACCEPT

    def diagnostic_status(self) -> DiagnosticStatus:
        """Return the node's status with the emergency stop's: engaged (WARN while it is) and how often."""
        status = super().diagnostic_status()
        status.values.append(KeyValue(key='emergency_stop', value=str(self.safety.engaged).lower()))
        status.values.append(KeyValue(key='emergency_stops', value=str(self.emergency_stops)))
        status.values.append(KeyValue(key='progress_unsaved', value=str(self.progress_unsaved)))
        if self.safety.engaged:
            status.level = max(status.level, DiagnosticStatus.WARN)
            status.message = f'emergency stop engaged; {status.message}'
        return status

    def destroy_node(self) -> None:
        """Stop the robot before going away (shutdown)."""
        if self.active is not None:
            try:
                self.finish(SHUTDOWN)
                # a sample still unacknowledged when its publisher is destroyed may never arrive
                if not self.flush(CMD_VEL, LAST_WORD_WAIT):
                    self.get_logger().warning(f'the last zero command was not acknowledged within {LAST_WORD_WAIT} s')
            except Exception:  # the context may be gone already: nothing more can be sent
                pass
        super().destroy_node()

    # --- goals ----------------------------------------------------------------------------------

    def open_map(self, map_path: str) -> tuple[int, TaughtRoute | None, goals.RouteLength, str]:
        """Return the snapshot count, the route's shape (goals.route_shape; None without), where its snapshots lie
        along it (goals.route_length) and the path of the goal's map (its own, or the node's); raise MapError."""
        path = map_path or self.values['map']
        if not path:
            raise MapError('no map: the goal names none and the route node has no `map` parameter')
        with MapStore.open(path) as store:
            count, odometry, commanded = len(store), store.odometry_poses(), store.commanded_poses()
            route, source = goals.route_shape(odometry, commanded)
            length = goals.route_length(count, odometry, commanded, store.meta)
        if source == 'nothing':
            self.get_logger().info(f'{path}: no odometry or commands of the teach: steering on the home vectors alone')
        elif source == 'commands':
            self.get_logger().info(f"{path}: the route's shape by dead reckoning from the teach's velocity commands")
        return count, route, length, str(path)

    async def configure_peers(self, settings: dict[str, dict[str, Any]]) -> None:
        """Set parameters of other nodes ({node: {name: value}}) unless configure_peers is off (skynav_route.peers)."""
        if self.values['configure_peers']:
            await self.peers.configure(settings, self.values['peer_timeout'])

    async def run_goal(
        self, kind: Any, handle: Any, controller: RouteFollower | Homer, peers: dict, time_limit: TimeLimit
    ) -> tuple[str, ActiveGoal | None]:
        """Configure the graph for a goal, drive it and return how it ended ('busy' if another one runs)."""
        if self.active is not None:
            return 'busy', None
        goal = self.active = ActiveGoal(kind, handle, controller, Future(), time_limit)
        if self.watchdog_timer is not None:
            self.watchdog_timer.reset()
        self.get_logger().info(f'time limit of the goal: {time_limit.describe()}')
        if handle.is_cancel_requested:  # canceled before its execution began, when on_cancel found no active goal
            self.finish(CANCELED)
            return CANCELED, goal
        await self.configure_peers(peers)
        handle.publish_feedback(goals.first_feedback(kind))
        return await goal.done, goal

    async def execute_follow(self, handle: Any) -> FollowRoute.Result:
        """Drive along the route of a FollowRoute goal."""
        request, result, codes = handle.request, FollowRoute.Result(), FollowRoute.Result
        if self.safety.engaged:
            return self.refuse(handle, result, (codes.EMERGENCY_STOP, goals.emergency_refusal(self.safety.reason())))
        try:
            count, route, length, path = self.open_map(request.map_path)
        except MapError as exc:
            return self.refuse(handle, result, (codes.NO_MAP, str(exc)))
        refusal = goals.follow_refusal(request, count)
        if refusal is not None:
            return self.refuse(handle, result, refusal)
        end = goals.follow_end(request, count)
        goal_limits = limits(self.values, request.max_speed)
        controller = RouteFollower(request.start_index, end, goal_limits, self.settings, route)
        peers = goals.follow_peers(self.values['map'], path, self.values['lookahead'], request.start_index)
        timing = self.values['goal_timeout'], self.values['goal_time_factor']
        time_limit = goals.follow_time_limit(length, request.start_index, end, goal_limits.max_speed, *timing)
        outcome, active = await self.run_goal(FollowRoute, handle, controller, peers, time_limit)
        if active is None:
            return self.refuse(handle, result, (codes.BUSY, 'another follow or home goal is running'))
        if outcome != SHUTDOWN:
            await self.configure_peers(goals.UNTRACKED)
        result.reached_index = max(controller.matched, -1)
        lost = goals.unplaced(controller.matched, request.start_index)
        result = self.conclude(handle, result, outcome, active, codes, lost)
        ended = outcome if outcome in (REACHED, CANCELED) else error_name(result)
        reached, driven = result.reached_index, result.driven_length
        self.record_progress(RouteProgress(path, count, request.start_index, end, reached, ended, driven, now()))
        return result

    def record_progress(self, progress: RouteProgress) -> None:
        """Store where a follow goal got to beside its map (skynav_core.route_progress) for `skynav follow --resume`;
        a record that cannot be written is logged and counted (progress_unsaved), and the goal's result stands."""
        try:
            write_progress(progress)
        except ProgressError as exc:
            self.progress_unsaved += 1
            self.get_logger().warning(f'{exc}: `skynav follow --resume` will not know where this goal ended')

    async def execute_home(self, handle: Any) -> Home.Result:
        """Drive to the place of the Home goal's snapshot."""
        request, result, codes = handle.request, Home.Result(), Home.Result
        if self.safety.engaged:
            return self.refuse(handle, result, (codes.EMERGENCY_STOP, goals.emergency_refusal(self.safety.reason())))
        try:
            count, _, _, path = self.open_map(request.map_path)
        except MapError as exc:
            return self.refuse(handle, result, (codes.NO_MAP, str(exc)))
        refusal = goals.home_refusal(request, count)
        if refusal is not None:
            return self.refuse(handle, result, refusal)
        goal_limits = limits(self.values, request.max_speed)
        controller = Homer(request.index, goal_limits, self.settings)
        peers = goals.home_peers(self.values['map'], path, request.index)
        timing = self.values['goal_timeout'], self.values['goal_time_factor']
        time_limit = goals.home_time_limit(self.values['home_distance'], goal_limits.max_speed, *timing)
        outcome, active = await self.run_goal(Home, handle, controller, peers, time_limit)
        if active is None:
            return self.refuse(handle, result, (codes.BUSY, 'another follow or home goal is running'))
        return self.conclude(handle, result, outcome, active, codes)

    def refuse(self, handle: Any, result: Any, refusal: goals.Refusal) -> Any:
        """Abort a goal before it drove: no command is published (nothing moved)."""
        result.error_code, result.error_msg = refusal
        self.get_logger().warning(f'goal refused: {refusal[1]}')
        handle.abort()
        return result

    def conclude(
        self, handle: Any, result: Any, outcome: str, goal: ActiveGoal, codes: Any, lost: str | None = None
    ) -> Any:
        """Fill a finished goal's result and end its handle by the outcome (`lost`: the text of LOST, if not the
        usual one)."""
        result.driven_length = float(goal.driven)
        if outcome == REACHED:
            handle.succeed()
        elif outcome == CANCELED:
            handle.canceled()
        else:
            result.error_code, result.error_msg = goals.failure(
                outcome, codes, self.values['input_timeout'], goal.time_limit, lost, goal.stop_reason
            )
            handle.abort()
        return result


def main(args=None) -> int:
    """Run the route node until Ctrl-C."""
    return run_node(RouteNode, args)
