# SPDX-License-Identifier: Apache-2.0
"""Regenerate the figures of docs/results.md that the bundled recordings measure, from the commands' own output.

    .venv/bin/python tools/results.py [--only NAME ...] [--page FILE]
    .venv/bin/python tools/results.py --check [--page FILE]

A block of the page between `<!-- results: NAME -->` and `<!-- /results -->` holds one evaluation: the commands
that measure it (as a newcomer types them in the repository's root), the commit and the kind of data, and what
the last command printed. The script runs each evaluation in a scratch folder (the maps it needs built there)
and writes its block anew, so the figure, its command and its commit cannot drift apart. A block's commit names
uncommitted changes when the tree had any. The longer evaluations (closed loops, the landscapes) keep their
hand-written tables, each with its command and commit.

--check runs nothing: it checks that the page's blocks and this script name the same evaluations, with the same
commands (what the tests check).
"""

from __future__ import annotations

import argparse
import re
import shlex
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / 'docs' / 'results.md'
SKYNAV = Path(sys.executable).with_name('skynav')
BLOCK = re.compile(r'<!-- results: (?P<name>[\w-]+) -->\n(?P<body>.*?)<!-- /results -->', re.S)
OUT = '{out}'  # in a command: the scratch folder (shown as the current folder)


@dataclass(frozen=True)
class Evaluation:
    """One block: the commands (the last one's output is shown) and the kind of data."""

    commands: tuple[str, ...]  # as typed in the repository's root; {out}: the scratch folder
    data: str = 'synthetic'
    # the last command's output lines kept: a line naming a file in the scratch folder (a plot) is not a figure
    drop: str = r'^(plots?:|skynav [\w ]+: saved)'


def localization(drive: str, repeat: str) -> Evaluation:
    """Return the evaluation of place recognition over a bundled drive against its teach drive's map."""
    return Evaluation(
        (
            f'skynav map build bags/synthetic_{drive}_teach.mcap --baselines --out {OUT}/{drive}.db',
            f'skynav eval localization bags/synthetic_{repeat}.mcap --map {OUT}/{drive}.db --plots {OUT}/plots',
        )
    )


SKYLINE_SETS = ' '.join(f'bags/synthetic_{world}_skyline.mcap' for world in ('garden', 'park', 'mineral'))
EVALUATIONS = {
    'skyline': Evaluation((f'skynav skyline eval {SKYLINE_SETS} --methods sector-min-error --plot {OUT}/skyline.png',)),
    'localization-garden': localization('garden', 'garden_repeat'),
    'localization-mineral': localization('mineral', 'mineral_repeat'),
    'localization-detour': localization('garden', 'garden_detour'),
    'compass-garden': Evaluation((f'skynav eval compass bags/synthetic_garden_compass.mcap --plots {OUT}/plots',)),
    'compass-mineral': Evaluation((f'skynav eval compass bags/synthetic_mineral_compass.mcap --plots {OUT}/plots',)),
    'homing-level': Evaluation((f'skynav eval homing bags/synthetic_park_homing.mcap --plots {OUT}/plots',)),
    'homing-bumpy': Evaluation((f'skynav eval homing bags/synthetic_park_bumpy_homing.mcap --plots {OUT}/plots',)),
    'bench': Evaluation(('skynav bench',)),
}


def shown(command: str) -> str:
    """Return a command as the page shows it: run from the repository's root, the scratch folder as '.'."""
    return command.replace(f'{OUT}/', '')


def commands_shown(evaluation: Evaluation) -> str:
    """Return the block's opening: its commands as the page shows them, in a shell code block."""
    return '```sh\n' + '\n'.join(shown(command) for command in evaluation.commands) + '\n```'


def commit() -> str:
    """Return the short commit of the tree, with ' and uncommitted changes' when it has any besides the page."""
    head = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=ROOT, capture_output=True, text=True).stdout
    # the page itself, being written, is no change to what measured it
    dirty = subprocess.run(
        ['git', 'status', '--porcelain', '--untracked-files=no', '--', '.', ':!docs/results.md'],
        cwd=ROOT,
        capture_output=True,
    )
    return head.strip() + (' and uncommitted changes' if dirty.stdout.strip() else '')


def run(name: str, evaluation: Evaluation, at: str) -> str:
    """Run one evaluation in a scratch folder; return its block's body."""
    with tempfile.TemporaryDirectory(prefix='skynav-results-') as folder:
        for command in evaluation.commands:
            argv = [str(SKYNAV), *shlex.split(command.replace(OUT, folder))[1:]]
            done = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True)
            if done.returncode != 0:
                raise SystemExit(f'results: {name}: `{shown(command)}` failed:\n{done.stderr.strip()}')
        lines = [line.rstrip() for line in done.stdout.replace(folder + '/', '').splitlines()]
    kept = '\n'.join(line for line in lines if not re.match(evaluation.drop, line)).strip('\n')
    origin = f'At {at}, {evaluation.data} data (`tools/results.py --only {name}`):'
    return f'{commands_shown(evaluation)}\n\n{origin}\n\n```text\n{kept}\n```\n'


def with_block(page: str, name: str, body: str) -> str:
    """Return the page with the body of block `name` replaced."""
    match = next(m for m in BLOCK.finditer(page) if m['name'] == name)
    return page[: match.start('body')] + body + page[match.end('body') :]


def check(page: str) -> tuple[list[str], list[str]]:
    """Return what is wrong between the page's blocks and the evaluations: blocks missing or unknown, and blocks
    that do not show the commands that measure them (which regenerating mends); empty lists: nothing."""
    blocks = {m['name']: m['body'] for m in BLOCK.finditer(page)}
    missing = [
        f'the page has a block {name!r} that tools/results.py does not measure'
        for name in sorted(set(blocks) - set(EVALUATIONS))
    ]
    missing += [f'the page has no block for {name!r}' for name in EVALUATIONS if name not in blocks]
    stale = [
        f'block {name!r} does not show the commands that measure it'
        for name, evaluation in EVALUATIONS.items()
        if name in blocks and not blocks[name].startswith(commands_shown(evaluation))
    ]
    return missing, stale


def main(argv: list[str] | None = None) -> int:
    """Regenerate (or check) the page's blocks; return an exit code."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--only', nargs='+', choices=sorted(EVALUATIONS), help='regenerate only these blocks')
    parser.add_argument('--check', action='store_true', help='check the page against the evaluations; run nothing')
    parser.add_argument('--page', type=Path, default=PAGE, help='the page (default docs/results.md)')
    args = parser.parse_args(argv)
    page = args.page.read_text()
    missing, stale = check(page)
    if args.check:
        problems = missing + stale
        print('\n'.join(f'results: {p}' for p in problems) or f'results: {args.page} agrees with tools/results.py')
        return 1 if problems else 0
    if missing:
        print('\n'.join(f'results: {p}' for p in missing))
        return 1
    at = commit()
    names = args.only or list(EVALUATIONS)
    for k, name in enumerate(names, 1):
        print(f'[{k}/{len(names)}] {name}: {"; ".join(shown(c) for c in EVALUATIONS[name].commands)}', flush=True)
        page = with_block(page, name, run(name, EVALUATIONS[name], at))
    args.page.write_text(page)
    print(f'results: wrote {len(names)} blocks of {args.page}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
