# SPDX-License-Identifier: Apache-2.0
"""The compass's SO(3) machinery against skynav_sh: complex form, Wigner small d, generators, the FFT correlation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_compass.so3 import (
    EulerGrid,
    complex_form,
    correlation_products,
    generators,
    so3_correlation,
    wigner_small_d_table,
)
from skynav_sh.layouts import to_padded
from skynav_sh.rotation import rotate, rotate_by_matrix, rotate_z_padded, wigner_small_d

DEGREE = 8


def random_coefficients(seed: int, degree: int = DEGREE) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal((degree + 1) ** 2)


def test_complex_form_diagonalises_z_rotations():
    c = to_padded(random_coefficients(4))
    m = np.arange(-DEGREE, DEGREE + 1)
    assert np.allclose(complex_form(rotate_z_padded(c, 0.3)), np.exp(1j * m * 0.3) * complex_form(c), atol=1e-13)


def test_wigner_table_matches_skynav_sh():
    betas = (0.0, 0.4, 1.7, np.pi)
    table = wigner_small_d_table(DEGREE, betas)
    for b, beta in enumerate(betas):
        for l in range(DEGREE + 1):
            block = table[b, l, DEGREE - l : DEGREE + l + 1, DEGREE - l : DEGREE + l + 1]
            assert np.allclose(block, wigner_small_d(l, beta), atol=1e-13)


@pytest.mark.parametrize('axis', range(3))
def test_generators_are_derivatives_of_rotations(axis):
    c = to_padded(random_coefficients(7))
    h = 1e-6
    w = np.zeros(3)
    w[axis] = h
    numeric = (
        rotate_by_matrix(c, Rotation.from_rotvec(w).as_matrix())
        - rotate_by_matrix(c, Rotation.from_rotvec(-w).as_matrix())
    ) / (2 * h)
    analytic = np.matmul(generators(DEGREE)[axis], c[..., None])[..., 0]
    assert np.allclose(numeric, analytic, atol=1e-7)


def test_fft_correlation_equals_direct_inner_products():
    a, b = random_coefficients(1), random_coefficients(2)
    grid = EulerGrid.create(DEGREE, oversampling=1.0)
    values = so3_correlation(correlation_products(to_padded(a)[None], to_padded(b)[None])[None], grid)[0]
    assert values.shape == grid.shape
    rng = np.random.default_rng(3)
    for _ in range(10):
        index = tuple(int(rng.integers(n)) for n in grid.shape)
        alpha, beta, gamma = grid.angles(index)
        turned = rotate(b, Rotation.from_euler('ZYZ', [alpha, beta, gamma]))
        assert values[index] == pytest.approx(float(a @ turned), abs=1e-10)


def test_euler_grid_limits_beta_and_uses_fast_sizes():
    grid = EulerGrid.create(16, max_beta=np.radians(60))
    assert grid.n >= 33 and grid.n % 2 == 0
    assert grid.betas[0] == 0.0 and grid.betas[-1] == pytest.approx(np.radians(60))
    assert np.all(np.diff(grid.betas) <= grid.step + 1e-12)
