# SPDX-License-Identifier: Apache-2.0
"""Set other nodes' parameters through their parameter services: what the route node does for each goal (its goal
context, skynav_route.context) and the localize node when a teach ends (the taught map).

Each node's parameters are sent in one request; `atomically` (the default) they are taken all or none, by one call
of the node's configure, so a node never runs on half a goal's settings. All nodes are asked at once and waited
for together. Waits are in steady (wall) time: they end even while sim time stands still. Import after
:func:`skynav_core.process.environment.apply_ros_environment` (as skynav_core.ros).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.task import Future

PEER_POLL = 0.02  # s of steady time between looks at whether another node was found or answered
NOT_FOUND = 'no answer: its parameter services were not found'
NO_ANSWER = 'no answer in time'

Settings = Mapping[str, Sequence[tuple[str, Any]]]  # {node: [(parameter, value), ...]}, in the order they are set


class PeerParameters:
    """Sets other nodes' parameters, by node name relative to this node's namespace; one client per node, kept."""

    def __init__(self, node: Node, names: Iterable[str] = ()) -> None:
        """Serve `node` (its clients and timers are its own); clients for `names` start discovery at once."""
        self.node = node
        self.clients: dict[str, AsyncParameterClient] = {}
        self.steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        for name in names:
            self.client(name)

    def client(self, name: str) -> AsyncParameterClient:
        """Return the parameter client of node `name`, made on first use."""
        if name not in self.clients:
            self.clients[name] = AsyncParameterClient(self.node, name)
        return self.clients[name]

    async def set(
        self, settings: Settings, timeout: float, discovery: float | None = None, atomically: bool = True
    ) -> dict[str, str]:
        """Set each node's parameters and return why those that did not take them did not ({node: reason}).

        Waits up to `timeout` s (steady) in all; a node whose services are not found within `discovery` s (default:
        the whole timeout) is not asked.
        """
        start = time.monotonic()
        deadline, found_by = start + timeout, start + (timeout if discovery is None else discovery)
        unasked = {name: list(values) for name, values in settings.items()}
        asked: dict[str, Future] = {}
        while True:
            for name in [name for name in unasked if self.client(name).services_are_ready()]:
                parameters = [Parameter(key, value=value) for key, value in unasked.pop(name)]
                client = self.clients[name]
                asked[name] = (client.set_parameters_atomically if atomically else client.set_parameters)(parameters)
            now = time.monotonic()
            waiting = (unasked and now < found_by) or any(not future.done() for future in asked.values())
            if not waiting or now >= deadline:
                break
            await self.pause(PEER_POLL)
        failures = dict.fromkeys(unasked, NOT_FOUND)
        for name, future in asked.items():
            if not future.done():
                failures[name] = NO_ANSWER
                continue
            response = future.result()
            results = [response.result] if atomically else list(response.results)
            refused = [result.reason for result in results if not result.successful]
            if refused:
                failures[name] = '; '.join(refused)
        return failures

    async def pause(self, seconds: float) -> None:
        """Wait `seconds` of steady (wall) time without blocking the node's executor."""
        # a timer on the node's clock would never fire while sim time stands still
        future = Future()
        timer = self.node.create_timer(
            seconds, lambda: future.done() or future.set_result(True), clock=self.steady_clock
        )
        await future
        self.node.destroy_timer(timer)
