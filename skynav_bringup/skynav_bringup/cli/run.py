# SPDX-License-Identifier: Apache-2.0
"""Run the whole node graph over a recording in one process and record every output topic.

Deterministic: every input frame is processed, in recording order, none dropped, however fast
the machine is; the same recording gives the same outputs. The nodes are the installed ones (the
same classes `skynav launch` starts), with their parameters from the shipped defaults and --params.
Without --map the nodes that compare against a map are left out.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from skynav_core.cli import add_skip_damaged

HELP = 'run the node graph over a bag offline and record every output'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav run`."""
    parser.add_argument('bag', metavar='BAG', help='rosbag2 directory or .mcap file with the camera topics')
    add_skip_damaged(parser)
    parser.add_argument('--out', required=True, metavar='OUT.mcap', help='recording of every output topic')
    parser.add_argument('--map', type=Path, metavar='MAP.db', help='map for the nodes that need one')
    parser.add_argument('--params', type=Path, metavar='FILE', help='ROS 2 parameter file (YAML)')
    parser.add_argument('--nodes', nargs='+', metavar='NAME', help='run only these nodes')


def run(args: argparse.Namespace) -> int:
    """Run the graph; return the exit code."""
    from tqdm import tqdm

    from skynav_core.cli import open_map
    from skynav_core.graph import in_process, node_class
    from skynav_core.nodes import installed_nodes
    from skynav_core.recording.bag import BagWriter, open_bag
    from skynav_core.recording.cdr import rosbags_cdr

    from ..parameters import ros_arguments
    from . import CliError

    specs = installed_nodes()
    if args.nodes:
        if unknown := sorted(set(args.nodes) - {s.name for s in specs}):
            raise CliError(f'no installed node {", ".join(unknown)} (installed: {", ".join(s.name for s in specs)})')
        specs = [s for s in specs if s.name in args.nodes]
    if args.map is not None:  # a map the nodes would refuse stops the run here, in one line
        open_map(args.map).close()
    skipped = [s.name for s in specs if args.map is None and node_class(s).needs_map]
    specs = [s for s in specs if s.name not in skipped]
    if not specs:
        raise CliError('no skynav nodes to run (none installed, or all need a map)')
    ros_args = ros_arguments(args.params, args.map)
    with open_bag(args.bag) as bag:
        writer = BagWriter(args.out)

        def record(topic: str, msgtype: str, log_time: int, data: bytes) -> None:
            if topic not in writer.topics:
                writer.add_topic(topic, msgtype)
            writer.write(
                topic, log_time, rosbags_cdr(msgtype, data)
            )  # as rosbags reads it (see skynav_core.recording.cdr)

        try:
            with in_process(specs, ros_args, sink=record) as graph:
                topics = graph.input_topics & set(bag.topics)
                if not topics:
                    raise CliError(
                        f'{args.bag} has none of the topics the nodes read ({", ".join(sorted(graph.input_topics))})'
                    )
                total = sum(bag.topics[t].count for t in topics)
                with tqdm(total=total, unit='msg', desc='skynav run', file=sys.stderr, disable=None) as bar:
                    graph.run(bag, progress=bar.update)
                report = summary(graph)
                errors = sum(node.errors for node in graph.nodes)
                refused = [node.get_name() for node in graph.nodes if node.rejected.get('parameters')]
        except BaseException:
            writer.abort()  # an interrupted run must not leave an output that looks complete
            raise
        writer.close()
    print(report, file=sys.stderr)
    if skipped:
        print(f'skynav run: left out (no --map): {", ".join(skipped)}', file=sys.stderr)
    print(f'skynav run: wrote {sum(writer.counts.values())} messages to {writer.path}', file=sys.stderr)
    if errors:
        print(f'skynav run: error: {errors} inputs failed with an exception (see the log above)', file=sys.stderr)
    if refused:
        print(
            f'skynav run: error: {", ".join(refused)} could not use the given parameters and ran on defaults '
            '(see the log above)',
            file=sys.stderr,
        )
    return 1 if errors or refused else 0


def summary(graph) -> str:
    """Return a table of what each node received, published, rejected (and dropped), and its time per input."""
    lines = [f'{"node":12s} {"received":>9s} {"published":>10s} {"rejected":>9s} {"errors":>7s} {"ms/input":>9s}']
    for node in graph.nodes:
        per_input = 1e3 * node.processing_total / node.processing_count if node.processing_count else float('nan')
        rejected = ', '.join(
            [f'{k} {v}' for k, v in sorted(node.rejected.items())]
            + [f'dropped {k} {v}' for k, v in sorted(node.dropped.items())]
            + ([f'time restarts {node.time_resets}'] if node.time_resets else [])
        )
        lines.append(
            f'{node.get_name():12s} {sum(node.received.values()):9d} {sum(node.published.values()):10d} '
            f'{sum(node.rejected.values()):9d} {node.errors:7d} {per_input:9.2f}'
            + (f'   ({rejected})' if rejected else '')
        )
    return '\n'.join(lines)
