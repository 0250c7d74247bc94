# SPDX-License-Identifier: Apache-2.0
"""Evaluation of home vectors against ground truth: angular errors, binned statistics, timing, quiver plots.

Arrays in, numbers and figures out. Poses are those of camera_link in map (position in m, quaternion (x, y, z, w)
as geometry_msgs orders it). The true home direction of a current view at (p_c, Q_c) towards a snapshot taken at
p_s is Q_c^-1 (p_s - p_c) normalised (docs/interfaces.md), in the current camera_link; the true compass rotation is
R = Q_s^-1 Q_c (d_snapshot = R d_current).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from skynav_core.evaluation import Column, text_table
from skynav_core.rotations import as_matrix, home_direction, relative_rotation, rotation_angle, tilt

DISTANCE_BINS = ((0.5, 1.0), (1.0, 2.0), (2.0, 4.0))  # m
TILT_BINS = ((0.0, 5.0), (5.0, 10.0), (10.0, 20.0), (20.0, 30.0))  # degrees


def _orientations(quaternions: np.ndarray) -> np.ndarray:
    """Return the rotation matrices (N, 3, 3) of one or N quaternions (..., 4) as (x, y, z, w)."""
    return as_matrix(np.asarray(quaternions, dtype=float).reshape(-1, 4))


def true_home_directions(
    current_positions: np.ndarray, current_quaternions: np.ndarray, snapshot_position: np.ndarray
) -> np.ndarray:
    """Return unit home vectors (N, 3) in each current camera_link: Q_c^-1 (p_s - p_c) normalised."""
    positions = np.asarray(current_positions, dtype=float).reshape(-1, 3)
    return home_direction(snapshot_position, positions, _orientations(current_quaternions))


def true_rotations(snapshot_quaternion: np.ndarray, current_quaternions: np.ndarray) -> np.ndarray:
    """Return the true compass rotations R = Q_s^-1 Q_c (N, 3, 3): d_snapshot = R d_current."""
    return relative_rotation(snapshot_quaternion, _orientations(current_quaternions))


def tilt_angles(quaternions: np.ndarray) -> np.ndarray:
    """Return the tilt (degrees) of camera_link: the angle between its +z and the map's vertical, (N,)."""
    return np.degrees(tilt(_orientations(quaternions)))


def angular_errors(estimated: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Return the angle (degrees) between estimated and true directions (N, 3); nan where an estimate is zero."""
    estimated = np.asarray(estimated, dtype=float).reshape(-1, 3)
    true = np.asarray(true, dtype=float).reshape(-1, 3)
    norm = np.linalg.norm(estimated, axis=-1) * np.linalg.norm(true, axis=-1)
    cosine = np.divide(np.sum(estimated * true, axis=-1), norm, out=np.full(len(norm), np.nan), where=norm > 0)
    return np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))


def rotation_errors(estimated: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Return the angle (degrees) of R_est^T R_true for rotation matrices (N, 3, 3)."""
    return np.degrees(rotation_angle(estimated, true))


@dataclass(frozen=True)
class BinStatistics:
    """Errors of the estimates whose value (distance in m, tilt in degrees) lies in [low, high)."""

    low: float
    high: float
    count: int
    median: float  # degrees; nan when the bin is empty
    p90: float  # 90th percentile, degrees


def binned_statistics(
    errors: np.ndarray, values: np.ndarray, bins: Sequence[tuple[float, float]] = DISTANCE_BINS
) -> list[BinStatistics]:
    """Return median and 90th percentile of errors (degrees) per bin [low, high) of values; nan errors left out."""
    errors = np.asarray(errors, dtype=float)
    values = np.asarray(values, dtype=float)
    out = []
    for low, high in bins:
        chosen = errors[(values >= low) & (values < high) & np.isfinite(errors)]
        out.append(
            BinStatistics(
                float(low),
                float(high),
                int(chosen.size),
                float(np.median(chosen)) if chosen.size else float('nan'),
                float(np.percentile(chosen, 90)) if chosen.size else float('nan'),
            )
        )
    return out


def summary_table(
    errors: dict[str, np.ndarray],
    distances: np.ndarray,
    tilts: np.ndarray,
    seconds: dict[str, float] | None = None,
    distance_bins=DISTANCE_BINS,
    tilt_bins=TILT_BINS,
) -> str:
    """Return a text table: per method, median / p90 error (degrees) per distance and tilt bin, time per estimate."""
    titles = [f'{lo:g}-{hi:g} m' for lo, hi in distance_bins] + [f'tilt {lo:g}-{hi:g} deg' for lo, hi in tilt_bins]
    columns = [Column('method', 14, align='<'), *(Column(title, 17) for title in [*titles, 'all'])]
    columns += [Column('ms/estimate', 13, '.1f')] if seconds else []
    rows: list[list] = [['', *(['n med p90'] * (len(titles) + 1))]]
    for method, error in errors.items():
        cells = binned_statistics(error, distances, distance_bins) + binned_statistics(error, tilts, tilt_bins)
        cells.append(binned_statistics(error, np.zeros(len(error)), [(-1.0, 1.0)])[0])
        rows.append(
            [
                method,
                *(f'{c.count:>5d}{c.median:>6.1f}{c.p90:>6.1f}' for c in cells),
                *([1e3 * seconds.get(method, float('nan'))] if seconds else []),
            ]
        )
    return text_table(columns, rows, gap='', rule=False)


def seconds_per_call(function: Callable[[], object], repeats: int = 3) -> float:
    """Return the least wall time (s) of `repeats` calls of function() (after one warm-up call)."""
    function()
    best = float('inf')
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return best


def home_vectors_in_map(directions: np.ndarray, current_quaternions: np.ndarray) -> np.ndarray:
    """Return home vectors (N, 3) of the current camera_link expressed in map: Q_c d."""
    vectors = np.asarray(directions, dtype=float).reshape(-1, 3)
    return np.einsum('nij,nj->ni', _orientations(current_quaternions), vectors)


def quiver_plot(
    path: str,
    current_positions: np.ndarray,
    snapshot_position: np.ndarray,
    true_map: np.ndarray,
    estimates_map: dict[str, np.ndarray],
    title: str,
    synthetic: bool = True,
) -> str:
    """Save a quiver plot (PNG) of true and estimated home vectors (map x-y, unit length); return its title."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    positions = np.asarray(current_positions, dtype=float).reshape(-1, 3)
    origin = np.asarray(snapshot_position, dtype=float)
    xy = positions[:, :2] - origin[:2]

    def planar(vectors: np.ndarray) -> np.ndarray:
        v = np.asarray(vectors, dtype=float).reshape(-1, 3)[:, :2]
        norm = np.linalg.norm(v, axis=-1, keepdims=True)
        return np.divide(v, norm, out=np.zeros_like(v), where=norm > 0)

    figure, axes = plt.subplots(figsize=(9.0, 7.0))
    truth = planar(true_map)
    axes.quiver(
        xy[:, 0],
        xy[:, 1],
        truth[:, 0],
        truth[:, 1],
        color='0.6',
        angles='xy',
        scale_units='xy',
        scale=3.0,
        width=0.006,
        label='true home direction',
    )
    colours = ['tab:red', 'tab:blue', 'tab:green', 'tab:orange', 'tab:purple']
    for (method, vectors), colour in zip(estimates_map.items(), colours):
        v = planar(vectors)
        axes.quiver(
            xy[:, 0],
            xy[:, 1],
            v[:, 0],
            v[:, 1],
            color=colour,
            angles='xy',
            scale_units='xy',
            scale=3.0,
            width=0.0035,
            label=f'{method} (estimate)',
        )
    axes.plot([0.0], [0.0], marker='*', markersize=16, color='k', linestyle='none', label='snapshot place')
    axes.set_aspect('equal')
    axes.set_xlabel('x - x_snapshot in map (m)')
    axes.set_ylabel('y - y_snapshot in map (m)')
    prefix = 'synthetic data: ' if synthetic and 'synthetic' not in title.lower() else ''
    title = prefix + title
    axes.set_title(title)
    axes.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0), fontsize='small')
    axes.grid(True, alpha=0.3)
    figure.savefig(path, dpi=110, bbox_inches='tight')
    plt.close(figure)
    return title
