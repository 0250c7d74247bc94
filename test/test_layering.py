# SPDX-License-Identifier: Apache-2.0
"""Every package imports only along the edges of docs/architecture.md: nothing upward, nothing sideways."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: package -> the skynav packages its code may import (docs/architecture.md, "The edges, exactly").
ALLOWED = {
    'skynav_core': {'skynav_msgs'},
    'skynav_sh': {'skynav_msgs', 'skynav_core'},
    'skynav_skyline': {'skynav_msgs', 'skynav_core'},
    'skynav_localize': {'skynav_msgs', 'skynav_core', 'skynav_sh'},
    'skynav_compass': {'skynav_msgs', 'skynav_core', 'skynav_sh'},
    'skynav_warping': {'skynav_msgs', 'skynav_core', 'skynav_sh', 'skynav_compass'},
    'skynav_sim': {'skynav_msgs', 'skynav_core', 'skynav_localize'},
    'skynav_route': {'skynav_msgs', 'skynav_core', 'skynav_sh', 'skynav_localize', 'skynav_compass', 'skynav_warping'},
    'skynav_viz': {'skynav_msgs', 'skynav_core'},
    'skynav_bringup': {
        'skynav_msgs',
        'skynav_core',
        'skynav_sh',
        'skynav_skyline',
        'skynav_localize',
        'skynav_compass',
        'skynav_warping',
        'skynav_sim',
        'skynav_route',
        'skynav_viz',
    },
}


def imported_packages(path: Path) -> set[tuple[str, int]]:
    """Return the skynav packages a module imports (at any depth, in functions too), with the line of each."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        found |= {(name.split('.')[0], node.lineno) for name in names if name.startswith('skynav_')}
    return found


def test_the_diagram_of_the_docs_is_the_table_here():
    text = (ROOT / 'docs' / 'architecture.md').read_text()
    for package, allowed in ALLOWED.items():
        row = re.search(rf'^\| `{package}` \| (.*) \|$', text, re.M)
        assert row is not None, package
        listed = set(re.findall(r'`(skynav_\w+)`', row.group(1))) or set()
        assert listed | {'skynav_msgs'} == allowed | {'skynav_msgs'} or row.group(1) == 'every package', package


@pytest.mark.parametrize('package', sorted(ALLOWED))
def test_a_package_imports_only_along_the_documented_edges(package):
    code = ROOT / package / package
    assert code.is_dir()
    breaks = sorted(
        f'{path.relative_to(ROOT)}:{line} imports {target}'
        for path in code.rglob('*.py')
        for target, line in imported_packages(path)
        if target != package and target not in ALLOWED[package]
    )
    assert breaks == []


def test_the_layering_check_finds_an_upward_import(tmp_path):
    module = tmp_path / 'module.py'
    module.write_text('def f():\n    from skynav_bringup.cli import main\n    import skynav_sim.world\n')
    assert imported_packages(module) == {('skynav_bringup', 2), ('skynav_sim', 3)}
