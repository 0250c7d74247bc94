# SPDX-License-Identifier: Apache-2.0
"""The overlay image on scripted frames, no ROS: the mask edge, the image circle and the home vector in place."""

import cv2
import numpy as np

from skynav_core.camera import EquidistantCamera
from skynav_viz import overlay

CAMERA = EquidistantCamera.for_field_of_view(96, 80, np.deg2rad(180.0))


def half_sky() -> np.ndarray:
    """Return a mask of sky above row 40 (inside the image circle), ground below and outside."""
    mask = np.zeros((80, 96), np.uint8)
    mask[:40] = 255
    mask[~CAMERA.image_circle()] = 0
    return mask


def is_colour(pixel: np.ndarray, colour: tuple[int, int, int], tolerance: int = 60) -> bool:
    """Return whether a BGR pixel is near `colour` (the lines are antialiased)."""
    return bool(np.all(np.abs(pixel.astype(int) - np.array(colour)) <= tolerance))


def test_the_mask_edge_is_drawn_along_the_skyline_and_not_along_the_image_circle():
    uv = np.full((80, 96), 0.5, np.float32)
    image = overlay.draw(uv, half_sky(), overlay.Overlay(CAMERA))
    edge = np.all(image == overlay.EDGE_COLOUR, axis=2)
    rows, columns = np.nonzero(edge)
    assert rows.size > 20 and set(rows) <= {39, 40}  # the sky/ground border only
    assert columns.min() > 10 and columns.max() < 85  # within the circle, not along its rim


def test_the_image_circle_and_the_home_vector_are_drawn_where_the_camera_sees_them():
    uv = np.zeros((80, 96), np.uint8)
    view = overlay.Overlay(CAMERA)
    left = np.array([0.0, 1.0, 0.0])  # robot-left is image-down (docs/interfaces.md, "Camera model")
    image = overlay.draw(uv, np.zeros_like(uv), view, left)
    a, b = view.circle_axes
    cx, cy = view.centre
    assert is_colour(image[cy, cx + a], overlay.CIRCLE_COLOUR) and is_colour(image[cy - b, cx], overlay.CIRCLE_COLOUR)
    red = np.all(image == overlay.HOME_COLOUR, axis=2)
    rows, columns = np.nonzero(red)
    assert rows.size > 10 and rows.min() >= cy - 1 and rows.max() > cy + 0.7 * b  # downwards from the centre
    assert np.all(np.abs(columns - cx) <= 3)
    assert view.home_tip(np.array([0.0, 0.0, 1.0])) is None  # straight up: no azimuth, no arrow


def test_without_a_camera_only_the_edge_is_drawn_and_a_mask_of_another_size_is_left_out():
    uv = np.zeros((80, 96), np.uint16)
    image = overlay.draw(uv, half_sky(), None, np.array([1.0, 0.0, 0.0]))
    assert np.all(image == overlay.EDGE_COLOUR, axis=2).any()
    assert not np.all(image == overlay.HOME_COLOUR, axis=2).any()
    assert not overlay.draw(uv, np.zeros((10, 10), np.uint8), None).any()


def test_uv_of_any_encoding_is_scaled_to_8_bits_by_its_brightest_pixel():
    for pixels in (np.array([[0, 1000, 4000]], np.uint16), np.array([[0.0, 0.25, 1.0]], np.float32)):
        grey = overlay.to_bgr8(pixels)[..., 0]
        assert grey[0, 0] == 0 and grey[0, 2] == 255 and 60 <= grey[0, 1] <= 65
    assert not overlay.to_bgr8(np.array([[np.nan, -1.0]], np.float32)).any()  # nothing bright: black


def test_the_jpeg_decodes_to_the_drawn_image():
    ramp = overlay.draw(np.tile(np.arange(96, dtype=np.uint8), (80, 1)), None, None)
    decoded = cv2.imdecode(np.frombuffer(overlay.jpeg(ramp, 95), np.uint8), cv2.IMREAD_COLOR)
    assert decoded.shape == ramp.shape
    assert np.abs(decoded.astype(int) - ramp.astype(int)).max() <= 3
    drawn = overlay.draw(np.zeros((80, 96), np.uint8), half_sky(), overlay.Overlay(CAMERA))
    decoded = cv2.imdecode(np.frombuffer(overlay.jpeg(drawn, 95), np.uint8), cv2.IMREAD_COLOR)
    blue, green, red = (int(v) for v in decoded[40, 48])  # yellow on the edge (JPEG halves the colour resolution)
    assert green > 200 and red > 200 and blue < 150
    assert is_colour(decoded[20, 48], (0, 0, 0), 30)
