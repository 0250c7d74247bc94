# SPDX-License-Identifier: Apache-2.0
"""The views of a recording as the node graph sees them: SH coefficients of each exposure, with its ground truth.

For offline tools (map building, evaluations): the installed skyline and SH nodes run in this process
over the recording (the same code and parameters as `skynav run`), and each /skyline/sh output is
joined by stamp with the recording's UV image (a colour camera's blue plane stands in for it), ground-truth
pose and frame label. recorded_frames reads what a recording holds per exposure (camera, ground-truth poses,
images) for the readers of data sets; a colour camera's frames come as linear RGB (skynav_core.colour).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from skynav_core.recording.bag import BagError, open_bag

from .camera import EquidistantCamera
from .camera_input import CAMERA_INFO_TOPICS, recorded_source
from .colour import decode_compressed, decode_image
from .images import DTYPES, image_to_array, stamp_ns
from .names import (
    COLOUR_COMPRESSED,
    COLOUR_IMAGE,
    GROUND_TRUTH_POSE,
    SH_NODE,
    SKYLINE_MASK,
    SKYLINE_NODE,
    SKYLINE_SH,
    UV_IMAGE,
)


@dataclass
class View:
    """One exposure as the graph saw it."""

    stamp: int  # ns
    coefficients: np.ndarray  # real SH, (L+1)^2
    max_degree: int
    uv: np.ndarray | None  # the raw UV image, when asked for
    pose: np.ndarray | None  # (x, y, z, qx, qy, qz, qw) of camera_link in map, when the recording has one
    label: str  # the frame's label in a synthetic recording ('' otherwise)
    mask: np.ndarray | None = None  # the skyline node's mask (uint8, 255 sky), when asked for
    field_of_view: float = 0.0  # rad, full opening angle the coefficients describe (as /skyline/sh carries it)
    fill: str = 'zero'  # how the SH node filled what the camera does not see


class Described:
    """What a recording says about itself: `description`, the skynav_sim metadata of a synthetic one ({} otherwise)."""

    description: dict

    @property
    def synthetic(self) -> bool:
        """Return whether the recording says it is synthetic."""
        return bool(self.description.get('synthetic'))

    def labels(self) -> list[str]:
        """Return the frame labels of the recording's metadata, in frame order ('' where a frame has none)."""
        return [f.get('label', '') for f in self.description.get('frames', [])]


@dataclass
class RecordingViews(Described):
    """Every view of a recording, its camera, and what the recording says about itself."""

    path: Path
    views: list[View]
    camera: EquidistantCamera | None
    description: dict  # the skynav_sim metadata of a synthetic recording, {} otherwise


@dataclass
class RecordedFrames(Described):
    """What a recording holds per exposure, by stamp (ns): its camera, ground-truth poses and images."""

    camera: EquidistantCamera | None  # of the first camera info
    stamps: list[int]  # of the camera infos: one per exposure, in the recording's order
    poses: dict[int, np.ndarray]  # (x, y, z, qx, qy, qz, qw) of camera_link in map
    images: dict[str, dict[int, np.ndarray]]  # topic -> stamp -> pixels (H, W) in the encoding's dtype
    description: dict  # the skynav_sim metadata of a synthetic recording, {} otherwise


def recorded_frames(
    bag: Any, image_topics: Sequence[str] = (), encodings: tuple[str, ...] = tuple(DTYPES)
) -> RecordedFrames:
    """Return the camera, ground-truth poses and images of `image_topics` of an open recording (recording.bag).

    Topics the recording lacks are left out (their tables empty); an image in another encoding is an ImageError.
    The camera and the frame order come from the camera info of the recording's camera source; the colour
    camera's topics give uint16 (H, W, 3) linear RGB.
    """
    frames = RecordedFrames(
        None,
        [],
        {},
        {topic: {} for topic in image_topics},
        yaml.safe_load(bag.custom_data.get('skynav_sim') or '{}') or {},
    )
    source = recorded_source(bag.topics)
    info_topic = source.info if source else next((t for t in CAMERA_INFO_TOPICS if t in bag.topics), None)
    wanted = [t for t in (info_topic, GROUND_TRUTH_POSE, *image_topics) if t in bag.topics]
    decoders = {COLOUR_IMAGE: decode_image, COLOUR_COMPRESSED: decode_compressed}
    for raw in bag.messages(wanted):
        message = bag.deserialize(raw)
        stamp = stamp_ns(message.header)
        if raw.topic == info_topic:  # one per exposure: the frame order of the recording
            frames.camera = frames.camera or EquidistantCamera.from_camera_info(message)
            frames.stamps.append(stamp)
        elif raw.topic == GROUND_TRUTH_POSE:
            p, q = message.pose.position, message.pose.orientation
            frames.poses[stamp] = np.array([p.x, p.y, p.z, q.x, q.y, q.z, q.w])
        elif raw.topic in decoders:
            frames.images[raw.topic][stamp] = decoders[raw.topic](message)
        else:
            frames.images[raw.topic][stamp] = image_to_array(message, encodings)
    return frames


def recording_views(
    path: str | Path, ros_args: list[str] | None = None, images: bool = True, progress=None, masks: bool = False
) -> RecordingViews:
    """Run the skyline and SH nodes over a recording in this process and return its views in stamp order.

    `images` keeps each view's raw UV image (a colour camera's linear blue plane), `masks` the skyline node's mask.
    """
    from skynav_core.graph import in_process  # noqa: PLC0415 (the graph loads rclpy; callers that only read views need no ROS)
    from skynav_core.nodes import installed_nodes  # noqa: PLC0415 (node discovery reads the ament index; only a run of the graph needs it)

    specs = [s for s in installed_nodes() if s.name in (SKYLINE_NODE, SH_NODE)]
    if len(specs) != 2:
        raise RuntimeError('the skyline and sh nodes are not installed')
    path = Path(path)
    coefficients: dict[int, tuple[np.ndarray, int, float, str]] = {}
    node_masks: dict[int, np.ndarray] = {}
    with open_bag(path) as bag:
        source = recorded_source(bag.topics)
        if source is None or source.info not in bag.topics:
            raise BagError(f'{path}: no camera frames with their camera info; the nodes need the camera topics')
        image_topic = source.images[0]
        with in_process(specs, ros_args) as graph:
            graph.keep_outputs = True
            graph.run(bag, progress=progress)
            for output in graph.outputs:
                if masks and output.topic == SKYLINE_MASK:
                    node_masks[stamp_ns(output.message.header)] = image_to_array(output.message)
                if output.topic == SKYLINE_SH:
                    message = output.message
                    coefficients[stamp_ns(message.header)] = (
                        np.asarray(message.coefficients, np.float64),
                        int(message.max_degree),
                        float(message.field_of_view),
                        str(message.fill),
                    )
        recorded = recorded_frames(bag, [image_topic] if images else [])
    labels, uvs = recorded.labels(), recorded.images.get(image_topic, {})
    if image_topic != UV_IMAGE:
        uvs = {stamp: rgb[..., 2] for stamp, rgb in uvs.items()}  # blue stands in for UV
    frame_index = {stamp: k for k, stamp in enumerate(sorted(set(recorded.stamps) | set(coefficients)))}
    views = [
        View(
            stamp,
            c,
            degree,
            uvs.get(stamp),
            recorded.poses.get(stamp),
            labels[frame_index[stamp]] if frame_index[stamp] < len(labels) else '',
            node_masks.get(stamp),
            field_of_view,
            fill,
        )
        for stamp, (c, degree, field_of_view, fill) in sorted(coefficients.items())
    ]
    return RecordingViews(path, views, recorded.camera, recorded.description)
