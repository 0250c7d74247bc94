# SPDX-License-Identifier: Apache-2.0
"""Fixtures for every test of the repository.

Each test run gets a ROS domain of its own (so concurrent runs never cross) and
the environment ROS needs here; subprocesses inherit both.
"""

from __future__ import annotations

import importlib
import os

import pytest

from skynav_core.process.environment import apply_ros_environment
from skynav_testing import claim_domain_id

_domain_lock = None


# The Python packages, imported with this file (before pytest loads any package's test/conftest.py):
# pytest's importlib mode names a test module after its path (skynav_sh/test/test_x.py ->
# skynav_sh.test.test_x) and would otherwise register the repository folder skynav_sh/ as an empty
# namespace module that hides the real package.
PACKAGES = (
    'skynav_core',
    'skynav_bringup',
    'skynav_skyline',
    'skynav_sh',
    'skynav_localize',
    'skynav_compass',
    'skynav_warping',
    'skynav_sim',
    'skynav_route',
    'skynav_viz',
)
for _package in PACKAGES:
    importlib.import_module(_package)


def pytest_configure(config: pytest.Config) -> None:
    global _domain_lock
    domain, _domain_lock = claim_domain_id()
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    apply_ros_environment()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Run the heavy test files first, longest first: two workers taking whole files (`make test`) then end
    together, the many short files filling in last (with xdist's own order, fewest tests first, a lone
    several-minute test could start last and run on while the other worker idles)."""

    def weight(item: pytest.Item) -> float:
        marker = item.get_closest_marker('heavy')
        return -marker.args[0] if marker is not None else 0.0

    items.sort(key=weight)  # stable: a file's tests stay together and in their order


def pytest_report_header(config: pytest.Config) -> str:
    return f'ROS_DOMAIN_ID={os.environ.get("ROS_DOMAIN_ID")}'


@pytest.fixture
def own_ros_domain(monkeypatch):
    """A ROS domain id of the test's alone (for a test that lists every topic of its domain); ask for it before
    ros_context and anything else that starts ROS."""
    domain, lock = claim_domain_id()
    monkeypatch.setenv('ROS_DOMAIN_ID', str(domain))
    yield domain
    lock.close()


@pytest.fixture
def ros_context():
    """An initialised rclpy context of the test's own, shut down afterwards."""
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    yield context
    rclpy.try_shutdown(context=context)


@pytest.fixture(scope='session')
def stellarium():
    """The folder of the real Stellarium landscapes (fetched once); the test skips with one line without them."""
    from skynav_sim.landscape import LandscapeUnavailable, fetch

    try:
        return fetch()
    except LandscapeUnavailable as exc:
        pytest.skip(f'real landscapes (stellarium-data) unavailable: {exc}')
