# SPDX-License-Identifier: Apache-2.0
"""`skynav map build` and `skynav eval localization`: maps hold what the product uses; featureless drives are normal.

A map of skynav's own holds each snapshot's SH coefficients and pose, nothing else; the baselines' descriptors come
only with --baselines. Featureless drives (synthetic: the bundled garden drive's camera and poses with uniform,
noise-free images: all sky, all ground, an open field with a level horizon) build like any other, and a baseline
that cannot train on them says so in one line and is left out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from skynav_core.maps import MapError, MapStore
from skynav_core.testing import one_line_error, run_skynav
from skynav_localize.localizer import Localizer

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
