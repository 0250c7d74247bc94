# SPDX-License-Identifier: Apache-2.0
"""Synthetic scenes with known geometry, for tests and demonstrations of warping (all of it made up).

- An equal-distance world for 3D-warping: every scene point lies on a sphere of radius rho around the snapshot's
  place and carries the value of a smooth function of its direction (a horizon step plus round "crowns").
  render_equal_distance_view samples the view of a camera anywhere inside that sphere, with any orientation, on a
  quadrature grid and returns its WarpView: the exact world of the translation model.
- A planar pole world for the planar baselines: vertical cylinders of random radius, height and grey value on
  level ground; render_pole_panorama draws the panoramic band of an upright camera.
Frames: map for positions; camera_link of the rendered camera for views (rotation Q: d_map = Q d_camera).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skynav_sh.basis import DEFAULT_DEGREE
from skynav_sh.transform import grid
from skynav_warping.views import WarpView, cap_fraction, rim_weights, view_from_samples


@dataclass(frozen=True)
class BlobScene:
    """A function on the unit sphere (map frame): 1 above a wavy horizon, 0 below, minus smooth round crowns."""

    centres: np.ndarray  # (K, 3) unit directions of the crowns
    widths: np.ndarray  # (K,) rad
    horizon_tilt: float  # rad, amplitude of the horizon's ripple

    def __call__(self, directions: np.ndarray) -> np.ndarray:
        """Return the scene's value at unit directions (..., 3) of the map frame."""
        d = np.asarray(directions, dtype=float)
        elevation = np.arcsin(np.clip(d[..., 2], -1.0, 1.0))
        azimuth = np.arctan2(d[..., 1], d[..., 0])
        horizon = self.horizon_tilt * np.sin(3 * azimuth) + 0.5 * self.horizon_tilt * np.cos(5 * azimuth + 1.0)
        value = 0.5 * (1 + np.tanh((elevation - 0.15 - horizon) / 0.06))
        for centre, width in zip(self.centres, self.widths):
            angle = np.arccos(np.clip(d @ centre, -1.0, 1.0))
            value = value * (1 - np.exp(-0.5 * (angle / width) ** 2))
        return value


def blob_scene(seed: int = 0, count: int = 9) -> BlobScene:
    """Return a random BlobScene: crowns between 10 and 70 degrees elevation, 6 to 16 degrees wide."""
    rng = np.random.default_rng(seed)
    elevation = np.radians(rng.uniform(10, 70, count))
    azimuth = rng.uniform(0, 2 * np.pi, count)
    centres = np.stack(
        [np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], -1
    )
    return BlobScene(centres, np.radians(rng.uniform(6, 16, count)), np.radians(4.0))


def render_equal_distance_view(
    scene: BlobScene,
    position: np.ndarray,
    rotation: np.ndarray,
    field_of_view: float = np.radians(200),
    degree: int = DEFAULT_DEGREE,
    radius: float = 1.0,
    rim_taper: float = np.radians(10.0),
) -> WarpView:
    """Return the WarpView of a camera at `position` (map, |position| < radius) turned by `rotation` (d_map = Q d)."""

    quadrature = grid(2 * degree + 2)
    d_camera = quadrature.directions()
    d_map = d_camera @ np.asarray(rotation, dtype=float).T
    p = np.asarray(position, dtype=float)
    # the ray p + s d_map meets the sphere of `radius` at s = -p.d + sqrt((p.d)^2 - |p|^2 + radius^2)
    along = d_map @ p
    s = -along + np.sqrt(along * along - p @ p + radius * radius)
    hit = p + s[..., None] * d_map
    values = scene(hit / radius)
    theta_max = 0.5 * float(field_of_view)
    visibility = cap_fraction(quadrature, theta_max) * rim_weights(quadrature.theta, theta_max, rim_taper)[:, None]
    return view_from_samples(quadrature, values, visibility, degree)


@dataclass(frozen=True)
class PoleWorld:
    """Vertical cylinders on level ground (map frame, z up, ground at z = 0)."""

    positions: np.ndarray  # (K, 2) m
    radii: np.ndarray  # (K,) m
    heights: np.ndarray  # (K,) m
    grey: np.ndarray  # (K,) values in (0, 1); sky is 1, ground 0


def pole_world(seed: int = 0, count: int = 40, near: float = 3.0, far: float = 12.0) -> PoleWorld:
    """Return random poles between `near` and `far` metres from the origin."""
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, 2 * np.pi, count)
    distance = rng.uniform(near, far, count)
    return PoleWorld(
        np.stack([distance * np.cos(angle), distance * np.sin(angle)], -1),
        rng.uniform(0.2, 1.0, count),
        rng.uniform(1.0, 6.0, count),
        rng.uniform(0.2, 0.8, count),
    )


def render_pole_panorama(
    world: PoleWorld,
    position: np.ndarray,
    heading: float,
    elevations: np.ndarray,
    n_azimuth: int = 72,
    camera_height: float = 0.3,
    textured: bool = True,
) -> np.ndarray:
    """Return the panoramic band (rows of `elevations` in rad, n_azimuth columns) of an upright camera.

    heading: azimuth (rad) of the camera's +x in map; column j looks along heading + 2 pi j / n_azimuth.
    Sky 1, ground 0, poles their grey value (or 0 when not textured); nearer poles hide farther ones.
    """
    e = np.asarray(elevations, dtype=float)
    image = np.where(e[:, None] < 0, 0.0, 1.0) * np.ones((1, n_azimuth))
    relative = world.positions - np.asarray(position, dtype=float)[:2]
    for j in range(n_azimuth):
        a = heading + 2 * np.pi * j / n_azimuth
        u = np.array([np.cos(a), np.sin(a)])
        along = relative @ u
        across = np.abs(relative[:, 0] * u[1] - relative[:, 1] * u[0])
        hit = np.flatnonzero((along > 0) & (across < world.radii))
        for k in hit[np.argsort(-along[hit])]:  # far to near, so nearer poles paint over
            top = np.arctan((world.heights[k] - camera_height) / along[k])
            bottom = np.arctan(-camera_height / along[k])
            image[(e < top) & (e > bottom), j] = world.grey[k] if textured else 0.0
    return image
