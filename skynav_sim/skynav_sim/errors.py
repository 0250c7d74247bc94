# SPDX-License-Identifier: Apache-2.0
"""The error of skynav_sim: worlds, routes, scenarios and renderings that cannot be made."""

from __future__ import annotations

from skynav_core.errors import SkynavError


class SimError(SkynavError, ValueError):
    """A simulator input or setting that cannot be used (a ValueError too, as the built-in it replaces)."""
