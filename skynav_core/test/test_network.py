# SPDX-License-Identifier: Apache-2.0
"""Discovery and transport settings become the environment variables ROS 2 and Fast DDS read."""

import io
import os
import socket
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from skynav_core.process.network import (
    SOCKET_BUFFER,
    NetworkError,
    discovery_server_command,
    make_super_client,
    network_environment,
    server_locator,
    socket_buffer_warning,
    start_discovery_server,
)

FASTDDS = '{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}'


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
    profile = ET.parse(network_environment(transport=transport)['FASTRTPS_DEFAULT_PROFILES_FILE']).getroot()
    descriptors = {d.findtext(f'{FASTDDS}transport_id'): d for d in profile.iter(f'{FASTDDS}transport_descriptor')}
    used = [t.text for users in profile.iter(f'{FASTDDS}userTransports') for t in users]
    kinds = {descriptors[t].findtext(f'{FASTDDS}type') for t in used}
    assert kinds == ({'UDPv4', 'SHM'} if transport == 'shm' else {'UDPv4'})
    (udp,) = [d for d in descriptors.values() if d.findtext(f'{FASTDDS}type') == 'UDPv4']
    # large enough for camera frames crossing to another host in bursts of 64 kB datagrams
    assert int(udp.findtext(f'{FASTDDS}sendBufferSize')) == int(udp.findtext(f'{FASTDDS}receiveBufferSize'))
    assert int(udp.findtext(f'{FASTDDS}receiveBufferSize')) == SOCKET_BUFFER


def write_limits(proc_sys: Path, rmem_max: int, wmem_max: int) -> Path:
    """Write the kernel's socket buffer limits as /proc/sys shows them, under `proc_sys`."""
    (proc_sys / 'net' / 'core').mkdir(parents=True)
    (proc_sys / 'net' / 'core' / 'rmem_max').write_text(f'{rmem_max}\n')
    (proc_sys / 'net' / 'core' / 'wmem_max').write_text(f'{wmem_max}\n')
    return proc_sys


def test_kernel_limits_below_the_profiles_socket_buffers_are_named_in_one_line(tmp_path):
    assert socket_buffer_warning(write_limits(tmp_path / 'big', SOCKET_BUFFER, 2 * SOCKET_BUFFER)) is None
    warning = socket_buffer_warning(write_limits(tmp_path / 'stock', 212992, SOCKET_BUFFER))
    assert warning is not None and '\n' not in warning
    assert 'net.core.rmem_max is 212992' in warning and 'wmem_max is' not in warning
    assert f'sysctl -w net.core.rmem_max={SOCKET_BUFFER} net.core.wmem_max={SOCKET_BUFFER}' in warning
    assert socket_buffer_warning(tmp_path / 'not-linux') is None


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
