"""The warping node: which way is the snapshot's place from here?

Subscribes /skyline/sh (fill 'zero': the masked comparison needs the seen part alone),
/localization/match and, with `use_compass`, /compass/orientation; publishes /homing/home_vector
(skynav_msgs/HomeVector) for every view: the unit direction towards the target snapshot's place in
the current camera_link, the rotation R (d_snapshot = R d_current), and as residual the 3D-warping
cost at the optimum relative to the best pure rotation's: near 0 the views agree once moved, near
1 they tell nothing about where home is (for instance, at home).

The target snapshot: the one the latest accepted place match names (`target: match`), a fixed
index (`target: index`), or the match's successor `lookahead` snapshots along the route
(`target: next`, route following). With `use_compass` a view waits for the compass estimate of
the same stamp and the search starts from it (unless it tilts the views further apart than
`max_tilt_deg`, the bound of the whole rotation search). A view or target snapshot without a skyline
(all sky or all ground in its field of view) gets no compass estimate and waits for none: its home
vector has residual 1 (nothing to home on; the direction is the search's best, as for any residual).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch, ShCoefficients

from skynav_core.images import stamp_ns
from skynav_core.node import SkynavNode
from skynav_core.pairing import StampPairer
from skynav_core.ros import run_node
from skynav_sh.product import message_sky_share, shows_skyline
from skynav_compass.compass import MAX_TILT

from .homing import estimate_home_vector
from .views import view_from_coefficients
from .warping3d import WarpingSettings
from .parameters import PARAMETERS, TARGETS

SH_TOPIC = '/skyline/sh'
MATCH_TOPIC = '/localization/match'
COMPASS_TOPIC = '/compass/orientation'
HOME_TOPIC = '/homing/home_vector'
SNAPSHOT_VIEWS_CACHED = 64


class WarpingNode(SkynavNode):
    """Estimates the home vector of every view towards the target snapshot."""

    PARAMETERS = PARAMETERS

    needs_map = True

    def __init__(self, **kwargs) -> None:
        super().__init__('warping', **kwargs)
        self.declare_table(PARAMETERS)
        self.store = None
        self.match: PlaceMatch | None = None
        self.pairer = StampPairer(('sh', 'compass'), tolerance_ns=0)
        self.last_stamp = -1
        self.input(SH_TOPIC, ShCoefficients, self.on_coefficients)
        self.input(MATCH_TOPIC, PlaceMatch, self.on_match)
        self.input(COMPASS_TOPIC, CompassEstimate, self.on_compass)
        self.output(HOME_TOPIC, HomeVector)
        self.start()

    def configure(self, values: dict) -> None:
        """Open the map and set the search up (ValueError if unusable)."""
        from skynav_core.maps import map_for_parameter

        if values['target'] not in TARGETS:
            raise ValueError(f'target must be one of {", ".join(TARGETS)}')
        if values['lookahead'] < 0 or values['index'] < 0 or not 4 <= values['max_degree'] <= 32:
            raise ValueError('lookahead and index must not be negative; max_degree must be within 4..32')
        if not 0 < values['max_tilt_deg'] <= 180:
            raise ValueError('max_tilt_deg must be more than 0 and at most 180 degrees')
        store = map_for_parameter(self.store, values['map'])
        self.values = values
        self.settings = WarpingSettings(degree=values['max_degree'],
                                        max_relative_tilt=float(np.radians(values['max_tilt_deg'])))
        self.store = store
        # the views of map snapshots, built once per map and setting (least recently used dropped first)
        self.snapshot_view = lru_cache(SNAPSHOT_VIEWS_CACHED)(self.build_snapshot_view)

    def build_snapshot_view(self, index: int, field_of_view: float):
        """Return the view of one map snapshot as this node compares it."""
        return view_from_coefficients(self.store.snapshot(index).coefficients, field_of_view, self.settings.degree)

    def on_match(self, match: PlaceMatch) -> None:
        """Remember the latest accepted place match."""
        if match.accepted and match.index >= 0:
            self.match = match

    def on_compass(self, estimate: CompassEstimate) -> None:
        """Pair a compass estimate with the view of the same stamp."""
        if self.values['use_compass']:
            pair = self.pairer.add('compass', stamp_ns(estimate.header), estimate)
            if pair is not None:
                self.home(pair[1], pair[2])

    def on_coefficients(self, message: ShCoefficients) -> None:
        """Take a view: home at once, or when its compass estimate has come."""
        if message.fill != 'zero':
            self.reject('fill', f"coefficients filled with {message.fill!r}; warping needs fill 'zero'")
            return
        if not self.values['use_compass'] or not self.shows_skylines(message):
            self.home(message, None)  # the compass estimates no featureless view or snapshot: nothing to wait for
            return
        pair = self.pairer.add('sh', stamp_ns(message.header), message)
        if pair is not None:
            self.home(pair[1], pair[2])

    def shows_skylines(self, message: ShCoefficients) -> bool:
        """Return whether a view and, when it is known already, the snapshot it would home to both show a skyline."""
        fov = float(message.field_of_view)
        coefficients = np.asarray(message.coefficients, np.float64)
        if coefficients.size == 0 or not np.isfinite(coefficients[0]):
            return True  # malformed: home() counts it
        if not shows_skyline(message_sky_share(coefficients, fov, message.fill)):
            return False
        index = self.target_index(count=False) if self.store is not None and len(self.store) else None
        return index is None or bool(shows_skyline(message_sky_share(self.store.coefficients()[index], fov)))

    def target_index(self, count: bool = True) -> int | None:
        """Return the snapshot to home to, or None when there is none (the reason counted unless count is False)."""
        n_snapshots = len(self.store)
        if n_snapshots == 1:
            return 0
        if self.values['target'] == 'index':
            return min(self.values['index'], n_snapshots - 1)
        if self.match is None:
            if count:
                self.reject('no_target', 'no accepted place match yet to choose the snapshot to home to')
            return None
        if self.match.index >= n_snapshots:
            if count:
                self.reject('match_beyond_map', f'the place match names snapshot {self.match.index} of map '
                                                f'{self.match.map_name!r}; this node has {n_snapshots} snapshots '
                                                f'of {self.store.name!r}')
            return None
        if self.values['target'] == 'next':
            return min(self.match.index + self.values['lookahead'], n_snapshots - 1)
        return int(self.match.index)

    def home(self, message: ShCoefficients, compass: CompassEstimate | None) -> None:
        """Publish the home vector of one view."""
        stamp = stamp_ns(message.header)
        if stamp <= self.last_stamp:
            self.reject('out_of_order', f'view stamped {stamp} is not newer than the last one')
            return
        if self.store is None or len(self.store) == 0:
            self.reject('no_map', 'no map with snapshots to home to (set the map parameter)')
            return
        index = self.target_index()
        if index is None:
            return
        coefficients = np.asarray(message.coefficients, np.float64)
        if coefficients.size != (message.max_degree + 1) ** 2 or message.max_degree < self.settings.degree:
            self.reject('degree', f'coefficients of degree {message.max_degree} ({coefficients.size} values); '
                                  f'the search needs degree {self.settings.degree}')
            return
        if not np.all(np.isfinite(coefficients)):
            self.reject('non_finite', f'view stamped {stamp} has NaN or infinite coefficients')
            return
        self.last_stamp = stamp
        with self.processing(stamp):
            current = view_from_coefficients(coefficients, float(message.field_of_view), self.settings.degree)
            snapshot = self.snapshot_view(index, float(message.field_of_view))
            rotation = None
            if compass is not None:  # against this snapshot or a neighbour: a good start either way
                q = compass.rotation
                rotation = np.array([q.x, q.y, q.z, q.w])
            estimate = estimate_home_vector(current, snapshot, rotation, self.settings)
            result = HomeVector(snapshot_index=index)
            result.header = message.header
            result.direction.x, result.direction.y, result.direction.z = (float(v) for v in estimate.best_direction)
            (result.rotation.x, result.rotation.y, result.rotation.z,
             result.rotation.w) = (float(v) for v in estimate.quaternion)
            result.residual = float(1.0 - estimate.confidence)
        self.emit(HOME_TOPIC, result)


def main(args=None) -> int:
    """Run the warping node until Ctrl-C."""
    return run_node(WarpingNode, args)
