# SPDX-License-Identifier: Apache-2.0
"""End to end on the bundled synthetic garden pair: teach map -> repeat drive, every method, same evaluation.

SH coefficients come from the ground-truth masks (L = 16), so this measures place recognition alone. Figures
measured when the test was written (synthetic data, 1 m tolerance, 80 snapshots, 89 queries):

    method           R@100%P  AUC   R@1     (repeat turned 180 deg: R@100%P)
    amplitude(-seq)  1.00     1.00  1.00    1.00
    bispectrum(-seq) 1.00     1.00  1.00    1.00
    raw-uv           1.00     1.00  1.00    0.00
    seqslam-raw-uv   1.00     1.00  1.00    0.00
    bow-orb          1.00     1.00  1.00    1.00

Every matched snapshot of amplitude-seq lay within 0.44 m of the query (the repeat drive runs 0.25 m to the side
of the taught route; snapshots are 0.1 m apart), so the 1 m tolerance is not what makes the figures. The bounds
below are the project's target (recall at 100 % precision >= 0.9), every query matched within the tolerance as
measured, and the comparisons with the baselines as they came out: no baseline does better on the plain drive
(they tie), and the image baselines lose everything once the robot is turned, which the rotation-invariant
descriptors do not notice.
"""

from __future__ import annotations

import numpy as np
import pytest

from skynav_core.maps import MapStore, Snapshot
from skynav_localize.eval.baselines import EVALUATED_METHODS, snapshot_descriptors, train_bow
from skynav_localize.eval.evaluation import evaluate, format_table
from skynav_localize.localizer import OUR_METHODS, Localizer
from skynav_localize.mapping import build_map

TARGET_RECALL_AT_FULL_PRECISION = 0.9  # the project's target for amplitude-spectrum matching with sequences
TOLERANCE = 1.0  # m, the evaluation's default
TURN = np.pi  # rad about the camera's axis: the robot drives the route turned around (it mows in reverse)


@pytest.fixture(scope='module')
def garden_map(garden, tmp_path_factory):
    teach = garden['teach']
    snapshots = [
        Snapshot(i, int(stamp), c, pose, snapshot_descriptors(c, 16, uv, teach.circle))
        for i, (stamp, c, pose, uv) in enumerate(zip(teach.stamps, teach.coefficients, teach.poses, teach.uv))
    ]
    path = tmp_path_factory.mktemp('maps') / 'garden.db'
    build_map(path, 'synthetic garden', 16, snapshots, created_from='bags/synthetic_garden_teach.mcap').close()
    with MapStore.open(path, writable=True) as store:
        train_bow(store)
    return MapStore.open(path)


def turned(recording, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the recording's coefficients and UV images turned by angle (rad) about the optical axis (+z)."""
    import cv2

    from skynav_sh.rotation import rotate_z

    coefficients = rotate_z(recording.coefficients, angle)
    centre = (recording.camera.cx, recording.camera.cy)
    # +z rotation by angle turns the image about the principal point by -angle in OpenCV's (clockwise-down) sense
    matrix = cv2.getRotationMatrix2D(centre, -np.degrees(angle), 1.0)
    images = np.array([cv2.warpAffine(uv, matrix, uv.shape[::-1]) for uv in recording.uv])
    return coefficients, images


def run_all(store, recording, coefficients, images):
    """Return the result of every method on one query drive."""
    results = {}
    for name in EVALUATED_METHODS:
        matches = Localizer(store, name, circle=recording.circle).match_sequence(coefficients, images)
        results[name] = evaluate(
            name, matches.index, matches.score, recording.poses[:, :3], store.positions(), TOLERANCE, matches.accepted
        )
    return results


@pytest.fixture(scope='module')
def plain(garden, garden_map):
    repeat = garden['repeat']
    results = run_all(garden_map, repeat, repeat.coefficients, repeat.uv)
    print(
        '\ngarden repeat vs teach map (synthetic, ground-truth masks, L = 16)\n' + format_table(list(results.values()))
    )
    return results


def test_amplitude_sequences_reach_the_target_and_no_baseline_does_better(plain):
    ours = plain['amplitude-seq']
    assert ours.positives == ours.queries == 89
    assert ours.recall_at_full_precision >= TARGET_RECALL_AT_FULL_PRECISION
    for name in OUR_METHODS:
        assert plain[name].recall_at_1 == 1.0  # every repeat query matched within the tolerance
    for name in ('raw-uv', 'seqslam-raw-uv', 'bow-orb'):
        assert ours.recall_at_full_precision >= plain[name].recall_at_full_precision
        assert ours.auc >= plain[name].auc


def test_matches_lie_close_to_the_query(plain, garden, garden_map):
    matched = garden_map.positions()[plain['amplitude-seq'].matched]
    error = np.linalg.norm(matched - garden['repeat'].poses[:, :3], axis=1)
    assert error.max() < 0.5  # the repeat runs 0.25 m beside the route, snapshots are 0.1 m apart


def test_a_turned_robot_is_still_localized_and_the_image_baselines_are_not(garden, garden_map):
    repeat = garden['repeat']
    results = run_all(garden_map, repeat, *turned(repeat, TURN))
    print('\ngarden repeat turned 180 deg vs teach map (synthetic)\n' + format_table(list(results.values())))
    for name in OUR_METHODS:
        assert results[name].recall_at_full_precision >= TARGET_RECALL_AT_FULL_PRECISION
    for name in ('raw-uv', 'seqslam-raw-uv'):
        assert results['amplitude-seq'].recall_at_full_precision > results[name].recall_at_full_precision
        assert results['amplitude-seq'].auc > results[name].auc


def test_views_off_the_route_are_not_accepted(garden, garden_map):
    compass = garden['compass']  # one place 8 m from the route, tilted up to 30 degrees
    off_route = np.min(np.linalg.norm(compass.poses[:, None, :3] - garden_map.positions()[None], axis=-1))
    assert off_route > 5.0
    for name in OUR_METHODS:
        matches = Localizer(garden_map, name).match_sequence(compass.coefficients)
        assert not np.any(matches.accepted), name
