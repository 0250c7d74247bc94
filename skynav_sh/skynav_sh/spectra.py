# SPDX-License-Identifier: Apache-2.0
"""Rotation-invariant descriptors of real SH coefficients and distances between views.

Amplitude spectrum A_l = ||c_l|| (one number per degree). Bispectrum over the degree triples
l1 <= l2 <= l3 <= min(l1 + l2, L) with l1 + l2 + l3 even:
    b(l1, l2, l3) = sum over m of G(l1 m1, l2 m2, l3 m3) c_l1m1 c_l2m2 c_l3m3 = integral of f_l1 f_l2 f_l3,
f_l being the degree-l part of f and G the real Gaunt coefficients. Each f_l turns by the orthogonal D_l under a
rotation and the triple integral does not change, so b is invariant under any rotation. Triples with an odd
sum need the non-Gaunt (antisymmetric) coupling and are left out; permutations of a triple are redundant.
"""

from __future__ import annotations

from functools import cache, lru_cache

import numpy as np

from skynav_sh.basis import degree_from_size, degree_order
from skynav_sh.coupling import real_gaunt
from skynav_sh.errors import ShError
from skynav_sh.transform import grid


def amplitude_spectrum(coefficients: np.ndarray) -> np.ndarray:
    """Return A_l = sqrt(sum_m c_lm^2) for l = 0..L, shape (..., L+1) (units of f x sqrt(sr))."""
    coefficients = np.asarray(coefficients, dtype=float)
    degree = degree_from_size(coefficients.shape[-1])
    starts = np.arange(degree + 1) ** 2
    return np.sqrt(np.add.reduceat(np.square(coefficients), starts, axis=-1))


@cache
def bispectrum_triples(max_degree: int) -> np.ndarray:
    """Return the (l1, l2, l3) rows of the bispectrum in output order, shape (count, 3), read-only."""
    rows = [
        (l1, l2, l3)
        for l1 in range(max_degree + 1)
        for l2 in range(l1, max_degree + 1)
        for l3 in range(l2, min(l1 + l2, max_degree) + 1)
        if (l1 + l2 + l3) % 2 == 0
    ]
    table = np.array(rows, dtype=np.intp).reshape(-1, 3)
    table.flags.writeable = False
    return table


def bispectrum_size(max_degree: int) -> int:
    """Return the number of bispectrum entries of degree L (285 for L = 16, 1785 for 32, 12529 for 64)."""
    return len(bispectrum_triples(int(max_degree)))


@lru_cache(maxsize=8)
def _gaunt_contraction(max_degree: int) -> tuple[np.ndarray, ...]:
    """Return (i1, i2, i3, G, triple number) of the ordered Gaunt coefficients of degree L (cached)."""
    gaunt = real_gaunt(max_degree, max_degree, max_degree, True)
    l, _ = degree_order(max_degree)
    triples = bispectrum_triples(max_degree)
    lookup = np.full((max_degree + 1,) * 3, -1, dtype=np.intp)
    lookup[triples[:, 0], triples[:, 1], triples[:, 2]] = np.arange(len(triples))
    target = lookup[l[gaunt.first], l[gaunt.second], l[gaunt.third]]
    return gaunt.first, gaunt.second, gaunt.third, gaunt.values, target


def _bispectrum_gaunt(flat: np.ndarray, degree: int) -> np.ndarray:
    """Return bispectra (B, count) of coefficients (B, n) as sums of G c c c grouped by degree triple."""
    first, second, third, values, target = _gaunt_contraction(degree)
    count = bispectrum_size(degree)
    terms = values * flat[:, first] * flat[:, second] * flat[:, third]  # (B, nnz)
    offsets = (np.arange(flat.shape[0]) * count)[:, None]
    return np.bincount((target + offsets).ravel(), terms.ravel(), minlength=flat.shape[0] * count).reshape(
        flat.shape[0], count
    )


#: Views per batch of the grid bispectrum: bounds its working arrays (~0.7 MB per view at L = 32).
BISPECTRUM_BATCH = 16


def _bispectrum_grid(flat: np.ndarray, degree: int) -> np.ndarray:
    """Return bispectra (B, count) of coefficients (B, n) as quadratures of f_l1 f_l2 f_l3 on an exact grid."""

    quadrature = grid((3 * degree + 1) // 2)  # exact for products of degree up to 3L
    triples = bispectrum_triples(degree)
    # f_l(-d) = (-1)^l f_l(d) and l1 + l2 + l3 is even: the integrand is even under d -> -d, which maps ring k to
    # ring n - 1 - k of the grid (phi + pi is a node too, n_phi being even), so the northern rings suffice
    rings = (quadrature.n_theta + 1) // 2
    ring_weights = quadrature.weights[:rings].copy()
    ring_weights[: quadrature.n_theta // 2] *= 2.0  # the equator ring (odd n_theta) is its own mirror image
    out = np.empty((flat.shape[0], len(triples)))
    for start in range(0, flat.shape[0], BISPECTRUM_BATCH):
        batch = slice(start, start + BISPECTRUM_BATCH)
        # every degree's part f_l sampled on the northern rings: (B, l, node)
        samples = quadrature.degree_parts(flat[batch], rings).reshape(-1, degree + 1, ring_weights.size)
        weighted = samples * ring_weights.ravel()
        across = samples.transpose(0, 2, 1)  # (B, node, l3)
        position = 0
        for l1 in range(degree + 1):
            rows = triples[triples[:, 0] == l1]
            if rows.size == 0:
                continue
            l2_values = np.arange(l1, rows[:, 1].max() + 1)
            pair = weighted[:, l1, None] * samples[:, l2_values]  # (B, l2, node): w f_l1 f_l2
            integrals = pair @ across[:, :, l1:]  # (B, l2, l3 >= l1): integral of f_l1 f_l2 f_l3
            out[batch, position : position + len(rows)] = integrals[:, rows[:, 1] - l1, rows[:, 2] - l1]
            position += len(rows)
    return out


def bispectrum(coefficients: np.ndarray, method: str = 'grid') -> np.ndarray:
    """Return the real bispectrum (..., count) over bispectrum_triples(L) (units of f^3 x sr)."""
    # method 'grid': triple integrals of the degree parts on an exact quadrature grid (fast at any L);
    # 'gaunt': contraction with the cached sparse real Gaunt coefficients (same numbers; costly beyond L ~ 32)
    coefficients = np.asarray(coefficients, dtype=float)
    degree = degree_from_size(coefficients.shape[-1])
    flat = coefficients.reshape(-1, coefficients.shape[-1])
    if method == 'grid':
        out = _bispectrum_grid(flat, degree)
    elif method == 'gaunt':
        out = _bispectrum_gaunt(flat, degree)
    else:
        raise ShError(f"unknown bispectrum method {method!r} (expected 'grid' or 'gaunt')")
    return out.reshape(*coefficients.shape[:-1], out.shape[-1])


def illumination_invariant(coefficients: np.ndarray) -> np.ndarray:
    """Return the coefficients with c_00 set to 0, scaled to unit norm (zero stays zero): gain and offset drop out."""
    out = np.array(coefficients, dtype=float, copy=True)
    out[..., 0] = 0.0
    norm = np.linalg.norm(out, axis=-1, keepdims=True)
    return np.divide(out, norm, out=np.zeros_like(out), where=norm > 0)


def squared_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return sum (a - b)^2 over the last axis; for SH coefficients it equals the integral of (f - g)^2 (Parseval)."""
    return np.sum(np.square(np.asarray(a, dtype=float) - np.asarray(b, dtype=float)), axis=-1)


def coefficient_distance(f: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Return the integral over the sphere of (f - g)^2 from coefficients (..., n) (value^2 x sr)."""
    return squared_distance(f, g)


def amplitude_distance(f: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Return sum_l (A_l(f) - A_l(g))^2: rotation-invariant, a lower bound of the coefficient distance."""
    return squared_distance(amplitude_spectrum(f), amplitude_spectrum(g))


def bispectrum_distance(f: np.ndarray, g: np.ndarray, method: str = 'grid') -> np.ndarray:
    """Return the squared Euclidean distance between the bispectra of f and g (rotation-invariant)."""
    return squared_distance(bispectrum(f, method), bispectrum(g, method))
