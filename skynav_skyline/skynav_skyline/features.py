# SPDX-License-Identifier: Apache-2.0
"""Decoding of UV/green images into trusted linear values and normalised log features.

Encodings (docs/interfaces.md): `mono8` and `mono16` are linear counts with a black
level (default 0) and the encoding's maximum means saturated; `32FC1` is linear
radiance in one fixed unit for both channels, NaN/inf mark invalid pixels.

Per-image normalisation (all encodings alike). Each channel of an 8/16-bit image
has its own unknown exposure and gain, so log UV and log G of one image are
shifted by unknown per-channel constants. Every channel of every image is
therefore divided by its own *reference level*: a high percentile (default the
90th) of its linear values over the image circle, saturated pixels taken at
their clipped value and dark ones at the dark floor. The features are

    x = log(UV / UV_ref),   y = log(G / G_ref)    (natural log, dimensionless)

An upward-looking camera sees mostly sky, so the reference lies in the sky and
the features say "how bright relative to the bright sky of this image"; the
contrast x - y then is log(UV/G) relative to the sky's own colour. This is
invariant to any per-channel gain, identical for `mono8`, `mono16` and `32FC1`
views of one scene (up to quantisation), and the same function is used for
learning and for classification, so a global threshold learned on one encoding
holds for the others. 32FC1 is normalised too: its absolute radiance would let
a global threshold depend on the time of day, which is what the skyline must
not do. The price: the reference leaves the sky when less than
(100 - percentile) % of the image circle is sky (e.g. under a tree canopy), or
when more than that share is saturated (then the reference is the saturation
level); local methods are unaffected by the first, since they only shift.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from skynav_skyline.errors import SkylineError

#: Largest raw value of each integer encoding (counts); it means saturated.
ENCODING_MAX_COUNTS: dict[str, int] = {'mono8': 255, 'mono16': 65535}
#: Encodings the skyline accepts (docs/interfaces.md, input topics).
ENCODINGS: tuple[str, ...] = ('mono8', 'mono16', '32FC1')
#: Dark margin above the black level (counts): 2 counts of an 8-bit image, scaled to the encoding's full range.
DARK_MARGIN_COUNTS: dict[str, float] = {'mono8': 2.0, 'mono16': 2.0 * 257}
#: Default percentile (%) of a channel's linear values inside the image circle that becomes its reference level.
REFERENCE_PERCENTILE = 90.0

_EXPECTED_DTYPES = {'mono8': np.uint8, 'mono16': np.uint16}


@dataclass(frozen=True)
class Channel:
    """One decoded image channel: linear values and per-pixel trust flags."""

    linear: np.ndarray  # float32 (H, W), black level removed: counts (mono8/16) or radiance units (32FC1)
    saturated: np.ndarray  # bool (H, W): raw value at the encoding maximum
    dark: np.ndarray  # bool (H, W): raw value at or below black level + dark margin
    invalid: np.ndarray  # bool (H, W): NaN or inf (32FC1 only)
    floor: float  # linear value (same unit as `linear`) that dark pixels are clamped to for the log
    counts: np.ndarray | None = None  # the raw integer image of mono8/mono16 (for exact percentiles by counting)
    black_level: float = 0.0

    @property
    def trusted(self) -> np.ndarray:
        """Return the bool mask of pixels that are neither saturated, dark nor invalid."""
        return ~(self.saturated | self.dark | self.invalid)


def _as_image(image: np.ndarray, encoding: str) -> np.ndarray:
    """Return `image` as a 2-D array checked against `encoding`; raise ValueError otherwise."""
    if encoding not in ENCODINGS:
        raise SkylineError(f'unknown image encoding {encoding!r}; expected one of {", ".join(ENCODINGS)}')
    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim != 2 or image.size == 0:
        raise SkylineError(f'{encoding} image must be a non-empty single-channel 2-D array, got shape {image.shape}')
    if encoding in _EXPECTED_DTYPES:
        if image.dtype != _EXPECTED_DTYPES[encoding]:
            raise SkylineError(
                f'{encoding} image must have dtype {np.dtype(_EXPECTED_DTYPES[encoding])}, got {image.dtype}'
            )
    elif not np.issubdtype(image.dtype, np.floating):
        raise SkylineError(f'32FC1 image must have a floating dtype, got {image.dtype}')
    return image


def decode(image: np.ndarray, encoding: str, black_level: float = 0.0, dark_margin: float | None = None) -> Channel:
    """Return the linear values (counts or radiance, black level removed) and trust flags of one channel image.

    `black_level` is in counts for mono8/mono16 and in radiance units for 32FC1.
    `dark_margin` (same unit) defaults to DARK_MARGIN_COUNTS for integer
    encodings and to 0 for 32FC1: a pixel is dark when raw <= black_level + margin.
    """
    image = _as_image(image, encoding)
    black_level = float(black_level)
    if not np.isfinite(black_level) or black_level < 0:
        raise SkylineError(f'black level must be finite and non-negative, got {black_level}')
    if encoding in ENCODING_MAX_COUNTS:
        full = ENCODING_MAX_COUNTS[encoding]
        margin = DARK_MARGIN_COUNTS[encoding] if dark_margin is None else float(dark_margin)
        if black_level + margin >= full:
            raise SkylineError(f'black level {black_level} + dark margin {margin} leaves no range in {encoding}')
        raw = image.astype(np.float32)
        saturated = image >= full
        dark = raw <= black_level + margin
        invalid = np.zeros(image.shape, bool)
        linear = raw - np.float32(black_level)
        floor = max(margin, 1.0)  # a dark pixel holds at most `margin` counts; at least one count for the log
    else:
        margin = 0.0 if dark_margin is None else float(dark_margin)
        linear = image.astype(np.float32) - np.float32(black_level)
        invalid = ~np.isfinite(linear)
        saturated = np.zeros(image.shape, bool)
        dark = ~invalid & (linear <= margin)
        if margin > 0:
            floor = margin  # a dark pixel holds at most the margin
        else:
            # Without a margin, dark pixels (<= black level) are dimmer than the dimmest trusted one: clamp to it.
            floor = float(np.min(linear, where=~(invalid | dark), initial=np.inf))
            floor = floor if np.isfinite(floor) else float(np.finfo(np.float32).tiny)
        if invalid.any():
            linear[invalid] = 0  # `linear` is a fresh array
    counts = image if encoding in ENCODING_MAX_COUNTS else None
    return Channel(linear.astype(np.float32, copy=False), saturated, dark, invalid, float(floor), counts, black_level)


def reference_level(
    channel: Channel, circle: np.ndarray, percentile: float = REFERENCE_PERCENTILE, stride: int = 1
) -> float:
    """Return a channel's reference level (its unit): the `percentile` of its finite linear values in the circle.

    With `stride` > 1 only every stride-th column counts: a sample for large images.
    """
    if not 0 < percentile <= 100:
        raise SkylineError(f'reference percentile must be in (0, 100], got {percentile}')
    every = (slice(None), slice(None, None, stride))
    usable = circle[every] if channel.counts is not None else circle[every] & ~channel.invalid[every]
    if not usable.any():
        raise SkylineError('no finite pixel inside the image circle (all NaN/inf or empty circle)')
    if channel.counts is not None:
        # Integer images (never invalid): the same inverted-CDF percentile, counted in a histogram of raw values.
        counts = channel.counts[every]
        values = (counts if usable.all() else counts[usable]).ravel()
        rank = _inverted_cdf_rank(percentile, values.size)
        raw = int(np.searchsorted(np.cumsum(np.bincount(values)), rank, side='right'))
        return float(max(np.float32(raw - channel.black_level), np.float32(channel.floor)))
    values = np.maximum(channel.linear[every][usable], np.float32(channel.floor))
    rank = _inverted_cdf_rank(percentile, values.size)
    return float(np.partition(values, rank)[rank])


def _inverted_cdf_rank(percentile: float, size: int) -> int:
    """Return the 0-based rank of the inverted-CDF `percentile` (%) among `size` sorted values."""
    return max(int(np.ceil(percentile / 100 * size)), 1) - 1


def log_feature(
    channel: Channel, circle: np.ndarray, percentile: float = REFERENCE_PERCENTILE, stride: int = 1
) -> np.ndarray:
    """Return float32 log(linear / reference level) (dimensionless, natural log); dark clamped, invalid 0."""
    reference = reference_level(channel, circle, percentile, stride)
    if channel.counts is not None:  # integer images: the log of every possible value, looked up
        table = _log_table(channel.counts.dtype.str, channel.black_level, channel.floor)
        return table.take(channel.counts) - np.float32(np.log(reference))
    clamped = np.maximum(channel.linear, np.float32(channel.floor))
    feature = np.log(clamped / np.float32(reference), dtype=np.float32)
    feature[channel.invalid] = 0.0
    return feature


@lru_cache(maxsize=16)
def _log_table(dtype: str, black_level: float, floor: float) -> np.ndarray:
    """Return log(max(raw - black level, floor)) (float32) for every raw value of an integer dtype."""
    raw = np.arange(np.iinfo(np.dtype(dtype)).max + 1, dtype=np.float32)
    return np.log(np.maximum(raw - np.float32(black_level), np.float32(floor)), dtype=np.float32)


@dataclass(frozen=True)
class Features:
    """Normalised log features of one UV/green image pair and the trust flags they came with."""

    uv: Channel
    green: Channel | None
    x: np.ndarray  # float32 (H, W): log(UV / UV reference)
    y: np.ndarray | None  # float32 (H, W): log(G / G reference); None when only UV was decoded
    reference_percentile: float

    @property
    def shape(self) -> tuple[int, int]:
        """Return the image shape (rows, columns)."""
        return self.x.shape

    def sky_by_rule(self, circle: np.ndarray) -> np.ndarray:
        """Return pixels classified sky whatever the threshold: UV saturated inside the circle."""
        return circle & self.uv.saturated

    def by_threshold(self, circle: np.ndarray, uses_green: bool) -> np.ndarray:
        """Return pixels whose class the threshold decides: UV trusted (and green finite if used), in the circle."""
        mask = circle & self.uv.trusted
        if uses_green:
            mask &= ~self._green().invalid
        return mask

    def trusted(self, circle: np.ndarray, uses_green: bool) -> np.ndarray:
        """Return pixels trusted in every channel used (for histograms): in the circle, none flagged."""
        mask = circle & self.uv.trusted
        if uses_green:
            mask &= self._green().trusted
        return mask

    def _green(self) -> Channel:
        """Return the green channel; ValueError if it was not decoded."""
        if self.green is None:
            raise SkylineError('the green channel is needed but was not decoded')
        return self.green


def extract_features(
    uv: np.ndarray,
    green: np.ndarray | None,
    encoding_uv: str,
    encoding_green: str | None,
    circle: np.ndarray,
    black_level: tuple[float, float] = (0.0, 0.0),
    reference_percentile: float = REFERENCE_PERCENTILE,
    dark_margin: float | None = None,
    stride: int = 1,
) -> Features:
    """Return the normalised log features (dimensionless) of a UV image and an optional green image.

    `black_level` is (UV, green) in each channel's raw unit. Raises ValueError
    for an unknown encoding, mismatched shapes or no finite pixel in the circle.
    """
    uv_channel = decode(uv, encoding_uv, black_level[0], dark_margin)
    circle = _check_circle(circle, uv_channel.linear.shape)
    green_channel = None
    if green is not None:
        if encoding_green is None:
            raise SkylineError('a green image needs its encoding')
        green_channel = decode(green, encoding_green, black_level[1], dark_margin)
        if green_channel.linear.shape != uv_channel.linear.shape:
            raise SkylineError(
                f'UV image {uv_channel.linear.shape} and green image {green_channel.linear.shape} differ in shape'
            )
    x = log_feature(uv_channel, circle, reference_percentile, stride)
    y = None if green_channel is None else log_feature(green_channel, circle, reference_percentile, stride)
    return Features(uv_channel, green_channel, x, y, float(reference_percentile))


def _check_circle(circle: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """Return the image-circle mask as bool after checking its shape; raise ValueError otherwise."""
    circle = np.asarray(circle)
    if circle.shape != tuple(shape):
        raise SkylineError(f'image circle mask {circle.shape} and image {tuple(shape)} differ in shape')
    return circle.astype(bool, copy=False)
