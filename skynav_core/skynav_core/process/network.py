# SPDX-License-Identifier: Apache-2.0
"""How the nodes find each other and what carries their messages: discovery and transport for real networks.

By default (skynav_core.process.environment) discovery stays on this machine and messages between processes go
through shared memory. A robot and a base station on one network need wider discovery: the subnet
(multicast), static peers (unicast to given addresses, where multicast is blocked, as on many Wi-Fi
networks), or a Fast DDS discovery server that every participant asks. The transport 'shm' keeps shared
memory between processes of one machine (UDP between machines); 'udp' uses UDP only.

With a discovery server, start it before the nodes: with the Fast DDS 2.14 of the wheels, participants that
started before their server did may never find each other through it (docs/networking.md, 'Robot and base station').
A plain client learns only of the topics it reads or writes; the tools that list the graph (record, echo,
replay) are made super clients (ROS_SUPER_CLIENT), which learn of every topic.

Both profiles ask for UDP socket buffers of SOCKET_BUFFER bytes, so that a camera frame (a burst of 64 kB
datagrams) is not dropped on its way to another host; Linux caps them at net.core.rmem_max and wmem_max,
which must be raised on each host (:func:`socket_buffer_warning` says when they are too low).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
from collections.abc import MutableMapping
from pathlib import Path
from typing import TextIO

from ..errors import SkynavError
from .environment import FASTDDS_PROFILE, PACKAGE, share_directory

DISCOVERY_RANGES = ('localhost', 'subnet', 'off', 'system_default')
TRANSPORTS = {'shm': FASTDDS_PROFILE, 'udp': Path('config') / 'fastdds_udp.xml'}
DISCOVERY_SERVER_PORT = 11811  # Fast DDS's default discovery server port (UDP)
DISCOVERY_SERVER = 'fast-discovery-server'  # the server program the Fast DDS wheel installs
DISCOVERY_SERVER_READY = 'Server is running'  # what the server prints once it serves
DISCOVERY_SERVER_START_TIMEOUT = 10.0  # s for the server to say it serves
SOCKET_BUFFER = 4194304  # bytes: the UDP socket buffers the profiles ask for (<sendBufferSize>, <receiveBufferSize>)
SOCKET_BUFFER_LIMITS = ('net.core.rmem_max', 'net.core.wmem_max')  # Linux's caps on them, bytes


class NetworkError(SkynavError, ValueError):
    """A discovery or transport setting that cannot be used."""


def server_locator(text: str) -> tuple[str, int]:
    """Return (address, UDP port) of 'ADDRESS[:PORT]' (NetworkError if malformed)."""
    address, _, port = text.partition(':')
    if not address or (port and not port.isdigit()) or not 0 < int(port or DISCOVERY_SERVER_PORT) < 65536:
        raise NetworkError(f'discovery server {text!r}: expected ADDRESS or ADDRESS:PORT')
    return address, int(port or DISCOVERY_SERVER_PORT)


def network_environment(
    discovery_range: str | None = None,
    static_peers: list[str] | None = None,
    discovery_server: str | None = None,
    transport: str | None = None,
) -> dict[str, str]:
    """Return the environment variables that set discovery and transport as given (None: leave as is)."""
    env: dict[str, str] = {}
    if discovery_range is None and discovery_server is not None:
        discovery_range = 'subnet'  # the server is on another host: discovery must leave this one
    if discovery_range is not None:
        if discovery_range not in DISCOVERY_RANGES:
            raise NetworkError(f'discovery range must be one of {", ".join(DISCOVERY_RANGES)}')
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = discovery_range.upper()
    if static_peers:
        if bad := [p for p in static_peers if not p or ';' in p or ' ' in p]:
            raise NetworkError(f'static peers must be addresses or host names: {bad}')
        env['ROS_STATIC_PEERS'] = ';'.join(static_peers)
    if discovery_server is not None:
        address, port = server_locator(discovery_server)
        env['ROS_DISCOVERY_SERVER'] = f'{address}:{port}'
    if transport is not None:
        if transport not in TRANSPORTS:
            raise NetworkError(f'transport must be one of {", ".join(TRANSPORTS)}')
        share = share_directory(PACKAGE)
        if share is None or not (share / TRANSPORTS[transport]).is_file():
            raise NetworkError(f'the Fast DDS profile of transport {transport!r} is not installed (run make setup)')
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(share / TRANSPORTS[transport])
    return env


def socket_buffer_warning(proc_sys: Path = Path('/proc/sys')) -> str | None:
    """Return one line naming the kernel limits that cap the UDP socket buffers below SOCKET_BUFFER, None if none.

    Unreadable limits (not Linux) say nothing.
    """
    low = []
    for name in SOCKET_BUFFER_LIMITS:
        try:
            value = int((proc_sys / name.replace('.', '/')).read_text())
        except (OSError, ValueError):
            continue
        if value < SOCKET_BUFFER:
            low.append(f'{name} is {value}')
    if not low:
        return None
    raise_all = ' '.join(f'{name}={SOCKET_BUFFER}' for name in SOCKET_BUFFER_LIMITS)
    return (
        f'{" and ".join(low)} bytes, below the {SOCKET_BUFFER} of the UDP socket buffers the Fast DDS profile asks '
        f'for: large messages to other hosts (camera images) will be lost; as root, sysctl -w {raise_all} '
        "(docs/networking.md, 'Robot and base station')"
    )


def discovery_server_command(locator: str) -> tuple[list[str], dict[str, str]]:
    """Return the command line of a Fast DDS discovery server listening on 'ADDRESS[:PORT]', and its environment.

    The server program comes with the Fast DDS wheel; its libraries are in this environment's lib/ and in the
    wheel's own library folder (ros_fastrtps.libs, next to the Python packages).
    """
    address, port = server_locator(locator)
    program = Path(sys.prefix) / 'bin' / DISCOVERY_SERVER
    if not program.is_file():
        raise NetworkError(f'{program}: no Fast DDS discovery server installed')
    libraries = [str(Path(sys.prefix) / 'lib')] + [
        str(Path(p) / 'ros_fastrtps.libs') for p in sys.path if (Path(p) / 'ros_fastrtps.libs').is_dir()
    ]
    path = os.pathsep.join([*libraries, *filter(None, os.environ.get('LD_LIBRARY_PATH', '').split(os.pathsep))])
    return [str(program), '-i', '0', '-l', address, '-p', str(port)], {'LD_LIBRARY_PATH': path}


def start_discovery_server(locator: str, out: TextIO) -> subprocess.Popen:
    """Start a Fast DDS discovery server on 'ADDRESS[:PORT]' and return it once it serves; its output goes to `out`.

    NetworkError (and no server left running) if ADDRESS is not one of this host's or the server does not
    say it serves within DISCOVERY_SERVER_START_TIMEOUT s.
    """
    address, port = server_locator(locator)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.bind((address, 0))
        except OSError as error:
            raise NetworkError(
                f'cannot serve discovery on {address}: not an address of this host ({error.strerror})'
            ) from None
    command, env = discovery_server_command(locator)
    server = subprocess.Popen(
        command,
        env={**os.environ, **env},
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    serving = threading.Event()

    def relay() -> None:
        assert server.stdout is not None  # started with stdout=PIPE
        for line in server.stdout:
            if DISCOVERY_SERVER_READY in line:
                serving.set()
            out.write(f'[discovery] {line.rstrip()}\n')
            out.flush()

    threading.Thread(target=relay, daemon=True).start()
    if not serving.wait(DISCOVERY_SERVER_START_TIMEOUT):
        server.kill()
        server.wait()
        raise NetworkError(
            f'the discovery server on {address}:{port} did not start within {DISCOVERY_SERVER_START_TIMEOUT:g} s '
            f'(exit code {server.returncode})'
        )
    return server


def make_super_client(environ: MutableMapping[str, str] | None = None) -> None:
    """Make a tool that lists the graph a super client of the discovery server, if there is one (ROS_SUPER_CLIENT).

    A plain client learns only of the topics it reads or writes; a recorder or `skynav echo` must see them all.
    Only effective before the tool's participant is created; a user's own setting wins.
    """
    target = os.environ if environ is None else environ
    if target.get('ROS_DISCOVERY_SERVER'):
        target.setdefault('ROS_SUPER_CLIENT', 'TRUE')
