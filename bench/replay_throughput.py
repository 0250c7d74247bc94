# SPDX-License-Identifier: Apache-2.0
"""Benchmark: `skynav replay --rate 0` of 640x480 mono16 UV+green pairs, and what `skynav record` keeps.

    .venv/bin/python bench/replay_throughput.py [--pairs N]

Prints the replay throughput, the loss of a recorder fed at that rate, and, as
the peer, the rate of a bare rclpy publisher sending the same bytes from memory
(the transport's own ceiling), with the ratio of the two.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from skynav_core.names import CAMERA_FRAME, GREEN_IMAGE, UV_IMAGE
from skynav_core.process.environment import apply_ros_environment
from skynav_testing import claim_domain_id, start_skynav, wait_text

WIDTH, HEIGHT = 640, 480
FRAME_PERIOD_NS = 100_000_000  # 10 Hz, as the contract's recordings


def write_pairs(path: Path, pairs: int) -> list[bytes]:
    """Write `pairs` UV+green mono16 frames (smooth scene plus noise) and return the serialized images."""
    from skynav_core.recording.bag import BagWriter
    from skynav_core.recording.typestore import typestore

    T = typestore().types
    rng = np.random.default_rng(0)
    v, u = np.mgrid[0:HEIGHT, 0:WIDTH]
    scene = 20000 + 15000 * np.sin(u / 50.0) * np.cos(v / 40.0)
    blobs = []
    with BagWriter(path, compress=False) as writer:
        for topic in (UV_IMAGE, GREEN_IMAGE):
            writer.add_topic(topic, 'sensor_msgs/msg/Image')
        for i in range(pairs):
            t = 1_763_780_400 * 10**9 + i * FRAME_PERIOD_NS
            header = T['std_msgs/msg/Header'](T['builtin_interfaces/msg/Time'](t // 10**9, t % 10**9), CAMERA_FRAME)
            for topic in (UV_IMAGE, GREEN_IMAGE):
                pixels = (scene + rng.normal(0, 300, scene.shape)).clip(0, 65535).astype(np.uint16)
                image = T['sensor_msgs/msg/Image'](
                    header, HEIGHT, WIDTH, 'mono16', 0, 2 * WIDTH, pixels.view(np.uint8).ravel()
                )
                blob = bytes(typestore().serialize_cdr(image, 'sensor_msgs/msg/Image'))
                writer.write(topic, t, blob)
                blobs.append(blob)
    return blobs


def bare_publisher_rate(blobs: list[bytes]) -> float:
    """Return messages per second of an rclpy publisher sending `blobs` to a recorder, from memory."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from skynav_core.ros import message_class

    context = Context()
    rclpy.init(context=context)
    node = Node('bare_publisher', context=context)
    publisher = node.create_publisher(
        message_class('sensor_msgs/msg/Image'),
        UV_IMAGE,
        QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE),
    )
    with tempfile.TemporaryDirectory() as tmp:
        recorder = start_skynav('record', f'{tmp}/bare.mcap', UV_IMAGE)
        wait_text(recorder, 'recording')
        deadline = time.monotonic() + 30
        while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        start = time.monotonic()
        for blob in blobs:
            publisher.publish(blob)
        publisher.wait_for_all_acked()
        elapsed = time.monotonic() - start
        recorder.send_signal(signal.SIGINT)
        recorder.wait(timeout=60)
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    return len(blobs) / elapsed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--pairs', type=int, default=300)
    args = parser.parse_args()
    if 'ROS_DOMAIN_ID' not in os.environ:
        domain, _lock = claim_domain_id()
        os.environ['ROS_DOMAIN_ID'] = str(domain)
    apply_ros_environment()
    from skynav_core.recording.bag import open_bag

    with tempfile.TemporaryDirectory() as tmp:
        source, copy = Path(tmp, 'pairs.mcap'), Path(tmp, 'copy.mcap')
        blobs = write_pairs(source, args.pairs)
        megabytes = sum(map(len, blobs)) / 1e6
        recorder = start_skynav('record', str(copy), UV_IMAGE, GREEN_IMAGE)
        wait_text(recorder, 'recording')
        replay = subprocess.run(
            [
                sys.executable,
                '-m',
                'skynav_bringup.cli',
                'replay',
                str(source),
                '--rate',
                '0',
                '--wait-for-subscribers',
                '1',
            ],
            capture_output=True,
            text=True,
            check=True,
        )
        recorder.send_signal(signal.SIGINT)
        recorder.wait(timeout=60)
        # The replay reports its own publishing time (after discovery, until every message is acknowledged).
        seconds = float(replay.stderr.split(' in ')[1].split(' s ')[0])
        with open_bag(copy) as bag:
            kept = bag.message_count
        bare = bare_publisher_rate(blobs)

    replay_rate = len(blobs) / seconds
    print(f'images: {len(blobs)} ({args.pairs} UV+green pairs, {WIDTH}x{HEIGHT} mono16, {megabytes:.0f} MB)')
    print(
        f'skynav replay --rate 0 : {replay_rate:7.1f} msg/s  {replay_rate / 2:6.1f} pairs/s  '
        f'{megabytes / seconds:6.1f} MB/s'
    )
    print(f'bare rclpy publisher   : {bare:7.1f} msg/s  (the same bytes from memory)')
    print(f'ratio replay / bare    : {replay_rate / bare:.2f}')
    print(f'skynav record kept     : {kept}/{len(blobs)} ({len(blobs) - kept} lost)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
