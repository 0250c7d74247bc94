# SPDX-License-Identifier: Apache-2.0
"""The skynav nodes installed in this environment, found through the `skynav.nodes` entry points.

A package adds its node to the graph by declaring, in its setup.py, its node class
``entry_points={'skynav.nodes': ['skyline = skynav_skyline.node:SkylineNode'], ...}``
and, for `ros2 run`/`ros2 launch`, a console script ``skyline_node = skynav_skyline.node:main``
in the same module (main runs the class). `skynav launch` starts each class in a process
of its own; `skynav run` creates them all in one process.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib.metadata import entry_points

from .names import COMPASS_NODE, LOCALIZE_NODE, SH_NODE, SKYLINE_NODE, WARPING_NODE

ENTRY_POINT_GROUP = 'skynav.nodes'
# The data flow of docs/interfaces.md: nodes start in this order; others follow by name.
GRAPH_ORDER = (SKYLINE_NODE, SH_NODE, LOCALIZE_NODE, COMPASS_NODE, WARPING_NODE)


@dataclass(frozen=True)
class NodeSpec:
    """One node of the graph."""

    name: str  # its name in the graph, e.g. 'skyline'
    package: str  # the ROS package (distribution) that provides it
    entry: str  # 'module:Class' of its node class
    executable: str | None = None  # its console script for `ros2 run`, if the package declares one


def installed_nodes() -> list[NodeSpec]:
    """Return the installed skynav nodes in data-flow order."""
    specs = []
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        dist = ep.dist
        module = ep.value.partition(':')[0]
        scripts = (
            []
            if dist is None
            else [
                s.name
                for s in dist.entry_points
                if s.group == 'console_scripts' and s.value.partition(':')[0] == module
            ]
        )
        package = dist.metadata['Name'] if dist is not None else ep.module.split('.')[0]
        specs.append(NodeSpec(ep.name, package, ep.value, scripts[0] if scripts else None))

    def order(spec: NodeSpec) -> tuple[int, str]:
        rank = GRAPH_ORDER.index(spec.name) if spec.name in GRAPH_ORDER else len(GRAPH_ORDER)
        return rank, spec.name

    return sorted(specs, key=order)
