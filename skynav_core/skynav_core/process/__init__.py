# SPDX-License-Identifier: Apache-2.0
"""Processes and networks: the environment ROS needs here, discovery across hosts, network namespaces, the launcher."""
