# SPDX-License-Identifier: Apache-2.0
"""Two robots on one ROS domain: two graphs in two namespaces, each fed its own recording at the same time.

`skynav launch --namespace robotN` starts the skyline and SH nodes of each graph; `skynav replay --namespace robotN`
plays a different synthetic drive into each, both at once; `skynav record --namespace robotN` records each graph's
/skyline/sh (stored by the contract's name), and a third recorder takes every topic of the domain. Each graph's
coefficients must be exactly what `skynav run` gives for its own recording, none of the other's, every frame
accounted for (taken, or counted as dropped in the graph's /diagnostics), and no topic may appear outside the two
namespaces but ROS's own /rosout and /parameter_events.
"""

from __future__ import annotations

import signal
import time
from pathlib import Path

import pytest

from skynav_core.names import SKYLINE_SH
from skynav_core.recording.bag import open_bag
from skynav_testing import running, start_skynav, wait_text, write_first_frames

pytestmark = pytest.mark.heavy(50)

BAGS = Path(__file__).parents[1] / 'bags'
DRIVES = {'robot1': 'synthetic_garden_repeat.mcap', 'robot2': 'synthetic_mineral_repeat.mcap'}
FRAMES = 20
NODES = ('skyline', 'sh')
ROS_GLOBALS = ('/rosout', '/parameter_events')


def coefficients(path: Path) -> dict[int, object]:
    """Return a recording's /skyline/sh messages by stamp (ns)."""
    from skynav_core.recording.typestore import typestore

    store = typestore()
    with open_bag(path) as bag:
        messages = [store.deserialize_cdr(raw.data, raw.msgtype) for raw in bag.messages([SKYLINE_SH])]
    return {m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec: m for m in messages}


def test_two_namespaced_graphs_on_one_domain_each_give_exactly_their_own_run(
    own_ros_domain, tmp_path, skynav_main, ros_context
):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from skynav_testing import messages_equal

    drives = {ns: write_first_frames(BAGS / name, tmp_path / f'{ns}.mcap', FRAMES) for ns, name in DRIVES.items()}
    expected = {}
    for ns, drive in drives.items():
        code, _, err = skynav_main(['run', str(drive), '--nodes', *NODES, '--out', str(tmp_path / f'{ns}_run.mcap')])
        assert code == 0, err
        expected[ns] = coefficients(tmp_path / f'{ns}_run.mcap')
        assert len(expected[ns]) == FRAMES
    assert not set(expected['robot1']) & set(expected['robot2']) or any(
        not messages_equal(expected['robot1'][s], expected['robot2'][s])
        for s in set(expected['robot1']) & set(expected['robot2'])
    ), 'the two drives must differ for a cross-over to show'

    node = Node('namespaces_test', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    status: dict[str, dict[str, str]] = {}

    def on_diagnostics(ns: str, array: DiagnosticArray) -> None:
        for entry in array.status:
            status[f'{ns}/{entry.name.removeprefix("skynav/")}'] = {kv.key: kv.value for kv in entry.values}

    for ns in drives:
        node.create_subscription(
            DiagnosticArray,
            f'/{ns}/diagnostics',
            lambda array, ns=ns: on_diagnostics(ns, array),
            QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE),
        )

    def count(key: str, name: str, ns: str) -> int:
        return int(status.get(f'{ns}/{name}', {}).get(key, 0))

    def settled() -> bool:
        """Whether each SH node answered every frame its skyline node took, and the skyline nodes took or counted
        every frame replayed."""
        return all(
            count('published', 'skyline', ns) + count('dropped', 'skyline', ns) >= FRAMES
            and count('published', 'sh', ns) == count('published', 'skyline', ns)
            for ns in drives
        )

    launches = {ns: start_skynav('launch', '--namespace', ns, '--nodes', *NODES) for ns in drives}
    with running(launches['robot1']) as first, running(launches['robot2']) as second:
        recorders = {
            ns: start_skynav('record', '--namespace', ns, str(tmp_path / f'{ns}_live.mcap'), SKYLINE_SH)
            for ns in drives
        }
        everything = start_skynav('record', '--all', str(tmp_path / 'everything.mcap'))
        for recorder in [*recorders.values(), everything]:
            wait_text(recorder, 'Ctrl-C to stop')
        replays = {
            ns: start_skynav('replay', str(drive), '--namespace', ns, '--rate', '0.5') for ns, drive in drives.items()
        }
        while any(r.poll() is None for r in replays.values()):
            executor.spin_once(timeout_sec=0.05)
        for ns, replay in replays.items():
            assert replay.returncode == 0, (ns, replay.stderr.read())
        deadline = time.monotonic() + 60
        while not settled() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        time.sleep(1.0)  # the recorders take the last coefficients
        for recorder in [*recorders.values(), everything]:
            recorder.send_signal(signal.SIGINT)
        for recorder in [*recorders.values(), everything]:
            _, err = recorder.communicate(timeout=60)
            assert recorder.returncode == 0, err
        assert first.poll() is None and second.poll() is None, 'a graph ended early'
    executor.shutdown()
    node.destroy_node()

    for ns in drives:
        live = coefficients(tmp_path / f'{ns}_live.mcap')
        other = next(o for o in drives if o != ns)
        dropped = count('dropped', 'skyline', ns)
        # every frame is there, or counted as dropped (a best-effort camera queue on a busy machine)
        assert len(live) + dropped == FRAMES and dropped <= 2, (ns, len(live), status)
        for stamp, message in live.items():
            assert stamp in expected[ns], (ns, stamp)
            assert messages_equal(message, expected[ns][stamp]), f'{ns}: /skyline/sh at {stamp} is not its own run'
            crossed = expected[other].get(stamp)
            assert crossed is None or not messages_equal(message, crossed), f"{ns} got {other}'s coefficients"
    with open_bag(tmp_path / 'everything.mcap') as bag:
        topics = list(bag.topics)
    outside = [t for t in topics if t not in ROS_GLOBALS and not t.startswith(('/robot1/', '/robot2/'))]
    assert not outside, f'topics outside the namespaces: {outside}'
    for ns in drives:  # the recording's own topics and the graph's, under each namespace
        assert {f'/{ns}/camera/uv/image_raw', f'/{ns}/ground_truth/pose', f'/{ns}/skyline/sh'} <= set(topics), topics
