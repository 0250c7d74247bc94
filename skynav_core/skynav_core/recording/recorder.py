# SPDX-License-Identifier: Apache-2.0
"""Record live topics, as received CDR bytes, into a bag."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from functools import partial

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from ..namespaces import without_namespace
from ..ros import message_class
from .bag import BagError, BagWriter
from .cdr import rosbags_cdr
from .qos import bag_qos, subscription_qos
from .typestore import UnknownMessageType

# Subscriber history per topic: how far the writer may fall behind before messages are lost.
RECORD_DEPTH = 1000
# How often the graph is searched for topics that appeared (s).
DISCOVERY_PERIOD = 0.25
# After a stop request, spinning ends once no message arrived for this long (s) ...
DRAIN_QUIET = 0.3
# ... or after this long in all (s).
DRAIN_LIMIT = 5.0


class Recorder:
    """Subscribes raw to the wanted topics as they appear and writes every message to a BagWriter."""

    def __init__(
        self,
        node: Node,
        writer: BagWriter,
        topics: Iterable[str] | None = None,
        warn: Callable[[str], None] | None = None,
        namespace: str = '',
    ) -> None:
        self.node = node
        self.namespace = namespace  # only topics under it are recorded, named as outside it
        self.writer = writer
        self.wanted = None if topics is None else set(topics)
        self.received = 0
        self.warn = warn or (lambda text: node.get_logger().warning(text))
        self._subscriptions: dict[str, object] = {}
        self._types: dict[str, str] = {}
        self._ignored: set[str] = set()
        self._timer = node.create_timer(DISCOVERY_PERIOD, self.discover)
        self.discover()

    def discover(self) -> None:
        """Subscribe to every wanted topic that now has a publisher."""
        for topic, types in self.node.get_topic_names_and_types():
            name = without_namespace(topic, self.namespace)  # as the recording names it
            if name is None or name in self._subscriptions or name in self._ignored:
                continue
            if self.wanted is not None and name not in self.wanted:
                continue
            publishers = self.node.get_publishers_info_by_topic(topic)
            if not publishers:
                continue
            if len(types) != 1:
                self._ignore(name, f'{name} carries several types ({", ".join(types)}); not recorded')
                continue
            try:
                self.writer.add_topic(name, types[0], [bag_qos(p.qos_profile) for p in publishers])
                msg_class = message_class(types[0])
            except (BagError, UnknownMessageType) as exc:
                self._ignore(name, f'{name} not recorded: {exc}')
                continue
            self._types[name] = self.writer.topics[name]
            self._subscriptions[name] = self.node.create_subscription(
                msg_class,
                topic,
                partial(self._on_message, name),
                subscription_qos(publishers, RECORD_DEPTH),
                raw=True,
            )

    def _ignore(self, name: str, reason: str) -> None:
        self._ignored.add(name)
        self.warn(reason)

    def _on_message(self, topic: str, data: bytes) -> None:
        self.writer.write(topic, time.time_ns(), rosbags_cdr(self._types[topic], data))
        self.received += 1

    def drain(self, executor: SingleThreadedExecutor) -> None:
        """Take what is still queued: spin until nothing arrived for DRAIN_QUIET seconds."""
        self.node.destroy_timer(self._timer)
        deadline = time.monotonic() + DRAIN_LIMIT
        last_count, quiet_since = self.received, time.monotonic()
        while time.monotonic() < deadline and time.monotonic() - quiet_since < DRAIN_QUIET:
            executor.spin_once(timeout_sec=0.02)
            if self.received != last_count:
                last_count, quiet_since = self.received, time.monotonic()
