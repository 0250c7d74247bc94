# SPDX-License-Identifier: Apache-2.0
"""skynav_core.peers: another node's parameters set through its parameter services, all or none, and the nodes
that did not take theirs named with the reason."""

import uuid

import pytest
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from skynav_core.peers import NOT_FOUND, PeerParameters

TIMEOUT = 30.0  # s for discovery and answers under load


class Peer:
    """A node with parameters `reference` and `index` that records each configure call and refuses index < 0."""

    def __init__(self, context, name):
        self.node = Node(name, context=context)
        self.node.declare_parameter('reference', 'match')
        self.node.declare_parameter('index', 0)
        self.calls = []  # the parameters of each call, as {name: value}
        self.node.add_on_set_parameters_callback(self.on_set)

    def on_set(self, parameters):
        values = {p.name: p.value for p in parameters}
        if values.get('index', 0) < 0:
            return SetParametersResult(successful=False, reason='index must not be negative')
        self.calls.append(values)
        return SetParametersResult(successful=True)

    def value(self, name):
        return self.node.get_parameter(name).value


@pytest.fixture
def graph(ros_context):
    """Two peers and the node that sets their parameters, spun by one executor."""
    suffix = uuid.uuid4().hex[:8]  # other test processes may run nodes of their own
    peers = [Peer(ros_context, f'peer_{k}_{suffix}') for k in range(2)]
    setter = Node(f'setter_{suffix}', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    for node in [setter] + [p.node for p in peers]:
        executor.add_node(node)
    yield setter, peers, executor
    executor.shutdown()
    for node in [setter] + [p.node for p in peers]:
        node.destroy_node()


def run(executor, coroutine):
    """Run `coroutine` on `executor` to its end and return its result."""
    task = executor.create_task(coroutine)
    executor.spin_until_future_complete(task, timeout_sec=TIMEOUT + 10)
    assert task.done()
    return task.result()


def test_each_node_takes_its_parameters_in_one_call(graph):
    setter, (first, second), executor = graph
    client = PeerParameters(setter, [first.node.get_name(), second.node.get_name()])
    settings = {
        first.node.get_name(): [('reference', 'index'), ('index', 7)],
        second.node.get_name(): [('reference', 'live')],
    }
    assert run(executor, client.set(settings, TIMEOUT)) == {}
    assert first.calls == [{'reference': 'index', 'index': 7}]  # never 'index' with the old snapshot
    assert (first.value('reference'), first.value('index')) == ('index', 7)
    assert second.calls == [{'reference': 'live'}]


def test_a_refused_set_changes_nothing_and_says_why(graph):
    setter, (first, _), executor = graph
    client = PeerParameters(setter)
    failures = run(executor, client.set({first.node.get_name(): [('reference', 'index'), ('index', -1)]}, TIMEOUT))
    assert failures == {first.node.get_name(): 'index must not be negative'}
    assert first.value('reference') == 'match'  # all or none


def test_one_at_a_time_the_parameters_are_taken_in_order(graph):
    setter, (first, _), executor = graph
    client = PeerParameters(setter)
    failures = run(
        executor, client.set({first.node.get_name(): [('index', 3), ('index', 4)]}, TIMEOUT, atomically=False)
    )
    assert failures == {}
    assert first.calls == [{'index': 3}, {'index': 4}]


def test_a_node_that_is_not_running_is_named_and_the_others_still_take_theirs(graph):
    setter, (first, _), executor = graph
    client = PeerParameters(setter, [first.node.get_name()])
    settings = {'nobody_' + uuid.uuid4().hex[:8]: [('index', 1)], first.node.get_name(): [('index', 2)]}
    failures = run(executor, client.set(settings, TIMEOUT, discovery=5.0))
    assert list(failures.values()) == [NOT_FOUND]
    assert first.value('index') == 2
