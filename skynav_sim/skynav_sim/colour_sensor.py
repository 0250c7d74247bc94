# SPDX-License-Identifier: Apache-2.0
"""A synthetic colour camera's sensor: one exposure for red, green and blue, daylight white balance, noise, and
the frames a driver delivers (8-bit sRGB, 16-bit linear, Bayer mosaics, JPEG or PNG).

The model, in the order light goes through it:
- optics blur (Gaussian) of the radiance in each band (skynav_sim.sky.RGB: ~610, ~530 and ~460 nm);
- one automatic exposure for all three channels, from the image's bright pixels (as a colour camera's
  auto-exposure meters one image, not one channel): the ColourSensor.exposure_percentile of the brightest
  white-balanced channel inside the image circle goes to ColourSensor.exposure_level of full scale;
- photon (Poisson) and read (Gaussian) noise on each channel's electrons, saturation at the full well;
- white balance: fixed daylight gains (daylight_white_balance), as a camera's 'daylight' preset; a grey surface
  lit by the clear synthetic noon sky comes out grey (equal channels) and a saturated pixel white;
- the white-balanced linear signal (0..1 of full scale) encoded as COLOUR_ENCODINGS ask: 8-bit values
  sRGB-encoded (IEC 61966-2-1), 16-bit values linear, Bayer patterns the mosaic of that frame as a driver
  delivers it, and image_transport's `compressed` transport (skynav_core.colour.compress).
Spectral sensitivities are single wavelengths (no overlap between channels, so no colour matrix), there is no
vignetting, lens flare, chromatic aberration, rolling shutter, hot pixel or demosaicing of the sensor's own;
everything it delivers is synthetic.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache

import cv2
import numpy as np

from skynav_core.colour import CODECS, COLOUR_ENCODINGS, LINEAR_FULL_SCALE, compress, linear_to_srgb8, mosaic
from skynav_core.images import BAYER_PATTERNS

from .errors import SimError
from .sky import RGB, TIMES_OF_DAY, Sky

SRGB_FULL_SCALE = 255  # code value of a saturated 8-bit sample
WHITE_BALANCE_HOURS = TIMES_OF_DAY['noon']  # local solar time of the daylight the white balance is set for
DEFAULT_JPEG_QUALITY = 95  # libjpeg quality 0-100: image_transport's default `jpeg_quality`


@cache
def daylight_white_balance() -> tuple[float, float, float]:
    """Return the daylight white-balance gains (red, green, blue): a grey horizontal surface under the clear
    synthetic noon sky (direct sun + skylight) gives equal channels; the smallest gain is 1, so that a saturated
    pixel is white."""
    noon = Sky(WHITE_BALANCE_HOURS)
    irradiance = np.array([noon.global_irradiance(band) for band in RGB])
    gains = irradiance.max() / irradiance
    return (float(gains[0]), float(gains[1]), float(gains[2]))


@dataclass(frozen=True)
class ColourSensor:
    """Noise, exposure and white balance of a colour camera (all channels share one exposure)."""

    full_well: float = 12000.0  # electrons at saturation, per channel's photosite
    read_noise: float = 6.0  # electrons rms
    exposure_percentile: float = 99.0  # the percentile of the brightest white-balanced channel that ...
    exposure_level: float = 0.7  # ... automatic exposure maps to this share of full scale
    blur_sigma: float = 0.5  # px, optics point spread (Gaussian)
    white_balance: tuple[float, float, float] = field(default_factory=daylight_white_balance)  # gains R, G, B

    def exposure(self, radiance: np.ndarray, inside: np.ndarray) -> float:
        """Return the automatic exposure, electrons per unit radiance, of an (H, W, 3) RGB radiance field."""
        balanced = np.max(radiance[inside] * np.asarray(self.white_balance), axis=-1)
        reference = np.percentile(balanced, self.exposure_percentile)
        return self.exposure_level * self.full_well / max(float(reference), 1e-12)

    def capture(
        self, radiance: np.ndarray, inside: np.ndarray, rng: np.random.Generator, exposure: float | None = None
    ) -> np.ndarray:
        """Return the white-balanced linear signal (H, W, 3) float32, 0..1 of full scale, of an RGB radiance field
        (H, W, 3, W m^-2 sr^-1 nm^-1 in red, green, blue), exposed automatically unless `exposure` is given."""
        gain = self.exposure(radiance, inside) if exposure is None else exposure
        image = radiance.astype(np.float32)
        blurred = cv2.GaussianBlur(image, (0, 0), self.blur_sigma) if self.blur_sigma else image
        mean_electrons = np.clip(blurred.astype(np.float64) * gain, 0, 4 * self.full_well)
        electrons = rng.poisson(mean_electrons) + rng.normal(0.0, self.read_noise, radiance.shape)
        raw = np.clip(electrons, 0, self.full_well) / self.full_well
        return np.clip(raw * np.asarray(self.white_balance), 0.0, 1.0).astype(np.float32)


def channel_order(encoding: str) -> str:
    """Return the channel order or Bayer pattern of a colour encoding: 'rgb', 'bgra', 'bayer_rggb', ..."""
    return encoding.rstrip('0123456789')


def bits(encoding: str) -> int:
    """Return the bits per sample of a colour encoding (8 or 16)."""
    return 16 if encoding.endswith('16') else 8


def quantise(signal: np.ndarray, sample_bits: int) -> np.ndarray:
    """Return (H, W, 3) RGB of a linear signal (0..1): uint8 sRGB code values (8 bits) or uint16 linear (16)."""
    if sample_bits == 8:
        return linear_to_srgb8(signal)
    return np.rint(np.clip(signal, 0.0, 1.0) * LINEAR_FULL_SCALE).astype(np.uint16)


def encode(signal: np.ndarray, encoding: str) -> np.ndarray:
    """Return the pixels of a white-balanced linear RGB signal (H, W, 3; 0..1) in a colour encoding: (H, W, 3|4) in
    the encoding's channel order (alpha opaque), or (H, W) for a Bayer mosaic."""
    if encoding not in COLOUR_ENCODINGS:
        raise SimError(f'unknown colour encoding {encoding!r} (one of {", ".join(COLOUR_ENCODINGS)})')
    rgb = quantise(signal, bits(encoding))
    order = channel_order(encoding)
    if order.startswith('bayer_'):
        pattern = order.removeprefix('bayer_')
        assert pattern in BAYER_PATTERNS  # COLOUR_ENCODINGS holds only these
        return mosaic(rgb, pattern)
    pixels = rgb[..., ['rgb'.index(c) for c in order.rstrip('a')]]
    if order.endswith('a'):
        opaque = np.full(rgb.shape[:2] + (1,), np.iinfo(rgb.dtype).max, rgb.dtype)
        pixels = np.concatenate([pixels, opaque], axis=-1)
    return np.ascontiguousarray(pixels)


def compressed(signal: np.ndarray, codec: str, quality: int, sample_bits: int = 8) -> tuple[str, bytes]:
    """Return (format, data) of a linear RGB signal (H, W, 3; 0..1) as image_transport's `compressed` transport
    sends it: JPEG of 8-bit sRGB at `quality`, or PNG of 8-bit sRGB or 16-bit linear samples."""
    if codec not in CODECS:
        raise SimError(f'unknown codec {codec!r} (one of {", ".join(CODECS)})')
    if codec == 'jpeg' and sample_bits != 8:
        raise SimError('JPEG holds 8-bit samples only; use PNG for 16 bits')
    return compress(quantise(signal, sample_bits), codec, quality)
