# SPDX-License-Identifier: Apache-2.0
"""The route node's peer client: it sets the other nodes' parameters for each goal.

For each goal the route node sets the compass and warping nodes' snapshot choice through their parameters
(following: the compass against the match, the warping node `lookahead` snapshots ahead; homing: both against the
goal's index), localize's `tracking` while it follows the route (each view sought near the last accepted match, the
first ones near the goal's start_index when it names one; off again when the goal ends) and, for a goal naming
another map, the `map` of localize, compass and warping (skynav_route.goals). Waiting for a node to take them
(`peer_timeout`) is a wait on the other nodes, measured in steady (wall) time: it ends even while sim time stands
still.
"""

from __future__ import annotations

import time
from typing import Any

from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter as RosParameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.task import Future

PEER_POLL = 0.05  # s of steady time between looks at whether another node answered


class Peers:
    """Sets parameters of other nodes through their parameter services, one client per node kept for later goals."""

    def __init__(self, node: Node) -> None:
        self.node = node  # the route node: the clients and timers are its own
        self.clients: dict[str, AsyncParameterClient] = {}
        self.steady_clock = RosClock(clock_type=ClockType.STEADY_TIME)  # for waits on other nodes

    async def configure(self, settings: dict[str, dict[str, Any]], timeout: float) -> None:
        """Set other nodes' parameters ({node: {name: value}}), waiting up to `timeout` s (steady) for each."""
        # a node that does not answer is logged and skipped
        for name, values in settings.items():
            # a plain node name: its parameter services are sought in this node's namespace
            client = self.clients.get(name)
            if client is None:  # one per node, kept for later goals
                client = self.clients[name] = AsyncParameterClient(self.node, name)
            deadline = time.monotonic() + timeout  # steady: sim time may stand still
            while not client.services_are_ready() and time.monotonic() < deadline:
                await self.pause(PEER_POLL)
            if not client.services_are_ready():
                self.node.get_logger().warning(f'node {name} does not answer: its settings for this goal were not set')
                continue
            future = client.set_parameters([RosParameter(k, value=v) for k, v in values.items()])
            while not future.done() and time.monotonic() < deadline:
                await self.pause(PEER_POLL)
            failed = [r.reason for r in future.result().results if not r.successful] if future.done() else ['no answer']
            if failed:
                self.node.get_logger().warning(f'node {name} refused the settings of this goal: {"; ".join(failed)}')

    async def pause(self, seconds: float) -> None:
        """Wait `seconds` of steady (wall) time inside a goal's execution without blocking the executor."""
        # a timer on the node's clock would never fire while sim time stands still
        future = Future()
        timer = self.node.create_timer(
            seconds, lambda: future.done() or future.set_result(True), clock=self.steady_clock
        )
        await future
        self.node.destroy_timer(timer)
