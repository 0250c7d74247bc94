"""The compass node: how is the camera turned, in all three axes, against a snapshot?

Subscribes /skyline/sh and /localization/match; publishes /compass/orientation
(skynav_msgs/CompassEstimate) for every view: R with d_snapshot = R d_current, the snapshot's map
index (-1 for a live reference), and as residual the masked cost at the optimum (mean squared mask
difference over the part of the sphere both views see). No estimate tilts the two views further apart
than `max_tilt_deg` (a ground robot never turns its camera over).

The reference (`reference` parameter): the snapshot of the latest accepted place match ('match'),
a fixed snapshot ('index'), or a live view stored by calling the ~/store_reference service ('live').
A view or snapshot without a skyline (all sky or all ground in its field of view) fits every rotation
alike: it gets no estimate, and is counted ('featureless', 'featureless_snapshot') instead.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from skynav_msgs.msg import CompassEstimate, PlaceMatch, ShCoefficients
from std_srvs.srv import Trigger

from skynav_core.images import stamp_ns
from skynav_core.node import SkynavNode
from skynav_core.ros import run_node
from skynav_sh.product import seen_mean, shows_skyline

from .compass import MAX_TILT, Compass, CompassConfig
from .cost import PreparedSnapshot
from .views import CompassView
from .parameters import PARAMETERS, REFERENCES

SH_TOPIC = '/skyline/sh'
MATCH_TOPIC = '/localization/match'
COMPASS_TOPIC = '/compass/orientation'
SNAPSHOT_VIEWS_CACHED = 64


class CompassNode(SkynavNode):
    """Estimates the rotation of every view against its reference."""

    PARAMETERS = PARAMETERS

    needs_map = True

    def __init__(self, **kwargs) -> None:
        super().__init__('compass', **kwargs)
        self.declare_table(PARAMETERS)
        self.store = None
        self.match: PlaceMatch | None = None
        self.latest: CompassView | None = None
        self.live: CompassView | None = None
        self.last_stamp = -1
        self.input(SH_TOPIC, ShCoefficients, self.on_coefficients)
        self.input(MATCH_TOPIC, PlaceMatch, self.on_match)
        self.output(COMPASS_TOPIC, CompassEstimate)
        if self.router is None:
            self.create_service(Trigger, '~/store_reference', self.store_reference)
        self.start()

    def configure(self, values: dict) -> None:
        """Open the map and set the compass up (ValueError if unusable)."""
        from skynav_core.maps import map_for_parameter

        if values['reference'] not in REFERENCES:
            raise ValueError(f'reference must be one of {", ".join(REFERENCES)}')
        if values['index'] < 0 or not 2 <= values['max_degree'] <= 64:
            raise ValueError('index must not be negative; max_degree must be within 2..64')
        if not 0 < values['max_tilt_deg'] <= 180:
            raise ValueError('max_tilt_deg must be more than 0 and at most 180 degrees')
        store = map_for_parameter(self.store, values['map'])
        self.values = values
        self.compass = Compass(values['max_degree'], CompassConfig(max_tilt=np.radians(values['max_tilt_deg'])))
        self.store = store
        # the views of map snapshots, built once per map and setting (least recently used dropped first)
        self.snapshot_view = lru_cache(SNAPSHOT_VIEWS_CACHED)(self.build_snapshot_view)

    def store_reference(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Service: keep the latest view as the live reference."""
        response.success = self.latest is not None
        response.message = 'stored the latest view as the live reference' if self.latest is not None \
            else 'no view received yet'
        if self.latest is not None:
            self.live = self.latest
        return response

    def on_match(self, match: PlaceMatch) -> None:
        """Remember the latest accepted place match."""
        if match.accepted and match.index >= 0:
            self.match = match

    def build_snapshot_view(self, index: int, field_of_view: float) -> tuple[PreparedSnapshot, float]:
        """Return one map snapshot prepared once for every estimate, and the share of sky in what it sees."""
        view = CompassView.from_sh_message(self.store.snapshot(index).coefficients, field_of_view, 'zero',
                                           self.values['max_degree'])
        return self.compass.prepare(view), sky_share(view)

    def reference_view(self, field_of_view: float) -> tuple[int, CompassView | PreparedSnapshot, float] | None:
        """Return (index, view, sky share) of the reference, None when there is none yet (the reason is counted)."""
        reference = self.values['reference']
        if reference == 'live':
            if self.live is None:
                self.reject('no_reference', 'no live reference yet (call ~/store_reference)')
                return None
            return -1, self.live, sky_share(self.live)
        if self.store is None or len(self.store) == 0:
            self.reject('no_map', 'no map with snapshots to compare against (set the map parameter)')
            return None
        if len(self.store) == 1:
            index = 0
        elif reference == 'index':
            index = min(self.values['index'], len(self.store) - 1)
        elif self.match is None:
            self.reject('no_reference', 'no accepted place match yet to choose the snapshot')
            return None
        elif self.match.index >= len(self.store):
            self.reject('match_beyond_map', f'the place match names snapshot {self.match.index} of map '
                                            f'{self.match.map_name!r}; this node has {len(self.store)} snapshots '
                                            f'of {self.store.name!r}')
            return None
        else:
            index = int(self.match.index)
        return (index, *self.snapshot_view(index, field_of_view))

    def on_coefficients(self, message: ShCoefficients) -> None:
        """Estimate the rotation of one view against its reference and publish it."""
        stamp = stamp_ns(message.header)
        degree = self.values['max_degree']
        coefficients = np.asarray(message.coefficients, np.float64)
        if coefficients.size != (message.max_degree + 1) ** 2 or message.max_degree < degree:
            self.reject('degree', f'coefficients of degree {message.max_degree} ({coefficients.size} values); '
                                  f'the compass needs degree {degree}')
            return
        if not np.all(np.isfinite(coefficients)):
            self.reject('non_finite', f'view stamped {stamp} has NaN or infinite coefficients')
            return
        if stamp <= self.last_stamp:
            self.reject('out_of_order', f'view stamped {stamp} is not newer than the last one')
            return
        self.last_stamp = stamp
        try:
            current = CompassView.from_sh_message(coefficients, float(message.field_of_view), message.fill, degree)
        except ValueError as exc:
            self.reject('fill', f'view stamped {stamp}: {exc}')
            return
        share = sky_share(current)
        if not shows_skyline(share):
            self.reject('featureless', f'view stamped {stamp} shows no skyline (sky on {100 * share:.0f} % of '
                                       'what it sees): every rotation fits it alike')
            return
        self.latest = current
        reference = self.reference_view(float(message.field_of_view))
        if reference is None:
            return
        index, snapshot, share = reference
        if not shows_skyline(share):
            self.reject('featureless_snapshot', f'snapshot {index} shows no skyline (sky on {100 * share:.0f} % '
                                                'of what it sees): every rotation fits it alike')
            return
        with self.processing(stamp):
            estimate = self.compass.estimate(snapshot, current)
            result = CompassEstimate(snapshot_index=index, residual=float(estimate.residual))
            result.header = message.header
            (result.rotation.x, result.rotation.y, result.rotation.z,
             result.rotation.w) = (float(v) for v in estimate.quaternion)
        self.emit(COMPASS_TOPIC, result)


def sky_share(view: CompassView) -> float:
    """Return the share of sky in what a view sees (0..1)."""
    return float(seen_mean(view.weighted, view.visibility))


def main(args=None) -> int:
    """Run the compass node until Ctrl-C."""
    return run_node(CompassNode, args)
