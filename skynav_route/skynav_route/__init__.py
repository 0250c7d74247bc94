# SPDX-License-Identifier: Apache-2.0
"""The route controller: follows a taught route and homes to a snapshot by publishing velocity commands.

`controller` is the pure-numpy core (no ROS); `node` serves the FollowRoute and Home actions and publishes /cmd_vel
(docs/interfaces.md, "Driving: teach, follow, home").
"""
