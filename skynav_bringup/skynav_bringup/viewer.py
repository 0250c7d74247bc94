# SPDX-License-Identifier: Apache-2.0
"""Live topics forwarded to Foxglove: what `skynav view` runs (the Foxglove SDK's WebSocket server).

Every topic of the graph (or those asked for) becomes a Foxglove channel once it has a publisher: message
encoding `cdr`, schema encoding `ros2msg` with the type's full definition (its fields, then each type it uses after
a `MSG:` line, as MCAP recordings carry it), so Foxglove decodes the messages as it decodes a recording's. A topic
is subscribed (raw, with a profile that matches its publishers) only while some Foxglove client subscribes to its
channel, so an idle viewer costs the graph nothing but discovery. The bytes forwarded are the received CDR in the
form every reader takes (skynav_core.recording.cdr), logged at their time of receipt.

A topic that cannot be forwarded (a type without an installed definition, several types on one topic) is told
in one line, once, and the others go on. Hidden topics (a name part starting with '_', e.g. actions' feedback)
are left out.
"""

from __future__ import annotations

import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import partial
from typing import Any

import foxglove
from foxglove.websocket import ServerListener
from rclpy.node import Node
from rosbags.typesys import TypesysError

from skynav_core.errors import SkynavError
from skynav_core.namespaces import without_namespace
from skynav_core.recording.cdr import rosbags_cdr
from skynav_core.recording.qos import subscription_qos
from skynav_core.recording.typestore import ros2msg_definition
from skynav_core.ros import message_class

DISCOVERY_PERIOD = 1.0  # s between looks for topics that appeared
CLIENTS_PERIOD = 0.1  # s between looks at what the clients subscribe to (they are told within this)
FORWARD_DEPTH = 10  # subscriber history per topic: a viewer that falls behind loses the oldest messages
MESSAGE_ENCODING, SCHEMA_ENCODING = 'cdr', 'ros2msg'


@dataclass
class Forward:
    """One topic forwarded: its Foxglove channel, its type, and its subscription while a client wants it."""

    channel: foxglove.Channel
    msgtype: str
    msg_class: type
    subscription: Any = None


def hidden(topic: str) -> bool:
    """Return whether a topic is hidden (a part of its name starts with '_', as ROS 2 tools hide them)."""
    return any(part.startswith('_') for part in topic.split('/'))


def foxglove_channel(topic: str, msgtype: str, context: foxglove.Context | None = None) -> foxglove.Channel:
    """Return a Foxglove channel for CDR messages of `msgtype` with its ros2msg schema; UnknownMessageType if none."""
    schema = foxglove.Schema(name=msgtype, encoding=SCHEMA_ENCODING, data=ros2msg_definition(msgtype).encode())
    return foxglove.Channel(topic, schema=schema, message_encoding=MESSAGE_ENCODING, context=context)


class Viewer(ServerListener):
    """Advertises the graph's topics to Foxglove clients and forwards those they subscribe to."""

    def __init__(
        self,
        node: Node,
        topics: Iterable[str] | None = None,
        warn: Callable[[str], None] = print,
        say: Callable[[str], None] = lambda text: None,
        context: foxglove.Context | None = None,
        namespace: str = '',
    ) -> None:
        self.node = node
        self.namespace = namespace  # only the topics under it are advertised, by their names within it
        self.wanted = None if topics is None else set(topics)
        self.warn = warn
        self.say = say
        self.context = context
        self.forwards: dict[str, Forward] = {}
        self.refused: set[str] = set()
        self.forwarded: Counter = Counter()  # messages forwarded per topic
        self._clients: Counter = Counter()  # Foxglove subscriptions per topic (from the server's threads)
        self._lock = threading.Lock()
        self._changed = False
        # the server's threads only note a change; the executor (un)subscribes (the events executor of
        # `skynav view` has no guard conditions)
        self._timers = [
            node.create_timer(DISCOVERY_PERIOD, self.discover),
            node.create_timer(CLIENTS_PERIOD, self.follow_changed_clients),
        ]
        self.discover()

    # --- the foxglove.websocket.ServerListener protocol (called from the server's threads) -------

    def on_subscribe(self, client: Any, channel: Any) -> None:
        """A client subscribed to a channel."""
        with self._lock:
            self._clients[channel.topic] += 1
            self._changed = True

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        """A client unsubscribed from a channel (or went away)."""
        with self._lock:
            self._clients[channel.topic] = max(0, self._clients[channel.topic] - 1)
            self._changed = True

    # --- in the executor ----------------------------------------------------------------------------

    def discover(self) -> None:
        """Advertise every wanted topic that now has a publisher; tell once about one that cannot be forwarded."""
        for topic, types in self.node.get_topic_names_and_types():
            local = without_namespace(topic, self.namespace)
            if local is None or topic in self.forwards or topic in self.refused or hidden(local):
                continue
            if self.wanted is not None and local not in self.wanted:
                continue
            if not self.node.count_publishers(topic):
                continue
            if len(types) != 1:
                self.refuse(topic, f'it carries several types ({", ".join(types)})')
                continue
            try:  # the Python class first: a channel is advertised only for a topic that can be subscribed
                msg_class = message_class(types[0])
                channel = foxglove_channel(local, types[0], self.context)
            except (SkynavError, TypesysError) as exc:  # no definition, a crafted name, one rosbags cannot parse
                self.refuse(topic, ' '.join(str(exc).split()))
                continue
            self.forwards[topic] = Forward(channel, types[0], msg_class)
        self.follow_clients()

    def refuse(self, topic: str, reason: str) -> None:
        """Leave a topic out, saying why in one line."""
        self.refused.add(topic)
        self.warn(f'skynav view: {topic} is not forwarded: {reason}')

    def follow_changed_clients(self) -> None:
        """Follow the clients' subscriptions if they changed."""
        if self._changed:
            self.follow_clients()

    def follow_clients(self) -> None:
        """Subscribe to the topics some client wants now, and unsubscribe from the others."""
        with self._lock:
            wanted = {topic for topic, count in self._clients.items() if count > 0}
            self._changed = False
        for topic, forward in self.forwards.items():
            if forward.channel.topic() in wanted and forward.subscription is None:
                forward.subscription = self.node.create_subscription(
                    forward.msg_class,
                    topic,
                    partial(self.forward, topic),
                    subscription_qos(self.node.get_publishers_info_by_topic(topic), FORWARD_DEPTH),
                    raw=True,
                )
                self.say(f'skynav view: forwarding {topic} (a client subscribed)')
            elif forward.channel.topic() not in wanted and forward.subscription is not None:
                self.node.destroy_subscription(forward.subscription)
                forward.subscription = None
                self.say(f'skynav view: no longer forwarding {topic} (no client subscribes)')

    def forward(self, topic: str, data: bytes) -> None:
        """Send one received message to the clients subscribed to its channel."""
        forward = self.forwards[topic]
        forward.channel.log(rosbags_cdr(forward.msgtype, data), log_time=time.time_ns())
        self.forwarded[topic] += 1
