# SPDX-License-Identifier: Apache-2.0
"""The markers' geometry on scripted maps and views, no ROS: snapshot places, arrows, confidence and state."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_core.maps import ODOM_POSE, MapStore
from skynav_core.names import MAP_FRAME, ODOM_FRAME
from skynav_core.rotations import home_direction, relative_rotation
from skynav_viz import scene

DEGREE = 2


def pose(x: float, y: float, yaw_deg: float) -> np.ndarray:
    """Return (x, y, z, qx, qy, qz, qw) of a pose at (x, y, 0) turned `yaw_deg` about z."""
    return np.concatenate([[x, y, 0.0], Rotation.from_euler('z', yaw_deg, degrees=True).as_quat()])


def write_map(path, truth=None, odometry=None, count=4) -> MapStore:
    """Write a map of `count` snapshots with optional ground-truth and odometry poses; return it open for reading."""
    with MapStore.create(path, 'route', DEGREE) as store:
        for i in range(count):
            descriptors = {ODOM_POSE: odometry[i]} if odometry is not None else None
            store.add_snapshot(np.full(9, float(i)), 1000 + i, None if truth is None else truth[i], descriptors)
    return MapStore.open(path)


STRAIGHT = [pose(i, 0.0, 0.0) for i in range(4)]  # along +x, facing +x


def test_a_map_taught_live_is_drawn_from_its_odometry_in_odom(tmp_path):
    odometry = [pose(0, i, 90.0) for i in range(4)]
    odometry[2] = np.full(7, np.nan)  # a view without /odom
    with write_map(tmp_path / 'taught.db', truth=STRAIGHT, odometry=odometry) as store:
        route = scene.route_of(store)
    assert route is not None and route.frame_id == ODOM_FRAME
    np.testing.assert_allclose(route.drawn, [[0, 0, 0], [0, 1, 0], [0, 3, 0]])
    assert not route.known(2) and route.known(3) and not route.known(4) and not route.known(-1)


def test_a_map_built_from_a_recording_is_drawn_from_its_ground_truth_in_map(tmp_path):
    with write_map(tmp_path / 'built.db', truth=STRAIGHT) as store:
        route = scene.route_of(store)
    assert route is not None and route.frame_id == MAP_FRAME
    np.testing.assert_allclose(route.positions, [p[:3] for p in STRAIGHT])


def test_a_map_without_poses_has_no_route(tmp_path):
    with write_map(tmp_path / 'bare.db') as store:
        assert scene.route_of(store) is None
    with write_map(tmp_path / 'no_odom.db', odometry=[np.full(7, np.nan)] * 4) as store:
        assert scene.route_of(store) is None


def test_the_route_direction_points_to_the_next_snapshot_and_at_the_end_along_the_last_step(tmp_path):
    turned = [pose(0, 0, 0), pose(1, 0, 0), pose(1, 2, 0), pose(1, 3, 0)]
    with write_map(tmp_path / 'turn.db', truth=turned) as store:
        route = scene.route_of(store)
    assert route is not None
    first = scene.route_arrow(route, 1, 0.5)
    assert first is not None
    np.testing.assert_allclose(first.start, [1, 0, 0])
    np.testing.assert_allclose(first.end, [1, 0.5, 0])  # towards snapshot 2, 0.5 m long
    last = scene.route_arrow(route, 3, 2.0)
    assert last is not None
    np.testing.assert_allclose(last.end, [1, 5, 0])  # beyond the end, along the step 2 -> 3


def test_the_home_vector_is_turned_into_the_route_frame_through_its_snapshot(tmp_path):
    # the robot stands at snapshot 0's place turned 70 deg, the home vector points at snapshot 3 (turned -40 deg)
    places = [pose(0, 0, 70.0), pose(1, 1, 0), pose(2, 1, 0), pose(3, 4, -40.0)]
    with write_map(tmp_path / 'home.db', truth=places) as store:
        route = scene.route_of(store)
    assert route is not None
    current, target = Rotation.from_quat(places[0][3:]), Rotation.from_quat(places[3][3:])
    rotation = relative_rotation(target, current)  # d_snapshot = R d_current
    direction = home_direction(places[3][:3], places[0][:3], current)  # in the current camera_link
    arrow = scene.home_arrow(route, 0, 3, direction, rotation, 1.0)
    assert arrow is not None
    expected = (places[3][:3] - places[0][:3]) / np.linalg.norm(places[3][:3] - places[0][:3])
    np.testing.assert_allclose(arrow.end - arrow.start, expected, atol=1e-12)
    shown = scene.scene(route, 0, True, (3, direction, rotation), 1.0)
    assert (shown.matched, shown.accepted, shown.target) == (0, True, 3)
    assert shown.home is not None and shown.route is not None
    np.testing.assert_allclose(shown.home.end, arrow.end)


def test_on_odometry_poses_a_mounted_cameras_home_vector_is_turned_by_the_mount(tmp_path):
    # the camera is turned 90 deg left and pitched 4 deg on the robot; the map holds base_link's odometry poses
    mount = Rotation.from_euler('xyz', [0.0, 4.0, 90.0], degrees=True)
    places = [pose(0, 0, 70.0), pose(1, 1, 0), pose(2, 1, 0), pose(3, 4, -40.0)]
    with write_map(tmp_path / 'mounted.db', odometry=places) as store:
        route = scene.route_of(store)
    assert route is not None and route.frame_id == ODOM_FRAME
    current, target = (Rotation.from_quat(places[k][3:]) * mount for k in (0, 3))  # the cameras' orientations
    rotation = relative_rotation(target, current)
    direction = home_direction(places[3][:3], places[0][:3], current)
    expected = (places[3][:3] - places[0][:3]) / np.linalg.norm(places[3][:3] - places[0][:3])
    shown = scene.scene(route, 0, True, (3, direction, rotation), 1.0, mount.as_matrix())
    assert shown.home is not None
    np.testing.assert_allclose(shown.home.end - shown.home.start, expected, atol=1e-12)
    unmounted = scene.scene(route, 0, True, (3, direction, rotation), 1.0)  # the mount left out: off by far
    assert unmounted.home is not None and np.linalg.norm(unmounted.home.end - shown.home.end) > 0.5


def test_a_frame_without_a_match_shows_no_robot(tmp_path):
    with write_map(tmp_path / 'route.db', truth=STRAIGHT) as store:
        route = scene.route_of(store)
    assert route is not None
    shown = scene.scene(route, -1, False, (2, np.array([1.0, 0, 0]), np.eye(3)), 1.0)
    assert shown.matched is None and shown.home is None and shown.route is None and shown.target == 2
    assert scene.scene(route, 9, True, None, 1.0).matched is None  # beyond the map


@pytest.mark.parametrize(
    ('residual', 'expected'), [(0.25, 0.75), (1.7, 0.0), (-0.5, 1.0), (None, 0.0), (float('nan'), 0.0)]
)
def test_confidence_is_one_minus_the_residual_within_0_and_1(residual, expected):
    assert scene.confidence(residual) == pytest.approx(expected)


def test_state_tells_no_match_an_unaccepted_and_an_accepted_one():
    assert scene.state(-1, False) == scene.NO_MAP
    assert scene.state(4, False) == scene.LOCALIZING
    assert scene.state(4, True) == scene.LOCALIZED
