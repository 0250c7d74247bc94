# SPDX-License-Identifier: Apache-2.0
"""Real spherical harmonics of the contract (docs/interfaces.md): index helpers, Legendre values, basis values.

Order: index l*l + l + m for l = 0..L, m = -l..l. Basis without Condon-Shortley phase:
Y_l0 = N_l0 P_l(cos theta), Y_lm = sqrt(2) N_lm P_l^m(cos theta) cos(m phi) (m > 0),
Y_lm = sqrt(2) N_l|m| P_l^|m|(cos theta) sin(|m| phi) (m < 0); theta from +z, phi from +x to +y.
"""

from __future__ import annotations

from functools import cache
from typing import overload

import numpy as np

from skynav_sh.errors import ShError

SPHERE_AREA = 4 * np.pi  # sr, solid angle of the whole unit sphere
#: The SH degree L skynav works at by default: the SH node publishes it and the compass and warping nodes use it
#: (views of another degree are refused or cut). Degrees with their own meaning keep their own names, e.g. the
#: localizer's DESCRIPTOR_DEGREE its acceptance thresholds were calibrated at.
DEFAULT_DEGREE = 16
SQRT2 = np.sqrt(2.0)


def n_coefficients(degree: int) -> int:
    """Return the number of real SH coefficients up to degree L: (L+1)^2."""
    return (int(degree) + 1) ** 2


def degree_from_size(size: int) -> int:
    """Return L of a coefficient vector of length (L+1)^2; raise ValueError for other lengths."""
    degree = int(round(np.sqrt(size))) - 1
    if degree < 0 or n_coefficients(degree) != size:
        raise ShError(f'{size} is not a number of SH coefficients (L+1)^2')
    return degree


@overload
def lm_index(degree: int, order: int) -> int: ...


@overload
def lm_index(degree: np.ndarray, order: np.ndarray | int) -> np.ndarray: ...


@overload
def lm_index(degree: int, order: np.ndarray) -> np.ndarray: ...


def lm_index(degree: np.ndarray | int, order: np.ndarray | int) -> np.ndarray | int:
    """Return the flat coefficient index l*l + l + m of degree l and order m."""
    return degree * degree + degree + order


@cache
def _degree_order(max_degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Return the cached read-only (l, m) arrays of degree L."""
    l = np.repeat(np.arange(max_degree + 1), 2 * np.arange(max_degree + 1) + 1)
    m = np.arange(n_coefficients(max_degree)) - l * l - l
    l.flags.writeable = False
    m.flags.writeable = False
    return l, m


def degree_order(max_degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Return (l, m) integer arrays of length (L+1)^2 for every flat coefficient index (read-only)."""
    return _degree_order(int(max_degree))


def degree_slices(max_degree: int) -> list[slice]:
    """Return the slice of the flat coefficient vector that holds degree l, for l = 0..L."""
    return [slice(l * l, (l + 1) * (l + 1)) for l in range(int(max_degree) + 1)]


@cache
def _recurrence_factors(max_degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Return a[l, m], b[l, m] of P_lm = a (x P_(l-1)m - b P_(l-2)m) for the fully normalised functions."""
    l = np.arange(max_degree + 1, dtype=float)[:, None]
    m = np.arange(max_degree + 1, dtype=float)[None, :]
    with np.errstate(divide='ignore', invalid='ignore'):
        a = np.sqrt((4 * l * l - 1) / (l * l - m * m))
        b = np.sqrt(((l - 1) ** 2 - m * m) / (4 * (l - 1) ** 2 - 1))
    valid = m < l - 1e-9
    a = np.where(valid, a, 0.0)
    b = np.where(valid & (m < l - 1.5), b, 0.0)
    return a, b


def normalised_legendre(max_degree: int, x: np.ndarray) -> np.ndarray:
    """Return N_lm P_l^m(x) of x = cos(theta) (no Condon-Shortley phase), (..., L+1, L+1) as [l, m], 0 for m > l."""
    # stable three-term recurrences on fully normalised values (sectoral start sqrt((2m+1)/(2m)) sin(theta), then
    # the l-recurrence), never factorials, so it holds for large L; values below ~1e-308 (high orders next to the
    # poles, beyond L ~ 150) underflow to zero
    L = int(max_degree)
    x = np.asarray(x, dtype=float)
    sin_theta = np.sqrt(np.clip(1.0 - x * x, 0.0, None))
    out = np.zeros((L + 1, L + 1) + x.shape)
    out[0, 0] = 1.0 / np.sqrt(SPHERE_AREA)
    for m in range(1, L + 1):
        out[m, m] = np.sqrt((2 * m + 1) / (2 * m)) * sin_theta * out[m - 1, m - 1]
    a, b = _recurrence_factors(L)
    expand = (slice(None),) + (None,) * x.ndim
    for l in range(1, L + 1):
        # orders m <= l - 1: m = l - 1 has no P_(l-2)m term (b = 0 there)
        out[l, :l] = a[l, :l][expand] * (
            x * out[l - 1, :l] - b[l, :l][expand] * out[l - 2, :l] if l >= 2 else x * out[l - 1, :l]
        )
    return np.moveaxis(out, (0, 1), (-2, -1))


def _azimuth_factors(max_degree: int, phi: np.ndarray) -> np.ndarray:
    """Return the azimuthal factor of every flat index: 1, sqrt(2) cos(m phi) or sqrt(2) sin(|m| phi); (..., n)."""
    _, m = degree_order(max_degree)
    angle = np.abs(m) * np.asarray(phi, dtype=float)[..., None]
    return np.where(m > 0, SQRT2 * np.cos(angle), np.where(m < 0, SQRT2 * np.sin(angle), 1.0))


def real_sh(max_degree: int, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Return Y_lm(theta, phi) for all l <= L in flat order, shape (..., (L+1)^2); angles in rad, camera_link."""
    theta, phi = np.broadcast_arrays(np.asarray(theta, dtype=float), np.asarray(phi, dtype=float))
    l, m = degree_order(max_degree)
    legendre = normalised_legendre(max_degree, np.cos(theta))
    return legendre[..., l, np.abs(m)] * _azimuth_factors(max_degree, phi)


def real_sh_directions(max_degree: int, directions: np.ndarray) -> np.ndarray:
    """Return Y_lm of unit directions (..., 3) in camera_link, shape (..., (L+1)^2)."""
    d = np.asarray(directions, dtype=float)
    theta = np.arctan2(np.hypot(d[..., 0], d[..., 1]), d[..., 2])
    return real_sh(max_degree, theta, np.arctan2(d[..., 1], d[..., 0]))
