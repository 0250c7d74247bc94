# SPDX-License-Identifier: Apache-2.0
"""Run compass methods on frames: one prepared view per frame, one estimate per query against a snapshot.

A Method (built from an entry of the registry, methods.METHODS) turns a frame into its prepared view (SH
coefficients, panorama, features; timed as preparation) and two prepared views into a CompassEstimate (timed as the
estimate). Frames come as images (a compass set's: ImageViews projects them with the fish-eye transform) or as the
SH node's views (skynav_core.views.View: NodeViews reads their coefficients). A method whose compass can prepare a
snapshot once for many estimates (Compass.prepare, ExhaustiveCompass.prepare) does so on recordings, as the compass
node does; on compass sets it does so when named NAME+prepared, so both ways can be timed.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any, NamedTuple

import numpy as np

from skynav_compass.compass import Compass, CompassConfig, any_tilt_config
from skynav_compass.errors import CompassError
from skynav_compass.estimate import CompassEstimate
from skynav_compass.eval.evaluation import CompassResult, angular_error, relative_tilt
from skynav_compass.eval.exhaustive import ExhaustiveCompass, ExhaustiveConfig
from skynav_compass.eval.features import FeatureCompass, FeatureConfig
from skynav_compass.eval.methods import METHODS, PREPARED, CompassMethod
from skynav_compass.eval.yaw import PanoramicCompass, YawCompass
from skynav_compass.views import CompassView
from skynav_core.rotations import MAX_TILT
from skynav_sh.basis import DEFAULT_DEGREE
from skynav_sh.fisheye import FisheyeTransform


@dataclass(frozen=True)
class Method:
    """A named compass method: prepare(frame) -> view; estimate(snapshot view, current view).

    prepare_snapshot (optional): the snapshot's view -> the form estimate takes for it, built once per snapshot.
    """

    name: str
    prepare: Callable[[Any], Any]
    estimate: Callable[[Any, Any], CompassEstimate]
    prepare_snapshot: Callable[[Any], Any] | None = None


class Images(NamedTuple):
    """A frame given by its images: the UV image and the skyline mask (uint8, 255 sky)."""

    uv: np.ndarray
    mask: np.ndarray


class ImageViews:
    """The views (methods.VIEWS) of frames given by their images, through the fish-eye transform of each fill."""

    def __init__(self, camera, max_degree: int) -> None:
        self.camera = camera
        self.max_degree = int(max_degree)
        self._transforms: dict[str, FisheyeTransform] = {}  # built on first use, once per fill

    def transform(self, fill: str) -> FisheyeTransform:
        """Return the fish-eye transform of the camera to SH of degree L with a fill."""
        if fill not in self._transforms:
            self._transforms[fill] = FisheyeTransform(self.camera, self.max_degree, fill)
        return self._transforms[fill]

    def view(self, kind: str, frame: Images) -> Any:
        """Return one view of a frame."""
        if kind == 'masked':
            return CompassView.from_image(self.transform('zero'), frame.mask, binary=True)
        if kind == 'uv':
            return CompassView.from_image(self.transform('zero'), frame.uv, binary=False)
        if kind in ('zero', 'mean', 'mirror'):
            return self.transform(kind).coefficients(frame.mask)
        return frame.mask if kind == 'mask' else frame.uv


class NodeViews:
    """The views (methods.NODE_VIEWS) of the SH node's output, with the fill and field of view (rad) it used."""

    def __init__(self, max_degree: int, field_of_view: float, fill: str = 'zero') -> None:
        self.max_degree = int(max_degree)
        self.field_of_view = field_of_view
        self.fill = fill

    def view(self, kind: str, frame) -> Any:
        """Return one view of a frame (skynav_core.views.View, or anything with its coefficients, uv and mask)."""
        if kind in ('masked', 'zero'):
            view = CompassView.from_sh_message(frame.coefficients, self.field_of_view, self.fill, self.max_degree)
            return view if kind == 'masked' else view.weighted  # v f: nothing outside the field of view
        if kind in ('mask', 'image'):
            return frame.mask if kind == 'mask' else frame.uv
        raise CompassError(f'the SH node gives no {kind!r} view')


def build_method(
    entry: CompassMethod,
    views: ImageViews | NodeViews,
    max_degree: int,
    camera=None,
    max_tilt: float | None = MAX_TILT,
    prepared: bool = True,
    name: str | None = None,
) -> Method:
    """Return the Method of a registry entry: its view of frames and its compass (degree L, tilt bound in rad).

    prepared: prepare the snapshot once (compasses that can); name: what tables call it (default the entry's).
    """
    name, view, L = name or entry.name, partial(views.view, entry.view), int(max_degree)
    if entry.compass == 'panorama':
        panoramic = PanoramicCompass(camera)
        return Method(name, lambda frame: panoramic.unwrap(view(frame)), panoramic.estimate_panoramas)
    if entry.compass == 'features':
        features = FeatureCompass(camera, FeatureConfig(**entry.settings))
        return Method(name, lambda frame: features.features(view(frame)), features.estimate_features)
    if entry.compass == 'yaw':
        return Method(name, view, YawCompass(L).estimate)
    if entry.compass == 'exhaustive':
        compass: ExhaustiveCompass | Compass = ExhaustiveCompass(L, ExhaustiveConfig(**entry.settings))
    elif entry.compass == 'fft-any-tilt':
        compass = Compass(L, any_tilt_config(**entry.settings))
    else:
        compass = Compass(L, CompassConfig(**{'max_tilt': max_tilt, **entry.settings}))
    return Method(name, view, compass.estimate, compass.prepare if prepared else None)


def standard_methods(camera, max_degree: int = DEFAULT_DEGREE, names: Sequence[str] | None = None) -> list[Method]:
    """Return the named methods (default all of the registry) for frames given by images, a camera and degree L.

    A name may end in +prepared (methods.PREPARED) for a compass that prepares the snapshot once.
    """
    chosen = list(METHODS) if names is None else list(names)
    entries = {name: METHODS.get(name.removesuffix(PREPARED)) for name in chosen}
    unknown = [
        name for name, entry in entries.items() if entry is None or (name.endswith(PREPARED) and not entry.prepares)
    ]
    if unknown:
        raise CompassError(
            f'unknown methods {unknown}; expected some of {tuple(METHODS)} (the fft-* and exhaustive-* '
            f'ones also as NAME{PREPARED})'
        )
    views = ImageViews(camera, max_degree)
    return [
        build_method(
            METHODS[name.removesuffix(PREPARED)], views, max_degree, camera, prepared=name.endswith(PREPARED), name=name
        )
        for name in chosen
    ]


def compass_result(
    name: str, estimates: Sequence[CompassEstimate], truth: np.ndarray, seconds: np.ndarray
) -> CompassResult:
    """Return a method's result: its estimates' errors against the true rotations (Q, 3, 3) and their seconds."""
    return CompassResult(
        name,
        angular_error(np.array([e.quaternion for e in estimates]), truth),
        seconds,
        np.array([e.residual for e in estimates]),
        np.array([e.confident for e in estimates]),
        np.array([e.confidence for e in estimates]),
        relative_tilt(np.array([e.matrix for e in estimates])),
    )


@dataclass(frozen=True)
class RunResult:
    """A method's result on a set, with the estimates, the preparation time per view and of the snapshot (s)."""

    result: CompassResult
    estimates: tuple[CompassEstimate, ...]
    prepare_seconds: float
    snapshot_seconds: float = 0.0  # preparing the snapshot once (methods with prepare_snapshot), else 0


def timed_estimates(
    methods: Sequence[Method],
    snapshots: Sequence[Any],
    queries: Sequence[Sequence[Any]],
    clock: Callable[[], float] = time.process_time,
    repeats: int = 1,
) -> tuple[list[list[CompassEstimate]], np.ndarray, np.ndarray]:
    """Return every method's estimates of its query views against its snapshot view, with the seconds they took.

    snapshots[k] and queries[k][q] are method k's prepared views. A method with prepare_snapshot prepares its
    snapshot once first (timed apart). The methods take turns on every query and every repetition, so a change of
    load on the machine hits them alike; each estimate's least time over `repeats` counts. Returns (estimates
    [method][query], seconds (methods, queries), snapshot seconds (methods,)).
    """
    references, snapshot_seconds = [], np.zeros(len(methods))
    for k, (method, snapshot) in enumerate(zip(methods, snapshots)):
        if method.prepare_snapshot is not None:
            start = clock()
            snapshot = method.prepare_snapshot(snapshot)
            snapshot_seconds[k] = clock() - start
        references.append(snapshot)
        if len(queries[k]):
            method.estimate(snapshot, queries[k][0])  # warm-up (tables, caches)
    count = len(queries[0]) if len(queries) else 0
    seconds = np.full((len(methods), count), np.inf)
    estimates: list[list[CompassEstimate]] = [[] for _ in methods]
    for q in range(count):
        for repeat in range(max(int(repeats), 1)):
            for k, method in enumerate(methods):
                start = clock()
                estimate = method.estimate(references[k], queries[k][q])
                seconds[k, q] = min(seconds[k, q], clock() - start)
                if repeat == 0:
                    estimates[k].append(estimate)
    return estimates, seconds, snapshot_seconds


def run_methods(
    compass_set,
    methods: Sequence[Method],
    queries: Sequence[int] | None = None,
    clock: Callable[[], float] = time.process_time,
    repeats: int = 1,
) -> list[RunResult]:
    """Return every method's errors (deg) and seconds per estimate on the queries against the set's reference.

    The methods take turns on every query and every repetition, so a change of load on the machine hits them alike;
    each estimate's least time over `repeats` counts (CPU time of this process by default).
    """
    queries = list(compass_set.queries if queries is None else queries)
    truth = compass_set.true_rotations()
    frames = [compass_set.reference] + queries
    prepared: list[dict[int, Any]] = []
    prepare_seconds = []
    for method in methods:
        views = {}
        start = clock()
        for i in frames:
            views[i] = method.prepare(Images(compass_set.uv[i], compass_set.masks[i]))
        prepare_seconds.append((clock() - start) / len(frames))
        prepared.append(views)
    estimates, seconds, snapshot_seconds = timed_estimates(
        methods,
        [views[compass_set.reference] for views in prepared],
        [[views[i] for i in queries] for views in prepared],
        clock,
        repeats,
    )
    return [
        RunResult(
            compass_result(method.name, estimates[k], truth[queries], seconds[k]),
            tuple(estimates[k]),
            prepare_seconds[k],
            float(snapshot_seconds[k]),
        )
        for k, method in enumerate(methods)
    ]
