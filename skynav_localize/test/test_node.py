# SPDX-License-Identifier: Apache-2.0
"""The localize node in the in-process graph: matches on the route, none accepted off it, unusable maps."""

import sqlite3
from contextlib import closing
from pathlib import Path

import numpy as np
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message

from skynav_core.graph import in_process, type_name
from skynav_core.maps import MapStore
from skynav_core.names import LOCALIZATION_MATCH, SKYLINE_SH
from skynav_core.nodes import NodeSpec
from skynav_core.recording.bag import RawMessage
from skynav_core.views import recording_views
from skynav_localize.eval.evaluation import correct_matches
from skynav_localize.matching import MOTION_SLACK
from skynav_testing import run_skynav

BAGS = Path(__file__).parents[2] / 'bags'
SPEC = NodeSpec('localize', 'skynav_localize', 'skynav_localize.node:LocalizeNode')


def feed(graph, views, start=0):
    """Feed views as /skyline/sh messages (stamps in order from `start`); return the matches published."""
    from skynav_msgs.msg import ShCoefficients

    before = len(graph.outputs)
    for k, view in enumerate(views):
        message = ShCoefficients(max_degree=view.max_degree, coefficients=view.coefficients.tolist(), fill='zero')
        stamp = start + k * 10**8
        message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 10**9)
        graph.feed(RawMessage(SKYLINE_SH, type_name(message), stamp, serialize_message(message)))
    return [o.message for o in graph.outputs[before:] if o.topic == LOCALIZATION_MATCH]


def test_on_route_views_are_accepted_and_off_route_views_are_not(garden_map):
    on_route = recording_views(BAGS / 'synthetic_garden_repeat.mcap', images=False).views
    elsewhere = recording_views(BAGS / 'synthetic_park_skyline.mcap', images=False).views
    with in_process([SPEC], ['-p', f'map:={garden_map}']) as graph:
        graph.keep_outputs = True
        matches = feed(graph, on_route, start=10**18)
        assert len(matches) == len(on_route)
        assert np.mean([m.accepted for m in matches]) > 0.9
        assert all(m.map_name == 'garden' and len(m.candidate_indices) == 5 for m in matches)
        assert all(m.candidate_indices[0] == m.index for m in matches)
        off = feed(graph, elsewhere, start=2 * 10**18)
        assert len(off) == len(elsewhere) and not any(m.accepted for m in off)


def test_off_the_route_the_node_accepts_nothing(garden_map):
    # the bundled detour drive leaves the garden route for a loop up to 4.3 m away and comes back: every accepted
    # match must be within 1 m of the view's true place, and nine in ten views on the route must be accepted
    from skynav_localize.eval.evaluation import evaluate

    views = recording_views(BAGS / 'synthetic_garden_detour.mcap', images=False).views
    with in_process([SPEC], ['-p', f'map:={garden_map}']) as graph:
        graph.keep_outputs = True
        matches = feed(graph, views, start=10**18)
    assert len(matches) == len(views)
    with MapStore.open(garden_map) as store:
        result = evaluate(
            'localize node',
            np.array([m.index for m in matches]),
            np.array([m.distance for m in matches]),
            np.stack([v.pose[:3] for v in views]),
            store.positions(),
            1.0,
            np.array([m.accepted for m in matches]),
        )
    assert result.queries - result.positives >= 40 and result.off_route_accepted == 0
    assert result.accepted_precision >= 0.99 and result.accepted_recall >= 0.9


def test_views_it_cannot_use_are_rejected_by_the_shared_reasons(garden_map):
    from types import SimpleNamespace

    view = recording_views(BAGS / 'synthetic_garden_repeat.mcap', images=False).views[0]
    broken = view.coefficients.copy()
    broken[5] = np.nan
    low = view.coefficients[:81]  # degree 8: the descriptors need 16
    bad = [
        SimpleNamespace(max_degree=16, coefficients=low),
        SimpleNamespace(max_degree=16, coefficients=broken),
        SimpleNamespace(max_degree=8, coefficients=low),
    ]
    with in_process([SPEC], ['-p', f'map:={garden_map}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        assert feed(graph, bad, start=10**18) == []
        assert node.rejected == {'malformed': 1, 'non_finite': 1, 'degree': 1} and node.errors == 0
        assert len(feed(graph, [view], start=2 * 10**18)) == 1
    with in_process([SPEC]) as graph:  # without a map no degree is needed: every view gets its (empty) match
        graph.keep_outputs = True
        assert [m.index for m in feed(graph, bad[2:], start=10**18)] == [-1] and not graph.nodes[0].rejected


def test_self_similarity_bound_is_a_parameter(garden_map):
    # at 0 no place of the route counts as standing out, so every match waits for a sequence of views that vouched
    # for a steady drive: at the start of the detour drive and when it rejoins the route, where the default (0.3,
    # which every garden snapshot meets) accepts at once
    views = recording_views(BAGS / 'synthetic_garden_detour.mcap', images=False).views
    with in_process([SPEC], ['-p', f'map:={garden_map}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        default = [m.accepted for m in feed(graph, views, start=10**18)]
        refused = node.set_parameters([Parameter('max_self_similarity', value=-0.1)])[0]
        assert not refused.successful and 'max_self_similarity' in refused.reason
        assert node.set_parameters([Parameter('max_self_similarity', value=0.0)])[0].successful
        matches = feed(graph, views, start=2 * 10**18)
    strict = [m.accepted for m in matches]
    assert all(default[:10]) and not any(strict[:9])
    assert set(np.flatnonzero(strict)) < set(np.flatnonzero(default))
    # the sequences do vouch (16 of the 32 views the default accepts), each for the view's true place: a node that
    # forgot its views between frames would accept none
    with MapStore.open(garden_map) as store:
        correct = correct_matches(
            np.array([m.index for m in matches]), np.stack([v.pose[:3] for v in views]), store.positions(), 1.0
        )
    assert np.count_nonzero(strict) >= 12 and correct[strict].all()


def test_tracking_start_is_where_the_first_views_are_sought(garden_map):
    # the route node passes a FollowRoute goal's start_index: the node trusts it, so views of the route's start
    # tracked from its last snapshot are matched there; a start the map does not have is refused
    views = recording_views(BAGS / 'synthetic_garden_repeat.mcap', images=False).views[:4]
    with MapStore.open(garden_map) as store:
        last = len(store) - 1
    with in_process([SPEC], ['-p', f'map:={garden_map}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        placed = feed(graph, views, start=10**18)
        assert all(m.accepted and m.index < last // 2 for m in placed)
        assert node.set_parameters([Parameter('tracking', value=True)])[0].successful
        refused = node.set_parameters([Parameter('tracking_start', value=last + 1)])[0]
        assert not refused.successful and 'tracking_start' in refused.reason
        assert node.set_parameters([Parameter('tracking_start', value=last)])[0].successful
        tracked = feed(graph, views, start=2 * 10**18)
    # the first within the window about the start; then each may slip MOTION_SLACK back towards the views' place
    assert tracked[0].index >= last - MOTION_SLACK
    assert all(m.accepted and m.index > last // 2 for m in tracked)


def test_unusable_map_leaves_the_node_serving_without_one(tmp_path, garden_map):
    foreign = tmp_path / 'foreign.db'
    __import__('sqlite3').connect(foreign).execute('CREATE TABLE t (x)').connection.commit()
    views = recording_views(BAGS / 'synthetic_garden_repeat.mcap', images=False).views[:3]
    with in_process([SPEC], ['-p', f'map:={foreign}']) as graph:
        graph.keep_outputs = True
        node = graph.nodes[0]
        assert node.rejected['parameters'] == 1 and node.get_parameter('map').value == ''
        matches = feed(graph, views[:1], start=10**18)
        assert matches[0].index == -1 and matches[0].distance == float('inf') and not matches[0].accepted
        # Switching maps at run time: an unusable one is refused, a good one taken.
        refused = node.set_parameters([Parameter('map', value=str(tmp_path / 'missing.db'))])[0]
        assert not refused.successful and 'missing.db' in refused.reason
        assert node.set_parameters([Parameter('map', value=str(garden_map))])[0].successful
        matches = feed(graph, views[1:], start=2 * 10**18)
        assert all(m.index >= 0 and m.map_name == 'garden' for m in matches)


def test_map_info_refuses_foreign_and_corrupt_files(tmp_path, garden_map):
    from skynav_testing import one_line_error

    foreign = tmp_path / 'foreign.db'
    __import__('sqlite3').connect(foreign).execute('CREATE TABLE t (x)').connection.commit()
    corrupt = tmp_path / 'corrupt.db'
    data = bytearray(garden_map.read_bytes())
    # zeros over the root page of the snapshots table, wherever the layout put it (not a guessed offset that may
    # hold free space)
    with closing(sqlite3.connect(f'{garden_map.as_uri()}?mode=ro', uri=True)) as db:
        page_size = db.execute('PRAGMA page_size').fetchone()[0]
        root = db.execute("SELECT rootpage FROM sqlite_master WHERE name = 'snapshots'").fetchone()[0]
    data[(root - 1) * page_size : root * page_size] = bytes(page_size)
    corrupt.write_bytes(bytes(data))
    for path in (foreign, corrupt, tmp_path / 'missing.db'):
        result = run_skynav('map', 'info', str(path))
        assert result.returncode == 1 and one_line_error(result.stderr) and str(path) in result.stderr
    assert run_skynav('map', 'info', str(garden_map)).returncode == 0
