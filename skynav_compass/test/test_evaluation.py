# SPDX-License-Identifier: Apache-2.0
"""Evaluation functions: angular error, statistics, tables, plots, ground truth from poses, the method runner."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_compass import (
    CompassResult,
    angular_error,
    confident_statistics,
    error_statistics,
    format_table,
    heading_error,
    load_compass_set,
    plot_errors,
    relative_tilt,
    roc_auc,
    run_methods,
    standard_methods,
    summary_rows,
    true_rotation,
)

BAGS = Path(__file__).resolve().parents[2] / 'bags'


def test_angular_error_in_degrees_for_quaternions_and_matrices():
    truth = Rotation.from_euler('ZYX', [[10, 5, 0], [100, -20, 7]], degrees=True)
    estimated = truth * Rotation.from_euler('x', [[3.0], [-1.5]], degrees=True)
    assert angular_error(estimated.as_quat(), truth.as_quat()) == pytest.approx([3.0, 1.5])
    assert angular_error(estimated.as_matrix(), truth.as_matrix()) == pytest.approx([3.0, 1.5])
    assert angular_error(-estimated.as_quat(), truth.as_quat()) == pytest.approx([3.0, 1.5])  # q and -q alike


def test_tilt_and_heading():
    r = Rotation.from_euler('ZY', [40.0, 25.0], degrees=True)  # heading 40, then a tilt of 25 about y
    assert relative_tilt(r.as_quat()) == pytest.approx(25.0)
    assert heading_error(
        Rotation.from_euler('z', 170, degrees=True).as_quat(), Rotation.from_euler('z', -175, degrees=True).as_quat()
    ) == pytest.approx(15.0)


def test_true_rotation_from_poses_follows_the_contract():
    q_s = Rotation.from_euler('ZYX', [30, 4, -6], degrees=True)
    q_c = q_s * Rotation.from_euler('x', 12, degrees=True)
    r = Rotation.from_quat(true_rotation(q_s.as_quat(), q_c.as_quat()))
    d_current = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    # the same world direction: Q_s d_snapshot = Q_c d_current
    assert np.allclose(q_s.apply(r.apply(d_current)), q_c.apply(d_current))


def test_statistics_table_and_plot(tmp_path):
    errors = np.array([0.5, 1.0, 1.5, 2.5, np.inf])
    stats = error_statistics(errors)
    assert stats.median == pytest.approx(1.5) and stats.max == 180.0 and stats.share_under == pytest.approx(0.6)
    assert stats.count == 5 and stats.p90 == pytest.approx(np.percentile([0.5, 1, 1.5, 2.5, 180], 90))
    result = CompassResult('m', errors, np.full(5, 0.004))
    groups = {'rotation': np.array([True, True, True, False, False]), 'translation': np.array([False] * 3 + [True] * 2)}
    rows = summary_rows([result], groups)
    assert [r['group'] for r in rows] == ['rotation', 'translation'] and rows[0]['ms_per_estimate'] == pytest.approx(4)
    assert 'translation' in format_table(rows)
    path = plot_errors([result], np.arange(5.0), np.linspace(0, 0.5, 5), tmp_path / 'errors.png', synthetic=True)
    assert path.exists() and path.stat().st_size > 10_000


def test_confident_share_and_the_errors_of_the_confident_ones():
    errors = np.array([0.5, 1.0, 40.0, 3.0, np.inf, 120.0])
    confident = np.array([True, True, False, True, False, False])
    result = CompassResult('m', errors, np.full(6, 0.004), confident=confident)
    sure = result.confident_statistics()
    assert sure.share == pytest.approx(3 / 6) and sure.count == 3  # confident / all
    assert sure.max == 3.0 and sure.median == 1.0  # over the confident only: 40, inf and 120 are not
    assert result.confident_statistics(np.array([False, False, True, True, False, False])).share == 0.5
    # a failed estimate flagged confident counts as the worst error
    assert confident_statistics(errors, np.array([False] * 4 + [True, False])).max == 180.0
    nobody = confident_statistics(errors, np.zeros(6, dtype=bool))
    assert nobody.share == 0.0 and nobody.count == 0 and np.isnan(nobody.max) and np.isnan(nobody.median)
    assert np.isnan(CompassResult('m', errors, np.zeros(6)).confident_statistics().share)  # no flag at all
    # the summary rows and their table carry them per group
    groups = {'rotation': np.array([True] * 3 + [False] * 3), 'translation': np.array([False] * 3 + [True] * 3)}
    rows = summary_rows([result], groups)
    assert rows[0]['confident_share'] == pytest.approx(2 / 3) and rows[0]['confident_max'] == 1.0
    assert rows[1]['confident_share'] == pytest.approx(1 / 3) and rows[1]['confident_median'] == 3.0
    table = format_table(rows).splitlines()
    assert table[0].split()[7:10] == ['sure', 's.med', 's.max']
    assert table[2].split()[7:10] == ['67%', '0.75', '1.00'] and table[3].split()[7:10] == ['33%', '3.00', '3.00']
    assert format_table(summary_rows([CompassResult('m', errors, np.zeros(6))], groups)).splitlines()[2].split()[
        7:10
    ] == ['-', '-', '-']


def test_roc_auc_counts_right_estimates_ranked_above_wrong_ones():
    right = np.array([True, True, False, False])
    assert roc_auc([0.9, 0.8, 0.2, 0.1], right) == 1.0
    assert roc_auc([0.1, 0.2, 0.8, 0.9], right) == 0.0
    assert roc_auc([0.9, 0.2, 0.8, 0.1], right) == 0.75  # of 4 (right, wrong) pairs, 3 in order
    assert roc_auc([0.5, 0.5, 0.5, 0.5], right) == 0.5  # ties count half
    assert np.isnan(roc_auc([0.1, 0.2], [True, True]))  # nothing to separate
    # a method without a confidence is ranked by its residual, lower first
    errors = np.array([1.0, 2.0, 30.0, 90.0])
    by_residual = CompassResult(
        'm', errors, np.zeros(4), residuals=np.array([0.1, 0.2, 0.3, np.inf]), confidence=np.full(4, np.nan)
    )
    assert by_residual.separation() == 1.0
    by_confidence = CompassResult(
        'm', errors, np.zeros(4), residuals=np.array([0.1, 0.2, 0.3, 0.4]), confidence=np.array([0.2, 0.9, 0.1, 0.05])
    )
    assert by_confidence.separation() == 1.0
    assert by_confidence.separation(np.array([True, False, True, False])) == 1.0


def test_runner_on_a_few_frames_of_a_bundled_set():
    path = BAGS / 'synthetic_mineral_compass.mcap'
    data = load_compass_set(path)
    queries = [1, 2, 16]
    runs = run_methods(data, standard_methods(data.camera, 12, ['fft-masked', 'visual-compass-panorama']), queries)
    masked, panorama = (r.result for r in runs)
    assert masked.errors.shape == (3,) and np.all(masked.errors < 3.0)
    assert np.all(masked.seconds > 0) and runs[0].prepare_seconds > 0
    # the yaw-only compass cannot follow tilt: its 3D error is at least about the tilt of the view
    tilts = data.tilts()[queries]
    assert np.all(panorama.errors >= 0.5 * tilts)
