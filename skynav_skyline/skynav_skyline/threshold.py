# SPDX-License-Identifier: Apache-2.0
"""Histogram thresholds of the projected contrast: Otsu and Kittler-Illingworth minimum error.

Every function works on one histogram (shape (bins,)) or on a stack of them
(shape (n, bins), e.g. one per azimuth sector) at once. A *cut* k puts bins
0..k-1 into the low class (ground) and bins k..bins-1 into the high class
(sky); its threshold is the bin edge edges[k], and a value is sky when it lies
above the threshold. Where the best cut is followed by empty bins (a gap
between two modes), all those cuts make the same partition and the threshold
is the middle of that gap; among different partitions that tie, the first wins.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from skynav_skyline.errors import SkylineError

#: Histogram bins of the projected contrast used by the local methods.
DEFAULT_BINS = 256
#: Percentiles (%) of the values that span the histogram; values outside go to the end bins.
HISTOGRAM_RANGE_PERCENTILES = (0.1, 99.9)
#: Values sampled (evenly spaced) to place the histogram range.
RANGE_SAMPLE = 20000


@dataclass(frozen=True)
class HistogramSplit:
    """A two-class split of one histogram or of a stack of histograms (arrays of shape (n,) or scalars)."""

    threshold: np.ndarray  # value of the cut (the histogram's unit: projected log contrast)
    separability: np.ndarray  # Otsu's between-class / total variance at the cut, in [0, 1]; 0 if undefined
    mean_low: np.ndarray  # mean of the low (ground) class, histogram unit
    mean_high: np.ndarray  # mean of the high (sky) class, histogram unit
    weight_low: np.ndarray  # share of the counts in the low class, in [0, 1]
    count: np.ndarray  # total counts of the histogram

    def take(self, index: int | slice | np.ndarray) -> HistogramSplit:
        """Return the splits of the histograms at `index` of a stack."""
        return HistogramSplit(*(np.asarray(getattr(self, f.name))[index] for f in fields(self)))


def histogram_range(values: np.ndarray) -> tuple[float, float]:
    """Return a robust (low, high) span (value unit) of `values` for a histogram; never empty."""
    values = np.asarray(values)
    if values.size == 0:
        raise SkylineError('cannot build a histogram of no values')
    # The span only places the bins: percentiles of an evenly spread sample are as good and much cheaper.
    sample = values.ravel()[:: max(1, values.size // RANGE_SAMPLE)]
    low, high = (float(v) for v in _percentiles(sample, HISTOGRAM_RANGE_PERCENTILES))
    if not high > low:
        low, high = float(values.min()), float(values.max())
    if not high > low:
        pad = max(abs(low) * 1e-6, 1e-6)
        low, high = low - pad, high + pad
    return low, high


def _percentiles(values: np.ndarray, percentiles: tuple[float, ...]) -> np.ndarray:
    """Return percentiles (float64) of a 1-D array, interpolated linearly as np.percentile does, by one partial sort."""
    position = np.asarray(percentiles, np.float64) / 100 * (values.size - 1)
    below = np.floor(position).astype(np.intp)
    above = np.minimum(below + 1, values.size - 1)
    ordered = np.partition(values, np.union1d(below, above))
    low, high = ordered[below].astype(np.float64), ordered[above].astype(np.float64)
    return low + (position - below) * (high - low)


def bin_index(values: np.ndarray, bins: int, value_range: tuple[float, float]) -> np.ndarray:
    """Return the int index (0..bins-1) of each value's bin on `bins` equal bins over `value_range`."""
    low, high = value_range
    index = ((np.asarray(values, np.float64) - low) * (bins / (high - low))).astype(np.intp)  # floor for >= 0
    index[values < low] = 0
    return np.clip(index, 0, bins - 1, out=index)


def bin_edges(bins: int, value_range: tuple[float, float]) -> np.ndarray:
    """Return the bins + 1 edges (value unit) of `bins` equal bins over `value_range`."""
    return np.linspace(value_range[0], value_range[1], bins + 1)


def histogram(
    values: np.ndarray, bins: int = DEFAULT_BINS, value_range: tuple[float, float] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Return (counts, edges) of `values` on equal bins; values outside the range go to the end bins."""
    value_range = histogram_range(values) if value_range is None else value_range
    counts = np.bincount(bin_index(values, bins, value_range), minlength=bins).astype(np.float64)
    return counts, bin_edges(bins, value_range)


@dataclass(frozen=True)
class _Moments:
    """Class counts, sums and sums of squares (histogram unit) of every cut k = 1..bins-1 of histograms (..., bins)."""

    n0: np.ndarray  # counts below each cut (..., bins - 1)
    s0: np.ndarray  # sum of bin centres below each cut
    q0: np.ndarray  # sum of squared bin centres below each cut
    n1: np.ndarray  # the same above each cut
    s1: np.ndarray
    q1: np.ndarray
    total: np.ndarray  # (..., 1) totals over the whole histogram
    s_total: np.ndarray
    q_total: np.ndarray


def _moments(counts: np.ndarray, edges: np.ndarray) -> _Moments:
    """Return the per-cut class moments of histograms `counts` (..., bins) on `edges`."""
    counts = np.asarray(counts, np.float64)
    centres = (edges[:-1] + edges[1:]) / 2
    weighted = counts * centres
    squared = weighted * centres
    n0 = np.cumsum(counts, axis=-1)
    s0 = np.cumsum(weighted, axis=-1)
    q0 = np.cumsum(squared, axis=-1)
    total, s_total, q_total = n0[..., -1:], s0[..., -1:], q0[..., -1:]
    n0, s0, q0 = n0[..., :-1], s0[..., :-1], q0[..., :-1]
    return _Moments(n0, s0, q0, total - n0, s_total - s0, q_total - q0, total, s_total, q_total)


def _otsu_score(m: _Moments) -> np.ndarray:
    """Return Otsu's between-class variance (unit squared) of every cut; -inf where a class is empty."""
    with np.errstate(divide='ignore', invalid='ignore'):
        w0, w1 = m.n0 / m.total, m.n1 / m.total
        mu0, mu1 = m.s0 / m.n0, m.s1 / m.n1
        variance = w0 * w1 * (mu1 - mu0) ** 2
    return np.where((m.n0 > 0) & (m.n1 > 0), variance, -np.inf)


def _minimum_error_criterion(m: _Moments, edges: np.ndarray) -> np.ndarray:
    """Return Kittler-Illingworth's criterion (lower better) of every cut; inf where a class is empty."""
    floor = (edges[1] - edges[0]) ** 2 / 12
    with np.errstate(divide='ignore', invalid='ignore'):
        p0, p1 = m.n0 / m.total, m.n1 / m.total
        var0 = np.maximum(m.q0 / m.n0 - (m.s0 / m.n0) ** 2, floor)
        var1 = np.maximum(m.q1 / m.n1 - (m.s1 / m.n1) ** 2, floor)
        criterion = p0 * np.log(var0) + p1 * np.log(var1) - 2 * (p0 * np.log(p0) + p1 * np.log(p1))
    return np.where((m.n0 > 0) & (m.n1 > 0), criterion, np.inf)


def between_class_variance(counts: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Return Otsu's between-class variance (unit squared) of every cut k = 1..bins-1; -inf where a class is empty."""
    return _otsu_score(_moments(counts, edges))


def minimum_error_criterion(counts: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Return Kittler-Illingworth's criterion (dimensionless, lower better) of every cut; inf where a class is empty.

    J(k) = P0 ln(var0) + P1 ln(var1) - 2 (P0 ln P0 + P1 ln P1), the class
    variances floored at the variance of one bin (width^2 / 12).
    """
    return _minimum_error_criterion(_moments(counts, edges), edges)


def _best_cut(score: np.ndarray, below: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (first, last, valid) best cuts k (1..bins-1) of scores (higher better); `below`: counts under each cut.

    `first` is the first best cut; `last` the last cut with the same partition
    (only empty bins between them), so the threshold can go to the gap's middle.
    """
    best = score.max(axis=-1)
    valid = np.isfinite(best)
    first = np.argmax(score == best[..., None], axis=-1)
    below_first = np.take_along_axis(below, first[..., None], -1)
    last = np.count_nonzero(below <= below_first, axis=-1) - 1  # `below` never decreases along the cuts
    return first + 1, np.maximum(last, first) + 1, valid


def _split_at(m: _Moments, cut: np.ndarray, threshold: np.ndarray) -> HistogramSplit:
    """Return the class statistics of the histograms with moments `m` split at cut index `cut` (1..bins-1)."""
    pick = np.asarray(cut)[..., None] - 1

    def at(a: np.ndarray) -> np.ndarray:
        """Return the per-cut array `a` at the chosen cut."""
        return np.take_along_axis(a, pick, -1)[..., 0]

    total, s_total, q_total = m.total[..., 0], m.s_total[..., 0], m.q_total[..., 0]
    a0, b0, a1, b1 = at(m.n0), at(m.s0), at(m.n1), at(m.s1)
    with np.errstate(divide='ignore', invalid='ignore'):
        mu0, mu1 = b0 / a0, b1 / a1
        w0 = a0 / total
        variance = q_total / total - (s_total / total) ** 2
        between = w0 * (1 - w0) * (mu1 - mu0) ** 2
        separability = np.where((a0 > 0) & (a1 > 0) & (variance > 0), between / variance, 0.0)
    return HistogramSplit(
        np.asarray(threshold, float), np.clip(separability, 0.0, 1.0), mu0, mu1, np.nan_to_num(w0), total
    )


def _split_by_score(m: _Moments, edges: np.ndarray, score: np.ndarray) -> HistogramSplit:
    """Return the split at the best cut of `score` (higher better), threshold in the middle of a tied gap."""
    edges = np.asarray(edges, np.float64)
    first, last, valid = _best_cut(score, m.n0)
    threshold = (edges[first] + edges[last]) / 2
    centre = (edges[0] + edges[-1]) / 2
    threshold = np.where(valid, threshold, centre)
    split = _split_at(m, first, threshold)
    if not np.all(valid):
        split = HistogramSplit(
            split.threshold,
            np.where(valid, split.separability, 0.0),
            split.mean_low,
            split.mean_high,
            split.weight_low,
            split.count,
        )
    return split


def otsu_split(counts: np.ndarray, edges: np.ndarray) -> HistogramSplit:
    """Return Otsu's split (maximal between-class variance) of histograms `counts` (..., bins) on `edges`."""
    moments = _moments(counts, edges)
    return _split_by_score(moments, edges, _otsu_score(moments))


def minimum_error_split(counts: np.ndarray, edges: np.ndarray) -> HistogramSplit:
    """Return Kittler-Illingworth's minimum error split of histograms `counts` (..., bins) on `edges`."""
    moments = _moments(counts, edges)
    return _split_by_score(moments, edges, -_minimum_error_criterion(moments, edges))


#: Histogram threshold methods by name.
HISTOGRAM_METHODS = {'otsu': otsu_split, 'min-error': minimum_error_split}


def otsu_threshold(
    values: np.ndarray, bins: int = DEFAULT_BINS, value_range: tuple[float, float] | None = None
) -> float:
    """Return Otsu's threshold (value unit) of `values`: sky above it."""
    counts, edges = histogram(values, bins, value_range)
    return float(otsu_split(counts, edges).threshold)


def minimum_error_threshold(
    values: np.ndarray, bins: int = DEFAULT_BINS, value_range: tuple[float, float] | None = None
) -> float:
    """Return Kittler-Illingworth's minimum error threshold (value unit) of `values`: sky above it."""
    counts, edges = histogram(values, bins, value_range)
    return float(minimum_error_split(counts, edges).threshold)
