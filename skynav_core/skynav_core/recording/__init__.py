# SPDX-License-Identifier: Apache-2.0
"""Recordings: reading, writing and checking MCAP and rosbag2 files, and playing and recording them over DDS."""
