# SPDX-License-Identifier: Apache-2.0
"""The source method as baseline: exhaustive coarse-to-fine search over ZYZ Euler angles with fast z/y rotations.

Every candidate R = Rz(alpha) Ry(beta) Rz(gamma) is scored with the same cost as the default compass (cost.py):
the current view's functions are turned by gamma (z-step), by beta (fixed quarter turn J, z-step, J^T) and
compared with the snapshot's functions turned back by alpha (z-step), all candidates of one level at once. The
first level covers alpha, gamma in [0, 2 pi) and beta in [0, max tilt] with a coarse step; each next level
searches +-1 old step around the best candidates with the step divided by `factor`, down to `final_step`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skynav_compass.compass import UNITS
from skynav_compass.cost import CostProblem, PreparedSnapshot, build_problem, prepare_snapshot
from skynav_compass.estimate import CompassEstimate, Hypothesis
from skynav_compass.views import CompassView
from skynav_core.rotations import rotation_angle, zyz_matrix
from skynav_sh.rotation import quarter_turn_padded, rotate_z_padded, z_rotation_factors_padded

View = CompassView | np.ndarray
Snapshot = CompassView | np.ndarray | PreparedSnapshot  # a view, or one prepared by ExhaustiveCompass.prepare


def grid_channel_values(
    problem: CostProblem,
    alphas: np.ndarray,
    betas: np.ndarray,
    gammas: np.ndarray,
    turned_snapshot: np.ndarray | None = None,
) -> np.ndarray:
    """Return every channel at all R = Rz(a) Ry(b) Rz(g) of the outer grid: (channels, n_alpha, n_beta, n_gamma).

    turned_snapshot: Z(-alpha) a for these alphas, (A, q, L+1, 2L+1), if already at hand.
    """
    L = problem.max_degree
    size = 2 * L + 1
    turn = quarter_turn_padded(L)  # (L+1, 2L+1, 2L+1)
    r = problem.current.shape[0]
    # current side: Z(gamma) b, then J^T, Z(beta), J; columns (term, gamma) side by side for one BLAS product per l
    turned = rotate_z_padded(problem.current, np.asarray(gammas))  # (G, r, L+1, 2L+1)
    columns = turned.transpose(2, 3, 1, 0).reshape(L + 1, size, -1)  # (L+1, 2L+1, r G)
    back = np.matmul(np.swapaxes(turn, 1, 2), columns)  # J^T
    beta = np.asarray(betas, dtype=float)
    cos, sin = z_rotation_factors_padded(L, beta)  # (B, 2L+1)
    stepped = cos[:, None, :, None] * back[None] + sin[:, None, :, None] * back[None, :, ::-1, :]  # (B, L+1, 2L+1, r G)
    rotated = np.matmul(turn[None], stepped)  # (B, L+1, 2L+1, r G)
    n_beta, n_gamma = len(beta), len(gammas)
    # ((L+1)(2L+1), r B G): the columns of term j form one block (a strided view BLAS takes as it is)
    right = rotated.reshape(n_beta, L + 1, size, r, n_gamma).transpose(1, 2, 3, 0, 4).reshape((L + 1) * size, -1)
    # snapshot side: Z(alpha)^T a = Z(-alpha) a; each channel sums w <Z(-alpha) a_i, Y(beta) Z(gamma) b_j> over its
    # terms, one matrix product per term (only the pairs the cost uses)
    snap = (
        turned_snapshot
        if turned_snapshot is not None
        else rotate_z_padded(problem.snapshot, -np.asarray(alphas, dtype=float))
    )  # (A, q, L+1, 2L+1)
    n_alpha, block = snap.shape[0], n_beta * n_gamma
    out = np.zeros((len(problem.channels), n_alpha, block))
    for k, channel in enumerate(problem.channels):
        for i, j, w in channel:
            out[k] += w * (snap[:, i].reshape(n_alpha, -1) @ right[:, j * block : (j + 1) * block])
    return out.reshape(len(problem.channels), n_alpha, n_beta, n_gamma)


def grid_search_costs(
    problem: CostProblem,
    alphas: np.ndarray,
    betas: np.ndarray,
    gammas: np.ndarray,
    turned_snapshot: np.ndarray | None = None,
) -> np.ndarray:
    """Return the cost at all R = Rz(a) Ry(b) Rz(g) of the outer grid, (n_alpha, n_beta, n_gamma); inf if invalid."""
    values = list(grid_channel_values(problem, alphas, betas, gammas, turned_snapshot))
    with np.errstate(divide='ignore', invalid='ignore'):
        return problem.mask_invalid(values, problem.formula(values))


@dataclass(frozen=True)
class ExhaustiveConfig:
    """Settings of the exhaustive search (angles in rad)."""

    cost: str = 'masked'
    normalise: bool = False
    max_tilt: float | None = None  # largest beta searched at the coarse level; None: [0, pi]
    coarse_step: float | None = None  # None: 2 pi / (2L + 2), the default compass's grid step
    factor: int = 3  # step divisor per level
    final_step: float = np.radians(0.05)  # stop once the step is below this
    keep: int = 2  # best candidates carried from one level to the next
    min_overlap: float = 0.25


class ExhaustiveCompass:
    """The source method: exhaustive ZYZ search, coarse to fine, with the fast z-rotation and the fixed y trick."""

    def __init__(self, max_degree: int, config: ExhaustiveConfig | None = None) -> None:
        """Prepare the search of degree L."""
        self.max_degree = int(max_degree)
        self.config = config or ExhaustiveConfig()
        quarter_turn_padded(self.max_degree)

    @property
    def method(self) -> str:
        """Return a short name of the configured method."""
        return f'exhaustive-{self.config.cost}{"-normalised" if self.config.normalise else ""}'

    @property
    def coarse_step(self) -> float:
        """Return the step (rad) of the first level."""
        c = self.config
        return c.coarse_step if c.coarse_step is not None else 2 * np.pi / (2 * self.max_degree + 2)

    def _coarse_alphas(self) -> np.ndarray:
        """Return the alphas (= gammas) of the first level (rad)."""
        n = int(round(2 * np.pi / self.coarse_step))
        return 2 * np.pi / n * np.arange(n)

    def prepare(self, snapshot: Snapshot) -> PreparedSnapshot:
        """Return the snapshot's side of the search, built once for any number of estimates against it.

        Holds the padded snapshot functions and the snapshot turned by every alpha of the first level;
        `estimate(prepared, current)` equals `estimate(snapshot, current)`.
        """
        c = self.config
        prepared = prepare_snapshot(snapshot, self.max_degree, c.cost, c.normalise)
        alphas = self._coarse_alphas()
        prepared.memo[('exhaustive-coarse', len(alphas))] = rotate_z_padded(prepared.padded, -alphas)
        return prepared

    def estimate(self, snapshot: Snapshot, current: View) -> CompassEstimate:
        """Return R with d_snapshot = R d_current (camera_link) by exhaustive coarse-to-fine search.

        The snapshot may be a view or prepared by `prepare` (same estimate, less work per call).
        """
        c = self.config
        problem = build_problem(snapshot, current, self.max_degree, c.cost, c.normalise, c.min_overlap)
        alphas = self._coarse_alphas()
        step = 2 * np.pi / len(alphas)
        max_beta = np.pi if c.max_tilt is None else float(c.max_tilt)
        betas = np.linspace(0.0, max_beta, int(np.ceil(max_beta / step - 1e-9)) + 1)
        assert problem.side is not None  # a CostProblem always has its snapshot's side
        turned = problem.side.memo.get(('exhaustive-coarse', len(alphas)))
        costs = grid_search_costs(problem, alphas, betas, alphas, turned)
        candidates = self._best(costs, alphas, betas, alphas, c.keep, 2 * step)
        evaluated = costs.size
        offsets = np.arange(-c.factor, c.factor + 1)
        while step > c.final_step and candidates:
            step /= c.factor
            refined = []
            for _cost, (a, b, g) in candidates:
                local_a, local_g = a + step * offsets, g + step * offsets
                local_b = np.unique(np.clip(b + step * offsets, -max_beta, max_beta))  # stay within the tilt limit
                local = grid_search_costs(problem, local_a, local_b, local_g)
                evaluated += local.size
                refined.extend(self._best(local, local_a, local_b, local_g, 1, 0.0))
            refined.sort(key=lambda item: item[0])
            candidates = refined[: c.keep]
        units = UNITS[c.cost, c.normalise]
        if not candidates:
            return CompassEstimate(np.eye(3), float('inf'), (), 0.0, False, self.method, units)
        hypotheses = [Hypothesis(zyz_matrix(*angles), cost) for cost, angles in candidates]
        distinct = [
            h
            for k, h in enumerate(hypotheses)
            if all(rotation_angle(h.matrix, other.matrix) > np.radians(5) for other in hypotheses[:k])
        ]
        margin = distinct[1].cost - distinct[0].cost if len(distinct) > 1 else float('inf')
        return CompassEstimate(
            distinct[0].matrix,
            distinct[0].cost,
            tuple(distinct),
            margin,
            True,
            self.method,
            units,
            {'evaluated_rotations': evaluated},
        )

    @staticmethod
    def _best(
        costs: np.ndarray, alphas: np.ndarray, betas: np.ndarray, gammas: np.ndarray, keep: int, separation: float
    ) -> list[tuple[float, tuple[float, float, float]]]:
        """Return up to `keep` lowest (cost, (alpha, beta, gamma)) of a grid, at least `separation` rad apart."""
        order = np.argsort(costs, axis=None)
        out: list[tuple[float, tuple[float, float, float]]] = []
        matrices: list[np.ndarray] = []
        for flat in order[: max(keep, 1) * 64]:
            cost = float(costs.flat[flat])
            if not np.isfinite(cost):
                break
            i, j, k = np.unravel_index(flat, costs.shape)
            angles = (float(alphas[i]), float(betas[j]), float(gammas[k]))
            matrix = zyz_matrix(*angles)
            if all(rotation_angle(matrix, other) > separation for other in matrices):
                out.append((cost, angles))
                matrices.append(matrix)
            if len(out) == keep:
                break
        return out
