# SPDX-License-Identifier: Apache-2.0
"""The error of skynav_compass: views, snapshots and settings the compass cannot compare."""

from __future__ import annotations

from skynav_core.errors import SkynavError


class CompassError(SkynavError, ValueError):
    """A compass input or setting that cannot be used (a ValueError too, as the built-in it replaces)."""
