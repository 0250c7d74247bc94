# SPDX-License-Identifier: Apache-2.0
"""Where the last FollowRoute goal on a map got to, stored beside the map so that a later goal resumes from there.

The route node writes the record when a follow goal ends, however it ends (reached, canceled, LOST, emergency
stop, ...): `<map>.progress.yaml` next to `<map>` (docs/interfaces.md, "Resuming a route"). `skynav follow MAP
--resume` reads it and starts the next goal at its `reached_index`, so the lanes a mower has cut are not cut again.
The file is replaced atomically (written beside, flushed to disk, renamed over): a kill -9 leaves the previous record
or the new one, never half of one. Plain Python and YAML, no rclpy.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import yaml

from skynav_core.errors import SkynavError

SUFFIX = '.progress.yaml'
FORMAT = 1  # the record's layout version


class ProgressError(SkynavError):
    """A progress record that cannot be read or written."""


@dataclass(frozen=True)
class RouteProgress:
    """How one follow goal on a map ended: its snapshots (start -1: placed by localization), the last one passed
    (-1: none), the outcome ('reached', 'canceled' or an error code's name), metres driven and when (Unix s)."""

    map_path: str
    snapshots: int  # the map's snapshot count when the goal ran (a map taught again since has other indices)
    start_index: int
    end_index: int
    reached_index: int
    outcome: str
    driven_length: float
    ended_at: float

    @property
    def finished(self) -> bool:
        """Return whether the goal reached its end: nothing is left to resume."""
        return self.outcome == 'reached'

    def resume_from(self) -> int:
        """Return the start_index of the goal that carries on: the last snapshot passed, else where it started."""
        return self.reached_index if self.reached_index >= 0 else self.start_index


def progress_path(map_path: str | os.PathLike) -> Path:
    """Return where the progress record of a map lies: beside it, `<map>.progress.yaml`."""
    path = Path(map_path)
    return path.with_name(path.name + SUFFIX)


def write_progress(progress: RouteProgress) -> Path:
    """Store a goal's progress beside its map, replacing the last record atomically; return the file's path."""
    target = progress_path(progress.map_path)
    record = {'format': FORMAT, **asdict(progress)}
    try:
        with tempfile.NamedTemporaryFile('w', dir=target.parent, prefix=target.name, suffix='.tmp', delete=False) as f:
            yaml.safe_dump(record, f, sort_keys=False)
            f.flush()
            os.fsync(f.fileno())
        os.replace(f.name, target)
    except OSError as exc:
        raise ProgressError(f'{target}: cannot write the route progress ({exc.strerror or exc})') from None
    return target


def read_progress(map_path: str | os.PathLike) -> RouteProgress | None:
    """Return the progress record beside a map, None if there is none; ProgressError for one that is unusable."""
    source = progress_path(map_path)
    try:
        text = source.read_text()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise ProgressError(f'{source}: cannot read the route progress ({exc.strerror or exc})') from None
    try:
        record = yaml.safe_load(text)
    except yaml.YAMLError:
        raise ProgressError(f'{source}: not a YAML progress record') from None
    if not isinstance(record, dict) or record.get('format') != FORMAT:
        raise ProgressError(f'{source}: not a skynav route progress record (format {FORMAT})')
    try:
        progress = RouteProgress(
            map_path=str(record['map_path']),
            snapshots=_integer(record['snapshots']),
            start_index=_integer(record['start_index']),
            end_index=_integer(record['end_index']),
            reached_index=_integer(record['reached_index']),
            outcome=str(record['outcome']),
            driven_length=float(record['driven_length']),
            ended_at=float(record['ended_at']),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ProgressError(f'{source}: a field is missing or malformed ({exc})') from None
    if not (-1 <= progress.reached_index <= progress.end_index < progress.snapshots and progress.start_index >= -1):
        raise ProgressError(f'{source}: its snapshot indices do not fit a map of {progress.snapshots} snapshots')
    if not (math.isfinite(progress.driven_length) and math.isfinite(progress.ended_at)):
        raise ProgressError(f'{source}: driven_length and ended_at must be finite')
    return progress


def _integer(value: object) -> int:
    """Return a whole number of a record (bool and fractions are malformed)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f'{value!r} is not a whole number')
    return value


def now() -> float:
    """Return the wall time (Unix s) a record is stamped with."""
    return time.time()
