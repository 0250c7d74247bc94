# SPDX-License-Identifier: Apache-2.0
"""Fish-eye calibration on synthetic checkerboard views rendered through a known 200-degree camera (skynav_sim)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from skynav_core.calibration import (
    FIT_FLAGS,
    MIN_VIEWS,
    OPENCV_THETA_LIMIT,
    Board,
    CalibrationError,
    ImageCircle,
    View,
    calibrate,
    coverage,
    find_corners,
    find_image_circle,
    grey_for_detection,
    guess_camera,
    plot_calibration,
)
from skynav_core.camera import EquidistantCamera, angles_from_directions
from skynav_sim.checkerboard import BoardRenderer, Checkerboard, calibration_poses, synthetic_fisheye

FOV = np.radians(200.0)  # the synthetic lens's full field of view
BOARD = Board(9, 6, 0.025)
VIEWS = 14  # the fewest views that met the targets on every seed tried (docs/cameras.md)
# The targets (issue 28): focal lengths within 1 %, principal point within 1.5 px, projected radius within
# 1.5 px for every polar angle up to 85 degrees.
FOCAL_TOLERANCE = 0.01
PRINCIPAL_POINT_TOLERANCE_PX = 1.5
RADIUS_TOLERANCE_PX = 1.5
RADIUS_UP_TO = np.radians(85.0)


def radius_error(camera: EquidistantCamera, truth: EquidistantCamera) -> float:
    """Return the largest difference (px) of the projected radius r(theta) along u and v, theta up to 85 degrees."""
    theta = np.linspace(0.0, RADIUS_UP_TO, 500)
    along_u = np.abs(camera.fx * camera.distort(theta) - truth.fx * truth.distort(theta))
    along_v = np.abs(camera.fy * camera.distort(theta) - truth.fy * truth.distort(theta))
    return float(max(along_u.max(), along_v.max()))


def assert_meets_the_targets(camera: EquidistantCamera, truth: EquidistantCamera) -> None:
    """Assert the issue's calibration targets for a fitted camera against the true one."""
    assert abs(camera.fx / truth.fx - 1) < FOCAL_TOLERANCE
    assert abs(camera.fy / truth.fy - 1) < FOCAL_TOLERANCE
    assert abs(camera.cx - truth.cx) < PRINCIPAL_POINT_TOLERANCE_PX
    assert abs(camera.cy - truth.cy) < PRINCIPAL_POINT_TOLERANCE_PX
    assert radius_error(camera, truth) < RADIUS_TOLERANCE_PX


@pytest.fixture(scope='module')
def rendered():
    """Synthetic views of a 9x6 board held all over a 200-degree lens's circle, their grey images and poses."""
    truth = synthetic_fisheye(640, 480, FOV)
    assert all(k != 0 for k in truth.k)
    board = Checkerboard(BOARD.cols, BOARD.rows, BOARD.square)
    renderer = BoardRenderer(truth, board, FOV, seed=3)
    poses = calibration_poses(truth, board, VIEWS, seed=3, lens_fov=FOV)
    greys = [grey_for_detection(renderer.render(pose, i), linear=False) for i, pose in enumerate(poses)]
    return truth, renderer, poses, greys


@pytest.fixture(scope='module')
def detected(rendered):
    """The views with the corners the detector found."""
    _, _, _, greys = rendered
    return [View(f'synthetic_{i:02d}', find_corners(grey, BOARD)) for i, grey in enumerate(greys)]


@pytest.fixture(scope='module')
def calibrated(rendered, detected):
    """The calibration of every detected view, from the image circle found in them."""
    _, _, _, greys = rendered
    circle = find_image_circle(np.max(greys, axis=0))
    return calibrate(_copies(detected), BOARD, (640, 480), circle)


def _copies(views: list[View]) -> list[View]:
    """Return fresh copies of views (name, corners, reason), so a test's changes stay its own."""
    return [View(v.name, None if v.corners is None else v.corners.copy(), v.reason) for v in views]


def test_the_detector_finds_every_board_within_a_fraction_of_a_pixel(rendered, detected):
    truth, renderer, poses, _ = rendered
    assert all(view.corners is not None for view in detected)
    errors = []
    for view, pose in zip(detected, poses):
        true = renderer.true_corners(pose)
        # The detector may number the corners from another end of the board: match each to the nearest true one.
        nearest = np.linalg.norm(view.corners[:, None] - true[None], axis=-1).min(axis=1)
        errors.append(nearest)
    errors = np.concatenate(errors)
    assert np.sqrt(np.mean(errors**2)) < 0.2 and errors.max() < 0.6
    theta, _ = angles_from_directions(
        np.concatenate([p.to_camera(renderer.board, renderer.board.corners()) for p in poses])
    )
    assert np.degrees(theta.max()) > 90  # the views reach past the horizon, where OpenCV's model stops


def test_calibration_on_a_200_degree_lens_meets_the_targets(rendered, calibrated):
    truth = rendered[0]
    camera = calibrated.camera
    assert_meets_the_targets(camera, truth)
    assert len(calibrated.used) == VIEWS and not calibrated.refused
    assert calibrated.rms < 0.3  # px: corners good to a fraction of a pixel fit to a fraction of a pixel


def test_the_image_circle_is_found_in_the_views(rendered):
    truth, _, _, greys = rendered
    circle = find_image_circle(np.max(greys, axis=0))
    lens_radius = truth.fx * float(truth.distort(np.array(FOV / 2)))  # the light circle of the lens (fx ~ fy)
    assert circle.fitted
    assert abs(circle.cx - truth.cx) < 0.5 and abs(circle.cy - truth.cy) < 0.5
    assert abs(circle.radius - lens_radius) < 1.5


def test_a_circle_cut_by_the_frame_is_fitted_to_the_edge_inside_it():
    views = np.zeros((480, 640), np.uint8)
    # A disc of radius 260 px about (321.25, 238.5) (drawn at 1/16 px): the frame cuts off its top and bottom.
    cv2.circle(views, (round(321.25 * 16), round(238.5 * 16)), 260 * 16, 180, -1, cv2.LINE_AA, shift=4)
    circle = find_image_circle(views)
    assert circle.fitted
    assert circle.cx == pytest.approx(321.25, abs=0.3) and circle.cy == pytest.approx(238.5, abs=0.3)
    assert circle.radius == pytest.approx(260, abs=0.7)


def test_a_frame_filling_disc_falls_back_to_the_frame():
    bright = np.full((48, 64), 200, np.uint8)
    circle = find_image_circle(bright)
    assert not circle.fitted and (circle.cx, circle.cy) == (31.5, 23.5)
    assert circle.radius == pytest.approx(np.hypot(63, 47) / 2)


def test_without_the_circle_guess_opencv_fails_on_the_200_degree_lens(rendered, detected):
    truth = rendered[0]
    objects, images = [], []
    for view in detected:
        below = angles_from_directions(truth.unproject(view.corners))[0] < OPENCV_THETA_LIMIT  # even told the truth
        objects.append(BOARD.object_points()[below][None])
        images.append(view.corners[below][None])
    size = (truth.width, truth.height)
    plain_flags = FIT_FLAGS & ~cv2.fisheye.CALIB_USE_INTRINSIC_GUESS  # OpenCV's own start
    try:
        _, k, _, _, _ = cv2.fisheye.calibrate(objects, images, size, np.eye(3), np.zeros(4), flags=plain_flags)
        failed = abs(k[0, 0] / truth.fx - 1) > 0.1 or abs(k[0, 2] - truth.cx) > 10
    except cv2.error:
        failed = True
    assert failed
    # The same corners, the same fit, from the image circle's guess of a 200-degree lens: within the targets.
    guess = guess_camera(ImageCircle(truth.cx + 2, truth.cy - 2, 226.0), *size, FOV)
    k = np.array([[guess.fx, 0, guess.cx], [0, guess.fy, guess.cy], [0, 0, 1]])
    _, k, d, _, _ = cv2.fisheye.calibrate(objects, images, size, k, np.zeros(4), flags=FIT_FLAGS)
    fitted = EquidistantCamera(*size, k[0, 0], k[1, 1], k[0, 2], k[1, 2], tuple(np.ravel(d)))
    assert_meets_the_targets(fitted, truth)


def test_a_view_with_misplaced_corners_is_refused_as_an_outlier(rendered, detected):
    truth, _, _, greys = rendered
    views = _copies(detected)
    views[4].corners[10:16] += 2.5  # six corners mis-detected by 2.5 px each way
    result = calibrate(views, BOARD, (640, 480), find_image_circle(np.max(greys, axis=0)), fov=FOV)
    assert [view.name for view in result.refused] == ['synthetic_04']  # every other view is used
    assert 'reprojection error' in result.refused[0].reason and 'median' in result.refused[0].reason
    assert_meets_the_targets(result.camera, truth)


def test_views_without_the_board_are_refused_and_too_few_views_raise(rendered, detected):
    _, _, _, greys = rendered
    circle = find_image_circle(np.max(greys, axis=0))
    views = _copies(detected[: MIN_VIEWS - 1]) + [View('empty', None, 'board not found')]
    with pytest.raises(CalibrationError, match=f'too few views: {MIN_VIEWS - 1} usable of {MIN_VIEWS}') as refused:
        calibrate(views, BOARD, (640, 480), circle)
    assert '\n' not in str(refused.value)
    assert find_corners(np.full((120, 160), 128, np.uint8), BOARD) is None


def test_coverage_counts_the_cells_of_the_circle_holding_a_corner(calibrated):
    camera, circle = calibrated.camera, calibrated.circle
    # One corner at the centre, one half way out to the right, one near the rim below: three cells.
    corners = np.array(
        [
            [circle.cx + 1, circle.cy + 1],
            [circle.cx + 0.5 * circle.radius, circle.cy + 2],
            [circle.cx + 3, circle.cy + 0.95 * circle.radius],
        ]
    )
    few = coverage(camera, circle, [View('a', corners)])
    assert few.cells_filled == 3 and few.cells_total == 60  # the circle lies inside the frame: every cell counts
    assert np.degrees(few.max_off_axis) == pytest.approx(
        np.degrees(angles_from_directions(camera.unproject(corners[2]))[0]), abs=1e-6
    )
    # The corners cover most of the circle and reach past the 85 degrees up to which the radius is checked.
    assert calibrated.coverage.share > 0.6 and np.degrees(calibrated.coverage.max_off_axis) > 85


def test_linear_views_are_brought_to_an_srgb_like_curve_for_the_detector():
    linear = np.tile(np.linspace(0, 4000, 1000, dtype=np.uint16), (10, 1))  # a dark 16-bit linear view
    grey = grey_for_detection(linear, linear=True)
    assert grey.dtype == np.uint8 and grey.max() == 255
    assert np.all(np.diff(grey[0].astype(int)) >= 0)
    assert 110 < grey[0, 180] < 125  # 18 % of white (the 99.5th percentile) is mid-grey (sRGB 118)
    rgb = np.dstack([linear, linear, linear])
    np.testing.assert_array_equal(grey_for_detection(rgb, linear=True), grey)
    srgb = np.full((4, 4, 3), (200, 100, 50), np.uint8)  # 8-bit sRGB is taken as it is
    assert grey_for_detection(srgb, linear=False)[0, 0] == round(0.299 * 200 + 0.587 * 100 + 0.114 * 50)


def test_the_board_argument_is_checked():
    assert Board.parse('9x6', 0.025) == Board(9, 6, 0.025)
    assert np.array_equal(Board(3, 3, 0.1).object_points()[[0, 1, 3]], [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]])
    for text, square in (('9-6', 0.025), ('2x6', 0.025), ('9x6', 0.0), ('9x6', float('nan'))):
        with pytest.raises(ValueError):
            Board.parse(text, square)


def test_the_plot_is_written(calibrated, rendered, tmp_path):
    path = plot_calibration(calibrated, np.max(rendered[3], axis=0), tmp_path / 'plot.png')
    image = cv2.imread(str(path))
    assert image is not None and image.shape[1] > 1000 and image.std() > 10
