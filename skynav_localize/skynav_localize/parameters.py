# SPDX-License-Identifier: Apache-2.0
"""The localize node's parameters: names, defaults and meaning (skynav_core.parameters)."""

from __future__ import annotations

import math

from skynav_core.parameters import Parameter

from .localizer import DESCRIPTOR_DEGREE, OUR_METHODS
from .teaching import DEFAULT_ODOMETRY_TOLERANCE_NS, DEFAULT_SPACING, VIEW_CHANGE_PER_METRE

PARAMETERS = {
    'map': Parameter('', 'SQLite map file (`skynav map build`); empty: no map'),
    'method': Parameter('amplitude-seq', f'one of {", ".join(OUR_METHODS)}'),
    'sequence_length': Parameter(10, 'views in a sequence (sequence methods)'),
    'min_speed': Parameter(0.5, 'slowest progress along the map, snapshots per view (sequence methods)'),
    'max_speed': Parameter(2.0, 'fastest progress along the map, snapshots per view (sequence methods)'),
    'max_ratio': Parameter(math.nan, "acceptance: best / runner-up distance at most this; NaN: the method's"),
    'max_view_ratio': Parameter(
        math.nan,
        "acceptance of sequences: the newest view's own best / runner-up ratio at "
        "the matched snapshot at most this; NaN: the method's",
    ),
    'max_distance': Parameter(math.inf, 'acceptance: best descriptor distance at most this'),
    'max_self_similarity': Parameter(
        math.nan,
        "acceptance where the route looks alike: a match whose snapshot's "
        "self-similarity (the route's step there over the distance to its "
        'nearest look-alike elsewhere on the route) exceeds this is accepted '
        'only after views that vouched for a steady drive (sequences); NaN: '
        "the method's",
    ),
    'tracking': Parameter(
        False,
        'seek each view near the last accepted match, as a robot following the route is (sequence methods; the '
        'route node sets it for a FollowRoute goal)',
    ),
    'tracking_start': Parameter(
        -1,
        'with tracking: the snapshot the robot starts at, sought near from the first view (the FollowRoute '
        "goal's start_index); -1: wherever its first accepted match places it",
    ),
    'candidates': Parameter(5, 'runners-up in each match'),
    'max_degree': Parameter(DESCRIPTOR_DEGREE, 'SH degree of the place descriptors (views and map are cut to it)'),
    'teach_spacing': Parameter(DEFAULT_SPACING, 'Teach goals: m of travel between snapshots when the goal says <= 0'),
    'teach_view_change': Parameter(
        VIEW_CHANGE_PER_METRE,
        'Teach goals without /odom: amplitude-descriptor change per metre of spacing that makes a snapshot '
        '(calibrated on the bundled synthetic teach drives)',
    ),
    'odometry_tolerance': Parameter(
        DEFAULT_ODOMETRY_TOLERANCE_NS * 1e-9,
        's between a view and the /odom sample paired with it (teaching, tracking)',
    ),
    'teach_input_timeout': Parameter(10.0, 'Teach goals: s without a usable view before the goal ends with NO_INPUT'),
    'cmd_vel_stamped': Parameter(
        True,
        'Teach goals: /cmd_vel, the commands the robot is driven with, is geometry_msgs/TwistStamped (false: Twist, '
        "as the route node's cmd_vel_stamped); read at start",
    ),
    'teach_map_nodes': Parameter(
        ['compass', 'warping'], 'nodes whose `map` parameter is set to a map taught here when its goal ends'
    ),
}
