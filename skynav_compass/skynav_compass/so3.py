# SPDX-License-Identifier: Apache-2.0
"""SO(3) machinery on real SH coefficients (camera_link): padded layout, Wigner tables, rotations, generators.

Padded layout: coefficients (..., (L+1)^2) in the contract's flat order become (..., L+1, 2L+1) arrays with
entry [l, m + L] (zero where |m| > l), so every degree is a row and per-degree matrices act by batched matmul.
Rotation convention (as skynav_sh.rotate): D(R) c are the coefficients of f(R^T d); D(R1 R2) = D(R1) D(R2);
R = Rz(alpha) Ry(beta) Rz(gamma) (ZYZ) has D = Z(alpha) J Z(beta) J^T Z(gamma), J = D(Rx(-90 deg)).
Complex form: A_lm = s_m (c_l|m| + i sgn(m) c_l,-|m|) / sqrt(2) (A_l0 = c_l0, s_m = (-1)^m for m > 0, else 1)
turns Z(alpha) into diag(exp(i m alpha)) and D_l(Ry(beta)) into Wigner's small d^l(beta), so
    <a, D(R) b> = sum_l sum_mn conj(A_lm) exp(i m alpha) d^l_mn(beta) exp(i n gamma) B_ln.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.fft import irfft2, next_fast_len
from scipy.sparse import block_diag, vstack

from skynav_compass.errors import CompassError
from skynav_core.rotations import zyz_angles
from skynav_sh.basis import degree_from_size, degree_order
from skynav_sh.rotation import quarter_turn


@lru_cache(maxsize=16)
def _flat_to_padded(max_degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Return (row l, column m + L) of every flat coefficient index of degree L."""
    l, m = degree_order(max_degree)
    return np.asarray(l), np.asarray(m + max_degree)


def to_padded(coefficients: np.ndarray, max_degree: int | None = None) -> np.ndarray:
    """Return coefficients (..., (L'+1)^2) in the padded layout (..., L+1, 2L+1), truncated or zero-extended to L."""
    coefficients = np.asarray(coefficients, dtype=float)
    source = degree_from_size(coefficients.shape[-1])
    degree = source if max_degree is None else int(max_degree)
    keep = min(source, degree)
    rows, cols = _flat_to_padded(keep)
    out = np.zeros(coefficients.shape[:-1] + (degree + 1, 2 * degree + 1))
    out[..., rows, cols - keep + degree] = coefficients[..., : (keep + 1) ** 2]
    return out


def from_padded(padded: np.ndarray) -> np.ndarray:
    """Return the flat coefficients (..., (L+1)^2) of a padded array (..., L+1, 2L+1)."""
    rows, cols = _flat_to_padded(padded.shape[-2] - 1)
    return padded[..., rows, cols]


@lru_cache(maxsize=16)
def _complex_factors(max_degree: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (weight of c_l|m|, weight of i c_l,-|m|, column of c_l,-|m|) per padded column m + L."""
    L = max_degree
    m = np.arange(-L, L + 1)
    phase = np.where((m > 0) & (m % 2 == 1), -1.0, 1.0)
    real_weight = np.where(m == 0, 1.0, phase / np.sqrt(2.0))
    imag_weight = np.where(m == 0, 0.0, phase * np.sign(m) / np.sqrt(2.0))
    return real_weight, imag_weight, L - np.abs(m)


def complex_form(padded: np.ndarray) -> np.ndarray:
    """Return the complex coefficients A_lm (..., L+1, 2L+1) of real padded coefficients (see module docstring)."""
    L = padded.shape[-2] - 1
    real_weight, imag_weight, negative = _complex_factors(L)
    positive = L + np.abs(np.arange(-L, L + 1))
    return real_weight * padded[..., positive] + 1j * imag_weight * padded[..., negative]


# --- rotations of padded coefficients ----------------------------------------------------------------------


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
def _z_factors(max_degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Return |m| and the sine's sign (-1 for m > 0) per padded column of degree L."""
    m = np.arange(-max_degree, max_degree + 1)
    return np.abs(m).astype(float), np.where(m > 0, -1.0, 1.0)


def rotate_z_padded(padded: np.ndarray, alpha: float | np.ndarray) -> np.ndarray:
    """Return Z(alpha) applied to padded coefficients (..., L+1, 2L+1): f turned by alpha (rad) about +z.

    An array of angles (*A) gives (*A, ..., L+1, 2L+1): every angle applied to the whole input.
    """
    order, sign = _z_factors((padded.shape[-1] - 1) // 2)
    if np.ndim(alpha) == 0:
        angle = float(alpha) * order
    else:
        alpha = np.asarray(alpha, dtype=float)
        angle = alpha.reshape(alpha.shape + (1,) * (padded.ndim - 1) + (1,)) * order  # (*A, 1.., 2L+1)
    return np.cos(angle) * padded + (sign * np.sin(angle)) * padded[..., ::-1]


def _zyz_steps(matrix: np.ndarray, max_degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Return cos and signed sin (K, 3, 2L+1) per padded column of the z-steps gamma, beta, alpha of K rotations."""
    # the ZYZ angles of all K rotations (..., 3, 3) in one batched call
    angles = np.stack(zyz_angles(matrix.reshape(-1, 3, 3))[::-1], axis=-1)  # (K, 3): gamma, beta, alpha
    order, sign = _z_factors(max_degree)
    phases = angles[:, :, None] * order
    return np.cos(phases), sign * np.sin(phases)


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


@lru_cache(maxsize=16)
def _quarter_turn_transposed(max_degree: int) -> np.ndarray:
    """Return J_l^T for l = 0..L, contiguous and read-only (L+1, 2L+1, 2L+1)."""
    out = np.ascontiguousarray(np.swapaxes(quarter_turn_padded(max_degree), -1, -2))
    out.flags.writeable = False
    return out


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


@lru_cache(maxsize=16)
def generators(max_degree: int) -> np.ndarray:
    """Return G_x, G_y, G_z (3, L+1, 2L+1, 2L+1): D(exp(t e_i)) = exp(t G_i) in the padded layout, read-only."""
    # (G_z c)_m = -m c_-m (derivative of the z-step); Ry(t) = Q Rz(t) Q^T gives G_y = J G_z J^T, and
    # Rx(t) = Rz(-90 deg) Ry(t) Rz(90 deg) gives G_x = Z(-pi/2) G_y Z(pi/2)
    L = int(max_degree)
    m = np.arange(-L, L + 1)
    g_z = np.zeros((2 * L + 1, 2 * L + 1))
    g_z[np.arange(2 * L + 1), (-m) + L] = -m
    mask = np.abs(m)[None, :] <= np.arange(L + 1)[:, None]
    g_z = g_z[None] * (mask[:, :, None] & mask[:, None, :])
    turn = quarter_turn_padded(L)
    g_y = turn @ g_z @ np.swapaxes(turn, -1, -2)
    g_x = rotate_z_padded(np.swapaxes(rotate_z_padded(np.swapaxes(g_y, -1, -2), -np.pi / 2), -1, -2), -np.pi / 2)
    out = np.stack([g_x, g_y, g_z])
    out.flags.writeable = False
    return out


@lru_cache(maxsize=16)
def stacked_generators(max_degree: int):  # -> scipy.sparse.csr_matrix
    """Return [G_x; G_y; G_z] as one sparse (3 N, N) matrix on flattened padded coefficients, N = (L+1)(2L+1)."""

    parts = []
    for blocks in generators(max_degree):
        matrix = block_diag(list(blocks), format='csr')
        matrix.data[np.abs(matrix.data) < 1e-12] = 0.0  # G_x, G_y couple m only to its neighbours: drop rounding
        matrix.eliminate_zeros()
        parts.append(matrix)
    return vstack(parts, format='csr')


# --- Wigner small d on an Euler-angle grid and the SO(3) correlation by FFT ---------------------------------


@lru_cache(maxsize=16)
def _complex_quarter_turn(max_degree: int) -> np.ndarray:
    """Return Delta_l = V J_l V^H (L+1, 2L+1, 2L+1), V the real-to-complex map above: d^l(b) = Delta E(b) Delta^H."""
    L = int(max_degree)
    real_weight, imag_weight, negative = _complex_factors(L)
    positive = L + np.abs(np.arange(-L, L + 1))
    v = np.zeros((2 * L + 1, 2 * L + 1), dtype=complex)
    v[np.arange(2 * L + 1), positive] += real_weight
    v[np.arange(2 * L + 1), negative] += 1j * imag_weight
    return v @ quarter_turn_padded(L) @ v.conj().T


def wigner_small_d_table(max_degree: int, betas: Sequence[float]) -> np.ndarray:
    """Return Wigner's small d^l_mn(beta) (n_beta, L+1, 2L+1, 2L+1) on the given betas (rad), padded."""
    # d^l(beta) = Delta_l diag(exp(i k beta)) Delta_l^H from the stable quarter turn: no factorials, any L
    delta = _complex_quarter_turn(max_degree)
    L = int(max_degree)
    k = np.arange(-L, L + 1)
    phases = np.exp(1j * np.multiply.outer(np.asarray(betas, dtype=float), k))  # (B, 2L+1)
    scaled = delta[None] * phases[:, None, None, :]  # (B, l, m, k)
    return np.matmul(scaled, np.swapaxes(delta.conj(), -1, -2)[None]).real


@dataclass(frozen=True)
class EulerGrid:
    """A ZYZ Euler-angle grid: alpha_j = gamma_j = 2 pi j / n (j < n) and betas in [0, beta_max] (rad)."""

    max_degree: int
    n: int
    betas: tuple[float, ...]

    @classmethod
    def create(cls, max_degree: int, oversampling: float = 1.0, max_beta: float = np.pi) -> EulerGrid:
        """Return the grid of degree L with n >= oversampling (2L+2) azimuth steps and betas of the same step."""

        n = int(np.ceil(oversampling * (2 * max_degree + 2) / 2.0)) * 2
        while n % 2 or next_fast_len(n) != n:  # even, with small prime factors only (fast FFTs)
            n += 1
        step = 2 * np.pi / n
        max_beta = float(np.clip(max_beta, 0.0, np.pi))
        count = int(np.ceil(max_beta / step - 1e-9)) + 1
        return cls(int(max_degree), n, tuple(np.linspace(0.0, max_beta, count).tolist()) if count > 1 else (0.0,))

    @property
    def step(self) -> float:
        """Return the azimuth step 2 pi / n (rad)."""
        return 2 * np.pi / self.n

    @property
    def alphas(self) -> np.ndarray:
        """Return the alpha (= gamma) values (rad)."""
        return self.step * np.arange(self.n)

    @property
    def shape(self) -> tuple[int, int, int]:
        """Return the shape (n_beta, n_alpha, n_gamma) of values on this grid."""
        return len(self.betas), self.n, self.n

    def angles(self, index: tuple[int, int, int]) -> tuple[float, float, float]:
        """Return (alpha, beta, gamma) in rad of a grid index (beta, alpha, gamma)."""
        b, a, g = index
        return self.step * a, float(self.betas[b]), self.step * g

    def half_table(self) -> np.ndarray:
        """Return the table's n >= 0 half laid out for so3_correlation: ((2L+1)(L+1), n_beta, L+1), cached."""
        return _half_table(self.max_degree, self.betas)


@lru_cache(maxsize=8)
def _half_table(max_degree: int, betas: tuple[float, ...]) -> np.ndarray:
    """Return d^l_mn(beta) for n >= 0 as a contiguous ((2L+1)(L+1), n_beta, L+1) array, read-only."""
    L = int(max_degree)
    table = wigner_small_d_table(L, betas)[..., L:]
    out = np.ascontiguousarray(table.reshape(len(betas), L + 1, -1).transpose(2, 0, 1))
    out.flags.writeable = False
    return out


def correlation_products(a: np.ndarray, b: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Return sum_k w_k conj(A_k,lm) B_k,ln for n >= 0, (L+1, 2L+1, L+1) complex: the spectrum of sum w_k <a_k, D b_k>.

    a, b: padded real coefficients (K, L+1, 2L+1); weights (K,) default 1.
    """
    L = a.shape[-2] - 1
    big_a, big_b = complex_form(a), complex_form(b)[..., L:]  # n >= 0 only (the correlation is real)
    w = np.ones(a.shape[0]) if weights is None else np.asarray(weights, dtype=float)
    out = np.zeros((L + 1, 2 * L + 1, L + 1), dtype=complex)
    for weight, left, right in zip(w, big_a.conj(), big_b):
        out += (weight * left)[:, :, None] * right[:, None, :]
    return out


def so3_correlation(products: np.ndarray, grid: EulerGrid) -> np.ndarray:
    """Return correlations on the Euler grid, (K, n_beta, n, n) [beta, alpha, gamma], of products (K, L+1, 2L+1, L+1).

    The products come from correlation_products; value = sum_l,m,n conj(A_lm) e^(i m alpha) d^l_mn(beta)
    e^(i n gamma) B_ln = <a, D(Rz(alpha) Ry(beta) Rz(gamma)) b>.
    """
    L = grid.max_degree
    if products.shape[1:] != (L + 1, 2 * L + 1, L + 1):
        raise CompassError('products and grid of different degrees')
    return so3_correlation_cells(np.ascontiguousarray(products.transpose(2, 3, 1, 0)), grid)


def so3_correlation_cells(products: np.ndarray, grid: EulerGrid) -> np.ndarray:
    """Return correlations on the Euler grid, (K, n_beta, n, n), of products laid out per cell: (2L+1, L+1, L+1, K).

    products[m + L, n, l, k] = sum conj(A_lm) B_ln of correlation k (n >= 0), complex and C-contiguous (the layout
    so3_correlation turns its input into; building it directly saves the copies).
    """

    L = grid.max_degree
    k = products.shape[-1]
    if products.shape[:3] != (2 * L + 1, L + 1, L + 1) or products.dtype != complex:
        raise CompassError('products and grid of different degrees (or not complex)')
    n_beta = len(grid.betas)
    cells = (2 * L + 1) * (L + 1)
    # T[(m, n), b, k] = sum_l d[(m, n), b, l] P[(m, n), l, k]: one batched real product over the (m, n) cells, on
    # the real and imaginary parts side by side (the complex array seen as interleaved floats)
    lhs = grid.half_table()  # (cells, B, l)
    values = np.matmul(lhs, np.ascontiguousarray(products).reshape(cells, L + 1, k).view(float))  # (cells, B, 2K)
    values = values.view(complex).reshape(2 * L + 1, L + 1, n_beta, k)
    spectrum = np.zeros((k, n_beta, grid.n, grid.n // 2 + 1), dtype=complex)
    spectrum[:, :, : L + 1, : L + 1] = values[L:].transpose(3, 2, 0, 1)  # m = 0..L
    spectrum[:, :, grid.n - L :, : L + 1] = values[:L].transpose(3, 2, 0, 1)  # m = -L..-1
    # the correlation is real, so T_-m,-n = conj(T_mn) and the half n >= 0 is exactly what irfft2 expects;
    # norm='forward' leaves the inverse transform unscaled: the plain sum over (m, n)
    return irfft2(spectrum, s=(grid.n, grid.n), axes=(-2, -1), norm='forward', overwrite_x=True)
