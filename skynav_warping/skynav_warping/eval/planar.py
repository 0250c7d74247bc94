# SPDX-License-Identifier: Apache-2.0
"""Planar warping baselines on panoramic images: 2D-warping (Franz et al. 1998) and min-warping (Moeller 2010).

Both search a movement of the robot in the plane and a turn about the vertical, and predict the current view from
the snapshot. Geometry (snapshot frame, azimuths from +x towards +y): the current place lies at distance d in
direction alpha from the snapshot's place, and the current camera is turned by psi about the vertical
(d_snapshot = Rz(psi) d_current). A landmark seen at azimuth x from the snapshot's place and at x' (snapshot frame)
from the current place satisfies sin(x' - x) = (d / r) sin(x' - alpha), r its distance from the snapshot's place;
seen from the current place it lies on the arc from x (r -> infinity) towards alpha + pi (r -> 0), and looks
|sin(x' - alpha)| / |sin(x - alpha)| = r / r' times larger (r' its distance from the current place).
The home vector in the current camera_link points from the current place to the snapshot's: azimuth
alpha + pi - psi, in the camera's horizontal plane.

Assumptions (why these are baselines for a mower on bumpy ground):
- planar motion: both cameras upright, moving in one horizontal plane; the camera_link x-y plane is taken for
  the ground plane, so any tilt of either camera is read as parallax, and the home vector has no vertical part;
- only a turn about the vertical between the views (one angle psi), no roll or pitch;
- 2D-warping: all landmarks at the same distance r from the snapshot's place (equal-distance assumption, one ratio
  d / r searched for the whole view) and a one-dimensional image (the band's mean per azimuth column);
- min-warping: every snapshot column may have its own distance (no equal-distance assumption); it is matched to
  the most similar current column on its arc (the nearest-neighbour / minimum assumption), with the vertical
  magnification r / r' that the arc position implies (scale planes); the band is a 2D panoramic image;
- both: the search is on a grid of alpha and psi steps of the image's azimuth step, landmarks are
  static and visible in both views, and the images are comparable as values (for masks: sky 1, ground 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from skynav_warping.errors import WarpingError


@dataclass(frozen=True)
class PlanarResult:
    """A planar warping estimate; direction and rotation in the current camera_link."""

    direction: np.ndarray  # unit home vector (cos, sin, 0) of azimuth alpha + pi - psi
    rotation: np.ndarray  # Rz(psi): d_snapshot = R d_current
    movement_azimuth: float  # alpha (rad): direction of the current place from the snapshot's, snapshot frame
    turn: float  # psi (rad)
    distance_ratio: float  # d / r of the optimum (2D-warping); nan for min-warping (per column)
    residual: float  # mean squared difference at the optimum (image units^2)
    residual_no_movement: float  # best cost of a pure turn
    confidence: float  # 1 - residual / residual_no_movement, in [0, 1]


def _result(alpha: float, psi: float, ratio: float, cost: float, still: float) -> PlanarResult:
    """Return the PlanarResult of a planar optimum (angles in rad)."""
    home = alpha + np.pi - psi
    c, s = np.cos(psi), np.sin(psi)
    confidence = float(np.clip(1.0 - cost / still, 0.0, 1.0)) if still > 0 else 0.0
    return PlanarResult(
        direction=np.array([np.cos(home), np.sin(home), 0.0]),
        rotation=np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]),
        movement_azimuth=float(np.remainder(alpha, 2 * np.pi)),
        turn=float(np.remainder(psi, 2 * np.pi)),
        distance_ratio=float(ratio),
        residual=float(cost),
        residual_no_movement=float(still),
        confidence=confidence,
    )


def horizon_profile(panorama: np.ndarray) -> np.ndarray:
    """Return the one-dimensional image of 2D-warping: the mean of every azimuth column of a band (n_azimuth,)."""
    return np.asarray(panorama, dtype=float).mean(axis=0)


def _periodic_interpolation(values: np.ndarray, position: np.ndarray) -> np.ndarray:
    """Return values (n,) read at fractional column positions by linear interpolation, period n."""
    n = values.shape[-1]
    low = np.floor(position)
    weight = position - low
    low = low.astype(int) % n
    return (1 - weight) * values[low] + weight * values[(low + 1) % n]


DEFAULT_RATIOS_2D = tuple(np.linspace(0.1, 0.9, 9))  # d / r searched by 2D-warping


def warping_2d(
    snapshot: np.ndarray, current: np.ndarray, ratios: tuple[float, ...] = DEFAULT_RATIOS_2D, n_alpha: int | None = None
) -> PlanarResult:
    """Return the 2D-warping home vector from one-dimensional images or panoramic bands (rows averaged).

    snapshot, current: (n,) or (rows, n), column j at azimuth 2 pi j / n; alpha searched in n_alpha steps (default
    n), psi in steps of one column, d / r over `ratios` (each < 1).
    """
    s = horizon_profile(np.atleast_2d(snapshot))
    c = horizon_profile(np.atleast_2d(current))
    n = s.shape[0]
    if c.shape[0] != n:
        raise WarpingError('snapshot and current images need the same number of columns')
    n_alpha = n if n_alpha is None else int(n_alpha)
    step = 2 * np.pi / n
    alphas = 2 * np.pi * np.arange(n_alpha) / n_alpha
    nu = np.asarray(ratios, dtype=float)
    if np.any((nu <= 0) | (nu >= 1)):
        raise WarpingError('distance ratios d / r must lie in (0, 1)')
    seen_at = step * np.arange(n)  # x': azimuth (snapshot frame) at which the current place sees the landmark
    # the snapshot's azimuth x of that landmark: x = x' - asin(nu sin(x' - alpha)); (alpha, nu, x')
    source = seen_at - np.arcsin(nu[None, :, None] * np.sin(seen_at - alphas[:, None, None]))
    warped = _periodic_interpolation(s, source / step)  # the snapshot warped to the current place, snapshot frame
    # predicted current column y = snapshot-frame column y + psi: cost over all psi by circular correlation
    correlation = np.fft.irfft(np.conj(np.fft.rfft(c)) * np.fft.rfft(warped, axis=-1), n=n, axis=-1)  # [.., q]
    costs = (np.sum(c * c) + np.sum(warped * warped, axis=-1)[..., None] - 2 * correlation) / n
    a, r, q = np.unravel_index(np.argmin(costs), costs.shape)
    still_correlation = np.fft.irfft(np.conj(np.fft.rfft(c)) * np.fft.rfft(s), n=n)
    still = (np.sum(c * c) + np.sum(s * s) - 2 * still_correlation) / n
    return _result(alphas[a], q * step, nu[r], costs[a, r, q], float(np.min(still)))


DEFAULT_SCALES = tuple(2.0 ** (np.arange(-4, 5) / 4))  # r / r' of min-warping's scale planes (0.5 .. 2)


def scale_planes(
    snapshot: np.ndarray, current: np.ndarray, elevations: np.ndarray, scales: tuple[float, ...] = DEFAULT_SCALES
) -> np.ndarray:
    """Return D[k, i, j]: mean squared difference of snapshot column i magnified by scales[k] and current column j.

    A landmark r / r' times nearer from the current place appears at elevation e' with tan e' = (r / r') tan e;
    the magnified column reads the snapshot at tan e = tan e' / scale (rows outside the band are left out).
    elevations: (rows,) in rad, descending from row 0, as PanoramaUnwrapper gives them.
    """
    s = np.asarray(snapshot, dtype=float)
    c = np.asarray(current, dtype=float)
    e = np.asarray(elevations, dtype=float)
    order = np.argsort(e)  # np.interp wants ascending positions
    planes = []
    for scale in scales:
        source = np.arctan(np.tan(e) / scale)
        valid = ((source >= e.min()) & (source <= e.max())).astype(float)
        magnified = np.stack([np.interp(source, e[order], column[order]) for column in s.T], axis=1)  # (rows, n)
        weight = valid[:, None]
        count = max(valid.sum(), 1.0)
        planes.append(
            (
                np.sum(weight * magnified**2, 0)[:, None]
                + np.sum(weight * c**2, 0)[None, :]
                - 2 * (weight * magnified).T @ c
            )
            / count
        )
    return np.maximum(np.stack(planes), 0.0)


def min_warping_costs(
    planes: np.ndarray, scales: tuple[float, ...] = DEFAULT_SCALES, n_alpha: int | None = None
) -> np.ndarray:
    """Return min-warping costs [alpha a, psi q] (alpha = 2 pi a / n_alpha, psi = q column steps) from scale planes."""

    n_scales, n, _ = planes.shape
    n_alpha = n if n_alpha is None else int(n_alpha)
    step = 2 * np.pi / n
    log_scales = np.log(np.asarray(scales, dtype=float))
    columns = np.arange(n)
    # E[k, i, m] = D[k, i, -m mod n] over two periods, plus a plane of +inf for steps past an arc's end: then the
    # costs D[k, i, (t - q) mod n] of all turns q are the contiguous run E[k, i, m0 : m0 + n], m0 = -t mod n
    reversed_rows = planes[..., (-np.arange(2 * n)) % n]
    runs = sliding_window_view(np.concatenate([reversed_rows, np.full((1, n, 2 * n), np.inf)]), n, axis=-1)
    arc = np.arange(n // 2 + 1)  # steps along the arc, one column each
    costs = np.empty((n_alpha, n))
    for a in range(n_alpha):
        alpha = 2 * np.pi * a / n_alpha
        beta = np.angle(np.exp(1j * (step * columns - alpha)))  # x - alpha in (-pi, pi]
        side = np.where(beta >= 0, 1, -1)
        offset = side[:, None] * arc[None, :]  # (n, A) columns moved along the arc
        inside = arc[None, :] * step <= (np.pi - np.abs(beta))[:, None] + 1e-9  # the arc ends at alpha + pi
        moved = beta[:, None] + offset * step  # x' - alpha
        sin_beta = np.abs(np.sin(beta))[:, None]
        ratio = np.divide(np.abs(np.sin(moved)), sin_beta, out=np.ones_like(moved), where=sin_beta > 1e-9)
        ratio = np.where(ratio > 0, ratio, 1.0)  # r / r' of a landmark seen at x' from the current place
        plane = np.abs(np.log(ratio)[..., None] - log_scales).argmin(-1)  # nearest scale plane
        plane = np.where(inside, plane, n_scales)
        start = (-(columns[:, None] + offset)) % n  # t = current column (snapshot frame) before the turn
        costs[a] = runs[plane, columns[:, None], start].min(axis=1).mean(axis=0)
    return costs


def min_warping(
    snapshot: np.ndarray,
    current: np.ndarray,
    elevations: np.ndarray,
    scales: tuple[float, ...] = DEFAULT_SCALES,
    n_alpha: int | None = None,
) -> PlanarResult:
    """Return the min-warping home vector from two panoramic bands (rows, n) with row elevations (rad).

    Every snapshot column is matched with the best current column on its arc (within the scale planes); alpha in
    n_alpha steps (default n), psi in steps of one column.
    """
    planes = scale_planes(snapshot, current, elevations, scales)
    n = planes.shape[1]
    n_alpha = n if n_alpha is None else int(n_alpha)
    costs = min_warping_costs(planes, scales, n_alpha)
    a, q = np.unravel_index(np.argmin(costs), costs.shape)
    still = planes[int(np.argmin(np.abs(np.log(np.asarray(scales, dtype=float)))))]
    columns = np.arange(n)
    still_costs = np.array([np.mean(still[columns, (columns - q0) % n]) for q0 in range(n)])
    return _result(2 * np.pi * a / n_alpha, q * 2 * np.pi / n, np.nan, costs[a, q], float(still_costs.min()))
