# SPDX-License-Identifier: Apache-2.0
"""A homing grid read from a recording (synthetic or real): snapshot frame 0, current views after it.

Reads a rosbag2 MCAP through skynav_core.views.recorded_frames (imported when called: the warping code itself needs
no recording). Frames are paired by header stamp across /ground_truth/pose, /ground_truth/mask and the two image
topics; the camera comes from /camera/uv/camera_info.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skynav_core.camera_input import CAMERA_INFO_TOPIC
from skynav_core.names import GREEN_IMAGE, GROUND_TRUTH_MASK, UV_IMAGE
from skynav_core.recording.bag import open_bag
from skynav_core.views import recorded_frames
from skynav_warping.errors import WarpingError


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


def load_homing_grid(path: str) -> HomingGrid:
    """Return the frames of a homing recording (needs /ground_truth/pose, /ground_truth/mask, camera info)."""

    with open_bag(path) as bag:
        recorded = recorded_frames(bag, [GROUND_TRUTH_MASK, UV_IMAGE, GREEN_IMAGE])
    if recorded.camera is None:
        raise WarpingError(f'{path}: no {CAMERA_INFO_TOPIC} messages')
    stamps = sorted(s for s in recorded.poses if s in recorded.images[GROUND_TRUTH_MASK])
    if len(stamps) < 2:
        raise WarpingError(f'{path}: fewer than two frames with ground-truth pose and mask')
    poses = np.stack([recorded.poses[s] for s in stamps])

    def stack(topic: str) -> np.ndarray | None:
        images = recorded.images[topic]
        return np.stack([images[s] for s in stamps]) if all(s in images for s in stamps) else None

    masks = stack(GROUND_TRUTH_MASK)
    assert masks is not None  # every stamp kept has a mask
    return HomingGrid(
        camera=recorded.camera,
        positions=poses[:, :3],
        quaternions=poses[:, 3:],
        masks=masks,
        uv=stack(UV_IMAGE),
        green=stack(GREEN_IMAGE),
        labels=tuple(recorded.labels()[: len(stamps)]),
        synthetic=recorded.synthetic,
    )
