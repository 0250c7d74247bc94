# SPDX-License-Identifier: Apache-2.0
"""Evaluation of place recognition on a route with ground truth: precision-recall, recall@1, and plots.

Definitions (one match per query; lower score = more confident):
- a match is *correct* when the matched snapshot's true position lies within `tolerance` (m, Euclidean over the
  coordinates given, map frame) of the query's true position;
- a query is *positive* when some snapshot of the map lies within the tolerance (an off-route query is not);
- accepting the queries whose score <= t gives precision(t) = correct accepted / accepted (1 when none is
  accepted) and recall(t) = correct accepted / positive queries; the curve has one point per distinct score;
- recall at 100 % precision: the largest recall of a point with precision 1;
- area under the PR curve: the step-wise sum over the points of (recall increase) x precision (average precision);
- recall@1: correct matches / positive queries, whatever the acceptance;
- of the matches the method's acceptance test accepted (`accepted`, what the localize node publishes): precision =
  correct accepted / accepted (1 when none is accepted), recall = correct accepted / positive queries, and how many
  off-route queries (no snapshot within the tolerance) it accepted: every one of them is wrong, whatever its index.
Plots use matplotlib's Agg canvas (no display, no pyplot state).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skynav_core.evaluation import Column, text_table
from skynav_localize.errors import LocalizeError

DEFAULT_TOLERANCE = 1.0  # m


def _distances_to(points: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Return the Euclidean distances (Q, N) between points (Q, k) and targets (N, k) (m)."""
    points, targets = np.asarray(points, float), np.asarray(targets, float)
    if points.ndim != 2 or targets.ndim != 2 or points.shape[1] != targets.shape[1]:
        raise LocalizeError(
            f'positions must be (Q, k) and (N, k) with the same k, got {points.shape} and {targets.shape}'
        )
    return np.linalg.norm(points[:, None, :] - targets[None, :, :], axis=-1)


def correct_matches(
    matched: np.ndarray,
    query_positions: np.ndarray,
    snapshot_positions: np.ndarray,
    tolerance: float = DEFAULT_TOLERANCE,
) -> np.ndarray:
    """Return per query (Q,) whether its matched snapshot index lies within tolerance (m) of its true position."""
    matched = np.asarray(matched, dtype=np.intp)
    query_positions = np.asarray(query_positions, float)
    snapshot_positions = np.asarray(snapshot_positions, float)
    valid = (matched >= 0) & (matched < len(snapshot_positions))
    out = np.zeros(matched.shape, dtype=bool)
    if np.any(valid):
        gap = np.linalg.norm(snapshot_positions[matched[valid]] - query_positions[valid], axis=-1)
        out[valid] = gap <= tolerance
    return out


def has_true_place(
    query_positions: np.ndarray, snapshot_positions: np.ndarray, tolerance: float = DEFAULT_TOLERANCE
) -> np.ndarray:
    """Return per query (Q,) whether any snapshot lies within tolerance (m) of it (an on-route, positive query)."""
    if len(snapshot_positions) == 0:
        return np.zeros(len(query_positions), dtype=bool)
    return np.min(_distances_to(query_positions, snapshot_positions), axis=1) <= tolerance


def nearest_snapshots(query_positions: np.ndarray, snapshot_positions: np.ndarray) -> np.ndarray:
    """Return per query (Q,) the index of the snapshot nearest to its true position (ground-truth match)."""
    return np.argmin(_distances_to(query_positions, snapshot_positions), axis=1)


@dataclass(frozen=True)
class PRCurve:
    """A precision-recall curve over the acceptance threshold, one point per distinct score (ascending)."""

    thresholds: np.ndarray  # (T,) accept score <= threshold
    precision: np.ndarray  # (T,)
    recall: np.ndarray  # (T,)


def precision_recall(scores: np.ndarray, correct: np.ndarray, positives: int) -> PRCurve:
    """Return the PR curve of matches with scores (Q,) (lower = surer), correctness (Q,), and the positive count."""
    scores = np.asarray(scores, dtype=float)
    correct = np.asarray(correct, dtype=bool)
    if scores.shape != correct.shape or scores.ndim != 1:
        raise LocalizeError(f'scores and correct must be (Q,) arrays of one shape, got {scores.shape}, {correct.shape}')
    order = np.argsort(scores, kind='stable')
    sorted_scores = scores[order]
    true_positives = np.cumsum(correct[order])
    accepted = np.arange(1, scores.size + 1)
    last_of_tie = (
        np.flatnonzero(np.append(sorted_scores[1:] != sorted_scores[:-1], True))
        if scores.size
        else np.zeros(0, dtype=np.intp)
    )
    tp, acc = true_positives[last_of_tie], accepted[last_of_tie]
    recall = tp / positives if positives > 0 else np.zeros(tp.shape)
    return PRCurve(sorted_scores[last_of_tie], tp / acc, recall)


def recall_at_full_precision(curve: PRCurve) -> float:
    """Return the largest recall among the curve's points with precision 1 (0 if the surest match is wrong)."""
    full = curve.precision >= 1.0
    return float(np.max(curve.recall[full])) if np.any(full) else 0.0


def threshold_at_full_precision(curve: PRCurve) -> float:
    """Return the largest score threshold that keeps precision 1 (-inf if even the surest match is wrong)."""
    full = np.flatnonzero(curve.precision >= 1.0)
    return float(curve.thresholds[full[-1]]) if full.size else -np.inf


def pr_auc(curve: PRCurve) -> float:
    """Return the area under the step-wise PR curve: sum of recall increases times precision (average precision)."""
    increase = np.diff(np.concatenate([[0.0], curve.recall]))
    return float(np.sum(increase * curve.precision))


def recall_at_1(correct: np.ndarray, positive: np.ndarray) -> float:
    """Return the share of positive queries whose best match is correct (whatever the acceptance)."""
    correct, positive = np.asarray(correct, bool), np.asarray(positive, bool)
    count = int(np.count_nonzero(positive))
    return float(np.count_nonzero(correct & positive)) / count if count else 0.0


@dataclass(frozen=True)
class LocalizationResult:
    """One method's figures on one query run against one map."""

    method: str
    tolerance: float  # m
    queries: int
    positives: int  # queries with a snapshot within the tolerance
    recall_at_full_precision: float
    auc: float
    recall_at_1: float
    threshold_at_full_precision: float  # largest acceptance threshold with precision 1 on this run
    curve: PRCurve
    correct: np.ndarray  # (Q,) bool
    matched: np.ndarray  # (Q,) snapshot index
    scores: np.ndarray  # (Q,)
    accepted: np.ndarray | None = None  # (Q,) bool, by the method's acceptance test, when given
    positive: np.ndarray | None = None  # (Q,) bool: a snapshot lies within the tolerance (on the route)

    @property
    def accepted_precision(self) -> float:
        """Return the precision of the matches the acceptance test accepted (1 when none; nan without a test)."""
        if self.accepted is None:
            return float('nan')
        count = int(np.count_nonzero(self.accepted))
        return float(np.count_nonzero(self.accepted & self.correct)) / count if count else 1.0

    @property
    def accepted_recall(self) -> float:
        """Return the recall of the matches the acceptance test accepted (nan without a test)."""
        if self.accepted is None:
            return float('nan')
        return float(np.count_nonzero(self.accepted & self.correct)) / self.positives if self.positives else 0.0

    @property
    def off_route_accepted(self) -> int:
        """Return how many off-route queries (no snapshot within the tolerance) the acceptance test accepted."""
        if self.accepted is None or self.positive is None:
            return 0
        return int(np.count_nonzero(self.accepted & ~self.positive))


def evaluate(
    method: str,
    matched: np.ndarray,
    scores: np.ndarray,
    query_positions: np.ndarray,
    snapshot_positions: np.ndarray,
    tolerance: float = DEFAULT_TOLERANCE,
    accepted: np.ndarray | None = None,
) -> LocalizationResult:
    """Return the figures of per-query matched indices and scores given true query and snapshot positions (m)."""
    matched = np.asarray(matched)
    correct = correct_matches(matched, query_positions, snapshot_positions, tolerance)
    positive = has_true_place(query_positions, snapshot_positions, tolerance)
    curve = precision_recall(scores, correct, int(np.count_nonzero(positive)))
    return LocalizationResult(
        method,
        float(tolerance),
        int(matched.size),
        int(np.count_nonzero(positive)),
        recall_at_full_precision(curve),
        pr_auc(curve),
        recall_at_1(correct, positive),
        threshold_at_full_precision(curve),
        curve,
        correct,
        matched,
        np.asarray(scores, float),
        None if accepted is None else np.asarray(accepted, bool),
        positive,
    )


TABLE_COLUMNS = (
    Column('method', 24, align='<'),
    Column('R@100%P', 8, '.3f'),
    Column('AUC', 6, '.3f'),
    Column('R@1', 6, '.3f'),
    Column('acc. P', 7, '.3f'),
    Column('acc. R', 7, '.3f'),
    Column('off acc.', 9),
    Column('thr@100%P', 10, '.4g'),
)


def format_table(results: Sequence[LocalizationResult]) -> str:
    """Return a plain-text table of results: method, recall@100%P, AUC, recall@1, and of the accepted matches
    precision, recall and the off-route queries accepted."""
    rows = [
        (
            r.method,
            r.recall_at_full_precision,
            r.auc,
            r.recall_at_1,
            r.accepted_precision,
            r.accepted_recall,
            f'{r.off_route_accepted}/{r.queries - r.positives}',
            r.threshold_at_full_precision,
        )
        for r in results
    ]
    tolerance = results[0].tolerance if results else DEFAULT_TOLERANCE
    return (
        text_table(TABLE_COLUMNS, rows) + f'\n(tolerance {tolerance:g} m; R@1 counts positive queries; acc. = accepted '
        'by the default acceptance test: precision, recall over positive queries, off-route queries accepted of '
        'all off-route)'
    )


# --- plots --------------------------------------------------------------------------------------------------------


def _title(title: str, synthetic: bool) -> str:
    """Return the title with the data's nature said plainly."""
    return f'{title} (synthetic data)' if synthetic else title


def _save(figure, path: str | Path | None):
    """Save a figure to path (format from the suffix) when given, and return it."""
    if path is not None:
        figure.savefig(path, dpi=120, bbox_inches='tight')
    return figure


def plot_pr_curves(
    results: Sequence[LocalizationResult],
    title: str = 'Place recognition: precision-recall',
    synthetic: bool = False,
    path: str | Path | None = None,
):
    """Return (and save to path) a figure with the PR curves of several methods, figures in the legend."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(6.4, 4.8))
    axes = figure.add_subplot()
    for result in results:
        recall = np.concatenate([[0.0], result.curve.recall])
        precision = np.concatenate([[1.0], result.curve.precision])
        axes.step(
            recall,
            precision,
            where='post',
            label=f'{result.method}: R@100%P {result.recall_at_full_precision:.2f}, AUC {result.auc:.2f}',
        )
    axes.set_xlim(0.0, 1.02)
    axes.set_ylim(0.0, 1.02)
    axes.set_xlabel('recall (share of on-route queries matched and accepted)')
    axes.set_ylabel('precision (share of accepted matches that are correct)')
    tolerance = results[0].tolerance if results else DEFAULT_TOLERANCE
    axes.set_title(_title(f'{title}\ncorrect = within {tolerance:g} m', synthetic))
    axes.grid(True, alpha=0.3)
    axes.legend(loc='lower left', fontsize='small')
    return _save(figure, path)


def plot_matches_along_route(
    snapshot_positions: np.ndarray,
    query_positions: np.ndarray,
    matched: np.ndarray,
    correct: np.ndarray,
    accepted: np.ndarray | None = None,
    title: str = 'Matches along the route',
    synthetic: bool = False,
    path: str | Path | None = None,
):
    """Return (and save) a top view of snapshots, queries and query->match lines, and matched vs true snapshot index."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    snapshots = np.asarray(snapshot_positions, float)
    queries = np.asarray(query_positions, float)
    matched = np.asarray(matched, dtype=np.intp)
    correct = np.asarray(correct, bool)
    accepted = np.ones(matched.shape, bool) if accepted is None else np.asarray(accepted, bool)
    valid = matched >= 0
    figure = Figure(figsize=(12.0, 5.2))
    top, index_axes = figure.subplots(1, 2)

    top.plot(snapshots[:, 0], snapshots[:, 1], '-', color='0.6', lw=1, zorder=1)
    top.plot(snapshots[:, 0], snapshots[:, 1], 'o', color='0.3', ms=3, zorder=2)
    top.plot(queries[:, 0], queries[:, 1], 'x', color='tab:blue', ms=4, zorder=3)
    for q in np.flatnonzero(valid):
        s = snapshots[matched[q]]
        top.plot(
            [queries[q, 0], s[0]],
            [queries[q, 1], s[1]],
            '-' if accepted[q] else ':',
            color='tab:green' if correct[q] else 'tab:red',
            lw=0.9,
            alpha=0.9 if accepted[q] else 0.5,
            zorder=2,
        )
    top.set_aspect('equal', adjustable='datalim')
    top.set_xlabel('x in map (m)')
    top.set_ylabel('y in map (m)')
    top.set_title('top view')
    top.grid(True, alpha=0.3)
    top.legend(
        handles=[
            Line2D([], [], color='0.3', marker='o', ls='-', ms=3, label='snapshots (taught route)'),
            Line2D([], [], color='tab:blue', marker='x', ls='', label='queries (true position)'),
            Line2D([], [], color='tab:green', label='correct match'),
            Line2D([], [], color='tab:red', label='wrong match'),
            Line2D([], [], color='0.4', ls=':', label='not accepted'),
        ],
        fontsize='small',
        loc='best',
    )

    order = np.arange(matched.size)
    if len(snapshots) and len(queries):
        truth = nearest_snapshots(queries, snapshots)
        index_axes.plot(order, truth, '-', color='0.6', label='nearest snapshot (ground truth)')
    for is_correct, colour, label in ((True, 'tab:green', 'correct'), (False, 'tab:red', 'wrong')):
        for is_accepted in (True, False):
            chosen = valid & (correct == is_correct) & (accepted == is_accepted)
            index_axes.plot(
                order[chosen],
                matched[chosen],
                'o',
                ms=4,
                color=colour,
                mfc=colour if is_accepted else 'none',
                label=f'{label}, {"accepted" if is_accepted else "not accepted"}',
            )
    index_axes.set_xlabel('query (frame number of the repeat drive)')
    index_axes.set_ylabel('matched snapshot index')
    index_axes.set_title('matched vs true snapshot')
    index_axes.grid(True, alpha=0.3)
    index_axes.legend(fontsize='small', loc='best')
    figure.suptitle(_title(title, synthetic))
    return _save(figure, path)


def compare(results: Mapping[str, LocalizationResult], ours: str, baselines: Sequence[str]) -> dict[str, bool]:
    """Return per baseline whether `ours` beats it: higher recall at 100 % precision, or equal and higher AUC."""
    mine = results[ours]
    return {
        name: (
            mine.recall_at_full_precision > results[name].recall_at_full_precision
            or (
                mine.recall_at_full_precision == results[name].recall_at_full_precision and mine.auc > results[name].auc
            )
        )
        for name in baselines
    }
