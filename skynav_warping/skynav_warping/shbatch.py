# SPDX-License-Identifier: Apache-2.0
"""Batched SH rotations with one rotation per hypothesis (camera_link, contract basis), coefficient axis first.

skynav_sh.rotate turns a whole batch by one rotation; a warping search needs a different rotation per hypothesis.
Arrays here hold the coefficient index on axis 0 and hypotheses on the last axis, c[(L+1)^2, ..., M]: the sparse
quarter turn J then multiplies one contiguous (n, K) block and the elementwise z-steps run along long rows.
rotate_zyz_columns(c, a, b, g) turns column i (c[..., i]) by
Rz(a_i) Ry(b_i) Rz(g_i) with the convention of skynav_sh.rotate (coefficients of f(R^T d)): z-steps are
elementwise cos/sin of m * angle (skynav_sh.rotation.z_rotation_factors), the y-step is J Z(b) J^T with skynav_sh's
cached quarter turn applied by skynav_sh.rotation.apply_sparse along axis 0.
"""

from __future__ import annotations

import numpy as np

from skynav_core.rotations import zyz_angles
from skynav_sh.basis import degree_from_size
from skynav_sh.rotation import apply_sparse, quarter_turn_sparse, z_rotation_factors


def rotate_z_columns(c: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Return c (n, ..., M) with column i turned by angles[i] (rad) about +z: g(theta, phi) = f(theta, phi - a_i)."""
    # factors (n, 1.., M) broadcast over the middle axes: the sines and cosines of each angle are taken once, not
    # once per middle index (the products are the same, element by element)
    cos, sin, partner = z_rotation_factors(degree_from_size(c.shape[0]), np.asarray(angles, dtype=float))
    middle = (1,) * (c.ndim - 2)
    out = cos.reshape(cos.shape[:1] + middle + cos.shape[1:]) * c
    out += sin.reshape(out.shape[:1] + middle + sin.shape[1:]) * c[partner]
    return out


def rotate_zyz_columns(c: np.ndarray, alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Return c (n, ..., M) with column i turned by Rz(alpha_i) Ry(beta_i) Rz(gamma_i) (rad; skynav_sh convention)."""
    forward, backward = quarter_turn_sparse(degree_from_size(c.shape[0]))
    c = apply_sparse(backward, rotate_z_columns(np.asarray(c, dtype=float), gamma), axis=0)
    return rotate_z_columns(apply_sparse(forward, rotate_z_columns(c, beta), axis=0), alpha)


def rotate_columns(c: np.ndarray, matrices: np.ndarray) -> np.ndarray:
    """Return c (n, ..., M) with column i turned by the rotation matrix matrices[i] (coefficients of f(R_i^T d))."""
    return rotate_zyz_columns(c, *zyz_angles(matrices))
