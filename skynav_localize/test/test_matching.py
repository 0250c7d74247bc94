# SPDX-License-Identifier: Apache-2.0
"""Matching: nearest snapshot with the ratio test, SeqSLAM trajectories, online = offline."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skynav_localize.matching import (
    MOTION_SLACK,
    TRACKING_PULL,
    TRACKING_SLACK,
    TRACKING_SLIP,
    TRACKING_VIEWS,
    Acceptance,
    RouteTracker,
    SequenceBuffer,
    SequenceParams,
    best_candidates,
    contrast_normalise,
    displaced_ratios,
    distance_ratio,
    local_steps,
    motion_tests,
    motion_window,
    runner_up,
    self_similarity,
    sequence_match,
    sequence_scores,
    single_frame,
    trajectory_scores,
    view_change,
    view_in_place,
)

SNAPSHOTS = 200
QUERIES = 60
START = 20  # snapshot of the first query


def diagonal_with_decoys(speed: float, seed: int, decoys: int = 3, noise: float = 0.15) -> tuple[np.ndarray, ...]:
    """Return a distance matrix (Q, N) whose true match moves `speed` snapshots per query, and the true indices.

    Distance grows with the gap to the true place, noise is added, and every query has `decoys` random snapshots
    that look perfect (distance 0): perceptual aliasing that fools a single frame but does not line up in time.
    """
    rng = np.random.default_rng(seed)
    truth = START + speed * np.arange(QUERIES)
    gap = np.abs(np.arange(SNAPSHOTS)[None, :] - truth[:, None])
    distances = np.minimum(0.1 * gap, 1.0) + noise * rng.random((QUERIES, SNAPSHOTS))
    rows = np.repeat(np.arange(QUERIES), decoys)
    distances[rows, rng.integers(0, SNAPSHOTS, rows.size)] = 0.0
    return distances, truth


@pytest.mark.parametrize('speed', [1.5, 0.7])
def test_seqslam_recovers_the_diagonal_that_single_frames_miss(speed):
    distances, truth = diagonal_with_decoys(speed, seed=int(speed * 10))
    params = SequenceParams(length=10, min_speed=0.5, max_speed=2.0)
    values, choice = sequence_scores(distances, params)
    best, _, _ = sequence_match(values, choice, exclusion=10 + params.extent())
    settled = np.arange(QUERIES) >= params.length - 1  # a full sequence behind the query
    # the true place lies between two snapshots: the match is one of them or a neighbour of one of them
    assert np.all(np.abs(best[settled] - truth[settled]) <= 1.5)
    single, _, _ = single_frame(distances)
    assert np.mean(np.abs(single - truth) > 1.5) > 0.5  # the decoys do fool single frames


def test_contrast_normalisation_removes_a_stretch_of_the_route_that_resembles_everything():
    # the true place's distance bottoms out at 0.3 (another time of day), while snapshots 120..179 sit at 0.25 for
    # every query (a stretch of featureless route): raw distances, even in sequences, prefer that stretch; within
    # a window of snapshots it is flat and the true valley stands out
    rng = np.random.default_rng(8)
    truth = START + 1.3 * np.arange(QUERIES)
    gap = np.abs(np.arange(SNAPSHOTS)[None, :] - truth[:, None])
    distances = np.minimum(0.3 + 0.14 * gap, 1.0)
    distances[:, 120:180] = 0.25
    distances += 0.05 * rng.random(distances.shape)
    settled = np.arange(QUERIES) >= 9
    for window, expect_right in ((0, False), (10, True)):
        params = SequenceParams(length=10, window=window)
        best, _, _ = sequence_match(*sequence_scores(distances, params), exclusion=10 + params.extent())
        right = np.abs(best[settled] - truth[settled]) <= 1.5
        assert np.all(right) if expect_right else not np.any(right)


def test_trajectory_scores_by_brute_force():
    rng = np.random.default_rng(1)
    values = rng.random((7, 15))
    params = SequenceParams(length=4, min_speed=0.5, max_speed=2.0)
    expected = np.full(values.shape, np.inf)
    for t in range(7):
        for j in range(15):
            for speed_offsets in params.offsets():
                steps = range(min(t + 1, params.length))
                mean = np.mean([values[t - k, max(j - speed_offsets[k], 0)] for k in steps])
                expected[t, j] = min(expected[t, j], mean)
    np.testing.assert_allclose(trajectory_scores(values, params), expected, atol=1e-12)


def test_speed_offsets_cover_the_range_once():
    offsets = SequenceParams(length=10, min_speed=0.5, max_speed=2.0).offsets()
    assert np.all(offsets[:, 0] == 0)
    assert len(np.unique(offsets, axis=0)) == len(offsets)
    assert set(offsets[:, -1]) == set(range(5, 19))  # every whole number of snapshots in 0.5 x 9 .. 2 x 9
    assert SequenceParams(length=10, min_speed=0.5, max_speed=2.0).extent() == 18
    with pytest.raises(ValueError):
        SequenceParams(min_speed=2.0, max_speed=1.0)


@pytest.mark.parametrize('window', [0, 5])
def test_online_buffer_equals_offline_scores(window):
    distances, _ = diagonal_with_decoys(1.2, seed=4)
    params = SequenceParams(length=6, min_speed=0.8, max_speed=1.6, window=window)
    values, choice = sequence_scores(distances, params)
    buffer = SequenceBuffer(params)
    for q, row in enumerate(distances):
        online_values, online_choice = buffer.push(row)
        np.testing.assert_allclose(online_values, values[q], atol=1e-12)
        np.testing.assert_allclose(online_choice, choice[q], atol=1e-12)
    assert len(buffer) == params.length
    buffer.clear()
    assert len(buffer) == 0


def test_contrast_normalisation_by_brute_force():
    rng = np.random.default_rng(2)
    rows = rng.random((3, 30)) + np.linspace(0, 2, 30)
    window = 4
    normalised = contrast_normalise(rows, window)
    for q in range(3):
        for j in range(30):
            low = min(max(j - window, 0), 30 - (2 * window + 1))
            part = rows[q, low : low + 2 * window + 1]
            assert normalised[q, j] == pytest.approx((rows[q, j] - part.mean()) / part.std(), abs=1e-9)


def test_ratio_score_and_runner_up():
    distances = np.array([[0.5, 0.1, 0.12, 0.9, 0.4, 0.8]])
    assert runner_up(distances, np.array([1]), exclusion=1)[0] == pytest.approx(0.4)
    best, best_distance, ratio = single_frame(distances, exclusion=1)
    assert best[0] == 1 and best_distance[0] == pytest.approx(0.1) and ratio[0] == pytest.approx(0.25)
    assert runner_up(distances, np.array([1]), exclusion=10)[0] == np.inf
    np.testing.assert_array_equal(distance_ratio([0.1, 0.0, 0.2], [np.inf, 0.0, 0.4]), [0.0, 1.0, 0.5])


def test_best_candidates_best_first():
    indices, values = best_candidates(np.array([0.3, 0.1, 0.2, 0.1, 0.9]), 3)
    np.testing.assert_array_equal(indices, [1, 3, 2])
    np.testing.assert_allclose(values, [0.1, 0.1, 0.2])
    assert len(best_candidates(np.array([0.5, 0.4]), 10)[0]) == 2
    assert len(best_candidates(np.zeros(0), 5)[0]) == 0


def test_acceptance_is_vectorised():
    acceptance = Acceptance(max_score=0.5, max_distance=0.2)
    np.testing.assert_array_equal(
        acceptance.accepts(np.array([0.4, 0.6, 0.4]), np.array([0.1, 0.1, 0.3])), [True, False, False]
    )


def test_acceptance_checks_the_newest_view_where_it_is_asked_to():
    acceptance = Acceptance(max_score=0.4, max_view_score=0.45)
    scores, distances, views = np.array([0.1, 0.1, 0.5]), np.array([0.1, 0.1, 0.1]), np.array([0.3, 0.6, 0.3])
    np.testing.assert_array_equal(acceptance.accepts(scores, distances, views), [True, False, False])
    np.testing.assert_array_equal(Acceptance(max_score=0.4).accepts(scores, distances, views), [True, True, False])


def test_the_newest_view_chooses_its_snapshot_within_the_sequence_place():
    # snapshot 12 is the view's best within 10 of the sequence's choice (15); snapshot 40 looks better still but
    # lies in another place, so it is the runner-up of the view's ratio, not its match
    row = np.full(60, 1.0)
    row[[12, 15, 40]] = [0.2, 0.3, 0.1]
    index, distance, ratio, place = view_in_place(row[None, :], np.array([15]), exclusion=10)
    assert index[0] == 12 and distance[0] == pytest.approx(0.2) and ratio[0] == pytest.approx(2.0)
    assert np.all(np.isinf(place[0, :5])) and np.all(np.isinf(place[0, 26:])) and place[0, 12] == pytest.approx(0.2)
    row[40] = 0.8  # without the better place elsewhere the view vouches for its snapshot: ratio 0.2 / 0.8
    assert view_in_place(row[None, :], np.array([15]), exclusion=10)[2][0] == pytest.approx(0.25)


def test_the_route_step_is_the_median_between_successive_snapshots_within_the_place():
    steps = np.array([1.0, 1.0, 1.0, 9.0, 1.0, 2.0, 2.0])  # between snapshots 0-1, ..., 6-7
    # exclusion 1: the steps on either side of a snapshot (one at the ends); exclusion 2: up to four of them
    np.testing.assert_allclose(local_steps(steps, 1), [1.0, 1.0, 1.0, 5.0, 5.0, 1.5, 2.0, 2.0])
    np.testing.assert_allclose(local_steps(steps, 2), [1.0, 1.0, 1.0, 1.0, 1.5, 2.0, 2.0, 2.0])
    assert local_steps(np.zeros(0), 10).shape == (1,)
    # a place whose nearest look-alike is three steps away, one as close as its next snapshot, one with none
    np.testing.assert_allclose(
        self_similarity(np.array([1.0, 1.0, 1.0]), np.array([3.0, 1.0, np.inf])), [1 / 3, 1.0, 0.0]
    )


PARAMS = SequenceParams(length=10, min_speed=0.5, max_speed=2.0)


def test_motion_of_a_steady_drive_is_consistent_and_steady():
    indices = 5 + np.round(0.7 * np.arange(30))  # 0.7 snapshots per view, as the bundled repeat drives
    consistent, steady = motion_tests(indices, np.ones(30, bool), PARAMS)
    assert np.all(consistent)
    np.testing.assert_array_equal(steady, np.arange(30) >= PARAMS.length - 1)  # a full sequence behind the view
    # every fifth view not vouching (two of a sequence's ten) changes nothing; every third (three or four) leaves it
    # unsure: too few views vouched for the drive
    assert np.all(motion_tests(indices, np.arange(30) % 5 != 1, PARAMS)[1][PARAMS.length - 1 :])
    assert not np.any(motion_tests(indices, np.arange(30) % 3 != 1, PARAMS)[1])


def test_motion_of_a_stalled_or_jittering_sequence_is_neither():
    # a sequence stuck near one snapshot while the robot drives (views biased onto another stretch of a route that
    # looks alike): its vouched snapshots jitter about 3 by one, never advancing
    indices = 3 + np.tile([0, 1, -1], 10)
    consistent, steady = motion_tests(indices, np.ones(30, bool), PARAMS)
    assert not np.any(steady)
    assert not np.any(consistent[PARAMS.length - 1 :])  # 4.5 snapshots of travel expected over 9 views
    assert np.all(consistent[:3])  # a few views cannot tell a stall from the slack
    # the same against views that did not vouch: nothing to contradict
    assert np.all(motion_tests(indices, np.zeros(30, bool), PARAMS)[0])
    # standing still for ten views, then two snapshots on within the slack (a robot leaving the route sideways):
    # the slack hides a stall for 6 views, so the test looks back twice as far
    assert motion_window(PARAMS) == 12
    stall_and_jump = np.array([8] * 12 + [9, 10], float)
    assert not motion_tests(stall_and_jump, np.ones(14, bool), PARAMS)[0][-1]
    # random jitter by up to two snapshots: never steady, and mostly inconsistent
    rng = np.random.default_rng(4)
    jitter = 3 + rng.integers(-2, 3, 30)
    consistent, steady = motion_tests(jitter, np.ones(30, bool), PARAMS)
    assert not np.any(steady) and np.mean(consistent[PARAMS.length - 1 :]) < 0.2


def test_motion_refuses_a_jump_back_from_what_views_vouched_for_but_not_a_return_after_a_detour():
    indices = np.array([30, 31, 32, 33, 34, 35, 10, 11, 12, 13], float)  # jumps 25 snapshots back after view 5
    vouched = np.ones(10, bool)
    consistent, _ = motion_tests(indices, vouched, PARAMS)
    assert np.all(consistent[:6]) and not np.any(consistent[6:])
    # the same jump after views that did not vouch (off the route), or ahead (a robot faster than the sequence
    # assumes: the view's choice within the place follows it), contradicts nothing
    assert np.all(motion_tests(indices, np.arange(10) >= 6, PARAMS)[0])
    assert np.all(motion_tests(indices[::-1] + 3 * np.arange(10), vouched, PARAMS)[0])
    backwards = np.arange(33, 23, -1, dtype=float)  # a view per snapshot backwards: within the slack for two views
    assert not np.any(motion_tests(backwards, vouched, PARAMS)[0][3:])
    # after a detour no view vouched for its snapshot: the first view back is judged on its own
    rejoin = np.array([50, 44, 46, 52, 38, 40, 12, 13, 14, 15], float)
    vouched_rejoin = np.arange(10) >= 6
    consistent, steady = motion_tests(rejoin, vouched_rejoin, PARAMS)
    assert np.all(consistent[6:]) and not np.any(steady)
    assert MOTION_SLACK == 3


def test_acceptance_where_the_route_looks_alike():
    acceptance = Acceptance(max_score=0.4, max_view_score=0.45, motion_slack=3, max_self_similarity=0.3)
    consistent = np.array([True, True, True, False, False])
    steady = np.array([False, True, False, True, False])
    alike = np.array([0.5, 0.5, 0.1, 0.1, 0.1])  # the place looks like another stretch, or stands out
    np.testing.assert_array_equal(
        acceptance.passes_place_tests(consistent, steady, alike), [False, True, True, False, False]
    )
    # without motion tests (single frames) only the place counts; without a bound every place stands out
    np.testing.assert_array_equal(
        Acceptance(0.45, max_self_similarity=0.3).passes_place_tests(consistent, steady, alike),
        [False, False, True, True, True],
    )
    assert np.all(Acceptance(0.45).passes_place_tests(consistent, steady, alike))
    # a view vouches by its own ratio at the snapshot it chose (sequences), or by the match's ratio (single frames)
    np.testing.assert_array_equal(acceptance.vouches(np.array([0.1, 0.9]), np.array([0.5, 0.3])), [False, True])
    np.testing.assert_array_equal(Acceptance(0.45).vouches(np.array([0.1, 0.9])), [True, False])


def test_acceptance_bounds_the_relative_distance_and_the_displaced_ratio_of_a_distinct_place():
    acceptance = Acceptance(0.4, max_view_score=0.45, motion_slack=3, max_self_similarity=0.3, max_displaced_ratio=2.0)
    consistent = np.ones(4, dtype=bool)
    steady = np.array([False, False, True, False])
    alike = np.full(4, 0.1)  # every place stands out by its look-alike elsewhere
    displaced = np.array([0.5, 3.0, 3.0, 2.0])  # above 2: a metre from the place, views look like elsewhere
    np.testing.assert_array_equal(
        acceptance.passes_place_tests(consistent, steady, alike, displaced), [True, False, True, True]
    )
    # without the displaced ratios (or without a bound on them) only the self-similarity counts
    assert np.all(acceptance.passes_place_tests(consistent, steady, alike))
    relative = np.array([0.1, 0.33, 0.5, np.inf])
    np.testing.assert_array_equal(
        Acceptance(0.4, max_relative_distance=0.33).passes_relative_distance(relative), [True, True, False, False]
    )
    assert np.all(Acceptance(0.4).passes_relative_distance(relative))


def test_view_change_and_displaced_ratio_of_a_route():
    # snapshots on a line, a metre per snapshot: distances are metres along it, and the view changes evenly
    positions = np.arange(30.0)
    rows = np.abs(positions[:, None] - positions[None, :])
    exclusion = 3
    indices = np.array([0, 10, 29])
    np.testing.assert_allclose(view_change(rows[indices], indices, exclusion), [3.0, 3.0, 3.0])
    assert view_change(rows[:2, :2], np.array([0, 1]), exclusion).tolist() == [0.0, 0.0]  # nothing 3 snapshots on
    # the snapshot 3 after 10 is 3 from it and 4 from the nearest snapshot more than 3 from both (6 or 17): 0.75
    np.testing.assert_allclose(displaced_ratios(rows[[13]], np.array([10]), np.array([13]), exclusion), [0.75])
    # where the route jumps (a view that changes abruptly between 10 and 13), the neighbour resembles the far
    # snapshots more than the place: a ratio above 1
    jump = positions + 20.0 * (positions >= 12)
    rows = np.abs(jump[:, None] - jump[None, :])
    assert displaced_ratios(rows[[13]], np.array([10]), np.array([13]), exclusion)[0] > 1.0


def uneven_route(count: int = 200) -> np.ndarray:
    """Return the distances (m) along a taught route of snapshots about 0.12 m apart, unevenly in places."""
    rng = np.random.default_rng(1)
    return np.concatenate([[0.0], np.cumsum(0.12 + 0.03 * rng.standard_normal(count - 1).clip(-1, 1))])


@pytest.mark.parametrize('driven', [0.0, 0.05, 0.5, 2.0, 8.0])
def test_tracking_window_holds_the_place_odometry_expects_and_widens_with_the_distance(driven):
    # accepted at snapshot 30 at 10 m of the drive's odometry; `driven` m later, unaccepted views in between
    route = uneven_route()
    tracker = RouteTracker(SequenceParams(), route)
    assert tracker.window(10.0) is None  # nothing accepted yet: the whole route
    tracker.update(30, True, 10.0)
    tracker.update(31, False, 10.0 + driven / 2)
    first, last = tracker.window(10.0 + driven)
    expected, reach = route[30] + driven, TRACKING_SLACK + TRACKING_SLIP * driven
    assert route[first] >= expected - reach - 1e-12 and route[last] <= expected + reach + 1e-12
    assert first == 0 or route[first - 1] < expected - reach  # every snapshot within reach is in it
    assert last == route.size - 1 or route[last + 1] > expected + reach
    assert first <= int(np.argmin(np.abs(route - expected))) <= last


def test_a_match_that_stalls_cannot_hold_the_tracked_place_back():
    # the robot drives 0.1 m per view; every view is matched (accepted) to snapshot 30, behind it
    route = 0.1 * np.arange(200)
    tracker = RouteTracker(SequenceParams(), route)
    tracker.update(30, True, 0.0)
    for k in range(1, 41):
        tracker.update(30, True, 0.1 * k)
    # pulled back by at most TRACKING_PULL of each step: the place moved on by at least the rest of the odometry
    assert tracker.place == pytest.approx(route[30] + (1 - TRACKING_PULL) * 4.0)
    first, _ = tracker.window(4.1)
    assert first > 30  # the stalled snapshot has left the window: the next match must move on
    assert tracker.nearest() == int(round(tracker.place / 0.1))
    # matches at the true place (snapshot 30 + k after k views) pull it onto the drive within as many views as the
    # gap takes at TRACKING_PULL x 0.1 m a view; standing still, nothing moves it
    views = round((route[70] - tracker.place) / (TRACKING_PULL * 0.1))
    for k in range(41, 41 + views):
        tracker.update(30 + k, True, 0.1 * k)
    assert tracker.place == pytest.approx(route[30 + 40 + views])
    tracker.update(199, True, 0.1 * (40 + views))
    assert tracker.place == pytest.approx(route[30 + 40 + views])


def test_tracking_window_without_odometry_counts_views_and_ends():
    params = SequenceParams()
    tracker = RouteTracker(params, None)
    tracker.update(40, True, None)
    assert tracker.window(None) == (40 - MOTION_SLACK, 40 + math.ceil(params.max_speed + MOTION_SLACK))
    for _ in range(TRACKING_VIEWS):
        tracker.update(41, False, None)
    assert tracker.window(None) is None  # too long without an accepted match: the whole route again
    tracker.reset()
    assert tracker.window(None) is None


@pytest.mark.parametrize('odometry', [True, False], ids=['odometry', 'views'])
def test_tracking_from_a_start_seeks_the_first_view_near_it(odometry):
    route = 0.1 * np.arange(100)
    tracker = RouteTracker(SequenceParams(), route if odometry else None)
    tracker.start_at(60)
    first, last = tracker.window(5.0 if odometry else None)  # the first view: no step of the odometry yet
    assert first <= 60 <= last and last - first <= 2 * MOTION_SLACK + SequenceParams().max_speed + 1
    tracker.update(61, True, 5.0 if odometry else None)
    first, last = tracker.window(5.1 if odometry else None)
    assert first <= 62 <= last and first > 50  # from then on as after an accepted match
    tracker.reset()
    assert tracker.window(5.1 if odometry else None) is None


def test_tracking_window_ends_at_the_route_end():
    route = 0.1 * np.arange(50)
    tracker = RouteTracker(SequenceParams(), route)
    tracker.update(45, True, 0.0)
    assert tracker.window(3.0) == (49, 49)  # beyond the end: the last snapshot
