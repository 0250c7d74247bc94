# SPDX-License-Identifier: Apache-2.0
"""Translation operator against resampling the translated view."""

from __future__ import annotations

import numpy as np
import pytest

from skynav_sh.basis import degree_order, n_coefficients
from skynav_sh.rotation import rotate
from skynav_sh.transform import grid
from skynav_sh.translation import source_directions, translate, translate_z, translated_directions, z_translation_blocks

DEGREE = 16


def natural_view(degree: int, seed: int) -> np.ndarray:
    """Random coefficients with a natural-image-like spectrum, amplitude ~ 1 / (l + 1)."""
    l, _ = degree_order(degree)
    return np.random.default_rng(seed).standard_normal(n_coefficients(degree)) / (1.0 + l)


def resampled_translation(coefficients: np.ndarray, tau: np.ndarray, grid_degree: int) -> np.ndarray:
    """Sample g(d') = f(d) with normalise(d - tau) = d' on a grid of grid_degree, transform, keep degrees <= L."""
    g = grid(grid_degree)
    values = g.synthesis_at(coefficients, source_directions(g.directions(), tau))
    return g.analysis(values)[..., : coefficients.shape[-1]]


@pytest.mark.parametrize('ratio', [0.05, 0.2, 0.5, 0.8])
def test_translation_equals_resampling(ratio, record_property):
    direction = np.array([0.4, -0.7, 0.6])
    tau = ratio * direction / np.linalg.norm(direction)
    f = natural_view(DEGREE, 22)
    predicted = translate(f, tau)
    # the translated view is not band-limited: the reference grid must be finer than degree L (4L here)
    fine = resampled_translation(f, tau, 4 * DEGREE)
    error = np.linalg.norm(predicted - fine) / np.linalg.norm(fine)
    # on the grid of degree L itself the reference is aliased; this is what a same-size resampling would cost
    coarse = resampled_translation(f, tau, DEGREE)
    aliased = np.linalg.norm(coarse - fine) / np.linalg.norm(fine)
    record_property('relative_error', float(error))
    record_property('same_grid_resampling_error', float(aliased))
    assert error < 1e-10
    assert aliased > 100 * error  # the operator is the better of the two


def test_points_move_as_the_contract_says():
    rng = np.random.default_rng(23)
    d = rng.standard_normal((50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tau = np.array([0.1, 0.3, -0.2])
    moved = translated_directions(d, tau)
    np.testing.assert_allclose(source_directions(moved, tau), d, atol=1e-14)
    # a scene point at distance rho seen from the camera moved by t: direction of rho d - t
    rho, t = 5.0, 5.0 * tau
    np.testing.assert_allclose(moved, (rho * d - t) / np.linalg.norm(rho * d - t, axis=1, keepdims=True))


def test_general_direction_is_the_rotated_z_step():
    f = natural_view(10, 24)
    np.testing.assert_allclose(translate(f, [0.0, 0.0, 0.3]), translate_z(f, 0.3), atol=1e-13)
    # stepping along -z equals turning the view upside down, stepping along +z, turning back
    half_turn = np.diag([1.0, -1.0, -1.0])
    np.testing.assert_allclose(
        translate(f, [0.0, 0.0, -0.3]), rotate(translate_z(rotate(f, half_turn), 0.3), half_turn), atol=1e-12
    )


def test_no_step_and_constant_views():
    f = natural_view(8, 25)
    np.testing.assert_allclose(translate(f, np.zeros(3)), f)
    for m, block in enumerate(z_translation_blocks(8, 0.0)):
        np.testing.assert_allclose(block, np.eye(9 - m), atol=1e-13)
    constant = np.zeros(n_coefficients(8))
    constant[0] = 1.0
    np.testing.assert_allclose(translate(constant, [0.2, 0.1, -0.5]), constant, atol=1e-13)


def test_quadrature_has_converged():
    default = z_translation_blocks(20, 0.7)
    denser = z_translation_blocks(20, 0.7, n_nodes=300)  # about 2.5 times the default's nodes
    assert max(np.abs(a - b).max() for a, b in zip(default, denser)) < 1e-11


def test_batches_and_bad_ratios():
    f = np.stack([natural_view(6, 26), natural_view(6, 27)])
    tau = [0.2, -0.1, 0.1]
    np.testing.assert_allclose(translate(f, tau)[1], translate(f[1], tau), atol=1e-14)
    with pytest.raises(ValueError):
        translate(f, [0.0, 0.0, 1.0])
