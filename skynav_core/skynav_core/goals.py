# SPDX-License-Identifier: Apache-2.0
"""Send one action goal from a command and follow it to its end: what `skynav teach|follow|home` share.

Once the server is seen, the client lets discovery settle before it sends the goal. The goal's feedback goes to a
callback (the command's progress line, :class:`ProgressLine`); a stop request (Ctrl-C, SIGTERM) cancels the goal once
and waits for its result, a second one gives up waiting. :func:`goal_result` turns the outcome into the command's
exit: the result of a goal that ended well, or a CliError naming the result's error code (exit code 1). Import after
:func:`skynav_core.environment.apply_ros_environment` (as skynav_core.ros).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TextIO

from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from .actions import ERROR_NONE, error_name
from .cli import CliError
from .ros import StopRequest, spin_until, tool_node

RESULT_AFTER_CANCEL = 30.0  # s a server gets to answer a cancel with its result (a Teach goal finishes its map)
STOP_AFTER_CANCEL = 10.0  # s a driving goal's server gets to confirm a cancel (the robot stops at once)
# s to let discovery finish the other way once the server is seen: a request sent before the server has matched
# this client is lost (DDS discovery is per direction; ENV.md: a late joiner can take seconds)
SERVER_SETTLE = 2.0
PRINT_PERIOD = 1.0  # s between progress lines when the output is not a terminal
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


class ProgressLine:
    """One line of progress: rewritten in place on a terminal, printed at most every `period` s elsewhere."""

    def __init__(self, stream: TextIO | None = None, period: float = PRINT_PERIOD) -> None:
        self.stream = sys.stdout if stream is None else stream
        self.tty = self.stream.isatty()
        self.period = period
        self.printed_at = -float('inf')
        self.text = ''

    def show(self, text: str) -> None:
        """Show the latest progress."""
        self.text = text
        if self.tty:
            self.stream.write(f'\r{text}\033[K')
        elif time.monotonic() - self.printed_at >= self.period:
            self.stream.write(f'{text}\n')
            self.printed_at = time.monotonic()
        self.stream.flush()

    def end(self) -> None:
        """Finish the line on a terminal."""
        if self.tty and self.text:
            self.stream.write('\n')
            self.stream.flush()
            self.text = ''


def run_goal(
    node: Node,
    executor: SingleThreadedExecutor,
    action_type: type,
    action_name: str,
    goal: Any,
    stop: StopRequest,
    on_feedback: Callable[[Any], None] | None = None,
    server_timeout: float = 10.0,
    cancel_wait: float = RESULT_AFTER_CANCEL,
) -> GoalOutcome | None:
    """Send `goal` to the action server `action_name` and spin until it ends; None if stopped before it was sent.

    CliError when no server answers within server_timeout s (nor the goal), when the goal is rejected, or when a
    canceled goal's result does not come within cancel_wait s or before a second stop request.
    """
    client = ActionClient(node, action_type, action_name)
    try:
        spin_until(executor, lambda: client.server_is_ready() or stop.requested, server_timeout)
        if stop.requested:
            return None
        if not client.server_is_ready():
            raise CliError(
                f'no {action_name} action server answered within {server_timeout:g} s: is `skynav launch` running?'
            )
        spin_until(executor, lambda: stop.requested, SERVER_SETTLE)
        if stop.requested:
            return None
        feedback = None if on_feedback is None else (lambda message: on_feedback(message.feedback))
        sent = client.send_goal_async(goal, feedback_callback=feedback)
        if not spin_until(executor, sent.done, server_timeout):
            raise CliError(f'the {action_name} server did not answer the goal within {server_timeout:g} s')
        handle = sent.result()
        if not handle.accepted:
            raise CliError(f'the {action_name} server rejected the goal')
        result = handle.get_result_async()
        canceled, stops, deadline = False, 0, 0.0
        while not result.done():
            if stop.requested and not canceled:
                handle.cancel_goal_async()
                canceled, deadline = True, time.monotonic() + cancel_wait
                stops = stop.count
            if canceled and (stop.count > stops or time.monotonic() > deadline):
                raise CliError(f'canceled, but the {action_name} server did not confirm the end of the goal')
            executor.spin_once(timeout_sec=0.05)
        response = result.result()
        return GoalOutcome(response.status, response.result, canceled)
    finally:
        client.destroy()


def send_goal(
    action_type: type,
    action_name: str,
    goal: Any,
    on_feedback: Callable[[Any], None] | None,
    server_timeout: float,
    node_name: str = 'skynav_goal_client',
    cancel_wait: float = STOP_AFTER_CANCEL,
) -> GoalOutcome | None:
    """Run one goal from a node of its own with Ctrl-C as the stop request (:func:`run_goal`)."""
    with StopRequest() as stop, tool_node(node_name) as (node, executor):
        return run_goal(node, executor, action_type, action_name, goal, stop, on_feedback, server_timeout, cancel_wait)


def goal_result(
    outcome: GoalOutcome | None, cancel_finishes: bool = False, detail: Callable[[Any], str] | None = None
) -> Any:
    """Return the result of a goal that ended well (succeeded; canceled too when `cancel_finishes`).

    KeyboardInterrupt (exit code 130) when the goal was not sent; CliError otherwise: 'canceled (the robot stopped)'
    or the error code's name and message, followed by ` (detail(result))` when given.
    """
    if outcome is None:
        raise KeyboardInterrupt
    result = outcome.result
    canceled = outcome.status == GoalStatus.STATUS_CANCELED
    if canceled and not cancel_finishes:
        raise CliError('canceled (the robot stopped)')
    if int(result.error_code) != ERROR_NONE or not (canceled or outcome.status == GoalStatus.STATUS_SUCCEEDED):
        message = f'{error_name(result)}: {result.error_msg or f"the goal was {outcome.status_name}"}'
        raise CliError(message if detail is None else f'{message} ({detail(result)})')
    return result
