# SPDX-License-Identifier: Apache-2.0
"""Building a map: which frames become snapshots, the descriptors stored with each, and the map's creation.

A map holds what the product uses: each snapshot's SH coefficients (and pose). skynav's descriptors (amplitude
spectrum, bispectrum) are derived from them when a Localizer loads the map. The baselines' descriptors (down-sampled
UV image, ORB features and their vocabulary) are stored only on request (`skynav map build --baselines`, for the
evaluations; skynav_localize.eval.baselines makes them); nothing in building a map depends on them. A map build goes:

    store = create_map(path, name, L, created_from=bag)           # or build_map(...) for one atomic write
    selector = SnapshotSelector()
    for each frame: coefficients (skyline -> SH), pose (if the recording has one), UV image (with baselines)
        if selector.keep(describe('amplitude', coefficients, L), position):
            descriptors = baseline_descriptors(uv, circle) if baselines else {}
            store.add_snapshot(coefficients, stamp_ns, pose, descriptors)   # one transaction each
    left_out = finish_baselines(store)                             # with baselines: the ORB vocabulary, if it can be
    store.close()

create_map/build_map record descriptor_settings() in the map, so a Localizer knows whether stored SH descriptors
(a map may still hold them) are current (else it derives them from the coefficients) and describes baseline queries
the same way (baseline_descriptors, finish_baselines: skynav_localize.eval.baselines).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from skynav_core.maps import MapStore, Snapshot
from skynav_localize.descriptors import DESCRIPTOR_VERSION

#: skynav's descriptors: derived from the coefficients (stored only if a caller asks for them: eval.baselines).
SH_DESCRIPTOR_NAMES = ('amplitude', 'bispectrum')
# The settings the baselines' descriptors are made with (skynav_localize.eval.baselines takes them from here), recorded
# in every map so that their queries are described as its snapshots were.
RAW_UV_SIZE = (32, 24)  # px (width, height) of the down-sampled fish-eye image
RAW_UV_PATCH = 4  # px, side of the normalisation patches of the down-sampled image
ORB_FEATURES = 500  # features per image
SETTINGS_KEY = 'descriptor_settings'  # map meta key: JSON of the settings the stored descriptors were made with
DEFAULT_MIN_TRAVEL = 0.1  # m of travel between snapshots
DEFAULT_MIN_CHANGE = 0.05  # amplitude-descriptor distance (dimensionless) that counts as a changed view
#: The range of each integer in a map's descriptor settings (inclusive): wider than any setting this library wrote,
#: narrow enough that a crafted map cannot make a query allocate more than a small image.
_SETTING_RANGES = {
    'descriptor_version': (0, 1_000_000),
    'raw_uv_size': (1, 1024),  # px, each of width and height of the down-sampled image
    'raw_uv_patch': (1, 1024),  # px
    'orb_features': (1, 100_000),  # ORB features per image
}


def descriptor_settings() -> dict:
    """Return the settings the descriptors of this library are made with (stored in a map's meta)."""
    return {
        'descriptor_version': DESCRIPTOR_VERSION,
        'raw_uv_size': list(RAW_UV_SIZE),
        'raw_uv_patch': RAW_UV_PATCH,
        'orb_features': ORB_FEATURES,
    }


def stored_settings(meta: Mapping[str, str]) -> dict:
    """Return the descriptor settings recorded in a map's meta ({} when it has none); ValueError if they are damaged.

    Each setting must have the type and range descriptor_settings() writes (a crafted map's are refused, not used).
    """
    try:
        settings = json.loads(meta.get(SETTINGS_KEY, '{}'))
    except json.JSONDecodeError:
        raise ValueError(f'meta {SETTINGS_KEY!r} is not JSON') from None
    if not isinstance(settings, dict):
        raise ValueError(f'meta {SETTINGS_KEY!r} is not a JSON object')
    for key, value in settings.items():
        wanted = _SETTING_RANGES.get(key)
        values = value if key == 'raw_uv_size' and isinstance(value, list) and len(value) == 2 else [value]
        if wanted is not None and not all(
            isinstance(v, int) and not isinstance(v, bool) and wanted[0] <= v <= wanted[1] for v in values
        ):
            raise ValueError(f'meta {SETTINGS_KEY!r}: {key} {str(value)[:40]} is not usable')
    return settings


class SnapshotSelector:
    """Decides which frames of a teach drive become snapshots: every min_travel m, or when the view changed enough."""

    def __init__(
        self, min_travel: float | None = DEFAULT_MIN_TRAVEL, min_change: float | None = DEFAULT_MIN_CHANGE
    ) -> None:
        """Keep a frame after min_travel (m) of travel or an amplitude-descriptor change of min_change (None: off)."""
        self.min_travel = min_travel
        self.min_change = min_change
        self._position: np.ndarray | None = None
        self._descriptor: np.ndarray | None = None

    def keep(self, descriptor: np.ndarray, position: np.ndarray | None = None) -> bool:
        """Return whether a frame (amplitude descriptor, position in m or None) becomes a snapshot (then kept)."""
        descriptor = np.asarray(descriptor, dtype=float)
        first = self._descriptor is None
        travelled = (
            self.min_travel is not None
            and position is not None
            and self._position is not None
            and float(np.linalg.norm(np.asarray(position, float) - self._position)) >= self.min_travel
        )
        changed = (
            self.min_change is not None
            and not first
            and float(np.linalg.norm(descriptor - self._descriptor)) >= self.min_change
        )
        if first or travelled or changed:
            self._descriptor = descriptor
            self._position = None if position is None else np.asarray(position, dtype=float)
            return True
        return False


def _with_settings(metadata: Mapping[str, Any] | None) -> dict[str, Any]:
    """Return caller metadata plus this library's descriptor settings."""
    return {**(metadata or {}), SETTINGS_KEY: descriptor_settings()}


def create_map(
    path: str | Path,
    name: str,
    max_degree: int,
    *,
    created_from: str = '',
    metadata: Mapping[str, Any] | None = None,
    overwrite: bool = False,
) -> MapStore:
    """Create an empty map (MapStore.create) that records this library's descriptor settings; add snapshots to it."""
    return MapStore.create(
        path, name, max_degree, created_from=created_from, metadata=_with_settings(metadata), overwrite=overwrite
    )


def build_map(
    path: str | Path,
    name: str,
    max_degree: int,
    snapshots: Iterable[Snapshot],
    *,
    created_from: str = '',
    metadata: Mapping[str, Any] | None = None,
    overwrite: bool = False,
    finish=None,
) -> MapStore:
    """Write a whole map atomically (MapStore.build) with this library's descriptor settings; return it read-only."""
    return MapStore.build(
        path,
        name,
        max_degree,
        snapshots,
        created_from=created_from,
        metadata=_with_settings(metadata),
        overwrite=overwrite,
        finish=finish,
    )
