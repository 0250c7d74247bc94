# SPDX-License-Identifier: Apache-2.0
"""Synthetic checkerboard views: the board's pattern, where it is drawn, the image circle, the poses a person holds."""

from __future__ import annotations

import numpy as np
import pytest

from skynav_core.camera import angles_from_directions
from skynav_sim.checkerboard import (
    HOLDING_DISTANCE,
    HOLDING_TILT,
    INK_REFLECTANCE,
    PAPER_REFLECTANCE,
    SYNTHETIC_CIRCLE_FILL,
    BoardRenderer,
    Checkerboard,
    calibration_poses,
    facing_pose,
    synthetic_fisheye,
)
from skynav_sim.errors import SimError

FOV = np.radians(200.0)
BOARD = Checkerboard(9, 6, 0.025)


@pytest.fixture(scope='module')
def camera():
    return synthetic_fisheye(320, 240, FOV)


def test_the_pattern_alternates_round_every_inner_corner_and_has_a_white_margin():
    m = BOARD.square
    around = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]) * m  # the four squares at a corner
    for corner in BOARD.corners()[[0, 7, 30, 53]]:
        values = BOARD.reflectance(corner[0] + around[:, 0], corner[1] + around[:, 1])
        assert sorted(values) == [INK_REFLECTANCE, INK_REFLECTANCE, PAPER_REFLECTANCE, PAPER_REFLECTANCE]
        assert values[0] == values[2] and values[1] == values[3]  # opposite squares alike
    margin = BOARD.reflectance(np.array([-1.5 * m, 4 * m]), np.array([2 * m, 5.5 * m + m]))
    assert np.all(margin == PAPER_REFLECTANCE)
    assert np.isnan(BOARD.reflectance(np.array([-2.5 * m]), np.array([0.0]))[0])  # off the sheet
    with pytest.raises(SimError):
        Checkerboard(1, 6, 0.025)


def test_the_synthetic_lens_throws_its_circle_inside_the_frame(camera):
    radius = camera.fx * float(camera.distort(np.array(FOV / 2)))
    assert radius == pytest.approx(SYNTHETIC_CIRCLE_FILL * (240 - 1) / 2)
    assert all(k != 0 for k in camera.k) and camera.fy != camera.fx
    assert (camera.cx, camera.cy) != ((320 - 1) / 2, (240 - 1) / 2)


def test_a_board_is_drawn_where_the_camera_projects_it_and_black_outside_the_circle(camera):
    renderer = BoardRenderer(camera, BOARD, FOV, seed=1)
    pose = facing_pose(np.radians(40.0), np.radians(30.0), 0.3)
    image = renderer.render(pose, 0).astype(float).mean(axis=-1)
    m = BOARD.square
    # The centres of a black and a white square next to the first inner corner, seen through the camera.
    black, white = (m * np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0]]))[
        np.argsort(BOARD.reflectance(np.array([-0.5 * m, 0.5 * m]), np.array([-0.5 * m, -0.5 * m])))
    ]
    u, v = np.round(camera.project(pose.to_camera(BOARD, np.array([black, white])))).astype(int).T
    assert image[v[0], u[0]] < 80 and image[v[1], u[1]] > image[v[0], u[0]] + 50
    theta, _ = angles_from_directions(camera.pixel_directions())
    outside = theta > FOV / 2 + 3 / camera.fx  # a few pixels beyond the light circle
    assert outside.any() and image[outside].max() < 20
    assert np.median(image[theta < np.radians(30.0)]) > 150  # the bright sky at the zenith
    np.testing.assert_array_equal(renderer.render(pose, 0), renderer.render(pose, 0))  # seeded


def test_calibration_poses_cover_the_circle_with_the_board_facing_the_lens(camera):
    poses = calibration_poses(camera, BOARD, 14, seed=2, lens_fov=FOV)
    centres = np.array([pose.centre for pose in poses])
    theta, phi = angles_from_directions(centres)
    assert theta.min() < np.radians(5) and theta.max() > np.radians(75)
    assert len(set((np.degrees(phi[theta > np.radians(20)]) // 90).astype(int))) == 4  # every quadrant
    distance = np.linalg.norm(centres, axis=-1)
    assert np.all((distance >= HOLDING_DISTANCE[0]) & (distance <= HOLDING_DISTANCE[1]))
    for pose in poses:
        facing = -pose.rotation[:, 2] @ (pose.centre / np.linalg.norm(pose.centre))  # printed face towards the lens
        assert facing >= np.cos(HOLDING_TILT) - 1e-9
        corners, _ = angles_from_directions(pose.to_camera(BOARD, BOARD.outline()))
        assert corners.max() < FOV / 2  # the whole sheet is seen
    with pytest.raises(SimError, match='smaller board'):
        calibration_poses(camera, BOARD, 1, seed=0, lens_fov=np.radians(40.0))  # a lens that cannot see it whole
