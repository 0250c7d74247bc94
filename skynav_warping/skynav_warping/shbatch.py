# SPDX-License-Identifier: Apache-2.0
"""Batched SH rotations with one rotation per hypothesis (camera_link, contract basis), coefficient axis first.

skynav_sh.rotate turns a whole batch by one rotation; a warping search needs a different rotation per hypothesis.
Arrays here hold the coefficient index on axis 0 and hypotheses on the last axis, c[(L+1)^2, ..., M]: the sparse
quarter turn J then multiplies one contiguous (n, K) block and the elementwise z-steps run along long rows.
rotate_zyz_columns(c, a, b, g) turns column i (c[..., i]) by
Rz(a_i) Ry(b_i) Rz(g_i) with the convention of skynav_sh.rotate (coefficients of f(R^T d)): z-steps are
elementwise cos/sin of m * angle, the y-step is J Z(b) J^T with skynav_sh's cached quarter turn.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from skynav_core.rotations import zyz_angles
from skynav_sh.basis import degree_from_size, degree_order
from skynav_sh.rotation import quarter_turn_sparse, z_rotation_index


@lru_cache(maxsize=16)
def _signed_order(max_degree: int) -> np.ndarray:
    """Return, per flat index, the row of the table [sin(|m| a) for m >= 0; -sin(|m| a) for m > 0] it reads."""
    _, m = degree_order(max_degree)
    # the sine term enters with sign -1 for m > 0 (cosine-type) and +1 for m <= 0: rows L + 1 .. 2L hold -sin
    return np.where(m > 0, max_degree + m, -m)


def z_factors(max_degree: int, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return cos(|m| a) and signed sin(|m| a), shape (n,) + angles.shape, and the partner index; angles in rad."""
    L = int(max_degree)
    order, _, partner = z_rotation_index(L)
    multiple = np.arange(L + 1).reshape((-1,) + (1,) * np.ndim(angles)) * np.asarray(angles, dtype=float)
    sin = np.sin(multiple)
    # one gather per table (no full-size temporaries): the signs sit in the small table
    return np.cos(multiple)[order], np.concatenate([sin, -sin[1:]])[_signed_order(L)], partner


def rotate_z_columns(c: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Return c (n, ..., M) with column i turned by angles[i] (rad) about +z: g(theta, phi) = f(theta, phi - a_i)."""
    # factors (n, 1.., M) broadcast over the middle axes: the sines and cosines of each angle are taken once, not
    # once per middle index (the products are the same, element by element)
    cos, sin, partner = z_factors(degree_from_size(c.shape[0]), np.asarray(angles, dtype=float))
    middle = (1,) * (c.ndim - 2)
    out = cos.reshape(cos.shape[:1] + middle + cos.shape[1:]) * c
    out += sin.reshape(out.shape[:1] + middle + sin.shape[1:]) * c[partner]
    return out


def apply_sparse(matrix, c: np.ndarray) -> np.ndarray:
    """Return matrix @ c over the coefficient axis 0 of c (n, ...)."""
    return (matrix @ c.reshape(c.shape[0], -1)).reshape(c.shape)


def rotate_zyz_columns(c: np.ndarray, alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Return c (n, ..., M) with column i turned by Rz(alpha_i) Ry(beta_i) Rz(gamma_i) (rad; skynav_sh convention)."""
    forward, backward = quarter_turn_sparse(degree_from_size(c.shape[0]))
    c = apply_sparse(backward, rotate_z_columns(np.asarray(c, dtype=float), gamma))
    return rotate_z_columns(apply_sparse(forward, rotate_z_columns(c, beta)), alpha)


def rotate_columns(c: np.ndarray, matrices: np.ndarray) -> np.ndarray:
    """Return c (n, ..., M) with column i turned by the rotation matrix matrices[i] (coefficients of f(R_i^T d))."""
    return rotate_zyz_columns(c, *zyz_angles(matrices))
