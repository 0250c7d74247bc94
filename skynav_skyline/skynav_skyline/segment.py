# SPDX-License-Identifier: Apache-2.0
"""Skyline segmentation: one entry point for the global, whole-image and per-sector threshold methods.

Methods: 'global' (learned angle and threshold), 'otsu' and 'min-error' (one
threshold per image from the histogram of the contrast inside the image
circle), 'sector-otsu' and 'sector-min-error' (one threshold per azimuth
sector, interpolated between sector centres), and 'discriminant': each image's
own linear discriminant of its channels' logs, learned from sky and ground
exemplars where an upward view puts them (discriminant.py), thresholded per
sector within SECTOR_DEVIATION spreads of the image's own threshold; without
enough exemplars it falls back to 'sector-min-error' on the learned contrast.
The same methods segment a colour camera's frames (segment_colour): the
discriminant on all three channels, the others on blue for UV and green.

Fit check. A threshold method of the UV/green contrast (its angle and global
threshold learned on some camera's recordings) may not fit the camera at
hand. With a finite `max_disagreement` each image is segmented by its own
discriminant too, and where the two masks disagree on more than that share of
the image circle the discriminant's is taken: the learned thresholds do not
fit this image. A stream of exposures may skip the check on some
(`segment`'s check_fit; FitCheckSchedule says which get it).

Exposure check. A frame more than half saturated, or nine tenths dark, in the image circle is refused
(exposure.ExposureError): the saturated-is-sky and dark-is-ground rules, not the image, would decide its mask.

Bimodality test. A histogram split is *bimodal* when it has at least
MIN_SECTOR_PIXELS trusted pixels, Otsu's separability (between-class over
total variance at the chosen cut; about 0.64 for one Gaussian, 0.75 for a
uniform ramp such as a smooth sky gradient, towards 1 for two well-separated
modes) reaches `min_separability`, and, for a sector and when the reference
threshold is trusted, its two class means lie on opposite sides of that
reference. The last condition rejects sectors with two modes of one class:
the sun against the sky in HDR input, sunlit against shaded ground.

Reference and fallback. The reference threshold is the whole image's own
threshold when the whole image is bimodal (trusted), else the configured
global threshold if any (trusted), else the whole image's threshold all the
same (not trusted: the class-mean condition is then skipped, since a whole
image that fails the test usually means the illumination changes so much with
azimuth that no single threshold fits, which is the case sectors are for). A
sector that is not bimodal takes its threshold from the nearest bimodal
sectors on either side, interpolated linearly in azimuth (circularly); with
no bimodal sector at all every sector uses the reference. For the whole-image
methods a non-bimodal image uses the configured global threshold when there
is one.

Structure. After any method, two optional steps use the shape of an upward
view (structure.py): enclosed ground that nowhere falls `hole_margin` below
its threshold becomes sky, and sky beyond a ring of ground along the rays
from the principal point becomes ground when such rings cover at least
`ring_share` of the azimuths. Both are off in SkylineParams' defaults and on
in the skyline node's (parameters.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, overload

import numpy as np

from skynav_skyline.errors import SkylineError

from . import discriminant
from .classify import CHANNEL_MODES, GROUND, SKY, UV_GREEN_CONTRAST_ANGLE, GlobalModel, project
from .exposure import check_exposure
from .features import REFERENCE_PERCENTILE, Features, decode, extract_features, log_feature
from .geometry import SectorLayout, SkylineGeometry
from .structure import RAY_COUNT, RAY_STEP, outermost_band_end, unanchored_ground
from .threshold import DEFAULT_BINS, HISTOGRAM_METHODS, HistogramSplit, bin_edges, bin_index, histogram_range

if TYPE_CHECKING:
    from skynav_core.camera import EquidistantCamera

#: Segmentation methods.
METHODS: tuple[str, ...] = ('global', 'otsu', 'min-error', 'sector-otsu', 'sector-min-error', 'discriminant')
#: The per-image discriminant method, and the method it falls back to without enough exemplars.
DISCRIMINANT, DISCRIMINANT_FALLBACK = 'discriminant', 'sector-min-error'
#: Encoding of a decoded colour frame's planes (skynav_core.colour: uint16 linear, full scale saturated).
LINEAR_ENCODING = 'mono16'

#: Default number of azimuth sectors of the sector methods.
DEFAULT_SECTORS = 16
#: Default least Otsu separability (dimensionless, 0..1) of a bimodal histogram.
MIN_SEPARABILITY = 0.8
#: Least trusted pixels of a sector for its own threshold.
MIN_SECTOR_PIXELS = 100
#: Least trusted pixels inside the image circle for any segmentation; fewer raise ValueError.
MIN_TRUSTED_PIXELS = 100
#: Most pixels the per-image statistics (reference levels, histograms) use: larger images are sampled evenly.
#: Every pixel is still classified; 320x240 fish-eye images (about 45,000 pixels in the circle) use them all.
STATISTICS_SAMPLE = 60000
#: Relative margin (dimensionless) around the sector thresholds' span that covers float32 rounding.
_INTERPOLATION_ROUNDING = 1e-5
#: Default least width (degrees of off-axis angle, along a ray) of a band of ground in the ground-ring step.
RING_WIDTH_DEG = 2.0


@dataclass(frozen=True)
class SkylineParams:
    """Settings of the skyline segmentation."""

    method: str = 'sector-otsu'  # one of METHODS
    channels: str = 'uv'  # 'uv' (angle 0) or 'uv-green'
    angle: float | None = None  # projection angle (rad); None: 0 for 'uv', UV_GREEN_CONTRAST_ANGLE for 'uv-green'
    threshold: float | None = None  # global threshold (normalised log units); needed by 'global', else fallback
    sectors: int = DEFAULT_SECTORS  # azimuth sectors of the sector methods
    bins: int = DEFAULT_BINS  # histogram bins of the local methods
    black_level: tuple[float, float] = (0.0, 0.0)  # (UV, green) in raw units (counts, or radiance for 32FC1)
    reference_percentile: float = REFERENCE_PERCENTILE  # per-channel normalisation percentile (%)
    min_separability: float = MIN_SEPARABILITY  # bimodality test, Otsu separability in [0, 1]
    max_deviation: float = math.inf  # local thresholds stay within this of the global one (normalised log units)
    hole_margin: float = 0.0  # enclosed ground nowhere this far below its threshold becomes sky (log units); 0: off
    ring_share: float = math.inf  # share of azimuths (0..1) ringed by ground that cuts the sky beyond; above 1: off
    ring_width_deg: float = RING_WIDTH_DEG  # least width of such a band of ground along a ray (degrees)
    max_disagreement: float = math.inf  # a threshold method gives way to the discriminant beyond this share (0..1)

    def __post_init__(self) -> None:
        """Check the settings (ValueError) and store the black level as a (UV, green) pair."""
        if self.method not in METHODS:
            raise SkylineError(f'unknown skyline method {self.method!r}; expected one of {", ".join(METHODS)}')
        if self.channels not in CHANNEL_MODES:
            raise SkylineError(f'unknown channel mode {self.channels!r}; expected one of {", ".join(CHANNEL_MODES)}')
        if self.channels == 'uv' and self.angle not in (None, 0, 0.0):
            raise SkylineError(f'UV-only means projection angle 0, got {self.angle}')
        if self.angle is not None and not np.isfinite(self.angle):
            raise SkylineError(f'projection angle must be finite, got {self.angle}')
        if self.method == 'global' and self.threshold is None:
            raise SkylineError("method 'global' needs a learned threshold")
        if self.threshold is not None and not np.isfinite(self.threshold):
            raise SkylineError(f'threshold must be finite, got {self.threshold}')
        if int(self.sectors) < 1 or int(self.bins) < 2:
            raise SkylineError(f'need at least 1 sector and 2 bins, got {self.sectors} and {self.bins}')
        if not 0 <= self.min_separability <= 1:
            raise SkylineError(f'min_separability must be in [0, 1], got {self.min_separability}')
        if not 0 < self.reference_percentile <= 100:
            raise SkylineError(f'reference percentile must be in (0, 100], got {self.reference_percentile}')
        if not self.hole_margin >= 0:
            raise SkylineError(f'hole_margin must be at least 0 (0: off), got {self.hole_margin}')
        if not self.ring_share > 0:
            raise SkylineError(f'ring_share must be above 0 (above 1: off), got {self.ring_share}')
        if not self.max_disagreement >= 0:
            raise SkylineError(f'max_disagreement must be at least 0 (inf: off), got {self.max_disagreement}')
        if not (self.ring_width_deg > 0 and math.isfinite(self.ring_width_deg)):
            raise SkylineError(f'ring_width_deg must be positive and finite, got {self.ring_width_deg}')
        black = np.broadcast_to(np.asarray(self.black_level, float), (2,))
        object.__setattr__(self, 'black_level', (float(black[0]), float(black[1])))

    @property
    def uses_green(self) -> bool:
        """Return whether the green channel enters the contrast."""
        return self.channels == 'uv-green'

    @property
    def fills_holes(self) -> bool:
        """Return whether enclosed ground near the threshold becomes sky."""
        return self.hole_margin > 0

    @property
    def cuts_rings(self) -> bool:
        """Return whether sky beyond a ring of ground becomes ground."""
        return self.ring_share <= 1

    @property
    def checks_fit(self) -> bool:
        """Return whether a threshold method of the UV/green contrast is checked against the image's discriminant."""
        return self.method != DISCRIMINANT and self.uses_green and math.isfinite(self.max_disagreement)

    @property
    def projection_angle(self) -> float:
        """Return the projection angle (rad) actually used."""
        if self.channels == 'uv':
            return 0.0
        return UV_GREEN_CONTRAST_ANGLE if self.angle is None else float(self.angle)

    @classmethod
    def from_model(cls, model: GlobalModel, method: str = 'global', **changes) -> SkylineParams:
        """Return settings that use a learned model's channels, angle, threshold and normalisation."""
        return cls(
            method=method,
            channels=model.channels,
            angle=None if model.channels == 'uv' else model.angle,
            threshold=model.threshold,
            reference_percentile=model.reference_percentile,
            **changes,
        )


@dataclass(frozen=True)
class SectorThresholds:
    """Per-sector thresholds after the bimodality test and fallback."""

    thresholds: np.ndarray  # (n,) thresholds used (contrast unit)
    own: HistogramSplit  # each sector's own split
    bimodal: np.ndarray  # bool (n,): the sector passed the bimodality test
    reference: float  # the reference threshold of the test and the last fallback


@dataclass(frozen=True)
class Segmentation:
    """A skyline mask and how it was made."""

    mask: np.ndarray  # uint8 (H, W): 255 sky, 0 ground (0 outside the image circle)
    contrast: np.ndarray  # float32 (H, W): projected contrast s (log units)
    threshold: np.ndarray | float  # the threshold (contrast unit): a scalar or a per-pixel map
    image_split: HistogramSplit | None  # the whole image's split (local methods)
    sectors: SectorThresholds | None  # per-sector thresholds (sector methods)


def is_bimodal(
    split: HistogramSplit,
    min_separability: float = MIN_SEPARABILITY,
    reference: float | None = None,
    min_pixels: int = MIN_SECTOR_PIXELS,
) -> np.ndarray:
    """Return whether each split is bimodal: enough pixels, separability, class means either side of `reference`."""
    ok = (split.count >= min_pixels) & (split.separability >= min_separability)
    if reference is not None:
        with np.errstate(invalid='ignore'):
            ok = ok & (split.mean_low < reference) & (split.mean_high > reference)
    return np.asarray(ok, bool)


def sector_histograms(
    values: np.ndarray, sector: np.ndarray, count: int, bins: int, value_range: tuple[float, float]
) -> np.ndarray:
    """Return float64 histograms (count, bins) of `values`, one per sector index in `sector` (same shape)."""
    cells = sector * bins + bin_index(values, bins, value_range)
    return np.bincount(cells, minlength=count * bins).reshape(count, bins).astype(np.float64)


def fall_back(
    own: HistogramSplit,
    reference: float,
    min_separability: float = MIN_SEPARABILITY,
    min_pixels: int = MIN_SECTOR_PIXELS,
    test_reference: bool = True,
) -> SectorThresholds:
    """Return the sector thresholds (contrast unit) of the sectors' own splits after the bimodality test and fallback.

    A sector that fails the test takes the threshold interpolated (circularly in azimuth)
    between the nearest bimodal sectors; with none, every sector takes `reference`.
    """
    count = np.size(own.threshold)
    bimodal = is_bimodal(own, min_separability, reference if test_reference else None, min_pixels)
    if bimodal.any():
        good = np.flatnonzero(bimodal)
        thresholds = np.interp(np.arange(count), good, own.threshold[good], period=count)
    else:
        thresholds = np.full(count, float(reference))
    return SectorThresholds(thresholds, own, bimodal, float(reference))


def sector_thresholds(
    contrast: np.ndarray,
    trusted: np.ndarray,
    layout: SectorLayout,
    reference: float,
    method: str = 'otsu',
    bins: int = DEFAULT_BINS,
    value_range: tuple[float, float] | None = None,
    min_separability: float = MIN_SEPARABILITY,
    min_pixels: int = MIN_SECTOR_PIXELS,
    test_reference: bool = True,
) -> SectorThresholds:
    """Return one threshold (contrast unit) per azimuth sector from the histograms of the trusted pixels, with fallback.

    `reference` is the last fallback and, if `test_reference`, the value each
    bimodal sector's class means must lie on either side of.
    """
    if method not in HISTOGRAM_METHODS:
        raise SkylineError(f'unknown histogram method {method!r}; expected one of {", ".join(HISTOGRAM_METHODS)}')
    values = contrast[trusted]
    if values.size == 0:
        raise SkylineError('no trusted pixel to threshold')
    value_range = histogram_range(values) if value_range is None else value_range
    counts = sector_histograms(values, layout.index[trusted], layout.count, bins, value_range)
    own = HISTOGRAM_METHODS[method](counts, bin_edges(bins, value_range))
    return fall_back(own, reference, min_separability, min_pixels, test_reference)


def above_sector_thresholds(contrast: np.ndarray, layout: SectorLayout, thresholds: np.ndarray) -> np.ndarray:
    """Return contrast > the sector thresholds interpolated in azimuth, pixel by pixel (bool, contrast's shape).

    The interpolated threshold of a pixel lies between the least and the greatest
    sector threshold, so only pixels whose contrast falls in that band need it.
    """
    thresholds = np.asarray(thresholds, np.float64)
    low, high = float(thresholds.min()), float(thresholds.max())
    margin = _INTERPOLATION_ROUNDING * (1.0 + max(abs(low), abs(high)))  # float32 rounding of the interpolation
    above = contrast > high + margin
    band = np.flatnonzero((contrast > low - margin) & ~above)
    if band.size:
        flat = above.reshape(-1)
        flat[band] = contrast.reshape(-1)[band] > layout.interpolate(thresholds, band)
    return above


class FitCheckSchedule:
    """Which exposures of a stream get the fit check: one in `period`, and each one while the last check came near
    the bound (disagreement above half of `max_disagreement`).

    The check asks whether the learned thresholds fit the camera at hand in this light, which changes over seconds,
    not from one frame to the next; checking every exposure costs about twice the segmentation itself.
    """

    def __init__(self, period: int, max_disagreement: float) -> None:
        """Check one exposure in `period` (1: every one) against the fit check's bound."""
        if period < 1:
            raise SkylineError(f'the fit check period must be at least 1 exposure, got {period}')
        self.period, self.watch = int(period), 0.5 * max_disagreement
        self.wait = 0  # exposures until the next check

    def due(self) -> bool:
        """Return whether the next exposure gets the check."""
        return self.wait <= 0

    def done(self, disagreement: float | None) -> None:
        """Note an exposure's check (its disagreement; None: it had none)."""
        if disagreement is None:
            self.wait -= 1
        else:
            self.wait = 0 if disagreement > self.watch else self.period - 1


class SkylineSegmenter:
    """Sky/ground segmentation for one camera geometry; build once, call per frame."""

    def __init__(self, geometry: SkylineGeometry | np.ndarray | EquidistantCamera, params: SkylineParams | None = None):
        """Keep the geometry (a SkylineGeometry, a camera model, or a bool image-circle mask) and the settings."""
        if isinstance(geometry, SkylineGeometry):
            self.geometry = geometry
        elif isinstance(geometry, np.ndarray):
            self.geometry = SkylineGeometry.from_circle(geometry)
        else:
            self.geometry = SkylineGeometry.from_camera(geometry)
        self.params = SkylineParams() if params is None else params
        # Work on the pixels inside the image circle only: one row of them, scattered back at the end.
        self._row, self._pixels = self.geometry.packed()
        self._stride = max(1, -(-self._pixels.size // STATISTICS_SAMPLE))  # of the statistics' sample
        p = self.params
        if p.method == DISCRIMINANT:
            # The discriminant's projection is in spreads with the image's own threshold at 0 (discriminant.py);
            # an image without a model falls back to the learned contrast's sector thresholds.
            self._projected = replace(
                p,
                method=DISCRIMINANT_FALLBACK,
                threshold=0.0,
                max_deviation=discriminant.SECTOR_DEVIATION,
                hole_margin=discriminant.HOLE_MARGIN if p.fills_holes else 0.0,
            )
            self._fallback = replace(p, method=DISCRIMINANT_FALLBACK)
            self._first_pass = replace(self._projected, hole_margin=0.0, ring_share=math.inf)  # labels for the refit
            radius = self._row.radius()[0]
            self._inner_half = radius <= discriminant.INNER_RADIUS_SHARE * radius.max()
        if p.method.startswith('sector-') or p.method == DISCRIMINANT:
            self._row.sectors(p.sectors)  # precompute now, not on the first frame
        # the learned thresholds give way to the image's own discriminant where they do not fit the camera
        self._fit_check: SkylineSegmenter | None = None
        self.disagreement: float | None = None  # share of the circle the last checked pair's masks disagree on
        if p.checks_fit:
            self._fit_check = SkylineSegmenter(
                self.geometry, replace(p, method=DISCRIMINANT, max_disagreement=math.inf)
            )
        if self.params.fills_holes:
            # The enclosed-ground step works on the image circle's bounding box: its circle, the row position of
            # each of its pixels (-1 outside the circle) for the pixels it fills, and the circle's inside off the rim.
            circle = self.geometry.circle
            rows, columns = np.flatnonzero(circle.any(axis=1)), np.flatnonzero(circle.any(axis=0))
            self._box = (slice(rows[0], rows[-1] + 1), slice(columns[0], columns[-1] + 1))
            self._box_circle = np.ascontiguousarray(circle[self._box])
            self._row_position = np.full(self._box_circle.shape, -1, np.intp)
            self._row_position[self._box_circle] = np.arange(self._pixels.size)
            inner = np.ones(self.geometry.shape, bool)  # False on the circle's rim
            inner.reshape(-1)[self.geometry.rim()] = False
            self._inner = np.ascontiguousarray(inner[self._box])
        if self.params.cuts_rings:
            self._rays = self.geometry.rays(RAY_COUNT, RAY_STEP)  # ValueError without a camera model
            # each ray sample reads the row position of its nearest pixel (-1: outside the circle or the image)
            position = np.full(self.geometry.shape, -1, np.intp)
            position.reshape(-1)[self._pixels] = np.arange(self._pixels.size)
            u, v = np.rint(self._rays.map_u).astype(np.intp), np.rint(self._rays.map_v).astype(np.intp)
            on_image = (u >= 0) & (u < position.shape[1]) & (v >= 0) & (v < position.shape[0])
            sample = np.where(on_image, position[np.where(on_image, v, 0), np.where(on_image, u, 0)], -1)
            self._ray_inside = sample >= 0
            self._ray_sample = np.maximum(sample, 0)
            self._ray_index = self._row.sectors(RAY_COUNT).index
            self._ray_radius = self._row.radius().astype(np.float32)
            self._ring_samples = max(
                1, math.ceil(math.radians(self.params.ring_width_deg) * self._rays.samples_per_radian)
            )

    def features(
        self, uv: np.ndarray, green: np.ndarray | None, encoding_uv: str, encoding_green: str | None = None
    ) -> Features:
        """Return the normalised log features of an image pair (green ignored in 'uv' mode, its shape still checked)."""
        p = self.params
        if p.uses_green and green is None:
            raise SkylineError("channel mode 'uv-green' needs the green image")
        if green is not None and np.shape(green)[:2] != np.shape(uv)[:2]:
            raise SkylineError(f'UV image {np.shape(uv)} and green image {np.shape(green)} differ in shape')
        return extract_features(
            uv,
            green if p.uses_green else None,
            encoding_uv,
            encoding_green,
            self.geometry.circle,
            p.black_level,
            p.reference_percentile,
        )

    def _bounded(self, thresholds: np.ndarray, p: SkylineParams) -> np.ndarray:
        """Return local thresholds kept within max_deviation of the global threshold of `p` (when there is one)."""
        if p.threshold is None or not math.isfinite(p.max_deviation):
            return thresholds
        return np.clip(thresholds, p.threshold - p.max_deviation, p.threshold + p.max_deviation)

    @overload
    def _pack(self, image: np.ndarray, encoding: str | None) -> np.ndarray: ...

    @overload
    def _pack(self, image: None, encoding: str | None) -> None: ...

    def _pack(self, image: np.ndarray | None, encoding: str | None) -> np.ndarray | None:
        """Return the image-circle pixels of an image as one row, after checking its shape."""
        if image is None:
            return None
        image = np.asarray(image)
        if image.ndim == 3 and image.shape[2] == 1:
            image = image[:, :, 0]
        if image.shape != self.geometry.shape:
            raise SkylineError(f'{encoding} image {image.shape} and image circle {self.geometry.shape} differ in shape')
        return image[self.geometry.circle][None]

    def _scatter(self, row: np.ndarray, outside: float | int) -> np.ndarray:
        """Return an image with `row` at the image-circle pixels and `outside` elsewhere."""
        image = np.full(self.geometry.shape, outside, row.dtype)
        image[self.geometry.circle] = row.ravel()
        return image

    def run(
        self, uv: np.ndarray, green: np.ndarray | None, encoding_uv: str, encoding_green: str | None = None
    ) -> Segmentation:
        """Return the skyline segmentation of one UV/green image pair (raw arrays and their encodings)."""
        row = self._run_row(uv, green, encoding_uv, encoding_green)
        threshold = row.threshold
        if row.sectors is not None:
            assert isinstance(row.threshold, np.ndarray)  # the sector methods' row holds one threshold per sector
            threshold = self._scatter(self._row.sectors(self.params.sectors).interpolate(row.threshold), np.nan)
        return Segmentation(
            self._scatter(row.mask, GROUND),
            self._scatter(row.contrast, np.nan),
            threshold,
            row.image_split,
            row.sectors,
        )

    def segment(
        self,
        uv: np.ndarray,
        green: np.ndarray | None,
        encoding_uv: str,
        encoding_green: str | None = None,
        check_fit: bool = True,
    ) -> np.ndarray:
        """Return the skyline mask (uint8: 255 sky, 0 ground and outside the image circle) of one image pair.

        check_fit: run the fit check on this pair (when the settings have one); its share of disagreement is
        kept in `disagreement` (None: not checked).
        """
        return self._scatter(self._run_row(uv, green, encoding_uv, encoding_green, check_fit).mask, GROUND)

    def segment_colour(self, rgb: np.ndarray) -> np.ndarray:
        """Return the skyline mask (uint8) of a colour frame: uint16 linear RGB (H, W, 3) as skynav_core.colour gives.

        The discriminant uses all three channels; the other methods the blue plane for UV and the green for green.
        """
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3:
            raise SkylineError(f'a colour frame is (height, width, 3) linear RGB, got shape {rgb.shape}')
        if self.params.method != DISCRIMINANT:
            return self.segment(rgb[..., 2], rgb[..., 1], LINEAR_ENCODING, LINEAR_ENCODING)
        if rgb.shape[:2] != self.geometry.shape:
            raise SkylineError(f'colour frame {rgb.shape[:2]} and image circle {self.geometry.shape} differ in shape')
        circle, p = self._row.circle, self.params
        pixels = np.ascontiguousarray(rgb).reshape(-1, 3).take(self._pixels, axis=0)  # (n, 3): the circle's pixels
        channels = [decode(pixels[None, :, k], LINEAR_ENCODING) for k in range(3)]
        check_exposure(channels, circle)
        logs = np.stack([log_feature(c, circle, p.reference_percentile, self._stride) for c in channels])
        trusted = circle & channels[0].trusted & channels[1].trusted & channels[2].trusted
        dark = channels[0].dark & channels[1].dark & channels[2].dark
        nothing = np.zeros_like(circle)  # no colour is sky by rule: saturated pixels are classified by their clamp

        def fallback() -> Segmentation:
            return self._threshold_row(rgb[..., 2], rgb[..., 1], LINEAR_ENCODING, LINEAR_ENCODING, self._fallback)

        # the seed model on blue and green (sky colour: blue over green), refitted on all three channels
        segmentation = self._discriminate(logs[1:], logs, trusted, circle & ~dark, nothing, dark, fallback)
        return self._scatter(segmentation.mask, GROUND)

    def _run_row(
        self,
        uv: np.ndarray,
        green: np.ndarray | None,
        encoding_uv: str,
        encoding_green: str | None = None,
        check_fit: bool = True,
    ) -> Segmentation:
        """Return the segmentation of the image-circle pixels of an image pair, as one row (see classify_row)."""
        self.disagreement = None

        def fallback() -> Segmentation:
            return self._threshold_row(uv, green, encoding_uv, encoding_green, self._fallback)

        if self.params.method != DISCRIMINANT:
            features = self._features_row(uv, green, encoding_uv, encoding_green, self.params)
            segmentation = self._threshold_features(features, self.params)
            if self._fit_check is None or not check_fit:
                return segmentation
            # the check's settings differ in the method only: the same features serve its discriminant
            own = self._fit_check._discriminate_pair(features, lambda: segmentation)  # no model: nothing to check
            self.disagreement = np.count_nonzero(own.mask != segmentation.mask) / max(own.mask.size, 1)
            return own if self.disagreement > self.params.max_disagreement else segmentation
        if not self.params.uses_green:
            # UV alone has no colour to tell bright ground from sky by (the discriminant on it was worse than the
            # learned threshold: 94.9 % against 98.5 % on the synthetic and landscape sets); it is the fallback
            return fallback()
        return self._discriminate_pair(
            self._features_row(uv, green, encoding_uv, encoding_green, self.params), fallback
        )

    def _discriminate_pair(self, features: Features, fallback: Callable[[], Segmentation]) -> Segmentation:
        """Return the segmentation of a UV/green pair's features (one row) by the image's own discriminant."""
        circle = self._row.circle
        assert features.y is not None  # the green channel is decoded in 'uv-green' mode
        logs = np.stack([features.y, features.x])  # sky colour: UV over green
        return self._discriminate(
            logs,
            logs,
            features.trusted(circle, True),
            features.by_threshold(circle, True),
            features.sky_by_rule(circle),
            features.uv.dark,
            fallback,
        )

    def _discriminate(
        self,
        seed_logs: np.ndarray,
        logs: np.ndarray,
        trusted: np.ndarray,
        decided: np.ndarray,
        by_rule: np.ndarray,
        dark: np.ndarray,
        fallback: Callable[[], Segmentation],
    ) -> Segmentation:
        """Return the segmentation of the row by the image's own discriminant (discriminant.py).

        The exemplars and the first model take log features `seed_logs` (channels, 1, n); the model refitted on
        the first segmentation's pixels (thresholded without the structure steps) takes `logs`, which may hold more
        channels; the structure steps clean the refitted model's segmentation (the first model's, if the refit
        fails). Both fits use the statistics' sample; without a first model, `fallback()`.
        """
        every = slice(None, None, self._stride)
        sample, usable = seed_logs[:, 0, every], trusted[0, every]
        sky, ground = discriminant.exemplars(sample, self._inner_half[every], usable)
        model = discriminant.fit(sample, sky, ground)
        if model is None:
            return fallback()
        contrast = model.project(seed_logs)
        first = self.classify_row(contrast, trusted, decided, by_rule, dark, self._first_pass)
        labels = first.mask.view(bool)[0, every]
        refitted = discriminant.fit(logs[:, 0, every], labels & usable, ~labels & usable)
        if refitted is not None:
            contrast = refitted.project(logs)
        return self.classify_row(contrast, trusted, decided, by_rule, dark, self._projected)

    def _features_row(
        self, uv: np.ndarray, green: np.ndarray | None, encoding_uv: str, encoding_green: str | None, p: SkylineParams
    ) -> Features:
        """Return the normalised log features of the image-circle pixels of an image pair, as one row."""
        if p.uses_green and green is None:
            raise SkylineError("channel mode 'uv-green' needs the green image")
        if green is not None and np.shape(green)[:2] != np.shape(uv)[:2]:
            raise SkylineError(f'UV image {np.shape(uv)} and green image {np.shape(green)} differ in shape')
        features = extract_features(
            self._pack(uv, encoding_uv),
            self._pack(green, encoding_green) if p.uses_green else None,
            encoding_uv,
            encoding_green,
            self._row.circle,
            p.black_level,
            p.reference_percentile,
            stride=self._stride,
        )
        check_exposure([features.uv] if features.green is None else [features.uv, features.green], self._row.circle)
        return features

    def _threshold_row(
        self, uv: np.ndarray, green: np.ndarray | None, encoding_uv: str, encoding_green: str | None, p: SkylineParams
    ) -> Segmentation:
        """Return the segmentation of an image pair's circle (one row) by the learned contrast and `p`'s method."""
        return self._threshold_features(self._features_row(uv, green, encoding_uv, encoding_green, p), p)

    def _threshold_features(self, features: Features, p: SkylineParams) -> Segmentation:
        """Return the segmentation of the circle's features (one row) by the learned contrast and `p`'s method."""
        circle = self._row.circle
        return self.classify_row(
            project(features.x, features.y, p.projection_angle),
            features.trusted(circle, p.uses_green),
            features.by_threshold(circle, p.uses_green),
            features.sky_by_rule(circle),
            features.uv.dark,
            p,
        )

    def classify_row(
        self,
        contrast: np.ndarray,
        trusted: np.ndarray,
        decided: np.ndarray,
        by_rule: np.ndarray,
        dark: np.ndarray,
        params: SkylineParams | None = None,
    ) -> Segmentation:
        """Return the segmentation of the image circle's pixels (one row) from their contrast (log units).

        The thresholds of `params`' method (default the segmenter's; a threshold method) come from the `trusted`
        pixels' histograms; `decided` pixels are sky above them, `by_rule` pixels are sky whatever the threshold,
        `dark` ones clearly ground; then the structure steps. The row's `threshold` is a scalar, or for the sector
        methods the (bounded) threshold of each sector.
        """
        p = self.params if params is None else params
        stride = self._stride
        if np.count_nonzero(trusted) < MIN_TRUSTED_PIXELS:
            raise SkylineError(
                f'fewer than {MIN_TRUSTED_PIXELS} trusted pixels inside the image circle '
                '(image dark, saturated or invalid)'
            )
        image_split = sectors = None
        if p.method == 'global':
            assert p.threshold is not None  # SkylineParams gives 'global' a threshold
            threshold: np.ndarray | float = float(p.threshold)
        else:
            sample = (slice(None), slice(None, None, stride))  # the statistics' pixels of the row
            in_sample = trusted[sample]
            values = contrast[sample][in_sample]
            value_range = histogram_range(values)
            split_method = HISTOGRAM_METHODS[p.method.removeprefix('sector-')]
            edges = bin_edges(p.bins, value_range)
            if p.method.startswith('sector-'):
                # The whole image's histogram is the sum of its sectors': both split in one call.
                sector = self._row.sectors(p.sectors).sampled(stride).index[in_sample]
                counts = sector_histograms(values, sector, p.sectors, p.bins, value_range)
                splits = split_method(np.vstack([counts, counts.sum(axis=0)]), edges)
                image_split, own = splits.take(-1), splits.take(slice(0, -1))
            else:
                counts = np.bincount(bin_index(values, p.bins, value_range), minlength=p.bins).astype(np.float64)
                image_split = split_method(counts, edges)
            whole = float(image_split.threshold)
            image_bimodal = bool(is_bimodal(image_split, p.min_separability, None, MIN_TRUSTED_PIXELS))
            reference = whole if image_bimodal or p.threshold is None else float(p.threshold)
            trusted_reference = image_bimodal or p.threshold is not None
            if p.method.startswith('sector-'):
                sectors = fall_back(own, reference, p.min_separability, MIN_SECTOR_PIXELS // stride, trusted_reference)
                threshold = self._bounded(sectors.thresholds, p)
            else:
                threshold = float(self._bounded(np.array([reference]), p)[0])
        if sectors is None:
            above = contrast > threshold
        else:
            assert isinstance(threshold, np.ndarray)  # one per sector
            above = above_sector_thresholds(contrast, self._row.sectors(p.sectors), threshold)
        sky = by_rule | (decided & above)
        if p.fills_holes or p.cuts_rings:
            strong = self._clearly_ground(dark, contrast, threshold, sectors, decided, p) if p.fills_holes else None
            sky = self._apply_structure(sky, strong)
        mask = sky.view(np.uint8) * np.uint8(SKY)  # True -> 255, False -> 0 (GROUND)
        return Segmentation(mask, contrast, threshold, image_split, sectors)

    def _clearly_ground(
        self,
        dark: np.ndarray,
        contrast: np.ndarray,
        threshold: np.ndarray | float,
        sectors: SectorThresholds | None,
        decided: np.ndarray,
        p: SkylineParams,
    ) -> np.ndarray:
        """Return the row's pixels clearly ground: contrast at least p.hole_margin below the threshold, or `dark`."""
        margin = p.hole_margin
        if not math.isfinite(margin):
            return dark
        if sectors is None:
            below = contrast <= threshold - margin
        else:
            below = ~above_sector_thresholds(contrast, self._row.sectors(p.sectors), np.asarray(threshold) - margin)
        return (decided & below) | dark

    def _apply_structure(self, sky: np.ndarray, strong: np.ndarray | None) -> np.ndarray:
        """Return the row's sky after the structure steps: enclosed ground filled (given `strong`), ground ring cut."""
        if strong is not None:
            # the row as an image of the circle's box: 0 sky (and outside the circle), 1 ground, 2 clearly ground
            ground = ~sky
            state = np.zeros(self._box_circle.shape, np.uint8)
            state[self._box_circle] = (ground.view(np.uint8) + (strong & ground).view(np.uint8)).reshape(-1)
            filled = unanchored_ground(state, self._inner)
            if filled.size:
                sky.reshape(-1)[self._row_position.reshape(-1)[filled]] = True
        if self.params.cuts_rings:
            beyond = self._beyond_ground_ring(sky)
            if beyond is not None:
                sky &= ~beyond
        return sky

    def _beyond_ground_ring(self, sky: np.ndarray) -> np.ndarray | None:
        """Return the row's sky pixels beyond a band of ground on their ray if such bands ring enough azimuths.

        None when too few azimuths are ringed.
        """
        ground = ~sky.reshape(-1).take(self._ray_sample)  # samples outside the circle are masked by _ray_inside
        end, cut = outermost_band_end(ground, self._ray_inside, self._ring_samples)
        if np.count_nonzero(cut) < self.params.ring_share * self._rays.count:
            return None
        # sky farther from the centre than the band's last sample (pixels) is beyond the band
        limit = np.where(cut, (end - 1) * self._rays.spacing, np.inf).astype(np.float32)
        return sky & (self._ray_radius > limit.take(self._ray_index))


def segment(
    uv: np.ndarray,
    green: np.ndarray | None,
    encoding_uv: str,
    encoding_green: str | None,
    circle: SkylineGeometry | np.ndarray | EquidistantCamera,
    params: SkylineParams | None = None,
    **changes,
) -> np.ndarray:
    """Return the skyline mask (uint8: 255 sky, 0 ground) of one image pair; `changes` override fields of `params`.

    For a stream of frames build a SkylineSegmenter once per camera instead:
    this function recomputes the sector layout on every call.
    """
    params = SkylineParams() if params is None else params
    if changes:
        params = replace(params, **changes)
    return SkylineSegmenter(circle, params).segment(uv, green, encoding_uv, encoding_green)
