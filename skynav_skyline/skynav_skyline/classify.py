# SPDX-License-Identifier: Apache-2.0
"""Contrast projection, the global (learned) sky/ground separator and the classification rate.

The contrast of a pixel is s = cos(a) x + sin(a) y of its normalised log
features x (UV) and y (green) (see features.py); a = 0 is UV only, a = -45
degrees is log(UV/G) / sqrt(2). Sky is where s > t.

Pixels the threshold does not decide (rule shared by learning and
segmentation): outside the image circle -> ground; UV saturated -> sky (the
sun and bright sky; ground reflects little UV); UV dark -> ground; UV or (when
used) green NaN/inf -> ground. A saturated or dark *green* value is clamped
(to the saturation level or the dark floor) and its contrast used as is: with
a < 0 a clamped bright green gives an upper bound of the true contrast and a
clamped dark green a lower bound, so such pixels err only where the bound
itself crosses the threshold.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from skynav_skyline.errors import SkylineError

from .features import REFERENCE_PERCENTILE, Features

#: Channel modes: UV only (projection angle 0) or the UV/green contrast (learned angle).
CHANNEL_MODES: tuple[str, ...] = ('uv', 'uv-green')
#: Projection angle (rad) of the plain UV/green contrast log(UV/G); a learned angle replaces it.
UV_GREEN_CONTRAST_ANGLE = -np.pi / 4
#: Angle grid step (rad) of the global search, and the range it covers (rad): UV weight never negative.
ANGLE_GRID_STEP = np.deg2rad(1.0)
ANGLE_SEARCH_RANGE = (-np.pi / 2, np.pi / 2)
#: Subdivisions of one grid step in the refinement around the best grid angle (one grid step either side).
ANGLE_REFINE_SUBDIVISIONS = 20
#: Mask values of /skyline/mask and of ground-truth masks.
SKY, GROUND = 255, 0


def project(x: np.ndarray, y: np.ndarray | None, angle: float) -> np.ndarray:
    """Return the float32 contrast s = cos(angle) x + sin(angle) y (log units); y may be None at angle 0."""
    x = np.asarray(x, np.float32)
    if y is None:
        if angle != 0:
            raise SkylineError(f'contrast at angle {angle} rad needs the green feature')
        return x.copy()
    return np.float32(np.cos(angle)) * x + np.float32(np.sin(angle)) * np.asarray(y, np.float32)


def best_threshold(contrast: np.ndarray, is_sky: np.ndarray) -> tuple[float, int]:
    """Return (t, correct): the threshold (contrast unit) matching most labels by s > t, and that count.

    One sort: after sorting, cutting before position k calls the first k pixels
    ground and the rest sky; the matches are the ground labels below plus the
    sky labels above, a cumulative sum. Only cuts between distinct values
    count. t is the midpoint of the two values around the best cut, computed in
    the contrast's own dtype so that s > t reproduces the count exactly.
    """
    contrast = np.ravel(contrast)
    is_sky = np.ravel(np.asarray(is_sky, bool))
    if contrast.shape != is_sky.shape:
        raise SkylineError(f'{contrast.size} contrast values but {is_sky.size} labels')
    n = contrast.size
    if n == 0:
        return 0.0, 0
    order = np.argsort(contrast, kind='stable')
    values, sky = contrast[order], is_sky[order]
    ground_below = np.concatenate([[0], np.cumsum(~sky)])
    sky_above = int(sky.sum()) - np.concatenate([[0], np.cumsum(sky)])
    correct = ground_below + sky_above
    distinct = np.ones(n + 1, bool)
    distinct[1:n] = values[1:] > values[:-1]
    correct = np.where(distinct, correct, -1)
    k = int(np.argmax(correct))
    kind = values.dtype.type
    if k == 0:
        t = np.nextafter(values[0], kind(-np.inf))
    elif k == n:
        t = values[-1]
    else:
        low, high = values[k - 1], values[k]
        t = low + (high - low) / kind(2)
        if not low <= t < high:
            t = low
    return float(t), int(correct[k])


@dataclass(frozen=True)
class GlobalModel:
    """A learned global separator: sky where cos(angle) x + sin(angle) y > threshold."""

    channels: str  # 'uv' or 'uv-green'
    angle: float  # projection angle (rad)
    threshold: float  # contrast threshold (normalised log units)
    rate: float  # classification rate on the training pixels inside the image circle, in [0, 1]
    reference_percentile: float = REFERENCE_PERCENTILE  # normalisation the features were made with (%)

    def to_dict(self) -> dict:
        """Return the model as a plain dict (for YAML/JSON)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> GlobalModel:
        """Return the model stored by `to_dict`."""
        return cls(
            str(data['channels']),
            float(data['angle']),
            float(data['threshold']),
            float(data['rate']),
            float(data.get('reference_percentile', REFERENCE_PERCENTILE)),
        )


def _labels(truth: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Return a ground-truth mask (255 sky, 0 ground) as bool sky, checking its shape."""
    truth = np.asarray(truth)
    if truth.shape != tuple(shape):
        raise SkylineError(f'ground-truth mask {truth.shape} and image {tuple(shape)} differ in shape')
    return truth > 127


def _training_pixels(
    features: Sequence[Features], truths: Sequence[np.ndarray], circles: Sequence[np.ndarray], uses_green: bool
):
    """Return pooled x, y, sky labels of threshold-decided pixels, rule-decided correct count, circle total."""
    xs: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    labels: list[np.ndarray] = []
    fixed_correct = total = 0
    for feature, truth, circle in zip(features, truths, circles, strict=True):
        circle = np.asarray(circle, bool)
        if circle.shape != feature.shape:
            raise SkylineError(f'image circle mask {circle.shape} and image {feature.shape} differ in shape')
        sky = _labels(truth, feature.shape)
        decided = feature.by_threshold(circle, uses_green)
        fixed = circle & ~decided
        fixed_correct += int(np.count_nonzero(feature.sky_by_rule(circle)[fixed] == sky[fixed]))
        total += int(np.count_nonzero(circle))
        xs.append(feature.x[decided])
        if uses_green:
            assert feature.y is not None  # decoded along with the green channel
            ys.append(feature.y[decided])
        labels.append(sky[decided])
    x = np.concatenate(xs)
    y = np.concatenate(ys) if uses_green else None
    return x, y, np.concatenate(labels), fixed_correct, total


def learn_global(
    features: Sequence[Features],
    truths: Sequence[np.ndarray],
    circles: np.ndarray | Sequence[np.ndarray],
    channels: str = 'uv-green',
    angles: np.ndarray | None = None,
    refine: int = ANGLE_REFINE_SUBDIVISIONS,
    max_samples: int | None = None,
    seed: int = 0,
) -> GlobalModel:
    """Return the global separator (angle rad, threshold, rate) maximising the classification rate on labelled images.

    `features` from extract_features (same reference percentile for all),
    `truths` the ground-truth masks (255 sky, 0 ground), `circles` one
    image-circle mask for all or one per image. For 'uv' the angle is 0; for
    'uv-green' every angle of `angles` (default: 1 degree steps over
    ANGLE_SEARCH_RANGE) is tried, each with its best threshold from one sort,
    then the best one refined on a grid of `refine` subdivisions of the
    smallest grid step, one step either side (refine=0: no refinement).
    With `max_samples`, angles are compared on a random sample of the pixels;
    the final threshold and rate always use every pixel. The rate counts every
    pixel inside the image circle, rule-decided ones (saturated/dark UV,
    invalid) included, so it equals `classification_rate` of `segment` with
    this model on the same images.
    """
    if channels not in CHANNEL_MODES:
        raise SkylineError(f'unknown channel mode {channels!r}; expected one of {", ".join(CHANNEL_MODES)}')
    features = list(features)
    truths = list(truths)
    if not features or len(features) != len(truths):
        raise SkylineError(f'need one ground-truth mask per feature image, got {len(features)} and {len(truths)}')
    percentiles = {f.reference_percentile for f in features}
    if len(percentiles) != 1:
        raise SkylineError(f'features were normalised with different reference percentiles: {sorted(percentiles)}')
    circles = [circles] * len(features) if isinstance(circles, np.ndarray) and circles.ndim == 2 else list(circles)
    uses_green = channels == 'uv-green'
    if uses_green and any(f.y is None for f in features):
        raise SkylineError('uv-green learning needs features with the green channel')
    x, y, sky, fixed_correct, total = _training_pixels(features, truths, circles, uses_green)
    if total == 0:
        raise SkylineError('no pixel inside the image circle')

    if not uses_green:
        best_angle = 0.0
    else:
        sample = np.arange(x.size)
        if max_samples is not None and x.size > max_samples:
            sample = np.random.default_rng(seed).choice(x.size, int(max_samples), replace=False)
        xs, ys, skys = x[sample], y[sample], sky[sample]

        def score(angle: float) -> int:
            """Return the most sample labels any threshold matches at `angle` (rad)."""
            return best_threshold(project(xs, ys, angle), skys)[1]

        grid = (
            np.arange(ANGLE_SEARCH_RANGE[0], ANGLE_SEARCH_RANGE[1] + ANGLE_GRID_STEP / 2, ANGLE_GRID_STEP)
            if angles is None
            else np.asarray(angles, float)
        )
        if grid.size == 0:
            raise SkylineError('no angle to search')
        best_angle = float(grid[int(np.argmax([score(a) for a in grid]))])
        if refine > 0 and np.unique(grid).size > 1:
            step = float(np.min(np.diff(np.unique(grid))))
            fine = best_angle + step * np.arange(-refine, refine + 1) / refine
            best_angle = float(fine[int(np.argmax([score(a) for a in fine]))])
    threshold, correct = best_threshold(project(x, y, best_angle), sky)
    rate = (fixed_correct + correct) / total
    return GlobalModel(channels, best_angle, threshold, rate, percentiles.pop())


def classification_rate(mask: np.ndarray, truth: np.ndarray, circle: np.ndarray) -> float:
    """Return the share (0..1) of pixels inside the image circle whose class (255 sky, 0 ground) matches the truth."""
    mask, truth, circle = np.asarray(mask), np.asarray(truth), np.asarray(circle, bool)
    if not mask.shape == truth.shape == circle.shape:
        raise SkylineError(
            f'mask {mask.shape}, ground truth {truth.shape} and image circle {circle.shape} differ in shape'
        )
    inside = int(np.count_nonzero(circle))
    if inside == 0:
        raise SkylineError('the image circle is empty')
    return int(np.count_nonzero(((mask > 127) == (truth > 127)) & circle)) / inside
