# SPDX-License-Identifier: Apache-2.0
"""Reading a map: opening a file (read-only unless asked), checking it (the package docstring, "Checking") and
every query of its snapshots, poses, descriptors, artifacts and metadata; MapReader is MapStore's reading half."""

from __future__ import annotations

import math
import os
import sqlite3
import threading
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any, Self
from urllib.parse import quote

import numpy as np

from .schema import (
    CHECKS,
    COMMAND_POSE,
    ODOM_POSE,
    POSE_COLUMNS,
    SQLITE_MAGIC,
    MapError,
    Snapshot,
    _crc,
    _row_crc,
    _unpack,
    checked_meta,
)


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


class MapReader:
    """The reading half of a map (MapStore): its state, opening and checking a file, every query, closing."""

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
    def open(cls, path: str | os.PathLike, *, writable: bool = False, check: str = 'quick') -> Self:
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
            store._meta = checked_meta(db, path)
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

    # --- closing -------------------------------------------------------------------------------------------------

    def close(self) -> None:
        """Close the file; a writable map is checkpointed into one self-contained file first."""
        with self._lock:
            self._close()

    def _close(self) -> None:
        """Close the connection (caller holds the lock); MapWriter checkpoints a writable map first."""
        if self._db is None:
            return
        self._db.close()
        self._db = None  # type: ignore[assignment]  # a closed store: the methods check for None first

    def __enter__(self) -> Self:
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
        """Return the schema version the file was written with (package docstring, 'Versions')."""
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
