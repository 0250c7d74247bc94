# SPDX-License-Identifier: Apache-2.0
"""Merging exposure brackets into linear radiance."""

from __future__ import annotations

import numpy as np
import pytest

from skynav_skyline.hdr import merge_brackets

TIMES = np.array([0.5e-3, 4e-3, 32e-3])  # exposure times (s), three stops apart


def _brackets(radiance, encoding, scale, black_level=0):
    """Linear brackets of `radiance` (counts per second = radiance * scale), rounded, offset and clipped."""
    full = {'mono8': 255, 'mono16': 65535}[encoding]
    dtype = {'mono8': np.uint8, 'mono16': np.uint16}[encoding]
    return [np.clip(np.round(radiance * scale * t) + black_level, 0, full).astype(dtype) for t in TIMES]


@pytest.fixture
def radiance():
    rng = np.random.default_rng(0)
    return np.exp(rng.uniform(np.log(1.0), np.log(300.0), (40, 50))).astype(np.float32)


@pytest.mark.parametrize('encoding, scale', [('mono8', 1200.0), ('mono16', 1200.0 * 257)])
def test_linear_merge_recovers_radiance(radiance, encoding, scale):
    merged = merge_brackets(_brackets(radiance, encoding, scale), TIMES, encoding)
    assert merged.dtype == np.float32 and merged.shape == radiance.shape
    # Every value is well exposed in some bracket: the brightest reach 180 of 255 counts in the shortest,
    # the dimmest 38 counts in the longest.
    relative = merged / (radiance * scale)
    assert np.max(np.abs(relative - 1)) < (0.04 if encoding == 'mono8' else 1e-3)


def test_linear_merge_honours_the_black_level(radiance):
    plain = merge_brackets(_brackets(radiance, 'mono16', 500.0), TIMES, 'mono16')
    offset = merge_brackets(_brackets(radiance, 'mono16', 500.0, black_level=1000), TIMES, 'mono16', black_level=1000)
    np.testing.assert_allclose(offset, plain, rtol=0.02)


def test_saturated_everywhere_is_a_bright_lower_bound_and_dark_everywhere_an_upper_bound():
    radiance = np.array([[1e7, 1.0, 1e-3]], np.float32)
    merged = merge_brackets(_brackets(radiance, 'mono8', 1.0), TIMES, 'mono8')
    assert merged[0, 0] == pytest.approx(255 / TIMES[0])  # the shortest exposure's saturated estimate
    assert merged[0, 0] > merged[0, 1]
    assert 0 <= merged[0, 2] <= 2 / TIMES[-1]  # dark in every bracket: at most the dark margin


def test_debevec_merge_agrees_with_the_linear_merge(radiance):
    brackets = _brackets(radiance, 'mono8', 1200.0)
    linear = merge_brackets(brackets, TIMES, 'mono8')
    debevec = merge_brackets(brackets, TIMES, 'mono8', method='debevec')
    assert debevec.dtype == np.float32
    ratio = debevec / linear
    assert np.median(np.abs(ratio - 1)) < 0.03


def test_32fc1_brackets_average_and_skip_invalid():
    a = np.array([[1.0, np.nan, 4.0]], np.float32)
    b = np.array([[2.0, 6.0, np.inf]], np.float32)
    merged = merge_brackets([a, b], [1.0, 2.0], '32FC1')
    np.testing.assert_allclose(merged, [[1.0, 3.0, 4.0]])
    assert np.isnan(merge_brackets([np.full((1, 1), np.nan, np.float32)], [1.0], '32FC1')[0, 0])


def test_bad_brackets_raise():
    image = np.zeros((4, 4), np.uint8)
    with pytest.raises(ValueError, match='exposure times'):
        merge_brackets([image, image], [1.0], 'mono8')
    with pytest.raises(ValueError, match='positive'):
        merge_brackets([image], [0.0], 'mono8')
    with pytest.raises(ValueError, match='differ in shape'):
        merge_brackets([image, np.zeros((4, 5), np.uint8)], [1.0, 2.0], 'mono8')
    with pytest.raises(ValueError, match='at least one'):
        merge_brackets([], [], 'mono8')
    with pytest.raises(ValueError, match='unknown merge method'):
        merge_brackets([image], [1.0], 'mono8', method='mertens')
    with pytest.raises(ValueError, match='mono8'):
        merge_brackets([image.astype(np.uint16)], [1.0], 'mono16', method='debevec')
