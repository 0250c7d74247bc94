# SPDX-License-Identifier: Apache-2.0
"""Segmentation: the image circle, untrusted pixels, invariances, encodings, sectors and their fallback."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skynav_skyline.classify import classification_rate
from skynav_skyline.exposure import ExposureError
from skynav_skyline.geometry import SkylineGeometry
from skynav_skyline.segment import (
    METHODS,
    SkylineParams,
    SkylineSegmenter,
    above_sector_thresholds,
    is_bimodal,
    sector_thresholds,
    segment,
)

LOCAL_METHODS = [m for m in METHODS if m != 'global']


def _images(scene, encoder, encoding='mono8', uv_level=0.8, green_level=0.7):
    encode, exposure_gain = encoder
    uv = encode(scene.uv, encoding, exposure_gain(scene.uv, scene.circle, encoding, uv_level))
    green = encode(scene.green, encoding, exposure_gain(scene.green, scene.circle, encoding, green_level))
    return uv, green


def _agreement(a, b, circle):
    return float(np.mean((a == b)[circle]))


@pytest.mark.parametrize('channels', ['uv', 'uv-green'])
@pytest.mark.parametrize('method', METHODS)
def test_pixels_outside_the_image_circle_are_never_sky(scene_factory, encoder, method, channels):
    scene = scene_factory(1, sun=True, mineral=False)
    uv, green = _images(scene, encoder)
    uv[~scene.circle] = 255  # saturated, the brightest possible, outside the circle
    green[~scene.circle] = 1
    params = SkylineParams(method=method, channels=channels, threshold=-50.0)  # global: all decided pixels sky
    segmentation = SkylineSegmenter(scene.circle, params).run(uv, green, 'mono8', 'mono8')
    assert segmentation.mask.dtype == np.uint8
    assert set(np.unique(segmentation.mask)) <= {0, 255}
    assert not segmentation.mask[~scene.circle].any()
    if method == 'global':  # at threshold -50 every pixel of the circle is sky
        assert (segmentation.mask[scene.circle] == 255).all()
    else:
        assert classification_rate(segmentation.mask, scene.truth, scene.circle) >= 0.97


@pytest.mark.parametrize('channels', ['uv', 'uv-green'])
def test_saturated_uv_is_sky_and_dark_uv_is_ground_whatever_the_threshold(scene_factory, encoder, channels):
    scene = scene_factory(2, sun=True)
    uv, green = _images(scene, encoder)
    assert (uv[scene.circle] == 255).sum() > 20 and (uv[scene.circle] <= 2).sum() == 0
    uv[scene.circle & (scene.elevation < 0.3) & (np.abs(scene.azimuth) < 0.5)] = 1  # a dark patch
    dark = scene.circle & (uv <= 2)
    saturated = scene.circle & (uv == 255)
    assert dark.sum() > 20
    nothing_passes = segment(
        uv, green, 'mono8', 'mono8', scene.circle, method='global', channels=channels, threshold=50.0
    )
    np.testing.assert_array_equal(nothing_passes == 255, saturated)
    everything_passes = segment(
        uv, green, 'mono8', 'mono8', scene.circle, method='global', channels=channels, threshold=-50.0
    )
    np.testing.assert_array_equal(everything_passes == 255, scene.circle & ~dark)


def test_invalid_pixels_are_ground_and_green_is_ignored_in_uv_mode(scene_factory):
    scene = scene_factory(3)
    uv, green = scene.uv.copy(), scene.green.copy()
    sky = scene.truth == 255
    nan_uv = sky & (scene.azimuth > 2.0)
    nan_green = sky & (scene.azimuth < -2.0)
    uv[nan_uv] = np.nan
    green[nan_green] = np.inf
    green[sky & (np.abs(scene.azimuth) < 0.3)] = 0.0  # dark green in the sky: irrelevant to UV only
    assert nan_uv.sum() > 20 and nan_green.sum() > 20
    for channels in ('uv', 'uv-green'):
        mask = segment(uv, green, '32FC1', '32FC1', scene.circle, method='sector-otsu', channels=channels)
        assert not mask[nan_uv].any()
        if channels == 'uv':
            assert mask[nan_green].all()
            reference = segment(uv, scene.green, '32FC1', '32FC1', scene.circle, method='sector-otsu')
            np.testing.assert_array_equal(mask, reference)
        else:
            assert not mask[nan_green].any()


def test_saturated_green_is_clamped_not_dropped(scene_factory, encoder):
    scene = scene_factory(4, mineral=False)
    uv, green = _images(scene, encoder, green_level=0.95)
    cloud = scene.circle & (scene.elevation > 1.0) & (scene.azimuth > 0) & (scene.azimuth < 1.5)
    green[cloud] = 255  # a cloud: bright in green, nearly invisible in UV
    params = SkylineParams(method='global', channels='uv-green', angle=-np.pi / 4, threshold=-0.5)
    segmentation = SkylineSegmenter(scene.circle, params).run(uv, green, 'mono8', 'mono8')
    expected = segmentation.contrast[cloud] > -0.5
    np.testing.assert_array_equal(segmentation.mask[cloud] == 255, expected)
    assert np.all(np.isfinite(segmentation.contrast[cloud]))
    assert expected.mean() > 0.9  # clamped at saturation the contrast is an upper bound: still sky here


@pytest.mark.parametrize('channels', ['uv', 'uv-green'])
@pytest.mark.parametrize('method', METHODS)
def test_masks_do_not_depend_on_per_channel_gain(scene_factory, encoder, method, channels):
    encode, exposure_gain = encoder
    scene = scene_factory(6, light=0.4)
    params = SkylineParams(method=method, channels=channels, threshold=-0.9 if channels == 'uv' else -0.3)
    segmenter = SkylineSegmenter(scene.circle, params)
    # Radiance: any gain per channel.
    base = segmenter.segment(scene.uv, scene.green, '32FC1', '32FC1')
    scaled = segmenter.segment(scene.uv * np.float32(123.0), scene.green * np.float32(0.004), '32FC1', '32FC1')
    assert _agreement(base, scaled, scene.circle) >= 0.999
    # 16-bit counts multiplied by 4 (no saturation reached): the same features.
    uv16 = encode(scene.uv, 'mono16', exposure_gain(scene.uv, scene.circle, 'mono16', 0.2))
    green16 = encode(scene.green, 'mono16', exposure_gain(scene.green, scene.circle, 'mono16', 0.15))
    assert uv16.max() < 65535 // 4
    base = segmenter.segment(uv16, green16, 'mono16', 'mono16')
    scaled = segmenter.segment(uv16 * np.uint16(4), green16 * np.uint16(4), 'mono16', 'mono16')
    assert _agreement(base, scaled, scene.circle) >= 0.999
    # 8-bit images of different exposure: quantisation and saturation differ, the mask hardly.
    low = segmenter.segment(*_images(scene, encoder, 'mono8', 0.5, 0.9), 'mono8', 'mono8')
    high = segmenter.segment(*_images(scene, encoder, 'mono8', 0.95, 0.4), 'mono8', 'mono8')
    assert _agreement(low, high, scene.circle) >= 0.98


@pytest.mark.parametrize('method', LOCAL_METHODS)
def test_encodings_give_consistent_masks(scene_factory, encoder, method):
    scene = scene_factory(8, light=0.3)
    segmenter = SkylineSegmenter(scene.circle, SkylineParams(method=method, channels='uv-green'))
    masks = {
        encoding: segmenter.segment(*_images(scene, encoder, encoding), encoding, encoding)
        for encoding in ('mono8', 'mono16', '32FC1')
    }
    for encoding, mask in masks.items():
        assert classification_rate(mask, scene.truth, scene.circle) >= 0.98, encoding
    assert _agreement(masks['mono8'], masks['32FC1'], scene.circle) >= 0.99
    assert _agreement(masks['mono16'], masks['32FC1'], scene.circle) >= 0.995


@pytest.fixture
def uneven_scene(scene_factory):
    """UV-only scene lit 11x brighter on one side, open to the sky (no ground) over 90 degrees of azimuth."""
    return scene_factory(0, width=200, height=200, mineral=False, light=1.2, open_sector=(0.3, 1.9))


@pytest.mark.parametrize('sectors', [8, 16, 32])
@pytest.mark.parametrize('histogram_method', ['otsu', 'min-error'])
def test_sectors_adapt_to_uneven_light_and_fall_back_where_all_is_sky(uneven_scene, encoder, histogram_method, sectors):
    scene = uneven_scene
    uv, _ = _images(scene, encoder, 'mono16')
    whole = segment(uv, None, 'mono16', None, scene.circle, method=histogram_method)
    assert classification_rate(whole, scene.truth, scene.circle) < 0.95  # one threshold cannot fit

    geometry = SkylineGeometry.from_camera(scene.camera)
    segmenter = SkylineSegmenter(geometry, SkylineParams(method=f'sector-{histogram_method}', sectors=sectors))
    result = segmenter.run(uv, None, 'mono16')
    assert classification_rate(result.mask, scene.truth, scene.circle) >= 0.99

    layout = geometry.sectors(sectors)
    width = 2 * np.pi / sectors
    all_sky = (layout.centres - width / 2 >= 0.3) & (layout.centres + width / 2 <= 1.9)
    assert all_sky.sum() >= sectors // 8  # 90 degrees open: at least one whole sector in 8
    assert not result.sectors.bimodal[all_sky].any()
    assert result.sectors.bimodal[~all_sky].mean() >= 0.8
    for k in np.flatnonzero(all_sky):
        pixels = scene.circle & (layout.index == k)
        if histogram_method == 'otsu':
            own = result.contrast[pixels] > result.sectors.own.threshold[k]
            assert own.mean() < 0.9  # the sector's own threshold would cut its sky in two
        assert (result.mask[pixels] == 255).mean() >= 0.99  # the fallback keeps it sky


def test_without_any_bimodal_sector_the_global_threshold_is_used(scene_factory, encoder):
    scene = scene_factory(9, mineral=False, open_sector=(-np.pi, np.pi))  # nothing but sky
    assert (scene.truth[scene.circle] == 255).all()
    uv, green = _images(scene, encoder)
    own_only = segment(uv, green, 'mono8', 'mono8', scene.circle, method='sector-otsu')
    assert classification_rate(own_only, scene.truth, scene.circle) < 0.9  # a histogram cannot tell
    with_global = SkylineSegmenter(scene.circle, SkylineParams(method='sector-otsu', threshold=-1.2)).run(
        uv, green, 'mono8', 'mono8'
    )
    assert not with_global.sectors.bimodal.any()
    np.testing.assert_array_equal(with_global.sectors.thresholds, -1.2)
    assert classification_rate(with_global.mask, scene.truth, scene.circle) == 1.0
    whole = segment(uv, green, 'mono8', 'mono8', scene.circle, method='otsu', threshold=-1.2)
    assert classification_rate(whole, scene.truth, scene.circle) == 1.0


def test_sector_thresholds_have_no_seams(uneven_scene, encoder):
    scene = uneven_scene
    uv, _ = _images(scene, encoder, 'mono16')
    geometry = SkylineGeometry.from_camera(scene.camera)
    result = SkylineSegmenter(geometry, SkylineParams(method='sector-otsu', sectors=16)).run(uv, None, 'mono16')
    layout = geometry.sectors(16)
    smooth = result.threshold
    stepped = result.sectors.thresholds[layout.index]
    v, u = np.mgrid[0 : scene.circle.shape[0], 0 : scene.circle.shape[1]]
    away = scene.circle & (np.hypot(u - scene.camera.cx, v - scene.camera.cy) > 20)
    pair = away[:, 1:] & away[:, :-1]
    largest_step = np.max(np.abs(np.diff(np.r_[result.sectors.thresholds, result.sectors.thresholds[0]])))
    assert largest_step > 0.1
    assert np.max(np.abs(np.diff(stepped, axis=1))[pair]) == pytest.approx(largest_step, rel=0.3)
    # 20 px from the centre a pixel step is at most 1/20 rad of azimuth, about 1/8 of a sector.
    assert np.max(np.abs(np.diff(smooth, axis=1))[pair]) < 0.2 * largest_step
    # At the sector centres the interpolated threshold is the sector's own.
    phi = geometry.azimuth()
    for k in range(16):
        near = away & (np.abs(np.angle(np.exp(1j * (phi - layout.centres[k])))) < 0.01)
        if near.any():
            np.testing.assert_allclose(smooth[near], result.sectors.thresholds[k], atol=0.03 * largest_step)


def test_sector_layout_follows_the_azimuth_convention():
    circle = np.ones((21, 21), bool)
    geometry = SkylineGeometry(circle, (10.0, 10.0))
    layout = geometry.sectors(4)  # sectors start at phi = -pi: [-pi, -pi/2), [-pi/2, 0), [0, pi/2), [pi/2, pi)
    assert layout.index[10, 20] == 2  # +u: phi = 0 (robot forward)
    assert layout.index[20, 10] == 3  # +v: phi = pi/2 (robot left)
    assert layout.index[10, 0] in (0, 3)  # -u: phi = +-pi
    assert layout.index[0, 10] == 1  # -v: phi = -pi/2
    np.testing.assert_allclose(layout.centres, [-3 * np.pi / 4, -np.pi / 4, np.pi / 4, 3 * np.pi / 4])
    assert layout.lower[20, 20] == 2 and layout.weight[20, 20] == pytest.approx(0.0, abs=1e-6)  # a centre
    assert layout.lower[10, 20] == 1 and layout.weight[10, 20] == pytest.approx(0.5)  # between centres 1, 2
    np.testing.assert_allclose(layout.interpolate(np.array([0.0, 1.0, 3.0, 2.0]))[10, 20], 2.0)


def test_geometry_from_camera_and_from_circle(scene_factory):
    scene = scene_factory(0)
    geometry = SkylineGeometry.from_camera(scene.camera)
    assert geometry.centre == (scene.camera.cx, scene.camera.cy)
    np.testing.assert_array_equal(geometry.circle, scene.circle)
    estimated = SkylineGeometry.from_circle(scene.circle)
    assert estimated.centre == pytest.approx(geometry.centre, abs=0.5)
    assert geometry.sectors(8) is geometry.sectors(8)  # built once


def test_bad_input_raises_clear_errors(scene_factory, encoder):
    scene = scene_factory(0, width=64, height=48)
    uv, green = _images(scene, encoder)
    circle = scene.circle
    with pytest.raises(ValueError, match='unknown image encoding'):
        segment(uv, green, 'rgb8', 'mono8', circle)
    with pytest.raises(ValueError, match='differ in shape'):
        segment(uv, green[:, :-1], 'mono8', 'mono8', circle, channels='uv-green')
    with pytest.raises(ValueError, match='differ in shape'):
        segment(uv, green[:, :-1], 'mono8', 'mono8', circle, channels='uv')
    with pytest.raises(ValueError, match='differ in shape'):
        segment(uv, green, 'mono8', 'mono8', circle[:-1])
    with pytest.raises(ValueError, match='no finite pixel'):
        segment(np.full(uv.shape, np.nan, np.float32), None, '32FC1', None, circle)
    # all dark, all saturated: refused for the exposure (skynav_skyline.exposure) before anything is counted
    with pytest.raises(ExposureError, match='underexposed'):
        segment(np.zeros_like(uv), None, 'mono8', None, circle)
    with pytest.raises(ExposureError, match='overexposed'):
        segment(np.full_like(uv, 255), None, 'mono8', None, circle)
    # half saturated, the rest dark but for 50 pixels: an exposure within the bounds, too few pixels measured
    inside = np.flatnonzero(np.asarray(circle, bool))
    few = np.zeros_like(uv)
    few.flat[inside[: inside.size // 2]] = 255
    few.flat[inside[inside.size // 2 : inside.size // 2 + 50]] = 100
    with pytest.raises(ValueError, match='trusted pixels'):
        segment(few, None, 'mono8', None, circle)
    with pytest.raises(ValueError, match='needs the green image'):
        segment(uv, None, 'mono8', None, circle, channels='uv-green')
    with pytest.raises(ValueError, match='learned threshold'):
        SkylineParams(method='global')
    with pytest.raises(ValueError, match='unknown skyline method'):
        SkylineParams(method='sector-magic')
    with pytest.raises(ValueError, match='angle 0'):
        SkylineParams(channels='uv', angle=-0.7)
    with pytest.raises(ValueError, match='unknown channel mode'):
        SkylineParams(channels='green')


def test_classification_rate_counts_only_the_image_circle():
    circle = np.array([[True, True, False], [True, True, False]])
    truth = np.array([[255, 0, 255], [255, 0, 0]], np.uint8)
    mask = np.array([[255, 255, 0], [255, 0, 255]], np.uint8)
    assert classification_rate(mask, truth, circle) == 0.75
    with pytest.raises(ValueError, match='differ in shape'):
        classification_rate(mask[:, :2], truth, circle)
    with pytest.raises(ValueError, match='empty'):
        classification_rate(mask, truth, np.zeros_like(circle))


def test_black_level_is_removed_per_channel(scene_factory, encoder):
    scene = scene_factory(12, mineral=False)
    uv, green = _images(scene, encoder, 'mono16', 0.4, 0.4)
    assert max(uv.max(), green.max()) < 65535 - 2000  # no wrap-around below
    lifted_uv, lifted_green = uv + np.uint16(2000), green + np.uint16(700)
    params = SkylineParams(method='otsu', channels='uv-green')
    plain = SkylineSegmenter(scene.circle, params).run(uv, green, 'mono16', 'mono16')
    removed = SkylineSegmenter(scene.circle, replace(params, black_level=(2000, 700))).run(
        lifted_uv, lifted_green, 'mono16', 'mono16'
    )
    kept = SkylineSegmenter(scene.circle, params).run(lifted_uv, lifted_green, 'mono16', 'mono16')
    trusted = scene.circle & (uv > 600) & (green > 600)
    np.testing.assert_allclose(removed.contrast[trusted], plain.contrast[trusted], atol=1e-4)
    assert np.max(np.abs(kept.contrast - plain.contrast)[trusted]) > 0.3  # the offset dims the ground's contrast
    assert _agreement(plain.mask, removed.mask, scene.circle) >= 0.999


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-3, 3), min_size=16, max_size=16), st.integers(0, 2**32 - 1))
def test_sky_by_sector_thresholds_equals_comparing_with_the_interpolated_map(thresholds, seed):
    geometry = SkylineGeometry(np.ones((40, 60), bool), (29.5, 19.5))
    layout = geometry.sectors(16)
    thresholds = np.array(thresholds)
    interpolated = layout.interpolate(thresholds)
    rng = np.random.default_rng(seed)
    contrast = rng.uniform(-4, 4, geometry.shape).astype(np.float32)
    # Values at and one float32 step either side of every pixel's own threshold: the band's edge cases.
    pick = rng.random(geometry.shape)
    contrast = np.where(pick < 0.2, interpolated, contrast)
    contrast = np.where((pick >= 0.2) & (pick < 0.3), np.nextafter(interpolated, np.float32(np.inf)), contrast)
    contrast = np.where((pick >= 0.3) & (pick < 0.4), np.nextafter(interpolated, np.float32(-np.inf)), contrast)
    np.testing.assert_array_equal(above_sector_thresholds(contrast, layout, thresholds), contrast > interpolated)


@pytest.mark.parametrize('histogram_method', ['otsu', 'min-error'])
def test_sector_mask_is_the_contrast_above_the_returned_threshold_map(uneven_scene, encoder, histogram_method):
    uv, green = _images(uneven_scene, encoder, 'mono16')
    params = SkylineParams(method=f'sector-{histogram_method}', channels='uv-green', threshold=-0.8, max_deviation=0.3)
    segmenter = SkylineSegmenter(SkylineGeometry.from_camera(uneven_scene.camera), params)
    result = segmenter.run(uv, green, 'mono16', 'mono16')
    features = segmenter.features(uv, green, 'mono16', 'mono16')
    circle = uneven_scene.circle
    expected = features.sky_by_rule(circle) | (
        features.by_threshold(circle, True) & (result.contrast > result.threshold)
    )
    np.testing.assert_array_equal(result.mask == 255, expected)
    np.testing.assert_array_equal(segmenter.segment(uv, green, 'mono16', 'mono16'), result.mask)


def test_sector_thresholds_alone_equal_the_segmenters(uneven_scene, encoder):
    uv, _ = _images(uneven_scene, encoder, 'mono16')
    geometry = SkylineGeometry.from_camera(uneven_scene.camera)
    segmenter = SkylineSegmenter(geometry, SkylineParams(method='sector-min-error', sectors=12))
    result = segmenter.run(uv, None, 'mono16')
    trusted = segmenter.features(uv, None, 'mono16').trusted(uneven_scene.circle, False)
    whole_bimodal = bool(is_bimodal(result.image_split, min_pixels=100))  # else the reference is not trusted
    alone = sector_thresholds(
        result.contrast,
        trusted,
        geometry.sectors(12),
        result.sectors.reference,
        'min-error',
        test_reference=whole_bimodal,
    )
    np.testing.assert_array_equal(alone.bimodal, result.sectors.bimodal)
    np.testing.assert_allclose(alone.thresholds, result.sectors.thresholds, rtol=1e-12)
