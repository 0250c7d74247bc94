# SPDX-License-Identifier: Apache-2.0
"""The node graph in one process, driven by a recording: what `skynav run` (and the offline tools) use.

The real node classes are created with a router instead of DDS. Each recorded input is delivered to
the nodes that subscribe its topic; whatever they publish is recorded and delivered to its
subscribers before the call returns, depth first. So every input frame is processed, in recording
order, whatever the speed of the machine, and the output is the same on every run.
"""

from __future__ import annotations

import importlib
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.signals import SignalHandlerOptions

from .node import DIAGNOSTICS_PERIOD, SkynavNode
from .nodes import NodeSpec
from .process.environment import apply_ros_environment
from .recording.bag import BagError, BagReader, RawMessage
from .ros import message_class

# (topic, type name, log time in ns, serialized message)
Sink = Callable[[str, str, int, bytes], None]


def node_class(spec: NodeSpec) -> type[SkynavNode]:
    """Return the node class a `skynav.nodes` entry point names ('module:Class')."""
    module, _, name = spec.entry.partition(':')
    return getattr(importlib.import_module(module), name)


def graph_readers(specs: Iterable[NodeSpec]) -> dict[str, list[str]]:
    """Return, per topic, the names of the nodes of a graph that subscribe to it."""
    readers: dict[str, list[str]] = defaultdict(list)
    for spec in specs:
        for topic in node_class(spec).INPUT_TOPICS:
            readers[topic].append(spec.name)
    return dict(readers)


def type_name(message: Any) -> str:
    """Return 'pkg/msg/Name' of an rclpy message."""
    return f'{type(message).__module__.split(".")[0]}/msg/{type(message).__name__}'


@dataclass
class Output:
    """One message a node published during a run."""

    topic: str
    message: Any
    log_time: int


class InProcessGraph:
    """Nodes wired by a synchronous in-process bus (rclpy must be initialised)."""

    def __init__(self, specs: Iterable[NodeSpec], sink: Sink | None = None, context: Context | None = None) -> None:
        self._subscribers: dict[str, list[Callable[[Any], None]]] = defaultdict(list)
        self._sink = sink
        self._now = 0
        self._next_diagnostics: int | None = None
        self.outputs: list[Output] = []
        self.keep_outputs = False
        self.nodes: list[SkynavNode] = [
            node_class(spec)(router=self, context=context)  # type: ignore[call-arg]  # a concrete node names itself
            for spec in specs
        ]

    # --- the Router protocol ------------------------------------------------------------------

    def subscribe(self, topic: str, callback: Callable[[Any], None]) -> None:
        """Deliver every message published on `topic` to `callback`."""
        self._subscribers[topic].append(callback)

    def publish(self, topic: str, message: Any) -> None:
        """Record an output and deliver it to its subscribers at once, as they would receive it over DDS.

        Subscribers get the message serialized and read back: a float32 field holds a Python float until it
        is serialized, so a node handed the publisher's object would compute with more precision than it ever
        gets live (and `skynav run` would differ from the running graph in the last digits).
        """
        data = serialize_message(message) if self._sink is not None or topic in self._subscribers else b''
        if self._sink is not None:
            self._sink(topic, type_name(message), self._now, data)
        if self.keep_outputs:
            self.outputs.append(Output(topic, message, self._now))
        if callbacks := list(self._subscribers.get(topic, ())):
            delivered = deserialize_message(data, type(message))
            for callback in callbacks:
                callback(delivered)

    def now_ns(self) -> int:
        """Return the log time of the input being processed."""
        return self._now

    def advance(self, now_ns: int) -> None:
        """Set the graph's time (ns) for what is published next: a simulator's clock, stepping the graph itself."""
        self._now = now_ns

    # --- driving --------------------------------------------------------------------------------

    @property
    def input_topics(self) -> set[str]:
        """Return the topics some node subscribes to."""
        return set(self._subscribers)

    def feed(self, raw: RawMessage) -> None:
        """Deliver one recorded message (and everything it causes) to the graph."""
        self._now = raw.log_time
        if self._next_diagnostics is None:
            self._next_diagnostics = raw.log_time + int(DIAGNOSTICS_PERIOD * 1e9)
        try:
            message = deserialize_message(raw.data, message_class(raw.msgtype))
        except RuntimeError as exc:  # rclpy's RMWError: bytes that are no message of their type (a crafted bag)
            raise BagError(
                f'a {raw.msgtype} message on {raw.topic} (logged at {raw.log_time} ns) does not decode: '
                + ' '.join(str(exc).split(', at ')[0].split())
            ) from None
        for callback in list(self._subscribers.get(raw.topic, ())):
            callback(message)
        if raw.log_time >= self._next_diagnostics:
            self.publish_diagnostics()
            self._next_diagnostics = raw.log_time + int(DIAGNOSTICS_PERIOD * 1e9)

    def publish_diagnostics(self) -> None:
        """Have every node publish its status now (in recording time)."""
        for node in self.nodes:
            node.publish_diagnostics()

    def run(self, bag: BagReader, progress: Callable[[int], None] | None = None) -> int:
        """Feed every message of the topics the graph subscribes to; return how many were fed."""
        topics = sorted(self.input_topics & set(bag.topics))
        fed = 0
        for raw in bag.messages(topics):
            self.feed(raw)
            fed += 1
            if progress is not None:
                progress(1)
        if fed:
            self.publish_diagnostics()
        return fed

    def destroy(self) -> None:
        """Destroy every node."""
        for node in self.nodes:
            node.destroy_node()


@contextmanager
def in_process(
    specs: Iterable[NodeSpec], ros_args: list[str] | None = None, sink: Sink | None = None
) -> Iterator[InProcessGraph]:
    """Yield an InProcessGraph of the given nodes in an rclpy context of its own (ros_args: --params-file, -p)."""

    apply_ros_environment()
    context = Context()
    rclpy.init(args=['--ros-args', *(ros_args or [])], context=context, signal_handler_options=SignalHandlerOptions.NO)
    graph = None
    try:
        graph = InProcessGraph(specs, sink, context)
        yield graph
    finally:
        if graph is not None:
            graph.destroy()
        rclpy.try_shutdown(context=context)


def process(bag: BagReader, specs: Iterable[NodeSpec], ros_args: list[str] | None = None) -> list[Output]:
    """Run nodes over a recording in this process; return everything they published, in order."""
    with in_process(specs, ros_args) as graph:
        graph.keep_outputs = True
        graph.run(bag)
        return list(graph.outputs)
