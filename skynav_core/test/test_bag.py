# SPDX-License-Identifier: Apache-2.0
"""Recordings: round trips, atomic writes, and one clear error for every kind of damaged file."""

import json

import mcap.reader
import pytest
from rosbags.rosbag2 import Reader

from skynav_core.names import CAMERA_FRAME, SKYLINE_SH, UV_IMAGE
from skynav_core.process.environment import share_directory
from skynav_core.recording.bag import BagError, BagWriter, open_bag
from skynav_core.recording.typestore import typestore
from skynav_testing import messages_equal, write_sample_bag


@pytest.fixture(scope='module')
def sample_bag(tmp_path_factory):
    path = tmp_path_factory.mktemp('bags') / 'sample.mcap'
    return path, write_sample_bag(path, frames=4)


def test_round_trip_keeps_every_message_in_time_order(sample_bag):
    path, written = sample_bag
    with open_bag(path) as bag:
        read = list(bag.messages())
        assert bag.message_count == len(written)
        assert {t.name: t.msgtype for t in bag.topics.values()} == {t: m for t, m, _, _ in written}
        assert bag.start_time == written[0][2] and bag.end_time == written[-1][2]
        assert [m.log_time for m in read] == sorted(m.log_time for m in read)
        for topic in bag.topics:
            mine = [msg for t, _, _, msg in written if t == topic]
            theirs = [bag.deserialize(m) for m in read if m.topic == topic]
            assert len(mine) == len(theirs) and all(map(messages_equal, mine, theirs)), topic


def test_topic_filter(sample_bag):
    path, _ = sample_bag
    with open_bag(path) as bag:
        assert {m.topic for m in bag.messages([SKYLINE_SH])} == {SKYLINE_SH}
        with pytest.raises(BagError, match='no topic /nope'):
            list(bag.messages(['/nope']))


def test_other_readers_read_it(sample_bag):
    path, written = sample_bag
    with path.open('rb') as stream:
        reader = mcap.reader.make_reader(stream)
        summary = reader.get_summary()
        assert summary.statistics.message_count == len(written)
        schemas = {s.name: s for s in summary.schemas.values()}
        assert schemas['skynav_msgs/msg/PlaceMatch'].encoding == 'ros2msg'
        assert b'candidate_distances' in schemas['skynav_msgs/msg/PlaceMatch'].data
        assert reader.get_header().profile == 'ros2'
    with Reader(path) as reader:  # rosbags' own reader
        assert reader.message_count == len(written)


def test_type_hashes_match_rosidl(sample_bag, tmp_path):
    # Written as a rosbag2 directory, metadata.yaml carries the type hashes ros2 bag checks.
    write_sample_bag(tmp_path / 'dir_bag', frames=1)
    with Reader(tmp_path / 'dir_bag') as reader:
        hashes = {c.msgtype: c.digest for c in reader.connections}
    for name in ('ShCoefficients', 'PlaceMatch', 'CompassEstimate', 'HomeVector'):
        description = json.loads((share_directory('skynav_msgs') / 'msg' / f'{name}.json').read_text())
        assert hashes[f'skynav_msgs/msg/{name}'] == description['type_hashes'][0]['hash_string']


@pytest.mark.parametrize('name', ['custom.mcap', 'custom_dir'])
def test_custom_data_round_trip(tmp_path, name):
    with BagWriter(tmp_path / name) as writer:
        writer.set_custom_data('skynav_sim', 'scenario: teach\nseed: 3\n')
        writer.add_topic(SKYLINE_SH, 'skynav_msgs/msg/ShCoefficients')
    with open_bag(tmp_path / name) as bag:
        assert bag.custom_data == {'skynav_sim': 'scenario: teach\nseed: 3\n'}
        assert bag.ros_distro == 'rosbags'


def test_directory_bag_round_trip(tmp_path):
    written = write_sample_bag(tmp_path / 'run1', frames=2)
    assert (tmp_path / 'run1' / 'metadata.yaml').is_file()
    assert (tmp_path / 'run1' / 'run1.mcap').is_file()
    with open_bag(tmp_path / 'run1') as bag:
        assert bag.message_count == len(written) and bag.storage == 'mcap'


def test_writes_are_atomic(tmp_path):
    path = tmp_path / 'out.mcap'
    writer = BagWriter(path)
    writer.add_topic(SKYLINE_SH, 'skynav_msgs/msg/ShCoefficients')
    assert not path.exists() and writer.partial.is_dir()
    writer.close()
    assert path.is_file() and not writer.partial.exists()


def test_never_overwrites_or_discards(tmp_path):
    path = tmp_path / 'out.mcap'
    path.write_bytes(b'precious')
    with pytest.raises(BagError, match='exists already'):
        BagWriter(path)
    assert path.read_bytes() == b'precious'
    stale = tmp_path / '.new.mcap.partial'
    stale.mkdir()
    with pytest.raises(BagError, match='did not finish'):
        BagWriter(tmp_path / 'new.mcap')
    assert stale.is_dir()


def test_closes_with_data_even_after_an_error(tmp_path):
    path = tmp_path / 'out.mcap'
    sh = typestore().types
    with pytest.raises(RuntimeError), BagWriter(path) as writer:
        writer.add_topic(UV_IMAGE, 'sensor_msgs/msg/Image')
        image = sh['sensor_msgs/msg/Image'](
            sh['std_msgs/msg/Header'](sh['builtin_interfaces/msg/Time'](1, 0), CAMERA_FRAME),
            1,
            1,
            'mono8',
            0,
            1,
            __import__('numpy').zeros(1, 'uint8'),
        )
        writer.write(UV_IMAGE, 10**9, typestore().serialize_cdr(image, 'sensor_msgs/msg/Image'))
        raise RuntimeError('processing failed')
    with open_bag(path) as bag:
        assert bag.message_count == 1


def test_unknown_type_is_a_clear_error(tmp_path):
    with BagWriter(tmp_path / 'x.mcap') as writer, pytest.raises(BagError, match='no definition of foo/msg/Bar'):
        writer.add_topic('/x', 'foo/msg/Bar')


@pytest.mark.parametrize(
    ('damage', 'message'),
    [
        (lambda data: data[: len(data) // 2], 'truncated MCAP file'),
        (lambda data: b'not a bag at all', 'not an MCAP file'),
        (lambda data: b'', 'not an MCAP file'),
    ],
)
def test_damaged_files_are_one_clear_error(sample_bag, tmp_path, damage, message):
    path, _ = sample_bag
    broken = tmp_path / 'broken.mcap'
    broken.write_bytes(damage(path.read_bytes()))
    with pytest.raises(BagError, match=message) as info:
        with open_bag(broken) as bag:
            list(bag.messages())
    assert str(broken) in str(info.value) and '\n' not in str(info.value)


def test_corrupt_chunk_is_reported_when_reached(sample_bag, tmp_path):
    path, _ = sample_bag
    data = bytearray(path.read_bytes())
    with path.open('rb') as stream:
        chunk = mcap.reader.make_reader(stream).get_summary().chunk_indexes[0]
    # Overwrite the chunk's compression name and sizes: its contents can no longer be unpacked.
    start = chunk.chunk_start_offset + 1 + 8 + 28
    data[start : start + 24] = b'\xff' * 24
    broken = tmp_path / 'corrupt.mcap'
    broken.write_bytes(bytes(data))
    with pytest.raises(BagError, match='1 damaged chunk') as info:
        with open_bag(broken) as bag:
            list(bag.messages())
    assert '\n' not in str(info.value)
    assert SKYLINE_SH in str(info.value) and 'logged 0.000-0.300 s into the recording' in str(info.value)


@pytest.mark.parametrize(
    ('make', 'message'),
    [
        (lambda p: p, 'no such file'),
        (lambda p: p.mkdir() or p, 'not a rosbag2 directory'),
        (lambda p: (p.with_suffix('.txt').write_text('x'), p.with_suffix('.txt'))[1], 'not a bag'),
    ],
)
def test_not_a_bag(tmp_path, make, message):
    with pytest.raises(BagError, match=message):
        open_bag(make(tmp_path / 'thing'))
