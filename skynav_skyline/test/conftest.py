# SPDX-License-Identifier: Apache-2.0
"""Synthetic UV/green fish-eye scenes for the skyline tests.

A scene is rendered in linear radiance through the contract's fish-eye model:
a sky with a smooth gradient (UV-rich, UV/G about 1.6), a ground band below a
random skyline (vegetation: little UV, UV/G about 0.17, with texture), an
optional mineral patch (bright in UV like the dim sky near the horizon, but
UV/G about 0.5), an optional sun disc, and an optional azimuthal illumination
change (one side of the view much brighter than the other). Encoding applies a
per-channel gain, 8/16-bit quantisation and saturation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from skynav_core.camera import EquidistantCamera, angles_from_directions

SKY_UV = 1.0  # sky UV radiance at the zenith (arbitrary radiance unit)
SKY_UV_GREEN_RATIO = 1.6  # UV/G of the sky
VEGETATION_UV, VEGETATION_GREEN = 0.06, 0.35  # ground radiance (same unit)
MINERAL_UV, MINERAL_GREEN = 0.45, 0.9  # diffusely lit mineral: bright in UV, UV/G 0.5
SUN_UV = 60.0  # sun disc radiance, far above any exposure's range
FOV_DEG = 190.0


@dataclass
class Scene:
    """A rendered scene: radiance of both channels, the ground truth and the camera."""

    camera: EquidistantCamera
    circle: np.ndarray  # bool
    truth: np.ndarray  # uint8, 255 sky, 0 ground (0 outside the circle)
    uv: np.ndarray  # float32 radiance
    green: np.ndarray  # float32 radiance
    mineral: np.ndarray  # bool: mineral pixels
    sun: np.ndarray  # bool: sun pixels
    azimuth: np.ndarray  # rad, per pixel
    elevation: np.ndarray  # rad, per pixel


def render_scene(
    seed: int = 0,
    width: int = 160,
    height: int = 120,
    mineral: bool = True,
    sun: bool = False,
    light: float = 0.0,
    open_sector: tuple[float, float] | None = None,
    fov_deg: float = FOV_DEG,
) -> Scene:
    """Return a synthetic scene; `light` is the log amplitude of the azimuthal illumination change."""
    rng = np.random.default_rng(seed)
    camera = EquidistantCamera.for_field_of_view(width, height, np.deg2rad(fov_deg))
    circle = camera.image_circle()
    theta, phi = angles_from_directions(camera.pixel_directions())
    elevation = np.pi / 2 - theta
    p = rng.uniform(0, 2 * np.pi, 3)
    skyline = np.deg2rad(16 + 9 * np.sin(2 * phi + p[0]) + 5 * np.sin(5 * phi + p[1]) + 3 * np.sin(11 * phi + p[2]))
    if open_sector is not None:
        lo, hi = open_sector
        skyline = np.where((phi >= lo) & (phi <= hi), np.deg2rad(-20.0), skyline)
    ground = elevation < skyline
    sun_azimuth = rng.uniform(-np.pi, np.pi)
    illumination = np.exp(light * np.cos(phi - sun_azimuth))

    # Sky: UV brighter towards the zenith, green relatively brighter (whiter) towards the horizon.
    height_factor = np.sin(np.clip(elevation, 0, None))
    sky_uv = SKY_UV * (0.55 + 0.45 * height_factor) * illumination
    sky_green = sky_uv / SKY_UV_GREEN_RATIO * (1.15 - 0.15 * height_factor)

    shade = gaussian_filter(rng.standard_normal(phi.shape), 2.0)
    shade = 0.35 * shade / shade.std()
    ground_uv = VEGETATION_UV * np.exp(shade) * illumination
    ground_green = VEGETATION_GREEN * np.exp(shade + 0.1 * rng.standard_normal(phi.shape)) * illumination
    patch = np.zeros(phi.shape, bool)
    if mineral:
        centre = rng.uniform(-np.pi, np.pi)
        patch = ground & (np.abs(np.angle(np.exp(1j * (phi - centre)))) < np.deg2rad(50))
        ground_uv = np.where(patch, MINERAL_UV * np.exp(0.3 * shade) * illumination, ground_uv)
        ground_green = np.where(patch, MINERAL_GREEN * np.exp(0.3 * shade) * illumination, ground_green)

    uv = np.where(ground, ground_uv, sky_uv)
    green = np.where(ground, ground_green, sky_green)
    sun_mask = np.zeros(phi.shape, bool)
    if sun:
        sun_direction = np.array([np.cos(sun_azimuth) * np.cos(0.9), np.sin(sun_azimuth) * np.cos(0.9), np.sin(0.9)])
        sun_mask = (camera.pixel_directions() @ sun_direction > np.cos(np.deg2rad(5))) & ~ground
        uv = np.where(sun_mask, SUN_UV, uv)
        green = np.where(sun_mask, SUN_UV, green)
    noise = rng.standard_normal((2, *phi.shape)) * 0.02
    uv = (uv * np.exp(noise[0])).astype(np.float32)
    green = (green * np.exp(noise[1])).astype(np.float32)
    uv[~circle] = 0.0  # outside the image circle the lens gives no light
    green[~circle] = 0.0
    truth = np.where(circle & ~ground, 255, 0).astype(np.uint8)
    return Scene(camera, circle, truth, uv, green, patch & circle, sun_mask & circle, phi, elevation)


def encode(radiance: np.ndarray, encoding: str, gain: float) -> np.ndarray:
    """Return radiance times `gain` as an image of `encoding` (rounded and clipped for mono8/mono16)."""
    scaled = radiance.astype(np.float64) * gain
    if encoding == 'mono8':
        return np.clip(np.round(scaled), 0, 255).astype(np.uint8)
    if encoding == 'mono16':
        return np.clip(np.round(scaled), 0, 65535).astype(np.uint16)
    if encoding == '32FC1':
        return scaled.astype(np.float32)
    raise AssertionError(encoding)


def exposure_gain(radiance: np.ndarray, circle: np.ndarray, encoding: str, level: float) -> float:
    """Return the gain that puts the 95th percentile of the sky-dominated circle at `level` of the full scale."""
    full = {'mono8': 255.0, 'mono16': 65535.0, '32FC1': 1.0}[encoding]
    return level * full / float(np.percentile(radiance[circle], 95))


@pytest.fixture
def scene_factory():
    """Return render_scene (a factory, so tests choose the scene)."""
    return render_scene


@pytest.fixture
def encoder():
    """Return (encode, exposure_gain)."""
    return encode, exposure_gain
