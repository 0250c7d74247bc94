# SPDX-License-Identifier: Apache-2.0
"""Rotation invariance of the amplitude spectrum and bispectrum; the distances."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from skynav_sh.basis import n_coefficients
from skynav_sh.rotation import rotate
from skynav_sh.spectra import (
    BISPECTRUM_BATCH,
    amplitude_distance,
    amplitude_spectrum,
    bispectrum,
    bispectrum_distance,
    bispectrum_size,
    bispectrum_triples,
    coefficient_distance,
    illumination_invariant,
)
from skynav_sh.transform import grid, synthesis_at

quaternions = st.tuples(*(st.floats(-1, 1, allow_nan=False) for _ in range(4))).map(np.array)


def random_rotation(quaternion: np.ndarray) -> np.ndarray:
    assume(np.linalg.norm(quaternion) > 0.1)
    return Rotation.from_quat(quaternion / np.linalg.norm(quaternion)).as_matrix()


def degree_parts(coefficients: np.ndarray, degree: int) -> np.ndarray:
    """Samples of every degree's part f_l on a grid exact for triple products (independent of spectra.py)."""
    g = grid(2 * degree)
    parts = []
    for l in range(degree + 1):
        part = np.zeros(n_coefficients(degree))
        part[l * l : (l + 1) ** 2] = coefficients[l * l : (l + 1) ** 2]
        parts.append(g.synthesis(part))
    return g, np.array(parts)


def sphere_integral(samples: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Midpoint rule over the sphere of samples (..., rings, 2 rings) at ring angles theta (rad): value x sr."""
    cell = (np.pi / theta.size) ** 2  # dtheta dphi; the solid angle of a cell is sin(theta) dtheta dphi
    return np.sum(samples * np.sin(theta)[:, None], axis=(-2, -1)) * cell


def midpoint_directions(rings: int) -> tuple[np.ndarray, np.ndarray]:
    """Return the ring angles theta (rings,) and the unit directions (rings, 2 rings, 3) of a midpoint grid.

    Independent of the Gauss-Legendre grid of the transform: exact in azimuth for band-limited functions, and
    second order in theta (relative error 2e-5 at 150 rings here).
    """
    theta = (np.arange(rings) + 0.5) * np.pi / rings
    phi = (np.arange(2 * rings) + 0.5) * np.pi / rings
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    return theta, np.stack(np.broadcast_arrays(st * np.cos(phi), st * np.sin(phi), ct), axis=-1)


def test_amplitude_spectrum_is_the_root_of_each_degree_part_s_squared_integral():
    # Parseval on the sphere: A_l^2 = integral of f_l^2 over the sphere (sr), f_l the degree-l part of f
    degree = 6
    coefficients = np.random.default_rng(17).standard_normal(n_coefficients(degree))
    parts = np.zeros((degree + 1, coefficients.size))
    for l in range(degree + 1):
        parts[l, l * l : (l + 1) ** 2] = coefficients[l * l : (l + 1) ** 2]
    theta, directions = midpoint_directions(150)
    expected = np.sqrt(sphere_integral(synthesis_at(parts, directions) ** 2, theta))
    np.testing.assert_allclose(amplitude_spectrum(coefficients), expected, rtol=5e-5)


def test_amplitude_spectrum_of_known_functions():
    # f = 3 + 2 z: the constant's A_0^2 = 9 * 4 pi, z's A_1^2 = 4 * integral of z^2 = 4 * 4 pi / 3
    g = grid(4)
    z = g.directions()[..., 2]
    spectrum = amplitude_spectrum(g.analysis(3.0 + 2.0 * z))
    np.testing.assert_allclose(spectrum[:2], [3 * np.sqrt(4 * np.pi), 2 * np.sqrt(4 * np.pi / 3)], rtol=1e-12)
    np.testing.assert_allclose(spectrum[2:], 0.0, atol=1e-12)


@settings(max_examples=40, deadline=None, database=None)
@given(quaternion=quaternions, degree=st.integers(1, 16), seed=st.integers(0, 2**32 - 1))
def test_amplitude_spectrum_is_rotation_invariant(quaternion, degree, seed):
    coefficients = np.random.default_rng(seed).standard_normal(n_coefficients(degree))
    spectrum = amplitude_spectrum(coefficients)
    turned = amplitude_spectrum(rotate(coefficients, random_rotation(quaternion)))
    np.testing.assert_allclose(turned, spectrum, rtol=1e-10, atol=1e-12)


@settings(max_examples=40, deadline=None, database=None)
@given(quaternion=quaternions, degree=st.integers(1, 12), seed=st.integers(0, 2**32 - 1))
def test_bispectrum_is_rotation_invariant(quaternion, degree, seed):
    coefficients = np.random.default_rng(seed).standard_normal(n_coefficients(degree))
    b = bispectrum(coefficients)
    turned = bispectrum(rotate(coefficients, random_rotation(quaternion)))
    assert np.abs(turned - b).max() <= 1e-10 * np.abs(b).max()


def test_bispectrum_invariance_at_degree_32():
    coefficients = np.random.default_rng(11).standard_normal(n_coefficients(32))
    matrix = Rotation.from_euler('ZYZ', [0.3, 2.0, -2.5]).as_matrix()
    b = bispectrum(coefficients)
    assert np.abs(bispectrum(rotate(coefficients, matrix)) - b).max() <= 1e-10 * np.abs(b).max()


def test_bispectrum_is_the_triple_integral_of_degree_parts():
    degree = 7
    coefficients = np.random.default_rng(12).standard_normal(n_coefficients(degree))
    g, parts = degree_parts(coefficients, degree)
    triples = bispectrum_triples(degree)
    expected = np.array([g.integrate(parts[a] * parts[b] * parts[c]) for a, b, c in triples])
    np.testing.assert_allclose(bispectrum(coefficients), expected, atol=1e-12)
    np.testing.assert_allclose(bispectrum(coefficients, method='gaunt'), expected, atol=1e-12)


def test_bispectrum_triples_and_count():
    for degree in (0, 1, 5, 16):
        triples = bispectrum_triples(degree)
        brute = {
            (a, b, c)
            for a in range(degree + 1)
            for b in range(degree + 1)
            for c in range(degree + 1)
            if a <= b <= c <= a + b and (a + b + c) % 2 == 0
        }
        assert set(map(tuple, triples)) == brute and len(triples) == len(brute) == bispectrum_size(degree)
    assert [bispectrum_size(d) for d in (16, 32)] == [285, 1785]


def test_bispectrum_of_a_constant():
    coefficients = np.zeros(n_coefficients(3))
    coefficients[0] = 2.0
    b = bispectrum(coefficients)
    assert b[0] == pytest.approx(8.0 / np.sqrt(4 * np.pi), rel=1e-14)  # integral of (2 Y00)^3
    assert np.all(np.abs(b[1:]) < 1e-15)


def test_bispectrum_tells_apart_what_the_amplitude_spectrum_cannot():
    # same amplitude spectrum (a per-degree orthogonal map that is no rotation), different bispectrum
    rng = np.random.default_rng(13)
    degree = 6
    f = rng.standard_normal(n_coefficients(degree))
    g = f.copy()
    for l in range(2, degree + 1):
        part = slice(l * l, (l + 1) ** 2)
        q, _ = np.linalg.qr(rng.standard_normal((2 * l + 1, 2 * l + 1)))
        g[part] = q @ f[part]
    assert amplitude_distance(f, g) < 1e-20
    assert bispectrum_distance(f, g) > 1e-3 * np.sum(bispectrum(f) ** 2)


def test_batched_descriptors():
    coefficients = np.random.default_rng(14).standard_normal((2, 3, n_coefficients(5)))
    assert amplitude_spectrum(coefficients).shape == (2, 3, 6)
    b = bispectrum(coefficients)
    assert b.shape == (2, 3, bispectrum_size(5))
    np.testing.assert_allclose(b[1, 2], bispectrum(coefficients[1, 2]), atol=1e-14)
    np.testing.assert_allclose(bispectrum(coefficients, method='gaunt'), b, atol=1e-12)


def test_bispectra_of_many_views_go_in_batches_with_the_same_numbers():
    coefficients = np.random.default_rng(17).standard_normal((2 * BISPECTRUM_BATCH + 3, n_coefficients(6)))
    b = bispectrum(coefficients)
    np.testing.assert_allclose(b, bispectrum(coefficients, method='gaunt'), atol=1e-12)
    np.testing.assert_allclose(b[-1], bispectrum(coefficients[-1]), atol=1e-14)
    assert bispectrum(coefficients[:0]).shape == (0, bispectrum_size(6))


def test_coefficient_distance_is_the_integral_squared_error():
    rng = np.random.default_rng(15)
    degree = 8
    f, g = rng.standard_normal((2, n_coefficients(degree)))
    quadrature = grid(degree)
    integral = quadrature.integrate((quadrature.synthesis(f) - quadrature.synthesis(g)) ** 2)
    assert coefficient_distance(f, g) == pytest.approx(integral, rel=1e-12)
    assert amplitude_distance(f, g) <= coefficient_distance(f, g)  # reverse triangle inequality per degree


def test_illumination_invariant_ignores_gain_and_offset():
    rng = np.random.default_rng(16)
    f = rng.standard_normal(n_coefficients(6))
    brighter = 3.7 * f
    brighter[0] += 5.0  # a constant offset only changes c_00
    np.testing.assert_allclose(illumination_invariant(brighter), illumination_invariant(f), atol=1e-15)
    assert np.linalg.norm(illumination_invariant(f)) == pytest.approx(1.0)
    assert np.all(illumination_invariant(np.eye(1, 49)[0]) == 0)  # only c_00: stays zero, no division by zero
