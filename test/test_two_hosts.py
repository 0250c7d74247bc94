# SPDX-License-Identifier: Apache-2.0
"""The graph split across two hosts over UDP gives the outputs of one process, frame for frame.

Two network namespaces joined by a veth pair stand for a robot and a base station (skynav_core.process.netns):
each has its own /dev/shm, so between them Fast DDS can only use UDP, as between two machines. The robot
runs the camera (a bundled bag replayed), skyline and sh; the base station localize, compass, warping and
the route controller (idle: it has no goal) and a recorder. What the base station records must equal what
`skynav run` records over the same bag. There multicast is blocked, as on many Wi-Fi networks, and the
hosts find each other through the Fast DDS discovery server the base station's `skynav launch` serves;
the late-start and restart test finds them by static peers.

The compass and the warping node compare against a fixed snapshot here ('index'): with the default rules
('match', 'next') a live node takes the snapshot of the latest place match it has received, which for a
given view may be that of the view before (the view reaches it directly, the match only after the localize
node's work) where `skynav run` delivers the match first; that is a property of the live graph, one host
or two, not of the link.
"""

import signal
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import pytest
import yaml

from skynav_core.images import stamp_ns
from skynav_core.names import (
    COMPASS_ORIENTATION,
    GREEN_IMAGE,
    HOME_VECTOR,
    LOCALIZATION_MATCH,
    SKYLINE_SH,
    UV_CAMERA_INFO,
    UV_IMAGE,
)
from skynav_core.process import netns
from skynav_core.process.network import DISCOVERY_SERVER_PORT
from skynav_core.recording.bag import open_bag
from skynav_testing import BAGS, messages_equal, run_skynav, skynav_command, write_first_frames

pytestmark = pytest.mark.heavy(95)

PROBE = Path(__file__).with_name('graph_probe.py')
CAMERA = (UV_IMAGE, GREEN_IMAGE, UV_CAMERA_INFO)
CROSSING = SKYLINE_SH  # what the robot sends the base station
BASE_OUTPUTS = (LOCALIZATION_MATCH, COMPASS_ORIENTATION, HOME_VECTOR)
ROBOT_NODES = ('skyline', 'sh')
BASE_NODES = ('localize', 'compass', 'warping', 'route')
# readers of each topic once the base station is up, among localize, compass, warping, route, the recorder and
# the probe
BASE_READERS = {CROSSING: 6, LOCALIZATION_MATCH: 5, COMPASS_ORIENTATION: 4, HOME_VECTOR: 3}
REPLAY_RATE = 0.2  # 2 Hz: the warping node (about 0.1 s a view, several times that on a loaded machine) keeps up
EQUAL_FRAMES = 35  # the first views of the repeat drive compared frame for frame: past both fixed snapshots (3, 8)
# the robot's replays wait for its one camera reader, its skyline node (by default a replay waits for every node of
# the graph that reads the camera, the viz node among them, which no host runs here: 30 s lost per replay)
ROBOT_CAMERA_READERS = ('--wait-for-subscribers', '1')


@pytest.fixture(scope='module')
def unavailable():
    """Why two hosts cannot be made here, or None."""
    return netns.unavailable()


@pytest.fixture(scope='module')
def garden_map(tmp_path_factory) -> Path:
    """The map of the bundled garden teach drive, as `skynav map build` writes it (both tests read it)."""
    path = tmp_path_factory.mktemp('maps') / 'garden.db'
    built = run_skynav('map', 'build', str(BAGS / 'synthetic_garden_teach.mcap'), '--out', str(path))
    assert built.returncode == 0, built.stderr
    return path


def fixed_reference_params(path: Path) -> Path:
    """Write the parameter file of both runs: compass and warping against fixed snapshots."""
    path.write_text(
        yaml.safe_dump(
            {
                'compass': {'ros__parameters': {'reference': 'index', 'index': 3}},
                'warping': {'ros__parameters': {'target': 'index', 'index': 8}},
            }
        )
    )
    return path


def by_stamp(path: Path, topics) -> dict[str, dict[int, object]]:
    """Return {topic: {header stamp ns: message}} of a recording."""
    found: dict[str, dict[int, object]] = defaultdict(dict)
    with open_bag(path) as bag:
        for raw in bag.messages([t for t in topics if t in bag.topics]):
            message = bag.deserialize(raw)
            found[raw.topic][stamp_ns(message.header)] = message
    return found


def probe(host: netns.Host, env: dict, log: Path, *args: str) -> subprocess.Popen:
    """Start the graph probe on a host."""
    return host.start([sys.executable, str(PROBE), *args], env, log)


def finished(process: subprocess.Popen, log: Path, timeout: float) -> None:
    """Wait for a process to end and assert it succeeded (its log in the message)."""
    try:
        code = process.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        code = None
    assert code == 0, f'{" ".join(process.args[-6:])} ended with {code}:\n{log.read_text()[-3000:]}'


def ready(process: subprocess.Popen, log: Path, timeout: float = 60) -> None:
    """Wait until a probe's subscriptions have matched their publishers."""
    deadline = time.monotonic() + timeout
    while 'graph_probe: ready' not in log.read_text():
        assert process.poll() is None and time.monotonic() < deadline, f'probe never ready:\n{log.read_text()}'
        time.sleep(0.1)


def started(log: Path, line: str, process: subprocess.Popen, timeout: float = 60) -> None:
    """Wait until a process has written `line` in its log."""
    deadline = time.monotonic() + timeout
    while line not in log.read_text():
        assert process.poll() is None and time.monotonic() < deadline, f'never said {line!r}:\n{log.read_text()}'
        time.sleep(0.1)


def test_base_station_over_udp_equals_one_process(tmp_path, unavailable, garden_map):
    if unavailable:
        pytest.skip(f'two hosts on one machine: {unavailable}')
    bag = write_first_frames(BAGS / 'synthetic_garden_repeat.mcap', tmp_path / 'repeat_start.mcap', EQUAL_FRAMES)
    map_file = garden_map
    params = fixed_reference_params(tmp_path / 'params.yaml')
    reference = tmp_path / 'one_process.mcap'
    one = run_skynav('run', str(bag), '--map', str(map_file), '--params', str(params), '--out', str(reference))
    assert one.returncode == 0, one.stderr
    expected = by_stamp(reference, (CROSSING, *BASE_OUTPUTS))
    assert all(len(expected[t]) > 10 for t in (CROSSING, *BASE_OUTPUTS)), {t: len(v) for t, v in expected.items()}

    recorded = tmp_path / 'base_station.mcap'
    domain = 1 + int(tmp_path.stat().st_ino) % 200
    with netns.TwoHosts(domain, multicast=False) as hosts:
        server = f'{hosts.base.address}:{DISCOVERY_SERVER_PORT}'
        robot_env = hosts.environment(hosts.robot, domain, discovery_server=server)
        base_env = hosts.environment(hosts.base, domain, discovery_server=server)
        logs = {name: tmp_path / f'{name}.log' for name in ('robot', 'base', 'record', 'replay', 'wait', 'count')}
        # the base station first: it serves discovery (launch's options, not the environment, tell the nodes so)
        base_launch = hosts.base.start(
            skynav_command(
                'launch', '--map', str(map_file), '--params', str(params), '--nodes', *BASE_NODES,
                '--discovery-server', hosts.base.address, '--serve-discovery',
            ),
            {k: v for k, v in base_env.items() if k != 'ROS_DISCOVERY_SERVER'},
            logs['base'],
        )  # fmt: skip
        started(logs['base'], '[launch] route: started', base_launch)
        hosts.robot.start(
            skynav_command('launch', '--params', str(params), '--nodes', *ROBOT_NODES, '--discovery-server', server),
            {k: v for k, v in robot_env.items() if k != 'ROS_DISCOVERY_SERVER'},
            logs['robot'],
        )
        recorder = hosts.base.start(
            skynav_command('record', str(recorded), CROSSING, *BASE_OUTPUTS), base_env, logs['record']
        )
        # the robot's sh writer knows the base station's readers, and the base station's inner topics are taken up
        finished(probe(hosts.robot, robot_env, logs['wait'], '--subscribers', f'{CROSSING}=5'), logs['wait'], 120)
        counts = (f'{t}={len(expected[t])}' for t in (CROSSING, *BASE_OUTPUTS))
        base_readers = (f'{t}={n}' for t, n in BASE_READERS.items())
        counter = probe(
            hosts.base,
            base_env,
            logs['count'],
            *('--timeout', '300', '--publishers', f'{CROSSING}=1', '/cmd_vel=1', '--subscribers', *base_readers),
            *('--messages', *counts),
        )
        ready(counter, logs['count'], 120)
        # the skyline node takes the camera best effort: the replay gives it time to take the last frame as it ends
        replay = hosts.robot.start(
            skynav_command('replay', str(bag), '--rate', str(REPLAY_RATE), *ROBOT_CAMERA_READERS, '--topics', *CAMERA),
            robot_env,
            logs['replay'],
        )
        finished(replay, logs['replay'], 180)
        finished(counter, logs['count'], 120)
        recorder.send_signal(signal.SIGINT)
        finished(recorder, logs['record'], 60)
        assert base_launch.poll() is None and 'process ended' not in logs['base'].read_text(), logs['base'].read_text()

    got = by_stamp(recorded, (CROSSING, *BASE_OUTPUTS))
    for topic in (CROSSING, *BASE_OUTPUTS):
        assert sorted(got[topic]) == sorted(expected[topic]), f'{topic}: other frames than one process'
        differing = [s for s in expected[topic] if not messages_equal(expected[topic][s], got[topic][s])]
        assert not differing, f'{topic}: {len(differing)} of {len(expected[topic])} frames differ'


def logged(log: Path, topic: str) -> set[int]:
    """Return the header stamps of a topic in a probe's --log file."""
    if not log.exists():
        return set()
    return {int(line.split()[1]) for line in log.read_text().splitlines() if line.split()[0] == topic}


def wait_logged(log: Path, stamps: dict[str, set[int]], timeout: float) -> None:
    """Wait until a probe has logged every given stamp of every given topic, or `timeout` s pass."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and any(not s <= logged(log, t) for t, s in stamps.items()):
        time.sleep(0.2)


LATE_START = 10.0  # s the base station starts after the robot's camera
LATE_RATE = 0.35  # the first drive lasts 25 s: the base station sees its last 15 s
RESTART_DISCOVERY = 10  # views (1 s) the restarted robot may send before the base station has found it


def test_base_station_starts_late_and_survives_a_robot_restart(tmp_path, unavailable, garden_map):
    if unavailable:
        pytest.skip(f'two hosts on one machine: {unavailable}')
    map_file = garden_map
    domain = 1 + int(tmp_path.stat().st_ino) % 200
    match = LOCALIZATION_MATCH
    with netns.TwoHosts(domain) as hosts:
        robot, base = hosts.robot, hosts.base
        robot_env, base_env = hosts.environment(robot, domain), hosts.environment(base, domain)
        seen_on_base = tmp_path / 'base_seen.txt'

        def start_robot(boot: int, drive: Path, rate: float) -> tuple[subprocess.Popen, Path]:
            """Start the robot's nodes, a probe logging its coefficients, and the drive's replay."""
            robot.start(skynav_command('launch', '--nodes', *ROBOT_NODES), robot_env, tmp_path / f'robot{boot}.log')
            seen, log = tmp_path / f'robot_seen{boot}.txt', tmp_path / f'robot_probe{boot}.log'
            local = probe(
                robot, robot_env, log, '--timeout', '300', '--log', str(seen), '--messages', f'{CROSSING}=10000'
            )
            ready(local, log, 120)
            replay = robot.start(
                skynav_command('replay', str(drive), '--rate', str(rate), *ROBOT_CAMERA_READERS, '--topics', *CAMERA),
                robot_env,
                tmp_path / f'replay{boot}.log',
            )
            return replay, seen

        # the robot drives 10 s alone; then the base station starts
        replay, robot_seen = start_robot(1, BAGS / 'synthetic_garden_repeat.mcap', LATE_RATE)
        time.sleep(LATE_START)
        assert replay.poll() is None, 'the first drive ended before the base station started'
        base.start(
            skynav_command('launch', '--map', str(map_file), '--nodes', 'localize'), base_env, tmp_path / 'base.log'
        )
        base_probe = probe(
            base, base_env, tmp_path / 'base_probe.log', '--timeout', '600', '--log', str(seen_on_base),
            '--messages', f'{CROSSING}=10000', f'{match}=10000',
        )  # fmt: skip
        finished(replay, tmp_path / 'replay1.log', 120)
        # every view published after a reader of the base station joined reaches it: the probe's coefficients,
        # the localize node's matches (it joins a little later, being slower to start)
        sent = logged(robot_seen, CROSSING)
        wait_logged(seen_on_base, {CROSSING: {max(sent)}, match: {max(sent)}}, 30)
        for topic in (CROSSING, match):
            joined = min(logged(seen_on_base, topic), default=max(sent) + 1)
            after = {s for s in sent if s >= joined}
            assert len(after) >= 20, f'{topic}: the base station joined too late to tell ({len(after)} of {len(sent)})'
            assert after <= logged(seen_on_base, topic), f'{topic}: views lost after the base station joined'

        # the robot host crashes and reboots; the base station (still running) takes up its second drive
        robot.crash()
        replay, robot_seen = start_robot(2, BAGS / 'synthetic_garden_teach.mcap', 1.0)
        finished(replay, tmp_path / 'replay2.log', 120)
        sent = logged(robot_seen, CROSSING)
        assert len(sent) >= 70
        wait_logged(seen_on_base, {CROSSING: {max(sent)}, match: {max(sent)}}, 30)
        # the base station finds the restarted robot's nodes by discovery; what they send before a reader of the
        # base station has matched them reaches no one (volatile topics): from the first view the base station
        # has, within RESTART_DISCOVERY views, none is lost and every one is localized
        for topic, lost in ((CROSSING, 'coefficients lost'), (match, 'views not localized')):
            joined = min(logged(seen_on_base, topic) & sent, default=max(sent) + 1)
            after = {s for s in sent if s >= joined}
            assert len(after) >= len(sent) - RESTART_DISCOVERY, f'{topic}: the base station took up the robot late'
            assert after <= logged(seen_on_base, topic), f'{lost} after the robot restarted'
        assert base_probe.poll() is None and all(p.poll() is None for p in base.processes)
