# SPDX-License-Identifier: Apache-2.0
"""Basis values against scipy, orthonormality, index helpers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import assoc_legendre_p, sph_harm_y

from skynav_core.camera import directions_from_angles
from skynav_sh.basis import (
    degree_from_size,
    degree_order,
    degree_slices,
    lm_index,
    n_coefficients,
    normalised_legendre,
    real_sh,
    real_sh_directions,
)
from skynav_sh.transform import grid


def contract_real_sh_from_scipy(max_degree: int, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """The contract's real basis built from scipy's complex Y_l^m (scipy's sph_harm_y(n, m, theta, phi), CS phase)."""
    columns = []
    for l in range(max_degree + 1):
        for m in range(-l, l + 1):
            # scipy's Y_l^|m| = (-1)^|m| N P_l^|m| e^{i|m| phi}: undo the Condon-Shortley phase
            y = sph_harm_y(l, abs(m), theta, phi) * (-1.0) ** abs(m)
            if m == 0:
                columns.append(y.real)
            elif m > 0:
                columns.append(np.sqrt(2) * y.real)
            else:
                columns.append(np.sqrt(2) * y.imag)
    return np.stack(columns, axis=-1)


def test_index_helpers_are_consistent():
    L = 7
    l, m = degree_order(L)
    assert l.size == n_coefficients(L) == 64
    assert np.array_equal(lm_index(l, m), np.arange(64))
    assert np.all(np.abs(m) <= l)
    for degree, part in enumerate(degree_slices(L)):
        assert np.all(l[part] == degree)
        assert np.array_equal(m[part], np.arange(-degree, degree + 1))
    assert degree_from_size(64) == 7
    with pytest.raises(ValueError):
        degree_from_size(63)


def test_real_sh_matches_scipy_in_the_contract_form():
    rng = np.random.default_rng(1)
    theta = np.concatenate([rng.uniform(0, np.pi, 200), [0.0, np.pi, np.pi / 2]])
    phi = np.concatenate([rng.uniform(-np.pi, np.pi, 200), [0.3, -2.0, 1.0]])
    L = 10
    np.testing.assert_allclose(real_sh(L, theta, phi), contract_real_sh_from_scipy(L, theta, phi), atol=1e-13)


def test_real_sh_written_out_for_low_degrees():
    # the contract's formulas by hand: Y_11 ~ x, Y_1-1 ~ y, Y_10 ~ z, Y_2-2 ~ xy (no Condon-Shortley sign)
    rng = np.random.default_rng(2)
    d = rng.standard_normal((50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    y = real_sh_directions(2, d)
    c1 = np.sqrt(3 / (4 * np.pi))
    np.testing.assert_allclose(y[:, 0], 1 / np.sqrt(4 * np.pi))
    np.testing.assert_allclose(y[:, 1:4], c1 * d[:, [1, 2, 0]], atol=1e-14)
    np.testing.assert_allclose(y[:, 4], np.sqrt(15 / (4 * np.pi)) * d[:, 0] * d[:, 1], atol=1e-14)


def test_normalised_legendre_matches_scipy_without_phase():
    x = np.linspace(-1, 1, 41)
    L = 12
    table = normalised_legendre(L, x)
    assert table.shape == (41, L + 1, L + 1)
    from math import factorial

    for l in range(L + 1):
        for m in range(L + 1):
            if m > l:
                assert np.all(table[:, l, m] == 0)
                continue
            norm = np.sqrt((2 * l + 1) / (4 * np.pi) * factorial(l - m) / factorial(l + m))
            reference = norm * assoc_legendre_p(l, m, x)[0] * (-1.0) ** m  # value row; scipy includes (-1)^m
            np.testing.assert_allclose(table[:, l, m], reference, atol=1e-12, rtol=1e-12)


def test_legendre_is_orthonormal_at_degree_128():
    # integral over x of Pbar_lm Pbar_l'm = delta_ll' / (2 pi) for every order m; Gauss-Legendre with 129 nodes is exact
    L = 128
    x, w = np.polynomial.legendre.leggauss(L + 1)
    table = normalised_legendre(L, x)
    assert np.all(np.isfinite(table))
    worst = 0.0
    for m in range(L + 1):
        block = table[:, m:, m]
        gram = 2 * np.pi * (block * w[:, None]).T @ block
        worst = max(worst, np.abs(gram - np.eye(L + 1 - m)).max())
    assert worst < 1e-11


def test_real_sh_is_orthonormal_on_the_sphere():
    L = 12
    g = grid(L)
    basis = real_sh(L, g.theta[:, None], g.phi[None, :]).reshape(-1, n_coefficients(L))
    gram = (basis * g.weights.reshape(-1, 1)).T @ basis
    np.testing.assert_allclose(gram, np.eye(n_coefficients(L)), atol=1e-13)


def test_unsold_sum_is_constant_per_degree():
    # sum_m Y_lm(d)^2 = (2l+1)/(4 pi) at every direction: the bound the fish-eye tests rely on
    rng = np.random.default_rng(3)
    d = directions_from_angles(rng.uniform(0, np.pi, 30), rng.uniform(-np.pi, np.pi, 30))
    y = real_sh_directions(20, d)
    sums = np.add.reduceat(y**2, np.arange(21) ** 2, axis=-1)
    np.testing.assert_allclose(sums, np.broadcast_to((2 * np.arange(21) + 1) / (4 * np.pi), sums.shape), rtol=1e-12)
