# SPDX-License-Identifier: Apache-2.0
"""The `skynav` command.

Every subcommand is a module found through the ``skynav.commands`` entry
points, so each package adds its own (``skynav sim``, ``skynav eval compass``,
...). The entry point's name is the command path with dots (``eval.compass``);
its module defines

- ``HELP``: one line for the command list,
- ``configure(parser)``: adds the arguments,
- ``run(args) -> int``: does the work and returns the exit code.

Modules import only argparse-level things at import time; heavy imports live
inside ``run``. Only the command being run is configured (some list choices
that take a while to import), so a command starts as fast as its own needs.
Exit codes: 0 success, 1 the work failed (a missing or corrupt file, an
unknown topic or type), 2 a malformed command line.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from importlib.metadata import entry_points

from skynav_core.cli import CliError
from skynav_core.process.environment import apply_ros_environment

COMMAND_GROUP = 'skynav.commands'
__all__ = ['CliError', 'build_parser', 'main']


def _subparsers(parser: argparse.ArgumentParser, path: str) -> argparse._SubParsersAction:
    """Return the subcommand table of `parser`, creating it on first use."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action
    return parser.add_subparsers(title='commands', metavar='COMMAND', dest=f'command_{path or "root"}')


def _chosen_command(argv: Sequence[str], names: set[str]) -> str:
    """Return the command path (dots) that the leading words of `argv` name ('' for none)."""
    path = ''
    for word in argv:
        candidate = f'{path}.{word}' if path else word
        if word.startswith('-') or not any(n == candidate or n.startswith(candidate + '.') for n in names):
            break
        path = candidate
    return path


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """Return the parser of `skynav` with every installed subcommand; given the command line `argv`, only the
    command it names gets its arguments (the others are listed)."""
    parser = argparse.ArgumentParser(
        prog='skynav',
        description='Insect-inspired visual navigation from an upward-looking UV/green fish-eye camera.',
    )
    parser.set_defaults(parser=parser)
    groups: dict[str, argparse.ArgumentParser] = {'': parser}

    def group(path: str, help: str | None = None, description: str | None = None) -> argparse.ArgumentParser:
        """Return the parser of a command group, creating it (and its parents) on first use."""
        if path not in groups:
            parent, _, name = path.rpartition('.')
            sub = _subparsers(group(parent), parent).add_parser(
                name, help=help or f'{name} commands', description=description
            )
            sub.set_defaults(parser=sub)
            groups[path] = sub
        return groups[path]

    # A package found twice on the path (an overlay workspace over an underlay, a build beside the source) lists its
    # commands twice: the first on the path wins, as its modules do.
    unique = {ep.name: ep for ep in reversed(list(entry_points(group=COMMAND_GROUP)))}
    commands = sorted(unique.values(), key=lambda ep: ep.name)
    chosen = None if argv is None else _chosen_command(argv, {ep.name for ep in commands})
    # Sorted, a group's own module ('eval') comes before its commands ('eval.compass').
    for ep in commands:
        try:
            module = ep.load()
        except Exception as exc:  # a broken plug-in must not take the other commands down
            print(f'skynav: warning: command {ep.name.replace(".", " ")} unavailable: {exc}', file=sys.stderr)
            continue
        if not hasattr(module, 'run'):  # a module that only describes a command group
            group(ep.name, help=module.HELP, description=module.__doc__)
            continue
        parent, _, name = ep.name.rpartition('.')
        sub = _subparsers(group(parent), parent).add_parser(
            name,
            help=module.HELP,
            description=module.__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        if chosen is None or ep.name == chosen:
            module.configure(sub)
        sub.set_defaults(run=module.run, parser=sub, command=ep.name.replace('.', ' '))
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run `skynav` with `argv` (default: the process arguments) and return its exit code."""
    apply_ros_environment()
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    if not hasattr(args, 'run'):
        args.parser.print_help(sys.stderr)
        return 2
    from skynav_core.errors import SkynavError
    from skynav_core.recording.bag import set_skip_damaged  # loaded after the parser: `skynav --help` stays light

    set_skip_damaged(getattr(args, 'skip_damaged', False))  # for this command only (tests call main repeatedly)
    try:
        return args.run(args) or 0
    except CliError as exc:
        print(f'skynav {args.command}: error: {exc}', file=sys.stderr)
        return exc.exit_code
    except SkynavError as exc:  # a damaged file, an unknown type, a bad map: one line
        print(f'skynav {args.command}: error: {exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # `skynav echo ... | head`: the reader left, which is fine
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    finally:
        set_skip_damaged(False)


def entry() -> None:
    """Console-script entry point."""
    sys.exit(main())
