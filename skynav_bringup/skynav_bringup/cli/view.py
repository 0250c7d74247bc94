# SPDX-License-Identifier: Apache-2.0
"""Watch the running graph live in Foxglove: a Foxglove WebSocket server forwarding the live topics.

Open Foxglove, "Open connection", "Foxglove WebSocket", the address printed, then import the layout printed
(skynav_bringup/config/skynav.foxglove.json). Topics are forwarded as their CDR bytes with their ros2msg schemas
(skynav_bringup.viewer), each only while a Foxglove client subscribes to it. The server listens on 127.0.0.1 by
default; --host 0.0.0.0 lets another machine (a laptop on the robot's network) connect.
"""

from __future__ import annotations

import argparse
import sys

from skynav_core.cli import add_namespace

HELP = 'serve the live topics to Foxglove (WebSocket)'
DEFAULT_PORT = 8765  # Foxglove's usual WebSocket port


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav view`."""
    parser.add_argument('--host', default='127.0.0.1', help='address to listen on (default 127.0.0.1; 0.0.0.0: all)')
    parser.add_argument(
        '--port', type=int, default=DEFAULT_PORT, help=f'port to listen on (default {DEFAULT_PORT}; 0: any free one)'
    )
    parser.add_argument('--topics', nargs='+', metavar='TOPIC', help='forward only these topics (default: all)')
    add_namespace(parser, 'the graph to watch: only its topics are forwarded, named as outside a namespace')


def layout_file():
    """Return the Foxglove layout shipped with skynav_bringup, if installed."""
    from skynav_core.process.environment import share_directory

    share = share_directory('skynav_bringup')
    path = None if share is None else share / 'config' / 'skynav.foxglove.json'
    return path if path is not None and path.is_file() else None


def run(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C; return the exit code."""
    import foxglove

    from skynav_core.ros import StopRequest, tool_node

    from ..viewer import Viewer
    from . import CliError

    if not 0 <= args.port <= 65535:
        raise CliError(f'--port {args.port} is not a port number (0..65535)', exit_code=2)

    def warn(text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    with StopRequest() as stop, tool_node('skynav_view', events=True) as (node, executor):
        viewer = Viewer(node, args.topics, warn, say=warn, namespace=args.namespace)
        try:
            server = foxglove.start_server(name='skynav', host=args.host, port=args.port, server_listener=viewer)
        except Exception as exc:  # the SDK raises its own error types (e.g. the port in use)
            raise CliError(f'cannot serve on {args.host}:{args.port}: {exc}') from None
        layout = layout_file()
        print(
            f'skynav view: Foxglove WebSocket server on ws://{args.host}:{server.port} '
            '(Foxglove: Open connection, Foxglove WebSocket)' + (f'; layout: {layout}' if layout is not None else ''),
            file=sys.stderr,
            flush=True,
        )
        try:
            while not stop.requested:
                executor.spin_once(timeout_sec=0.25)
        finally:
            server.stop()
    total = sum(viewer.forwarded.values())
    print(f'skynav view: forwarded {total} messages on {len(viewer.forwarded)} topics', file=sys.stderr)
    return 0
