# SPDX-License-Identifier: Apache-2.0
"""The camera's sensor: optics blur, automatic exposure per channel, photon and read noise, quantisation.

Each channel (UV, green) has its own exposure, as a real two-channel camera
with automatic exposure and gain has; no message carries it, so methods must
not rely on the absolute level of 8/16-bit images (docs/interfaces.md). 32FC1 output
is the linear radiance itself (with the photon noise of the exposure it would
have had), in W m^-2 sr^-1 nm^-1 for both channels.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from skynav_sim.errors import SimError

ENCODINGS = ('mono8', 'mono16', '32FC1')
FULL_SCALE = {'mono8': 255, 'mono16': 65535}


@dataclass(frozen=True)
class Sensor:
    """Noise and exposure model of one channel."""

    full_well: float = 12000.0  # electrons at saturation
    read_noise: float = 6.0  # electrons rms
    exposure_percentile: float = 99.0  # the radiance percentile inside the image circle that ...
    exposure_level: float = 0.7  # ... automatic exposure maps to this share of full scale
    blur_sigma: float = 0.5  # px, optics point spread (Gaussian)

    def exposure(self, radiance: np.ndarray, inside: np.ndarray) -> float:
        """Return the automatic exposure: electrons per unit radiance, from the image's bright pixels."""
        reference = np.percentile(radiance[inside], self.exposure_percentile)
        return self.exposure_level * self.full_well / max(float(reference), 1e-12)

    def capture(
        self,
        radiance: np.ndarray,
        inside: np.ndarray,
        encoding: str,
        rng: np.random.Generator,
        exposure: float | None = None,
    ) -> np.ndarray:
        """Return the image of a radiance field (H, W) in `encoding`: uint8, uint16 or float32 radiance."""
        if encoding not in ENCODINGS:
            raise SimError(f'unknown encoding {encoding!r} (one of {", ".join(ENCODINGS)})')
        gain = self.exposure(radiance, inside) if exposure is None else exposure
        blurred = (
            cv2.GaussianBlur(radiance.astype(np.float32), (0, 0), self.blur_sigma) if self.blur_sigma else radiance
        )
        mean_electrons = np.clip(blurred.astype(np.float64) * gain, 0, 4 * self.full_well)
        electrons = rng.poisson(mean_electrons) + rng.normal(0.0, self.read_noise, radiance.shape)
        if encoding == '32FC1':
            return (np.maximum(electrons, 0) / gain).astype(np.float32)
        scale = FULL_SCALE[encoding]
        counts = np.round(np.clip(electrons / self.full_well, 0, 1) * scale)
        return counts.astype(np.uint8 if encoding == 'mono8' else np.uint16)
