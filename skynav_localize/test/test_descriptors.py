# SPDX-License-Identifier: Apache-2.0
"""Place descriptors: exact rotation invariance, the documented normalisation, and vectorised distances."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from skynav_localize.descriptors import (
    DescriptorIndex,
    amplitude_descriptor,
    bispectrum_descriptor,
    bispectrum_size,
    describe,
    descriptor_distance,
    distance_matrix,
)
from skynav_sh.basis import degree_order, n_coefficients
from skynav_sh.rotation import rotate

quaternions = st.tuples(*(st.floats(-1, 1, allow_nan=False) for _ in range(4))).map(np.array)


def view(degree: int, seed: int) -> np.ndarray:
    """Random coefficients with a skyline-like spectrum (amplitude falling as 1 / (l + 1))."""
    l, _ = degree_order(degree)
    return np.random.default_rng(seed).standard_normal(n_coefficients(degree)) / (l + 1.0)


def unit_quaternion(quaternion: np.ndarray) -> np.ndarray:
    assume(np.linalg.norm(quaternion) > 0.1)
    return quaternion / np.linalg.norm(quaternion)


@settings(max_examples=30, deadline=None, database=None)
@given(quaternion=quaternions, degree=st.integers(2, 24), seed=st.integers(0, 2**32 - 1))
def test_amplitude_descriptor_is_rotation_invariant(quaternion, degree, seed):
    coefficients = view(degree, seed)
    turned = rotate(coefficients, unit_quaternion(quaternion))
    np.testing.assert_allclose(amplitude_descriptor(turned), amplitude_descriptor(coefficients), rtol=0, atol=1e-12)


@settings(max_examples=20, deadline=None, database=None)
@given(quaternion=quaternions, degree=st.integers(2, 16), seed=st.integers(0, 2**32 - 1))
def test_bispectrum_descriptor_is_rotation_invariant(quaternion, degree, seed):
    coefficients = view(degree, seed)
    turned = rotate(coefficients, unit_quaternion(quaternion))
    # log(1 + |b| / s) is linear near 0, so rounding errors of the bispectrum stay at rounding level
    np.testing.assert_allclose(bispectrum_descriptor(turned), bispectrum_descriptor(coefficients), rtol=0, atol=1e-9)


def test_descriptors_of_a_real_skyline_are_invariant_to_tilt_and_heading(garden):
    coefficients = garden['teach'].coefficients[::20]
    rotations = Rotation.from_euler('ZYZ', [[1.0, 0.35, -2.0], [-2.5, 0.5, 0.4], [3.0, 0.17, 1.0], [0.2, 0.52, 0.0]])
    turned = np.array([rotate(c, r.as_matrix()) for c, r in zip(coefficients, rotations)])
    np.testing.assert_allclose(amplitude_descriptor(turned), amplitude_descriptor(coefficients), atol=1e-12)
    np.testing.assert_allclose(bispectrum_descriptor(turned), bispectrum_descriptor(coefficients), atol=1e-9)


@pytest.mark.parametrize('name', ['amplitude', 'bispectrum'])
def test_normalisation_drops_sky_fraction_and_scale(name):
    coefficients = view(12, 3)
    reference = describe(name, coefficients)
    assert np.linalg.norm(reference) == pytest.approx(1.0)
    shifted = coefficients.copy()
    shifted[0] += 2.0  # more sky everywhere changes c_00 only
    np.testing.assert_allclose(describe(name, shifted), reference, atol=1e-12)
    np.testing.assert_allclose(describe(name, 3.5 * coefficients), reference, atol=1e-12)
    assert describe(name, coefficients).shape == ((12,) if name == 'amplitude' else (bispectrum_size(12),))


def test_no_skyline_gives_the_zero_descriptor():
    all_sky = np.zeros(n_coefficients(8))
    all_sky[0] = np.sqrt(4 * np.pi)
    assert not np.any(amplitude_descriptor(all_sky)) and not np.any(bispectrum_descriptor(all_sky))


def test_descriptors_are_vectorised_and_truncate_to_a_lower_degree():
    batch = np.array([view(10, seed) for seed in range(5)])
    np.testing.assert_allclose(amplitude_descriptor(batch), [amplitude_descriptor(c) for c in batch])
    np.testing.assert_allclose(bispectrum_descriptor(batch), [bispectrum_descriptor(c) for c in batch], atol=1e-12)
    np.testing.assert_allclose(describe('amplitude', batch, 6), amplitude_descriptor(batch[:, :49]))
    with pytest.raises(ValueError, match='degree 10 cannot give descriptors of degree 12'):
        describe('amplitude', batch, 12)
    with pytest.raises(ValueError, match='unknown SH descriptor'):
        describe('colour', batch)


@pytest.mark.parametrize('metric', ['euclidean', 'sad', 'cosine'])
def test_distance_matrix_matches_pairwise_distances(metric):
    rng = np.random.default_rng(5)
    snapshots = rng.standard_normal((40, 7))
    queries = rng.standard_normal((6, 7))
    if metric == 'cosine':
        snapshots /= np.linalg.norm(snapshots, axis=1, keepdims=True)
        queries /= np.linalg.norm(queries, axis=1, keepdims=True)
    expected = descriptor_distance(queries[:, None, :], snapshots[None, :, :], metric)
    np.testing.assert_allclose(distance_matrix(queries, snapshots, metric), expected, atol=1e-10)
    index = DescriptorIndex(snapshots, metric)
    np.testing.assert_allclose(index.distances(queries[2]), expected[2], atol=1e-10)
    assert len(index) == 40 and index.dimension == 7
    with pytest.raises(ValueError, match='queries must be'):
        index.distance_matrix(queries[:, :3])
