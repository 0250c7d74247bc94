# SPDX-License-Identifier: Apache-2.0
"""`skynav sim teach`: a scripted operator drives the simulated mower while a Teach goal records the map, in the
in-process graph (the localize node serves /skynav/teach there and takes /odom through the graph), and the taught
map is one `skynav sim follow` follows. Everything is synthetic."""

import numpy as np
import pytest
import yaml

from skynav_core.maps import ODOM_POSE, MapStore
from skynav_localize.parameters import PARAMETERS
from skynav_sim.closed_loop import truth_at
from skynav_testing import one_line_error, run_skynav

pytestmark = pytest.mark.heavy(45)

LENGTH = 4.0  # m of route taught


@pytest.fixture(scope='module')
def taught(tmp_path_factory):
    out = tmp_path_factory.mktemp('sim_teach')
    result = run_skynav('sim', 'teach', '--length', str(LENGTH), '--out', str(out))
    assert result.returncode == 0, result.stderr
    return out, result.stdout


def test_a_taught_route_has_snapshots_spaced_by_odometry(taught):
    out, stdout = taught
    spacing = PARAMETERS['teach_spacing'].default
    with MapStore.open(out / 'teach.db') as store:
        odometry = store.descriptor_matrix(ODOM_POSE)[:, :2]
        stamps = store.stamps()
    description = yaml.safe_load((out / 'teach.yaml').read_text())
    truth = truth_at(stamps, np.array(description['truth']['stamps']), np.array(description['truth']['poses']))
    # every snapshot has its odometry pose, and one is stored every `teach_spacing` m by odometry
    assert np.all(np.isfinite(odometry)) and np.all(np.isfinite(truth))
    steps = np.linalg.norm(np.diff(odometry, axis=0), axis=1)
    assert np.median(steps) == pytest.approx(spacing, rel=0.3) and steps.max() < 2.5 * spacing, steps
    # the operator drove the route's length from the first frame: the snapshots cover it
    assert np.sum(steps) == pytest.approx(LENGTH, rel=0.15)
    true_steps = np.linalg.norm(np.diff(truth[:, :2], axis=0), axis=1)
    assert np.median(true_steps) == pytest.approx(spacing, rel=0.3)
    assert f'taught {len(stamps)} snapshots' in stdout


def test_the_operators_commands_give_the_route_shape_too(taught):
    # the localize node hears the operator's /cmd_vel and dead reckons: the shape a robot without odometry keeps.
    # The base obeys with up to 5 % slip (the simulator's default), which a shape by commands cannot see.
    out, _ = taught
    with MapStore.open(out / 'teach.db') as store:
        commanded = store.commanded_poses()[:, :2]
        stamps = store.stamps()
    description = yaml.safe_load((out / 'teach.yaml').read_text())
    truth = truth_at(stamps, np.array(description['truth']['stamps']), np.array(description['truth']['poses']))[:, :2]
    distances = np.linalg.norm(commanded[:, None] - commanded[None], axis=2)
    true_distances = np.linalg.norm(truth[:, None] - truth[None], axis=2)
    assert np.all(np.abs(distances - true_distances) <= 0.05 * true_distances + 0.02)


def test_sim_follow_follows_a_taught_route_at_another_time(taught, tmp_path):
    out, _ = taught
    result = run_skynav(
        'sim',
        'follow',
        str(out / 'teach.yaml'),
        '--map',
        str(out / 'teach.db'),
        '--time',
        'morning',
        '--out',
        str(tmp_path),
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'goal ended: reached' in result.stdout and '(reached the end)' in result.stdout
    assert (tmp_path / 'route_following.png').stat().st_size > 0


def test_sim_follow_refuses_a_description_that_is_not_one_in_one_line(tmp_path):
    bogus = tmp_path / 'teach.yaml'
    bogus.write_text('scenario: teach\nworld: garden\n')
    result = run_skynav('sim', 'follow', str(bogus), '--map', str(tmp_path / 'none.db'))
    assert result.returncode == 1 and one_line_error(result.stderr), result.stderr
    assert 'not a description written by `skynav sim teach`' in result.stderr
