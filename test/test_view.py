# SPDX-License-Identifier: Apache-2.0
"""Watching live in Foxglove: `skynav view` forwards what the nodes publish so that a client decodes it exactly.

A Foxglove WebSocket client (the `websockets` library, the SDK's subprotocol) connects to `skynav view`,
subscribes to /skyline/sh and /skynav/viz/markers, and decodes what arrives with rosbags from the advertised
ros2msg schema alone, as Foxglove does; every message the nodes published (`skynav run` over a bundled recording,
replayed live) arrives with the same values. The shipped layout names only topics the graph publishes.
"""

from __future__ import annotations

import asyncio
import json
import struct
import time
from pathlib import Path

import foxglove
import pytest
import websockets
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from skynav_bringup.cli.view import layout_file
from skynav_bringup.viewer import Viewer
from skynav_core.images import stamp_ns
from skynav_core.names import SKYLINE_SH, TEACH_ACTION, VIZ_CONFIDENCE, VIZ_MARKERS, VIZ_OVERLAY, VIZ_STATE
from skynav_core.recording.bag import open_bag
from skynav_testing import messages_equal, start_skynav, wait_text

BAGS = Path(__file__).parents[1] / 'bags'
RECORDING = BAGS / 'synthetic_park_skyline.mcap'  # 20 frames, with ground truth: a map with poses
SH, MARKERS = SKYLINE_SH, VIZ_MARKERS
SUBPROTOCOL = 'foxglove.sdk.v1'  # the Foxglove SDK's WebSocket protocol (foxglove-sdk 0.30)
UNKNOWN_CHANNEL = 'Unknown channel ID: '  # the server's status for a subscription it did not take
MESSAGE_DATA = 1  # opcode of a binary message-data frame: opcode, subscription id (u32), log time (u64), payload


@pytest.fixture(scope='module')
def graph_output(tmp_path_factory, skynav_main) -> Path:
    """Return the recording of every output of the whole graph (`skynav run --map`) over a short synthetic drive."""
    folder = tmp_path_factory.mktemp('view')
    code, _, err = skynav_main(['map', 'build', str(RECORDING), '--out', str(folder / 'park.db')])
    assert code == 0, err
    code, _, err = skynav_main(
        ['run', str(RECORDING), '--map', str(folder / 'park.db'), '--out', str(folder / 'run.mcap')]
    )
    assert code == 0, err
    return folder / 'run.mcap'


def published(path: Path, topic: str) -> dict[int, object]:
    """Return a recording's messages of `topic` by stamp (a MarkerArray: its first marker's)."""
    with open_bag(path) as bag:
        messages = [bag.deserialize(raw) for raw in bag.messages([topic])]
    return {stamp_ns(m.markers[0].header if topic == MARKERS else m.header): m for m in messages}


async def receive(url: str, topics: dict[str, int], timeout: float) -> tuple[dict[str, dict], dict[str, list[bytes]]]:
    """Subscribe to `topics` ({topic: messages expected}); return their advertised channels and payloads received.

    foxglove-sdk 0.30 may answer a subscription sent at once after the advertisement with the status "Unknown
    channel ID: N" (it tells the client of a channel a moment before it takes subscriptions to it); the client then
    subscribes again.
    """
    channels: dict[str, dict] = {}
    payloads: dict[str, list[bytes]] = {topic: [] for topic in topics}
    by_subscription: dict[int, str] = {}
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as client:

        async def subscribe(wanted: list[dict]) -> None:
            subscriptions = []
            for channel in wanted:
                subscription = len(by_subscription)
                by_subscription[subscription] = channel['topic']
                subscriptions.append({'id': subscription, 'channelId': channel['id']})
            await client.send(json.dumps({'op': 'subscribe', 'subscriptions': subscriptions}))

        deadline = time.monotonic() + timeout
        while any(len(payloads[t]) < n for t, n in topics.items()) and time.monotonic() < deadline:
            try:
                frame = await asyncio.wait_for(client.recv(), max(0.1, deadline - time.monotonic()))
            except TimeoutError:
                break
            if isinstance(frame, bytes) and frame[0] == MESSAGE_DATA:
                subscription, _log_time = struct.unpack_from('<IQ', frame, 1)
                payloads[by_subscription[subscription]].append(bytes(frame[13:]))
                continue
            message = json.loads(frame)
            if message['op'] == 'advertise':
                wanted = [c for c in message['channels'] if c['topic'] in topics and c['topic'] not in channels]
                channels.update({c['topic']: c for c in wanted})
                if wanted:
                    await subscribe(wanted)
            elif message['op'] == 'status' and message['message'].startswith(UNKNOWN_CHANNEL):
                refused = int(message['message'].removeprefix(UNKNOWN_CHANNEL))
                await subscribe([c for c in channels.values() if c['id'] == refused])
    return channels, payloads


def test_a_foxglove_client_decodes_exactly_what_the_nodes_published(graph_output):
    expected = {topic: published(graph_output, topic) for topic in (SH, MARKERS)}
    assert len(expected[SH]) == 20 and len(expected[MARKERS]) >= 15, {t: len(v) for t, v in expected.items()}
    view = start_skynav('view', '--port', '0', '--topics', SH, MARKERS)
    replay = None
    try:
        line = wait_text(view, 'Foxglove WebSocket server on ')[-1]
        url = line.split(' on ')[1].split()[0]
        # the replay waits until the viewer subscribes, which it does once the client subscribes to the channel
        replay = start_skynav(
            'replay', str(graph_output), '--topics', SH, MARKERS, '--rate', '4', '--wait-for-subscribers', '1'
        )
        counts = {topic: len(messages) for topic, messages in expected.items()}
        channels, payloads = asyncio.run(receive(url, counts, timeout=60))
        assert replay.wait(timeout=60) == 0, replay.stderr.read() if replay.stderr else ''
    finally:
        for process in (replay, view):
            if process is not None and process.poll() is None:
                process.terminate()
                process.wait(timeout=20)
    assert view.returncode == 0
    for topic, messages in expected.items():
        channel = channels[topic]
        assert (channel['encoding'], channel['schemaEncoding']) == ('cdr', 'ros2msg')
        store = get_typestore(Stores.EMPTY)  # only what the schema says, as Foxglove decodes
        store.register(get_types_from_msg(channel['schema'], channel['schemaName']))
        decoded = [store.deserialize_cdr(data, channel['schemaName']) for data in payloads[topic]]
        got = {stamp_ns(m.markers[0].header if topic == MARKERS else m.header): m for m in decoded}
        assert len(decoded) == len(messages) and sorted(got) == sorted(messages), topic
        assert all(messages_equal(got[stamp], messages[stamp]) for stamp in messages), topic


def test_a_topic_that_cannot_be_forwarded_is_told_once_and_the_others_are_served(ros_context, monkeypatch):
    from rclpy.node import Node

    node = Node('view_test', context=ros_context)
    graph = [
        ('/unknown', ['nowhere_msgs/msg/Nothing']),
        ('/crafted', ['../msg/Evil']),
        ('/twice', ['std_msgs/msg/Float64', 'std_msgs/msg/Int32']),
        (f'{TEACH_ACTION}/_action/feedback', ['skynav_msgs/action/Teach_FeedbackMessage']),
        (VIZ_CONFIDENCE, ['std_msgs/msg/Float64']),
    ]
    monkeypatch.setattr(node, 'get_topic_names_and_types', lambda: graph)
    monkeypatch.setattr(node, 'count_publishers', lambda topic: 1)
    lines: list[str] = []
    viewer = Viewer(node, warn=lines.append, context=foxglove.Context())
    viewer.discover()
    assert sorted(viewer.forwards) == [VIZ_CONFIDENCE]
    assert viewer.forwards[VIZ_CONFIDENCE].channel.schema_name() == 'std_msgs/msg/Float64'
    assert len(lines) == 3 and all('\n' not in line for line in lines)
    assert [line.split()[2] for line in lines] == ['/unknown', '/crafted', '/twice']
    node.destroy_node()


def layout_topics(layout: dict) -> set[str]:
    """Return every topic a Foxglove layout's panels name."""
    topics = set()
    for panel, config in layout['configById'].items():
        kind = panel.split('!')[0]
        if kind == '3D':
            topics |= set(config['topics'])
        elif kind == 'Image':
            topics.add(config['imageMode']['imageTopic'])
        elif kind == 'Plot':
            topics |= {path['value'].split('.')[0] for path in config['paths']}
        else:
            raise AssertionError(f'a panel of an unexpected kind: {panel}')
    return topics


def test_the_layout_parses_and_names_only_topics_the_graph_publishes(graph_output):
    path = layout_file()
    assert path is not None and path.name == 'skynav.foxglove.json'
    layout = json.loads(path.read_text())
    panels = set(layout['configById'])
    assert {p.split('!')[0] for p in panels} == {'3D', 'Image', 'Plot'}

    def leaves(node) -> set[str]:
        return {node} if isinstance(node, str) else leaves(node['first']) | leaves(node['second'])

    assert leaves(layout['layout']) == panels  # every panel configured is placed, and only those
    with open_bag(graph_output) as bag:
        outputs = set(bag.topics)
    named = layout_topics(layout)
    assert named <= outputs, named - outputs
    assert {MARKERS, VIZ_OVERLAY, VIZ_CONFIDENCE, VIZ_STATE} <= named
