# SPDX-License-Identifier: Apache-2.0
"""Fish-eye calibration from checkerboard views: corners, the image circle, the fisheye fit, coverage, a plot.

The steps (`skynav calibrate` runs them):

1. Corners: OpenCV's sector-based detector (`cv2.findChessboardCornersSB`) on 8-bit grey views (linear input is
   brought to an sRGB-like curve first, so a dark board in front of a bright sky is found), refined by
   `cv2.cornerSubPix`.
2. The image circle: the bright disc of the views themselves (black outside it), from the per-pixel maximum of
   every view; a circle fitted to its edge where the edge lies inside the frame.
3. A first guess from the circle: principal point at its centre, focal length from its radius for an equidistant
   lens of a given field of view (r = f theta). OpenCV's fisheye fit needs it on wide lenses: from its own start
   (f = max(width, height) / pi at the image's centre) it lands far off on a 200-degree lens.
4. `cv2.fisheye.calibrate` from that guess. OpenCV's fisheye model takes theta = atan(r) of x/z, so it cannot see
   points at or behind 90 degrees off-axis; the contract's model (docs/interfaces.md, theta = atan2, valid past 90
   degrees) has the same K and D meaning below 90 degrees. The fit therefore takes each view's corners below
   OPENCV_THETA_LIMIT, widening to it in OPENCV_STEPS. Each view's error is then measured in the contract's model.
5. Views whose own reprojection error is an outlier among the views are refused (and the fit repeated).

Plain numpy, scipy and OpenCV; no rclpy. Pixels are (u, v), px, with integer values at pixel centres; angles in rad
unless a name says deg.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from .camera import EquidistantCamera, angles_from_directions
from .colour import linear_to_srgb8
from .errors import SkynavError

# Detector flags: EXHAUSTIVE tries every candidate quad (boards at the rim are small and sheared). Measured on 21
# synthetic 200-degree views (640x480): without it 5 boards of 21 were found, with it all 21. ACCURACY (corners
# refined on an upsampled view) found no more and, once cornerSubPix refines the corners, gave the same accuracy
# (radius error up to 85 degrees 0.05-0.29 px either way, 4 seeds) at 2.5 times the time (0.3 s a view, not 0.12 s).
DETECTOR_FLAGS = cv2.CALIB_CB_EXHAUSTIVE
# A view of at most this size (px, longer side) in which the detector misses the board is searched again enlarged
# UPSCALE times (measured: a board of 6-px squares at 69 degrees off-axis is found so, and missed otherwise).
UPSCALE_MAX_SIDE_PX = 1280
UPSCALE = 2
# cornerSubPix after the detector, in a window of half the corner spacing (at least 3, at most 12 px each side).
# Measured on synthetic 200-degree views (640x480, 9x6 board, 21 views, 3 seeds): the detector's own corners left
# 0.30-0.75 px of radius error up to 85 degrees, refined ones 0.04-0.08 px (see docs/cameras.md).
SUBPIX_HALF_WINDOW_PX = (3, 12)
SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 50, 1e-4)
# OpenCV's fisheye fit: start from the image circle's guess, fix skew (the contract has none).
FIT_FLAGS = cv2.fisheye.CALIB_USE_INTRINSIC_GUESS | cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
FIT_CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-8)
# Corners OpenCV's fit takes: polar angle below this (rad); near 90 degrees its x/z blows up.
OPENCV_THETA_LIMIT = np.radians(85.0)
# The fit widens in steps to OPENCV_THETA_LIMIT, each from the last one's camera, freeing the distortion terms the
# wider field determines: (polar angle limit in rad, flags added). Started at the rim from a rough guess, OpenCV's
# fit fails or lands far off for most guesses (measured on synthetic views: 4 of 7 guesses from 140 to 260 degrees).
OPENCV_STEPS = (
    (np.radians(60.0), cv2.fisheye.CALIB_FIX_K3 | cv2.fisheye.CALIB_FIX_K4),
    (np.radians(75.0), cv2.fisheye.CALIB_FIX_K4),
    (OPENCV_THETA_LIMIT, 0),
)
# A view takes part in OpenCV's fit with this many corners below its limit, in as many rows and columns of the
# board each (its pose needs points spread over the board, not along a line).
MIN_CORNERS_FOR_OPENCV = 9
MIN_LINES_FOR_OPENCV = 3
# A narrower step of the fit (its distortion terms in part fixed) takes place with this many views, else it is
# left out and the next, wider step starts from the camera so far.
MIN_VIEWS_EARLY_STEP = 3
# Full fields of view (deg) tried for the first guess when none is given; the fit with the least RMS is kept.
DEFAULT_FOV_CANDIDATES_DEG = (180.0, 200.0, 220.0)
# Fewer views showing the board than this cannot determine the eight intrinsics and each view's pose well.
MIN_VIEWS = 5
# A view is an outlier when its RMS reprojection error exceeds OUTLIER_FACTOR times the views' median and
# OUTLIER_FLOOR_PX (px): a mis-detected corner or a board bent while it was held.
OUTLIER_FACTOR = 3.0
OUTLIER_FLOOR_PX = 0.75
# Rounds of refusing outliers and fitting again.
OUTLIER_ROUNDS = 3
# Coverage cells of the image circle: rings of equal width from the centre to the rim, sectors of equal azimuth.
COVERAGE_RINGS = 5
COVERAGE_SECTORS = 12
# Image circle: a pixel belongs to the disc when its brightest value over the views exceeds the dark level (the
# frame outside the circle) by this share of the way to the disc's typical level.
CIRCLE_LEVEL = 0.12
# Edge points of the disc closer than this (px) to the frame's border belong to the frame, not the circle.
CIRCLE_BORDER_PX = 2.0
# Edge points farther than this (px) from the fitted circle are left out and the circle fitted again.
CIRCLE_OUTLIER_PX = 2.0
# Share of the image circle's edge that must lie inside the frame for the circle to be fitted from it.
CIRCLE_MIN_EDGE_SHARE = 0.15
# The image extensions a folder of views is read for.
IMAGE_SUFFIXES = ('.png', '.jpg', '.jpeg', '.bmp', '.tif', '.tiff', '.pgm', '.ppm', '.webp')
# Percentile of a linear view's brightness that becomes white before the sRGB-like curve (the bright sky).
LINEAR_WHITE_PERCENTILE = 99.5


class CalibrationError(SkynavError):
    """A calibration that cannot be made (too few views showing the board, no usable fit); one line."""


@dataclass(frozen=True)
class Board:
    """A checkerboard: `cols` x `rows` inner corners, squares of `square` m."""

    cols: int
    rows: int
    square: float

    @classmethod
    def parse(cls, text: str, square: float) -> Board:
        """Return the board of a COLSxROWS text (inner corners) and a square size (m); ValueError if malformed."""
        match = re.fullmatch(r'\s*(\d+)\s*[xX]\s*(\d+)\s*', text)
        if match is None:
            raise ValueError(f'--board must be COLSxROWS inner corners such as 9x6, not {text!r}')
        cols, rows = int(match.group(1)), int(match.group(2))
        if cols < 3 or rows < 3:
            raise ValueError(f'a board of {cols}x{rows} inner corners is too small; at least 3x3')
        if not (np.isfinite(square) and square > 0):
            raise ValueError(f'--square must be a positive size in metres, not {square}')
        return cls(cols, rows, float(square))

    def object_points(self) -> np.ndarray:
        """Return the inner corners (cols * rows, 3) in the board frame (m), row by row as the detector orders them."""
        x, y = np.meshgrid(np.arange(self.cols) * self.square, np.arange(self.rows) * self.square)
        return np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=-1)


# ---------------------------------------------------------------------------------------------------------------------
# Views: grey images for the detector, corners


def grey_for_detection(pixels: np.ndarray, linear: bool, order: str = 'rgb') -> np.ndarray:
    """Return an 8-bit grey view (H, W) for the corner detector from grey (H, W) or colour (H, W, 3|4) pixels.

    8-bit values that are not `linear` are taken as they are (sRGB-encoded, as cameras and image files give
    them). Linear values (16-bit colour, float, or `linear` 8-bit) are scaled so LINEAR_WHITE_PERCENTILE of the
    view is white, then sRGB-encoded, so a dark board keeps its contrast. `order` names colour channels.
    """
    image = np.asarray(pixels)
    if image.ndim == 3:
        channels = image.shape[2]
        if channels not in (3, 4):
            raise ValueError(f'a view with {channels} channels is neither grey nor colour')
        code = {'rgb': cv2.COLOR_RGB2GRAY, 'bgr': cv2.COLOR_BGR2GRAY}[order]
        if channels == 4:
            image = image[..., :3]
        image = cv2.cvtColor(
            np.ascontiguousarray(image if image.dtype != np.float64 else image.astype(np.float32)), code
        )
    elif image.ndim != 2:
        raise ValueError(f'a view of shape {image.shape} is not an image')
    if image.dtype == np.uint8 and not linear:
        return image
    values = image.astype(np.float32)
    white = float(np.percentile(values, LINEAR_WHITE_PERCENTILE))
    if not white > 0:
        return np.zeros(values.shape, np.uint8)
    return linear_to_srgb8(values / white)


def find_corners(grey: np.ndarray, board: Board, flags: int = DETECTOR_FLAGS) -> np.ndarray | None:
    """Return the board's inner corners (cols * rows, 2) in pixels (u, v) of an 8-bit grey view, None if not found.

    The sector-based detector finds them, on the view twice enlarged when it misses a board in a view of at most
    UPSCALE_MAX_SIDE_PX (squares of a few pixels); cv2.cornerSubPix refines them on the view itself.
    """
    found, corners = cv2.findChessboardCornersSB(grey, (board.cols, board.rows), flags=flags)
    if not found and max(grey.shape) <= UPSCALE_MAX_SIDE_PX:
        larger = cv2.resize(grey, None, fx=UPSCALE, fy=UPSCALE, interpolation=cv2.INTER_LINEAR)
        found, corners = cv2.findChessboardCornersSB(larger, (board.cols, board.rows), flags=flags)
        if found and corners is not None:
            corners = (corners + 0.5) / UPSCALE - 0.5  # pixel centres of the enlarged view -> of the view
    if not found or corners is None or len(corners) != board.cols * board.rows:
        return None
    return refine_corners(grey, corners.reshape(-1, 2).astype(float), board)


def corner_spacing(corners: np.ndarray, board: Board) -> np.ndarray:
    """Return each corner's distance (px) to its nearest neighbour along the board's rows and columns, (N,)."""
    grid = corners.reshape(board.rows, board.cols, 2)
    along = np.linalg.norm(np.diff(grid, axis=1), axis=-1)  # (rows, cols - 1)
    across = np.linalg.norm(np.diff(grid, axis=0), axis=-1)  # (rows - 1, cols)
    nearest = np.full((board.rows, board.cols), np.inf)
    for distances, left, right in (
        (along, np.s_[:, :-1], np.s_[:, 1:]),
        (across, np.s_[:-1, :], np.s_[1:, :]),
    ):
        nearest[left] = np.minimum(nearest[left], distances)
        nearest[right] = np.minimum(nearest[right], distances)
    return nearest.ravel()


def refine_corners(grey: np.ndarray, corners: np.ndarray, board: Board) -> np.ndarray:
    """Return corners (N, 2) refined by cv2.cornerSubPix, each in a window half its spacing to its neighbours wide."""
    low, high = SUBPIX_HALF_WINDOW_PX
    half = np.clip(np.floor(corner_spacing(corners, board) / 2), low, high).astype(int)
    refined = corners.astype(np.float32)
    for size in np.unique(half):
        chosen = half == size
        refined[chosen] = cv2.cornerSubPix(
            grey, refined[chosen].reshape(-1, 1, 2), (int(size), int(size)), (-1, -1), SUBPIX_CRITERIA
        ).reshape(-1, 2)
    return refined.astype(float)


# ---------------------------------------------------------------------------------------------------------------------
# The image circle


@dataclass(frozen=True)
class ImageCircle:
    """The bright disc a fish-eye lens throws on the sensor: centre (cx, cy) and radius, px; `fitted` False when
    the disc fills the frame and the centre and radius are the frame's (centre, half-diagonal)."""

    cx: float
    cy: float
    radius: float
    fitted: bool = True


def find_image_circle(brightest: np.ndarray) -> ImageCircle:
    """Return the image circle of the per-pixel brightest values (H, W) over the views (any dtype, grey).

    The disc is the largest bright region; the circle is fitted (least squares, then again without points more
    than CIRCLE_OUTLIER_PX off) to its edge where the edge lies inside the frame. A disc that fills the frame
    gives the frame's centre and half-diagonal instead.
    """
    image = np.asarray(brightest, np.float32)
    height, width = image.shape
    dark = float(np.percentile(image, 1.0))
    bright = float(np.median(image[image > dark + 0.1 * (image.max() - dark)])) if image.max() > dark else dark
    disc = (image > dark + CIRCLE_LEVEL * (bright - dark)).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(disc, connectivity=8)
    frame = ImageCircle((width - 1) / 2, (height - 1) / 2, float(np.hypot(width - 1, height - 1) / 2), fitted=False)
    if count < 2:
        return frame
    largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    filled = (labels == largest).astype(np.uint8)
    filled = cv2.morphologyEx(filled, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    contours, _ = cv2.findContours(filled, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    edge = max(contours, key=len).reshape(-1, 2).astype(float)
    inside = (
        (edge[:, 0] > CIRCLE_BORDER_PX)
        & (edge[:, 1] > CIRCLE_BORDER_PX)
        & (edge[:, 0] < width - 1 - CIRCLE_BORDER_PX)
        & (edge[:, 1] < height - 1 - CIRCLE_BORDER_PX)
    )
    if inside.mean() < CIRCLE_MIN_EDGE_SHARE or inside.sum() < 20:
        return frame
    points = edge[inside]
    keep = np.ones(len(points), bool)
    for _ in range(3):
        cx, cy, radius = _fit_circle(points[keep])
        keep = np.abs(np.hypot(points[:, 0] - cx, points[:, 1] - cy) - radius) < CIRCLE_OUTLIER_PX
    # The contour runs through the centres of the outermost pixels brighter than the level, which the edge crosses.
    return ImageCircle(cx, cy, radius)


def _fit_circle(points: np.ndarray) -> tuple[float, float, float]:
    """Return (cx, cy, radius) of the least-squares circle through points (N, 2) (Kasa's algebraic fit)."""
    x, y = points[:, 0], points[:, 1]
    design = np.stack([x, y, np.ones_like(x)], axis=-1)
    (a, b, c), *_ = np.linalg.lstsq(design, x * x + y * y, rcond=None)
    cx, cy = a / 2, b / 2
    return float(cx), float(cy), float(np.sqrt(c + cx * cx + cy * cy))


def guess_camera(circle: ImageCircle, width: int, height: int, fov: float) -> EquidistantCamera:
    """Return the first guess: principal point at the circle's centre, f = radius / (fov / 2) (equidistant, k = 0)."""
    f = circle.radius / (fov / 2)
    return EquidistantCamera(width, height, f, f, circle.cx, circle.cy)


# ---------------------------------------------------------------------------------------------------------------------
# The fit


@dataclass
class View:
    """One view offered to the calibration: its name, and its corners (N, 2) px if the board was found."""

    name: str
    corners: np.ndarray | None = None
    reason: str = ''  # why the view was refused ('' while it is used)
    rms: float = float('nan')  # px, the view's own reprojection error in the final fit
    rotation: np.ndarray = field(default_factory=lambda: np.zeros(3))  # board -> camera_link, Rodrigues vector
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))  # board origin in camera_link, m

    @property
    def used(self) -> bool:
        """Return whether the view takes part in the fit."""
        return self.corners is not None and not self.reason


@dataclass(frozen=True)
class Coverage:
    """How much of the image circle the used corners cover: cells of COVERAGE_RINGS rings x COVERAGE_SECTORS sectors."""

    filled: np.ndarray  # (rings, sectors) bool: the cell holds a corner
    in_frame: np.ndarray  # (rings, sectors) bool: the cell's centre lies inside the frame (only those count)
    max_off_axis: float  # rad, the largest polar angle a corner reached (by the fitted camera)

    @property
    def cells_filled(self) -> int:
        """Return the number of counted cells holding a corner."""
        return int((self.filled & self.in_frame).sum())

    @property
    def cells_total(self) -> int:
        """Return the number of counted cells (those inside the frame)."""
        return int(self.in_frame.sum())

    @property
    def share(self) -> float:
        """Return the share of the circle's cells holding a corner (0..1)."""
        return self.cells_filled / self.cells_total if self.cells_total else 0.0


@dataclass
class Calibration:
    """The result: the camera, the views (used and refused), the RMS error, the circle and the coverage."""

    camera: EquidistantCamera
    views: list[View]
    rms: float  # px, over every used corner
    circle: ImageCircle
    coverage: Coverage
    fov_guess: float  # rad, the field of view of the first guess that gave this fit
    corners_used: int

    @property
    def used(self) -> list[View]:
        """Return the views that took part in the fit."""
        return [v for v in self.views if v.used]

    @property
    def refused(self) -> list[View]:
        """Return the views that were refused, each with its reason."""
        return [v for v in self.views if not v.used]


def project(camera: EquidistantCamera, points: np.ndarray, rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """Return the pixels (N, 2) of board points (N, 3) at a pose (Rodrigues vector, m) in the contract's model."""
    matrix = cv2.Rodrigues(np.asarray(rotation, float))[0]
    return camera.project(points @ matrix.T + translation)


def _polar_angles(camera: EquidistantCamera, corners: np.ndarray) -> np.ndarray:
    """Return the polar angle (rad) of each pixel (N, 2) by a camera model."""
    return angles_from_directions(camera.unproject(corners))[0]


Pose = tuple[np.ndarray, np.ndarray]  # a board's pose: Rodrigues vector (board -> camera_link) and translation (m)


@dataclass(frozen=True)
class _Selection:
    """The corners one step of OpenCV's fit takes: per view taken, its board points and pixels; `taken` indexes."""

    objects: list[np.ndarray]  # (1, N, 3) float64 board points, m
    images: list[np.ndarray]  # (1, N, 2) float64 pixels
    taken: list[int]  # index of each view taken in the list the selection was made from


def _select(camera: EquidistantCamera, views: list[View], board: Board, limit: float) -> _Selection:
    """Return each view's corners below polar angle `limit` (rad, by `camera`) for OpenCV's fit.

    A view stays out unless such corners are MIN_CORNERS_FOR_OPENCV or more and span MIN_LINES_FOR_OPENCV rows and
    columns of the board.
    """
    selection = _Selection([], [], [])
    points = board.object_points()
    for index, view in enumerate(views):
        assert view.corners is not None
        below = _polar_angles(camera, view.corners) < limit
        rows, cols = np.divmod(np.flatnonzero(below), board.cols)
        if below.sum() >= MIN_CORNERS_FOR_OPENCV and min(len(set(rows)), len(set(cols))) >= MIN_LINES_FOR_OPENCV:
            selection.objects.append(points[below].reshape(1, -1, 3).astype(np.float64))
            selection.images.append(view.corners[below].reshape(1, -1, 2).astype(np.float64))
            selection.taken.append(index)
    return selection


def _fit_opencv(
    camera: EquidistantCamera, selection: _Selection, flags: int
) -> tuple[EquidistantCamera, dict[int, Pose]]:
    """Return OpenCV's fisheye fit of the selected corners from `camera`, and the pose of each view taken (by index).

    CalibrationError if OpenCV fails.
    """
    k = np.array([[camera.fx, 0, camera.cx], [0, camera.fy, camera.cy], [0, 0, 1]], float)
    d = np.array(camera.k, float).reshape(4, 1)
    try:
        _, k, d, rotations, translations = cv2.fisheye.calibrate(
            selection.objects, selection.images, (camera.width, camera.height), k, d, flags=flags, criteria=FIT_CRITERIA
        )
    except cv2.error as exc:
        message = ' '.join(str(exc).split())
        raise CalibrationError(f"OpenCV's fisheye fit failed: {message[message.find(')') + 1 :].strip()}") from None
    k1, k2, k3, k4 = (float(x) for x in np.ravel(d))
    fx, fy, cx, cy = (float(x) for x in (k[0, 0], k[1, 1], k[0, 2], k[1, 2]))
    fitted = EquidistantCamera(camera.width, camera.height, fx, fy, cx, cy, (k1, k2, k3, k4))
    poses = {index: (np.ravel(r), np.ravel(t)) for index, r, t in zip(selection.taken, rotations, translations)}
    return fitted, poses


def _fit_widening(
    guess: EquidistantCamera, views: list[View], board: Board
) -> tuple[EquidistantCamera, dict[int, Pose]]:
    """Return OpenCV's fit widened over OPENCV_STEPS from `guess`, and the last step's poses of the views (by index).

    An early step with fewer than MIN_VIEWS_EARLY_STEP views is left out; the last needs MIN_VIEWS views.
    """
    camera = guess
    poses: dict[int, Pose] = {}
    for step, (limit, flags) in enumerate(OPENCV_STEPS):
        selection = _select(camera, views, board, limit)
        if step < len(OPENCV_STEPS) - 1 and len(selection.taken) < MIN_VIEWS_EARLY_STEP:
            continue
        if step == len(OPENCV_STEPS) - 1 and len(selection.taken) < MIN_VIEWS:
            raise CalibrationError(
                f'only {len(selection.taken)} views hold {MIN_CORNERS_FOR_OPENCV} corners within '
                f'{np.degrees(limit):.0f} degrees of the axis; at least {MIN_VIEWS} are needed'
            )
        camera, poses = _fit_opencv(camera, selection, FIT_FLAGS | flags)
    return camera, poses


def _view_errors(camera: EquidistantCamera, view: View, board: Board) -> np.ndarray:
    """Return the reprojection distances (N,) px of a view's corners at its fitted pose in the contract's model."""
    assert view.corners is not None
    projected = project(camera, board.object_points(), view.rotation, view.translation)
    return np.linalg.norm(projected - view.corners, axis=-1)


def _fit(guess: EquidistantCamera, views: list[View], board: Board) -> EquidistantCamera:
    """Fit the camera from `guess` over the used views, refusing outliers; the views keep their pose and RMS.

    Each round widens OpenCV's fit over OPENCV_THETA_STEPS from the guess, then refuses the views whose own RMS
    error is an outlier, until none is (at most OUTLIER_ROUNDS times).
    """
    for round_ in range(OUTLIER_ROUNDS + 1):
        active = [view for view in views if view.used]
        _require_views(active, views, board)
        camera, poses = _fit_widening(guess, active, board)
        for index, view in enumerate(active):
            if index not in poses:  # not in the last step's fit
                view.reason = (
                    f'fewer than {MIN_CORNERS_FOR_OPENCV} corners within {np.degrees(OPENCV_THETA_LIMIT):.0f} '
                    'degrees of the axis; hold the board a little nearer it'
                )
                continue
            view.rotation, view.translation = poses[index]
            view.rms = float(np.sqrt(np.mean(np.square(_view_errors(camera, view, board)))))
        fitted = [view for view in active if view.used]
        median = float(np.median([view.rms for view in fitted]))
        limit = max(OUTLIER_FACTOR * median, OUTLIER_FLOOR_PX)
        outliers = [view for view in fitted if view.rms > limit]
        if not outliers or round_ == OUTLIER_ROUNDS:
            _require_views(fitted, views, board)
            return camera
        for view in outliers:
            view.reason = (
                f'reprojection error {view.rms:.2f} px, over {limit:.2f} px '
                f'(the larger of {OUTLIER_FACTOR:g} x the median view, {median:.2f} px, and {OUTLIER_FLOOR_PX:g} px)'
            )
    raise AssertionError('unreachable')


def _require_views(used: Sequence[View], views: Sequence[View], board: Board) -> None:
    """Raise CalibrationError when fewer than MIN_VIEWS views are left to fit."""
    if len(used) < MIN_VIEWS:
        shown = sum(view.corners is not None for view in views)
        raise CalibrationError(
            f'too few views: {len(used)} usable of {len(views)} ({shown} show the {board.cols}x{board.rows} board); '
            f'at least {MIN_VIEWS} are needed, with the board across the whole image circle'
        )


def coverage(camera: EquidistantCamera, circle: ImageCircle, views: Iterable[View]) -> Coverage:
    """Return how much of the image circle the corners of the used views cover (cells of rings x sectors)."""
    used = [view.corners for view in views if view.used and view.corners is not None]
    corners = np.concatenate(used) if used else np.zeros((0, 2))
    offset = corners - [circle.cx, circle.cy]
    ring = (np.hypot(offset[:, 0], offset[:, 1]) / circle.radius * COVERAGE_RINGS).astype(int)
    sector = ((np.arctan2(offset[:, 1], offset[:, 0]) % (2 * np.pi)) / (2 * np.pi) * COVERAGE_SECTORS).astype(int)
    filled = np.zeros((COVERAGE_RINGS, COVERAGE_SECTORS), bool)
    inside = ring < COVERAGE_RINGS
    filled[ring[inside], np.minimum(sector[inside], COVERAGE_SECTORS - 1)] = True
    middle_radius = (np.arange(COVERAGE_RINGS) + 0.5) / COVERAGE_RINGS * circle.radius
    middle_azimuth = (np.arange(COVERAGE_SECTORS) + 0.5) / COVERAGE_SECTORS * 2 * np.pi
    u = circle.cx + middle_radius[:, None] * np.cos(middle_azimuth)
    v = circle.cy + middle_radius[:, None] * np.sin(middle_azimuth)
    in_frame = (u >= 0) & (u <= camera.width - 1) & (v >= 0) & (v <= camera.height - 1)
    reached = float(_polar_angles(camera, corners).max()) if len(corners) else 0.0
    return Coverage(filled, in_frame, reached)


def calibrate(
    views: list[View],
    board: Board,
    size: tuple[int, int],
    circle: ImageCircle,
    fov: float | None = None,
) -> Calibration:
    """Return the fish-eye calibration of views (names and detected corners) of one camera of `size` (width, height).

    The first guess comes from the image circle with a field of view `fov` (rad, full angle), or each of
    DEFAULT_FOV_CANDIDATES_DEG, keeping the fit with the least RMS. CalibrationError when fewer than MIN_VIEWS
    views show the board or every fit fails.
    """
    width, height = size
    _require_views([view for view in views if view.used], views, board)
    candidates = [fov] if fov is not None else [np.radians(x) for x in DEFAULT_FOV_CANDIDATES_DEG]
    best: Calibration | None = None
    failure: CalibrationError | None = None
    for candidate in candidates:
        trial = [View(v.name, v.corners, v.reason) for v in views]
        try:
            camera = _fit(guess_camera(circle, width, height, candidate), trial, board)
        except CalibrationError as exc:
            failure = exc
            continue
        errors = np.concatenate([_view_errors(camera, view, board) for view in trial if view.used])
        result = Calibration(
            camera,
            trial,
            float(np.sqrt(np.mean(np.square(errors)))),
            circle,
            coverage(camera, circle, trial),
            candidate,
            len(errors),
        )
        if best is None or result.rms < best.rms:
            best = result
    if best is None:
        assert failure is not None
        raise failure
    return best


def circle_field_of_view(calibration: Calibration) -> float:
    """Return the full field of view (rad) the fitted camera gives the image circle's edge."""
    camera, circle = calibration.camera, calibration.circle
    theta_d = circle.radius / np.sqrt(camera.fx * camera.fy)
    return 2 * float(camera.undistort(np.array(theta_d)))


# Polar angles (deg) of the rings the plot draws with the fitted camera.
PLOT_RINGS_DEG = (30, 60, 90)


def plot_calibration(calibration: Calibration, brightest: np.ndarray, path: str | os.PathLike) -> Path:
    """Draw the corners over the image circle (coloured by view) and each view's error into a PNG; return its path."""
    import matplotlib  # noqa: PLC0415 (0.5 s to load: only a plot needs it)

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt  # noqa: PLC0415

    camera, circle = calibration.camera, calibration.circle
    figure, (image_axis, error_axis) = plt.subplots(
        1, 2, figsize=(14, 6.2), gridspec_kw={'width_ratios': [1.25, 1]}, layout='constrained'
    )
    image_axis.imshow(brightest, cmap='gray', vmin=0, vmax=max(float(np.max(brightest)), 1.0) * 2.5)
    colours = plt.get_cmap('tab20')
    for index, view in enumerate(calibration.views):
        if view.corners is None:
            continue
        if view.used:
            colour = colours(index % 20)
            image_axis.scatter(*view.corners.T, s=6, color=colour, linewidths=0)
            image_axis.annotate(str(index), view.corners.mean(axis=0), color=colour, fontsize=8, ha='center')
        else:
            image_axis.scatter(*view.corners.T, s=10, color='0.6', marker='x', linewidths=0.6)
    _shade_empty_cells(image_axis, calibration)
    turn = np.linspace(0, 2 * np.pi, 361)
    image_axis.plot(
        circle.cx + circle.radius * np.cos(turn),
        circle.cy + circle.radius * np.sin(turn),
        '--',
        color='w',
        linewidth=1.2,
        label=f'image circle found in the views ({circle_field_of_view(calibration) / np.pi * 180:.0f} deg)',
    )
    for degrees in PLOT_RINGS_DEG:
        ring = camera.project(
            np.stack(
                [
                    np.sin(np.radians(degrees)) * np.cos(turn),
                    np.sin(np.radians(degrees)) * np.sin(turn),
                    np.full_like(turn, np.cos(np.radians(degrees))),
                ],
                axis=-1,
            )
        )
        image_axis.plot(*ring.T, ':', color='#ffd54f', linewidth=0.9)
        image_axis.annotate(f'{degrees} deg', ring[315], color='#ffd54f', fontsize=8)
    image_axis.plot(camera.cx, camera.cy, '+', color='#ffd54f', markersize=12, label='principal point (zenith)')
    image_axis.plot([], [], ':', color='#ffd54f', label='off-axis angle, fitted camera')
    image_axis.plot([], [], 'x', color='0.6', label='corners of refused views')
    image_axis.fill([], [], color='#e53935', alpha=0.3, label='cells without a corner: add views there')
    image_axis.set_xlim(-0.5, camera.width - 0.5)
    image_axis.set_ylim(camera.height - 0.5, -0.5)
    image_axis.legend(loc='lower left', fontsize=8, framealpha=0.8)
    coverage = calibration.coverage
    image_axis.set_title(
        f'corners of {len(calibration.used)} views (colour and number: view); {coverage.cells_filled} of '
        f'{coverage.cells_total} cells of the circle ({coverage.share:.0%}), up to '
        f'{np.degrees(coverage.max_off_axis):.0f} deg off-axis',
        fontsize=10,
    )
    indices = [index for index, view in enumerate(calibration.views) if view.corners is not None]
    errors = [calibration.views[index].rms for index in indices]
    bar_colours = [colours(i % 20) if calibration.views[i].used else '0.7' for i in indices]
    error_axis.bar(range(len(indices)), np.nan_to_num(errors), color=bar_colours)
    error_axis.set_xticks(range(len(indices)), [str(i) for i in indices], fontsize=7)
    error_axis.axhline(calibration.rms, color='k', linewidth=1, label=f'RMS over all corners: {calibration.rms:.3f} px')
    error_axis.set_xlabel('view (grey: refused)')
    error_axis.set_ylabel('RMS reprojection error of the view (px)')
    error_axis.legend(fontsize=9)
    error_axis.set_title(
        f'fx {camera.fx:.2f}  fy {camera.fy:.2f}  cx {camera.cx:.2f}  cy {camera.cy:.2f} px\n'
        f'k1..k4 {" ".join(f"{k:.4g}" for k in camera.k)}',
        fontsize=10,
    )
    figure.suptitle(f'skynav calibrate: fish-eye calibration ({camera.width}x{camera.height})')
    path = Path(path)
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return path


def _shade_empty_cells(axis, calibration: Calibration) -> None:
    """Shade the coverage cells of the image circle that hold no corner, in a matplotlib axis of the image."""
    from matplotlib.patches import Wedge  # noqa: PLC0415 (only a plot needs it)

    circle, cells = calibration.circle, calibration.coverage
    step = 360 / COVERAGE_SECTORS
    for ring, sector in zip(*np.nonzero(~cells.filled & cells.in_frame)):
        outer = (ring + 1) / COVERAGE_RINGS * circle.radius
        wedge = Wedge((circle.cx, circle.cy), outer, sector * step, (sector + 1) * step, width=outer / (ring + 1))
        wedge.set(facecolor='#e53935', alpha=0.3, edgecolor='none')
        axis.add_patch(wedge)
