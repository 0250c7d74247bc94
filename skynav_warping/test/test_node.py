# SPDX-License-Identifier: Apache-2.0
"""The warping node in the in-process graph: home vectors with and without the compass, route targets, bad input.

The current views are the SH coefficients of bags/synthetic_park_homing.mcap as the installed skyline and SH
nodes give them (degree 16): the 'snapshot' frame, stored as a one-snapshot map, and 40 grid views 0.74-3.2 m
from it. The true home direction is Q_c^-1 (p_s - p_c) normalised. Measured angular errors of the home vector,
median / p90 over the 40 views: 11.2 / 18.3 deg without the compass, 9.4 / 20.8 deg with the compass node in
the same graph (the same figures as `skynav eval homing`, test_cli.py). With the compass, 5 of the 40 views
(2.4-3.2 m away) start from a compass estimate turned ~180 deg and keep it (errors up to 143 deg; residual
0.83-0.91 against 0.5-0.8 elsewhere). At the snapshot itself the views tell nothing about where home is: that view
gets no home vector (counted in /diagnostics as undetermined); every grid view gets one.

Coefficients with NaN or infinities, and a place match naming a snapshot beyond the loaded map (localize
running with another map), are rejected with a reason of their own and the node keeps serving.
"""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from scipy.spatial.transform import Rotation

from skynav_core.graph import in_process, type_name
from skynav_core.images import stamp_ns
from skynav_core.maps import Snapshot
from skynav_core.names import CAMERA_FRAME, COMPASS_ORIENTATION, HOME_VECTOR, LOCALIZATION_MATCH, SKYLINE_SH
from skynav_core.nodes import NodeSpec
from skynav_core.recording.bag import RawMessage
from skynav_core.rotations import as_matrix
from skynav_core.views import recording_views
from skynav_localize.mapping import build_map
from skynav_msgs.msg import CompassEstimate, PlaceMatch, ShCoefficients
from skynav_warping import node as warping_node
from skynav_warping.homing import estimate_home_vector

BAG = Path(__file__).resolve().parents[2] / 'bags' / 'synthetic_park_homing.mcap'
WARPING = NodeSpec('warping', 'skynav_warping', 'skynav_warping.node:WarpingNode')
COMPASS = NodeSpec('compass', 'skynav_compass', 'skynav_compass.node:CompassNode')
NO_COMPASS = ['-p', 'use_compass:=false']


@pytest.fixture(scope='module')
def recording():
    return recording_views(BAG, images=False)


@pytest.fixture(scope='module')
def snapshot(recording):
    """The snapshot's view: the recording's 'snapshot' frame."""
    [view] = [v for v in recording.views if v.label == 'snapshot']
    return view


@pytest.fixture(scope='module')
def home_map(tmp_path_factory, snapshot):
    """A one-snapshot map of the snapshot frame."""
    path = tmp_path_factory.mktemp('maps') / 'home.db'
    build_map(
        path,
        'home',
        snapshot.max_degree,
        [Snapshot(0, snapshot.stamp, snapshot.coefficients, snapshot.pose)],
        created_from='test',
        overwrite=True,
    )
    return path


@pytest.fixture(scope='module')
def route_map(tmp_path_factory, recording):
    """A map of five snapshots (the first grid views) to follow as a route."""
    path = tmp_path_factory.mktemp('maps') / 'route.db'
    views = [v for v in recording.views if v.label == 'grid'][:5]
    build_map(
        path,
        'route',
        views[0].max_degree,
        [Snapshot(k, v.stamp, v.coefficients, v.pose) for k, v in enumerate(views)],
        created_from='test',
        overwrite=True,
    )
    return path


def sh_message(view, field_of_view, stamp=None, coefficients=None, max_degree=None, fill='zero'):
    """Return a view as the SH node publishes it (its own stamp unless `stamp` is given)."""
    coefficients = view.coefficients if coefficients is None else np.asarray(coefficients)
    message = ShCoefficients(
        max_degree=view.max_degree if max_degree is None else max_degree,
        coefficients=coefficients.tolist(),
        fill=fill,
        field_of_view=float(field_of_view),
    )
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(view.stamp if stamp is None else stamp, 10**9)
    message.header.frame_id = CAMERA_FRAME
    return message


def place_match(index, accepted, stamp):
    message = PlaceMatch(map_name='route', index=index, accepted=accepted)
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 10**9)
    return message


def deliver(graph, topic, message, outputs=HOME_VECTOR):
    """Feed one message to the graph as a recording would; return what it caused on `outputs`."""
    before = len(graph.outputs)
    graph.feed(RawMessage(topic, type_name(message), stamp_ns(message.header), serialize_message(message)))
    return [o.message for o in graph.outputs[before:] if o.topic == outputs]


def feed(graph, message):
    """Feed one view on /skyline/sh; return the home vectors it caused."""
    return deliver(graph, SKYLINE_SH, message)


def direction(home_vector):
    d = home_vector.direction
    return np.array([d.x, d.y, d.z])


def true_home_direction(snapshot, view):
    """Q_c^-1 (p_s - p_c) normalised: the snapshot's place seen from the current camera_link."""
    towards = Rotation.from_quat(view.pose[3:]).inv().apply(snapshot.pose[:3] - view.pose[:3])
    return towards / np.linalg.norm(towards)


def home_errors_deg(snapshot, views, home_vectors, near=0.5, far=4.0):
    """Return the angular errors (deg) of the home vectors of the views near..far (m) from the snapshot."""
    errors = []
    for view, home in zip(views, home_vectors):
        if near <= np.linalg.norm(view.pose[:3] - snapshot.pose[:3]) <= far:
            cosine = np.dot(direction(home), true_home_direction(snapshot, view))
            errors.append(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))
    return np.array(errors)


def check_home_vectors(views, home_vectors, index, snapshot):
    """One home vector per view but the snapshot's own (undetermined: at home), stamped like it, towards snapshot
    `index`: unit direction and rotation."""
    assert [stamp_ns(h.header) for h in home_vectors] == [v.stamp for v in views if v.stamp != snapshot.stamp]
    for home in home_vectors:
        q = home.rotation
        assert home.header.frame_id == CAMERA_FRAME and home.snapshot_index == index
        assert np.linalg.norm(direction(home)) == pytest.approx(1.0)
        assert np.linalg.norm([q.x, q.y, q.z, q.w]) == pytest.approx(1.0)
        assert 0.0 <= home.residual <= 1.0


def test_home_vectors_point_home_without_the_compass(recording, snapshot, home_map):
    fov = recording.camera.field_of_view
    with in_process([WARPING], ['-p', f'map:={home_map}', '-p', 'target:=index', *NO_COMPASS]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        at_home = []
        home_vectors = []
        for view in recording.views:
            published = feed(graph, sh_message(view, fov))
            home_vectors += published
            if view.stamp == snapshot.stamp:
                at_home = published
        assert not node.rejected and node.errors == 0
        # at the snapshot the views tell nothing about where home is: no home vector, counted; elsewhere they do
        values = {kv.key: kv.value for kv in node.diagnostic_status().values}
        assert at_home == [] and node.undetermined == 1 and values['undetermined'] == '1'
    check_home_vectors(recording.views, home_vectors, 0, snapshot)
    grid = {v.stamp: v for v in recording.views if v.label == 'grid'}
    current = [(grid[stamp_ns(h.header)], h) for h in home_vectors if stamp_ns(h.header) in grid]
    errors = home_errors_deg(snapshot, *zip(*current))
    assert len(errors) == 40 and np.median(errors) < 15.0
    assert np.median([h.residual for _, h in current]) < 0.95


@pytest.fixture(scope='module')
def with_compass(recording, home_map):
    """The compass and warping nodes in one graph, one map for both: what they published and what they saw."""
    fov = recording.camera.field_of_view
    starts = []  # the compass rotation each view's homing started from (3x3, or None)

    def spy(current, snapshot, compass=None, *settings):
        starts.append(None if compass is None else as_matrix(compass))
        return estimate_home_vector(current, snapshot, compass, *settings)

    with pytest.MonkeyPatch.context() as patch, in_process([COMPASS, WARPING], ['-p', f'map:={home_map}']) as graph:
        patch.setattr(warping_node, 'estimate_home_vector', spy)
        graph.keep_outputs = True
        compass, warping = graph.nodes
        for view in recording.views:
            feed(graph, sh_message(view, fov))
        return SimpleNamespace(
            starts=starts,
            estimates=[o.message for o in graph.outputs if o.topic == COMPASS_ORIENTATION],
            home_vectors=[o.message for o in graph.outputs if o.topic == HOME_VECTOR],
            maps=[node.get_parameter('map').value for node in graph.nodes],
            use_compass=warping.get_parameter('use_compass').value,
            estimates_received=warping.received[COMPASS_ORIENTATION],
            problems=sum(compass.rejected.values()) + sum(warping.rejected.values()) + compass.errors + warping.errors,
        )


def test_home_vectors_with_the_compass_point_home(recording, snapshot, home_map, with_compass):
    # -p applies to every node of the graph
    assert with_compass.maps == [str(home_map)] * 2 and with_compass.use_compass is True
    assert with_compass.estimates_received == len(recording.views) and with_compass.problems == 0
    assert [stamp_ns(e.header) for e in with_compass.estimates] == [v.stamp for v in recording.views]
    check_home_vectors(recording.views, with_compass.home_vectors, 0, snapshot)
    grid = {v.stamp: v for v in recording.views if v.label == 'grid'}
    current = [(grid[stamp_ns(h.header)], h) for h in with_compass.home_vectors if stamp_ns(h.header) in grid]
    errors = home_errors_deg(snapshot, *zip(*current))
    # better than without the compass (11.2 deg): a compass read the wrong way round leaves 11.1
    assert len(errors) == 40 and np.median(errors) < 10.0


def test_the_homing_starts_from_the_compass_rotation(recording, snapshot, with_compass):
    """Both messages mean d_snapshot = R d_current: the search starts from a confident estimate's R, near the true
    one; a non-confident estimate is no start (None: the search aligns the views itself)."""
    assert len(with_compass.starts) == len(with_compass.estimates) == len(recording.views)
    errors = []
    for view, estimate, start in zip(recording.views, with_compass.estimates, with_compass.starts):
        if not estimate.confident:
            assert start is None
            continue
        q = estimate.rotation
        np.testing.assert_allclose(start, Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix(), atol=1e-9)
        truth = Rotation.from_quat(snapshot.pose[3:]).inv() * Rotation.from_quat(view.pose[3:])
        errors.append(np.degrees((truth.inv() * Rotation.from_matrix(start)).magnitude()))
    assert np.median(errors) < 10.0  # measured 7.9 (the compass node's own error)


def test_a_view_waits_for_its_compass_estimate(recording, home_map, with_compass):
    """use_compass: the home vector of a view comes when the compass estimate of its stamp does, in either order."""
    estimates, home_vectors = with_compass.estimates, with_compass.home_vectors
    fov = recording.camera.field_of_view
    first, second = recording.views[5], recording.views[6]
    estimate = {stamp_ns(e.header): e for e in estimates}
    expected = {stamp_ns(h.header): h for h in home_vectors}
    with in_process([WARPING], ['-p', f'map:={home_map}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        assert feed(graph, sh_message(first, fov)) == []  # waits
        assert deliver(graph, COMPASS_ORIENTATION, estimate[second.stamp]) == []  # another stamp: waits too
        [home] = deliver(graph, COMPASS_ORIENTATION, estimate[first.stamp])
        assert stamp_ns(home.header) == first.stamp
        [later] = feed(graph, sh_message(second, fov))  # its estimate came first
        assert stamp_ns(later.header) == second.stamp
        assert not node.rejected and node.errors == 0
    # the same inputs as in the graph with the compass node: the same home vectors
    for result in (home, later):
        reference = expected[stamp_ns(result.header)]
        assert np.allclose(direction(result), direction(reference))
        assert result.residual == pytest.approx(reference.residual)


def compass_estimate(stamp, rotation, confident):
    """A compass estimate of the view stamped `stamp` (ns): rotation R (scipy Rotation), marked `confident` or not."""
    message = CompassEstimate(snapshot_index=0, residual=0.1, confidence=0.9 if confident else 0.1, confident=confident)
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 10**9)
    message.header.frame_id = CAMERA_FRAME
    x, y, z, w = rotation.as_quat()
    message.rotation.x, message.rotation.y, message.rotation.z, message.rotation.w = (
        float(x),
        float(y),
        float(z),
        float(w),
    )
    return message


def test_only_a_confident_compass_rotation_starts_the_homing(recording, snapshot, home_map):
    """A wrong rotation marked not confident leaves the home vector as without the compass (counted in /diagnostics);
    the same wrong rotation marked confident is the search's start, as before."""
    fov = recording.camera.field_of_view
    view = [v for v in recording.views if v.label == 'grid'][9]
    truth = Rotation.from_quat(snapshot.pose[3:]).inv() * Rotation.from_quat(view.pose[3:])
    # 25 deg of yaw off: inside the search's yaw window around its own alignment, so a search started from it keeps
    # it (a start far off is checked against the own alignment and loses: it would not show here)
    wrong = Rotation.from_euler('z', 25, degrees=True) * truth
    with in_process([WARPING], ['-p', f'map:={home_map}', *NO_COMPASS]) as graph:
        graph.keep_outputs = True
        [alone] = feed(graph, sh_message(view, fov))
    results, starts = {}, []

    def spy(current, snapshot, compass=None, *settings):
        starts.append(None if compass is None else as_matrix(compass))
        return estimate_home_vector(current, snapshot, compass, *settings)

    for confident in (False, True):
        with pytest.MonkeyPatch.context() as patch, in_process([WARPING], ['-p', f'map:={home_map}']) as graph:
            patch.setattr(warping_node, 'estimate_home_vector', spy)
            graph.keep_outputs = True
            node = graph.nodes[0]
            assert feed(graph, sh_message(view, fov)) == []  # waits for its estimate
            [results[confident]] = deliver(graph, COMPASS_ORIENTATION, compass_estimate(view.stamp, wrong, confident))
            values = {kv.key: kv.value for kv in node.diagnostic_status().values}
            assert values['compass_not_confident'] == ('0' if confident else '1')
            assert not node.rejected and node.errors == 0
    assert starts[0] is None
    np.testing.assert_allclose(starts[1], wrong.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(direction(results[False]), direction(alone), atol=1e-12)
    assert results[False].residual == pytest.approx(alone.residual)
    # the confident wrong start leads the search elsewhere (measured 40.6 deg): the flag is what separates the two
    assert np.degrees(np.arccos(np.clip(np.dot(direction(results[True]), direction(alone)), -1, 1))) > 5.0


def test_target_next_aims_lookahead_snapshots_beyond_the_match(recording, route_map):
    lookahead, count = 2, 5
    fov = recording.camera.field_of_view
    views = iter(recording.views[10:])
    ros_args = ['-p', f'map:={route_map}', '-p', 'target:=next', '-p', f'lookahead:={lookahead}', *NO_COMPASS]
    with in_process([WARPING], ros_args) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]

        def home_after(index=None, accepted=True):
            """Feed a place match (if index is given), then the next view; return its home vectors."""
            view = next(views)
            if index is not None:
                deliver(graph, LOCALIZATION_MATCH, place_match(index, accepted, view.stamp - 1))
            return feed(graph, sh_message(view, fov))

        assert home_after() == []
        assert node.rejected['no_match'] == 1
        targets = []
        for index, accepted in ((1, True), (0, False), (3, True), (0, True), (4, True)):
            [home] = home_after(index, accepted)
            assert np.linalg.norm(direction(home)) == pytest.approx(1.0)
            targets.append(home.snapshot_index)
        # an unaccepted match leaves the target; beyond the route's end the last snapshot is the target
        assert targets == [min(i + lookahead, count - 1) for i in (1, 1, 3, 0, 4)]
        # target 'match' (set at run time) homes to the matched snapshot itself
        assert node.set_parameters([Parameter('target', value='match')])[0].successful
        [home] = home_after()
        assert home.snapshot_index == 4
        assert node.rejected['no_match'] == 1 and node.errors == 0


def test_bad_views_are_rejected_and_the_node_keeps_serving(recording, home_map):
    fov = recording.camera.field_of_view
    view = recording.views[12]
    stamps = iter(view.stamp + k * 10**8 for k in range(100))

    def good():
        return feed(graph, sh_message(view, fov, stamp=next(stamps)))

    low = view.coefficients[:81]  # degree 8; the search needs 16
    with in_process([WARPING], ['-p', f'map:={home_map}', *NO_COMPASS]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        assert len(good()) == 1
        for fill in ('one', 'mean', 'mirror'):
            assert feed(graph, sh_message(view, fov, next(stamps), fill=fill)) == []
        assert node.rejected['fill'] == 3 and len(good()) == 1
        assert feed(graph, sh_message(view, fov, next(stamps), low, max_degree=8)) == []
        assert feed(graph, sh_message(view, fov, next(stamps), low, max_degree=16)) == []  # size and degree differ
        assert node.rejected['degree'] == 1 and node.rejected['malformed'] == 1 and len(good()) == 1
        last = next(stamps)
        assert len(feed(graph, sh_message(view, fov, stamp=last))) == 1
        assert feed(graph, sh_message(view, fov, stamp=last)) == []  # same stamp again
        assert feed(graph, sh_message(view, fov, stamp=last - 10**8)) == []  # older
        assert node.rejected['out_of_order'] == 2 and len(good()) == 1
        assert node.errors == 0 and sum(node.rejected.values()) == 7


def test_without_a_map_views_are_rejected_until_one_is_set(recording, home_map):
    fov = recording.camera.field_of_view
    with in_process([WARPING], NO_COMPASS) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        assert feed(graph, sh_message(recording.views[1], fov)) == []
        assert node.rejected['no_map'] == 1
        assert node.set_parameters([Parameter('map', value=str(home_map))])[0].successful
        [home] = feed(graph, sh_message(recording.views[2], fov))
        assert home.snapshot_index == 0 and node.errors == 0


def test_unusable_parameters_fall_back_to_the_defaults(home_map):
    with in_process([WARPING], ['-p', 'target:=bogus', '-p', f'map:={home_map}']) as graph:
        node = graph.nodes[0]
        assert node.rejected['parameters'] == 1
        # the defaults are the shipped ones (route following: the snapshot six beyond the match)
        assert node.parameter_values() == {
            'map': '',
            'target': 'next',
            'index': 0,
            'lookahead': 6,
            'use_compass': True,
            'max_degree': 16,
            'max_tilt_deg': 45.0,
        }
        refused = node.set_parameters([Parameter('lookahead', value=-1)])[0]
        assert not refused.successful and 'lookahead' in refused.reason
        assert node.get_parameter('lookahead').value == 6
        refused = node.set_parameters([Parameter('max_tilt_deg', value=0.0)])[0]
        assert not refused.successful and 'max_tilt_deg' in refused.reason
        assert node.set_parameters([Parameter('max_tilt_deg', value=30.0)])[0].successful
        assert np.degrees(node.settings.max_relative_tilt) == pytest.approx(30.0)


def test_non_finite_coefficients_are_rejected(recording, home_map):
    fov = recording.camera.field_of_view
    view = recording.views[3]
    broken = view.coefficients.copy()
    broken[5] = np.nan
    with in_process([WARPING], ['-p', f'map:={home_map}', *NO_COMPASS]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        answer = feed(graph, sh_message(view, fov, coefficients=broken))
        assert all(np.all(np.isfinite(direction(h))) for h in answer)
        assert len(feed(graph, sh_message(recording.views[4], fov))) == 1
        assert answer == [] and node.rejected == {'non_finite': 1} and node.errors == 0


def test_a_match_beyond_the_map_is_rejected(recording, route_map):
    fov = recording.camera.field_of_view
    view = recording.views[20]
    with in_process([WARPING], ['-p', f'map:={route_map}', *NO_COMPASS]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        # e.g. the localize node runs with a larger map than this node
        deliver(graph, LOCALIZATION_MATCH, place_match(7, True, view.stamp - 1))
        assert feed(graph, sh_message(view, fov)) == []
        assert node.errors == 0 and node.rejected == {'match_beyond_map': 1}


def test_views_and_snapshots_without_a_skyline_get_no_home_vector_and_no_wait(recording, snapshot, home_map, tmp_path):
    from skynav_compass.views import cap_visibility

    fov = recording.camera.field_of_view
    all_sky = cap_visibility(16, fov / 2)  # the mask is 1 wherever the camera sees
    view = next(v for v in recording.views if v.label == 'grid')
    stamps = iter(view.stamp + k * 10**8 for k in range(100))
    blank_map = tmp_path / 'blank.db'
    build_map(blank_map, 'blank', 16, [Snapshot(0, snapshot.stamp, all_sky, snapshot.pose)], created_from='test')
    with in_process([COMPASS, WARPING], ['-p', f'map:={home_map}']) as graph:  # with the compass: use_compass
        graph.keep_outputs = True
        compass, warping = graph.nodes
        for k, blank in enumerate((all_sky, np.zeros_like(all_sky))):
            # nothing to home on: no home vector, counted, and no compass estimate waited for
            assert feed(graph, sh_message(view, fov, next(stamps), blank)) == []
            assert warping.undetermined == k + 1 and warping.pairer.unpaired == 0
        assert compass.rejected == {'featureless': 2}
        [home] = feed(graph, sh_message(view, fov, next(stamps)))  # a view with a skyline: as before
        assert home.residual < 1.0 and warping.undetermined == 2
        for node in graph.nodes:
            assert node.set_parameters([Parameter('map', value=str(blank_map))])[0].successful
        assert feed(graph, sh_message(view, fov, next(stamps))) == []
        assert warping.undetermined == 3
        assert compass.rejected == {'featureless': 2, 'featureless_snapshot': 1}
        assert not warping.rejected and warping.errors == compass.errors == 0
        assert warping.pairer.unpaired == 0
