# SPDX-License-Identifier: Apache-2.0
"""The error of skynav_sh: coefficients of the wrong size or degree, grids and cameras that do not fit."""

from __future__ import annotations

from skynav_core.errors import SkynavError


class ShError(SkynavError, ValueError):
    """A spherical-harmonic input or setting that cannot be used (a ValueError too, as the built-in it replaces)."""
