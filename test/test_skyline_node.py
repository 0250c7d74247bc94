# SPDX-License-Identifier: Apache-2.0
"""The running skyline node: masks of a replayed recording against ground truth, and bad input survived."""

import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from skynav_core.camera import EquidistantCamera
from skynav_core.images import fill_image, image_to_array, stamp_ns
from skynav_core.names import (
    CAMERA_FRAME,
    DIAGNOSTICS,
    GREEN_IMAGE,
    GROUND_TRUTH_MASK,
    SKYLINE_MASK,
    UV_CAMERA_INFO,
    UV_IMAGE,
)
from skynav_core.recording.bag import open_bag
from skynav_skyline.classify import classification_rate
from skynav_testing import start_skynav

BAGS = Path(__file__).parents[1] / 'bags'
# `skynav skyline eval` on the bundled skyline sets: default method 99.1 % mean, worst exposure 96.2 %.
MEAN_RATE_BOUND = 0.98
WORST_RATE_BOUND = 0.95


def ground_truth(path):
    """Return {stamp: truth mask} and the camera of a labelled recording."""
    truths, camera = {}, None
    with open_bag(path) as bag:
        for raw in bag.messages([GROUND_TRUTH_MASK, UV_CAMERA_INFO]):
            message = bag.deserialize(raw)
            if raw.topic == UV_CAMERA_INFO:
                camera = EquidistantCamera.from_camera_info(message)
            else:
                truths[stamp_ns(message.header)] = image_to_array(message)
    return truths, camera


def start_node(module: str, *ros_args: str) -> subprocess.Popen:
    """Start a node class in a process of its own, as `skynav launch` does."""
    return subprocess.Popen(
        [sys.executable, '-m', 'skynav_core.run_node', module, '--ros-args', *ros_args],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )


def spin_until(executor, done, timeout):
    deadline = time.monotonic() + timeout
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return done()


@pytest.fixture
def graph_node(ros_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    node = Node('skyline_test', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    yield node, executor
    executor.shutdown()
    node.destroy_node()


def test_replayed_recording_gives_masks_that_match_ground_truth(graph_node):
    from sensor_msgs.msg import Image

    node, executor = graph_node
    bag = BAGS / 'synthetic_mineral_skyline.mcap'
    truths, camera = ground_truth(bag)
    masks = {}
    node.create_subscription(Image, SKYLINE_MASK, lambda m: masks.__setitem__(stamp_ns(m.header), m), 50)
    skyline = start_node('skynav_skyline.node:SkylineNode')
    try:
        assert spin_until(executor, lambda: node.count_publishers(SKYLINE_MASK) > 0, 30)
        replay = start_skynav(
            'replay',
            str(bag),
            '--rate',
            '1',
            '--wait-for-subscribers',
            '1',  # this test's skyline node, the only one running (a graph's sh would read the camera info too)
            '--topics',
            UV_IMAGE,
            GREEN_IMAGE,
            UV_CAMERA_INFO,
        )
        assert replay.wait(timeout=120) == 0, replay.stderr.read()
        spin_until(executor, lambda: len(masks) == len(truths), 30)
    finally:
        skyline.terminate()
        skyline.wait(timeout=30)
    assert set(masks) == set(truths)  # one mask per exposure, stamped as the exposure
    circle = camera.image_circle()
    rates = []
    for stamp, message in masks.items():
        assert message.encoding == 'mono8' and message.header.frame_id == CAMERA_FRAME
        mask = image_to_array(message)
        assert set(np.unique(mask)) <= {0, 255} and not mask[~circle].any()
        rates.append(classification_rate(mask, truths[stamp], circle))
    assert np.mean(rates) >= MEAN_RATE_BOUND and min(rates) >= WORST_RATE_BOUND, rates


def _image(encoding, pixels, stamp, frame=CAMERA_FRAME):
    from sensor_msgs.msg import Image

    if encoding == 'rgb8':  # not an encoding of the contract: built by hand
        message = Image(
            height=pixels.shape[0],
            width=pixels.shape[1] // 3,
            encoding='rgb8',
            step=pixels.shape[1],
            data=pixels.tobytes(),
        )
    else:
        message = fill_image(Image(), pixels, encoding)
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 10**9)
    message.header.frame_id = frame
    return message


def _camera_info(camera, stamp):
    from sensor_msgs.msg import CameraInfo

    info = CameraInfo()
    for key, value in camera.camera_info_fields().items():
        setattr(info, key, value)
    info.header.stamp.sec, info.header.stamp.nanosec = divmod(stamp, 10**9)
    return info


def _diagnostic_values(array, name):
    for status in array.status:
        if status.name == name:
            return {kv.key: kv.value for kv in status.values}
    return None


def test_bad_input_is_logged_counted_and_survived(graph_node):
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import CameraInfo, Image

    node, executor = graph_node
    camera = EquidistantCamera.for_field_of_view(64, 48, math.radians(200))
    uv_pub = node.create_publisher(Image, UV_IMAGE, 50)
    green_pub = node.create_publisher(Image, GREEN_IMAGE, 50)
    info_pub = node.create_publisher(CameraInfo, UV_CAMERA_INFO, 50)
    masks, diagnostics = [], []
    node.create_subscription(Image, SKYLINE_MASK, masks.append, 50)
    node.create_subscription(DiagnosticArray, DIAGNOSTICS, diagnostics.append, 50)
    skyline = start_node('skynav_skyline.node:SkylineNode')
    try:
        assert spin_until(
            executor,
            lambda: (
                uv_pub.get_subscription_count()
                and green_pub.get_subscription_count()
                and info_pub.get_subscription_count()
                and node.count_publishers(SKYLINE_MASK)
            ),
            30,
        )
        rng = np.random.default_rng(0)
        sky = np.full((48, 64), 30000, np.uint16)
        sky[:, :20] = 2000  # a band of ground
        good_uv = (sky + rng.integers(0, 300, sky.shape)).astype(np.uint16)
        good_green = (sky // 2 + 8000 + rng.integers(0, 300, sky.shape)).astype(np.uint16)
        step = 100_000_000
        t0 = time.time_ns()

        def frame(k, uv, green, uv_encoding='mono16', green_encoding='mono16'):
            uv_pub.publish(_image(uv_encoding, uv, t0 + k * step))
            green_pub.publish(_image(green_encoding, green, t0 + k * step))
            spin_until(executor, lambda: False, 0.1)  # as a 10 Hz camera: the node's camera queue is short

        # Until a mask comes back, discovery may still drop the first samples of a best-effort topic.
        k = 0
        while not masks and k < 100:
            info_pub.publish(_camera_info(camera, t0 + k * step))
            frame(k, good_uv, good_green)
            k += 1
        assert masks, 'the skyline node never answered'
        masks.clear()
        # Bad inputs: wrong encoding, UV and green of different sizes, an all-NaN radiance image,
        # the last good exposure again (no newer than the last one, and close to it: not a restart of time);
        # then a good frame.
        frame(k + 1, np.zeros((48, 64, 3), np.uint8).reshape(48, 192), good_green, 'rgb8')
        frame(k + 2, good_uv, good_green[:, :32])
        frame(k + 3, np.full((48, 64), np.nan, np.float32), np.full((48, 64), np.nan, np.float32), '32FC1', '32FC1')
        frame(k - 1, good_uv, good_green)
        frame(k + 4, good_uv, good_green)
        assert spin_until(executor, lambda: len(masks) >= 1, 30)

        def counts():
            values = _diagnostic_values(diagnostics[-1], 'skynav/skyline') if diagnostics else None
            return values or {}

        assert spin_until(
            executor,
            lambda: all(
                int(counts().get(f'rejected_{reason}', 0)) >= 1
                for reason in ('encoding', 'size_mismatch', 'invalid_image', 'out_of_order')
            ),
            30,
        ), ' '.join(f'{k}={v}' for k, v in sorted(counts().items()))
        assert skyline.poll() is None  # still serving
        assert int(counts()['errors']) == 0
        assert [stamp_ns(m.header) for m in masks] == [t0 + (k + 4) * step]
    finally:
        skyline.terminate()
        out, _ = skyline.communicate(timeout=30)
    for reason in ('encoding', 'size_mismatch', 'invalid_image', 'out_of_order'):
        assert sum(f'rejected input ({reason})' in line for line in out.splitlines()) == 1, out
    assert 'Traceback' not in out


def test_missing_camera_info_is_counted_and_nothing_crashes(graph_node):
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import Image

    node, executor = graph_node
    uv_pub = node.create_publisher(Image, UV_IMAGE, 100)
    green_pub = node.create_publisher(Image, GREEN_IMAGE, 100)
    diagnostics = []
    node.create_subscription(DiagnosticArray, DIAGNOSTICS, diagnostics.append, 50)
    skyline = start_node('skynav_skyline.node:SkylineNode')
    try:
        assert spin_until(executor, lambda: uv_pub.get_subscription_count() and green_pub.get_subscription_count(), 30)
        pixels = np.full((48, 64), 1000, np.uint16)
        for k in range(40):  # more exposures than the node holds while it waits for camera info
            stamp = 1_800_000_000 * 10**9 + k * 10**8
            uv_pub.publish(_image('mono16', pixels, stamp))
            green_pub.publish(_image('mono16', pixels, stamp))
            spin_until(executor, lambda: False, 0.1)  # a 10 Hz camera

        def dropped():
            values = _diagnostic_values(diagnostics[-1], 'skynav/skyline') if diagnostics else None
            return int((values or {}).get('dropped_no_camera_info', 0))

        assert spin_until(executor, lambda: dropped() >= 5, 30)
        assert skyline.poll() is None
    finally:
        skyline.terminate()
        out, _ = skyline.communicate(timeout=30)
    assert 'dropped input (no_camera_info)' in out and 'Traceback' not in out


def test_an_image_too_large_for_the_transport_is_counted_as_lost(graph_node):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image

    node, executor = graph_node
    uv_pub = node.create_publisher(Image, UV_IMAGE, QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE))
    diagnostics = []
    node.create_subscription(DiagnosticArray, DIAGNOSTICS, diagnostics.append, 50)
    skyline = start_node('skynav_skyline.node:SkylineNode')

    def values():
        found = _diagnostic_values(diagnostics[-1], 'skynav/skyline') if diagnostics else None
        return found or {}

    try:
        assert spin_until(executor, lambda: uv_pub.get_subscription_count() and node.count_publishers(DIAGNOSTICS), 30)
        stamp = 1_800_000_000 * 10**9
        # small frames until the node takes them (discovery may still drop the first ones), then one of
        # 4200x4200 pixels (17.6 MB: beyond the 16 MiB shared-memory segment of skynav's Fast DDS profile; an
        # 8000x8000 one vanishes alike), then a small one again, which tells the node that one went missing
        small = np.full((48, 64), 1000, np.uint16)
        k = 0
        while int(values().get('received', 0)) == 0 and k < 100:
            uv_pub.publish(_image('mono16', small, stamp + k * 10**8))
            spin_until(executor, lambda: False, 0.2)
            k += 1
        received = int(values()['received'])
        lost = int(values().get('dropped_lost', 0))
        uv_pub.publish(_image('mono8', np.full((4200, 4200), 100, np.uint8), stamp + (k + 1) * 10**8))
        uv_pub.publish(_image('mono16', small, stamp + (k + 2) * 10**8))
        assert spin_until(executor, lambda: int(values().get('received', 0)) > received, 30)
        assert spin_until(executor, lambda: int(values().get('dropped_lost', 0)) == lost + 1, 10), values()
        assert skyline.poll() is None
    finally:
        skyline.terminate()
        out, _ = skyline.communicate(timeout=30)
    assert 'dropped input (lost)' in out and 'Traceback' not in out
