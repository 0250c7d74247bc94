# SPDX-License-Identifier: Apache-2.0
"""Ground-truth home directions, angular errors, binned statistics and the quiver plot."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_warping import (
    angular_errors,
    binned_statistics,
    home_vectors_in_map,
    quiver_plot,
    rotation_errors,
    summary_table,
    tilt_angles,
    true_home_directions,
    true_rotations,
)


def test_true_home_direction_follows_the_contract():
    # a camera 2 m along map +x of the snapshot, turned by 90 degrees (its +x is map +y): the snapshot lies along
    # map -x, which is the camera's +y
    quaternion = Rotation.from_euler('z', 90, degrees=True).as_quat()
    home = true_home_directions(np.array([[2.0, 0.0, 0.0]]), quaternion[None], np.zeros(3))
    np.testing.assert_allclose(home, [[0.0, 1.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(home_vectors_in_map(home, quaternion[None]), [[-1.0, 0.0, 0.0]], atol=1e-12)
    snapshot_q = Rotation.from_euler('z', 30, degrees=True).as_quat()
    rotation = true_rotations(snapshot_q, quaternion[None])[0]  # Q_s^-1 Q_c
    np.testing.assert_allclose(rotation, Rotation.from_euler('z', 60, degrees=True).as_matrix(), atol=1e-12)
    tilted = Rotation.from_euler('x', 12, degrees=True).as_quat()
    assert tilt_angles(tilted[None])[0] == pytest.approx(12.0)


def test_errors():
    estimated = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
    true = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    errors = angular_errors(estimated, true)
    assert errors[0] == pytest.approx(0.0, abs=1e-6) and errors[1] == pytest.approx(90.0) and np.isnan(errors[2])
    turn = Rotation.from_euler('y', 7, degrees=True).as_matrix()
    assert rotation_errors(turn[None], np.eye(3)[None])[0] == pytest.approx(7.0)


def test_binned_statistics_and_table():
    errors = np.array([1.0, 2.0, 3.0, 10.0, 20.0, np.nan])
    distances = np.array([0.6, 0.7, 0.8, 1.5, 3.0, 3.5])
    bins = binned_statistics(errors, distances)
    assert [b.count for b in bins] == [3, 1, 1]  # the nan (no estimate) is left out
    assert bins[0].median == pytest.approx(2.0) and bins[0].p90 == pytest.approx(2.8)
    table = summary_table({'3d-warping': errors}, distances, np.zeros(6), {'3d-warping': 0.02})
    assert '3d-warping' in table and '20.0' in table.splitlines()[-1]


def test_quiver_plot_says_synthetic(tmp_path):
    import matplotlib

    matplotlib.use('Agg')
    positions = np.array([[1.0, 0.0, 0.0], [0.0, 1.5, 0.0]])
    true = np.array([[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    path = tmp_path / 'quiver.png'
    title = quiver_plot(str(path), positions, np.zeros(3), true, {'3d-warping': true + 0.1}, 'home vectors, park grid')
    assert 'synthetic' in title and path.stat().st_size > 1000
