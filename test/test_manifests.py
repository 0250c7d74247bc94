# SPDX-License-Identifier: Apache-2.0
"""Every package.xml declares what its code imports, so that `rosdep install` and colcon on a ROS install bring
everything a package needs (docs/install.md).

The imports are read from the source (ast), in functions too, leaving out `if TYPE_CHECKING:` blocks; the code of
a package is its module folder (skynav_x/skynav_x) and its launch files, not its tests. A package's run
dependencies (depend, exec_depend, build_export_depend) must be:
- exactly the skynav packages its code imports; skynav_bringup also every package that provides a node through a
  `skynav.nodes` entry point (it launches them) and those in RUNS;
- a superset of the ROS packages its code imports;
- exactly the rosdep keys (ros/rosdistro rosdep/python.yaml) of the third-party libraries its code imports, as
  ROSDEP_KEYS maps them; a library without any key is named in an XML comment that says so (PIP_ONLY).
A package's tests may import ROS packages and libraries its code does not: those are declared too (test_depend
will do). skynav packages that only tests import are not required: test_depend edges between skynav packages
would make cycles that colcon refuses to order.
"""

from __future__ import annotations

import ast
import configparser
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from catkin_pkg.package import parse_package

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = sorted(path.parent.name for path in ROOT.glob('*/package.xml'))

#: ROS packages the code may import (each is declared by its own name).
ROS_PACKAGES = frozenset(
    {
        'action_msgs',
        'ament_index_python',
        'builtin_interfaces',
        'diagnostic_msgs',
        'geometry_msgs',
        'launch',
        'launch_ros',
        'nav_msgs',
        'rcl_interfaces',
        'rclpy',
        'rosgraph_msgs',
        'sensor_msgs',
        'std_msgs',
        'std_srvs',
        'tf2_msgs',
        'unique_identifier_msgs',
        'visualization_msgs',
    }
)
#: Third-party module -> its rosdep key, as rosdep/python.yaml of ros/rosdistro names it.
ROSDEP_KEYS = {
    'cv2': 'python3-opencv',
    'hypothesis': 'python3-hypothesis',
    'matplotlib': 'python3-matplotlib',
    'numpy': 'python3-numpy',
    'pytest': 'python3-pytest',
    'scipy': 'python3-scipy',
    'tqdm': 'python3-tqdm',
    'websockets': 'python3-websockets',
    'yaml': 'python3-yaml',
}
#: Third-party module -> its pip distribution, for libraries rosdep/python.yaml has no key for (neither a system
#: nor a -pip one): not declared, but named in a comment of the package.xml that says "no rosdep key".
PIP_ONLY = {
    'backports': 'backports.zstd',
    'foxglove': 'foxglove-sdk',
    'mcap': 'mcap',
    'mcap_ros2': 'mcap-ros2-support',
    'rosbags': 'rosbags',
}
#: skynav packages a package needs at run time without importing them, and why.
RUNS = {'skynav_bringup': {'skynav_sim': '`skynav demo` runs `skynav sim teach` and `skynav sim follow`'}}
NODE_ENTRY_POINTS = 'skynav.nodes'


@dataclass(frozen=True)
class Manifest:
    """What a package.xml declares."""

    name: str
    run: frozenset[str]  # depend, exec_depend, build_export_depend
    test: frozenset[str]  # test_depend
    comments: tuple[str, ...]  # the text of its XML comments


def read_manifest(path: Path) -> Manifest:
    """Parse a package.xml as colcon and rosdep do (catkin_pkg: format 3, no duplicate dependency)."""
    package = parse_package(str(path))
    run = {d.name for d in (*package.exec_depends, *package.build_export_depends)}
    comments = tuple(' '.join(c.split()) for c in re.findall(r'<!--(.*?)-->', path.read_text(), re.S))
    return Manifest(package.name, frozenset(run), frozenset(d.name for d in package.test_depends), comments)


def _type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == 'TYPE_CHECKING') or (
        isinstance(test, ast.Attribute) and test.attr == 'TYPE_CHECKING'
    )


class _Imports(ast.NodeVisitor):
    """The top-level modules a module imports absolutely, anywhere but under `if TYPE_CHECKING:`, first line each."""

    def __init__(self) -> None:
        self.found: dict[str, int] = {}

    def visit_If(self, node: ast.If) -> None:
        if _type_checking(node.test):
            for child in node.orelse:
                self.visit(child)
        else:
            self.generic_visit(node)

    def visit_Import(self, node: ast.Import) -> None:
        for alias in node.names:
            self.found.setdefault(alias.name.split('.')[0], node.lineno)

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        if node.level == 0 and node.module:
            self.found.setdefault(node.module.split('.')[0], node.lineno)


def imports(files: list[Path], root: Path) -> dict[str, str]:
    """Return the non-standard top-level modules the files import, each with where it is first imported."""
    found: dict[str, str] = {}
    for path in sorted(files):
        visitor = _Imports()
        visitor.visit(ast.parse(path.read_text(), str(path)))
        for module, line in visitor.found.items():
            if module not in sys.stdlib_module_names and module != '__future__':
                found.setdefault(module, f'{path.relative_to(root)}:{line}')
    return found


def code_files(root: Path, package: str) -> list[Path]:
    """A package's code: its module folder and its launch files."""
    return [*(root / package / package).rglob('*.py'), *(root / package / 'launch').glob('*.py')]


def node_packages(root: Path) -> dict[str, str]:
    """Return each package that provides a node through a `skynav.nodes` entry point (setup.cfg or setup.py),
    with its nodes' names."""
    found = {}
    for package_xml in sorted(root.glob('*/package.xml')):
        folder = package_xml.parent
        config = configparser.ConfigParser()
        config.read(folder / 'setup.cfg')
        lines = config.get('options.entry_points', NODE_ENTRY_POINTS, fallback='').split('\n')
        if (folder / 'setup.py').is_file():
            for call in ast.walk(ast.parse((folder / 'setup.py').read_text())):
                if isinstance(call, ast.Call):
                    for keyword in call.keywords:
                        if keyword.arg == 'entry_points':
                            lines += ast.literal_eval(keyword.value).get(NODE_ENTRY_POINTS, [])
        names = [line.partition('=')[0].strip() for line in lines if line.strip()]
        if names:
            found[folder.name] = ', '.join(names)
    return found


def says_no_key(comment: str, distribution: str) -> bool:
    """Whether an XML comment says that the pip distribution has no rosdep key."""
    named = re.search(rf'(?<![\w.-]){re.escape(distribution)}(?![\w-])', comment)
    return 'no rosdep key' in comment.lower() and named is not None


def check_package(root: Path, package: str) -> list[str]:
    """Return what the package.xml of `package` gets wrong against its code, one line each (empty: nothing)."""
    where = f'{package}/package.xml'
    manifest = read_manifest(root / package / 'package.xml')
    skynav = {path.parent.name for path in root.glob('*/package.xml')}
    problems = [] if manifest.name == package else [f'{where}: named {manifest.name}, not {package}']
    code = imports(code_files(root, package), root)
    tests = imports(list((root / package / 'test').rglob('*.py')), root)

    needed = {module: f'imported by {place}' for module, place in code.items() if module in skynav - {package}}
    if package == 'skynav_bringup':
        for provider, nodes in node_packages(root).items():
            needed.setdefault(provider, f'launched: it provides the node {nodes}')
    for runs, why in RUNS.get(package, {}).items():
        needed.setdefault(runs, f'run: {why}')
    declared = manifest.run & skynav
    problems += [f'{where}: misses skynav dependency {d} ({needed[d]})' for d in sorted(needed.keys() - declared)]
    problems += [
        f'{where}: declares {d}, which its code neither imports nor runs' for d in sorted(declared - needed.keys())
    ]

    for module, place in sorted(code.items()):
        if module in skynav:
            continue
        if module in ROS_PACKAGES and module not in manifest.run:
            problems.append(f'{where}: misses ROS dependency {module} (imported by {place})')
        elif module in ROSDEP_KEYS and ROSDEP_KEYS[module] not in manifest.run:
            problems.append(f'{where}: misses rosdep key {ROSDEP_KEYS[module]} for {module} (imported by {place})')
        elif module not in ROS_PACKAGES | ROSDEP_KEYS.keys() | PIP_ONLY.keys():
            problems.append(
                f'{where}: {place} imports {module}, which test_manifests.py does not know: add it to '
                'ROS_PACKAGES, ROSDEP_KEYS (its key in rosdep/python.yaml) or PIP_ONLY'
            )
    keys = {ROSDEP_KEYS[module] for module in code if module in ROSDEP_KEYS}
    problems += [
        f'{where}: declares {key}, which its code does not import'
        for key in sorted((manifest.run & set(ROSDEP_KEYS.values())) - keys)
    ]

    for module, place in sorted(tests.items()):
        key = ROSDEP_KEYS.get(module, module)
        if (module in ROS_PACKAGES or module in ROSDEP_KEYS) and key not in manifest.run | manifest.test:
            problems.append(f'{where}: misses test dependency {key} (imported by {place})')

    for module, place in sorted({**tests, **code}.items()):
        if module in PIP_ONLY and not any(says_no_key(comment, PIP_ONLY[module]) for comment in manifest.comments):
            problems.append(
                f'{where}: no comment says that {PIP_ONLY[module]} ({module}, imported by {place}) has no rosdep key'
            )
    return problems


def test_the_packages_are_found():
    assert {'skynav_core', 'skynav_msgs', 'skynav_bringup', 'skynav_route'} <= set(PACKAGES)
    assert len(PACKAGES) == 11


@pytest.mark.parametrize('package', PACKAGES)
def test_package_xml_declares_what_the_code_imports(package):
    problems = check_package(ROOT, package)
    assert not problems, '\n'.join(problems)


def test_bringup_declares_every_package_that_provides_a_node():
    providers = node_packages(ROOT)
    assert set(providers) >= {'skynav_skyline', 'skynav_sh', 'skynav_localize', 'skynav_compass', 'skynav_warping'}
    assert 'skyline' in providers['skynav_skyline']
    assert set(providers) <= read_manifest(ROOT / 'skynav_bringup' / 'package.xml').run


def test_every_rosdep_key_is_one_rosdistro_has():
    # Keys as rosdep/python.yaml of ros/rosdistro spells them: python3-<name>, the Debian/Ubuntu package's name.
    assert all(re.fullmatch(r'python3-[a-z0-9.-]+', key) for key in ROSDEP_KEYS.values())
    assert ROSDEP_KEYS.keys().isdisjoint(PIP_ONLY)


# The checker itself, on a made-up workspace: each mistake is caught and named.

PACKAGE_XML = """<?xml version="1.0"?>
<package format="3">
  <name>{name}</name>
  <version>0.1.0</version>
  <description>a package</description>
  <maintainer email="a@example.org">a</maintainer>
  <license>Apache-2.0</license>
{deps}
  <export><build_type>ament_python</build_type></export>
</package>
"""


def _package(root: Path, name: str, deps: list[str], code: str = '', comment: str = '', nodes: str = '') -> None:
    folder = root / name
    (folder / name).mkdir(parents=True)
    lines = [f'  <exec_depend>{d}</exec_depend>' for d in deps] + ([f'  <!-- {comment} -->'] if comment else [])
    (folder / 'package.xml').write_text(PACKAGE_XML.format(name=name, deps='\n'.join(lines)))
    (folder / name / '__init__.py').write_text(code)
    if nodes:
        (folder / 'setup.cfg').write_text(f'[options.entry_points]\n{NODE_ENTRY_POINTS} =\n    {nodes}\n')


def test_the_check_names_a_missing_and_an_extra_skynav_dependency_and_counts_lazy_imports(tmp_path):
    _package(tmp_path, 'skynav_core', [])
    _package(tmp_path, 'skynav_sh', [])
    code = 'def f():\n    from skynav_core.recording.bag import open_bag\n'
    _package(tmp_path, 'skynav_skyline', ['skynav_sh', 'rclpy'], code)
    assert check_package(tmp_path, 'skynav_skyline') == [
        'skynav_skyline/package.xml: misses skynav dependency skynav_core '
        '(imported by skynav_skyline/skynav_skyline/__init__.py:2)',
        'skynav_skyline/package.xml: declares skynav_sh, which its code neither imports nor runs',
    ]


def test_the_check_leaves_out_type_checking_imports_and_names_missing_ros_and_library_keys(tmp_path):
    code = (
        'from typing import TYPE_CHECKING\nimport numpy\nimport sensor_msgs.msg\n'
        'if TYPE_CHECKING:\n    import cv2\nelse:\n    import yaml\n'
    )
    _package(tmp_path, 'skynav_x', ['python3-scipy'], code)
    assert check_package(tmp_path, 'skynav_x') == [
        'skynav_x/package.xml: misses rosdep key python3-numpy for numpy (imported by skynav_x/skynav_x/__init__.py:2)',
        'skynav_x/package.xml: misses ROS dependency sensor_msgs (imported by skynav_x/skynav_x/__init__.py:3)',
        'skynav_x/package.xml: misses rosdep key python3-yaml for yaml (imported by skynav_x/skynav_x/__init__.py:7)',
        'skynav_x/package.xml: declares python3-scipy, which its code does not import',
    ]


def test_the_check_wants_a_comment_for_a_library_without_key_and_knows_no_unknown_module(tmp_path):
    _package(tmp_path, 'skynav_a', [], 'import rosbags\nimport somelib\n')
    _package(tmp_path, 'skynav_b', [], 'import rosbags\n', comment='No rosdep key exists for rosbags: pip')
    problems = check_package(tmp_path, 'skynav_a')
    assert len(problems) == 2
    assert 'imports somelib, which test_manifests.py does not know' in problems[0]
    assert problems[1].startswith('skynav_a/package.xml: no comment says that rosbags (rosbags, imported by')
    assert check_package(tmp_path, 'skynav_b') == []


def test_the_check_wants_bringup_to_declare_the_node_packages(tmp_path):
    _package(tmp_path, 'skynav_y', [], nodes='y = skynav_y.node:YNode')
    _package(tmp_path, 'skynav_sim', [])
    _package(tmp_path, 'skynav_bringup', ['skynav_sim'])
    assert check_package(tmp_path, 'skynav_bringup') == [
        'skynav_bringup/package.xml: misses skynav dependency skynav_y (launched: it provides the node y)'
    ]
