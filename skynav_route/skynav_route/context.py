# SPDX-License-Identifier: Apache-2.0
"""The goal context: what localize, compass and warping compare against while a goal drives, as one typed value.

The route node sends it to the three nodes before a goal drives, as one parameter set per node taken all or none
(skynav_core.peers), and waits until they took it; the contract's way to fix a node's snapshot choice is a node
parameter (docs/interfaces.md, "Driving: teach, follow, home", the goal context). Following: the compass against
the latest accepted match, warping `lookahead` snapshots beyond it, localize tracking along the route (its first
views sought near `start_index` when the goal names one); once a follow goal ends, localize seeks the place on the
whole route again (AFTER_FOLLOW). Homing: compass and warping against the goal's snapshot. A goal naming another
map than the route node's gives it to all three.

No rclpy. test/test_goal_context.py checks every parameter set here against the node's own parameter table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from skynav_core.names import COMPASS_NODE, LOCALIZE_NODE, WARPING_NODE

ALONG_ROUTE = -1  # GoalContext.snapshot while following: no one snapshot, the route's

Settings = dict[str, dict[str, Any]]  # {node: {parameter: value}}


@dataclass(frozen=True)
class GoalContext:
    """What the nodes upstream of the route node compare against during one goal."""

    snapshot: int  # homing: the goal's snapshot index; ALONG_ROUTE while following
    lookahead: int = 0  # following: snapshots beyond the matched one that warping homes to
    start_index: int = -1  # following: the snapshot the robot starts at (-1: wherever localization places it)
    map_path: str = ''  # the goal's map when it is not the route node's own ('': each node keeps its map)

    @classmethod
    def follow(cls, lookahead: int, start_index: int, map_path: str = '') -> GoalContext:
        """Return the context of a FollowRoute goal."""
        return cls(ALONG_ROUTE, lookahead, start_index, map_path)

    @classmethod
    def home(cls, index: int, map_path: str = '') -> GoalContext:
        """Return the context of a Home goal to snapshot `index`."""
        return cls(index, map_path=map_path)

    @property
    def following(self) -> bool:
        """Return whether this is a follow goal's context (no one snapshot)."""
        return self.snapshot == ALONG_ROUTE

    def parameters(self) -> Settings:
        """Return the parameter set of each node that takes this context ({node: {parameter: value}})."""
        compass: dict[str, Any]
        warping: dict[str, Any]
        localize: dict[str, Any]
        if self.following:
            compass = {'reference': 'match'}
            warping = {'target': 'next', 'lookahead': self.lookahead}
            localize = {'tracking': True, 'tracking_start': self.start_index}
        else:
            compass = {'reference': 'index', 'index': self.snapshot}
            warping = {'target': 'index', 'index': self.snapshot}
            localize = {}
        settings: Settings = {COMPASS_NODE: compass, WARPING_NODE: warping, LOCALIZE_NODE: localize}
        if self.map_path:
            for values in settings.values():
                values['map'] = self.map_path
        return {node: values for node, values in settings.items() if values}


#: localize's parameter set once a follow goal has ended: off the route, the place is sought on the whole route again
AFTER_FOLLOW: Settings = {LOCALIZE_NODE: {'tracking': False, 'tracking_start': -1}}

#: the nodes a goal context is sent to
NODES = (LOCALIZE_NODE, COMPASS_NODE, WARPING_NODE)
