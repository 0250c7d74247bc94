# SPDX-License-Identifier: Apache-2.0
"""The route node keeps the contract's command rules (docs/interfaces.md, "Driving").

The node runs in the in-process graph (its topics delivered synchronously, as in the simulator) and its action
servers answer a real action client over DDS. The test plays the other nodes: for each camera frame it
publishes the place match, compass estimate, home vector and view that the stages would, stamped alike.
"""

import itertools
import math
import os

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Twist, TwistStamped
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool

from skynav_core.actions import error_name
from skynav_core.graph import in_process
from skynav_core.images import stamp_ns
from skynav_core.maps import Snapshot
from skynav_core.names import (
    BASE_FRAME,
    BUMPER,
    CAMERA_FRAME,
    CLOCK,
    CMD_VEL,
    COMPASS_ORIENTATION,
    EMERGENCY_STOP,
    FOLLOW_ROUTE_ACTION,
    HOME_ACTION,
    HOME_VECTOR,
    IMU,
    LOCALIZATION_MATCH,
    SKYLINE_SH,
    TF_STATIC,
)
from skynav_core.namespaces import relative
from skynav_core.nodes import installed_nodes
from skynav_localize.mapping import build_map
from skynav_msgs.action import FollowRoute, Home
from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch, ShCoefficients
from skynav_testing import CanceledGoalHandle, run_without_waiting

START = 1_750_000_000_000_000_000  # ns
FRAME = 200_000_000  # ns between frames
GRAPHS = itertools.count()  # numbers the in-process graphs of this module, each in a namespace of its own
SNAPSHOTS = 20


@pytest.fixture(scope='module')
def route_map(tmp_path_factory):
    path = tmp_path_factory.mktemp('maps') / 'line.db'
    rng = np.random.default_rng(1)
    snapshots = [Snapshot(k, START - (SNAPSHOTS - k) * FRAME, rng.normal(size=25)) for k in range(SNAPSHOTS)]
    build_map(path, 'line', 4, snapshots, created_from='test (synthetic)', overwrite=True).close()
    return path


class Driver:
    """The route node in an in-process graph, an action client and the messages the other nodes would send."""

    def __init__(self, graph):
        self.graph = graph
        self.node = graph.nodes[0]
        self.client_node = Node('route_test_client', context=self.node.context)
        self.executor = SingleThreadedExecutor(context=self.node.context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.client_node)
        self.commands = []
        graph.subscribe(CMD_VEL, self.commands.append)
        self.feedback = []
        self.frame = 0

    def spin_until(self, done, seconds=30.0):
        import time

        deadline = time.monotonic() + seconds
        while not done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)
        return done()

    def send(self, kind, name, goal):
        client = ActionClient(self.client_node, kind, relative(name))  # in the graph's namespace
        assert self.spin_until(client.server_is_ready)
        sent = client.send_goal_async(goal, feedback_callback=lambda m: self.feedback.append(m.feedback))
        assert self.spin_until(sent.done) and sent.result().accepted
        handle = sent.result()
        result = handle.get_result_async()
        assert self.spin_until(lambda: bool(self.feedback) or result.done())  # set up for the goal
        return handle, result

    def stamp(self):
        return START + self.frame * FRAME

    def publish_frame(self, index=3, accepted=True, home=True, residual=0.3, home_index=None):
        """Publish one frame's outputs of the stages, then its view; return its stamp (ns)."""
        stamp = self.stamp()
        self.frame += 1
        self.graph.advance(stamp)
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = divmod(stamp, 1_000_000_000)
        self.graph.publish(CLOCK, clock)
        match = PlaceMatch(map_name='line', index=index, accepted=accepted, distance=0.1)
        compass = CompassEstimate(snapshot_index=index, residual=0.1, confidence=0.9, confident=True)
        compass.rotation.z, compass.rotation.w = math.sin(0.1), math.cos(0.1)  # the route runs 0.2 rad to the right
        vector = HomeVector(snapshot_index=index + 6 if home_index is None else home_index, residual=residual)
        vector.direction.x, vector.direction.y = 1.0, 0.0
        vector.rotation.w = 1.0
        view = ShCoefficients(max_degree=4, coefficients=[0.0] * 25, fill='zero', field_of_view=3.5)
        messages = [(LOCALIZATION_MATCH, match), (COMPASS_ORIENTATION, compass)]
        if home:
            messages.append((HOME_VECTOR, vector))
        messages.append((SKYLINE_SH, view))
        commands, heard = len(self.commands), len(self.feedback)
        for topic, message in messages:
            message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            message.header.frame_id = CAMERA_FRAME
            self.graph.publish(topic, message)
        if len(self.commands) > commands:  # its feedback comes before the next frame (the client drops late ones)
            self.spin_until(lambda: len(self.feedback) > heard, 10.0)
        self.executor.spin_once(timeout_sec=0)
        return stamp

    def close(self):
        self.executor.remove_node(self.node)
        self.executor.remove_node(self.client_node)
        self.client_node.destroy_node()
        self.executor.shutdown()


def route_graph(route_map, *parameters, others=()):
    """The route node (and the nodes named in `others` after it) in an in-process graph of a namespace of its own:
    the action servers of earlier tests' graphs, which discovery may still list for a while, are never matched
    instead of this one's."""
    specs = [s for name in ('route', *others) for s in installed_nodes() if s.name == name]
    arguments = ['-r', f'__ns:=/route_test_{os.getpid()}_{next(GRAPHS)}']
    arguments += ['-p', f'map:={route_map}', '-p', 'configure_peers:=false', '-p', 'input_timeout:=1.0']
    for parameter in parameters:
        arguments += ['-p', parameter]
    return in_process(specs, arguments)


def is_zero(command):
    t = getattr(command, 'twist', command)  # a TwistStamped, or a bare Twist (cmd_vel_stamped false)
    return t.linear.x == 0.0 and t.angular.z == 0.0


def publish_clock(graph, now):
    """Set the graph's time to `now` (ns) and publish it on /clock (the watchdog's tick in the in-process graph)."""
    clock = Clock()
    graph.advance(now)
    clock.clock.sec, clock.clock.nanosec = divmod(now, 1_000_000_000)
    graph.publish(CLOCK, clock)


def test_one_stamped_command_per_frame_while_active_and_a_zero_command_on_cancel(route_map):
    with route_graph(route_map) as graph:
        driver = Driver(graph)
        try:
            for _ in range(3):
                driver.publish_frame()
            assert driver.commands == []  # nothing while no goal is active
            handle, result = driver.send(
                FollowRoute, FOLLOW_ROUTE_ACTION, FollowRoute.Goal(start_index=-1, end_index=-1, max_speed=0.3)
            )
            stamps = [driver.publish_frame(index=3 + k // 3) for k in range(10)]
            assert [stamp_ns(c.header) for c in driver.commands] == stamps  # exactly one per frame, its stamp
            for command in driver.commands:
                t = command.twist
                assert command.header.frame_id == BASE_FRAME
                assert (t.linear.y, t.linear.z, t.angular.x, t.angular.y) == (0.0, 0.0, 0.0, 0.0)
            assert driver.commands[-1].twist.linear.x > 0.1  # it drives
            assert driver.commands[-1].twist.angular.z < 0  # towards the route, which runs to the right
            assert driver.spin_until(lambda: len(driver.feedback) >= 11)
            assert driver.feedback[-1].state == 'following' and driver.feedback[-1].matched_index == 6
            cancel = handle.cancel_goal_async()
            assert driver.spin_until(result.done)
            assert cancel.done() and result.result().status == 5  # CANCELED
            assert len(driver.commands) == 11 and is_zero(driver.commands[-1])
            driver.publish_frame(index=7)
            assert len(driver.commands) == 11  # idle again: nothing
        finally:
            driver.close()


@pytest.mark.parametrize('kind', ['follow', 'home'])
def test_a_goal_canceled_before_its_execution_began_never_drives(route_map, kind):
    # rclpy takes a cancel that comes with its goal before the goal's execution starts, when no goal is active
    with route_graph(route_map) as graph:
        driver = Driver(graph)
        try:
            node = driver.node
            if kind == 'follow':
                handle = CanceledGoalHandle(FollowRoute.Goal(start_index=-1, end_index=-1, max_speed=0.3))
                result = run_without_waiting(node.goal_server.execute_follow(handle))
            else:
                handle = CanceledGoalHandle(Home.Goal(index=4))
                result = run_without_waiting(node.goal_server.execute_home(handle))
            assert handle.ended == ['canceled'] and error_name(result) == 'NONE' and node.active is None
            for _ in range(3):
                driver.publish_frame(home_index=4)
            assert len(driver.commands) == 1 and is_zero(driver.commands[0])  # the stop at its end, nothing else
        finally:
            driver.close()


def test_stale_inputs_stop_the_robot_and_abort(route_map):
    with route_graph(route_map) as graph:
        driver = Driver(graph)
        try:
            handle, result = driver.send(FollowRoute, FOLLOW_ROUTE_ACTION, FollowRoute.Goal(end_index=-1))
            for _ in range(5):
                driver.publish_frame()
            assert not is_zero(driver.commands[-1])
            # the clock runs on, the frames stop coming
            for k in range(1, 7):
                clock = Clock()
                now = driver.stamp() + k * FRAME
                graph.advance(now)
                clock.clock.sec, clock.clock.nanosec = divmod(now, 1_000_000_000)
                graph.publish(CLOCK, clock)
            assert driver.spin_until(result.done)
            assert error_name(result.result().result) == 'STALE_INPUT'
            assert len(driver.commands) == 6 and is_zero(driver.commands[-1])
        finally:
            driver.close()


@pytest.mark.parametrize('start', [-1, 0])
def test_a_robot_never_placed_on_the_route_is_lost_where_it_stands(route_map, start):
    with route_graph(route_map, 'lost_frames:=3') as graph:
        driver = Driver(graph)
        try:
            handle, result = driver.send(
                FollowRoute, FOLLOW_ROUTE_ACTION, FollowRoute.Goal(start_index=start, end_index=-1)
            )
            for _ in range(4):
                driver.publish_frame(accepted=False)
            assert driver.spin_until(result.done)
            outcome = result.result().result
            assert error_name(outcome) == 'LOST' and 'never moved' in outcome.error_msg
            assert ('--from' in outcome.error_msg) == (start < 0)  # the hint only where no start was given
            assert outcome.reached_index == -1 and all(is_zero(c) for c in driver.commands)
        finally:
            driver.close()


def test_home_arrives_on_frames_whose_home_vector_the_warping_node_refused(route_map):
    # the warping node publishes no home vector whose direction the views do not determine (at the snapshot): with
    # it in the graph, frames without one are unsure, and a few in a row mean arrived; without it they are missing
    # (a warping node that refuses every view while the place match lies far from the goal's snapshot would look
    # the same: those frames are missing, and the goal is lost, not reached where the robot stands)
    cases = ((('warping',), 4, 'NONE'), ((), 4, 'LOST'), (('warping',), 12, 'LOST'))
    for others, matched, outcome in cases:
        with route_graph(route_map, 'lost_frames:=3', 'arrived_frames:=3', others=others) as graph:
            driver = Driver(graph)
            try:
                assert driver.node.home_vectors_come() == bool(others)
                handle, result = driver.send(Home, HOME_ACTION, Home.Goal(index=4))
                for _ in range(5):
                    if not result.done():
                        driver.publish_frame(index=matched, home=False)
                assert driver.spin_until(result.done)
                assert error_name(result.result().result) == outcome
                assert all(is_zero(c) for c in driver.commands)  # started at home: it never drove
                assert len(driver.commands) == (3 if outcome == 'NONE' else 4)
            finally:
                driver.close()


def test_lost_stops_the_robot_and_aborts(route_map):
    with route_graph(route_map, 'lost_frames:=3') as graph:
        driver = Driver(graph)
        try:
            handle, result = driver.send(FollowRoute, FOLLOW_ROUTE_ACTION, FollowRoute.Goal(end_index=-1))
            for _ in range(4):
                driver.publish_frame()
            stamps = [driver.publish_frame(accepted=False, home=False) for _ in range(4)]
            assert driver.spin_until(result.done)
            outcome = result.result().result
            assert error_name(outcome) == 'LOST' and 'lost' in outcome.error_msg
            assert [stamp_ns(c.header) for c in driver.commands[-4:]] == stamps  # frames without a home vector too
            assert driver.spin_until(lambda: len(driver.feedback) == 9)  # the goal's first feedback and one per frame
            assert [f.state for f in driver.feedback[-4:]] == ['recovering'] * 3 + ['stopping']
            assert is_zero(driver.commands[-1]) and not is_zero(driver.commands[-2])
        finally:
            driver.close()


def test_bumper_contact_stops_the_robot_and_aborts_blocked(route_map):
    with route_graph(route_map) as graph:
        driver = Driver(graph)
        try:
            graph.publish(BUMPER, Bool(data=False))
            handle, result = driver.send(Home, HOME_ACTION, Home.Goal(index=4))
            for _ in range(3):
                driver.publish_frame(home_index=4)
            assert not is_zero(driver.commands[-1])
            graph.publish(BUMPER, Bool(data=True))
            assert driver.spin_until(result.done)
            outcome = result.result().result
            assert error_name(outcome) == 'BLOCKED' and 'bumper' in outcome.error_msg
            assert len(driver.commands) == 4 and is_zero(driver.commands[-1])
            driver.publish_frame(home_index=4)
            assert len(driver.commands) == 4  # idle again: nothing
            # still pressed when the next goal begins: its first frame is answered with a stop, stamped alike
            handle, result = driver.send(FollowRoute, FOLLOW_ROUTE_ACTION, FollowRoute.Goal(end_index=-1))
            stamp = driver.publish_frame()
            assert driver.spin_until(result.done)
            assert error_name(result.result().result) == 'BLOCKED'
            assert len(driver.commands) == 5 and is_zero(driver.commands[-1])
            assert stamp_ns(driver.commands[-1].header) == stamp
            # released: a goal drives again
            graph.publish(BUMPER, Bool(data=False))
            handle, result = driver.send(Home, HOME_ACTION, Home.Goal(index=4))
            for _ in range(3):
                driver.publish_frame(home_index=4)
            assert len(driver.commands) == 8 and not is_zero(driver.commands[-1])
            handle.cancel_goal_async()
            assert driver.spin_until(result.done)
        finally:
            driver.close()


def test_shutdown_stops_the_robot(route_map):
    commands = []
    with route_graph(route_map) as graph:
        driver = Driver(graph)
        graph.subscribe(CMD_VEL, commands.append)
        driver.send(Home, HOME_ACTION, Home.Goal(index=4))
        for _ in range(5):
            driver.publish_frame(home_index=4)
        assert not is_zero(commands[-1])
        driver.close()
    assert len(commands) == 6 and is_zero(commands[-1])  # the node's last word


def test_home_to_an_index_the_map_lacks_aborts_with_a_clear_error(route_map):
    with route_graph(route_map) as graph:
        driver = Driver(graph)
        try:
            client = ActionClient(driver.client_node, Home, relative(HOME_ACTION))
            assert driver.spin_until(client.server_is_ready)
            sent = client.send_goal_async(Home.Goal(index=SNAPSHOTS))
            assert driver.spin_until(sent.done)
            result = sent.result().get_result_async()
            assert driver.spin_until(result.done)
            outcome = result.result().result
            assert error_name(outcome) == 'BAD_INDEX'
            assert outcome.error_msg == f'no snapshot {SNAPSHOTS}: the map has snapshots 0..{SNAPSHOTS - 1}'
            driver.publish_frame()
            assert driver.commands == []  # it never drove
        finally:
            driver.close()


def test_a_goal_without_a_map_aborts_no_map(tmp_path, route_map):
    with route_graph(route_map) as graph:
        driver = Driver(graph)
        try:
            client = ActionClient(driver.client_node, FollowRoute, relative(FOLLOW_ROUTE_ACTION))
            assert driver.spin_until(client.server_is_ready)
            sent = client.send_goal_async(FollowRoute.Goal(map_path=str(tmp_path / 'missing.db')))
            assert driver.spin_until(sent.done)
            result = sent.result().get_result_async()
            assert driver.spin_until(result.done)
            assert error_name(result.result().result) == 'NO_MAP'
        finally:
            driver.close()


def mount_transform(rpy_deg, parent=BASE_FRAME, child=CAMERA_FRAME):
    """Return a tf2_msgs/TFMessage of one transform parent -> child turned by roll, pitch, yaw (deg)."""
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    from skynav_core.rotations import as_quaternion, rpy_matrix

    transform = TransformStamped(child_frame_id=child)
    transform.header.frame_id = parent
    transform.transform.translation.z = 0.3
    q = transform.transform.rotation
    q.x, q.y, q.z, q.w = map(float, as_quaternion(rpy_matrix(*np.radians(rpy_deg))))
    return TFMessage(transforms=[transform])


def home_turn(driver, static=None):
    """Send a Home goal, answer 3 frames whose home vector is the camera's +x (and publish `static` on /tf_static
    first); return the last command's turn rate (rad/s)."""
    if static is not None:
        driver.graph.publish(TF_STATIC, static)
    driver.send(Home, HOME_ACTION, Home.Goal(index=9))
    for _ in range(3):
        driver.publish_frame(home_index=9)
    return driver.commands[-1].twist.angular.z


# the home vector points along the camera's +x: ahead of a camera on the robot's axes, left of one turned right
@pytest.mark.parametrize(
    'mount, turn', [(None, 0), ('[0, 0, 90]', 1), ('[0.0, 4.0, -90.0]', -1), ('[0.0, 0.0, 180.0]', None)]
)
def test_the_route_node_steers_on_home_vectors_turned_by_the_mount_parameter(route_map, mount, turn):
    with route_graph(route_map, *([f'camera_mount_rpy_deg:={mount}'] if mount else [])) as graph:
        driver = Driver(graph)
        try:
            angular = home_turn(driver)
            assert driver.node.rejected == {}
        finally:
            driver.close()
    if turn is None:  # home behind: a hard turn either way, no speed
        assert abs(angular) > 0.5 and driver.commands[-1].twist.linear.x == 0.0
    else:
        assert np.sign(round(angular, 9)) == turn and (turn == 0 or abs(angular) > 0.5)


def test_tf_static_wins_over_the_mount_parameter(route_map):
    # a robot_state_publisher says the camera is turned right, the parameter says left: /tf_static is believed
    with route_graph(route_map, 'camera_mount_rpy_deg:=[0.0, 0.0, 90.0]') as graph:
        driver = Driver(graph)
        try:
            static = mount_transform([0.0, 0.0, -90.0], 'mast_link')
            static.transforms.append(mount_transform([0.0, 0.0, 0.0], BASE_FRAME, 'mast_link').transforms[0])
            assert home_turn(driver, static) < -0.5
            assert driver.node.rejected == {}
            np.testing.assert_allclose(driver.node.mount[:, 0], [0.0, -1.0, 0.0], atol=1e-12)
        finally:
            driver.close()


def test_an_unusable_mount_is_refused_and_the_node_keeps_its_mount(route_map):
    from rclpy.parameter import Parameter

    with route_graph(route_map, 'camera_mount_rpy_deg:=[0.0, 90.0]') as graph:
        node = graph.nodes[0]
        assert node.rejected == {'parameters': 1}  # at start-up: the default, with one log line
        assert node.get_parameter('camera_mount_rpy_deg').value == [0.0, 0.0, 0.0]
        assert np.array_equal(node.mount, np.eye(3))
        assert node.set_parameters([Parameter('camera_mount_rpy_deg', value=[0.0, 0.0, 90.0])])[0].successful
        for bad in ([1.0, float('nan'), 0.0], 'yaw 90', [0.0, 0.0, 0.0, 1.0]):
            result = node.set_parameters([Parameter('camera_mount_rpy_deg', value=bad)])[0]
            assert not result.successful and 'camera_mount_rpy_deg' in result.reason and '\n' not in result.reason
        np.testing.assert_allclose(node.mount[:, 0], [0.0, 1.0, 0.0], atol=1e-12)  # still turned left
        broken = mount_transform([0.0, 0.0, -90.0])
        broken.transforms[0].transform.rotation.z = float('nan')
        node.on_static_transforms(broken)  # a broken /tf_static: one reject, and the mount stays
        assert node.rejected['transform'] == 1 and node.static_mount is None


def test_a_latched_tf_static_published_before_the_node_started_reaches_it(ros_context):
    # as robot_state_publisher publishes it: once, reliable, transient local, depth 1
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from skynav_route.node import RouteNode
    from tf2_msgs.msg import TFMessage

    from skynav_core.mount import mount_rpy_deg
    from skynav_testing import wait_until

    robot = Node('robot_state_publisher', context=ros_context)
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    robot.create_publisher(TFMessage, TF_STATIC, qos).publish(mount_transform([0.0, 4.0, 90.0]))
    node = RouteNode(context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    try:
        wait_until(lambda: executor.spin_once(timeout_sec=0.05) or node.static_mount is not None, 'the mount', 20.0)
        assert mount_rpy_deg(node.mount) == pytest.approx((0.0, 4.0, 90.0))
    finally:
        executor.remove_node(node)
        node.destroy_node()
        robot.destroy_node()
        executor.shutdown()


def test_a_goal_sent_while_the_clock_reads_zero_drives_once_it_starts(route_map):
    # sim time before the first /clock: the node's clock reads 0 when the goal comes, then jumps to the simulator's
    with route_graph(route_map) as graph:
        driver = Driver(graph)
        try:
            handle, result = driver.send(FollowRoute, FOLLOW_ROUTE_ACTION, FollowRoute.Goal(end_index=-1))
            for _ in range(3):
                publish_clock(graph, 0)  # the watchdog looks while the clock stands at zero
            stamps = [driver.publish_frame(index=3 + k // 3) for k in range(10)]  # 2 s at START (1.75e9 s)
            assert not result.done()  # neither TIMEOUT nor STALE_INPUT from the jump
            assert [stamp_ns(c.header) for c in driver.commands] == stamps and not is_zero(driver.commands[-1])
            assert driver.node.elapsed.jumps >= 1  # the jump was seen, and left out
            # the watchdog still measures the time that passes: frames stop, STALE_INPUT after input_timeout
            for k in range(1, 7):
                publish_clock(graph, driver.stamp() + k * FRAME)
            assert driver.spin_until(result.done)
            assert error_name(result.result().result) == 'STALE_INPUT' and is_zero(driver.commands[-1])
        finally:
            driver.close()


def test_a_clock_that_jumps_back_fires_no_timeout_and_the_frames_are_answered(route_map):
    # a recording replayed with its own clock starts again an hour earlier while the goal runs
    with route_graph(route_map, 'goal_timeout:=1.0', 'goal_time_factor:=0.0') as graph:
        driver = Driver(graph)
        try:
            handle, result = driver.send(Home, HOME_ACTION, Home.Goal(index=4))
            before = [driver.publish_frame(home_index=4) for _ in range(4)]  # 0.6 s of the 1 s limit
            driver.frame -= 3600 * 5  # an hour back (5 frames a second)
            after = [driver.publish_frame(home_index=4) for _ in range(2)]  # the jump counts as nothing: 0.8 s
            assert not result.done()
            assert [stamp_ns(c.header) for c in driver.commands] == before + after  # each answered, the jump too
            assert not is_zero(driver.commands[-1])
            assert driver.node.rejected == {}  # no frame taken as late or out of order
            # the limit still counts the time that passes after the jump: 1 s of goal in all
            driver.publish_frame(home_index=4)  # 1.0 s: not over it
            assert not result.done()
            driver.publish_frame(home_index=4)  # 1.2 s
            assert driver.spin_until(result.done)
            outcome = result.result().result
            assert error_name(outcome) == 'TIMEOUT' and is_zero(driver.commands[-1])
            assert outcome.error_msg == (
                'the goal ran longer than its time limit of 1.0 s: goal_timeout 1 s + goal_time_factor 0 x 10.0 m '
                '(home_distance) at 0.3 m/s'
            )
        finally:
            driver.close()


def test_home_vectors_that_lag_the_views_restart_no_time(route_map):
    # warping a second and more behind on a loaded computer: its home vectors are late, not a clock that jumped
    with route_graph(route_map, 'lost_frames:=100') as graph:  # frames without a home vector: recovering, not LOST
        driver = Driver(graph)
        try:
            handle, result = driver.send(Home, HOME_ACTION, Home.Goal(index=4))
            stamps = []
            for k in range(12):
                stamps.append(driver.publish_frame(home=False))
                if k >= 8:  # the home vector of the frame 1.6 s before
                    vector = HomeVector(snapshot_index=4, residual=0.3)
                    vector.direction.x, vector.rotation.w = 1.0, 1.0
                    vector.header.stamp.sec, vector.header.stamp.nanosec = divmod(stamps[k - 8], 1_000_000_000)
                    graph.publish(HOME_VECTOR, vector)
            assert [stamp_ns(c.header) for c in driver.commands] == stamps  # each frame answered once, in order
            assert driver.node.time_resets == 0 and driver.node.rejected == {'late': 4}
            handle.cancel_goal_async()
            assert driver.spin_until(result.done)
        finally:
            driver.close()


def test_a_follow_goal_that_runs_past_its_limit_aborts_timeout_saying_how_the_limit_was_computed(route_map):
    # the test map has no odometry, commands or spacing: 19 gaps of the assumed spacing from snapshot 0 to 19
    with route_graph(route_map, 'goal_timeout:=0.2', 'goal_time_factor:=0.1', 'max_speed:=9.5') as graph:
        driver = Driver(graph)
        try:
            handle, result = driver.send(FollowRoute, FOLLOW_ROUTE_ACTION, FollowRoute.Goal(end_index=-1))
            publish_clock(graph, 0)  # the clock starts after the goal
            for _ in range(3):  # 0.4 s: 0.2 s + 0.1 x 19 m / 9.5 m/s
                driver.publish_frame()
            assert not result.done()
            driver.publish_frame()  # 0.6 s
            assert driver.spin_until(result.done)
            outcome = result.result().result
            assert error_name(outcome) == 'TIMEOUT' and len(driver.commands) == 4 and is_zero(driver.commands[-1])
            assert outcome.error_msg.startswith('the goal ran longer than its time limit of 0.4 s: goal_timeout 0.2 s')
            assert '19.0 m (the route from snapshot 0 to 19, snapshots taken as 1 m apart' in outcome.error_msg
        finally:
            driver.close()


@pytest.mark.parametrize('kind', ['follow', 'home'])
def test_an_emergency_stop_stops_the_robot_at_once_aborts_and_nothing_moves_until_a_new_goal(route_map, kind):
    def send():
        if kind == 'follow':
            return driver.send(FollowRoute, FOLLOW_ROUTE_ACTION, FollowRoute.Goal(end_index=-1))
        return driver.send(Home, HOME_ACTION, Home.Goal(index=9))

    with route_graph(route_map) as graph:
        driver = Driver(graph)
        node = driver.node
        try:
            graph.publish(EMERGENCY_STOP, Bool(data=False))
            handle, result = send()
            for _ in range(3):
                driver.publish_frame(home_index=9)
            assert len(driver.commands) == 3 and not is_zero(driver.commands[-1])
            graph.publish(EMERGENCY_STOP, Bool(data=True))
            assert len(driver.commands) == 4 and is_zero(driver.commands[-1])  # at once, before the next frame
            assert driver.spin_until(result.done)
            outcome = result.result().result
            assert error_name(outcome) == 'EMERGENCY_STOP' and 'emergency stop' in outcome.error_msg
            status = {v.key: v.value for v in node.diagnostic_status().values}
            assert (status['emergency_stop'], status['emergency_stops']) == ('true', '1')
            assert node.diagnostic_status().level == DiagnosticStatus.WARN
            for _ in range(2):
                driver.publish_frame(home_index=9)
            assert len(driver.commands) == 4  # no goal: nothing
            # a goal while the stop is still engaged is refused and never moves
            handle, result = send()
            assert driver.spin_until(result.done)
            assert error_name(result.result().result) == 'EMERGENCY_STOP'
            driver.publish_frame(home_index=9)
            graph.publish(EMERGENCY_STOP, Bool(data=True))  # still engaged: no second stop, no command
            assert len(driver.commands) == 4 and node.emergency_stops == 1
            # released: still nothing until a new goal
            graph.publish(EMERGENCY_STOP, Bool(data=False))
            for _ in range(2):
                driver.publish_frame(home_index=9)
            assert len(driver.commands) == 4
            assert {v.key: v.value for v in node.diagnostic_status().values}['emergency_stop'] == 'false'
            # a new goal drives again
            handle, result = send()
            for _ in range(3):
                driver.publish_frame(home_index=9)
            assert len(driver.commands) == 7 and not is_zero(driver.commands[-1])
            handle.cancel_goal_async()
            assert driver.spin_until(result.done)
        finally:
            driver.close()


def test_cmd_vel_stamped_false_publishes_a_bare_twist_for_every_command(route_map):
    with route_graph(route_map, 'cmd_vel_stamped:=false') as graph:
        driver = Driver(graph)
        try:
            handle, result = driver.send(Home, HOME_ACTION, Home.Goal(index=9))
            for _ in range(3):
                driver.publish_frame(home_index=9)
            handle.cancel_goal_async()
            assert driver.spin_until(result.done)
            assert len(driver.commands) == 4 and all(type(c) is Twist for c in driver.commands)
            moving, stop = driver.commands[-2], driver.commands[-1]
            assert moving.linear.x > 0.0 and is_zero(stop)
            for command in driver.commands:
                assert (command.linear.y, command.linear.z, command.angular.x, command.angular.y) == (0.0,) * 4
            # the message type is the publisher's: it cannot change at run time
            from rclpy.parameter import Parameter

            refused = driver.node.set_parameters([Parameter('cmd_vel_stamped', value=True)])[0]
            assert not refused.successful and 'start-up' in refused.reason
        finally:
            driver.close()


@pytest.mark.parametrize('stamped', [True, False])
def test_the_live_node_publishes_the_velocity_type_cmd_vel_stamped_asks_for(route_map, stamped):
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions
    from skynav_route.node import RouteNode

    from skynav_testing import wait_until

    context = Context()
    arguments = ['--ros-args', '-p', f'cmd_vel_stamped:={str(stamped).lower()}', '-r', 'cmd_vel:=/base/cmd_vel']
    rclpy.init(args=arguments, context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = RouteNode(context=context)
    listener = Node('base', context=context, use_global_arguments=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(listener)
    kind = TwistStamped if stamped else Twist
    commands = []
    listener.create_subscription(kind, '/base/cmd_vel', commands.append, 10)
    try:
        wait_until(lambda: executor.spin_once(timeout_sec=0.05) or node.count_subscribers('/base/cmd_vel'), 'a match')
        node.stop(START)  # a zero command, as at the end of every goal
        wait_until(lambda: executor.spin_once(timeout_sec=0.05) or commands, 'the command')
        topics = dict(listener.get_topic_names_and_types())
        assert topics['/base/cmd_vel'] == [f'geometry_msgs/msg/{kind.__name__}']  # remapped, of that type alone
        assert CMD_VEL not in topics
        assert type(commands[0]) is kind and is_zero(commands[0])
        if stamped:
            assert stamp_ns(commands[0].header) == START and commands[0].header.frame_id == BASE_FRAME
    finally:
        executor.shutdown()
        listener.destroy_node()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_a_namespaced_node_serves_its_actions_and_sets_its_peers_in_its_namespace(route_map):
    specs = [s for s in installed_nodes() if s.name == 'route']
    arguments = ['-r', '__ns:=/robot1', '-p', f'map:={route_map}', '-p', 'peer_timeout:=30.0']
    with in_process(specs, arguments) as graph:
        driver = Driver(graph)
        node = driver.node
        compass = Node('compass', namespace='/robot1', context=node.context, use_global_arguments=False)
        compass.declare_parameter('reference', 'index')
        driver.executor.add_node(compass)
        try:
            client = ActionClient(driver.client_node, Home, '/robot1/skynav/home')
            assert driver.spin_until(client.server_is_ready)
            # the route node's own services (the graph may still show nodes of earlier tests outside the namespace)
            services = {name for name, _ in driver.client_node.get_service_names_and_types_by_node('route', '/robot1')}
            assert '/robot1/skynav/home/_action/send_goal' in services
            assert '/robot1/skynav/follow_route/_action/send_goal' in services
            assert all(name.startswith('/robot1/') for name in services)
            task = driver.executor.create_task(node.goal_server.set_context({'compass': {'reference': 'match'}}))
            assert driver.spin_until(task.done)
            assert compass.get_parameter('reference').value == 'match'  # found as /robot1/compass
        finally:
            driver.executor.remove_node(compass)
            compass.destroy_node()
            driver.close()


def test_waiting_for_a_peer_ends_while_sim_time_stands_still(route_map):
    # use_sim_time and no /clock yet: the node's clock reads 0 and does not move; the wait is on steady time
    with route_graph(route_map, 'use_sim_time:=true', 'configure_peers:=true', 'peer_timeout:=0.2') as graph:
        driver = Driver(graph)
        try:
            assert driver.node.get_clock().now().nanoseconds == 0
            task = driver.executor.create_task(driver.node.goal_server.set_context({'nobody': {'reference': 'match'}}))
            assert driver.spin_until(task.done)  # it gave up on the node that does not answer
            assert task.exception() is None
        finally:
            driver.close()


def imu_at(stamp, tilt_deg):
    """Return a sensor_msgs/Imu stamped `stamp` (ns) of a robot rolled by `tilt_deg` (its orientation)."""
    from sensor_msgs.msg import Imu

    imu = Imu()
    imu.header.frame_id = BASE_FRAME
    imu.header.stamp.sec, imu.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
    imu.orientation.x, imu.orientation.w = math.sin(math.radians(tilt_deg) / 2), math.cos(math.radians(tilt_deg) / 2)
    return imu


def test_an_imu_that_shows_the_robot_tipping_stops_it_like_the_emergency_stop(route_map):
    with route_graph(route_map, 'max_tilt_deg:=35.0') as graph:
        driver = Driver(graph)
        node = driver.node
        try:
            handle, result = driver.send(Home, HOME_ACTION, Home.Goal(index=9))
            for _ in range(2):
                stamp = driver.publish_frame(home_index=9)
                graph.publish(IMU, imu_at(stamp, 20.0))  # a slope: it drives on
            graph.publish(IMU, imu_at(stamp + 10_000_000, 50.0))  # a jolt, not lasting
            graph.publish(IMU, imu_at(stamp + 20_000_000, 10.0))
            driver.publish_frame(home_index=9)
            assert not result.done() and len(driver.commands) == 3 and not is_zero(driver.commands[-1])
            start = driver.stamp()
            graph.publish(IMU, imu_at(start, 45.0))
            graph.publish(IMU, imu_at(start + 100_000_000, 45.0))  # 0.1 s over: not yet
            assert len(driver.commands) == 3
            graph.publish(IMU, imu_at(start + 200_000_000, 45.0))  # 0.2 s: stop at once
            assert len(driver.commands) == 4 and is_zero(driver.commands[-1])
            assert driver.spin_until(result.done)
            outcome = result.result().result
            assert error_name(outcome) == 'EMERGENCY_STOP'
            assert outcome.error_msg == (
                'emergency stop: the robot leans 45 deg from the vertical, over max_tilt_deg 35; the robot stopped'
            )
            assert node.emergency_stops == 1
            handle, result = driver.send(Home, HOME_ACTION, Home.Goal(index=9))  # still tipped: refused
            assert driver.spin_until(result.done) and error_name(result.result().result) == 'EMERGENCY_STOP'
            graph.publish(IMU, imu_at(start + 300_000_000, 5.0))  # level again: a new goal drives
            handle, result = driver.send(Home, HOME_ACTION, Home.Goal(index=9))
            for _ in range(2):
                driver.publish_frame(home_index=9)
            assert len(driver.commands) == 6 and not is_zero(driver.commands[-1])
            handle.cancel_goal_async()
            assert driver.spin_until(result.done)
        finally:
            driver.close()
