# SPDX-License-Identifier: Apache-2.0
"""Helpers for tests that run ROS: a ROS domain of their own, and the `skynav` command as a subprocess."""

from __future__ import annotations

import dataclasses
import fcntl
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, TypeVar

import numpy as np
import yaml

from skynav_core.camera import EquidistantCamera
from skynav_core.names import (
    CAMERA_FRAME,
    COMPASS_ORIENTATION,
    GREEN_IMAGE,
    GROUND_TRUTH_MASK,
    GROUND_TRUTH_POSE,
    HOME_VECTOR,
    LOCALIZATION_MATCH,
    SKYLINE_SH,
    UV_CAMERA_INFO,
    UV_IMAGE,
)
from skynav_core.recording.bag import BagWriter, open_bag
from skynav_core.recording.typestore import ensure_type, typestore
from skynav_core.rotations import as_matrix

# Fast DDS maps domain ids up to 232 to UDP ports; tests take theirs from the upper part.
TEST_DOMAINS = range(100, 232)
BAGS = Path(__file__).resolve().parents[2] / 'bags'  # the bundled (synthetic) recordings


def claim_domain_id() -> tuple[int, IO]:
    """Return a ROS domain id no other test run on this machine holds, and the lock that holds it.

    Keep the returned file open for as long as the id is in use.
    """
    candidates = list(TEST_DOMAINS)
    random.shuffle(candidates)
    for domain in candidates:
        lock = open(Path(tempfile.gettempdir()) / f'skynav-ros-domain-{domain}.lock', 'w')
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.close()
            continue
        return domain, lock
    raise RuntimeError(f'every ROS domain id in {TEST_DOMAINS} is held by another test run')


T = TypeVar('T')


def on_executor_thread(executor: Any, call: Callable[[], T], timeout: float = 30.0) -> T:
    """Return what `call()` returns, run on the thread that spins `executor` (an rclpy executor spinning elsewhere).

    Make every action-client call (send_goal_async, get_result_async, cancel_goal_async) of a client spun by another
    thread this way: Jazzy's rclpy drops an answer that is taken before the call has registered its request, and
    its future never completes (ros2/rclpy#1123); on the spinning thread no answer can be taken in between.
    """
    task = executor.create_task(call)
    deadline = time.monotonic() + timeout
    while not task.done():
        if time.monotonic() > deadline:
            raise AssertionError(f'the executor did not run the call within {timeout:g} s')
        time.sleep(0.005)
    return task.result()


class CanceledGoalHandle:
    """A server's goal handle whose cancel the server took before the goal's execution began (rclpy's order when a
    goal's cancel comes in the same wait as the goal); records how the server ended it."""

    is_cancel_requested = True

    def __init__(self, request: Any) -> None:
        self.request = request
        self.ended: list[str] = []
        self.feedback: list[Any] = []

    def canceled(self) -> None:
        self.ended.append('canceled')

    def succeed(self) -> None:
        self.ended.append('succeeded')

    def abort(self) -> None:
        self.ended.append('aborted')

    def publish_feedback(self, feedback: Any) -> None:
        self.feedback.append(feedback)


def run_without_waiting(coroutine: Any) -> Any:
    """Return what `coroutine` returns; AssertionError if it waits for anything."""
    try:
        coroutine.send(None)
    except StopIteration as end:
        return end.value
    coroutine.close()
    raise AssertionError('the coroutine waited instead of returning')


def wait_until(condition: Callable[[], object], what: str, timeout: float = 30.0) -> None:
    """Wait until condition() is true (a thread or another process makes it so); fail naming `what` after timeout s."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f'timed out waiting for {what}'
        time.sleep(0.01)


def skynav_command(*args: str) -> list[str]:
    """Return the command line that runs `skynav ARGS` with this interpreter."""
    return [sys.executable, '-m', 'skynav_bringup.cli', *args]


def run_skynav(
    *args: str, timeout: float = 120, cwd: str | os.PathLike | None = None, env: dict | None = None
) -> subprocess.CompletedProcess:
    """Run `skynav ARGS` to the end and return the finished process with its text output."""
    return subprocess.run(skynav_command(*args), capture_output=True, text=True, timeout=timeout, cwd=cwd, env=env)


def start_skynav(*args: str, cwd: str | os.PathLike | None = None, env: dict | None = None) -> subprocess.Popen:
    """Start `skynav ARGS` in the background with its output captured as text."""
    return subprocess.Popen(
        skynav_command(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd, env=env
    )


@contextmanager
def running(process: subprocess.Popen, stop_timeout: float = 60.0) -> Iterator[subprocess.Popen]:
    """Hold a started `skynav` process (start_skynav) for a block, and stop it with SIGINT after the block; a
    failure in the block carries what the process wrote (the graph's log, for `skynav launch`)."""
    try:
        yield process
    except AssertionError as failure:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=stop_timeout)
        raise AssertionError(f'{failure}\n--- the process wrote ---\n{out}{err}') from None
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
            process.communicate(timeout=stop_timeout)


def one_line_error(stderr: str) -> bool:
    """Return whether `stderr` is exactly one line of error and no traceback."""
    lines = [line for line in stderr.splitlines() if line.strip()]
    return len(lines) == 1 and 'Traceback' not in stderr and 'error' in lines[0]


def wait_text(process: subprocess.Popen, text: str, stream: str = 'stderr') -> list[str]:
    """Read lines of a running process's output until one contains `text`; return the lines read."""
    lines = []
    for line in getattr(process, stream):
        lines.append(line)
        if text in line:
            return lines
    raise AssertionError(f'{text!r} never appeared; the process wrote: {"".join(lines)}')


def sample_messages(frames: int = 5, width: int = 64, height: int = 48) -> list[tuple[str, str, int, object]]:
    """Return (topic, type, log time ns, rosbags message) of every kind a recording holds, at 10 Hz.

    Images (mono16 UV and green), camera info, a ground-truth pose and one
    message of each skynav_msgs type per frame, with values that differ per frame.
    """

    store = typestore()
    for name in ('ShCoefficients', 'PlaceMatch', 'CompassEstimate', 'HomeVector'):
        ensure_type(f'skynav_msgs/msg/{name}')
    T = store.types
    rng = np.random.default_rng(7)
    start = 1_763_780_400 * 10**9
    out: list[tuple[str, str, int, object]] = []
    for i in range(frames):
        t = start + i * 100_000_000
        stamp = T['builtin_interfaces/msg/Time'](t // 10**9, t % 10**9)
        header = T['std_msgs/msg/Header'](stamp, CAMERA_FRAME)
        quaternion = T['geometry_msgs/msg/Quaternion'](*(lambda q: q / np.linalg.norm(q))(rng.normal(size=4)))
        for topic in (UV_IMAGE, GREEN_IMAGE):
            pixels = rng.integers(0, 65535, (height, width), dtype=np.uint16)
            out.append(
                (
                    topic,
                    'sensor_msgs/msg/Image',
                    t,
                    T['sensor_msgs/msg/Image'](
                        header, height, width, 'mono16', 0, 2 * width, pixels.view(np.uint8).ravel()
                    ),
                )
            )
        roi = T['sensor_msgs/msg/RegionOfInterest'](0, 0, 0, 0, False)
        k = np.array([20.0, 0, width / 2 - 0.5, 0, 20.0, height / 2 - 0.5, 0, 0, 1])
        out.append(
            (
                UV_CAMERA_INFO,
                'sensor_msgs/msg/CameraInfo',
                t,
                T['sensor_msgs/msg/CameraInfo'](
                    header,
                    height,
                    width,
                    'equidistant',
                    np.array([0.01, -0.002, 0.0003, -0.00004]),
                    k,
                    np.eye(3).ravel(),
                    np.concatenate([k.reshape(3, 3), np.zeros((3, 1))], axis=1).ravel(),
                    1,
                    1,
                    roi,
                ),
            )
        )
        pose = T['geometry_msgs/msg/Pose'](T['geometry_msgs/msg/Point'](*rng.normal(size=3)), quaternion)
        map_header = T['std_msgs/msg/Header'](stamp, 'map')
        out.append(
            (
                GROUND_TRUTH_POSE,
                'geometry_msgs/msg/PoseStamped',
                t,
                T['geometry_msgs/msg/PoseStamped'](map_header, pose),
            )
        )
        out.append(
            (
                SKYLINE_SH,
                'skynav_msgs/msg/ShCoefficients',
                t,
                T['skynav_msgs/msg/ShCoefficients'](header, 4, rng.normal(size=25), 'zero', np.float32(3.4906585)),
            )
        )
        out.append(
            (
                LOCALIZATION_MATCH,
                'skynav_msgs/msg/PlaceMatch',
                t,
                T['skynav_msgs/msg/PlaceMatch'](
                    header,
                    'garden',
                    i - 1,
                    T['builtin_interfaces/msg/Time'](i, 500),
                    float('inf') if i == 0 else 0.5 * i,
                    i % 2 == 1,
                    np.array([i, i + 1, i + 2], dtype=np.int32),
                    np.array([0.5, 0.75, 2.0]) * i,
                ),
            )
        )
        out.append(
            (
                COMPASS_ORIENTATION,
                'skynav_msgs/msg/CompassEstimate',
                t,
                T['skynav_msgs/msg/CompassEstimate'](header, i, quaternion, 0.01 * i, 0.9, True),
            )
        )
        direction = T['geometry_msgs/msg/Vector3'](*(lambda v: v / np.linalg.norm(v))(rng.normal(size=3)))
        out.append(
            (
                HOME_VECTOR,
                'skynav_msgs/msg/HomeVector',
                t,
                T['skynav_msgs/msg/HomeVector'](header, i, direction, quaternion, 0.02 * i),
            )
        )
    return out


def write_sample_bag(path: str | os.PathLike, frames: int = 5, width: int = 64, height: int = 48) -> list:
    """Write `sample_messages` into a bag at `path`; return them."""

    messages = sample_messages(frames, width, height)
    with BagWriter(path) as writer:
        for topic, msgtype, t, message in messages:
            writer.add_topic(topic, msgtype)
            writer.write(topic, t, typestore().serialize_cdr(message, msgtype))
    return messages


def write_first_frames(source: str | Path, path: str | os.PathLike, frames: int) -> Path:
    """Copy the messages of a recording logged before its UV exposure number `frames` + 1 into a new bag at `path`.

    The CDR bytes, offered QoS and custom data (the synthetic drive's frame list cut to the same frames) are kept,
    so the copy stays marked synthetic and replays like the start of the original.
    """

    with open_bag(source) as bag:
        exposures = [raw.log_time for raw in bag.messages([UV_IMAGE])]
        end = exposures[frames] if frames < len(exposures) else bag.end_time + 1  # log time (ns), not kept
        with BagWriter(path) as writer:
            for key, value in bag.custom_data.items():
                described = yaml.safe_load(value) if key == 'skynav_sim' else None
                if isinstance(described, dict) and isinstance(described.get('frames'), list):
                    value = yaml.safe_dump({**described, 'frames': described['frames'][:frames]}, sort_keys=False)
                writer.set_custom_data(key, value)
            for topic in bag.topics.values():
                writer.add_topic(topic.name, topic.msgtype, topic.offered_qos)
            for raw in bag.messages():
                if raw.log_time < end:
                    writer.write(raw.topic, raw.log_time, raw.data)
    return Path(path)


def messages_equal(a: object, b: object) -> bool:
    """Return whether two rosbags messages hold the same values, field by field (NaN equals NaN)."""

    if dataclasses.is_dataclass(a):
        return type(a).__name__ == type(b).__name__ and all(
            messages_equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a)
        )
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=a.dtype.kind == 'f'))
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(messages_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b):
        return True
    return a == b


#: Kinds of featureless recording: everything sky, everything ground, an open field (sky above a level horizon).
FEATURELESS_KINDS = ('sky', 'ground', 'open-field')
OPEN_FIELD_HORIZON = 1.5  # deg: elevation of the open field's horizon in map (level ground, no relief)
SKY_LEVELS = (80, 43)  # mono8 (UV, green) of the uniform sky: the bundled garden drive's medians
GROUND_LEVELS = (5, 20)  # mono8 (UV, green) of the uniform ground: the same drive's medians


def write_featureless_recording(
    path: str | os.PathLike, kind: str, frames: int = 30, source: str = 'synthetic_garden_teach.mcap'
) -> Path:
    """Write the first frames of a bundled synthetic drive (camera, poses, stamps) with uniform, noise-free images.

    kind 'sky': every pixel sky; 'ground': every pixel ground; 'open-field': sky above a level horizon at
    OPEN_FIELD_HORIZON in map (the camera's own tilt included), ground below. No texture anywhere, so ORB finds
    nothing to describe. The ground-truth mask matches the images; the recording stays marked synthetic.
    """

    if kind not in FEATURELESS_KINDS:
        raise ValueError(f'unknown kind {kind!r}; expected one of {", ".join(FEATURELESS_KINDS)}')
    store = typestore()
    poses: dict[int, tuple[float, float, float, float]] = {}  # camera_link orientation in map by stamp (ns)
    kept: list[int] = []  # stamps (ns) of the frames kept
    with open_bag(BAGS / source) as bag:
        description = yaml.safe_load(bag.custom_data.get('skynav_sim') or '{}') or {}
        description.update(featureless=kind, frames=description.get('frames', [])[:frames])
        messages: list[tuple[str, str, int, Any]] = [
            (raw.topic, raw.msgtype, raw.log_time, bag.deserialize(raw)) for raw in bag.messages()
        ]
    info = next(message for topic, _, _, message in messages if topic == UV_CAMERA_INFO)
    camera = EquidistantCamera.from_camera_info(info)
    directions, circle = camera.pixel_directions(), camera.image_circle()
    for topic, _, _, message in messages:
        if topic == GROUND_TRUTH_POSE:
            q = message.pose.orientation
            poses[message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec] = (q.x, q.y, q.z, q.w)
    with BagWriter(path) as writer:
        writer.set_custom_data('skynav_sim', yaml.safe_dump(description, sort_keys=False))
        for topic, msgtype, log_time, message in messages:
            stamp = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
            if stamp not in kept:
                if len(kept) == frames:
                    continue
                kept.append(stamp)
            if topic in (UV_IMAGE, GREEN_IMAGE, GROUND_TRUTH_MASK):
                if kind == 'open-field':
                    up = directions.reshape(-1, 3) @ as_matrix(poses[stamp])[2]  # z in map of every pixel's ray
                    sky = up.reshape(circle.shape) > np.sin(np.radians(OPEN_FIELD_HORIZON))
                else:
                    sky = np.full(circle.shape, kind == 'sky')
                channel = {UV_IMAGE: 0, GREEN_IMAGE: 1}.get(topic)
                pixels = (
                    sky * np.uint8(255)
                    if channel is None
                    else np.where(sky, SKY_LEVELS[channel], GROUND_LEVELS[channel]) * circle
                )
                message = dataclasses.replace(
                    message, encoding='mono8', step=message.width, data=np.ascontiguousarray(pixels, np.uint8).ravel()
                )
            if topic not in writer.topics:
                writer.add_topic(topic, msgtype)
            writer.write(topic, log_time, store.serialize_cdr(message, msgtype))
    return Path(path)
