#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""How much of each stage package no node loads: the product apart from the lab (issue 31).

Each stage's node module is imported in a fresh interpreter, and the skynav modules that import loaded are its
import closure. A module that no node's closure holds, outside `cli/` (the commands) and `eval/` (evaluation,
baselines, peer methods), is code no robot runs: lab code in a product package. Prints one row per package and
the total share. Run from the repository root: `.venv/bin/python tools/node_closure.py`.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The packages whose node a robot runs, and the module that holds it.
STAGES = (
    'skynav_sh',
    'skynav_skyline',
    'skynav_localize',
    'skynav_compass',
    'skynav_warping',
    'skynav_route',
    'skynav_viz',
)
APART = ('cli', 'eval')  # subpackages that are meant to stay out of a node's closure


def loaded_by_node(package: str) -> set[str]:
    """Return the skynav modules that importing `package`'s node loads (a fresh interpreter)."""
    code = (
        f'import json, sys, {package}.node; '
        'print(json.dumps(sorted(m for m in sys.modules if m.startswith("skynav_"))))'
    )
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True, cwd=ROOT)
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


def modules(package: str) -> dict[str, Path]:
    """Return the package's modules (dotted name -> file), outside the APART subpackages."""
    folder = ROOT / package / package
    found = {}
    for path in folder.rglob('*.py'):
        parts = path.relative_to(folder).with_suffix('').parts
        if parts[0] in APART:
            continue
        name = '.'.join([package, *(parts[:-1] if parts[-1] == '__init__' else parts)])
        found[name] = path
    return found


def lines(path: Path) -> int:
    """Return the count of non-blank source lines of a file."""
    return sum(1 for line in path.read_text().splitlines() if line.strip())


def main() -> int:
    """Print the table; return 0."""
    total = unloaded_total = 0
    closure = set().union(*(loaded_by_node(package) for package in STAGES))
    print(f'{"package":18} {"lines":>6} {"not loaded":>10} {"share":>6}  modules no node loads')
    for package in STAGES:
        sources = modules(package)
        unloaded = {name: path for name, path in sources.items() if name not in closure}
        count = sum(lines(p) for p in sources.values())
        left = sum(lines(p) for p in unloaded.values())
        total, unloaded_total = total + count, unloaded_total + left
        names = ', '.join(sorted(n.rpartition('.')[2] for n in unloaded))
        print(f'{package:18} {count:6d} {left:10d} {100 * left / max(count, 1):5.1f}%  {names}')
    print(f'{"all":18} {total:6d} {unloaded_total:10d} {100 * unloaded_total / max(total, 1):5.1f}%')
    return 0


if __name__ == '__main__':
    sys.exit(main())
