# SPDX-License-Identifier: Apache-2.0
"""Benchmark: homing on the bundled synthetic grid, 3D-warping against min-warping and 2D-warping, one thread.

    .venv/bin/python bench/homing.py [--bag BAG] [--repeats N] [--plot OUT.png]

For every place of the grid (frame 0 is the snapshot) each method estimates the home vector from the ground-truth
sky masks; the table gives the time per estimate (median over places of the best of N runs, wall clock, one
thread), the median and 90th-percentile angular error against the true direction Q_c^-1 (p_s - p_c), and the
ratios to 3D-warping. 3D-warping runs with a simulated compass (the true rotation turned by a seeded error of
1, 1, 3 degrees rms about x, y, z) and without any rotation (its own pre-alignment); the planar baselines search
their own turn. Preparation (mask -> SH view, mask -> panoramic band) is timed apart. The data is synthetic.
Pin it to one core (`taskset -c 0`) for the one-core figure; `--bag bags/synthetic_park_bumpy_homing.mcap` runs
the same on bumpy ground.
"""

from __future__ import annotations

import os

for _variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS', 'NUMEXPR_NUM_THREADS'):
    os.environ[_variable] = '1'  # before numpy loads its BLAS

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

BAG = Path(__file__).resolve().parents[1] / 'bags' / 'synthetic_park_homing.mcap'
DEGREE = 16


def best_time(function, repeats: int) -> tuple[float, object]:
    """Return the least wall time (s) over `repeats` calls of function() and the last result."""
    best, result = float('inf'), None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        best = min(best, time.perf_counter() - start)
    return best, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--bag', default=str(BAG), help='homing recording (default: the bundled synthetic grid)')
    parser.add_argument('--repeats', type=int, default=3, help='runs per estimate; the fastest counts')
    parser.add_argument('--plot', help='save a quiver plot of the home vectors to this PNG')
    args = parser.parse_args()

    from scipy.spatial.transform import Rotation

    from skynav_sh.fisheye import FisheyeTransform
    from skynav_warping import (
        PanoramaUnwrapper,
        WarpingSettings,
        angular_errors,
        estimate_home_vector,
        home_vectors_in_map,
        load_homing_grid,
        min_warping,
        quiver_plot,
        true_home_directions,
        true_rotations,
        view_from_coefficients,
        view_from_fisheye,
        warping_2d,
        warping_tables,
    )

    grid = load_homing_grid(args.bag)
    positions, quaternions = grid.positions, grid.quaternions
    true = true_home_directions(positions[1:], quaternions[1:], positions[0])
    rotations = true_rotations(quaternions[0], quaternions[1:])
    distance = np.linalg.norm(positions[1:] - positions[0], axis=1)
    compass = [
        Rotation.from_rotvec(np.radians([1.0, 1.0, 3.0]) * np.random.default_rng(i).standard_normal(3)).as_matrix() @ r
        for i, r in enumerate(rotations)
    ]

    start = time.perf_counter()
    transform = FisheyeTransform(grid.camera, DEGREE, fill='zero')
    unwrapper = PanoramaUnwrapper(grid.camera)
    warping_tables(WarpingSettings())
    setup = time.perf_counter() - start
    prepare_view = np.median(
        [best_time(lambda m=m: view_from_fisheye(transform, m), args.repeats)[0] for m in grid.masks]
    )
    coefficients = transform.coefficients(grid.masks[0])
    prepare_coefficients = best_time(
        lambda: view_from_coefficients(coefficients, grid.camera.field_of_view, DEGREE), args.repeats
    )[0]
    prepare_band = np.median([best_time(lambda m=m: unwrapper(m), args.repeats)[0] for m in grid.masks])
    views = [view_from_fisheye(transform, m) for m in grid.masks]
    bands = [unwrapper(m) for m in grid.masks]

    methods = {
        '3d-warping + compass': lambda i: estimate_home_vector(views[i + 1], views[0], compass[i]),
        '3d-warping alone': lambda i: estimate_home_vector(views[i + 1], views[0]),
        'min-warping': lambda i: min_warping(bands[0], bands[i + 1], unwrapper.elevations),
        '2d-warping': lambda i: warping_2d(bands[0], bands[i + 1]),
    }
    for method in methods.values():  # warm-up: caches, lazy imports
        method(0)
    rows = {}
    estimates_map = {}
    for name, method in methods.items():
        seconds, directions = [], []
        for i in range(len(true)):
            spent, result = best_time(lambda: method(i), args.repeats)
            seconds.append(spent)
            directions.append(getattr(result, 'best_direction', result.direction))
        errors = angular_errors(np.array(directions), true)
        rows[name] = (float(np.median(seconds)), float(np.median(errors)), float(np.percentile(errors, 90)))
        estimates_map[name] = home_vectors_in_map(np.array(directions), quaternions[1:])

    reference = rows['3d-warping + compass']
    print(
        f'homing benchmark on {Path(args.bag).name} ({"synthetic" if grid.synthetic else "recorded"} data): '
        f'{len(true)} places {distance.min():.2f}-{distance.max():.2f} m from the snapshot, one thread'
    )
    print(f'setup (transform, panorama maps, warping tables): {setup * 1e3:.0f} ms once')
    print(
        f'preparation per frame: mask -> SH view {prepare_view * 1e3:.2f} ms, SH coefficients -> view '
        f'{prepare_coefficients * 1e3:.2f} ms, mask -> panoramic band {prepare_band * 1e3:.2f} ms'
    )
    print(
        f'{"method":<22}{"ms/estimate":>12}{"x 3d+compass":>13}{"median deg":>12}{"p90 deg":>9}'
        f'{"median / 3d+compass":>21}'
    )
    for name, (seconds, median, p90) in rows.items():
        print(
            f'{name:<22}{seconds * 1e3:>12.1f}{seconds / reference[0]:>13.2f}{median:>12.1f}{p90:>9.1f}'
            f'{median / reference[1]:>21.2f}'
        )
    if args.plot:
        title = quiver_plot(
            args.plot,
            positions[1:],
            positions[0],
            home_vectors_in_map(true, quaternions[1:]),
            estimates_map,
            f'home vectors (unit, map x-y) on {Path(args.bag).name}',
            synthetic=grid.synthetic,
        )
        print(f'quiver plot "{title}" saved to {args.plot}')


if __name__ == '__main__':
    main()
