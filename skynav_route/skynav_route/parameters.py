# SPDX-License-Identifier: Apache-2.0
"""The route node's parameters: names, defaults and meaning (skynav_core.parameters), and what they set."""

from __future__ import annotations

import math
from dataclasses import fields

from skynav_core.parameters import Parameter

from .controller import Limits, Settings
from .inputs import TILT_HOLD

_LIMITS, _SETTINGS = Limits(), Settings()

PARAMETERS = {
    'map': Parameter('', 'SQLite map file of the route (`skynav map build`, `skynav teach`); a goal may name another'),
    'max_speed': Parameter(_LIMITS.max_speed, 'forward speed limit (m/s); a goal may ask for less or more'),
    'max_acceleration': Parameter(_LIMITS.max_acceleration, 'limit of the change of forward speed (m/s^2)'),
    'max_turn_rate': Parameter(_LIMITS.max_turn_rate, 'turn-rate limit (rad/s)'),
    'max_turn_acceleration': Parameter(_LIMITS.max_turn_acceleration, 'limit of the change of turn rate (rad/s^2)'),
    'heading_gain': Parameter(_SETTINGS.heading_gain, 'turn rate per heading error (rad/s per rad)'),
    'approach': Parameter(
        _SETTINGS.approach, 'route following: turn towards the route by atan(cross-track offset / approach) (m)'
    ),
    'bearing_noise': Parameter(
        _SETTINGS.bearing_noise, "route following: standard deviation (rad) of a fully confident home vector's bearing"
    ),
    'match_noise': Parameter(
        _SETTINGS.match_noise,
        "route following: standard deviation (m) of an accepted place match's position along the route",
    ),
    'odometry_drift': Parameter(
        _SETTINGS.odometry_drift,
        "route following: growth of the position's standard deviation per square-root metre driven (m); raise it "
        'where the compass is degrees off',
    ),
    'odometry_noise': Parameter(
        _SETTINGS.odometry_noise, 'route following: standard deviation of the distance driven, as a share of it'
    ),
    'homing_gain': Parameter(
        _SETTINGS.homing_gain,
        "route following on a map without the teach's odometry: weight of a fully confident home vector against the "
        "route's direction",
    ),
    'route_lead': Parameter(
        _SETTINGS.route_lead,
        "route following: the route's curvature over this many snapshots from the match on is fed forward (turn rate)",
    ),
    'lookahead': Parameter(6, 'route following: how many snapshots beyond the matched one the warping node homes to'),
    'unsure_residual': Parameter(
        _SETTINGS.unsure_residual, 'home vectors with a larger residual are unsure (homing: several in a row = arrived)'
    ),
    'arrived_frames': Parameter(_SETTINGS.arrived_frames, 'homing: consecutive unsure home vectors that mean arrived'),
    'arrive_creep': Parameter(
        _SETTINGS.arrive_creep,
        'homing: m the robot keeps its course straight on through unsure home vectors before it stops (arrived)',
    ),
    'lost_frames': Parameter(
        _SETTINGS.lost_frames, 'consecutive unaccepted or unsure frames (after trying to recover) that end a goal LOST'
    ),
    'recover_speed': Parameter(
        _SETTINGS.recover_speed, 'share of the speed limit at which the robot creeps on while recovering'
    ),
    'recover_distance': Parameter(
        _SETTINGS.recover_distance, 'm of odometry driven while recovering that end a goal LOST'
    ),
    'input_timeout': Parameter(
        1.0, 'inputs older than this (s) stop the robot and abort the goal with STALE_INPUT (the watchdog)'
    ),
    'frame_wait': Parameter(
        0.5, 'a frame that gets no home vector is answered without one when a view this much newer (s) arrives'
    ),
    'goal_timeout': Parameter(
        120.0,
        "the fixed part of a goal's time limit (s: localizing, setting the graph up, starting and stopping); a goal "
        'running longer than its limit stops and aborts with TIMEOUT',
    ),
    'goal_time_factor': Parameter(
        3.0,
        "a goal's time limit adds this many times the time its distance takes at the goal's speed limit (follow: the "
        "route's length from start to end by the map; home: home_distance), so long routes are not cut short",
    ),
    'home_distance': Parameter(
        10.0,
        'Home goals: the farthest the robot is expected to drive to the snapshot (m), for their time limit; homing '
        'works within a few metres of it',
    ),
    'configure_peers': Parameter(
        True,
        "give the localize, compass and warping nodes each goal's context (snapshot choice, tracking, map) through "
        'their parameters (skynav_route.context)',
    ),
    'peer_timeout': Parameter(
        5.0,
        "how long the localize, compass and warping nodes get to take a goal's context (s of steady, wall time)",
    ),
    'max_tilt_deg': Parameter(
        35.0,
        'the optional /camera/imu (sensor_msgs/Imu): base_link leaning more than this (deg) from the vertical for '
        f"{TILT_HOLD} s stops the robot like the emergency stop (EMERGENCY_STOP); by the IMU's orientation, else its "
        "acceleration's direction, turned into base_link by /tf_static (an IMU frame it does not link counts as "
        'base_link); 0: off',
    ),
    'cmd_vel_stamped': Parameter(
        True,
        'publish /cmd_vel as geometry_msgs/TwistStamped (true) or as a bare geometry_msgs/Twist for bases that take '
        'that (false); read at start-up',
    ),
}


def check(values: dict) -> None:
    """Raise ValueError if the parameter values cannot drive a robot."""
    numbers = [v for v in values.values() if isinstance(v, float)]
    if not all(math.isfinite(v) and v >= 0 for v in numbers):
        raise ValueError('every limit, gain and timeout must be finite and not negative')
    if values['max_tilt_deg'] > 180:
        raise ValueError('max_tilt_deg is an angle from the vertical: at most 180 (0: off)')
    if values['max_speed'] <= 0 or values['max_turn_rate'] <= 0 or values['input_timeout'] <= 0:
        raise ValueError('max_speed, max_turn_rate and input_timeout must be more than 0')
    if values['lost_frames'] < 1 or values['arrived_frames'] < 1 or values['lookahead'] < 0:
        raise ValueError('lost_frames and arrived_frames must be at least 1, lookahead not negative')
    if min(values['approach'], values['bearing_noise'], values['match_noise']) <= 0 or values['route_lead'] < 0:
        raise ValueError('approach, bearing_noise and match_noise must be more than 0, route_lead not negative')


def settings(values: dict) -> Settings:
    """Return the controller's settings from the parameter values (the settings no parameter names keep defaults)."""
    return Settings(**{f.name: values[f.name] for f in fields(Settings) if f.name in values})


def limits(values: dict, max_speed: float) -> Limits:
    """Return the limits of a goal asking for `max_speed` (m/s; <= 0: the parameter's)."""
    speed = max_speed if max_speed > 0 else values['max_speed']
    return Limits(speed, values['max_acceleration'], values['max_turn_rate'], values['max_turn_acceleration'])
