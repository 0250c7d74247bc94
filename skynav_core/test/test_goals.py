# SPDX-License-Identifier: Apache-2.0
"""skynav_core.goals: a command's goal survives the service answers that DDS loses.

A Teach action server runs in this process, over DDS, and the command's action client runs through
skynav_core.goals.run_goal, as `skynav teach|follow|home` do. Either side may be a subclass that loses chosen
messages on the way to it: a client its first goal or result answer (as Fast DDS drops an answer while the server
has not yet discovered the client's reader of answers), a server its first goal request.
"""

import threading
import time

import pytest
from rclpy.action import ActionClient, ActionServer, CancelResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.node import Node

from skynav_core import goals
from skynav_core.cli import CliError
from skynav_core.names import TEACH_ACTION
from skynav_msgs.action import Teach
from skynav_testing import wait_until

TIMEOUT = 30.0  # s for discovery and answers under load


class Stop:
    """A stop request (skynav_core.ros.StopRequest) that comes once `when()` is true."""

    def __init__(self, when=lambda: False):
        self.when = when
        self.count = 0

    @property
    def requested(self):
        if self.count == 0 and self.when():
            self.count = 1
        return self.count > 0


def losing_first(base):
    """Return a subclass of the action client or server class `base` that loses, on the way to it, the first
    message of each kind in its `lose` ('goal', 'result': answers to a client, requests to a server)."""

    class Losing(base):
        lose: set[str] = set()

        def take_data(self):
            data = super().take_data()
            for kind in self.lose & set(data):
                self.lose = self.lose - {kind}
                del data[kind]
            return data

    return Losing


LosingClient = losing_first(ActionClient)
LosingServer = losing_first(ActionServer)


class Server:
    """A Teach server whose goals publish feedback, then end: succeeded after `run_for` s, or, when `hold` is true,
    canceled once a cancel comes (a goal that would drive until stopped)."""

    def __init__(self, context, run_for=0.0, hold=False, lose=()):
        self.node = Node('goal_test_server', context=context)
        self.run_for, self.hold = run_for, hold
        self.started = []  # goal ids, in order
        self.ended = {}  # goal id: 'canceled' or 'succeeded'
        self.server = LosingServer(
            self.node,
            Teach,
            TEACH_ACTION,
            execute_callback=self.execute,
            cancel_callback=lambda handle: CancelResponse.ACCEPT,
            callback_group=ReentrantCallbackGroup(),
        )
        self.server.lose = set(lose)
        self.executor = MultiThreadedExecutor(num_threads=3, context=context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def execute(self, handle):
        goal_id = bytes(handle.goal_id.uuid)
        self.started.append(goal_id)
        end = time.monotonic() + self.run_for
        while (self.hold or time.monotonic() < end) and not handle.is_cancel_requested:
            handle.publish_feedback(Teach.Feedback(snapshots=len(self.started)))
            time.sleep(0.05)
        if handle.is_cancel_requested:
            handle.canceled()
            self.ended[goal_id] = 'canceled'
            return Teach.Result(snapshots=len(self.started))
        handle.publish_feedback(Teach.Feedback(snapshots=len(self.started)))
        handle.succeed()
        self.ended[goal_id] = 'succeeded'
        return Teach.Result(snapshots=len(self.started))

    def close(self):
        self.executor.shutdown()
        self.thread.join(timeout=TIMEOUT)
        self.server.destroy()
        self.node.destroy_node()


@pytest.fixture
def command(ros_context, monkeypatch):
    """Run one goal as a command does, its client losing the first answers of the kinds given; return
    (outcome, feedback it showed)."""
    monkeypatch.setattr(goals, 'RESULT_ASK_AGAIN', 1.0)
    monkeypatch.setattr(goals, 'ActionClient', LosingClient)
    node = Node('goal_test_command', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)

    def run(lose=(), stop=None, timeout=TIMEOUT):
        monkeypatch.setattr(LosingClient, 'lose', set(lose))
        shown = []
        goal = Teach.Goal(map_path='/tmp/never-written.db')
        outcome = goals.run_goal(node, executor, Teach, TEACH_ACTION, goal, stop or Stop(), shown.append, timeout)
        return outcome, shown

    yield run
    executor.shutdown()
    node.destroy_node()


def test_a_goal_the_server_never_got_is_sent_again(ros_context, command):
    server = Server(ros_context, lose={'goal'})
    try:
        outcome, shown = command()
        assert outcome.status_name == 'succeeded' and outcome.result.snapshots == 1
        assert len(server.started) == 1 and shown and all(feedback.snapshots == 1 for feedback in shown)
    finally:
        server.close()


def test_a_running_goal_whose_answer_is_lost_is_followed_to_its_end(ros_context, command):
    # the server runs the goal (a robot drives it): neither a second goal nor a cancel may come
    server = Server(ros_context, run_for=2 * goals.GOAL_ANSWER_WAIT)
    try:
        outcome, shown = command(lose={'goal'})
        assert outcome.status_name == 'succeeded' and outcome.result.snapshots == 1
        assert list(server.ended.values()) == ['succeeded'] and shown
    finally:
        server.close()


def test_a_result_whose_answer_is_lost_is_asked_for_again(ros_context, command):
    server = Server(ros_context)
    try:
        outcome, _ = command(lose={'result'})
        assert outcome.status_name == 'succeeded' and outcome.result.snapshots == 1
        assert len(server.started) == 1
    finally:
        server.close()


def test_a_stop_while_the_answer_is_lost_cancels_the_goal(ros_context, command):
    # Ctrl-C before any answer came: the goal that runs unseen is canceled (the robot stops)
    server = Server(ros_context, hold=True)
    try:
        outcome, _ = command(lose={'goal'}, stop=Stop(lambda: bool(server.started)))
        # None: stopped before the goal was seen; or seen (its status) and then canceled
        assert outcome is None or (outcome.canceled and outcome.status_name == 'canceled')
        wait_until(lambda: server.ended, 'the goal to end')
        assert list(server.ended.values()) == ['canceled'] and len(server.started) == 1
    finally:
        server.close()


def test_a_server_that_never_answers_fails_in_one_line(ros_context, command):
    # a server that is seen but never spins (a node stuck in a callback)
    silent = Node('goal_test_silent_server', context=ros_context)
    server = ActionServer(silent, Teach, TEACH_ACTION, execute_callback=lambda handle: Teach.Result())
    try:
        with pytest.raises(CliError, match=f'the {TEACH_ACTION} server did not answer the goal within 3 s'):
            command(timeout=3.0)
    finally:
        server.destroy()
        silent.destroy_node()
