# SPDX-License-Identifier: Apache-2.0
"""Crafted bags: malformed metadata and type names are refused by every bag-reading command in one line."""

from __future__ import annotations

import shutil

import mcap.reader
import pytest
import yaml
from mcap.writer import Writer

from skynav_core.names import UV_CAMERA_INFO
from skynav_testing import BAGS, one_line_error

SOURCE = BAGS / 'synthetic_garden_compass.mcap'
# Commands that read a bag, each on the crafted one: (arguments; {bag} and {out} filled in).
COMMANDS = [
    ['info', '{bag}'],
    ['map', 'build', '{bag}', '--out', '{out}/map.db'],
    ['replay', '{bag}', '--rate', '0'],
    ['run', '{bag}', '--out', '{out}/run.mcap', '--nodes', 'skyline'],
    ['eval', 'compass', '{bag}', '--methods', 'fft-masked', '--plots', '{out}/plots'],
]
METADATA_CHANGES = {
    'custom_data_list': ({'custom_data': [1, 2]}, 'custom_data is'),
    'count_lots': ({'message_count': 'lots'}, "message_count is 'lots', not a count"),
    'negative_count': ({'message_count': -3}, 'message_count is'),
    'topics_not_list': ({'topics_with_message_count': 'many'}, 'topics_with_message_count is'),
    'file_outside': ({'relative_file_paths': ['../../etc/passwd']}, 'a storage file outside the bag'),
    'duration_text': ({'duration': {'nanoseconds': 'long'}}, 'duration.nanoseconds is'),
}
TYPE_NAMES = ['.evil/msg/X', '../msg/Passwd', 'std_msgs/msg/__class__', 'std_msgs/msg/', 'a/b/c/d', 'std_msgs/srv/X']


def rosbag2_metadata() -> dict:
    """Return the rosbag2 metadata the bundled bag carries."""
    with SOURCE.open('rb') as stream:
        record = next(m for m in mcap.reader.make_reader(stream).iter_metadata() if m.name == 'rosbag2')
    return yaml.safe_load(record.metadata['serialized_metadata'])


def directory_bag(root, name: str, change: dict):
    """Return a rosbag2 directory holding the bundled bag, its metadata.yaml changed by `change`."""
    folder = root / name
    folder.mkdir()
    shutil.copy(SOURCE, folder / f'{name}.mcap')
    info = rosbag2_metadata() | {'relative_file_paths': [f'{name}.mcap']}
    info['files'] = [dict(f, path=f'{name}.mcap') for f in info.get('files', [])]
    (folder / 'metadata.yaml').write_text(yaml.safe_dump({'rosbag2_bagfile_information': info | change}))
    return folder


def typed_bag(path, msgtype: str, data: bytes = b'\x00\x01\x00\x00\x02\x00\x00\x00a\x00'):
    """Write a small MCAP file whose one topic claims the type `msgtype`, each message holding `data`."""
    with path.open('wb') as stream:
        writer = Writer(stream)
        writer.start(profile='ros2', library='crafted')
        channel = writer.register_channel(
            UV_CAMERA_INFO, 'cdr', writer.register_schema(msgtype, 'ros2msg', b'string data\n')
        )
        for t in range(3):
            writer.add_message(channel, log_time=10**9 + t, publish_time=10**9 + t, data=data)
        writer.finish()
    return path


def assert_refused(call, arguments: list[str], bag, out, expected: str) -> None:
    code, stdout, stderr = call([a.format(bag=bag, out=out) for a in arguments])
    assert code == 1 and one_line_error(stderr), (arguments, code, stderr)
    assert expected in stderr and 'Traceback' not in stdout, (arguments, stderr)


def test_the_unchanged_directory_bag_reads(tmp_path, skynav_main):
    code, stdout, stderr = skynav_main(['info', str(directory_bag(tmp_path, 'plain', {}))])
    assert code == 0 and 'Messages:          155' in stdout, stderr


@pytest.mark.parametrize('name', METADATA_CHANGES)
def test_malformed_metadata_is_refused_by_every_command(tmp_path, name, skynav_main):
    change, expected = METADATA_CHANGES[name]
    bag = directory_bag(tmp_path, name, change)
    for arguments in COMMANDS:
        assert_refused(skynav_main, arguments, bag, tmp_path, expected)


@pytest.mark.parametrize('msgtype', TYPE_NAMES)
def test_crafted_type_names_are_refused_by_every_command(tmp_path, msgtype, skynav_main):
    bag = typed_bag(tmp_path / 'typed.mcap', msgtype)
    for arguments in COMMANDS:
        assert_refused(skynav_main, arguments, bag, tmp_path, 'not a message type name')


def test_messages_that_do_not_decode_are_one_line(tmp_path, skynav_main):
    # A well-formed file (checksums right) whose camera info bytes are no CameraInfo: a crafted bag.
    bag = typed_bag(
        tmp_path / 'garbage.mcap', 'sensor_msgs/msg/CameraInfo', b'\x00\x01\x00\x00\xff\xff\xff\x7f' + bytes(20)
    )
    assert_refused(skynav_main, COMMANDS[3], bag, tmp_path, 'does not decode')
