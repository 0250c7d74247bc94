# SPDX-License-Identifier: Apache-2.0
"""The structure steps of an upward view: enclosed ground near the threshold, and sky beyond a ring of ground."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.ndimage import label

from skynav_core.camera import EquidistantCamera, angles_from_directions
from skynav_skyline.geometry import SkylineGeometry
from skynav_skyline.segment import SkylineParams, SkylineSegmenter
from skynav_skyline.structure import outermost_band_end, unanchored_ground

SKY = 1.0  # sky radiance: the 90th percentile of the views below, so its log feature is 0
THRESHOLD = math.log(0.5)  # global UV threshold: sky above half the sky's radiance
DIM = 0.4  # dim sky: log 0.4 - log 0.5 = 0.22 below the threshold (ground to the threshold, but not clearly)
DARK = 0.05  # a crown or a tree line: 2.3 below the threshold
BRIGHT = 0.9  # sunlit snow: above the threshold, read as sky


@pytest.fixture(scope='module')
def view():
    """A 190-degree camera and each pixel's elevation and azimuth (rad)."""
    camera = EquidistantCamera.for_field_of_view(160, 120, math.radians(190))
    theta, phi = angles_from_directions(camera.pixel_directions())
    return camera, np.pi / 2 - theta, phi


def _segment(camera: EquidistantCamera, uv: np.ndarray, **changes) -> np.ndarray:
    """Return the sky (bool) of a UV radiance image by the global UV threshold and the given structure settings."""
    params = SkylineParams(method='global', channels='uv', threshold=THRESHOLD, **changes)
    mask = SkylineSegmenter(SkylineGeometry.from_camera(camera), params).segment(uv.astype(np.float32), None, '32FC1')
    return mask == 255


def _blob(elevation: np.ndarray, azimuth: np.ndarray, centre: tuple[float, float], radius: float) -> np.ndarray:
    """Return the pixels within `radius` (rad) of the direction at (elevation, azimuth) `centre`."""
    e, a = centre
    cosine = np.sin(elevation) * np.sin(e) + np.cos(elevation) * np.cos(e) * np.cos(azimuth - a)
    return cosine > np.cos(radius)


def test_enclosed_ground_near_the_threshold_becomes_sky_and_clear_ground_stays(view):
    camera, elevation, azimuth = view
    circle = camera.image_circle()
    uv = np.where(elevation > math.radians(15), SKY, DARK)
    dim = _blob(elevation, azimuth, (math.radians(60), 0.0), math.radians(12))  # dim sky, enclosed by sky
    crown = _blob(elevation, azimuth, (math.radians(55), 2.5), math.radians(12))  # a crown, enclosed by sky
    # dim sky touching the crown is part of the crown's region, which holds clearly ground pixels
    beside = _blob(elevation, azimuth, (math.radians(55), 2.5 + math.radians(24)), math.radians(8)) & ~crown
    low = _blob(elevation, azimuth, (math.radians(12), -2.0), math.radians(10))  # dim, joined to the tree line
    uv = np.where(dim | beside | low, SKY * DIM, uv)
    uv = np.where(crown, SKY * DARK, uv)
    plain = _segment(camera, uv)
    assert not plain[dim].any() and not plain[crown].any() and not plain[beside].any()
    filled = _segment(camera, uv, hole_margin=0.5)
    assert filled[dim & circle].all()
    np.testing.assert_array_equal(filled[~dim], plain[~dim])  # the crown, what touches it, and the low patch stay
    # the margin is the test: the crown lies log(0.5 / 0.05) = 2.3 below the threshold
    assert not _segment(camera, uv, hole_margin=2.0)[crown].any()
    assert _segment(camera, uv, hole_margin=2.5)[crown & circle].all()
    assert _segment(camera, uv, hole_margin=math.inf)[(crown | beside | dim) & circle].all()


@pytest.mark.parametrize('sectors', [8, 16])
def test_enclosed_ground_is_measured_against_its_own_sector_s_threshold(sectors):
    # Light 7x brighter on one side: the thresholds of the UV-only sector method follow it, lowest at the sector
    # centre `darkest`. There a dim patch enclosed by sky lies half the margin below its own threshold: ground,
    # but not clearly ground, so it is filled. At 8 sectors the neighbours' thresholds lie higher by more than half
    # the margin (0.32, 0.35): measured against theirs the patch would be clearly ground and stay ground.
    camera = EquidistantCamera.for_field_of_view(320, 240, math.radians(190))
    theta, azimuth = angles_from_directions(camera.pixel_directions())
    elevation = np.pi / 2 - theta
    circle = camera.image_circle()
    darkest = -np.pi + np.pi / sectors  # the centre of sector 0
    light = np.exp(1.5 * np.cos(azimuth - darkest - np.pi))
    texture = np.exp(0.3 * np.random.default_rng(3).standard_normal(elevation.shape))  # spreads the histograms
    uv = np.where(elevation > math.radians(15), SKY, DARK) * light * texture
    params = SkylineParams(method='sector-otsu', channels='uv', sectors=sectors, hole_margin=0.5)
    segmenter = SkylineSegmenter(SkylineGeometry.from_camera(camera), params)
    before = segmenter.run(uv.astype(np.float32), None, '32FC1')
    sky = (before.mask == 255) & circle
    offset = before.contrast[sky] - np.log(uv[sky])  # contrast = log UV + the normalisation's offset
    assert np.ptp(offset) < 1e-4 and before.sectors.bimodal.all()
    patch = _blob(elevation, azimuth, (math.radians(50), darkest), math.radians(4)) & circle
    after = before
    for _ in range(2):  # the patch moves its sector's threshold a little: placed again against the moved one
        uv = np.where(patch, np.exp(after.threshold - 0.5 * params.hole_margin - offset[0]), uv)
        after = segmenter.run(uv.astype(np.float32), None, '32FC1')
    below = after.threshold[patch] - after.contrast[patch]  # how far each patch pixel lies below its threshold
    assert np.all((below > 0.3 * params.hole_margin) & (below < 0.7 * params.hole_margin))  # the patch is as meant
    assert (after.mask[patch] == 255).all()
    plain = SkylineSegmenter(SkylineGeometry.from_camera(camera), replace(params, hole_margin=0.0))
    assert not (plain.segment(uv.astype(np.float32), None, '32FC1')[patch] == 255).any()  # ground by its threshold


def _ringed(elevation: np.ndarray, azimuth: np.ndarray, ringed: float) -> tuple[np.ndarray, np.ndarray]:
    """Return (UV radiance, snow pixels): a tree line from 5 to 20 degrees over `ringed` radians of azimuth from -pi,
    sunlit snow below it down to the rim, and open sky elsewhere."""
    band = (azimuth + np.pi) < ringed
    trees = band & (elevation > math.radians(5)) & (elevation <= math.radians(20))
    snow = band & (elevation <= math.radians(5))
    uv = np.where(trees, SKY * DARK, np.where(snow, SKY * BRIGHT, SKY))
    return uv, snow


def test_sky_beyond_a_ground_ring_becomes_ground_where_the_ring_surrounds_most_of_the_view(view):
    camera, elevation, azimuth = view
    circle = camera.image_circle()
    uv, snow = _ringed(elevation, azimuth, 2 * np.pi)
    assert _segment(camera, uv)[snow & circle].all()  # by its brightness the snow is sky
    cut = _segment(camera, uv, ring_share=0.5)
    assert not cut[snow].any()
    np.testing.assert_array_equal(cut[~snow], _segment(camera, uv)[~snow])


def test_a_ring_around_a_third_of_the_view_leaves_the_sky_alone_unless_the_share_allows(view):
    camera, elevation, azimuth = view
    circle = camera.image_circle()
    uv, snow = _ringed(elevation, azimuth, 2 * np.pi / 3)
    plain = _segment(camera, uv)
    np.testing.assert_array_equal(_segment(camera, uv, ring_share=0.5), plain)
    cut = _segment(camera, uv, ring_share=0.3)
    inner = np.abs(azimuth + np.pi - np.pi / 3) < np.pi / 3 - math.radians(3)  # away from the ring's ends
    assert not cut[snow & inner].any()
    open_sky = (azimuth + np.pi > 2 * np.pi / 3 + math.radians(3)) & circle
    np.testing.assert_array_equal(cut[open_sky], plain[open_sky])  # the open side keeps its sky to the rim


def test_a_crown_over_the_camera_does_not_cut_the_sky_around_it(view):
    camera, elevation, azimuth = view
    crown = elevation > math.radians(70)  # the rays start in ground: no sky before it
    uv = np.where(crown, SKY * DARK, SKY)
    np.testing.assert_array_equal(_segment(camera, uv, ring_share=0.01), _segment(camera, uv))


def test_structure_steps_need_valid_settings_and_the_ring_a_camera_model():
    for bad in (
        {'hole_margin': -0.1},
        {'hole_margin': math.nan},
        {'ring_share': 0.0},
        {'ring_width_deg': 0.0},
        {'ring_width_deg': math.inf},
    ):
        with pytest.raises(ValueError):
            SkylineParams(**bad)
    defaults = SkylineParams()
    assert not defaults.fills_holes and not defaults.cuts_rings
    circle = np.ones((20, 20), bool)
    SkylineSegmenter(circle, SkylineParams(hole_margin=0.5))  # holes need no angles
    with pytest.raises(ValueError, match='camera model'):
        SkylineSegmenter(circle, SkylineParams(ring_share=0.5))


def test_rim_and_rays_of_a_camera_geometry(view):
    camera = view[0]
    geometry = SkylineGeometry.from_camera(camera)
    rim = np.zeros(geometry.shape, bool)
    rim.reshape(-1)[geometry.rim()] = True
    circle = geometry.circle
    assert rim.any() and not (rim & ~circle).any()
    interior = circle & ~rim
    padded = np.pad(circle, 1)
    for dv, du in ((-1, 0), (1, 0), (0, -1), (0, 1)):  # interior pixels have all four neighbours in the circle
        assert padded[1 + dv : 1 + dv + circle.shape[0], 1 + du : 1 + du + circle.shape[1]][interior].all()
    assert geometry.pixels_per_radian == pytest.approx(camera.fx, rel=1e-6)  # no distortion: r = f theta
    rays = geometry.rays(8, math.radians(1.0))
    assert rays.spacing == pytest.approx(max(1.0, camera.fx * math.radians(1.0)))
    centre_angles = np.arctan2(rays.map_v[:, -1] - camera.cy, rays.map_u[:, -1] - camera.cx)
    np.testing.assert_allclose(centre_angles, geometry.sectors(8).centres, atol=1e-5)
    reach = np.hypot(rays.map_u - camera.cx, rays.map_v - camera.cy)
    np.testing.assert_allclose(np.diff(reach, axis=1), rays.spacing, rtol=1e-4)
    assert reach[:, -1].min() >= geometry.radius()[circle].max() - 1e-6  # rays reach the farthest pixel
    with pytest.raises(ValueError, match='camera model'):
        SkylineGeometry.from_circle(circle).rays(8, 0.01)


def _unanchored_reference(weak: np.ndarray, strong: np.ndarray, rim: np.ndarray) -> set[int]:
    """Return flat indices of ground pixels in 8-connected ground regions with no strong or rim pixel."""
    labels, count = label(weak | strong, structure=np.ones((3, 3)))
    anchored = set(labels[strong | (rim & (weak | strong))].tolist()) | {0}
    free = [k for k in range(1, count + 1) if k not in anchored]
    return set(np.flatnonzero(np.isin(labels, free)).tolist())


@settings(max_examples=200, deadline=None)
@given(
    arrays(np.uint8, st.tuples(st.integers(1, 14), st.integers(1, 14)), elements=st.integers(0, 2)),
    st.integers(0, 2**32 - 1),
)
def test_unanchored_ground_equals_labelling_the_whole_ground(classes, seed):
    weak, strong = classes == 1, classes == 2
    rim = np.random.default_rng(seed).random(classes.shape) < 0.1
    found = unanchored_ground(classes, ~rim)
    assert set(found.tolist()) == _unanchored_reference(weak, strong, rim)
    assert len(set(found.tolist())) == found.size


def _band_end_reference(ground: np.ndarray, inside: np.ndarray, width: int) -> tuple[int, bool]:
    """Return (end, cut) of one ray by walking along it."""
    states = ['ground' if g and i else ('sky' if i else 'outside') for g, i in zip(ground, inside)]
    end, sky_so_far, sky_before_run, run = len(states), False, False, 0
    for k, state in enumerate(states):
        if state == 'ground':
            if run == 0:
                sky_before_run = sky_so_far
            run += 1
            if run >= width and sky_before_run:
                end = k + 1
        else:
            run = 0
            sky_so_far = sky_so_far or state == 'sky'
    return end, 'sky' in states[end:]


@settings(max_examples=300, deadline=None)
@given(arrays(bool, st.tuples(st.integers(1, 6), st.integers(1, 30))), st.integers(1, 6), st.integers(0, 2**32 - 1))
def test_outermost_band_end_equals_walking_each_ray(ground, width, seed):
    rng = np.random.default_rng(seed)
    inside = np.arange(ground.shape[1]) < rng.integers(0, ground.shape[1] + 1, ground.shape[0])[:, None]
    end, cut = outermost_band_end(ground, inside, width)
    for ray in range(ground.shape[0]):
        expected_end, expected_cut = _band_end_reference(ground[ray], inside[ray], width)
        assert cut[ray] == expected_cut
        assert end[ray] == expected_end
