# SPDX-License-Identifier: Apache-2.0
"""The Teach action server of the localize node, live: views and /odom in, a map out that the nodes switch to.

The views are the bundled synthetic garden teach drive's (SH of its ground-truth masks, conftest.read_recording),
published on /skyline/sh; its ground-truth poses play /odom. The localize, compass and warping nodes run in this
process on DDS, each as it runs in `skynav launch` (one single-threaded executor each); the kill -9 test runs the
localize node in a process of its own.
"""

import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from rclpy.parameter import Parameter

from skynav_core.actions import error_name
from skynav_core.goals import SERVER_SETTLE
from skynav_core.maps import ODOM_POSE, MapStore
from skynav_core.names import (
    BASE_FRAME,
    CAMERA_FRAME,
    CLOCK,
    CMD_VEL,
    LOCALIZATION_MATCH,
    ODOM,
    ODOM_FRAME,
    SKYLINE_SH,
    TEACH_ACTION,
)
from skynav_testing import CanceledGoalHandle, on_executor_thread, run_without_waiting, wait_until

TIMEOUT = 30.0  # s for discovery and results under load


def spin_in_thread(node, context):
    """Spin one node in a thread with a single-threaded executor of its own; return (executor, thread)."""
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    return executor, thread


class Operator:
    """The test's side: publishes views and odometry, sends Teach goals (its own node and executor thread)."""

    def __init__(self, context):
        from geometry_msgs.msg import TwistStamped
        from nav_msgs.msg import Odometry
        from rclpy.action import ActionClient
        from rclpy.node import Node
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        from skynav_msgs.action import Teach
        from skynav_msgs.msg import ShCoefficients

        self.node = Node('operator', context=context)
        self.views = self.node.create_publisher(
            ShCoefficients, SKYLINE_SH, QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        )
        self.odometry = self.node.create_publisher(Odometry, ODOM, 100)
        self.commands = self.node.create_publisher(TwistStamped, CMD_VEL, 100)
        self.client = ActionClient(self.node, Teach, TEACH_ACTION)
        self.feedback = []
        self.executor, self.thread = spin_in_thread(self.node, context)
        assert self.client.wait_for_server(timeout_sec=TIMEOUT)
        wait_until(lambda: self.views.get_subscription_count() >= 1, 'the localize node to subscribe /skyline/sh')
        time.sleep(SERVER_SETTLE)  # as `skynav teach` does: until the server has matched this client, a goal is lost

    def drive(self, recording, indices, odometry=True, period=0.04, shift=0, commands=None):
        """Publish views (and, just before each, /odom of the same instant; just after, the velocity command
        commands[k], stamped like it) of a recording's frames."""
        from geometry_msgs.msg import TwistStamped
        from nav_msgs.msg import Odometry

        from skynav_msgs.msg import ShCoefficients

        for k in indices:
            stamp = int(recording.stamps[k]) + shift  # ns
            if odometry:
                message = Odometry()
                message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 10**9)
                message.header.frame_id, message.child_frame_id = ODOM_FRAME, BASE_FRAME
                p, q = message.pose.pose.position, message.pose.pose.orientation
                p.x, p.y, p.z, q.x, q.y, q.z, q.w = (float(v) for v in recording.poses[k])
                self.odometry.publish(message)
            view = ShCoefficients(max_degree=16, coefficients=recording.coefficients[k].tolist(), fill='zero')
            view.header.stamp.sec, view.header.stamp.nanosec = divmod(stamp, 10**9)
            view.header.frame_id = CAMERA_FRAME
            view.field_of_view = float(np.radians(200))
            self.views.publish(view)
            if commands is not None:
                command = TwistStamped()
                command.header.stamp = view.header.stamp
                command.twist.linear.x, command.twist.angular.z = (float(v) for v in commands[k])
                self.commands.publish(command)
            time.sleep(period)

    def send(self, **fields):
        """Send a Teach goal; return its goal handle (accepted)."""
        from skynav_msgs.action import Teach

        goal = Teach.Goal(**fields)
        future = on_executor_thread(
            self.executor,
            lambda: self.client.send_goal_async(goal, feedback_callback=lambda m: self.feedback.append(m.feedback)),
        )
        wait_until(future.done, 'the goal to be accepted')
        handle = future.result()
        assert handle.accepted
        return handle

    def result(self, handle):
        """Return (status, result) of a goal once it ended."""
        future = on_executor_thread(self.executor, handle.get_result_async)
        wait_until(future.done, 'the result')
        return future.result().status, future.result().result

    def cancel(self, handle):
        """Cancel a goal; return (status, result)."""
        future = on_executor_thread(self.executor, handle.cancel_goal_async)
        wait_until(future.done, 'the cancel response')
        return self.result(handle)

    def close(self):
        self.executor.shutdown()
        self.thread.join(timeout=TIMEOUT)
        self.client.destroy()
        self.node.destroy_node()


@pytest.fixture
def graph(ros_context):
    """The localize, compass and warping nodes live, and an operator."""
    from skynav_compass.node import CompassNode
    from skynav_localize.node import LocalizeNode
    from skynav_warping.node import WarpingNode

    nodes = [LocalizeNode(context=ros_context), CompassNode(context=ros_context), WarpingNode(context=ros_context)]
    nodes[0].set_parameters([Parameter('teach_input_timeout', value=1.0)])
    spinners = [spin_in_thread(node, ros_context) for node in nodes]
    operator = Operator(ros_context)
    yield dict(zip(('localize', 'compass', 'warping'), nodes, strict=True)), operator
    operator.close()
    for executor, thread in spinners:  # every callback finished before any node goes
        executor.shutdown()
        thread.join(timeout=TIMEOUT)
    for node in nodes:
        node.destroy_node()


def test_a_canceled_teach_leaves_a_map_every_node_uses_at_once(graph, garden, tmp_path):
    from action_msgs.msg import GoalStatus

    from skynav_msgs.msg import PlaceMatch

    nodes, operator = graph
    drive = garden['teach']
    path = tmp_path / 'taught.db'
    handle = operator.send(map_path=str(path), spacing=0.3)
    operator.drive(drive, range(len(drive.stamps)))
    wait_until(lambda: nodes['localize'].last_stamp == drive.stamps[-1], 'the last view taken')
    assert nodes['localize'].received[SKYLINE_SH] == len(drive.stamps)
    status, result = operator.cancel(handle)
    assert status == GoalStatus.STATUS_CANCELED and error_name(result) == 'NONE'
    travelled = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(drive.poses[:, :3], axis=0), axis=1))])
    assert result.snapshots >= travelled[-1] / 0.4
    assert result.route_length == pytest.approx(operator.feedback[-1].route_length)
    assert [f.snapshots for f in operator.feedback] == list(range(result.snapshots + 1))  # 0: teaching began
    with MapStore.open(path) as store:
        assert len(store) == result.snapshots and store.name == 'taught'
        kept = np.searchsorted(drive.stamps, store.stamps())
        np.testing.assert_array_equal(drive.stamps[kept], store.stamps())
        # the first view past each 0.3 m mark from the first snapshot with odometry (odometry extrapolated over
        # <= 0.1 s, to 1 cm), at least half a spacing apart
        first = int(np.argmax(np.isfinite(store.descriptor_matrix(ODOM_POSE)[:, 0])))
        marks = np.floor((travelled[kept[first:]] - travelled[kept[first]]) / 0.3 + 0.01 / 0.3)
        assert np.all(np.diff(marks) >= 1) and np.all(np.diff(travelled[kept[first:]]) >= 0.15 - 0.01)
        odometry = store.descriptor_matrix(ODOM_POSE)
        paired = np.isfinite(odometry[:, 0])  # the first view may come before the first odometry sample
        assert paired[1:].all()
        np.testing.assert_allclose(odometry[paired, :3], drive.poses[kept][paired, :3], atol=0.02)
    for name, node in nodes.items():
        assert node.get_parameter('map').value == str(path), name
    assert len(nodes['localize'].store) == result.snapshots
    assert all(len(nodes[name].snapshots.store) == result.snapshots for name in ('compass', 'warping'))
    # localization runs on the new map from the next view on
    matches = []
    operator.node.create_subscription(PlaceMatch, LOCALIZATION_MATCH, matches.append, 10)
    wait_until(lambda: operator.node.count_publishers(LOCALIZATION_MATCH) >= 1, 'the match publisher')
    time.sleep(0.5)  # the new subscription is matched on both sides
    operator.drive(drive, [40], odometry=False, shift=10**10)  # on a second drive, 10 s later
    wait_until(lambda: matches, 'a match')
    assert matches[-1].map_name == 'taught' and matches[-1].index >= 0
    # taught again into the same file, which every node has open: they all load the new map
    handle = operator.send(map_path=str(path), spacing=0.5, overwrite=True)
    operator.drive(drive, range(10), shift=2 * 10**10)
    wait_until(lambda: nodes['localize'].last_stamp == drive.stamps[9] + 2 * 10**10, 'the second drive taken')
    status, again = operator.cancel(handle)
    assert status == GoalStatus.STATUS_CANCELED and 1 < again.snapshots < result.snapshots
    assert len(nodes['localize'].store) == again.snapshots
    assert all(len(nodes[name].snapshots.store) == again.snapshots for name in ('compass', 'warping'))


def test_without_odometry_the_velocity_commands_give_the_route_shape(graph, garden, tmp_path):
    from scipy.spatial.transform import Rotation

    nodes, operator = graph
    drive = garden['teach']
    # the commands that move the drive's ground truth from each frame to the next (an arc of the same chord and turn)
    headings = Rotation.from_quat(drive.poses[:, 3:]).as_euler('zyx')[:, 0]
    steps = np.linalg.norm(np.diff(drive.poses[:, :2], axis=0), axis=1)
    turns = np.arctan2(np.sin(np.diff(headings)), np.cos(np.diff(headings)))
    chords = np.where(np.abs(turns) > 1e-9, np.abs(turns / 2) / np.maximum(np.abs(np.sin(turns / 2)), 1e-12), 1.0)
    seconds = np.diff(drive.stamps.astype(np.int64)) / 1e9
    commands = np.column_stack([steps * chords / seconds, turns / seconds])
    commands = np.vstack([commands, [[np.nan, 0.0]]])  # the last one broken: counted and ignored
    path = tmp_path / 'commanded.db'
    rejected = nodes['localize'].rejected.get('command', 0)
    handle = operator.send(map_path=str(path), spacing=0.3)
    operator.drive(drive, range(len(drive.stamps)), odometry=False, commands=commands)
    wait_until(lambda: nodes['localize'].last_stamp == drive.stamps[-1], 'the last view taken')
    _, result = operator.cancel(handle)
    assert nodes['localize'].rejected['command'] == rejected + 1
    with MapStore.open(path) as store:
        kept = np.searchsorted(drive.stamps, store.stamps())
        assert np.all(np.isnan(store.odometry_poses()))
        shape = store.commanded_poses()[:, :2]
    truth = drive.poses[kept, :2]
    distances = np.linalg.norm(shape[:, None] - shape[None], axis=2)
    true_distances = np.linalg.norm(truth[:, None] - truth[None], axis=2)
    assert np.max(np.abs(distances - true_distances)) < 0.05
    assert result.route_length == pytest.approx(np.sum(steps[kept[0] : kept[-1]]), rel=0.02)


def test_max_length_ends_the_goal_with_success(graph, garden, tmp_path):
    from action_msgs.msg import GoalStatus

    _, operator = graph
    drive = garden['teach']
    handle = operator.send(map_path=str(tmp_path / 'short.db'), spacing=0.5, max_length=2.0)
    operator.drive(drive, range(40))
    status, result = operator.result(handle)
    assert status == GoalStatus.STATUS_SUCCEEDED and error_name(result) == 'NONE'
    assert 2.0 <= result.route_length < 2.5
    with MapStore.open(tmp_path / 'short.db') as store:
        assert len(store) == result.snapshots


def test_goals_that_cannot_be_taught_end_with_named_errors(graph, garden, tmp_path):
    from action_msgs.msg import GoalStatus

    _, operator = graph
    taken = tmp_path / 'taken.db'
    taken.write_bytes(b'not a map')
    status, result = operator.result(operator.send(map_path=str(taken)))
    assert (status, error_name(result)) == (GoalStatus.STATUS_ABORTED, 'MAP_EXISTS')
    assert taken.read_bytes() == b'not a map'
    status, result = operator.result(operator.send(map_path=str(tmp_path / 'no' / 'such.db')))
    assert (status, error_name(result)) == (GoalStatus.STATUS_ABORTED, 'MAP_WRITE_FAILED')
    status, result = operator.result(operator.send(map_path=''))
    assert (status, error_name(result)) == (GoalStatus.STATUS_ABORTED, 'BAD_GOAL')
    # no views at all: NO_INPUT after teach_input_timeout (1 s here); a second goal meanwhile is BUSY
    first = operator.send(map_path=str(tmp_path / 'silent.db'))
    status, result = operator.result(operator.send(map_path=str(tmp_path / 'other.db')))
    assert (status, error_name(result)) == (GoalStatus.STATUS_ABORTED, 'BUSY')
    status, result = operator.result(first)
    assert (status, error_name(result), result.snapshots) == (GoalStatus.STATUS_ABORTED, 'NO_INPUT', 0)
    assert 'no usable view' in result.error_msg
    assert not (tmp_path / 'silent.db').exists()


KILLED_NODE = [sys.executable, '-m', 'skynav_core.run_node', 'skynav_localize.node:LocalizeNode']


def test_a_teach_canceled_before_its_execution_began_writes_no_map(ros_context, tmp_path):
    # rclpy takes a cancel that comes with its goal before the goal's execution starts, when no goal is active
    from skynav_localize.node import LocalizeNode
    from skynav_msgs.action import Teach

    node = LocalizeNode(context=ros_context)
    try:
        handle = CanceledGoalHandle(Teach.Goal(map_path=str(tmp_path / 'taught.db'), spacing=0.3))
        result = run_without_waiting(node.teach.execute(handle))
        assert handle.ended == ['canceled'] and error_name(result) == 'NONE' and result.snapshots == 0
        assert 'no map' in result.error_msg and node.teach.active is None
        assert not (tmp_path / 'taught.db').exists()
    finally:
        node.destroy_node()


def test_a_teach_killed_with_sigkill_leaves_a_readable_map(ros_context, garden, tmp_path):
    drive = garden['teach']
    path = tmp_path / 'killed.db'
    process = subprocess.Popen(KILLED_NODE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    operator = None
    try:
        operator = Operator(ros_context)
        operator.send(map_path=str(path), spacing=0.1)
        # the node's action server may answer before its view subscription is matched: views sent then are lost
        wait_until(lambda: operator.views.get_subscription_count() > 0, "the node's view subscription")
        operator.drive(drive, range(30), period=0.05)
        wait_until(lambda: len(operator.feedback) >= 11, 'ten snapshots')
        process.send_signal(signal.SIGKILL)
        process.wait(timeout=TIMEOUT)
        committed = operator.feedback[-1].snapshots  # each feedback follows its snapshot's commit
    finally:
        if process.poll() is None:
            process.kill()
        if operator is not None:
            operator.close()
    assert process.returncode == -signal.SIGKILL
    with MapStore.open(path) as store:
        assert len(store) >= committed
        kept = np.searchsorted(drive.stamps, store.stamps())
        np.testing.assert_array_equal(drive.stamps[kept], store.stamps())
        np.testing.assert_allclose(store.coefficients(), drive.coefficients[kept])


def test_a_goal_sent_before_the_first_clock_teaches_and_jumps_fire_no_timeout(ros_context, garden, tmp_path):
    """Sim time: the node's clock reads 0 until the first /clock, then jumps to the recording's time, later jumps
    on by 1000 s; no jump counts as silence (NO_INPUT), while a running clock without views still ends the goal."""
    from action_msgs.msg import GoalStatus
    from rosgraph_msgs.msg import Clock

    from skynav_localize.node import LocalizeNode

    node = LocalizeNode(context=ros_context)
    node.set_parameters([Parameter('use_sim_time', value=True), Parameter('teach_input_timeout', value=1.0)])
    executor, thread = spin_in_thread(node, ros_context)
    operator = Operator(ros_context)
    clock = operator.node.create_publisher(Clock, CLOCK, 10)

    def tick(stamp: int) -> None:
        message = Clock()
        message.clock.sec, message.clock.nanosec = divmod(stamp, 10**9)
        clock.publish(message)

    try:
        drive, path = garden['teach'], tmp_path / 'sim_time.db'
        handle = operator.send(map_path=str(path), spacing=0.3)
        result = on_executor_thread(operator.executor, handle.get_result_async)
        time.sleep(2.0)  # twice the input timeout of wall time, with no clock: no time passed
        assert not result.done(), 'the goal ended before the clock started'
        assert node.get_clock().now().nanoseconds == 0
        for part, (frames, shift) in enumerate(((range(0, 20), 0), (range(20, 40), 1000 * 10**9))):
            for k in frames:  # the clock starts (part 0) or jumps 1000 s on (part 1) with the frames
                tick(int(drive.stamps[k]) + shift)
                operator.drive(drive, [k], shift=shift)
            newest = int(drive.stamps[frames[-1]]) + shift
            wait_until(lambda newest=newest: node.last_stamp == newest, f'part {part} taken')
            assert not result.done(), f'part {part}: the goal ended ({result.result() if result.done() else ""})'
        assert node.elapsed.jumps >= 2
        # the clock runs on without views: that is silence, NO_INPUT after 1 s of sim time
        last = int(drive.stamps[39]) + 1000 * 10**9
        for step in range(1, 40):
            tick(last + step * 10**8)
            time.sleep(0.05)
            if result.done():
                break
        wait_until(result.done, 'NO_INPUT on a running clock')
        status, taught = result.result().status, result.result().result
        assert (status, error_name(taught)) == (GoalStatus.STATUS_ABORTED, 'NO_INPUT'), taught.error_msg
        with MapStore.open(path) as store:  # everything taught before the silence is kept, both parts
            stamps = store.stamps()
            assert len(store) == taught.snapshots >= 4
            assert stamps.min() < drive.stamps[20] and stamps.max() > drive.stamps[20] + 1000 * 10**9
    finally:
        operator.close()
        executor.shutdown()
        thread.join(timeout=TIMEOUT)
        node.destroy_node()
