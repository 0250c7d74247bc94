# SPDX-License-Identifier: Apache-2.0
"""Real Wigner-D matrices and rotations of coefficients against resampling the rotated function."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from skynav_core.rotations import as_matrix, zyz_angles, zyz_matrix
from skynav_sh.basis import degree_slices, n_coefficients
from skynav_sh.rotation import (
    quarter_turn,
    rotate,
    rotate_y,
    rotate_z,
    rotate_zyz,
    wigner_d,
    wigner_d_matrix,
    wigner_d_recurrence,
    y_rotation_block,
)
from skynav_sh.transform import grid

quaternions = st.tuples(*(st.floats(-1, 1, allow_nan=False) for _ in range(4))).map(np.array)


def rotation_of(quaternion: np.ndarray) -> np.ndarray:
    assume(np.linalg.norm(quaternion) > 0.1)
    return Rotation.from_quat(quaternion / np.linalg.norm(quaternion)).as_matrix()


def resampled_rotation(coefficients: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Coefficients of g(d) = f(R^T d): sample f at R^T d on the grid, transform (exact: g has the same degree)."""
    degree = int(np.sqrt(coefficients.shape[-1])) - 1
    g = grid(degree)
    turned_back = g.directions() @ matrix  # row vectors: d^T R = (R^T d)^T
    return g.analysis(g.synthesis_at(coefficients, turned_back))


@settings(max_examples=40, deadline=None, database=None)
@given(quaternion=quaternions, degree=st.integers(0, 14), seed=st.integers(0, 2**32 - 1))
def test_rotate_equals_resampling_the_rotated_function(quaternion, degree, seed):
    matrix = rotation_of(quaternion)
    coefficients = np.random.default_rng(seed).standard_normal(n_coefficients(degree))
    expected = resampled_rotation(coefficients, matrix)
    np.testing.assert_allclose(rotate(coefficients, matrix), expected, atol=1e-10 * max(1, np.abs(expected).max()))


def test_rotate_at_degree_48_equals_resampling():
    matrix = Rotation.from_euler('ZYZ', [2.1, 0.7, -1.2]).as_matrix()
    coefficients = np.random.default_rng(7).standard_normal(n_coefficients(48))
    np.testing.assert_allclose(rotate(coefficients, matrix), resampled_rotation(coefficients, matrix), atol=1e-10)


def test_convention_on_a_linear_function():
    # f(d) = a . d has coefficients proportional to (a_y, a_z, a_x); f(R^T d) = (R a) . d
    a = np.array([0.3, -1.2, 0.5])
    matrix = Rotation.from_rotvec([0.4, 0.9, -0.3]).as_matrix()
    scale = np.sqrt(4 * np.pi / 3)
    coefficients = np.concatenate([[0.0], scale * a[[1, 2, 0]]])
    turned = rotate(coefficients, matrix)
    np.testing.assert_allclose(turned[1:] / scale, (matrix @ a)[[1, 2, 0]], atol=1e-14)


def test_compass_convention_snapshot_from_current():
    # the camera turns so that d_snapshot = R d_current; a scene direction s seen at d_c is seen at d_s = R d_c,
    # so f_snapshot(d_s) = f_current(R^T d_s): f_snapshot = rotate(f_current, R)
    rng = np.random.default_rng(8)
    f_current = rng.standard_normal(n_coefficients(6))
    matrix = Rotation.from_rotvec([0.0, 0.3, 1.1]).as_matrix()
    f_snapshot = rotate(f_current, matrix)
    d_current = rng.standard_normal((20, 3))
    d_current /= np.linalg.norm(d_current, axis=1, keepdims=True)
    d_snapshot = d_current @ matrix.T
    np.testing.assert_allclose(
        grid(6).synthesis_at(f_snapshot, d_snapshot), grid(6).synthesis_at(f_current, d_current), atol=1e-12
    )


@settings(max_examples=30, deadline=None, database=None)
@given(first=quaternions, second=quaternions, degree=st.integers(1, 12))
def test_wigner_d_is_orthogonal_and_a_representation(first, second, degree):
    r1, r2 = rotation_of(first), rotation_of(second)
    d1, d2, d12 = wigner_d(r1, degree), wigner_d(r2, degree), wigner_d(r1 @ r2, degree)
    for l in range(degree + 1):
        np.testing.assert_allclose(d1[l] @ d1[l].T, np.eye(2 * l + 1), atol=1e-12)
        np.testing.assert_allclose(d1[l] @ d2[l], d12[l], atol=1e-12)
    assert np.abs(np.linalg.det(wigner_d_matrix(r1, degree)) - 1) < 1e-10


@settings(max_examples=30, deadline=None, database=None)
@given(quaternion=quaternions, degree=st.integers(0, 20))
def test_recurrence_agrees_with_zyz_factorisation(quaternion, degree):
    matrix = rotation_of(quaternion)
    for a, b in zip(wigner_d_recurrence(matrix, degree), wigner_d(matrix, degree)):
        np.testing.assert_allclose(a, b, atol=1e-12)


def test_input_forms_agree():
    rotation = Rotation.from_rotvec([0.2, -0.5, 0.9])
    coefficients = np.random.default_rng(9).standard_normal(n_coefficients(5))
    by_matrix = rotate(coefficients, rotation.as_matrix())
    np.testing.assert_allclose(rotate(coefficients, rotation.as_quat()), by_matrix, atol=1e-13)  # (x, y, z, w)
    np.testing.assert_allclose(rotate(coefficients, rotation), by_matrix, atol=1e-13)
    np.testing.assert_allclose(rotate_zyz(coefficients, *rotation.as_euler('ZYZ')), by_matrix, atol=1e-13)
    np.testing.assert_allclose(zyz_matrix(*zyz_angles(rotation)), rotation.as_matrix(), atol=1e-14)
    with pytest.raises(ValueError):
        as_matrix(np.zeros(3))


@settings(max_examples=25, deadline=None, database=None)
@given(angle=st.floats(-7, 7), degree=st.integers(0, 16), seed=st.integers(0, 2**32 - 1))
def test_z_and_y_paths_equal_the_general_rotation(angle, degree, seed):
    coefficients = np.random.default_rng(seed).standard_normal(n_coefficients(degree))
    about_z = Rotation.from_rotvec([0, 0, angle]).as_matrix()
    about_y = Rotation.from_rotvec([0, angle, 0]).as_matrix()
    np.testing.assert_allclose(rotate_z(coefficients, angle), resampled_rotation(coefficients, about_z), atol=1e-11)
    np.testing.assert_allclose(rotate_y(coefficients, angle), rotate(coefficients, about_y), atol=1e-11)
    np.testing.assert_allclose(rotate_y(coefficients, angle), resampled_rotation(coefficients, about_y), atol=1e-11)
    by_blocks = np.concatenate(
        [y_rotation_block(l, angle) @ coefficients[part] for l, part in enumerate(degree_slices(degree))]
    )
    np.testing.assert_allclose(by_blocks, rotate_y(coefficients, angle), atol=1e-11)


def test_z_rotation_mixes_only_plus_minus_m_pairs():
    coefficients = np.zeros(n_coefficients(4))
    coefficients[16 + 4 + 3] = 1.0  # l = 4, m = 3: cos(3 phi)
    turned = rotate_z(coefficients, 0.25)
    assert set(np.flatnonzero(np.abs(turned) > 1e-15)) == {16 + 4 + 3, 16 + 4 - 3}
    np.testing.assert_allclose(turned[[23, 17]], [np.cos(0.75), np.sin(0.75)], atol=1e-15)


def test_batched_rotation():
    matrix = Rotation.from_rotvec([1.0, 0.5, -0.2]).as_matrix()
    coefficients = np.random.default_rng(10).standard_normal((3, 2, n_coefficients(7)))
    turned = rotate(coefficients, matrix)
    assert turned.shape == coefficients.shape
    np.testing.assert_allclose(turned[2, 1], rotate(coefficients[2, 1], matrix), atol=1e-14)


def test_quarter_turn_is_orthogonal_at_degree_128():
    # the Jacobi-polynomial small-d keeps J_l orthogonal to high degree (the plain recurrence drifts there)
    turns = quarter_turn(128)
    worst = max(np.abs(j @ j.T - np.eye(j.shape[0])).max() for j in turns[96:])
    assert worst < 1e-11
    # J maps the polar axis onto +y: the l = 1 block acts on (y, z, x) like Rx(-90 deg)
    np.testing.assert_allclose(turns[1] @ np.array([0.0, 1.0, 0.0]), [1.0, 0.0, 0.0], atol=1e-15)
