# SPDX-License-Identifier: Apache-2.0
"""Start the skynav node graph on live topics, one process per node; Ctrl-C stops every node cleanly.

The nodes are those installed in this environment (see `skynav_core.nodes`).
Parameters come from the defaults shipped in skynav_bringup/config, overridden by the YAML file
given with --params, in the ROS 2 format (`node_name: {ros__parameters: {...}}`); --map sets the
map of the nodes that compare against one (localize, compass, warping). On a full ROS 2 install,
`ros2 launch skynav_bringup skynav.launch.py` starts the same graph.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = 'start the whole node graph on live topics'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav launch`."""
    parser.add_argument(
        '--params', metavar='FILE', type=Path, help='ROS 2 parameter file (YAML) over the shipped defaults'
    )
    parser.add_argument('--map', type=Path, metavar='MAP.db', help='map for the nodes that need one')
    parser.add_argument('--nodes', nargs='+', metavar='NAME', help='start only these nodes')


def default_params_file() -> Path | None:
    """Return the parameter file shipped with skynav_bringup, if installed."""
    from skynav_core.environment import share_directory

    share = share_directory('skynav_bringup')
    path = None if share is None else share / 'config' / 'skynav.yaml'
    return path if path is not None and path.is_file() else None


def run(args: argparse.Namespace) -> int:
    """Launch and wait; return the exit code."""
    from skynav_core.launcher import Launcher
    from skynav_core.nodes import installed_nodes
    from skynav_core.ros import StopRequest

    from . import CliError
    from .run import ros_arguments

    if args.map is not None and not args.map.is_file():
        raise CliError(f'{args.map}: no such map file')
    ros_args = ros_arguments(args.params, args.map)
    specs = installed_nodes()
    if args.nodes:
        if unknown := sorted(set(args.nodes) - {s.name for s in specs}):
            raise CliError(
                f'no installed node {", ".join(unknown)} (installed: {", ".join(s.name for s in specs) or "none"})'
            )
        specs = [s for s in specs if s.name in args.nodes]
    if not specs:
        print('skynav launch: no skynav nodes are installed yet; nothing to start.', file=sys.stderr)
        return 0
    launcher = Launcher(specs, ros_args)
    with StopRequest() as stop:
        launcher.start()
        return launcher.wait(lambda: stop.requested)
