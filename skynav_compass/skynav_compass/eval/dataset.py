# SPDX-License-Identifier: Apache-2.0
"""Compass sets from recordings: images, masks, camera and ground-truth poses of camera_link in map.

A compass set (skynav sim bag compass) holds a reference view (frame 0, the snapshot) and views rotated and/or
moved against it. Reading goes through skynav_core.views.recorded_frames; everything else here is plain arrays.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skynav_compass.errors import CompassError
from skynav_compass.eval.evaluation import relative_tilt
from skynav_core.camera import EquidistantCamera
from skynav_core.camera_input import CAMERA_INFO_TOPIC
from skynav_core.names import GREEN_IMAGE, GROUND_TRUTH_MASK, UV_IMAGE
from skynav_core.recording.bag import open_bag
from skynav_core.rotations import as_quaternion, relative_rotation
from skynav_core.views import recorded_frames

IMAGE_TOPICS = {'uv': UV_IMAGE, 'green': GREEN_IMAGE, 'mask': GROUND_TRUTH_MASK}


def true_rotation(snapshot_orientation: np.ndarray, current_orientations: np.ndarray) -> np.ndarray:
    """Return the true compass rotations Q_s^-1 Q_c as quaternions (..., 4) (x, y, z, w) from map orientations."""
    return as_quaternion(relative_rotation(snapshot_orientation, current_orientations))


@dataclass(frozen=True)
class CompassSet:
    """Frames of one compass set: images (N, H, W) uint8, poses of camera_link in map, labels, camera."""

    camera: EquidistantCamera
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

        return relative_tilt(self.true_rotations())


def load_compass_set(path: str | Path) -> CompassSet:
    """Return the compass set of a recording (first camera info; frames in stamp order; labels from metadata)."""

    with open_bag(path) as bag:
        recorded = recorded_frames(bag, list(IMAGE_TOPICS.values()), encodings=('mono8',))
    if recorded.camera is None:
        raise CompassError(f'{path}: no {CAMERA_INFO_TOPIC} message')
    images = {key: recorded.images[topic] for key, topic in IMAGE_TOPICS.items()}
    stamps = sorted(s for s in recorded.poses if all(s in by_stamp for by_stamp in images.values()))
    meta_frames = recorded.description.get('frames') or []
    labels = tuple(
        str(meta_frames[i].get('label', 'frame')) if i < len(meta_frames) else 'frame' for i in range(len(stamps))
    )
    poses = np.stack([recorded.poses[s] for s in stamps])
    uv, green, masks = (np.stack([images[key][s] for s in stamps]) for key in IMAGE_TOPICS)
    return CompassSet(
        recorded.camera,
        uv,
        green,
        masks,
        poses[:, :3],
        poses[:, 3:],
        labels,
        recorded.synthetic,
        Path(path).stem,
    )
