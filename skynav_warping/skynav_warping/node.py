# SPDX-License-Identifier: Apache-2.0
"""The warping node: which way is the snapshot's place from here?

Subscribes /skyline/sh (fill 'zero': the masked comparison needs the seen part alone),
/localization/match and, with `use_compass`, /compass/orientation; publishes /homing/home_vector
(skynav_msgs/HomeVector) for every view whose home direction the views determine: the unit direction
towards the target snapshot's place in the current camera_link, the rotation R (d_snapshot = R
d_current), and as residual the 3D-warping cost at the optimum relative to the best pure rotation's
(1 - confidence): near 0 the views agree once moved, near 1 a step explains little more than a turn.

A view whose home direction the views do not determine gets no home vector (skynav_warping.warping3d:
not `confident`): where no step explains the views clearly better than a pure rotation (confidence
below `confidence_threshold`, 0.03: at the snapshot's place or too near it to tell, where parallax
vanishes; or 0 when the best cost falls below zero, the band limit's ringing), and where a step the
other way explains about as much as the best one (`opposite_share` at or above `max_opposite_share`,
0.5: the residual is flat over directions). It is logged (at most one
line a LOG_PERIOD) and counted in /diagnostics as `undetermined`; the route node takes a frame without
a home vector as unsure (homing: several in a row mean arrived).

The target snapshot: the one the latest accepted place match names (`target: match`), a fixed
index (`target: index`), or the match's successor `lookahead` snapshots along the route
(`target: next`, route following). With `use_compass` a view waits for the compass estimate of
the same stamp and the search starts from it (unless it tilts the views further apart than
`max_tilt_deg`, the bound of the whole rotation search) and is `confident`: a rotation the compass is not
sure of (an ambiguous yaw) is no start; the search then aligns the views itself, as without the compass, and
/diagnostics counts such views as `compass_not_confident`. A view or target snapshot without a skyline
(all sky or all ground in its field of view) gets no compass estimate and waits for none, and no home
vector either (nothing to home on: counted as `undetermined`).

Rejected views are counted in /diagnostics by reason (README, 'Nodes'): a message the search cannot use
('malformed', 'non_finite', 'degree', 'fill': skynav_core.sh_input), 'out_of_order', and no snapshot to
home to ('no_map', 'no_match', 'match_beyond_map': skynav_core.snapshots, which chooses the target as the
compass node chooses its reference).
"""

from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from skynav_core.images import stamp_ns
from skynav_core.names import COMPASS_ORIENTATION, HOME_VECTOR, LOCALIZATION_MATCH, SKYLINE_SH, WARPING_NODE
from skynav_core.node import SkynavNode
from skynav_core.pairing import StampPairer
from skynav_core.ros import run_node
from skynav_core.sh_input import usable_coefficients
from skynav_core.snapshots import SnapshotChoice
from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch, ShCoefficients
from skynav_sh.product import message_sky_share, shows_skyline
from skynav_warping.errors import WarpingError

from .homing import HomeEstimate, estimate_home_vector
from .parameters import PARAMETERS, TARGETS
from .views import view_from_coefficients
from .warping3d import WarpingSettings

WARPING_FILLS = ('zero',)  # the masked comparison needs the seen part alone
LOG_PERIOD = 10.0  # s: at most one log line this often about views whose home vector was refused


class WarpingNode(SkynavNode):
    """Estimates the home vector of every view towards the target snapshot."""

    PARAMETERS = PARAMETERS
    INPUT_TOPICS = (SKYLINE_SH, LOCALIZATION_MATCH, COMPASS_ORIENTATION)

    needs_map = True

    def __init__(self, **kwargs) -> None:
        super().__init__(WARPING_NODE, **kwargs)
        self.declare_table(PARAMETERS)
        self.snapshots = SnapshotChoice(self.reject, self.snapshot_view)
        self.compass_not_confident = 0  # views whose compass estimate was not confident: aligned without it
        self.undetermined = 0  # views whose home direction the views do not determine: no home vector published
        self.pairer = StampPairer(('sh', 'compass'), tolerance_ns=0, on_drop=self.drop_unpaired)
        self.input(SKYLINE_SH, ShCoefficients, self.on_coefficients)
        self.input(LOCALIZATION_MATCH, PlaceMatch, self.snapshots.on_match)
        self.input(COMPASS_ORIENTATION, CompassEstimate, self.on_compass)
        self.output(HOME_VECTOR, HomeVector)
        self.start()

    def configure(self, values: dict) -> None:
        """Open the map and set the search up (ValueError if unusable)."""
        if values['target'] not in TARGETS:
            raise WarpingError(f'target must be one of {", ".join(TARGETS)}')
        if values['lookahead'] < 0 or values['index'] < 0 or not 4 <= values['max_degree'] <= 32:
            raise WarpingError('lookahead and index must not be negative; max_degree must be within 4..32')
        if not 0 < values['max_tilt_deg'] <= 180:
            raise WarpingError('max_tilt_deg must be more than 0 and at most 180 degrees')
        self.snapshots.configure(values['map'], values['target'], values['index'], values['lookahead'])
        self.values = values
        self.settings = WarpingSettings(
            degree=values['max_degree'], max_relative_tilt=float(np.radians(values['max_tilt_deg']))
        )

    def snapshot_view(self, coefficients: np.ndarray, field_of_view: float):
        """Return the view of a map snapshot as this node compares it."""
        return view_from_coefficients(coefficients, field_of_view, self.settings.degree)

    def drop_unpaired(self, count: int) -> None:
        """Count views whose compass estimate never came (or estimates whose view never came)."""
        self.drop('unpaired', count, 'a view whose compass estimate never came, or an estimate without its view')

    def reset_time(self) -> None:
        """Forget the last stamp, what waits for its partner and the latest place match."""
        super().reset_time()
        self.pairer.clear()
        self.snapshots.forget_match()

    def on_compass(self, estimate: CompassEstimate) -> None:
        """Pair a compass estimate with the view of the same stamp."""
        if self.values['use_compass']:
            self.pair('compass', estimate)

    def pair(self, channel: str, message: ShCoefficients | CompassEstimate) -> None:
        """Home once a view ('sh') and its compass estimate ('compass') of the same stamp have both come."""
        stamp = stamp_ns(message.header)
        self.stamp_jumped(stamp, self.last_stamp)
        pair = self.pairer.add(channel, stamp, message)
        if pair is not None:
            self.home(pair[1], pair[2])

    def on_coefficients(self, message: ShCoefficients) -> None:
        """Take a view: home at once, or when its compass estimate has come."""
        if usable_coefficients(message, self.reject, self.settings.degree, WARPING_FILLS) is None:
            return
        if not self.values['use_compass'] or not self.shows_skylines(message):
            self.home(message, None)  # the compass estimates no featureless view or snapshot: nothing to wait for
            return
        self.pair('sh', message)

    def shows_skylines(self, message: ShCoefficients) -> bool:
        """Return whether a view and, when it is known already, the snapshot it would home to both show a skyline."""
        fov = float(message.field_of_view)
        if not shows_skyline(message_sky_share(np.asarray(message.coefficients, np.float64), fov, message.fill)):
            return False
        index = self.snapshots.choose(count=False)
        if index is None:
            return True
        assert self.snapshots.store is not None  # choose() found the snapshot in it
        return bool(shows_skyline(message_sky_share(self.snapshots.store.coefficients()[index], fov)))

    def home(self, message: ShCoefficients, compass: CompassEstimate | None) -> None:
        """Publish the home vector of one view."""
        stamp = stamp_ns(message.header)
        if not self.in_order(stamp, self.last_stamp):
            return
        index = self.snapshots.choose()
        if index is None:
            return
        self.last_stamp = stamp
        with self.processing(stamp):
            current = view_from_coefficients(
                np.asarray(message.coefficients, np.float64), float(message.field_of_view), self.settings.degree
            )
            snapshot = self.snapshots.view(index, float(message.field_of_view))
            rotation = None
            if compass is not None and not compass.confident:  # a guess is no start: align the views ourselves
                self.compass_not_confident += 1
            elif compass is not None:  # against this snapshot or a neighbour: a good start either way
                q = compass.rotation
                rotation = np.array([q.x, q.y, q.z, q.w])
            estimate = estimate_home_vector(current, snapshot, rotation, self.settings)
            if not estimate.confident:
                self.refuse(stamp, index, estimate)
                return
            result = HomeVector(snapshot_index=index)
            result.header = message.header
            result.direction.x, result.direction.y, result.direction.z = (float(v) for v in estimate.direction)
            (result.rotation.x, result.rotation.y, result.rotation.z, result.rotation.w) = (
                float(v) for v in estimate.quaternion
            )
            result.residual = float(1.0 - estimate.confidence)
        self.emit(HOME_VECTOR, result)

    def refuse(self, stamp: int, index: int, estimate: HomeEstimate) -> None:
        """Count (and log, rate-limited) a view whose home direction the views do not determine: no home vector."""
        self.undetermined += 1
        threshold, bound = self.settings.confidence_threshold, self.settings.max_opposite_share
        why = (
            f'a step explains the views barely better than a turn (confidence {estimate.confidence:.3f} < '
            f'{threshold:g}: at the snapshot or too near it to tell, or a view without a skyline)'
            if estimate.confidence < threshold or estimate.distance_ratio == 0
            else f'a step the other way explains as much ({estimate.warp.opposite_share:.2f} of the best step, '
            f'over {bound:g})'
        )
        self.get_logger().info(
            f'no home vector to snapshot {index} for the view stamped {stamp}: {why}; counted in /diagnostics as '
            'undetermined',
            throttle_duration_sec=LOG_PERIOD,
        )

    def diagnostic_status(self) -> DiagnosticStatus:
        """Return the node's status with how many views were aligned without their non-confident compass estimate,
        and how many got no home vector because the views do not determine its direction."""
        status = super().diagnostic_status()
        status.values.append(KeyValue(key='compass_not_confident', value=str(self.compass_not_confident)))
        status.values.append(KeyValue(key='undetermined', value=str(self.undetermined)))
        return status


def main(args=None) -> int:
    """Run the warping node until Ctrl-C."""
    return run_node(WarpingNode, args)
