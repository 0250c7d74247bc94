# SPDX-License-Identifier: Apache-2.0
"""`skynav replay` -> `skynav record` across processes keeps every message; a stopped recorder leaves a whole bag."""

import signal
import time

import mcap.reader
import numpy as np
import pytest
from rosbags.rosbag2 import Reader

from skynav_core.names import SKYLINE_SH
from skynav_core.recording.bag import open_bag
from skynav_testing import messages_equal, start_skynav, wait_text, write_sample_bag


def test_replay_then_record_reproduces_the_bag(tmp_path):
    source = tmp_path / 'source.mcap'
    sent = write_sample_bag(source, frames=6, width=640, height=480)
    out = tmp_path / 'copy.mcap'
    recorder = start_skynav('record', str(out), '--all')
    wait_text(recorder, 'recording every topic')
    replay = start_skynav('replay', str(source), '--rate', '0', '--wait-for-subscribers', '1')
    assert replay.wait(timeout=90) == 0, replay.stderr.read()
    recorder.send_signal(signal.SIGINT)
    assert recorder.wait(timeout=30) == 0, recorder.stderr.read()

    with open_bag(out) as bag:
        for topic in {t for t, _, _, _ in sent}:
            mine = [m for t, _, _, m in sent if t == topic]
            theirs = [bag.deserialize(m) for m in bag.messages([topic])]
            assert len(theirs) == len(mine), topic
            assert all(map(messages_equal, mine, theirs)), topic
    # The copy is a rosbag2 MCAP that other tools read too.
    with Reader(out) as reader:
        assert reader.topics[SKYLINE_SH].msgcount == 6
    with out.open('rb') as stream:
        summary = mcap.reader.make_reader(stream).get_summary()
        assert {s.encoding for s in summary.schemas.values()} == {'ros2msg'}


def test_replay_follows_the_recorded_timing(tmp_path):
    source = tmp_path / 'timed.mcap'
    write_sample_bag(source, frames=11)  # 10 Hz: 1.0 s of recording
    out = tmp_path / 'timed_copy.mcap'
    recorder = start_skynav('record', str(out), SKYLINE_SH)
    wait_text(recorder, 'recording')
    replay = start_skynav('replay', str(source), '--rate', '2', '--topics', SKYLINE_SH, '--wait-for-subscribers', '1')
    assert replay.wait(timeout=60) == 0, replay.stderr.read()
    recorder.send_signal(signal.SIGINT)
    assert recorder.wait(timeout=30) == 0
    with open_bag(out) as bag:
        times = np.array([m.log_time for m in bag.messages()]) / 1e9
    assert len(times) == 11
    # At rate 2 the 1.0 s of recording takes 0.5 s; intervals are 50 ms.
    assert 0.4 < times[-1] - times[0] < 0.75
    assert np.median(np.diff(times)) == pytest.approx(0.05, abs=0.015)


@pytest.mark.parametrize('stop', [signal.SIGINT, signal.SIGTERM])
def test_stopped_recorder_leaves_a_whole_bag(tmp_path, ros_context, stop):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from skynav_core.ros import message_class

    ShCoefficients = message_class('skynav_msgs/msg/ShCoefficients')
    node = Node('sh_source', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    publisher = node.create_publisher(ShCoefficients, SKYLINE_SH, 100)
    out = tmp_path / 'stopped.mcap'
    recorder = start_skynav('record', str(out), SKYLINE_SH)
    deadline = time.monotonic() + 30
    while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    assert publisher.get_subscription_count() == 1
    # Publish steadily and stop the recorder in the middle of the stream.
    for i in range(300):
        message = ShCoefficients(max_degree=1, coefficients=[float(i)] * 4, fill='zero')
        message.header.stamp.sec = i
        publisher.publish(message)
        if i == 200:
            recorder.send_signal(stop)
        time.sleep(0.002)
    assert recorder.wait(timeout=30) == 0, recorder.stderr.read()
    stderr = recorder.stderr.read()
    assert not out.with_name(f'.{out.name}.partial').exists()
    with open_bag(out) as bag:
        stamps = [bag.deserialize(m).header.stamp.sec for m in bag.messages()]
    assert f'wrote {len(stamps)} messages' in stderr
    # Everything from the first message on arrived, without a gap, at least up to the stop.
    assert stamps == list(range(stamps[0], stamps[0] + len(stamps)))
    assert stamps[0] == 0 and stamps[-1] >= 200
    executor.shutdown()
    node.destroy_node()


def test_a_recorder_stopped_right_after_a_burst_keeps_all_of_it(tmp_path, ros_context):
    # 500 messages published reliably as fast as they go, then Ctrl-C at once: what is still queued or on its way
    # when the stop comes is taken before the file is finished, so every message of the burst is in it
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from skynav_core.ros import message_class

    burst = 500
    ShCoefficients = message_class('skynav_msgs/msg/ShCoefficients')
    node = Node('sh_burst', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    publisher = node.create_publisher(ShCoefficients, SKYLINE_SH, burst)  # reliable; keeps the burst to resend
    out = tmp_path / 'burst.mcap'
    recorder = start_skynav('record', str(out), SKYLINE_SH)
    try:
        wait_text(recorder, 'recording')
        deadline = time.monotonic() + 30
        while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert publisher.get_subscription_count() == 1
        for i in range(burst):
            message = ShCoefficients(max_degree=1, coefficients=[float(i)] * 4, fill='zero')
            message.header.stamp.sec = i
            publisher.publish(message)
        recorder.send_signal(signal.SIGINT)
        assert recorder.wait(timeout=30) == 0, recorder.stderr.read()
        stderr = recorder.stderr.read()
    finally:
        if recorder.poll() is None:
            recorder.kill()
            recorder.wait()
        executor.shutdown()
        node.destroy_node()
    with open_bag(out) as bag:
        stamps = [bag.deserialize(m).header.stamp.sec for m in bag.messages()]
    assert len(stamps) == burst, f'{len(stamps)} of the {burst} messages recorded'
    assert stamps == list(range(burst)) and f'wrote {burst} messages' in stderr
