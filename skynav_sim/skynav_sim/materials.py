# SPDX-License-Identifier: Apache-2.0
"""Surface materials with their reflectance in ultraviolet (~360 nm), blue (~460 nm), green (~530 nm) and red (~610 nm).

Ranges are typical values of spectral libraries for these surface classes
(USGS Spectral Library v7, Kokaly et al. 2017; ECOSTRESS library, Meerdink et al.
2019; green vegetation and bark: Coemans et al. 1994) and of Fig. 2.1 of
Differt (2017). What matters for the skyline: vegetation, soil, brick and
wood reflect little ultraviolet; minerals (sand, limestone, gravel, concrete,
lime plaster) reflect much more, which makes them the hard case for sky/ground
separation in UV alone. A surface's reflectance varies inside its range with
a texture noise of the material's own feature size.

In the visible bands (the same libraries' spectra read at 460 and 610 nm): green leaves reflect little blue and
red (chlorophyll absorbs both) and peak at ~550 nm, so grass, foliage and hedges are green and dark; dry grass,
soil and bark rise steadily towards red (brown, straw); iron oxides make brick and roof tile red (reflectance
doubles from 530 to 610 nm); quartz sand, limestone, gravel, granite, concrete and lime plaster are pale and
near neutral, rising gently towards red (the USGS and ECOSTRESS spectra of quartz sand, limestone and concrete
rise by 10-30 % from 460 to 610 nm); weathered wood is grey-brown.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np


@dataclass(frozen=True)
class Material:
    """A Lambertian surface class: reflectance ranges (0..1) per band and the feature size of its texture."""

    name: str
    uv: tuple[float, float]  # reflectance range at ~360 nm (0..1)
    green: tuple[float, float]  # reflectance range at ~530 nm (0..1)
    texture_scale: float  # feature size of the reflectance texture (m)
    blue: tuple[float, float]  # reflectance range at ~460 nm (0..1)
    red: tuple[float, float]  # reflectance range at ~610 nm (0..1)


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
    # name, ultraviolet, green, texture scale (m), then blue and red
    Surface.GRASS: Material('grass', (0.02, 0.04), (0.08, 0.14), 0.4, blue=(0.03, 0.06), red=(0.04, 0.08)),
    Surface.DRY_GRASS: Material('dry grass', (0.03, 0.07), (0.10, 0.20), 0.5, blue=(0.05, 0.10), red=(0.14, 0.28)),
    Surface.SOIL: Material('soil', (0.03, 0.06), (0.06, 0.12), 0.3, blue=(0.04, 0.08), red=(0.09, 0.18)),
    Surface.SAND: Material('sand', (0.12, 0.22), (0.22, 0.35), 0.6, blue=(0.18, 0.28), red=(0.27, 0.41)),
    Surface.GRAVEL: Material('gravel', (0.08, 0.16), (0.14, 0.26), 0.1, blue=(0.12, 0.22), red=(0.16, 0.29)),
    Surface.LIMESTONE: Material('limestone', (0.15, 0.28), (0.24, 0.40), 0.8, blue=(0.21, 0.36), red=(0.26, 0.43)),
    Surface.GRANITE: Material('granite', (0.07, 0.14), (0.13, 0.24), 0.3, blue=(0.11, 0.21), red=(0.15, 0.27)),
    Surface.FOLIAGE: Material('foliage', (0.02, 0.05), (0.06, 0.12), 0.3, blue=(0.02, 0.05), red=(0.03, 0.06)),
    Surface.BARK: Material('bark', (0.03, 0.06), (0.06, 0.12), 0.2, blue=(0.04, 0.07), red=(0.09, 0.17)),
    Surface.HEDGE: Material('hedge', (0.02, 0.04), (0.05, 0.10), 0.2, blue=(0.02, 0.04), red=(0.03, 0.05)),
    Surface.BRICK: Material('brick', (0.05, 0.09), (0.09, 0.17), 0.3, blue=(0.06, 0.10), red=(0.22, 0.38)),
    Surface.LIME_PLASTER: Material(
        'lime plaster', (0.25, 0.45), (0.55, 0.75), 1.0, blue=(0.50, 0.70), red=(0.58, 0.78)
    ),
    Surface.CONCRETE: Material('concrete', (0.14, 0.24), (0.22, 0.34), 0.6, blue=(0.20, 0.31), red=(0.24, 0.36)),
    Surface.ROOF_TILE: Material('roof tile', (0.04, 0.08), (0.08, 0.15), 0.3, blue=(0.05, 0.09), red=(0.18, 0.32)),
    Surface.WOOD: Material('weathered wood', (0.05, 0.10), (0.14, 0.24), 0.3, blue=(0.10, 0.18), red=(0.17, 0.28)),
}

# Per-material range bounds as arrays indexed by Surface, for vectorised lookup.
UV_RANGE = np.array([MATERIALS[s].uv for s in Surface])
BLUE_RANGE = np.array([MATERIALS[s].blue for s in Surface])
GREEN_RANGE = np.array([MATERIALS[s].green for s in Surface])
RED_RANGE = np.array([MATERIALS[s].red for s in Surface])
#: Reflectance ranges (Surface, 2) per band of the daylight model (skynav_sim.sky.BANDS).
BAND_RANGES = {'uv': UV_RANGE, 'blue': BLUE_RANGE, 'green': GREEN_RANGE, 'red': RED_RANGE}
TEXTURE_SCALE = np.array([MATERIALS[s].texture_scale for s in Surface])
