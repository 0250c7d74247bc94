# SPDX-License-Identifier: Apache-2.0
"""skynav_route.context: what localize, compass and warping are given for a goal."""

from skynav_route.context import AFTER_FOLLOW, NODES, GoalContext


def test_following_points_the_compass_at_the_match_warping_ahead_and_localize_along_the_route():
    assert GoalContext.follow(lookahead=6, start_index=3).parameters() == {
        'compass': {'reference': 'match'},
        'warping': {'target': 'next', 'lookahead': 6},
        'localize': {'tracking': True, 'tracking_start': 3},
    }


def test_homing_points_the_compass_and_warping_at_the_goal_snapshot_and_leaves_localize_alone():
    assert GoalContext.home(7).parameters() == {
        'compass': {'reference': 'index', 'index': 7},
        'warping': {'target': 'index', 'index': 7},
    }


def test_another_map_goes_to_all_three_nodes():
    for context in (GoalContext.follow(6, -1, 'other.db'), GoalContext.home(7, 'other.db')):
        parameters = context.parameters()
        assert set(parameters) == set(NODES)
        assert all(values['map'] == 'other.db' for values in parameters.values())
    assert GoalContext.follow(6, -1, 'other.db').parameters()['localize']['tracking'] is True
    assert GoalContext.home(7, 'other.db').parameters()['localize'] == {'map': 'other.db'}


def test_a_follow_goal_ends_with_localize_off_the_route():
    assert AFTER_FOLLOW == {'localize': {'tracking': False, 'tracking_start': -1}}
    assert GoalContext.follow(6, 3).following and not GoalContext.home(0).following
