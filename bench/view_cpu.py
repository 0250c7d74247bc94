# SPDX-License-Identifier: Apache-2.0
"""Benchmark: the CPU `skynav view` adds to the running graph at 10 Hz, with a Foxglove client watching.

    .venv/bin/python bench/view_cpu.py [--seconds S] [--drive BAG --teach BAG]

`skynav launch --map` runs the whole graph (skyline, sh, localize, compass, warping, route, viz), `skynav replay
--loop` plays a synthetic 10 Hz repeat drive in real time (default: the bundled garden drive, 320x240), and
`skynav view` serves the live topics to a Foxglove WebSocket client (this script, with the SDK's subprotocol)
subscribed to every topic of the shipped layout (skynav_bringup/config/skynav.foxglove.json: the markers, the
overlay image, confidence, state, the match and the home vector), as the Foxglove app with that layout would be.

For S seconds with the client subscribed, then S seconds with no client, the CPU time (user + system, from
/proc) of the view process and of the graph's node processes is read; printed: each one's CPU as a share of one
core, and the ratio view / graph (the target: under 5 %). The viz node is a node of the graph; its own share is
printed too.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import websockets

from skynav_bringup.cli.view import layout_file
from skynav_core.names import HOME_VECTOR
from skynav_testing import BAGS, claim_domain_id, run_skynav, skynav_command

SUBPROTOCOL = 'foxglove.sdk.v1'
UNKNOWN_CHANNEL = 'Unknown channel ID: '
TICKS = os.sysconf('SC_CLK_TCK')
STARTED = re.compile(r'^\[launch\] (\w+): started \(pid (\d+)')


def cpu_seconds(pid: int) -> float:
    """Return a process's CPU time so far (user + system, s)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def layout_topics() -> set[str]:
    """Return the topics the shipped Foxglove layout's panels show."""
    path = layout_file()
    if path is None:
        sys.exit('the Foxglove layout is not installed (make setup)')
    topics = set()
    for panel, config in json.loads(path.read_text())['configById'].items():
        if panel.startswith('3D!'):
            topics |= set(config['topics'])
        elif panel.startswith('Image!'):
            topics.add(config['imageMode']['imageTopic'])
        elif panel.startswith('Plot!'):
            topics |= {p['value'].split('.')[0] for p in config['paths']}
    return topics


class Client:
    """A Foxglove WebSocket client in a thread of its own: subscribes to `topics`, counts what arrives."""

    def __init__(self, url: str, topics: set[str]) -> None:
        self.url, self.topics = url, topics
        self.messages = 0
        self.bytes = 0
        self.subscribed: set[str] = set()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=lambda: asyncio.run(self.run()), daemon=True)
        self.thread.start()

    async def run(self) -> None:
        async with websockets.connect(self.url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
            channels: dict[int, str] = {}
            while not self.stop.is_set():
                try:
                    frame = await asyncio.wait_for(ws.recv(), 0.2)
                except TimeoutError:
                    continue
                if isinstance(frame, bytes):
                    self.messages += 1
                    self.bytes += len(frame)
                    continue
                message = json.loads(frame)
                if message['op'] == 'advertise':
                    wanted = [c for c in message['channels'] if c['topic'] in self.topics]
                elif message['op'] == 'status' and message['message'].startswith(UNKNOWN_CHANNEL):
                    refused = int(message['message'].removeprefix(UNKNOWN_CHANNEL))
                    wanted = [{'id': refused, 'topic': channels[refused]}]
                else:
                    continue
                for channel in wanted:
                    channels[channel['id']] = channel['topic']
                    self.subscribed.add(channel['topic'])
                subscriptions = [{'id': c['id'] + 1000 * len(self.subscribed), 'channelId': c['id']} for c in wanted]
                if subscriptions:
                    await ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subscriptions}))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=10)


def read_lines(process: subprocess.Popen, lines: list[str]) -> threading.Thread:
    """Collect a process's merged output lines in a thread."""

    def collect() -> None:
        assert process.stdout is not None
        for line in process.stdout:
            lines.append(line)

    thread = threading.Thread(target=collect, daemon=True)
    thread.start()
    return thread


def wait_for(condition, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            sys.exit(f'timed out waiting for {what}')
        time.sleep(0.1)


def measure(pids: dict[str, int], seconds: float) -> tuple[dict[str, float], float]:
    """Return each process's CPU seconds over the next `seconds` of wall time, and the wall time."""
    before = {name: cpu_seconds(pid) for name, pid in pids.items()}
    start = time.monotonic()
    time.sleep(seconds)
    wall = time.monotonic() - start
    return {name: cpu_seconds(pid) - before[name] for name, pid in pids.items()}, wall


def report(title: str, used: dict[str, float], wall: float, client: Client | None = None) -> None:
    graph = sum(v for name, v in used.items() if name != 'view')
    print(f'\n{title} ({wall:.1f} s)')
    for name, value in sorted(used.items(), key=lambda item: -item[1]):
        print(f'  {name:10s} {value:7.2f} s CPU  {100 * value / wall:6.1f} % of a core')
    print(f'  graph      {graph:7.2f} s CPU  {100 * graph / wall:6.1f} % of a core (every node, viz included)')
    print(
        f'  view / graph = {100 * used["view"] / graph:.2f} %   (viz node / graph = {100 * used["viz"] / graph:.2f} %)'
    )
    if client is not None:
        print(f'  client received {client.messages / wall:.1f} msg/s, {client.bytes / wall / 1e3:.1f} kB/s')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=30.0, help='length of each measurement (s, default 30)')
    parser.add_argument('--drive', type=Path, default=BAGS / 'synthetic_garden_repeat.mcap', help='10 Hz drive')
    parser.add_argument('--teach', type=Path, default=BAGS / 'synthetic_garden_teach.mcap', help='its teach drive')
    args = parser.parse_args()
    domain, _lock = claim_domain_id()
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    topics = layout_topics()
    with tempfile.TemporaryDirectory() as folder:
        map_file = Path(folder) / 'route.db'
        built = run_skynav('map', 'build', str(args.teach), '--out', str(map_file), timeout=600)
        if built.returncode != 0:
            sys.exit(built.stderr)
        launch_lines: list[str] = []
        launch = subprocess.Popen(
            skynav_command('launch', '--map', str(map_file)),
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
        )  # fmt: skip
        read_lines(launch, launch_lines)
        view_lines: list[str] = []
        view = subprocess.Popen(
            skynav_command('view', '--port', '0'), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        read_lines(view, view_lines)
        replay = client = None
        try:
            wait_for(lambda: sum(bool(STARTED.match(line)) for line in launch_lines) >= 7, 60, 'the graph to start')
            pids = {m.group(1): int(m.group(2)) for line in launch_lines if (m := STARTED.match(line))}
            wait_for(lambda: any('server on ws://' in line for line in view_lines), 60, 'skynav view')
            url = next(line for line in view_lines if 'server on ws://' in line).split(' on ')[1].split()[0]
            pids['view'] = view.pid
            client = Client(url, topics)
            wait_for(lambda: client.subscribed >= topics - {HOME_VECTOR}, 60, 'the layout topics')
            replay = subprocess.Popen(
                skynav_command('replay', str(args.drive), '--loop', '--rate', '1'),
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            )  # fmt: skip
            wait_for(lambda: client.messages > 50, 120, 'the first frames to reach the client')
            watched, wall = measure(pids, args.seconds)
            report('a Foxglove client subscribed to the layout', watched, wall, client)
            client.close()
            client = None
            time.sleep(2.0)  # the viewer unsubscribes
            idle, wall = measure(pids, args.seconds)
            report('no client', idle, wall)
        finally:
            if client is not None:
                client.close()
            for process in (replay, view):
                if process is not None and process.poll() is None:
                    process.send_signal(signal.SIGINT)
                    process.wait(timeout=30)
            launch.send_signal(signal.SIGINT)
            launch.wait(timeout=60)
    return 0


if __name__ == '__main__':
    sys.exit(main())
