# SPDX-License-Identifier: Apache-2.0
"""The route node: serves /skynav/follow_route and /skynav/home and drives the robot through /cmd_vel.

It takes /skyline/sh (the frame clock), /localization/match, /compass/orientation and /homing/home_vector, and when
the robot has them /odom, /bumper, /emergency_stop, /camera/imu and /tf_static (the camera's mount); while a goal is
active it publishes exactly one command per camera frame it processes, stamped with that frame's stamp, a zero
command whenever it stops, and nothing while idle (docs/interfaces.md, "Driving" and "On a robot"). It never reads
/ground_truth/*. Every name is relative to the node's namespace.

The parts: skynav_route.goal_server (the two action servers), skynav_route.goals (a goal's map, refusals, plan,
time limit, results), skynav_route.context (what localize, compass and warping compare against during the goal, set
through skynav_core.peers before it drives),
skynav_route.frames (which frame is processed when), skynav_route.controller (the command), skynav_route.safety
(the emergency stop, the tilt and the bumper). The watchdog (a timer live, /clock in the in-process graph) ends a
goal with STALE_INPUT when no frame was processed for `input_timeout` s and with TIMEOUT past its time limit, both
in elapsed time (`elapsed_ns()`: the clock's jumps left out). A goal canceled before its execution began never
drives (skynav_core.goals).
"""

from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu
from std_msgs.msg import Bool

from skynav_core.motion import fill_twist, fill_velocity_command
from skynav_core.mount import frame_name
from skynav_core.names import (
    BASE_FRAME,
    BUMPER,
    CLOCK,
    CMD_VEL,
    COMPASS_ORIENTATION,
    EMERGENCY_STOP,
    HOME_VECTOR,
    IMU,
    LOCALIZATION_MATCH,
    ODOM,
    ROUTE_NODE,
    SKYLINE_SH,
    TF_STATIC,
)
from skynav_core.node import SkynavNode
from skynav_core.ros import run_node
from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch, ShCoefficients

from . import goals
from .controller import Command
from .frames import Frames
from .goal_server import GoalServer
from .goals import BLOCKED, EMERGENCY, SHUTDOWN, STALE, TIMED_OUT, ActiveGoal
from .parameters import PARAMETERS, check, settings
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
        self.goal_server = GoalServer(self)
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
            step = goal.plan.controller.step(view)
            goal.record(step, view.odometry, stamp, previous, self.elapsed_ns())
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

    def begin(self, goal: ActiveGoal) -> None:
        """Make `goal` the one driven from the next frame on, and start the watchdog."""
        self.active = goal
        if self.watchdog_timer is not None:
            self.watchdog_timer.reset()

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
        if now - goal.started > goal.plan.time_limit.seconds * 1e9:
            self.finish(TIMED_OUT)
        elif now - goal.last_frame > self.values['input_timeout'] * 1e9:
            self.finish(STALE)

    def diagnostic_status(self) -> DiagnosticStatus:
        """Return the node's status with the emergency stop's: engaged (WARN while it is) and how often."""
        status = super().diagnostic_status()
        status.values.append(KeyValue(key='emergency_stop', value=str(self.safety.engaged).lower()))
        status.values.append(KeyValue(key='emergency_stops', value=str(self.emergency_stops)))
        status.values.append(KeyValue(key='progress_unsaved', value=str(self.goal_server.progress_unsaved)))
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


def main(args=None) -> int:
    """Run the route node until Ctrl-C."""
    return run_node(RouteNode, args)
