# SPDX-License-Identifier: Apache-2.0
"""What the localize, compass and warping nodes share: the check of /skyline/sh messages and the snapshot choice."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from skynav_core.maps import MapStore
from skynav_core.names import VIZ_CONFIDENCE
from skynav_core.sh_input import SH_REJECTIONS, usable_coefficients
from skynav_core.snapshots import SNAPSHOT_REJECTIONS, SnapshotChoice

DEGREE = 4


class Rejections(list):
    """A node's reject(): the reasons, in order."""

    def __call__(self, reason: str, detail: str) -> None:
        assert detail and '\n' not in detail
        self.append(reason)


def sh_message(coefficients, max_degree: int = DEGREE, fill: str = 'zero'):
    header = SimpleNamespace(stamp=SimpleNamespace(sec=3, nanosec=5))
    return SimpleNamespace(header=header, max_degree=max_degree, coefficients=list(coefficients), fill=fill)


def test_a_usable_message_gives_its_coefficients():
    reject = Rejections()
    values = np.linspace(-1, 1, (DEGREE + 1) ** 2)
    coefficients = usable_coefficients(sh_message(values), reject, DEGREE, ('zero',))
    assert coefficients.dtype == np.float64 and np.array_equal(coefficients, values) and reject == []


def test_each_problem_of_a_message_has_its_reason_the_first_that_applies_counting():
    reject = Rejections()
    good = np.ones((DEGREE + 1) ** 2)
    broken = good.copy()
    broken[3] = np.inf
    messages = [
        sh_message(good[:-1]),  # 24 values for degree 4
        sh_message(broken),
        sh_message(good, fill='mirror'),  # fine but for the fill ...
        sh_message(good[:9], max_degree=2, fill='mirror'),  # ... which counts after the degree
        sh_message(np.full(9, np.nan), max_degree=3),
    ]  # 9 values for degree 3: malformed before non-finite
    assert all(usable_coefficients(m, reject, DEGREE, ('zero',)) is None for m in messages)
    assert reject == ['malformed', 'non_finite', 'fill', 'degree', 'malformed']
    assert set(reject) == set(SH_REJECTIONS)
    assert usable_coefficients(sh_message(good, fill='anything'), reject) is not None  # any fill, any degree


@pytest.fixture
def three_snapshots(tmp_path):
    path = tmp_path / 'route.db'
    with MapStore.create(path, 'route', DEGREE) as store:
        for k in range(3):
            store.add_snapshot(np.full((DEGREE + 1) ** 2, float(k)), 10 + k)
    return str(path)


def match(index: int, accepted: bool = True):
    return SimpleNamespace(index=index, accepted=accepted, map_name='route')


@pytest.mark.parametrize(
    'rule, expected', [('match', [None, 1, 1, 2, None]), ('next', [None, 2, 2, 2, None]), ('index', [2, 2, 2, 2, 2])]
)
def test_the_rule_chooses_the_snapshot(three_snapshots, rule, expected):
    reject = Rejections()
    choice = SnapshotChoice(reject, lambda coefficients, fov: (coefficients[0], fov))
    choice.configure(three_snapshots, rule, index=5, lookahead=1)
    chosen = [choice.choose()]
    for place in (match(1), match(0, accepted=False), match(2), match(3)):
        choice.on_match(place)
        chosen.append(choice.choose())
    assert chosen == expected
    assert reject == ([] if rule == 'index' else ['no_match', 'match_beyond_map'])


def test_without_a_map_or_with_one_snapshot(tmp_path, three_snapshots):
    reject = Rejections()
    choice = SnapshotChoice(reject, lambda coefficients, fov: coefficients[0])
    choice.configure('', 'match')
    assert choice.choose() is None and choice.choose(count=False) is None and reject == ['no_map']
    one = tmp_path / 'one.db'
    with MapStore.create(one, 'one', DEGREE) as store:
        store.add_snapshot(np.full((DEGREE + 1) ** 2, 7.0), 1)
    choice.configure(str(one), 'match')
    assert choice.choose() == 0 and choice.view(0, 3.0) == 7.0  # no match needed with one snapshot
    with pytest.raises(ValueError, match='missing.db'):
        choice.configure(str(tmp_path / 'missing.db'), 'match')
    assert choice.choose() == 0  # an unusable map changes nothing
    assert set(reject) <= set(SNAPSHOT_REJECTIONS)


def test_views_are_built_once_per_snapshot_until_the_node_is_configured_again(three_snapshots):
    built = []

    def view_of(coefficients, field_of_view):
        built.append((coefficients[0], field_of_view))
        return coefficients[0] * field_of_view

    choice = SnapshotChoice(Rejections(), view_of)
    choice.configure(three_snapshots, 'index')
    assert [choice.view(k, 2.0) for k in (2, 1, 2, 1)] == [4.0, 2.0, 4.0, 2.0] and built == [(2.0, 2.0), (1.0, 2.0)]
    choice.configure(three_snapshots, 'index')  # e.g. another degree: views are built afresh
    assert choice.view(2, 2.0) == 4.0 and len(built) == 3


def test_an_output_is_watched_only_while_something_takes_it(ros_context):
    import time

    from rclpy.node import Node
    from std_msgs.msg import Float64

    from skynav_core.node import SkynavNode

    node = SkynavNode('watched_test', context=ros_context)
    node.output(VIZ_CONFIDENCE, Float64)
    assert not node.watched(VIZ_CONFIDENCE)
    viewer = Node('viewer', context=ros_context)
    viewer.create_subscription(Float64, VIZ_CONFIDENCE, lambda _: None, 10)
    deadline = time.monotonic() + 10
    while not node.watched(VIZ_CONFIDENCE) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert node.watched(VIZ_CONFIDENCE)
    viewer.destroy_node()
    node.destroy_node()
