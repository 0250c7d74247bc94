# SPDX-License-Identifier: Apache-2.0
"""Wait, on one host, until the graph is connected and has published enough: a helper the two-host tests run.

python graph_probe.py [--subscribers TOPIC=N ...] [--publishers TOPIC=N ...] [--messages TOPIC=N ...]
                      [--timeout S] [--log FILE]

Prints 'graph_probe: ready' once every topic has at least N subscribers / publishers known to this host and
each --messages topic's subscription has matched a publisher. Exits 0 once, moreover, N messages of every
--messages topic were received (counted from the probe's start), 1 with one line on timeout. With --log,
every message received is written there as a line 'TOPIC STAMP_NS RECEIVED_NS' (header stamp, wall clock
at reception), read from the serialized message (CDR: 4 bytes of encapsulation, then the header's stamp).
"""

from __future__ import annotations

import argparse
import struct
import sys
import time
from collections import Counter

from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from skynav_core.ros import message_class, spin_until, tool_node

RELIABLE = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE)


def counts(pairs: list[str]) -> dict[str, int]:
    """Return {topic: n} of 'TOPIC=N' arguments."""
    return {topic: int(n) for topic, _, n in (p.rpartition('=') for p in pairs)}


def main() -> int:
    """Wait as the arguments say; return the exit code."""
    parser = argparse.ArgumentParser()
    parser.add_argument('--subscribers', nargs='*', default=[])
    parser.add_argument('--publishers', nargs='*', default=[])
    parser.add_argument('--messages', nargs='*', default=[])
    parser.add_argument('--timeout', type=float, default=60.0)
    parser.add_argument('--log', help='write every message received there: topic, header stamp, reception time')
    args = parser.parse_args()
    subscribers, publishers, wanted = counts(args.subscribers), counts(args.publishers), counts(args.messages)
    received: Counter[str] = Counter()
    log = open(args.log, 'w', buffering=1) if args.log else None  # noqa: SIM115 (open for the whole run)

    def take(topic: str, data: bytes) -> None:
        received[topic] += 1
        if log is not None:
            sec, nanosec = struct.unpack_from('<iI', data, 4)
            log.write(f'{topic} {sec * 1_000_000_000 + nanosec} {time.time_ns()}\n')

    start = time.monotonic()
    with tool_node('graph_probe') as (node, executor):
        subscriptions = {}
        ready = False

        def done() -> bool:
            types = dict(node.get_topic_names_and_types())
            nonlocal ready
            for topic in set(wanted) - set(subscriptions):
                if topic in types:
                    subscriptions[topic] = node.create_subscription(
                        message_class(types[topic][0]), topic, lambda m, t=topic: take(t, m), RELIABLE, raw=True
                    )
            connected = (
                all(node.count_subscribers(t) >= n for t, n in subscribers.items())
                and all(node.count_publishers(t) >= n for t, n in publishers.items())
                and len(subscriptions) == len(wanted)
                and all(s.get_publisher_count() > 0 for s in subscriptions.values())
            )
            if connected and not ready:
                ready = True
                print(f'graph_probe: ready after {time.monotonic() - start:.1f} s', file=sys.stderr, flush=True)
            return connected and all(received[t] >= n for t, n in wanted.items())

        if spin_until(executor, done, args.timeout):
            return 0
        state = ', '.join(
            [f'{t}: {node.count_subscribers(t)}/{n} subscribers' for t, n in subscribers.items()]
            + [f'{t}: {node.count_publishers(t)}/{n} publishers' for t, n in publishers.items()]
            + [f'{t}: {received[t]}/{n} messages' for t, n in wanted.items()]
        )
        print(f'graph_probe: timeout after {args.timeout:g} s ({state})', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
