# SPDX-License-Identifier: Apache-2.0
"""Repeat drives with a detour: off the taught route in free space, back on it, and labelled so evaluations can tell."""

import numpy as np
import pytest

from skynav_sim.scenarios import ScenarioParameters, build, describe
from skynav_sim.world import generate
from skynav_testing import one_line_error, run_skynav

ROUTE = dict(route_length=8.0, speed=0.9, offset=0.25)  # the bundled garden repeat drive's route and offset


@pytest.fixture(scope='module')
def garden():
    return generate('garden', 1)


def positions(frames) -> np.ndarray:
    """Return the frames' camera positions (x, y) in m."""
    return np.array([f.pose.position[:2] for f in frames])


def distance_to(points: np.ndarray, route: np.ndarray) -> np.ndarray:
    """Return each point's distance (m) to the nearest of the route's points."""
    return np.min(np.linalg.norm(points[:, None] - route[None], axis=-1), axis=1)


@pytest.mark.parametrize('reach', [2.0, 4.0])
def test_a_detour_leaves_the_route_in_free_space_and_comes_back(garden, reach):
    taught = positions(build('teach', garden, ScenarioParameters(route_length=8.0, speed=0.1), seed=1))
    plain = build('repeat', garden, ScenarioParameters(**ROUTE), seed=1)
    frames = build('repeat', garden, ScenarioParameters(**ROUTE, detour=reach), seed=1)
    labels = np.array([f.label for f in frames])
    on_loop = np.flatnonzero(labels == 'detour')
    # route, one loop, route: one block of detour frames between two blocks of route frames
    assert on_loop.size > 0 and np.all(np.diff(on_loop) == 1) and 0 < on_loop[0] and on_loop[-1] < len(frames) - 1
    assert set(labels) == {'route', 'detour'}
    where = positions(frames)
    assert np.all(garden.is_free(where[:, 0], where[:, 1]))
    gap = distance_to(where, taught)
    assert reach - 0.5 < gap[on_loop].max() < reach + 0.5  # the loop runs out as far as asked
    assert gap[labels == 'route'].max() < 0.5  # elsewhere the drive keeps to the route (0.25 m beside it)
    # the same drive as without the detour up to where the loop leaves, and the same end
    np.testing.assert_allclose(where[: on_loop[0]], positions(plain)[: on_loop[0]], atol=1e-9)
    assert np.linalg.norm(where[-1] - positions(plain)[-1]) < 0.9 / 10 + 1e-9
    # a frame every 0.09 m of travel (speed / frame rate), the loop and its ends included: no jump, no stop
    step = np.linalg.norm(np.diff(where, axis=0), axis=1)
    assert np.all((0.7 * 0.09 < step) & (step < 1.2 * 0.09))


def test_a_detour_is_reproducible_and_recorded_only_when_used(garden):
    params = ScenarioParameters(**ROUTE, shake=3.0, wobble=25.0, detour=3.0)
    one, two = (build('repeat', garden, params, seed=1) for _ in range(2))
    assert all(np.array_equal(a.pose.position, b.pose.position) and a.label == b.label for a, b in zip(one, two))
    assert describe('repeat', garden, params, 1, one)['parameters']['detour'] == 3.0
    # recordings made before detours existed regenerate byte for byte: no detour, no entry
    plain = ScenarioParameters(**ROUTE)
    assert 'detour' not in describe('repeat', garden, plain, 1, build('repeat', garden, plain, seed=1))['parameters']


@pytest.mark.parametrize(('detour', 'text'), [('-1', 'must be 0 (none) or positive'), ('40', 'no free room')])
def test_impossible_detours_are_refused_in_one_line(tmp_path, detour, text):
    out = tmp_path / 'never.mcap'
    result = run_skynav(
        'sim',
        'bag',
        'repeat',
        '--world',
        'garden',
        '--seed',
        '1',
        '--size',
        '96x72',
        '--length',
        '8',
        '--detour',
        detour,
        '--out',
        str(out),
    )
    assert result.returncode == 2 and text in result.stderr and one_line_error(result.stderr), result.stderr
    assert list(tmp_path.iterdir()) == []
