# SPDX-License-Identifier: Apache-2.0
"""Decoding of mono8/mono16/32FC1 images, trust flags and the per-channel normalisation."""

from __future__ import annotations

import numpy as np
import pytest

from skynav_skyline.features import DARK_MARGIN_COUNTS, decode, extract_features, log_feature, reference_level


def test_mono8_flags_and_black_level():
    image = np.array([[0, 5, 6, 7, 100, 254, 255]], np.uint8)
    channel = decode(image, 'mono8', black_level=4)
    assert DARK_MARGIN_COUNTS['mono8'] == 2
    np.testing.assert_array_equal(channel.dark, [[True, True, True, False, False, False, False]])
    np.testing.assert_array_equal(channel.saturated, [[False] * 6 + [True]])
    assert not channel.invalid.any()
    np.testing.assert_array_equal(channel.linear, [[-4, 1, 2, 3, 96, 250, 251]])
    assert channel.linear.dtype == np.float32
    np.testing.assert_array_equal(channel.trusted, [[False, False, False, True, True, True, False]])


def test_mono16_flags_scale_with_the_full_range():
    image = np.array([[0, 514, 515, 40000, 65534, 65535]], np.uint16)
    channel = decode(image, 'mono16')
    np.testing.assert_array_equal(channel.dark, [[True, True, False, False, False, False]])
    np.testing.assert_array_equal(channel.saturated, [[False] * 5 + [True]])


def test_32fc1_nan_and_inf_are_invalid_and_non_positive_is_dark():
    image = np.array([[np.nan, np.inf, -np.inf, -1.0, 0.0, 0.5, 2.0]], np.float32)
    channel = decode(image, '32FC1')
    np.testing.assert_array_equal(channel.invalid, [[True, True, True, False, False, False, False]])
    np.testing.assert_array_equal(channel.dark, [[False, False, False, True, True, False, False]])
    assert not channel.saturated.any()
    assert channel.floor == 0.5  # dark pixels are clamped to the dimmest trusted value
    assert np.all(np.isfinite(channel.linear))


@pytest.mark.parametrize('encoding', ['rgb8', 'bgr8', '8UC1', 'MONO8', '', 'mono32'])
def test_unknown_encoding_raises(encoding):
    with pytest.raises(ValueError, match='unknown image encoding'):
        decode(np.zeros((4, 4), np.uint8), encoding)


@pytest.mark.parametrize(
    'encoding, dtype', [('mono8', np.uint16), ('mono16', np.uint8), ('mono8', np.float32), ('32FC1', np.uint8)]
)
def test_dtype_not_matching_the_encoding_raises(encoding, dtype):
    with pytest.raises(ValueError, match='dtype'):
        decode(np.zeros((4, 4), dtype), encoding)


def test_bad_shapes_raise():
    circle = np.ones((4, 5), bool)
    with pytest.raises(ValueError, match='differ in shape'):
        extract_features(np.zeros((4, 5), np.uint8), np.zeros((5, 4), np.uint8), 'mono8', 'mono8', circle)
    with pytest.raises(ValueError, match='differ in shape'):
        extract_features(np.zeros((4, 4), np.uint8), None, 'mono8', None, circle)
    with pytest.raises(ValueError, match='2-D'):
        decode(np.zeros((4, 4, 3), np.uint8), 'mono8')
    with pytest.raises(ValueError, match='black level'):
        decode(np.zeros((4, 4), np.uint8), 'mono8', black_level=254)


def test_all_nan_image_raises_a_clear_error():
    circle = np.ones((6, 6), bool)
    image = np.full((6, 6), np.nan, np.float32)
    with pytest.raises(ValueError, match='no finite pixel'):
        extract_features(image, None, '32FC1', None, circle)


def test_reference_level_is_the_percentile_inside_the_circle():
    image = np.arange(100, dtype=np.float32).reshape(10, 10) + 1
    circle = np.zeros((10, 10), bool)
    circle[:5] = True  # values 1..50
    channel = decode(image, '32FC1')
    assert reference_level(channel, circle, 90) == 45.0
    assert reference_level(channel, circle, 100) == 50.0


def test_normalised_features_do_not_depend_on_channel_gain(scene_factory):
    scene = scene_factory(3)
    base = extract_features(scene.uv, scene.green, '32FC1', '32FC1', scene.circle)
    scaled = extract_features(
        scene.uv * np.float32(37.0), scene.green * np.float32(0.013), '32FC1', '32FC1', scene.circle
    )
    inside = scene.circle
    np.testing.assert_allclose(scaled.x[inside], base.x[inside], atol=1e-5)
    np.testing.assert_allclose(scaled.y[inside], base.y[inside], atol=1e-5)


def test_normalised_features_agree_across_encodings(scene_factory, encoder):
    encode, exposure_gain = encoder
    scene = scene_factory(5)
    features = {}
    for encoding in ('mono8', 'mono16', '32FC1'):
        uv = encode(scene.uv, encoding, exposure_gain(scene.uv, scene.circle, encoding, 0.8))
        green = encode(scene.green, encoding, exposure_gain(scene.green, scene.circle, encoding, 0.7))
        features[encoding] = extract_features(uv, green, encoding, encoding, scene.circle)
    # Compare where the 8-bit values are trusted and not too coarsely quantised (>= 20 counts).
    well_exposed = scene.circle & features['mono8'].uv.trusted & (features['mono8'].uv.linear >= 20)
    for encoding in ('mono8', 'mono16'):
        error = np.abs(features[encoding].x - features['32FC1'].x)[well_exposed]
        assert np.max(error) < 0.06  # 8-bit rounding: at most 0.5 / 20 counts, plus the percentile's own rounding
    assert np.max(np.abs(features['mono16'].x - features['32FC1'].x)[well_exposed]) < 1e-3


def test_dark_pixels_are_clamped_not_infinite():
    image = np.array([[0, 1, 2, 3, 200]], np.uint8)
    channel = decode(image, 'mono8')
    feature = log_feature(channel, np.ones_like(image, bool), 100)
    assert np.all(np.isfinite(feature))
    assert feature[0, 0] == feature[0, 1] == feature[0, 2] == pytest.approx(np.log(2 / 200))


@pytest.mark.parametrize('encoding, dtype', [('mono8', np.uint8), ('mono16', np.uint16), ('32FC1', np.float32)])
@pytest.mark.parametrize('percentile', [0.5, 50.0, 90.0, 100.0])
def test_reference_level_equals_numpy_inverted_cdf_percentile_for_every_encoding(encoding, dtype, percentile):
    rng = np.random.default_rng(7)
    top = 255 if dtype is np.uint8 else 65535
    image = rng.integers(3 * (top // 255), top, size=(40, 50)).astype(dtype)
    circle = rng.random((40, 50)) < 0.7
    channel = decode(image, encoding)
    expected = np.percentile(channel.linear[circle], percentile, method='inverted_cdf')
    assert reference_level(channel, circle, percentile) == expected
    every_third = circle.copy()
    every_third[:, np.arange(50) % 3 != 0] = False
    expected = np.percentile(channel.linear[every_third], percentile, method='inverted_cdf')
    assert reference_level(channel, circle, percentile, stride=3) == expected
