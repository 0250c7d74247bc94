# SPDX-License-Identifier: Apache-2.0
"""Record live topics into a rosbag2 MCAP recording.

OUT ending in .mcap becomes a bare MCAP file, any other name a rosbag2
directory. Messages are stored as received (CDR) with their type definitions,
so `ros2 bag`, rosbags, the mcap tools and Foxglove read the file. Until the
recording ends, data goes to a hidden .OUT.partial directory beside OUT;
Ctrl-C or SIGTERM takes what is still queued, finishes the file and moves it
into place.
"""

from __future__ import annotations

import argparse
import sys

from skynav_core.cli import add_namespace

HELP = 'record live topics into an MCAP bag'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav record`."""
    parser.add_argument('out', metavar='OUT.mcap', help='the recording to write (must not exist)')
    parser.add_argument('topics', nargs='*', metavar='TOPIC', help='topics to record; they may appear later')
    parser.add_argument('--all', action='store_true', help='record every topic, also those that appear later')
    parser.add_argument('--no-compression', action='store_true', help='store chunks uncompressed (default zstd)')
    add_namespace(
        parser,
        "the graph to record: TOPIC (and --all) within it, stored by the contract's names (/NS/skyline/sh "
        'as /skyline/sh)',
    )


def run(args: argparse.Namespace) -> int:
    """Record until Ctrl-C or SIGTERM; return the exit code."""
    from skynav_core.recording.bag import BagWriter
    from skynav_core.recording.recorder import Recorder
    from skynav_core.ros import StopRequest, tool_node

    from . import CliError

    if not args.topics and not args.all:
        raise CliError('name the topics to record, or pass --all', exit_code=2)
    if args.topics and args.all:
        raise CliError('give either topics or --all, not both', exit_code=2)
    for topic in args.topics:
        if not topic.startswith('/') or ' ' in topic:
            raise CliError(f'{topic!r} is not an absolute topic name (like /camera/uv/image_raw)', exit_code=2)

    def warn(text: str) -> None:
        print(f'skynav record: warning: {text}', file=sys.stderr)

    with BagWriter(args.out, compress=not args.no_compression) as writer:
        with StopRequest() as stop, tool_node('skynav_record') as (node, executor):
            recorder = Recorder(node, writer, None if args.all else args.topics, warn=warn, namespace=args.namespace)
            where = f' of {args.namespace}' if args.namespace else ''
            print(
                f'skynav record: recording {"every topic" if args.all else " ".join(args.topics)}{where} '
                f'into {args.out}; Ctrl-C to stop',
                file=sys.stderr,
            )
            while not stop.requested:
                executor.spin_once(timeout_sec=0.1)
            recorder.drain(executor)
    for topic in args.topics:
        if not writer.counts.get(topic):
            warn(f'nothing received on {topic}')
    summary = ', '.join(f'{t}: {n}' for t, n in sorted(writer.counts.items())) or 'no messages'
    print(f'skynav record: wrote {recorder.received} messages to {writer.path} ({summary})', file=sys.stderr)
    return 0
