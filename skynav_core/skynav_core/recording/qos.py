# SPDX-License-Identifier: Apache-2.0
"""Quality of service for replaying, recording and echoing topics.

A publisher that offers RELIABLE matches subscribers asking for either
reliability, and one that offers TRANSIENT_LOCAL matches either durability, so
the replayer offers the stronger policies; a subscriber must not ask for more
than every publisher offers, so the recorder and echo ask for the weakest
policy any publisher of the topic offers.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import Enum
from typing import TypeVar

from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.topic_endpoint_info import TopicEndpointInfo
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)

# How rosbag2 writes an infinite duration (RMW_DURATION_INFINITE) into bag metadata.
INFINITE = QosTime(2147483647, 4294967295)

PolicyT = TypeVar('PolicyT', bound=Enum)  # a rosbags QoS policy enum


def replay_qos(offered: Sequence[Qos], depth: int) -> QoSProfile:
    """Return the profile to republish a recorded topic with, given what its publishers offered."""
    latched = bool(offered) and all(q.durability == QosDurability.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=max([depth] + [q.depth for q in offered if latched]),
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def subscription_qos(publishers: Sequence[TopicEndpointInfo], depth: int) -> QoSProfile:
    """Return a profile that matches every publisher of a topic: reliable, latched only when all are.

    With no publisher known yet the profile is best effort, which matches any publisher.
    """
    profiles = [p.qos_profile for p in publishers]
    reliable = bool(profiles) and all(p.reliability == ReliabilityPolicy.RELIABLE for p in profiles)
    latched = bool(profiles) and all(p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in profiles)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def _bag_time(duration: Duration) -> QosTime:
    """Return an rclpy duration as bag metadata time; 0 and infinity as rosbag2 writes them."""
    nanoseconds = duration.nanoseconds
    if nanoseconds < 0 or nanoseconds >= INFINITE.sec * 10**9:
        return INFINITE
    return QosTime(*divmod(nanoseconds, 10**9))


def bag_qos(profile: QoSProfile) -> Qos:
    """Return an rclpy QoS profile as the offered-QoS entry of bag metadata."""

    def convert(enum: type[PolicyT], policy: object) -> PolicyT:
        return enum.__members__.get(getattr(policy, 'name', ''), enum['UNKNOWN'])

    return Qos(
        history=convert(QosHistory, profile.history),
        depth=profile.depth,
        reliability=convert(QosReliability, profile.reliability),
        durability=convert(QosDurability, profile.durability),
        deadline=_bag_time(profile.deadline),
        lifespan=_bag_time(profile.lifespan),
        liveliness=convert(QosLiveliness, profile.liveliness),
        liveliness_lease_duration=_bag_time(profile.liveliness_lease_duration),
        avoid_ros_namespace_conventions=profile.avoid_ros_namespace_conventions,
    )
