# SPDX-License-Identifier: Apache-2.0
"""The SQLite map store: round trip, atomic build, durability under SIGKILL, and a clear error for bad files."""

from __future__ import annotations

import signal
import sqlite3
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from skynav_core.maps import PAGE_SIZE, SCHEMA_VERSION, MapError, MapStore, Snapshot, _crc, partial_path

DEGREE = 4
SIZE = (DEGREE + 1) ** 2


def coefficients_of(index: int) -> np.ndarray:
    """Deterministic coefficients of snapshot `index` (so a reader can check every stored value)."""
    return np.sin(np.arange(SIZE) * 0.37 + index)


def pose_of(index: int) -> np.ndarray:
    return np.array([0.1 * index, -0.05 * index, 0.3, 0.0, 0.0, np.sin(index / 10), np.cos(index / 10)])


def write_map(path, count: int = 5, poses: bool = True) -> None:
    with MapStore.create(path, 'garden', DEGREE, created_from='test.mcap') as store:
        for i in range(count):
            store.add_snapshot(
                coefficients_of(i),
                1_000_000_000 + i,
                pose_of(i) if poses else None,
                {'amplitude': np.arange(DEGREE, dtype=float) + i, 'orb': np.full((i + 1, 32), i, np.uint8)},
            )


def assert_one_line_map_error(excinfo, path, *words):
    message = str(excinfo.value)
    assert '\n' not in message and str(path) in message
    for word in words:
        assert word in message, message


def test_round_trip(tmp_path):
    path = tmp_path / 'garden.db'
    write_map(path)
    store = MapStore.open(path)
    assert len(store) == 5 and store.name == 'garden' and store.max_degree == DEGREE
    for i, snapshot in enumerate(store.snapshots()):
        assert snapshot.index == i and snapshot.stamp_ns == 1_000_000_000 + i
        np.testing.assert_array_equal(snapshot.coefficients, coefficients_of(i))
        np.testing.assert_array_equal(snapshot.pose, pose_of(i))
        np.testing.assert_array_equal(snapshot.descriptors['orb'], np.full((i + 1, 32), i, np.uint8))
        assert snapshot.descriptors['orb'].dtype == np.uint8
    matrix = store.descriptor_matrix('amplitude')
    assert matrix.shape == (5, DEGREE) and not matrix.flags.writeable
    assert store.descriptor_matrix('amplitude') is matrix  # cached
    np.testing.assert_array_equal(store.poses(), np.array([pose_of(i) for i in range(5)]))
    np.testing.assert_array_equal(store.stamps(), 1_000_000_000 + np.arange(5))
    assert store.descriptor_names() == ['amplitude', 'orb']
    info = store.info()
    assert info['snapshots'] == 5 and info['schema_version'] == SCHEMA_VERSION and info['max_degree'] == DEGREE
    assert info['created_from'] == 'test.mcap' and info['has_poses']
    assert info['route_length_m'] == pytest.approx(4 * np.hypot(0.1, 0.05))
    with pytest.raises(MapError, match='read-only'):
        store.add_snapshot(coefficients_of(5), 0)
    with pytest.raises(KeyError, match='no descriptor'):
        store.descriptor_matrix('bispectrum')
    with pytest.raises(MapError, match='not one vector'):
        store.descriptor_matrix('orb')
    store.close()


def test_map_without_poses_and_finished_map_is_one_file(tmp_path):
    path = tmp_path / 'plain.db'
    write_map(path, count=3, poses=False)
    assert not (tmp_path / 'plain.db-wal').exists()  # close() folded the WAL into the file
    store = MapStore.open(path)
    assert not store.has_poses and np.all(np.isnan(store.poses()))
    assert store.snapshot(0).pose is None


def test_appending_artifacts_and_descriptors(tmp_path):
    path = tmp_path / 'garden.db'
    write_map(path, count=3)
    with MapStore.open(path, writable=True) as store:
        store.put_artifact('bow-orb.idf', np.array([0.5, 1.5]))
        store.put_descriptors('bow-orb', [np.full(2, i, np.float32) for i in range(3)])
        assert store.descriptor_matrix('bow-orb').dtype == np.float32
        store.set_meta('camera', {'fx': 100.0})
        with pytest.raises(ValueError, match='2 descriptors for 3 snapshots'):
            store.put_descriptors('other', [np.zeros(2)] * 2)
        store.add_snapshot(coefficients_of(3), 7)  # added later: has no 'bow-orb' descriptor
    store = MapStore.open(path)
    assert len(store) == 4
    np.testing.assert_array_equal(store.artifact('bow-orb.idf'), [0.5, 1.5])
    assert store.artifact('missing') is None
    assert store.meta['camera'] == '{"fx": 100.0}'
    with pytest.raises(MapError, match="'bow-orb' is stored for 3 of 4 snapshots .snapshot 3 lacks it."):
        store.descriptor_matrix('bow-orb')
    np.testing.assert_array_equal(store.snapshot(2).descriptors['orb'], np.full((3, 32), 2, np.uint8))
    assert store.snapshot(3).descriptors == {}


def tables_of(path) -> set[str]:
    with sqlite3.connect(path) as db:
        names = {row[0] for row in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    db.close()
    return names


def test_a_map_of_coefficients_holds_meta_and_snapshots_only(tmp_path):
    path = tmp_path / 'product.db'
    with MapStore.create(path, 'product', DEGREE) as store:
        for i in range(3):
            store.add_snapshot(coefficients_of(i), i, pose_of(i))
    assert tables_of(path) == {'meta', 'snapshots'}
    with sqlite3.connect(path) as db:
        assert db.execute('PRAGMA page_size').fetchone()[0] == PAGE_SIZE
    db.close()
    store = MapStore.open(path)
    assert store.descriptor_names() == [] and store.artifact('bow-orb.words') is None
    assert store.snapshot(1).descriptors == {} and store.info()['artifacts'] == []
    with pytest.raises(KeyError, match='no descriptor .raw_uv. in this map .it has: none.'):
        store.descriptor_list('raw_uv')
    store.close()
    with MapStore.open(path, writable=True) as store:  # the optional tables come with their first rows
        store.put_descriptors('raw_uv', [np.full(4, i, np.float32) for i in range(3)])
        store.put_artifact('words', np.eye(2))
    assert tables_of(path) == {'meta', 'snapshots', 'descriptors', 'artifacts'}
    store = MapStore.open(path)
    np.testing.assert_array_equal(store.descriptor_matrix('raw_uv')[:, 0], [0, 1, 2])
    np.testing.assert_array_equal(store.artifact('words'), np.eye(2))


def test_removed_descriptors_leave_no_free_pages_in_a_built_map(tmp_path):
    path = tmp_path / 'built.db'
    snapshots = [
        Snapshot(
            i,
            i,
            coefficients_of(i),
            pose_of(i),
            {'orb': np.full((200, 32), i, np.uint8), 'raw_uv': np.full(768, i, np.float32)},
        )
        for i in range(6)
    ]
    store = MapStore.build(path, 'built', DEGREE, snapshots, finish=lambda s: s.remove_descriptors('orb'))
    assert store.descriptor_names() == ['raw_uv'] and len(store) == 6
    with sqlite3.connect(path) as db:
        assert db.execute('PRAGMA freelist_count').fetchone()[0] == 0
    db.close()


V1_SCHEMA = """
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE snapshots (idx INTEGER PRIMARY KEY CHECK (idx >= 0), stamp_ns INTEGER NOT NULL,
    coefficients BLOB NOT NULL, checksum INTEGER NOT NULL,
    x REAL, y REAL, z REAL, qx REAL, qy REAL, qz REAL, qw REAL, CHECK ((x IS NULL) = (qw IS NULL)));
CREATE TABLE descriptors (snapshot_idx INTEGER NOT NULL REFERENCES snapshots(idx), name TEXT NOT NULL,
    dtype TEXT NOT NULL, shape TEXT NOT NULL, data BLOB NOT NULL, checksum INTEGER NOT NULL,
    PRIMARY KEY (snapshot_idx, name)) WITHOUT ROWID;
CREATE INDEX descriptors_by_name ON descriptors(name, snapshot_idx);
CREATE TABLE artifacts (name TEXT PRIMARY KEY, dtype TEXT NOT NULL, shape TEXT NOT NULL, data BLOB NOT NULL,
    checksum INTEGER NOT NULL);
"""


def test_a_version_1_map_still_opens(tmp_path):
    # as skynav wrote maps before schema version 2: every table, 4 kB pages, SH descriptors stored
    path = tmp_path / 'old.db'
    with sqlite3.connect(path) as db:
        db.executescript(V1_SCHEMA)
        db.executemany(
            'INSERT INTO meta VALUES (?, ?)',
            [('format', 'skynav-map'), ('schema_version', '1'), ('name', 'old'), ('max_degree', str(DEGREE))],
        )
        for i in range(3):
            blob = coefficients_of(i).astype('<f8').tobytes()
            db.execute(
                'INSERT INTO snapshots VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)',
                (i, 100 + i, blob, _crc(blob), *pose_of(i)),
            )
            amplitude = np.full(DEGREE, float(i)).astype('<f8').tobytes()
            db.execute(
                'INSERT INTO descriptors VALUES (?, ?, ?, ?, ?, ?)',
                (i, 'amplitude', '<f8', str(DEGREE), amplitude, _crc(amplitude)),
            )
    db.close()
    store = MapStore.open(path)
    assert len(store) == 3 and store.info()['schema_version'] == 1 and store.name == 'old'
    np.testing.assert_array_equal(store.coefficients()[2], coefficients_of(2))
    np.testing.assert_array_equal(store.descriptor_matrix('amplitude')[:, 0], [0.0, 1.0, 2.0])


def test_build_is_atomic(tmp_path):
    path = tmp_path / 'built.db'
    snapshots = [Snapshot(i, i, coefficients_of(i), pose_of(i), {'amplitude': np.ones(DEGREE)}) for i in range(4)]

    def failing():
        yield from snapshots[:2]
        raise RuntimeError('bag ended badly')

    with pytest.raises(RuntimeError):
        MapStore.build(path, 'built', DEGREE, failing())
    assert list(tmp_path.iterdir()) == []  # nothing at the target, no partial file left behind
    store = MapStore.build(path, 'built', DEGREE, snapshots)
    assert len(store) == 4 and [p.name for p in tmp_path.iterdir()] == ['built.db']
    with pytest.raises(MapError, match='exists already'):
        MapStore.build(path, 'built', DEGREE, snapshots)


def test_a_failed_write_leaves_nothing_behind_and_the_next_write_works(tmp_path):
    path = tmp_path / 'm.db'
    write_map(path, count=3)
    with sqlite3.connect(path) as db:  # a stray row (e.g. another writer's) that snapshot 3's descriptor will hit
        db.execute("INSERT INTO descriptors VALUES (3, 'amplitude', '<f8', '[4]', x'00', 0)")
    db.close()
    store = MapStore.open(path, writable=True)
    with pytest.raises(MapError, match='cannot write snapshot 3'):
        store.add_snapshot(coefficients_of(99), 99, pose_of(99), {'amplitude': np.zeros(DEGREE)})
    assert len(store) == 3
    with sqlite3.connect(path) as db:  # the snapshot row written before the descriptor failed was rolled back
        assert db.execute('SELECT count(*) FROM snapshots').fetchone()[0] == 3
    db.close()
    assert store.add_snapshot(coefficients_of(3), 1_000_000_003, pose_of(3)) == 3
    store.close()
    with MapStore.open(path) as store:
        assert len(store) == 4 and store.stamps()[3] == 1_000_000_003
        np.testing.assert_array_equal(store.coefficients()[3], coefficients_of(3))


def test_bad_input_is_refused(tmp_path):
    store = MapStore.create(tmp_path / 'm.db', 'm', DEGREE)
    with pytest.raises(ValueError, match='expected 25 coefficients'):
        store.add_snapshot(np.zeros(SIZE + 1), 0)
    with pytest.raises(ValueError, match='finite'):
        store.add_snapshot(np.full(SIZE, np.nan), 0)
    with pytest.raises(ValueError, match='pose'):
        store.add_snapshot(np.zeros(SIZE), 0, pose=np.zeros(6))
    assert len(store) == 0
    with pytest.raises(MapError, match='reserved'):
        MapStore.create(tmp_path / 'n.db', 'n', DEGREE, metadata={'name': 'x'})
    with pytest.raises(MapError, match='exists already'):
        MapStore.create(tmp_path / 'm.db', 'm', DEGREE)


# --- errors: one MapError line naming the file and the problem --------------------------------------------------


def test_missing_file(tmp_path):
    with pytest.raises(MapError) as excinfo:
        MapStore.open(tmp_path / 'nothing.db')
    assert_one_line_map_error(excinfo, tmp_path / 'nothing.db', 'no such map file')


def test_not_sqlite_and_empty(tmp_path):
    path = tmp_path / 'text.db'
    path.write_text('this is a text file, not a map\n')
    with pytest.raises(MapError) as excinfo:
        MapStore.open(path)
    assert_one_line_map_error(excinfo, path, 'not an SQLite database')
    empty = tmp_path / 'empty.db'
    empty.write_bytes(b'')
    with pytest.raises(MapError) as excinfo:
        MapStore.open(empty)
    assert_one_line_map_error(excinfo, empty, 'empty file')


def test_foreign_sqlite(tmp_path):
    path = tmp_path / 'foreign.db'
    with sqlite3.connect(path) as db:
        db.execute('CREATE TABLE songs (title TEXT)')
    db.close()
    with pytest.raises(MapError) as excinfo:
        MapStore.open(path)
    assert_one_line_map_error(excinfo, path, 'not a skynav map', 'songs')
    alien = tmp_path / 'alien.db'
    with sqlite3.connect(alien) as db:
        db.execute('CREATE TABLE meta (key TEXT, value TEXT)')
        db.execute("INSERT INTO meta VALUES ('format', 'someone-else')")
    db.close()
    with pytest.raises(MapError) as excinfo:
        MapStore.open(alien)
    assert_one_line_map_error(excinfo, alien, 'not a skynav map', 'someone-else')


def test_newer_schema(tmp_path):
    path = tmp_path / 'future.db'
    write_map(path, count=1)
    with sqlite3.connect(path) as db:
        db.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'", (str(SCHEMA_VERSION + 1),))
    db.close()
    with pytest.raises(MapError) as excinfo:
        MapStore.open(path)
    assert_one_line_map_error(excinfo, path, f'schema version {SCHEMA_VERSION + 1} is newer')


def test_missing_table_or_snapshot(tmp_path):
    path = tmp_path / 'damaged.db'
    write_map(path, count=3)
    with sqlite3.connect(path) as db:
        db.execute('DELETE FROM snapshots WHERE idx = 1')
    db.close()
    with pytest.raises(MapError) as excinfo:
        MapStore.open(path)
    assert_one_line_map_error(excinfo, path, 'index 1 is missing')
    with sqlite3.connect(path) as db:
        db.execute('ALTER TABLE descriptors RENAME COLUMN checksum TO crc')  # an optional table, but damaged
    db.close()
    with pytest.raises(MapError) as excinfo:
        MapStore.open(path)
    assert_one_line_map_error(excinfo, path, 'damaged map', 'descriptors', 'checksum')
    with sqlite3.connect(path) as db:
        db.execute('DROP TABLE descriptors')
        db.execute('DROP TABLE snapshots')
    db.close()
    with pytest.raises(MapError) as excinfo:
        MapStore.open(path)
    assert_one_line_map_error(excinfo, path, 'damaged map', 'snapshots')


def test_truncated_file(tmp_path):
    path = tmp_path / 'cut.db'
    write_map(path, count=200)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(MapError) as excinfo:
        MapStore.open(path)
    assert_one_line_map_error(excinfo, path, 'corrupt')


def test_corrupt_coefficients_are_caught_by_their_checksum(tmp_path):
    path = tmp_path / 'flipped.db'
    write_map(path, count=3)
    data = bytearray(path.read_bytes())
    blob = coefficients_of(2).astype('<f8').tobytes()
    at = data.find(blob)
    assert at > 0
    data[at + 8 : at + 16] = np.float64(123.0).tobytes()  # a plausible but wrong value: SQLite cannot notice
    path.write_bytes(bytes(data))
    with pytest.raises(MapError) as excinfo:
        MapStore.open(path)
    assert_one_line_map_error(excinfo, path, 'checksum of snapshot 2')


def test_corrupt_descriptor_is_caught_when_read(tmp_path):
    path = tmp_path / 'flipped.db'
    write_map(path, count=3)
    data = bytearray(path.read_bytes())
    blob = (np.arange(DEGREE, dtype=float) + 1).astype('<f8').tobytes()
    at = data.find(blob)
    assert at > 0
    data[at : at + 8] = np.float64(-7.0).tobytes()
    path.write_bytes(bytes(data))
    store = MapStore.open(path)
    with pytest.raises(MapError, match="checksum of descriptor 'amplitude' of snapshot 1"):
        store.descriptor_matrix('amplitude')


WRITER = textwrap.dedent("""
    import itertools, sys
    import numpy as np
    from skynav_core.maps import MapStore
    store = MapStore.create(sys.argv[1], 'killed', {degree})
    for i in itertools.count():
        store.add_snapshot(np.sin(np.arange({size}) * 0.37 + i), i, None, {{'amplitude': np.full({degree}, float(i))}})
        print(i, flush=True)
""")


def test_sigkill_while_building_keeps_every_committed_snapshot(tmp_path):
    path = tmp_path / 'killed.db'
    writer = subprocess.Popen(
        [sys.executable, '-c', WRITER.format(degree=DEGREE, size=SIZE), str(path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        for line in writer.stdout:
            if int(line) >= 40:
                break
        writer.send_signal(signal.SIGKILL)
    finally:
        writer.wait(timeout=30)
    assert writer.returncode == -signal.SIGKILL
    reported = [int(n) for n in writer.stdout.read().split()]
    committed = (reported[-1] if reported else int(line)) + 1  # printed only after its commit returned
    store = MapStore.open(path)
    assert committed <= len(store) <= committed + 1  # at most the snapshot in flight differs
    for i in range(len(store)):
        np.testing.assert_array_equal(store.coefficients()[i], coefficients_of(i))
    np.testing.assert_array_equal(store.descriptor_matrix('amplitude')[:, 0], np.arange(len(store)))
    assert store.info()['snapshots'] == len(store)


# --- crafted headers: refused in one line before anything is allocated ------------------------------------------


def craft(path, *statements: str, parameters: tuple = ()) -> None:
    """Change a map file with SQL, as a crafted or damaged file would hold it (checksums left as they were)."""
    with sqlite3.connect(path) as db:
        for statement in statements:
            db.execute(statement, parameters if '?' in statement else ())
    db.close()


@pytest.mark.parametrize(
    ('statement', 'words'),
    [
        ("UPDATE meta SET value = '100000' WHERE key = 'max_degree'", ('max_degree 100000', 'above the 64')),
        ("UPDATE meta SET value = '-1' WHERE key = 'max_degree'", ("max_degree '-1'",)),
        ("UPDATE meta SET value = 'lots' WHERE key = 'max_degree'", ("max_degree 'lots'",)),
        ("UPDATE meta SET value = 'lots' WHERE key = 'schema_version'", ("schema_version 'lots'",)),
        ("UPDATE meta SET value = X'34' WHERE key = 'max_degree'", ("meta 'max_degree'", 'bytes value')),
        ("UPDATE meta SET value = 'lawn' WHERE key = 'name'", ('checksum of the meta table',)),
        ("UPDATE snapshots SET x = 'here' WHERE idx = 1", ('snapshot 1', 'pose is not 7 finite numbers')),
        ('UPDATE snapshots SET qx = NULL WHERE idx = 1', ('snapshot 1', 'pose is not 7 finite numbers')),
        ('UPDATE snapshots SET x = x + 0.5 WHERE idx = 1', ('checksum of snapshot 1',)),
        ('UPDATE snapshots SET stamp_ns = stamp_ns + 1 WHERE idx = 2', ('checksum of snapshot 2',)),
        ("UPDATE snapshots SET stamp_ns = 'soon' WHERE idx = 2", ('snapshot 2', 'not an integer')),
        ("UPDATE snapshots SET coefficients = 'text' WHERE idx = 0", ('snapshot 0 has 0 bytes',)),
        ('UPDATE snapshots SET idx = 7 WHERE idx = 1', ('index 1 is missing',)),
    ],
)
def test_crafted_headers_and_rows_are_refused_in_one_line(tmp_path, statement, words):
    path = tmp_path / 'crafted.db'
    write_map(path, count=3)
    craft(path, statement)
    with pytest.raises(MapError) as excinfo:
        MapStore.open(path)
    assert_one_line_map_error(excinfo, path, *words)


@pytest.mark.parametrize(
    ('column', 'value', 'words'),
    [
        ('dtype', '|O', ("dtype '|O'",)),
        ('dtype', 'O', ("dtype 'O'",)),
        ('dtype', '<f8,<f8', ("dtype '<f8,<f8'",)),  # numpy would read a structure
        ('dtype', '>f8', ("dtype '>f8'",)),
        ('dtype', 3, ("dtype '3'",)),  # TEXT affinity: stored as '3'
        ('shape', '99999,99999', ('needs 79998400008 bytes, has 32',)),
        ('shape', '-4', ("shape '-4'",)),
        ('shape', '1,1,1,1,4', ("shape '1,1,1,1,4'",)),
        ('shape', '²', ("shape '²'",)),
        ('shape', '4x1', ("shape '4x1'",)),
    ],
)
def test_a_crafted_descriptor_is_refused_when_read_and_only_then(tmp_path, column, value, words):
    path = tmp_path / 'crafted.db'
    write_map(path, count=3)
    craft(
        path, f"UPDATE descriptors SET {column} = ? WHERE snapshot_idx = 1 AND name = 'amplitude'", parameters=(value,)
    )
    store = MapStore.open(path)  # the coefficients, stamps and poses are intact: the map opens
    snapshot = store.snapshot(1)
    np.testing.assert_array_equal(snapshot.coefficients, coefficients_of(1))
    np.testing.assert_array_equal(snapshot.descriptors['orb'], np.full((2, 32), 1, np.uint8))
    assert store.descriptor_list('orb')[1].shape == (2, 32)
    for read in (lambda: snapshot.descriptors['amplitude'], lambda: store.descriptor_matrix('amplitude')):
        with pytest.raises(MapError) as excinfo:
            read()
        assert_one_line_map_error(excinfo, path, "descriptor 'amplitude' of snapshot 1", *words)


def test_a_damaged_descriptor_matters_only_to_whoever_reads_it(tmp_path):
    path = tmp_path / 'flipped.db'
    write_map(path, count=3)
    with sqlite3.connect(path) as db:
        (data,) = db.execute("SELECT data FROM descriptors WHERE snapshot_idx = 2 AND name = 'orb'").fetchone()
        damaged = bytes([data[0] ^ 0x10]) + data[1:]
        db.execute("UPDATE descriptors SET data = ? WHERE snapshot_idx = 2 AND name = 'orb'", (damaged,))
    db.close()
    store = MapStore.open(path)
    snapshots = store.snapshots()  # every snapshot with its descriptors: nothing read yet
    assert [sorted(s.descriptors) for s in snapshots] == [['amplitude', 'orb']] * 3
    np.testing.assert_array_equal(snapshots[2].coefficients, coefficients_of(2))
    np.testing.assert_array_equal(store.descriptor_matrix('amplitude')[:, 0], [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(snapshots[1].descriptors['orb'], np.full((2, 32), 1, np.uint8))
    with pytest.raises(MapError) as excinfo:
        snapshots[2].descriptors['orb']
    assert_one_line_map_error(excinfo, path, "checksum of descriptor 'orb' of snapshot 2")
    with pytest.raises(MapError, match="checksum of descriptor 'orb' of snapshot 2"):
        store.descriptor_list('orb')


def test_set_meta_keeps_the_meta_checksum(tmp_path):
    path = tmp_path / 'm.db'
    write_map(path, count=2)
    store = MapStore.open(path, writable=True)
    store.set_meta('note', {'mowed': True})
    store.close()
    reopened = MapStore.open(path)
    assert reopened.meta['note'] == '{"mowed": true}' and reopened.schema_version == SCHEMA_VERSION


def test_an_interrupted_build_keeps_its_partial_map(tmp_path):
    path = tmp_path / 'built.db'

    def interrupted():
        for i in range(3):
            yield Snapshot(i, 1_000_000_000 + i, coefficients_of(i), pose_of(i))
        raise KeyboardInterrupt  # Ctrl-C (and SIGTERM in `skynav map build`) while the drive is read

    with pytest.raises(KeyboardInterrupt):
        MapStore.build(path, 'built', DEGREE, interrupted())
    assert not path.exists() and [p.name for p in tmp_path.iterdir()] == [partial_path(path).name]  # checkpointed
    store = MapStore.open(partial_path(path))
    assert len(store) == 3 and store.has_poses
    np.testing.assert_array_equal(store.coefficients()[2], coefficients_of(2))
