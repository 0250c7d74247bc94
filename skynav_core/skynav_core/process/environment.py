# SPDX-License-Identifier: Apache-2.0
"""The process environment that ROS 2 from the PyPI wheels needs, applied by skynav itself.

Every entry point (`skynav`, each node, the test fixtures) calls
:func:`apply_ros_environment` before rclpy is initialised, so nobody has to
source a setup script. Variables the user has set always win; in particular a
user's own ``ROS_DOMAIN_ID`` is kept.
"""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Mapping, MutableMapping
from pathlib import Path

PACKAGE = 'skynav_core'
FASTDDS_PROFILE = Path('config') / 'fastdds_shm.xml'


def ament_prefixes(environ: Mapping[str, str]) -> list[Path]:
    """Return the install prefixes of the ament index: AMENT_PREFIX_PATH, then this interpreter's."""
    prefixes = [Path(p) for p in environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    if Path(sys.prefix) not in prefixes:
        prefixes.append(Path(sys.prefix))
    return prefixes


def share_directory(package: str, environ: Mapping[str, str] | None = None) -> Path | None:
    """Return the installed share directory of an ament package, or None when it is not installed."""
    for prefix in ament_prefixes(os.environ if environ is None else environ):
        marker = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / package
        if marker.is_file():
            return prefix / 'share' / package
    return None


def default_log_dir(environ: Mapping[str, str]) -> Path:
    """Return where ROS should write its logs: $ROS_HOME/log, ~/.ros/log, or a temp dir without HOME."""
    if environ.get('ROS_HOME'):
        return Path(environ['ROS_HOME']) / 'log'
    home = environ.get('HOME')
    if home and os.access(home, os.W_OK):
        return Path(home) / '.ros' / 'log'
    return Path(tempfile.gettempdir()) / f'skynav-ros-log-{os.getuid()}'


def ros_environment(environ: Mapping[str, str]) -> dict[str, str]:
    """Return the variables to add to `environ` so that rclpy works on this machine."""
    added: dict[str, str] = {}
    prefixes = ament_prefixes(environ)
    path = os.pathsep.join(str(p) for p in prefixes)
    if environ.get('AMENT_PREFIX_PATH', '') != path:
        added['AMENT_PREFIX_PATH'] = path
    # Discovery stays on this machine unless the user widens it (ROS_LOCALHOST_ONLY is deprecated).
    if 'ROS_AUTOMATIC_DISCOVERY_RANGE' not in environ:
        added['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    if 'ROS_LOG_DIR' not in environ:
        added['ROS_LOG_DIR'] = str(default_log_dir(environ))
    if 'RMW_IMPLEMENTATION' not in environ:
        added['RMW_IMPLEMENTATION'] = 'rmw_fastrtps_cpp'
    # Each node is one process on one core; multithreaded BLAS makes the small matrix products of the
    # per-frame work up to ten times slower on a two-core robot computer. Only effective before numpy loads.
    for variable in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS'):
        if variable not in environ:
            added[variable] = '1'
    if 'FASTRTPS_DEFAULT_PROFILES_FILE' not in environ:
        share = share_directory(PACKAGE, {**environ, **added})
        if share is not None and (share / FASTDDS_PROFILE).is_file():
            added['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(share / FASTDDS_PROFILE)
    return added


def apply_ros_environment(environ: MutableMapping[str, str] | None = None) -> dict[str, str]:
    """Set what ROS 2 needs in `environ` (default: os.environ), keep the user's values; return what was set."""
    target = os.environ if environ is None else environ
    added = ros_environment(target)
    target.update(added)
    if 'ROS_LOG_DIR' in added:
        Path(added['ROS_LOG_DIR']).mkdir(parents=True, exist_ok=True)
    return added
