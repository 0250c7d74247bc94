# SPDX-License-Identifier: Apache-2.0
"""What every evaluation command shares: the choice of methods, the checks of its arguments, its text tables.

Each stage keeps one registry of its methods, in the order its tables list them (localization:
skynav_localize.eval.baselines.EVALUATED_METHODS, compass: skynav_compass.eval.methods.METHODS, homing:
skynav_warping.eval.methods.METHODS, skyline: skynav_skyline.methods.METHODS). `skynav eval
localization|compass|homing` and `skynav skyline eval` take --methods, check their numbers and folders and print
their tables through the helpers here, so a method is offered, refused and listed alike everywhere. A refused
argument is a CliError: exit code 2 for a malformed command line, 1 for a file that cannot be used.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .cli import CliError


def unknown_methods(chosen: Iterable[str], known: Iterable[str]) -> str | None:
    """Return one line naming the chosen methods a stage's registry lacks (None when it has them all)."""
    known = list(known)
    if unknown := [name for name in chosen if name not in known]:
        return f'unknown method {", ".join(unknown)} (one of {", ".join(known)})'
    return None


def add_methods_argument(
    parser: argparse.ArgumentParser, known: Sequence[str], default: Sequence[str] | None = None
) -> None:
    """Add --methods: some of a stage's registry `known`, by default `default` (None: all of them)."""
    if default is None:
        default, text = known, f'default all: {", ".join(known)}'
    else:
        text = f'default {" ".join(default)}; one of {", ".join(known)}'
    parser.add_argument(
        '--methods', nargs='+', default=list(default), metavar='METHOD', help=f'methods to compare ({text})'
    )


def check_methods(chosen: Iterable[str], known: Iterable[str]) -> None:
    """Raise CliError (a malformed command line) naming every chosen method a stage's registry lacks."""
    if problem := unknown_methods(chosen, known):
        raise CliError(problem, exit_code=2)


def add_plots_argument(parser: argparse.ArgumentParser, default: str, what: str = 'the plots') -> None:
    """Add --plots: the folder the command saves `what` in (created when missing)."""
    parser.add_argument(
        '--plots', type=Path, default=Path(default), metavar='DIR', help=f'folder for {what} (default {default})'
    )


def plots_folder(path: Path) -> Path:
    """Create the folder for plots (with its parents) and return it; CliError if it cannot be made."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CliError(f'{path}: cannot create the folder for the plots ({exc.strerror or exc})') from None
    return path


def check_recordings(paths: Iterable[str | Path]) -> None:
    """Raise CliError unless every recording exists (before any of them is evaluated)."""
    for path in paths:
        if not Path(path).exists():
            raise CliError(f'{path}: no such recording')


def check_at_least(value: float, least: float, option: str) -> None:
    """Raise CliError (a malformed command line) if an option's value is below `least`."""
    if value < least:
        raise CliError(f'{option} must be at least {least:g}', exit_code=2)


def check_not_negative(value: float, option: str) -> None:
    """Raise CliError (a malformed command line) if an option's value is negative."""
    if value < 0:
        raise CliError(f'{option} must not be negative', exit_code=2)


def check_positive(value: float, option: str) -> None:
    """Raise CliError (a malformed command line) unless an option's value is more than 0."""
    if not value > 0:
        raise CliError(f'{option} must be more than 0', exit_code=2)


@dataclass(frozen=True)
class Column:
    """A column of a text table: its title, width in characters, the format of its numbers and its alignment."""

    title: str
    width: int
    number: str = ''  # format spec of numeric cells (e.g. '.2f'); text cells stand as they are
    align: str = '>'  # '>' right, '<' left

    def cell(self, value: Any) -> str:
        """Return a value as this column shows it, padded to the column's width."""
        text = value if isinstance(value, str) or not self.number else format(value, self.number)
        return f'{text:{self.align}{self.width}}'


def text_table(columns: Sequence[Column], rows: Iterable[Sequence[Any]], gap: str = ' ', rule: bool = True) -> str:
    """Return a text table: the column titles, a rule of dashes as long as them (if rule), one line per row.

    Columns are joined by `gap`; a row shorter than the columns ends early (e.g. a second header line).
    """

    def line(cells: Sequence[Any]) -> str:
        return gap.join(column.cell(value) for column, value in zip(columns, cells))

    header = line([column.title for column in columns])
    return '\n'.join([header, *(['-' * len(header)] if rule else []), *(line(row) for row in rows)])
