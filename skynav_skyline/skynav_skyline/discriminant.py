# SPDX-License-Identifier: Apache-2.0
"""The per-image discriminant: each image's own sky and ground colours, learned from where an upward view puts them.

No constant says where sky and ground lie in a camera's colour space: white balance, exposure, haze, clouds, the
sun's height and the scene move them from one image to the next. So each image teaches its own classifier:

1. Exemplars. The sky is what is bright or sky-coloured near the zenith; the ground what is dark near the rim. Of
   the trusted pixels in the inner half of the image circle (by radius), those among the brightest EXEMPLAR_SHARE
   or the most sky-coloured EXEMPLAR_SHARE are sky exemplars; of those in the outer half, the darkest
   EXEMPLAR_SHARE that are not among the more sky-coloured half are ground exemplars. Brightness is the mean of
   the channels' normalised logs, sky colour the last channel's log over the first's (blue over red for a colour
   camera, UV over green for the UV/green pair): clear sky is blue and UV-rich, clouds are bright, ground is dark
   and warm or green where it is not in the sun.
2. Direction. Fisher's linear discriminant of the exemplars in the channels' normalised logs.
3. Threshold. Along that direction, a Gaussian per class (the exemplars' mean and spread); the threshold is where
   the two posteriors meet between the class means, with the exemplars' shares as priors. The projection is
   returned shifted and scaled so that this threshold is 0 and the pooled spread 1 (*spread units*).

The caller thresholds the projection per azimuth sector around 0 and applies the structure steps (segment.py), as
for the learned contrast. With too few exemplars of either class the image has no model (None).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Share of the inner (outer) half's trusted pixels taken as sky (ground) exemplars by each criterion.
EXEMPLAR_SHARE = 0.2
#: Least exemplars of either class for a model.
MIN_EXEMPLARS = 50
#: Most exemplars of a class a fit uses (evenly spaced): the class's mean and spread need no more.
FIT_SAMPLE = 20000
#: The inner half of the image circle: pixels at most this share of the circle's radius from its centre.
INNER_RADIUS_SHARE = 0.5
#: Ridge (log units squared) added to the pooled covariance's diagonal, so that the direction is always defined.
COVARIANCE_RIDGE = 1e-4
#: Least spread of a class along the direction, as a share of the class means' distance (a flat class has a width).
MIN_SPREAD = 1e-3
#: Sector thresholds of the projection stay within this many spreads of the image's threshold (segment.py).
SECTOR_DEVIATION = 1.0
#: Enclosed ground that nowhere falls this many spreads below its threshold is sky (structure.py); 0 when off.
HOLE_MARGIN = 3.0
#: Along the direction, sky lies within this many of its own spreads of its mean; farther below it is ground.
SKY_SPREADS = 4.0
#: Values between the class means at which the posteriors are compared.
THRESHOLD_STEPS = 400


@dataclass(frozen=True)
class Discriminant:
    """A per-image linear sky/ground classifier of normalised log features: sky where weights . f > threshold."""

    weights: np.ndarray  # (channels,) the direction, in spread units per log unit
    offset: float  # subtracted after the weights: the threshold lands on 0
    sky_exemplars: int
    ground_exemplars: int

    def project(self, logs: np.ndarray) -> np.ndarray:
        """Return the float32 projection (spread units; sky above 0) of log features (channels, ...)."""
        weights = self.weights.astype(np.float32)
        return np.tensordot(weights, np.asarray(logs, np.float32), axes=1) - np.float32(self.offset)


def exemplars(
    logs: np.ndarray, inner: np.ndarray, trusted: np.ndarray, share: float = EXEMPLAR_SHARE
) -> tuple[np.ndarray, np.ndarray]:
    """Return bool (sky, ground) exemplars among pixels of log features (channels, n), given the inner half (n,).

    Only `trusted` pixels are exemplars (see the module's description).
    """
    brightness = logs.mean(axis=0)
    near, far = inner & trusted, ~inner & trusted
    sky = near & (brightness >= _quantile(brightness, near, 1 - share))
    ground = far & (brightness <= _quantile(brightness, far, share))
    if len(logs) > 1:  # a single channel has no colour
        colour = logs[-1] - logs[0]
        sky |= near & (colour >= _quantile(colour, near, 1 - share))
        ground &= colour < _quantile(colour, far, 0.5)
    return sky, ground


def _quantile(values: np.ndarray, where: np.ndarray, q: float) -> float:
    """Return the q-quantile of `values` where `where` holds (NaN when it holds nowhere, so no comparison is true)."""
    chosen = values[where]
    return float(np.quantile(chosen, q)) if chosen.size else math.nan


def fit(logs: np.ndarray, sky: np.ndarray, ground: np.ndarray) -> Discriminant | None:
    """Return the discriminant of sky and ground exemplars (bool (n,)) of log features (channels, n).

    None with too few exemplars of either class, or when they do not separate along any direction.
    """
    count_sky, count_ground = int(np.count_nonzero(sky)), int(np.count_nonzero(ground))
    if min(count_sky, count_ground) < MIN_EXEMPLARS:
        return None
    features = np.asarray(logs).reshape(len(logs), -1)
    sky_features = features[:, sky][:, :: max(1, count_sky // FIT_SAMPLE)].astype(np.float64)
    ground_features = features[:, ground][:, :: max(1, count_ground // FIT_SAMPLE)].astype(np.float64)
    sky_mean, ground_mean = sky_features.mean(axis=1), ground_features.mean(axis=1)
    scatter = _scatter(sky_features, sky_mean) + _scatter(ground_features, ground_mean)
    pooled = scatter / (sky_features.shape[1] + ground_features.shape[1]) + COVARIANCE_RIDGE * np.eye(len(features))
    direction = np.linalg.solve(pooled, sky_mean - ground_mean)
    sky_values, ground_values = direction @ sky_features, direction @ ground_features
    high, low = float(sky_values.mean()), float(ground_values.mean())
    if not (math.isfinite(high) and math.isfinite(low) and high > low):
        return None
    high_spread = max(float(sky_values.std()), MIN_SPREAD * (high - low))
    low_spread = max(float(ground_values.std()), MIN_SPREAD * (high - low))
    threshold = class_threshold(high, high_spread, low, low_spread, count_sky / (count_sky + count_ground))
    threshold = max(threshold, high - SKY_SPREADS * high_spread)  # the sky is a narrow class; the rest is ground
    spread = math.sqrt((count_sky * high_spread**2 + count_ground * low_spread**2) / (count_sky + count_ground))
    return Discriminant(direction / spread, threshold / spread, count_sky, count_ground)


def _scatter(features: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """Return the scatter matrix (sum of outer products of deviations) of features (channels, n) about `mean`."""
    centred = features - mean[:, None]
    return centred @ centred.T


def class_threshold(high: float, high_spread: float, low: float, low_spread: float, prior_high: float) -> float:
    """Return where, going up from the low class's mean to the high one's, the high class's posterior first wins.

    Two Gaussian classes (means low < high, spreads, the high class's prior); with unequal spreads the posteriors
    may meet twice, and only the meeting between the means separates the classes. The high mean if it never wins.
    """
    prior_high = min(max(prior_high, 1e-6), 1 - 1e-6)
    values = np.linspace(low, high, THRESHOLD_STEPS)
    log_ratio = (
        -0.5 * ((values - high) / high_spread) ** 2
        + 0.5 * ((values - low) / low_spread) ** 2
        + math.log(low_spread / high_spread)
        + math.log(prior_high / (1 - prior_high))
    )
    wins = np.flatnonzero(log_ratio > 0)
    return float(values[wins[0]] if wins.size else high)
