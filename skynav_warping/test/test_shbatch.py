# SPDX-License-Identifier: Apache-2.0
"""Batched per-hypothesis rotations against skynav_sh's own rotation."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from skynav_core.rotations import zyz_angles, zyz_matrix
from skynav_sh.basis import n_coefficients
from skynav_sh.rotation import rotate, rotate_z
from skynav_warping.shbatch import rotate_columns, rotate_z_columns


def test_each_column_turns_as_skynav_sh_rotates():
    degree = 12
    rng = np.random.default_rng(3)
    coefficients = rng.standard_normal((n_coefficients(degree), 2, 6))  # (n, terms, hypotheses)
    matrices = Rotation.random(6, random_state=4).as_matrix()
    matrices[0] = np.eye(3)
    matrices[1] = np.diag([1.0, -1.0, -1.0])  # beta = 180 degrees, the other gimbal end
    turned = rotate_columns(coefficients, matrices)
    for i, matrix in enumerate(matrices):
        np.testing.assert_allclose(turned[..., i].T, rotate(coefficients[..., i].T, matrix), atol=1e-12)


def test_z_steps_per_column():
    rng = np.random.default_rng(5)
    coefficients = rng.standard_normal((n_coefficients(8), 3))
    angles = np.array([0.0, 0.4, -2.0])
    turned = rotate_z_columns(coefficients, angles)
    for i, angle in enumerate(angles):
        np.testing.assert_allclose(turned[:, i], rotate_z(coefficients[:, i], angle), atol=1e-13)


def test_zyz_angles_rebuild_the_matrices():
    matrices = Rotation.random(20, random_state=6).as_matrix()
    for matrix, angles in zip(matrices, zip(*zyz_angles(matrices))):
        np.testing.assert_allclose(zyz_matrix(*angles), matrix, atol=1e-12)
