# SPDX-License-Identifier: Apache-2.0
"""Send one action goal from a command and follow it to its end: what `skynav teach|follow|home` share.

Once the server is seen, the client lets discovery settle before it sends the goal. The goal's feedback goes to a
callback (the command's progress line, :class:`ProgressLine`); a stop request (Ctrl-C, SIGTERM) cancels the goal once
and waits for its result, a second one gives up waiting. :func:`goal_result` turns the outcome into the command's
exit: the result of a goal that ended well, or a CliError naming the result's error code (exit code 1). Import after
:func:`skynav_core.process.environment.apply_ros_environment` (as skynav_core.ros).

An action's goal and result are services, and Fast DDS drops a service's answer when the server has not yet
discovered the client's reader of answers (rmw_fastrtps: "client will not receive response"). rclpy's server then
either never runs the goal (it logs "Failed to send goal response") or runs it unseen. So a goal unanswered for
GOAL_ANSWER_WAIT s is followed if the server shows it runs it (the goal's status or feedback); otherwise it is
canceled by its id and sent again with a new id, until the command's wait is over. A goal that the status topic
says has ended is asked for its result again every RESULT_ASK_AGAIN s.
"""

from __future__ import annotations

import sys
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TextIO

from action_msgs.msg import GoalStatus, GoalStatusArray
from rclpy.action import ActionClient
from rclpy.action.client import ClientGoalHandle
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_action_status_default
from unique_identifier_msgs.msg import UUID

from .actions import ERROR_NONE, error_name
from .cli import CliError
from .ros import StopRequest, spin_until, tool_node

RESULT_AFTER_CANCEL = 30.0  # s a server gets to answer a cancel with its result (a Teach goal finishes its map)
STOP_AFTER_CANCEL = 10.0  # s a driving goal's server gets to confirm a cancel (the robot stops at once)
# s to let discovery finish the other way once the server is seen: a request sent before the server has matched
# this client is lost (DDS discovery is per direction; ENV.md: a late joiner can take seconds)
SERVER_SETTLE = 2.0
GOAL_ANSWER_WAIT = 5.0  # s for the answer to a goal before it is canceled and sent again (see the module notes)
RESULT_ASK_AGAIN = 5.0  # s after the status topic said the goal ended before its result is asked for again
ENDED = (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED, GoalStatus.STATUS_ABORTED)
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
    statuses: dict[bytes, int] = {}  # goal id: its latest status on the action's status topic

    def on_status(message: GoalStatusArray) -> None:
        statuses.update((bytes(s.goal_info.goal_id.uuid), s.status) for s in message.status_list)

    status_topic = f'{action_name}/_action/status'
    subscription = node.create_subscription(GoalStatusArray, status_topic, on_status, qos_profile_action_status_default)
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
        sending = GoalSender(client, executor, action_type, action_name, statuses, on_feedback)
        handle = sending.send(goal, stop, server_timeout)
        if handle is None:
            return None
        if not handle.accepted:
            raise CliError(f'the {action_name} server rejected the goal')
        result = handle.get_result_async()
        canceled, stops, deadline = False, 0, 0.0
        asked_at = time.monotonic()
        while not result.done():
            if stop.requested and not canceled:
                handle.cancel_goal_async()
                canceled, deadline = True, time.monotonic() + cancel_wait
                stops = stop.count
            if canceled and (stop.count > stops or time.monotonic() > deadline):
                raise CliError(f'canceled, but the {action_name} server did not confirm the end of the goal')
            ended = statuses.get(bytes(handle.goal_id.uuid)) in ENDED
            if ended and time.monotonic() - asked_at > RESULT_ASK_AGAIN:
                result, asked_at = handle.get_result_async(), time.monotonic()  # the answer to the last ask was lost
            executor.spin_once(timeout_sec=0.05)
        response = result.result()
        return GoalOutcome(response.status, response.result, canceled)
    finally:
        node.destroy_subscription(subscription)
        client.destroy()


class GoalSender:
    """Sends a goal until the server answers it or shows that it has it (the goal's status or feedback)."""

    def __init__(
        self,
        client: ActionClient,
        executor: SingleThreadedExecutor,
        action_type: Any,
        action_name: str,
        statuses: dict[bytes, int],
        on_feedback: Callable[[Any], None] | None,
    ) -> None:
        self.client, self.executor, self.action_name = client, executor, action_name
        self.accepted = action_type.Impl.SendGoalService.Response(accepted=True)
        self.statuses = statuses  # kept up to date by the caller's subscription to the status topic
        self.on_feedback = on_feedback
        self.current = UUID()  # the goal last sent: the only one whose feedback is shown
        self.heard: set[bytes] = set()  # goals some feedback came from

    def feedback(self, message: Any) -> None:
        """Take one feedback message of a goal sent (shown only if it is the current goal's)."""
        key = bytes(message.goal_id.uuid)
        self.heard.add(key)
        if self.on_feedback is not None and key == bytes(self.current.uuid):
            self.on_feedback(message.feedback)

    def shows(self, key: bytes) -> bool:
        """Return whether the server has shown that it has the goal of id `key` (its status, or its feedback)."""
        return key in self.statuses or key in self.heard

    def send(self, goal: Any, stop: StopRequest, timeout: float) -> ClientGoalHandle | None:
        """Send `goal` (a new goal id every GOAL_ANSWER_WAIT s) until the server has it; return its goal handle.

        A goal without an answer that the server shows it runs is followed (only its answer was lost); one the server
        does not show is canceled by its id before the next is sent. None when stopped first (the goal canceled, its
        cancel given GOAL_ANSWER_WAIT s to be answered); CliError when the server had none within `timeout` s.
        """
        deadline = time.monotonic() + timeout
        while True:
            self.current = UUID(uuid=list(uuid.uuid4().bytes))
            key = bytes(self.current.uuid)
            sent = self.client.send_goal_async(goal, feedback_callback=self.feedback, goal_uuid=self.current)
            give_up = min(time.monotonic() + GOAL_ANSWER_WAIT, deadline)
            while not (sent.done() or self.shows(key) or stop.requested) and time.monotonic() < give_up:
                self.executor.spin_once(timeout_sec=0.05)
            if sent.done():
                return sent.result()
            handle = ClientGoalHandle(self.client, self.current, self.accepted)
            if self.shows(key) and not stop.requested:
                return handle
            canceling = handle.cancel_goal_async()
            if stop.requested or time.monotonic() >= deadline:
                spin_until(self.executor, canceling.done, GOAL_ANSWER_WAIT)  # the cancel is out before the client goes
                if stop.requested:
                    return None
                raise CliError(f'the {self.action_name} server did not answer the goal within {timeout:g} s')


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
