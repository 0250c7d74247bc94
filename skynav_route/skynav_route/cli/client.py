# SPDX-License-Identifier: Apache-2.0
"""What `skynav follow` and `skynav home` share: send a goal to the running graph, show its progress, cancel on Ctrl-C.

The progress line is rewritten in place on a terminal and printed once a second otherwise. Exit code 0 when the
goal succeeded; otherwise a CliError naming the result's error code (LOST, NO_MAP, ...), exit code 1.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any

from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from skynav_core.actions import error_name
from skynav_core.cli import CliError
from skynav_core.ros import StopRequest, tool_node

SUCCEEDED, CANCELED = 4, 5  # action_msgs/GoalStatus
PRINT_PERIOD = 1.0  # s between progress lines when the output is not a terminal
CANCEL_WAIT = 10.0  # s to wait for the result of a canceled goal
# s to let discovery finish the other way once the server is seen: a request sent before the server has matched
# this client is lost (DDS discovery is per direction; ENV.md: a late joiner can take seconds)
SERVER_SETTLE = 2.0


def spin_until(executor: SingleThreadedExecutor, done: Callable[[], bool], seconds: float, stop: StopRequest) -> bool:
    """Spin until `done()`, `seconds` passed or Ctrl-C; return done()."""
    deadline = time.monotonic() + seconds
    while not done() and time.monotonic() < deadline and not stop.requested:
        executor.spin_once(timeout_sec=0.05)
    return done()


class ProgressLine:
    """One line of progress: rewritten in place on a terminal, printed at most once a second elsewhere."""

    def __init__(self) -> None:
        self.tty = sys.stdout.isatty()
        self.printed_at = 0.0
        self.text = ''

    def show(self, text: str) -> None:
        """Show the latest progress."""
        self.text = text
        if self.tty:
            print(f'\r{text}\033[K', end='', flush=True)
        elif time.monotonic() - self.printed_at >= PRINT_PERIOD:
            print(text, flush=True)
            self.printed_at = time.monotonic()

    def end(self) -> None:
        """Finish the line on a terminal."""
        if self.tty and self.text:
            print(flush=True)


def send_goal(
    action_type: type, action_name: str, goal: Any, describe: Callable[[Any], str], wait: float
) -> tuple[Any, int]:
    """Send `goal`, show `describe(feedback)` until the result; return (result, status). Ctrl-C cancels the goal."""
    with tool_node('skynav_goal_client') as (node, executor), StopRequest() as stop:
        return _send(node, executor, stop, action_type, action_name, goal, describe, wait)


def _send(
    node: Node,
    executor: SingleThreadedExecutor,
    stop: StopRequest,
    action_type: type,
    action_name: str,
    goal: Any,
    describe: Callable[[Any], str],
    wait: float,
) -> tuple[Any, int]:
    client = ActionClient(node, action_type, action_name)
    if not spin_until(executor, client.server_is_ready, wait, stop):
        if stop.requested:
            raise KeyboardInterrupt
        raise CliError(f'no {action_name} action server answered within {wait:g} s: is `skynav launch` running?')
    spin_until(executor, lambda: False, SERVER_SETTLE, stop)
    if stop.requested:
        raise KeyboardInterrupt
    line = ProgressLine()
    sent = client.send_goal_async(goal, feedback_callback=lambda m: line.show(describe(m.feedback)))
    if not spin_until(executor, sent.done, wait, stop):
        raise CliError(f'the {action_name} server did not answer the goal within {wait:g} s')
    if not sent.result().accepted:
        raise CliError(f'the {action_name} server rejected the goal')
    handle = sent.result()
    result = handle.get_result_async()
    while not result.done() and not stop.requested:
        executor.spin_once(timeout_sec=0.05)
    if not result.done():  # Ctrl-C: cancel, the robot stops
        stop.requested = False
        handle.cancel_goal_async()
        spin_until(executor, result.done, CANCEL_WAIT, stop)
        line.end()
        if not result.done():
            raise CliError('canceled, but the server did not confirm the end of the goal')
        raise CliError('canceled (the robot stopped)')
    line.end()
    answer = result.result()
    return answer.result, answer.status


def conclude(result: Any, status: int, summary: str) -> int:
    """Print the summary of a finished goal and return 0, or raise CliError with the error code's name."""
    if status == SUCCEEDED:
        print(summary)
        return 0
    if status == CANCELED:
        raise CliError('canceled (the robot stopped)')
    raise CliError(f'{error_name(result)}: {result.error_msg or "the goal was aborted"}')
