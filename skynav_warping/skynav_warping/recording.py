"""A homing grid read from a recording (synthetic or real): snapshot frame 0, current views after it.

Reads a rosbag2 MCAP through skynav_core.bag (imported when called; a workspace sibling, not needed by the
warping code itself). Frames are paired by header stamp across /ground_truth/pose, /ground_truth/mask and the two
image topics; the camera comes from /camera/uv/camera_info.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

POSE = '/ground_truth/pose'
MASK = '/ground_truth/mask'
UV = '/camera/uv/image_raw'
GREEN = '/camera/green/image_raw'
INFO = '/camera/uv/camera_info'


@dataclass(frozen=True)
class HomingGrid:
    """Frames of a homing recording; frame 0 is the snapshot."""

    camera: object  # skynav_sh EquidistantCamera
    positions: np.ndarray  # (N, 3) camera_link in map, m
    quaternions: np.ndarray  # (N, 4) camera_link in map, (x, y, z, w)
    masks: np.ndarray  # (N, H, W) uint8, 255 sky
    uv: np.ndarray | None  # (N, H, W) as recorded (mono8 / mono16 / float32), None if not recorded
    green: np.ndarray | None
    labels: tuple[str, ...]
    synthetic: bool


def _image(message) -> np.ndarray:
    """Return the pixels of a sensor_msgs/Image with encoding mono8, mono16 or 32FC1 as an (H, W) array."""
    dtypes = {'mono8': np.uint8, 'mono16': np.uint16, '32FC1': np.float32}
    dtype = np.dtype(dtypes[message.encoding])
    if message.is_bigendian:
        dtype = dtype.newbyteorder('>')
    row = np.frombuffer(bytes(message.data), dtype=dtype).reshape(message.height, -1)
    return row[:, : message.width].astype(dtype.newbyteorder('='))


def load_homing_grid(path: str) -> HomingGrid:
    """Return the frames of a homing recording (needs /ground_truth/pose, /ground_truth/mask, camera info)."""
    import yaml

    from skynav_core.bag import open_bag
    from skynav_core.camera import EquidistantCamera

    by_stamp: dict[int, dict] = {}
    camera = None
    with open_bag(path) as bag:
        description = yaml.safe_load(bag.custom_data.get('skynav_sim', '{}') or '{}') or {}
        for raw in bag.messages([POSE, MASK, UV, GREEN, INFO]):
            message = bag.deserialize(raw)
            if raw.topic == INFO:
                camera = camera or EquidistantCamera.from_camera_info(message)
                continue
            stamp = message.header.stamp.sec * 10 ** 9 + message.header.stamp.nanosec
            entry = by_stamp.setdefault(stamp, {})
            if raw.topic == POSE:
                p, q = message.pose.position, message.pose.orientation
                entry['pose'] = ([p.x, p.y, p.z], [q.x, q.y, q.z, q.w])
            else:
                entry[raw.topic] = _image(message)
    if camera is None:
        raise ValueError(f'{path}: no {INFO} messages')
    frames = [by_stamp[s] for s in sorted(by_stamp) if 'pose' in by_stamp[s] and MASK in by_stamp[s]]
    if len(frames) < 2:
        raise ValueError(f'{path}: fewer than two frames with ground-truth pose and mask')
    labels = tuple(f.get('label', '') for f in description.get('frames', []))[: len(frames)]

    def stack(topic: str) -> np.ndarray | None:
        return np.stack([f[topic] for f in frames]) if all(topic in f for f in frames) else None

    return HomingGrid(camera=camera, positions=np.array([f['pose'][0] for f in frames]),
                      quaternions=np.array([f['pose'][1] for f in frames]), masks=stack(MASK), uv=stack(UV),
                      green=stack(GREEN), labels=labels, synthetic=bool(description.get('synthetic', False)))
