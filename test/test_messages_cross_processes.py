# SPDX-License-Identifier: Apache-2.0
"""Every message type of a recording crosses processes intact: replayed by `skynav replay`, received typed.

The sender serialises with rosbags (from the bag), the receiver deserialises
with the rosidl type support of the built skynav_msgs, so this also proves
that the two agree on every field of the contract's messages.
"""

import array
import time

import numpy as np

from skynav_core.names import (
    COMPASS_ORIENTATION,
    GROUND_TRUTH_POSE,
    HOME_VECTOR,
    LOCALIZATION_MATCH,
    SKYLINE_SH,
    UV_CAMERA_INFO,
    UV_IMAGE,
)
from skynav_core.recording.msgyaml import to_plain
from skynav_core.ros import message_class
from skynav_testing import start_skynav, write_sample_bag


def rclpy_to_plain(message):
    """Return an rclpy message as nested dicts, lists and scalars."""
    if hasattr(message, 'get_fields_and_field_types'):
        return {name: rclpy_to_plain(getattr(message, name)) for name in message.get_fields_and_field_types()}
    if isinstance(message, np.ndarray | array.array | list | tuple):
        return [rclpy_to_plain(v) for v in message]
    if isinstance(message, bytes):
        return list(message)
    return message


def test_every_message_type_crosses_processes(tmp_path, ros_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    sent = write_sample_bag(tmp_path / 'all_types.mcap', frames=3)
    topics = {topic: msgtype for topic, msgtype, _, _ in sent}
    node = Node('receiver', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    received = {topic: [] for topic in topics}
    for topic, msgtype in topics.items():
        node.create_subscription(
            message_class(msgtype),
            topic,
            received[topic].append,
            QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE),
        )
    replay = start_skynav('replay', str(tmp_path / 'all_types.mcap'), '--rate', '0', '--wait-for-subscribers', '1')
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and sum(map(len, received.values())) < len(sent):
        executor.spin_once(timeout_sec=0.05)
    assert replay.wait(timeout=60) == 0, replay.stderr.read()
    for topic in topics:
        mine = [to_plain(m, truncate_length=None) for t, _, _, m in sent if t == topic]
        theirs = [rclpy_to_plain(m) for m in received[topic]]
        assert theirs == mine, topic
    assert set(topics) >= {
        SKYLINE_SH,
        LOCALIZATION_MATCH,
        COMPASS_ORIENTATION,
        HOME_VECTOR,
        UV_IMAGE,
        UV_CAMERA_INFO,
        GROUND_TRUTH_POSE,
    }
    executor.shutdown()
    node.destroy_node()
