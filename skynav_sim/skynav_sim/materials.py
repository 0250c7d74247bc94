# SPDX-License-Identifier: Apache-2.0
"""Surface materials with their ultraviolet (~360 nm) and green (~530 nm) reflectance.

Ranges are typical values of spectral libraries for these surface classes
(USGS Spectral Library v7, Kokaly et al. 2017; ECOSTRESS library, Meerdink et al.
2019; green vegetation and bark: Coemans et al. 1994) and of Fig. 2.1 of
Differt (2017). What matters for the skyline: vegetation, soil, brick and
wood reflect little ultraviolet; minerals (sand, limestone, gravel, concrete,
lime plaster) reflect much more, which makes them the hard case for sky/ground
separation in UV alone. A surface's reflectance varies inside its range with
a texture noise of the material's own feature size.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np


@dataclass(frozen=True)
class Material:
    """A Lambertian surface class."""

    name: str
    uv: tuple[float, float]  # reflectance range at ~360 nm (0..1)
    green: tuple[float, float]  # reflectance range at ~530 nm (0..1)
    texture_scale: float  # feature size of the reflectance texture (m)


class Surface(IntEnum):
    """Index of each material in MATERIALS (also stored per terrain cell and per primitive)."""

    GRASS = 0
    DRY_GRASS = 1
    SOIL = 2
    SAND = 3
    GRAVEL = 4
    LIMESTONE = 5
    GRANITE = 6
    FOLIAGE = 7
    BARK = 8
    HEDGE = 9
    BRICK = 10
    LIME_PLASTER = 11
    CONCRETE = 12
    ROOF_TILE = 13
    WOOD = 14


MATERIALS: dict[Surface, Material] = {
    Surface.GRASS: Material('grass', (0.02, 0.04), (0.08, 0.14), 0.4),
    Surface.DRY_GRASS: Material('dry grass', (0.03, 0.07), (0.10, 0.20), 0.5),
    Surface.SOIL: Material('soil', (0.03, 0.06), (0.06, 0.12), 0.3),
    Surface.SAND: Material('sand', (0.12, 0.22), (0.22, 0.35), 0.6),
    Surface.GRAVEL: Material('gravel', (0.08, 0.16), (0.14, 0.26), 0.1),
    Surface.LIMESTONE: Material('limestone', (0.15, 0.28), (0.24, 0.40), 0.8),
    Surface.GRANITE: Material('granite', (0.07, 0.14), (0.13, 0.24), 0.3),
    Surface.FOLIAGE: Material('foliage', (0.02, 0.05), (0.06, 0.12), 0.3),
    Surface.BARK: Material('bark', (0.03, 0.06), (0.06, 0.12), 0.2),
    Surface.HEDGE: Material('hedge', (0.02, 0.04), (0.05, 0.10), 0.2),
    Surface.BRICK: Material('brick', (0.05, 0.09), (0.09, 0.17), 0.3),
    Surface.LIME_PLASTER: Material('lime plaster', (0.25, 0.45), (0.55, 0.75), 1.0),
    Surface.CONCRETE: Material('concrete', (0.14, 0.24), (0.22, 0.34), 0.6),
    Surface.ROOF_TILE: Material('roof tile', (0.04, 0.08), (0.08, 0.15), 0.3),
    Surface.WOOD: Material('weathered wood', (0.05, 0.10), (0.14, 0.24), 0.3),
}

# Per-material range bounds as arrays indexed by Surface, for vectorised lookup.
UV_RANGE = np.array([MATERIALS[s].uv for s in Surface])
GREEN_RANGE = np.array([MATERIALS[s].green for s in Surface])
TEXTURE_SCALE = np.array([MATERIALS[s].texture_scale for s in Surface])
