# SPDX-License-Identifier: Apache-2.0
"""Show what a recording holds: files, size, duration, and each topic with its type and count.

The layout follows `ros2 bag info`. BAG is a rosbag2 directory or a bare
.mcap file.
"""

from __future__ import annotations

import argparse
from datetime import UTC, datetime

from skynav_core.cli import add_skip_damaged

HELP = 'topics, types, counts and duration of a bag'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav info`."""
    parser.add_argument('bag', metavar='BAG', help='rosbag2 directory or .mcap file')
    add_skip_damaged(parser)


def _stamp(nanoseconds: int) -> str:
    """Return a time as `ros2 bag info` shows it: UTC date and seconds since the epoch."""
    seconds, rest = divmod(nanoseconds, 10**9)
    date = datetime.fromtimestamp(seconds, tz=UTC).strftime('%b %d %Y %H:%M:%S')
    return f'{date}.{rest:09d} ({seconds}.{rest:09d})'


def _size(size: float) -> str:
    """Return a size in bytes with a binary unit."""
    for unit in ('B', 'KiB', 'MiB', 'GiB'):
        if size < 1024 or unit == 'GiB':
            return f'{size:.1f} {unit}' if unit != 'B' else f'{size} B'
        size /= 1024
    raise AssertionError('unreachable')


def describe(bag) -> str:
    """Return the description of an open bag as text."""
    duration = (bag.end_time - bag.start_time) / 1e9 if bag.message_count else 0.0
    width = max((len(t) for t in bag.topics), default=0)
    type_width = max((len(t.msgtype) for t in bag.topics.values()), default=0)
    lines = [
        f'Files:             {", ".join(p.name for p in bag.files)}',
        f'Bag size:          {_size(bag.size)}',
        f'Storage id:        {bag.storage}',
        f'ROS Distro:        {bag.ros_distro or "unknown"}',
        f'Duration:          {duration:.9f}s',
    ]
    if bag.message_count:
        lines += [f'Start:             {_stamp(bag.start_time)}', f'End:               {_stamp(bag.end_time)}']
    lines.append(f'Messages:          {bag.message_count}')
    if getattr(bag, 'skipped', 0):  # --skip-damaged: what the damaged chunks held
        lines.append(f'Unreadable:        {bag.skipped} messages in damaged chunks (skipped)')
    for i, topic in enumerate(sorted(bag.topics.values(), key=lambda t: t.name)):
        lines.append(
            ('Topic information: ' if i == 0 else ' ' * 19)
            + f'Topic: {topic.name:<{width}} | Type: {topic.msgtype:<{type_width}} | Count: {topic.count}'
            + ' | Serialization Format: cdr'
        )
    if not bag.topics:
        lines.append('Topic information: none')
    return '\n'.join(lines)


def run(args: argparse.Namespace) -> int:
    """Print the description; return the exit code."""
    from skynav_core.recording.bag import open_bag

    with open_bag(args.bag) as bag:
        print(describe(bag))
    return 0
