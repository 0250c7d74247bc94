# SPDX-License-Identifier: Apache-2.0
"""The localize node: where on the taught route is the current view?

Subscribes /skyline/sh; publishes /localization/match (skynav_msgs/PlaceMatch) for every view: the
best snapshot of the map given by the `map` parameter, its descriptor distance, whether it passed
the acceptance test, and the runners-up. Setting `map` at run time switches maps; a map that cannot
be opened is refused (the old one stays). Without a usable map every match is index -1, distance +inf.
A view without a skyline (all sky or all ground in its field of view) is matched but never accepted,
nor is a match on a snapshot without one. Where the route looks alike, a sequence's match is accepted
only if it moves along the route with the robot (matching, the module notes). With `tracking` (set by the route
node while it follows the route) each view is sought near the last accepted match, or from the first view near
`tracking_start` (the snapshot the FollowRoute goal starts at).

The node also serves the Teach action /skynav/teach (teach_server), in a live graph and in an in-process one
(the simulator's) alike: while a goal runs, the views it takes (with /odom, and the /cmd_vel commands the robot is
driven with) become snapshots of a new map, which it and the nodes of `teach_map_nodes` use as soon as the goal ends.

Rejected views are counted in /diagnostics by reason (README, 'Nodes'): a message the node cannot use
('malformed', 'non_finite', 'degree': below the descriptors' degree, checked with a map;
skynav_core.sh_input) and 'out_of_order'.
"""

from __future__ import annotations

import dataclasses
import math

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry

from skynav_core.images import stamp_ns
from skynav_core.maps import MapError, MapStore, map_for_parameter
from skynav_core.names import CMD_VEL, LOCALIZATION_MATCH, LOCALIZE_NODE, ODOM, SKYLINE_SH
from skynav_core.node import SkynavNode
from skynav_core.ros import run_node
from skynav_core.sh_input import usable_coefficients
from skynav_msgs.msg import PlaceMatch, ShCoefficients

from .localizer import METHODS, OUR_METHODS, Localizer
from .matching import SequenceParams
from .parameters import PARAMETERS
from .teach_server import COMMAND_QOS, ODOM_QOS, TeachServer, odometry_pose
from .teaching import OdometryTrack

SEQUENCE_GAP_NS = 2_000_000_000  # views further apart than this do not form a sequence: history is forgotten


class LocalizeNode(SkynavNode):
    """Matches every view's SH coefficients against the snapshots of a map."""

    PARAMETERS = PARAMETERS
    INPUT_TOPICS = (SKYLINE_SH, ODOM, CMD_VEL)

    needs_map = True

    def __init__(self, **kwargs) -> None:
        super().__init__(LOCALIZE_NODE, **kwargs)
        self.declare_table(PARAMETERS)
        self.store: MapStore | None = None
        self.localizer: Localizer | None = None
        self.input(SKYLINE_SH, ShCoefficients, self.on_coefficients)
        self.output(LOCALIZATION_MATCH, PlaceMatch)
        self.teach = TeachServer(self)
        self.odometry = OdometryTrack()  # the drive's path length, for tracking's window
        self.input(ODOM, Odometry, self.on_odometry, ODOM_QOS)
        if self.get_parameter('cmd_vel_stamped').value:  # the type of /cmd_vel is fixed for the node's life
            self.input(CMD_VEL, TwistStamped, self.teach.on_command, COMMAND_QOS)
        else:
            self.input(CMD_VEL, Twist, self.teach.on_twist, COMMAND_QOS)
        self.start()

    def configure(self, values: dict) -> None:
        """Open the map and prepare the method (ValueError, with the map's problem, if unusable)."""
        if values['method'] not in OUR_METHODS:
            raise ValueError(f'method must be one of {", ".join(OUR_METHODS)}')
        if not 0 < values['min_speed'] <= values['max_speed']:
            raise ValueError('need 0 < min_speed <= max_speed')
        if not 1 <= values['max_degree'] <= 64:
            raise ValueError('max_degree must be within 1..64')
        if values['sequence_length'] < 1 or values['candidates'] < 1:
            raise ValueError('sequence_length and candidates must be at least 1')
        if values['max_self_similarity'] < 0:  # NaN (the method's) passes
            raise ValueError("max_self_similarity must be at least 0 (NaN: the method's)")
        self.teach.configure(values)
        self.odometry_tolerance_ns = int(values['odometry_tolerance'] * 1e9)
        store = map_for_parameter(self.store, values['map'])
        if store is None:
            self.store, self.localizer = None, None
            return
        method_acceptance = METHODS[values['method']].acceptance
        ratio = method_acceptance.max_score if math.isnan(values['max_ratio']) else values['max_ratio']
        view = method_acceptance.max_view_score if math.isnan(values['max_view_ratio']) else values['max_view_ratio']
        alike = (
            method_acceptance.max_self_similarity
            if math.isnan(values['max_self_similarity'])
            else values['max_self_similarity']
        )
        acceptance = dataclasses.replace(
            method_acceptance,
            max_score=ratio,
            max_distance=values['max_distance'],
            max_view_score=view,
            max_self_similarity=alike,
        )
        sequence = SequenceParams(values['sequence_length'], values['min_speed'], values['max_speed'])
        try:
            localizer = Localizer(
                store,
                values['method'],
                acceptance=acceptance,
                sequence=sequence,
                candidates=values['candidates'],
                degree=values['max_degree'],
            )
        except MapError as exc:  # a descriptor of the map damaged: refused like a map that cannot be opened
            if store is not self.store:
                store.close()
            raise ValueError(str(exc)) from None
        localizer.tracking = bool(values['tracking'])
        if not -1 <= values['tracking_start'] < len(store):
            raise ValueError(f'tracking_start must be -1 or a snapshot of the map (0..{len(store) - 1})')
        if localizer.tracking and values['tracking_start'] >= 0:
            localizer.track_from(values['tracking_start'])
        self.localizer = localizer
        if self.store is not None and self.store is not store:
            self.store.close()
        self.store = store
        self.get_logger().info(
            f'map {store.name!r}: {len(store)} snapshots, degree {store.max_degree}, method {values["method"]}'
            + (', tracking the route' if localizer.tracking else '')
        )

    def on_odometry(self, message: Odometry) -> None:
        """Take one odometry sample (for tracking, and for the goal being taught)."""
        self.odometry.add(stamp_ns(message.header), odometry_pose(message))
        self.teach.on_odometry(message)

    def reset_time(self) -> None:
        """Forget the last stamp, the sequence of views so far and the odometry."""
        super().reset_time()
        self.odometry = OdometryTrack()
        if self.localizer is not None:
            self.localizer.reset()

    def on_coefficients(self, message: ShCoefficients) -> None:
        """Match one view and publish the result."""
        stamp = stamp_ns(message.header)
        degree = self.localizer.degree if self.localizer is not None else 0
        coefficients = usable_coefficients(message, self.reject, degree)
        if coefficients is None:
            return
        if not self.in_order(stamp, self.last_stamp):
            return
        if self.localizer is not None and self.last_stamp >= 0 and stamp - self.last_stamp > SEQUENCE_GAP_NS:
            self.localizer.reset()
        self.last_stamp = stamp
        with self.processing(stamp):
            result = PlaceMatch()
            result.header = message.header
            result.index, result.distance, result.accepted = -1, math.inf, False
            if self.localizer is not None:
                assert self.store is not None  # a localizer is built from the store
                odometry = self.odometry.at(stamp, self.odometry_tolerance_ns)
                match = self.localizer.query(
                    coefficients=coefficients[: (self.localizer.degree + 1) ** 2],
                    field_of_view=float(message.field_of_view),
                    fill=message.fill,
                    travelled=None if odometry is None else odometry[1],
                )
                result.map_name = self.store.name
                result.index, result.distance, result.accepted = (
                    int(match.index),
                    float(match.distance),
                    bool(match.accepted),
                )
                if match.index >= 0:
                    sec, nanosec = divmod(self.store.snapshot_stamp(match.index), 1_000_000_000)
                    result.snapshot_stamp.sec, result.snapshot_stamp.nanosec = sec, nanosec
                result.candidate_indices = [int(i) for i in match.candidate_indices]
                result.candidate_distances = [float(d) for d in match.candidate_distances]
        self.emit(LOCALIZATION_MATCH, result)
        self.teach.on_view(stamp, coefficients)

    def destroy_node(self) -> None:
        """Close a map being taught, then the node."""
        self.teach.close()
        super().destroy_node()


def main(args=None) -> int:
    """Run the localize node until Ctrl-C."""
    return run_node(LocalizeNode, args)
