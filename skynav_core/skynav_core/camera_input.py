# SPDX-License-Identifier: Apache-2.0
"""Camera geometry for a node from /camera/uv/camera_info: the latest model, and inputs held until the first.

Logic only (no rclpy): the node passes in camera info messages and the inputs that need a camera.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from .camera import EquidistantCamera

if TYPE_CHECKING:
    from sensor_msgs.msg import CameraInfo

CAMERA_INFO_TOPIC = '/camera/uv/camera_info'
HELD_INPUTS = 30  # inputs that wait for the first camera info; older ones are dropped beyond this
HELD_AT_MOST_NS = 5_000_000_000  # an input waits at most this long for camera info (ns), then it is dropped


class CameraInput:
    """The camera model of the latest valid camera info, narrowed to a field-of-view limit."""

    def __init__(
        self,
        reject: Callable[[str, str], None],
        drop: Callable[[str, int, str], None],
        capacity: int = HELD_INPUTS,
        max_wait_ns: int = HELD_AT_MOST_NS,
    ) -> None:
        self.reject = reject
        self.drop = drop  # (cause, count, detail): inputs that were never processed
        self.camera: EquidistantCamera | None = None
        self.fov_limit = 2 * np.pi  # rad, full angle; a node parameter may narrow it
        self._held: deque[tuple[int, Any]] = deque()  # (time held since in ns, input)
        self._capacity = capacity
        self._max_wait_ns = max_wait_ns

    def update(self, info: CameraInfo) -> bool:
        """Take a camera info message; return whether the camera model changed."""
        try:
            camera = EquidistantCamera.from_camera_info(info).with_fov_limit(self.fov_limit)
        except ValueError as exc:
            self.reject('camera_info', f'camera info rejected: {exc}')
            return False
        if camera == self.camera:
            return False
        self.camera = camera
        return True

    def set_fov_limit(self, fov: float) -> None:
        """Narrow the field of view to `fov` (rad, full angle; 0 or less: the whole image circle)."""
        self.fov_limit = fov if fov > 0 else 2 * np.pi
        if self.camera is not None:
            self.camera = replace(self.camera, fov_limit=self.fov_limit)

    def hold(self, item: Any, now_ns: int) -> None:
        """Keep an input from `now_ns` until a camera is known; past capacity the oldest is dropped and counted."""
        self._held.append((now_ns, item))
        if len(self._held) > self._capacity:
            self._held.popleft()
            self.drop(
                'no_camera_info', 1, f'no camera info on {CAMERA_INFO_TOPIC} yet; the oldest waiting input was dropped'
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
            f'no camera info on {CAMERA_INFO_TOPIC} within {self._max_wait_ns / 1e9:g} s; the inputs waiting for it '
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

    def matches(self, shape: tuple[int, int]) -> bool:
        """Return whether an image of `shape` (height, width) fits the camera; reject it otherwise."""
        assert self.camera is not None  # callers hold their inputs until a camera is known
        if (self.camera.height, self.camera.width) != tuple(shape):
            self.reject(
                'camera_info_mismatch',
                f'image of {shape[1]}x{shape[0]} pixels, but the camera info '
                f'says {self.camera.width}x{self.camera.height}',
            )
            return False
        return True
