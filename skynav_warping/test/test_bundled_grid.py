"""Homing on the bundled synthetic homing grid (bags/synthetic_park_homing.mcap) and compass set.

Views are the ground-truth sky masks through FisheyeTransform (degree 16, fill 'zero'), so these tests measure
warping, not segmentation. The compass input is simulated: the true rotation Q_s^-1 Q_c turned by a seeded error
of 1, 1 and 3 degrees rms about x, y, z (camera_link), as a visual compass would leave it.

Measured on this grid (40 places 0.74-3.2 m from the snapshot, tilt 0-8 degrees), median / p90 error in degrees:
    with compass:     0.5-1 m 11.5 / 17.7 (4 places), 1-2 m 9.4 / 19.9, 2-4 m 7.9 / 15.4, all 9.2 / 18.1
    without compass:  all 11.7 / 22.1;  2D-warping 13.7 / 33.1;  min-warping 53.7 / 119 (tilt breaks it)
Bounds: the issue's 15-degree median from 1 m on (the 0.5-1 m bin holds four places: 20 degrees), p90 25 (with
compass) and 30 (without) degrees, and 3D-warping at most half min-warping's median. Confidence: every place from
1 m on passed the threshold (least confidence 0.031 there) and no pure rotation did (largest 0.013 over 150 runs
on five synthetic compass sets), so here at least 90 % from 1 m on must be confident and no pure rotation may be.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_sh.fisheye import FisheyeTransform
from skynav_warping import PanoramaUnwrapper, angular_errors, binned_statistics, estimate_home_vector, \
    load_homing_grid, min_warping, true_home_directions, true_rotations, view_from_fisheye, warping_2d

BAGS = Path(__file__).resolve().parents[2] / 'bags'
DEGREE = 16


def simulated_compass(true: np.ndarray, seed: int) -> np.ndarray:
    """Return the true rotation with a seeded error of 1, 1, 3 degrees rms about x, y, z."""
    error = np.radians([1.0, 1.0, 3.0]) * np.random.default_rng(seed).standard_normal(3)
    return Rotation.from_rotvec(error).as_matrix() @ true


@pytest.fixture(scope='module')
def grid():
    return load_homing_grid(str(BAGS / 'synthetic_park_homing.mcap'))


@pytest.fixture(scope='module')
def truth(grid):
    positions, quaternions = grid.positions, grid.quaternions
    return {'home': true_home_directions(positions[1:], quaternions[1:], positions[0]),
            'rotation': true_rotations(quaternions[0], quaternions[1:]),
            'distance': np.linalg.norm(positions[1:] - positions[0], axis=1)}


@pytest.fixture(scope='module')
def estimates(grid, truth):
    transform = FisheyeTransform(grid.camera, DEGREE, fill='zero')
    views = [view_from_fisheye(transform, mask) for mask in grid.masks]
    out = {'compass': [], 'none': []}
    for i, view in enumerate(views[1:]):
        out['compass'].append(estimate_home_vector(view, views[0], simulated_compass(truth['rotation'][i], i)))
        out['none'].append(estimate_home_vector(view, views[0]))
    return out


def test_grid_is_synthetic_and_complete(grid):
    assert grid.synthetic and grid.labels[0] == 'snapshot'
    assert len(grid.masks) == len(grid.positions) == 41


@pytest.mark.parametrize('mode', ['compass', 'none'])
def test_3d_warping_errors(estimates, truth, mode):
    directions = np.array([e.best_direction for e in estimates[mode]])
    errors = angular_errors(directions, truth['home'])
    near, middle, far = binned_statistics(errors, truth['distance'])
    assert near.count + middle.count + far.count == 40
    assert near.median < 20.0 and middle.median < 15.0 and far.median < 15.0
    assert np.percentile(errors, 90) < (25.0 if mode == 'compass' else 30.0)
    confident = np.array([e.confident for e in estimates[mode]])
    assert confident[truth['distance'] >= 1.0].mean() >= 0.9
    for e in estimates[mode]:  # a confident vector is the optimum's unit direction, otherwise zero
        assert np.allclose(e.direction, e.best_direction if e.confident else 0.0)


def test_baselines_run_and_3d_warping_beats_min_warping(grid, truth, estimates):
    unwrapper = PanoramaUnwrapper(grid.camera)
    bands = [unwrapper(mask) for mask in grid.masks]
    results = {'2d': [warping_2d(bands[0], band) for band in bands[1:]],
               'min': [min_warping(bands[0], band, unwrapper.elevations) for band in bands[1:]]}
    medians = {}
    for method, found in results.items():
        directions = np.array([r.direction for r in found])
        assert np.all(np.isfinite(directions)) and np.allclose(np.linalg.norm(directions, axis=1), 1.0)
        medians[method] = np.median(angular_errors(directions, truth['home']))
    warped = np.median(angular_errors(np.array([e.best_direction for e in estimates['compass']]), truth['home']))
    assert warped < 0.5 * medians['min']
    assert medians['2d'] < 30.0  # nearly level here (tilt up to 8 degrees): 2D-warping still points roughly home


def test_pure_rotations_give_no_confident_home_vector():
    compass_set = load_homing_grid(str(BAGS / 'synthetic_garden_compass.mcap'))
    transform = FisheyeTransform(compass_set.camera, DEGREE, fill='zero')
    rotations = [i for i, label in enumerate(compass_set.labels) if label == 'rotation']
    assert len(rotations) == 15
    reference = view_from_fisheye(transform, compass_set.masks[0])
    truths = true_rotations(compass_set.quaternions[0], compass_set.quaternions[rotations])
    for i, true in zip(rotations, truths):
        view = view_from_fisheye(transform, compass_set.masks[i])
        for compass in (simulated_compass(true, i), None):
            estimate = estimate_home_vector(view, reference, compass)
            assert not estimate.confident and np.all(estimate.direction == 0.0)
