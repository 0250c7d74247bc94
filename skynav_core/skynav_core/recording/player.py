# SPDX-License-Identifier: Apache-2.0
"""Publish a recording's messages on their topics with the recorded timing, as the stored CDR bytes."""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from rclpy.duration import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import ReliabilityPolicy

from ..namespaces import namespaced
from ..ros import StopRequest, message_class, spin_until
from .bag import BagReader, RawMessage
from .qos import replay_qos

# History kept per replayed topic: the burst a slow subscriber may fall behind before losing messages.
REPLAY_DEPTH = 100
# Longest wait at the end for subscribers to acknowledge what was published (s), for all topics together.
ACK_TIMEOUT = 5.0
# Longest single sleep between checks for Ctrl-C while waiting for a message's time (s).
SLEEP_SLICE = 0.05
# Time given to subscribers after this publisher has matched them (s): discovery runs both ways, and a subscriber
# may match the publisher a little later; a best-effort one drops whatever comes before. Without it, about one
# replay in three into a running graph lost its first exposure (test/test_replay_passes.py).
SUBSCRIBER_SETTLE = 1.0
# Time given to best-effort subscribers to take the last messages before the publishers go (s): they acknowledge
# nothing, and what they have not taken from shared memory when the publishing process ends is lost (about one
# replay in three lost its last exposure so). Reliable subscribers have acknowledged everything by then.
SUBSCRIBER_LINGER = 1.0
# While waiting for subscribers, what is still missing is told this often (s).
WAIT_REPORT_PERIOD = 5.0


@dataclass
class ReplayStats:
    """What a replay published."""

    published: Counter = field(default_factory=Counter)
    loops: int = 0
    wall_time: float = 0.0
    unacknowledged: list[str] = field(default_factory=list)
    best_effort: int = 0  # best-effort subscriptions given SUBSCRIBER_LINGER s to take the last messages

    @property
    def total(self) -> int:
        """Return the number of messages published on all topics."""
        return sum(self.published.values())


class Player:
    """Publishers for the chosen topics of a bag, and the loop that feeds them."""

    def __init__(self, node: Node, bag: BagReader, topics: Sequence[str] | None = None, namespace: str = '') -> None:
        self.node = node
        self.bag = bag
        self.topics = list(bag.topics) if topics is None else list(topics)
        #: recorded name -> the name it is published on (under `namespace`, if given)
        self.names = {name: namespaced(name, namespace) if namespace else name for name in self.topics}
        self.publishers: dict[str, Publisher] = {}
        for name in self.topics:
            topic = bag.topics[name]
            self.publishers[name] = node.create_publisher(
                message_class(topic.msgtype), self.names[name], replay_qos(topic.offered_qos, REPLAY_DEPTH)
            )

    @property
    def message_count(self) -> int:
        """Return the number of messages one pass publishes."""
        return sum(self.bag.topics[name].count for name in self.topics)

    def wait_for_subscribers(
        self,
        executor: SingleThreadedExecutor,
        expected: Mapping[str, int | Sequence[str]],
        timeout: float,
        stop: StopRequest | None = None,
        report: Callable[[list[str], float], None] | None = None,
    ) -> list[str]:
        """Wait until each topic has matched its expected subscribers; return what is still missing, one per topic.

        `expected` gives per topic a number of subscribers, or the names of the nodes that must subscribe to it
        (each matched: its subscription in the graph, and as many matched subscriptions as names). `report` is
        told what is missing and the seconds waited, every WAIT_REPORT_PERIOD s of waiting.
        """

        def missing() -> list[str]:
            short = []
            for topic, publisher in self.publishers.items():
                want = expected.get(topic, 0)
                matched = publisher.get_subscription_count()
                if isinstance(want, int):
                    if matched < want:
                        short.append(f'{self.names[topic]} ({matched} of {want} subscribers)')
                    continue
                present = {info.node_name for info in self.node.get_subscriptions_info_by_topic(self.names[topic])}
                absent = [name for name in want if name not in present]
                if absent or matched < len(want):
                    short.append(
                        f'{self.names[topic]} ({matched} subscribers; not yet: {", ".join(absent) or "matching"})'
                    )
            return short

        def stopped() -> bool:
            return stop is not None and stop.requested

        started = time.monotonic()
        while (waited := time.monotonic() - started) < timeout:
            if spin_until(executor, lambda: stopped() or not missing(), min(WAIT_REPORT_PERIOD, timeout - waited)):
                if not stopped():
                    spin_until(executor, stopped, SUBSCRIBER_SETTLE)
                break
            if report is not None and time.monotonic() - started < timeout:
                report(missing(), time.monotonic() - started)
        return missing()

    def play(
        self,
        rate: float,
        loop: bool,
        stop: StopRequest,
        on_message: Callable[[RawMessage], None] | None = None,
    ) -> ReplayStats:
        """Publish every message at its recorded time scaled by 1/`rate` (0: as fast as possible)."""
        stats = ReplayStats()
        started = time.monotonic()
        while not stop.requested:
            pass_start = time.monotonic()
            for message in self.bag.messages(self.topics):
                if rate > 0:
                    due = pass_start + (message.log_time - self.bag.start_time) / 1e9 / rate
                    while not stop.requested and (wait := due - time.monotonic()) > 0:
                        time.sleep(min(wait, SLEEP_SLICE))
                if stop.requested:
                    break
                self.publishers[message.topic].publish(message.data)
                stats.published[message.topic] += 1
                if on_message is not None:
                    on_message(message)
            stats.loops += 1
            if not loop:
                break
        stats.wall_time = time.monotonic() - started
        acked_by = time.monotonic() + ACK_TIMEOUT  # one deadline for every topic (a dead reader never acknowledges)
        stats.unacknowledged = [
            name
            for name, publisher in self.publishers.items()
            if not publisher.wait_for_all_acked(Duration(seconds=max(acked_by - time.monotonic(), 0.0)))
        ]
        stats.best_effort = self.best_effort_subscriptions()
        if stats.best_effort:
            time.sleep(SUBSCRIBER_LINGER)
        return stats

    def best_effort_subscriptions(self) -> int:
        """Return the subscriptions to the replayed topics that take them best effort (they acknowledge nothing)."""
        return sum(
            info.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
            for topic in self.publishers
            for info in self.node.get_subscriptions_info_by_topic(self.names[topic])
        )
