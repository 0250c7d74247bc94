"""The views of a recording as the node graph sees them: SH coefficients of each exposure, with its ground truth.

For offline tools (map building, evaluations): the installed skyline and SH nodes run in this process
over the recording (the same code and parameters as `skynav run`), and each /skyline/sh output is
joined by stamp with the recording's UV image, ground-truth pose and frame label.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .camera import EquidistantCamera


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


@dataclass
class RecordingViews:
    """Every view of a recording, its camera, and what the recording says about itself."""

    path: Path
    views: list[View]
    camera: EquidistantCamera | None
    description: dict  # the skynav_sim metadata of a synthetic recording, {} otherwise

    @property
    def synthetic(self) -> bool:
        """Return whether the recording says it is synthetic."""
        return bool(self.description.get('synthetic'))


def recording_views(path: str | Path, ros_args: list[str] | None = None, images: bool = True,
                    progress=None, masks: bool = False) -> RecordingViews:
    """Run the skyline and SH nodes over a recording in this process and return its views in stamp order.

    `images` keeps each view's raw UV image, `masks` the skyline node's mask.
    """
    import yaml

    from skynav_core.bag import BagError, open_bag
    from skynav_core.graph import in_process
    from skynav_core.images import image_to_array, stamp_ns
    from skynav_core.nodes import installed_nodes

    specs = [s for s in installed_nodes() if s.name in ('skyline', 'sh')]
    if len(specs) != 2:
        raise RuntimeError('the skyline and sh nodes are not installed')
    path = Path(path)
    coefficients: dict[int, tuple[np.ndarray, int, float, str]] = {}
    node_masks: dict[int, np.ndarray] = {}
    with open_bag(path) as bag:
        needed = ['/camera/uv/image_raw', '/camera/uv/camera_info']
        if missing := [t for t in needed if t not in bag.topics]:
            raise BagError(f'{path}: no {", ".join(missing)}; the nodes need the camera topics')
        with in_process(specs, ros_args) as graph:
            graph.keep_outputs = True
            graph.run(bag, progress=progress)
            for output in graph.outputs:
                if masks and output.topic == '/skyline/mask':
                    node_masks[stamp_ns(output.message.header)] = image_to_array(output.message)
                if output.topic == '/skyline/sh':
                    message = output.message
                    coefficients[stamp_ns(message.header)] = (np.asarray(message.coefficients, np.float64),
                                                              int(message.max_degree),
                                                              float(message.field_of_view), str(message.fill))
        description = yaml.safe_load(bag.custom_data.get('skynav_sim') or '{}') or {}
        labels = [f.get('label', '') for f in description.get('frames', [])]
        topics = ['/camera/uv/camera_info'] + [t for t in ('/ground_truth/pose',) if t in bag.topics]
        if images:
            topics.append('/camera/uv/image_raw')
        camera, poses, uvs, order = None, {}, {}, []
        for raw in bag.messages(topics):
            message = bag.deserialize(raw)
            stamp = stamp_ns(message.header)
            if raw.topic == '/camera/uv/camera_info':  # one per exposure: the frame order of the recording
                camera = camera or EquidistantCamera.from_camera_info(message)
                order.append(stamp)
            elif raw.topic == '/ground_truth/pose':
                p, q = message.pose.position, message.pose.orientation
                poses[stamp] = np.array([p.x, p.y, p.z, q.x, q.y, q.z, q.w])
            else:
                uvs[stamp] = image_to_array(message)
    frame_index = {stamp: k for k, stamp in enumerate(sorted(set(order) | set(coefficients)))}
    views = [View(stamp, c, degree, uvs.get(stamp), poses.get(stamp),
                  labels[frame_index[stamp]] if frame_index[stamp] < len(labels) else '', node_masks.get(stamp),
                  field_of_view, fill)
             for stamp, (c, degree, field_of_view, fill) in sorted(coefficients.items())]
    return RecordingViews(path, views, camera, description)
