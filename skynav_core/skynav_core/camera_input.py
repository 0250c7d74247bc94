# SPDX-License-Identifier: Apache-2.0
"""Camera sources and geometry for a node: which camera it takes, its latest model, and inputs held until the first.

A robot carries the UV/green pair or one colour camera (docs/interfaces.md, "Cameras as robots have them"). A node
that reads camera frames takes one source: the one its `camera` parameter names, or (`auto`) the first that
delivers; frames of any other are counted and dropped. Its geometry comes from that source's camera info topic, or
from the file `camera_info_url` names when the driver's is missing or wrong.

Logic only (no rclpy): the node passes in camera info messages and the inputs that need a camera.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from .camera import EquidistantCamera
from .errors import SkynavError
from .names import COLOUR_CAMERA_INFO, COLOUR_COMPRESSED, COLOUR_IMAGE, GREEN_IMAGE, UV_CAMERA_INFO, UV_IMAGE
from .parameters import Parameter

if TYPE_CHECKING:
    from sensor_msgs.msg import CameraInfo

CAMERA_INFO_TOPIC = UV_CAMERA_INFO  # the UV/green pair's camera info (the source of the contract's first cameras)
HELD_INPUTS = 30  # inputs that wait for the first camera info; older ones are dropped beyond this
HELD_AT_MOST_NS = 5_000_000_000  # an input waits at most this long for camera info (ns), then it is dropped
AUTO = 'auto'  # the `camera` setting that takes the first source to deliver


@dataclass(frozen=True)
class CameraSource:
    """One kind of camera a robot carries: the topics of its frames and of its geometry."""

    name: str
    images: tuple[str, ...]  # every topic one exposure arrives on
    info: str  # its sensor_msgs/CameraInfo topic


#: The sources, in the order `auto` prefers them in a recording that holds several.
CAMERA_SOURCES: dict[str, CameraSource] = {
    source.name: source
    for source in (
        CameraSource('uv-green', (UV_IMAGE, GREEN_IMAGE), UV_CAMERA_INFO),
        CameraSource('colour', (COLOUR_IMAGE,), COLOUR_CAMERA_INFO),
        CameraSource('colour-compressed', (COLOUR_COMPRESSED,), COLOUR_CAMERA_INFO),
    )
}
#: Values of the `camera` parameter.
CAMERA_SETTINGS = (AUTO, *CAMERA_SOURCES)
#: Every camera info topic a node that needs geometry reads.
CAMERA_INFO_TOPICS = tuple(dict.fromkeys(source.info for source in CAMERA_SOURCES.values()))
#: Every topic of every camera source: frames and geometry.
CAMERA_TOPICS = tuple(dict.fromkeys(t for source in CAMERA_SOURCES.values() for t in (*source.images, source.info)))

#: The parameters of every node that needs camera geometry.
CAMERA_PARAMETERS = {
    'camera': Parameter(
        AUTO, f'camera source: {", ".join(CAMERA_SETTINGS)} (auto: the first that delivers; others are dropped)'
    ),
    'camera_info_url': Parameter(
        '', "camera geometry from this camera_info_manager YAML (file:///path/camera.yaml); empty: the topic's"
    ),
}


class CameraSourceError(SkynavError, ValueError):
    """A camera setting or geometry file a node cannot use."""


def recorded_source(topics: Iterable[str]) -> CameraSource | None:
    """Return the camera source whose frames a recording of `topics` holds (the first in CAMERA_SOURCES), or None."""
    present = set(topics)
    return next((s for s in CAMERA_SOURCES.values() if set(s.images) <= present), None)


class CameraInput:
    """The camera source a node takes and its geometry: the latest valid camera info, narrowed to a field of view."""

    def __init__(
        self,
        reject: Callable[[str, str], None],
        drop: Callable[[str, int, str], None],
        capacity: int = HELD_INPUTS,
        max_wait_ns: int = HELD_AT_MOST_NS,
    ) -> None:
        self.reject = reject
        self.drop = drop  # (cause, count, detail): inputs that were never processed
        self.setting = AUTO  # the `camera` parameter
        self.source: CameraSource | None = None  # the source taken (None: none yet, with `auto`)
        self.fov_limit = 2 * np.pi  # rad, full angle; a node parameter may narrow it
        self._cameras: dict[str, EquidistantCamera] = {}  # the latest camera of each camera info topic
        self._info_topic: str | None = None  # the camera info topic in use (None: none has delivered yet)
        self._fixed: EquidistantCamera | None = None  # from camera_info_url, over any topic
        self._held: deque[tuple[int, Any]] = deque()  # (time held since in ns, input)
        self._capacity = capacity
        self._max_wait_ns = max_wait_ns

    @property
    def camera(self) -> EquidistantCamera | None:
        """Return the camera model in use: camera_info_url's, else the source's camera info (None: not known yet)."""
        if self._fixed is not None:
            return self._fixed
        return None if self._info_topic is None else self._cameras.get(self._info_topic)

    @property
    def info_topic(self) -> str:
        """Return the camera info topic whose geometry is in use (or awaited), for messages."""
        return self._info_topic or (self.source.info if self.source else ' or '.join(CAMERA_INFO_TOPICS))

    def configure(self, setting: str, url: str, fov: float) -> None:
        """Take the `camera` setting, the camera_info_url (empty: none) and a field of view (rad, full; 0: all).

        CameraSourceError for an unknown setting, SkynavError for a geometry file that cannot be read.
        """
        if setting not in CAMERA_SETTINGS:
            raise CameraSourceError(f'camera must be one of {", ".join(CAMERA_SETTINGS)}, not {setting!r}')
        fixed = None
        if url:
            from .camera_yaml import camera_from_url  # noqa: PLC0415 (only nodes given a camera file read YAML)

            fixed = camera_from_url(url)
        self.fov_limit = fov if fov > 0 else 2 * np.pi
        self._fixed = None if fixed is None else fixed.with_fov_limit(self.fov_limit)
        self._cameras = {topic: replace(camera, fov_limit=self.fov_limit) for topic, camera in self._cameras.items()}
        if setting != self.setting:
            self.setting = setting
            self.source = CAMERA_SOURCES.get(setting)
            self._info_topic = None if self.source is None else self.source.info

    def admits(self, source: str) -> bool:
        """Return whether a frame of camera source `source` is taken; count and drop it otherwise.

        The configured source is taken; with `auto` the first source to deliver a frame is, from then on.
        """
        if self.source is None:
            self.source = CAMERA_SOURCES[source]
            self._info_topic = self.source.info
        if self.source.name == source:
            return True
        self.drop(
            'other_camera',
            1,
            f'a frame of the {source} camera, but the node takes the {self.source.name} camera '
            f'(parameter camera = {self.setting})',
        )
        return False

    def update(self, info: CameraInfo, topic: str = CAMERA_INFO_TOPIC) -> bool:
        """Take a camera info message of `topic`; return whether the camera model in use changed."""
        try:
            camera = EquidistantCamera.from_camera_info(info).with_fov_limit(self.fov_limit)
        except ValueError as exc:
            self.reject('camera_info', f'camera info on {topic} rejected: {exc}')
            return False
        before = self.camera
        self._cameras[topic] = camera
        if self._info_topic is None and (self.source is None or self.source.info == topic):
            self._info_topic = topic  # a node without frames of its own (sh) takes the first geometry to come
        return self.camera != before

    def hold(self, item: Any, now_ns: int) -> None:
        """Keep an input from `now_ns` until a camera is known; past capacity the oldest is dropped and counted."""
        self._held.append((now_ns, item))
        if len(self._held) > self._capacity:
            self._held.popleft()
            self.drop(
                'no_camera_info', 1, f'no camera info on {self.info_topic} yet; the oldest waiting input was dropped'
            )

    def expire(self, now_ns: int) -> None:
        """Drop (and count) the inputs that have waited for camera info longer than allowed at `now_ns`."""
        expired = 0
        while self._held and now_ns - self._held[0][0] > self._max_wait_ns:
            self._held.popleft()
            expired += 1
        self.drop(
            'no_camera_info',
            expired,
            f'no camera info on {self.info_topic} within {self._max_wait_ns / 1e9:g} s; the inputs waiting for it '
            'were dropped',
        )

    def forget(self, cause: str) -> None:
        """Drop (and count under `cause`) every input held."""
        self.drop(cause, len(self._held), f'{len(self._held)} inputs waiting for camera info were forgotten')
        self._held.clear()

    @property
    def held(self) -> int:
        """Return the number of inputs waiting for camera info."""
        return len(self._held)

    def release(self) -> list[Any]:
        """Return (and forget) the inputs held so far, oldest first."""
        held = [item for _, item in self._held]
        self._held.clear()
        return held

    def matches(self, shape: tuple[int, ...]) -> bool:
        """Return whether an image of `shape` (height, width, ...) fits the camera; reject it otherwise.

        A node without a source of its own (`auto`, no frames: the SH node) moves to another camera info topic
        whose camera has the image's size.
        """
        camera = self.camera
        assert camera is not None  # callers hold their inputs until a camera is known
        size = tuple(shape[:2])
        if (camera.height, camera.width) == size:
            return True
        if self._fixed is None and self.source is None:
            fitting = [t for t, c in self._cameras.items() if (c.height, c.width) == size]
            if fitting:
                self._info_topic = fitting[0]
                return True
        self.reject(
            'camera_info_mismatch',
            f'image of {size[1]}x{size[0]} pixels, but the camera info says {camera.width}x{camera.height}',
        )
        return False
