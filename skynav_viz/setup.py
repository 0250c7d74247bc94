# SPDX-License-Identifier: Apache-2.0
"""ament_python needs a setup.py; the package metadata is declarative, in setup.cfg."""

from setuptools import setup

setup()
