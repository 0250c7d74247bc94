# SPDX-License-Identifier: Apache-2.0
"""Verification of compass hypotheses on sphere samples of the two skyline masks, recovered from their SH.

The SH cost compares band-limited functions: v f, v f^2 and v cut to degree L. Where a skyline runs close to the
rim of the field of view (an open field, a roof-top panorama: the horizon 0-10 degrees above the rim of a 200-degree
fish-eye) that cut blurs the skyline into the rim, and the cost of a wrong rotation that pushes the skyline out of
the overlap can come out as low as the right one's. On samples the masks are sharp again: each view's skyline
mask is recovered as f = (v f)_L / v_L > 1/2 where the view sees (v_L > 1/2), and a hypothesis R is judged by the
share of the overlap where the two masks disagree (the snapshot's mask at R d against the current's at d). The
skyline's position survives the cut to degree L far better than its edge does, so the sharp masks tell a right
rotation from a wrong one that the blurred cost cannot.

Only binary views (skyline masks: v f^2 = v f) are verified; grey views keep the SH cost.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from skynav_compass.cost import CostProblem
from skynav_sh.layouts import from_padded
from skynav_sh.rotation import rotate_by_matrix
from skynav_sh.transform import GaussLegendreGrid

#: Sample grid: 65 Gauss-Legendre rings of 128 nodes, 2.8 degrees apart (more if the views' degree needs them).
#: Fine enough to follow the recovered skyline (at 3.7 degrees the choice got worse on the real landscapes at
#: L = 16, at 5.5 it failed; at L = 32 2.8 chose as well as 1.4), coarse enough for a few hypotheses per ms.
SAMPLE_RINGS = 65
SAMPLE_AZIMUTHS = 128
#: Least v_L by which v f is divided to recover f near the rim (the cut visibility falls to 1/2 at the rim).
VISIBILITY_FLOOR = 0.25


@dataclass(frozen=True)
class Verification:
    """Sample figures of K hypotheses R (d_snapshot = R d_current), each (K,).

    disagreement: share (0..1) of the overlap where the two recovered masks differ; overlap: the overlap's
    solid angle as a share of the smaller view's; contrast: the share two unrelated masks with the overlap's sky
    shares would disagree on, p_s (1 - p_c) + p_c (1 - p_s) (0 when the overlap holds only sky or only ground).
    """

    disagreement: np.ndarray
    overlap: np.ndarray
    contrast: np.ndarray

    @property
    def score(self) -> np.ndarray:
        """Return what ranks the hypotheses, lowest best: the disagreement."""
        return self.disagreement

    def subset(self, index) -> Verification:
        """Return the figures of some hypotheses (an index array or slice)."""
        return Verification(self.disagreement[index], self.overlap[index], self.contrast[index])


@lru_cache(maxsize=8)
def sample_grid(max_degree: int):  # -> skynav_sh.transform.GaussLegendreGrid
    """Return the shared Gauss-Legendre sample grid for views of SH degree L (SAMPLE_RINGS x SAMPLE_AZIMUTHS)."""

    L = int(max_degree)
    return GaussLegendreGrid(L, n_phi=max(SAMPLE_AZIMUTHS, 2 * L + 2), n_theta=max(SAMPLE_RINGS, L + 1))


def is_binary(problem: CostProblem) -> bool:
    """Return whether both views of a masked problem are binary masks (v f^2 = v f on both sides)."""
    if problem.kind != 'masked':
        return False
    snapshot, current = problem.snapshot, problem.current
    return _same(snapshot[0], snapshot[1]) and _same(current[1], current[2])


def _same(first: np.ndarray, second: np.ndarray) -> bool:
    """Return whether two coefficient arrays agree to rounding (one transform of a mask may give both)."""
    scale = max(float(np.max(np.abs(first), initial=0.0)), 1e-300)
    return bool(np.max(np.abs(first - second), initial=0.0) <= 1e-9 * scale)


def recovered_masks(weighted: np.ndarray, visibility: np.ndarray, max_degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Return (seen, sky) booleans on the sample grid of flat coefficients v f and v (..., (L+1)^2)."""
    values = sample_grid(max_degree).synthesis(np.stack([weighted, visibility], axis=-2))
    v_f, v = values[..., 0, :, :], values[..., 1, :, :]
    seen = v > 0.5
    return seen, v_f > 0.5 * np.maximum(v, VISIBILITY_FLOOR)


def current_masks(problem: CostProblem) -> tuple[np.ndarray, np.ndarray]:
    """Return (seen, sky) of a masked problem's current view on the sample grid."""
    return recovered_masks(from_padded(problem.current[1]), from_padded(problem.current[0]), problem.max_degree)


def verify(
    problem: CostProblem, rotations: np.ndarray, current: tuple[np.ndarray, np.ndarray] | None = None
) -> Verification:
    """Return the sample figures of rotations R (K, 3, 3) for a masked problem of two binary views.

    current: the current view's masks (current_masks), if already at hand.
    """
    rotations = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
    L = problem.max_degree
    grid = sample_grid(L)
    # the current view on the grid as it is; the snapshot's at R d for every node d: its functions turned by R^T
    seen_c, sky_c = current_masks(problem) if current is None else current
    turned = from_padded(rotate_by_matrix(problem.snapshot[1:], np.swapaxes(rotations, 1, 2)))  # (K, 2, n): v f, v
    seen_s, sky_s = recovered_masks(turned[:, 0], turned[:, 1], L)
    weights = grid.weights
    both = (seen_s & seen_c) * weights  # (K, n_theta, n_phi)
    area = np.sum(both, axis=(1, 2))
    smaller = min(float(np.sum(weights * seen_c)), float(np.sum(weights[None] * seen_s, axis=(1, 2)).min()))
    with np.errstate(divide='ignore', invalid='ignore'):
        disagreement = np.sum(both * (sky_s != sky_c), axis=(1, 2)) / area
        share_s = np.sum(both * sky_s, axis=(1, 2)) / area
        share_c = np.sum(both * sky_c, axis=(1, 2)) / area
    contrast = share_s * (1 - share_c) + share_c * (1 - share_s)
    empty = area <= 0
    return Verification(np.where(empty, 1.0, disagreement), area / max(smaller, 1e-300), np.where(empty, 0.0, contrast))
