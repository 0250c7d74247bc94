# SPDX-License-Identifier: Apache-2.0
"""The map file's schema (the package docstring, "Schema" and "Versions"): its versions, tables, names and bounds,
the encoding of rows and arrays (checksums, packed BLOBs), the check of a file's header and MapError."""

from __future__ import annotations

import json
import math
import sqlite3
import struct
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SkynavError

SCHEMA_VERSION = 3
FIRST_CHECKED_VERSION = 3  # the first schema version whose checksums cover stamps, poses and the meta table
PAGE_SIZE = 8192  # bytes per SQLite page of a new map
MAP_FORMAT = 'skynav-map'
APPLICATION_ID = 0x736B6E76  # 'sknv'
SQLITE_MAGIC = b'SQLite format 3\x00'
POSE_COLUMNS = ('x', 'y', 'z', 'qx', 'qy', 'qz', 'qw')
#: Per-snapshot descriptor of a map taught live: (x, y, z, qx, qy, qz, qw) of base_link in `odom` (m), NaN if none.
ODOM_POSE = 'odom_pose'
#: ...and the same pose by dead reckoning from the velocity commands (/cmd_vel) since teaching began, for a robot
#: without wheel odometry: (x, y, z, qx, qy, qz, qw) of base_link in the frame where teaching began (m).
COMMAND_POSE = 'command_pose'
META_CHECKSUM = 'meta_checksum'  # meta key of the meta table's own CRC-32 (schema 3 on)
RESERVED_META = ('format', 'schema_version', 'name', 'max_degree', 'created_utc', 'created_from', META_CHECKSUM)
CHECKS = ('none', 'quick', 'full')

# Bounds a map's header is checked against before anything is allocated from it (a crafted map must not make a
# reader allocate what its numbers claim).
MAX_DEGREE = 64  # highest SH degree of a map: the nodes work up to 64; (64 + 1)^2 coefficients = 33.8 kB a snapshot
MAX_DESCRIPTOR_DIMENSIONS = 4  # axes of a stored array (the descriptors are vectors, ORB (K, 32) matrices)
MAX_SHAPE_TEXT = 64  # characters of a stored array's shape ('500,32'): 4 axes of up to 15 digits with commas
#: The dtypes a stored array may have: plain little-endian numbers as _pack writes them (never objects, strings,
#: structures or big-endian data, which a crafted map could declare).
STORED_DTYPES = frozenset(('|b1', '|i1', '|u1', '<i2', '<u2', '<f2', '<i4', '<u4', '<f4', '<i8', '<u8', '<f8'))

_SCHEMA = """
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL) WITHOUT ROWID;
CREATE TABLE snapshots (
    idx INTEGER PRIMARY KEY CHECK (idx >= 0),
    stamp_ns INTEGER NOT NULL,
    coefficients BLOB NOT NULL,
    checksum INTEGER NOT NULL,
    x REAL, y REAL, z REAL, qx REAL, qy REAL, qz REAL, qw REAL,
    CHECK ((x IS NULL) = (qw IS NULL))
);
"""
#: The optional tables, each created in the transaction that first writes to it.
_OPTIONAL_TABLES = {
    'descriptors': """
CREATE TABLE descriptors (
    snapshot_idx INTEGER NOT NULL REFERENCES snapshots(idx),
    name TEXT NOT NULL,
    dtype TEXT NOT NULL,
    shape TEXT NOT NULL,
    data BLOB NOT NULL,
    checksum INTEGER NOT NULL,
    PRIMARY KEY (snapshot_idx, name)
)""",
    'artifacts': """
CREATE TABLE artifacts (
    name TEXT PRIMARY KEY,
    dtype TEXT NOT NULL,
    shape TEXT NOT NULL,
    data BLOB NOT NULL,
    checksum INTEGER NOT NULL
)""",
}
_REQUIRED_COLUMNS = {
    'meta': {'key', 'value'},
    'snapshots': {'idx', 'stamp_ns', 'coefficients', 'checksum', *POSE_COLUMNS},
}
_OPTIONAL_COLUMNS = {
    'descriptors': {'snapshot_idx', 'name', 'dtype', 'shape', 'data', 'checksum'},
    'artifacts': {'name', 'dtype', 'shape', 'data', 'checksum'},
}


def _count(text: str) -> int:
    """Return the non-negative integer a meta value holds; ValueError for anything else ('lots', '-1', '3.5')."""
    if not (text.isascii() and text.isdigit()) or len(text) > 20:
        raise ValueError(f'{text[:40]!r} is not a count')
    return int(text)


class MapError(SkynavError):
    """A map file that cannot be opened, read or written; the message names the file and what is wrong."""


@dataclass(frozen=True)
class Snapshot:
    """One stored snapshot: index (0-based, recording order), stamp (ns), SH coefficients, optional pose."""

    index: int
    stamp_ns: int
    coefficients: np.ndarray  # (L+1)^2 float64
    pose: np.ndarray | None = None  # (x, y, z, qx, qy, qz, qw) of camera_link in map (m, unit quaternion)
    descriptors: Mapping[str, np.ndarray] = field(default_factory=dict)


def _crc(data: bytes) -> int:
    """Return the CRC-32 of a byte string (stored next to every BLOB)."""
    return zlib.crc32(data) & 0xFFFFFFFF


def _row_crc(coefficients: bytes, stamp_ns: int, pose: tuple, version: int) -> int:
    """Return the checksum of a snapshot row: CRC-32 of its coefficient bytes, then (schema 3 on) of its stamp as
    little-endian int64 and its pose as 7 little-endian float64 (nothing when it has none)."""
    if version < FIRST_CHECKED_VERSION:
        return _crc(coefficients)
    # + 0.0: SQLite stores -0.0 as 0, so the sign of a zero must not count
    pose_bytes = b'' if pose[0] is None else (np.asarray(pose, dtype='<f8') + 0.0).tobytes()
    return _crc(coefficients + struct.pack('<q', stamp_ns) + pose_bytes)


def _meta_crc(meta: Mapping[str, str]) -> int:
    """Return the CRC-32 of a meta table (every row but META_CHECKSUM, sorted by key, as JSON)."""
    rows = sorted((key, value) for key, value in meta.items() if key != META_CHECKSUM)
    return _crc(json.dumps(rows).encode())


def _pack(array: np.ndarray) -> tuple[str, str, bytes, int]:
    """Return (dtype, shape, little-endian bytes, CRC-32) of an array for a BLOB column."""
    array = np.asarray(array)
    if array.dtype.kind not in 'biuf':
        raise ValueError(f'cannot store an array of dtype {array.dtype} (numbers only)')
    little = np.ascontiguousarray(array, dtype=array.dtype.newbyteorder('<'))
    data = little.tobytes()
    return little.dtype.str, ','.join(str(n) for n in array.shape), data, _crc(data)


def _unpack(dtype: object, shape: object, data: object) -> np.ndarray:
    """Return the array stored as (dtype, shape, bytes); ValueError unless they are sane and fit together.

    Everything is checked before numpy sees it: the dtype is one of STORED_DTYPES, the shape at most
    MAX_DESCRIPTOR_DIMENSIONS non-negative sizes whose product times the item size is the number of bytes.
    """
    if dtype not in STORED_DTYPES:
        raise ValueError(f'dtype {dtype!r} is not one of the stored number types')
    if not isinstance(shape, str) or len(shape) > MAX_SHAPE_TEXT:
        raise ValueError(f'shape {str(shape)[:MAX_SHAPE_TEXT]!r} is not a list of sizes')
    if not isinstance(data, bytes):
        raise ValueError(f'data is {type(data).__name__}, not bytes')
    texts = shape.split(',') if shape else []
    if len(texts) > MAX_DESCRIPTOR_DIMENSIONS or not all(text.isascii() and text.isdigit() for text in texts):
        raise ValueError(f'shape {shape!r} is not up to {MAX_DESCRIPTOR_DIMENSIONS} non-negative sizes')
    dims = tuple(int(text) for text in texts)
    item = np.dtype(dtype)
    if math.prod(dims) * item.itemsize != len(data):
        raise ValueError(f'shape {shape!r} of {dtype} needs {math.prod(dims) * item.itemsize} bytes, has {len(data)}')
    return np.frombuffer(data, dtype=item).reshape(dims)


def create_tables(db: sqlite3.Connection) -> None:
    """Create the tables every map holds, meta and snapshots (inside the caller's transaction)."""
    for statement in filter(str.strip, _SCHEMA.split(';')):
        db.execute(statement)


def has_table(db: sqlite3.Connection, table: str) -> bool:
    """Return whether the file holds table `table` (the optional tables appear with their first rows)."""
    return db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?", (table,)).fetchone() is not None


def create_optional_table(db: sqlite3.Connection, table: str) -> None:
    """Create optional table `table` unless it exists (inside the caller's transaction)."""
    if not has_table(db, table):
        db.execute(_OPTIONAL_TABLES[table])


def checked_meta(db: sqlite3.Connection, path: Path) -> dict[str, str]:
    """Return the meta table of a skynav map of a schema version this code reads; MapError for anything else.

    Versions 1 and 2 are read as they are (nothing is rewritten); the checksums they lack (of stamps, poses, the
    meta table) are not asked of them.
    """
    tables = {row[0] for row in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    if 'meta' not in tables:
        listed = ', '.join(sorted(tables)) or 'none'
        raise MapError(f'{path}: an SQLite database but not a skynav map (no meta table; tables: {listed})')
    try:
        rows = db.execute('SELECT key, value FROM meta').fetchall()
    except sqlite3.OperationalError:
        raise MapError(f'{path}: an SQLite database but not a skynav map (alien meta table)') from None
    for key, value in rows:
        if not isinstance(key, str) or not isinstance(value, str):
            raise MapError(
                f'{path}: damaged map (meta {str(key)[:40]!r}: a {type(key).__name__} key with a '
                f'{type(value).__name__} value, where both are text)'
            )
    meta = dict(rows)
    if meta.get('format') != MAP_FORMAT:
        raise MapError(
            f'{path}: an SQLite database but not a skynav map (meta format is '
            f'{meta.get("format")!r}, expected {MAP_FORMAT!r})'
        )
    try:
        version = _count(meta.get('schema_version', ''))
    except ValueError:
        raise MapError(f'{path}: damaged map (schema_version {meta.get("schema_version")!r} is not a number)') from None
    if version > SCHEMA_VERSION:
        raise MapError(
            f'{path}: map schema version {version} is newer than this skynav reads ({SCHEMA_VERSION}); update skynav'
        )
    if version < 1:
        raise MapError(f'{path}: damaged map (schema version {version})')
    optional = {table: columns for table, columns in _OPTIONAL_COLUMNS.items() if table in tables}
    for table, columns in {**_REQUIRED_COLUMNS, **optional}.items():
        present = {row[1] for row in db.execute(f'PRAGMA table_info({table})')}
        if missing := columns - present:
            raise MapError(f'{path}: damaged map (table {table} lacks {", ".join(sorted(missing))})')
    try:
        degree = _count(meta['max_degree'])
    except (KeyError, ValueError):
        raise MapError(f'{path}: damaged map (max_degree {meta.get("max_degree", "")[:40]!r})') from None
    if degree > MAX_DEGREE:
        raise MapError(f'{path}: damaged map (max_degree {degree} is above the {MAX_DEGREE} skynav reads)')
    if version >= FIRST_CHECKED_VERSION and meta.get(META_CHECKSUM) != str(_meta_crc(meta)):
        raise MapError(f'{path}: corrupt map (checksum of the meta table does not match)')
    return meta
