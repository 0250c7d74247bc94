# SPDX-License-Identifier: Apache-2.0
"""A Teach goal sent before the first /clock, then a recording replayed with its own clock: the goal teaches.

The graph runs on sim time (`use_sim_time: true` under `/**`): its clock reads zero until the recording's /clock
arrives, then jumps to the recording's time. `skynav teach` sends its goal first, as an operator does before
starting the drive; the replay of a cut of the synthetic garden teach drive, with a /clock message at each frame,
follows. Before the graph's timeouts measured the time passed with the clock's jumps left out, the goal ended
NO_INPUT the moment the clock jumped ("no usable view for 1782022320.0 s").
"""

from __future__ import annotations

import signal
from pathlib import Path

import pytest
import yaml

from skynav_core.maps import MapStore
from skynav_core.names import CLOCK, UV_IMAGE
from skynav_core.recording.bag import BagWriter, open_bag
from skynav_testing import running, start_skynav, wait_text, write_first_frames

pytestmark = pytest.mark.heavy(40)

BAGS = Path(__file__).parents[1] / 'bags'
FRAMES = 40
NODES = ('skyline', 'sh', 'localize')
CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'


def with_clock(source: Path, target: Path) -> Path:
    """Copy a recording, adding a /clock message stamped as each UV exposure, logged just before it."""
    from skynav_core.recording.typestore import typestore

    store = typestore()
    clock, time = store.types[CLOCK_TYPE], store.types['builtin_interfaces/msg/Time']
    with open_bag(source) as bag, BagWriter(target) as writer:
        for topic in bag.topics.values():
            writer.add_topic(topic.name, topic.msgtype, topic.offered_qos)
        writer.add_topic(CLOCK, CLOCK_TYPE)
        for raw in bag.messages():
            if raw.topic == UV_IMAGE:
                stamp = bag.deserialize(raw).header.stamp
                data = store.serialize_cdr(clock(clock=time(sec=stamp.sec, nanosec=stamp.nanosec)), CLOCK_TYPE)
                writer.write(CLOCK, raw.log_time - 1, data)
            writer.write(raw.topic, raw.log_time, raw.data)
    return target


def test_a_teach_goal_sent_before_the_clock_starts_teaches_a_recording_with_its_own_clock(tmp_path):
    drive = with_clock(
        write_first_frames(BAGS / 'synthetic_garden_teach.mcap', tmp_path / 'cut.mcap', FRAMES), tmp_path / 'drive.mcap'
    )
    params = tmp_path / 'sim_time.yaml'
    params.write_text(yaml.safe_dump({'/**': {'ros__parameters': {'use_sim_time': True}}}))
    path = tmp_path / 'taught.db'
    with running(start_skynav('launch', '--params', str(params), '--nodes', *NODES)) as launch:
        teach = start_skynav('teach', str(path), '--spacing', '0.2', '--wait', '60')
        with running(teach):
            wait_text(teach, 'drive the route')  # the goal runs, and the graph's clock still reads zero
            replay = start_skynav('replay', str(drive), '--rate', '2')
            _, err = replay.communicate(timeout=120)
            assert replay.returncode == 0, err
            assert teach.poll() is None, f'the goal ended before it was canceled: {teach.communicate()}'
            teach.send_signal(signal.SIGINT)
            out, err = teach.communicate(timeout=60)
        assert teach.returncode == 0, err
        assert launch.poll() is None
    assert 'NO_INPUT' not in err and 'canceled' in err, err
    with MapStore.open(path) as store:
        assert len(store) >= 5, err  # some 1.5 m of the drive at 0.2 m spacing
