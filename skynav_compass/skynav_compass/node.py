# SPDX-License-Identifier: Apache-2.0
"""The compass node: how is the camera turned, in all three axes, against a snapshot?

Subscribes /skyline/sh and /localization/match; publishes /compass/orientation
(skynav_msgs/CompassEstimate) for every view: R with d_snapshot = R d_current, the snapshot's map
index (-1 for a live reference), and as residual the masked cost at the optimum (mean squared mask
difference over the part of the sphere both views see). No estimate tilts the two views further apart
than `max_tilt_deg` (a ground robot never turns its camera over).

The reference (`reference` parameter): the snapshot of the latest accepted place match ('match'),
a fixed snapshot ('index'), both chosen as the warping node chooses its target (skynav_core.snapshots), or
a live view stored by calling the ~/store_reference service ('live').
A view or snapshot without a skyline (all sky or all ground in its field of view) fits every rotation
alike: it gets no estimate, and is counted ('featureless', 'featureless_snapshot') instead.

Rejected views are counted in /diagnostics by reason (docs/cli.md, 'What the nodes report'): a message the
compass cannot use ('malformed', 'non_finite', 'degree', 'fill': skynav_core.sh_input), 'out_of_order', no snapshot
to compare against ('no_map', 'no_match', 'match_beyond_map': skynav_core.snapshots; 'no_reference': no live view
stored yet), 'featureless' and 'featureless_snapshot'.
"""

from __future__ import annotations

import numpy as np
from std_srvs.srv import Trigger

from skynav_compass.errors import CompassError
from skynav_core.images import stamp_ns
from skynav_core.names import COMPASS_NODE, COMPASS_ORIENTATION, LOCALIZATION_MATCH, SKYLINE_SH
from skynav_core.node import SkynavNode
from skynav_core.ros import run_node
from skynav_core.sh_input import usable_coefficients
from skynav_core.snapshots import SnapshotChoice
from skynav_msgs.msg import CompassEstimate, PlaceMatch, ShCoefficients
from skynav_sh.product import seen_mean, shows_skyline

from .compass import Compass, CompassConfig
from .cost import PreparedSnapshot
from .parameters import PARAMETERS, REFERENCES
from .views import FILL_MODES, CompassView


class CompassNode(SkynavNode):
    """Estimates the rotation of every view against its reference."""

    PARAMETERS = PARAMETERS
    INPUT_TOPICS = (SKYLINE_SH, LOCALIZATION_MATCH)

    needs_map = True

    def __init__(self, **kwargs) -> None:
        super().__init__(COMPASS_NODE, **kwargs)
        self.declare_table(PARAMETERS)
        self.snapshots = SnapshotChoice(self.reject, self.snapshot_view)
        self.latest: CompassView | None = None
        self.live: CompassView | None = None
        self.input(SKYLINE_SH, ShCoefficients, self.on_coefficients)
        self.input(LOCALIZATION_MATCH, PlaceMatch, self.snapshots.on_match)
        self.output(COMPASS_ORIENTATION, CompassEstimate)
        if self.router is None:
            self.create_service(Trigger, '~/store_reference', self.store_reference)
        self.start()

    def configure(self, values: dict) -> None:
        """Open the map and set the compass up (ValueError if unusable)."""
        if values['reference'] not in REFERENCES:
            raise CompassError(f'reference must be one of {", ".join(REFERENCES)}')
        if values['index'] < 0 or not 2 <= values['max_degree'] <= 64:
            raise CompassError('index must not be negative; max_degree must be within 2..64')
        if not 0 < values['max_tilt_deg'] <= 180:
            raise CompassError('max_tilt_deg must be more than 0 and at most 180 degrees')
        self.snapshots.configure(values['map'], values['reference'], values['index'])
        self.values = values
        self.compass = Compass(values['max_degree'], CompassConfig(max_tilt=np.radians(values['max_tilt_deg'])))

    def reset_time(self) -> None:
        """Forget the last stamp and the latest place match."""
        super().reset_time()
        self.snapshots.forget_match()

    def store_reference(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Service: keep the latest view as the live reference."""
        response.success = self.latest is not None
        response.message = (
            'stored the latest view as the live reference' if self.latest is not None else 'no view received yet'
        )
        if self.latest is not None:
            self.live = self.latest
        return response

    def snapshot_view(self, coefficients: np.ndarray, field_of_view: float) -> tuple[PreparedSnapshot, float]:
        """Return a map snapshot prepared once for every estimate, and the share of sky in what it sees."""
        view = CompassView.from_sh_message(coefficients, field_of_view, 'zero', self.values['max_degree'])
        return self.compass.prepare(view), sky_share(view)

    def reference_view(self, field_of_view: float) -> tuple[int, CompassView | PreparedSnapshot, float] | None:
        """Return (index, view, sky share) of the reference, None when there is none yet (the reason is counted)."""
        if self.values['reference'] == 'live':
            if self.live is None:
                self.reject('no_reference', 'no live reference yet (call ~/store_reference)')
                return None
            return -1, self.live, sky_share(self.live)
        index = self.snapshots.choose()
        return None if index is None else (index, *self.snapshots.view(index, field_of_view))

    def on_coefficients(self, message: ShCoefficients) -> None:
        """Estimate the rotation of one view against its reference and publish it."""
        stamp = stamp_ns(message.header)
        degree = self.values['max_degree']
        coefficients = usable_coefficients(message, self.reject, degree, FILL_MODES)
        if coefficients is None:
            return
        if not self.in_order(stamp, self.last_stamp):
            return
        self.last_stamp = stamp
        current = CompassView.from_sh_message(coefficients, float(message.field_of_view), message.fill, degree)
        share = sky_share(current)
        if not shows_skyline(share):
            self.reject(
                'featureless',
                f'view stamped {stamp} shows no skyline (sky on {100 * share:.0f} % of '
                'what it sees): every rotation fits it alike',
            )
            return
        self.latest = current
        reference = self.reference_view(float(message.field_of_view))
        if reference is None:
            return
        index, snapshot, share = reference
        if not shows_skyline(share):
            self.reject(
                'featureless_snapshot',
                f'snapshot {index} shows no skyline (sky on {100 * share:.0f} % '
                'of what it sees): every rotation fits it alike',
            )
            return
        with self.processing(stamp):
            estimate = self.compass.estimate(snapshot, current)
            result = CompassEstimate(
                snapshot_index=index,
                residual=float(estimate.residual),
                confidence=float(estimate.confidence),
                confident=bool(estimate.confident),
            )
            result.header = message.header
            (result.rotation.x, result.rotation.y, result.rotation.z, result.rotation.w) = (
                float(v) for v in estimate.quaternion
            )
        self.emit(COMPASS_ORIENTATION, result)


def sky_share(view: CompassView) -> float:
    """Return the share of sky in what a view sees (0..1)."""
    return float(seen_mean(view.weighted, view.visibility))


def main(args=None) -> int:
    """Run the compass node until Ctrl-C."""
    return run_node(CompassNode, args)
