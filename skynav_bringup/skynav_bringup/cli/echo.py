# SPDX-License-Identifier: Apache-2.0
"""Print a topic's messages as YAML, like `ros2 topic echo`.

The type is found in the graph (or given with --type, then the topic may
appear later). Works for the standard types and skynav_msgs; long arrays are
abbreviated to their first elements.
"""

from __future__ import annotations

import argparse
import sys

from skynav_core.cli import add_namespace

HELP = "print a topic's messages as YAML"


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav echo`."""
    parser.add_argument('topic', metavar='TOPIC')
    parser.add_argument('--once', action='store_true', help='print one message and exit')
    add_namespace(parser, 'the graph whose TOPIC to print (/NS/TOPIC)')
    parser.add_argument('--count', type=int, metavar='N', help='print N messages and exit')
    parser.add_argument('--type', metavar='PKG/msg/TYPE', help='message type; skips looking it up in the graph')
    parser.add_argument(
        '--truncate-length',
        type=int,
        default=16,
        metavar='N',
        help='show at most N elements of an array (default 16); 0 shows all',
    )
    parser.add_argument(
        '--wait',
        type=float,
        default=10.0,
        metavar='SECONDS',
        help='how long to look for the topic in the graph before giving up (default 10)',
    )


def run(args: argparse.Namespace) -> int:
    """Echo the topic; return the exit code."""
    from rclpy.validate_topic_name import validate_topic_name

    from skynav_core.namespaces import namespaced
    from skynav_core.recording.msgyaml import to_yaml
    from skynav_core.recording.qos import subscription_qos
    from skynav_core.recording.typestore import ensure_type, typestore
    from skynav_core.ros import StopRequest, message_class, spin_until, tool_node

    from . import CliError

    count = 1 if args.once else args.count
    if count is not None and count < 1:
        raise CliError('--count must be at least 1', exit_code=2)
    try:
        validate_topic_name(args.topic)
    except Exception as exc:
        reason = str(exc).splitlines()[0].removeprefix('Invalid topic name: ').rstrip(':')
        raise CliError(f'{args.topic!r} is not a valid topic name: {reason}', exit_code=2) from None
    truncate = args.truncate_length or None

    with StopRequest() as stop, tool_node('skynav_echo') as (node, executor):
        topic = namespaced(args.topic, args.namespace) if args.namespace else node.resolve_topic_name(args.topic)

        def topic_types() -> list[str]:
            return dict(node.get_topic_names_and_types()).get(topic, [])

        if args.type:
            msgtype = args.type
        else:
            spin_until(executor, lambda: bool(topic_types()) or stop.requested, args.wait)
            types = topic_types()
            if stop.requested:
                return 0
            if not types:
                known = sorted(name for name, _ in node.get_topic_names_and_types())
                raise CliError(
                    f'no topic {topic} in the graph after {args.wait:g} s (topics seen: {", ".join(known) or "none"})'
                )
            if len(types) > 1:
                raise CliError(f'{topic} carries several types ({", ".join(types)}); choose one with --type')
            msgtype = types[0]
        msgtype = ensure_type(msgtype)
        msg_class = message_class(msgtype)
        printed = 0

        def on_message(data: bytes) -> None:
            nonlocal printed
            if count is not None and printed >= count:
                return
            sys.stdout.write(to_yaml(typestore().deserialize_cdr(data, msgtype), truncate) + '---\n')
            sys.stdout.flush()
            printed += 1

        qos = subscription_qos(node.get_publishers_info_by_topic(topic), depth=10)
        node.create_subscription(msg_class, topic, on_message, qos, raw=True)
        while not stop.requested and (count is None or printed < count):
            executor.spin_once(timeout_sec=0.1)
    return 0
