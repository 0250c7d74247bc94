# SPDX-License-Identifier: Apache-2.0
"""`skynav follow` and `skynav home` against a route node running in a process of its own, as `skynav launch`
starts it: errors by name in one line, the live watchdog, Ctrl-C cancels and the robot stops, and the node's
last word on shutdown is a zero command."""

import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from geometry_msgs.msg import TwistStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from skynav_core.maps import Snapshot
from skynav_core.names import BASE_FRAME, CMD_VEL
from skynav_core.route_progress import read_progress
from skynav_localize.mapping import build_map
from skynav_testing import one_line_error, run_skynav, start_skynav

pytestmark = pytest.mark.heavy(40)

SNAPSHOTS = 12


@pytest.fixture(scope='module')
def route_map(tmp_path_factory):
    path = tmp_path_factory.mktemp('maps') / 'line.db'
    rng = np.random.default_rng(2)
    snapshots = [Snapshot(k, 10**18 + k * 10**8, rng.normal(size=25)) for k in range(SNAPSHOTS)]
    build_map(path, 'line', 4, snapshots, created_from='test (synthetic)', overwrite=True).close()
    return path


def start_route_node(route_map, *parameters):
    arguments = ['--ros-args', '-p', f'map:={route_map}', '-p', 'configure_peers:=false']
    for parameter in parameters:
        arguments += ['-p', parameter]
    return subprocess.Popen(
        [sys.executable, '-m', 'skynav_core.run_node', 'skynav_route.node:RouteNode', *arguments],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.fixture
def listener(ros_context):
    node = Node('cmd_vel_listener', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    commands = []
    node.create_subscription(TwistStamped, CMD_VEL, commands.append, 10)
    yield node, executor, commands
    executor.shutdown()
    node.destroy_node()


def spin_while(executor, condition, seconds):
    deadline = time.monotonic() + seconds
    while condition() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)


def stop(process):
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    return process.communicate(timeout=30)


def test_home_to_a_missing_index_fails_in_one_line_by_name(route_map):
    node = start_route_node(route_map)
    try:
        result = run_skynav('home', str(route_map), '--index', str(SNAPSHOTS), '--wait', '60')
    finally:
        stop(node)
    assert result.returncode == 1, result.stderr
    assert one_line_error(result.stderr), result.stderr
    assert f'BAD_INDEX: no snapshot {SNAPSHOTS}: the map has snapshots 0..{SNAPSHOTS - 1}' in result.stderr


def test_follow_without_camera_frames_is_stopped_by_the_watchdog(route_map, listener):
    node, executor, commands = listener
    route = start_route_node(route_map, 'input_timeout:=1.0')
    try:
        spin_while(executor, lambda: node.count_publishers(CMD_VEL) == 0, 60)
        follow = start_skynav('follow', '--wait', '60')
        spin_while(executor, lambda: follow.poll() is None, 90)
        out, err = follow.communicate(timeout=30)
        spin_while(executor, lambda: not commands, 5)
    finally:
        stop(route)
    assert follow.returncode == 1, err
    assert one_line_error(err) and 'STALE_INPUT' in err, err
    assert len(commands) == 1  # no frame, so no command but the stop
    assert commands[0].twist.linear.x == 0.0 and commands[0].twist.angular.z == 0.0
    assert commands[0].header.frame_id == BASE_FRAME
    # the node recorded where the goal ended beside the map, for `skynav follow --resume`
    progress = read_progress(route_map)
    assert (progress.outcome, progress.reached_index, progress.start_index) == ('STALE_INPUT', -1, -1)
    assert (progress.end_index, progress.snapshots, progress.map_path) == (SNAPSHOTS - 1, SNAPSHOTS, str(route_map))


def test_ctrl_c_cancels_and_the_robot_stops_and_shutdown_stops_it_too(route_map, listener):
    node, executor, commands = listener
    route = start_route_node(route_map, 'input_timeout:=1000.0')
    try:
        spin_while(executor, lambda: node.count_publishers(CMD_VEL) == 0, 60)
        follow = start_skynav('follow', '--wait', '60')
        deadline = time.monotonic() + 60
        line = ''
        while 'localizing' not in line and time.monotonic() < deadline:  # its first progress line: the goal runs
            line = follow.stdout.readline()
        follow.send_signal(signal.SIGINT)
        out, err = follow.communicate(timeout=30)
        spin_while(executor, lambda: not commands, 5)
        assert follow.returncode == 1, err
        assert one_line_error(err) and 'canceled (the robot stopped)' in err, err
        assert len(commands) == 1 and commands[0].twist.linear.x == 0.0

        # a goal runs while the node is stopped: its last word is a zero command
        home = start_skynav('home', '--index', '3', '--wait', '60')
        deadline = time.monotonic() + 60
        line = ''
        while 'homing' not in line and time.monotonic() < deadline:
            line = home.stdout.readline()
        route.send_signal(signal.SIGINT)
        route_out, route_err = route.communicate(timeout=30)
        spin_while(executor, lambda: len(commands) < 2, 10)
        home_out, home_err = stop(home)
    finally:
        stop(route)
    assert route.returncode == 0, route_err
    assert len(commands) == 2 and commands[1].twist.linear.x == 0.0 and commands[1].twist.angular.z == 0.0
    assert 'Traceback' not in route_err


@pytest.mark.parametrize('delay', [0.2, 1.0, 3.0])
def test_a_signal_at_any_moment_of_the_start_ends_the_node_cleanly(route_map, delay):
    # the node takes the signals itself (it must stop the robot first): one that comes while rclpy is creating
    # something must not leave it half made (a Task without its fields printed a traceback at exit)
    route = start_route_node(route_map)
    time.sleep(delay)
    out, err = stop(route)
    assert route.returncode == 0 and 'Traceback' not in out + err and 'Exception ignored' not in err, err
