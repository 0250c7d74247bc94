# SPDX-License-Identifier: Apache-2.0
"""One frame's messages as the controller's View: camera_link turned into base_link by the camera's mount."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from skynav_route.controller import Homer, Limits, Settings, ground_angle, route_direction
from skynav_route.inputs import frame_view, imu_tilt

from skynav_core.mount import mount_from_rpy_deg
from skynav_core.rotations import as_quaternion, home_direction, relative_rotation, rpy_matrix, yaw, yaw_matrix
from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch

STAMP = 1_750_000_000_000_000_000


def messages(rotation, direction, residual=0.2, index=4, confident=True):
    """Return the match, compass estimate and home vector of one frame (rotation (3, 3), direction (3,))."""
    match = PlaceMatch(index=index, accepted=True)
    compass = CompassEstimate(snapshot_index=index, confidence=0.9 if confident else 0.2, confident=confident)
    compass.rotation.x, compass.rotation.y, compass.rotation.z, compass.rotation.w = map(float, as_quaternion(rotation))
    home = HomeVector(snapshot_index=index + 2, residual=residual)
    home.direction.x, home.direction.y, home.direction.z = map(float, direction)
    return match, compass, home


def test_without_a_mount_the_view_holds_the_messages_values():
    rotation, direction = yaw_matrix(0.3), np.array([2.0, 0.0, 0.0])
    view = frame_view(STAMP, *messages(rotation, direction), np.eye(3))
    assert (view.stamp, view.match_index, view.match_accepted, view.rotation_index) == (STAMP, 4, True, 4)
    np.testing.assert_allclose(view.rotation, rotation, atol=1e-12)
    np.testing.assert_allclose(view.home_direction, [1.0, 0.0, 0.0])  # normalised
    assert (view.home_index, view.home_residual) == (6, 0.2)
    assert (view.rotation_confident, view.rotation_confidence) == (True, 0.9)
    unsure = frame_view(STAMP, *messages(rotation, direction, confident=False), np.eye(3))
    assert (unsure.rotation_confident, unsure.rotation_confidence) == (False, 0.2)  # the rotation itself is kept
    np.testing.assert_allclose(unsure.rotation, rotation, atol=1e-12)


def test_missing_or_unusable_messages_leave_their_part_of_the_view_empty():
    match, compass, home = messages(np.eye(3), [1.0, 0.0, 0.0])
    compass.rotation.x = compass.rotation.y = compass.rotation.z = compass.rotation.w = 0.0
    home.direction.x = float('nan')
    view = frame_view(STAMP, match, compass, home, np.eye(3))
    assert view.rotation is None and view.rotation_index == -1 and view.home_direction is None
    view = frame_view(STAMP, None, None, None, np.eye(3))
    assert view.match_index == -1 and not view.match_accepted and view.rotation is None and view.home_direction is None


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_a_mounted_cameras_messages_give_the_robots_turn_heading_and_bearing(seed):
    # the truth: two base poses on gently tilted ground, the camera mounted turned and pitched on the robot
    rng = np.random.default_rng(seed)
    mount = mount_from_rpy_deg(list(rng.uniform([-5, -5, -180], [5, 5, 180])))
    headings = rng.uniform(-np.pi, np.pi, 2)
    bases = rpy_matrix(*rng.uniform(-0.1, 0.1, (2, 2)).T, headings)  # (2, 3, 3): snapshot, current
    places = np.column_stack([rng.uniform(-5, 5, (2, 2)), [0.0, 0.0]])
    cameras = bases @ mount
    # what the compass and the warping would report, in camera_link
    camera_rotation = relative_rotation(cameras[0], cameras[1])
    camera_home = home_direction(places[0], places[1], cameras[1])
    view = frame_view(STAMP, *messages(camera_rotation, camera_home), mount)
    np.testing.assert_allclose(view.rotation, relative_rotation(bases[0], bases[1]), atol=1e-9)
    np.testing.assert_allclose(view.home_direction, home_direction(places[0], places[1], bases[1]), atol=1e-9)
    # the controller's readings: the heading's twist, the home bearing and the route's direction are the robot's
    turn = math.remainder(yaw(view.rotation) - (headings[1] - headings[0]), 2 * math.pi)
    assert abs(turn) < 0.02  # the ground's 0.1 rad tilts disturb a turn to second order only
    away = places[0] - places[1]
    bearing = math.remainder(ground_angle(view.home_direction) - (math.atan2(away[1], away[0]) - headings[1]), math.tau)
    assert abs(bearing) < 0.02
    forward = route_direction(view.rotation)  # the snapshot robot's forward axis in the current base_link
    np.testing.assert_allclose(forward, bases[1].T @ bases[0][:, 0], atol=1e-9)


def home_steps(mount_seen: np.ndarray, camera_home: np.ndarray):
    """Return a Homer's commands to two frames 0.2 s apart whose home vector is `camera_home` (camera_link), with the
    route node taking the camera's mount to be `mount_seen`."""
    homer = Homer(6, Limits(), Settings())
    return [homer.step(frame_view(STAMP + k * 200_000_000, *messages(np.eye(3), camera_home), mount_seen)).command
            for k in range(2)]  # fmt: skip


@pytest.mark.parametrize('mount_yaw', [90.0, 180.0, -90.0])
def test_homing_turns_towards_home_only_with_the_mount(mount_yaw):
    # home lies straight ahead of the robot; the camera, turned on it, sees it at -mount_yaw
    mount = mount_from_rpy_deg([0.0, 4.0, mount_yaw])
    camera_home = mount.T @ np.array([1.0, 0.0, 0.0])
    mounted = home_steps(mount, camera_home)[-1]
    assert mounted.angular == pytest.approx(0.0, abs=1e-9) and mounted.linear > 0.05  # straight on, speeding up
    unmounted = home_steps(np.eye(3), camera_home)[-1]  # the mount left out: home seems to lie to a side or behind
    assert abs(unmounted.angular) > 0.5 and unmounted.linear == pytest.approx(0.0, abs=1e-9)


def imu_message(orientation=None, acceleration=(0.0, 0.0, 9.81)):
    """Return a sensor_msgs/Imu with an orientation (3, 3; None: the IMU gives none) and a linear acceleration."""
    from sensor_msgs.msg import Imu

    imu = Imu()
    if orientation is None:
        imu.orientation_covariance[0] = -1.0  # REP-145: no orientation
    else:
        q = imu.orientation
        q.x, q.y, q.z, q.w = map(float, as_quaternion(orientation))
    a = imu.linear_acceleration
    a.x, a.y, a.z = map(float, acceleration)
    return imu


@pytest.mark.parametrize('roll, pitch', [(0.0, 0.0), (40.0, 0.0), (0.0, -25.0), (30.0, 30.0), (0.0, 120.0)])
def test_the_tilt_is_the_angle_of_base_links_z_from_the_vertical_by_orientation_or_gravity(roll, pitch):
    rotation = rpy_matrix(math.radians(roll), math.radians(pitch), math.radians(70.0))  # the heading plays no part
    expected = math.degrees(math.acos(rotation[2, 2]))
    by_orientation = imu_tilt(imu_message(rotation, acceleration=(0.0, 0.0, 0.0)), np.eye(3))
    # at rest the accelerometer reads the reaction to gravity: the world's up in the IMU's frame
    by_gravity = imu_tilt(imu_message(None, rotation.T @ np.array([0.0, 0.0, 9.81])), np.eye(3))
    assert math.degrees(by_orientation) == pytest.approx(expected, abs=1e-6)
    assert math.degrees(by_gravity) == pytest.approx(expected, abs=1e-6)


def test_an_imu_mounted_turned_is_read_in_base_link():
    # the IMU lies on its side (its y axis up) on a level robot: level in base_link, 90 deg in its own frame
    imu = imu_message(None, (0.0, 9.81, 0.0))
    mounted = rpy_matrix(math.radians(90.0), 0.0, 0.0)  # the IMU frame's rotation in base_link
    assert imu_tilt(imu, mounted) == pytest.approx(0.0, abs=1e-9)
    assert math.degrees(imu_tilt(imu, np.eye(3))) == pytest.approx(90.0)


def test_an_imu_without_a_usable_reading_gives_no_tilt():
    assert imu_tilt(imu_message(None, (0.0, 0.0, 0.0)), np.eye(3)) is None
    assert imu_tilt(imu_message(None, (math.nan, 0.0, 9.81)), np.eye(3)) is None
    # an orientation of zeros that does not say it is missing: the acceleration is read instead
    zeros = imu_message(None, (0.0, 9.81 * math.sin(0.5), 9.81 * math.cos(0.5)))
    zeros.orientation_covariance[0] = 0.0
    zeros.orientation.w = 0.0
    assert imu_tilt(zeros, np.eye(3)) == pytest.approx(0.5)
