# SPDX-License-Identifier: Apache-2.0
"""Writing a map (the package docstring, "Writing"): creating a file, adding snapshots, descriptors, artifacts and
metadata each in one committed transaction (a process killed while writing leaves every commit so far readable),
building a whole map under a temporary name, compacting and closing; MapWriter is MapStore's writing half."""

from __future__ import annotations

import json
import os
import sqlite3
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Self

import numpy as np

from .reader import MapReader
from .schema import (
    APPLICATION_ID,
    FIRST_CHECKED_VERSION,
    MAP_FORMAT,
    META_CHECKSUM,
    PAGE_SIZE,
    RESERVED_META,
    SCHEMA_VERSION,
    MapError,
    Snapshot,
    _meta_crc,
    _pack,
    _row_crc,
    create_optional_table,
    create_tables,
    has_table,
)


class MapWriter(MapReader):
    """The writing half of a map (MapStore): create and build a file, append and store rows, compact, close."""

    # --- creating ------------------------------------------------------------------------------------------------

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
    ) -> Self:
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
            create_tables(db)
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
        finish: Callable[[Self], None] | None = None,
    ) -> Self:
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
                        create_optional_table(self._db, 'descriptors')
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
                create_optional_table(self._db, 'descriptors')
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
                if has_table(self._db, 'descriptors'):
                    self._db.execute('DELETE FROM descriptors WHERE name = ?', (str(name),))
        except sqlite3.Error as exc:
            raise MapError(f'{self.path}: cannot remove descriptors {name!r}: {exc}') from None
        self._descriptor_cache.pop(name, None)

    def put_artifact(self, name: str, array: np.ndarray) -> None:
        """Store (or replace) a map-level array under a name (e.g. a vocabulary), in one transaction."""
        self._require_writable()
        try:
            with self._transaction():
                create_optional_table(self._db, 'artifacts')
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

    def _close(self) -> None:
        """Checkpoint a writable map into one self-contained file, then close the connection (caller holds the lock)."""
        try:
            if self._db is not None and self.writable:
                self._db.execute('PRAGMA wal_checkpoint(TRUNCATE)')
                self._db.execute('PRAGMA journal_mode=DELETE')
        except sqlite3.Error:
            pass  # another reader holds the WAL: it stays beside the file and SQLite replays it on the next open
        finally:
            super()._close()


def partial_path(path: str | os.PathLike) -> Path:
    """Return the file MapStore.build writes the map at `path` under until it is complete (hidden, beside it)."""
    path = Path(path)
    return path.with_name(f'.{path.name}.partial')
