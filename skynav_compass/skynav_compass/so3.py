# SPDX-License-Identifier: Apache-2.0
"""The compass's SO(3) machinery on real SH coefficients (camera_link): generators, Wigner tables, the correlation.

Coefficients are in skynav_sh's padded layout (skynav_sh.layouts: (..., L+1, 2L+1), entry [l, m + L]); their
rotations (rotate_by_matrix, rotate_degree_major, rotate_z_padded, the quarter turn J) live in skynav_sh.rotation.
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
from skynav_sh.rotation import quarter_turn_padded, rotate_z_padded


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


# --- generators of the padded rotations (the Newton refinement's derivatives) ---------------------------------


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
