# SPDX-License-Identifier: Apache-2.0
"""Benchmark: map loading and per-frame cost of following a route of 250, 1,000 and 3,000 snapshots, one thread.

    .venv/bin/python bench/long_route.py [--frames N] [--passes P] [--sizes 250 1000 3000]

Issue 32, long routes: map loading, tracking and the per-frame cost must not grow with the route's length; the
per-frame total at 3,000 snapshots is to stay within 1.2x that at 250. The maps are synthetic: the SH views of the
bundled synthetic garden teach drive (the skyline and SH nodes run in this process, skynav_core.views), thinned to
snapshots as `skynav map build` thins them (mapping.SnapshotSelector), repeated until the route is long enough (each
repetition's coefficients perturbed by small noise), with the teach's odometry poses laid out as lawn lanes (one
drive's snapshots 0.1 m apart per lane, the lanes joined at each end by two point turns and a 0.5 m crossing),
written with mapping.build_map into a temporary folder; the shorter maps are the longer ones' beginnings.

Per frame, as the nodes do it during a FollowRoute goal (no ROS: the cores): the localize node's match
(Localizer.query of the default method in tracking mode from the goal's start, `tracking_start`, with the drive's
odometry path length, and the stamp of the matched snapshot), the compass node's estimate against the snapshot of the
latest accepted match (the current view and its sky share, SnapshotChoice's cached view of the snapshot,
Compass.estimate) and the route controller (RouteFollower.step on a TaughtRoute.from_poses of the map's odometry
poses). The robot advances half a snapshot per frame; its view is the snapshot's, perturbed and turned about the
vertical a little. The map load is what the localize node does on a new `map`: MapStore.open and the Localizer (the
amplitude descriptors derived, the descriptor index), plus the featureless snapshots its first query finds. Each
figure is the median over all timed frames (after WARMUP frames) of PASSES passes; the maps take turns on every
frame (the same view on each) so that other load on the machine hits them alike. Prints the table, the ratio of the
per-frame totals at the largest and smallest map against the 1.2 target (and each stage's), and a verdict.
"""

from __future__ import annotations

import os

for _variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS', 'NUMEXPR_NUM_THREADS'):
    os.environ[_variable] = '1'  # before numpy loads its BLAS

import argparse  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from types import SimpleNamespace  # noqa: E402

import numpy as np  # noqa: E402
from skynav_route.controller import Limits, RouteFollower, Settings, TaughtRoute, View  # noqa: E402

from skynav_compass.compass import Compass, CompassConfig  # noqa: E402
from skynav_compass.node import sky_share  # noqa: E402
from skynav_compass.views import CompassView  # noqa: E402
from skynav_core.maps import ODOM_POSE, MapStore, Snapshot  # noqa: E402
from skynav_core.rotations import MAX_TILT  # noqa: E402
from skynav_core.snapshots import SnapshotChoice  # noqa: E402
from skynav_core.views import recording_views  # noqa: E402
from skynav_localize.descriptors import describe  # noqa: E402
from skynav_localize.localizer import DESCRIPTOR_DEGREE, Localizer  # noqa: E402
from skynav_localize.mapping import SnapshotSelector, build_map  # noqa: E402
from skynav_sh.product import shows_skyline  # noqa: E402
from skynav_sh.rotation import rotate_z  # noqa: E402

BAGS = Path(__file__).resolve().parents[1] / 'bags'
TEACH = BAGS / 'synthetic_garden_teach.mcap'
SIZES = (250, 1000, 3000)
TARGET = 1.2  # per-frame total at the largest map over that at the smallest
WARMUP = 20  # frames of each pass not timed
FRAMES = 400  # frames timed per pass
PASSES = 3
START_INDEX = 10  # the FollowRoute goal's start_index
SPEED = 0.5  # snapshots per frame (0.3 m/s at 5 Hz is 0.6)
SPACING = 0.1  # m between snapshots
LANE_GAP = 0.5  # m between lanes
NOISE = 0.02  # of the coefficients' spread: each repetition of the drive, and each current view
FRAME_NS = 200_000_000  # 5 Hz
START_NS = 1_750_000_000_000_000_000


def drive_views() -> tuple[np.ndarray, float, str]:
    """Return the SH coefficients (K, n) of the synthetic garden teach drive's snapshots, thinned as `skynav map
    build` does (by the views' ground-truth positions), and the views' field of view (rad) and fill."""
    views = recording_views(TEACH, images=False).views
    selector = SnapshotSelector()
    kept = [
        v.coefficients
        for v in views
        if selector.keep(describe('amplitude', v.coefficients, v.max_degree), None if v.pose is None else v.pose[:3])
    ]
    return np.stack(kept), views[0].field_of_view, views[0].fill


def lane_poses(count: int, lane: int) -> np.ndarray:
    """Return (count, 7) odometry poses (x, y, z, qx, qy, qz, qw) of base_link on lawn lanes of `lane` snapshots
    SPACING apart, joined at each end by a point turn, a LANE_GAP crossing and another point turn."""
    positions: list[tuple[float, float]] = []
    headings: list[float] = []
    x, y, heading = 0.0, 0.0, 0.0
    turn_left = True
    while len(positions) < count:
        for _ in range(lane):  # along the lane
            positions.append((x, y))
            headings.append(heading)
            x, y = x + SPACING * math.cos(heading), y + SPACING * math.sin(heading)
        x, y = x - SPACING * math.cos(heading), y - SPACING * math.sin(heading)  # the lane's last snapshot
        side = 1.0 if turn_left else -1.0
        for _ in range(2):  # turn 90 degrees in place, in two steps
            heading += side * math.pi / 4
            positions.append((x, y))
            headings.append(heading)
        for _ in range(round(LANE_GAP / SPACING) - 1):  # cross to the next lane
            x, y = x + SPACING * math.cos(heading), y + SPACING * math.sin(heading)
            positions.append((x, y))
            headings.append(heading)
        x, y = x + SPACING * math.cos(heading), y + SPACING * math.sin(heading)
        for _ in range(2):  # and turn into it
            heading += side * math.pi / 4
            positions.append((x, y))
            headings.append(heading)
        x, y = x + SPACING * math.cos(heading), y + SPACING * math.sin(heading)
        turn_left = not turn_left
    xy, yaw = np.array(positions[:count]), np.array(headings[:count])
    zeros = np.zeros(count)
    return np.column_stack([xy, zeros, zeros, zeros, np.sin(yaw / 2), np.cos(yaw / 2)])


def write_map(path: Path, count: int, drive: np.ndarray, rng: np.random.Generator) -> None:
    """Write a synthetic map of `count` snapshots: the drive's views repeated (each repetition perturbed), on lanes."""
    poses = lane_poses(count, len(drive))
    spread = NOISE * float(np.std(drive))
    noise = {}

    def snapshots():
        for k in range(count):
            repetition, place = divmod(k, len(drive))
            if repetition not in noise:
                noise[repetition] = rng.normal(0.0, spread, drive.shape) if repetition else np.zeros(drive.shape)
            coefficients = drive[place] + noise[repetition][place]
            yield Snapshot(k, START_NS + k * FRAME_NS, coefficients, None, {ODOM_POSE: poses[k]})

    build_map(path, f'synthetic lanes {count}', DESCRIPTOR_DEGREE, snapshots(), created_from=str(TEACH)).close()


def load(path: Path, field_of_view: float, fill: str) -> tuple[MapStore, Localizer, float]:
    """Open a map as the localize node does for a FollowRoute goal; return it, its Localizer and the time (s)."""
    start = time.perf_counter()
    store = MapStore.open(path)
    localizer = Localizer(store, 'amplitude-seq')
    localizer.featureless_snapshots(field_of_view, fill)  # the first query's: which snapshots show no skyline
    localizer.tracking = True
    localizer.track_from(START_INDEX)
    return store, localizer, time.perf_counter() - start


class Follower:
    """The three nodes' cores following the route of one map from the goal's start, frame by frame."""

    def __init__(self, path: Path, field_of_view: float, fill: str, seed: int) -> None:
        """Load the map as the nodes do (the load timed: `load_time`, s); the views come from a generator of `seed`."""
        self.rng = np.random.default_rng(seed)
        self.field_of_view, self.fill = field_of_view, fill
        self.store, self.localizer, self.load_time = load(path, field_of_view, fill)
        self.compass = Compass(DESCRIPTOR_DEGREE, CompassConfig(max_tilt=MAX_TILT))
        self.choice = SnapshotChoice(lambda reason, detail: None, self.snapshot_view)
        self.choice.configure(str(path), 'match')
        route = TaughtRoute.from_poses(self.store.odometry_poses())
        assert route is not None, 'the map has its odometry poses'
        self.follower = RouteFollower(START_INDEX, len(self.store) - 1, Limits(), Settings(), route)
        self.along = route.along
        self.coefficients = self.store.coefficients()
        self.spread = NOISE * float(np.std(self.coefficients[:START_INDEX]))  # the same on every map
        self.accepted = 0

    def snapshot_view(self, coefficients: np.ndarray, field_of_view: float):
        """The compass node's view of a map snapshot (CompassNode.snapshot_view)."""
        view = CompassView.from_sh_message(coefficients, field_of_view, 'zero', DESCRIPTOR_DEGREE)
        return self.compass.prepare(view), sky_share(view)

    def frame(self, k: int) -> tuple[float, float, float]:
        """Handle frame k as the nodes do; return the times (s) of the localize, compass and controller stages."""
        store, localizer, choice, field_of_view, fill = (
            self.store,
            self.localizer,
            self.choice,
            self.field_of_view,
            self.fill,
        )
        place = START_INDEX + SPEED * k
        nearest = min(round(place), len(store) - 1)
        travelled = float(np.interp(place, np.arange(len(self.along)), self.along))
        perturbed = self.coefficients[nearest] + self.rng.normal(0.0, self.spread, self.coefficients.shape[1])
        current = rotate_z(perturbed, self.rng.normal(0, 0.1))
        stamp = START_NS + k * FRAME_NS
        # localize node: on_coefficients
        start = time.perf_counter()
        match = localizer.query(
            coefficients=current[: (localizer.degree + 1) ** 2],
            field_of_view=field_of_view,
            fill=fill,
            travelled=travelled,
        )
        store.snapshot_stamp(match.index)
        localized = time.perf_counter()
        self.accepted += match.accepted
        choice.on_match(SimpleNamespace(accepted=match.accepted, index=match.index, map_name=store.name))
        # compass node: on_coefficients (reference 'match')
        view = CompassView.from_sh_message(current, field_of_view, fill, DESCRIPTOR_DEGREE)
        estimate, index = None, None
        if shows_skyline(sky_share(view)) and (index := choice.choose()) is not None:
            snapshot, share = choice.view(index, field_of_view)
            if shows_skyline(share):
                estimate = self.compass.estimate(snapshot, view)
        estimated = time.perf_counter()
        # route node: the controller's step on the frame's match, compass estimate and a home vector ahead
        self.follower.step(
            View(
                stamp,
                match_index=match.index,
                match_accepted=match.accepted,
                rotation=None if estimate is None else estimate.matrix,
                rotation_index=-1 if index is None else index,
                rotation_confident=estimate is not None and estimate.confident,
                rotation_confidence=math.nan if estimate is None else estimate.confidence,
                home_direction=np.array([1.0, 0.0, 0.0]),
                home_residual=0.5,
                home_index=min(match.index + 3, len(store) - 1),
                home_expected=True,
                odometry=SPEED * SPACING,
            )
        )
        stepped = time.perf_counter()
        return localized - start, estimated - localized, stepped - estimated

    def close(self) -> None:
        """Close the maps the nodes opened."""
        self.store.close()
        if self.choice.store is not None:
            self.choice.store.close()


def main() -> None:
    """Build the maps, follow each, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--frames', type=int, default=FRAMES, help=f'frames timed per pass (default {FRAMES})')
    parser.add_argument('--passes', type=int, default=PASSES, help=f'passes over the sizes (default {PASSES})')
    parser.add_argument('--sizes', type=int, nargs='+', default=list(SIZES), help='snapshots per map')
    args = parser.parse_args()
    sizes = sorted(args.sizes)
    if START_INDEX + SPEED * (WARMUP + args.frames) >= sizes[0]:
        parser.error(f'{args.frames} frames run past the end of a map of {sizes[0]} snapshots')
    drive, field_of_view, fill = drive_views()
    print(f'synthetic maps: {len(drive)} snapshots of {TEACH.name} repeated (perturbed) on lawn lanes')
    loads: dict[int, list[float]] = {n: [] for n in sizes}
    frames: dict[int, list[np.ndarray]] = {n: [] for n in sizes}
    with tempfile.TemporaryDirectory() as folder:
        paths = {n: Path(folder) / f'synthetic_lanes_{n}.db' for n in sizes}
        for n, path in paths.items():
            write_map(path, n, drive, np.random.default_rng(0))  # the same route, as far as the shorter maps go
        for run in range(args.passes):
            followers = {n: Follower(paths[n], field_of_view, fill, seed=run) for n in sizes}
            timed = {n: np.zeros((WARMUP + args.frames, 3)) for n in sizes}
            for k in range(WARMUP + args.frames):
                for n in sizes[k % len(sizes) :] + sizes[: k % len(sizes)]:  # the same frame on every map in turn
                    timed[n][k] = followers[n].frame(k)
            for n, follower in followers.items():
                follower.close()
                if follower.accepted < (WARMUP + args.frames) // 2:
                    raise SystemExit(f'{n} snapshots: {follower.accepted} matches accepted: the route was not followed')
                loads[n].append(follower.load_time)
                frames[n].append(timed[n][WARMUP:])
    print(f'{args.passes} passes x {args.frames} frames (after {WARMUP} warm-up), medians, one thread')
    print(
        f'{"snapshots":>9}  {"map load (s)":>12}  {"localize (ms)":>13}  {"compass (ms)":>12}  '
        f'{"controller (ms)":>15}  {"total (ms)":>10}'
    )
    totals, stages_of = {}, {}
    for n in sizes:
        times = np.concatenate(frames[n])
        stages = stages_of[n] = 1e3 * np.median(times, axis=0)
        totals[n] = 1e3 * float(np.median(times.sum(axis=1)))
        print(
            f'{n:>9}  {np.median(loads[n]):>12.3f}  {stages[0]:>13.3f}  {stages[1]:>12.3f}  {stages[2]:>15.3f}  '
            f'{totals[n]:>10.3f}'
        )
    small, large = sizes[0], sizes[-1]
    ratio = totals[large] / totals[small]
    print(f'total({large}) / total({small}) = {ratio:.3f} (target <= {TARGET})')
    each = stages_of[large] / stages_of[small]
    print(f'by stage: localize {each[0]:.3f}, compass {each[1]:.3f}, controller {each[2]:.3f}')
    verdict = 'within' if ratio <= TARGET else 'OVER'
    print(f'verdict: the per-frame cost at {large} snapshots is {verdict} {TARGET}x that at {small} (synthetic data)')


if __name__ == '__main__':
    main()
