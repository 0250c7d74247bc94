# SPDX-License-Identifier: Apache-2.0
"""`ros2 launch skynav_bringup skynav.launch.py`: what each node gets from the launch arguments.

The ROS 2 launch tools are not installed here (not on PyPI), so the launch file cannot be imported or run: it is
checked by parsing (its declared arguments, and that it hands each of them and each node's settings on), and what
it starts is checked through skynav_bringup.ros_launch, where all of its logic lives, with the installed nodes.
"""

from __future__ import annotations

import ast
import inspect
from dataclasses import fields
from pathlib import Path

import pytest
import yaml

from skynav_bringup import ros_launch
from skynav_bringup.ros_launch import (
    CAMERA_CHOICES,
    LaunchArgumentError,
    NodeLaunch,
    graph_launch,
    node_executable,
    split_remap_arguments,
)
from skynav_core.graph import node_class
from skynav_core.names import CLOCK, TF_STATIC
from skynav_core.namespaces import NamespaceError
from skynav_core.nodes import installed_nodes
from skynav_core.parameters import ParameterFileError, load_parameter_file

LAUNCH_FILE = Path(__file__).resolve().parents[1] / 'launch' / 'skynav.launch.py'
ARGUMENTS = {'map', 'params_file', 'use_sim_time', 'namespace', 'camera'}


def launch_tree() -> ast.Module:
    return ast.parse(LAUNCH_FILE.read_text(), str(LAUNCH_FILE))


def calls(tree: ast.AST, name: str) -> list[ast.Call]:
    """The calls of a function called by its plain name in a module."""
    return [
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == name
    ]


def declared_arguments() -> dict[str, dict[str, ast.expr]]:
    """The launch file's DeclareLaunchArgument calls: name -> keywords."""
    declared = {}
    for call in calls(launch_tree(), 'DeclareLaunchArgument'):
        assert isinstance(call.args[0], ast.Constant), ast.unparse(call)
        declared[call.args[0].value] = {k.arg: k.value for k in call.keywords if k.arg}
    return declared


def test_the_launch_file_declares_the_five_arguments_each_empty_by_default():
    declared = declared_arguments()
    assert set(declared) == ARGUMENTS
    assert all(ast.literal_eval(keywords['default_value']) == '' for keywords in declared.values())
    assert all(ast.literal_eval(keywords['description']) for keywords in declared.values())
    assert ast.unparse(declared['camera']['choices']) == 'list(CAMERA_CHOICES)'
    assert ast.unparse(declared['use_sim_time']['choices']) == 'list(SIM_TIME_CHOICES)'
    assert CAMERA_CHOICES == ('', 'auto', 'uv-green', 'colour', 'colour-compressed')


def test_the_launch_file_hands_every_argument_to_graph_launch():
    (call,) = calls(launch_tree(), 'graph_launch')
    read = {}
    for keyword in call.keywords:
        # keyword=LaunchConfiguration('<argument>').perform(context)
        value = keyword.value
        assert isinstance(value, ast.Call) and isinstance(value.func, ast.Attribute), ast.unparse(value)
        assert value.func.attr == 'perform' and isinstance(value.func.value, ast.Call)
        assert ast.unparse(value.func.value.func) == 'LaunchConfiguration'
        read[keyword.arg] = ast.literal_eval(value.func.value.args[0])
    assert set(read.values()) == ARGUMENTS
    positional = [p.name for p in inspect.signature(graph_launch).parameters.values() if p.kind is not p.KEYWORD_ONLY]
    assert sorted(read) == sorted(positional)
    assert read['map_path'] == 'map' and all(read[name] == name for name in read if name != 'map_path')


def test_the_launch_file_starts_each_node_as_ros_launch_describes_it():
    (node,) = calls(launch_tree(), 'Node')
    keywords = {k.arg: ast.unparse(k.value) for k in node.keywords}
    assert keywords == {
        'executable': 'str(node.executable)',
        'name': 'node.name',
        'namespace': 'node.namespace or None',
        'parameters': 'node.parameters',
        'remappings': 'node.remappings',
        'output': "'screen'",
    }
    assert {'executable', 'name', 'namespace', 'parameters', 'remappings'} <= {f.name for f in fields(NodeLaunch)}
    (opaque,) = calls(launch_tree(), 'OpaqueFunction')
    assert ast.unparse(opaque.keywords[0].value) == 'start_nodes'


def test_the_launch_file_imports_only_the_launch_tools_and_ros_launch():
    imported = {}
    for node in ast.walk(launch_tree()):
        if isinstance(node, ast.ImportFrom):
            imported[node.module] = {alias.name for alias in node.names}
    assert set(imported) == {'launch', 'launch.actions', 'launch.substitutions', 'launch_ros.actions',
                             'skynav_bringup.ros_launch'}  # fmt: skip
    assert all(hasattr(ros_launch, name) for name in imported['skynav_bringup.ros_launch'])


def launched_nodes() -> list[str]:
    return [spec.name for spec in installed_nodes() if spec.executable is not None]


def test_without_arguments_every_node_starts_from_the_shipped_parameters():
    nodes = graph_launch(scratch=None)
    assert [node.name for node in nodes] == launched_nodes()
    assert {'skyline', 'sh', 'localize', 'compass', 'warping', 'route', 'viz'} <= {node.name for node in nodes}
    shipped = Path(nodes[0].parameters[0])
    assert shipped.name == 'skynav.yaml' and shipped.parent.name == 'config'
    for node in nodes:
        assert node.namespace == '' and node.remappings == []
        assert node.parameters == [str(shipped)]
        assert node.executable.is_file() and node.executable.name == f'{node.name}_node'


def test_a_namespace_moves_the_graph_its_clock_and_static_transforms_and_rewrites_the_parameter_files(tmp_path):
    params = tmp_path / 'mine.yaml'
    params.write_text('/**:\n  ros__parameters:\n    use_sim_time: true\nskyline:\n  ros__parameters:\n    bins: 64\n')
    scratch = tmp_path / 'scratch'
    scratch.mkdir()
    nodes = graph_launch(namespace='robot1', params_file=str(params), scratch=scratch)
    for node in nodes:
        assert node.namespace == '/robot1'
        assert node.remappings == [(CLOCK, '/robot1/clock'), (TF_STATIC, '/robot1/tf_static')]
        assert [Path(p).parent for p in node.parameters] == [scratch, scratch]
    shipped, mine = (load_parameter_file(p) for p in nodes[0].parameters)
    assert mine == {
        '/**': {'ros__parameters': {'use_sim_time': True}},
        '/**/skyline': {'ros__parameters': {'bins': 64}},
    }
    original = load_parameter_file(graph_launch()[0].parameters[0])
    assert shipped == {f'/**/{name}': section for name, section in original.items()}
    assert {'/**/skyline', '/**/localize'} <= set(shipped)


def test_a_namespace_ros_cannot_take_is_refused():
    with pytest.raises(NamespaceError, match='1robot'):
        graph_launch(namespace='1robot')


def test_the_map_goes_to_the_nodes_whose_table_has_one(tmp_path, monkeypatch):
    (tmp_path / 'route.db').write_bytes(b'')
    monkeypatch.chdir(tmp_path)
    nodes = graph_launch(map_path='route.db')
    with_map = {spec.name for spec in installed_nodes() if 'map' in node_class(spec).PARAMETERS}
    assert {'localize', 'compass', 'warping'} <= with_map
    for node in nodes:
        overrides = node.parameters[-1] if isinstance(node.parameters[-1], dict) else {}
        assert overrides.get('map') == (str(tmp_path / 'route.db') if node.name in with_map else None), node.name
    with pytest.raises(LaunchArgumentError, match=r'map:=missing\.db: no such map file'):
        graph_launch(map_path='missing.db')


def test_the_camera_goes_to_the_nodes_that_read_camera_frames():
    nodes = {node.name: node for node in graph_launch(camera='colour-compressed')}
    assert nodes['skyline'].parameters[-1] == {'camera': 'colour-compressed'}
    for name, node in nodes.items():
        has_camera = 'camera' in node_class(next(s for s in installed_nodes() if s.name == name)).PARAMETERS
        assert isinstance(node.parameters[-1], dict) == has_camera, name
    with pytest.raises(LaunchArgumentError, match='camera:=fisheye is none of auto, uv-green'):
        graph_launch(camera='fisheye')


def test_use_sim_time_goes_to_every_node_only_when_given():
    assert all(node.parameters[-1] == {'use_sim_time': True} for node in graph_launch(use_sim_time='true'))
    assert all(node.parameters[-1] == {'use_sim_time': False} for node in graph_launch(use_sim_time='false'))
    assert all(len(node.parameters) == 1 for node in graph_launch(use_sim_time=''))
    with pytest.raises(LaunchArgumentError, match='use_sim_time:=yes'):
        graph_launch(use_sim_time='yes')


def test_the_users_parameter_file_comes_after_the_shipped_one_and_must_be_one(tmp_path):
    params = tmp_path / 'mine.yaml'
    params.write_text(yaml.safe_dump({'sh': {'ros__parameters': {'max_degree': 8}}}))
    (node, *_) = graph_launch(params_file=str(params))
    assert node.parameters[1] == str(params) and node.parameters[0].endswith('skynav.yaml')
    with pytest.raises(ParameterFileError, match='cannot read'):
        graph_launch(params_file=str(tmp_path / 'none.yaml'))
    (tmp_path / 'bad.yaml').write_text('sh: 3\n')
    with pytest.raises(ParameterFileError, match='not in the ROS 2 format'):
        graph_launch(params_file=str(tmp_path / 'bad.yaml'))


def test_remap_arguments_split_into_namespace_and_rules():
    assert split_remap_arguments(['-r', '__ns:=/a', '-r', '/clock:=/a/clock']) == ('/a', [(CLOCK, '/a/clock')])
    assert split_remap_arguments([]) == ('', [])
    with pytest.raises(ValueError, match='not a remapping rule'):
        split_remap_arguments(['-p', 'x:=1'])


def test_a_nodes_executable_is_found_in_lib_then_bin_of_its_prefix(tmp_path, monkeypatch):
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    monkeypatch.setenv('PATH', str(tmp_path / 'nowhere'))
    marker = tmp_path / 'share' / 'ament_index' / 'resource_index' / 'packages' / 'pkg_x'
    marker.parent.mkdir(parents=True)
    marker.write_text('')
    in_lib, in_bin = tmp_path / 'lib' / 'pkg_x' / 'x_node', tmp_path / 'bin' / 'x_node'
    for path in (in_lib, in_bin):
        path.parent.mkdir(parents=True)
        path.write_text('')
    assert node_executable('pkg_x', 'x_node') == in_lib
    in_lib.unlink()
    assert node_executable('pkg_x', 'x_node') == in_bin
    in_bin.unlink()
    with pytest.raises(LaunchArgumentError, match='pkg_x: its executable x_node is in neither lib/pkg_x nor bin'):
        node_executable('pkg_x', 'x_node')
