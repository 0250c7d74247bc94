# SPDX-License-Identifier: Apache-2.0
"""Discovery and transport settings become the environment variables ROS 2 and Fast DDS read."""

import io
import os
import socket
import subprocess
from pathlib import Path

import pytest

from skynav_core.network import (
    NetworkError,
    discovery_server_command,
    make_super_client,
    network_environment,
    server_locator,
    start_discovery_server,
)


def test_nothing_given_changes_nothing():
    assert network_environment() == {}


def test_range_and_static_peers():
    env = network_environment('subnet', ['192.168.1.20', 'robot.local'])
    assert env == {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET', 'ROS_STATIC_PEERS': '192.168.1.20;robot.local'}


def test_a_discovery_server_widens_discovery_to_the_subnet_unless_told():
    assert network_environment(discovery_server='10.0.0.1') == {
        'ROS_DISCOVERY_SERVER': '10.0.0.1:11811',
        'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET',
    }
    env = network_environment('localhost', discovery_server='127.0.0.1:9000')
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST' and env['ROS_DISCOVERY_SERVER'] == '127.0.0.1:9000'


@pytest.mark.parametrize('transport', ['shm', 'udp'])
def test_each_transport_names_an_installed_profile_of_its_kind(transport):
    profile = Path(network_environment(transport=transport)['FASTRTPS_DEFAULT_PROFILES_FILE'])
    text = profile.read_text()
    assert '<type>UDPv4</type>' in text and ('<type>SHM</type>' in text) == (transport == 'shm')


@pytest.mark.parametrize(
    'kwargs',
    [
        {'discovery_range': 'everywhere'},
        {'static_peers': ['a;b']},
        {'discovery_server': 'host:port'},
        {'discovery_server': ':11811'},
        {'discovery_server': 'host:70000'},
        {'transport': 'tcp'},
    ],
)
def test_unusable_settings_are_refused_in_one_line(kwargs):
    with pytest.raises(NetworkError) as error:
        network_environment(**kwargs)
    assert '\n' not in str(error.value)


def test_the_discovery_server_command_listens_where_asked():
    command, env = discovery_server_command('10.0.0.1:11888')
    assert Path(command[0]).name == 'fast-discovery-server' and command[-4:] == ['-l', '10.0.0.1', '-p', '11888']
    started = subprocess.run([command[0], '-h'], env={**os.environ, **env}, capture_output=True, text=True, timeout=30)
    assert started.returncode == 0 and 'Usage' in started.stdout, started.stderr  # its libraries are found
    assert server_locator('10.0.0.1') == ('10.0.0.1', 11811)


def free_udp_port() -> int:
    """Return a UDP port of 127.0.0.1 that nothing listens on now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def test_a_started_discovery_server_serves_until_stopped():
    out = io.StringIO()
    port = free_udp_port()
    server = start_discovery_server(f'127.0.0.1:{port}', out)
    try:
        assert server.poll() is None and '[discovery] ### Server is running ###' in out.getvalue()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s, pytest.raises(OSError):
            s.bind(('127.0.0.1', port))  # the server holds its port
    finally:
        server.terminate()
        assert server.wait(timeout=10) == 0


def test_discovery_is_served_only_on_an_address_of_this_host():
    with pytest.raises(NetworkError, match='not an address of this host') as error:
        start_discovery_server('192.0.2.1', io.StringIO())  # TEST-NET-1: never assigned
    assert '\n' not in str(error.value)


def test_tools_become_super_clients_only_with_a_discovery_server():
    plain: dict[str, str] = {}
    make_super_client(plain)
    assert plain == {}
    served = {'ROS_DISCOVERY_SERVER': '10.0.0.1:11811'}
    make_super_client(served)
    assert served['ROS_SUPER_CLIENT'] == 'TRUE'
    told = {'ROS_DISCOVERY_SERVER': '10.0.0.1:11811', 'ROS_SUPER_CLIENT': 'FALSE'}
    make_super_client(told)
    assert told['ROS_SUPER_CLIENT'] == 'FALSE'
