# SPDX-License-Identifier: Apache-2.0
"""Every message type skynav records, as rclpy serialises it, read back identically by rosbags and mcap_ros2.

The bytes go the way `skynav record` and `skynav run` store them: serialised by
rclpy (Fast-CDR), passed through `rosbags_cdr`, written by BagWriter. Two
independent readers must then give the values back: rosbags' own reader and
the mcap library's ROS 2 decoder (mcap_ros2). The empty-array cases matter:
Fast-CDR pads an empty sequence of 8-byte numbers, which rosbags refuses.
"""

from __future__ import annotations

import dataclasses

import mcap.reader
import numpy as np
import pytest
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.rosbag2 import Reader

from skynav_core.names import LOCALIZATION_MATCH, SKYLINE_SH, UV_CAMERA_INFO, UV_IMAGE
from skynav_core.recording.bag import BagWriter
from skynav_core.recording.cdr import rosbags_cdr
from skynav_core.recording.typestore import ensure_type, typestore
from skynav_core.ros import message_class
from skynav_testing import messages_equal, sample_messages


def empty_array_cases() -> list[tuple[str, str, int, object]]:
    """Return messages with empty arrays, under frame ids of 1 and 11 characters (both alignments)."""
    for name in ('ShCoefficients', 'PlaceMatch'):
        ensure_type(f'skynav_msgs/msg/{name}')
    T = typestore().types
    cases = []
    for n, frame in enumerate(('c', 'camera_link')):
        t = 1_763_780_500 * 10**9 + n
        header = T['std_msgs/msg/Header'](T['builtin_interfaces/msg/Time'](t // 10**9, t % 10**9), frame)
        empty_f8, empty_i4 = np.zeros(0), np.zeros(0, np.int32)
        never = T['builtin_interfaces/msg/Time'](0, 0)
        cases += [
            (  # what the localize node publishes with an empty map
                LOCALIZATION_MATCH,
                'skynav_msgs/msg/PlaceMatch',
                t,
                T['skynav_msgs/msg/PlaceMatch'](header, '', -1, never, float('inf'), False, empty_i4, empty_f8),
            ),
            (
                SKYLINE_SH,
                'skynav_msgs/msg/ShCoefficients',
                t,
                T['skynav_msgs/msg/ShCoefficients'](header, 0, empty_f8, 'zero', np.float32(3.0)),
            ),
            (
                UV_CAMERA_INFO,
                'sensor_msgs/msg/CameraInfo',
                t,
                T['sensor_msgs/msg/CameraInfo'](
                    header,
                    0,
                    0,
                    '',
                    empty_f8,
                    np.zeros(9),
                    np.zeros(9),
                    np.zeros(12),
                    0,
                    0,
                    T['sensor_msgs/msg/RegionOfInterest'](0, 0, 0, 0, False),
                ),
            ),
            (
                UV_IMAGE,
                'sensor_msgs/msg/Image',
                t,
                T['sensor_msgs/msg/Image'](header, 0, 0, 'mono8', 0, 0, np.zeros(0, np.uint8)),
            ),
        ]
    return cases


def rclpy_bytes(msgtype: str, message: object) -> bytes:
    """Return the message as rclpy serialises it (what a node publishes and the recorder receives)."""
    cls = message_class(msgtype)
    return serialize_message(deserialize_message(bytes(typestore().serialize_cdr(message, msgtype)), cls))


def same_as_decoded(ours: object, decoded: object) -> bool:
    """Return whether an mcap_ros2 decoded message holds the values of a rosbags message, field by field."""
    if dataclasses.is_dataclass(ours):
        return all(
            same_as_decoded(getattr(ours, f.name), getattr(decoded, f.name))
            for f in dataclasses.fields(ours)
            if not f.name.startswith('__')
        )
    if isinstance(ours, np.ndarray):
        if isinstance(decoded, bytes):  # mcap_ros2 gives uint8[] as bytes
            decoded = np.frombuffer(decoded, np.uint8)
        return bool(np.array_equal(ours, np.asarray(decoded, dtype=ours.dtype)))
    if isinstance(ours, list):
        return len(ours) == len(decoded) and all(map(same_as_decoded, ours, decoded))
    return ours == decoded or (isinstance(ours, float) and np.isnan(ours) and np.isnan(decoded))


@pytest.fixture(scope='module')
def recorded(tmp_path_factory):
    """Return the messages and the bag they were recorded into, the way the recorder writes them."""
    messages = sample_messages(frames=2) + empty_array_cases()
    path = tmp_path_factory.mktemp('interop') / 'interop.mcap'
    with BagWriter(path) as writer:
        for topic, msgtype, t, message in messages:
            writer.add_topic(topic, msgtype)
            writer.write(topic, t, rosbags_cdr(msgtype, rclpy_bytes(msgtype, message)))
    return messages, path


def test_rclpy_pads_an_empty_map_match_that_rosbags_refuses():
    # The cause: 76 bytes from rclpy, 72 from rosbags, for the PlaceMatch of an empty map.
    topic, msgtype, _, message = empty_array_cases()[-4]
    raw = rclpy_bytes(msgtype, message)
    assert (len(raw), len(typestore().serialize_cdr(message, msgtype))) == (76, 72)
    with pytest.raises(Exception, match='size mismatch'):
        typestore().deserialize_cdr(raw, msgtype)
    assert len(rosbags_cdr(msgtype, raw)) == 72
    assert messages_equal(typestore().deserialize_cdr(rosbags_cdr(msgtype, raw), msgtype), message)


def test_rosbags_reads_every_message_back(recorded):
    messages, path = recorded
    with Reader(path) as reader:
        read = [(c.topic, t, typestore().deserialize_cdr(data, c.msgtype)) for c, t, data in reader.messages()]
    assert len(read) == len(messages)
    for topic, _, t, message in messages:
        matches = [m for rtopic, rt, m in read if rtopic == topic and rt == t]
        assert len(matches) == 1 and messages_equal(message, matches[0]), (topic, t)


def test_mcap_ros2_decoder_reads_every_message_back(recorded):
    messages, path = recorded
    with path.open('rb') as stream:
        reader = mcap.reader.make_reader(stream, decoder_factories=[DecoderFactory()])
        decoded = [(c.topic, m.log_time, d) for _, c, m, d in reader.iter_decoded_messages()]
    assert len(decoded) == len(messages)
    for topic, _, t, message in messages:
        matches = [d for dtopic, dt, d in decoded if dtopic == topic and dt == t]
        assert len(matches) == 1 and same_as_decoded(message, matches[0]), (topic, t)
