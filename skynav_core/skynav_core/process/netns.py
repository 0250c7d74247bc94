# SPDX-License-Identifier: Apache-2.0
"""Two hosts on one machine, for tests and benchmarks: network namespaces joined by a veth pair.

Each host is a network namespace with its own mount namespace and its own tmpfs on /dev/shm, so its
processes share memory among themselves (Fast DDS's shared-memory transport works inside a host) but
not with the other host: between the hosts everything goes over UDP on the veth link, as between two
machines. Every process of a host enters the namespaces of one holder process (`nsenter`), so they all
see the same /dev/shm (Fast DDS participants of one address that cannot share memory exchange no data).
Multicast can be blocked, as many Wi-Fi access points do: no socket of either host may then join a multicast
group (net.ipv4.igmp_max_memberships = 0), so no multicast datagram is taken in.
Needs root (`ip netns`, `unshare`, `nsenter`); :func:`unavailable` says why not, in one line.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

SUBNET = '10.231.{tag}.{host}'  # the link's addresses, /24
HOLDER_START_TIMEOUT = 10.0  # s for a host's holder process to set its /dev/shm up
COMMANDS = ('ip', 'unshare', 'nsenter', 'mount')


def unavailable() -> str | None:
    """Return why network namespaces cannot be made here (one line), None when they can."""
    if os.geteuid() != 0:
        return 'network namespaces need root'
    if missing := [c for c in COMMANDS if shutil.which(c) is None]:
        return f'missing commands: {", ".join(missing)}'
    probe = f'skynav-probe-{os.getpid()}'
    made = subprocess.run(['ip', 'netns', 'add', probe], capture_output=True, text=True)
    if made.returncode != 0:
        return f'ip netns add failed: {made.stderr.strip()}'
    subprocess.run(['ip', 'netns', 'del', probe], capture_output=True)
    return None


@dataclass
class Host:
    """One host: a network namespace, its address on the link, and the holder of its mount namespace."""

    namespace: str
    interface: str
    address: str
    holder: subprocess.Popen | None = None
    processes: list[subprocess.Popen] = field(default_factory=list)

    def command(self, argv: list[str]) -> list[str]:
        """Return `argv` run inside this host (its network and mount namespaces)."""
        assert self.holder is not None, 'host not started'
        return ['nsenter', '-t', str(self.holder.pid), '-n', '-m', f'--wd={os.getcwd()}', '--', *argv]

    def start(self, argv: list[str], env: dict[str, str], log: Path) -> subprocess.Popen:
        """Start a process on this host with its output in `log`; it is stopped with the host."""
        with open(log, 'w') as out:
            process = subprocess.Popen(
                self.command(argv), env=env, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL
            )
        self.processes.append(process)
        return process

    def boot(self) -> None:
        """Start the holder: a fresh mount namespace with a private tmpfs on /dev/shm."""
        self.holder = subprocess.Popen(
            [
                'ip',
                'netns',
                'exec',
                self.namespace,
                'unshare',
                '-m',
                '--propagation',
                'private',
                'sh',
                '-c',
                'mount -t tmpfs skynav-shm /dev/shm && exec sleep infinity',
            ],  # fmt: skip
            stdin=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + HOLDER_START_TIMEOUT
        comm = Path(f'/proc/{self.holder.pid}/comm')
        while time.monotonic() < deadline and self.holder.poll() is None:
            if comm.read_text().strip() == 'sleep':
                return
            time.sleep(0.02)
        raise RuntimeError(f'host {self.namespace}: could not set up its /dev/shm')

    def snmp(self) -> dict[str, int]:
        """Return this host's IP and UDP counters since its namespace was made, e.g. {'Udp.RcvbufErrors': 0}."""
        lines = run(['ip', 'netns', 'exec', self.namespace, 'cat', '/proc/net/snmp']).splitlines()
        counters = {}
        for names, values in zip(lines[::2], lines[1::2]):  # a line of names, then one of values, per protocol
            protocol, *fields = names.split()
            counters.update({f'{protocol[:-1]}.{f}': int(v) for f, v in zip(fields, values.split()[1:])})
        return counters

    def crash(self) -> None:
        """Kill every process of this host at once (SIGKILL) and start it again with an empty /dev/shm: a reboot."""
        self.halt(grace=0.0)
        self.boot()

    def kill_all(self) -> None:
        """SIGKILL every process left in this host's network namespace (children of processes stopped already)."""
        listed = subprocess.run(['ip', 'netns', 'pids', self.namespace], capture_output=True, text=True)
        for pid in listed.stdout.split():
            try:
                os.kill(int(pid), signal.SIGKILL)
            except ProcessLookupError:
                pass

    def halt(self, grace: float = 10.0) -> None:
        """Stop every process of this host (SIGINT, then SIGKILL after `grace` s) and its holder."""
        for process in self.processes:
            if process.poll() is None:
                process.send_signal(signal.SIGINT if grace > 0 else signal.SIGKILL)
        deadline = time.monotonic() + grace
        for process in self.processes:
            try:
                process.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        self.processes.clear()
        self.kill_all()
        if self.holder is not None:
            self.holder.kill()
            self.holder.wait()
            self.holder = None


class TwoHosts:
    """A robot and a base station joined by a veth link; a context manager that removes everything it made."""

    def __init__(self, tag: int, multicast: bool = True) -> None:
        self.tag = tag % 250 + 1
        self.multicast = multicast
        name = f'skynav{os.getpid()}'
        self.robot = Host(f'{name}-robot', f'skv{self.tag}r', SUBNET.format(tag=self.tag, host=1))
        self.base = Host(f'{name}-base', f'skv{self.tag}b', SUBNET.format(tag=self.tag, host=2))

    def __enter__(self) -> TwoHosts:
        try:
            for host in (self.robot, self.base):
                run(['ip', 'netns', 'add', host.namespace])
            run([
                'ip', 'link', 'add', self.robot.interface, 'netns', self.robot.namespace, 'type', 'veth',
                'peer', 'name', self.base.interface, 'netns', self.base.namespace,
            ])  # fmt: skip
            for host in (self.robot, self.base):
                run(['ip', '-n', host.namespace, 'addr', 'add', f'{host.address}/24', 'dev', host.interface])
                run(['ip', '-n', host.namespace, 'link', 'set', host.interface, 'up'])
                run(['ip', '-n', host.namespace, 'link', 'set', 'lo', 'up'])
                if not self.multicast:
                    run(['ip', 'netns', 'exec', host.namespace, 'sysctl', '-qw', 'net.ipv4.igmp_max_memberships=0'])
                host.boot()
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        for host in (self.robot, self.base):
            host.halt()
        for host in (self.robot, self.base):
            subprocess.run(['ip', 'netns', 'del', host.namespace], capture_output=True)

    def peer(self, host: Host) -> Host:
        """Return the other host."""
        return self.base if host is self.robot else self.robot

    def environment(
        self, host: Host, domain: int, base: dict[str, str] | None = None, discovery_server: str | None = None
    ) -> dict[str, str]:
        """Return the environment of a ROS process on `host`: subnet discovery with the other host as static peer.

        With `discovery_server` ('ADDRESS:PORT'), discovery goes through that Fast DDS server instead.
        """
        env = dict(os.environ if base is None else base)
        env.update({'ROS_DOMAIN_ID': str(domain), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET', 'PYTHONUNBUFFERED': '1'})
        if discovery_server is None:
            env['ROS_STATIC_PEERS'] = self.peer(host).address
        else:
            env['ROS_DISCOVERY_SERVER'] = discovery_server
            env.pop('ROS_STATIC_PEERS', None)
        return env

    def link_bytes(self) -> int:
        """Return the bytes sent so far from the robot to the base station over the link."""
        path = f'/sys/class/net/{self.robot.interface}/statistics/tx_bytes'
        out = run(['ip', 'netns', 'exec', self.robot.namespace, 'cat', path])
        return int(out.strip())


def run(argv: list[str]) -> str:
    """Run a command to the end; RuntimeError with its message if it fails."""
    done = subprocess.run(argv, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f'{" ".join(argv)}: {done.stderr.strip()}')
    return done.stdout
