# SPDX-License-Identifier: Apache-2.0
"""Property tests of the rotation helpers against scipy's independent implementation, flat and batched."""

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from skynav_core.rotations import (
    as_matrix,
    as_quaternion,
    home_direction,
    relative_rotation,
    rotation_angle,
    tilt,
    within_tilt,
    wrap_angle,
    yaw,
    yaw_matrix,
    zyz_angles,
    zyz_matrix,
)

seeds = st.integers(0, 2**32 - 1)


def random_rotations(seed: int, count: int) -> Rotation:
    """Return `count` uniformly random rotations, some of them at gimbal lock (beta 0 or pi)."""
    rng = np.random.default_rng(seed)
    rotations = Rotation.random(count, random_state=rng)
    locked = Rotation.from_euler(
        'ZYZ', np.column_stack([rng.uniform(-np.pi, np.pi, 2), [0.0, np.pi], rng.uniform(-np.pi, np.pi, 2)])
    )
    return Rotation.concatenate([rotations, locked])


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_zyz_angles_rebuild_the_matrix_to_rounding_and_match_scipys_convention(seed):
    rotations = random_rotations(seed, 50)
    alpha, beta, gamma = zyz_angles(rotations.as_matrix())
    np.testing.assert_allclose(zyz_matrix(alpha, beta, gamma), rotations.as_matrix(), atol=1e-12)
    np.testing.assert_allclose(
        zyz_matrix(alpha, beta, gamma),
        Rotation.from_euler('ZYZ', np.column_stack([alpha, beta, gamma])).as_matrix(),
        atol=1e-12,
    )
    assert np.all((beta >= 0) & (beta <= np.pi)) and np.all((gamma >= -np.pi) & (gamma < np.pi))


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_batched_results_equal_one_rotation_at_a_time(seed):
    matrices = random_rotations(seed, 8).as_matrix()
    batched = zyz_angles(matrices)
    for k, matrix in enumerate(matrices):
        assert zyz_angles(matrix) == pytest.approx(tuple(angle[k] for angle in batched), abs=1e-15)
        assert rotation_angle(matrix, matrices[0]) == pytest.approx(rotation_angle(matrices, matrices[0])[k])
        assert tilt(matrix) == pytest.approx(tilt(matrices)[k])


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_angle_between_rotations_is_scipys_magnitude(seed):
    first, second = random_rotations(seed, 20), random_rotations(seed + 1, 20)
    np.testing.assert_allclose(rotation_angle(first, second), (first.inv() * second).magnitude(), atol=1e-7)
    np.testing.assert_allclose(rotation_angle(first.as_quat(), first.as_matrix()), 0.0, atol=1e-7)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_tilt_is_the_zyz_beta_and_ignores_turns_about_z(seed):
    rotations = random_rotations(seed, 20)
    np.testing.assert_allclose(tilt(rotations), zyz_angles(rotations)[1], atol=1e-7)
    turned = (
        Rotation.from_euler('z', np.random.default_rng(seed).uniform(-np.pi, np.pi, (len(rotations), 1))) * rotations
    )
    np.testing.assert_allclose(tilt(turned), tilt(rotations), atol=1e-7)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_yaw_is_the_zyz_alpha_plus_gamma_and_a_turn_about_z_adds_to_it(seed):
    rotations = random_rotations(seed, 20)
    alpha, beta, gamma = zyz_angles(rotations)
    keep = beta < np.radians(170)  # near beta = pi the twist about z is ill-defined
    np.testing.assert_allclose(np.cos(yaw(rotations) - alpha - gamma)[keep], 1.0, atol=1e-9)
    turns = np.random.default_rng(seed).uniform(-np.pi, np.pi, len(rotations))
    turned = Rotation.from_euler('z', turns[:, None]) * rotations
    np.testing.assert_allclose(np.cos(yaw(turned) - yaw(rotations) - turns)[keep], 1.0, atol=1e-9)


def test_yaw_between_tilted_cameras_is_the_turn_to_second_order():
    rng = np.random.default_rng(3)
    for degrees in (5.0, 10.0, 20.0):
        axes = rng.uniform(0, 2 * np.pi, (200, 2))
        tilts = [
            Rotation.from_rotvec(np.radians(degrees) * np.column_stack([np.cos(a), np.sin(a), np.zeros(200)]))
            for a in axes.T
        ]
        turns = rng.uniform(-np.pi, np.pi, 200)
        between = tilts[0].inv() * Rotation.from_euler('z', turns[:, None]) * tilts[1]
        matrices = between.as_matrix()
        error = np.abs(wrap_angle(yaw(matrices) - turns))
        # the azimuth of the snapshot's forward axis seen from the tilted current camera, for comparison
        projected = np.abs(wrap_angle(-np.arctan2(matrices[:, 0, 1], matrices[:, 0, 0]) - turns))
        # both cameras tilted 20 degrees: 3.6 degrees at most, where the forward axis's azimuth is 8.9 degrees off
        assert np.max(error) < 0.55 * np.radians(degrees) ** 2 and np.max(error) < np.max(projected) / 2


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_quaternions_round_trip_in_ros_order(seed):
    rotations = random_rotations(seed, 20)
    quaternions = as_quaternion(rotations)
    assert np.all(quaternions[..., 3] >= 0)
    np.testing.assert_allclose(as_matrix(quaternions), rotations.as_matrix(), atol=1e-12)
    np.testing.assert_allclose(
        as_matrix(quaternions.reshape(2, -1, 4)), rotations.as_matrix().reshape(2, -1, 3, 3), atol=1e-12
    )


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_relative_rotation_maps_current_view_directions_to_the_snapshots(seed):
    rng = np.random.default_rng(seed)
    snapshot, current = Rotation.random(random_state=rng), Rotation.random(10, random_state=rng)
    world_directions = rng.normal(size=(10, 3))
    d_current = current.inv().apply(world_directions)  # the same world direction in each current camera_link
    d_snapshot = snapshot.inv().apply(world_directions)
    rotations = relative_rotation(snapshot.as_quat(), current.as_quat())
    np.testing.assert_allclose(np.einsum('kij,kj->ki', rotations, d_current), d_snapshot, atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_home_direction_points_at_the_snapshot_in_the_current_view(seed):
    rng = np.random.default_rng(seed)
    current, positions, home = Rotation.random(10, random_state=rng), rng.normal(size=(10, 3)), rng.normal(size=3)
    directions = home_direction(home, positions, current.as_quat())
    np.testing.assert_allclose(
        current.apply(directions) * np.linalg.norm(home - positions, axis=1)[:, None], home - positions, atol=1e-12
    )


def test_a_rotation_of_the_wrong_shape_is_refused_in_one_line():
    with pytest.raises(ValueError, match='3x3 matrices or quaternions'):
        as_matrix(np.zeros(3))


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_yaw_matrix_is_the_turn_about_z_one_angle_or_many(seed):
    angles = np.random.default_rng(seed).uniform(-2 * np.pi, 2 * np.pi, (4, 5))
    by_scipy = Rotation.from_euler('z', angles.reshape(-1, 1)).as_matrix().reshape(4, 5, 3, 3)
    np.testing.assert_allclose(yaw_matrix(angles), by_scipy, atol=1e-15)
    np.testing.assert_array_equal(yaw_matrix(angles)[1, 2], yaw_matrix(angles[1, 2]))
    np.testing.assert_allclose(yaw_matrix(angles), zyz_matrix(angles, 0.0, 0.0), atol=1e-15)


def test_importing_the_rotations_leaves_scipy_spatial_unloaded():
    # the stage nodes import this module at start-up; scipy.spatial loads on the first quaternion instead
    check = "import sys, skynav_core.rotations; sys.exit('scipy.spatial' in sys.modules)"
    assert subprocess.run([sys.executable, '-c', check]).returncode == 0


@pytest.mark.parametrize('angle', [0.0, 1.0, -1.0, np.pi, -np.pi, 3 * np.pi, 7.5, -7.5, 1e3])
def test_wrap_angle_lands_in_minus_pi_to_pi_and_keeps_the_direction(angle):
    wrapped = wrap_angle(angle)
    assert isinstance(wrapped, float) and -np.pi <= wrapped < np.pi
    assert np.cos(wrapped) == pytest.approx(np.cos(angle), abs=1e-9)
    assert np.sin(wrapped) == pytest.approx(np.sin(angle), abs=1e-9)


def test_wrap_angle_broadcasts_over_arrays_as_over_scalars():
    angles = np.array([[0.0, np.pi, -np.pi], [3 * np.pi, 7.5, -7.5]])
    wrapped = wrap_angle(angles)
    assert wrapped.shape == angles.shape
    np.testing.assert_array_equal(wrapped, np.vectorize(wrap_angle)(angles))


def test_within_tilt_is_the_tilt_against_the_bound():
    rotations = Rotation.random(200, random_state=7).as_matrix()
    for bound in (0.1, 0.5, 1.2):
        assert [within_tilt(r, bound) for r in rotations] == [tilt(r) <= bound for r in rotations]
    assert all(within_tilt(r, None) for r in rotations)  # no bound
