# SPDX-License-Identifier: Apache-2.0
"""Views prepared for the compass: SH coefficients of v f, v f^2 and v (camera_link, contract order and basis).

f is the view's value (a skyline mask: sky 1, ground 0; or a grey value), v its visibility (the seen share of
each direction, 1 inside the fish-eye's image circle, 0 outside). The masked cost compares two views only where
both see, through these three functions (see cost.py); nothing outside the field of view enters, so no fill does.
For a binary mask v f^2 = v f at every point, so a mask needs one transform.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import eval_legendre

from skynav_compass.errors import CompassError
from skynav_sh.basis import SPHERE_AREA, degree_from_size, n_coefficients
from skynav_sh.fisheye import image_values
from skynav_sh.product import product

FILL_MODES = ('zero', 'mean', 'mirror')


def cap_visibility(max_degree: int, theta_max: float) -> np.ndarray:
    """Return the SH coefficients (degree L) of the cap theta <= theta_max (rad) about +z: 1 inside, 0 outside."""
    # zonal: c_l0 = 2 pi N_l0 integral_{cos theta_max}^1 P_l(x) dx,
    # with (2l+1) integral_a^1 P_l = P_(l-1)(a) - P_(l+1)(a)

    L = int(max_degree)
    a = float(np.cos(theta_max))
    l = np.arange(L + 1)
    integral = np.where(
        l == 0, 1.0 - a, (eval_legendre(np.maximum(l - 1, 0), a) - eval_legendre(l + 1, a)) / (2 * l + 1)
    )
    out = np.zeros(n_coefficients(L))
    out[l * l + l] = 2 * np.pi * np.sqrt((2 * l + 1) / SPHERE_AREA) * integral
    return out


def _truncate(coefficients: np.ndarray, max_degree: int) -> np.ndarray:
    """Return coefficients cut (or zero-extended) to degree L."""
    coefficients = np.asarray(coefficients, dtype=float)
    out: np.ndarray = np.zeros(coefficients.shape[:-1] + (n_coefficients(max_degree),))  # numpy's stubs: 0-d
    n = min(out.shape[-1], coefficients.shape[-1])
    out[..., :n] = coefficients[..., :n]
    return out


@dataclass(frozen=True)
class CompassView:
    """One view for the masked compass: SH coefficients (degree L) of v f, v f^2 and v, all in camera_link."""

    weighted: np.ndarray  # v f
    weighted_square: np.ndarray  # v f^2
    visibility: np.ndarray  # v (1 seen, 0 not)

    def __post_init__(self) -> None:
        sizes = {np.shape(self.weighted)[-1], np.shape(self.weighted_square)[-1], np.shape(self.visibility)[-1]}
        if len(sizes) != 1:
            raise CompassError('the three functions of a CompassView must have the same degree')
        degree_from_size(sizes.pop())

    @property
    def max_degree(self) -> int:
        """Return the SH degree L of the view."""
        return degree_from_size(np.shape(self.weighted)[-1])

    def truncated(self, max_degree: int) -> CompassView:
        """Return the view cut (or zero-extended) to degree L."""
        return CompassView(
            _truncate(self.weighted, max_degree),
            _truncate(self.weighted_square, max_degree),
            _truncate(self.visibility, max_degree),
        )

    @property
    def area(self) -> float:
        """Return the solid angle the view sees (sr)."""
        return float(self.visibility[0] * np.sqrt(SPHERE_AREA))

    @classmethod
    def from_samples(
        cls, grid, samples: np.ndarray, seen: np.ndarray, square_samples: np.ndarray | None = None
    ) -> CompassView:
        """Return the view of cell values v f (samples), v f^2 (default v f: binary) and v (seen) on an SH grid."""
        # grid: a skynav_sh GaussLegendreGrid; its analysis is truncated at grid.max_degree
        if square_samples is None:  # binary: f^2 = f, one analysis fewer and the two terms exactly alike
            weighted, visibility = grid.analysis(np.stack([samples, seen]))
            return cls(weighted, weighted.copy(), visibility)
        weighted, weighted_square, visibility = grid.analysis(np.stack([samples, square_samples, seen]))
        return cls(weighted, weighted_square, visibility)

    @classmethod
    def from_image(cls, transform, image: np.ndarray, binary: bool | None = None) -> CompassView:
        """Return the view of a fish-eye mask or grey image through a zero-fill FisheyeTransform (camera_link)."""
        # binary None: decided from the data (bool images, or only the values 0 and the dtype's maximum)

        if transform.fill != 'zero':
            raise CompassError("CompassView.from_image needs a FisheyeTransform with fill='zero' (it yields v f)")
        values = image_values(image)
        if binary is None:
            binary = bool(np.all((values == 0) | (values == 1)))
        samples = transform.samples(values)
        square = None if binary else transform.samples(np.square(values))
        return cls.from_samples(transform.grid, samples, transform.visibility, square)

    @classmethod
    def from_coefficients(
        cls,
        coefficients: np.ndarray,
        visibility: np.ndarray | None = None,
        max_degree: int | None = None,
        binary: bool = False,
    ) -> CompassView:
        """Return the view of a function f (coefficients, unseen part arbitrary) and visibility v by SH products.

        The products are exact for band-limited f and v (degree L defaults to that of f); visibility None means the
        full sphere (v = 1).
        """

        f = np.asarray(coefficients, dtype=float)
        degree = degree_from_size(f.shape[-1]) if max_degree is None else int(max_degree)
        if visibility is None:
            v = np.zeros(n_coefficients(degree))
            v[0] = np.sqrt(SPHERE_AREA)
            seen_f = f
        else:
            v = _truncate(visibility, degree)
            seen_f = product(np.asarray(visibility, dtype=float), f)
        weighted = _truncate(seen_f, degree)
        full = weighted if binary else product(seen_f, f, max_degree=degree)
        return cls(weighted, full, v)

    @classmethod
    def from_sh_message(
        cls, coefficients: np.ndarray, field_of_view: float, fill: str = 'zero', max_degree: int | None = None
    ) -> CompassView:
        """Return the view of a skyline mask's SH (ShCoefficients: coefficients, fill, field_of_view in rad).

        zero fill: v f is the message itself; mean fill: v f = f - mu (1 - v) with mu = c_00 / sqrt(4 pi) exactly;
        mirror fill: v f by the SH product with the cap (approximate). A mask is binary, so v f^2 = v f.
        """

        f = np.asarray(coefficients, dtype=float)
        degree = degree_from_size(f.shape[-1]) if max_degree is None else int(max_degree)
        v = cap_visibility(degree, field_of_view / 2)
        if fill == 'zero':
            weighted = _truncate(f, degree)
        elif fill == 'mean':
            mean = f[0] / np.sqrt(SPHERE_AREA)
            unseen = -v
            unseen[0] += np.sqrt(SPHERE_AREA)
            weighted = _truncate(f, degree) - mean * unseen
        elif fill == 'mirror':
            weighted = product(cap_visibility(degree_from_size(f.shape[-1]), field_of_view / 2), f, max_degree=degree)
        else:
            raise CompassError(f'unknown fill {fill!r}; expected one of {FILL_MODES}')
        return cls(weighted, weighted, v)
