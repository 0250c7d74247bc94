# SPDX-License-Identifier: Apache-2.0
"""Benchmark: what crosses the link between a robot and a base station, for two splits of the graph.

    .venv/bin/python bench/link_split.py [--frames N] [--transport shm|udp] [--discovery peers|server]
    (as root: network namespaces)

Two hosts on one machine (skynav_core.process.netns: network namespaces joined by a veth pair, UDP between them). A
synthetic 640x480 mono16 repeat drive of the garden at 10 Hz is replayed on the robot in real time, with

- images across: only the camera on the robot; skyline, sh, localize, compass, warping, route on the base station;
- coefficients across: camera, skyline and sh on the robot; localize, compass, warping, route on the base station
  (the route controller idle: it has no goal).

The hosts find each other by static peers (--discovery peers, the default) or, with multicast blocked, through the
Fast DDS discovery server the base station's `skynav launch --serve-discovery` runs (--discovery server).

Prints, per split, the bytes sent from the robot to the base station over the link (discovery and
acknowledgements included) per second while the drive plays (from the first camera frame to one frame
period after the last, the link's byte counter read every LINK_SAMPLE_PERIOD s) and per camera frame
(from the replay's start to 2 s after its end), the frames whose home vector reached the base station,
and the latency from the camera frame's reception on the robot to its home vector's on the base station
(both hosts read the same clock), median and 95th percentile: the link's share plus the base station's
work; and the UDP datagrams dropped during the replay (/proc/net/snmp of each host): the base station's
for a full socket receive buffer (Udp.RcvbufErrors), the robot's for a full send buffer (Udp.SndbufErrors),
and the IP datagrams the base station could not reassemble from their fragments (Ip.ReasmFails).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from skynav_core.names import GREEN_IMAGE, HOME_VECTOR, SKYLINE_SH, UV_CAMERA_INFO, UV_IMAGE
from skynav_core.process import netns
from skynav_core.process.network import DISCOVERY_SERVER_PORT, socket_buffer_warning
from skynav_testing import BAGS, claim_domain_id, run_skynav, skynav_command

PROBE = Path(__file__).parents[1] / 'test' / 'graph_probe.py'
CAMERA = (UV_IMAGE, GREEN_IMAGE, UV_CAMERA_INFO)
FRAME_PERIOD_NS = 100_000_000  # the drive's 10 Hz
LINK_SAMPLE_PERIOD = 0.1  # s between two readings of the link's byte counter
DROPS = (('base', 'Udp.RcvbufErrors'), ('robot', 'Udp.SndbufErrors'), ('base', 'Ip.ReasmFails'))
SPLITS = {
    'images across': (('skyline', 'sh', 'localize', 'compass', 'warping', 'route'), UV_IMAGE, 1),
    'coefficients across': (('localize', 'compass', 'warping', 'route'), SKYLINE_SH, 4),
}  # base station's nodes, the topic that crosses, how many base station readers it has


def write_drive(out: Path, frames: int) -> Path:
    """Render the synthetic 640x480 mono16 garden repeat drive of `frames` frames at 10 Hz."""
    result = run_skynav(
        'sim', 'bag', 'repeat', '--world', 'garden', '--seed', '1', '--size', '640x480', '--encoding', 'mono16',
        '--length', f'{frames / 10:.1f}', '--speed', '1.0', '--time', 'morning', '--out', str(out), timeout=900,
    )  # fmt: skip
    if result.returncode != 0:
        sys.exit(result.stderr)
    return out


def receptions(log: Path, topic: str) -> dict[int, int]:
    """Return {header stamp: reception time ns} of one topic in a probe's log."""
    found = {}
    for line in log.read_text().splitlines():
        name, stamp, received = line.split()
        if name == topic:
            found.setdefault(int(stamp), int(received))
    return found


def sample_link(hosts: netns.TwoHosts, samples: list[tuple[int, int]], stop: threading.Event) -> None:
    """Append (wall clock ns, bytes sent robot -> base station) every LINK_SAMPLE_PERIOD s until `stop` is set."""
    while not stop.is_set():
        samples.append((time.time_ns(), hosts.link_bytes()))
        stop.wait(LINK_SAMPLE_PERIOD)


def drive_rate(samples: list[tuple[int, int]], first_ns: int, last_ns: int) -> float:
    """Return the bytes per second over the link from `first_ns` to a frame period after `last_ns` (wall clock)."""
    times, sent = np.array(samples, dtype=float).T
    end_ns = last_ns + FRAME_PERIOD_NS
    start, end = np.interp([first_ns, end_ns], times, sent)
    return float(end - start) / ((end_ns - first_ns) / 1e9)


def measure(split: str, drive: Path, map_file: Path, work: Path, domain: int, transport: str, served: bool) -> dict:
    """Run one split over the drive (`served`: discovery through a server, multicast blocked); return its figures."""
    base_nodes, crossing, readers = SPLITS[split]
    robot_nodes = [n for n in ('skyline', 'sh') if n not in base_nodes]
    with netns.TwoHosts(domain, multicast=not served) as hosts:
        robot, base = hosts.robot, hosts.base
        server = f'{base.address}:{DISCOVERY_SERVER_PORT}' if served else None
        env = {h.namespace: hosts.environment(h, domain, discovery_server=server) for h in (robot, base)}
        launch = ['launch', '--transport', transport, '--map', str(map_file), '--nodes', *base_nodes]
        if served:  # the base station first, serving discovery (nodes started before their server may never match)
            launch += ['--discovery-server', str(server), '--serve-discovery']
        log = work / f'{split}_base.log'
        base_launch = base.start(skynav_command(*launch), env[base.namespace], log)
        while served and '[launch] route: started' not in log.read_text():
            if base_launch.poll() is not None:
                sys.exit(f'{split}: the base station did not start:\n{log.read_text()}')
            time.sleep(0.1)
        if robot_nodes:
            launch = ['launch', '--transport', transport, '--nodes', *robot_nodes]
            robot.start(skynav_command(*launch), env[robot.namespace], work / f'{split}_robot.log')
        wait = robot.start(
            [sys.executable, str(PROBE), '--timeout', '120', '--subscribers', f'{crossing}={readers}'],
            env[robot.namespace],
            work / f'{split}_wait.log',
        )
        if wait.wait(timeout=150) != 0:
            sys.exit(f'{split}: the hosts never connected')
        camera_log, home_log = work / f'{split}_camera.txt', work / f'{split}_home.txt'
        probe = [sys.executable, str(PROBE), '--timeout', '600']
        robot.start([*probe, '--log', str(camera_log), '--messages', f'{CAMERA[0]}=1000000'], env[robot.namespace],
                    work / f'{split}_camera.log')  # fmt: skip
        base.start([*probe, '--log', str(home_log), '--messages', '/homing/home_vector=1000000'], env[base.namespace],
                   work / f'{split}_home.log')  # fmt: skip
        time.sleep(5.0)  # the probes join (a reliable reader of the camera on the robot: the replay waits for it)
        counters = {'robot': robot.snmp(), 'base': base.snmp()}
        before, samples, stop = hosts.link_bytes(), [], threading.Event()
        sampler = threading.Thread(target=sample_link, args=(hosts, samples, stop))
        sampler.start()
        replay = robot.start(  # the hosts are connected: wait for one reader a topic, not the viz node's too
            skynav_command('replay', str(drive), '--topics', *CAMERA, '--wait-for-subscribers', '1'),
            env[robot.namespace],
            work / f'{split}_replay.log',
        )
        replay.wait(timeout=600)
        time.sleep(2.0)  # the last frames' work on the base station
        stop.set()
        sampler.join()
        sent = hosts.link_bytes() - before
        after = {'robot': robot.snmp(), 'base': base.snmp()}
        drops = {f'{h} {name}': after[h][name] - counters[h][name] for h, name in DROPS}
    camera, home = receptions(camera_log, CAMERA[0]), receptions(home_log, HOME_VECTOR)
    latency = np.array([home[s] - camera[s] for s in home if s in camera]) / 1e6
    return {
        'bytes_per_s': drive_rate(samples, min(camera.values()), max(camera.values())) if camera else 0.0,
        'bytes_per_frame': sent / max(1, len(camera)),
        'frames': len(camera),
        'home_vectors': len(home),
        'missing': [i for i, s in enumerate(sorted(camera)) if s not in home],  # frames without a home vector
        'latency_ms': (float(np.median(latency)), float(np.percentile(latency, 95))) if len(latency) else None,
        'drops': drops,
    }


def main() -> int:
    """Measure both splits and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--frames', type=int, default=100, help='frames of the drive at 10 Hz (default 100)')
    parser.add_argument('--transport', choices=('shm', 'udp'), default='shm', help='within each host (default shm)')
    parser.add_argument(
        '--discovery',
        choices=('peers', 'server'),
        default='peers',
        help='static peers (default), or a discovery server on the base station with multicast blocked',
    )
    args = parser.parse_args()
    if reason := netns.unavailable():
        sys.exit(f'link_split: {reason}')
    if warning := socket_buffer_warning():
        print(f'link_split: warning: {warning}', flush=True)
    domain, _lock = claim_domain_id()
    with tempfile.TemporaryDirectory(prefix='skynav-link-') as folder:
        work = Path(folder)
        drive = write_drive(work / 'synthetic_garden_repeat_640x480.mcap', args.frames)
        map_file = work / 'garden.db'
        if run_skynav('map', 'build', str(BAGS / 'synthetic_garden_teach.mcap'), '--out', str(map_file)).returncode:
            sys.exit('link_split: map build failed')
        figures = defaultdict(dict)
        for split in SPLITS:
            figures[split] = measure(split, drive, map_file, work, domain, args.transport, args.discovery == 'server')
            f = figures[split]
            latency = 'n/a' if f['latency_ms'] is None else '{:.0f} ms median, {:.0f} ms p95'.format(*f['latency_ms'])
            print(
                f'{split:20s} {f["bytes_per_s"] / 1e3:10.1f} kB/s {f["bytes_per_frame"] / 1e3:8.1f} kB/frame  '
                f'home vectors {f["home_vectors"]:4d} of {f["frames"]:4d} frames  camera -> home vector {latency}',
                flush=True,
            )
            print(
                f'{"":20s} frames without a home vector: {f["missing"] or "none"}; '
                f'dropped: {", ".join(f"{name} {count}" for name, count in f["drops"].items())}',
                flush=True,
            )
        ratio = figures['coefficients across']['bytes_per_s'] / figures['images across']['bytes_per_s']
        print(f'coefficients / images: {ratio:.4f} of the bytes (1/{1 / ratio:.0f})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
