"""The default visual 3D compass: SO(3) correlation on a ZYZ Euler grid by FFTs, then Newton refinement.

For two views (snapshot and current) the cost of every rotation R = Rz(alpha) Ry(beta) Rz(gamma) on the grid
comes at once from SO(3) correlations (so3.so3_correlation: per beta a 2D inverse FFT over alpha and gamma). The
lowest grid minimum is refined by Newton steps on the rotation vector with the exact cost (refine.refine); for the
next few distinct minima (hypotheses) one Newton model predicts the cost of their optimum, and those that come
close are refined fully. The estimate is R with d_snapshot = R d_current in camera_link (CONTRACT.md), its
residual the cost there; a small margin to the second hypothesis (relative to the depth of the cost landscape)
or a large residual marks it as not confident instead of silently picking one of several similar yaws.

Many views compared against one snapshot: `prepared = compass.prepare(snapshot)` does the snapshot's share of the
work once (padded and complex coefficients, the derivative matrix of the refinement), and
`compass.estimate(prepared, current)` gives the same estimate as `compass.estimate(snapshot, current)`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import numpy as np

from skynav_compass.cost import CostProblem, PreparedSnapshot, build_problem, cost_channels, prepare_snapshot
from skynav_compass.estimate import CompassEstimate, Hypothesis
from skynav_compass.refine import newton_prediction, refine
from skynav_compass.so3 import EulerGrid
from skynav_compass.views import CompassView

View = Union[CompassView, np.ndarray]
Snapshot = Union[CompassView, np.ndarray, PreparedSnapshot]  # a view, or one prepared by Compass.prepare
UNITS = {('masked', False): 'mean squared difference over the overlap (value^2)',
         ('masked', True): '1 - correlation coefficient over the overlap',
         ('plain', False): 'integral of the squared difference (value^2 sr)',
         ('plain', True): '2 - 2 correlation of unit-norm views without c_00'}


@dataclass(frozen=True)
class CompassConfig:
    """Settings of the compass (angles in rad)."""

    cost: str = 'masked'  # 'masked' (only where both views see) or 'plain' (filled views, whole sphere)
    normalise: bool = False  # illumination invariance: gain and offset of f drop out
    max_tilt: float | None = None  # largest relative tilt (Euler beta) searched; None: all of [0, pi]
    oversampling: float = 1.0  # Euler grid with n = oversampling (2L + 2) steps in alpha and gamma
    hypotheses: int = 3  # grid minima refined and kept
    min_overlap: float = 0.25  # masked: least overlap, as a share of the smaller view's area
    max_residual: float = float('inf')  # confident only if the residual is at most this (the method's units)
    min_relative_margin: float = 0.05  # confident only if (second - best) / (mean grid cost - best) is at least this
    separation: float = np.radians(5.0)  # hypotheses closer than this (rad) count as one


def rotation_angle(first: np.ndarray, second: np.ndarray) -> float:
    """Return the angle (rad) of the rotation first^T second between two 3x3 rotations."""
    cosine = (float(np.sum(np.asarray(first) * np.asarray(second))) - 1.0) / 2.0  # trace(first^T second)
    return float(np.arccos(np.clip(cosine, -1.0, 1.0)))


def zyz_matrices(alpha: np.ndarray, beta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Return the matrices Rz(alpha) Ry(beta) Rz(gamma) (..., 3, 3) of ZYZ angle arrays (rad)."""
    ca, sa, cb, sb, cg, sg = (f(x) for x in (alpha, beta, gamma) for f in (np.cos, np.sin))
    return np.stack([
        np.stack([ca * cb * cg - sa * sg, -ca * cb * sg - sa * cg, ca * sb], -1),
        np.stack([sa * cb * cg + ca * sg, -sa * cb * sg + ca * cg, sa * sb], -1),
        np.stack([-sb * cg, sb * sg, cb], -1)], -2)


def neighbourhood_minimum(costs: np.ndarray) -> np.ndarray:
    """Return the least value over every cell's 3x3x3 neighbourhood of grid costs [beta, alpha, gamma]."""
    # separable: gamma and alpha wrap around, beta (poles at its ends) does not
    padded = np.concatenate([costs[:, :, -1:], costs, costs[:, :, :1]], axis=2)
    low = np.minimum(np.minimum(padded[:, :, :-2], padded[:, :, 1:-1]), padded[:, :, 2:])
    padded = np.concatenate([low[:, -1:], low, low[:, :1]], axis=1)
    low = np.minimum(np.minimum(padded[:, :-2], padded[:, 1:-1]), padded[:, 2:])
    out = low.copy()
    np.minimum(out[1:], low[:-1], out=out[1:])
    np.minimum(out[:-1], low[1:], out=out[:-1])
    return out


def grid_minima(costs: np.ndarray, count: int, pole_rows: tuple[int, ...] = ()) -> list[tuple[int, int, int]]:
    """Return indices (beta, alpha, gamma) of the lowest local minima of grid costs (at most 4 count), lowest first.

    pole_rows: beta rows at 0 or pi, where only alpha + gamma (or alpha - gamma) matters; their gamma = 0 cell stands
    for the whole row, so one rotation is not listed many times.
    """
    flat = costs.ravel()
    finite = np.isfinite(costs)
    slack = 1e-9 * float(np.max(np.abs(costs[finite]), initial=1.0))  # FFT rounding between equal rotations
    candidate = finite & (costs <= neighbourhood_minimum(costs) + slack)
    for row in pole_rows:
        candidate[row, :, 1:] = False
    candidates = np.flatnonzero(candidate)
    order = candidates[np.argsort(flat[candidates], kind='stable')][: max(count, 1) * 4]
    return [tuple(int(i) for i in np.unravel_index(c, costs.shape)) for c in order]


class Compass:
    """The visual 3D compass of degree L: FFT correlation on an Euler grid, then refinement; tables built once."""

    def __init__(self, max_degree: int, config: CompassConfig | None = None) -> None:
        """Prepare the Euler grid and its Wigner small-d table for degree L."""
        self.max_degree = int(max_degree)
        self.config = config or CompassConfig()
        max_beta = np.pi if self.config.max_tilt is None else float(self.config.max_tilt)
        self.grid = EulerGrid.create(self.max_degree, self.config.oversampling, max_beta)
        self.grid.half_table()  # build and cache now, not in the first estimate

    @property
    def method(self) -> str:
        """Return a short name of the configured method."""
        return f"fft-{self.config.cost}{'-normalised' if self.config.normalise else ''}"

    def prepare(self, snapshot: Snapshot) -> PreparedSnapshot:
        """Return the snapshot's side of this compass's cost, built once for any number of estimates against it.

        `estimate(prepared, current)` equals `estimate(snapshot, current)` and skips the snapshot's share of the work
        (the padded and complex coefficients and the refinement's derivative matrix are built here, on first use).
        """
        c = self.config
        prepared = prepare_snapshot(snapshot, self.max_degree, c.cost, c.normalise)
        prepared.conjugate()  # build the cached parts now, not in the first estimate
        prepared.zonal()
        prepared.channel_matrix(cost_channels(c.cost, c.normalise), True)
        return prepared

    def problem(self, snapshot: Snapshot, current: View) -> CostProblem:
        """Return the cost problem of two views (CompassView for 'masked', coefficients or CompassView for 'plain')."""
        c = self.config
        return build_problem(snapshot, current, self.max_degree, c.cost, c.normalise, c.min_overlap)

    def cost(self, snapshot: Snapshot, current: View, rotation) -> float:
        """Return the cost of a rotation R (scipy Rotation, 3x3 or quaternion x, y, z, w; d_s = R d_c)."""
        from skynav_sh.rotation import as_matrix

        return self.problem(snapshot, current).cost(as_matrix(rotation))

    def grid_costs(self, snapshot: Snapshot, current: View) -> np.ndarray:
        """Return the cost on the Euler grid (n_beta, n, n) [beta, alpha, gamma] (see self.grid for the angles)."""
        return self.problem(snapshot, current).grid_costs(self.grid)

    def estimate(self, snapshot: Snapshot, current: View) -> CompassEstimate:
        """Return R with d_snapshot = R d_current (camera_link), its residual and the other hypotheses.

        The snapshot may be a view or prepared by `prepare` (same estimate, less work per call).
        """
        c = self.config
        problem = self.problem(snapshot, current)
        costs = problem.grid_costs(self.grid)
        poles = tuple(k for k, beta in enumerate(self.grid.betas) if min(beta, np.pi - beta) < 1e-12)
        minima = grid_minima(costs, c.hypotheses, poles)
        starts: list[tuple[np.ndarray, float]] = []
        if minima:
            angles = np.array([self.grid.angles(index) for index in minima])
            matrices = zyz_matrices(angles[:, 0], angles[:, 1], angles[:, 2])
            # cos of the angle between two rotations is (trace(A^T B) - 1) / 2; keep minima 2 grid steps apart
            close = np.einsum('aij,bij->ab', matrices, matrices) > 1.0 + 2.0 * np.cos(2 * self.grid.step)
            kept: list[int] = []
            for k in range(len(minima)):
                if not any(close[k, j] for j in kept):
                    kept.append(k)
                    if len(kept) == c.hypotheses:
                        break
            starts = [(matrices[k], float(costs[minima[k]])) for k in kept]
        if not starts:
            return CompassEstimate(np.eye(3), float('inf'), (), 0.0, False, self.method, UNITS[c.cost, c.normalise])
        # the best grid minimum is refined to convergence; for the others one Newton model predicts the cost of their
        # local minimum (all the margin needs), and those that come close to the best are refined fully
        start_jets = problem.jets(np.stack([matrix for matrix, _ in starts]))  # all starts in one pass
        first = refine(problem, starts[0][0], radius=self.grid.step, jet=start_jets[0])
        results = [first]
        typical = float(np.mean(costs[np.isfinite(costs)]))  # the landscape's level; its depth is typical - best
        competitive = first.cost + 2.0 * c.min_relative_margin * (typical - first.cost)
        predicted = 0
        for (matrix, _), jet in zip(starts[1:], start_jets[1:]):
            result = newton_prediction(problem, matrix, radius=self.grid.step, jet=jet)
            if result.cost <= competitive:
                result = refine(problem, result.matrix, radius=self.grid.step)
            else:
                predicted += 1
            results.append(result)
        iterations = sum(r.iterations for r in results)
        found: list[Hypothesis] = []
        for result in sorted(results, key=lambda r: r.cost):
            if np.isfinite(result.cost) and all(rotation_angle(result.matrix, h.matrix) > c.separation for h in found):
                found.append(Hypothesis(result.matrix, result.cost))
        if not found:
            return CompassEstimate(np.eye(3), float('inf'), (), 0.0, False, self.method, UNITS[c.cost, c.normalise])
        found.sort(key=lambda h: h.cost)
        best = found[0]
        margin = found[1].cost - best.cost if len(found) > 1 else float('inf')
        # the margin against the depth of the cost landscape: the mean grid cost above the best
        depth = typical - best.cost
        relative = float(np.clip(margin / depth, 0.0, 1.0)) if depth > 0 else 0.0
        confident = best.cost <= c.max_residual and relative >= c.min_relative_margin
        details = {'refine_iterations': iterations, 'predicted_hypotheses': predicted}
        return CompassEstimate(best.matrix, best.cost, tuple(found), margin, confident, self.method,
                               UNITS[c.cost, c.normalise], details, relative_margin=relative)


def estimate_rotation(snapshot: Snapshot, current: View, max_degree: int | None = None,
                      config: CompassConfig | None = None) -> CompassEstimate:
    """Return the compass estimate of two views with a cached Compass of degree L (default: the views' degree)."""
    if max_degree is None:
        if isinstance(snapshot, PreparedSnapshot):
            max_degree = snapshot.max_degree
        else:
            source = snapshot.weighted if isinstance(snapshot, CompassView) else snapshot
            max_degree = int(round(np.sqrt(np.shape(source)[-1]))) - 1
    return _cached_compass(int(max_degree), config or CompassConfig()).estimate(snapshot, current)


_COMPASSES: dict = {}


def _cached_compass(max_degree: int, config: CompassConfig) -> Compass:
    """Return a shared Compass of degree L and settings (its tables are built once)."""
    key = (max_degree, config)
    if key not in _COMPASSES:
        if len(_COMPASSES) >= 8:
            _COMPASSES.pop(next(iter(_COMPASSES)))
        _COMPASSES[key] = Compass(max_degree, config)
    return _COMPASSES[key]
