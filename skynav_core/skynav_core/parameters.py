# SPDX-License-Identifier: Apache-2.0
"""Node parameters defined once: a table per node that the node declares, the offline tools read and the shipped
parameter file is generated from.

A node's table maps each parameter name to its default and a one-line description. The node declares exactly
these (SkynavNode.declare_table), `skynav run` and the evaluations start the same node classes, and the shipped
`skynav_bringup/config/skynav.yaml` is `parameter_file(...)` of every installed node's table, so a default lives in
one place: its table.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import yaml

from .errors import SkynavError

ALL_NODES = '/**'  # a parameter file's section for every node


class Parameter(NamedTuple):
    """A node parameter's default and a one-line description of what it means (with its unit)."""

    default: Any
    description: str


ParameterTable = Mapping[str, Parameter]


class ParameterFileError(SkynavError):
    """A parameter file that cannot be read, or that is not in the ROS 2 format."""


def defaults(table: ParameterTable) -> dict[str, Any]:
    """Return the defaults of a parameter table by name."""
    return {name: parameter.default for name, parameter in table.items()}


def load_parameter_file(path: str | Path) -> dict[str, dict]:
    """Return a ROS 2 parameter file's sections ({node: {'ros__parameters': {...}}}); else ParameterFileError."""
    try:
        content = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise ParameterFileError(f'cannot read parameter file {path}: {exc.strerror}') from None
    except yaml.YAMLError as exc:
        raise ParameterFileError(f'parameter file {path} is not valid YAML: {str(exc).splitlines()[0]}') from None
    if content is None:
        return {}
    if not (
        isinstance(content, dict)
        and all(isinstance(v, dict) and isinstance(v.get('ros__parameters'), dict) for v in content.values())
    ):
        raise ParameterFileError(
            f'parameter file {path} is not in the ROS 2 format (node_name: {{ros__parameters: ...}})'
        )
    for section, entries in content.items():
        for name, value in entries['ros__parameters'].items():
            if isinstance(value, list) and len({_kind(item) for item in value}) > 1:
                raise ParameterFileError(
                    f'parameter file {path}: {section}: {name}: {value} mixes kinds of values, which ROS refuses '
                    '(write every number of a list alike, e.g. [0.0, 0.0, 90.0])'
                )
    return content


def _kind(value: Any) -> str:
    """Return the ROS parameter kind of a YAML value: bool, integer, double, string or other."""
    kinds = ((bool, 'bool'), (int, 'integer'), (float, 'double'), (str, 'string'))
    return next((kind for cls, kind in kinds if isinstance(value, cls)), 'other')


def read_parameter_file(path: str | Path, node: str, table: ParameterTable) -> dict[str, Any]:
    """Return the values a ROS 2 parameter file sets for `node` (its section over '/**'), only the table's names."""
    content = load_parameter_file(path)
    values: dict[str, Any] = {}
    for section in (ALL_NODES, node, f'/{node}'):
        entries = content.get(section, {}).get('ros__parameters', {})
        values.update({name: value for name, value in entries.items() if name in table})
    return values


def _literal(value: Any) -> str:
    """Return a parameter value as YAML, with the names ROS 2 reads for non-finite floats."""
    if isinstance(value, float) and not math.isfinite(value):
        return '.nan' if math.isnan(value) else ('.inf' if value > 0 else '-.inf')
    return yaml.safe_dump(value, default_flow_style=True, width=1000).strip().removesuffix('\n...').strip()


def parameter_file(tables: Mapping[str, ParameterTable], header: str = '') -> str:
    """Return a ROS 2 parameter file of every node's defaults, each parameter with its description as a comment."""
    lines = [f'# {line}'.rstrip() for line in header.splitlines()]
    for node, table in tables.items():
        if lines:
            lines.append('')
        lines += [f'{node}:', '  ros__parameters:']
        width = max((len(name) + len(_literal(p.default)) for name, p in table.items()), default=0)
        for name, parameter in table.items():
            text = f'{name}: {_literal(parameter.default)}'
            lines.append(f'    {text.ljust(width + 2)}  # {parameter.description}')
    return '\n'.join(lines) + '\n'


# Parameters every skynav node declares (SkynavNode), repeated in each node's section of the shipped parameter file.
COMMON_PARAMETERS: ParameterTable = {
    'max_stamp_jump_s': Parameter(
        1.0, "an input stamped over this before or after the last one taken restarts the node's time (s)"
    ),
    'camera_mount_rpy_deg': Parameter(
        [0.0, 0.0, 0.0],
        'camera_link turned against base_link: roll, pitch, yaw (deg, fixed axes X, Y, Z as REP-103); /tf_static '
        'wins when it gives base_link -> camera_link',
    ),
}
