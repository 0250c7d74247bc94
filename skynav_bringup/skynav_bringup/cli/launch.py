# SPDX-License-Identifier: Apache-2.0
"""Start the skynav node graph on live topics, one process per node; Ctrl-C stops every node cleanly.

The nodes are those installed in this environment (see `skynav_core.nodes`).
Parameters come from the defaults shipped in skynav_bringup/config, overridden by the YAML file
given with --params, in the ROS 2 format (`node_name: {ros__parameters: {...}}`); --map sets the
map of the nodes that compare against one (localize, compass, warping). --namespace puts the whole graph under
/NS (skynav_core.namespaces) and --remap renames a topic for every node. On a full ROS 2 install,
`ros2 launch skynav_bringup skynav.launch.py` starts the same graph.

Across machines (a robot and a base station, docs/networking.md, 'Robot and base station'): --discovery-range
subnet, --static-peers where multicast is blocked, or --discovery-server (with --serve-discovery on
the one host that runs the server), and the transport (shm: shared memory between processes of this
machine, UDP between machines; udp: UDP only).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from skynav_core.cli import add_namespace
from skynav_core.process.network import DISCOVERY_RANGES, DISCOVERY_SERVER_PORT, TRANSPORTS

HELP = 'start the whole node graph on live topics'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav launch`."""
    parser.add_argument(
        '--params', metavar='FILE', type=Path, help='ROS 2 parameter file (YAML) over the shipped defaults'
    )
    parser.add_argument('--map', type=Path, metavar='MAP.db', help='map for the nodes that need one')
    parser.add_argument('--nodes', nargs='+', metavar='NAME', help='start only these nodes')
    add_namespace(parser, 'the graph: every node, topic, service and action under /NS, its /clock and /tf_static too')
    parser.add_argument(
        '--remap',
        action='append',
        default=[],
        metavar='FROM:=TO',
        help="rename a topic for every node (repeatable): FROM as the contract names it (/cmd_vel), TO the robot's "
        'topic (absolute, or relative to the namespace)',
    )
    parser.add_argument(
        '--discovery-range',
        choices=DISCOVERY_RANGES,
        help='where to look for other nodes (ROS_AUTOMATIC_DISCOVERY_RANGE; default localhost)',
    )
    parser.add_argument(
        '--static-peers', nargs='+', metavar='ADDRESS', help='other hosts to reach by unicast (ROS_STATIC_PEERS)'
    )
    parser.add_argument(
        '--discovery-server',
        metavar='ADDRESS[:PORT]',
        help=f'find the other nodes through this Fast DDS discovery server (default port {DISCOVERY_SERVER_PORT})',
    )
    parser.add_argument(
        '--serve-discovery',
        action='store_true',
        help='also run the discovery server of --discovery-server on this host, started before the nodes '
        '(ADDRESS must be one of its own); start this host before the others',
    )
    parser.add_argument(
        '--transport',
        choices=tuple(TRANSPORTS),
        help='shm (default): shared memory on this machine, UDP between machines; udp: UDP only',
    )


def run(args: argparse.Namespace) -> int:
    """Launch and wait; return the exit code."""
    from skynav_core.namespaces import NamespaceError, remap_arguments
    from skynav_core.nodes import installed_nodes
    from skynav_core.process.launcher import Launcher
    from skynav_core.process.network import network_environment, socket_buffer_warning, start_discovery_server
    from skynav_core.ros import StopRequest

    from ..parameters import ros_arguments
    from . import CliError

    if args.map is not None and not args.map.is_file():
        raise CliError(f'{args.map}: no such map file')
    try:
        remaps = remap_arguments(args.namespace, args.remap)
    except NamespaceError as exc:
        raise CliError(str(exc), exit_code=2) from None
    scratch = tempfile.TemporaryDirectory(prefix='skynav-launch-')  # the parameter files made for the namespace
    ros_args = ros_arguments(args.params, args.map, args.namespace, Path(scratch.name)) + remaps
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
    if args.serve_discovery and args.discovery_server is None:
        raise CliError('--serve-discovery needs --discovery-server ADDRESS[:PORT] (where to serve)')
    os.environ.update(
        network_environment(args.discovery_range, args.static_peers, args.discovery_server, args.transport)
    )
    leaves_host = args.discovery_range in ('subnet', 'system_default') or args.static_peers or args.discovery_server
    if leaves_host and (warning := socket_buffer_warning()):
        print(f'skynav launch: warning: {warning}', file=sys.stderr, flush=True)
    server = None
    if args.serve_discovery:
        # before the nodes: participants that start before their server may never find each other through it
        server = start_discovery_server(args.discovery_server, sys.stdout)
        print(f'[launch] discovery server serving on {args.discovery_server} (pid {server.pid})', flush=True)
    launcher = Launcher(specs, ros_args)
    if args.namespace:
        print(f'[launch] namespace {args.namespace}: topics and actions under {args.namespace}/', flush=True)
    try:
        with StopRequest() as stop:
            launcher.start()
            return launcher.wait(lambda: stop.requested)
    finally:
        scratch.cleanup()
        if server is not None:
            server.terminate()
            server.wait(timeout=10)
