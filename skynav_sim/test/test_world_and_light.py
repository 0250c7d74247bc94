# SPDX-License-Identifier: Apache-2.0
"""Terrain, primitives, worlds, daylight and sensor: each against an independent computation."""

import numpy as np
import pytest

from skynav_core.rotations import tilt
from skynav_sim.materials import GREEN_RANGE, UV_RANGE, Surface
from skynav_sim.primitives import ConvexPolytope, Cylinder, Ellipsoid
from skynav_sim.robot import bump, camera_pose
from skynav_sim.scenarios import ScenarioParameters, build, describe
from skynav_sim.sensor import Sensor
from skynav_sim.sky import TIMES_OF_DAY, Sky
from skynav_sim.world import STYLES, generate


@pytest.fixture(scope='module')
def worlds():
    return {style: generate(style, 5) for style in STYLES}


def _dense_march(terrain, origin, directions, step=0.01, reach=60.0):
    """Return the first terrain crossing of each ray by brute force (1 cm steps)."""
    s = np.arange(step, reach, step)
    hits = np.full(len(directions), np.inf)
    for k, d in enumerate(directions):
        p = origin + s[:, None] * d
        below = np.flatnonzero(p[:, 2] < terrain.height(p[:, 0], p[:, 1]))
        if below.size:
            hits[k] = s[below[0]]
    return hits


def test_terrain_intersection_matches_brute_force(worlds):
    terrain = worlds['mineral'].terrain
    rng = np.random.default_rng(1)
    origin = np.array([1.0, 2.0, float(terrain.height(np.array(1.0), np.array(2.0))) + 0.3])
    elevation = rng.uniform(np.radians(-40), np.radians(10), 300)
    azimuth = rng.uniform(0, 2 * np.pi, 300)
    d = np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], 1)
    fast = terrain.intersect(origin, d, 60.0, terrain.first_contact(origin, d))
    slow = _dense_march(terrain, origin, d)
    # Rays that graze a crest may disagree; they are rare.
    assert np.mean(np.isfinite(fast) == np.isfinite(slow)) > 0.99
    both = np.isfinite(fast) & np.isfinite(slow)
    assert np.median(np.abs(fast[both] - slow[both])) < 0.01
    assert np.mean(np.abs(fast[both] - slow[both]) < 0.05) > 0.98


def test_horizon_bound_never_drops_a_ray_that_hits(worlds):
    terrain = worlds['park'].terrain
    origin = np.array([0.0, 0.0, float(terrain.height(np.array(0.0), np.array(0.0))) + 0.3])
    rng = np.random.default_rng(2)
    d = rng.normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hits = np.isfinite(terrain.intersect(origin, d, 250.0))
    assert hits.sum() > 500
    assert terrain.may_hit(origin, d, 250.0)[hits].all()


def _ray_sphere(o, d, c, r):
    b = d @ (o - c)
    disc = b * b - ((o - c) @ (o - c) - r * r)
    return -b - np.sqrt(disc) if disc >= 0 and -b - np.sqrt(disc) > 0 else np.inf


def test_primitives_against_closed_forms():
    rng = np.random.default_rng(3)
    origins = rng.normal(0, 0.2, (500, 3)) + [0.0, 0.0, 0.3]
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    sphere = Ellipsoid(np.array([3.0, 1.0, 2.0]), np.full(3, 1.5), 0.7, Surface.FOLIAGE)
    expected = np.array([_ray_sphere(o, v, sphere.center, 1.5) for o, v in zip(origins, d)])
    assert np.allclose(sphere.intersect(origins, d), expected, equal_nan=False)
    # A box is entered through the face whose plane the ray crosses last.
    box = ConvexPolytope.box(np.array([0.0, 0.0, 5.0]), np.array([1.0, 2.0, 0.5]), 0.0, Surface.BRICK)
    up = np.tile([0.0, 0.0, 1.0], (3, 1))
    assert box.intersect(np.array([[0.0, 0.0, 0.0], [0.9, 1.9, 0.0], [1.1, 0.0, 0.0]]), up) == pytest.approx(
        [4.5, 4.5, np.inf]
    )
    assert np.allclose(box.normal(np.array([[0.0, 0.0, 4.5]])), [[0.0, 0.0, -1.0]])
    trunk = Cylinder(np.array([2.0, 0.0, 0.0]), 0.25, 3.0, Surface.BARK)
    ahead = np.tile([1.0, 0.0, 0.0], (2, 1))
    assert trunk.intersect(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 3.5]]), ahead) == pytest.approx([1.75, np.inf])


def test_gable_roof_ridge_and_eaves():
    roof = ConvexPolytope.gable_roof(np.array([0.0, 0.0, 3.0]), 5.0, 4.0, 2.0, 0.0, Surface.ROOF_TILE)
    down = np.tile([0.0, 0.0, -1.0], (3, 1))
    # From above: the ridge (y = 0) at 5 m, half-way down the slope at 4 m, beyond the eaves nothing.
    hits = roof.intersect(np.array([[0.0, 0.0, 10.0], [0.0, 2.0, 10.0], [0.0, 4.5, 10.0]]), down)
    assert hits == pytest.approx([5.0, 6.0, np.inf])


def test_worlds_are_reproducible_and_distinct():
    a, b, c = generate('garden', 11), generate('garden', 11), generate('garden', 12)
    assert np.array_equal(a.terrain.heights, b.terrain.heights) and len(a.primitives) == len(b.primitives)
    assert np.array_equal(a.centers, b.centers)
    assert not np.array_equal(a.terrain.heights, c.terrain.heights)
    with pytest.raises(ValueError, match='unknown world style'):
        generate('desert', 1)


def test_styles_differ_in_what_they_are_made_of(worlds):
    def ground_share(world, surfaces):
        return np.isin(world.terrain.materials, surfaces).mean()

    minerals = [Surface.SAND, Surface.GRAVEL, Surface.LIMESTONE]
    assert ground_share(worlds['mineral'], minerals) > 0.8
    assert ground_share(worlds['garden'], [Surface.GRASS]) > 0.7
    trees = {style: sum(f.kind == 'tree' for f in w.footprints) for style, w in worlds.items()}
    assert trees['park'] > trees['garden'] > trees['mineral']
    assert sum(f.kind == 'rock' for f in worlds['mineral'].footprints) > 15
    assert sum(f.kind == 'building' for f in worlds['garden'].footprints) >= 2


def test_robot_tilts_as_the_ground_does(worlds):
    world = worlds['mineral']
    axis = np.linspace(-9, 9, 91)
    x, y = np.meshgrid(axis, axis)
    free = world.is_free(x, y)
    tilts = np.degrees([tilt(camera_pose(world.terrain, px, py, 0.3).rotation) for px, py in zip(x[free], y[free])])
    assert np.percentile(tilts, 95) > 10 and tilts.max() > 20 and tilts.max() < 45
    # The camera's z axis is the terrain plane's normal; its x axis keeps the heading.
    pose = camera_pose(world.terrain, 0.0, 0.0, 1.0)
    forward = pose.rotation.apply([1.0, 0.0, 0.0])
    assert np.arctan2(forward[1], forward[0]) == pytest.approx(1.0, abs=0.02)


def test_daylight_spans_orders_of_magnitude_and_shifts_colour():
    dawn, noon = Sky(TIMES_OF_DAY['dawn']), Sky(TIMES_OF_DAY['noon'])
    assert noon.global_irradiance('green') / dawn.global_irradiance('green') > 100
    sunrise = Sky(TIMES_OF_DAY['sunrise'])
    # Low sun: the direct light is far poorer in ultraviolet than at noon.
    assert sunrise.direct['uv'] / sunrise.direct['green'] < 0.2 * noon.direct['uv'] / noon.direct['green']
    # The sky is ultraviolet-rich relative to the direct sunlight.
    assert noon.diffuse['uv'] / noon.diffuse['green'] > 2 * noon.direct['uv'] / noon.direct['green']


@pytest.mark.parametrize('time', ['sunrise', 'morning', 'forenoon', 'noon'])
def test_clouds_are_bright_in_green_and_faint_in_ultraviolet(time):
    sky = Sky(TIMES_OF_DAY[time], cloud_cover=0.5, cloud_seed=4)
    rng = np.random.default_rng(5)
    d = rng.normal(size=(20000, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.3
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origin = np.zeros(3)
    clouds = sky.cloud_density(d, origin)
    cloudy, clear = clouds > 0.9, clouds == 0
    assert cloudy.sum() > 100 and clear.sum() > 100
    away_from_sun = d @ sky.sun < np.cos(np.radians(20))
    contrast = {
        band: np.median(sky.radiance(band, d[cloudy & away_from_sun], origin))
        / np.median(sky.radiance(band, d[clear & away_from_sun], origin))
        for band in ('uv', 'green')
    }
    assert contrast['green'] > 1.8
    assert 0.9 < contrast['uv'] < 1.2


def test_sensor_encodings_saturate_and_quantise():
    radiance = np.linspace(0, 2.0, 100 * 100).reshape(100, 100).astype(np.float32)
    radiance[:3, :3] = 500.0  # the sun's disc
    inside = np.ones_like(radiance, bool)
    rng = np.random.default_rng(0)
    sensor = Sensor(blur_sigma=0)
    eight = sensor.capture(radiance, inside, 'mono8', rng)
    sixteen = sensor.capture(radiance, inside, 'mono16', rng)
    linear = sensor.capture(radiance, inside, '32FC1', rng)
    assert eight.dtype == np.uint8 and sixteen.dtype == np.uint16 and linear.dtype == np.float32
    assert (eight[:3, :3] == 255).all() and (sixteen[:3, :3] == 65535).all()  # the sun saturates
    assert 0.6 * 255 < np.percentile(eight, 99) < 0.8 * 255  # automatic exposure: p99 at 70 % of full scale
    # 32FC1 is radiance itself, up to photon noise.
    assert np.median(np.abs(linear - radiance)[radiance > 0.5] / radiance[radiance > 0.5]) < 0.02
    # Automatic exposure: scaling the light scales nothing in 8-bit output but the noise.
    brighter = sensor.capture(10 * radiance, inside, 'mono8', np.random.default_rng(0))
    assert np.abs(brighter.astype(int) - eight.astype(int)).mean() < 2
    with pytest.raises(ValueError, match='unknown encoding'):
        sensor.capture(radiance, inside, 'rgb8', rng)


def test_material_ranges_put_minerals_above_vegetation_in_ultraviolet():
    assert UV_RANGE[Surface.LIMESTONE, 0] > 3 * UV_RANGE[Surface.GRASS, 1]
    assert np.all(UV_RANGE[:, 0] <= UV_RANGE[:, 1]) and np.all(GREEN_RANGE[:, 0] <= GREEN_RANGE[:, 1])
    assert np.all((UV_RANGE > 0) & (UV_RANGE < 1) & (GREEN_RANGE > 0) & (GREEN_RANGE < 1))


def test_bumps_tilt_up_to_their_limit_and_no_bump_draws_nothing():
    rng = np.random.default_rng(5)
    assert bump(rng, 0.0) is None
    assert rng.uniform() == np.random.default_rng(5).uniform()  # nothing was drawn
    angles = np.degrees([bump(rng, 20.0).magnitude() for _ in range(2000)])
    assert angles.max() <= 20.0 + 1e-9
    # uniform over the cap of up directions: the share within half the limit is about a quarter
    assert 0.2 < np.mean(angles < 10.0) < 0.3
    axes = np.array([bump(rng, 20.0).as_rotvec() for _ in range(200)])
    assert np.allclose(axes[:, 2], 0.0)  # about horizontal axes of base_link


def test_a_bumpy_homing_grid_tilts_the_same_places_more(worlds):
    world = worlds['park']
    params = ScenarioParameters(spacing=0.75, grid_radius=2.25)
    level = build('homing', world, params, 3)
    bumpy = build('homing', world, ScenarioParameters(spacing=0.75, grid_radius=2.25, bump_tilt=20.0), 3)
    assert [f.label for f in level] == [f.label for f in bumpy]
    level_tilt = np.degrees([tilt(f.pose.rotation) for f in level])
    bumpy_tilt = np.degrees([tilt(f.pose.rotation) for f in bumpy])
    assert np.median(bumpy_tilt) > np.median(level_tilt) + 5.0
    assert bumpy_tilt.max() <= level_tilt.max() + 20.0 + 1e-6
    # a recording without bumps describes itself as before bumps existed (its bytes do not change)
    assert 'bump_tilt' not in describe('homing', world, params, 3, level)['parameters']
    assert describe('homing', world, ScenarioParameters(bump_tilt=20.0), 3, bumpy)['parameters']['bump_tilt'] == 20.0
