# SPDX-License-Identifier: Apache-2.0
"""`skynav teach` against the running graph (`skynav launch`) over a replayed bundled teach drive.

The bundled drives have no /odom, so snapshots come by view change; the map taught live should look like the one
`skynav map build` makes of the same drive (its snapshots every 0.1 m by ground truth) and serve
`skynav eval localization`.
"""

import os
import re
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from skynav_core.maps import MapStore
from skynav_core.names import GREEN_IMAGE, UV_CAMERA_INFO, UV_IMAGE
from skynav_localize.cli.eval import positions_at
from skynav_testing import claim_domain_id, one_line_error, run_skynav, running, start_skynav, wait_text

pytestmark = pytest.mark.heavy(40)

BAGS = Path(__file__).parents[2] / 'bags'
TEACH = BAGS / 'synthetic_garden_teach.mcap'
CAMERA = (UV_IMAGE, GREEN_IMAGE, UV_CAMERA_INFO)


def replay(bag, rate):
    """Replay a bag's camera topics to the end, once the graph's skyline node reads them; fail on a non-zero exit."""
    # --wait-for-subscribers is a count (the skyline node; the default would wait for the viz node, not launched
    # here); --wait-timeout the time a loaded machine may take to start the graph
    wait = ('--wait-for-subscribers', '1', '--wait-timeout', '60')
    done = run_skynav('replay', str(bag), '--rate', str(rate), *wait, '--topics', *CAMERA)
    assert done.returncode == 0, done.stderr


def test_teach_over_a_replayed_drive_makes_a_map_like_map_build(tmp_path):
    built = tmp_path / 'built.db'
    assert run_skynav('map', 'build', str(TEACH), '--out', str(built)).returncode == 0
    taught = tmp_path / 'taught.db'
    params = tmp_path / 'params.yaml'  # no NO_INPUT while a loaded machine starts the replay
    params.write_text('localize:\n  ros__parameters:\n    teach_input_timeout: 60.0\n')
    with running(start_skynav('launch', '--nodes', 'skyline', 'sh', 'localize', '--params', str(params))):
        # warm the graph up (its first frames are slow) on a drive recorded earlier than the teach drive
        replay(BAGS / 'synthetic_garden_skyline.mcap', 0)
        teach = start_skynav('teach', str(taught), '--wait', '60')
        wait_text(teach, 'drive the route')
        replay(TEACH, 1)
        time.sleep(1.0)  # the last views through the graph
        teach.send_signal(signal.SIGINT)
        _, err = teach.communicate(timeout=60)
        assert teach.returncode == 0, err
        summary = err.strip().splitlines()[-1]
        assert re.fullmatch(rf'skynav teach: canceled: \d+ snapshots -> {re.escape(str(taught))} \(\d+ kB\)', summary)
        again = run_skynav('teach', str(taught), '--wait', '30')
        assert again.returncode == 1 and one_line_error(again.stderr) and 'MAP_EXISTS' in again.stderr
    with MapStore.open(taught) as live, MapStore.open(built) as offline:
        assert 0.8 * len(offline) <= len(live) <= 1.3 * len(offline), (len(live), len(offline))
        spacing = np.linalg.norm(np.diff(positions_at(TEACH, live.stamps()), axis=0), axis=1)
        assert 0.07 <= np.median(spacing) <= 0.15 and spacing.max() <= 0.5, spacing
        assert f'snapshots -> {taught}' in summary and f' {len(live)} snapshots' in summary
    evaluated = run_skynav(
        'eval',
        'localization',
        str(BAGS / 'synthetic_garden_repeat.mcap'),
        '--map',
        str(taught),
        '--map-poses',
        str(TEACH),
        '--methods',
        'amplitude',
        '--plots',
        str(tmp_path / 'plots'),
    )
    assert evaluated.returncode == 0, evaluated.stderr
    recall_at_1 = float(re.search(r'^amplitude\s+\S+\s+\S+\s+(\S+)', evaluated.stdout, re.M).group(1))
    assert recall_at_1 >= 0.95, evaluated.stdout


def test_teach_without_a_graph_fails_in_one_line(tmp_path):
    domain, lock = claim_domain_id()  # a domain of its own: no graph of an earlier test can linger there
    with lock:
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
        result = run_skynav('teach', str(tmp_path / 'map.db'), '--wait', '1', env=env)
    assert result.returncode == 1 and one_line_error(result.stderr), result.stderr
    assert 'no /skynav/teach action server' in result.stderr
    assert not (tmp_path / 'map.db').exists()


def test_a_map_without_poses_needs_the_teach_recording_for_evaluation(tmp_path):
    # the map of a live teach holds no ground truth: eval localization says how to give it
    from skynav_localize.teaching import RouteTeacher

    teacher = RouteTeacher(tmp_path / 'taught.db')
    teacher.offer(1, np.ones(289))
    teacher.finish()
    repeat = str(BAGS / 'synthetic_garden_repeat.mcap')
    result = run_skynav('eval', 'localization', repeat, '--map', str(tmp_path / 'taught.db'))
    assert result.returncode == 1 and one_line_error(result.stderr) and '--map-poses' in result.stderr
    result = run_skynav('eval', 'localization', repeat, '--map', str(tmp_path / 'taught.db'), '--map-poses', repeat)
    assert result.returncode == 1 and one_line_error(result.stderr)
    assert 'no /ground_truth/pose stamped 1' in result.stderr
