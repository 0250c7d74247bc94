# SPDX-License-Identifier: Apache-2.0
"""The ROS environment skynav applies: defaults where the user set nothing, the user's values kept."""

import sys
from pathlib import Path

from skynav_core.process.environment import ament_prefixes, ros_environment, share_directory


def test_defaults_fill_an_empty_environment():
    added = ros_environment({'HOME': '/nonexistent-home'})
    assert added['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    assert added['RMW_IMPLEMENTATION'] == 'rmw_fastrtps_cpp'
    assert added['OPENBLAS_NUM_THREADS'] == '1' and added['OMP_NUM_THREADS'] == '1'
    assert str(sys.prefix) in added['AMENT_PREFIX_PATH'].split(':')
    # HOME is not writable, so logs go to a temp directory rather than failing rclpy.init.
    assert 'skynav-ros-log' in added['ROS_LOG_DIR']
    profile = Path(added['FASTRTPS_DEFAULT_PROFILES_FILE'])
    assert profile.name == 'fastdds_shm.xml' and profile.is_file()
    assert 'segment_size' in profile.read_text()


def test_user_settings_win():
    user = {
        'ROS_DOMAIN_ID': '17',
        'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET',
        'ROS_LOG_DIR': '/tmp/mylogs',
        'FASTRTPS_DEFAULT_PROFILES_FILE': '/etc/my_profile.xml',
    }
    added = ros_environment(user)
    assert not set(added) & set(user)


def test_ament_prefix_keeps_user_prefixes_first():
    prefixes = ament_prefixes({'AMENT_PREFIX_PATH': '/opt/ros/jazzy:/ws/install'})
    assert prefixes[:2] == [Path('/opt/ros/jazzy'), Path('/ws/install')]
    assert prefixes[-1] == Path(sys.prefix)


def test_installed_packages_are_in_the_ament_index():
    for package in ('skynav_msgs', 'skynav_bringup', 'skynav_sh'):
        share = share_directory(package)
        assert share is not None and (share / 'package.xml').is_file(), package
    assert share_directory('no_such_package_anywhere') is None
