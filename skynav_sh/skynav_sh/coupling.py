# SPDX-License-Identifier: Apache-2.0
"""Real Gaunt coefficients: G(l1 m1, l2 m2, l3 m3) = integral over the sphere of Y_l1m1 Y_l2m2 Y_l3m3.

They couple real SH the way Clebsch-Gordan coefficients couple complex ones (G is the CG coupling of the real
basis scaled by the l-only factor of CG(l1 0 l2 0 | l3 0)), and vanish unless |l1 - l2| <= l3 <= l1 + l2 and
l1 + l2 + l3 is even. Built exactly by quadrature: the azimuthal integral of three cos/sin factors in closed
form, the polar one by Gauss-Legendre with enough nodes for the polynomial degree l1 + l2 + l3.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from scipy.sparse import csr_matrix

from skynav_sh.basis import lm_index, n_coefficients, normalised_legendre


@dataclass(frozen=True)
class RealGaunt:
    """Sparse real Gaunt coefficients with l1 <= L1, l2 <= L2, l3 <= L3 (COO arrays of flat indices)."""

    degrees: tuple[int, int, int]
    first: np.ndarray  # flat index of (l1, m1)
    second: np.ndarray  # flat index of (l2, m2)
    third: np.ndarray  # flat index of (l3, m3)
    values: np.ndarray  # G for each entry (dimensionless; Y are in 1/sqrt(sr))

    @property
    def nnz(self) -> int:
        """Return the number of stored non-zero coefficients."""
        return int(self.values.size)

    @cached_property
    def product_matrix(self):  # -> scipy.sparse.csr_matrix
        """Return the sparse (n3, n1 * n2) matrix M with h = M @ outer(f, g).ravel() (SH of the product f g)."""

        n1, n2, n3 = (n_coefficients(d) for d in self.degrees)
        return csr_matrix((self.values, (self.third, self.first * n2 + self.second)), shape=(n3, n1 * n2))


def _azimuth_integral(m1: np.ndarray, m2: np.ndarray, m3: np.ndarray) -> np.ndarray:
    """Return the integral over phi in [0, 2 pi) of Phi_m1 Phi_m2 Phi_m3 (Phi_0 = 1, sqrt2 cos / sqrt2 sin)."""
    a, b, c = np.abs(m1), np.abs(m2), np.abs(m3)
    n_sin = (m1 < 0).astype(int) + (m2 < 0) + (m3 < 0)
    scale = np.sqrt(2.0) ** ((m1 != 0).astype(int) + (m2 != 0) + (m3 != 0))

    def delta(x: np.ndarray) -> np.ndarray:
        return (x == 0).astype(float)

    # cos a cos b = (cos(a-b) + cos(a+b)) / 2 and  int cos(x phi) cos(c phi) = pi (delta(x - c) + delta(x + c))
    diff = delta(a - b - c) + delta(a - b + c)
    total = delta(a + b - c) + delta(a + b + c)
    value = np.zeros(np.broadcast(a, b, c).shape)
    # all three cosines
    value = np.where(n_sin == 0, 0.5 * np.pi * (diff + total), value)
    # two sines and a cosine: the sine pair gives (cos(x-y) - cos(x+y)) / 2 with x, y the sine orders
    sin_pair_diff = np.where(
        m1 >= 0, delta(b - c - a) + delta(b - c + a), np.where(m2 >= 0, delta(a - c - b) + delta(a - c + b), diff)
    )
    sin_pair_total = np.where(
        m1 >= 0, delta(b + c - a) + delta(b + c + a), np.where(m2 >= 0, delta(a + c - b) + delta(a + c + b), total)
    )
    value = np.where(n_sin == 2, 0.5 * np.pi * (sin_pair_diff - sin_pair_total), value)
    return scale * value  # an odd number of sines integrates to zero


def _degree_triples(degrees: tuple[int, int, int], ordered: bool) -> list[tuple[int, int, int]]:
    """Return the (l1, l2, l3) with non-zero Gaunt coefficients (ordered: also l1 <= l2 <= l3)."""
    L1, L2, L3 = degrees
    triples = []
    for l1 in range(L1 + 1):
        for l2 in range(l1 if ordered else 0, L2 + 1):
            for l3 in range(max(abs(l1 - l2), l2 if ordered else 0), min(l1 + l2, L3) + 1):
                if (l1 + l2 + l3) % 2 == 0:
                    triples.append((l1, l2, l3))
    return triples


@lru_cache(maxsize=8)
def real_gaunt(degree_1: int, degree_2: int, degree_3: int, ordered: bool = False) -> RealGaunt:
    """Return all non-zero real Gaunt coefficients with l_i <= L_i (cached); `ordered` keeps l1 <= l2 <= l3 only."""
    degrees = (int(degree_1), int(degree_2), int(degree_3))
    triples = _degree_triples(degrees, ordered)
    n_nodes = (sum(degrees) + 2) // 2  # Gauss-Legendre with n nodes is exact to polynomial degree 2n - 1
    x, w = np.polynomial.legendre.leggauss(n_nodes)
    legendre = normalised_legendre(max(degrees), x)  # (k, l, m)
    weighted = legendre * w[:, None, None]
    parts: list[tuple[np.ndarray, ...]] = []
    for l1, l2, l3 in triples:
        m1, m2 = (m.ravel() for m in np.meshgrid(np.arange(-l1, l1 + 1), np.arange(-l2, l2 + 1), indexing='ij'))
        # the phi integral needs |m3| = |m1| + |m2| or ||m1| - |m2||, and m3 sin-type iff exactly one of m1, m2 is
        sign = np.where(((m1 < 0).astype(int) + (m2 < 0)) % 2 == 1, -1, 1)
        smaller = np.minimum(np.abs(m1), np.abs(m2))
        for branch, candidate in enumerate((np.abs(m1) + np.abs(m2), np.abs(np.abs(m1) - np.abs(m2)))):
            m3 = sign * candidate
            keep = candidate <= l3
            if branch == 1:
                keep &= smaller > 0  # with a zero order both branches give the same m3: count it once
            a, b, c = m1[keep], m2[keep], m3[keep]
            if a.size == 0:
                continue
            phi_part = _azimuth_integral(a, b, c)
            nonzero = np.abs(phi_part) > 1e-12
            a, b, c, phi_part = a[nonzero], b[nonzero], c[nonzero], phi_part[nonzero]
            theta_part = np.einsum(
                'kn,kn,kn->n', weighted[:, l1, np.abs(a)], legendre[:, l2, np.abs(b)], legendre[:, l3, np.abs(c)]
            )
            value = theta_part * phi_part
            nonzero = np.abs(value) > 1e-14
            parts.append((lm_index(l1, a[nonzero]), lm_index(l2, b[nonzero]), lm_index(l3, c[nonzero]), value[nonzero]))
    if parts:
        first, second, third, values = (np.concatenate(column) for column in zip(*parts))
    else:
        first = second = third = np.zeros(0, dtype=np.intp)
        values = np.zeros(0)
    for array in (first, second, third, values):
        array.flags.writeable = False
    return RealGaunt(degrees, first.astype(np.intp), second.astype(np.intp), third.astype(np.intp), values)
