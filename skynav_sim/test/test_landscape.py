# SPDX-License-Identifier: Apache-2.0
"""Real landscapes (Debian's stellarium-data) as a world's backdrop: geometry, the skyline, rendered views."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import binary_erosion
from scipy.spatial.transform import Rotation

from skynav_core.camera import EquidistantCamera
from skynav_sim.landscape import LANDSCAPES, Backdrop, load
from skynav_sim.render import CameraPose, Renderer
from skynav_sim.robot import CAMERA_HEIGHT
from skynav_sim.sky import Sky
from skynav_sim.world import generate


@pytest.fixture(scope='module')
def landscapes(stellarium):
    """Every landscape, loaded once."""
    return {name: load(name, stellarium.parent) for name in LANDSCAPES}


def test_geneva_skyline_follows_its_measured_horizon_line(landscapes, stellarium):
    # horizon_Geneve.txt lists (azimuth from north through east, altitude) in degrees, interpolated between points
    points = np.loadtxt(stellarium / 'geneva' / 'horizon_Geneve.txt', comments='#')
    azimuth = np.radians(np.arange(1.0, 360.0, 7.0))
    expected = np.interp(np.degrees(azimuth), points[:, 0], points[:, 1], period=360)
    skyline = np.degrees(landscapes['geneva'].horizon(azimuth))
    assert np.max(np.abs(skyline - expected)) < 0.1


@pytest.mark.parametrize('name', LANDSCAPES)
def test_every_landscape_has_a_real_skyline_with_sky_above_and_ground_below(landscapes, name):
    landscape = landscapes[name]
    azimuth = np.radians(np.arange(0.0, 360.0, 1.0))
    skyline = landscape.horizon(azimuth)
    assert np.all(skyline < np.radians(60)) and np.all(skyline > np.radians(-20))
    assert np.ptp(skyline) > np.radians(2)  # relief, not a flat line
    ground_up, _ = landscape.sample(azimuth, np.full_like(azimuth, np.radians(80)))
    ground_down, colour = landscape.sample(azimuth, np.full_like(azimuth, np.radians(-45)))
    assert not ground_up.any() and ground_down.all()
    assert np.all(colour >= 0) and np.all(colour <= 1) and np.all(np.isfinite(colour))


def test_backdrop_from_the_centre_is_the_panorama_and_elsewhere_shows_parallax(landscapes):
    backdrop = Backdrop(landscapes['guereins'], distance=40.0)
    rng = np.random.default_rng(3)
    azimuth, altitude = rng.uniform(0, 2 * np.pi, 200), rng.uniform(-1.2, 1.2, 200)
    # a point on the cylinder at (azimuth, altitude) seen from the centre's eye
    points = np.column_stack([40.0 * np.sin(azimuth), 40.0 * np.cos(azimuth), CAMERA_HEIGHT + 40.0 * np.tan(altitude)])
    for origin in (np.array([0.0, 0.0, CAMERA_HEIGHT]), np.array([6.0, -3.0, 0.5])):
        directions = points - origin
        distance = np.linalg.norm(directions, axis=1)
        t, seen_azimuth, seen_altitude = backdrop.intersect(origin, directions / distance[:, None])
        np.testing.assert_allclose(t, distance, rtol=1e-9)
        np.testing.assert_allclose(np.angle(np.exp(1j * (seen_azimuth - azimuth))), 0, atol=1e-9)
        np.testing.assert_allclose(seen_altitude, altitude, atol=1e-9)
    with pytest.raises(ValueError, match='outside'):
        backdrop.intersect(np.array([50.0, 0.0, 0.3]), points[:1] / np.linalg.norm(points[:1]))


@pytest.mark.parametrize('name', LANDSCAPES)
def test_rendered_view_at_the_centre_shows_the_landscape_skyline(name):
    world = generate(name, 1)
    camera = EquidistantCamera.for_field_of_view(160, 120, np.radians(200), (0.0, 0.0, 0.0, 0.0))
    view = Renderer(world, camera).render(
        CameraPose(np.array([0.0, 0.0, CAMERA_HEIGHT]), Rotation.identity()), Sky(10.0)
    )
    directions = camera.pixel_directions()[view.inside]  # camera_link = map here: x east, y north, z up
    azimuth = np.arctan2(directions[:, 0], directions[:, 1])
    altitude = np.arcsin(np.clip(directions[:, 2], -1, 1))
    skyline = world.backdrop.landscape.horizon(azimuth)
    clear = np.abs(altitude - skyline) > np.radians(2)  # away from the skyline (and the panorama's own holes)
    agree = view.sky[view.inside][clear] == (altitude[clear] > skyline[clear])
    assert agree.mean() > 0.97
    assert np.all(np.isfinite(view.uv)) and np.all(view.uv[view.inside] > 0)
    # depth is the centre ray's, the label the majority's: compare away from the boundary
    sky_inside, ground_inside = binary_erosion(view.sky), binary_erosion(view.inside & ~view.sky)
    # (thin twigs, wires and gaps in a canopy: a centre ray on one is outvoted by the pixel's other samples)
    assert np.isinf(view.depth[sky_inside]).mean() > 0.99
    assert np.isfinite(view.depth[ground_inside]).mean() > 0.99
    assert np.all(view.depth[ground_inside] >= world.backdrop.distance - 1e-4)


def test_ground_radiance_follows_the_photographs_colours_per_band(landscapes):
    # red, green and blue are the visible bands' albedos and blue stands in for ultraviolet: a ray at the nadir
    # sees the ground texture's centre
    world = Backdrop(landscapes['guereins'])
    sky = Sky(10.0)
    radiance, sky_hit, _ = world.shade(
        np.array([0.0, 0.0, CAMERA_HEIGHT]), np.array([[0.0, 0.0, -1.0]]), sky, ('uv', 'blue', 'green', 'red')
    )
    _, colour = landscapes['guereins'].sample(np.zeros(1), np.full(1, -np.pi / 2))
    assert not sky_hit[0]
    assert len(set(np.round(colour[0], 4))) == 3  # a coloured ground, so a channel mixed up would show
    for band, channel in (('uv', 2), ('blue', 2), ('green', 1), ('red', 0)):
        assert radiance[band][0] == pytest.approx(colour[0, channel] * sky.global_irradiance(band) / np.pi)
