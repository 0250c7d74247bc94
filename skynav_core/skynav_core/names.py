# SPDX-License-Identifier: Apache-2.0
"""The names of skynav's outside: topics, frames, actions and nodes (docs/interfaces.md), each written once.

Called `names` rather than `interfaces` because in ROS 2 "interfaces" are the message, service and action
*types* (skynav_msgs); this module holds only the strings the graph is wired by. Topic and action names are
absolute, as the contract writes them; a node in a namespace makes them relative (skynav_core.namespaces),
and `skynav record`/`view` map them back. Plain strings: importing this module loads nothing else.
test/test_names.py checks the topics and actions against the tables of docs/interfaces.md.
"""

from __future__ import annotations

# Input topics, from the robot or a recording (docs/interfaces.md, "Topics").
UV_IMAGE = '/camera/uv/image_raw'  # sensor_msgs/msg/Image: ultraviolet channel
GREEN_IMAGE = '/camera/green/image_raw'  # sensor_msgs/msg/Image: green channel, pixel-aligned with UV
UV_CAMERA_INFO = '/camera/uv/camera_info'  # sensor_msgs/msg/CameraInfo: geometry of both channels
IMU = '/camera/imu'  # sensor_msgs/msg/Imu: optional
ODOM = '/odom'  # nav_msgs/msg/Odometry: optional wheel odometry of base_link in odom
BUMPER = '/bumper'  # std_msgs/msg/Bool: optional contact (skynav's own addition)
EMERGENCY_STOP = '/emergency_stop'  # std_msgs/msg/Bool: optional, latches a stop
TF_STATIC = '/tf_static'  # tf2_msgs/msg/TFMessage: optional camera mount (base_link -> camera_link)
CLOCK = '/clock'  # rosgraph_msgs/msg/Clock: simulation time
GROUND_TRUTH_POSE = '/ground_truth/pose'  # geometry_msgs/msg/PoseStamped: recordings only, camera_link in map
GROUND_TRUTH_MASK = '/ground_truth/mask'  # sensor_msgs/msg/Image: recordings only, mono8 sky mask

# One colour camera instead of the UV/green pair (docs/interfaces.md, "Cameras as robots have them").
COLOUR_IMAGE = '/camera/image_raw'  # sensor_msgs/msg/Image: colour or Bayer
COLOUR_COMPRESSED = '/camera/image_raw/compressed'  # sensor_msgs/msg/CompressedImage: image_transport's compressed
COLOUR_CAMERA_INFO = '/camera/camera_info'  # sensor_msgs/msg/CameraInfo: geometry of the colour camera

# Output topics (docs/interfaces.md, "Topics").
SKYLINE_MASK = '/skyline/mask'  # sensor_msgs/msg/Image: mono8 sky mask, from skyline
SKYLINE_SH = '/skyline/sh'  # skynav_msgs/msg/ShCoefficients: the mask's SH coefficients, from sh
LOCALIZATION_MATCH = '/localization/match'  # skynav_msgs/msg/PlaceMatch: best snapshot of the map, from localize
COMPASS_ORIENTATION = '/compass/orientation'  # skynav_msgs/msg/CompassEstimate: rotation to a snapshot, from compass
HOME_VECTOR = '/homing/home_vector'  # skynav_msgs/msg/HomeVector: direction to a snapshot, from warping
DIAGNOSTICS = '/diagnostics'  # diagnostic_msgs/msg/DiagnosticArray: every node's rates and rejections
CMD_VEL = '/cmd_vel'  # geometry_msgs/msg/TwistStamped (or Twist): velocity commands, from route

# Visualization topics, from viz (docs/interfaces.md, "Visualization").
VIZ_MARKERS = '/skynav/viz/markers'  # visualization_msgs/msg/MarkerArray: route, snapshots, home vector
VIZ_OVERLAY = '/skynav/viz/overlay/compressed'  # sensor_msgs/msg/CompressedImage: the UV image with the skyline
VIZ_CONFIDENCE = '/skynav/viz/confidence'  # std_msgs/msg/Float64: 1 - the home vector's residual
VIZ_STATE = '/skynav/viz/state'  # std_msgs/msg/Int32: 0 no match, 1 not accepted, 2 accepted

#: The UV/green pair: the two images of one exposure, paired by stamp.
UV_GREEN_IMAGES = (UV_IMAGE, GREEN_IMAGE)
#: The ground truth a recording may hold: evaluation tools read it, no node subscribes to it.
GROUND_TRUTH = (GROUND_TRUTH_POSE, GROUND_TRUTH_MASK)

# Actions, served by the running graph (docs/interfaces.md, "Driving: teach, follow, home").
TEACH_ACTION = '/skynav/teach'  # skynav_msgs/action/Teach: served by localize
FOLLOW_ROUTE_ACTION = '/skynav/follow_route'  # skynav_msgs/action/FollowRoute: served by route
HOME_ACTION = '/skynav/home'  # skynav_msgs/action/Home: served by route

# Frames (docs/interfaces.md, "Frames and angles").
BASE_FRAME = 'base_link'  # the robot's body, REP-103; velocity commands are given in it
CAMERA_FRAME = 'camera_link'  # the view frame and optical frame of the fish-eye; every output's frame_id
MAP_FRAME = 'map'  # where recordings put ground truth
ODOM_FRAME = 'odom'  # wheel odometry's frame for base_link

# Node names in the graph: each package's `skynav.nodes` entry point (its setup.py) has the same name.
SKYLINE_NODE = 'skyline'
SH_NODE = 'sh'
LOCALIZE_NODE = 'localize'
COMPASS_NODE = 'compass'
WARPING_NODE = 'warping'
ROUTE_NODE = 'route'
VIZ_NODE = 'viz'
