# SPDX-License-Identifier: Apache-2.0
"""The route node keeps the contract's command rules (docs/interfaces.md, "Driving").

The node runs in the in-process graph (its topics delivered synchronously, as in the simulator) and its action
servers answer a real action client over DDS. The test plays the other nodes: for each camera frame it
publishes the place match, compass estimate, home vector and view that the stages would, stamped alike.
"""

import math

import numpy as np
import pytest
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool

from skynav_core.actions import error_name
from skynav_core.graph import in_process
from skynav_core.images import stamp_ns
from skynav_core.maps import Snapshot
from skynav_core.nodes import installed_nodes
from skynav_core.testing import CanceledGoalHandle, run_without_waiting
from skynav_localize.mapping import build_map
from skynav_msgs.action import FollowRoute, Home
from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch, ShCoefficients

START = 1_750_000_000_000_000_000  # ns
FRAME = 200_000_000  # ns between frames
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
        graph.subscribe('/cmd_vel', self.commands.append)
        self.feedback = []
        self.frame = 0

    def spin_until(self, done, seconds=30.0):
        import time

        deadline = time.monotonic() + seconds
        while not done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)
        return done()

    def send(self, kind, name, goal):
        client = ActionClient(self.client_node, kind, name)
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
        self.graph.publish('/clock', clock)
        match = PlaceMatch(map_name='line', index=index, accepted=accepted, distance=0.1)
        compass = CompassEstimate(snapshot_index=index, residual=0.1)
        compass.rotation.z, compass.rotation.w = math.sin(0.1), math.cos(0.1)  # the route runs 0.2 rad to the right
        vector = HomeVector(snapshot_index=index + 6 if home_index is None else home_index, residual=residual)
        vector.direction.x, vector.direction.y = 1.0, 0.0
        vector.rotation.w = 1.0
        view = ShCoefficients(max_degree=4, coefficients=[0.0] * 25, fill='zero', field_of_view=3.5)
        messages = [('/localization/match', match), ('/compass/orientation', compass)]
        if home:
            messages.append(('/homing/home_vector', vector))
        messages.append(('/skyline/sh', view))
        commands, heard = len(self.commands), len(self.feedback)
        for topic, message in messages:
            message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            message.header.frame_id = 'camera_link'
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


def route_graph(route_map, *parameters):
    specs = [s for s in installed_nodes() if s.name == 'route']
    arguments = ['-p', f'map:={route_map}', '-p', 'configure_peers:=false', '-p', 'input_timeout:=1.0']
    for parameter in parameters:
        arguments += ['-p', parameter]
    return in_process(specs, arguments)


def is_zero(command):
    t = command.twist
    return t.linear.x == 0.0 and t.angular.z == 0.0


def test_one_stamped_command_per_frame_while_active_and_a_zero_command_on_cancel(route_map):
    with route_graph(route_map) as graph:
        driver = Driver(graph)
        try:
            for _ in range(3):
                driver.publish_frame()
            assert driver.commands == []  # nothing while no goal is active
            handle, result = driver.send(
                FollowRoute, '/skynav/follow_route', FollowRoute.Goal(start_index=-1, end_index=-1, max_speed=0.3)
            )
            stamps = [driver.publish_frame(index=3 + k // 3) for k in range(10)]
            assert [stamp_ns(c.header) for c in driver.commands] == stamps  # exactly one per frame, its stamp
            for command in driver.commands:
                t = command.twist
                assert command.header.frame_id == 'base_link'
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
                result = run_without_waiting(node.execute_follow(handle))
            else:
                handle = CanceledGoalHandle(Home.Goal(index=4))
                result = run_without_waiting(node.execute_home(handle))
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
            handle, result = driver.send(FollowRoute, '/skynav/follow_route', FollowRoute.Goal(end_index=-1))
            for _ in range(5):
                driver.publish_frame()
            assert not is_zero(driver.commands[-1])
            # the clock runs on, the frames stop coming
            for k in range(1, 7):
                clock = Clock()
                now = driver.stamp() + k * FRAME
                graph.advance(now)
                clock.clock.sec, clock.clock.nanosec = divmod(now, 1_000_000_000)
                graph.publish('/clock', clock)
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
                FollowRoute, '/skynav/follow_route', FollowRoute.Goal(start_index=start, end_index=-1)
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


def test_lost_stops_the_robot_and_aborts(route_map):
    with route_graph(route_map, 'lost_frames:=3') as graph:
        driver = Driver(graph)
        try:
            handle, result = driver.send(FollowRoute, '/skynav/follow_route', FollowRoute.Goal(end_index=-1))
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
            graph.publish('/bumper', Bool(data=False))
            handle, result = driver.send(Home, '/skynav/home', Home.Goal(index=4))
            for _ in range(3):
                driver.publish_frame(home_index=4)
            assert not is_zero(driver.commands[-1])
            graph.publish('/bumper', Bool(data=True))
            assert driver.spin_until(result.done)
            outcome = result.result().result
            assert error_name(outcome) == 'BLOCKED' and 'bumper' in outcome.error_msg
            assert len(driver.commands) == 4 and is_zero(driver.commands[-1])
            driver.publish_frame(home_index=4)
            assert len(driver.commands) == 4  # idle again: nothing
            # still pressed when the next goal begins: its first frame is answered with a stop, stamped alike
            handle, result = driver.send(FollowRoute, '/skynav/follow_route', FollowRoute.Goal(end_index=-1))
            stamp = driver.publish_frame()
            assert driver.spin_until(result.done)
            assert error_name(result.result().result) == 'BLOCKED'
            assert len(driver.commands) == 5 and is_zero(driver.commands[-1])
            assert stamp_ns(driver.commands[-1].header) == stamp
            # released: a goal drives again
            graph.publish('/bumper', Bool(data=False))
            handle, result = driver.send(Home, '/skynav/home', Home.Goal(index=4))
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
        graph.subscribe('/cmd_vel', commands.append)
        driver.send(Home, '/skynav/home', Home.Goal(index=4))
        for _ in range(5):
            driver.publish_frame(home_index=4)
        assert not is_zero(commands[-1])
        driver.close()
    assert len(commands) == 6 and is_zero(commands[-1])  # the node's last word


def test_home_to_an_index_the_map_lacks_aborts_with_a_clear_error(route_map):
    with route_graph(route_map) as graph:
        driver = Driver(graph)
        try:
            client = ActionClient(driver.client_node, Home, '/skynav/home')
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
            client = ActionClient(driver.client_node, FollowRoute, '/skynav/follow_route')
            assert driver.spin_until(client.server_is_ready)
            sent = client.send_goal_async(FollowRoute.Goal(map_path=str(tmp_path / 'missing.db')))
            assert driver.spin_until(sent.done)
            result = sent.result().get_result_async()
            assert driver.spin_until(result.done)
            assert error_name(result.result().result) == 'NO_MAP'
        finally:
            driver.close()


def mount_transform(rpy_deg, parent='base_link', child='camera_link'):
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
        driver.graph.publish('/tf_static', static)
    driver.send(Home, '/skynav/home', Home.Goal(index=9))
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
            static.transforms.append(mount_transform([0.0, 0.0, 0.0], 'base_link', 'mast_link').transforms[0])
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
    from skynav_core.testing import wait_until

    robot = Node('robot_state_publisher', context=ros_context)
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    robot.create_publisher(TFMessage, '/tf_static', qos).publish(mount_transform([0.0, 4.0, 90.0]))
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
