# SPDX-License-Identifier: Apache-2.0
"""What every skynav node shares: inputs and outputs that run live or in-process, bad-input accounting, diagnostics.

A skynav node is an ordinary rclpy node with three habits:

- it declares its topics with `input()` and `output()` and publishes with `emit()`, so the same code
  runs on live topics (`skynav launch`) and, given a router, inside `skynav run`, where every message
  is delivered synchronously and none can be dropped;
- bad input never kills it: `reject(reason, detail)` logs one clear line for the first input of each
  kind of problem, counts every one, and the node goes on (`in_order` rejects an input no newer than
  the last one taken as 'out_of_order'); an exception in a callback is logged and counted the same way;
- its parameters are turned into working state by one method, `configure(values)`, which raises
  ValueError for values it cannot use: at start-up the node then keeps its defaults, at run time the
  change is refused with that reason.

It publishes a DiagnosticStatus on /diagnostics once a second: output rate, processing time per
input, age of the data at publication, and counts of inputs received, outputs published, inputs
rejected (by reason) and callback errors.
"""

from __future__ import annotations

import time
import traceback
from collections import Counter, deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, ClassVar, Protocol

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from .parameters import ParameterTable

# Camera topics: best effort matches any publisher (drivers often publish best effort).
SENSOR_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
# skynav's own topics: reliable, a short queue.
STREAM_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE)
DIAGNOSTICS_PERIOD = 1.0  # s
PROCESSING_WINDOW = 100  # inputs whose processing times the diagnostics summarise


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

    def __init__(self, name: str, router: Router | None = None, context: Context | None = None) -> None:
        super().__init__(name, context=context)
        self.router = router
        self.received: Counter = Counter()
        self.published: Counter = Counter()
        self.rejected: Counter = Counter()
        self.errors = 0
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
        self.output('/diagnostics', DiagnosticArray)
        if router is None:
            self.create_timer(DIAGNOSTICS_PERIOD, self.publish_diagnostics)

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
        try:
            self.configure(values)
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    # --- topics -----------------------------------------------------------------------------

    def input(
        self, topic: str, message_type: type, callback: Callable[[Any], None], qos: QoSProfile = STREAM_QOS
    ) -> None:
        """Receive `topic`: live through a subscription, in `skynav run` through the router."""

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

        if self.router is not None:
            self.router.subscribe(topic, receive)
        else:
            self.create_subscription(message_type, topic, receive, qos)

    def output(self, topic: str, message_type: type, qos: QoSProfile = STREAM_QOS) -> None:
        """Declare a topic this node publishes."""
        self._output_publishers[topic] = (
            None if self.router is not None else self.create_publisher(message_type, topic, qos)
        )

    def emit(self, topic: str, message: Any) -> None:
        """Publish `message` on a declared output topic."""
        if self.router is not None:
            self.router.publish(topic, message)
        else:
            self._output_publishers[topic].publish(message)
        if topic != '/diagnostics':
            self.published[topic] += 1

    # --- accounting ---------------------------------------------------------------------------

    def reject(self, reason: str, detail: str) -> None:
        """Count a rejected input; log one clear line the first time each `reason` occurs."""
        self.rejected[reason] += 1
        if self.rejected[reason] == 1:
            self.get_logger().warning(
                f'rejected input ({reason}): {detail}; '
                f'further inputs rejected for this reason are counted in /diagnostics'
            )

    def in_order(self, stamp: int, last: int, what: str = 'view') -> bool:
        """Return whether an input stamped `stamp` (ns) is newer than the last one taken; reject it otherwise."""
        if stamp > last:
            return True
        self.reject('out_of_order', f'{what} stamped {stamp} is not newer than the last one')
        return False

    def now_ns(self) -> int:
        """Return the current time: the node's clock live, the input's time in `skynav run`."""
        return self.router.now_ns() if self.router is not None else self.get_clock().now().nanoseconds

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
        if self.router is None:
            self._ages.append((self.get_clock().now().nanoseconds - stamp) / 1e9)

    def diagnostic_status(self) -> DiagnosticStatus:
        """Return this node's status: rates, processing time, counts."""
        now = self.now_ns()
        outputs = sum(self.published.values())
        elapsed = (now - self._reported_at) / 1e9 if self._reported_at is not None else 0.0
        rate = (outputs - self._published_at_report) / elapsed if elapsed > 0 else 0.0
        problems = sum(self.rejected.values()) + self.errors
        values = {
            'rate_hz': f'{rate:.2f}',
            'processing_ms_mean': f'{1e3 * sum(self._processing) / len(self._processing):.2f}'
            if self._processing
            else 'nan',
            'processing_ms_max': f'{1e3 * max(self._processing):.2f}' if self._processing else 'nan',
            'received': str(sum(self.received.values())),
            'published': str(outputs),
            'rejected': str(sum(self.rejected.values())),
            'errors': str(self.errors),
        }
        if self._ages:
            values['latency_ms_mean'] = f'{1e3 * sum(self._ages) / len(self._ages):.2f}'
        values.update({f'rejected_{reason}': str(count) for reason, count in sorted(self.rejected.items())})
        fresh_problems = problems - self._problems_at_report
        self._reported_at, self._published_at_report, self._problems_at_report = now, outputs, problems
        if fresh_problems:
            level, text = DiagnosticStatus.WARN, f'{fresh_problems} inputs rejected or failed since the last report'
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
        """Publish the status on /diagnostics."""
        array = DiagnosticArray(status=[self.diagnostic_status()])
        now = self.now_ns()
        array.header.stamp.sec, array.header.stamp.nanosec = divmod(now, 1_000_000_000)
        self.emit('/diagnostics', array)
