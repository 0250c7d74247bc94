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
    'skynav_route': {'skynav_msgs', 'skynav_core'},
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


def module_name(path: Path) -> str:
    """Return the dotted module name of a source file of a package folder (skynav_x/skynav_x/a/b.py -> skynav_x.a.b)."""
    parts = path.relative_to(path.parents[len(path.relative_to(ROOT).parts) - 2]).with_suffix('').parts
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def imported_modules(path: Path, name: str, known: set[str]) -> set[str]:
    """Return the skynav modules (of `known`) a module imports, at any depth, relative imports resolved."""
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    tree = ast.parse(path.read_text(), str(path))
    for block in ast.walk(tree):  # imports for type checkers only run no code: not part of a circle
        if isinstance(block, ast.If) and getattr(block.test, 'id', None) == 'TYPE_CHECKING':
            block.body = []
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package.split('.')[: len(package.split('.')) - node.level + 1] if node.level else []
            module = '.'.join([*base, *([node.module] if node.module else [])])
            targets = [module, *(f'{module}.{alias.name}' for alias in node.names)]
        else:
            continue
        found |= {t for t in targets if t in known and t != name}
    return found


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Return the strongly connected groups of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        for other in graph[module]:
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            group = []
            while True:
                other = stack.pop()
                group.append(other)
                if other == module:
                    break
            if len(group) > 1:
                cycles.append(sorted(group))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return cycles


def test_no_module_imports_itself_round_a_circle():
    # a package's __init__ re-exporting its modules is not a circle of their code: left out
    sources = {module_name(p): p for pkg in ALLOWED for p in (ROOT / pkg / pkg).rglob('*.py')}
    known = set(sources)
    graph = {
        name: {m for m in imported_modules(path, name, known) if not sources[m].name == '__init__.py'}
        for name, path in sources.items()
    }
    assert import_cycles(graph) == []


def test_the_circle_check_finds_a_circle():
    assert import_cycles({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}}) == [['a', 'b', 'c']]
    assert import_cycles({'a': {'b'}, 'b': set()}) == []
