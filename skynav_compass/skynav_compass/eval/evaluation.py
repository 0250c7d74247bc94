# SPDX-License-Identifier: Apache-2.0
"""Evaluation of compass estimates against ground truth: angular errors, statistics, tables and plots.

Rotations are compass rotations R (d_snapshot = R d_current, camera_link) given as quaternions (..., 4) in
(x, y, z, w) order, scipy Rotations or 3x3 matrices (..., 3, 3). Angles out are in degrees.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import rankdata

from skynav_core.evaluation import Column, text_table
from skynav_core.rotations import RotationLike, as_matrix, rotation_angle, tilt

ERROR_THRESHOLD_DEG = 2.0  # the share of estimates under this error is reported
RIGHT_DEG = 5.0  # an estimate within this error (deg) counts as right when judging how its confidence ranks it


def angular_error(estimated: RotationLike, true: RotationLike) -> np.ndarray:
    """Return the angle (deg) of R_true^-1 R_est per estimate: the full 3D rotation error."""
    return np.degrees(rotation_angle(true, estimated))


def relative_tilt(rotations: RotationLike) -> np.ndarray:
    """Return the tilt (deg) of compass rotations: the angle between R z and z (the Euler beta of ZYZ)."""
    return np.degrees(tilt(rotations))


def heading(rotations: RotationLike) -> np.ndarray:
    """Return the heading (deg) of compass rotations: the azimuth of R x projected on the snapshot's xy-plane."""
    x = as_matrix(rotations)[..., :, 0]
    return np.degrees(np.arctan2(x[..., 1], x[..., 0]))


def heading_error(estimated, true) -> np.ndarray:
    """Return the absolute heading difference (deg, in [0, 180]): the error a yaw-only compass is judged by."""
    difference = heading(estimated) - heading(true)
    return np.abs((difference + 180.0) % 360.0 - 180.0)


@dataclass(frozen=True)
class ErrorStatistics:
    """Summary of angular errors (deg): median, 90th percentile, maximum, share under 2 deg, count."""

    median: float
    p90: float
    p95: float
    max: float
    share_under: float  # share (0..1) of errors below ERROR_THRESHOLD_DEG
    count: int

    def as_dict(self) -> dict:
        """Return the statistics as a plain dict."""
        return {
            'median': self.median,
            'p90': self.p90,
            'p95': self.p95,
            'max': self.max,
            'share_under_2deg': self.share_under,
            'count': self.count,
        }


def error_statistics(errors: Sequence[float] | np.ndarray, threshold: float = ERROR_THRESHOLD_DEG) -> ErrorStatistics:
    """Return median, p90, p95, max and the share under `threshold` deg of angular errors (deg)."""
    e = np.asarray(errors, dtype=float)
    if e.size == 0:
        nan = float('nan')
        return ErrorStatistics(nan, nan, nan, nan, nan, 0)
    e = np.where(np.isfinite(e), e, 180.0)  # a failed estimate counts as the worst error
    return ErrorStatistics(
        float(np.median(e)),
        float(np.percentile(e, 90)),
        float(np.percentile(e, 95)),
        float(e.max()),
        float(np.mean(e < threshold)),
        int(e.size),
    )


def roc_auc(scores: Sequence[float] | np.ndarray, positive: Sequence[bool] | np.ndarray) -> float:
    """Return the area under the ROC curve of scores (higher: more likely positive): the probability that a random
    positive scores above a random negative, ties counting half; NaN if either class is empty."""

    s, p = np.asarray(scores, dtype=float), np.asarray(positive, dtype=bool)
    n_positive, n_negative = int(p.sum()), int((~p).sum())
    if n_positive == 0 or n_negative == 0:
        return float('nan')
    ranks = rankdata(np.where(np.isnan(s), -np.inf, s))  # average ranks of ties (Mann-Whitney U)
    return float((ranks[p].sum() - n_positive * (n_positive + 1) / 2) / (n_positive * n_negative))


@dataclass(frozen=True)
class CompassResult:
    """One compass method's results on one set: errors (deg) per query frame and seconds per estimate."""

    method: str
    errors: np.ndarray  # (Q,) deg
    seconds: np.ndarray  # (Q,) s per estimate
    residuals: np.ndarray | None = None  # (Q,) cost at the optimum (method's units)
    confident: np.ndarray | None = None  # (Q,) bool
    confidence: np.ndarray | None = None  # (Q,) 0..1 (NaN: the method has none)
    tilts: np.ndarray | None = None  # (Q,) deg, the tilt between the two views each estimate claims

    def ranking(self) -> np.ndarray:
        """Return what ranks the estimates, higher more trusted: the confidence, else minus the residual."""
        if self.confidence is not None and np.all(np.isfinite(self.confidence)):
            return np.asarray(self.confidence, dtype=float)
        if self.residuals is None:
            return np.zeros(len(self.errors))
        return -np.where(np.isfinite(self.residuals), self.residuals, np.inf)

    def separation(self, selection: np.ndarray | None = None) -> float:
        """Return the ROC AUC of the ranking between estimates under RIGHT_DEG of error and the others (NaN if one
        side is empty)."""
        chosen = slice(None) if selection is None else selection
        errors = np.where(np.isfinite(self.errors), self.errors, 180.0)[chosen]
        return roc_auc(self.ranking()[chosen], errors < RIGHT_DEG)

    def confident_statistics(self, selection: np.ndarray | None = None) -> ConfidentStatistics:
        """Return the share of estimates marked confident and the median and worst error (deg) among them (a
        failed estimate counts as 180 degrees); NaN share without the flag, NaN errors when none is confident."""
        return confident_statistics(self.errors, self.confident, selection)


@dataclass(frozen=True)
class ConfidentStatistics:
    """How many estimates are marked confident (share 0..1, count) and how wrong those are (median, max; deg)."""

    share: float
    count: int
    median: float
    max: float


def confident_statistics(
    errors: np.ndarray, confident: np.ndarray | None, selection: np.ndarray | None = None
) -> ConfidentStatistics:
    """Return the share of estimates flagged confident and the median and worst error (deg) among those."""
    nan = float('nan')
    chosen = slice(None) if selection is None else selection
    e = np.where(np.isfinite(errors), errors, 180.0)[chosen]
    if confident is None or e.size == 0:
        return ConfidentStatistics(nan, 0, nan, nan)
    flags = np.asarray(confident, dtype=bool)[chosen]
    if not flags.any():
        return ConfidentStatistics(0.0, 0, nan, nan)
    return ConfidentStatistics(float(flags.mean()), int(flags.sum()), float(np.median(e[flags])), float(e[flags].max()))


def summary_rows(results: Sequence[CompassResult], groups: Mapping[str, np.ndarray]) -> list[dict]:
    """Return one row per (method, group): statistics of the errors in each group (boolean masks over queries)."""
    rows = []
    for result in results:
        for group, selection in groups.items():
            stats = error_statistics(result.errors[selection])
            sure = result.confident_statistics(selection)
            rows.append(
                {
                    'method': result.method,
                    'group': group,
                    **stats.as_dict(),
                    'confident_share': sure.share,
                    'confident_median': sure.median,
                    'confident_max': sure.max,
                    'ms_per_estimate': 1e3 * float(np.median(result.seconds[selection]))
                    if np.any(selection)
                    else float('nan'),
                }
            )
    return rows


#: The columns of error statistics (deg) every compass table shows after the method's name.
STATISTICS_COLUMNS = (Column('n', 3, 'd'), Column('median', 7, '.2f'), Column('p90', 7, '.2f'), Column('max', 7, '.2f'))


def share_cell(share: float) -> str:
    """Return a share (0..1) as a table shows it: whole per cent ('-' for NaN: nothing to count)."""
    return '-' if np.isnan(share) else f'{100 * share:.0f}%'


#: The columns of what the estimates marked confident are: their share, median and worst error (deg).
CONFIDENT_COLUMNS = (Column('sure', 5), Column('s.med', 7, '.2f'), Column('s.max', 7, '.2f'))


def confident_cells(statistics: ConfidentStatistics) -> tuple:
    """Return the cells of CONFIDENT_COLUMNS: '-' where there is nothing to show (no flag, none confident)."""
    return (
        share_cell(statistics.share),
        *('-' if np.isnan(value) else value for value in (statistics.median, statistics.max)),
    )


def format_table(rows: Sequence[dict]) -> str:
    """Return a text table of summary rows: method, group, median/p90/max error (deg), share < 2 deg, the share
    marked confident with the median and worst error among those (deg), ms."""
    columns = (
        Column('method', 28, align='<'),
        Column('views', 12, align='<'),
        *STATISTICS_COLUMNS,
        Column('<2deg', 6),
        *CONFIDENT_COLUMNS,
        Column('ms', 8, '.2f'),
    )
    return text_table(
        columns,
        [
            (
                r['method'],
                r['group'],
                r['count'],
                r['median'],
                r['p90'],
                r['max'],
                share_cell(r['share_under_2deg']),
                *confident_cells(
                    ConfidentStatistics(r['confident_share'], 0, r['confident_median'], r['confident_max'])
                ),
                r['ms_per_estimate'],
            )
            for r in rows
        ],
    )


def plot_errors(
    results: Sequence[CompassResult],
    tilt: np.ndarray,
    translation: np.ndarray,
    path: str | Path,
    synthetic: bool = True,
    title: str = '',
) -> Path:
    """Save a figure of angular error (deg) against relative tilt (deg) and against translation (m) per method."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    tag = 'synthetic data' if synthetic else 'recorded data'
    figure, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    markers = 'os^vD<>xP*'
    for k, result in enumerate(results):
        errors = np.where(np.isfinite(result.errors), result.errors, 180.0)
        for axis, x in zip(axes, (tilt, translation)):
            axis.plot(x, errors, linestyle='none', marker=markers[k % len(markers)], alpha=0.8, label=result.method)
    for axis, label in zip(axes, ('relative tilt against the snapshot (deg)', 'distance from the snapshot (m)')):
        axis.set_yscale('log')
        axis.axhline(ERROR_THRESHOLD_DEG, color='grey', linewidth=0.8, linestyle='--')
        axis.set_xlabel(label)
        axis.set_ylabel('3D rotation error (deg)')
        axis.grid(True, which='both', alpha=0.3)
    axes[0].set_title(f'compass error against tilt ({tag})')
    axes[1].set_title(f'compass error against translation ({tag})')
    axes[1].legend(fontsize=8, loc='best')
    if title:
        figure.suptitle(f'{title} ({tag})')
    path = Path(path)
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
