# SPDX-License-Identifier: Apache-2.0
"""Per-camera precomputation: the image circle, its rim, the azimuth sectors and the rays around the principal point.

Sector k of n covers the azimuth phi = atan2(v - cy, u - cx) in
[-pi + k w, -pi + (k + 1) w) with w = 2 pi / n; its centre is at -pi + (k + 1/2) w.
A per-pixel threshold is interpolated linearly in azimuth between the two
nearest sector centres (circularly), so the skyline has no seams at sector borders.
Ray k of n runs outwards from the principal point along sector k's centre, sampled
at a fixed spacing; a pixel belongs to the ray of its sector.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from skynav_skyline.errors import SkylineError

if TYPE_CHECKING:
    from skynav_core.camera import EquidistantCamera


@dataclass(frozen=True)
class SectorLayout:
    """Azimuth sectors of one image geometry: membership and interpolation weights of every pixel."""

    count: int  # number of sectors
    index: np.ndarray  # int (H, W): the sector each pixel belongs to
    lower: np.ndarray  # int (H, W): the sector centre at or before the pixel's azimuth
    upper: np.ndarray  # int (H, W): the next sector centre, (lower + 1) mod count
    weight: np.ndarray  # float32 (H, W): interpolation weight of `upper`, in [0, 1)
    centres: np.ndarray  # (count,) azimuth of each sector centre (rad)

    def sampled(self, stride: int) -> SectorLayout:
        """Return the layout of every stride-th pixel of each row (for statistics of a sample)."""
        if stride == 1:
            return self
        every = (slice(None), slice(None, None, stride))
        return SectorLayout(
            self.count, self.index[every], self.lower[every], self.upper[every], self.weight[every], self.centres
        )

    def interpolate(self, per_sector: np.ndarray, pixels: np.ndarray | None = None) -> np.ndarray:
        """Return values interpolated linearly in azimuth from one value per sector: a map (H, W) or at `pixels`."""
        values = np.asarray(per_sector, np.float64)
        if values.shape != (self.count,):
            raise SkylineError(f'expected {self.count} sector values, got shape {values.shape}')
        low = values.astype(np.float32)
        step = (np.roll(values, -1) - values).astype(np.float32)  # from each centre to the next
        lower, weight = self.lower, self.weight
        if pixels is not None:
            lower, weight = lower.reshape(-1)[pixels], weight.reshape(-1)[pixels]
        return low.take(lower) + step.take(lower) * weight


@dataclass(frozen=True)
class RayLayout:
    """Rays outwards from the principal point: where to sample the image along each, `spacing` pixels apart."""

    count: int  # rays; ray k runs along the centre of sector k of `count`
    spacing: float  # pixels between samples along a ray
    map_u: np.ndarray  # float32 (count, steps): pixel column of sample j of ray k, at j * spacing from the centre
    map_v: np.ndarray  # float32 (count, steps): its pixel row
    pixels_per_radian: float  # radial scale of the image (pixels per radian of off-axis angle) near the rim

    @property
    def samples_per_radian(self) -> float:
        """Return the samples per radian of off-axis angle along a ray."""
        return self.pixels_per_radian / self.spacing


@dataclass
class SkylineGeometry:
    """The image circle and principal point of one camera, with sector layouts built once per sector count."""

    circle: np.ndarray  # bool (H, W): pixels inside the image circle
    centre: tuple[float, float]  # principal point (cx, cy) in pixels
    phi: np.ndarray | None = field(default=None, repr=False, compare=False)  # azimuths, if not from (u, v)
    rho: np.ndarray | None = field(default=None, repr=False, compare=False)  # distances from the centre, likewise
    pixels_per_radian: float | None = None  # radial scale near the rim (from the camera model; None: unknown)
    _layouts: dict[int, SectorLayout] = field(default_factory=dict, repr=False, compare=False)
    _rays: dict[tuple[int, float], RayLayout] = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        """Check the mask (ValueError) and store it as bool."""
        self.circle = np.asarray(self.circle).astype(bool, copy=False)
        if self.circle.ndim != 2:
            raise SkylineError(f'image circle mask must be 2-D, got shape {self.circle.shape}')
        if not self.circle.any():
            raise SkylineError('image circle mask is empty')
        self.centre = (float(self.centre[0]), float(self.centre[1]))

    @property
    def shape(self) -> tuple[int, int]:
        """Return the image shape (rows, columns)."""
        return self.circle.shape

    @classmethod
    def from_camera(cls, camera: EquidistantCamera) -> SkylineGeometry:
        """Return the geometry of a camera model with `image_circle()`, `cx`, `cy`, `theta_max` and `project`.

        The radial scale is the image circle's radius over its off-axis angle (pixels per radian).
        """
        theta_max = float(camera.theta_max)
        rim = np.asarray(camera.project(np.array([[np.sin(theta_max), 0.0, np.cos(theta_max)]])), float)[0]
        radius = float(np.hypot(rim[0] - camera.cx, rim[1] - camera.cy))
        scale = radius / theta_max if theta_max > 0 and radius > 0 else None
        return cls(camera.image_circle(), (camera.cx, camera.cy), pixels_per_radian=scale)

    @classmethod
    def from_circle(cls, circle: np.ndarray) -> SkylineGeometry:
        """Return the geometry of a bare image-circle mask; its centroid (pixels) stands in for the principal point."""
        circle = np.asarray(circle).astype(bool, copy=False)
        if circle.ndim != 2 or not circle.any():
            raise SkylineError('image circle mask must be a non-empty 2-D array')
        rows, cols = np.nonzero(circle)
        return cls(circle, (float(cols.mean()), float(rows.mean())))

    def azimuth(self) -> np.ndarray:
        """Return the azimuth phi = atan2(v - cy, u - cx) (rad, in (-pi, pi]) of every pixel centre."""
        if self.phi is not None:
            return self.phi
        v, u = np.mgrid[0 : self.shape[0], 0 : self.shape[1]]
        return np.arctan2(v - self.centre[1], u - self.centre[0])

    def radius(self) -> np.ndarray:
        """Return the distance (pixels) of every pixel centre from the principal point."""
        if self.rho is not None:
            return self.rho
        v, u = np.mgrid[0 : self.shape[0], 0 : self.shape[1]]
        return np.hypot(u - self.centre[0], v - self.centre[1])

    def packed(self) -> tuple[SkylineGeometry, np.ndarray]:
        """Return the geometry of the circle's pixels alone, as one row, and their flat indices in the image.

        Segmenting that row and scattering it back gives the same mask as segmenting the image,
        with the work of the pixels outside the circle saved.
        """
        pixels = np.flatnonzero(self.circle)
        row = SkylineGeometry(
            np.ones((1, pixels.size), bool),
            self.centre,
            self.azimuth().ravel()[pixels][None],
            self.radius().ravel()[pixels][None],
            self.pixels_per_radian,
        )
        return row, pixels

    def rim(self) -> np.ndarray:
        """Return the flat indices of the circle's pixels on its edge: a 4-neighbour outside it or off the image."""
        padded = np.pad(self.circle, 1, constant_values=False)
        inner = padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:]
        return np.flatnonzero(self.circle & ~inner)

    def rays(self, count: int, step: float) -> RayLayout:
        """Return (and cache) `count` rays from the principal point to the farthest pixel of the circle.

        Samples lie `step` radians of off-axis angle apart, but at least one pixel. Needs the
        radial scale of a camera model (ValueError for a bare image-circle mask).
        """
        count = int(count)
        if count < 1:
            raise SkylineError(f'number of rays must be at least 1, got {count}')
        if not step > 0:
            raise SkylineError(f'ray sample step must be positive, got {step}')
        if self.pixels_per_radian is None:
            raise SkylineError('rays need the camera model (its radial scale), not a bare image-circle mask')
        key = (count, float(step))
        if key not in self._rays:
            spacing = max(1.0, float(step) * self.pixels_per_radian)
            steps = int(np.ceil(float(self.radius()[self.circle].max()) / spacing)) + 1
            angle = -np.pi + (np.arange(count) + 0.5) * (2 * np.pi / count)
            reach = spacing * np.arange(steps, dtype=np.float64)
            map_u = (self.centre[0] + np.cos(angle)[:, None] * reach).astype(np.float32)
            map_v = (self.centre[1] + np.sin(angle)[:, None] * reach).astype(np.float32)
            self._rays[key] = RayLayout(count, spacing, map_u, map_v, float(self.pixels_per_radian))
        return self._rays[key]

    def sectors(self, count: int) -> SectorLayout:
        """Return (and cache) the layout of `count` equal azimuth sectors."""
        count = int(count)
        if count < 1:
            raise SkylineError(f'number of sectors must be at least 1, got {count}')
        if count not in self._layouts:
            self._layouts[count] = _layout(self.azimuth(), count)
        return self._layouts[count]


def _layout(phi: np.ndarray, count: int) -> SectorLayout:
    """Return the sector layout of pixel azimuths `phi` (rad) for `count` sectors."""
    width = 2 * np.pi / count
    position = (phi + np.pi) / width  # in sector widths from phi = -pi
    index = np.minimum(np.floor(position).astype(np.intp), count - 1)
    from_centre = np.mod(position - 0.5, count)  # in sector widths from the first sector centre
    lower = np.minimum(np.floor(from_centre).astype(np.intp), count - 1)
    weight = (from_centre - lower).astype(np.float32)
    centres = -np.pi + (np.arange(count) + 0.5) * width
    return SectorLayout(count, index, lower, (lower + 1) % count, weight, centres)
