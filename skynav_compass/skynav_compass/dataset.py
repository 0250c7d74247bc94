"""Compass sets from recordings: images, masks, camera and ground-truth poses of camera_link in map.

A compass set (skynav sim bag compass) holds a reference view (frame 0, the snapshot) and views rotated and/or
moved against it. Reading needs skynav_bringup (imported on call only); everything else here is plain arrays.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skynav_core.rotations import as_quaternion, relative_rotation

IMAGE_TOPICS = {'uv': '/camera/uv/image_raw', 'green': '/camera/green/image_raw', 'mask': '/ground_truth/mask'}
POSE_TOPIC = '/ground_truth/pose'
INFO_TOPIC = '/camera/uv/camera_info'


def true_rotation(snapshot_orientation: np.ndarray, current_orientations: np.ndarray) -> np.ndarray:
    """Return the true compass rotations Q_s^-1 Q_c as quaternions (..., 4) (x, y, z, w) from map orientations."""
    return as_quaternion(relative_rotation(snapshot_orientation, current_orientations))


@dataclass(frozen=True)
class CompassSet:
    """Frames of one compass set: images (N, H, W) uint8, poses of camera_link in map, labels, camera."""

    camera: object  # skynav_sh EquidistantCamera
    uv: np.ndarray  # (N, H, W)
    green: np.ndarray  # (N, H, W)
    masks: np.ndarray  # (N, H, W), 255 sky, 0 ground (ground truth)
    positions: np.ndarray  # (N, 3) m, camera_link in map
    orientations: np.ndarray  # (N, 4) quaternions (x, y, z, w), camera_link in map
    labels: tuple[str, ...]  # 'reference', 'rotation', 'translation', ...
    synthetic: bool
    name: str = ''
    reference: int = 0

    def __len__(self) -> int:
        """Return the number of frames."""
        return len(self.labels)

    @property
    def queries(self) -> np.ndarray:
        """Return the indices of all frames but the reference."""
        return np.array([i for i in range(len(self)) if i != self.reference])

    def true_rotations(self) -> np.ndarray:
        """Return Q_ref^-1 Q_i for every frame, (N, 4) quaternions (x, y, z, w): d_reference = R d_frame."""
        return true_rotation(self.orientations[self.reference], self.orientations)

    def translations(self) -> np.ndarray:
        """Return every frame's distance (m) from the reference position."""
        return np.linalg.norm(self.positions - self.positions[self.reference], axis=1)

    def tilts(self) -> np.ndarray:
        """Return every frame's relative tilt (deg) against the reference: angle between their camera z axes."""
        from skynav_compass.evaluation import relative_tilt

        return relative_tilt(self.true_rotations())


def load_compass_set(path: str | Path) -> CompassSet:
    """Return the compass set of a recording (first camera info; frames in stamp order; labels from metadata)."""
    import yaml

    from skynav_core.bag import open_bag
    from skynav_core.camera import EquidistantCamera

    frames: dict[int, dict] = {}
    camera = None
    custom: dict = {}
    with open_bag(path) as bag:
        if bag.custom_data and 'skynav_sim' in bag.custom_data:
            custom = yaml.safe_load(bag.custom_data['skynav_sim']) or {}
        topics = list(IMAGE_TOPICS.values()) + [POSE_TOPIC, INFO_TOPIC]
        for raw in bag.messages(topics):
            message = bag.deserialize(raw)
            if raw.topic == INFO_TOPIC:
                camera = camera or EquidistantCamera.from_camera_info(message)
                continue
            stamp = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
            frame = frames.setdefault(stamp, {})
            if raw.topic == POSE_TOPIC:
                p, q = message.pose.position, message.pose.orientation
                frame['position'] = (p.x, p.y, p.z)
                frame['orientation'] = (q.x, q.y, q.z, q.w)
            else:
                if message.encoding != 'mono8':
                    raise ValueError(f'{path}: {raw.topic} has encoding {message.encoding}, expected mono8')
                image = np.frombuffer(bytes(message.data), dtype=np.uint8).reshape(message.height, message.step)
                key = next(k for k, topic in IMAGE_TOPICS.items() if topic == raw.topic)
                frame[key] = image[:, : message.width].copy()
    if camera is None:
        raise ValueError(f'{path}: no {INFO_TOPIC} message')
    stamps = sorted(s for s, f in frames.items() if {'position', 'uv', 'green', 'mask'} <= set(f))
    meta_frames = custom.get('frames') or []
    labels = tuple(str(meta_frames[i].get('label', 'frame')) if i < len(meta_frames) else 'frame'
                   for i in range(len(stamps)))
    stack = lambda key: np.stack([frames[s][key] for s in stamps])  # noqa: E731
    return CompassSet(camera, stack('uv'), stack('green'), stack('mask'), stack('position').astype(float),
                      stack('orientation').astype(float), labels, bool(custom.get('synthetic', False)),
                      Path(path).stem)
