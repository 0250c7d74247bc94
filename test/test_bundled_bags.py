# SPDX-License-Identifier: Apache-2.0
"""Every bundled recording: synthetic by name, readable by rosbags and by skynav, the contract's topics."""

from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.records import Chunk, DataEnd, Footer
from mcap.stream_reader import StreamReader
from rosbags.rosbag2 import Reader

from skynav_core.camera import EquidistantCamera
from skynav_core.names import (
    CAMERA_FRAME,
    COLOUR_CAMERA_INFO,
    COLOUR_COMPRESSED,
    GREEN_IMAGE,
    GROUND_TRUTH_MASK,
    GROUND_TRUTH_POSE,
    UV_CAMERA_INFO,
    UV_IMAGE,
)
from skynav_core.recording.bag import open_bag
from skynav_testing import run_skynav

BAGS = sorted((Path(__file__).parents[1] / 'bags').glob('*.mcap'))
INPUT_TOPICS = {
    UV_IMAGE: 'sensor_msgs/msg/Image',
    GREEN_IMAGE: 'sensor_msgs/msg/Image',
    UV_CAMERA_INFO: 'sensor_msgs/msg/CameraInfo',
    GROUND_TRUTH_POSE: 'geometry_msgs/msg/PoseStamped',
    GROUND_TRUTH_MASK: 'sensor_msgs/msg/Image',
}
#: The topics of a recording of one colour camera delivering JPEG (synthetic_garden_colour_repeat.mcap).
COLOUR_TOPICS = {
    COLOUR_COMPRESSED: 'sensor_msgs/msg/CompressedImage',
    COLOUR_CAMERA_INFO: 'sensor_msgs/msg/CameraInfo',
    GROUND_TRUTH_POSE: 'geometry_msgs/msg/PoseStamped',
    GROUND_TRUTH_MASK: 'sensor_msgs/msg/Image',
}


def test_the_bundle_is_complete_and_small():
    names = {p.name for p in BAGS}
    for kind in ('teach', 'repeat', 'homing', 'compass', 'skyline'):
        assert any(kind in name for name in names), kind
    assert len({name.split('_')[1] for name in names}) >= 2  # world styles
    assert sum(p.stat().st_size for p in BAGS) < 40 * 2**20


@pytest.mark.parametrize('path', BAGS, ids=[p.name for p in BAGS])
def test_bundled_bag(path):
    assert path.name.startswith('synthetic_')
    with Reader(path) as reader:  # rosbags reads it
        topics = {c.topic: c.msgtype for c in reader.connections}
        assert topics in (INPUT_TOPICS, COLOUR_TOPICS)
        count = reader.message_count
    with open_bag(path) as bag:
        description = yaml.safe_load(bag.custom_data['skynav_sim'])
        assert description['synthetic'] is True
        assert (topics == COLOUR_TOPICS) == ('camera' in description)  # a colour recording says which camera
        assert description.get('camera', {'synthetic': True})['synthetic'] is True
        stamps: dict[str, list[int]] = {}
        for message in bag.messages():
            data = bag.deserialize(message)
            stamp = data.header.stamp.sec * 10**9 + data.header.stamp.nanosec
            stamps.setdefault(message.topic, []).append(stamp)
            assert message.log_time == stamp
            if message.topic.endswith('image_raw'):
                assert data.encoding in ('mono8', 'mono16', '32FC1') and data.header.frame_id == CAMERA_FRAME
            if message.topic.endswith('compressed'):
                assert data.format == 'rgb8; jpeg compressed bgr8' and data.header.frame_id == CAMERA_FRAME
            if message.topic == GROUND_TRUTH_MASK:
                assert data.encoding == 'mono8' and set(np.unique(data.data)) <= {0, 255}
            if message.topic.endswith('camera_info'):
                camera = EquidistantCamera.from_camera_info(data)
                assert camera.field_of_view <= np.radians(220) + 1e-9
    frames = len(description['frames'])
    assert count == len(topics) * frames
    with path.open('rb') as stream:  # every checksum is there, and the mcap library finds them right
        records = list(StreamReader(stream, validate_crcs=True, emit_chunks=True).records)
    chunks = [r for r in records if isinstance(r, Chunk)]
    assert chunks and all(chunk.uncompressed_crc for chunk in chunks)
    assert next(r for r in records if isinstance(r, DataEnd)).data_section_crc
    assert next(r for r in records if isinstance(r, Footer)).summary_crc
    for topic, times in stamps.items():
        assert len(times) == frames and np.all(np.diff(times) > 0), topic  # strictly increasing
        assert times == stamps[GROUND_TRUTH_POSE], topic  # one stamp per exposure on every topic


def test_skynav_replays_every_bundled_bag():
    for path in BAGS:
        result = run_skynav('replay', str(path), '--rate', '0', '--wait-for-subscribers', '0')
        assert result.returncode == 0, (path.name, result.stderr)
        assert f'published {sum(1 for _ in open_bag(path).messages())} messages' in result.stderr
