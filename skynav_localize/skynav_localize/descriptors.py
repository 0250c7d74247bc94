# SPDX-License-Identifier: Apache-2.0
"""Rotation-invariant place descriptors of a skyline's SH coefficients, and distances vectorised over a map.

Normalisation (the same for every map, so distances are comparable across maps and degrees):

- amplitude: a = (A_1, ..., A_L) / ||(A_1, ..., A_L)|| with A_l = ||c_l|| (skynav_sh.spectra.amplitude_spectrum).
  A_0 = |c_00| is the sky's solid angle / sqrt(4 pi), the overall sky fraction: it is dropped, and the unit norm
  removes the remaining overall scale (sum_l>=1 A_l^2 is the variance of the mask over the sphere), so the
  descriptor describes the *shape* of the skyline's power spectrum. Entries are >= 0, so the Euclidean distance
  between two descriptors lies in [0, sqrt(2)].
- bispectrum: the real bispectrum b(l1, l2, l3) over the triples with 1 <= l1 <= l2 <= l3 (triples with l = 0 only
  repeat c_00 * A_l^2), divided by E^(3/2) with E = sum_l>=1 A_l^2 (scale-free), log-compressed as
  sign(b) log(1 + |b| / BISPECTRUM_LOG_SCALE) (its magnitudes span several decades; near 0 the map is linear, so
  rounding errors stay at rounding level), and scaled to unit norm. Euclidean distance in [0, 2].

Both are exactly invariant to any rotation of the coefficients (only rounding differs). A mask without any
sky/ground edge (all sky or all ground) has no spectrum above degree 0 and gets the zero descriptor.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from skynav_localize.errors import LocalizeError
from skynav_sh.basis import degree_from_size
from skynav_sh.spectra import amplitude_spectrum, bispectrum, bispectrum_triples

#: Version of the normalisation above; maps store it so that a change makes stored descriptors stale.
DESCRIPTOR_VERSION = 1
#: Scale (of b / E^(3/2), dimensionless) below which the bispectrum's log compression is linear.
BISPECTRUM_LOG_SCALE = 1e-3
#: Distance metrics of the methods: Euclidean, mean absolute difference (SeqSLAM's SAD), cosine distance.
METRICS = ('euclidean', 'sad', 'cosine')


def _unit_rows(values: np.ndarray) -> np.ndarray:
    """Return the vectors along the last axis scaled to unit norm (zero vectors stay zero)."""
    norm = np.linalg.norm(values, axis=-1, keepdims=True)
    return np.divide(values, norm, out=np.zeros_like(values), where=norm > 0)


def _truncate(coefficients: np.ndarray, max_degree: int | None) -> np.ndarray:
    """Return coefficients (..., n) cut to degree max_degree (None: keep all); ValueError if there are fewer."""

    coefficients = np.asarray(coefficients, dtype=float)
    degree = degree_from_size(coefficients.shape[-1])
    if max_degree is None or max_degree == degree:
        return coefficients
    if max_degree > degree:
        raise LocalizeError(f'coefficients of degree {degree} cannot give descriptors of degree {max_degree}')
    return coefficients[..., : (max_degree + 1) ** 2]


def amplitude_descriptor(coefficients: np.ndarray, max_degree: int | None = None) -> np.ndarray:
    """Return the unit-norm amplitude spectrum (A_1..A_L), shape (..., L), dimensionless, of coefficients (..., n)."""

    return _unit_rows(amplitude_spectrum(_truncate(coefficients, max_degree))[..., 1:])


def _bispectrum_rows(max_degree: int) -> np.ndarray:
    """Return the positions, among skynav_sh's bispectrum triples of degree L, of those with l1 >= 1."""

    return np.flatnonzero(bispectrum_triples(int(max_degree))[:, 0] >= 1)


def bispectrum_size(max_degree: int) -> int:
    """Return the length of the bispectrum descriptor of degree L (268 for L = 16, 1752 for L = 32)."""
    return int(_bispectrum_rows(max_degree).size)


def bispectrum_descriptor(coefficients: np.ndarray, max_degree: int | None = None) -> np.ndarray:
    """Return the normalised, log-compressed bispectrum (..., K) (dimensionless, unit norm) of coefficients (..., n)."""

    coefficients = _truncate(coefficients, max_degree)
    degree = degree_from_size(coefficients.shape[-1])
    values = bispectrum(coefficients)[..., _bispectrum_rows(degree)]
    energy = np.sum(np.square(coefficients[..., 1:]), axis=-1, keepdims=True)  # sum_l>=1 A_l^2
    scale = np.where(energy > 0, energy, 1.0) ** 1.5
    scaled = np.where(energy > 0, values / scale, 0.0)
    return _unit_rows(np.sign(scaled) * np.log1p(np.abs(scaled) / BISPECTRUM_LOG_SCALE))


#: The SH descriptors by name: coefficients (..., n), degree -> descriptors (..., D).
SH_DESCRIPTORS: dict[str, Callable[[np.ndarray, int | None], np.ndarray]] = {
    'amplitude': amplitude_descriptor,
    'bispectrum': bispectrum_descriptor,
}


def describe(name: str, coefficients: np.ndarray, max_degree: int | None = None) -> np.ndarray:
    """Return SH descriptor `name` ('amplitude' or 'bispectrum') of coefficients (..., n) up to degree L."""
    try:
        function = SH_DESCRIPTORS[name]
    except KeyError:
        raise LocalizeError(f'unknown SH descriptor {name!r}; expected one of {", ".join(SH_DESCRIPTORS)}') from None
    return function(coefficients, max_degree)


class DescriptorIndex:
    """A map's descriptor matrix (N, D) prepared for fast distances of queries to every snapshot."""

    def __init__(self, matrix: np.ndarray, metric: str = 'euclidean', dtype: np.dtype | type = np.float64) -> None:
        """Keep the matrix (cast to dtype) and what the metric needs precomputed (squared norms)."""
        if metric not in METRICS:
            raise LocalizeError(f'unknown metric {metric!r}; expected one of {", ".join(METRICS)}')
        matrix = np.asarray(matrix)
        if matrix.ndim != 2:
            raise LocalizeError(f'a descriptor matrix is (N, D), got shape {matrix.shape}')
        self.metric = metric
        self.matrix = np.ascontiguousarray(matrix, dtype=dtype)
        self._squared_norms = np.einsum('nd,nd->n', self.matrix, self.matrix) if metric == 'euclidean' else None

    def __len__(self) -> int:
        """Return the number of snapshots N."""
        return self.matrix.shape[0]

    @property
    def dimension(self) -> int:
        """Return the descriptor length D."""
        return self.matrix.shape[1]

    def distances(self, query: np.ndarray) -> np.ndarray:
        """Return the distances (N,) of one query descriptor (D,) to every snapshot (metric units)."""
        query = np.asarray(query, dtype=self.matrix.dtype)
        if query.shape != (self.dimension,):
            raise LocalizeError(f'a query descriptor must be ({self.dimension},), got shape {query.shape}')
        if self.metric == 'euclidean':  # matrix-vector product and in-place element-wise steps
            squared = self.matrix @ query
            squared *= -2.0
            squared += self._squared_norms
            squared += query @ query
            np.maximum(squared, 0.0, out=squared)
            return np.sqrt(squared, out=squared).astype(float, copy=False)
        if self.metric == 'cosine':
            return (1.0 - self.matrix @ query).astype(float, copy=False)
        return np.mean(np.abs(self.matrix - query), axis=1).astype(float, copy=False)

    def distance_matrix(self, queries: np.ndarray) -> np.ndarray:
        """Return the distances (Q, N) of query descriptors (Q, D) to every snapshot (metric units)."""
        queries = np.asarray(queries, dtype=self.matrix.dtype)
        if queries.ndim != 2 or queries.shape[1] != self.dimension:
            raise LocalizeError(f'queries must be (Q, {self.dimension}), got shape {queries.shape}')
        if self.metric == 'euclidean':
            assert self._squared_norms is not None  # kept for the euclidean metric
            squared = self._squared_norms[None, :] - 2.0 * (queries @ self.matrix.T)
            squared += np.einsum('qd,qd->q', queries, queries)[:, None]
            return np.sqrt(np.maximum(squared, 0.0, out=squared), out=squared).astype(float, copy=False)
        if self.metric == 'cosine':
            return (1.0 - queries @ self.matrix.T).astype(float, copy=False)
        # 'sad': mean absolute difference, one query row at a time to bound memory at N x D
        out = np.empty((queries.shape[0], len(self)))
        for row, query in enumerate(queries):
            out[row] = np.mean(np.abs(self.matrix - query), axis=1)
        return out


def distance_matrix(queries: np.ndarray, matrix: np.ndarray, metric: str = 'euclidean') -> np.ndarray:
    """Return the distances (Q, N) between query descriptors (Q, D) and snapshot descriptors (N, D)."""
    return DescriptorIndex(matrix, metric).distance_matrix(queries)


def descriptor_distance(a: np.ndarray, b: np.ndarray, metric: str = 'euclidean') -> np.ndarray:
    """Return the distance between descriptors a and b (..., D), broadcast over leading axes (metric units)."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    if metric == 'euclidean':
        return np.linalg.norm(a - b, axis=-1)
    if metric == 'sad':
        return np.mean(np.abs(a - b), axis=-1)
    if metric == 'cosine':
        return 1.0 - np.sum(a * b, axis=-1)
    raise LocalizeError(f'unknown metric {metric!r}; expected one of {", ".join(METRICS)}')
