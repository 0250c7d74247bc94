# SPDX-License-Identifier: Apache-2.0
"""Where the last follow goal on a map got to (skynav_core.route_progress) and `skynav follow --resume`, which
carries on from there."""

import argparse
from pathlib import Path

import numpy as np
import pytest
import yaml
from skynav_route.cli.follow import resume

from skynav_core.cli import CliError
from skynav_core.maps import Snapshot
from skynav_core.route_progress import ProgressError, RouteProgress, progress_path, read_progress, write_progress
from skynav_localize.mapping import build_map

SNAPSHOTS = 40


@pytest.fixture
def lawn_map(tmp_path) -> Path:
    path = tmp_path / 'lawn.db'
    rng = np.random.default_rng(3)
    snapshots = [Snapshot(k, 10**18 + k * 10**8, rng.normal(size=25)) for k in range(SNAPSHOTS)]
    build_map(path, 'lawn', 4, snapshots, created_from='test (synthetic)', overwrite=True).close()
    return path


def ended(map_path: Path, outcome: str, reached: int, start: int = 0, end: int = SNAPSHOTS - 1) -> RouteProgress:
    return RouteProgress(str(map_path), SNAPSHOTS, start, end, reached, outcome, 3.5, 1.8e9)


def resume_args(map_path: Path | None, start: int = -1, end: int = -1) -> argparse.Namespace:
    return argparse.Namespace(map=map_path, start=start, end=end)


def test_a_record_lies_beside_its_map_and_reads_back_as_written(lawn_map):
    progress = ended(lawn_map, 'LOST', 17)
    assert write_progress(progress) == progress_path(lawn_map) == lawn_map.with_name('lawn.db.progress.yaml')
    assert read_progress(lawn_map) == progress
    write_progress(ended(lawn_map, 'canceled', 25, start=17))  # the next goal's record replaces it
    assert read_progress(lawn_map).reached_index == 25
    assert [p.name for p in lawn_map.parent.iterdir() if p.name.endswith('.tmp')] == []  # nothing left beside it
    assert read_progress(lawn_map.with_name('other.db')) is None


def test_a_goal_resumes_from_its_last_snapshot_passed_else_where_it_started(lawn_map):
    assert ended(lawn_map, 'EMERGENCY_STOP', 12).resume_from() == 12
    assert ended(lawn_map, 'LOST', -1, start=5).resume_from() == 5  # never placed: where it was to start
    assert ended(lawn_map, 'reached', SNAPSHOTS - 1).finished and not ended(lawn_map, 'canceled', 3).finished


@pytest.mark.parametrize(
    'text, complaint',
    [
        ('{not yaml', 'not a YAML'),
        ('- a list', 'not a skynav route progress record'),
        ('format: 2', 'not a skynav route progress record'),
        ('format: 1\nmap_path: x', 'missing or malformed'),
        (None, 'do not fit'),  # a crafted reached_index beyond the map
    ],
)
def test_a_corrupt_or_crafted_record_is_refused_in_one_clear_line(lawn_map, text, complaint):
    if text is None:
        record = {'format': 1, **ended(lawn_map, 'LOST', 17).__dict__, 'reached_index': SNAPSHOTS + 5}
        text = yaml.safe_dump(record)
    progress_path(lawn_map).write_text(text)
    with pytest.raises(ProgressError, match=complaint):
        read_progress(lawn_map)


def test_a_record_that_cannot_be_written_says_where(tmp_path):
    gone = tmp_path / 'removed' / 'lawn.db'  # the map's folder went away (a card pulled out)
    with pytest.raises(ProgressError, match=r'removed/lawn.db.progress.yaml: cannot write'):
        write_progress(ended(gone, 'LOST', 3))


def test_resume_carries_on_from_the_last_goals_record(lawn_map, capsys):
    write_progress(ended(lawn_map, 'EMERGENCY_STOP', 21))
    assert resume(resume_args(lawn_map)) == (21, SNAPSHOTS - 1)
    assert 'ended EMERGENCY_STOP at snapshot 21' in capsys.readouterr().out
    assert resume(resume_args(lawn_map, end=30)) == (21, 30)  # a nearer end may be given


def test_resume_after_the_end_was_reached_drives_nothing(lawn_map, capsys):
    write_progress(ended(lawn_map, 'reached', SNAPSHOTS - 1))
    assert resume(resume_args(lawn_map)) is None
    assert 'nothing to resume' in capsys.readouterr().out


@pytest.mark.parametrize(
    'case, complaint',
    [
        ('no map', 'needs the map'),
        ('with --from', 'leave out --from'),
        ('no record', 'no follow goal on'),
        ('taught again', 'taught again since'),
    ],
)
def test_resume_refuses_what_it_cannot_carry_on_from(lawn_map, case, complaint):
    if case == 'taught again':
        write_progress(RouteProgress(str(lawn_map), SNAPSHOTS + 10, 0, SNAPSHOTS + 9, 30, 'LOST', 3.0, 1.8e9))
    args = resume_args(None if case == 'no map' else lawn_map, start=4 if case == 'with --from' else -1)
    with pytest.raises(CliError, match=complaint):
        resume(args)
