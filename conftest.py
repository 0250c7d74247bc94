"""Fixtures for every test of the repository.

Each test run gets a ROS domain of its own (so concurrent runs never cross) and
the environment ROS needs here; subprocesses inherit both.
"""

from __future__ import annotations

import os

import pytest

from skynav_bringup.environment import apply_ros_environment
from skynav_bringup.testing import claim_domain_id

_domain_lock = None


def pytest_configure(config: pytest.Config) -> None:
    global _domain_lock
    domain, _domain_lock = claim_domain_id()
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    apply_ros_environment()


def pytest_report_header(config: pytest.Config) -> str:
    return f'ROS_DOMAIN_ID={os.environ.get("ROS_DOMAIN_ID")}'


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
