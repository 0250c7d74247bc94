# SPDX-License-Identifier: Apache-2.0
"""Exact real SH transforms on a Gauss-Legendre x equiangular grid (camera_link, theta from +z).

Samples are arrays (..., n_theta, n_phi) over the grid's nodes: theta ascending from the zenith (Gauss-Legendre
nodes in cos theta), phi_j = 2 pi j / n_phi. For functions of degree <= L the analysis is exact.
"""

from __future__ import annotations

from functools import cached_property, lru_cache

import numpy as np

from skynav_sh.basis import SQRT2, degree_order, n_coefficients, normalised_legendre, real_sh_directions
from skynav_sh.errors import ShError

# Directions per block in synthesis_at; bounds the (block, (L+1)^2) basis table to ~32 MB at L = 32.
_SYNTHESIS_BLOCK_VALUES = 4_000_000


class GaussLegendreGrid:
    """Quadrature grid of degree L: n_theta Gauss-Legendre nodes in cos(theta) times n_phi equal azimuth steps."""

    def __init__(self, max_degree: int, n_phi: int | None = None, n_theta: int | None = None) -> None:
        """Grid for degree L; defaults n_theta = L + 1 (the least for exactness), n_phi = 2L + 2 (>= 2L + 1)."""
        self.max_degree = L = int(max_degree)
        if L < 0:
            raise ShError('max_degree must be >= 0')
        self.n_theta = L + 1 if n_theta is None else int(n_theta)
        self.n_phi = 2 * L + 2 if n_phi is None else int(n_phi)
        if self.n_theta < L + 1 or self.n_phi < 2 * L + 1:
            raise ShError(f'grid too small for degree {L}: needs n_theta >= {L + 1}, n_phi >= {2 * L + 1}')
        x, w = np.polynomial.legendre.leggauss(self.n_theta)
        self.cos_theta: np.ndarray = x[::-1].copy()  # descending cos = ascending theta from the zenith
        self.theta_weights: np.ndarray = w[::-1].copy()  # Gauss-Legendre weights in cos(theta), sum 2
        self.theta: np.ndarray = np.arccos(self.cos_theta)  # rad
        self.phi: np.ndarray = 2 * np.pi * np.arange(self.n_phi) / self.n_phi  # rad
        self.phi_step = 2 * np.pi / self.n_phi  # rad
        for array in (self.cos_theta, self.theta_weights, self.theta, self.phi):
            array.flags.writeable = False

    @property
    def shape(self) -> tuple[int, int]:
        """Return the sample array shape (n_theta, n_phi)."""
        return self.n_theta, self.n_phi

    @cached_property
    def weights(self) -> np.ndarray:
        """Return the solid angle (sr) of every node's quadrature cell, (n_theta, n_phi), summing to 4 pi."""
        return np.repeat(self.theta_weights[:, None] * self.phi_step, self.n_phi, axis=1)

    def directions(self) -> np.ndarray:
        """Return the unit direction of every node in camera_link, shape (n_theta, n_phi, 3)."""
        st, ct = np.sin(self.theta)[:, None], self.cos_theta[:, None]
        return np.stack(np.broadcast_arrays(st * np.cos(self.phi), st * np.sin(self.phi), ct), axis=-1)

    def integrate(self, samples: np.ndarray) -> np.ndarray:
        """Return the quadrature of samples (..., n_theta, n_phi) over the sphere (value x sr)."""
        return np.einsum('...tp,t->...', samples, self.theta_weights) * self.phi_step

    @cached_property
    def _legendre(self) -> np.ndarray:
        """Table [m, l, k] = s_m N_lm P_l^m(x_k), s_0 = 1 and s_m = sqrt(2) for m > 0; zero for l < m."""
        table = np.ascontiguousarray(
            np.moveaxis(normalised_legendre(self.max_degree, self.cos_theta), 0, -1).transpose(1, 0, 2)
        )
        table[1:] *= SQRT2
        table.flags.writeable = False
        return table

    @cached_property
    def _analysis_table(self) -> np.ndarray:
        """Table [m, l, k] with the quadrature weights folded in (solid angle per node over the ring)."""
        table = self._legendre * (self.theta_weights * self.phi_step)
        table.flags.writeable = False
        return table

    @cached_property
    def _synthesis_table(self) -> np.ndarray:
        """Table [m, k, l], the transpose of the Legendre table, contiguous for the synthesis products."""
        table = np.ascontiguousarray(self._legendre.transpose(0, 2, 1))
        table.flags.writeable = False
        return table

    @cached_property
    def _flat_index(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For every flat coefficient: (part 0 = cos / 1 = sin, |m|, l) into the [part, m, l] layout."""
        l, m = degree_order(self.max_degree)
        return (m < 0).astype(np.intp), np.abs(m), l

    def analysis(self, samples: np.ndarray) -> np.ndarray:
        """Return coefficients (..., (L+1)^2) of samples (..., n_theta, n_phi) on this grid (exact up to degree L)."""
        samples = np.asarray(samples, dtype=float)
        if samples.shape[-2:] != self.shape:
            raise ShError(f'samples of shape {samples.shape} do not fit the grid {self.shape}')
        L = self.max_degree
        batch = samples.shape[:-2]
        spectrum = np.fft.rfft(samples.reshape(-1, *self.shape), axis=-1)[..., : L + 1]  # (B, k, m)
        # integral over phi of f cos(m phi) = step * Re F_m; of f sin(m phi) = -step * Im F_m (step folded in table)
        parts = np.concatenate([spectrum.real, -spectrum.imag], axis=0)  # (2B, k, m)
        per_order = np.matmul(self._analysis_table, parts.transpose(2, 1, 0))  # (m, l, 2B)
        n_batch = parts.shape[0] // 2
        per_order = per_order.reshape(L + 1, L + 1, 2, n_batch).transpose(2, 0, 1, 3)  # (part, m, l, B)
        part, order, degree = self._flat_index
        coefficients = per_order[part, order, degree]  # (n, B)
        return np.ascontiguousarray(coefficients.T).reshape(*batch, n_coefficients(L))

    def synthesis(self, coefficients: np.ndarray) -> np.ndarray:
        """Return samples (..., n_theta, n_phi) on this grid of coefficients (..., (L'+1)^2) with L' <= L."""
        coefficients = np.asarray(coefficients, dtype=float)
        L = self.max_degree
        batch = coefficients.shape[:-1]
        source_degree = int(round(np.sqrt(coefficients.shape[-1]))) - 1
        if n_coefficients(source_degree) != coefficients.shape[-1] or source_degree > L:
            raise ShError(f'{coefficients.shape[-1]} coefficients do not fit a grid of degree {L}')
        flat = coefficients.reshape(-1, coefficients.shape[-1])
        n_batch, n = flat.shape
        part, order, degree = self._flat_index
        layout = np.zeros((2, L + 1, L + 1, n_batch))  # (part, m, l, B)
        layout[part[:n], order[:n], degree[:n]] = flat.T
        per_order = np.matmul(self._synthesis_table, layout.transpose(1, 2, 0, 3).reshape(L + 1, L + 1, 2 * n_batch))
        per_order = per_order.reshape(L + 1, self.n_theta, 2, n_batch)  # (m, k, part, B)
        # f(phi) = sum_m G_m cos(m phi) + H_m sin(m phi) = Re sum_m (G_m - i H_m) e^{i m phi}
        spectrum = np.zeros((n_batch, self.n_theta, self.n_phi // 2 + 1), dtype=complex)
        spectrum[..., : L + 1] = (per_order[:, :, 0] - 1j * per_order[:, :, 1]).transpose(2, 1, 0)
        spectrum[..., 1:] *= 0.5
        samples = np.fft.irfft(spectrum, n=self.n_phi, axis=-1) * self.n_phi
        return samples.reshape(*batch, *self.shape)

    def degree_parts(self, coefficients: np.ndarray, rings: int | None = None) -> np.ndarray:
        """Return samples (..., L'+1, rings, n_phi) of each degree's part f_l of coefficients (..., (L'+1)^2), L' <= L.

        Only the first `rings` rings from the zenith are sampled (default all). Each part has one degree, so its
        per-order values are a product with the Legendre table, not a sum over degrees.
        """
        coefficients = np.asarray(coefficients, dtype=float)
        batch = coefficients.shape[:-1]
        source_degree = int(round(np.sqrt(coefficients.shape[-1]))) - 1
        if n_coefficients(source_degree) != coefficients.shape[-1] or source_degree > self.max_degree:
            raise ShError(f'{coefficients.shape[-1]} coefficients do not fit a grid of degree {self.max_degree}')
        rings = self.n_theta if rings is None else int(rings)
        flat = coefficients.reshape(-1, coefficients.shape[-1])
        n = flat.shape[1]
        size = source_degree + 1
        part, order, degree = (index[:n] for index in self._flat_index)
        # c_l,m - i c_l,-m per (batch, l, m): G_m - i H_m of the part of degree l
        packed = np.zeros((flat.shape[0], size, size), dtype=complex)
        cosine, sine = part == 0, part == 1
        packed.real[:, degree[cosine], order[cosine]] = flat[:, cosine]
        packed.imag[:, degree[sine], order[sine]] = -flat[:, sine]
        legendre = self._legendre[:size, :size, :rings].transpose(1, 2, 0)  # (l, k, m)
        spectrum = np.zeros((flat.shape[0], size, rings, self.n_phi // 2 + 1), dtype=complex)
        spectrum[..., :size] = legendre[None] * packed[:, :, None, :]
        spectrum[..., 1:] *= 0.5
        samples = np.fft.irfft(spectrum, n=self.n_phi, axis=-1) * self.n_phi
        return samples.reshape(*batch, size, rings, self.n_phi)

    def synthesis_at(self, coefficients: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Return the function of coefficients (..., (L'+1)^2) at unit directions (*D, 3): shape (..., *D)."""
        return synthesis_at(coefficients, directions)


def synthesis_at(coefficients: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Return sum_lm c_lm Y_lm(d) for coefficients (..., (L+1)^2) at unit directions (*D, 3): shape (..., *D)."""
    coefficients = np.asarray(coefficients, dtype=float)
    directions = np.asarray(directions, dtype=float)
    n = coefficients.shape[-1]
    degree = int(round(np.sqrt(n))) - 1
    if n_coefficients(degree) != n:
        raise ShError(f'{n} is not a number of SH coefficients (L+1)^2')
    points = directions.reshape(-1, 3)
    flat = coefficients.reshape(-1, n)
    out = np.empty((flat.shape[0], points.shape[0]))
    block = max(1, _SYNTHESIS_BLOCK_VALUES // n)
    for start in range(0, points.shape[0], block):
        basis = real_sh_directions(degree, points[start : start + block])  # (b, n)
        out[:, start : start + block] = flat @ basis.T
    return out.reshape(*coefficients.shape[:-1], *directions.shape[:-1])


@lru_cache(maxsize=16)
def grid(max_degree: int, n_phi: int | None = None, n_theta: int | None = None) -> GaussLegendreGrid:
    """Return the shared (cached) grid of degree L; its tables are built on first use."""
    return GaussLegendreGrid(max_degree, n_phi, n_theta)


def analysis(samples: np.ndarray, max_degree: int | None = None) -> np.ndarray:
    """Return coefficients of samples (..., L+1, 2L+2) on the default grid of degree L (inferred from the shape)."""
    samples = np.asarray(samples)
    degree = samples.shape[-2] - 1 if max_degree is None else int(max_degree)
    return grid(degree).analysis(samples)


def synthesis(coefficients: np.ndarray, max_degree: int | None = None) -> np.ndarray:
    """Return samples on the default grid of degree L (default: the degree of the coefficients)."""
    coefficients = np.asarray(coefficients)
    degree = int(round(np.sqrt(coefficients.shape[-1]))) - 1 if max_degree is None else int(max_degree)
    return grid(degree).synthesis(coefficients)
