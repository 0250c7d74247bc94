"""Run compass methods over a compass set: one prepared view per frame, one estimate per query against the reference.

A Method turns a frame's images (uv, green, mask) into its prepared view (SH coefficients, panorama, features;
timed as preparation) and two prepared views into a CompassEstimate (timed as the estimate). The default
methods: the FFT compass (masked and with the three fills; on masks, and on grey UV images with illumination
invariance), the exhaustive baseline, the yaw-only visual compass (panorama and SH) and the feature compass.
A method whose compass can prepare a snapshot once for many estimates (Compass.prepare, ExhaustiveCompass.prepare)
also comes as NAME+prepared: the reference's view is then prepared once (timed apart) and every estimate starts from
it, as a node comparing many views against one snapshot would run it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

from skynav_compass.estimate import CompassEstimate
from skynav_compass.evaluation import MethodResult, angular_error, relative_tilt


@dataclass(frozen=True)
class Method:
    """A named compass method: prepare(uv, green, mask) -> view; estimate(snapshot view, current view).

    prepare_snapshot (optional): the snapshot's view -> the form estimate takes for it, built once per snapshot.
    """

    name: str
    prepare: Callable[..., Any]
    estimate: Callable[[Any, Any], CompassEstimate]
    prepare_snapshot: Callable[[Any], Any] | None = None


METHOD_NAMES = ('fft-masked', 'fft-zero', 'fft-mean', 'fft-mirror', 'fft-masked-any-tilt', 'fft-uv-normalised',
                'exhaustive-masked', 'exhaustive-zero', 'visual-compass-panorama', 'visual-compass-sh', 'features-sift',
                'features-orb')
PREPARED = '+prepared'  # name suffix: the snapshot prepared once (the fft-* and exhaustive-* methods)


def with_snapshot_preparation(name: str, prepare: Callable[..., Any], compass) -> Method:
    """Return the Method of a compass with estimate and prepare; prepared once per snapshot if name ends +prepared."""
    return Method(name, prepare, compass.estimate, compass.prepare if name.endswith(PREPARED) else None)


def standard_methods(camera, max_degree: int = 16, names: Sequence[str] | None = None) -> list[Method]:
    """Return the named methods (default all of METHOD_NAMES) for a camera and SH degree L; masks feed the SH ones."""
    from skynav_sh.fisheye import FisheyeTransform

    from skynav_compass.compass import Compass, CompassConfig, any_tilt_config
    from skynav_compass.exhaustive import ExhaustiveCompass, ExhaustiveConfig
    from skynav_compass.features import FeatureCompass, FeatureConfig
    from skynav_compass.views import CompassView
    from skynav_compass.yaw import PanoramicCompass, YawCompass

    L = int(max_degree)
    transforms: dict[str, FisheyeTransform] = {}

    def transform(fill: str) -> FisheyeTransform:
        if fill not in transforms:
            transforms[fill] = FisheyeTransform(camera, L, fill)
        return transforms[fill]

    def masked_view(uv, green, mask):
        return CompassView.from_image(transform('zero'), mask, binary=True)

    def filled(fill: str):
        return lambda uv, green, mask: transform(fill).coefficients(mask)

    def uv_view(uv, green, mask):
        return CompassView.from_image(transform('zero'), uv, binary=False)

    # compasses that can prepare a snapshot: name -> (view of a frame, compass)
    compasses: dict[str, Callable[[], tuple[Callable, Any]]] = {
        'fft-masked': lambda: (masked_view, Compass(L)),
        'fft-masked-any-tilt': lambda: (masked_view, Compass(L, any_tilt_config())),
        'exhaustive-masked': lambda: (masked_view, ExhaustiveCompass(L)),
        'exhaustive-zero': lambda: (filled('zero'), ExhaustiveCompass(L, ExhaustiveConfig(cost='plain'))),
        # grey UV image instead of the mask, gain and offset removed over the overlap (masked correlation coefficient)
        'fft-uv-normalised': lambda: (uv_view, Compass(L, CompassConfig(normalise=True))),
    }
    for fill in ('zero', 'mean', 'mirror'):
        compasses[f'fft-{fill}'] = lambda fill=fill: (filled(fill), Compass(L, CompassConfig(cost='plain')))
    makers: dict[str, Callable[[], Method]] = {
        'visual-compass-sh': lambda: Method('visual-compass-sh', masked_view, YawCompass(L).estimate),
    }
    for base, make in compasses.items():
        for name in (base, base + PREPARED):
            makers[name] = lambda name=name, make=make: with_snapshot_preparation(name, *make())

    def panorama() -> Method:
        compass = PanoramicCompass(camera)
        return Method('visual-compass-panorama', lambda uv, green, mask: compass.unwrap(mask),
                      compass.estimate_panoramas)

    def features(detector: str) -> Method:
        compass = FeatureCompass(camera, FeatureConfig(detector=detector))
        return Method(f'features-{detector}', lambda uv, green, mask: compass.features(uv),
                      compass.estimate_features)

    makers['visual-compass-panorama'] = panorama
    makers['features-sift'] = lambda: features('sift')
    makers['features-orb'] = lambda: features('orb')
    chosen = METHOD_NAMES if names is None else names
    unknown = [n for n in chosen if n not in makers]
    if unknown:
        raise ValueError(f'unknown methods {unknown}; expected some of {METHOD_NAMES} (the fft-* and exhaustive-* '
                         f'ones also as NAME{PREPARED})')
    return [makers[name]() for name in chosen]


@dataclass(frozen=True)
class RunResult:
    """A method's result on a set, with the estimates, the preparation time per view and of the snapshot (s)."""

    result: MethodResult
    estimates: tuple[CompassEstimate, ...]
    prepare_seconds: float
    snapshot_seconds: float = 0.0  # preparing the snapshot once (methods with prepare_snapshot), else 0


def timed_estimates(methods: Sequence[Method], snapshots: Sequence[Any], queries: Sequence[Sequence[Any]],
                    clock: Callable[[], float] = time.process_time,
                    repeats: int = 1) -> tuple[list[list[CompassEstimate]], np.ndarray, np.ndarray]:
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


def run_methods(compass_set, methods: Sequence[Method], queries: Sequence[int] | None = None,
                clock: Callable[[], float] = time.process_time, repeats: int = 1) -> list[RunResult]:
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
            views[i] = method.prepare(compass_set.uv[i], compass_set.green[i], compass_set.masks[i])
        prepare_seconds.append((clock() - start) / len(frames))
        prepared.append(views)
    estimates, seconds, snapshot_seconds = timed_estimates(
        methods, [views[compass_set.reference] for views in prepared],
        [[views[i] for i in queries] for views in prepared], clock, repeats)
    out = []
    for k, method in enumerate(methods):
        errors = angular_error(np.array([e.quaternion for e in estimates[k]]), truth[queries])
        out.append(RunResult(MethodResult(method.name, errors, seconds[k],
                                          np.array([e.residual for e in estimates[k]]),
                                          np.array([e.confident for e in estimates[k]]),
                                          np.array([e.confidence for e in estimates[k]]),
                                          relative_tilt(np.array([e.matrix for e in estimates[k]]))),
                             tuple(estimates[k]), prepare_seconds[k], float(snapshot_seconds[k])))
    return out
