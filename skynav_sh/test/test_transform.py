# SPDX-License-Identifier: Apache-2.0
"""Exactness of the Gauss-Legendre transforms."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skynav_sh.basis import n_coefficients, real_sh_directions
from skynav_sh.transform import GaussLegendreGrid, analysis, grid, synthesis, synthesis_at


@pytest.mark.parametrize('degree', [0, 1, 2, 5, 16, 33, 64])
def test_analysis_inverts_synthesis(degree):
    rng = np.random.default_rng(degree)
    coefficients = rng.standard_normal(n_coefficients(degree))
    g = grid(degree)
    samples = g.synthesis(coefficients)
    assert samples.shape == (degree + 1, 2 * degree + 2)
    np.testing.assert_allclose(g.analysis(samples), coefficients, rtol=0, atol=1e-10)


@settings(max_examples=30, deadline=None, database=None)
@given(
    degree=st.integers(0, 24),
    extra_theta=st.integers(0, 5),
    extra_phi=st.integers(-1, 6),
    seed=st.integers(0, 2**32 - 1),
)
def test_round_trip_on_any_large_enough_grid(degree, extra_theta, extra_phi, seed):
    # n_phi = 2L + 1 (odd, the least) up to larger grids; more nodes than needed must stay exact
    coefficients = np.random.default_rng(seed).standard_normal((2, n_coefficients(degree)))
    g = GaussLegendreGrid(degree, n_phi=2 * degree + 2 + extra_phi, n_theta=degree + 1 + extra_theta)
    np.testing.assert_allclose(g.analysis(g.synthesis(coefficients)), coefficients, atol=1e-11)


def test_synthesis_matches_the_basis_sum_at_the_nodes():
    L = 9
    rng = np.random.default_rng(4)
    coefficients = rng.standard_normal(n_coefficients(L))
    g = grid(L)
    direct = real_sh_directions(L, g.directions()) @ coefficients
    np.testing.assert_allclose(g.synthesis(coefficients), direct, atol=1e-12)
    np.testing.assert_allclose(g.synthesis_at(coefficients, g.directions()), direct, atol=1e-12)


def test_analysis_of_a_basis_function_is_a_unit_vector():
    L = 6
    g = grid(L)
    basis = real_sh_directions(L, g.directions())  # (t, p, n)
    coefficients = g.analysis(np.moveaxis(basis, -1, 0))  # batch over basis functions
    np.testing.assert_allclose(coefficients, np.eye(n_coefficients(L)), atol=1e-13)


def test_lower_degree_coefficients_synthesise_on_a_larger_grid():
    coefficients = np.random.default_rng(5).standard_normal(n_coefficients(3))
    g = grid(10)
    padded = np.zeros(n_coefficients(10))
    padded[: coefficients.size] = coefficients
    np.testing.assert_allclose(g.synthesis(coefficients), g.synthesis(padded), atol=1e-14)


def test_batches_keep_their_leading_axes():
    L = 5
    rng = np.random.default_rng(6)
    coefficients = rng.standard_normal((3, 2, n_coefficients(L)))
    samples = synthesis(coefficients)
    assert samples.shape == (3, 2, L + 1, 2 * L + 2)
    np.testing.assert_allclose(samples[1, 0], synthesis(coefficients[1, 0]), atol=1e-14)
    np.testing.assert_allclose(analysis(samples), coefficients, atol=1e-12)
    directions = grid(L).directions()[:4]  # (4, n_phi, 3)
    values = synthesis_at(coefficients, directions)
    assert values.shape == (3, 2, 4, 2 * L + 2)
    np.testing.assert_allclose(values, samples[..., :4, :], atol=1e-12)


def test_quadrature_weights_integrate_polynomials():
    g = grid(20)
    assert g.weights.sum() == pytest.approx(4 * np.pi, rel=1e-14)
    z = g.directions()[..., 2]
    assert g.integrate(z**2) == pytest.approx(4 * np.pi / 3, rel=1e-13)
    assert g.integrate(z**40) == pytest.approx(4 * np.pi / 41, rel=1e-12)  # degree 40 = 2L: still exact


def test_grids_that_are_too_small_are_refused():
    with pytest.raises(ValueError):
        GaussLegendreGrid(8, n_phi=16)
    with pytest.raises(ValueError):
        GaussLegendreGrid(8, n_theta=8)
    with pytest.raises(ValueError):
        grid(4).analysis(np.zeros((4, 10)))
    with pytest.raises(ValueError):
        grid(4).synthesis(np.zeros(n_coefficients(5)))


@pytest.mark.parametrize('degree', [0, 1, 7, 16])
def test_degree_parts_are_the_syntheses_of_each_degree_alone_and_sum_to_the_function(degree):
    rng = np.random.default_rng(degree + 40)
    coefficients = rng.standard_normal((3, n_coefficients(degree)))
    g = grid(degree + 3)  # a larger grid than the coefficients need
    parts = g.degree_parts(coefficients)
    assert parts.shape == (3, degree + 1, *g.shape)
    for l in range(degree + 1):
        alone = np.zeros_like(coefficients)
        alone[:, l * l : (l + 1) ** 2] = coefficients[:, l * l : (l + 1) ** 2]
        np.testing.assert_allclose(parts[:, l], g.synthesis(alone), atol=1e-12)
    np.testing.assert_allclose(parts.sum(axis=1), g.synthesis(coefficients), atol=1e-11)
    np.testing.assert_array_equal(g.degree_parts(coefficients, rings=2), parts[..., :2, :])
