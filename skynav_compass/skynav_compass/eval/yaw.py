# SPDX-License-Identifier: Apache-2.0
"""Peer: the classic visual compass, yaw only (rotation about the camera's +z), on panoramas or on the SH.

Panoramic: both fish-eye images are unwrapped to panoramas (rows: polar angle theta from the zenith to the
image circle, columns: azimuth phi from +x towards +y) and the rotational image difference
RID(psi) = mean over the panorama of (P_s(theta, phi) - P_c(theta, phi - psi))^2 is minimised over all column
shifts at once by FFT, then to sub-column precision by a parabola through the least value and its neighbours.
SH: the same with the compass costs (cost.py) restricted to z-rotations, R = Rz(psi). In both, d_snapshot = R
d_current with R = Rz(psi) (camera_link); a yaw-only compass cannot see tilt, so its 3D error is at least the tilt.
"""

from __future__ import annotations

import cv2
import numpy as np

from skynav_compass.compass import UNITS
from skynav_compass.cost import build_problem
from skynav_compass.estimate import CompassEstimate, Hypothesis
from skynav_compass.so3 import complex_form
from skynav_compass.views import CompassView
from skynav_core.camera import directions_from_angles
from skynav_core.rotations import yaw_matrix
from skynav_sh.fisheye import image_values


def _parabola_offset(left: float, centre: float, right: float) -> float:
    """Return the offset (-0.5..0.5 samples) of the vertex of the parabola through three equally spaced values."""
    denominator = left - 2 * centre + right
    if not np.isfinite(denominator) or denominator <= 0:
        return 0.0
    return float(np.clip(0.5 * (left - right) / denominator, -0.5, 0.5))


class PanoramicCompass:
    """The classic visual compass: rotational image difference of unwrapped fish-eye panoramas over yaw only."""

    def __init__(self, camera, n_azimuth: int = 360, n_polar: int = 60, max_theta: float | None = None) -> None:
        """Prepare the unwrapping remap of a camera: n_azimuth columns over 2 pi, n_polar rows up to max_theta (rad)."""

        self.camera = camera
        self.n_azimuth = int(n_azimuth)
        self.max_theta = float(camera.theta_max if max_theta is None else min(max_theta, camera.theta_max))
        theta = (np.arange(n_polar) + 0.5) * self.max_theta / n_polar
        phi = 2 * np.pi * np.arange(self.n_azimuth) / self.n_azimuth
        pixels = camera.project(directions_from_angles(theta[:, None], phi[None, :])).astype(np.float32)
        self._maps = cv2.convertMaps(pixels[..., 0], pixels[..., 1], cv2.CV_16SC2)

    method = 'visual-compass-panorama'

    def unwrap(self, image: np.ndarray) -> np.ndarray:
        """Return the panorama (n_polar, n_azimuth) float32 of a fish-eye image (uint8 as / 255)."""

        return cv2.remap(
            image_values(image),
            self._maps[0],
            self._maps[1],
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=0.0,
        )

    def image_difference(self, snapshot: np.ndarray, current: np.ndarray) -> np.ndarray:
        """Return the rotational image difference (value^2) of two panoramas per column shift psi_k = 2 pi k / n."""
        s = np.asarray(snapshot, dtype=np.float64)
        c = np.asarray(current, dtype=np.float64)
        # sum_j s[j] c[j - k] for all k: inverse FFT of S conj(C) summed over rows
        cross = np.fft.irfft(np.sum(np.fft.rfft(s, axis=1) * np.conj(np.fft.rfft(c, axis=1)), axis=0), n=s.shape[1])
        return (np.sum(s * s) + np.sum(c * c) - 2 * cross) / s.size

    def estimate(self, snapshot_image: np.ndarray, current_image: np.ndarray) -> CompassEstimate:
        """Return R = Rz(psi) minimising the rotational image difference of two fish-eye images (mask or grey)."""
        return self.estimate_panoramas(self.unwrap(snapshot_image), self.unwrap(current_image))

    def estimate_panoramas(self, snapshot: np.ndarray, current: np.ndarray) -> CompassEstimate:
        """Return R = Rz(psi) minimising the rotational image difference of two panoramas (see unwrap)."""
        difference = self.image_difference(snapshot, current)
        k = int(np.argmin(difference))
        n = difference.size
        offset = _parabola_offset(difference[(k - 1) % n], difference[k], difference[(k + 1) % n])
        psi = 2 * np.pi * (k + offset) / n
        matrix = yaw_matrix(psi)
        return CompassEstimate(
            matrix,
            float(difference[k]),
            (Hypothesis(matrix, float(difference[k])),),
            float('inf'),
            True,
            self.method,
            'mean squared panorama difference (value^2)',
        )


class YawCompass:
    """The classic visual compass on the SH: the compass cost over z-rotations only (FFT over psi, then Newton)."""

    def __init__(
        self, max_degree: int, cost: str = 'masked', normalise: bool = False, oversampling: float = 4.0
    ) -> None:
        """Prepare the yaw search of degree L with n = oversampling (2L + 2) samples of psi."""
        self.max_degree = int(max_degree)
        self.cost = cost
        self.normalise = normalise
        self.n = int(np.ceil(oversampling * (2 * self.max_degree + 2)))

    @property
    def method(self) -> str:
        """Return a short name of the configured method."""
        return f'visual-compass-sh-{self.cost}'

    def estimate(self, snapshot: CompassView | np.ndarray, current: CompassView | np.ndarray) -> CompassEstimate:
        """Return R = Rz(psi) minimising the compass cost over yaw (d_snapshot = R d_current)."""

        problem = build_problem(snapshot, current, self.max_degree, self.cost, self.normalise)
        L = self.max_degree
        # channel(psi) = sum_lm conj(A_lm) exp(i m psi) B_lm: a trigonometric polynomial sampled by one inverse FFT
        spectra = np.zeros((len(problem.channels), self.n), dtype=complex)
        a_c, b_c = complex_form(problem.snapshot), complex_form(problem.current)
        for k, channel in enumerate(problem.channels):
            per_order = sum(w * np.sum(a_c[i].conj() * b_c[j], axis=0) for i, j, w in channel)  # (2L+1,)
            spectra[k, np.arange(-L, L + 1) % self.n] = per_order
        values = list(np.fft.ifft(spectra, axis=1).real * self.n)
        with np.errstate(divide='ignore', invalid='ignore'):
            costs = problem.mask_invalid(values, problem.formula(values))
        k = int(np.argmin(costs))
        psi = 2 * np.pi * k / self.n
        # Newton on psi alone: the z-component of the cost's rotation-vector derivatives
        for _ in range(8):
            jet = problem.jet(yaw_matrix(psi))
            if jet.hess[2, 2] <= 0 or not np.isfinite(jet.value):
                break
            step = float(np.clip(-jet.grad[2] / jet.hess[2, 2], -np.pi / self.n, np.pi / self.n))
            psi += step
            if abs(step) < 1e-10:
                break
        matrix = yaw_matrix(psi)
        residual = problem.cost(matrix)
        return CompassEstimate(
            matrix,
            residual,
            (Hypothesis(matrix, residual),),
            float('inf'),
            True,
            self.method,
            UNITS[self.cost, self.normalise],
        )
