# SPDX-License-Identifier: Apache-2.0
"""Show what a map holds: name, snapshots, degree, descriptors, route length, where it came from."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = 'describe a map file'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav map info`."""
    parser.add_argument('map', type=Path, metavar='MAP.db')


def run(args: argparse.Namespace) -> int:
    """Print the description; return the exit code."""
    from skynav_core.cli import open_map

    with open_map(args.map) as store:
        info = store.info()
    per_snapshot = f', {info["file_bytes"] / info["snapshots"]:.0f} bytes per snapshot' if info['snapshots'] else ''
    rows = [
        ('Map', info.get('name', '')),
        ('File', f'{info["path"]} ({info["file_bytes"] / 2**20:.2f} MiB{per_snapshot})'),
        ('Schema version', info['schema_version']),
        ('Snapshots', info['snapshots']),
        ('SH degree', info['max_degree']),
        (
            'Descriptors',
            ', '.join(info['descriptors']) or "none (skynav's methods derive theirs from the coefficients)",
        ),
        ('Map-level data', ', '.join(info['artifacts']) or 'none'),
        ('Ground-truth poses', 'yes' if info['has_poses'] else 'no'),
    ]
    if 'route_length_m' in info:
        rows.append(
            ('Route', f'{info["route_length_m"]:.2f} m, snapshots {info["median_spacing_m"]:.2f} m apart (median)')
        )
    if 'duration_s' in info:
        rows.append(('Time span', f'{info["duration_s"]:.1f} s'))
    rows += [('Created from', info.get('created_from', '')), ('Created', info.get('created_utc', ''))]
    if info.get('synthetic') == 'True':
        rows.append(('Data', 'synthetic'))
    width = max(len(key) for key, _ in rows) + 1
    for key, value in rows:
        print(f'{key + ":":{width}s} {value}')
    return 0
