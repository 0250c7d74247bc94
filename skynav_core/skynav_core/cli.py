# SPDX-License-Identifier: Apache-2.0
"""What every `skynav` subcommand shares, whichever package adds it: its error, and the node graph's arguments.

A package adds a subcommand through a ``skynav.commands`` entry point (see skynav_bringup.cli); its ``run`` raises
CliError for a failure to report as one line.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import SkynavError
from .parameters import ParameterFileError, load_parameter_file

if TYPE_CHECKING:
    from .maps import MapStore


class CliError(SkynavError):
    """A failure to report as one line, with the exit code to return."""

    def __init__(self, message: str, exit_code: int = 1) -> None:
        super().__init__(message)
        self.exit_code = exit_code


def check_params_file(path: Path) -> None:
    """Raise CliError unless `path` is a readable ROS 2 parameter file."""
    try:
        load_parameter_file(path)
    except ParameterFileError as exc:
        raise CliError(str(exc)) from None


def graph_arguments(params: Path | None, map_path: Path | None) -> list[str]:
    """Return the --ros-args of the node graph: the user's parameter file over the nodes' defaults, and the map."""
    arguments = []
    if params is not None:
        check_params_file(params)
        arguments += ['--params-file', str(params)]
    if map_path is not None:
        arguments += ['-p', f'map:={map_path}']
    return arguments


def add_namespace(parser: argparse.ArgumentParser, what: str = 'the graph this command talks to') -> None:
    """Add --namespace NS (docs/interfaces.md, "On a robot") to a command."""
    parser.add_argument(
        '--namespace',
        metavar='NS',
        type=_namespace,
        default='',
        help=f'the namespace of {what} (e.g. robot1: /robot1/skyline/sh); default none',
    )


def _namespace(text: str) -> str:
    """Return a --namespace value as ROS writes it; argparse's error for one ROS cannot take."""
    from .namespaces import NamespaceError, check_namespace  # noqa: PLC0415 (yaml loads only when used)

    try:
        return check_namespace(text)
    except NamespaceError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def open_map(path: Path) -> MapStore:
    """Open a map file for a command; CliError with the map's problem in one line if it cannot be used."""
    from .maps import MapError, MapStore  # noqa: PLC0415 (numpy is not loaded while the `skynav` command builds its parser)

    try:
        return MapStore.open(path)
    except MapError as exc:
        raise CliError(str(exc)) from None


def add_skip_damaged(parser: argparse.ArgumentParser) -> None:
    """Add --skip-damaged to a command that reads bags (the `skynav` command applies it to every bag it opens)."""
    parser.add_argument(
        '--skip-damaged',
        action='store_true',
        help='read past damaged chunks of a bag, leaving out their messages (and saying how many); '
        'without it a damaged bag is refused',
    )
