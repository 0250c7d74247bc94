# SPDX-License-Identifier: Apache-2.0
"""Views prepared for warping: the masked terms (v, v f, v f^2) of a partly seen view as SH coefficients.

A fish-eye sees a cap of the sphere. Warping compares a predicted snapshot with the real one only where both
have data (skynav_sh.product's masked distance):
    D = integral of v_p v_s (p - s)^2 / integral of v_p v_s.
Warping and turning a view commute with pointwise products, so the three terms of a view, X0 = v, X1 = v f and
X2 = v f^2, are warped on their own and D follows from inner products of the terms of both views. Here all three
are kept to one degree L (their products would need more; the search only ranks hypotheses, so the truncation is
shared by all of them; it leaves a floor: two identical views cost about 2 % of what a 40-degree turn costs).
The visibility v is the seen fraction of every cell, optionally tapered to 0 over the last
`rim_taper` radians before the image circle, which keeps the band-limited terms from ringing at the rim.
Frames: camera_link of the view (theta from +z). Units: the view's values (mask: sky 1, ground 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skynav_sh.basis import degree_from_size, n_coefficients
from skynav_sh.transform import grid
from skynav_warping.errors import WarpingError

DEFAULT_RIM_TAPER = np.radians(10.0)  # rad


@dataclass(frozen=True)
class WarpView:
    """A view's masked terms: terms[0] = v, terms[1] = v f, terms[2] = v f^2, each (L+1)^2 coefficients."""

    terms: np.ndarray  # (3, (L+1)^2), camera_link of the view

    @property
    def degree(self) -> int:
        """Return the degree L of the terms."""
        return degree_from_size(self.terms.shape[-1])

    @property
    def seen_area(self) -> float:
        """Return the integral of v (sr): the solid angle the view sees."""
        return float(self.terms[0, 0] * np.sqrt(4 * np.pi))

    def truncated(self, degree: int) -> WarpView:
        """Return the terms kept to degree <= `degree`."""
        return WarpView(np.ascontiguousarray(self.terms[:, : n_coefficients(degree)]))


def rim_weights(theta: np.ndarray, theta_max: float, rim_taper: float = DEFAULT_RIM_TAPER) -> np.ndarray:
    """Return the rim taper at polar angles theta (rad): 1 inside, a cosine fall to 0 over the last rim_taper rad."""
    if rim_taper <= 0:
        return np.ones_like(np.asarray(theta, dtype=float))
    x = np.clip((theta_max - np.asarray(theta, dtype=float)) / rim_taper, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * x)


def view_from_samples(
    quadrature, values: np.ndarray, visibility: np.ndarray, degree: int, standardise: bool = False
) -> WarpView:
    """Return the terms of a view from grid samples f and visibility v (n_theta, n_phi) on a skynav_sh grid."""
    values = np.asarray(values, dtype=float)
    visibility = np.asarray(visibility, dtype=float)
    if standardise:  # zero mean, unit variance over the seen part: for grey values of unknown exposure
        weights = quadrature.weights * visibility
        mean = np.sum(weights * values) / np.sum(weights)
        spread = np.sqrt(np.sum(weights * (values - mean) ** 2) / np.sum(weights))
        values = (values - mean) / max(spread, 1e-12)
    stack = np.stack([visibility, visibility * values, visibility * values * values])
    terms = quadrature.analysis(stack)[:, : n_coefficients(degree)]
    return WarpView(np.ascontiguousarray(terms))


def view_from_fisheye(
    transform,
    image: np.ndarray,
    degree: int | None = None,
    rim_taper: float = DEFAULT_RIM_TAPER,
    standardise: bool = False,
) -> WarpView:
    """Return the terms of a fish-eye image or mask through a skynav_sh FisheyeTransform with fill 'zero'."""
    if transform.fill != 'zero':
        raise WarpingError(f"warping needs a FisheyeTransform with fill 'zero', not {transform.fill!r}")
    # with the zero fill a cell's sample is (seen fraction) x (mean over its seen part)
    samples = transform.samples(image)
    fraction = transform.visibility
    values = np.divide(samples, fraction, out=np.zeros_like(samples), where=fraction > 0)
    taper = rim_weights(transform.grid.theta, transform.theta_max, rim_taper)[:, None]
    return view_from_samples(
        transform.grid, values, fraction * taper, transform.max_degree if degree is None else int(degree), standardise
    )


def cap_fraction(quadrature, theta_max: float) -> np.ndarray:
    """Return the share (n_theta, n_phi) of every grid cell with theta <= theta_max (exact: rings are cos bands)."""
    upper = 1.0 - np.concatenate([[0.0], np.cumsum(quadrature.theta_weights)[:-1]])
    lower = upper - quadrature.theta_weights
    fraction = np.clip((upper - np.cos(theta_max)) / (upper - lower), 0.0, 1.0)
    return np.repeat(fraction[:, None], quadrature.n_phi, axis=1)


def view_from_coefficients(
    coefficients: np.ndarray,
    field_of_view: float,
    degree: int | None = None,
    rim_taper: float = DEFAULT_RIM_TAPER,
    standardise: bool = False,
) -> WarpView:
    """Return the terms of a view given as SH coefficients (e.g. /skyline/sh) seen up to field_of_view / 2 (rad)."""

    coefficients = np.asarray(coefficients, dtype=float)
    source_degree = degree_from_size(coefficients.shape[-1])
    degree = source_degree if degree is None else int(degree)
    # four times finer than degree L needs (as FisheyeTransform samples), since the rim and its taper are sharp, and
    # fine enough that f^2 (degree 2 L_source) times Y_lm (l <= L) integrates exactly (nodes: L_grid + 1)
    quadrature = grid(max(4 * (degree + 1), source_degree + degree + 1))
    theta_max = 0.5 * float(field_of_view)
    visibility = cap_fraction(quadrature, theta_max) * rim_weights(quadrature.theta, theta_max, rim_taper)[:, None]
    return view_from_samples(quadrature, quadrature.synthesis(coefficients), visibility, degree, standardise)
