# SPDX-License-Identifier: Apache-2.0
"""Start nodes one process each, relay their output with a name prefix, and stop them cleanly.

This is what `skynav launch` runs where the ROS 2 `launch` tools are not
installed; on a full ROS 2 install ``ros2 launch skynav_bringup skynav.launch.py``
starts the same nodes.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from typing import TextIO

from ..nodes import NodeSpec
from ..run_node import STACKS_SIGNAL
from .environment import apply_ros_environment

# After SIGINT a node gets this long to shut down before SIGTERM, and as long again before SIGKILL (s).
STOP_GRACE = 10.0
POLL_PERIOD = 0.1
STACKS_WAIT = 1.0  # s a node that would not stop gets to write its stacks before it is killed


def node_command(spec: NodeSpec, ros_args: Sequence[str] = ()) -> list[str]:
    """Return the command line that runs one node in a process of its own, with its --ros-args."""
    return [sys.executable, '-m', 'skynav_core.run_node', spec.entry, '--ros-args', *ros_args]


class Launcher:
    """The processes of a set of nodes."""

    def __init__(self, specs: Sequence[NodeSpec], ros_args: Sequence[str] = (), out: TextIO = sys.stdout):
        self.specs = list(specs)
        self.ros_args = list(ros_args)
        self.out = out
        self.processes: dict[str, subprocess.Popen] = {}
        self.exit_codes: dict[str, int] = {}
        self._relays: list[threading.Thread] = []
        self._lock = threading.Lock()

    def say(self, text: str) -> None:
        """Print one line of the launcher's own."""
        with self._lock:
            print(f'[launch] {text}', file=self.out, flush=True)

    def start(self) -> None:
        """Start every node; each in its own session, so a terminal's Ctrl-C reaches only the launcher."""
        env = dict(os.environ)
        apply_ros_environment(env)
        env['PYTHONUNBUFFERED'] = '1'
        for spec in self.specs:
            process = subprocess.Popen(
                node_command(spec, self.ros_args),
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                env=env,
                text=True,
                start_new_session=True,
            )
            self.processes[spec.name] = process
            relay = threading.Thread(target=self._relay, args=(spec.name, process), daemon=True)
            relay.start()
            self._relays.append(relay)
            self.say(f'{spec.name}: started (pid {process.pid}, {spec.entry})')

    def _relay(self, name: str, process: subprocess.Popen) -> None:
        assert process.stdout is not None  # started with stdout=PIPE
        for line in process.stdout:
            with self._lock:
                self.out.write(f'[{name}] {line}' if line.endswith('\n') else f'[{name}] {line}\n')
                self.out.flush()

    def running(self) -> list[str]:
        """Return the nodes whose process is alive; report each one that ended since the last call."""
        alive = []
        for name, process in self.processes.items():
            code = process.poll()
            if code is None:
                alive.append(name)
            elif name not in self.exit_codes:
                self.exit_codes[name] = code
                self.say(f'{name}: process ended with exit code {code}')
        return alive

    def wait(self, stop_requested) -> int:
        """Wait until every node ended or `stop_requested()` is true, then stop the rest; return an exit code.

        The exit code is 0 when every node ended cleanly (exit code 0, or
        interrupted by the stop), 1 otherwise.
        """
        while self.running():
            if stop_requested():
                self.stop()
                break
            time.sleep(POLL_PERIOD)
        for relay in self._relays:
            relay.join(timeout=1.0)
        failed = {n: c for n, c in self.exit_codes.items() if c not in (0, -signal.SIGINT)}
        return 1 if failed else 0

    def stop(self) -> None:
        """Ask every node to stop (SIGINT), then insist (SIGTERM, SIGKILL) on those that do not; before the SIGKILL,
        a node that would not stop is asked for its threads' stacks (run_node.STACKS_SIGNAL), to show where it hung."""
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            alive = self.running()
            if not alive:
                return
            if signum == signal.SIGKILL:
                self.say(f'{", ".join(alive)} did not stop: the Python stacks of its threads follow')
                for name in alive:
                    self.processes[name].send_signal(STACKS_SIGNAL)
                time.sleep(STACKS_WAIT)
            self.say(f'sending {signal.Signals(signum).name} to {", ".join(alive)}')
            for name in alive:
                self.processes[name].send_signal(signum)
            deadline = time.monotonic() + STOP_GRACE
            while self.running() and time.monotonic() < deadline:
                time.sleep(POLL_PERIOD)
