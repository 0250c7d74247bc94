# SPDX-License-Identifier: Apache-2.0
"""Labelled frames from a recording: UV, green, the ground-truth sky mask, the camera, and where/when it was taken.

For training and evaluation only (nodes never read ground truth). World and time-of-day labels come
from the metadata of synthetic recordings (custom_data 'skynav_sim'); other recordings are labelled
with their file name and 'all'. A colour camera's frames (raw, Bayer or compressed) come as linear RGB, with
the blue plane standing in for UV and the green plane for green.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from skynav_core.camera import EquidistantCamera
from skynav_core.camera_input import recorded_source
from skynav_core.colour import decode_compressed, decode_image
from skynav_core.images import image_to_array, stamp_ns
from skynav_core.names import COLOUR_COMPRESSED, COLOUR_IMAGE, GREEN_IMAGE, GROUND_TRUTH_MASK, UV_IMAGE
from skynav_core.recording.bag import BagError, open_bag

#: How each camera topic's messages become pixels: colour frames as linear RGB, the rest as they are.
_DECODERS = {COLOUR_IMAGE: decode_image, COLOUR_COMPRESSED: decode_compressed}
#: Encoding of a decoded colour frame's planes (skynav_core.colour: uint16 linear).
LINEAR_ENCODING = 'mono16'


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
    rgb: np.ndarray | None = None  # a colour camera's frame: uint16 (H, W, 3) linear RGB (uv, green: its planes)


def count_frames(path: str | Path) -> int:
    """Return how many labelled exposures a recording holds (its ground-truth masks)."""

    with open_bag(path) as bag:
        return bag.topics[GROUND_TRUTH_MASK].count if GROUND_TRUTH_MASK in bag.topics else 0


def labelled_frames(path: str | Path) -> Iterator[LabelledFrame]:
    """Yield the exposures of a recording that have camera frames, camera info and a ground-truth mask."""

    with open_bag(path) as bag:
        source = recorded_source(bag.topics)
        if source is None or source.info not in bag.topics or GROUND_TRUTH_MASK not in bag.topics:
            raise BagError(
                f'{path}: no camera frames with camera info and {GROUND_TRUTH_MASK}; training and evaluation need '
                'labelled recordings'
            )
        info = yaml.safe_load(bag.custom_data.get('skynav_sim') or '{}') or {}
        world = info.get('world', Path(path).stem)
        labels = [f.get('label', 'all') for f in info.get('frames', [])]
        parts: dict[int, dict] = {}
        camera = None
        index = 0
        wanted = (*source.images, GROUND_TRUTH_MASK)
        for raw in bag.messages([*wanted, source.info]):
            message = bag.deserialize(raw)
            stamp = stamp_ns(message.header)
            if raw.topic == source.info:
                camera = EquidistantCamera.from_camera_info(message)
                continue
            decode = _DECODERS.get(raw.topic)
            parts.setdefault(stamp, {})[raw.topic] = (
                decode(message) if decode else image_to_array(message),
                getattr(message, 'encoding', LINEAR_ENCODING),
            )
            frame = parts[stamp]
            if len(frame) == len(wanted) and camera is not None:
                del parts[stamp]
                time = labels[index] if index < len(labels) and labels[index] in TIME_LABELS else 'all'
                index += 1
                yield _labelled(stamp, frame, camera, world, time)


def _labelled(stamp: int, frame: dict, camera: EquidistantCamera, world: str, time: str) -> LabelledFrame:
    """Return the labelled frame of one exposure's decoded topics (UV/green pair or colour frame, and truth)."""
    truth = frame.pop(GROUND_TRUTH_MASK)[0]
    if UV_IMAGE in frame:
        (uv, uv_encoding), (green, green_encoding) = frame[UV_IMAGE], frame[GREEN_IMAGE]
        return LabelledFrame(stamp, uv, green, (uv_encoding, green_encoding), truth, camera, world, time)
    rgb = next(iter(frame.values()))[0]
    encodings = (LINEAR_ENCODING, LINEAR_ENCODING)
    return LabelledFrame(stamp, rgb[..., 2], rgb[..., 1], encodings, truth, camera, world, time, rgb)


TIME_LABELS = ('dawn', 'sunrise', 'morning', 'forenoon', 'noon')
