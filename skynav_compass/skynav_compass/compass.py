# SPDX-License-Identifier: Apache-2.0
"""The default visual 3D compass: SO(3) correlation on a ZYZ Euler grid by FFTs, then Newton refinement.

For two views (snapshot and current) the cost of every rotation R = Rz(alpha) Ry(beta) Rz(gamma) on the grid
comes at once from SO(3) correlations (so3.so3_correlation: per beta a 2D inverse FFT over alpha and gamma).

A ground robot's physics is the prior: the grid's tilt beta between the two views runs only up to `max_tilt`
(MAX_TILT: 45 degrees, two views on opposite slopes of the rough lawn a mower drives on), the refinement never
steps beyond it, so no estimate turns the camera upside down; rotations whose fields of view overlap by less than
`min_overlap` of the smaller view are refused.

Several grid minima (hypotheses) are followed up. For two skyline masks each takes one Newton step on the rotation
vector with the exact cost, all are verified on sphere samples of the two masks (verify.py: the share of the
overlap where they disagree), and the best few by verification are refined by Newton steps (refine.refine) and
verified again: the least disagreement wins. For other views (grey images, filled views) the lowest grid minimum is
refined and the others' optima predicted by one Newton model; those that come close are refined fully, and the
least cost wins. The estimate is R with d_snapshot = R d_current in camera_link (docs/interfaces.md), its residual the
cost there, and a confidence in [0, 1] that ranks estimates: how sharply the cost rises along the optimum's least
determined axis (the Hessian's smallest eigenvalue over the typical grid cost), times how much skyline the overlap
holds (verified: the share two unrelated masks of its sky shares would disagree on) and how much better the best
fits the masks than the closest distinct rival (MIN_RIVAL_MARGIN: never confident below it), or how clearly the
best's cost stands out of the other hypotheses' (not verified).

Many views compared against one snapshot: `prepared = compass.prepare(snapshot)` does the snapshot's share of the
work once (padded and complex coefficients, the derivative matrix of the refinement), and
`compass.estimate(prepared, current)` gives the same estimate as `compass.estimate(snapshot, current)`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skynav_compass.cost import CostProblem, PreparedSnapshot, build_problem, cost_channels, prepare_snapshot
from skynav_compass.estimate import CompassEstimate, Hypothesis
from skynav_compass.refine import Refined, newton_prediction, refine
from skynav_compass.so3 import EulerGrid
from skynav_compass.verify import current_masks, is_binary, verify
from skynav_compass.views import CompassView
from skynav_core.rotations import MAX_TILT, as_matrix, rotation_angle, zyz_matrix

View = CompassView | np.ndarray
Snapshot = CompassView | np.ndarray | PreparedSnapshot  # a view, or one prepared by Compass.prepare
#: Evidence (sharpness x skyline share, rad^-2) at which the confidence is 1/2: on the real-landscape and synthetic
#: compass sets, estimates within 5 degrees of the truth mostly lie far above it, wrong ones below it.
CONFIDENCE_SCALE = 0.05
#: Verified hypotheses: how much better the best must fit the two masks than the closest distinct rival, as
#: rival_margin = 1 - best / rival disagreement. Two rotations that explain the views almost equally well (an open
#: horizon turned half round) leave the yaw undecided however sharp the best one's minimum is. On the real
#: landscapes' compass sets (seed 1, L = 16 and 32) every estimate marked confident more than 5 degrees off had a
#: rival margin of 0.02-0.25, and a skyline that is alike half a turn round gives 0.14-0.2 for its exact tie (the
#: two rotations see different parts of it at the rim); 95 % of the right estimates had more than 0.26. Below
#: MIN_RIVAL_MARGIN an estimate is never confident; below RIVAL_MARGIN_SCALE its evidence is scaled down in
#: proportion, so a close rival costs the confidence of an estimate whose other evidence is weak too. Checked on
#: seed 2 at another time of day (held out): no estimate marked confident more than 2.2 degrees off, against 84
#: degrees without the margin.
MIN_RIVAL_MARGIN = 0.25
RIVAL_MARGIN_SCALE = 0.4
UNITS = {
    ('masked', False): 'mean squared difference over the overlap (value^2)',
    ('masked', True): '1 - correlation coefficient over the overlap',
    ('plain', False): 'integral of the squared difference (value^2 sr)',
    ('plain', True): '2 - 2 correlation of unit-norm views without c_00',
}


@dataclass(frozen=True)
class CompassConfig:
    """Settings of the compass (angles in rad)."""

    cost: str = 'masked'  # 'masked' (only where both views see) or 'plain' (filled views, whole sphere)
    normalise: bool = False  # illumination invariance: gain and offset of f drop out
    max_tilt: float | None = MAX_TILT  # largest relative tilt (Euler beta) searched; None: all of [0, pi]
    verify: bool = True  # rank the refined hypotheses of two skyline masks on sphere samples (verify.py)
    oversampling: float = 1.0  # Euler grid with n = oversampling (2L + 2) steps in alpha and gamma
    hypotheses: int = 8  # grid minima followed up (one Newton step each)
    refined: int = 3  # verified hypotheses refined to convergence (the best few after one step)
    min_overlap: float = 0.5  # masked: least overlap, as a share of the smaller view's area
    max_residual: float = float('inf')  # confident only if the residual is at most this (the method's units)
    min_relative_margin: float = 0.05  # (second - best) / (mean grid cost - best) below this lowers the confidence
    min_rival_margin: float = MIN_RIVAL_MARGIN  # verified: confident only if the rival margin is at least this
    rival_margin_scale: float = RIVAL_MARGIN_SCALE  # verified: a rival margin below this scales the confidence down
    min_confidence: float = 0.5  # confident only if the confidence is at least this
    separation: float = np.radians(5.0)  # hypotheses closer than this (rad) count as one


def any_tilt_config(**changes) -> CompassConfig:
    """Return the settings of a compass without the ground robot's prior: the whole of SO(3), refused overlap below
    a quarter, three hypotheses ranked by the SH cost alone (as the default was before the tilt bound)."""
    return CompassConfig(**{'max_tilt': None, 'verify': False, 'hypotheses': 3, 'min_overlap': 0.25, **changes})


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
    return [(int(i), int(j), int(k)) for i, j, k in zip(*np.unravel_index(order, costs.shape))]


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
        return f'fft-{self.config.cost}{"-normalised" if self.config.normalise else ""}'

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
        failed = CompassEstimate(
            np.eye(3), float('inf'), (), 0.0, False, self.method, UNITS[c.cost, c.normalise], confidence=0.0
        )
        if not minima:
            return failed
        angles = np.array([self.grid.angles(index) for index in minima])
        matrices = zyz_matrix(*angles.T)
        # cos of the angle between two rotations is (trace(A^T B) - 1) / 2; keep minima 2 grid steps apart
        close = np.einsum('aij,bij->ab', matrices, matrices) > 1.0 + 2.0 * np.cos(2 * self.grid.step)
        kept: list[int] = []
        for k in range(len(minima)):
            if not any(close[k, j] for j in kept):
                kept.append(k)
                if len(kept) == c.hypotheses:
                    break
        starts = matrices[kept]
        start_jets = problem.jets(starts)  # all starts in one pass
        typical = float(np.mean(costs[np.isfinite(costs)]))  # the landscape's level; its depth is typical - best
        details: dict = {'typical_cost': typical}
        if c.verify and is_binary(problem):
            results = self._verified_optima(problem, starts, start_jets, details)
        else:
            results = self._optima(problem, starts, start_jets, typical, details)
        found: list[tuple[Hypothesis, Refined]] = []
        distinct: list[int] = []  # where the found ones stand in results
        for k, result in enumerate(results):  # best first
            if np.isfinite(result.cost) and all(
                rotation_angle(result.matrix, h.matrix) > c.separation for h, _ in found
            ):
                found.append((Hypothesis(result.matrix, result.cost), result))
                distinct.append(k)
        if not found:
            return failed
        best, optimum = found[0]
        others = [h.cost for h, _ in found[1:]]
        margin = min(others) - best.cost if others else float('inf')
        # the margin against the depth of the cost landscape: the mean grid cost above the best
        depth = typical - best.cost
        relative = float(np.clip(margin / depth, 0.0, 1.0)) if depth > 0 else 0.0
        # how sharply the cost rises along the optimum's least determined axis, against the cost's typical level
        curvature = float(np.linalg.eigvalsh(optimum.hessian)[0]) if np.all(np.isfinite(optimum.hessian)) else 0.0
        sharpness = max(curvature, 0.0) / typical if typical > 0 else 0.0
        verified = details.get('verified')
        if verified is not None:  # and how much of the overlap holds skyline, and how clearly no rival fits as well
            rival = rival_margin(verified.disagreement[distinct])
            details.update(rival_margin=rival)
            evidence = sharpness * float(verified.contrast[0])
            if c.rival_margin_scale > 0:
                evidence *= min(rival / c.rival_margin_scale, 1.0)
        else:  # and how clearly the best stands out of the other hypotheses
            evidence = (
                sharpness * min(relative / c.min_relative_margin, 1.0) if c.min_relative_margin > 0 else sharpness
            )
        confidence = evidence / (evidence + CONFIDENCE_SCALE)
        details.update(sharpness=sharpness)
        confident = (
            best.cost <= c.max_residual
            and confidence >= c.min_confidence
            and details.get('rival_margin', 1.0) >= c.min_rival_margin
        )
        return CompassEstimate(
            best.matrix,
            best.cost,
            tuple(h for h, _ in found),
            margin,
            confident,
            self.method,
            UNITS[c.cost, c.normalise],
            details,
            relative_margin=relative,
            confidence=confidence,
        )

    def _optima(
        self, problem: CostProblem, starts: np.ndarray, start_jets: list, typical: float, details: dict
    ) -> list[Refined]:
        """Return the local optima of the SH cost near the starts (3x3 each), lowest cost first.

        The best start is refined to convergence; for the others one Newton model predicts the cost of their local
        minimum (all the margin needs), and those that come close to the best are refined fully.
        """
        c = self.config
        first = refine(problem, starts[0], radius=self.grid.step, jet=start_jets[0], max_tilt=c.max_tilt)
        results = [first]
        competitive = first.cost + 2.0 * c.min_relative_margin * (typical - first.cost)
        predicted = 0
        for matrix, jet in zip(starts[1:], start_jets[1:]):
            result = newton_prediction(problem, matrix, radius=self.grid.step, jet=jet, max_tilt=c.max_tilt)
            if result.cost <= competitive:
                result = refine(problem, result.matrix, radius=self.grid.step, max_tilt=c.max_tilt)
            else:
                predicted += 1
            results.append(result)
        details.update(refine_iterations=sum(r.iterations for r in results), predicted_hypotheses=predicted)
        return sorted(results, key=lambda r: r.cost)

    def _verified_optima(
        self, problem: CostProblem, starts: np.ndarray, start_jets: list, details: dict
    ) -> list[Refined]:
        """Return local optima of the SH cost near the starts, ranked on sphere samples of the two masks (verify.py).

        Every start takes one Newton step (its Jet is at hand) and is verified there; the best few by verification
        are refined to convergence and verified again, best first.
        """
        c = self.config
        stepped = [
            newton_prediction(problem, matrix, radius=self.grid.step, jet=jet, max_tilt=c.max_tilt)
            for matrix, jet in zip(starts, start_jets)
        ]
        masks = current_masks(problem)
        first = verify(problem, np.stack([r.matrix for r in stepped]), masks)
        chosen = np.lexsort((np.array([r.cost for r in stepped]), first.score))[: c.refined]
        results = [refine(problem, stepped[k].matrix, radius=self.grid.step, max_tilt=c.max_tilt) for k in chosen]
        checked = verify(problem, np.stack([r.matrix for r in results]), masks)
        order = np.lexsort((np.array([r.cost for r in results]), checked.score))
        details.update(
            refine_iterations=sum(r.iterations for r in results),
            verified=checked.subset(order),
            screened=first,
            hessian=results[order[0]].hessian,
        )
        return [results[k] for k in order]


def rival_margin(disagreements: np.ndarray) -> float:
    """Return 1 - best / rival of distinct hypotheses' verified disagreements (best first): 0 when the rival fits as
    well as the best (both perfectly, too), 1 without a rival or when only the best fits perfectly."""
    if len(disagreements) < 2 or not np.isfinite(disagreements[1]):
        return 1.0
    if disagreements[1] <= 0:
        return 0.0
    return float(np.clip(1.0 - disagreements[0] / disagreements[1], 0.0, 1.0))


def estimate_rotation(
    snapshot: Snapshot, current: View, max_degree: int | None = None, config: CompassConfig | None = None
) -> CompassEstimate:
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
