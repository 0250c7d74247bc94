# SPDX-License-Identifier: Apache-2.0
"""Homing on the bundled synthetic homing grids (bags/synthetic_park_homing.mcap, level ground, and
bags/synthetic_park_bumpy_homing.mcap, the same places on bumps that tilt the camera up to 20 degrees more) and a
compass set.

Views are the ground-truth sky masks through FisheyeTransform (degree 16, fill 'zero'), so these tests measure
warping, not segmentation. The compass input is simulated: the true rotation Q_s^-1 Q_c turned by a seeded error
of 1, 1 and 3 degrees rms about x, y, z (camera_link), as a visual compass would leave it.

Measured (40 places 0.62-3.2 m from the snapshot), median / p90 error in degrees:
    level (tilt 0-8):    with compass  0.5-1 m 10.7 / 15.7 (4 places), 1-2 m 8.9 / 17.8, 2-4 m 7.6 / 15.3,
                         all 8.0 / 16.6; without compass all 11.7 / 22.1; 2D-warping 13.7 / 33.1;
                         min-warping 53.7 / 119 (tilt breaks it)
    bumpy (tilt 3-24):   with compass  0.5-1 m 14.3 / 16.3 (4 places), 1-2 m 7.0 / 13.3, 2-4 m 8.3 / 14.7,
                         all 8.1 / 15.2; without compass all 10.2 / 21.2; 2D-warping 28 / 79; min-warping 58 / 132
    a compass flipped by half a turn: the same as without compass (the own pre-alignment wins); without that
                         check (check_compass=False) 71-82 / 131-144
Bounds: the issue's 15-degree median from 1 m on (the 0.5-1 m bin holds four places: 20 degrees), p90 25 (with
compass) and 30 (without) degrees, and 3D-warping at most half min-warping's median. Confidence: every place from
1 m on but one passed the threshold and no pure rotation did (largest 0.013 over 150 runs on five synthetic
compass sets), so here at least 90 % from 1 m on must be confident and no pure rotation may be.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_sh.fisheye import FisheyeTransform
from skynav_warping import (
    PanoramaUnwrapper,
    angular_errors,
    binned_statistics,
    estimate_home_vector,
    load_homing_grid,
    min_warping,
    tilt_angles,
    true_home_directions,
    true_rotations,
    view_from_fisheye,
    warping_2d,
)

BAGS = Path(__file__).resolve().parents[2] / 'bags'
DEGREE = 16


def simulated_compass(true: np.ndarray, seed: int) -> np.ndarray:
    """Return the true rotation with a seeded error of 1, 1, 3 degrees rms about x, y, z."""
    error = np.radians([1.0, 1.0, 3.0]) * np.random.default_rng(seed).standard_normal(3)
    return Rotation.from_rotvec(error).as_matrix() @ true


GRIDS = ('synthetic_park_homing.mcap', 'synthetic_park_bumpy_homing.mcap')
HALF_TURN = Rotation.from_euler('z', 180.0, degrees=True).as_matrix()


@pytest.fixture(scope='module', params=GRIDS)
def grid(request):
    return load_homing_grid(str(BAGS / request.param))


@pytest.fixture(scope='module')
def truth(grid):
    positions, quaternions = grid.positions, grid.quaternions
    return {
        'home': true_home_directions(positions[1:], quaternions[1:], positions[0]),
        'rotation': true_rotations(quaternions[0], quaternions[1:]),
        'distance': np.linalg.norm(positions[1:] - positions[0], axis=1),
    }


@pytest.fixture(scope='module')
def estimates(grid, truth):
    transform = FisheyeTransform(grid.camera, DEGREE, fill='zero')
    views = [view_from_fisheye(transform, mask) for mask in grid.masks]
    out = {'compass': [], 'none': [], 'flipped': []}
    for i, view in enumerate(views[1:]):
        compass = simulated_compass(truth['rotation'][i], i)
        out['compass'].append(estimate_home_vector(view, views[0], compass))
        out['none'].append(estimate_home_vector(view, views[0]))
        out['flipped'].append(estimate_home_vector(view, views[0], compass @ HALF_TURN))
    return out


def test_grid_is_synthetic_and_complete(grid):
    assert grid.synthetic and grid.labels[0] == 'snapshot'
    assert len(grid.masks) == len(grid.positions) == 41


def test_the_bumpy_grid_tilts_the_camera_up_to_20_degrees_and_more():
    level, bumpy = (load_homing_grid(str(BAGS / name)) for name in GRIDS)
    # the same places (the camera, 0.3 m above the wheels, leans with the bump: up to 0.3 sin 24 degrees)
    assert np.abs(bumpy.positions[:, :2] - level.positions[:, :2]).max() < 0.15
    level_tilt, bumpy_tilt = tilt_angles(level.quaternions), tilt_angles(bumpy.quaternions)
    assert level_tilt.max() < 10.0
    assert np.count_nonzero(bumpy_tilt >= 10.0) >= 20 and bumpy_tilt.max() >= 20.0


@pytest.mark.parametrize('mode', ['compass', 'none', 'flipped'])
def test_3d_warping_errors(estimates, truth, mode):
    directions = np.array([e.best_direction for e in estimates[mode]])
    errors = angular_errors(directions, truth['home'])
    near, middle, far = binned_statistics(errors, truth['distance'])
    assert near.count + middle.count + far.count == 40
    assert near.median < 20.0 and middle.median < 15.0 and far.median < 15.0
    assert np.percentile(errors, 90) < (25.0 if mode == 'compass' else 30.0)
    assert all(e.residual >= 0.0 for e in estimates[mode])  # a masked squared difference
    confident = np.array([e.confident for e in estimates[mode]])
    assert confident[truth['distance'] >= 1.0].mean() >= 0.9
    for e in estimates[mode]:  # a confident vector is the optimum's unit direction, otherwise zero
        assert np.allclose(e.direction, e.best_direction if e.confident else 0.0)


def test_a_compass_flipped_by_half_a_turn_is_overruled_by_the_pre_alignment(estimates, truth):
    overruled = 0
    for i, estimate in enumerate(estimates['flipped']):
        flipped = simulated_compass(truth['rotation'][i], i) @ HALF_TURN
        overruled += not np.allclose(estimate.warp.start_rotation, flipped)
        found = Rotation.from_matrix(estimate.rotation.T @ truth['rotation'][i]).magnitude()
        assert np.degrees(found) < 20.0  # the rotation is the true one, not the flipped start
    assert overruled >= 38


def test_baselines_run_and_3d_warping_beats_min_warping(grid, truth, estimates):
    unwrapper = PanoramaUnwrapper(grid.camera)
    bands = [unwrapper(mask) for mask in grid.masks]
    results = {
        '2d': [warping_2d(bands[0], band) for band in bands[1:]],
        'min': [min_warping(bands[0], band, unwrapper.elevations) for band in bands[1:]],
    }
    medians = {}
    for method, found in results.items():
        directions = np.array([r.direction for r in found])
        assert np.all(np.isfinite(directions)) and np.allclose(np.linalg.norm(directions, axis=1), 1.0)
        medians[method] = np.median(angular_errors(directions, truth['home']))
    warped = np.median(angular_errors(np.array([e.best_direction for e in estimates['compass']]), truth['home']))
    assert warped < 0.5 * medians['min']
    if tilt_angles(grid.quaternions).max() < 10.0:
        assert medians['2d'] < 30.0  # nearly level: 2D-warping still points roughly home
    else:
        assert warped < 0.5 * medians['2d']  # on bumps the planar assumption breaks


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
