# SPDX-License-Identifier: Apache-2.0
"""Histogram thresholds: Otsu against brute force, Kittler-Illingworth on a known mixture, separability."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import norm

from skynav_skyline.threshold import (
    HISTOGRAM_RANGE_PERCENTILES,
    _percentiles,
    histogram,
    minimum_error_criterion,
    minimum_error_split,
    minimum_error_threshold,
    otsu_split,
    otsu_threshold,
)


def brute_force_between_class_variance(counts, centres):
    """Between-class variance of every cut k = 1..bins-1, written out directly (None if a class is empty)."""
    result = []
    total = sum(counts)
    for k in range(1, len(counts)):
        low, high = counts[:k], counts[k:]
        n0, n1 = sum(low), sum(high)
        if n0 == 0 or n1 == 0:
            result.append(None)
            continue
        mu0 = sum(c * m for c, m in zip(low, centres[:k])) / n0
        mu1 = sum(c * m for c, m in zip(high, centres[k:])) / n1
        result.append(n0 / total * n1 / total * (mu1 - mu0) ** 2)
    return result


@settings(max_examples=150, deadline=None)
@given(st.lists(st.integers(0, 50), min_size=2, max_size=40), st.floats(-3, 3), st.floats(0.1, 5))
def test_otsu_maximises_between_class_variance_like_brute_force(counts, start, width):
    counts = np.array(counts, float)
    edges = start + width * np.arange(counts.size + 1) / counts.size
    centres = (edges[:-1] + edges[1:]) / 2
    variance = brute_force_between_class_variance(list(counts), list(centres))
    defined = [v for v in variance if v is not None]
    split = otsu_split(counts, edges)
    if not defined:
        assert split.separability == 0.0
        return
    best = max(defined)
    best_cuts = [k + 1 for k, v in enumerate(variance) if v is not None and v >= best - 1e-12 * max(best, 1)]
    # The threshold is a best cut's edge (or the middle of a run of tied best cuts).
    assert edges[min(best_cuts)] - 1e-12 <= split.threshold <= edges[max(best_cuts)] + 1e-12
    below = counts[centres < split.threshold]
    above = counts[centres > split.threshold]
    n0, n1 = below.sum(), above.sum()
    mu0 = (below * centres[centres < split.threshold]).sum() / n0
    mu1 = (above * centres[centres > split.threshold]).sum() / n1
    assert n0 / counts.sum() * n1 / counts.sum() * (mu1 - mu0) ** 2 == pytest.approx(best, rel=1e-9, abs=1e-12)
    total_variance = (counts * centres**2).sum() / counts.sum() - ((counts * centres).sum() / counts.sum()) ** 2
    if total_variance > 1e-9:
        assert split.separability == pytest.approx(best / total_variance, rel=1e-6, abs=1e-9)


def test_otsu_threshold_sits_in_the_middle_of_an_empty_gap():
    counts = np.array([5, 9, 5, 0, 0, 0, 0, 3, 8, 3], float)
    edges = np.arange(11, dtype=float)
    split = otsu_split(counts, edges)
    assert split.threshold == pytest.approx(5.0)  # cuts 3..7 tie; edges 3 and 7
    assert split.weight_low == pytest.approx(19 / 33)
    assert split.mean_low == pytest.approx(1.5)
    assert split.mean_high == pytest.approx(8.5)


def test_batched_splits_equal_one_by_one():
    rng = np.random.default_rng(4)
    counts = rng.integers(0, 30, (7, 64)).astype(float)
    counts[3] = 0  # an empty histogram
    edges = np.linspace(-2, 1, 65)
    for method in (otsu_split, minimum_error_split):
        batched = method(counts, edges)
        for row in range(counts.shape[0]):
            single = method(counts[row], edges)
            assert batched.threshold[row] == pytest.approx(float(single.threshold))
            assert batched.separability[row] == pytest.approx(float(single.separability))
    assert otsu_split(counts, edges).separability[3] == 0.0


def test_otsu_on_a_symmetric_mixture_splits_in_the_middle():
    rng = np.random.default_rng(0)
    values = np.r_[rng.normal(-1, 0.3, 20000), rng.normal(2, 0.3, 20000)]
    assert otsu_threshold(values) == pytest.approx(0.5, abs=0.1)


def test_minimum_error_finds_the_bayes_threshold_of_an_unequal_gaussian_mixture():
    # Ground: 80 % at -2 (sd 0.25); sky: 20 % at 0 (sd 0.6). The Bayes threshold solves w0 p0(t) = w1 p1(t).
    w0, mu0, s0, w1, mu1, s1 = 0.8, -2.0, 0.25, 0.2, 0.0, 0.6
    rng = np.random.default_rng(1)
    values = np.r_[rng.normal(mu0, s0, int(200000 * w0)), rng.normal(mu1, s1, int(200000 * w1))]
    grid = np.linspace(mu0, mu1, 20001)
    bayes = grid[np.argmin(np.abs(w0 * norm.pdf(grid, mu0, s0) - w1 * norm.pdf(grid, mu1, s1)))]
    kittler = minimum_error_threshold(values, bins=256)
    assert kittler == pytest.approx(bayes, abs=0.05)
    # Otsu's bias towards equal class variances puts it further from the Bayes threshold here.
    assert abs(otsu_threshold(values, bins=256) - bayes) > abs(kittler - bayes)


def test_minimum_error_criterion_is_minimal_at_the_chosen_cut():
    rng = np.random.default_rng(2)
    counts, edges = histogram(np.r_[rng.normal(0, 1, 3000), rng.normal(5, 0.5, 800)], bins=64)
    criterion = minimum_error_criterion(counts, edges)
    split = minimum_error_split(counts, edges)
    k = int(np.argmin(criterion)) + 1
    assert edges[k] <= split.threshold + 1e-12
    assert criterion[int(np.searchsorted(edges, split.threshold - 1e-9)) - 1] == pytest.approx(criterion.min())


def test_separability_of_one_mode_is_low_and_of_two_modes_high():
    rng = np.random.default_rng(3)
    one = otsu_split(*histogram(rng.normal(0, 1, 50000)))
    assert float(one.separability) == pytest.approx(2 / np.pi, abs=0.02)
    ramp = otsu_split(*histogram(rng.uniform(0, 1, 50000)))
    assert float(ramp.separability) == pytest.approx(0.75, abs=0.02)
    two = otsu_split(*histogram(np.r_[rng.normal(0, 0.3, 30000), rng.normal(2.3, 0.3, 20000)]))
    assert float(two.separability) > 0.9


def test_histogram_of_constant_values_is_usable():
    counts, edges = histogram(np.full(10, 3.0), bins=8)
    assert counts.sum() == 10
    assert edges[0] < 3.0 < edges[-1]
    assert float(otsu_split(counts, edges).separability) == 0.0


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3, width=32), min_size=1, max_size=300))
def test_histogram_range_percentiles_equal_numpys(values):
    values = np.array(values, np.float32)
    np.testing.assert_allclose(
        _percentiles(values, HISTOGRAM_RANGE_PERCENTILES),
        np.percentile(values, HISTOGRAM_RANGE_PERCENTILES),
        rtol=1e-6,
        atol=1e-9,
    )


def test_split_of_a_stack_takes_rows_like_splitting_each():
    rng = np.random.default_rng(3)
    counts = rng.integers(0, 40, size=(5, 32)).astype(float)
    edges = np.linspace(-2.0, 1.0, 33)
    stacked = minimum_error_split(counts, edges)
    for row in range(5):
        single, taken = minimum_error_split(counts[row], edges), stacked.take(row)
        for name in ('threshold', 'separability', 'mean_low', 'mean_high', 'weight_low', 'count'):
            np.testing.assert_allclose(getattr(taken, name), getattr(single, name))
    np.testing.assert_array_equal(stacked.take(slice(1, 3)).threshold, stacked.threshold[1:3])
