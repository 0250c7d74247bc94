# SPDX-License-Identifier: Apache-2.0
"""Seeded, smooth 2D value noise for terrain, surface texture and clouds."""

from __future__ import annotations

import numpy as np

# Size of the random lattice; the noise repeats after this many cells.
_LATTICE = 256


class FractalNoise:
    """Sum of `octaves` layers of smooth value noise; roughly in [-1, 1]; feature size `scale` (m)."""

    def __init__(self, seed: int, scale: float, octaves: int = 4, persistence: float = 0.5) -> None:
        rng = np.random.default_rng(seed)
        self.values = rng.uniform(-1.0, 1.0, (octaves, _LATTICE, _LATTICE))
        self.offsets = rng.uniform(0, _LATTICE, (octaves, 2))
        self.scale = scale
        self.persistence = persistence
        amplitudes = persistence ** np.arange(octaves)
        self.amplitudes = amplitudes / amplitudes.sum()

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Return the noise at world coordinates (x, y) in metres."""
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        total = np.zeros(np.broadcast(x, y).shape)
        for octave, amplitude in enumerate(self.amplitudes):
            frequency = 2.0**octave / self.scale
            total += amplitude * _value_noise(
                self.values[octave], x * frequency + self.offsets[octave, 0], y * frequency + self.offsets[octave, 1]
            )
        return total


def _value_noise(lattice: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Return smoothly interpolated lattice values at lattice coordinates (x, y)."""
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = x - x0
    fy = y - y0
    sx = fx * fx * (3 - 2 * fx)
    sy = fy * fy * (3 - 2 * fy)
    i0 = x0.astype(np.int64) % _LATTICE
    j0 = y0.astype(np.int64) % _LATTICE
    i1 = (i0 + 1) % _LATTICE
    j1 = (j0 + 1) % _LATTICE
    top = lattice[j0, i0] * (1 - sx) + lattice[j0, i1] * sx
    bottom = lattice[j1, i0] * (1 - sx) + lattice[j1, i1] * sx
    return top * (1 - sy) + bottom * sy
