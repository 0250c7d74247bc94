# SPDX-License-Identifier: Apache-2.0
"""The padded layout and its rotations against the flat ones: one z-step table, one sparse product, one rotation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_sh.basis import degree_order
from skynav_sh.layouts import from_padded, to_padded
from skynav_sh.rotation import (
    apply_sparse,
    quarter_turn_sparse,
    rotate,
    rotate_by_matrix,
    rotate_degree_major,
    rotate_y,
    rotate_z,
    rotate_z_padded,
    z_rotation_factors,
    z_rotation_factors_padded,
)

DEGREE = 8


def random_coefficients(seed: int, degree: int = DEGREE) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal((degree + 1) ** 2)


def test_padded_round_trip_and_truncation():
    c = random_coefficients(0)
    assert np.array_equal(from_padded(to_padded(c)), c)
    assert np.array_equal(from_padded(to_padded(c, 5)), c[:36])
    extended = from_padded(to_padded(c, 10))
    assert np.array_equal(extended[:81], c) and not extended[81:].any()


@pytest.mark.parametrize('seed', range(3))
def test_padded_rotation_matches_the_flat_one(seed):
    c = random_coefficients(seed)
    r = Rotation.random(random_state=seed)
    assert np.allclose(from_padded(rotate_by_matrix(to_padded(c), r.as_matrix())), rotate(c, r), atol=1e-12)
    assert np.allclose(from_padded(rotate_z_padded(to_padded(c), 0.7)), rotate_z(c, 0.7), atol=1e-13)


def test_z_steps_of_both_layouts_read_the_same_factors():
    angles = np.array([[0.3, -1.2], [2.5, 7.0]])
    cos, sin, partner = z_rotation_factors(DEGREE, angles)  # (n, 2, 2)
    padded_cos, padded_sin = z_rotation_factors_padded(DEGREE, angles)  # (2, 2, 2L+1)
    l, m = degree_order(DEGREE)
    assert np.array_equal(cos, np.moveaxis(padded_cos[..., m + DEGREE], -1, 0))
    assert np.array_equal(sin, np.moveaxis(padded_sin[..., m + DEGREE], -1, 0))
    c = random_coefficients(5)
    turned = rotate_z_padded(to_padded(c), angles)  # (2, 2, L+1, 2L+1)
    for index in np.ndindex(angles.shape):
        expected = rotate_z(c, angles[index])
        assert np.array_equal(cos[(slice(None),) + index] * c + sin[(slice(None),) + index] * c[partner], expected)
        assert np.allclose(from_padded(turned[index]), expected, atol=1e-13)


def test_sparse_product_along_either_axis():
    forward, _ = quarter_turn_sparse(DEGREE)
    c = np.random.default_rng(6).standard_normal((3, 4, (DEGREE + 1) ** 2))
    last = apply_sparse(forward, c)
    first = apply_sparse(forward, np.ascontiguousarray(np.moveaxis(c, -1, 0)), axis=0)
    dense = forward.toarray()
    assert np.allclose(last, c @ dense.T, atol=1e-14)
    assert np.array_equal(np.moveaxis(first, 0, -1), last)
    assert np.allclose(rotate_y(c, 0.9), rotate(c, Rotation.from_euler('y', 0.9)), atol=1e-12)


def test_degree_first_rotation_matches_rotate_by_matrix():
    l, _ = degree_order(DEGREE)
    rng = np.random.default_rng(7)
    padded = to_padded(rng.standard_normal((3, l.size)) / (1.0 + l))  # (3, L+1, 2L+1)
    by_degree = np.ascontiguousarray(padded.transpose(1, 0, 2))
    matrices = np.concatenate(
        [
            Rotation.random(5, random_state=3).as_matrix(),
            Rotation.from_euler('ZYZ', [[0.3, 0.0, 0.2], [0.3, np.pi, -1.0], [0, np.pi / 2, 0]]).as_matrix(),
            np.eye(3)[None],
        ]
    )
    expected = rotate_by_matrix(padded, matrices)  # (K, 3, L+1, 2L+1)
    assert np.allclose(rotate_degree_major(by_degree, matrices).transpose(0, 2, 1, 3), expected, atol=1e-12)
    assert np.allclose(rotate_degree_major(by_degree, matrices[0]).transpose(1, 0, 2), expected[0], atol=1e-12)
