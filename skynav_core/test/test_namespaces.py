# SPDX-License-Identifier: Apache-2.0
"""Namespaces and remapping rules as the graph takes them (skynav_core.namespaces)."""

from __future__ import annotations

import pytest
import yaml

from skynav_core.names import CMD_VEL, SKYLINE_SH
from skynav_core.namespaces import (
    NamespaceError,
    check_namespace,
    namespaced,
    remap_arguments,
    without_namespace,
    write_any_namespace_file,
)


@pytest.mark.parametrize(
    ('given', 'written'), [('robot1', '/robot1'), ('/robot1/', '/robot1'), ('a/b', '/a/b'), ('', '')]
)
def test_a_namespace_is_written_as_ros_writes_it(given, written):
    assert check_namespace(given) == written


@pytest.mark.parametrize('bad', ['1robot', 'robot-1', 'a//b', 'a b', '~x'])
def test_a_namespace_ros_cannot_take_is_refused(bad):
    with pytest.raises(NamespaceError):
        check_namespace(bad)


def test_contract_names_move_into_a_namespace_and_back():
    assert namespaced(SKYLINE_SH, 'robot1') == '/robot1/skyline/sh'
    assert without_namespace('/robot1/skyline/sh', '/robot1') == SKYLINE_SH
    assert without_namespace('/robot2/skyline/sh', '/robot1') is None
    assert without_namespace('/robot10/skyline/sh', '/robot1') is None  # a prefix of a name is not its namespace
    assert without_namespace(SKYLINE_SH, '') == SKYLINE_SH


def test_a_graph_in_a_namespace_has_its_own_clock_and_static_transforms():
    assert remap_arguments('robot1') == [
        '-r',
        '__ns:=/robot1',
        '-r',
        '/clock:=/robot1/clock',
        '-r',
        '/tf_static:=/robot1/tf_static',
    ]
    assert remap_arguments('') == []


def test_a_remapping_names_the_contracts_topic_within_the_namespace():
    assert remap_arguments('', ['/cmd_vel:=/base/cmd_vel']) == ['-r', 'cmd_vel:=/base/cmd_vel']
    assert remap_arguments('r1', ['/cmd_vel:=wheels'])[-2:] == ['-r', 'cmd_vel:=wheels']
    for bad in (CMD_VEL, '/cmd_vel:=', ':=/x', '/cmd vel:=/x'):
        with pytest.raises(NamespaceError):
            remap_arguments('', [bad])


def test_node_sections_of_a_parameter_file_match_in_any_namespace(tmp_path):
    source = tmp_path / 'params.yaml'
    source.write_text(
        yaml.safe_dump(
            {
                'skyline': {'ros__parameters': {'sectors': 8}},
                '/**': {'ros__parameters': {'use_sim_time': True}},
                '/robot1/sh': {'ros__parameters': {'max_degree': 12}},
            }
        )
    )
    written = yaml.safe_load(write_any_namespace_file(source, tmp_path / 'out.yaml').read_text())
    assert written == {
        '/**/skyline': {'ros__parameters': {'sectors': 8}},
        '/**': {'ros__parameters': {'use_sim_time': True}},
        '/robot1/sh': {'ros__parameters': {'max_degree': 12}},
    }
