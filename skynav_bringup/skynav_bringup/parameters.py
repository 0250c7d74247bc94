# SPDX-License-Identifier: Apache-2.0
"""The shipped parameter file: every installed node's parameter table, with its defaults and meanings.

`skynav_bringup/config/skynav.yaml` is generated from the nodes' tables (`tools/write_parameters.py`) and a test
fails when the two differ, so a default lives in one place: its node's table. The file is what `skynav launch`,
`skynav run` and `ros2 launch skynav_bringup skynav.launch.py` start from; a user's --params file overrides it.
`ros_arguments` gives the graph's --ros-args from it, the user's file and the map (for `launch`, `run`, `bench`).
"""

from __future__ import annotations

from pathlib import Path

from skynav_core.cli import graph_arguments
from skynav_core.graph import node_class
from skynav_core.namespaces import write_any_namespace_file
from skynav_core.nodes import installed_nodes
from skynav_core.parameters import COMMON_PARAMETERS, parameter_file
from skynav_core.process.environment import share_directory

SHIPPED = Path(__file__).resolve().parents[1] / 'config' / 'skynav.yaml'
HEADER = """\
Default parameters of the skynav nodes: `skynav launch`, `skynav run` and
`ros2 launch skynav_bringup skynav.launch.py` start from these, and a parameter file of yours
(--params, params_file:=) overrides any of them. Copy the ones you change into your own file.

Generated from the nodes' parameter tables (each package's parameters.py) by tools/write_parameters.py;
edit the table, not this file. localize, compass and warping compare against a map: `skynav run --map`
and `skynav launch --map` set their `map` parameter.

skyline: the UV/green separator (angle_deg, threshold) and the UV-only threshold (threshold_uv) were
learned on SYNTHETIC recordings and are unlikely to fit a real UV/green camera: learn your own from
labelled recordings of it (`skynav skyline train`)."""


def shipped_parameter_file() -> str:
    """Return the text of the shipped parameter file, made from every installed node's parameter table."""
    # The parameters every node takes are repeated per node: a '/**' section would be applied after (and so
    # override) the nodes' sections of a user's file.
    tables = {spec.name: {**node_class(spec).PARAMETERS, **COMMON_PARAMETERS} for spec in installed_nodes()}
    return parameter_file(tables, HEADER)


def default_params_file() -> Path | None:
    """Return the parameter file shipped with skynav_bringup, if installed."""
    share = share_directory('skynav_bringup')
    path = None if share is None else share / 'config' / 'skynav.yaml'
    return path if path is not None and path.is_file() else None


def ros_arguments(
    params: Path | None, map_path: Path | None, namespace: str = '', scratch: Path | None = None
) -> list[str]:
    """Return the --ros-args of the graph: the shipped defaults, then the user's parameter file, and the map; in a
    namespace, the files' node sections rewritten into `scratch` to match there (skynav_core.namespaces)."""
    shipped = default_params_file()
    arguments = (['--params-file', str(shipped)] if shipped is not None else []) + graph_arguments(params, map_path)
    if namespace:
        assert scratch is not None  # the caller keeps the rewritten files while the graph runs
        for k, value in enumerate(arguments):
            if k > 0 and arguments[k - 1] == '--params-file':
                arguments[k] = str(write_any_namespace_file(Path(value), scratch / f'{k}-{Path(value).name}'))
    return arguments
