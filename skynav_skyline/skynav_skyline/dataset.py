# SPDX-License-Identifier: Apache-2.0
"""Labelled frames from a recording: UV, green, the ground-truth sky mask, the camera, and where/when it was taken.

For training and evaluation only (nodes never read ground truth). World and time-of-day labels come
from the metadata of synthetic recordings (custom_data 'skynav_sim'); other recordings are labelled
with their file name and 'all'.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from skynav_core.bag import BagError, open_bag
from skynav_core.camera import EquidistantCamera
from skynav_core.images import image_to_array, stamp_ns

UV, GREEN, INFO, TRUTH = (
    '/camera/uv/image_raw',
    '/camera/green/image_raw',
    '/camera/uv/camera_info',
    '/ground_truth/mask',
)


@dataclass
class LabelledFrame:
    """One exposure with its ground truth."""

    stamp: int  # ns
    uv: np.ndarray
    green: np.ndarray
    encoding: tuple[str, str]  # (UV, green)
    truth: np.ndarray  # uint8, 255 sky
    camera: EquidistantCamera
    world: str
    time: str  # time-of-day label


def count_frames(path: str | Path) -> int:
    """Return how many labelled exposures a recording holds (its ground-truth masks)."""

    with open_bag(path) as bag:
        return bag.topics[TRUTH].count if TRUTH in bag.topics else 0


def labelled_frames(path: str | Path) -> Iterator[LabelledFrame]:
    """Yield the exposures of a recording that have UV, green, camera info and a ground-truth mask."""

    with open_bag(path) as bag:
        missing = [t for t in (UV, GREEN, INFO, TRUTH) if t not in bag.topics]
        if missing:
            raise BagError(f'{path}: no {", ".join(missing)}; training and evaluation need labelled recordings')
        info = yaml.safe_load(bag.custom_data.get('skynav_sim') or '{}') or {}
        world = info.get('world', Path(path).stem)
        labels = [f.get('label', 'all') for f in info.get('frames', [])]
        parts: dict[int, dict] = {}
        camera = None
        index = 0
        for raw in bag.messages([UV, GREEN, INFO, TRUTH]):
            message = bag.deserialize(raw)
            stamp = stamp_ns(message.header)
            if raw.topic == INFO:
                camera = EquidistantCamera.from_camera_info(message)
                continue
            parts.setdefault(stamp, {})[raw.topic] = (image_to_array(message), message.encoding)
            frame = parts[stamp]
            if len(frame) == 3 and camera is not None:
                del parts[stamp]
                time = labels[index] if index < len(labels) and labels[index] in TIME_LABELS else 'all'
                index += 1
                yield LabelledFrame(
                    stamp,
                    frame[UV][0],
                    frame[GREEN][0],
                    (frame[UV][1], frame[GREEN][1]),
                    frame[TRUTH][0],
                    camera,
                    world,
                    time,
                )


TIME_LABELS = ('dawn', 'sunrise', 'morning', 'forenoon', 'noon')
