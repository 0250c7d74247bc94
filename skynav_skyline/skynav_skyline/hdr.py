# SPDX-License-Identifier: Apache-2.0
"""Merging exposure brackets of one channel into linear radiance (float32, like a 32FC1 image).

The images are linear in radiance (docs/interfaces.md), so each bracket estimates
radiance = (raw - black level) / exposure time; the merge averages these
estimates with a hat weight that trusts mid-range values most and ignores
saturated and dark ones. A pixel with no trusted bracket but a saturated one
gets the largest saturated estimate, i.e. that of the shortest saturated
exposure (a lower bound: still the brightest in the image); a pixel dark in
every bracket gets that of the longest exposure (an upper bound, possibly 0,
which the skyline then flags dark). `method='debevec'` instead
hands 8-bit brackets to OpenCV's MergeDebevec with a linear camera response.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from skynav_skyline.errors import SkylineError

from .features import decode

#: Relative weight floor of a trusted value at the ends of the range (the hat never reaches 0 for trusted values).
HAT_WEIGHT_FLOOR = 1e-3


def _check_brackets(images: Sequence[np.ndarray], exposure_times: Sequence[float]) -> np.ndarray:
    """Return the exposure times (s) as an array after checking them against the images; raise ValueError otherwise."""
    times = np.asarray(exposure_times, float)
    if len(images) == 0:
        raise SkylineError('need at least one bracket')
    if times.shape != (len(images),):
        raise SkylineError(f'{len(images)} brackets but {times.size} exposure times')
    if not np.all(np.isfinite(times) & (times > 0)):
        raise SkylineError(f'exposure times must be finite and positive, got {times}')
    shapes = {np.shape(image) for image in images}
    if len(shapes) != 1:
        raise SkylineError(f'brackets differ in shape: {sorted(shapes)}')
    return times


def merge_brackets(
    images: Sequence[np.ndarray],
    exposure_times: Sequence[float],
    encoding: str = 'mono8',
    black_level: float = 0.0,
    method: str = 'linear',
) -> np.ndarray:
    """Return the float32 linear radiance (counts per second of exposure) merged from brackets of one channel.

    `images` are raw arrays of one `encoding` ('mono8', 'mono16' or '32FC1'),
    `exposure_times` their exposure times (s). `method` 'linear' (any
    encoding, black level honoured) or 'debevec' (OpenCV, mono8, zero black level).
    """
    times = _check_brackets(images, exposure_times)
    if method == 'debevec':
        return _merge_debevec(images, times, encoding, black_level)
    if method != 'linear':
        raise SkylineError(f"unknown merge method {method!r}; expected 'linear' or 'debevec'")
    channels = [decode(image, encoding, black_level) for image in images]
    estimates = np.stack([c.linear / np.float32(t) for c, t in zip(channels, times)])
    trusted = np.stack([c.trusted for c in channels])
    valid = np.stack([~c.invalid for c in channels])
    if encoding == '32FC1':
        weights = trusted.astype(np.float32)
    else:
        full = np.float32(np.iinfo(np.asarray(images[0]).dtype).max - black_level)
        level = np.stack([c.linear for c in channels]) / full  # 0..1 of the usable range
        weights = np.where(trusted, np.maximum(1 - np.abs(2 * level - 1), HAT_WEIGHT_FLOOR), 0).astype(np.float32)
    weight_sum = weights.sum(axis=0)
    with np.errstate(invalid='ignore', divide='ignore'):
        merged = (weights * estimates).sum(axis=0) / weight_sum
    saturated = np.stack([c.saturated for c in channels])
    longest = estimates[int(np.argmax(times))]
    # No trusted bracket: a saturated one bounds the radiance from below (take the largest bound),
    # otherwise all are dark or invalid and the longest exposure bounds it from above.
    lower_bound = np.where(saturated, estimates, -np.inf).max(axis=0)
    fallback = np.where(saturated.any(axis=0), lower_bound, np.maximum(longest, 0))
    untrusted = weight_sum == 0
    merged = np.where(untrusted, fallback, merged)
    merged = np.where(valid.any(axis=0), merged, np.nan)
    return merged.astype(np.float32)


def _merge_debevec(images: Sequence[np.ndarray], times: np.ndarray, encoding: str, black_level: float) -> np.ndarray:
    """Return the float32 radiance of 8-bit brackets merged by OpenCV's MergeDebevec with a linear response."""

    if encoding != 'mono8' or black_level != 0:
        raise SkylineError("the 'debevec' merge takes mono8 brackets with zero black level")
    stack = [np.ascontiguousarray(decode(image, encoding).linear.astype(np.uint8)) for image in images]
    response = np.arange(256, dtype=np.float32).reshape(256, 1)
    response[0] = 1.0  # log of the response must stay finite; OpenCV's weights ignore value 0 anyway
    return cv2.createMergeDebevec().process(stack, times.astype(np.float32), response).astype(np.float32)
