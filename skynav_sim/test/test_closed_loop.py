# SPDX-License-Identifier: Apache-2.0
"""Closed-loop homing and route following in synthetic worlds: the route node drives the simulated mower.

The graph (the real nodes, the route node among them) runs in process; a Home or FollowRoute goal goes to the
route node's action server and the simulated mower obeys its /cmd_vel with wheel slip and odometry noise, on
sim time (skynav_sim.closed_loop). The bounds are the project's target (90 % homing success) and, for the
route, that the robot stays on the taught route to within a mower's cutting width.
"""

import re
from pathlib import Path

import numpy as np
import pytest

from skynav_testing import one_line_error, run_skynav

pytestmark = pytest.mark.heavy(250)

BAGS = Path(__file__).resolve().parents[2] / 'bags'
TEACH = BAGS / 'synthetic_garden_teach.mcap'


@pytest.fixture(scope='module')
def camera():
    from skynav_core.camera import EquidistantCamera

    return EquidistantCamera.for_field_of_view(320, 240, np.radians(200), (0.015, -0.002, 0.0, 0.0))


@pytest.fixture(scope='module')
def garden_map(tmp_path_factory):
    path = tmp_path_factory.mktemp('maps') / 'garden.db'
    result = run_skynav('map', 'build', str(TEACH), '--out', str(path))
    assert result.returncode == 0, result.stderr
    return path


# ten closed-loop runs of some 25 camera frames each (0.2 s of sim time apart): about 4 minutes on a quiet machine,
# more on a loaded one; the limit only guards against a hang
@pytest.mark.timeout(1200)
def test_homing_succeeds_from_nine_in_ten_starts(camera, tmp_path):
    from skynav_sim.closed_loop import SUCCESS_RADIUS, home_runs, random_starts, snapshot_map
    from skynav_sim.scenarios import ScenarioParameters, snapshot_place
    from skynav_sim.sky import parse_time
    from skynav_sim.world import generate

    world, seed, hours = generate('park', 3), 3, parse_time('forenoon')
    goal = snapshot_place(world, ScenarioParameters())
    snapshot_map(world, camera, goal, 0.0, hours, seed, tmp_path / 'home.db')
    starts = random_starts(world, goal, 10, 0.5, 4.0, np.random.default_rng(seed))
    assert len(starts) == 10
    runs = home_runs(world, camera, goal, starts, tmp_path / 'home.db', hours, seed, max_frames=100)
    distances = [np.linalg.norm(r.start - goal) for r in runs]
    assert min(distances) >= 0.5 and max(distances) <= 4.0 and max(distances) > 2.5
    assert sum(r.success for r in runs) >= 9, [(round(r.final_error, 2), r.stopped) for r in runs]
    # each run ends with the goal's own result: arrived (the route node believed it), after one command a frame
    assert all(r.stopped == 'reached' and r.commands == len(r.path) - 1 for r in runs if r.success)
    assert all(r.final_error == pytest.approx(np.linalg.norm(r.path[-1] - goal)) for r in runs)
    # a success is a real approach, not a stop at the start, and no wild detour
    successes = [r for r in runs if r.success]
    assert all(r.final_error <= SUCCESS_RADIUS < np.linalg.norm(r.start - goal) for r in successes)
    assert np.median([r.path_ratio for r in successes]) < 1.5


# the simulated graph in a namespace too (its nodes, actions and /clock under /robot1), as one of two robots, and
# with a base that takes geometry_msgs/Twist (cmd_vel_stamped false)
@pytest.mark.parametrize(
    ('namespace', 'stamped'), [('', True), ('robot1', True), ('', False)], ids=['global', 'namespaced', 'twist']
)
def test_a_mower_against_an_object_ends_its_goal_blocked_by_the_bumper(camera, tmp_path, namespace, stamped):
    from skynav_sim.closed_loop import Base, home_runs, snapshot_map
    from skynav_sim.scenarios import ScenarioParameters, snapshot_place
    from skynav_sim.sky import parse_time
    from skynav_sim.world import generate

    world, seed, hours = generate('park', 3), 3, parse_time('forenoon')
    goal = snapshot_place(world, ScenarioParameters())
    snapshot_map(world, camera, goal, 0.0, hours, seed, tmp_path / 'home.db')
    # inside an object's footprint every motion touches it: the first command moves nothing
    trunk = next(f for f in world.footprints if f.disc)
    start = np.asarray(trunk.center[:2], float)
    assert world.collides(*start)
    (run,) = home_runs(
        world,
        camera,
        goal,
        [(start, 0.0)],
        tmp_path / 'home.db',
        hours,
        seed,
        max_frames=20,
        base=Base(namespace=namespace),
        ros_args=['-p', f'cmd_vel_stamped:={str(stamped).lower()}'],
    )
    assert run.stopped == 'BLOCKED' and 'bumper' in run.result.error_msg
    assert [p.tolist() for p in run.path] == [start.tolist()] * 2  # one frame, and it stood still
    assert run.commands == 2  # the frame's command and the stop


# with and without wheel odometry (/odom): a robot may have none; the map has no teach odometry either way
@pytest.mark.parametrize('odometry', [True, False], ids=['odom', 'no_odom'])
def test_route_following_stays_on_the_taught_route(camera, garden_map, odometry):
    from skynav_sim.cli.follow import teach_world
    from skynav_sim.closed_loop import Base, follow_route, route_deviation
    from skynav_sim.sky import parse_time

    world, seed, teach_camera, truth = teach_world(TEACH)
    assert teach_camera.width == camera.width and world.style == 'garden' and truth is None
    from skynav_core.maps import MapStore
    from skynav_sim.robot import base_positions

    with MapStore.open(garden_map) as store:
        route = base_positions(store.poses())  # the base's places under the map's true camera poses
    heading = np.arctan2(*(route[3] - route[0])[::-1])
    left = np.array([-np.sin(heading), np.cos(heading)])
    start = route[0] + 0.3 * left
    run, followed = follow_route(
        world,
        teach_camera,
        garden_map,
        start,
        heading + np.radians(20),
        parse_time('morning'),
        seed,
        max_frames=300,
        base=Base(odometry=odometry),
    )
    assert np.array_equal(followed, route)
    deviation = route_deviation(run, route)
    assert deviation[0] == pytest.approx(0.3, abs=0.02)
    # the route node ended the goal itself (the route's end matched), standing within a metre of the last snapshot
    assert run.stopped == 'reached' and run.result.reached_index >= len(route) - 2
    assert np.linalg.norm(run.path[-1] - route[-1]) < 1.0
    assert np.median(deviation) < 0.2 and deviation.max() < 0.5
    # it drove the route's length, not a shortcut or a loop
    driven = np.sum(np.linalg.norm(np.diff(np.array(run.path), axis=0), axis=1))
    length = np.sum(np.linalg.norm(np.diff(route, axis=0), axis=1))
    assert 0.8 * length < driven < 1.3 * length


def test_route_deviation_measures_distance_to_the_polyline():
    from skynav_sim.closed_loop import Run, route_deviation

    route = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    run = Run(np.zeros(2), route[-1], [np.array(p) for p in ([0.5, 0.2], [1.3, 0.5], [2.0, 2.0], [-1.0, 0.0])])
    assert route_deviation(run, route) == pytest.approx([0.2, 0.3, np.hypot(1.0, 1.0), 1.0])


@pytest.mark.parametrize('case, code', [('not synthetic', 1), ('missing map', 1), ('bad time', 2)])
def test_follow_command_refuses_bad_input_in_one_line(case, code, garden_map, tmp_path):
    teach, map_file, extra = TEACH, garden_map, []
    if case == 'not synthetic':
        teach = tmp_path / 'other.mcap'
        from skynav_testing import write_sample_bag

        write_sample_bag(teach)
    elif case == 'missing map':
        map_file = tmp_path / 'missing.db'
    else:
        extra = ['--time', '25']
    result = run_skynav('sim', 'follow', str(teach), '--map', str(map_file), '--out', str(tmp_path), *extra)
    assert result.returncode == code, result.stderr
    assert one_line_error(result.stderr), result.stderr


@pytest.mark.parametrize(
    'extra', [['--bump-tilt', '95'], ['--bump-tilt', '-1'], ['--starts', '0'], ['--mount-rpy', '0', '4', 'nan']]
)
def test_home_command_refuses_bad_input_in_one_line(extra, tmp_path):
    result = run_skynav('sim', 'home', '--out', str(tmp_path), *extra)
    assert result.returncode == 2, result.stderr
    assert one_line_error(result.stderr), result.stderr
    assert not (tmp_path / 'home.db').exists()  # refused before anything was rendered


def test_home_command_homes_and_reports_it(tmp_path):
    # small and short: two starts 1-2.5 m away, a 160x120 camera; the figures are the command's own report
    result = run_skynav(
        'sim', 'home', '--starts', '2', '--min-distance', '1', '--max-distance', '2.5', '--max-frames', '60',
        '--size', '160x120', '--out', str(tmp_path),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    rows = [line.split() for line in result.stdout.splitlines() if re.match(r'\s+\d+\s+\d', line)]
    assert [row[0] for row in rows] == ['0', '1'] and all(row[-1] == 'reached' for row in rows)
    assert all(1.0 <= float(row[1]) <= 2.5 and float(row[2]) <= 0.3 for row in rows)  # start, end distance (m)
    assert '2 of 2 runs (100 %) ended within 0.3 m of home' in result.stdout
    assert (tmp_path / 'homing_paths.png').stat().st_size > 0
    from skynav_core.maps import MapStore

    with MapStore.open(tmp_path / 'home.db') as store:
        assert len(store) == 1
