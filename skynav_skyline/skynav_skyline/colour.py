# SPDX-License-Identifier: Apache-2.0
"""The skyline of a colour camera's frames: a colour model of each image, seeded by its own UV/green segmentation.

A colour camera knows more than a UV/green pair's stand-in (blue for UV): clear sky is blue and bright, clouds are
bright and grey, foliage and facades darker or warmer. No constant says where these lie in a given image (white
balance, exposure, haze and the scene change them), so every frame fits its own model:

1. Seed. The UV/green segmentation of the frame (blue for UV, green for green) with thresholds adapted to the image
   alone (per-sector minimum error, no learned global threshold) and the structure steps.
2. Model. A linear discriminant (Fisher) of the frame's normalised log R, log G and log B, fitted to the pixels the
   seed classified clearly: at least `seed_margin` from their threshold, trusted in every channel.
3. Skyline. The discriminant's projection, in the seed contrast's units, thresholded per azimuth sector and cleaned
   by the structure steps (enclosed ground, ground ring) as the UV/green methods are (segment.py).

`colour_method` may also name a UV/green method, which then runs on the blue and green planes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from skynav_skyline.errors import SkylineError

from .classify import GROUND, project
from .features import decode, log_feature
from .geometry import SkylineGeometry
from .segment import METHODS, STATISTICS_SAMPLE, SkylineParams, SkylineSegmenter, above_sector_thresholds

#: The colour method; the UV/green METHODS run on the blue and green planes of a colour frame too.
COLOUR_DISCRIMINANT = 'colour-discriminant'
COLOUR_METHODS: tuple[str, ...] = (COLOUR_DISCRIMINANT, *METHODS)
#: Encoding of the linear planes of a decoded colour frame (skynav_core.colour: uint16, full scale saturated).
LINEAR_ENCODING = 'mono16'
#: Default least distance (seed contrast, log units) of a seed pixel from its threshold to train the model.
SEED_MARGIN = 0.3
#: Least training pixels of each class for a colour model; with fewer the seed segmentation stands.
MIN_CLASS_PIXELS = 200
#: Ridge added to the pooled covariance's diagonal (log units squared): keeps the discriminant defined.
COVARIANCE_RIDGE = 1e-4


@dataclass(frozen=True)
class ColourParams:
    """Settings of the colour skyline: the method, the seed's and the final thresholding's settings."""

    method: str = COLOUR_DISCRIMINANT  # one of COLOUR_METHODS
    seed: SkylineParams = field(default_factory=SkylineParams)  # the UV/green settings on blue and green
    seed_margin: float = SEED_MARGIN  # log units of the seed contrast

    def __post_init__(self) -> None:
        """Check the settings (ValueError)."""
        if self.method not in COLOUR_METHODS:
            raise SkylineError(f'unknown colour method {self.method!r}; expected one of {", ".join(COLOUR_METHODS)}')
        if not (self.seed_margin >= 0 and math.isfinite(self.seed_margin)):
            raise SkylineError(f'seed_margin must be finite and at least 0, got {self.seed_margin}')

    @property
    def adaptive_seed(self) -> SkylineParams:
        """Return the seed's settings with thresholds from the image alone: no learned global threshold."""
        return replace(self.seed, method='sector-min-error', threshold=None, max_deviation=math.inf)


class ColourSegmenter:
    """Sky/ground segmentation of colour frames for one camera geometry; build once, call per frame."""

    def __init__(self, geometry: SkylineGeometry, params: ColourParams | None = None) -> None:
        """Keep the geometry and settings; build the per-camera tables of the seed and final thresholding."""
        self.geometry = geometry
        self.params = ColourParams() if params is None else params
        p = self.params
        if p.method == COLOUR_DISCRIMINANT:
            self.seeder = SkylineSegmenter(geometry, p.adaptive_seed)
            self.final = SkylineSegmenter(geometry, replace(p.adaptive_seed, channels='uv', angle=None))
        else:
            self.seeder = self.final = SkylineSegmenter(geometry, replace(p.seed, method=p.method))
        self._row, self._pixels = self.seeder._row, self.seeder._pixels
        self._stride = max(1, -(-self._pixels.size // STATISTICS_SAMPLE))

    def segment(self, rgb: np.ndarray) -> np.ndarray:
        """Return the skyline mask (uint8, 255 sky, 0 ground and outside the circle) of uint16 linear RGB (H, W, 3)."""
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.shape[:2] != self.geometry.shape:
            raise SkylineError(f'colour frame {rgb.shape} does not fit the image circle {self.geometry.shape} x 3')
        if self.params.method != COLOUR_DISCRIMINANT:
            return self.seeder.segment(rgb[..., 2], rgb[..., 1], LINEAR_ENCODING, LINEAR_ENCODING)
        return self.seeder._scatter(self.segment_row(rgb[self.geometry.circle].T[:, None, :]), GROUND)

    def segment_row(self, planes: np.ndarray) -> np.ndarray:
        """Return the mask row (uint8) of the image circle's pixels given as linear R, G, B planes (3, 1, N)."""
        circle = self._row.circle
        channels = [decode(plane, LINEAR_ENCODING) for plane in planes]
        logs = np.stack(
            [log_feature(c, circle, self.seeder.params.reference_percentile, self._stride) for c in channels]
        )
        red, green, blue = channels
        seed_contrast = project(logs[2], logs[1], self.seeder.params.projection_angle)
        seed = self.seeder.classify_row(
            seed_contrast,
            circle & blue.trusted & green.trusted,
            circle & ~blue.invalid,
            circle & blue.saturated,
            blue.dark,
        )
        trusted = circle & red.trusted & green.trusted & blue.trusted
        contrast = self._discriminant(logs, seed_contrast, seed, trusted)
        if contrast is None:
            return seed.mask
        dark = red.dark & green.dark & blue.dark
        saturated = red.saturated & green.saturated & blue.saturated
        return self.final.classify_row(contrast, trusted, circle & ~dark, saturated & ~dark, dark).mask

    def _discriminant(
        self, logs: np.ndarray, seed_contrast: np.ndarray, seed, trusted: np.ndarray
    ) -> np.ndarray | None:
        """Return the Fisher discriminant's projection of the log features (3, 1, N), in seed contrast units.

        None when the seed left too few clear pixels of either class.
        """
        margin = self.params.seed_margin
        layout = self.seeder._row.sectors(self.seeder.params.sectors)
        threshold = np.asarray(seed.threshold, np.float64)
        if threshold.ndim == 0:
            clearly_sky = seed_contrast > threshold + margin
            clearly_ground = seed_contrast <= threshold - margin
        else:
            clearly_sky = above_sector_thresholds(seed_contrast, layout, threshold + margin)
            clearly_ground = ~above_sector_thresholds(seed_contrast, layout, threshold - margin)
        every = slice(None, None, self._stride)  # the statistics' sample of the row
        sky = (seed.mask.view(bool) & clearly_sky & trusted)[0, every]
        ground = (~seed.mask.view(bool) & clearly_ground & trusted)[0, every]
        samples = logs[:, 0, every]
        sky_samples, ground_samples = samples[:, sky], samples[:, ground]
        if min(sky_samples.shape[1], ground_samples.shape[1]) < MIN_CLASS_PIXELS:
            return None
        sky_mean, ground_mean = sky_samples.mean(axis=1), ground_samples.mean(axis=1)
        scatter = np.cov(sky_samples) * (sky_samples.shape[1] - 1) + np.cov(ground_samples) * (
            ground_samples.shape[1] - 1
        )
        pooled = scatter / (sky_samples.shape[1] + ground_samples.shape[1] - 2) + COVARIANCE_RIDGE * np.eye(3)
        direction = np.linalg.solve(pooled, sky_mean - ground_mean)
        separation = float(direction @ (sky_mean - ground_mean))
        if not (math.isfinite(separation) and separation > 0):
            return None
        # in the seed contrast's units: the classes' means lie as far apart as they do in the seed contrast
        seed_values = seed_contrast[0, every]
        seed_gap = float(seed_values[sky].mean() - seed_values[ground].mean())
        scale = np.float32(max(seed_gap, 1e-6) / separation)
        weights = (direction * scale).astype(np.float32)
        return np.tensordot(weights, logs, axes=1).astype(np.float32)
