# SPDX-License-Identifier: Apache-2.0
"""What `ros2 launch skynav_bringup skynav.launch.py` starts: each node's executable, namespace, remappings and
parameters, from the launch file's arguments (docs/install.md, "The colcon way").

The launch file (launch/skynav.launch.py) declares the arguments and turns each NodeLaunch into a launch_ros Node;
the rest is here, without the ROS 2 launch tools, so it runs and is tested where they are missing. The graph is
the one `skynav launch` starts: every installed node (`skynav.nodes` entry points) that has an executable, with the
shipped parameter file and the user's over it, the map for the nodes whose parameter table has `map`, the camera
for those whose table has `camera`, and in a namespace its /clock and /tf_static too (skynav_core.namespaces).
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from skynav_core.camera_input import CAMERA_SETTINGS
from skynav_core.errors import SkynavError
from skynav_core.graph import node_class
from skynav_core.namespaces import check_namespace, remap_arguments, write_any_namespace_file
from skynav_core.nodes import NodeSpec, installed_nodes
from skynav_core.parameters import load_parameter_file
from skynav_core.process.environment import share_directory

#: Values of the launch argument `camera`; '' leaves it to the parameter files (the shipped one says auto).
CAMERA_CHOICES = ('', *CAMERA_SETTINGS)
#: Values of the launch argument `use_sim_time`; '' leaves it to the parameter files (false unless one sets it).
SIM_TIME_CHOICES = ('', 'true', 'false')


class LaunchArgumentError(SkynavError):
    """A launch argument, or an installed node, the graph cannot start with."""


@dataclass(frozen=True)
class NodeLaunch:
    """One node as the launch file starts it."""

    name: str  # its name in the graph, e.g. 'skyline'
    package: str  # the ROS package that provides it
    executable: Path  # its console script
    namespace: str  # '/NS', or '' for none
    parameters: list[str | dict[str, Any]]  # parameter files in order, then the values the arguments set
    remappings: list[tuple[str, str]]  # (from, to)


def graph_launch(
    namespace: str = '',
    map_path: str = '',
    params_file: str = '',
    use_sim_time: str = '',
    camera: str = '',
    *,
    specs: Sequence[NodeSpec] | None = None,
    scratch: Path | None = None,
) -> list[NodeLaunch]:
    """Return the nodes the launch arguments start (each '' when not given), in data-flow order.

    A namespaced graph's parameter files are rewritten so that their node sections match in the namespace; the
    copies go to `scratch` (a new temporary folder by default, left behind as launch_ros leaves its own).
    Raises a SkynavError naming the argument that cannot be used.
    """
    ns = check_namespace(namespace)
    if camera not in CAMERA_CHOICES:
        raise LaunchArgumentError(f'camera:={camera} is none of {", ".join(CAMERA_CHOICES[1:])}')
    if use_sim_time not in SIM_TIME_CHOICES:
        raise LaunchArgumentError(f'use_sim_time:={use_sim_time} is neither true nor false')
    files = parameter_files(params_file)
    if ns and files:
        folder = scratch if scratch is not None else Path(tempfile.mkdtemp(prefix='skynav_launch_'))
        files = [write_any_namespace_file(path, folder / f'{i}_{path.name}') for i, path in enumerate(files)]
    map_file = None
    if map_path:
        map_file = Path(map_path).expanduser().resolve()
        if not map_file.is_file():
            raise LaunchArgumentError(f'map:={map_path}: no such map file')
    node_namespace, remappings = split_remap_arguments(remap_arguments(ns))
    launches = []
    for spec in installed_nodes() if specs is None else specs:
        if spec.executable is None:
            continue
        table = node_class(spec).PARAMETERS
        values: dict[str, Any] = {}
        if use_sim_time:
            values['use_sim_time'] = use_sim_time == 'true'
        if map_file is not None and 'map' in table:
            values['map'] = str(map_file)
        if camera and 'camera' in table:
            values['camera'] = camera
        launches.append(
            NodeLaunch(
                name=spec.name,
                package=spec.package,
                executable=node_executable(spec.package, spec.executable),
                namespace=node_namespace,
                parameters=[*(str(path) for path in files), *([values] if values else [])],
                remappings=remappings,
            )
        )
    return launches


def parameter_files(params_file: str = '') -> list[Path]:
    """Return the parameter files every node reads: the shipped one (if installed), then the user's."""
    from .parameters import default_params_file  # noqa: PLC0415 (where the shipped file lives: one place)

    shipped = default_params_file()
    files = [shipped] if shipped is not None else []
    if params_file:
        user = Path(params_file).expanduser().resolve()
        load_parameter_file(user)  # a ParameterFileError naming the file when it is no ROS 2 parameter file
        files.append(user)
    return files


def split_remap_arguments(arguments: Sequence[str]) -> tuple[str, list[tuple[str, str]]]:
    """Return the namespace ('' for none) and the (from, to) remappings of '-r FROM:=TO' --ros-args."""
    namespace, remappings = '', []
    for flag, rule in zip(arguments[::2], arguments[1::2]):
        source, sep, target = rule.partition(':=')
        if flag != '-r' or not sep:
            raise ValueError(f'not a remapping rule: {flag} {rule}')
        if source == '__ns':
            namespace = target
        else:
            remappings.append((source, target))
    return namespace, remappings


def node_executable(package: str, executable: str) -> Path:
    """Return a node's console script: under lib/<package> (the `ros2 run` layout) or bin of the package's prefix
    (where this repository's setup.cfg files put it), else on PATH."""
    share = share_directory(package)
    if share is not None:
        prefix = share.parent.parent
        for candidate in (prefix / 'lib' / package / executable, prefix / 'bin' / executable):
            if candidate.is_file():
                return candidate
    found = shutil.which(executable)
    if found is None:
        raise LaunchArgumentError(
            f'{package}: its executable {executable} is in neither lib/{package} nor bin of its install prefix, '
            'nor on PATH (is the workspace sourced?)'
        )
    return Path(found)
