# SPDX-License-Identifier: Apache-2.0
"""`skynav map build` and `skynav eval localization`: maps hold what the product uses; featureless drives are normal.

A map of skynav's own holds each snapshot's SH coefficients and pose, nothing else; the baselines' descriptors come
only with --baselines. Featureless drives (synthetic: the bundled garden drive's camera and poses with uniform,
noise-free images: all sky, all ground, an open field with a level horizon) build like any other, and a baseline
that cannot train on them says so in one line and is left out. A build stopped by Ctrl-C or SIGTERM, or killed,
keeps its partial map with every snapshot written so far, as `skynav map build --help` says.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from skynav_core.maps import MapError, MapStore, partial_path
from skynav_localize.eval import baselines  # noqa: F401  (registers the baselines' methods, bow-orb among them)
from skynav_localize.localizer import Localizer
from skynav_testing import one_line_error, run_skynav

pytestmark = pytest.mark.heavy(70)

BAGS = Path(__file__).resolve().parents[2] / 'bags'
BYTES_PER_SNAPSHOT = 4096  # the target: at most 4 kB per snapshot at L = 16 without the baselines
FRAMES = 20  # of a featureless recording: 2 m of the garden drive


def build(bag: Path, out: Path, *options: str):
    """Run `skynav map build` and return the finished process."""
    return run_skynav('map', 'build', str(bag), '--out', str(out), *options)


def tables_of(path: Path) -> set[str]:
    import sqlite3

    with sqlite3.connect(path) as db:
        names = {row[0] for row in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    db.close()
    return names


def test_a_map_holds_the_coefficients_in_at_most_4_kB_per_snapshot_and_the_baselines_only_on_request(tmp_path):
    teach = BAGS / 'synthetic_garden_teach.mcap'
    plain = build(teach, tmp_path / 'garden.db')
    assert plain.returncode == 0, plain.stderr
    store = MapStore.open(tmp_path / 'garden.db')
    assert len(store) >= 50 and store.max_degree == 16 and store.has_poses
    assert store.descriptor_names() == [] and tables_of(store.path) == {'meta', 'snapshots'}
    size = store.path.stat().st_size  # the finished map is one file: no WAL beside it
    assert not Path(f'{store.path}-wal').exists()
    assert size / len(store) <= BYTES_PER_SNAPSHOT, size / len(store)
    assert f'{size / len(store):.0f} bytes per snapshot' in plain.stderr
    assert Localizer(store, 'bispectrum-seq').index.matrix.shape == (len(store), 268)  # derived from coefficients
    with_baselines = build(teach, tmp_path / 'garden_baselines.db', '--baselines')
    assert with_baselines.returncode == 0, with_baselines.stderr
    assert 'left out' not in with_baselines.stderr
    full = MapStore.open(tmp_path / 'garden_baselines.db')
    assert len(full) == len(store) and full.descriptor_names() == ['bow-orb', 'orb', 'raw_uv']
    np.testing.assert_array_equal(full.coefficients(), store.coefficients())  # the same snapshots either way
    assert full.artifact('bow-orb.words') is not None
    assert full.path.stat().st_size > 10 * size


@pytest.mark.parametrize('kind', ['sky', 'ground', 'open-field'])  # conftest.FEATURELESS_KINDS
def test_a_featureless_drive_builds_a_map_with_and_without_the_baselines(kind, featureless_recording, tmp_path):
    bag = featureless_recording(kind, FRAMES)
    plain = build(bag, tmp_path / 'plain.db')
    assert plain.returncode == 0 and 'Traceback' not in plain.stderr, plain.stderr
    store = MapStore.open(tmp_path / 'plain.db')
    assert len(store) > 10 and store.descriptor_names() == [] and np.all(np.isfinite(store.coefficients()))
    with_baselines = build(bag, tmp_path / 'baselines.db', '--baselines')
    assert with_baselines.returncode == 0 and 'Traceback' not in with_baselines.stderr, with_baselines.stderr
    full = MapStore.open(tmp_path / 'baselines.db')
    assert len(full) == len(store) and 'raw_uv' in full.descriptor_names()
    left_out = [line for line in with_baselines.stderr.splitlines() if 'left out' in line]
    if 'orb' in full.descriptor_names():  # ORB found corners somewhere (a pixel-stepped horizon): it trained
        assert left_out == [] and full.artifact('bow-orb.words') is not None
        Localizer(full, 'bow-orb')
    else:
        assert left_out == [
            'skynav map build: bow-orb: no ORB features in the teach drive; its descriptors are left out'
        ]
        assert full.artifact('bow-orb.words') is None
        with pytest.raises(MapError, match='needs ORB descriptors .* --baselines'):
            Localizer(full, 'bow-orb')
    if kind != 'open-field':  # uniform images: nothing for ORB to find
        assert left_out
    # skynav's methods load it and match its own views; a view without a skyline is never accepted
    views = store.coefficients()
    for name in ('amplitude', 'amplitude-seq', 'bispectrum-seq'):
        matches = Localizer(store, name).match_sequence(views, field_of_view=np.radians(200))
        assert np.all(np.isfinite(matches.distance)) and np.all(np.isfinite(matches.score))
        if kind != 'open-field':
            assert not np.any(matches.accepted)


def test_eval_localization_leaves_out_the_baselines_a_map_does_not_hold(featureless_recording, tmp_path):
    bag = featureless_recording('open-field', FRAMES)
    assert build(bag, tmp_path / 'plain.db').returncode == 0
    assert build(bag, tmp_path / 'baselines.db', '--baselines').returncode == 0
    methods = ('--methods', 'amplitude-seq', 'seqslam-raw-uv')
    plain = run_skynav(
        'eval',
        'localization',
        str(bag),
        '--map',
        str(tmp_path / 'plain.db'),
        *methods,
        '--plots',
        str(tmp_path / 'plots'),
    )
    assert plain.returncode == 0, plain.stderr
    notes = [line for line in plain.stderr.splitlines() if 'left out' in line]
    assert notes == [
        f'skynav eval localization: {tmp_path / "plain.db"} holds no descriptors of seqslam-raw-uv: '
        'their rows are left out (build the map with `skynav map build --baselines`)'
    ]
    rows = [line.split()[0] for line in plain.stdout.splitlines() if line.strip()]
    assert 'amplitude-seq' in rows and 'seqslam-raw-uv' not in rows
    full = run_skynav(
        'eval',
        'localization',
        str(bag),
        '--map',
        str(tmp_path / 'baselines.db'),
        *methods,
        '--plots',
        str(tmp_path / 'plots'),
    )
    assert full.returncode == 0 and 'left out' not in full.stderr, full.stderr
    rows = [line.split()[0] for line in full.stdout.splitlines() if line.strip()]
    assert 'amplitude-seq' in rows and 'seqslam-raw-uv' in rows
    only_baselines = run_skynav(
        'eval',
        'localization',
        str(bag),
        '--map',
        str(tmp_path / 'plain.db'),
        '--methods',
        'raw-uv',
        '--plots',
        str(tmp_path / 'plots'),
    )
    assert only_baselines.returncode == 1 and one_line_error(only_baselines.stderr), only_baselines.stderr


# Runs `skynav map build` with every snapshot write announced on stdout and followed by a pause, so that a signal
# lands while the map is being written (the build itself is the real command). SIGINT gets Python's own handler:
# a test run started in the background of a shell inherits SIGINT ignored, and so would the build.
SLOW_BUILD = """
import signal, sys, time
signal.signal(signal.SIGINT, signal.default_int_handler)
from skynav_bringup.cli import main
from skynav_core import maps
write = maps.MapStore.add_snapshot
def announced(self, *args, **kwargs):
    index = write(self, *args, **kwargs)
    print(index, flush=True)
    time.sleep(0.2)
    return index
maps.MapStore.add_snapshot = announced
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM, signal.SIGKILL], ids=lambda s: s.name)
def test_a_stopped_or_killed_build_keeps_every_snapshot_written_so_far(signum, featureless_recording, tmp_path):
    (tmp_path / 'maps').mkdir()
    out = tmp_path / 'maps' / 'garden.db'
    build = subprocess.Popen(
        [
            sys.executable,
            '-c',
            SLOW_BUILD,
            'map',
            'build',
            str(featureless_recording('open-field', FRAMES)),
            '--out',
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    written = -1
    for line in build.stdout:
        written = int(line)
        if written >= 2:
            break
    build.send_signal(signum)
    rest, stderr = build.communicate(timeout=60)
    written = max([written, *(int(n) for n in rest.split())]) + 1  # printed once its transaction committed
    partial = partial_path(out)
    assert not out.exists() and partial.exists()  # never taken for a finished map
    if signum == signal.SIGKILL:
        assert build.returncode == -signal.SIGKILL
    else:  # stopped cleanly: one line says where the snapshots are, and the file is self-contained
        assert build.returncode == 130 and 'Traceback' not in stderr
        assert stderr.splitlines()[-1] == (
            f'skynav map build: error: stopped: the {written} snapshots written so far are kept in {partial}'
        )
        assert sorted(p.name for p in out.parent.iterdir()) == [partial.name]
    store = MapStore.open(partial)
    assert written <= len(store) <= written + 1  # at most the snapshot in flight at a kill -9 differs
    assert store.has_poses and np.all(np.isfinite(store.coefficients()))
    matches = Localizer(store, 'amplitude').match_sequence(store.coefficients(), field_of_view=np.radians(200))
    assert list(matches.index) == list(range(len(store)))  # usable: each snapshot finds itself
    info = run_skynav('map', 'info', str(partial))
    assert info.returncode == 0 and f'Snapshots:          {len(store)}' in info.stdout


def test_a_colour_cameras_recording_builds_a_map_with_its_geometry(tmp_path):
    """The bundled synthetic colour drive (JPEG frames, /camera/camera_info): every exposure goes through the skyline
    node's colour method and the SH node; the snapshots carry the drive's ground-truth poses, and --baselines reads
    its blue plane as the UV image."""
    out = tmp_path / 'colour.db'
    result = build(BAGS / 'synthetic_garden_colour_repeat.mcap', out, '--baselines')
    assert result.returncode == 0, result.stderr
    with MapStore.open(out) as store:
        assert 30 < len(store) <= 89 and store.has_poses
        assert 'raw_uv' in store.descriptor_names()
