# SPDX-License-Identifier: Apache-2.0
"""Fish-eye camera models: pixels <-> view directions in camera_link (equidistant/Kannala-Brandt, OCamCalib).

Conventions (docs/interfaces.md): camera_link looks up along +z; polar angle theta from
+z, azimuth phi from +x towards +y; camera_link is also the optical frame, so
+x grows with image column u and +y with row v. Integer pixel coordinates are
pixel centres. A model maps unit directions (..., 3) to pixel coordinates
(..., 2) as (u, v) and back.
"""

from __future__ import annotations

import os
from dataclasses import Field, dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Self

import numpy as np

if TYPE_CHECKING:
    from sensor_msgs.msg import CameraInfo

# Newton steps that refine the inverse of the distortion polynomial after a table look-up.
_NEWTON_STEPS = 4


def directions_from_angles(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Return unit vectors (..., 3) in camera_link for polar angle theta and azimuth phi (radians)."""
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    sin_theta = np.sin(theta)
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), np.cos(theta)], axis=-1)


def angles_from_directions(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (theta, phi) in radians of directions (..., 3); theta in [0, pi], phi in (-pi, pi]."""
    d = np.asarray(directions, float)
    theta = np.arctan2(np.hypot(d[..., 0], d[..., 1]), d[..., 2])
    phi = np.arctan2(d[..., 1], d[..., 0])
    return theta, phi


class _PixelCamera:
    """What the camera models share on top of their own projection: the pixel grid and a narrower field of view."""

    __dataclass_fields__: ClassVar[dict[str, Field[Any]]]  # every model is a frozen dataclass
    width: int
    height: int
    fov_limit: float  # full field of view (rad) the model's theta_max is capped to

    @property
    def theta_max(self) -> float:
        """Polar angle (rad) of the image circle's edge: directions up to it are seen (each model's own)."""
        raise NotImplementedError

    @property
    def field_of_view(self) -> float:
        """Full opening angle (rad) of the image circle."""
        return 2 * self.theta_max

    def unproject(self, pixels: np.ndarray) -> np.ndarray:
        """Return unit directions (..., 3) of pixel coordinates (..., 2) given as (u, v) (each model's own)."""
        raise NotImplementedError

    def pixel_grid(self) -> np.ndarray:
        """Return the (u, v) coordinates of every pixel centre, shape (height, width, 2)."""
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(float)
        return np.stack([u, v], axis=-1)

    def pixel_directions(self) -> np.ndarray:
        """Return the view direction of every pixel centre, shape (height, width, 3)."""
        return self.unproject(self.pixel_grid())

    def with_fov_limit(self, fov: float) -> Self:
        """Return this camera with its field of view narrowed to `fov` (rad, full angle); never widened."""
        return replace(self, fov_limit=min(self.fov_limit, fov))


@dataclass(frozen=True)
class EquidistantCamera(_PixelCamera):
    """OpenCV's fisheye (Kannala-Brandt) model as CameraInfo `equidistant` carries it, valid past 90 degrees.

    r(theta) = f * theta_d with theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8),
    u = cx + fx theta_d cos(phi), v = cy + fy theta_d sin(phi).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    k: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    fov_limit: float = 2 * np.pi  # a narrower full field of view (rad) than the image circle allows; never wider

    def distort(self, theta: np.ndarray) -> np.ndarray:
        """Return theta_d of polar angles theta (rad)."""
        t2 = np.square(theta)
        k1, k2, k3, k4 = self.k
        return theta * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))

    def _distort_derivative(self, theta: np.ndarray) -> np.ndarray:
        t2 = np.square(theta)
        k1, k2, k3, k4 = self.k
        return 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))

    @cached_property
    def theta_domain(self) -> float:
        """Largest polar angle (rad, at most pi) up to which theta_d keeps growing: where the model is valid."""
        theta = np.linspace(0.0, np.pi, 4097)
        grows = self._distort_derivative(theta) > 0
        return float(np.pi if grows.all() else theta[max(int(np.argmin(grows)) - 1, 1)])

    def undistort(self, theta_d: np.ndarray) -> np.ndarray:
        """Return polar angles theta (rad) whose distorted value is theta_d; clamped to the model's domain.

        Starts from a monotone table of the model, then refines with Newton steps.
        """
        theta_d = np.asarray(theta_d, float)
        top = self.theta_domain
        table = np.linspace(0.0, top, 2049)
        theta = np.interp(theta_d, self.distort(table), table)
        valid = theta_d < self.distort(np.array(top))
        with np.errstate(divide='ignore', invalid='ignore'):
            for _ in range(_NEWTON_STEPS):
                step = (self.distort(theta) - theta_d) / self._distort_derivative(theta)
                theta = np.where(valid, theta - step, theta)
        return np.clip(theta, 0.0, top)

    @cached_property
    def theta_max(self) -> float:
        """Polar angle (rad) of the image circle: the largest circle about (cx, cy) inside the image."""
        theta_d_max = min(
            self.cx / self.fx,
            (self.width - 1 - self.cx) / self.fx,
            self.cy / self.fy,
            (self.height - 1 - self.cy) / self.fy,
        )
        return min(float(self.undistort(np.array(theta_d_max))), self.fov_limit / 2)

    def project(self, directions: np.ndarray) -> np.ndarray:
        """Return pixel coordinates (..., 2) as (u, v) of directions (..., 3); theta past 90 degrees included."""
        theta, phi = angles_from_directions(directions)
        theta_d = self.distort(theta)
        return np.stack([self.cx + self.fx * theta_d * np.cos(phi), self.cy + self.fy * theta_d * np.sin(phi)], axis=-1)

    def unproject(self, pixels: np.ndarray) -> np.ndarray:
        """Return unit directions (..., 3) of pixel coordinates (..., 2) given as (u, v)."""
        pixels = np.asarray(pixels, float)
        a = (pixels[..., 0] - self.cx) / self.fx
        b = (pixels[..., 1] - self.cy) / self.fy
        return directions_from_angles(self.undistort(np.hypot(a, b)), np.arctan2(b, a))

    def image_circle(self) -> np.ndarray:
        """Return a (height, width) bool mask of the pixels whose centre lies inside the image circle."""
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(float)
        radius = np.hypot((u - self.cx) / self.fx, (v - self.cy) / self.fy)  # theta_d of each pixel centre
        return radius <= self.distort(np.array(self.theta_max)) * (1 + 1e-12)

    def camera_info_fields(self) -> dict:
        """Return the sensor_msgs/CameraInfo fields that describe this camera."""
        k = [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0]
        return {
            'width': self.width,
            'height': self.height,
            'distortion_model': 'equidistant',
            'd': list(self.k),
            'k': k,
            'r': [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            'p': [self.fx, 0.0, self.cx, 0.0, 0.0, self.fy, self.cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        }

    @classmethod
    def from_camera_info(cls, info: CameraInfo) -> EquidistantCamera:
        """Return the camera of a CameraInfo message (rclpy or rosbags); raise ValueError if not equidistant."""
        if info.distortion_model != 'equidistant':
            raise ValueError(f'camera model {info.distortion_model!r} is not supported (expected equidistant)')
        k = np.asarray(info.k, float).reshape(3, 3)
        d = np.asarray(info.d, float)
        if d.size != 4:
            raise ValueError(f'equidistant camera info needs 4 distortion coefficients, got {d.size}')
        if not (np.all(np.isfinite(k)) and np.all(np.isfinite(d)) and k[0, 0] > 0 and k[1, 1] > 0):
            raise ValueError('camera info has non-finite or non-positive intrinsics')
        if int(info.width) <= 0 or int(info.height) <= 0:
            raise ValueError(f'camera info has no image size ({info.width}x{info.height})')
        k1, k2, k3, k4 = (float(x) for x in d)
        return cls(
            int(info.width),
            int(info.height),
            float(k[0, 0]),
            float(k[1, 1]),
            float(k[0, 2]),
            float(k[1, 2]),
            (k1, k2, k3, k4),
        )

    @classmethod
    def for_field_of_view(
        cls, width: int, height: int, fov: float, k: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    ) -> EquidistantCamera:
        """Return a centred camera whose image circle touches the shorter image side at `fov` (rad, full angle)."""
        cx, cy = (width - 1) / 2, (height - 1) / 2
        radius = min(cx, cy)
        probe = cls(width, height, 1.0, 1.0, cx, cy, k)
        f = radius / float(probe.distort(np.array(fov / 2)))
        return cls(width, height, f, f, cx, cy, k)


# OCamCalib writes the centre in Matlab's convention, where the first pixel is 1.
OCAM_CENTRE_ORIGIN = 1


def _polynomial(coefficients: tuple[float, ...], x: np.ndarray) -> np.ndarray:
    """Return sum_i coefficients[i] x^i (Horner)."""
    out = np.zeros_like(x)
    for a in reversed(coefficients):
        out = out * x + a
    return out


@dataclass(frozen=True)
class OCamCamera(_PixelCamera):
    """Scaramuzza's omnidirectional model as OCamCalib's calib_results.txt stores it (pol, invpol, centre, affine).

    OCamCalib's frame has x along image rows, y along columns and the optical axis along -z; its pixel is
    (row, column) = A (x, y) rho / |(x, y)| + centre with A = [[c, d], [e, 1]] and rho = invpol(atan(z / |(x, y)|));
    back, (x', y') = A^-1 (pixel - centre) and the ray is (x', y', pol(|(x', y')|)). camera_link is
    (x, y, z) = (y_ocam, x_ocam, -z_ocam), so u = column, v = row and +z is the optical axis. xc (row) and yc
    (column) are kept 0-based here (the file's Matlab values minus 1).
    """

    width: int
    height: int
    pol: tuple[float, ...]  # z_ocam(rho) = sum pol[i] rho^i, rho in px (unprojection)
    invpol: tuple[float, ...]  # rho(t) = sum invpol[i] t^i, t = atan(z_ocam / |(x, y)|) in rad (projection)
    xc: float  # row of the optical centre, px, 0-based
    yc: float  # column of the optical centre, px, 0-based
    c: float = 1.0
    d: float = 0.0
    e: float = 0.0
    fov_limit: float = 2 * np.pi  # a narrower full field of view (rad) than the image circle allows; never wider

    @classmethod
    def from_calib_file(cls, path: str | os.PathLike, centre_origin: int = OCAM_CENTRE_ORIGIN) -> OCamCamera:
        """Return the camera of an OCamCalib calib_results.txt (comment lines start with '#')."""
        lines = [
            line.split()
            for line in Path(path).read_text().splitlines()
            if line.strip() and not line.lstrip().startswith('#')
        ]
        if len(lines) < 5:
            raise ValueError(f'{path}: expected pol, invpol, centre, affine and size lines, found {len(lines)}')
        pol_line, invpol_line, centre, affine, size = lines[:5]

        def counted(values: list[str], name: str) -> tuple[float, ...]:
            count = int(float(values[0]))
            if len(values) - 1 < count:
                raise ValueError(f'{path}: {name} announces {count} coefficients, has {len(values) - 1}')
            return tuple(float(v) for v in values[1 : count + 1])

        height, width = (int(float(v)) for v in size[:2])
        return cls(
            width,
            height,
            counted(pol_line, 'pol'),
            counted(invpol_line, 'invpol'),
            float(centre[0]) - centre_origin,
            float(centre[1]) - centre_origin,
            *(float(v) for v in affine[:3]),
        )

    @cached_property
    def theta_max(self) -> float:
        """Polar angle (rad) of the image circle: the least theta over the image's border pixels."""
        u = np.arange(self.width, dtype=float)
        v = np.arange(self.height, dtype=float)
        border = np.concatenate(
            [
                np.stack([u, np.zeros_like(u)], -1),
                np.stack([u, np.full_like(u, self.height - 1)], -1),
                np.stack([np.zeros_like(v), v], -1),
                np.stack([np.full_like(v, self.width - 1), v], -1),
            ]
        )
        theta, _ = angles_from_directions(self.unproject(border))
        return float(min(theta.min(), self.fov_limit / 2))

    def project(self, directions: np.ndarray) -> np.ndarray:
        """Return pixel coordinates (..., 2) as (u, v) of directions (..., 3) in camera_link (OCamCalib's world2cam)."""
        d = np.asarray(directions, dtype=float)
        x_ocam, y_ocam, z_ocam = d[..., 1], d[..., 0], -d[..., 2]
        norm = np.hypot(x_ocam, y_ocam)
        rho = _polynomial(self.invpol, np.arctan2(z_ocam, norm))
        scale = np.divide(rho, norm, out=np.zeros_like(norm), where=norm > 0)
        x, y = x_ocam * scale, y_ocam * scale
        row = x * self.c + y * self.d + self.xc
        column = x * self.e + y + self.yc
        return np.stack([column, row], axis=-1)

    def unproject(self, pixels: np.ndarray) -> np.ndarray:
        """Return unit directions (..., 3) in camera_link of pixels (..., 2) given as (u, v) (OCamCalib's cam2world)."""
        pixels = np.asarray(pixels, dtype=float)
        row, column = pixels[..., 1] - self.xc, pixels[..., 0] - self.yc
        inverse_determinant = 1.0 / (self.c - self.d * self.e)
        x = inverse_determinant * (row - self.d * column)
        y = inverse_determinant * (-self.e * row + self.c * column)
        z = _polynomial(self.pol, np.hypot(x, y))
        ray = np.stack([y, x, -z], axis=-1)
        return ray / np.linalg.norm(ray, axis=-1, keepdims=True)

    def image_circle(self) -> np.ndarray:
        """Return a (height, width) bool mask of the pixels whose ray lies within theta_max."""
        theta, _ = angles_from_directions(self.pixel_directions())
        return theta <= self.theta_max


Camera = EquidistantCamera | OCamCamera


def load_camera(source: object) -> Camera:
    """Return a camera from a calib_results.txt path (OCamCalib), a CameraInfo (equidistant) or a camera itself."""
    if isinstance(source, (EquidistantCamera, OCamCamera)):
        return source
    if isinstance(source, (str, os.PathLike)):
        return OCamCamera.from_calib_file(source)
    if hasattr(source, 'distortion_model'):
        return EquidistantCamera.from_camera_info(source)
    raise TypeError(f'cannot make a camera from {type(source).__name__}')
