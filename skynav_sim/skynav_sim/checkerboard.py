# SPDX-License-Identifier: Apache-2.0
"""Synthetic checkerboard views through a known fish-eye camera, for testing and documenting calibration.

A printed board of COLS x ROWS inner corners (squares of `square` metres, a white margin around them) is held
at a 6-DoF pose in camera_link. Each pixel is cut into supersample x supersample sub-pixels whose rays (the
contract's equidistant model, valid past 90 degrees) are intersected with the board's plane; what a ray
misses shows a synthetic background: a sky brightest at the zenith with soft clouds, and a dark tree line
near the horizon. The linear radiance is blurred, vignetted, cut to black outside the lens's image circle,
given photon and read noise and written as 8-bit sRGB RGB, as a colour camera driver delivers it.
Everything here is synthetic.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from skynav_core.camera import EquidistantCamera, angles_from_directions, directions_from_angles
from skynav_core.colour import linear_to_srgb8
from skynav_core.rotations import as_matrix

from .errors import SimError
from .noise import FractalNoise

# Reflectance of the printed board's paper and of its black squares (diffuse, no unit).
PAPER_REFLECTANCE = 0.80
INK_REFLECTANCE = 0.05
# Irradiance on a board held facing down at an upward camera, relative to the zenith sky's radiance (shade).
BOARD_ILLUMINATION = 0.30
# Radiance of the board's unprinted back, relative to the zenith sky.
BOARD_BACK_RADIANCE = 0.10
# Sky radiance at the horizon relative to the zenith (a clear sky brightens towards the horizon in green,
# darkens in blue; the mean over the channels stays near one).
SKY_ZENITH_RGB = np.array([0.55, 0.75, 1.00])
SKY_HORIZON_RGB = np.array([0.85, 0.90, 0.95])
TREE_RGB = np.array([0.04, 0.07, 0.03])
# Mean elevation (rad above the horizon) of the synthetic tree line and how much it varies with azimuth.
TREE_LINE_ELEVATION = np.radians(14.0)
TREE_LINE_VARIATION = np.radians(8.0)
# Relative illumination at the image circle's edge (a cos^4-like fall-off, as wide lenses have).
RIM_VIGNETTING = 0.55
# The share of full scale that automatic exposure gives the zenith sky.
EXPOSURE_LEVEL = 0.85
# Sensor noise in linear full-scale units: photon noise variance per unit signal, and read noise.
PHOTON_NOISE_GAIN = 2.5e-4
READ_NOISE = 1.5e-3
# Optics blur (px, Gaussian sigma) applied to the linear radiance.
BLUR_SIGMA = 0.7
# Margin (px) round the projected sheet within which its sub-pixel rays are traced.
BOX_MARGIN_PX = 3
# Board poses a person calibrating holds: distance from the lens (m) and tilt of the board away from facing it.
HOLDING_DISTANCE = (0.28, 0.50)
HOLDING_TILT = np.radians(30.0)
# Off-axis angles (deg) of the board's centre that a set of calibration views visits: the centre, the middle
# of the circle and its wide periphery.
CALIBRATION_OFF_AXIS_DEG = (0.0, 30.0, 50.0, 65.0, 75.0, 82.0, 86.0)
# The synthetic lens: Kannala-Brandt k1..k4 (all non-zero; theta_d grows monotonically past 110 degrees), the ratio
# fy / fx of its pixels, its light circle's radius as a share of half the shorter image side, and the offset of its
# principal point from the image centre as a share of that half side (a lens is never mounted exactly centred).
SYNTHETIC_LENS_K = (0.03, -0.01, 0.002, -0.0003)
SYNTHETIC_ASPECT = 1.003
SYNTHETIC_CIRCLE_FILL = 0.94
SYNTHETIC_CENTRE_OFFSET = (0.012, -0.012)


def synthetic_fisheye(width: int, height: int, fov: float, k: tuple = SYNTHETIC_LENS_K) -> EquidistantCamera:
    """Return the synthetic fish-eye camera whose light circle of `fov` (rad, full angle) sits inside the frame.

    The circle's radius is SYNTHETIC_CIRCLE_FILL of half the shorter side, its centre (the principal point) off the
    image centre by SYNTHETIC_CENTRE_OFFSET of it, and fy = SYNTHETIC_ASPECT fx.
    """
    half = min(width - 1, height - 1) / 2
    probe = EquidistantCamera(width, height, 1.0, 1.0, 0.0, 0.0, k)
    fx = SYNTHETIC_CIRCLE_FILL * half / float(probe.distort(np.array(fov / 2)))
    cx = (width - 1) / 2 + SYNTHETIC_CENTRE_OFFSET[0] * half
    cy = (height - 1) / 2 + SYNTHETIC_CENTRE_OFFSET[1] * half
    return EquidistantCamera(width, height, fx, fx * SYNTHETIC_ASPECT, cx, cy, k)


@dataclass(frozen=True)
class Checkerboard:
    """A printed checkerboard: `cols` x `rows` inner corners, squares of `square` m, a white margin of `margin` squares.

    Board frame: origin at the first inner corner, x along a row of corners (cols of them), y along a column,
    z out of the printed face. Corners are ordered row by row, x fastest, as OpenCV's detectors return them.
    """

    cols: int
    rows: int
    square: float
    margin: float = 1.0

    def __post_init__(self) -> None:
        if self.cols < 2 or self.rows < 2 or not self.square > 0:
            raise SimError(f'a checkerboard needs at least 2x2 inner corners and squares > 0 m, got {self}')

    def corners(self) -> np.ndarray:
        """Return the inner corners (cols * rows, 3) in the board frame, m, row by row."""
        x, y = np.meshgrid(np.arange(self.cols) * self.square, np.arange(self.rows) * self.square)
        return np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=-1)

    @property
    def centre(self) -> np.ndarray:
        """Return the centre of the pattern in the board frame (m)."""
        return np.array([(self.cols - 1) * self.square / 2, (self.rows - 1) * self.square / 2, 0.0])

    def outline(self) -> np.ndarray:
        """Return the four corners (4, 3) of the sheet (pattern and margin) in the board frame, m."""
        low = -(1 + self.margin) * self.square
        high_x = (self.cols + self.margin) * self.square
        high_y = (self.rows + self.margin) * self.square
        return np.array([[low, low, 0.0], [high_x, low, 0.0], [high_x, high_y, 0.0], [low, high_y, 0.0]])

    def reflectance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the reflectance at board coordinates (x, y) in m; NaN off the sheet."""
        low = -(1 + self.margin) * self.square
        on_sheet = (
            (x >= low)
            & (y >= low)
            & (x <= (self.cols + self.margin) * self.square)
            & (y <= (self.rows + self.margin) * self.square)
        )
        i = np.floor(x / self.square)
        j = np.floor(y / self.square)
        in_pattern = (i >= -1) & (i <= self.cols - 1) & (j >= -1) & (j <= self.rows - 1)
        black = in_pattern & ((i + j) % 2 == 0)
        value = np.where(black, INK_REFLECTANCE, PAPER_REFLECTANCE)
        return np.where(on_sheet, value, np.nan)


@dataclass(frozen=True)
class BoardPose:
    """Where a board is held: `rotation` (3, 3) turns board-frame vectors into camera_link; `centre` (m) is where
    the pattern's centre is, in camera_link."""

    rotation: np.ndarray
    centre: np.ndarray

    def to_camera(self, board: Checkerboard, points: np.ndarray) -> np.ndarray:
        """Return board-frame points (..., 3) in camera_link (m)."""
        return (np.asarray(points, float) - board.centre) @ self.rotation.T + self.centre

    def extrinsics(self, board: Checkerboard) -> tuple[np.ndarray, np.ndarray]:
        """Return (R, t): camera_link point = R @ board point + t, as OpenCV's rvec/tvec mean it."""
        return self.rotation, self.centre - self.rotation @ board.centre


def facing_pose(
    off_axis: float, azimuth: float, distance: float, tilt: float = 0.0, tilt_azimuth: float = 0.0, roll: float = 0.0
) -> BoardPose:
    """Return the pose of a board whose centre is `distance` m from the lens at polar angle `off_axis` and azimuth
    `azimuth` (rad, camera_link), its printed face turned to the lens, then tilted by `tilt` (rad) about an axis in its
    plane at `tilt_azimuth` and turned by `roll` (rad) about its normal."""
    towards = directions_from_angles(np.array(off_axis), np.array(azimuth))
    normal = -towards  # the printed face (+z of the board) looks back at the lens
    helper = np.array([0.0, 0.0, 1.0]) if abs(normal[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x_axis = np.cross(helper, normal)
    x_axis /= np.linalg.norm(x_axis)
    y_axis = np.cross(normal, x_axis)
    facing = np.stack([x_axis, y_axis, normal], axis=-1)
    turn = _axis_angle(np.array([0.0, 0.0, 1.0]), roll)
    tilt_axis = np.array([np.cos(tilt_azimuth), np.sin(tilt_azimuth), 0.0])
    return BoardPose(facing @ _axis_angle(tilt_axis, tilt) @ turn, towards * distance)


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Return the rotation matrix of `angle` (rad) about unit `axis` (Rodrigues)."""
    return as_matrix(cv2.Rodrigues(np.asarray(axis, float) * angle)[0])


def calibration_poses(
    camera: EquidistantCamera, board: Checkerboard, count: int, seed: int, lens_fov: float | None = None
) -> list[BoardPose]:
    """Return `count` board poses spread over the image circle as a person calibrating holds them.

    The board's centre visits CALIBRATION_OFF_AXIS_DEG in turn (the wide periphery included) at azimuths spread
    round the circle, HOLDING_DISTANCE away, its face turned to the lens and tilted up to HOLDING_TILT. A pose is
    kept only when the whole sheet lies inside the lens's image circle (`lens_fov`, rad, full angle; default the
    camera's), a pixel or more from its edge, and in front of the lens plane's far side; else it is drawn again
    nearer the axis.
    """
    rng = np.random.default_rng([seed, 1729])
    theta_lens = (camera.field_of_view if lens_fov is None else lens_fov) / 2
    limit = theta_lens - 2.0 / camera.fx  # a sheet touching the circle's edge is one no person can see whole
    golden = np.pi * (3 - np.sqrt(5))  # azimuth step that never repeats
    poses = []
    for index in range(count):
        off_axis = np.radians(CALIBRATION_OFF_AXIS_DEG[index % len(CALIBRATION_OFF_AXIS_DEG)])
        azimuth = index * golden + rng.uniform(-0.2, 0.2)
        for _ in range(200):
            pose = facing_pose(
                off_axis,
                azimuth,
                rng.uniform(*HOLDING_DISTANCE),
                rng.uniform(0, HOLDING_TILT),
                rng.uniform(0, 2 * np.pi),
                rng.uniform(0, 2 * np.pi),
            )
            sheet = pose.to_camera(board, _sheet_edge(board))
            theta, _ = angles_from_directions(sheet)
            if theta.max() < limit:
                poses.append(pose)
                break
            off_axis *= 0.99  # nearer the axis, by little: a person holds a rim view as far out as it is seen whole
        else:
            raise SimError(f'no pose {index} keeps the board inside the image circle; use a smaller board')
    return poses


def _sheet_edge(board: Checkerboard, samples: int = 24) -> np.ndarray:
    """Return points (4 * samples, 3) along the edge of the board's sheet (board frame, m)."""
    outline = board.outline()
    steps = np.linspace(0, 1, samples, endpoint=False)[:, None]
    return np.concatenate([a + steps * (b - a) for a, b in zip(outline, np.roll(outline, -1, axis=0))])


class BoardRenderer:
    """Renders synthetic checkerboard views through one camera; the sub-pixel rays are computed once."""

    def __init__(
        self,
        camera: EquidistantCamera,
        board: Checkerboard,
        lens_fov: float | None = None,
        supersample: int = 3,
        seed: int = 0,
    ) -> None:
        self.camera = camera
        self.board = board
        self.lens_fov = camera.field_of_view if lens_fov is None else lens_fov  # rad, full angle of the light circle
        self.supersample = supersample
        self.seed = seed

    @cached_property
    def _theta(self) -> np.ndarray:
        """Return the polar angle (rad) of every pixel centre's ray, shape (height, width)."""
        return angles_from_directions(self.camera.pixel_directions())[0]

    def _board_box(self, pose: BoardPose) -> tuple[slice, slice] | None:
        """Return the rows and columns of the pixels the board's sheet may cover at `pose`, or None if none."""
        edge = pose.to_camera(self.board, _sheet_edge(self.board, samples=64))
        theta, _ = angles_from_directions(edge)
        if theta.max() >= self.camera.theta_domain:
            raise SimError("the board reaches past the camera model's domain; hold it nearer the axis")
        # The image of the sheet is the region its projected edge encloses; its edge samples are a few px apart.
        pixels = self.camera.project(edge)
        low = np.floor(pixels.min(axis=0)).astype(int) - BOX_MARGIN_PX
        high = np.ceil(pixels.max(axis=0)).astype(int) + BOX_MARGIN_PX + 1
        low = np.maximum(low, 0)
        high = np.minimum(high, [self.camera.width, self.camera.height])
        if np.any(high <= low):
            return None
        return slice(low[1], high[1]), slice(low[0], high[0])

    @cached_property
    def _background(self) -> np.ndarray:
        """Return the linear RGB radiance (height, width, 3) of the synthetic sky and tree line behind the board."""
        directions = self.camera.pixel_directions()
        theta, phi = angles_from_directions(directions)
        # Stereographic coordinates: conformal, so the textures look alike in every part of the circle.
        x, y = directions[..., 0] / (1 + directions[..., 2]), directions[..., 1] / (1 + directions[..., 2])
        clouds = FractalNoise(self.seed, scale=0.6, octaves=4)(x, y)
        cloud_cover = np.clip(2.0 * clouds, 0, 1)[..., None]
        blend = np.clip(theta / (np.pi / 2), 0, 1)[..., None] ** 2
        sky = (1 - blend) * SKY_ZENITH_RGB + blend * SKY_HORIZON_RGB
        sky = (1 - cloud_cover) * sky + cloud_cover * 0.95
        trees = FractalNoise(self.seed + 1, scale=1.0, octaves=3)(np.cos(phi) * 2, np.sin(phi) * 2)
        tree_line = np.pi / 2 - TREE_LINE_ELEVATION - TREE_LINE_VARIATION * trees
        leaves = FractalNoise(self.seed + 2, scale=0.03, octaves=2)(x, y)
        tree = TREE_RGB * (1 + 0.6 * leaves[..., None])
        return np.where((theta > tree_line)[..., None], tree, sky)

    def board_radiance(self, pose: BoardPose) -> tuple[np.ndarray, np.ndarray]:
        """Return the board's linear radiance (height, width) averaged over sub-pixels, and its coverage (0..1)."""
        h, w = self.camera.height, self.camera.width
        mean, coverage = np.zeros((h, w)), np.zeros((h, w))
        box = self._board_box(pose)
        if box is None:
            return mean, coverage
        rows, columns = box
        s = self.supersample
        offsets = (np.arange(s) + 0.5) / s - 0.5
        v = (np.arange(rows.start, rows.stop)[:, None] + offsets).ravel()
        u = (np.arange(columns.start, columns.stop)[:, None] + offsets).ravel()
        rays = self.camera.unproject(np.stack(np.meshgrid(u, v), axis=-1))
        normal = pose.rotation[:, 2]
        origin = pose.centre - pose.rotation @ self.board.centre  # board origin in camera_link
        facing = rays @ normal
        with np.errstate(divide='ignore', invalid='ignore'):
            distance = (normal @ origin) / facing  # along each ray to the board's plane (m)
        ahead = np.isfinite(distance) & (distance > 0)
        hits = (rays * np.where(ahead, distance, 0.0)[..., None] - origin) @ pose.rotation  # board frame (m)
        reflectance = self.board.reflectance(hits[..., 0], hits[..., 1])
        on_board = ahead & np.isfinite(reflectance)
        front = facing < 0  # a ray meeting the printed face travels against its normal
        radiance = np.where(front, BOARD_ILLUMINATION * np.nan_to_num(reflectance), BOARD_BACK_RADIANCE)
        radiance = np.where(on_board, radiance, 0.0)
        bh, bw = rows.stop - rows.start, columns.stop - columns.start
        mean[rows, columns] = radiance.reshape(bh, s, bw, s).mean(axis=(1, 3))
        coverage[rows, columns] = on_board.reshape(bh, s, bw, s).mean(axis=(1, 3))
        return mean, coverage

    def render(self, pose: BoardPose, index: int = 0) -> np.ndarray:
        """Return the synthetic view (height, width, 3) uint8 sRGB RGB of the board at `pose`; noise seeded by index."""
        radiance, coverage = self.board_radiance(pose)
        linear = (1 - coverage[..., None]) * self._background + radiance[..., None]
        theta = self._theta
        edge = self.lens_fov / 2
        vignetting = 1 - (1 - RIM_VIGNETTING) * np.clip(theta / edge, 0, 1) ** 2
        linear = linear * (vignetting * (theta <= edge) * EXPOSURE_LEVEL)[..., None]
        linear = cv2.GaussianBlur(linear.astype(np.float32), (0, 0), BLUR_SIGMA)  # the circle's edge blurs too
        rng = np.random.default_rng([self.seed, index, 97])
        noisy = linear + rng.normal(0.0, 1.0, linear.shape) * np.sqrt(PHOTON_NOISE_GAIN * linear + READ_NOISE**2)
        return linear_to_srgb8(noisy)

    def true_corners(self, pose: BoardPose) -> np.ndarray:
        """Return the exact pixel positions (cols * rows, 2) of the board's inner corners at `pose` (u, v)."""
        return self.camera.project(pose.to_camera(self.board, self.board.corners()))
