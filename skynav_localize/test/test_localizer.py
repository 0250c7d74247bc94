# SPDX-License-Identifier: Apache-2.0
"""The Localizer on a synthetic route: rotated queries found, off-route queries rejected, online = offline."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skynav_core.maps import ODOM_POSE, MapError, MapStore
from skynav_localize.eval.baselines import BASELINE_METHODS, EVALUATED_METHODS, snapshot_descriptors
from skynav_localize.localizer import METHODS, OUR_METHODS, Localizer, method, register
from skynav_localize.mapping import SnapshotSelector, create_map
from skynav_localize.matching import Acceptance

DEGREE = 10
SNAPSHOTS = 150
SPACING = 0.1  # m between snapshots along x
QUERY_START, QUERY_SPEED, QUERIES = 5.0, 1.3, 60  # snapshots, snapshots per query frame, frames


@pytest.fixture
def route(make_route):
    return make_route(SNAPSHOTS, DEGREE, 0.4, seed=1)


@pytest.fixture
def store(route, tmp_path):
    with create_map(tmp_path / 'route.db', 'route', DEGREE) as writer:
        for i, coefficients in enumerate(route):
            writer.add_snapshot(
                coefficients, i, np.array([SPACING * i, 0, 0, 0, 0, 0, 1.0]), snapshot_descriptors(coefficients, DEGREE)
            )
    return MapStore.open(tmp_path / 'route.db')


def repeat_drive(route: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Return views between the snapshots (a repeat at another speed), each turned at random and noisy."""
    rng = np.random.default_rng(seed)
    position = QUERY_START + QUERY_SPEED * np.arange(QUERIES)
    low = np.floor(position).astype(int)
    weight = (position - low)[:, None]
    views = (1 - weight) * route[low] + weight * route[low + 1]
    views += 0.02 * rng.standard_normal(views.shape) * np.linalg.norm(route[0])
    rotations = Rotation.random(QUERIES, random_state=seed).as_matrix()
    from skynav_sh.rotation import rotate

    return np.array([rotate(v, r) for v, r in zip(views, rotations)]), position


@pytest.mark.parametrize('name', OUR_METHODS)
def test_turned_repeat_drive_is_localized_and_online_equals_offline(store, route, name):
    views, truth = repeat_drive(route, seed=2)
    localizer = Localizer(store, name)
    offline = localizer.match_sequence(views)
    online = [localizer.query(v) for v in views]
    np.testing.assert_array_equal([m.index for m in online], offline.index)
    # the same numbers, summed in another order (matrix-vector vs matrix-matrix): rounding of the method's dtype
    rounding = 1e-9 if localizer.method.dtype == np.float64 else 1e-5
    np.testing.assert_allclose([m.score for m in online], offline.score, atol=rounding)
    np.testing.assert_array_equal([m.accepted for m in online], offline.accepted)
    settled = np.arange(QUERIES) >= (localizer.sequence.length - 1 if localizer.method.sequence else 0)
    # the true place lies between two snapshots: the match is one of them or a neighbour of one of them
    assert np.all(np.abs(offline.index[settled] - truth[settled]) <= 1.5)
    assert np.all(offline.accepted[settled])
    first = online[-1]
    assert first.candidate_indices[0] == first.index and len(first.candidate_indices) == localizer.candidates
    assert np.all(np.diff(first.candidate_distances) >= 0)


@pytest.mark.parametrize('name', OUR_METHODS)
def test_off_route_views_are_not_accepted(store, make_route, make_view, name):
    localizer = Localizer(store, name)
    rng = np.random.default_rng(7)
    elsewhere = make_route(30, DEGREE, 0.4, seed=99)  # a drive somewhere else: a route of its own
    matches = localizer.match_sequence(elsewhere)
    assert not np.any(matches.accepted)
    single = Localizer(store, name)
    assert not any(single.query(make_view(DEGREE, rng)).accepted for _ in range(20))


@pytest.mark.parametrize('name', ['amplitude-seq', 'bispectrum-seq'])
def test_where_every_place_looks_alike_only_a_steady_drive_is_accepted(make_view, tmp_path, name):
    # a route whose snapshots are all one view plus noise: the nearest snapshot elsewhere on the route is as close
    # as the next one, and no place stands out. Views taken exactly at the snapshots still single each one out
    from skynav_sh.basis import degree_order

    rng = np.random.default_rng(3)
    degree_scale = 1.0 + degree_order(DEGREE)[0]
    alike = make_view(DEGREE, rng) + 0.05 * rng.standard_normal((80, (DEGREE + 1) ** 2)) / degree_scale
    with create_map(tmp_path / 'alike.db', 'alike', DEGREE) as writer:
        for i, coefficients in enumerate(alike):
            writer.add_snapshot(coefficients, i)
    store = MapStore.open(writer.path)
    localizer = Localizer(store, name)
    assert np.min(localizer.self_similarity(np.arange(len(alike)))) > METHODS[name].acceptance.max_self_similarity
    noise = 0.002 * rng.standard_normal((40, alike.shape[1])) / degree_scale
    # driving along it, one snapshot per view: accepted once a whole sequence of views vouched for the drive
    steady = 5 + np.arange(40)
    offline = localizer.match_sequence(alike[steady] + noise)
    np.testing.assert_array_equal(offline.accepted, np.arange(40) >= localizer.sequence.length - 1)
    assert np.all(np.abs(offline.index - steady) <= 2)
    online = Localizer(store, name)
    np.testing.assert_array_equal([online.query(v).accepted for v in alike[steady] + noise], offline.accepted)
    # standing at one place (or views biased onto it while the robot drives): the matches never move along the
    # route as a sequence assumes, and nothing is accepted; the ratio tests alone accepted some of them
    stalled = 40 + np.tile([0, 1, -1, 0], 10)
    assert not np.any(Localizer(store, name).match_sequence(alike[stalled] + noise).accepted)
    ratios = METHODS[name].acceptance
    only_ratios = Acceptance(ratios.max_score, max_view_score=ratios.max_view_score)
    assert (
        np.count_nonzero(Localizer(store, name, acceptance=only_ratios).match_sequence(alike[stalled] + noise).accepted)
        >= 2
    )


def test_empty_map_and_missing_baseline_data(tmp_path, route):
    with MapStore.create(tmp_path / 'empty.db', 'empty', DEGREE) as writer:
        pass
    empty = MapStore.open(writer.path)
    for name in ('amplitude', 'amplitude-seq', 'bispectrum'):
        match = Localizer(empty, name).query(route[0])
        assert match.index == -1 and match.distance == math.inf and not match.accepted
        assert len(match.candidate_indices) == 0 and len(match.candidate_distances) == 0
    assert len(Localizer(empty, 'amplitude').match_sequence(route[:3])) == 3
    with MapStore.create(tmp_path / 'sh.db', 'sh', DEGREE) as writer:
        writer.add_snapshot(route[0], 0)
    sh_only = MapStore.open(writer.path)
    with pytest.raises(MapError, match='needs raw UV descriptors .* --baselines'):
        Localizer(sh_only, 'seqslam-raw-uv')
    with pytest.raises(MapError, match='needs ORB descriptors .* --baselines'):
        Localizer(sh_only, 'bow-orb')
    # SH descriptors are derived from the coefficients when the map does not store them
    one = Localizer(sh_only, 'amplitude').query(route[0])
    assert one.index == 0 and one.distance == pytest.approx(0.0, abs=1e-7) and one.score == 0.0
    with pytest.raises(ValueError, match='needs SH coefficients'):
        Localizer(sh_only, 'amplitude').query()
    with pytest.raises(ValueError, match='unknown localization method'):
        method('nearest-neighbour')


def test_method_table_is_honest():
    assert set(OUR_METHODS) == {'amplitude', 'amplitude-seq', 'bispectrum', 'bispectrum-seq'}
    assert tuple(METHODS) == OUR_METHODS  # the product's registry: what the node may run, no baseline
    assert set(BASELINE_METHODS) == {'raw-uv', 'seqslam-raw-uv', 'bow-orb'}
    assert tuple(EVALUATED_METHODS) == OUR_METHODS + BASELINE_METHODS
    assert all(EVALUATED_METHODS[name].source == 'uv' for name in BASELINE_METHODS)
    assert EVALUATED_METHODS['seqslam-raw-uv'].sequence and not EVALUATED_METHODS['bow-orb'].sequence
    assert EVALUATED_METHODS['raw-uv'].label == 'raw-uv (baseline)'
    assert method('bow-orb') is EVALUATED_METHODS['bow-orb']  # registered by the laboratory
    with pytest.raises(ValueError, match="'amplitude' is one of skynav's own"):
        register(dataclasses.replace(METHODS['amplitude'], baseline=True))


def test_the_localize_node_loads_no_baseline_and_no_evaluation():
    code = 'import sys, skynav_localize.node; print(sorted(m for m in sys.modules if m.startswith("skynav_")))'
    loaded = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True).stdout
    assert 'skynav_localize.localizer' in loaded
    assert 'skynav_localize.eval' not in loaded


def test_snapshot_selector_by_travel_and_by_view_change():
    selector = SnapshotSelector(min_travel=0.5, min_change=0.2)
    a, b = np.array([1.0, 0.0]), np.array([0.0, 1.0])
    assert selector.keep(a, np.zeros(3))  # the first frame always
    assert not selector.keep(a, np.array([0.3, 0, 0]))
    assert selector.keep(a, np.array([0.6, 0, 0]))  # 0.6 m from the last snapshot
    assert selector.keep(b, np.array([0.7, 0, 0]))  # the view changed
    assert not selector.keep(b, None)  # no position, same view


def test_stored_and_derived_descriptors_match_alike(store, route, tmp_path):
    with MapStore.create(tmp_path / 'coefficients.db', 'route', DEGREE) as writer:
        for i, coefficients in enumerate(route):
            writer.add_snapshot(coefficients, i)  # as `skynav map build` writes them: no descriptors
    derived = MapStore.open(writer.path)
    assert derived.descriptor_names() == [] and set(store.descriptor_names()) == {'amplitude', 'bispectrum'}
    views, _ = repeat_drive(route, seed=3)
    for name in OUR_METHODS:
        ours, theirs = Localizer(derived, name), Localizer(store, name)
        np.testing.assert_allclose(ours.index.matrix, theirs.index.matrix, atol=1e-12)
        a, b = ours.match_sequence(views), theirs.match_sequence(views)
        np.testing.assert_array_equal(a.index, b.index)
        np.testing.assert_array_equal(a.accepted, b.accepted)


def featureless_route(route: np.ndarray, blank: np.ndarray, share: float = 1.0) -> np.ndarray:
    """Return the route with the views at `blank` given sky share `share` of a hemisphere (0: all ground, 1: all sky).

    Only c_00 changes, which no descriptor uses: the rule that such views hold nothing is all that can tell them apart.
    """
    out = route.copy()
    out[blank, 0] = share * 2 * np.pi / np.sqrt(4 * np.pi)  # c_00 of that much sky seen up to 90 degrees
    return out


@pytest.mark.parametrize('name', OUR_METHODS)
def test_views_and_snapshots_without_a_skyline_are_never_accepted(route, name, tmp_path):
    fov = np.pi  # the views' field of view (rad): a hemisphere
    route = featureless_route(route, np.ones(SNAPSHOTS, bool), 0.5)  # half sky: every view shows a skyline
    with create_map(tmp_path / 'route.db', 'route', DEGREE) as writer:
        for i, coefficients in enumerate(route):
            writer.add_snapshot(coefficients, i)
    store = MapStore.open(writer.path)
    normal, _ = repeat_drive(route, seed=2)
    blank = np.zeros(QUERIES, bool)
    blank[[20, 21, 40]] = True
    reference = Localizer(store, name).match_sequence(normal, field_of_view=fov)
    assert np.all(reference.accepted[blank])
    for share in (0.0, 1.0):  # all ground, all sky
        queries = featureless_route(normal, blank, share)
        judged = Localizer(store, name).match_sequence(queries, field_of_view=fov)
        assert not np.any(judged.accepted[blank])
        np.testing.assert_array_equal(judged.accepted[~blank], reference.accepted[~blank])
        np.testing.assert_array_equal(judged.index, reference.index)  # matched all the same
        online = Localizer(store, name)
        matches = [online.query(q, field_of_view=fov) for q in queries]
        np.testing.assert_array_equal([m.accepted for m in matches], judged.accepted)
        assert not np.any(Localizer(store, name).match_sequence(queries).accepted != reference.accepted)  # no fov
    # snapshots without a skyline: a match on one is not accepted either
    with create_map(tmp_path / 'blank.db', 'blank', DEGREE) as writer:
        for i, coefficients in enumerate(featureless_route(route, np.arange(SNAPSHOTS) % 10 == 0)):
            writer.add_snapshot(coefficients, i)
    matches = Localizer(MapStore.open(writer.path), name).match_sequence(normal, field_of_view=fov)
    on_blank = matches.index % 10 == 0
    assert np.any(on_blank) and not np.any(matches.accepted[on_blank])
    np.testing.assert_array_equal(matches.accepted[~on_blank], reference.accepted[~on_blank])


def test_a_map_and_views_of_a_higher_degree_are_cut_to_the_descriptor_degree(route, store, tmp_path):
    # the same route at degree 10 plus made-up degrees 11-12: a degree-10 Localizer must not see the extra degrees
    rng = np.random.default_rng(5)
    extra = rng.normal(size=(len(route), (DEGREE + 3) ** 2 - (DEGREE + 1) ** 2))
    higher = np.concatenate([route, extra], axis=1)
    with create_map(tmp_path / 'higher.db', 'higher', DEGREE + 2) as writer:
        for i, coefficients in enumerate(higher):
            writer.add_snapshot(coefficients, i, np.array([SPACING * i, 0, 0, 0, 0, 0, 1.0]))
    queries, _ = repeat_drive(route, seed=3)
    queries_higher = np.concatenate([queries, rng.normal(size=(len(queries), extra.shape[1]))], axis=1)
    for name in OUR_METHODS:
        reference = Localizer(store, name).match_sequence(coefficients=queries)
        cut = Localizer(MapStore.open(tmp_path / 'higher.db'), name, degree=DEGREE)
        assert cut.degree == DEGREE
        matches = cut.match_sequence(coefficients=queries_higher)
        np.testing.assert_array_equal(matches.index, reference.index)
        np.testing.assert_array_equal(matches.accepted, reference.accepted)
        full = Localizer(MapStore.open(tmp_path / 'higher.db'), name, degree=64)
        assert full.degree == DEGREE + 2  # never above the map's


@pytest.fixture
def route_back(make_route, tmp_path):
    """A taught route of 150 snapshots whose last 50 pass the places of snapshots 20-69 again, with its odometry."""
    first = make_route(100, DEGREE, 0.4, seed=5)
    coefficients = np.concatenate([first, first[20:70]])
    with create_map(tmp_path / 'back.db', 'back', DEGREE) as writer:
        for i, c in enumerate(coefficients):
            writer.add_snapshot(c, i, None, {ODOM_POSE: np.array([SPACING * i, 0, 0, 0, 0, 0, 1.0])})
    return MapStore.open(writer.path), coefficients


@pytest.mark.parametrize('odometry', [True, False], ids=['odometry', 'views'])
def test_tracking_follows_a_route_past_its_look_alikes(route_back, odometry):
    # driving snapshots 5..64 at one snapshot per view: from 20 on, every place has a twin 80 snapshots on, and the
    # ratio tests cannot tell them apart. Tracking seeks each view near the last accepted match and stays on the drive
    store, coefficients = route_back
    rng = np.random.default_rng(4)
    truth = np.arange(5, 65)
    views = coefficients[truth] + 0.01 * rng.standard_normal((truth.size, coefficients.shape[1]))
    travelled = SPACING * truth + 0.02 * rng.standard_normal(truth.size)  # the drive's own odometry, noisy

    def drive(tracking: bool) -> list:
        localizer = Localizer(store, 'amplitude-seq')
        localizer.tracking = tracking
        return [localizer.query(v, travelled=float(t) if odometry else None) for v, t in zip(views, travelled)]

    twins = truth >= 20 + Localizer(store, 'amplitude-seq').sequence.length
    untracked = drive(tracking=False)
    assert not any(m.accepted for m, twin in zip(untracked, twins) if twin)
    tracked = drive(tracking=True)
    accepted = np.array([m.accepted for m in tracked])
    index = np.array([m.index for m in tracked])
    assert np.all(accepted[twins])
    assert np.all(np.abs(index[accepted] - truth[accepted]) <= 2)


def test_tracking_from_a_start_places_the_robot_where_the_route_looks_alike(route_back):
    # standing at snapshot 30, whose twin is snapshot 110: the ratio tests refuse every view, and a start names the
    # place. The same views tracked from snapshot 110 (the goal says so) are sought there instead
    store, coefficients = route_back
    rng = np.random.default_rng(8)
    views = coefficients[30] + 0.01 * rng.standard_normal((5, coefficients.shape[1]))
    for start, twin in ((30, 110), (110, 30)):
        localizer = Localizer(store, 'amplitude-seq')
        localizer.track_from(start)
        localizer.reset()  # a gap in the views before the first: the robot still stands at the start
        matches = [localizer.query(v, travelled=0.0) for v in views]
        assert all(m.accepted for m in matches)
        assert all(abs(m.index - start) <= 2 for m in matches) and not any(abs(m.index - twin) <= 2 for m in matches)
    untracked = Localizer(store, 'amplitude-seq')
    assert not any(untracked.query(v).accepted for v in views)


def test_tracking_starts_only_from_an_accepted_match(route_back):
    # on the look-alike stretch from the start, nothing was accepted yet: tracking has no place to seek near
    store, coefficients = route_back
    localizer = Localizer(store, 'amplitude-seq')
    localizer.tracking = True
    matches = [localizer.query(c, travelled=SPACING * i) for i, c in enumerate(coefficients[30:60], start=30)]
    assert not any(m.accepted for m in matches)


def test_tracking_past_the_route_end_matches_the_views_to_the_last_snapshot(make_route, tmp_path):
    # a robot drives the last 30 snapshots of a route with odometry, then on past its end (odometry 1 m beyond it)
    # while its views still show the end. The tracking window then holds the last snapshot alone: every view there is
    # matched to it (the best candidate, a ratio below 1), not to whatever the window's end leaves
    coefficients = make_route(60, DEGREE, 0.4, seed=5)
    with create_map(tmp_path / 'end.db', 'end', DEGREE) as writer:
        for i, c in enumerate(coefficients):
            writer.add_snapshot(c, i, None, {ODOM_POSE: np.array([SPACING * i, 0, 0, 0, 0, 0, 1.0])})
    last = coefficients.shape[0] - 1
    shown = np.concatenate([np.arange(30, last + 1), np.full(10, last)])
    travelled = SPACING * np.concatenate([np.arange(30, last + 1), last + np.arange(1, 11)])
    rng = np.random.default_rng(3)
    views = coefficients[shown] + 0.01 * rng.standard_normal((shown.size, coefficients.shape[1]))
    localizer = Localizer(MapStore.open(writer.path), 'amplitude-seq')
    localizer.tracking = True
    matches = [localizer.query(v, travelled=float(t)) for v, t in zip(views, travelled)]
    at_end = [m for m, s in zip(matches, shown) if s == last]
    assert all(m.accepted and m.index == last for m in at_end)
    assert [int(m.candidate_indices[0]) for m in at_end] == [last] * len(at_end)
    assert all(m.score < 1.0 for m in at_end)
