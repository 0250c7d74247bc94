# SPDX-License-Identifier: Apache-2.0
"""Benchmark: loading a map and one localization query against maps of 1,000 and 10,000 snapshots, on one thread.

    .venv/bin/python bench/localize_query.py [--degree L] [--sizes 1000 10000] [--quick]

Maps are real SQLite maps (mapping.build_map) as `skynav map build --baselines` writes them: random coefficients
of degree L (skynav's descriptors are derived from them when a Localizer loads the map) and a random raw-UV
descriptor (32 x 24) for the baseline; only the timing means anything. Loading is timed from the open map to a
Localizer ready to query (the descriptor matrix derived or read); the bispectrum is derived once per map and
shared by bispectrum and bispectrum-seq, so the second shows only its own preparation. A query is timed from
its input to the Match, as the node would run it: SH coefficients of degree L for skynav's methods (descriptor
computed from them each time), a 640x480 mono8 UV image for the SeqSLAM raw-UV baseline (down-sampled and
patch-normalised each time). Sequence methods are timed in steady state (the sequence buffer full). Prints the
map size on disk and its opening time, then per method the load time, the time per query and the ratio to the
seqslam-raw-uv baseline at the same map size. Target: amplitude under 2 ms at 10,000 snapshots.
"""

from __future__ import annotations

import os

for _variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS', 'NUMEXPR_NUM_THREADS'):
    os.environ[_variable] = '1'  # before numpy loads its BLAS

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

MIN_SECONDS = 0.3  # s of repetitions per measurement
REPEATS = 5  # measurements; the best counts
TARGET_MS = 2.0  # ms per amplitude query at 10,000 snapshots
IMAGE_SHAPE = (480, 640)  # px of the baseline's query image
METHODS = ('amplitude', 'amplitude-seq', 'bispectrum', 'bispectrum-seq', 'raw-uv', 'seqslam-raw-uv')


def seconds_per_call(function: Callable[[], object], min_seconds: float = MIN_SECONDS) -> float:
    """Return the best over REPEATS of the mean time (s) of one call, each run lasting about min_seconds."""
    function()
    start = time.perf_counter()
    function()
    once = max(time.perf_counter() - start, 1e-7)
    loops = max(1, int(min_seconds / REPEATS / once))
    best = float('inf')
    for _ in range(REPEATS):
        start = time.perf_counter()
        for _ in range(loops):
            function()
        best = min(best, (time.perf_counter() - start) / loops)
    return best


def build_map(path: Path, count: int, degree: int, rng: np.random.Generator):
    """Write a map of `count` random snapshots with the baseline's raw-UV descriptor; return it opened."""
    from skynav_core.maps import MapStore, Snapshot
    from skynav_localize.eval.baselines import RAW_UV_SIZE
    from skynav_localize.mapping import build_map

    size = (degree + 1) ** 2
    raw_size = RAW_UV_SIZE[0] * RAW_UV_SIZE[1]

    def snapshots():
        for i in range(count):
            yield Snapshot(
                i, i, rng.standard_normal(size), None, {'raw_uv': rng.standard_normal(raw_size).astype(np.float32)}
            )

    build_map(path, f'random {count}', degree, snapshots()).close()
    start = time.perf_counter()
    store = MapStore.open(path)
    return store, time.perf_counter() - start


def main() -> None:
    """Build the maps, time the queries, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--degree', type=int, default=32, help='SH degree L (default 32, as DESIGN.md times)')
    parser.add_argument('--sizes', type=int, nargs='+', default=[1000, 10000], help='map sizes (snapshots)')
    parser.add_argument('--quick', action='store_true', help='shorter measurements')
    args = parser.parse_args()
    global MIN_SECONDS
    if args.quick:
        MIN_SECONDS = 0.05

    from skynav_localize.localizer import Localizer

    rng = np.random.default_rng(0)
    coefficients = rng.standard_normal((args.degree + 1) ** 2)
    image = rng.integers(0, 256, IMAGE_SHAPE, dtype=np.uint8)
    print(
        f'one thread; SH degree L = {args.degree}; random maps (timing only); '
        f'baseline query image {IMAGE_SHAPE[1]}x{IMAGE_SHAPE[0]} mono8'
    )
    timings: dict[tuple[str, int], float] = {}
    loads: dict[tuple[str, int], float] = {}
    with tempfile.TemporaryDirectory() as folder:
        for count in args.sizes:
            start = time.perf_counter()
            store, opening = build_map(Path(folder) / f'map{count}.db', count, args.degree, rng)
            built = time.perf_counter() - start
            megabytes = store.path.stat().st_size / 1e6
            print(
                f'map of {count} snapshots: {megabytes:.1f} MB ({1e6 * megabytes / count:.0f} bytes per snapshot, '
                f"with the baseline's raw UV), built in {built:.1f} s, "
                f'opened and checked in {1e3 * opening:.0f} ms'
            )
            for name in METHODS:
                start = time.perf_counter()
                localizer = Localizer(store, name)
                loads[name, count] = time.perf_counter() - start
                query = (
                    (lambda loc=localizer: loc.query(uv=image))
                    if localizer.method.source == 'uv'
                    else (lambda loc=localizer: loc.query(coefficients))
                )
                for _ in range(localizer.sequence.length):
                    query()  # steady state: the sequence buffer is full
                timings[name, count] = seconds_per_call(query)
            store.close()

    print()
    header = f'{"method":<16}' + ''.join(
        f'{f"N={n} load (ms)":>20}{"query (ms)":>12}{"x baseline":>12}' for n in args.sizes
    )
    print(header)
    print('-' * len(header))
    for name in METHODS:
        cells = ''.join(
            f'{1e3 * loads[name, n]:20.1f}{1e3 * timings[name, n]:12.3f}'
            f'{timings[name, n] / timings["seqslam-raw-uv", n]:12.2f}'
            for n in args.sizes
        )
        print(f'{name:<16}{cells}')
    largest = max(args.sizes)
    verdict = 'meets' if 1e3 * timings['amplitude', largest] < TARGET_MS else 'misses'
    print(
        f'\namplitude at N={largest}: {1e3 * timings["amplitude", largest]:.3f} ms per query, {verdict} the '
        f'{TARGET_MS:g} ms target; amplitude-seq {1e3 * timings["amplitude-seq", largest]:.3f} ms'
    )


if __name__ == '__main__':
    main()
