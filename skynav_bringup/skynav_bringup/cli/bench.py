# SPDX-License-Identifier: Apache-2.0
"""Measure whether this computer keeps up with the camera: the whole node graph over a recording, timed per node.

The graph runs in this process over the recording, as `skynav run` runs it (the installed nodes, the shipped
parameters and --params, every input frame processed in order, none dropped), and the CPU time of every node's
callbacks is measured on its own (what a node's callback spends in the nodes it publishes to is theirs), as is
the decoding of the recorded inputs (live, each node decodes what it receives). The first --warmup frames are run
but not timed (tables built once, caches filled). Printed per node: milliseconds of CPU per camera frame, the
frames per second that gives, and the share of one core it takes at the camera rate (--rate, default 10 Hz); and
for the whole graph, the sum, its ratio to the camera period and whether this computer keeps up: live every node
is a process of its own, so the graph keeps up when its slowest node does and the sum fits the cores.

The nodes that compare against a map (localize, compass, warping) need one: --map, or a map built here from a
teach drive (--teach; the bundled default's is the bundled garden teach drive, another recording's is the
recording itself). The default recording is the bundled synthetic garden repeat drive (320x240, 10 Hz).

These are in-process figures: live, DDS, the rclpy executor and each process's timers cost more on top
(docs/bench.md, 'Compute', gives this project's live figures against these). Times are CPU time of this
process's thread, so other programs running at the same time disturb them less than wall-clock time.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from skynav_core.cli import add_skip_damaged

HELP = 'measure the frames per second the node graph sustains on this computer'
BUNDLED = Path(__file__).resolve().parents[3] / 'bags'  # the bundled (synthetic) recordings, in a source checkout
DEFAULT_BAG = BUNDLED / 'synthetic_garden_repeat.mcap'
DEFAULT_TEACH = BUNDLED / 'synthetic_garden_teach.mcap'
DECODING = 'decoding'  # the row of the recorded inputs' decoding


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav bench`."""
    parser.add_argument(
        '--bag',
        type=Path,
        default=DEFAULT_BAG,
        metavar='BAG',
        help=f'recording with the camera topics ({DEFAULT_BAG.name})',
    )
    add_skip_damaged(parser)
    parser.add_argument('--rate', type=float, default=10.0, metavar='HZ', help='camera rate to check against (10)')
    parser.add_argument('--map', type=Path, metavar='MAP.db', help='map for the nodes that need one')
    parser.add_argument(
        '--teach', type=Path, metavar='BAG', help='build the map from this teach drive (default: see above)'
    )
    parser.add_argument('--frames', type=int, metavar='N', help='time only the first N frames after the warm-up')
    parser.add_argument('--warmup', type=int, default=3, metavar='N', help='frames run before timing starts (3)')
    parser.add_argument('--params', type=Path, metavar='FILE', help='ROS 2 parameter file (YAML)')


class NodeClock:
    """CPU time spent in each node's callbacks, each callback's own (nested deliveries are the receivers')."""

    def __init__(self) -> None:
        import time

        self._now = time.thread_time
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self._nested: list[float] = []  # per open callback: the time its nested callbacks took
        self.running = False

    def wrap(self, name: str, callback):
        """Return `callback` timed as work of node `name`."""
        self.seconds.setdefault(name, 0.0)
        self.calls.setdefault(name, 0)

        def timed(*args, **kwargs):
            if not self.running:
                return callback(*args, **kwargs)
            start = self._now()
            self._nested.append(0.0)
            try:
                return callback(*args, **kwargs)
            finally:
                elapsed = self._now() - start
                nested = self._nested.pop()
                self.seconds[name] += elapsed - nested
                self.calls[name] += 1
                if self._nested:
                    self._nested[-1] += elapsed

        return timed

    def measure(self, name: str, function, *args) -> None:
        """Call function(*args) and count its CPU time, less its callbacks', as `name`'s."""
        self.wrap(name, function)(*args)


def time_nodes(graph) -> NodeClock:
    """Wrap every node's input callbacks and diagnostics in a NodeClock; return it (stopped)."""
    clock = NodeClock()
    # A node subscribes its topics while it is built, in graph order: the callbacks of a topic are those of the
    # nodes that list it among their input topics, in that order.
    subscribers = graph._subscribers
    for topic, callbacks in subscribers.items():
        owners = [node.get_name() for node in graph.nodes for t in node.input_topics if t == topic]
        if len(owners) != len(callbacks):
            raise RuntimeError(f'cannot tell which node subscribed which callback of {topic}')
        subscribers[topic] = [clock.wrap(owner, callback) for owner, callback in zip(owners, callbacks)]
    for node in graph.nodes:
        node.publish_diagnostics = clock.wrap(node.get_name(), node.publish_diagnostics)
    return clock


def build_map(teach: Path, folder: Path, params: Path | None) -> Path:
    """Build a map from a teach drive with `skynav map build`; return its path."""
    import contextlib
    import io

    from . import CliError, main

    path = folder / 'bench.db'
    arguments = ['map', 'build', str(teach), '--out', str(path)] + (['--params', str(params)] if params else [])
    errors = io.StringIO()
    with contextlib.redirect_stderr(errors):
        code = main(arguments)
    if code != 0:
        raise CliError(f'building a map from {teach} failed:\n{errors.getvalue().strip()}')
    return path


def run(args: argparse.Namespace) -> int:
    """Run the graph over the recording, timed; print the table; return the exit code."""
    import tempfile

    from . import CliError

    if args.rate <= 0:
        raise CliError('--rate must be positive', exit_code=2)
    if args.warmup < 0 or (args.frames is not None and args.frames <= 0):
        raise CliError('--warmup must not be negative and --frames must be positive', exit_code=2)
    if not args.bag.exists():
        where = ' (the bundled recordings come with a source checkout)' if args.bag == DEFAULT_BAG else ''
        raise CliError(f'{args.bag}: no such recording{where}')
    with tempfile.TemporaryDirectory(prefix='skynav-bench-') as folder:
        map_path = args.map
        if map_path is None:
            teach = args.teach or (DEFAULT_TEACH if args.bag == DEFAULT_BAG else args.bag)
            map_path = build_map(teach, Path(folder), args.params)
        result = measure(args.bag, map_path, args.params, args.warmup, args.frames)
    print(table(result, args.rate))
    return 0


def measure(bag_path: Path, map_path: Path, params: Path | None, warmup: int, frames: int | None) -> dict:
    """Run the graph over a recording; return what was timed: per row CPU seconds and calls, frames, the camera."""
    from rclpy.serialization import deserialize_message

    from skynav_core.camera_input import recorded_source
    from skynav_core.cli import open_map
    from skynav_core.graph import in_process
    from skynav_core.nodes import installed_nodes
    from skynav_core.recording.bag import open_bag
    from skynav_core.ros import message_class

    from ..parameters import ros_arguments
    from . import CliError

    open_map(map_path).close()  # a map the nodes would refuse stops here, in one line
    specs = installed_nodes()
    if not specs:
        raise CliError('no skynav nodes installed')
    with open_bag(bag_path) as bag, in_process(specs, ros_arguments(params, map_path)) as graph:
        source = recorded_source(bag.topics)
        if source is None:
            raise CliError(f'{bag_path} holds no camera frames (none of the camera topics the nodes read)')
        frame_topic = source.images[0]
        clock = time_nodes(graph)
        topics = sorted(graph.input_topics & set(bag.topics))
        seen = timed_frames = 0
        width = height = 0
        for raw in bag.messages(topics):
            if raw.topic == frame_topic:
                seen += 1
                if frames is not None and seen > warmup + frames:
                    break
                clock.running = seen > warmup
                timed_frames += clock.running
            if not width and raw.topic == source.info:
                info = deserialize_message(raw.data, message_class(raw.msgtype))
                width, height = int(info.width), int(info.height)
            # what feeding takes besides the nodes' callbacks: decoding the recorded input, delivering it
            clock.measure(DECODING, graph.feed, raw)
        clock.running = False
        nodes = [node.get_name() for node in graph.nodes]
    if timed_frames == 0:
        raise CliError(f'{bag_path} has {seen} camera frames: none left to time after {warmup} of warm-up')
    return {
        'bag': bag_path,
        'frames': timed_frames,
        'warmup': warmup,
        'size': (width, height),
        'rows': [(name, clock.seconds[name], clock.calls[name]) for name in [*nodes, DECODING]],
    }


def table(result: dict, rate: float) -> str:
    """Return the readable report of a measurement at a camera rate (Hz)."""
    frames = result['frames']
    period = 1e3 / rate  # ms
    cores = os.cpu_count() or 1
    width, height = result['size']
    lines = [
        f'skynav bench: {Path(result["bag"]).name}'
        + (f' ({width}x{height})' if width else '')
        + f', {frames} frames timed after {result["warmup"]} of warm-up; camera at {rate:g} Hz '
        f'({period:.0f} ms a frame); {cores} cores',
        '',
        f'{"node":10s} {"calls":>7s} {"ms/frame":>9s} {"fps":>9s} {f"core at {rate:g} Hz":>15s}',
    ]
    total_ms = 0.0
    slowest = ('', 0.0)
    for name, seconds, calls in result['rows']:
        ms = 1e3 * seconds / frames
        total_ms += ms
        if name != DECODING and ms > slowest[1]:
            slowest = (name, ms)
        lines.append(f'{name:10s} {calls:7d} {ms:9.2f} {fps(ms):9.1f} {100 * ms / period:14.1f} %')
    lines.append(f'{"all":10s} {"":7s} {total_ms:9.2f} {fps(total_ms):9.1f} {100 * total_ms / period:14.1f} %')
    sustained = min(fps(slowest[1]), cores * fps(total_ms))
    keeps_up = sustained >= rate
    lines += [
        '',
        f'whole graph: {total_ms:.1f} ms of CPU per frame = {total_ms / period:.2f} x the camera period '
        f'({fps(total_ms):.1f} fps on one core)',
        f'live, one process per node on {cores} cores: at most {sustained:.1f} fps (slowest node {slowest[0]} '
        f'{fps(slowest[1]):.1f} fps; the sum over {cores} cores {cores * fps(total_ms):.1f} fps), before the '
        'transport and executor overhead of a live graph',
        f'keeps up with {rate:g} Hz: {"yes" if keeps_up else "no"}'
        + (f' ({sustained / rate:.1f} x the camera rate)' if keeps_up else f' (only {sustained:.1f} fps)'),
    ]
    return '\n'.join(lines)


def fps(ms: float) -> float:
    """Return frames per second of `ms` milliseconds per frame (inf for none)."""
    return 1e3 / ms if ms > 0 else float('inf')
