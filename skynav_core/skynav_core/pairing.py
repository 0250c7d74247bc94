# SPDX-License-Identifier: Apache-2.0
"""Pairing the UV and green frames of one exposure by their stamps."""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any

DEFAULT_TOLERANCE_NS = 2_000_000  # 2 ms: frames of one exposure carry the same stamp; nearest within this


@dataclass
class StampPairer:
    """Collects items of two channels and yields pairs with equal stamps (exact first, else nearest within tolerance).

    Items older than the newest completed pair are dropped as they can no longer pair
    (counted in `unpaired`, and told to `on_drop` with their number); at most `capacity` items wait per channel.
    """

    channels: tuple[Hashable, Hashable]
    tolerance_ns: int = DEFAULT_TOLERANCE_NS
    capacity: int = 10
    unpaired: int = 0
    on_drop: Callable[[int], None] | None = None
    _waiting: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._waiting = {channel: OrderedDict() for channel in self.channels}

    def _dropped(self, count: int) -> None:
        """Count `count` items that will never pair."""
        self.unpaired += count
        if self.on_drop is not None and count:
            self.on_drop(count)

    def clear(self) -> None:
        """Drop (and count) every waiting item: none of them can pair any more (the time restarted)."""
        self._dropped(sum(len(queue) for queue in self._waiting.values()))
        for queue in self._waiting.values():
            queue.clear()

    def add(self, channel: Hashable, stamp: int, item: Any) -> tuple[int, Any, Any] | None:
        """Add an item; return (stamp, item of channel 0, item of channel 1) when it completes a pair."""
        mine = self._waiting[channel]
        other_channel = self.channels[1] if channel == self.channels[0] else self.channels[0]
        other = self._waiting[other_channel]
        match = stamp if stamp in other else None
        if match is None and other:
            nearest = min(other, key=lambda s: abs(s - stamp))
            if abs(nearest - stamp) <= self.tolerance_ns:
                match = nearest
        if match is None:
            mine[stamp] = item
            while len(mine) > self.capacity:
                mine.popitem(last=False)
                self._dropped(1)
            return None
        partner = other.pop(match)
        # Anything older than this pair can no longer find its partner.
        for queue in (mine, other):
            for old in [s for s in queue if s < min(stamp, match)]:
                del queue[old]
                self._dropped(1)
        pair_stamp = min(stamp, match)
        return (pair_stamp, item, partner) if channel == self.channels[0] else (pair_stamp, partner, item)
