# SPDX-License-Identifier: Apache-2.0
"""The compass node in the in-process graph: estimates against a map snapshot and a live reference, bad input.

The current views are the SH coefficients of bags/synthetic_garden_compass.mcap as the installed skyline and SH
nodes give them (degree 16); the snapshot is its 'reference' frame, stored as a one-snapshot map. Measured
rotation errors against the ground truth Q_s^-1 Q_c, median / max: 0.18 / 0.29 deg over the 15 pure rotations,
1.8 / 2.6 deg over the 15 views moved 0.18-0.48 m, 0.0 deg for the reference frame itself. A live reference
stored from the same frame gives the same estimates (same math; measured: bit-identical).

Coefficients with NaN or infinities, and a place match naming a snapshot beyond the loaded map (localize
running with another map), are rejected with a reason of their own and the node keeps serving.
"""

from pathlib import Path

import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from scipy.spatial.transform import Rotation
from std_srvs.srv import Trigger

from skynav_compass.eval.dataset import true_rotation
from skynav_core.graph import in_process, type_name
from skynav_core.images import stamp_ns
from skynav_core.maps import Snapshot
from skynav_core.names import CAMERA_FRAME, COMPASS_ORIENTATION, LOCALIZATION_MATCH, SKYLINE_SH
from skynav_core.nodes import NodeSpec
from skynav_core.recording.bag import RawMessage
from skynav_core.views import recording_views
from skynav_localize.mapping import build_map
from skynav_msgs.msg import PlaceMatch, ShCoefficients

BAG = Path(__file__).resolve().parents[2] / 'bags' / 'synthetic_garden_compass.mcap'
SPEC = NodeSpec('compass', 'skynav_compass', 'skynav_compass.node:CompassNode')


@pytest.fixture(scope='module')
def recording():
    return recording_views(BAG, images=False)


@pytest.fixture(scope='module')
def reference(recording):
    """The snapshot's view: the recording's 'reference' frame."""
    [view] = [v for v in recording.views if v.label == 'reference']
    return view


@pytest.fixture(scope='module')
def reference_map(tmp_path_factory, reference):
    """A one-snapshot map of the reference frame."""
    path = tmp_path_factory.mktemp('maps') / 'reference.db'
    snapshot = Snapshot(0, reference.stamp, reference.coefficients, reference.pose)
    build_map(path, 'reference', reference.max_degree, [snapshot], created_from='test', overwrite=True)
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


def deliver(graph, topic, message, outputs=COMPASS_ORIENTATION):
    """Feed one message to the graph as a recording would; return what it caused on `outputs`."""
    before = len(graph.outputs)
    log_time = stamp_ns(message.header)
    graph.feed(RawMessage(topic, type_name(message), log_time, serialize_message(message)))
    return [o.message for o in graph.outputs[before:] if o.topic == outputs]


def feed(graph, message):
    """Feed one view on /skyline/sh; return the compass estimates it caused."""
    return deliver(graph, SKYLINE_SH, message)


def quaternion(estimate):
    q = estimate.rotation
    return np.array([q.x, q.y, q.z, q.w])


def angle_deg(q_first, q_second):
    """Return the angle (deg) of the rotation between two quaternions (x, y, z, w)."""
    return float(np.degrees((Rotation.from_quat(q_first).inv() * Rotation.from_quat(q_second)).magnitude()))


def run_views(graph, recording, views):
    """Feed every view; return their estimates (exactly one per view, stamped like it)."""
    estimates = []
    for view in views:
        [estimate] = feed(graph, sh_message(view, recording.camera.field_of_view))
        assert stamp_ns(estimate.header) == view.stamp and estimate.header.frame_id == CAMERA_FRAME
        estimates.append(estimate)
    return estimates


def test_map_reference_estimates_follow_the_ground_truth(recording, reference, reference_map):
    # Default reference 'match' with no match: a one-snapshot map's snapshot is always the reference.
    with in_process([SPEC], ['-p', f'map:={reference_map}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        estimates = run_views(graph, recording, recording.views)
        assert not node.rejected and node.errors == 0
    assert all(e.snapshot_index == 0 for e in estimates)
    assert np.allclose([np.linalg.norm(quaternion(e)) for e in estimates], 1.0)
    errors = {}
    for view, estimate in zip(recording.views, estimates):
        truth = true_rotation(reference.pose[3:], view.pose[3:])  # d_snapshot = R d_current
        errors.setdefault(view.label, []).append(angle_deg(quaternion(estimate), truth))
    assert len(errors['rotation']) == 15 and len(errors['translation']) == 15
    assert np.median(errors['rotation']) < 1.0
    assert np.median(errors['translation']) < 3.0
    assert errors['reference'][0] < 0.5
    assert all(np.isfinite(e.residual) and e.residual >= 0.0 for e in estimates)
    # how sure it is, published with each estimate: confident where the confidence reaches 1/2 (no residual bound)
    confidences = np.array([e.confidence for e in estimates])
    assert np.all((confidences >= 0.0) & (confidences <= 1.0))
    assert [e.confident for e in estimates] == [bool(c >= 0.5) for c in confidences]
    flat = [
        angle_deg(quaternion(e), true_rotation(reference.pose[3:], v.pose[3:]))
        for v, e in zip(recording.views, estimates)
    ]
    assert sum(e.confident for e in estimates) >= 0.5 * len(estimates)
    assert max(err for err, e in zip(flat, estimates) if e.confident) < 5.0


def test_live_reference_is_the_view_stored_by_the_service(recording, reference, reference_map):
    others = [v for v in recording.views if v.label != 'reference']
    assert recording.views[0] is reference  # the reference frame comes first: it can be stored before the others
    with in_process([SPEC], ['-p', f'map:={reference_map}']) as graph:
        graph.keep_outputs = True
        from_map = run_views(graph, recording, recording.views)[1:]
    with in_process([SPEC], ['-p', 'reference:=live']) as graph:  # no map needed
        graph.keep_outputs = True
        node = graph.nodes[0]
        assert not node.store_reference(Trigger.Request(), Trigger.Response()).success  # no view yet
        assert feed(graph, sh_message(reference, recording.camera.field_of_view)) == []
        assert node.rejected['no_reference'] == 1
        # In-process there is no service: call its callback.
        assert node.store_reference(Trigger.Request(), Trigger.Response()).success
        live = run_views(graph, recording, others)
        assert node.rejected['no_reference'] == 1 and node.errors == 0
    assert all(e.snapshot_index == -1 for e in live)
    for a, b in zip(live, from_map):
        assert angle_deg(quaternion(a), quaternion(b)) < 1e-3
        assert a.residual == pytest.approx(b.residual, rel=1e-6, abs=1e-12)


def test_bad_views_are_rejected_and_the_node_keeps_serving(recording, reference_map):
    fov = recording.camera.field_of_view
    view = next(v for v in recording.views if v.label == 'rotation')
    stamps = iter(view.stamp + k * 10**8 for k in range(100))

    def good():
        return feed(graph, sh_message(view, fov, stamp=next(stamps)))

    low = view.coefficients[:81]  # degree 8; the compass needs 16
    with in_process([SPEC], ['-p', f'map:={reference_map}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        assert len(good()) == 1
        assert feed(graph, sh_message(view, fov, next(stamps), low, max_degree=8)) == []
        assert feed(graph, sh_message(view, fov, next(stamps), low, max_degree=16)) == []  # size and degree differ
        assert node.rejected['degree'] == 1 and node.rejected['malformed'] == 1 and len(good()) == 1
        last = next(stamps)
        assert len(feed(graph, sh_message(view, fov, stamp=last))) == 1
        assert feed(graph, sh_message(view, fov, stamp=last)) == []  # same stamp again
        assert feed(graph, sh_message(view, fov, stamp=last - 10**8)) == []  # older
        assert node.rejected['out_of_order'] == 2 and len(good()) == 1
        assert feed(graph, sh_message(view, fov, next(stamps), fill='bogus')) == []
        assert node.rejected['fill'] == 1 and len(good()) == 1
        assert node.errors == 0 and sum(node.rejected.values()) == 5


def test_without_a_map_views_are_rejected_until_one_is_set(recording, reference_map):
    view = recording.views[1]
    with in_process([SPEC]) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        assert feed(graph, sh_message(view, recording.camera.field_of_view)) == []
        assert node.rejected['no_map'] == 1
        assert node.set_parameters([Parameter('map', value=str(reference_map))])[0].successful
        later = recording.views[2]
        [estimate] = feed(graph, sh_message(later, recording.camera.field_of_view))
        assert estimate.snapshot_index == 0 and node.errors == 0


def test_unusable_parameters_fall_back_to_the_defaults(reference_map):
    with in_process([SPEC], ['-p', 'reference:=bogus', '-p', f'map:={reference_map}']) as graph:
        node = graph.nodes[0]
        assert node.rejected['parameters'] == 1
        # every parameter falls back, the map too
        assert node.parameter_values() == {
            'map': '',
            'reference': 'match',
            'index': 0,
            'max_degree': 16,
            'max_tilt_deg': 45.0,
        }
        # at run time an unusable value is refused and the current one kept
        refused = node.set_parameters([Parameter('reference', value='bogus')])[0]
        assert not refused.successful and 'reference' in refused.reason
        assert node.get_parameter('reference').value == 'match'
        for tilt in (0.0, -10.0, 181.0):  # no tilt at all, or more than turning the camera over
            refused = node.set_parameters([Parameter('max_tilt_deg', value=tilt)])[0]
            assert not refused.successful and 'max_tilt_deg' in refused.reason
        assert node.get_parameter('max_tilt_deg').value == 45.0
        assert node.set_parameters([Parameter('max_tilt_deg', value=30.0)])[0].successful
        assert np.degrees(node.compass.config.max_tilt) == pytest.approx(30.0)


def test_a_match_selects_the_snapshot_of_a_larger_map(recording, tmp_path):
    """With several snapshots, reference 'match' waits for an accepted place match and follows it."""
    views = [v for v in recording.views if v.label == 'rotation'][:3]
    path = tmp_path / 'three.db'
    build_map(
        path,
        'three',
        16,
        [Snapshot(k, v.stamp, v.coefficients, v.pose) for k, v in enumerate(views)],
        created_from='test',
        overwrite=True,
    )
    current = [v for v in recording.views if v.label == 'translation'][:4]
    fov = recording.camera.field_of_view

    def match(index, accepted, view):
        message = PlaceMatch(map_name='three', index=index, accepted=accepted)
        message.header.stamp.sec, message.header.stamp.nanosec = divmod(view.stamp - 1, 10**9)
        deliver(graph, LOCALIZATION_MATCH, message)

    with in_process([SPEC], ['-p', f'map:={path}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        assert feed(graph, sh_message(current[0], fov)) == []
        assert node.rejected['no_match'] == 1
        match(2, True, current[1])
        [estimate] = feed(graph, sh_message(current[1], fov))
        assert estimate.snapshot_index == 2
        match(0, False, current[2])  # not accepted: the target stays
        [estimate] = feed(graph, sh_message(current[2], fov))
        assert estimate.snapshot_index == 2
        match(1, True, current[3])
        [estimate] = feed(graph, sh_message(current[3], fov))
        assert estimate.snapshot_index == 1
    truth = true_rotation(views[1].pose[3:], current[3].pose[3:])
    assert angle_deg(quaternion(estimate), truth) < 3.0


def test_non_finite_coefficients_are_rejected(recording, reference_map):
    view = recording.views[1]
    broken = view.coefficients.copy()
    broken[5] = np.nan
    with in_process([SPEC], ['-p', f'map:={reference_map}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        answer = feed(graph, sh_message(view, recording.camera.field_of_view, coefficients=broken))
        assert all(np.all(np.isfinite(quaternion(e))) for e in answer)
        assert len(feed(graph, sh_message(recording.views[2], recording.camera.field_of_view))) == 1
        assert answer == [] and node.rejected == {'non_finite': 1} and node.errors == 0


def test_a_match_beyond_the_map_is_rejected(recording, tmp_path):
    views = [v for v in recording.views if v.label == 'rotation'][:2]
    path = tmp_path / 'two.db'
    build_map(
        path,
        'two',
        16,
        [Snapshot(k, v.stamp, v.coefficients, v.pose) for k, v in enumerate(views)],
        created_from='test',
        overwrite=True,
    )
    current = next(v for v in recording.views if v.label == 'translation')
    with in_process([SPEC], ['-p', f'map:={path}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        # e.g. the localize node runs with a larger map than this node
        match = PlaceMatch(map_name='other', index=7, accepted=True)
        match.header.stamp.sec, match.header.stamp.nanosec = divmod(current.stamp - 1, 10**9)
        deliver(graph, LOCALIZATION_MATCH, match)
        assert feed(graph, sh_message(current, recording.camera.field_of_view)) == []
        assert node.errors == 0 and node.rejected == {'match_beyond_map': 1}


def test_views_and_snapshots_without_a_skyline_get_no_estimate_and_are_counted(recording, reference, tmp_path):
    from skynav_compass.views import cap_visibility

    fov = recording.camera.field_of_view
    all_sky = cap_visibility(16, fov / 2)  # the mask is 1 wherever the camera sees: v f = v
    all_ground = np.zeros_like(all_sky)
    view = next(v for v in recording.views if v.label == 'rotation')
    stamps = iter(view.stamp + k * 10**8 for k in range(100))
    blank_map = tmp_path / 'blank.db'
    build_map(blank_map, 'blank', 16, [Snapshot(0, reference.stamp, all_sky, reference.pose)], created_from='test')
    reference_map = tmp_path / 'reference.db'
    build_map(
        reference_map,
        'reference',
        16,
        [Snapshot(0, reference.stamp, reference.coefficients, reference.pose)],
        created_from='test',
    )
    with in_process([SPEC], ['-p', f'map:={reference_map}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        for blank in (all_sky, all_ground):
            assert feed(graph, sh_message(view, fov, next(stamps), blank)) == []
        assert node.rejected == {'featureless': 2}
        [estimate] = feed(graph, sh_message(view, fov, next(stamps)))  # and the node keeps serving
        assert np.isfinite(estimate.residual)
        assert node.set_parameters([Parameter('map', value=str(blank_map))])[0].successful
        assert feed(graph, sh_message(view, fov, next(stamps))) == []
        assert node.rejected == {'featureless': 2, 'featureless_snapshot': 1} and node.errors == 0
