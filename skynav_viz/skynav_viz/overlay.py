# SPDX-License-Identifier: Apache-2.0
"""The overlay image of a camera frame: the UV input with the skyline mask's edge, the image circle, the home vector.

The UV image (any encoding of the contract) is scaled to 8 bits by its brightest pixel; the mask's edge (the
pixels where sky meets ground inside the image circle) is drawn in yellow, the image circle in blue, and the home
vector as a red arrow from the principal point (the zenith) towards its azimuth, ending at HOME_ARROW_REACH of the
image circle's radius. Images are BGR (OpenCV's order) until encoded as JPEG. Logic only (no rclpy).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from skynav_core.camera import EquidistantCamera, directions_from_angles
from skynav_core.colour import LINEAR_FULL_SCALE, linear_to_srgb8

EDGE_COLOUR = (0, 255, 255)  # BGR: yellow, the mask's edge
CIRCLE_COLOUR = (255, 160, 0)  # BGR: blue, the image circle
HOME_COLOUR = (0, 0, 255)  # BGR: red, the home vector
TEXT_COLOUR = (255, 255, 255)
HOME_ARROW_REACH = 0.9  # the home arrow's length as a share of the image circle's radius
EDGE_INSET_PX = 2  # the mask's edge is drawn this far inside the image circle only (the circle has its own line)
LINE_PX = 2  # width of the drawn lines (pixels)


@dataclass(frozen=True)
class Overlay:
    """What is drawn on every frame of one camera: its image circle, and where its mask's edge may lie."""

    camera: EquidistantCamera

    @cached_property
    def edge_area(self) -> np.ndarray:
        """Return a (height, width) bool mask of the pixels EDGE_INSET_PX inside the image circle."""
        inside = self.camera.image_circle().astype(np.uint8)
        kernel = np.ones((2 * EDGE_INSET_PX + 1, 2 * EDGE_INSET_PX + 1), np.uint8)
        return cv2.erode(inside, kernel).astype(bool)

    @cached_property
    def circle_axes(self) -> tuple[int, int]:
        """Return the image circle's half axes (u, v) in pixels."""
        theta_d = float(self.camera.distort(np.array(self.camera.theta_max)))
        return round(self.camera.fx * theta_d), round(self.camera.fy * theta_d)

    @property
    def centre(self) -> tuple[int, int]:
        """Return the principal point (u, v), rounded to pixels: where the zenith is seen."""
        return round(self.camera.cx), round(self.camera.cy)

    def home_tip(self, direction: np.ndarray) -> tuple[int, int] | None:
        """Return the pixel the home arrow ends at for a home vector in camera_link; None if it has no azimuth."""
        x, y = float(direction[0]), float(direction[1])
        if not np.isfinite(x + y) or np.hypot(x, y) == 0:
            return None
        theta = np.array(HOME_ARROW_REACH * self.camera.theta_max)
        tip = self.camera.project(directions_from_angles(theta, np.array(np.arctan2(y, x))))
        return round(float(tip[0])), round(float(tip[1]))


def to_bgr8(pixels: np.ndarray) -> np.ndarray:
    """Return an image as 8-bit BGR: a single channel (uint8, uint16 or float radiance) scaled by its brightest
    pixel, a colour frame (uint16 linear RGB, skynav_core.colour) sRGB-encoded as the camera delivered it."""
    if pixels.ndim == 3:
        return cv2.cvtColor(linear_to_srgb8(pixels / np.float32(LINEAR_FULL_SCALE)), cv2.COLOR_RGB2BGR)
    if pixels.dtype == np.uint8:
        grey = pixels
    else:
        values = np.nan_to_num(pixels.astype(np.float32, copy=False), nan=0.0, posinf=0.0, neginf=0.0)
        top = float(values.max(initial=0.0))
        grey = (
            (np.clip(values, 0.0, None) * (255.0 / top)).astype(np.uint8)
            if top > 0
            else np.zeros_like(values, np.uint8)
        )
    return cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)


def mask_edge(mask: np.ndarray) -> np.ndarray:
    """Return a bool mask of the pixels on the border between sky (non-zero) and ground (0) of a skyline mask."""
    sky = (mask > 0).astype(np.uint8)
    return cv2.morphologyEx(sky, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)).astype(bool)


def draw(
    uv: np.ndarray,
    mask: np.ndarray | None,
    overlay: Overlay | None,
    home: np.ndarray | None = None,
    label: str = '',
) -> np.ndarray:
    """Return the overlay image (BGR, uint8) of a frame: its image, the mask's edge, the image circle, the home vector.

    Without a camera (`overlay` None) only the mask's edge is drawn; a mask of another size than the image is left
    out; `home` is the home vector in camera_link; `label` is written in the top left corner.
    """
    image = to_bgr8(uv)
    if mask is not None and mask.shape == uv.shape[:2]:
        edge = mask_edge(mask)
        if overlay is not None and overlay.edge_area.shape == edge.shape:
            edge &= overlay.edge_area
        image[edge] = EDGE_COLOUR
    if overlay is not None and (overlay.camera.height, overlay.camera.width) == uv.shape[:2]:
        cv2.ellipse(image, overlay.centre, overlay.circle_axes, 0.0, 0.0, 360.0, CIRCLE_COLOUR, LINE_PX, cv2.LINE_AA)
        tip = overlay.home_tip(home) if home is not None else None
        if tip is not None:
            cv2.arrowedLine(image, overlay.centre, tip, HOME_COLOUR, LINE_PX, cv2.LINE_AA, tipLength=0.08)
    if label:
        cv2.putText(image, label, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, TEXT_COLOUR, 1, cv2.LINE_AA)
    return image


def jpeg(image: np.ndarray, quality: int) -> bytes:
    """Return an image (BGR, uint8) encoded as JPEG of `quality` (1..100)."""
    ok, data = cv2.imencode('.jpg', image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # OpenCV fails only on an empty image, which draw() never returns
        raise ValueError('the overlay image could not be encoded')
    return data.tobytes()
