# SPDX-License-Identifier: Apache-2.0
"""Rotations of real SH coefficients (camera_link): real Wigner-D matrices, fast z- and y-rotations.

Convention: rotate(c, R) returns the coefficients of g(d) = f(R^T d), the function f turned by R
(so if d_snapshot = R d_current, the compass convention, then f_snapshot = rotate(f_current, R)).
The per-degree matrices D_l(R) of this action satisfy D(R1 R2) = D(R1) D(R2) and are orthogonal.
A rotation is given as a scipy Rotation, a 3x3 matrix or a quaternion (x, y, z, w) as ROS and scipy order it;
ZYZ Euler angles (alpha, beta, gamma) mean R = Rz(alpha) Ry(beta) Rz(gamma) (scipy 'ZYZ', intrinsic). The rotation
maths itself (matrices, quaternions, ZYZ angles) lives in skynav_core.rotations.
Both coefficient layouts turn here: the flat (..., (L+1)^2) one of the contract (rotate, rotate_z, ...) and the
padded (..., L+1, 2L+1) one of skynav_sh.layouts (rotate_z_padded, rotate_by_matrix, rotate_degree_major); their
z-steps read the same cos(m alpha), sin(m alpha) table (z_phases), indexed per layout.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.linalg import block_diag as dense_block_diag
from scipy.sparse import block_diag as sparse_block_diag
from scipy.special import eval_jacobi, gammaln

from skynav_core.rotations import RotationLike, as_matrix, zyz_angles
from skynav_sh.basis import degree_from_size, degree_order, degree_slices

# --- Ivanic-Ruedenberg recurrence (J. Phys. Chem. 100, 6342 (1996), with the 1998 erratum) ---------------


def _degree_one(matrix: np.ndarray) -> np.ndarray:
    """Return D_1(R): the l = 1 real SH are proportional to (y, z, x) (no Condon-Shortley phase)."""
    order = [1, 2, 0]
    return matrix[np.ix_(order, order)]


def _next_degree(d1: np.ndarray, previous: np.ndarray, l: int) -> np.ndarray:
    """Return D_l from D_1 and D_(l-1) by the Ivanic-Ruedenberg recurrence, vectorised over (m, n)."""
    size = 2 * l + 1
    # prev_pad[a + l + 1, :] = D_(l-1)[a, :] for |a| <= l - 1, zero rows for |a| = l, l + 1
    prev_pad = np.zeros((2 * l + 3, 2 * l - 1))
    prev_pad[2 : 2 * l + 1] = previous

    def p_matrix(i: int) -> np.ndarray:
        # P(i, a, b) for all a (padded rows) and b = -l..l (columns)
        out = np.empty((2 * l + 3, size))
        out[:, 1:-1] = d1[i + 1, 1] * prev_pad
        out[:, -1] = d1[i + 1, 2] * prev_pad[:, -1] - d1[i + 1, 0] * prev_pad[:, 0]
        out[:, 0] = d1[i + 1, 2] * prev_pad[:, 0] + d1[i + 1, 0] * prev_pad[:, -1]
        return out

    p_minus, p_zero, p_plus = p_matrix(-1), p_matrix(0), p_matrix(1)
    m = np.arange(-l, l + 1)
    n = np.arange(-l, l + 1)
    row = lambda a: a + l + 1  # noqa: E731 - padded row of order a

    abs_m = np.abs(m).astype(float)
    delta_m0 = (m == 0).astype(float)
    denominator = np.where(np.abs(n) == l, 2.0 * l * (2 * l - 1), (l + n) * (l - n)).astype(float)
    u = np.sqrt(((l + m) * (l - m))[:, None] / denominator[None, :])
    v = (
        0.5
        * np.sqrt(((1 + delta_m0) * (l + abs_m - 1) * (l + abs_m))[:, None] / denominator[None, :])
        * (1 - 2 * delta_m0)[:, None]
    )
    w = (
        -0.5
        * np.sqrt((np.clip(l - abs_m - 1, 0, None) * (l - abs_m))[:, None] / denominator[None, :])
        * (1 - delta_m0)[:, None]
    )

    big_u = p_zero[row(m)]
    big_v = np.empty((size, size))
    big_w = np.zeros((size, size))
    positive, negative = m > 0, m < 0
    mp, mn = m[positive], m[negative]
    big_v[m == 0] = p_plus[row(1)] + p_minus[row(-1)]
    big_v[positive] = (
        p_plus[row(mp - 1)] * np.sqrt(1.0 + (mp == 1))[:, None] - p_minus[row(-mp + 1)] * (1.0 - (mp == 1))[:, None]
    )
    big_v[negative] = (
        p_plus[row(mn + 1)] * (1.0 - (mn == -1))[:, None] + p_minus[row(-mn - 1)] * np.sqrt(1.0 + (mn == -1))[:, None]
    )
    inner_p = positive & (m <= l - 2)
    inner_n = negative & (m >= -(l - 2))
    mp, mn = m[inner_p], m[inner_n]
    big_w[inner_p] = p_plus[row(mp + 1)] + p_minus[row(-mp - 1)]
    big_w[inner_n] = p_plus[row(mn - 1)] - p_minus[row(-mn + 1)]
    return u * big_u + v * big_v + w * big_w


def wigner_d_recurrence(rotation: RotationLike, max_degree: int) -> list[np.ndarray]:
    """Return [D_0, ..., D_L] by the Ivanic-Ruedenberg recurrence (a cross-check; accurate to ~1e-11 up to L = 64)."""
    # its rounding errors grow geometrically with l (measured ~1e-11 at l = 64, 1e-7..1e-5 at l = 128), so the
    # library's own path is the ZYZ factorisation with the Jacobi-based quarter turn
    matrix = as_matrix(rotation)
    blocks = [np.ones((1, 1))]
    if max_degree >= 1:
        blocks.append(_degree_one(matrix))
    for l in range(2, int(max_degree) + 1):
        blocks.append(_next_degree(blocks[1], blocks[-1], l))
    return blocks


# --- y-rotations from Wigner's small d, the fixed quarter turn and the ZYZ factorisation -----------------


def wigner_small_d(degree: int, beta: float) -> np.ndarray:
    """Return Wigner's small d^l_(m' m)(beta) (complex basis, beta in rad) as an array [m' + l, m + l]."""
    # d = xi sqrt(s! (s+mu+nu)! / ((s+mu)! (s+nu)!)) sin(beta/2)^mu cos(beta/2)^nu P_s^(mu,nu)(cos beta) with
    # mu = |m - m'|, nu = |m + m'|, s = l - (mu + nu)/2, xi = (-1)^(m' - m) for m < m'; factorials through
    # log-gamma and the Jacobi polynomial by its three-term recurrence, so it stays accurate to high degree

    l = int(degree)
    order = np.arange(-l, l + 1)
    row, col = np.meshgrid(order, order, indexing='ij')
    # symmetries d_(m'm) = (-1)^(m-m') d_(mm') = d_(-m,-m'): evaluate the wedge m' >= |m| only, then gather
    swap = np.abs(col) > np.abs(row)  # |m| > |m'|: transpose first
    p, q = np.where(swap, col, row), np.where(swap, row, col)
    sign = np.where(swap & ((row - col) % 2 == 1), -1.0, 1.0)
    negative = p < 0  # m' <= -|m|: d_(p q) = (-1)^(q - p) d_(-p, -q) with -p >= |q|
    sign = np.where(negative & ((q - p) % 2 == 1), -sign, sign)
    p, q = np.where(negative, -p, p), np.where(negative, -q, q)
    wedge_row, wedge_col = np.nonzero(np.arange(-l, l + 1)[:, None] >= np.abs(np.arange(-l, l + 1))[None, :])
    m_row, m_col = wedge_row - l, wedge_col - l
    mu, nu = np.abs(m_col - m_row), np.abs(m_col + m_row)
    s = l - (mu + nu) // 2
    wedge_sign = np.where((m_col >= m_row) | ((m_row - m_col) % 2 == 0), 1.0, -1.0)
    half_sin, half_cos = np.sin(beta / 2), np.cos(beta / 2)
    with np.errstate(divide='ignore', invalid='ignore'):
        log_size = (
            0.5 * (gammaln(s + 1) + gammaln(s + mu + nu + 1) - gammaln(s + mu + 1) - gammaln(s + nu + 1))
            + np.where(mu > 0, mu * np.log(np.abs(half_sin)), 0.0)
            + np.where(nu > 0, nu * np.log(np.abs(half_cos)), 0.0)
        )
    power_sign = np.where((mu % 2 == 1) & (half_sin < 0), -1.0, 1.0) * np.where(
        (nu % 2 == 1) & (half_cos < 0), -1.0, 1.0
    )
    wedge = np.zeros((2 * l + 1, 2 * l + 1))
    wedge[wedge_row, wedge_col] = wedge_sign * power_sign * np.exp(log_size) * eval_jacobi(s, mu, nu, np.cos(beta))
    return sign * wedge[p + l, q + l]


def y_rotation_block(degree: int, beta: float) -> np.ndarray:
    """Return the real D_l(Ry(beta)) from Wigner's small d (it mixes cos-type m >= 0 and sin-type m < 0 apart)."""
    l = int(degree)
    d = wigner_small_d(l, beta)
    c = l
    k = np.arange(1, l + 1)
    sign_k = (-1.0) ** k
    block = np.zeros((2 * l + 1, 2 * l + 1))
    block[c, c] = d[c, c]
    block[c + k, c] = (sign_k * d[c + k, c] + d[c - k, c]) / np.sqrt(2)
    block[c, c + k] = (sign_k * d[c, c + k] + d[c, c - k]) / np.sqrt(2)
    row, col = np.meshgrid(k, k, indexing='ij')
    sign_row, sign_col = (-1.0) ** row, (-1.0) ** col
    a = sign_row * sign_col * d[c + row, c + col]
    b = sign_row * d[c + row, c - col]
    e = sign_col * d[c - row, c + col]
    f = d[c - row, c - col]
    block[c + row, c + col] = 0.5 * (a + b + e + f)
    block[c - row, c - col] = 0.5 * (a - b - e + f)
    return block


def _quarter_z_step(block: np.ndarray, sign: int) -> np.ndarray:
    """Return Z_l(sign * pi/2) @ block exactly: cos(m pi/2), sin(m pi/2) are 0 or +-1, so rows only swap and flip."""
    l = (block.shape[0] - 1) // 2
    m = np.arange(-l, l + 1)
    cos = np.array([1.0, 0.0, -1.0, 0.0])[np.abs(m) % 4]
    sin = sign * np.array([0.0, 1.0, 0.0, -1.0])[np.abs(m) % 4] * np.where(m > 0, -1.0, 1.0)
    return cos[:, None] * block + sin[:, None] * block[l - m]


@lru_cache(maxsize=8)
def quarter_turn(max_degree: int) -> tuple[np.ndarray, ...]:
    """Return the cached J_l = D_l(Rx(-90 deg)) (the turn of +z onto +y) for l = 0..L, read-only, stable to high L."""
    # Q = Rx(-90 deg) turns +z onto +y, so Ry(beta) = Q Rz(beta) Q^T and D(Ry(beta)) = J Z(beta) J^T with J = D(Q);
    # Q = Rz(-90 deg) Ry(-90 deg) Rz(90 deg), so J_l = Z_l(-pi/2) D_l(Ry(pi/2))^T Z_l(pi/2)
    blocks = []
    for l in range(int(max_degree) + 1):
        m = np.arange(-l, l + 1)
        # J commutes with the mirror x -> -x (Y_lm gets (-1)^m, sin-type -(-1)^m) and takes the mirror y -> -y
        # (cos-type +1, sin-type -1) to z -> -z ((-1)^(l+m)): J[m, m'] = 0 unless both signs match, 3/4 of J
        mirror_x = np.where(m >= 0, 1, -1) * (-1) ** np.abs(m)
        mirror_y = np.where(m >= 0, 1, -1)
        mirror_z = (-1) ** ((l + np.abs(m)) % 2)
        allowed = (mirror_x[:, None] == mirror_x[None, :]) & (mirror_z[:, None] == mirror_y[None, :])
        # Z(-pi/2) Y^T Z(pi/2) = Z(-pi/2) (Z(-pi/2) Y)^T, Z(pi/2) being the transpose of Z(-pi/2)
        turned = _quarter_z_step(_quarter_z_step(y_rotation_block(l, np.pi / 2), -1).T, -1)
        block = np.where(allowed, turned, 0.0)
        block.flags.writeable = False
        blocks.append(block)
    return tuple(blocks)


# --- z-rotations: cos(m alpha), sin(m alpha) per order once; the flat and padded layouts only index them -----


@lru_cache(maxsize=16)
def z_rotation_index(max_degree: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (|m|, sign, partner index) for every flat index: the z-step pairs c_l,m with c_l,-m."""
    l, m = degree_order(max_degree)
    # a' = a cos - b sin (a = c_l,m with m > 0), b' = a sin + b cos (b = c_l,-m): sign -1 on the cos-type entries
    return np.abs(m), np.where(m > 0, -1.0, 1.0), l * l + l - m


@lru_cache(maxsize=32)
def _z_rows(max_degree: int, padded: bool) -> tuple[np.ndarray, np.ndarray]:
    """Return, per entry of the layout, its row of the cos table and of the signed sin table of z_phases."""
    m = np.arange(-max_degree, max_degree + 1) if padded else degree_order(max_degree)[1]
    # the sine enters with sign -1 for m > 0 (cos-type) and +1 for m <= 0: rows L + 1 .. 2L of the signed table
    # [sin(m a) for m = 0..L; -sin(m a) for m = 1..L] hold -sin
    return np.abs(m), np.where(m > 0, max_degree + m, -m)


def z_phases(max_degree: int, angles: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return cos(m a) and sin(m a) for the orders m = 0..L, shape (L+1,) + angles.shape; angles in rad."""
    multiple = np.arange(int(max_degree) + 1).reshape((-1,) + (1,) * np.ndim(angles)) * np.asarray(angles, dtype=float)
    return np.cos(multiple), np.sin(multiple)


def _layout_z_factors(max_degree: int, angles: float | np.ndarray, padded: bool) -> tuple[np.ndarray, np.ndarray]:
    """Return cos(|m| a) and signed sin(|m| a) per entry of the layout, shape (entries,) + angles.shape."""
    cos, sin = z_phases(max_degree, angles)
    cos_rows, sin_rows = _z_rows(int(max_degree), padded)
    # one gather per table (no full-size temporaries): the signs sit in the small table
    return cos[cos_rows], np.concatenate([sin, -sin[1:]])[sin_rows]


def z_rotation_factors(max_degree: int, angles: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return cos(|m| a), signed sin(|m| a), shape (n,) + angles.shape, and the partner index (flat layout).

    The z-step by a is cos * c + sin * c[partner] along the coefficient axis.
    """
    cos, sin = _layout_z_factors(max_degree, angles, padded=False)
    return cos, sin, z_rotation_index(int(max_degree))[2]


def z_rotation_factors_padded(max_degree: int, angles: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return cos(|m| a) and signed sin(|m| a) per padded column, shape angles.shape + (2L+1,), contiguous.

    The z-step by a of padded coefficients p (..., L+1, 2L+1) is cos * p + sin * p[..., ::-1].
    """
    cos, sin = _layout_z_factors(max_degree, angles, padded=True)
    return np.ascontiguousarray(np.moveaxis(cos, 0, -1)), np.ascontiguousarray(np.moveaxis(sin, 0, -1))


def rotate_z(coefficients: np.ndarray, alpha: float) -> np.ndarray:
    """Return the coefficients (..., n) of f turned by alpha (rad) about +z: g(theta, phi) = f(theta, phi - alpha)."""
    coefficients = np.asarray(coefficients, dtype=float)
    cos, sin, partner = z_rotation_factors(degree_from_size(coefficients.shape[-1]), alpha)
    return cos * coefficients + sin * coefficients[..., partner]


@lru_cache(maxsize=16)
def quarter_turn_sparse(max_degree: int):  # -> tuple[scipy.sparse.csr_matrix, scipy.sparse.csr_matrix]
    """Return the block-diagonal J = diag(J_0..J_L) and J^T as sparse matrices (about a quarter of J_l is non-zero)."""

    forward = sparse_block_diag(quarter_turn(max_degree), format='csr')
    forward.eliminate_zeros()
    return forward, forward.T.tocsr()


def apply_sparse(matrix, coefficients: np.ndarray, axis: int = -1) -> np.ndarray:
    """Return matrix @ c for the coefficient vectors c along the given axis of coefficients (default the last)."""
    moved = np.moveaxis(coefficients, axis, 0)
    product = np.asarray(matrix @ moved.reshape(moved.shape[0], -1)).reshape(moved.shape)
    return np.moveaxis(product, 0, axis)


def rotate_y(coefficients: np.ndarray, beta: float) -> np.ndarray:
    """Return the coefficients of f turned by beta (rad) about +y, by J Z(beta) J^T (fixed quarter turns)."""
    coefficients = np.asarray(coefficients, dtype=float)
    forward, backward = quarter_turn_sparse(degree_from_size(coefficients.shape[-1]))
    return apply_sparse(forward, rotate_z(apply_sparse(backward, coefficients), beta))


def rotate_zyz(coefficients: np.ndarray, alpha: float, beta: float, gamma: float) -> np.ndarray:
    """Return the coefficients of f turned by R = Rz(alpha) Ry(beta) Rz(gamma): two z-steps, two quarter turns."""
    return rotate_z(rotate_y(rotate_z(coefficients, gamma), beta), alpha)


def rotate(coefficients: np.ndarray, rotation: RotationLike) -> np.ndarray:
    """Return the coefficients (..., n) of g(d) = f(R^T d): f turned by R (f_snapshot = rotate(f_current, R))."""
    return rotate_zyz(coefficients, *zyz_angles(rotation))


def z_rotation_blocks(max_degree: int, alpha: float) -> list[np.ndarray]:
    """Return the per-degree matrices Z_l(alpha) of a turn by alpha (rad) about +z."""
    cos, sin, partner = z_rotation_factors(int(max_degree), alpha)
    blocks = []
    for part in degree_slices(max_degree):
        size = part.stop - part.start
        block = np.diag(cos[part])
        block[np.arange(size), partner[part] - part.start] += sin[part]
        blocks.append(block)
    return blocks


def wigner_d(rotation: RotationLike, max_degree: int) -> list[np.ndarray]:
    """Return the real Wigner-D matrices [D_0, ..., D_L] of R: rotate(c, R)[l] = D_l @ c[l]."""
    alpha, beta, gamma = zyz_angles(rotation)
    turns = quarter_turn(max_degree)
    za, zb, zg = (z_rotation_blocks(max_degree, float(angle)) for angle in (alpha, beta, gamma))  # one rotation
    return [za[l] @ turns[l] @ zb[l] @ turns[l].T @ zg[l] for l in range(int(max_degree) + 1)]


def wigner_d_matrix(rotation: RotationLike, max_degree: int) -> np.ndarray:
    """Return the block-diagonal ((L+1)^2, (L+1)^2) matrix of all D_l(R)."""

    return dense_block_diag(*wigner_d(rotation, max_degree))


# --- rotations of padded coefficients (skynav_sh.layouts: (..., L+1, 2L+1), entry [l, m + L]) ----------------


@lru_cache(maxsize=16)
def quarter_turn_padded(max_degree: int) -> np.ndarray:
    """Return J_l = D_l(Rx(-90 deg)) for l = 0..L as a read-only padded stack (L+1, 2L+1, 2L+1)."""

    L = int(max_degree)
    out = np.zeros((L + 1, 2 * L + 1, 2 * L + 1))
    for l, block in enumerate(quarter_turn(L)):
        out[l, L - l : L + l + 1, L - l : L + l + 1] = block
    out.flags.writeable = False
    return out


@lru_cache(maxsize=16)
def _quarter_turn_transposed(max_degree: int) -> np.ndarray:
    """Return J_l^T for l = 0..L, contiguous and read-only (L+1, 2L+1, 2L+1)."""
    out = np.ascontiguousarray(np.swapaxes(quarter_turn_padded(max_degree), -1, -2))
    out.flags.writeable = False
    return out


def rotate_z_padded(padded: np.ndarray, alpha: float | np.ndarray) -> np.ndarray:
    """Return Z(alpha) applied to padded coefficients (..., L+1, 2L+1): f turned by alpha (rad) about +z.

    An array of angles (*A) gives (*A, ..., L+1, 2L+1): every angle applied to the whole input.
    """
    cos, sin = z_rotation_factors_padded((padded.shape[-1] - 1) // 2, alpha)
    if np.ndim(alpha) > 0:
        expand = np.shape(alpha) + (1,) * (padded.ndim - 1) + cos.shape[-1:]  # (*A, 1.., 2L+1)
        cos, sin = cos.reshape(expand), sin.reshape(expand)
    return cos * padded + sin * padded[..., ::-1]


def _zyz_steps(matrix: np.ndarray, max_degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Return cos and signed sin (K, 3, 2L+1) per padded column of the z-steps gamma, beta, alpha of K rotations."""
    # the ZYZ angles of all K rotations (..., 3, 3) in one batched call
    angles = np.stack(zyz_angles(matrix.reshape(-1, 3, 3))[::-1], axis=-1)  # (K, 3): gamma, beta, alpha
    return z_rotation_factors_padded(max_degree, angles)


def rotate_by_matrix(padded: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Return D(R) applied to padded coefficients (..., L+1, 2L+1): the function turned by R (3x3).

    A stack of K matrices (K, 3, 3) gives (K, ..., L+1, 2L+1), every input turned by every R.
    """
    matrix = np.asarray(matrix, dtype=float)
    batch = matrix.shape[:-2]
    L = padded.shape[-2] - 1
    turn = quarter_turn_padded(L)
    expand = (slice(None),) + (None,) * (padded.ndim - 1)
    cos, sin = _zyz_steps(matrix, L)
    x = cos[:, 0][expand] * padded + sin[:, 0][expand] * padded[..., ::-1]
    x = np.matmul(x[..., None, :], turn)[..., 0, :]  # J^T x, as the row x^T J
    x = cos[:, 1][expand] * x + sin[:, 1][expand] * x[..., ::-1]
    x = np.matmul(turn, x[..., None])[..., 0]
    x = cos[:, 2][expand] * x + sin[:, 2][expand] * x[..., ::-1]
    return x.reshape(batch + padded.shape)


def rotate_degree_major(stack: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Return D(R) applied to functions laid out degree first, (L+1, r, 2L+1) [l, function, m + L].

    The same rotation as rotate_by_matrix, with every quarter turn one matrix product per degree for all r
    functions at once. A stack of K matrices (K, 3, 3) gives (K, L+1, r, 2L+1).
    """
    matrix = np.asarray(matrix, dtype=float)
    batch = matrix.shape[:-2]
    L = stack.shape[-3] - 1
    cos, sin = (factor[:, :, None, None, :] for factor in _zyz_steps(matrix, L))
    x = cos[:, 0] * stack + sin[:, 0] * stack[..., ::-1]
    x = x @ quarter_turn_padded(L)  # J^T x, as the rows x^T J
    x = cos[:, 1] * x + sin[:, 1] * x[..., ::-1]
    x = x @ _quarter_turn_transposed(L)  # J x, as the rows x^T J^T
    x = cos[:, 2] * x + sin[:, 2] * x[..., ::-1]
    return x.reshape(batch + stack.shape)
