# SPDX-License-Identifier: Apache-2.0
"""Goal handling without ROS: refused requests, the other nodes' settings, results; the parameters' checks."""

import math

import numpy as np
import pytest
from skynav_route.controller import LOST, Limits, Settings
from skynav_route.parameters import PARAMETERS, check, limits, settings

from skynav_core.parameters import defaults
from skynav_msgs.action import FollowRoute, Home
from skynav_route import goals


def follow(start: int = -1, end: int = -1, speed: float = 0.0) -> FollowRoute.Goal:
    return FollowRoute.Goal(start_index=start, end_index=end, max_speed=speed)


@pytest.mark.parametrize(
    ('request_', 'code'),
    [
        (follow(), None),
        (follow(0, 9), None),
        (follow(4, 4), None),
        (follow(10), FollowRoute.Result.BAD_INDEX),
        (follow(-2), FollowRoute.Result.BAD_INDEX),
        (follow(0, 10), FollowRoute.Result.BAD_INDEX),
        (follow(5, 4), FollowRoute.Result.BAD_INDEX),
        (follow(speed=math.nan), FollowRoute.Result.BAD_GOAL),
        (follow(speed=math.inf), FollowRoute.Result.BAD_GOAL),
    ],
)
def test_a_follow_request_is_refused_with_its_error_code(request_, code):
    refusal = goals.follow_refusal(request_, 10)
    assert (refusal and refusal[0]) == code
    if refusal is not None:
        assert refusal[1]  # a text the client prints


def test_a_follow_request_ends_at_its_end_index_or_the_last_snapshot():
    assert goals.follow_end(follow(), 10) == 9
    assert goals.follow_end(follow(end=3), 10) == 3


@pytest.mark.parametrize(
    ('index', 'speed', 'code'),
    [
        (0, 0.0, None),
        (9, 0.5, None),
        (10, 0.0, Home.Result.BAD_INDEX),
        (-1, 0.0, Home.Result.BAD_INDEX),
        (3, math.nan, Home.Result.BAD_GOAL),
    ],
)
def test_a_home_request_is_refused_with_its_error_code(index, speed, code):
    refusal = goals.home_refusal(Home.Goal(index=index, max_speed=speed), 10)
    assert (refusal and refusal[0]) == code
    if code == Home.Result.BAD_INDEX:
        assert 'snapshots 0..9' in refusal[1]


def test_every_way_a_goal_fails_has_its_own_code_and_text():
    limit = goals.home_time_limit(10.0, 0.5, 120.0, 3.0)
    for kind in (FollowRoute, Home):
        codes = kind.Result
        failures = {
            outcome: goals.failure(outcome, codes, 1.0, limit)
            for outcome in (LOST, goals.STALE, goals.TIMED_OUT, goals.BLOCKED, goals.EMERGENCY)
        }
        assert [code for code, _ in failures.values()] == [
            codes.LOST,
            codes.STALE_INPUT,
            codes.TIMEOUT,
            codes.BLOCKED,
            codes.EMERGENCY_STOP,
        ]
        assert codes.EMERGENCY_STOP == 9  # the contract's value
        assert len({text for _, text in failures.values()}) == len(failures)
        assert failures[goals.EMERGENCY][1] == 'emergency stop: the emergency stop input is true; the robot stopped'
        tilted = goals.failure(goals.EMERGENCY, codes, 1.0, limit, stop_reason='the robot leans 40 deg')
        assert tilted == (codes.EMERGENCY_STOP, 'emergency stop: the robot leans 40 deg; the robot stopped')
        # the limit and how it was computed: 120 s + 3 x 10 m / 0.5 m/s
        assert failures[goals.TIMED_OUT][1] == (
            'the goal ran longer than its time limit of 180.0 s: goal_timeout 120 s + goal_time_factor 3 x 10.0 m '
            '(home_distance) at 0.5 m/s'
        )
        assert goals.failure(goals.SHUTDOWN, codes, 1.0, limit)[0] == codes.LOST
        assert goals.failure(LOST, codes, 1.0, limit, 'never placed')[1] == 'never placed'


def test_the_route_length_is_the_odometrys_else_the_commands_else_the_spacing_else_an_assumed_one():
    line = poses_along(np.linspace(0, 5, 26), np.zeros(26))  # 0.2 m apart
    wide = poses_along(np.linspace(0, 10, 26), np.zeros(26))  # 0.4 m apart
    nowhere = poses_along(np.zeros(26), np.zeros(26))  # no command came while teaching
    missing = np.full((26, 7), np.nan)
    length = goals.route_length(26, line, wide, {})
    assert length.between(0, 25) == pytest.approx(5.0) and length.between(5, 10) == pytest.approx(1.0)
    assert 'odometry' in length.source
    length = goals.route_length(26, missing, wide, {'spacing_m': '0.1'})
    assert length.between(0, 25) == pytest.approx(10.0) and 'commands' in length.source
    length = goals.route_length(26, None, nowhere, {'spacing_m': '0.3'})  # the teach's spacing
    assert length.between(0, 25) == pytest.approx(7.5) and "teach's spacing" in length.source
    for meta in ({}, {'spacing_m': 'wide'}, {'spacing_m': '-1'}, {'spacing_m': 'nan'}):
        length = goals.route_length(26, None, None, meta)
        assert length.between(0, 25) == pytest.approx(25 * goals.UNKNOWN_SPACING)
        assert 'records no odometry, commands or spacing' in length.source


def test_a_follow_goals_time_limit_scales_with_the_route_from_its_start_to_its_end():
    line = poses_along(np.linspace(0, 5, 26), np.zeros(26))
    length = goals.route_length(26, line, None, {})
    whole = goals.follow_time_limit(length, -1, 25, 0.5, 120.0, 3.0)  # placed anywhere: from the first snapshot
    assert whole.seconds == pytest.approx(120.0 + 3.0 * 5.0 / 0.5)
    part = goals.follow_time_limit(length, 20, 25, 0.5, 120.0, 3.0)
    assert part.seconds == pytest.approx(120.0 + 3.0 * 1.0 / 0.5)
    assert 'from snapshot 20 to 25' in part.describe() and 'odometry' in part.describe()
    slow = goals.follow_time_limit(length, -1, 25, 0.1, 120.0, 3.0)
    assert slow.seconds == pytest.approx(120.0 + 3.0 * 5.0 / 0.1)
    assert goals.follow_time_limit(length, 7, 7, 0.5, 120.0, 3.0).seconds == 120.0  # already there


def test_a_kilometre_route_at_0_3_m_s_gets_more_than_the_time_it_takes_by_the_parameter_defaults():
    values = defaults(PARAMETERS)
    count = 10_001  # a snapshot every 0.1 m of odometry along 1 km
    odometry = poses_along(np.linspace(0.0, 1000.0, count), np.zeros(count))
    length = goals.route_length(count, odometry, None, {})
    speed = limits(values, 0.3).max_speed
    limit = goals.follow_time_limit(length, -1, count - 1, speed, values['goal_timeout'], values['goal_time_factor'])
    driving = 1000.0 / 0.3  # s at the speed limit all the way
    assert limit.seconds > driving > 600.0  # not capped at the old fixed 600 s
    assert limit.seconds == pytest.approx(values['goal_timeout'] + values['goal_time_factor'] * driving)


def test_a_home_goals_time_limit_counts_home_distance_at_its_speed():
    limit = goals.home_time_limit(10.0, 0.25, 120.0, 3.0)
    assert limit.seconds == pytest.approx(120.0 + 3.0 * 40.0)
    assert 'home_distance' in limit.describe()


def test_a_follow_goal_never_placed_on_the_route_says_so_and_how_to_help():
    assert goals.unplaced(0, -1) is None
    assert 'start_index' in goals.unplaced(-1, -1)
    assert 'start_index' not in goals.unplaced(-1, 4)


def test_the_first_feedback_says_no_frame_was_answered_yet():
    assert goals.first_feedback(FollowRoute).state == 'localizing'
    assert goals.first_feedback(Home).steps == 0


def test_the_parameter_defaults_are_the_controllers_and_bad_values_are_refused():
    values = defaults(PARAMETERS)
    check(values)
    assert settings(values) == Settings()
    assert limits(values, 0.0) == Limits()
    assert limits(values, 0.1).max_speed == 0.1
    for name, value in (
        ('max_speed', 0.0),
        ('approach', 0.0),
        ('heading_gain', math.nan),
        ('lost_frames', 0),
        ('goal_time_factor', -1.0),
        ('home_distance', math.inf),
        ('goal_timeout', -1.0),
        ('max_tilt_deg', 181.0),
    ):
        with pytest.raises(ValueError):
            check({**values, name: value})


def poses_along(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Return (N, 7) ground-plane poses at (x, y), heading along the way."""
    heading = np.arctan2(np.gradient(y), np.gradient(x))
    zeros = np.zeros_like(x)
    return np.column_stack([x, y, zeros, zeros, zeros, np.sin(heading / 2), np.cos(heading / 2)])


def test_the_route_shape_is_the_odometry_else_the_commands_else_none():
    line = poses_along(np.linspace(0, 5, 26), np.zeros(26))
    arc = poses_along(np.sin(np.linspace(0, 1, 26)), 1 - np.cos(np.linspace(0, 1, 26)))
    nowhere = poses_along(np.zeros(26), np.zeros(26))  # no command came while teaching: it never moved
    missing = np.full((26, 7), np.nan)
    route, source = goals.route_shape(line, arc)
    assert source == 'odometry' and np.allclose(route.positions, line[:, :2])
    route, source = goals.route_shape(missing, arc)
    assert source == 'commands' and np.allclose(route.positions, arc[:, :2])
    route, source = goals.route_shape(None, arc)
    assert source == 'commands'
    assert goals.route_shape(missing, nowhere) == (None, 'nothing')
    assert goals.route_shape(None, None) == (None, 'nothing')
