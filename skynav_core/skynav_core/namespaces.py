# SPDX-License-Identifier: Apache-2.0
"""Namespaces and remapping: one graph per robot on a shared ROS domain (docs/interfaces.md, "On a robot").

The contract names topics and actions absolutely (/skyline/sh, /skynav/follow_route). The nodes use them relative
to their namespace (`relative`), so `-r __ns:=/NS` puts the whole graph under /NS and the names are the contract's
outside any namespace. A graph's clock and static transforms are its own too: /clock and /tf_static are remapped
into the namespace (a recording replayed there brings its own clock). /rosout and /parameter_events stay global,
as ROS keeps them. Node sections of a parameter file (`skyline:`) are made to match the node in any namespace
(`/**/skyline:`), as a plain node name matches only outside one. No rclpy.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import yaml

from .errors import SkynavError
from .names import CLOCK, TF_STATIC

#: Topics of the graph that ROS names absolutely but each namespaced graph has its own of.
GRAPH_GLOBALS = (CLOCK, TF_STATIC)
# A ROS name's tokens: letters, digits and underscores, not starting with a digit; separated by single slashes.
_TOKEN = r'[A-Za-z_][A-Za-z0-9_]*'
_NAMESPACE = re.compile(rf'^/?{_TOKEN}(/{_TOKEN})*/?$')
_TOPIC = re.compile(rf'^[~/]?{_TOKEN}(/{_TOKEN})*$')


class NamespaceError(SkynavError):
    """A namespace or remapping rule that ROS cannot take."""


def check_namespace(namespace: str | None) -> str:
    """Return a namespace as ROS writes it ('/robot1'; '' for none), or NamespaceError."""
    if not namespace or namespace == '/':
        return ''
    if not _NAMESPACE.match(namespace) or '//' in namespace:
        raise NamespaceError(
            f'{namespace!r} is not a ROS namespace (letters, digits and underscores, not starting with a digit, '
            "separated by '/')"
        )
    return '/' + namespace.strip('/')


def relative(name: str) -> str:
    """Return a contract name (/skyline/sh) relative to the node's namespace (skyline/sh)."""
    return name.lstrip('/')


def namespaced(name: str, namespace: str | None) -> str:
    """Return the absolute name of a contract name (or one relative to the namespace) in `namespace`."""
    return f'{check_namespace(namespace)}/{relative(name)}'


def without_namespace(name: str, namespace: str | None) -> str | None:
    """Return an absolute name under `namespace` as the contract names it (None if it lies outside)."""
    prefix = check_namespace(namespace)
    if not prefix:
        return name
    return name[len(prefix) :] if name.startswith(prefix + '/') else None


def check_remap(rule: str) -> str:
    """Return a FROM:=TO remapping rule of topic names, or NamespaceError."""
    source, sep, target = rule.partition(':=')
    if not sep or not _TOPIC.match(source) or not _TOPIC.match(target):
        raise NamespaceError(f'{rule!r} is not a remapping FROM:=TO of two topic names (e.g. /cmd_vel:=/base/cmd_vel)')
    return rule


def remap_arguments(namespace: str | None, remaps: Sequence[str] = ()) -> list[str]:
    """Return the --ros-args rules that put a graph in `namespace` (its clock and static transforms too) and apply
    the user's FROM:=TO rules to every node: FROM is a contract name (/cmd_vel, taken within the namespace), TO the
    robot's topic (absolute, or relative to the namespace)."""
    ns, arguments = check_namespace(namespace), []
    if ns:
        arguments += ['-r', f'__ns:={ns}']
        for name in GRAPH_GLOBALS:
            arguments += ['-r', f'{name}:={ns}{name}']
    for rule in remaps:
        source, _, target = check_remap(rule).partition(':=')
        arguments += ['-r', f'{relative(source)}:={target}']  # FROM within the namespace, as the nodes name it
    return arguments


def any_namespace_sections(content: dict) -> dict:
    """Return a parameter file's sections with each plain node name (skyline) matching it in any namespace."""
    return {key if key.startswith('/') else f'/**/{key}': value for key, value in content.items()}


def write_any_namespace_file(source: Path, target: Path) -> Path:
    """Write the parameter file `source` with its node sections matching in any namespace to `target`; return it."""
    from .parameters import load_parameter_file  # noqa: PLC0415 (its ParameterFileError reaches the caller)

    target.write_text(yaml.safe_dump(any_namespace_sections(load_parameter_file(source)), sort_keys=False))
    return target
