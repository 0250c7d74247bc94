# SPDX-License-Identifier: Apache-2.0
"""Benchmark: what the bag checks (checksums, metadata and type checks, CDR normalisation) add to `skynav run`.

    .venv/bin/python bench/bag_checks.py [--bag BAG] [--teach BAG]

Runs `skynav run` once on BAG (the bundled synthetic garden repeat, against a
map built from the garden teach drive) and then, on the same data, times each
check on its own against the same work without it: reading the input with its
checksums verified (before reading: the data section and summary CRCs; while
reading: each chunk's CRC and zstd checksum) against a copy written without
checksums, writing the run's outputs with checksums against rosbags' plain
writer, and passing them through `rosbags_cdr`. Prints each cost and their sum
as a share of the run's time. Best of REPEATS for each timing.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

from skynav_bringup.cli import main
from skynav_core.recording.bag import BagWriter, open_bag
from skynav_core.recording.cdr import rosbags_cdr
from skynav_core.recording.typestore import typestore
from skynav_testing import BAGS

REPEATS = 5


def best(work: Callable[[], object]) -> float:
    """Return the least wall time (s) of REPEATS calls of `work`."""
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return min(times)


def skynav(*arguments: str) -> None:
    """Run `skynav ARGUMENTS` in this process; raise unless it exits 0."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(list(arguments))
    if code != 0:
        raise SystemExit(f'skynav {" ".join(arguments)} failed: {err.getvalue()}')


def write_plain(path: Path, messages: list, compress: bool) -> None:
    """Write messages [(topic, type, log time, bytes)] with rosbags' own writer: no checksums."""
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    if compress:
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        connections = {}
        for topic, msgtype, log_time, data in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=typestore())
            writer.write(connections[topic], log_time, data)


def write_checked(path: Path, messages: list, normalise: bool) -> None:
    """Write messages with BagWriter (checksums), through rosbags_cdr as `skynav run` does when `normalise`."""
    with BagWriter(path) as writer:
        for topic, msgtype, log_time, data in messages:
            writer.add_topic(topic, msgtype)
            writer.write(topic, log_time, rosbags_cdr(msgtype, data) if normalise else data)


def read_all(path: Path) -> int:
    """Open a bag as every command does and read every message; return the count."""
    with open_bag(path) as bag:
        return sum(1 for _ in bag.messages())


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--bag', type=Path, default=BAGS / 'synthetic_garden_repeat.mcap')
    parser.add_argument('--teach', type=Path, default=BAGS / 'synthetic_garden_teach.mcap')
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        skynav('map', 'build', str(args.teach), '--out', str(root / 'map.db'))
        start = time.perf_counter()
        skynav('run', str(args.bag), '--map', str(root / 'map.db'), '--out', str(root / 'run.mcap'))
        run_time = time.perf_counter() - start
        with open_bag(args.bag) as bag:
            inputs = [(m.topic, m.msgtype, m.log_time, m.data) for m in bag.messages()]
        with open_bag(root / 'run.mcap') as bag:
            outputs = [(m.topic, m.msgtype, m.log_time, m.data) for m in bag.messages()]
        write_plain(root / 'plain_in', inputs, compress=True)
        plain_input = root / 'plain_in' / 'plain_in.mcap'
        read_cost = best(lambda: read_all(args.bag)) - best(lambda: read_all(plain_input))
        counter = iter(range(10**6))
        checked_write = best(lambda: write_checked(root / f'c{next(counter)}.mcap', outputs, normalise=False))
        plain_write = best(lambda: write_plain(root / f'p{next(counter)}', outputs, compress=True))
        normalise = best(lambda: [rosbags_cdr(msgtype, data) for _, msgtype, _, data in outputs])
    write_cost = checked_write - plain_write
    total = read_cost + write_cost + normalise
    print(f'skynav run {args.bag.name}: {run_time:.2f} s ({len(inputs)} inputs, {len(outputs)} outputs)')
    print(f'  reading the input with its checksums checked: {1e3 * read_cost:+.1f} ms')
    print(f'  writing the outputs with checksums:           {1e3 * write_cost:+.1f} ms')
    print(f'  rosbags_cdr over the outputs:                 {1e3 * normalise:+.1f} ms')
    print(f'  all checks: {1e3 * total:.1f} ms, {100 * total / run_time:.2f} % of the run')


if __name__ == '__main__':
    main_bench()
