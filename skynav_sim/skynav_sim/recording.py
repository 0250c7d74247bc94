# SPDX-License-Identifier: Apache-2.0
"""Render a scenario and write it as a rosbag2 MCAP recording with the contract's topics and ground truth.

Per frame, all with the same header.stamp (FRAME_RATE apart, starting at the
first frame's time of day on SIMULATED_DATE): UV and green images, the camera
info, the ground-truth pose of camera_link in map and the ground-truth sky
mask. The recording's metadata (custom_data 'skynav_sim') says how it was made
and what each frame is; it is marked synthetic there and in its name.
"""

from __future__ import annotations

import datetime
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from skynav_core.bag import BagWriter
from skynav_core.camera import EquidistantCamera
from skynav_core.typestore import typestore

from .render import Renderer, View
from .scenarios import FRAME_RATE, Frame
from .sensor import Sensor
from .sky import Sky
from .world import World

SIMULATED_DATE = datetime.datetime(2026, 6, 21, tzinfo=datetime.UTC)  # the sun model's day (172)
TOPICS = {
    '/camera/uv/image_raw': 'sensor_msgs/msg/Image',
    '/camera/green/image_raw': 'sensor_msgs/msg/Image',
    '/camera/uv/camera_info': 'sensor_msgs/msg/CameraInfo',
    '/ground_truth/pose': 'geometry_msgs/msg/PoseStamped',
    '/ground_truth/mask': 'sensor_msgs/msg/Image',
}
CAMERA_FRAME = 'camera_link'
MAP_FRAME = 'map'


@dataclass
class Capture:
    """One rendered and captured frame."""

    stamp: int  # ns since the epoch
    frame: Frame
    view: View
    uv: np.ndarray  # image in the chosen encoding
    green: np.ndarray


def start_stamp(hours: float) -> int:
    """Return the stamp (ns) of a recording's first frame taken at `hours` local solar time."""
    return int(round((SIMULATED_DATE + datetime.timedelta(hours=hours)).timestamp() * 1e9))


def stamps(frames: list[Frame]) -> list[int]:
    """Return the header stamps (ns) of frames: FRAME_RATE apart from the first frame's time of day."""
    first = start_stamp(frames[0].hours)
    period = int(round(1e9 / FRAME_RATE))
    return [first + k * period for k in range(len(frames))]


def captures(
    world: World, camera: EquidistantCamera, frames: list[Frame], encoding: str, seed: int, sensor: Sensor | None = None
) -> Iterator[Capture]:
    """Render and capture each frame in turn; noise is seeded per frame, so output depends only on inputs."""
    renderer = Renderer(world, camera)
    sensor = sensor or Sensor()
    skies: dict[tuple[float, float], Sky] = {}
    for index, (frame, stamp) in enumerate(zip(frames, stamps(frames))):
        key = (frame.hours, frame.cloud_cover)
        if key not in skies:
            skies[key] = Sky(frame.hours, frame.cloud_cover, cloud_seed=seed)
        view = renderer.render(frame.pose, skies[key])
        rng = np.random.default_rng([seed, index, 31])
        uv = sensor.capture(view.uv, view.inside, encoding, rng)
        green = sensor.capture(view.green, view.inside, encoding, rng)
        yield Capture(stamp, frame, view, uv, green)


def write(
    path: str | Path,
    world: World,
    camera: EquidistantCamera,
    frames: list[Frame],
    encoding: str,
    seed: int,
    description: dict,
    progress: Callable[[int], None] | None = None,
) -> Path:
    """Render `frames` into a recording at `path` (written atomically); return the path."""

    store = typestore()
    T = store.types
    info_fields = camera.camera_info_fields()
    writer = BagWriter(path)
    try:
        writer.set_custom_data('skynav_sim', yaml.safe_dump(description, sort_keys=False))
        for topic, msgtype in TOPICS.items():
            writer.add_topic(topic, msgtype)
        for capture in captures(world, camera, frames, encoding, seed):
            sec, nanosec = divmod(capture.stamp, 10**9)
            time = T['builtin_interfaces/msg/Time'](sec, nanosec)
            header = T['std_msgs/msg/Header'](time, CAMERA_FRAME)
            messages = {
                '/camera/uv/image_raw': image_message(T, header, capture.uv, encoding),
                '/camera/green/image_raw': image_message(T, header, capture.green, encoding),
                '/camera/uv/camera_info': camera_info_message(T, header, info_fields),
                '/ground_truth/pose': pose_message(T, T['std_msgs/msg/Header'](time, MAP_FRAME), capture.frame),
                '/ground_truth/mask': image_message(T, header, capture.view.sky.astype(np.uint8) * 255, 'mono8'),
            }
            for topic, message in messages.items():
                writer.write(topic, capture.stamp, store.serialize_cdr(message, TOPICS[topic]))
            if progress is not None:
                progress(1)
    except BaseException:
        writer.abort()  # an interrupted scenario must not pass for a whole one
        raise
    return writer.close()


def image_message(T: dict, header: object, pixels: np.ndarray, encoding: str) -> object:
    """Return a sensor_msgs/Image (rosbags) of a single-channel image."""
    height, width = pixels.shape
    return T['sensor_msgs/msg/Image'](
        header, height, width, encoding, 0, width * pixels.itemsize, np.ascontiguousarray(pixels).view(np.uint8).ravel()
    )


def camera_info_message(T: dict, header: object, fields: dict) -> object:
    """Return a sensor_msgs/CameraInfo (rosbags) of the simulated camera."""
    roi = T['sensor_msgs/msg/RegionOfInterest'](0, 0, 0, 0, False)
    return T['sensor_msgs/msg/CameraInfo'](
        header,
        fields['height'],
        fields['width'],
        fields['distortion_model'],
        np.array(fields['d'], float),
        np.array(fields['k'], float),
        np.array(fields['r'], float),
        np.array(fields['p'], float),
        0,
        0,
        roi,
    )


def pose_message(T: dict, header: object, frame: Frame) -> object:
    """Return the geometry_msgs/PoseStamped (rosbags) of camera_link in map."""
    x, y, z = frame.pose.position
    qx, qy, qz, qw = frame.pose.quaternion
    pose = T['geometry_msgs/msg/Pose'](
        T['geometry_msgs/msg/Point'](x, y, z), T['geometry_msgs/msg/Quaternion'](qx, qy, qz, qw)
    )
    return T['geometry_msgs/msg/PoseStamped'](header, pose)
