# SPDX-License-Identifier: Apache-2.0
"""Which map snapshot a node compares the current view against, and the views of snapshots, built once.

The compass (its `reference`) and the warping node (its `target`) choose alike, by a rule:

- a map of one snapshot: that snapshot, whatever the rule;
- 'index': snapshot `index` (the map's last one beyond its end);
- 'match': the snapshot of the latest accepted place match (/localization/match);
- 'next': the match's successor `lookahead` snapshots along the route (the map's last one beyond its end).

Without a snapshot to compare against the view is rejected with one set of reasons, counted in /diagnostics as
rejected_<reason>:

- 'no_map': no map, or a map without snapshots;
- 'no_match': no accepted place match yet (rules 'match' and 'next');
- 'match_beyond_map': the match names a snapshot this node's map lacks (the localize node runs a larger map).

The node's view of a snapshot (whatever it compares, prepared once) is kept for the SNAPSHOT_VIEWS_CACHED
snapshots used last, per map and setting. Logic only (no rclpy).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np

from .maps import MapStore, map_for_parameter

SNAPSHOT_REJECTIONS = ('no_map', 'no_match', 'match_beyond_map')
SNAPSHOT_VIEWS_CACHED = 64  # views of map snapshots kept (least recently used dropped first)


class SnapshotChoice:
    """The map, the latest accepted place match and the rule that choose a node's snapshot."""

    def __init__(self, reject: Callable[[str, str], None], view_of: Callable[[np.ndarray, float], Any]) -> None:
        self.reject = reject
        self.view_of = view_of  # (a snapshot's SH coefficients, field of view in rad) -> the node's view of it
        self.store: MapStore | None = None
        self.match: Any = None  # the latest accepted skynav_msgs/PlaceMatch
        self.rule, self.index, self.lookahead = 'match', 0, 0
        self.view = lru_cache(SNAPSHOT_VIEWS_CACHED)(self._view)

    def configure(self, map_path: str, rule: str, index: int = 0, lookahead: int = 0) -> None:
        """Open the map a `map` parameter names (ValueError if unusable: nothing changes) and take the rule.

        The views built so far are forgotten: they depend on the map and on the node's settings.
        """
        self.store = map_for_parameter(self.store, map_path)
        self.rule, self.index, self.lookahead = rule, index, lookahead
        self.view = lru_cache(SNAPSHOT_VIEWS_CACHED)(self._view)

    def forget_match(self) -> None:
        """Forget the latest place match (the time restarted: where the robot is must be found again)."""
        self.match = None

    def on_match(self, match: Any) -> None:
        """Remember the latest accepted place match (skynav_msgs/PlaceMatch)."""
        if match.accepted and match.index >= 0:
            self.match = match

    def choose(self, count: bool = True) -> int | None:
        """Return the snapshot to compare against, None if there is none (the reason counted unless not count)."""
        reject = self.reject if count else _uncounted
        if self.store is None or len(self.store) == 0:
            reject('no_map', 'no map with snapshots to compare against (set the map parameter)')
            return None
        n_snapshots = len(self.store)
        if n_snapshots == 1:
            return 0
        if self.rule == 'index':
            return min(self.index, n_snapshots - 1)
        if self.match is None:
            reject('no_match', 'no accepted place match yet to choose the snapshot')
            return None
        if self.match.index >= n_snapshots:
            reject(
                'match_beyond_map',
                f'the place match names snapshot {self.match.index} of map '
                f'{self.match.map_name!r}; this node has {n_snapshots} snapshots of '
                f'{self.store.name!r}',
            )
            return None
        if self.rule == 'next':
            return min(self.match.index + self.lookahead, n_snapshots - 1)
        return int(self.match.index)

    def _view(self, index: int, field_of_view: float) -> Any:
        """Return the node's view of one map snapshot seen with a field of view (rad)."""
        assert self.store is not None  # the index comes from choose(), which needs a map
        return self.view_of(self.store.coefficients()[index].copy(), field_of_view)


def _uncounted(reason: str, detail: str) -> None:
    """Count nothing: a look at the choice that is no input's rejection."""
