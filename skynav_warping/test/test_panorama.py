# SPDX-License-Identifier: Apache-2.0
"""Unwrapping the fish-eye view into a panoramic band: azimuth and elevation land where docs/interfaces.md says."""

from __future__ import annotations

import numpy as np
import pytest

from skynav_core.camera import EquidistantCamera, angles_from_directions
from skynav_warping import PanoramaUnwrapper

CAMERA = EquidistantCamera.for_field_of_view(320, 240, np.radians(200))


def painted(condition) -> np.ndarray:
    """Return a float image: 1 where condition(theta, phi) holds for the pixel's direction, else 0."""
    theta, phi = angles_from_directions(CAMERA.pixel_directions())
    return condition(theta, np.remainder(phi, 2 * np.pi)).astype(np.float32) * CAMERA.image_circle()


def test_columns_are_azimuths_and_rows_elevations():
    unwrapper = PanoramaUnwrapper(CAMERA, n_azimuth=72, n_elevation=25)
    # a patch from azimuth 90 to 135 degrees (robot-left: image down) and elevation 10 to 30 degrees
    image = painted(
        lambda theta, phi: (
            (phi > np.radians(90)) & (phi < np.radians(135)) & (theta > np.radians(60)) & (theta < np.radians(80))
        )
    )
    band = unwrapper(image)
    columns = np.flatnonzero(band.max(axis=0) > 0.9)
    # 5-degree columns centred on 95 .. 130 degrees are inside; those centred on the patch's edges (90 and 135
    # degrees) see half of it (area averaging)
    assert columns.min() == 19 and columns.max() == 26
    assert 0.3 < band[:, 18].max() < 0.7 and 0.3 < band[:, 27].max() < 0.7
    rows = np.flatnonzero(band.max(axis=1) > 0.5)
    np.testing.assert_array_less(np.radians(9.0), unwrapper.elevations[rows])
    np.testing.assert_array_less(unwrapper.elevations[rows], np.radians(31.0))
    assert unwrapper.elevations[0] > unwrapper.elevations[-1]  # row 0 is the top of the band
    # robot-left (+y, azimuth 90 degrees) is image-down in camera_link's optical convention
    u, v = CAMERA.project(np.array([0.0, 1.0, 0.0]))
    assert v > CAMERA.cy and abs(u - CAMERA.cx) < 1e-9


def test_band_must_lie_inside_the_image_circle():
    with pytest.raises(ValueError):
        PanoramaUnwrapper(EquidistantCamera.for_field_of_view(320, 240, np.radians(170)))
