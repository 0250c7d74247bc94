# SPDX-License-Identifier: Apache-2.0
"""Send one action goal from a command and follow it to its end: what `skynav teach|follow|home` share.

The goal's feedback goes to a callback (the command's progress line); a stop request (Ctrl-C, SIGTERM) cancels the
goal once and waits for its result, a second one gives up waiting. Import after
:func:`skynav_core.environment.apply_ros_environment` (as skynav_core.ros).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from .cli import CliError
from .ros import StopRequest, spin_until

RESULT_AFTER_CANCEL = 30.0  # s a server gets to answer a cancel with its result
STATUS_NAMES = {
    GoalStatus.STATUS_SUCCEEDED: 'succeeded',
    GoalStatus.STATUS_CANCELED: 'canceled',
    GoalStatus.STATUS_ABORTED: 'aborted',
}


@dataclass
class GoalOutcome:
    """How a goal ended: its status (action_msgs GoalStatus), its result, and whether this side canceled it."""

    status: int
    result: Any
    canceled: bool

    @property
    def status_name(self) -> str:
        """Return 'succeeded', 'canceled', 'aborted' (or 'status N')."""
        return STATUS_NAMES.get(self.status, f'status {self.status}')


def run_goal(
    node: Node,
    executor: SingleThreadedExecutor,
    action_type: type,
    action_name: str,
    goal: Any,
    stop: StopRequest,
    on_feedback: Callable[[Any], None] | None = None,
    server_timeout: float = 10.0,
) -> GoalOutcome | None:
    """Send `goal` to the action server `action_name` and spin until it ends; None if stopped before it was sent.

    CliError when no server answers within server_timeout s, when the goal is rejected, or when a canceled goal's
    result does not come within RESULT_AFTER_CANCEL s.
    """
    client = ActionClient(node, action_type, action_name)
    try:
        spin_until(executor, lambda: client.server_is_ready() or stop.requested, server_timeout)
        if stop.requested:
            return None
        if not client.server_is_ready():
            raise CliError(
                f'no {action_name} action server after {server_timeout:g} s (is the graph running? `skynav launch`)'
            )
        feedback = None if on_feedback is None else (lambda message: on_feedback(message.feedback))
        sent = client.send_goal_async(goal, feedback_callback=feedback)
        while not sent.done():
            executor.spin_once(timeout_sec=0.1)
        handle = sent.result()
        if not handle.accepted:
            raise CliError(f'the {action_name} server rejected the goal')
        result = handle.get_result_async()
        canceled, stops, deadline = False, 0, 0.0
        while not result.done():
            if stop.requested and not canceled:
                handle.cancel_goal_async()
                canceled, deadline = True, time.monotonic() + RESULT_AFTER_CANCEL
                stops = stop.count
            if canceled and (stop.count > stops or time.monotonic() > deadline):
                raise CliError(f'canceled; the {action_name} server did not send its result')
            executor.spin_once(timeout_sec=0.1)
        response = result.result()
        return GoalOutcome(response.status, response.result, canceled)
    finally:
        client.destroy()
