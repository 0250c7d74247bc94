# SPDX-License-Identifier: Apache-2.0
"""Peer: a feature compass. ORB or SIFT on the fish-eye images, unit bearings, RANSAC, rotation.

Keypoints inside the image circle are matched (Lowe's ratio test, mutual best), turned into unit bearing vectors
in camera_link by the camera model (valid past 90 degrees, unlike cv2.findEssentialMat's perspective model),
and two models are fitted by RANSAC on the sphere:
* rotation only, d_s = R d_c: 2-point samples, Kabsch (SVD) fit, inliers by the angle between d_s and R d_c;
* essential matrix, d_s^T E d_c = 0 with E = [t]x R (t the current camera's position in the snapshot frame):
  8-point samples on bearings, inliers by the angle between d_s and the epipolar plane of d_c, the pair
  (R, t) of the decomposition that puts the triangulated points in front of both cameras.
The rotation model wins unless the essential one explains clearly more matches (little translation against the
scene's depth leaves E ill-conditioned while R alone fits). Residual: median inlier angle (deg).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from skynav_compass.errors import CompassError
from skynav_compass.estimate import CompassEstimate, Hypothesis

Features = tuple  # (bearings (N, 3) in camera_link, descriptors (N, D) or None)


def kabsch(source: np.ndarray, target: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Return the rotation(s) R (..., 3, 3) minimising sum w |target - R source|^2 of unit vectors (..., N, 3)."""
    w = np.ones(source.shape[:-1]) if weights is None else weights
    u, _, vt = np.linalg.svd(np.swapaxes(target * w[..., None], -1, -2) @ source)
    sign = np.sign(np.linalg.det(u @ vt))
    u = u.copy()
    u[..., :, 2] *= sign[..., None]
    return u @ vt


def eight_point(d_s: np.ndarray, d_c: np.ndarray) -> np.ndarray:
    """Return essential matrices E (..., 3, 3) (unit Frobenius norm, two equal singular values) of d_s^T E d_c = 0."""
    rows = (d_s[..., :, :, None] * d_c[..., :, None, :]).reshape(d_s.shape[:-1] + (9,))
    if rows.shape[-2] < 9:  # pad to a square system: the null vector is the same
        rows = np.concatenate([rows, np.zeros(rows.shape[:-2] + (9 - rows.shape[-2], 9))], axis=-2)
    _, _, vt = np.linalg.svd(rows)
    u, _, vt2 = np.linalg.svd(vt[..., -1, :].reshape(vt.shape[:-2] + (3, 3)))
    return (u * np.array([1.0, 1.0, 0.0])) @ vt2 / np.sqrt(2.0)


def epipolar_angle(essential: np.ndarray, d_s: np.ndarray, d_c: np.ndarray) -> np.ndarray:
    """Return the larger angle (rad) of d_s to the epipolar plane of d_c and of d_c to that of d_s; (..., N)."""
    forward = d_c @ np.swapaxes(essential, -1, -2)  # plane normals E d_c in the snapshot frame
    backward = d_s @ essential  # E^T d_s in the current frame
    product = np.abs(np.sum(d_s * forward, axis=-1))
    with np.errstate(divide='ignore', invalid='ignore'):
        first = product / np.linalg.norm(forward, axis=-1)
        second = product / np.linalg.norm(backward, axis=-1)
    return np.arcsin(np.clip(np.nan_to_num(np.maximum(first, second), nan=1.0), 0.0, 1.0))


def decompose_essential(essential: np.ndarray, d_s: np.ndarray, d_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (R, t) of E = [t]x R whose triangulated points lie in front of both cameras (most of them)."""
    u, _, vt = np.linalg.svd(essential)
    if np.linalg.det(u) < 0:
        u = -u
    if np.linalg.det(vt) < 0:
        vt = -vt
    w = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    best, best_count = (np.eye(3), np.zeros(3)), -1
    for rotation in (u @ w @ vt, u @ w.T @ vt):
        for t in (u[:, 2], -u[:, 2]):
            # lambda_s d_s = lambda_c R d_c + t, least squares per point
            turned = d_c @ rotation.T
            a11 = np.ones(len(d_s))
            a12 = -np.sum(d_s * turned, axis=1)
            a22 = np.ones(len(d_s))
            b1, b2 = np.sum(d_s * t, axis=1), -np.sum(turned * t, axis=1)
            determinant = a11 * a22 - a12 * a12
            with np.errstate(divide='ignore', invalid='ignore'):
                lam_s = (b1 * a22 - a12 * b2) / determinant
                lam_c = (a11 * b2 - a12 * b1) / determinant
            count = int(np.sum((lam_s > 0) & (lam_c > 0)))
            if count > best_count:
                best, best_count = (rotation, t), count
    return best


def _samples(rng, count: int, population: int, size: int) -> np.ndarray:
    """Return `count` random samples of `size` distinct indices below `population`, (count, size)."""
    return np.argpartition(rng.random((count, population)), size - 1, axis=1)[:, :size]


@dataclass(frozen=True)
class FeatureConfig:
    """Settings of the feature compass (angles in rad)."""

    detector: str = 'sift'  # 'sift' or 'orb'
    max_features: int = 2000
    ratio: float = 0.8  # Lowe's ratio test
    threshold: float = np.radians(1.0)  # inlier angle of both models
    iterations: int = 500
    model: str = 'auto'  # 'auto', 'rotation' or 'essential'
    essential_gain: float = 1.2  # auto: the essential model needs this many times the rotation model's inliers
    seed: int = 0


class FeatureCompass:
    """Feature-based compass on fish-eye images: keypoints, bearings on the sphere, RANSAC rotation / essential."""

    def __init__(self, camera, config: FeatureConfig | None = None) -> None:
        """Prepare the detector and the image-circle mask of a camera."""

        self.camera = camera
        self.config = config or FeatureConfig()
        c = self.config
        if c.detector == 'sift':
            self._detector: cv2.Feature2D = cv2.SIFT.create(nfeatures=c.max_features)
            self._norm = cv2.NORM_L2
        elif c.detector == 'orb':
            self._detector = cv2.ORB.create(nfeatures=c.max_features)
            self._norm = cv2.NORM_HAMMING
        else:
            raise CompassError(f'unknown detector {c.detector!r} (expected sift or orb)')
        self._mask = camera.image_circle().astype(np.uint8) * 255

    @property
    def method(self) -> str:
        """Return a short name of the configured method."""
        return f'features-{self.config.detector}'

    def features(self, image: np.ndarray) -> Features:
        """Return keypoint bearings (N, 3) in camera_link and descriptors of a grey fish-eye image."""
        keypoints, descriptors = self._detector.detectAndCompute(np.asarray(image), self._mask)
        if not keypoints:
            return np.zeros((0, 3)), None
        pixels = np.array([k.pt for k in keypoints], dtype=float)
        return self.camera.unproject(pixels), descriptors

    def matches(self, snapshot: Features, current: Features) -> tuple[np.ndarray, np.ndarray]:
        """Return matched bearings (d_s, d_c), each (M, 3), by ratio test and mutual consistency."""

        (d_s, desc_s), (d_c, desc_c) = snapshot, current
        if desc_s is None or desc_c is None or len(d_s) < 2 or len(d_c) < 2:
            return np.zeros((0, 3)), np.zeros((0, 3))
        matcher = cv2.BFMatcher(self._norm)
        forward = matcher.knnMatch(desc_c, desc_s, k=2)
        backward = {m[0].queryIdx: m[0].trainIdx for m in matcher.knnMatch(desc_s, desc_c, k=1) if m}
        pairs = [
            (m[0].trainIdx, m[0].queryIdx)
            for m in forward
            if len(m) == 2
            and m[0].distance < self.config.ratio * m[1].distance
            and backward.get(m[0].trainIdx) == m[0].queryIdx
        ]
        if not pairs:
            return np.zeros((0, 3)), np.zeros((0, 3))
        index = np.array(pairs)
        return d_s[index[:, 0]], d_c[index[:, 1]]

    def _ransac_rotation(self, d_s: np.ndarray, d_c: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
        """Return (R, inliers) of the rotation-only model d_s = R d_c (all 2-point hypotheses at once)."""
        c = self.config
        cos_threshold = np.cos(c.threshold)
        samples = _samples(rng, c.iterations, len(d_s), 2)
        rotations = kabsch(d_c[samples], d_s[samples])  # (K, 3, 3)
        agreement = np.einsum('ni,kij,nj->kn', d_s, rotations, d_c)
        best = agreement[int(np.argmax(np.sum(agreement > cos_threshold, axis=1)))] > cos_threshold
        rotation = np.eye(3)
        for _ in range(3):  # refit on the inliers, re-select
            if best.sum() < 2:
                break
            rotation = kabsch(d_c[best], d_s[best])
            best = np.sum(d_s * (d_c @ rotation.T), axis=1) > cos_threshold
        return rotation, best

    def _ransac_essential(self, d_s: np.ndarray, d_c: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
        """Return (E, inliers) of the essential model d_s^T E d_c = 0 (all 8-point hypotheses at once)."""
        c = self.config
        if len(d_s) < 8:
            return np.zeros((3, 3)), np.zeros(len(d_s), dtype=bool)
        samples = _samples(rng, c.iterations, len(d_s), 8)
        essentials = eight_point(d_s[samples], d_c[samples])  # (K, 3, 3)
        inliers = epipolar_angle(essentials[:, None], d_s[None], d_c[None])[:, 0] < c.threshold
        k = int(np.argmax(inliers.sum(axis=1)))
        best_e, best = essentials[k], inliers[k]
        for _ in range(3):
            if best.sum() < 8:
                break
            best_e = eight_point(d_s[best], d_c[best])
            best = epipolar_angle(best_e, d_s, d_c) < c.threshold
        return best_e, best

    def estimate(self, snapshot_image: np.ndarray, current_image: np.ndarray) -> CompassEstimate:
        """Return R with d_snapshot = R d_current (camera_link) from matched features of two grey fish-eye images."""
        return self.estimate_features(self.features(snapshot_image), self.features(current_image))

    def estimate_features(self, snapshot: Features, current: Features) -> CompassEstimate:
        """Return R with d_snapshot = R d_current from the features (bearings, descriptors) of two images."""
        c = self.config
        d_s, d_c = self.matches(snapshot, current)
        if len(d_s) < 3:
            return CompassEstimate(
                np.eye(3),
                float('inf'),
                (),
                0.0,
                False,
                self.method,
                'deg',
                {'matches': len(d_s), 'inliers': 0, 'model': 'none'},
            )
        rng = np.random.default_rng(c.seed)
        rotation, inliers = self._ransac_rotation(d_s, d_c, rng)
        model = 'rotation'
        if c.model in ('auto', 'essential'):
            essential, e_inliers = self._ransac_essential(d_s, d_c, rng)
            use = c.model == 'essential' or e_inliers.sum() > c.essential_gain * inliers.sum() + 4
            if use and e_inliers.sum() >= 8:
                rotation, _ = decompose_essential(essential, d_s[e_inliers], d_c[e_inliers])
                inliers, model = e_inliers, 'essential'
        angles = np.degrees(np.arccos(np.clip(np.sum(d_s[inliers] * (d_c[inliers] @ rotation.T), axis=1), -1, 1)))
        residual = float(np.median(angles)) if angles.size else float('inf')
        confident = bool(inliers.sum() >= 10)
        return CompassEstimate(
            rotation,
            residual,
            (Hypothesis(rotation, residual),),
            float('inf'),
            confident,
            self.method,
            'median inlier angle (deg)',
            {'matches': int(len(d_s)), 'inliers': int(inliers.sum()), 'model': model},
        )
