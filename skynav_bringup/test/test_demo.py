# SPDX-License-Identifier: Apache-2.0
"""`skynav demo` (what `make demo` runs) over the bundled garden drives: map build, `skynav run`, the summary, and
the closed loop of `skynav sim follow`, each as a newcomer meets it, with its figures held to what the chain does.

Measured: 57 snapshots of 80 teach frames; on the repeat drive 89 of 89 views accepted, all within 1 m of their
true place; compass error median 0.8 deg; the simulated robot reaches the route's end in 30 steps, median 0.14 m
from the taught route. About 50 s.
"""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

from skynav_core.bag import open_bag
from skynav_core.testing import run_skynav

BAGS = Path(__file__).resolve().parents[2] / 'bags'
OUTPUT_TOPICS = ('/skyline/mask', '/skyline/sh', '/localization/match', '/compass/orientation', '/homing/home_vector')


def figure(pattern: str, text: str) -> tuple[float, ...]:
    """Return the numbers a regular expression captures in the text (it must match)."""
    found = re.search(pattern, text)
    assert found, pattern
    return tuple(float(group) for group in found.groups())


def test_demo_runs_the_chain_and_reports_what_it_did(tmp_path):
    result = run_skynav(
        'demo',
        '--out',
        str(tmp_path),
        '--teach',
        str(BAGS / 'synthetic_garden_teach.mcap'),
        '--repeat',
        str(BAGS / 'synthetic_garden_repeat.mcap'),
        timeout=900,
    )
    assert result.returncode == 0, result.stderr
    out = result.stdout + result.stderr  # the steps print their commands' lines on either
    assert figure(r'(\d+) snapshots of (\d+) frames', out) == (57, 80)
    views, accepted, right = figure(r'(\d+) views, (\d+) accepted, (\d+) of them within 1 m', out)
    assert views == 89 and accepted >= 85 and right == accepted
    assert figure(r'3D rotation error median ([\d.]+) deg', out)[0] < 2.0
    assert 'goal ended: reached' in out and '(reached the end)' in out
    assert figure(r'distance from the taught route: median ([\d.]+) m', out)[0] < 0.3
    # `skynav run` recorded one output of every kind per exposure of the repeat drive
    with open_bag(tmp_path / 'repeat_run.mcap') as bag:
        counts = Counter(raw.topic for raw in bag.messages(OUTPUT_TOPICS))
    assert counts == dict.fromkeys(OUTPUT_TOPICS, 89)
    for name in ('localization_matches.png', 'route_following.png', 'skyline_sheet.png', 'synthetic_garden_teach.db'):
        assert (tmp_path / name).stat().st_size > 0, name
