# SPDX-License-Identifier: Apache-2.0
"""What every skynav node shares: inputs and outputs that run live or in-process, bad-input accounting, diagnostics.

A skynav node is an ordinary rclpy node with three habits:

- it declares its topics with `input()` and `output()` by the contract's names and publishes with
  `emit()`, so the same code runs on live topics (`skynav launch`; there the names are relative to the
  node's namespace, skynav_core.namespaces) and, given a router, inside `skynav run`, where every
  message is delivered synchronously and none can be dropped;
- bad input never kills it: `reject(reason, detail)` logs one clear line for the first input of each
  kind of problem, counts every one, and the node goes on (`in_order` rejects an input no newer than
  the last one taken as 'out_of_order'); an exception in a callback is logged and counted the same way;
- no input is lost unseen: `drop(cause, count, detail)` counts inputs that never got processed (lost
  before the callback: a gap in the publisher's sequence numbers; waiting too long for their partner
  or for camera info; waiting when the time restarted), logged once per cause;
- an input stamped more than `max_stamp_jump_s` before or after the last one taken (a camera clock
  that jumps, a recording replayed again) restarts the node's time: one log line, a count, and
  `reset_time()` forgets what depended on the old time, so later inputs are taken again;
- its timeouts measure `elapsed_ns()`, the time passed on the node's clock with its jumps left out
  (skynav_core.elapsed: sim time before the first /clock, a recording's clock that restarts), read
  at each input and every TIME_READ_PERIOD s of the node's clock, so no timeout fires from a clock that
  starts late or jumps;
- its parameters are turned into working state by one method, `configure(values)`, which raises
  ValueError for values it cannot use: at start-up the node then keeps its defaults, at run time the
  change is refused with that reason;
- it knows how the camera is mounted (`mount`: camera_link's rotation in base_link, skynav_core.mount): from
  the parameter `camera_mount_rpy_deg` that every node takes, or, in a node that calls `listen_for_mount()`,
  from /tf_static once that links base_link and camera_link (it wins over the parameter).

It publishes a DiagnosticStatus on /diagnostics once a second: output rate, processing time per
input, latency (from the receipt of the input to the publication of its output, live only), and
counts of inputs received, outputs published, inputs rejected (by reason), inputs dropped (by cause),
time restarts and callback errors.
"""

from __future__ import annotations

import time
import traceback
from collections import Counter, deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, ClassVar, Protocol

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from tf2_msgs.msg import TFMessage

from .elapsed import ElapsedTime
from .mount import StaticTransforms, describe, mount_from_rpy_deg
from .names import DIAGNOSTICS, TF_STATIC
from .namespaces import relative
from .parameters import COMMON_PARAMETERS, ParameterTable

# Camera topics: best effort matches any publisher (drivers often publish best effort).
SENSOR_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
# skynav's own topics: reliable, with room for 5 s of frames at 10 Hz: a node that starts, or stalls, while the
# frames come takes the burst its upstream sends on catching up (a queue of 10 overflowed after a robot restart).
STREAM_DEPTH = 50
STREAM_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=STREAM_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
# /tf_static as tf2's static listener takes it: latched (transient local), reliable, a long history
TF_STATIC_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
MOUNT_PARAMETER = 'camera_mount_rpy_deg'
DIAGNOSTICS_PERIOD = 1.0  # s
# s of the node's clock between readings of elapsed_ns() when no input comes (each input reads it too): under
# max_stamp_jump_s, so that a running clock's steps count; longer costs less (each wake-up of a node costs ~1 ms)
TIME_READ_PERIOD = 0.5
UNBOUNDED_STEP_NS = 2**63 - 1  # in the in-process graph every forward step of the inputs' time passes
PROCESSING_WINDOW = 100  # inputs whose processing times the diagnostics summarise
# rmw's value of a message-info sequence number the middleware does not provide.
SEQUENCE_UNSUPPORTED = 2**64 - 1


class Router(Protocol):
    """The in-process message bus of `skynav run`."""

    def subscribe(self, topic: str, callback: Callable[[Any], None]) -> None:
        """Deliver every message published on `topic` to `callback`."""

    def publish(self, topic: str, message: Any) -> None:
        """Record `message` and deliver it to the topic's subscribers before returning."""

    def now_ns(self) -> int:
        """Return the time of the input being processed (ns since the epoch)."""


class SkynavNode(Node):
    """Base class of the skynav nodes."""

    #: Nodes that compare against a map are left out of `skynav run` when no map is given.
    needs_map: ClassVar[bool] = False
    #: The node's parameters (declared with declare_table); the shipped parameter file is made from these tables.
    PARAMETERS: ClassVar[ParameterTable] = {}
    #: The topics the node subscribes to (with input()): `skynav replay` waits until each has matched them all.
    INPUT_TOPICS: ClassVar[tuple[str, ...]] = ()

    def __init__(self, name: str, router: Router | None = None, context: Context | None = None) -> None:
        super().__init__(name, context=context)
        self.router = router
        self.received: Counter = Counter()
        self.published: Counter = Counter()
        self.rejected: Counter = Counter()
        self.dropped: Counter = Counter()
        self.time_resets = 0
        self.errors = 0
        self.last_stamp = -1  # ns, the newest input taken (-1: none since the start or the last time restart)
        self._received_ns: int | None = None  # system time (ns) the input being handled was received
        self._sequences: dict[str, int] = {}  # topic -> publication sequence number of its last input
        self._expiring: list[Callable[[int], None]] = []
        self.input_topics: list[str] = []  # the topics subscribed with input()
        self._processing: deque[float] = deque(maxlen=PROCESSING_WINDOW)
        self.processing_total = 0.0  # s, all inputs processed so far
        self.processing_count = 0
        self._ages: deque[float] = deque(maxlen=PROCESSING_WINDOW)
        self._reported_at: int | None = None
        self._published_at_report = 0
        self._problems_at_report = 0
        self._output_publishers: dict[str, Any] = {}
        self._declared: list[str] = []
        self._defaults: dict[str, Any] = {}
        jump = COMMON_PARAMETERS['max_stamp_jump_s']
        value = self.declare_parameter(
            'max_stamp_jump_s', jump.default, ParameterDescriptor(description=jump.description)
        ).value
        try:
            self.max_stamp_jump_ns = self._stamp_jump_ns(value)
        except (TypeError, ValueError) as exc:
            self.rejected['parameters'] += 1
            self.get_logger().error(f'unusable parameters ({exc}); using the default {jump.default} s')
            self.set_parameters([Parameter('max_stamp_jump_s', value=jump.default)])
            self.max_stamp_jump_ns = self._stamp_jump_ns(jump.default)
        # what the timeouts measure (elapsed_ns): live, the node's clock with its jumps left out; in the in-process
        # graph, the inputs' own time, whose forward steps all pass (a gap in a recording is time it waited)
        self.elapsed = ElapsedTime(self.max_stamp_jump_ns if router is None else UNBOUNDED_STEP_NS)
        self.parameter_mount = self._declare_mount()  # camera_link in base_link by camera_mount_rpy_deg
        self.static_mount: np.ndarray | None = None  # ...by /tf_static, once heard (listen_for_mount)
        self.static_transforms = StaticTransforms()
        self.output(DIAGNOSTICS, DiagnosticArray)
        if router is None:
            self.create_timer(DIAGNOSTICS_PERIOD, self.publish_diagnostics)
            self.create_timer(TIME_READ_PERIOD, self.elapsed_ns)

    # --- the camera's mount -----------------------------------------------------------------

    def _declare_mount(self) -> np.ndarray:
        """Declare camera_mount_rpy_deg (ints or floats alike) and return its mount; the default's if unusable."""
        mount = COMMON_PARAMETERS[MOUNT_PARAMETER]
        descriptor = ParameterDescriptor(description=mount.description, dynamic_typing=True)
        value = self.declare_parameter(MOUNT_PARAMETER, mount.default, descriptor).value
        try:
            return mount_from_rpy_deg(value)
        except ValueError as exc:
            self.rejected['parameters'] += 1
            self.get_logger().error(f'unusable parameter ({exc}); using the default {mount.default}')
            self.set_parameters([Parameter(MOUNT_PARAMETER, value=mount.default)])
            return mount_from_rpy_deg(mount.default)

    @property
    def mount(self) -> np.ndarray:
        """Return camera_link's rotation (3, 3) in base_link: /tf_static's once heard, else the parameter's."""
        return self.static_mount if self.static_mount is not None else self.parameter_mount

    def listen_for_mount(self) -> None:
        """Take base_link -> camera_link from /tf_static too (the nodes that turn camera_link into base_link)."""
        self.input(TF_STATIC, TFMessage, self.on_static_transforms, TF_STATIC_QOS)

    def on_static_transforms(self, message: Any) -> None:
        """Keep a /tf_static message's transforms; once they link base_link and camera_link, that is the mount."""
        for problem in self.static_transforms.add(message):
            self.reject('transform', problem)
        try:
            mount = self.static_transforms.mount()
        except ValueError as exc:
            self.reject('transform', str(exc))
            return
        if mount is None or (self.static_mount is not None and np.allclose(mount, self.static_mount, atol=1e-9)):
            return
        self.static_mount = mount
        overridden = '' if np.allclose(mount, self.parameter_mount, atol=1e-9) else f' (over {MOUNT_PARAMETER})'
        self.get_logger().info(f'camera mount from {TF_STATIC}: {describe(mount)}{overridden}')

    # --- parameters -------------------------------------------------------------------------

    def declare_table(self, table: ParameterTable) -> None:
        """Declare every parameter of a table (skynav_core.parameters) with its default and description."""
        for name, (default, description) in table.items():
            self.parameter(name, default, description)

    def parameter(self, name: str, default: Any, description: str) -> Any:
        """Declare a parameter with its description and return its value."""
        self._declared.append(name)
        self._defaults[name] = default
        return self.declare_parameter(name, default, ParameterDescriptor(description=description)).value

    def parameter_values(self) -> dict[str, Any]:
        """Return every parameter declared through `parameter()` with its current value."""
        return {name: self.get_parameter(name).value for name in self._declared}

    def configure(self, values: dict[str, Any]) -> None:
        """Build the node's working state from parameter values; raise ValueError for unusable ones."""

    def start(self) -> None:
        """Configure from the declared parameters (the defaults, if they are unusable) and accept changes."""
        try:
            self.configure(self.parameter_values())
        except ValueError as exc:
            self.rejected['parameters'] += 1
            self.get_logger().error(f'unusable parameters ({exc}); using the defaults')
            self.set_parameters([Parameter(name, value=value) for name, value in self._defaults.items()])
            self.configure(dict(self._defaults))
        self.add_on_set_parameters_callback(self._on_set_parameters)

    def _on_set_parameters(self, parameters: list) -> SetParametersResult:
        values = self.parameter_values()
        values.update({p.name: p.value for p in parameters if p.name in values})
        jumps = [p.value for p in parameters if p.name == 'max_stamp_jump_s']
        mounts = [p.value for p in parameters if p.name == MOUNT_PARAMETER]
        try:
            jump = self._stamp_jump_ns(jumps[-1]) if jumps else self.max_stamp_jump_ns
            mount = mount_from_rpy_deg(mounts[-1]) if mounts else self.parameter_mount
            self.configure(values)
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.max_stamp_jump_ns, self.parameter_mount = jump, mount
        if self.router is None:
            self.elapsed.max_step_ns = jump
        return SetParametersResult(successful=True)

    @staticmethod
    def _stamp_jump_ns(seconds: float) -> int:
        """Return the max_stamp_jump_s parameter in ns; ValueError unless it is positive."""
        if not (isinstance(seconds, int | float) and seconds > 0):
            raise ValueError('max_stamp_jump_s must be positive')
        return int(seconds * 1e9)

    # --- topics -----------------------------------------------------------------------------

    def input(
        self, topic: str, message_type: type, callback: Callable[[Any], None], qos: QoSProfile = STREAM_QOS
    ) -> None:
        """Receive `topic` (one of INPUT_TOPICS): live through a subscription, in `skynav run` through the router."""
        self.input_topics.append(topic)

        def receive(message: Any) -> None:
            self.received[topic] += 1
            try:
                callback(message)
            except Exception:  # a bug must not take the node down; it is logged and counted
                self.errors += 1
                if self.errors <= 3:
                    self.get_logger().error(
                        f'error handling {topic} (counted in /diagnostics):\n{traceback.format_exc()}'
                    )

        def receive_live(message: Any, info: dict) -> None:
            self._received_ns = info.get('received_timestamp') or time.time_ns()
            self.elapsed_ns()
            self._count_lost(topic, info.get('publication_sequence_number', SEQUENCE_UNSUPPORTED))
            receive(message)

        if self.router is not None:
            self.router.subscribe(topic, receive)
        else:
            self.create_subscription(message_type, relative(topic), receive_live, qos)  # type: ignore[arg-type]  # rclpy passes MessageInfo to a 2-argument callback

    def _count_lost(self, topic: str, sequence: int) -> None:
        """Count the messages of `topic` lost before reaching the node: a gap in the publisher's sequence numbers."""
        if not 0 < sequence < SEQUENCE_UNSUPPORTED:
            return
        last = self._sequences.get(topic)
        self._sequences[topic] = sequence
        if last is None:
            return  # the node's first message on the topic: it may have joined late
        # A number at or below the last one is a new publisher: the node missed its first ones (sequence - 1).
        # Gaps are told apart only while the topic has a single publisher.
        missed = sequence - last - 1 if sequence > last else sequence - 1
        if missed > 0 and self.count_publishers(self.live_name(topic)) == 1:
            self.drop(
                'lost',
                missed,
                f"{missed} messages on {topic} never reached the callback: the subscription's queue overflowed "
                'while the node was busy, or the transport lost them (best effort; or too large for it: over the '
                "16 MiB shared-memory segment of skynav's Fast DDS profile)",
            )

    def output(self, topic: str, message_type: type, qos: QoSProfile = STREAM_QOS) -> None:
        """Declare a topic this node publishes."""
        self._output_publishers[topic] = (
            None if self.router is not None else self.create_publisher(message_type, relative(topic), qos)
        )

    def publishes(self, topic: str) -> bool:
        """Return whether this node declared `topic` as an output."""
        return topic in self._output_publishers

    def live_name(self, topic: str) -> str:
        """Return the name a contract topic has on the live graph: in the node's namespace, remapped."""
        return self.resolve_topic_name(relative(topic))

    def watched(self, topic: str) -> bool:
        """Return whether anything takes the output `topic` (always in the in-process graph, which records it): what
        only a person looks at need not be drawn for nobody."""
        return self.router is not None or self.count_subscribers(self.live_name(topic)) > 0

    def flush(self, topic: str, seconds: float) -> bool:
        """Wait up to `seconds` until reliable subscribers acknowledged all published on `topic`; return whether
        they did (always in the in-process graph)."""
        publisher = self._output_publishers[topic]
        return publisher is None or publisher.wait_for_all_acked(Duration(nanoseconds=int(seconds * 1e9)))

    def emit(self, topic: str, message: Any) -> None:
        """Publish `message` on a declared output topic."""
        if self.router is not None:
            self.router.publish(topic, message)
        else:
            self._output_publishers[topic].publish(message)
        if topic != DIAGNOSTICS:
            self.published[topic] += 1
            if self.router is None and self._received_ns is not None:
                self._ages.append((time.time_ns() - self._received_ns) / 1e9)

    # --- accounting ---------------------------------------------------------------------------

    def reject(self, reason: str, detail: str) -> None:
        """Count a rejected input; log one clear line the first time each `reason` occurs."""
        self.rejected[reason] += 1
        if self.rejected[reason] == 1:
            self.get_logger().warning(
                f'rejected input ({reason}): {detail}; '
                f'further inputs rejected for this reason are counted in /diagnostics'
            )

    def drop(self, cause: str, count: int, detail: str) -> None:
        """Count `count` inputs lost for `cause` without being processed; log one clear line the first time."""
        if count <= 0:
            return
        first = cause not in self.dropped
        self.dropped[cause] += count
        if first:
            self.get_logger().warning(
                f'dropped input ({cause}): {detail}; further inputs dropped for this cause are counted in /diagnostics'
            )

    def stamp_jumped(self, stamp: int, last: int) -> bool:
        """Restart the node's time if `stamp` lies over max_stamp_jump_s from `last` (ns; -1: none); return if so."""
        if last < 0 or abs(stamp - last) <= self.max_stamp_jump_ns:
            return False
        self.time_resets += 1
        self.get_logger().warning(
            f'input stamped {stamp} is {(stamp - last) / 1e9:+.3f} s from the last one taken: time restarted '
            '(a camera clock that jumped, or a recording played again); counted in /diagnostics as time_resets',
            throttle_duration_sec=1.0,
        )
        self.reset_time()
        return True

    def reset_time(self) -> None:
        """Forget whatever depends on the inputs' time; nodes extend it with their own (waiting inputs, history)."""
        self.last_stamp = -1

    def in_order(self, stamp: int, last: int, what: str = 'view') -> bool:
        """Return whether an input stamped `stamp` (ns) is to be taken after the last one taken; reject it otherwise.

        Newer inputs are taken; so is one that jumps (stamp_jumped), after the node's time restarts.
        """
        if self.stamp_jumped(stamp, last) or stamp > last:
            return True
        self.reject('out_of_order', f'{what} stamped {stamp} is not newer than the last one')
        return False

    def expire_with_time(self, expire: Callable[[int], None]) -> None:
        """Call `expire(elapsed_ns)` before each diagnostics report, to drop inputs that waited too long."""
        self._expiring.append(expire)

    def now_ns(self) -> int:
        """Return the current time: the node's clock live, the input's time in `skynav run`."""
        return self.router.now_ns() if self.router is not None else self.get_clock().now().nanoseconds

    def elapsed_ns(self) -> int:
        """Return the time passed on the node's clock since it started, its jumps left out (ns): for timeouts."""
        return self.elapsed.read(self.now_ns())

    @contextmanager
    def processing(self, stamp: int) -> Iterator[None]:
        """Measure the processing of the input stamped `stamp` (ns) for the diagnostics.

        Publish after the block: in `skynav run` publishing runs the downstream nodes at once.
        """
        start = time.perf_counter()
        yield
        elapsed = time.perf_counter() - start
        self._processing.append(elapsed)
        self.processing_total += elapsed
        self.processing_count += 1

    def diagnostic_status(self) -> DiagnosticStatus:
        """Return this node's status: rates, processing time, counts."""
        now = self.now_ns()
        outputs = sum(self.published.values())
        elapsed = (now - self._reported_at) / 1e9 if self._reported_at is not None else 0.0
        rate = (outputs - self._published_at_report) / elapsed if elapsed > 0 else 0.0
        problems = sum(self.rejected.values()) + sum(self.dropped.values()) + self.errors
        values = {
            'rate_hz': f'{rate:.2f}',
            'processing_ms_mean': f'{1e3 * sum(self._processing) / len(self._processing):.2f}'
            if self._processing
            else 'nan',
            'processing_ms_max': f'{1e3 * max(self._processing):.2f}' if self._processing else 'nan',
            'received': str(sum(self.received.values())),
            'published': str(outputs),
            'rejected': str(sum(self.rejected.values())),
            'dropped': str(sum(self.dropped.values())),
            'time_resets': str(self.time_resets),
            'clock_jumps': str(self.elapsed.jumps),
            'errors': str(self.errors),
        }
        if self._ages:
            values['latency_ms_mean'] = f'{1e3 * sum(self._ages) / len(self._ages):.2f}'
        values.update({f'rejected_{reason}': str(count) for reason, count in sorted(self.rejected.items())})
        values.update({f'dropped_{cause}': str(count) for cause, count in sorted(self.dropped.items())})
        fresh_problems = problems - self._problems_at_report
        self._reported_at, self._published_at_report, self._problems_at_report = now, outputs, problems
        if fresh_problems:
            level, text = (
                DiagnosticStatus.WARN,
                f'{fresh_problems} inputs rejected, dropped or failed since the last report',
            )
        else:
            level, text = DiagnosticStatus.OK, f'{rate:.1f} Hz'
        return DiagnosticStatus(
            level=level,
            name=f'skynav/{self.get_name()}',
            message=text,
            hardware_id='skynav',
            values=[KeyValue(key=k, value=v) for k, v in values.items()],
        )

    def publish_diagnostics(self) -> None:
        """Drop the inputs that waited too long, then publish the status on /diagnostics."""
        now, elapsed = self.now_ns(), self.elapsed_ns()
        for expire in self._expiring:
            expire(elapsed)
        array = DiagnosticArray(status=[self.diagnostic_status()])
        array.header.stamp.sec, array.header.stamp.nanosec = divmod(now, 1_000_000_000)
        self.emit(DIAGNOSTICS, array)
