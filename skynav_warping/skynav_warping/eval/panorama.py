# SPDX-License-Identifier: Apache-2.0
"""Panoramic images unwrapped from the fish-eye view: an azimuth x elevation band around the horizon (camera_link).

Column j holds azimuth phi_j = 2 pi j / n_azimuth (from +x, robot-forward, towards +y, robot-left); row 0 holds the
highest elevation and the last row the lowest (elevation = 90 degrees - theta, so 0 is the camera's horizontal
plane, positive above it). Every cell is the mean of k x k sub-samples spread over its azimuth x elevation extent,
each read from the fish-eye image by bilinear interpolation (cv2.remap): an area average, not a point sample.
The planar warping baselines read these images.
"""

from __future__ import annotations

import cv2
import numpy as np

from skynav_core.camera import directions_from_angles
from skynav_sh.fisheye import camera_image_values
from skynav_warping.errors import WarpingError

DEFAULT_ELEVATIONS = (np.radians(-10.0), np.radians(40.0))  # rad, lowest and highest elevation of the band


class PanoramaUnwrapper:
    """Fish-eye image (H, W) -> panoramic band (n_elevation, n_azimuth); remap tables built once per camera."""

    def __init__(
        self,
        camera,
        n_azimuth: int = 72,
        n_elevation: int = 25,
        elevations: tuple[float, float] = DEFAULT_ELEVATIONS,
        supersampling: int = 3,
    ) -> None:
        """Precompute the remap tables of a band from elevations[0] to elevations[1] (rad) for a skynav_sh camera."""

        low, high = float(elevations[0]), float(elevations[1])
        if not low < high:
            raise WarpingError('the elevation band needs low < high')
        if np.pi / 2 - low > camera.theta_max + 1e-9:
            raise WarpingError(
                f'elevation {np.degrees(low):.1f} deg lies outside the image circle '
                f'(lowest seen: {np.degrees(np.pi / 2 - camera.theta_max):.1f} deg)'
            )
        self.camera = camera
        self.n_azimuth, self.n_elevation, self.supersampling = int(n_azimuth), int(n_elevation), int(supersampling)
        self.azimuths = 2 * np.pi * np.arange(self.n_azimuth) / self.n_azimuth  # rad, column centres
        step = (high - low) / self.n_elevation
        self.elevations = high - step * (np.arange(self.n_elevation) + 0.5)  # rad, row centres, descending
        k = self.supersampling
        offsets = (np.arange(k) + 0.5) / k - 0.5
        sub_elevation = (self.elevations[:, None] - offsets[None, :] * step).reshape(-1)
        sub_azimuth = (self.azimuths[:, None] + offsets[None, :] * (2 * np.pi / self.n_azimuth)).reshape(-1)
        directions = directions_from_angles(np.pi / 2 - sub_elevation[:, None], sub_azimuth[None, :])
        pixels = camera.project(directions).astype(np.float32)
        self._map_fixed, self._map_fraction = cv2.convertMaps(pixels[..., 0], pixels[..., 1], cv2.CV_16SC2)

    def directions(self) -> np.ndarray:
        """Return the unit direction (camera_link) of every cell centre, (n_elevation, n_azimuth, 3)."""
        return directions_from_angles(np.pi / 2 - self.elevations[:, None], self.azimuths[None, :])

    def unwrap(self, image: np.ndarray) -> np.ndarray:
        """Return the panoramic band (n_elevation, n_azimuth) float32 of an image or mask (uint8 / max, bool 0/1)."""

        values = camera_image_values(image, self.camera)
        sub = cv2.remap(values, self._map_fixed, self._map_fraction, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        if self.supersampling == 1:
            return sub
        return cv2.resize(sub, (self.n_azimuth, self.n_elevation), interpolation=cv2.INTER_AREA)

    __call__ = unwrap
