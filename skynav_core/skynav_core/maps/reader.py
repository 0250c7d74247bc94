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
"""

from __future__ import annotations

import json
import math
import os
import sqlite3
import struct
import threading
import zlib
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any
from urllib.parse import quote

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


class CheckedDescriptors(Mapping):
    """One snapshot's descriptors by name, each checked (checksum, dtype, shape) only when it is looked up.

    A damaged descriptor the caller never reads never matters; one it reads raises MapError.
    """

    def __init__(self, rows: Mapping[str, tuple], check: Callable[[tuple, str], np.ndarray], index: int) -> None:
        """Keep the (dtype, shape, data, checksum) rows by name; check(row, what) turns one into its array."""
        self._rows = dict(rows)
        self._check = check
        self._index = index

    def __getitem__(self, name: str) -> np.ndarray:
        """Return descriptor `name`, checked; KeyError if the snapshot has none, MapError if it is damaged."""
        return self._check(self._rows[name], f'descriptor {name!r} of snapshot {self._index}')

    def __iter__(self) -> Iterator[str]:
        return iter(self._rows)

    def __len__(self) -> int:
        return len(self._rows)

    def __repr__(self) -> str:
        return f'CheckedDescriptors({sorted(self._rows)}, snapshot {self._index})'


class MapStore:
    """A map of snapshots in one SQLite file; MapStore.create() to write one, MapStore.open() to read one."""

    def __init__(self, path: Path, connection: sqlite3.Connection, writable: bool) -> None:
        """Wrap an open, checked connection (use create/open/build, not this)."""
        self.path = path
        self._db = connection
        self._lock = threading.RLock()  # one connection, usable from any thread (e.g. a node's callbacks)
        self.writable = writable
        self._meta: dict[str, str] = {}
        self._stamps = np.zeros(0, dtype=np.int64)
        self._coefficients = np.zeros((0, 0))
        self._poses = np.zeros((0, 7))
        self._descriptor_cache: dict[str, np.ndarray] = {}
        self._capacity = 0  # rows of the growable buffers behind the arrays above (writable maps)
        self._stamp_buffer = self._stamps
        self._coefficient_buffer = self._coefficients
        self._pose_buffer = self._poses

    # --- opening -------------------------------------------------------------------------------------------------

    @classmethod
    def create(
        cls,
        path: str | os.PathLike,
        name: str,
        max_degree: int,
        *,
        created_from: str = '',
        metadata: Mapping[str, Any] | None = None,
        overwrite: bool = False,
    ) -> MapStore:
        """Create an empty map file at path (SH degree L) and return it open for adding snapshots one by one."""
        path = Path(path)
        if int(max_degree) < 0:
            raise MapError(f'{path}: SH degree must be >= 0, got {max_degree}')
        if not path.parent.is_dir():
            raise MapError(f'{path}: no such directory {path.parent}')
        meta = {
            'format': MAP_FORMAT,
            'schema_version': str(SCHEMA_VERSION),
            'name': str(name),
            'max_degree': str(int(max_degree)),
            'created_utc': datetime.now(UTC).isoformat(timespec='seconds'),
            'created_from': str(created_from),
        }
        for key, value in (metadata or {}).items():
            if key in RESERVED_META:
                raise MapError(f'{path}: metadata key {key!r} is reserved')
            meta[str(key)] = value if isinstance(value, str) else json.dumps(value)
        meta[META_CHECKSUM] = str(_meta_crc(meta))
        if path.exists() or Path(f'{path}-wal').exists():
            if not overwrite:
                raise MapError(f'{path}: exists already; choose another name or pass overwrite')
            for stale in (path, Path(f'{path}-wal'), Path(f'{path}-shm'), Path(f'{path}-journal')):
                stale.unlink(missing_ok=True)
        db = None
        try:
            db = sqlite3.connect(path, isolation_level=None, check_same_thread=False)
            db.execute(f'PRAGMA page_size={PAGE_SIZE}')  # before the first table; WAL mode fixes it
            db.execute('PRAGMA journal_mode=WAL')
            db.execute('PRAGMA synchronous=FULL')  # a commit is on disk before add_snapshot returns
            db.execute(f'PRAGMA application_id={APPLICATION_ID}')
            db.execute('BEGIN')
            for statement in filter(str.strip, _SCHEMA.split(';')):
                db.execute(statement)
            db.executemany('INSERT INTO meta(key, value) VALUES (?, ?)', meta.items())
            db.execute('COMMIT')
        except sqlite3.Error as exc:
            if db is not None:
                db.close()
            for leftover in (path, Path(f'{path}-wal'), Path(f'{path}-shm')):
                leftover.unlink(missing_ok=True)
            raise MapError(f'{path}: cannot create the map: {exc}') from None
        store = cls(path, db, writable=True)
        store._meta = meta
        store._coefficients = store._coefficient_buffer = np.zeros((0, (int(max_degree) + 1) ** 2))
        return store

    @classmethod
    def open(cls, path: str | os.PathLike, *, writable: bool = False, check: str = 'quick') -> MapStore:
        """Open and check a map file, read-only unless writable; check 'quick'/'full' adds SQLite's own check."""
        path = Path(path)
        if check not in CHECKS:
            raise ValueError(f'unknown check {check!r}; expected one of {CHECKS}')
        if not path.exists():
            raise MapError(f'{path}: no such map file')
        if not path.is_file():
            raise MapError(f'{path}: not a file (a map is one SQLite file)')
        with path.open('rb') as stream:
            head = stream.read(len(SQLITE_MAGIC))
        if not head:
            raise MapError(f'{path}: empty file, not a map')
        if head != SQLITE_MAGIC:
            raise MapError(f'{path}: not a map (not an SQLite database)')
        try:
            if writable:
                db = sqlite3.connect(path, isolation_level=None, check_same_thread=False)
            else:
                db = sqlite3.connect(
                    f'file:{quote(str(path.resolve()))}?mode=ro',
                    uri=True,
                    isolation_level=None,
                    check_same_thread=False,
                )
        except sqlite3.Error as exc:
            raise MapError(f'{path}: cannot open the map: {exc}') from None
        store = cls(path, db, writable)
        try:
            store._check_schema()
            if check != 'none':
                pragma = 'quick_check' if check == 'quick' else 'integrity_check'
                result = [line for row in db.execute(f'PRAGMA {pragma}(3)') for line in row[0].splitlines()]
                if result != ['ok']:
                    raise MapError(f'{path}: corrupt map file (SQLite {pragma}: {"; ".join(result)})')
            store._load_snapshots()
            if writable:
                db.execute('PRAGMA journal_mode=WAL')
                db.execute('PRAGMA synchronous=FULL')
        except MapError:
            db.close()
            raise
        except sqlite3.Error as exc:
            db.close()
            raise MapError(f'{path}: corrupt or truncated map file ({exc})') from None
        return store

    @classmethod
    def build(
        cls,
        path: str | os.PathLike,
        name: str,
        max_degree: int,
        snapshots: Iterable[Snapshot],
        *,
        created_from: str = '',
        metadata: Mapping[str, Any] | None = None,
        overwrite: bool = False,
        finish: Callable[[MapStore], None] | None = None,
    ) -> MapStore:
        """Write a whole map in one go under a temporary name, rename it to path at the end; return it read-only.

        `finish(store)` may add map-level data (a vocabulary) before the rename. Interrupted (KeyboardInterrupt:
        Ctrl-C, or a signal the caller turns into one) or killed, the partial map (partial_path(path)) is kept with
        every snapshot written so far; on any other error it is removed.
        """
        path = Path(path)
        if path.exists() and not overwrite:
            raise MapError(f'{path}: exists already; choose another name or pass overwrite')
        partial = partial_path(path)
        store = cls.create(partial, name, max_degree, created_from=created_from, metadata=metadata, overwrite=True)
        store._db.execute('PRAGMA synchronous=OFF')  # a crash leaves only the partial file, removed or redone
        try:
            for snapshot in snapshots:
                store.add_snapshot(snapshot.coefficients, snapshot.stamp_ns, snapshot.pose, snapshot.descriptors)
            if finish is not None:
                finish(store)
            store._compact()
            store.close()
            with partial.open('rb') as stream:
                os.fsync(stream.fileno())
            os.replace(partial, path)
        except KeyboardInterrupt:
            store.close()  # checkpointed: the partial map is one self-contained file of the snapshots so far
            raise
        except BaseException:
            store.close()
            for leftover in (partial, Path(f'{partial}-wal'), Path(f'{partial}-shm')):
                leftover.unlink(missing_ok=True)
            raise
        return cls.open(path)

    def _check_schema(self) -> None:
        """Raise MapError unless the file holds a skynav map of a schema version this code reads."""
        tables = {row[0] for row in self._db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        if 'meta' not in tables:
            listed = ', '.join(sorted(tables)) or 'none'
            raise MapError(f'{self.path}: an SQLite database but not a skynav map (no meta table; tables: {listed})')
        try:
            rows = self._db.execute('SELECT key, value FROM meta').fetchall()
        except sqlite3.OperationalError:
            raise MapError(f'{self.path}: an SQLite database but not a skynav map (alien meta table)') from None
        for key, value in rows:
            if not isinstance(key, str) or not isinstance(value, str):
                raise MapError(
                    f'{self.path}: damaged map (meta {str(key)[:40]!r}: a {type(key).__name__} key with a '
                    f'{type(value).__name__} value, where both are text)'
                )
        meta = dict(rows)
        if meta.get('format') != MAP_FORMAT:
            raise MapError(
                f'{self.path}: an SQLite database but not a skynav map (meta format is '
                f'{meta.get("format")!r}, expected {MAP_FORMAT!r})'
            )
        try:
            version = _count(meta.get('schema_version', ''))
        except ValueError:
            raise MapError(
                f'{self.path}: damaged map (schema_version {meta.get("schema_version")!r} is not a number)'
            ) from None
        if version > SCHEMA_VERSION:
            raise MapError(
                f'{self.path}: map schema version {version} is newer than this skynav reads '
                f'({SCHEMA_VERSION}); update skynav'
            )
        if version < 1:
            raise MapError(f'{self.path}: damaged map (schema version {version})')
        optional = {table: columns for table, columns in _OPTIONAL_COLUMNS.items() if table in tables}
        for table, columns in {**_REQUIRED_COLUMNS, **optional}.items():
            present = {row[1] for row in self._db.execute(f'PRAGMA table_info({table})')}
            if missing := columns - present:
                raise MapError(f'{self.path}: damaged map (table {table} lacks {", ".join(sorted(missing))})')
        try:
            degree = _count(meta['max_degree'])
        except (KeyError, ValueError):
            raise MapError(f'{self.path}: damaged map (max_degree {meta.get("max_degree", "")[:40]!r})') from None
        if degree > MAX_DEGREE:
            raise MapError(f'{self.path}: damaged map (max_degree {degree} is above the {MAX_DEGREE} skynav reads)')
        if version >= FIRST_CHECKED_VERSION and meta.get(META_CHECKSUM) != str(_meta_crc(meta)):
            raise MapError(f'{self.path}: corrupt map (checksum of the meta table does not match)')
        self._meta = meta

    def _load_snapshots(self) -> None:
        """Read every snapshot's stamp, coefficients and pose, checking types, order, sizes and checksums.

        The coefficients are what every reader uses (skynav's descriptors are derived from them), so they are
        all checked here; every row is checked before the arrays are allocated.
        """
        rows = self._db.execute(
            'SELECT idx, stamp_ns, coefficients, checksum, ' + ', '.join(POSE_COLUMNS) + ' FROM snapshots ORDER BY idx'
        ).fetchall()
        size = (self.max_degree + 1) ** 2
        for position, row in enumerate(rows):
            self._check_snapshot_row(position, row, size, len(rows))
        coefficients = np.frombuffer(b''.join(row[2] for row in rows), dtype='<f8').reshape(len(rows), size).copy()
        poses = np.array([row[4:11] if row[4] is not None else (np.nan,) * 7 for row in rows], dtype=float)
        poses = poses.reshape(len(rows), 7)
        self._stamps = np.fromiter((row[1] for row in rows), dtype=np.int64, count=len(rows))
        self._coefficients = coefficients
        self._poses = poses
        self._stamp_buffer, self._coefficient_buffer, self._pose_buffer = self._stamps, coefficients, poses
        self._capacity = len(rows)
        self._descriptor_cache.clear()

    def _check_snapshot_row(self, position: int, row: tuple, size: int, count: int) -> None:
        """Raise MapError unless row `position` (of `count`) is snapshot `position`, whole and intact."""
        index, stamp, blob, checksum, *pose = row
        if index != position or not isinstance(index, int):
            raise MapError(
                f'{self.path}: damaged map (snapshot indices are not 0..{count - 1}; index {position} is missing)'
            )
        if not isinstance(stamp, int) or not isinstance(checksum, int):
            raise MapError(f'{self.path}: damaged map (snapshot {index}: stamp or checksum is not an integer)')
        if not isinstance(blob, bytes) or len(blob) != 8 * size:
            raise MapError(
                f'{self.path}: damaged map (snapshot {index} has {len(blob) if isinstance(blob, bytes) else 0} '
                f'bytes of coefficients, expected {8 * size} for degree {self.max_degree})'
            )
        if pose != [None] * 7 and not all(isinstance(v, float | int) and math.isfinite(v) for v in pose):
            raise MapError(f'{self.path}: damaged map (snapshot {index}: the pose is not 7 finite numbers)')
        if _row_crc(blob, stamp, tuple(pose), self.schema_version) != checksum:
            raise MapError(f'{self.path}: corrupt map (checksum of snapshot {index} does not match)')

    # --- writing -------------------------------------------------------------------------------------------------

    def _require_writable(self) -> None:
        """Raise MapError when the map was opened read-only or is closed."""
        if not self.writable:
            raise MapError(f'{self.path}: map is open read-only')
        if self._db is None:
            raise MapError(f'{self.path}: map is closed')

    def add_snapshot(
        self,
        coefficients: np.ndarray,
        stamp_ns: int,
        pose: np.ndarray | None = None,
        descriptors: Mapping[str, np.ndarray] | None = None,
    ) -> int:
        """Append one snapshot (coefficients, stamp in ns, optional pose, named descriptors) in one transaction."""
        self._require_writable()
        coefficients = np.asarray(coefficients, dtype=float)
        size = (self.max_degree + 1) ** 2
        if coefficients.shape != (size,):
            raise ValueError(
                f'{self.path}: expected {size} coefficients (degree {self.max_degree}), got shape {coefficients.shape}'
            )
        if not np.all(np.isfinite(coefficients)):
            raise ValueError(f'{self.path}: coefficients must be finite')
        pose_values: tuple = (None,) * 7
        if pose is not None:
            pose_array = np.asarray(pose, dtype=float)
            if pose_array.shape != (7,) or not np.all(np.isfinite(pose_array)):
                raise ValueError(f'{self.path}: a pose is 7 finite numbers (x, y, z, qx, qy, qz, qw)')
            pose_values = tuple(float(v) for v in pose_array)
        blob = coefficients.astype('<f8').tobytes()
        version = self.schema_version
        packed = [(str(name), *_pack(array)) for name, array in (descriptors or {}).items()]
        with self._lock:
            index = len(self)
            try:
                with self._transaction():
                    self._db.execute(
                        'INSERT INTO snapshots VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)',
                        (index, int(stamp_ns), blob, _row_crc(blob, int(stamp_ns), pose_values, version), *pose_values),
                    )
                    if packed:
                        self._create_table('descriptors')
                        self._db.executemany(
                            'INSERT INTO descriptors VALUES (?, ?, ?, ?, ?, ?)', [(index, *row) for row in packed]
                        )
            except sqlite3.Error as exc:
                raise MapError(f'{self.path}: cannot write snapshot {index}: {exc}') from None
            self._append(int(stamp_ns), coefficients, np.asarray(pose_values, dtype=float))
            self._descriptor_cache.clear()
        return index

    def _append(self, stamp_ns: int, coefficients: np.ndarray, pose: np.ndarray) -> None:
        """Append one row to the in-memory arrays, growing their capacity geometrically (amortised O(1))."""
        count = len(self)
        if count == self._capacity:
            self._capacity = max(16, 2 * self._capacity)
            self._stamp_buffer = np.resize(self._stamp_buffer, self._capacity)
            self._coefficient_buffer = np.resize(self._coefficient_buffer, (self._capacity, coefficients.size))
            self._pose_buffer = np.resize(self._pose_buffer, (self._capacity, 7))
        self._stamp_buffer[count] = stamp_ns
        self._coefficient_buffer[count] = coefficients
        self._pose_buffer[count] = pose
        self._stamps = self._stamp_buffer[: count + 1]
        self._coefficients = self._coefficient_buffer[: count + 1]
        self._poses = self._pose_buffer[: count + 1]

    def put_descriptors(self, name: str, arrays: Iterable[np.ndarray] | np.ndarray) -> None:
        """Store (or replace) descriptor `name` of every snapshot, one array per snapshot, in one transaction."""
        self._require_writable()
        rows = [(index, str(name), *_pack(array)) for index, array in enumerate(arrays)]
        if len(rows) != len(self):
            raise ValueError(f'{self.path}: {len(rows)} descriptors for {len(self)} snapshots')
        try:
            with self._transaction():
                self._create_table('descriptors')
                self._db.execute('DELETE FROM descriptors WHERE name = ?', (str(name),))
                self._db.executemany('INSERT INTO descriptors VALUES (?, ?, ?, ?, ?, ?)', rows)
        except sqlite3.Error as exc:
            raise MapError(f'{self.path}: cannot write descriptors {name!r}: {exc}') from None
        self._descriptor_cache.pop(name, None)

    def remove_descriptors(self, name: str) -> None:
        """Delete descriptor `name` of every snapshot (if stored), in one transaction."""
        self._require_writable()
        try:
            with self._transaction():
                if self._has_table('descriptors'):
                    self._db.execute('DELETE FROM descriptors WHERE name = ?', (str(name),))
        except sqlite3.Error as exc:
            raise MapError(f'{self.path}: cannot remove descriptors {name!r}: {exc}') from None
        self._descriptor_cache.pop(name, None)

    def put_artifact(self, name: str, array: np.ndarray) -> None:
        """Store (or replace) a map-level array under a name (e.g. a vocabulary), in one transaction."""
        self._require_writable()
        try:
            with self._transaction():
                self._create_table('artifacts')
                self._db.execute('INSERT OR REPLACE INTO artifacts VALUES (?, ?, ?, ?, ?)', (str(name), *_pack(array)))
        except sqlite3.Error as exc:
            raise MapError(f'{self.path}: cannot write artifact {name!r}: {exc}') from None

    def set_meta(self, key: str, value: Any) -> None:
        """Store a metadata entry (text; other values as JSON) in one transaction; reserved keys are refused."""
        self._require_writable()
        if key in RESERVED_META:
            raise MapError(f'{self.path}: metadata key {key!r} is reserved')
        text = value if isinstance(value, str) else json.dumps(value)
        meta = {**self._meta, str(key): text}
        rows = [(str(key), text)]
        if self.schema_version >= FIRST_CHECKED_VERSION:
            meta[META_CHECKSUM] = str(_meta_crc(meta))
            rows.append((META_CHECKSUM, meta[META_CHECKSUM]))
        try:
            with self._transaction():
                self._db.executemany('INSERT OR REPLACE INTO meta VALUES (?, ?)', rows)
        except sqlite3.Error as exc:
            raise MapError(f'{self.path}: cannot write metadata {key!r}: {exc}') from None
        self._meta = meta

    def _has_table(self, table: str) -> bool:
        """Return whether the file holds table `table` (the optional tables appear with their first rows)."""
        return (
            self._db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?", (table,)).fetchone()
            is not None
        )

    def _create_table(self, table: str) -> None:
        """Create optional table `table` unless it exists (inside the caller's transaction)."""
        if not self._has_table(table):
            self._db.execute(_OPTIONAL_TABLES[table])

    @contextmanager
    def _transaction(self) -> Iterator[None]:
        """Run the block as one IMMEDIATE transaction under the store's lock: committed, or rolled back on error."""
        with self._lock:
            self._db.execute('BEGIN IMMEDIATE')
            try:
                yield
            except BaseException:
                self._db.execute('ROLLBACK')
                raise
            self._db.execute('COMMIT')

    def _compact(self) -> None:
        """Give the pages that removed rows left free back to the file system (VACUUM), if there are any."""
        self._require_writable()
        with self._lock:
            if self._db.execute('PRAGMA freelist_count').fetchone()[0]:
                self._db.execute('VACUUM')

    def close(self) -> None:
        """Close the file; a writable map is checkpointed into one self-contained file first."""
        with self._lock:
            self._close()

    def _close(self) -> None:
        """Close the connection (caller holds the lock)."""
        if self._db is None:
            return
        try:
            if self.writable:
                self._db.execute('PRAGMA wal_checkpoint(TRUNCATE)')
                self._db.execute('PRAGMA journal_mode=DELETE')
        except sqlite3.Error:
            pass  # another reader holds the WAL: it stays beside the file and SQLite replays it on the next open
        finally:
            self._db.close()
            self._db = None  # type: ignore[assignment]  # a closed store: the methods check for None first

    def __enter__(self) -> MapStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- reading -------------------------------------------------------------------------------------------------

    @property
    def name(self) -> str:
        """Return the map's name."""
        return self._meta.get('name', '')

    @property
    def schema_version(self) -> int:
        """Return the schema version the file was written with (module docstring, 'Versions')."""
        return int(self._meta['schema_version'])

    @property
    def max_degree(self) -> int:
        """Return the SH degree L of the stored coefficients."""
        return int(self._meta['max_degree'])

    @property
    def meta(self) -> dict[str, str]:
        """Return a copy of the metadata table (key -> text)."""
        return dict(self._meta)

    def __len__(self) -> int:
        """Return the number of snapshots."""
        return int(self._stamps.size)

    def coefficients(self) -> np.ndarray:
        """Return all snapshots' SH coefficients, (N, (L+1)^2) float64, read-only, in index order."""
        view = self._coefficients.view()
        view.flags.writeable = False
        return view

    def stamps(self) -> np.ndarray:
        """Return all snapshots' stamps (ns since the epoch), (N,) int64."""
        return self._stamps.copy()

    def poses(self) -> np.ndarray:
        """Return all ground-truth poses (N, 7) as (x, y, z, qx, qy, qz, qw) of camera_link in map; NaN rows if none."""
        return self._poses.copy()

    def positions(self) -> np.ndarray:
        """Return the ground-truth positions (N, 3) of camera_link in map (m); NaN rows if none."""
        return self._poses[:, :3].copy()

    def odometry_poses(self) -> np.ndarray | None:
        """Return the teach's odometry poses (N, 7) of base_link in `odom` (ODOM_POSE); None if the map has none."""
        return self._pose_descriptor(ODOM_POSE)

    def commanded_poses(self) -> np.ndarray | None:
        """Return the teach's poses (N, 7) of base_link by its velocity commands (COMMAND_POSE); None if none."""
        return self._pose_descriptor(COMMAND_POSE)

    def _pose_descriptor(self, name: str) -> np.ndarray | None:
        """Return a per-snapshot pose descriptor as (N, 7); None if the map has none."""
        if not len(self) or name not in self.descriptor_names():
            return None
        return np.asarray(self.descriptor_matrix(name), float).reshape(len(self), -1)

    @property
    def has_poses(self) -> bool:
        """Return whether every snapshot has a ground-truth pose."""
        return bool(len(self)) and bool(np.all(np.isfinite(self._poses)))

    def snapshot(self, index: int) -> Snapshot:
        """Return one snapshot with its descriptors (each checked when it is looked up: CheckedDescriptors)."""
        if not 0 <= index < len(self):
            raise IndexError(f'{self.path}: no snapshot {index} (the map has {len(self)})')
        rows = self._read_optional(
            'descriptors',
            'SELECT name, dtype, shape, data, checksum FROM descriptors WHERE snapshot_idx = ?',
            (int(index),),
        )
        descriptors = CheckedDescriptors({str(row[0]): row[1:] for row in rows}, self._checked, index)
        pose = self._poses[index]
        return Snapshot(
            index,
            int(self._stamps[index]),
            self._coefficients[index].copy(),
            pose.copy() if np.all(np.isfinite(pose)) else None,
            descriptors,
        )

    def snapshots(self) -> list[Snapshot]:
        """Return every snapshot (index order) with its descriptors (each checked when it is looked up)."""
        return [self.snapshot(index) for index in range(len(self))]

    def descriptor_names(self) -> list[str]:
        """Return the names of the stored per-snapshot descriptors."""
        return [
            str(row[0])
            for row in self._read_optional('descriptors', 'SELECT DISTINCT name FROM descriptors ORDER BY name')
        ]

    def descriptor_list(self, name: str) -> list[np.ndarray]:
        """Return descriptor `name` of every snapshot as a list (for variable-size ones such as ORB)."""
        rows = self._read_optional(
            'descriptors',
            'SELECT snapshot_idx, dtype, shape, data, checksum FROM descriptors WHERE name = ? ORDER BY snapshot_idx',
            (str(name),),
        )
        if not rows:
            raise KeyError(
                f'{self.path}: no descriptor {name!r} in this map '
                f'(it has: {", ".join(self.descriptor_names()) or "none"})'
            )
        if len(rows) != len(self) or any(row[0] != i for i, row in enumerate(rows)):
            have = {row[0] for row in rows}
            first = next(i for i in range(len(self)) if i not in have)
            raise MapError(
                f'{self.path}: descriptor {name!r} is stored for {len(rows)} of {len(self)} snapshots '
                f'(snapshot {first} lacks it)'
            )
        return [self._checked(row[1:], f'descriptor {name!r} of snapshot {row[0]}') for row in rows]

    def descriptor_matrix(self, name: str) -> np.ndarray:
        """Return descriptor `name` of all snapshots as one (N, D) matrix (cached, read-only)."""
        if name not in self._descriptor_cache:
            arrays = self.descriptor_list(name)
            shapes = {array.shape for array in arrays}
            if len(shapes) != 1 or len(next(iter(shapes))) != 1:
                raise MapError(f'{self.path}: descriptor {name!r} is not one vector of equal size per snapshot')
            matrix = np.stack(arrays)
            matrix.flags.writeable = False
            self._descriptor_cache[name] = matrix
        return self._descriptor_cache[name]

    def derived(self, key: str, make: Callable[[], np.ndarray]) -> np.ndarray:
        """Return a matrix derived from the map's data by make(), made once, kept until the map changes (read-only)."""
        cached = f'derived:{key}'
        with self._lock:
            if cached not in self._descriptor_cache:
                matrix = np.asarray(make())
                matrix.flags.writeable = False
                self._descriptor_cache[cached] = matrix
            return self._descriptor_cache[cached]

    def artifact(self, name: str) -> np.ndarray | None:
        """Return the map-level array stored under `name`, None if there is none."""
        rows = self._read_optional(
            'artifacts', 'SELECT dtype, shape, data, checksum FROM artifacts WHERE name = ?', (str(name),)
        )
        return self._checked(rows[0], f'artifact {name!r}') if rows else None

    def _read(self, sql: str, parameters: tuple = ()) -> list[tuple]:
        """Run a query, turning SQLite failures into MapError."""
        if self._db is None:
            raise MapError(f'{self.path}: map is closed')
        try:
            with self._lock:
                return self._db.execute(sql, parameters).fetchall()
        except sqlite3.Error as exc:
            raise MapError(f'{self.path}: corrupt or truncated map file ({exc})') from None

    def _read_optional(self, table: str, sql: str, parameters: tuple = ()) -> list[tuple]:
        """Run a query on optional table `table`: no rows when the map does not hold that table."""
        with self._lock:
            present = self._read("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?", (table,))
            return self._read(sql, parameters) if present else []

    def _checked(self, row: tuple, what: str) -> np.ndarray:
        """Return the array of a (dtype, shape, data, checksum) row; MapError if it is damaged."""
        dtype, shape, data, checksum = row
        if not isinstance(data, bytes) or _crc(data) != checksum:
            raise MapError(f'{self.path}: corrupt map (checksum of {what} does not match)')
        try:
            return _unpack(dtype, shape, data)
        except ValueError as exc:
            raise MapError(f'{self.path}: damaged map ({what}: {exc})') from None

    def snapshot_stamp(self, index: int) -> int:
        """Return the stamp (ns since the epoch) of snapshot `index`."""
        return int(self._stamps[index])

    def info(self) -> dict[str, Any]:
        """Return a summary for `skynav map info`: name, size, degree, descriptors, route length, time span."""
        info: dict[str, Any] = {key: value for key, value in self._meta.items()}
        info['schema_version'] = int(self._meta['schema_version'])
        info['max_degree'] = self.max_degree
        info['path'] = str(self.path)
        info['file_bytes'] = self.path.stat().st_size if self.path.exists() else 0
        info['snapshots'] = len(self)
        info['descriptors'] = self.descriptor_names()
        info['artifacts'] = [
            row[0] for row in self._read_optional('artifacts', 'SELECT name FROM artifacts ORDER BY name')
        ]
        info['has_poses'] = self.has_poses
        if len(self):
            info['first_stamp_ns'] = int(self._stamps[0])
            info['last_stamp_ns'] = int(self._stamps[-1])
            info['duration_s'] = float(self._stamps[-1] - self._stamps[0]) * 1e-9
        if self.has_poses and len(self) > 1:
            steps = np.linalg.norm(np.diff(self._poses[:, :3], axis=0), axis=1)
            info['route_length_m'] = float(np.sum(steps))
            info['median_spacing_m'] = float(np.median(steps))
        return info

    def __repr__(self) -> str:
        return f'MapStore({str(self.path)!r}, name={self.name!r}, snapshots={len(self)}, L={self.max_degree})'


def partial_path(path: str | os.PathLike) -> Path:
    """Return the file MapStore.build writes the map at `path` under until it is complete (hidden, beside it)."""
    path = Path(path)
    return path.with_name(f'.{path.name}.partial')


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
