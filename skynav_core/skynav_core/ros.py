# SPDX-License-Identifier: Apache-2.0
"""Small rclpy helpers shared by the `skynav` tools and the nodes.

Import this module only after :func:`skynav_core.environment.apply_ros_environment`
has run (the `skynav` command and :func:`run_node` take care of it).
"""

from __future__ import annotations

import importlib
import signal
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType

import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from .environment import apply_ros_environment
from .network import make_super_client
from .typestore import UnknownMessageType, action_part, split_type


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
def tool_node(name: str, args: list[str] | None = None) -> Iterator[tuple[Node, SingleThreadedExecutor]]:
    """Yield a node and its executor in a context of their own; signals are left to the caller.

    The node has no /rosout logger and no parameter services, so a recorder of
    every topic does not record its own chatter. With a discovery server it is a
    super client, which learns of every topic of the graph.
    """
    apply_ros_environment()
    make_super_client()
    context = Context()
    rclpy.init(args=args, context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = Node(name, context=context, enable_rosout=False, start_parameter_services=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor
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


def run_node(node_factory: Callable[[], Node], args: list[str] | None = None) -> int:
    """Run one node until Ctrl-C or SIGTERM: the body of every skynav node's main(); return an exit code."""
    apply_ros_environment()
    # A node that drives the robot stops it on the way out, which needs the context alive: it takes the signals as
    # KeyboardInterrupt (SIGTERM too) instead of rclpy's handler, which shuts the context down first.
    own_signals = getattr(node_factory, 'stops_on_signal', False)
    if own_signals:
        signal.signal(signal.SIGTERM, signal.default_int_handler)
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO if own_signals else SignalHandlerOptions.ALL)
    node = None
    try:
        node = node_factory()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if rclpy.ok():  # a real failure, not a callback that raced the shutdown a signal started
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
