# SPDX-License-Identifier: Apache-2.0
"""The shipped parameter file is the nodes' parameter tables, and every node declares exactly its table."""

import yaml

from skynav_bringup.parameters import SHIPPED, shipped_parameter_file
from skynav_core.graph import node_class
from skynav_core.nodes import installed_nodes


def test_the_shipped_parameter_file_is_generated_from_the_nodes_tables():
    assert SHIPPED.read_text() == shipped_parameter_file(), 'run tools/write_parameters.py and commit the result'


def test_every_node_declares_its_table_with_the_shipped_defaults(ros_context):
    shipped = yaml.safe_load(SHIPPED.read_text())
    for spec in installed_nodes():
        node = node_class(spec)(context=ros_context)
        try:
            declared = node.parameter_values()
            table = {name: parameter.default for name, parameter in node.PARAMETERS.items()}
            assert set(declared) == set(table), spec.name
            assert sorted(node.input_topics) == sorted(node.INPUT_TOPICS), spec.name  # what `skynav replay` waits for
            for name, value in shipped[spec.name]['ros__parameters'].items():
                actual = node.get_parameter(name).value  # the node's table, and what every node takes
                assert value == actual or (value != value and actual != actual), (spec, name)
        finally:
            node.destroy_node()
