# SPDX-License-Identifier: Apache-2.0
"""Products of SH functions in the SH domain and the masked distance of two partly seen views (camera_link).

The product h = f g of degrees Lf, Lg has degree Lf + Lg; h_l3m3 = sum G(l1 m1, l2 m2, l3 m3) f_l1m1 g_l2m2 with the
real Gaunt coefficients G. The masked distance compares two views only where both have data:
    D(f, g) = integral of v_f v_g (f - g)^2 / integral of v_f v_g,
v_f, v_g being the visibilities (1 seen, 0 not seen) as SH coefficients. It splits into terms of each view alone,
    integral v_f v_g (f - g)^2 = <v_f f^2, v_g> - 2 <v_f f, v_g g> + <v_f, v_g g^2>,   area = <v_f, v_g>
(<a, b> = sum of a_lm b_lm = integral of a b), so MaskedView holds (v, v f, v f^2) and turns with rotate().
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skynav_core.rotations import RotationLike
from skynav_sh.basis import SPHERE_AREA, degree_from_size, n_coefficients
from skynav_sh.coupling import real_gaunt
from skynav_sh.errors import ShError
from skynav_sh.rotation import rotate
from skynav_sh.transform import grid


def product_grid_degree(degree_f: int, degree_g: int, degree_out: int) -> int:
    """Return the least grid degree whose quadrature makes the product's coefficients up to degree_out exact."""
    return max((degree_f + degree_g + degree_out + 1) // 2, degree_out, degree_f, degree_g)


def product(f: np.ndarray, g: np.ndarray, max_degree: int | None = None, method: str = 'grid') -> np.ndarray:
    """Return the coefficients (..., (L+1)^2) of the pointwise product f g, exact up to L (default Lf + Lg)."""
    # method 'gaunt': contraction with the cached sparse real Gaunt coefficients (cost grows like L^5);
    # 'grid': synthesis of both on an exact quadrature grid, product, analysis (cost ~L^3; same numbers)
    f, g = np.asarray(f, dtype=float), np.asarray(g, dtype=float)
    degree_f, degree_g = degree_from_size(f.shape[-1]), degree_from_size(g.shape[-1])
    degree = degree_f + degree_g if max_degree is None else int(max_degree)
    batch = np.broadcast_shapes(f.shape[:-1], g.shape[:-1])
    f = np.broadcast_to(f, batch + f.shape[-1:]).reshape(-1, f.shape[-1])
    g = np.broadcast_to(g, batch + g.shape[-1:]).reshape(-1, g.shape[-1])
    if method == 'grid':
        quadrature = grid(product_grid_degree(degree_f, degree_g, degree))
        out = quadrature.analysis(quadrature.synthesis(f) * quadrature.synthesis(g))[:, : n_coefficients(degree)]
    elif method == 'gaunt':
        matrix = real_gaunt(degree_f, degree_g, degree).product_matrix
        outer = (f[:, :, None] * g[:, None, :]).reshape(f.shape[0], -1)
        out = np.asarray((matrix @ outer.T).T)
    else:
        raise ShError(f"unknown product method {method!r} (expected 'grid' or 'gaunt')")
    return out.reshape(*batch, n_coefficients(degree))


def inner(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return the integral of a b over the sphere from coefficients, over the degrees both have (Parseval)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    n = min(a.shape[-1], b.shape[-1])
    return np.sum(a[..., :n] * b[..., :n], axis=-1)


@dataclass(frozen=True)
class MaskedView:
    """A view prepared for masked comparisons: v (degree Lv), v f (Lv + L) and v f^2 (kept to degree Lv)."""

    visibility: np.ndarray
    weighted: np.ndarray
    weighted_square: np.ndarray

    @classmethod
    def from_coefficients(cls, f: np.ndarray, visibility: np.ndarray, method: str = 'grid') -> MaskedView:
        """Return the masked terms of a view f (..., (L+1)^2) with visibility coefficients (..., (Lv+1)^2)."""
        visibility = np.asarray(visibility, dtype=float)
        degree_v = degree_from_size(visibility.shape[-1])
        weighted = product(visibility, f, method=method)
        weighted_square = product(weighted, f, max_degree=degree_v, method=method)
        return cls(visibility, weighted, weighted_square)

    def rotated(self, rotation: RotationLike) -> MaskedView:
        """Return the terms of the view turned by R (see rotate(): f(R^T d)); products commute with rotations."""
        return MaskedView(
            rotate(self.visibility, rotation), rotate(self.weighted, rotation), rotate(self.weighted_square, rotation)
        )


def masked_distance_views(a: MaskedView, b: MaskedView) -> np.ndarray:
    """Return the integral of v_a v_b (f_a - f_b)^2 over that of v_a v_b (value^2); inf where the overlap is empty."""
    if a.visibility.shape[-1] != b.visibility.shape[-1] or a.weighted.shape[-1] != b.weighted.shape[-1]:
        raise ShError('masked views of different degrees')
    squared = (
        inner(a.weighted_square, b.visibility)
        - 2 * inner(a.weighted, b.weighted)
        + inner(a.visibility, b.weighted_square)
    )
    area = inner(a.visibility, b.visibility)
    return np.where(area > 0, squared / np.where(area > 0, area, 1.0), np.inf)


def masked_distance(
    f: np.ndarray, g: np.ndarray, visibility_f: np.ndarray, visibility_g: np.ndarray, method: str = 'grid'
) -> np.ndarray:
    """Return the mean of (f - g)^2 over the region both views see (integral of v_f v_g (f - g)^2 / its area)."""
    return masked_distance_views(
        MaskedView.from_coefficients(f, visibility_f, method), MaskedView.from_coefficients(g, visibility_g, method)
    )


def overlap_area(visibility_f: np.ndarray, visibility_g: np.ndarray) -> np.ndarray:
    """Return the integral of v_f v_g (sr): the solid angle both views see."""
    return inner(visibility_f, visibility_g)


#: Least share (dimensionless) of what a view sees that sky and ground must each cover for the view to show a
#: skyline. Below it (all sky, all ground) nothing in the view tells places or rotations apart: it is featureless.
MIN_CLASS_SHARE = 0.01


def cap_area(theta_max: float) -> float:
    """Return the solid angle (sr) of the cap theta <= theta_max (rad) about +z."""
    return float(2 * np.pi * (1 - np.cos(np.clip(theta_max, 0.0, np.pi))))


def seen_mean(weighted: np.ndarray, visibility: np.ndarray) -> np.ndarray:
    """Return the mean of f over what a view sees, c_00(v f) / c_00(v) (a mask: its sky share); 0 if it sees nothing."""
    weighted, visibility = np.asarray(weighted, dtype=float), np.asarray(visibility, dtype=float)
    seen = visibility[..., 0]
    return np.divide(weighted[..., 0], seen, out=np.zeros_like(seen), where=seen > 0)


def message_sky_share(coefficients: np.ndarray, field_of_view: float, fill: str = 'zero') -> np.ndarray | float:
    """Return the sky share of what views see from their masks' SH (..., n) as /skyline/sh carries them (rad, fill).

    zero fill: c_00 over that of the seen cap; mean fill carries the seen part's mean onto the whole sphere (exactly),
    mirror fill about so. A field of view that is not known (not in (0, 2 pi]) counts as the whole sphere.
    """
    c00 = np.asarray(coefficients, dtype=float)[..., 0]
    known = fill == 'zero' and 0 < field_of_view <= 2 * np.pi
    area = cap_area(0.5 * field_of_view) if known else SPHERE_AREA
    share = c00 * (np.sqrt(SPHERE_AREA) / area)
    return float(share) if share.ndim == 0 else share


def shows_skyline(sky_share: np.ndarray | float, min_share: float = MIN_CLASS_SHARE) -> np.ndarray | bool:
    """Return whether a mask view whose sky covers `sky_share` of what it sees shows a skyline (both classes >= min)."""
    share = np.asarray(sky_share, dtype=float)
    result = (share >= min_share) & (share <= 1.0 - min_share)
    return bool(result) if result.ndim == 0 else result
