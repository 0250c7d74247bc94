# SPDX-License-Identifier: Apache-2.0
"""`skynav eval homing`: the numbers it prints (evaluate_homing on the bundled grid), its plot and its errors.

The views come from the installed skyline and SH nodes (recording_views), as the command runs them; so unlike
test_bundled_grid.py (ground-truth masks, simulated compass) these errors include segmentation and the real compass.
Measured on bags/synthetic_park_homing.mcap (40 views 0.74-3.2 m from the snapshot, camera tilt 0-8 degrees),
median / p90 over all views, degrees: 3d-warping 9.1 / 15.9, without compass 11.2 / 18.3, 2d-warping
13.9 / 33.1, min-warping 58.4 / 124. On bags/synthetic_park_bumpy_homing.mcap (the same places on bumps, tilt
3-24 degrees): 3d-warping 9.1 / 18.0 (tilt 10-20 degrees: 11.1 / 18.2), without compass 9.3 / 17.1, 2d-warping
29.4 / 82.9, min-warping 59.5 / 134. Bounds: the issue's 15-degree median over 0.5-4 m for both 3D-warping
variants, also on bumps and among the views tilted 10-20 degrees, and at most half of min-warping's median (the
tilt breaks the planar model) and, on bumps, of 2D-warping's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from skynav_bringup.cli import main
from skynav_core.maps import MapStore, Snapshot
from skynav_core.names import GROUND_TRUTH_POSE
from skynav_core.views import recording_views
from skynav_testing import one_line_error, run_skynav, sample_messages
from skynav_warping.cli import eval as eval_cli
from skynav_warping.eval.homing_eval import METHODS, HomingEvalError, evaluate_homing, map_snapshot

BAG = Path(__file__).resolve().parents[2] / 'bags' / 'synthetic_park_homing.mcap'


@pytest.fixture(scope='module')
def recording():
    return recording_views(BAG, images=False, masks=True)


@pytest.fixture(scope='module')
def evaluation(recording):
    return evaluate_homing(recording)


@pytest.fixture
def one_snapshot_map(recording, tmp_path):
    """A map whose snapshot 0 is the recording's snapshot frame, 1 a copy at an unrecorded stamp, 2 without pose."""
    first = recording.views[0]
    snapshots = [
        Snapshot(0, first.stamp, first.coefficients, first.pose),
        Snapshot(1, first.stamp + 1, first.coefficients, first.pose),
        Snapshot(2, first.stamp + 2, first.coefficients, None),
    ]
    store = MapStore.build(tmp_path / 'park.db', 'park', first.max_degree, snapshots)
    yield store
    store.close()


def test_3d_warping_meets_the_target_and_beats_min_warping(evaluation):
    assert list(evaluation.results) == list(METHODS) and not evaluation.skipped
    assert len(evaluation.distances) == 40 and evaluation.synthetic
    for method in ('3d-warping', '3d-warping-no-compass'):
        assert evaluation.median(method, 0.5, 4.0) < 15.0
        assert evaluation.median(method, 0.5, 4.0) < 0.5 * evaluation.median('min-warping', 0.5, 4.0)
    assert evaluation.results['3d-warping'].confident.mean() >= 0.9


def test_on_bumpy_ground_3d_warping_keeps_the_target_and_the_planar_methods_break():
    bumpy = evaluate_homing(
        recording_views(BAG.with_name('synthetic_park_bumpy_homing.mcap'), images=False, masks=True)
    )
    cells = bumpy.statistics('3d-warping')
    assert 'tilt 10-20 deg' in cells and cells['tilt 10-20 deg'][0] >= 20
    assert cells['tilt 10-20 deg'][1] < 15.0
    for method in ('3d-warping', '3d-warping-no-compass'):
        median = bumpy.median(method, 0.5, 4.0)
        assert median < 15.0
        assert median < 0.5 * bumpy.median('min-warping', 0.5, 4.0)
        assert median < 0.5 * bumpy.median('2d-warping', 0.5, 4.0)


def test_statistics_cover_every_bin_and_method(evaluation):
    for method, result in evaluation.results.items():
        assert np.allclose(np.linalg.norm(result.directions, axis=1), 1.0)
        assert 0.0 < result.seconds < 1.0
        cells = evaluation.statistics(method)
        # tilts here are 0-8 degrees: only the first tilt bin is present
        assert list(cells) == ['0.5-1 m', '1-2 m', '2-4 m', 'all', 'tilt 0-10 deg']
        assert sum(cells[b][0] for b in ('0.5-1 m', '1-2 m', '2-4 m')) == cells['all'][0] == 40
        count, median, p90 = cells['all']
        assert median == pytest.approx(np.median(evaluation.errors(method))) and p90 >= median
    table = evaluation.table().splitlines()
    assert len(table) == 2 + len(METHODS) and 'ms/estimate' in table[0] and '(n=40)' in table[1]
    # the vectors the node would publish (the confident ones) off by more than 30 degrees, and of how many
    assert 'off >30 deg' in table[0]
    for method in ('3d-warping', 'min-warping'):
        result = evaluation.results[method]
        published = np.ones(40, bool) if result.confident is None else result.confident
        cell = f'{np.count_nonzero(evaluation.errors(method)[published] > 30.0)} of {np.count_nonzero(published)}'
        assert next(row for row in table if row.split()[0] == method).endswith(cell), cell


def test_true_directions_follow_the_contract(evaluation):
    """Q_c^-1 (p_s - p_c) normalised, in the current camera_link."""
    from scipy.spatial.transform import Rotation

    k = 7
    vector = evaluation.snapshot.pose[:3] - evaluation.positions[k]
    expected = Rotation.from_quat(evaluation.quaternions[k]).inv().apply(vector)
    assert np.allclose(evaluation.true_directions[k], expected / np.linalg.norm(expected))
    assert np.allclose(evaluation.distances[k], np.linalg.norm(vector))


def test_quiver_plot_is_written(evaluation, tmp_path):
    path = tmp_path / 'grid_quiver.png'
    title = evaluation.quiver(path, 'grid: home vectors')
    assert path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and 'synthetic' in title


def test_map_snapshots(recording, evaluation, one_snapshot_map):
    recorded = map_snapshot(one_snapshot_map, 0, recording)  # the recording's frame: its mask, baselines run
    assert recorded.mask is not None
    again = evaluate_homing(recording, ['2d-warping'], recorded)
    assert np.allclose(again.results['2d-warping'].directions, evaluation.results['2d-warping'].directions)
    elsewhere = evaluate_homing(recording, ['2d-warping', 'min-warping'], map_snapshot(one_snapshot_map, 1, recording))
    assert not elsewhere.results and set(elsewhere.skipped) == {'2d-warping', 'min-warping'}
    with pytest.raises(HomingEvalError, match='no ground-truth pose'):
        map_snapshot(one_snapshot_map, 2, recording)
    with pytest.raises(HomingEvalError, match='no snapshot 3'):
        map_snapshot(one_snapshot_map, 3)


def test_cli_prints_the_table_and_saves_the_plot(one_snapshot_map, tmp_path):
    plots = tmp_path / 'plots'
    result = run_skynav(
        'eval',
        'homing',
        str(BAG),
        '--map',
        str(one_snapshot_map.path),
        '--methods',
        '2d-warping',
        '--plots',
        str(plots),
    )
    assert result.returncode == 0, result.stderr
    assert "40 synthetic views homing to map 'park' snapshot 0" in result.stdout
    rows = [line for line in result.stdout.splitlines() if line.startswith('2d-warping')]
    assert len(rows) == 1 and 'tilt 0-10 deg' in result.stdout
    assert (plots / 'synthetic_park_homing_quiver.png').stat().st_size > 10_000


def test_cli_offers_the_registry():
    import argparse

    parser = argparse.ArgumentParser()
    eval_cli.configure(parser)
    assert parser.parse_args(['grid.mcap']).methods == list(METHODS)
    assert eval_cli.METHODS is METHODS


def _write_pose_only_bag(path: Path) -> None:
    from skynav_core.recording.bag import BagWriter
    from skynav_core.recording.typestore import typestore

    with BagWriter(path) as writer:
        for topic, msgtype, t, message in sample_messages(frames=2):
            if topic == GROUND_TRUTH_POSE:
                writer.add_topic(topic, msgtype)
                writer.write(topic, t, typestore().serialize_cdr(message, msgtype))


@pytest.mark.parametrize(
    'case, code',
    [
        ('missing bag', 1),
        ('no camera topics', 1),
        ('unknown method', 2),
        ('corrupt map', 1),
        ('snapshot without pose', 1),
    ],
)
def test_bad_input_gives_one_line(case, code, one_snapshot_map, tmp_path, capsys):
    arguments = [str(BAG), '--plots', str(tmp_path / 'plots')]
    if case == 'missing bag':
        arguments[0] = str(tmp_path / 'missing.mcap')
    elif case == 'no camera topics':
        arguments[0] = str(tmp_path / 'poses.mcap')
        _write_pose_only_bag(Path(arguments[0]))
    elif case == 'unknown method':
        arguments += ['--methods', '3d-warping', 'sift-warping']
    elif case == 'corrupt map':
        corrupt = tmp_path / 'corrupt.db'
        corrupt.write_bytes(one_snapshot_map.path.read_bytes()[:4096])
        arguments += ['--map', str(corrupt)]
    else:
        arguments += ['--map', str(one_snapshot_map.path), '--index', '2']
    assert main(['eval', 'homing', *arguments]) == code
    stderr = capsys.readouterr().err
    assert one_line_error(stderr), stderr
    assert stderr.startswith('skynav eval homing: error: ')


def test_bad_input_in_a_process_of_its_own(tmp_path):
    result = run_skynav('eval', 'homing', str(tmp_path / 'missing.mcap'))
    assert result.returncode == 1 and one_line_error(result.stderr) and not result.stdout
