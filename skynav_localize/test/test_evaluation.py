# SPDX-License-Identifier: Apache-2.0
"""Evaluation metrics against hand-computed examples, and the plots."""

from __future__ import annotations

import numpy as np
import pytest

from skynav_localize.eval.evaluation import (
    compare,
    correct_matches,
    evaluate,
    format_table,
    has_true_place,
    plot_matches_along_route,
    plot_pr_curves,
    pr_auc,
    precision_recall,
    recall_at_full_precision,
    threshold_at_full_precision,
)

SNAPSHOTS = np.column_stack([np.arange(10.0), np.zeros(10)])  # a straight route, one snapshot per metre
# q0 near snapshot 2 (matched right), q1 at 5 m matched to 8 (wrong), q2 matched right, q3 30 m off the route
# (matched to 0: wrong, and no snapshot could be right), q4 matched right
QUERIES = np.array([[2.2, 0.1], [5.0, 0.0], [7.1, -0.2], [30.0, 0.0], [4.4, 0.3]])
MATCHED = np.array([2, 8, 7, 0, 4])
SCORES = np.array([0.1, 0.2, 0.3, 0.05, 0.4])


def test_correct_and_positive_queries():
    np.testing.assert_array_equal(correct_matches(MATCHED, QUERIES, SNAPSHOTS, 1.0), [True, False, True, False, True])
    np.testing.assert_array_equal(has_true_place(QUERIES, SNAPSHOTS, 1.0), [True, True, True, False, True])
    np.testing.assert_array_equal(correct_matches(np.array([-1, 2]), QUERIES[:2], SNAPSHOTS), [False, False])
    # q0 and q2 are 0.22 m from their snapshots, q4 0.5 m
    np.testing.assert_array_equal(correct_matches(MATCHED, QUERIES, SNAPSHOTS, 0.25), [True, False, True, False, False])


def test_hand_computed_curve_with_an_off_route_query_first():
    # by score: q3 wrong, q0 right, q1 wrong, q2 right, q4 right; 4 positive queries
    result = evaluate('m', MATCHED, SCORES, QUERIES, SNAPSHOTS, 1.0)
    np.testing.assert_allclose(result.curve.thresholds, [0.05, 0.1, 0.2, 0.3, 0.4])
    np.testing.assert_allclose(result.curve.precision, [0.0, 1 / 2, 1 / 3, 2 / 4, 3 / 5])
    np.testing.assert_allclose(result.curve.recall, [0.0, 0.25, 0.25, 0.5, 0.75])
    assert result.recall_at_full_precision == 0.0
    assert result.threshold_at_full_precision == -np.inf
    assert result.auc == pytest.approx(0.25 * 0.5 + 0.25 * 0.5 + 0.25 * 0.6)
    assert result.recall_at_1 == pytest.approx(0.75)
    assert result.positives == 4 and result.queries == 5


def test_hand_computed_curve_on_the_route_only():
    keep = [0, 1, 2, 4]
    result = evaluate('m', MATCHED[keep], SCORES[keep], QUERIES[keep], SNAPSHOTS, 1.0, accepted=SCORES[keep] <= 0.3)
    assert result.recall_at_full_precision == pytest.approx(0.25)
    assert result.threshold_at_full_precision == pytest.approx(0.1)
    assert result.auc == pytest.approx(0.25 * 1 + 0.25 * 2 / 3 + 0.25 * 3 / 4)
    assert result.accepted_precision == pytest.approx(2 / 3) and result.accepted_recall == pytest.approx(0.5)


def test_ties_count_together_and_perfect_runs():
    curve = precision_recall(np.array([0.2, 0.2, 0.5]), np.array([True, False, True]), positives=3)
    np.testing.assert_allclose(curve.precision, [0.5, 2 / 3])
    np.testing.assert_allclose(curve.recall, [1 / 3, 2 / 3])
    perfect = precision_recall(np.array([0.3, 0.1, 0.2]), np.ones(3, bool), positives=3)
    assert recall_at_full_precision(perfect) == 1.0 and pr_auc(perfect) == pytest.approx(1.0)
    assert threshold_at_full_precision(perfect) == pytest.approx(0.3)
    empty = precision_recall(np.zeros(0), np.zeros(0, bool), positives=0)
    assert recall_at_full_precision(empty) == 0.0 and pr_auc(empty) == 0.0


def test_compare_and_table():
    good = evaluate('ours', MATCHED[[0, 2, 4]], SCORES[[0, 2, 4]], QUERIES[[0, 2, 4]], SNAPSHOTS)
    bad = evaluate('peer', MATCHED, SCORES, QUERIES, SNAPSHOTS)
    assert compare({'ours': good, 'peer': bad}, 'ours', ['peer']) == {'peer': True}
    assert compare({'ours': good, 'peer': good}, 'ours', ['peer']) == {'peer': False}  # a tie does not beat
    table = format_table([good, bad])
    assert 'ours' in table and 'peer' in table and 'tolerance 1 m' in table


def test_plots_are_labelled_and_saved(tmp_path):
    results = [
        evaluate('ours', MATCHED, SCORES, QUERIES, SNAPSHOTS),
        evaluate('peer', MATCHED, SCORES[::-1], QUERIES, SNAPSHOTS),
    ]
    figure = plot_pr_curves(results, 'garden repeat vs teach', synthetic=True, path=tmp_path / 'pr.png')
    axes = figure.axes[0]
    assert 'synthetic' in axes.get_title() and 'within 1 m' in axes.get_title()
    assert axes.get_xlabel().startswith('recall') and axes.get_ylabel().startswith('precision')
    assert len(axes.get_legend().get_texts()) == 2
    assert (tmp_path / 'pr.png').stat().st_size > 10_000
    correct = correct_matches(MATCHED, QUERIES, SNAPSHOTS)
    figure = plot_matches_along_route(
        SNAPSHOTS, QUERIES, MATCHED, correct, SCORES < 0.25, 'garden', synthetic=True, path=tmp_path / 'route.png'
    )
    top, index_axes = figure.axes
    assert '(m)' in top.get_xlabel() and '(m)' in top.get_ylabel()
    assert 'snapshot index' in index_axes.get_ylabel() and 'query' in index_axes.get_xlabel()
    assert 'synthetic' in figure.get_suptitle()
    assert (tmp_path / 'route.png').stat().st_size > 10_000
    real = plot_pr_curves(results, 'field run', synthetic=False)
    assert 'synthetic' not in real.axes[0].get_title()
