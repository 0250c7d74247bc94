# SPDX-License-Identifier: Apache-2.0
"""The scores of `skynav eval follow|home` on scripted paths, and the commands' refusals of bad arguments."""

import numpy as np
import pytest

from skynav_bringup.cli import main
from skynav_sim.closed_loop import Run, route_deviation
from skynav_sim.drive_eval import ErrorSummary, cross_track, path_length, time_stopped, turns
from skynav_testing import one_line_error

PERIOD = 0.2  # s between frames


def test_path_length_sums_the_steps():
    assert path_length(np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0]])) == pytest.approx(7.0)
    assert path_length(np.array([[1.0, 2.0]])) == 0.0


def test_time_stopped_counts_frames_that_neither_moved_nor_turned():
    poses = np.array(
        [
            [0.0, 0.0, 0.0],
            [0.08, 0.0, 0.0],  # drove
            [0.08, 0.0, 0.0],  # stood
            [0.08, 0.0, 0.3],  # turned on the spot: not standing still
            [0.081, 0.0, 0.3],  # 1 mm: stood
            [0.081, 0.0, 0.3 - 2 * np.pi],  # the same heading, wrapped: stood
            [0.16, 0.0, 0.3],  # drove
        ]
    )
    assert time_stopped(poses, PERIOD) == pytest.approx(3 * PERIOD)


def test_cross_track_is_the_distance_to_the_route_with_the_foot_along_it():
    route = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])
    x = np.linspace(0.0, 10.0, 21)
    driven = np.column_stack([x, np.where(x < 5, 0.2, -0.1)])
    error, along = cross_track(driven, route)
    assert error == pytest.approx(np.where(x < 5, 0.2, 0.1))
    assert along == pytest.approx(x)
    # beyond the route's end the distance is to its last point
    error, along = cross_track(np.array([[0.0, 0.0], [2.5, 0.0], [5.0, 0.0], [7.5, 0.0], [13.0, 4.0]]), route)
    assert error == pytest.approx([0.0, 0.0, 0.0, 0.0, 5.0]) and along[-1] == pytest.approx(10.0)
    # the search starts at the route's start: a robot at its end, not driven there, is far from the route
    assert cross_track(np.array([[10.0, 0.0]]), route)[0] == pytest.approx([5.0])


def test_cross_track_follows_progress_on_a_route_that_passes_near_itself():
    # a hairpin: out along y = 0, back along y = 1; the robot drives the way out 0.9 m to the left of it
    route = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 1.0], [0.0, 1.0]])
    driven = np.column_stack([np.linspace(0.0, 5.0, 26), np.full(26, 0.9)])
    error, along = cross_track(driven, route)
    assert error == pytest.approx(np.full(26, 0.9))
    assert along == pytest.approx(driven[:, 0])
    # the whole route's nearest point (route_deviation) takes the way back for it
    run = Run(driven[0], driven[-1], list(driven))
    assert route_deviation(run, route) == pytest.approx(np.full(26, 0.1))


def test_turns_add_up_left_and_right_turns():
    # a quarter circle to the left (radius 2 m), then a straight, then a half circle to the right
    left = np.radians(np.linspace(-90, 0, 200))
    right = np.radians(np.linspace(180, 0, 400))
    route = np.vstack(
        [
            np.column_stack([2 * np.cos(left), 2 + 2 * np.sin(left)]),
            [[2.0, 4.0]],
            np.column_stack([4 + 2 * np.cos(right), 4 + 2 * np.sin(right)]),
        ]
    )
    assert turns(route, 0.05) == pytest.approx((90.0, 180.0), abs=4.0)


def test_error_summary():
    summary = ErrorSummary.of([0.4, 0.0, 0.2, 0.1, 0.3])
    assert summary.median == pytest.approx(0.2) and summary.max == pytest.approx(0.4)
    assert summary.p90 == pytest.approx(0.36) and summary.rmse == pytest.approx(np.sqrt(0.06))
    assert np.isnan(ErrorSummary.of([]).median)


@pytest.mark.parametrize(
    'arguments, code',
    [
        (['follow', '--worlds', 'forest'], 2),
        (['follow', '--length', '1'], 2),
        (['follow', '--clouds', '1.5'], 2),
        (['follow', '--time', 'teatime'], 2),
        (['follow', '--size', '10x10'], 2),
        (['follow', '--out', '/dev/null/plots'], 1),
        (['home', '--min-distance', '5', '--max-distance', '4'], 2),
        (['home', '--starts', '0'], 2),
        (['home', '--worlds', 'garden', 'moon'], 2),
        (['home', '--out', '/dev/null/plots'], 1),
    ],
)
def test_bad_arguments_give_one_line(arguments, code, capsys):
    assert main(['eval', *arguments]) == code
    stderr = capsys.readouterr().err
    assert one_line_error(stderr), stderr
    assert stderr.startswith(f'skynav eval {arguments[0]}: error: ')
