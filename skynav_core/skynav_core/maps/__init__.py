# SPDX-License-Identifier: Apache-2.0
"""The map store: one SQLite file per taught route, one row per snapshot (docs/interfaces.md, "Maps").

Schema (version SCHEMA_VERSION; `PRAGMA application_id` = APPLICATION_ID marks the file as a skynav map):

    meta(key TEXT PRIMARY KEY, value TEXT)       format='skynav-map', schema_version, name, max_degree, created_utc,
                                                 created_from, meta_checksum (CRC-32 of the other rows, see
                                                 _meta_crc), and any caller metadata (text)
    snapshots(idx INTEGER PRIMARY KEY,           0-based, in recording order, contiguous
              stamp_ns INTEGER,                  stamp of the frame the snapshot was made from (ns since the epoch)
              coefficients BLOB,                 (L+1)^2 little-endian float64, real SH of the skyline mask
              checksum INTEGER,                  CRC-32 of the coefficients, stamp and pose (see _row_crc)
              x, y, z, qx, qy, qz, qw REAL)      ground-truth pose of camera_link in map (m, quaternion), or all NULL
    descriptors(snapshot_idx, name, dtype, shape, data BLOB, checksum)   per-snapshot arrays (e.g. the baselines'
                                                                         'raw_uv', 'orb'); created with the first
    artifacts(name, dtype, shape, data BLOB, checksum)                   map-level arrays (e.g. the BoW vocabulary);
                                                                         created with the first

What the product uses is the coefficients: its descriptors (amplitude spectrum, bispectrum) are derived from them
when a map is loaded, so a map of skynav's own is the meta and snapshots tables only. The tables descriptors and
artifacts exist only in maps that hold more (the baselines' descriptors of `skynav map build --baselines`).
Pages are PAGE_SIZE bytes: three snapshot rows of degree 16 (about 2.4 kB each) fill one page, where 4 kB pages
would hold one each.

Versions: 1 (all four tables always, 4 kB pages; still read), 2 (descriptors and artifacts optional, meta
without rowid, PAGE_SIZE pages; still read) and 3 (a snapshot's checksum covers its stamp and pose too, not only
its coefficients; meta_checksum covers the meta table). A map of a newer version is refused in one line.

Checking: opening reads the meta table and every snapshot's stamp, coefficients and pose (what every reader uses)
and checks their checksums; the header is checked against named bounds (MAX_DEGREE, STORED_DTYPES, ...) before
anything is allocated from it. A descriptor or artifact is checked (checksum, dtype, shape) when it is read, so a
damaged one that a reader never uses never matters.

Writing: the file is in WAL mode and every snapshot is one transaction, so a process killed while building leaves
a readable map holding every committed snapshot. close() checkpoints and returns the file to rollback-journal mode
so a finished map is a single self-contained file. MapStore.build() writes a whole map under a temporary name and
renames it into place at the end. Reading opens the file read-only and checks it; every problem is one MapError.

Modules: schema (versions, tables, names, bounds, row encoding, the header check, MapError), reader (MapReader:
opening, checking, every query), writer (MapWriter: creating, adding in committed transactions, building,
compacting, closing); MapStore is the two halves in one class, the one users open.
"""

from __future__ import annotations

from pathlib import Path

from .reader import CheckedDescriptors, MapReader
from .schema import (
    APPLICATION_ID,
    CHECKS,
    COMMAND_POSE,
    FIRST_CHECKED_VERSION,
    MAP_FORMAT,
    MAX_DEGREE,
    MAX_DESCRIPTOR_DIMENSIONS,
    MAX_SHAPE_TEXT,
    META_CHECKSUM,
    ODOM_POSE,
    PAGE_SIZE,
    POSE_COLUMNS,
    RESERVED_META,
    SCHEMA_VERSION,
    SQLITE_MAGIC,
    STORED_DTYPES,
    MapError,
    Snapshot,
    _crc,
    _meta_crc,
    _pack,
    _row_crc,
    _unpack,
)
from .writer import MapWriter, partial_path

__all__ = [
    'APPLICATION_ID',
    'CHECKS',
    'COMMAND_POSE',
    'FIRST_CHECKED_VERSION',
    'MAP_FORMAT',
    'MAX_DEGREE',
    'MAX_DESCRIPTOR_DIMENSIONS',
    'MAX_SHAPE_TEXT',
    'META_CHECKSUM',
    'ODOM_POSE',
    'PAGE_SIZE',
    'POSE_COLUMNS',
    'RESERVED_META',
    'SCHEMA_VERSION',
    'SQLITE_MAGIC',
    'STORED_DTYPES',
    'CheckedDescriptors',
    'MapError',
    'MapReader',
    'MapStore',
    'MapWriter',
    'Snapshot',
    '_crc',
    '_meta_crc',
    '_pack',
    '_row_crc',
    '_unpack',
    'map_for_parameter',
    'partial_path',
]


class MapStore(MapWriter):
    """A map of snapshots in one SQLite file; MapStore.create() to write one, MapStore.open() to read one."""


def map_for_parameter(current: MapStore | None, path: str) -> MapStore | None:
    """Return the map a node's `map` parameter names: `current` if it is that file, None for ''; ValueError if bad."""
    if path == (str(current.path) if current is not None else ''):
        return current
    if not path:
        return None
    try:
        return MapStore.open(Path(path))
    except MapError as exc:
        raise ValueError(str(exc)) from None
