# SPDX-License-Identifier: Apache-2.0
"""Small rclpy helpers shared by the `skynav` tools and the nodes.

Import this module only after :func:`skynav_core.process.environment.apply_ros_environment`
has run (the `skynav` command and :func:`run_node` take care of it).
"""

from __future__ import annotations

import importlib
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType

import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from .process.environment import apply_ros_environment
from .process.network import make_super_client
from .recording.typestore import UnknownMessageType, action_part, split_type


def message_class(msgtype: str) -> type:
    """Return the rclpy message class of 'pkg/msg/Name' (or of an action's 'pkg/action/Name_Part'); raise
    UnknownMessageType when not installed."""
    package, kind, name = split_type(msgtype)
    try:
        module = importlib.import_module(f'{package}.{kind}')
        if kind == 'action':
            action, part = action_part(name)
            return getattr(getattr(module, action).Impl if part == 'FeedbackMessage' else getattr(module, action), part)
        return getattr(module, name)
    except (ImportError, AttributeError, ValueError):
        raise UnknownMessageType(
            f'message type {package}/{kind}/{name} is not installed (no Python module {package}.{kind})'
        ) from None


class StopRequest:
    """Turn SIGINT and SIGTERM into a flag while active, so a loop can finish its work and exit cleanly."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.requested = False
        self.count = 0
        self._previous: dict[int, Callable[[int, FrameType | None], object] | int | None] = {}

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        self.requested = True
        self.count += 1

    def __enter__(self) -> StopRequest:
        self._previous = {s: signal.signal(s, self._handle) for s in self.SIGNALS}
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)


@contextmanager
def tool_node(
    name: str, args: list[str] | None = None, events: bool = False
) -> Iterator[tuple[Node, SingleThreadedExecutor]]:
    """Yield a node and its executor in a context of their own; signals are left to the caller.

    `events` chooses rclpy's EventsExecutor (callbacks dispatched from C++: a fraction of the CPU per message of
    the single-threaded executor; no guard conditions) for a tool that takes many messages.

    The node has no /rosout logger and no parameter services, so a recorder of
    every topic does not record its own chatter. With a discovery server it is a
    super client, which learns of every topic of the graph.
    """
    apply_ros_environment()
    make_super_client()
    context = Context()
    rclpy.init(args=args, context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = Node(name, context=context, enable_rosout=False, start_parameter_services=False)
    executor = EventsExecutor(context=context) if events else SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor  # type: ignore[misc]  # the events executor passes for an Executor
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def spin_until(executor: SingleThreadedExecutor, done: Callable[[], bool], timeout: float) -> bool:
    """Spin until `done()` is true or `timeout` seconds pass; return done()."""
    deadline = time.monotonic() + timeout
    while not done():
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return done()
        executor.spin_once(timeout_sec=min(0.05, remaining))
    return True


SIGNAL_POLL_S = 0.1  # s: how often a node's spin loop looks whether a signal came


def run_node(node_factory: Callable[[], Node], args: list[str] | None = None) -> int:
    """Run one node until Ctrl-C or SIGTERM: the body of every skynav node's main(); return an exit code."""
    # Every node takes the signals itself (a flag its spin loop looks at) instead of rclpy's handler, which shuts the
    # context down from a thread of its own: that shutdown raced destroy_node on the main thread and could hang it in
    # the middleware, and a node that drives the robot needs the context alive to send its zero command on the way
    # out. A flag, not KeyboardInterrupt, so that a signal never lands inside rclpy's own code and leaves it half done;
    # one way down for every node: the spin loop ends, the node is destroyed, then the context shuts down.
    stop = threading.Event()
    node = None
    try:  # a signal at any moment from here on, even while rclpy starts or the node is built, ends quietly
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, lambda *_: stop.set())
        apply_ros_environment()
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        node = node_factory()
        spin_until_signal(node, stop)
    except ExternalShutdownException:  # the context was shut down by other code in this process
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def spin_until_signal(node: Node, stop: threading.Event) -> None:
    """Spin one node on an executor of its own until `stop` is set (looked at every SIGNAL_POLL_S s)."""
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=SIGNAL_POLL_S)
    finally:
        executor.remove_node(node)
        # now, while the context is up: left to the garbage collector (the node keeps a reference to its executor)
        # it would destroy its guard condition after rclpy's shutdown and print a traceback at exit
        executor.shutdown()
