# SPDX-License-Identifier: Apache-2.0
"""The `skynav` tools against a live graph: echo, bad bags for replay, and launching a node."""

import signal
import subprocess
import sys
import textwrap
import time

import pytest
import yaml

from skynav_core.names import CAMERA_FRAME, LOCALIZATION_MATCH, UV_IMAGE
from skynav_testing import one_line_error, run_skynav, start_skynav, wait_text, write_sample_bag

pytestmark = pytest.mark.heavy(50)


def test_echo_prints_a_custom_message_as_yaml(ros_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from skynav_core.ros import message_class

    PlaceMatch = message_class('skynav_msgs/msg/PlaceMatch')
    node = Node('match_source', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    publisher = node.create_publisher(PlaceMatch, LOCALIZATION_MATCH, 10)
    message = PlaceMatch(
        map_name='garden',
        index=42,
        distance=0.125,
        accepted=True,
        candidate_indices=list(range(40)),
        candidate_distances=[0.5, 1.5],
    )
    message.header.frame_id = CAMERA_FRAME
    message.snapshot_stamp.sec = 1234
    echo = start_skynav('echo', LOCALIZATION_MATCH, '--once')
    deadline = time.monotonic() + 60
    while echo.poll() is None and time.monotonic() < deadline:
        publisher.publish(message)
        executor.spin_once(timeout_sec=0.1)
    out, err = echo.communicate(timeout=10)
    assert echo.returncode == 0, err
    documents = [d for d in yaml.safe_load_all(out) if d is not None]
    assert len(documents) == 1
    printed = documents[0]
    assert printed['map_name'] == 'garden' and printed['index'] == 42 and printed['accepted'] is True
    assert printed['distance'] == 0.125 and printed['snapshot_stamp'] == {'sec': 1234, 'nanosec': 0}
    assert printed['header']['frame_id'] == CAMERA_FRAME
    # 40 candidates: the first 16 and a note of the rest.
    assert printed['candidate_indices'][:16] == list(range(16))
    assert printed['candidate_indices'][16] == '... 24 more, 40 in all'
    executor.shutdown()
    node.destroy_node()


def test_echo_in_a_namespace_prints_that_graphs_topic_only(ros_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from skynav_core.ros import message_class

    PlaceMatch = message_class('skynav_msgs/msg/PlaceMatch')
    node = Node('two_robots', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    publishers = {index: node.create_publisher(PlaceMatch, f'/robot{index}/localization/match', 10) for index in (1, 2)}
    echo = start_skynav('echo', LOCALIZATION_MATCH, '--namespace', 'robot2', '--count', '3')
    deadline = time.monotonic() + 60
    while echo.poll() is None and time.monotonic() < deadline:
        for index, publisher in publishers.items():
            publisher.publish(PlaceMatch(map_name=f'robot{index}', index=index))
        executor.spin_once(timeout_sec=0.1)
    out, err = echo.communicate(timeout=10)
    executor.shutdown()
    node.destroy_node()
    assert echo.returncode == 0, err
    printed = [d for d in yaml.safe_load_all(out) if d is not None]
    assert [(d['map_name'], d['index']) for d in printed] == [('robot2', 2)] * 3


def test_replay_of_damaged_bags_fails_in_one_line(tmp_path):
    good = tmp_path / 'good.mcap'
    write_sample_bag(good, frames=3)
    data = good.read_bytes()
    cases = {
        'truncated.mcap': data[: len(data) * 2 // 3],
        'foreign.mcap': b'%PDF-1.4 not a bag',
        'empty.mcap': b'',
    }
    for name, content in cases.items():
        (tmp_path / name).write_bytes(content)
        result = run_skynav('replay', str(tmp_path / name), '--rate', '0')
        assert result.returncode == 1, name
        assert one_line_error(result.stderr), (name, result.stderr)
        assert name in result.stderr


def test_launch_starts_and_stops_a_node_cleanly(tmp_path, ros_context):
    # A trivial node, registered the way skynav packages register theirs (a `skynav.nodes` entry point).
    (tmp_path / 'trivial_node.py').write_text(
        textwrap.dedent("""
        from rclpy.node import Node
        from skynav_core.ros import run_node

        class Trivial(Node):
            def __init__(self):
                super().__init__('trivial')
                greeting = self.declare_parameter('greeting', 'none').value
                self.get_logger().info(f'trivial node up, greeting={greeting}')

        def main(args=None):
            return run_node(Trivial, args)
    """)
    )
    dist = tmp_path / 'trivial_node-1.0.dist-info'
    dist.mkdir()
    (dist / 'METADATA').write_text('Metadata-Version: 2.1\nName: trivial-node\nVersion: 1.0\n')
    (dist / 'entry_points.txt').write_text('[skynav.nodes]\ntrivial = trivial_node:Trivial\n')
    params = tmp_path / 'params.yaml'
    params.write_text('trivial:\n  ros__parameters:\n    greeting: hello\n')
    env = dict(__import__('os').environ, PYTHONPATH=str(tmp_path))

    launch = subprocess.Popen(
        [sys.executable, '-m', 'skynav_bringup.cli', 'launch', '--params', str(params)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    lines = wait_text(launch, 'trivial node up', stream='stdout')
    assert any('[trivial]' in line and 'greeting=hello' in line for line in lines)

    from rclpy.node import Node

    observer = Node('observer', context=ros_context)
    deadline = time.monotonic() + 30
    while 'trivial' not in observer.get_node_names() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert 'trivial' in observer.get_node_names()
    observer.destroy_node()

    launch.send_signal(signal.SIGINT)
    out, _ = launch.communicate(timeout=60)
    assert launch.returncode == 0, out
    assert 'trivial: process ended with exit code 0' in out
    assert 'Traceback' not in out


def test_replay_waits_for_a_best_effort_subscriber_to_take_the_last_message(tmp_path, ros_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image

    from skynav_core.ros import spin_until

    bag = tmp_path / 'sample.mcap'
    frames = 5
    write_sample_bag(bag, frames=frames)
    topic = UV_IMAGE
    node = Node('last_frame_reader', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    stamps: dict[ReliabilityPolicy, list[int]] = {}
    for reliability in (ReliabilityPolicy.BEST_EFFORT, ReliabilityPolicy.RELIABLE):
        taken = stamps[reliability] = []
        node.create_subscription(
            Image,
            topic,
            lambda m, taken=taken: taken.append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec),
            QoSProfile(depth=frames, reliability=reliability),
        )
    try:
        replay = start_skynav('replay', str(bag), '--topics', topic, '--rate', '0', '--wait-for-subscribers', '2')
        spin_until(executor, lambda: replay.poll() is not None, 60)
        _, err = replay.communicate(timeout=10)
        spin_until(executor, lambda: all(len(t) == frames for t in stamps.values()), 2.0)
    finally:
        executor.shutdown()
        node.destroy_node()
    assert replay.returncode == 0, err
    # the best-effort reader acknowledges nothing: the replay gave it (and only it) time to take the last frame
    # before it ended; the reliable one acknowledged every frame
    assert 'gave 1 best-effort subscribers 1 s to take the last messages' in err, err
    for reliability, taken in stamps.items():
        assert len(taken) == frames and taken == sorted(taken), (reliability, taken)


def test_replay_says_at_once_whom_it_waits_for_and_keeps_saying_it(tmp_path):
    # No graph runs in this namespace: the replay waits, saying so from its first line on, then publishes anyway.
    bag = tmp_path / 'sample.mcap'
    write_sample_bag(bag, frames=3)
    result = run_skynav('replay', str(bag), '--namespace', 'nobody_here', '--wait-timeout', '6', '--rate', '0')
    assert result.returncode == 0, result.stderr
    lines = result.stderr.splitlines()
    assert 'first waiting up to 6 s for the skynav graph' in lines[0] and 'under /nobody_here' in lines[0], lines
    assert lines[1].startswith('skynav replay: waiting for ') and 'skyline' in lines[1], lines
    assert any('5 s: still waiting on' in line and '/nobody_here/camera/uv/image_raw' in line for line in lines), lines
    assert any('publishing anyway' in line for line in lines) and 'published' in lines[-1], lines


def test_launch_kills_a_node_that_will_not_stop_and_shows_where_it_hung(tmp_path):
    # A node that ignores SIGINT and SIGTERM (as a node stuck in a call would): after SIGINT and SIGTERM, each given
    # its grace, launch has it write its threads' Python stacks, then kills it and exits 1.
    (tmp_path / 'stubborn_node.py').write_text(
        textwrap.dedent("""
        import signal
        from rclpy.node import Node

        class Stubborn(Node):
            def __init__(self):
                super().__init__('stubborn')
                self.create_timer(0.05, self.hang_here)

            def hang_here(self):
                for signum in (signal.SIGINT, signal.SIGTERM):
                    signal.signal(signum, signal.SIG_IGN)
                print('stubborn node up', flush=True)
                while True:
                    signal.pause()
    """)
    )
    dist = tmp_path / 'stubborn_node-1.0.dist-info'
    dist.mkdir()
    (dist / 'METADATA').write_text('Metadata-Version: 2.1\nName: stubborn-node\nVersion: 1.0\n')
    (dist / 'entry_points.txt').write_text('[skynav.nodes]\nstubborn = stubborn_node:Stubborn\n')
    env = dict(__import__('os').environ, PYTHONPATH=str(tmp_path))
    launch = subprocess.Popen(
        [sys.executable, '-m', 'skynav_bringup.cli', 'launch', '--nodes', 'stubborn'],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    wait_text(launch, 'stubborn node up', stream='stdout')
    launch.send_signal(signal.SIGINT)
    out, _ = launch.communicate(timeout=120)
    assert launch.returncode == 1, out
    assert 'stubborn did not stop: the Python stacks of its threads follow' in out
    assert 'in hang_here' in out  # faulthandler's stack of the node's main thread
    assert 'stubborn: process ended with exit code -9' in out
