# SPDX-License-Identifier: Apache-2.0
"""The contract's actions (docs/interfaces.md, "Driving: teach, follow, home"): built, named codes, round-trip."""

import signal
import threading
import time

import pytest

from skynav_core.actions import ERROR_NONE, error_codes, error_name
from skynav_core.names import TEACH_ACTION
from skynav_testing import on_executor_thread

# The fields of each action exactly as the contract writes them: (goal, result, feedback), name -> rosidl type.
CONTRACT = {
    'Teach': (
        {
            'map_path': 'string',
            'map_name': 'string',
            'spacing': 'double',
            'max_length': 'double',
            'overwrite': 'boolean',
        },
        {'error_code': 'uint8', 'error_msg': 'string', 'snapshots': 'int32', 'route_length': 'double'},
        {'snapshots': 'int32', 'route_length': 'double'},
    ),
    'FollowRoute': (
        {'map_path': 'string', 'start_index': 'int32', 'end_index': 'int32', 'max_speed': 'double'},
        {'error_code': 'uint8', 'error_msg': 'string', 'reached_index': 'int32', 'driven_length': 'double'},
        {
            'matched_index': 'int32',
            'target_index': 'int32',
            'progress': 'double',
            'confidence': 'double',
            'state': 'string',
        },
    ),
    'Home': (
        {'map_path': 'string', 'index': 'int32', 'max_speed': 'double'},
        {'error_code': 'uint8', 'error_msg': 'string', 'driven_length': 'double'},
        {'confidence': 'double', 'steps': 'int32'},
    ),
}
# Error codes every action names (besides its own).
CODES = {
    'Teach': {'NONE', 'MAP_EXISTS', 'MAP_WRITE_FAILED', 'NO_INPUT'},
    'FollowRoute': {'NONE', 'LOST', 'NO_MAP', 'STALE_INPUT', 'TIMEOUT', 'BAD_INDEX', 'EMERGENCY_STOP'},
    'Home': {'NONE', 'LOST', 'NO_MAP', 'STALE_INPUT', 'TIMEOUT', 'BAD_INDEX', 'EMERGENCY_STOP'},
}
# One non-default value per rosidl type, to see every field survive serialisation.
SAMPLE = {'string': 'garden ü.db', 'double': -1.25, 'int32': -7, 'uint8': 3, 'boolean': True}


def action_type(name):
    from skynav_msgs import action

    return getattr(action, name)


@pytest.mark.parametrize('name', sorted(CONTRACT))
def test_fields_are_the_contracts(name):
    kind = action_type(name)
    for part, fields in zip((kind.Goal, kind.Result, kind.Feedback), CONTRACT[name], strict=True):
        assert part.get_fields_and_field_types() == fields, part.__name__


@pytest.mark.parametrize('name', sorted(CONTRACT))
def test_error_codes_are_named_and_distinct(name):
    result = action_type(name).Result
    codes = error_codes(result)
    assert set(codes.values()) >= CODES[name]
    assert codes[ERROR_NONE] == 'NONE'
    assert len(codes) == len(set(codes.values()))  # no two names share a code
    for code, constant in codes.items():
        assert getattr(result, constant) == code
        assert error_name(result(error_code=code)) == constant
    unnamed = max(codes) + 1
    assert error_name(result(error_code=unnamed)) == f'ERROR_{unnamed}'


@pytest.mark.parametrize('name', ['FollowRoute', 'Home'])
def test_the_emergency_stop_has_the_contracts_code(name):
    assert action_type(name).Result.EMERGENCY_STOP == 9  # docs/interfaces.md, "On a robot"


@pytest.mark.parametrize('name', sorted(CONTRACT))
def test_messages_round_trip_through_cdr(name):
    from rclpy.serialization import deserialize_message, serialize_message

    kind = action_type(name)
    for part, fields in zip((kind.Goal, kind.Result, kind.Feedback), CONTRACT[name], strict=True):
        message = part(**{field: SAMPLE[rosidl] for field, rosidl in fields.items()})
        back = deserialize_message(serialize_message(message), part)
        assert back == message
        assert back != part()  # the sample differs from the defaults in some field, so equality means something


def test_a_goal_round_trips_through_an_action_server(ros_context):
    """A Teach goal sent by a client reaches a server, which sends feedback and a result back (rclpy.action)."""
    from rclpy.action import ActionClient, ActionServer
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    teach = action_type('Teach')
    received = []

    def execute(goal_handle):
        received.append(goal_handle.request)
        goal_handle.publish_feedback(teach.Feedback(snapshots=2, route_length=0.5))
        goal_handle.succeed()
        return teach.Result(error_code=teach.Result.NONE, snapshots=3, route_length=0.75)

    server_node = Node('teach_server', context=ros_context)
    client_node = Node('teach_client', context=ros_context)
    server = ActionServer(server_node, teach, TEACH_ACTION, execute)
    client = ActionClient(client_node, teach, TEACH_ACTION)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(server_node)
    executor.add_node(client_node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        assert client.wait_for_server(timeout_sec=20)
        feedback = []
        goal = teach.Goal(map_path='/tmp/x.db', map_name='x', spacing=0.2, max_length=3.0, overwrite=True)
        future = on_executor_thread(
            executor, lambda: client.send_goal_async(goal, feedback_callback=lambda m: feedback.append(m.feedback))
        )
        deadline = time.monotonic() + 20
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        handle = future.result()
        assert handle.accepted
        result_future = on_executor_thread(executor, handle.get_result_async)
        while not result_future.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        result = result_future.result().result
        while not feedback and time.monotonic() < deadline:  # feedback is a topic: it may trail the result
            time.sleep(0.01)
        assert received == [goal]
        assert (result.snapshots, result.route_length, error_name(result)) == (3, 0.75, 'NONE')
        assert feedback == [teach.Feedback(snapshots=2, route_length=0.5)]
    finally:
        executor.shutdown()
        server.destroy()
        client.destroy()
        spinner.join(timeout=5)


@pytest.mark.parametrize('name', sorted(CONTRACT))
def test_the_typestore_knows_the_action_messages_with_rosidls_hashes(name):
    """Bags can hold an action's topics: rosbags' definitions of its parts hash as rosidl's (installed JSON)."""
    import json

    from skynav_core.process.environment import share_directory
    from skynav_core.recording.typestore import ensure_type, typestore

    rosidl = json.loads((share_directory('skynav_msgs') / 'action' / f'{name}.json').read_text())
    hashes = {entry['type_name']: entry['hash_string'] for entry in rosidl['type_hashes']}
    for part in ('Goal', 'Result', 'Feedback', 'FeedbackMessage'):
        msgtype = ensure_type(f'skynav_msgs/action/{name}_{part}')
        assert typestore().hash_rihs01(msgtype) == hashes[msgtype], msgtype


def test_a_feedback_message_crosses_rclpy_and_rosbags():
    from rclpy.serialization import serialize_message

    from skynav_core.recording.typestore import ensure_type, typestore
    from skynav_core.ros import message_class

    feedback_type = message_class('skynav_msgs/action/FollowRoute_FeedbackMessage')
    message = feedback_type()
    message.goal_id.uuid = list(range(16))
    message.feedback.matched_index, message.feedback.state, message.feedback.progress = 7, 'following', 0.25
    decoded = typestore().deserialize_cdr(
        serialize_message(message), ensure_type('skynav_msgs/action/FollowRoute_FeedbackMessage')
    )
    assert list(decoded.goal_id.uuid) == list(range(16))
    assert (decoded.feedback.matched_index, decoded.feedback.state, decoded.feedback.progress) == (7, 'following', 0.25)


def test_an_actions_feedback_is_echoed_and_not_recorded(tmp_path, ros_context):
    """`skynav echo` prints an action's feedback; `skynav record` leaves it out in one line (rosbags embeds
    definitions of pkg/msg/ types only)."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from skynav_core.recording.bag import open_bag
    from skynav_core.ros import message_class
    from skynav_testing import start_skynav, wait_text

    topic = f'{TEACH_ACTION}/_action/feedback'
    feedback_type = message_class('skynav_msgs/action/Teach_FeedbackMessage')
    node = Node('teach_feedback_source', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    publisher = node.create_publisher(feedback_type, topic, 10)
    out = tmp_path / 'feedback.mcap'
    recorder = start_skynav('record', str(out), '--all')
    wait_text(recorder, 'recording')
    echo = start_skynav('echo', topic, '--once', '--wait', '30')
    deadline = time.monotonic() + 30
    while publisher.get_subscription_count() < 1 and time.monotonic() < deadline:  # echo's (the recorder has none)
        executor.spin_once(timeout_sec=0.05)
    deadline = time.monotonic() + 30
    message = feedback_type()
    message.feedback.snapshots, message.feedback.route_length = 12, 1.5
    while echo.poll() is None and time.monotonic() < deadline:
        publisher.publish(message)
        time.sleep(0.1)
    printed, _ = echo.communicate(timeout=30)
    assert echo.returncode == 0 and 'snapshots: 12' in printed and 'route_length: 1.5' in printed, printed
    told = wait_text(recorder, f'{topic} not recorded')  # the recorder looks for new topics every second
    recorder.send_signal(signal.SIGINT)
    _, err = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, err
    assert 'Traceback' not in ''.join(told) + err
    with open_bag(out) as bag:
        assert topic not in bag.topics
    executor.shutdown()
    node.destroy_node()
