# SPDX-License-Identifier: Apache-2.0
"""Benchmark: the visual 3D compass against the exhaustive baseline and its peers, on one thread.

    .venv/bin/python bench/compass.py [--quick] [--repeats N] [--degrees 16 32] [--plots DIR] [--bags BAG ...]
                                      [--methods METHOD ...]

For L = 16 and 32 and each bundled (synthetic) compass set it prints, per method, the 3D rotation error against
ground truth (median, 90th percentile, maximum, share under 2 deg) separately for pure rotations and for views moved
up to 0.5 m, and the CPU time per estimate (the least of --repeats runs; the methods take turns on every query so
that other load on the machine hits them alike). Views are prepared once per frame (SH of the ground-truth mask,
panorama or keypoints) and timed apart. Then the speed ratio of the default (FFT correlation + Newton refinement)
to the exhaustive baseline with the same cost, and how often each reached the lower cost: cold (every estimate
starts from the two views) and with the snapshot prepared once (NAME+prepared: Compass.prepare /
ExhaustiveCompass.prepare, as the compass node compares many views against one snapshot; same estimates).

Methods: fft-masked (the default: tilt bound, hypotheses verified on samples of the two masks), fft-zero / fft-mean /
fft-mirror (plain cost on filled views), fft-masked-any-tilt (the whole of SO(3), unverified), fft-uv-normalised
(grey UV image instead of the mask, masked correlation coefficient: gain and offset drop out), exhaustive-masked /
exhaustive-zero (the source method's coarse-to-fine ZYZ search), visual-compass-panorama / visual-compass-sh (yaw
only), features-sift / features-orb (UV image, bearings, RANSAC; independent of L, so run at the first degree only).

--bags runs other compass sets (`skynav sim bag compass`, e.g. on a real landscape) instead of the bundled ones: the
compass on the ground-truth masks, where `skynav eval compass` runs it on the skyline node's masks. Every table ends
with the ROC AUC of each method's confidence (else its residual) between estimates under and over 5 degrees of
error, over all views ('-': all on one side).
"""

from __future__ import annotations

import os

for _variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS', 'NUMEXPR_NUM_THREADS'):
    os.environ[_variable] = '1'  # before numpy loads its BLAS

import argparse  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from skynav_compass.eval.methods import METHODS, PREPARED  # noqa: E402

BAGS = Path(__file__).resolve().parents[1] / 'bags'
SETS = ('garden', 'mineral')
PAIRS = (('fft-masked', 'exhaustive-masked'), ('fft-zero', 'exhaustive-zero'))
# every method of the registry on the SH, then the pairs with the snapshot prepared once; the image methods
SH_METHODS = (
    *(name for name, m in METHODS.items() if not m.needs_images),
    *(name + PREPARED for pair in PAIRS for name in pair),
)
IMAGE_METHODS = tuple(name for name, m in METHODS.items() if m.needs_images)


def ratio_lines(runs, label: str) -> list[str]:
    """Return lines comparing the default with the exhaustive baseline: time ratio, accuracy, who found lower costs.

    Per pair one line with both cold and both prepared (when both were run), and the time the preparation took.
    """
    by_name = {run.result.method: run for run in runs}
    lines = []
    for fast, slow in PAIRS:
        for suffix, mode in (('', 'cold    '), (PREPARED, 'prepared')):
            if fast + suffix not in by_name or slow + suffix not in by_name:
                continue
            a, b = by_name[fast + suffix].result, by_name[slow + suffix].result
            ratio = np.median(b.seconds) / np.median(a.seconds)
            lower = np.mean(a.residuals < b.residuals - 1e-12)
            higher = np.mean(a.residuals > b.residuals + 1e-12)
            once = ''
            if suffix:
                once = (
                    f'; snapshot prepared once in {1e3 * by_name[fast + suffix].snapshot_seconds:.2f} /'
                    f' {1e3 * by_name[slow + suffix].snapshot_seconds:.2f} ms'
                )
            lines.append(
                f'  {label} {mode}: {slow} / {fast} time ratio {ratio:5.1f}x  (median'
                f' {1e3 * np.median(b.seconds):.1f} ms vs {1e3 * np.median(a.seconds):.2f} ms{once});'
                f' median error {np.median(a.errors):.2f} vs {np.median(b.errors):.2f} deg; {fast} reached'
                f' the lower cost in {100 * lower:.0f} %, the higher in {100 * higher:.0f} % of the queries'
            )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='5 rotations and 5 moved views per set, 1 repeat')
    parser.add_argument('--repeats', type=int, default=3, help='timed runs per estimate (least counts)')
    parser.add_argument('--degrees', type=int, nargs='+', default=[16, 32])
    parser.add_argument('--plots', type=Path, default=None, help='directory for error plots (PNG)')
    parser.add_argument(
        '--bags', type=Path, nargs='+', default=None, help='compass sets to run (default: the bundled synthetic ones)'
    )
    parser.add_argument('--methods', nargs='+', default=None, help='methods to run (default: all)')
    args = parser.parse_args()

    from skynav_compass import format_table, load_compass_set, plot_errors, run_methods, standard_methods, summary_rows

    repeats = 1 if args.quick else args.repeats
    print(f'skynav_compass benchmark: one thread, CPU time per estimate (least of {repeats}), synthetic data')
    paths = args.bags or [BAGS / f'synthetic_{name}_compass.mcap' for name in SETS]
    sets = {Path(path).stem: load_compass_set(path) for path in paths}
    for k, degree in enumerate(args.degrees):
        for name, data in sets.items():
            queries = list(data.queries)
            if args.quick:
                rotations = [i for i in queries if data.labels[i] == 'rotation'][:5]
                moved = [i for i in queries if data.labels[i] != 'rotation'][:5]
                queries = rotations + moved
            names = SH_METHODS + (IMAGE_METHODS if k == 0 else ())
            if args.methods is not None:
                names = tuple(n for n in args.methods if n in SH_METHODS or (k == 0 and n in IMAGE_METHODS))
            runs = run_methods(data, standard_methods(data.camera, degree, names), queries, repeats=repeats)
            rotation = np.array([data.labels[i] == 'rotation' for i in queries])
            kind = 'synthetic' if data.synthetic else 'recorded'
            print(
                f'\n== {data.name} ({kind}), L = {degree}: {rotation.sum()} pure rotations (tilt up to '
                f'{data.tilts()[queries][rotation].max():.0f} deg), {(~rotation).sum()} moved views (up to '
                f'{data.translations()[queries].max():.2f} m) =='
            )
            print(format_table(summary_rows([r.result for r in runs], {'rotation': rotation, 'moved': ~rotation})))
            aucs = [(r.result.method, r.result.separation()) for r in runs]
            print('  AUC over all views: ' + ', '.join(f'{m} {"-" if np.isnan(a) else f"{a:.3f}"}' for m, a in aucs))
            print(
                '  preparation per view (ms): '
                + ', '.join(f'{r.result.method} {1e3 * r.prepare_seconds:.1f}' for r in runs)
            )
            for line in ratio_lines(runs, f'L = {degree}'):
                print(line)
            if args.plots is not None:
                args.plots.mkdir(parents=True, exist_ok=True)
                chosen = [
                    r.result
                    for r in runs
                    if r.result.method
                    in ('fft-masked', 'fft-zero', 'exhaustive-masked', 'visual-compass-panorama', 'features-sift')
                ]
                path = plot_errors(
                    chosen,
                    data.tilts()[queries],
                    data.translations()[queries],
                    args.plots / f'compass_{name}_L{degree}.png',
                    data.synthetic,
                    f'{data.name}, L = {degree}',
                )
                print(f'  plot: {path}')


if __name__ == '__main__':
    main()
