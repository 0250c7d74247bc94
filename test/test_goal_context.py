# SPDX-License-Identifier: Apache-2.0
"""The goal context the route node sends (skynav_route.context) is what localize, compass and warping declare:
every parameter it sets is in that node's parameter table, with the default's type, and each snapshot choice it
makes is one of the node's own."""

import pytest
from skynav_route.context import AFTER_FOLLOW, NODES, GoalContext

from skynav_compass.parameters import PARAMETERS as COMPASS
from skynav_compass.parameters import REFERENCES
from skynav_localize.parameters import PARAMETERS as LOCALIZE
from skynav_warping.parameters import PARAMETERS as WARPING
from skynav_warping.parameters import TARGETS

TABLES = {'localize': LOCALIZE, 'compass': COMPASS, 'warping': WARPING}
CONTEXTS = [
    GoalContext.follow(6, -1),
    GoalContext.follow(0, 12, 'other.db'),
    GoalContext.home(0),
    GoalContext.home(9, 'other.db'),
]


@pytest.mark.parametrize('settings', [c.parameters() for c in CONTEXTS] + [AFTER_FOLLOW])
def test_every_parameter_of_a_goal_context_is_declared_by_its_node_with_its_type(settings):
    assert set(settings) <= set(NODES) == set(TABLES)
    for node, values in settings.items():
        for name, value in values.items():
            assert name in TABLES[node], f'{node} declares no parameter {name}'
            assert type(value) is type(TABLES[node][name].default), f'{node}.{name}: {value!r}'


def test_the_snapshot_choices_are_the_nodes_own():
    for context in CONTEXTS:
        parameters = context.parameters()
        assert parameters['compass']['reference'] in REFERENCES
        assert parameters['warping']['target'] in TARGETS
