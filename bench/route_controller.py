# SPDX-License-Identifier: Apache-2.0
"""Benchmark: what the route controller adds per camera frame, one thread.

    .venv/bin/python bench/route_controller.py [--frames N]

Times (1) the controller core alone (skynav_route.controller: RouteFollower.step and Homer.step on scripted
views), and (2) the route node's whole handling of a frame in the in-process graph: the place match, compass
estimate, home vector and view messages delivered, the view built, the step, the TwistStamped published (to a
router that keeps nothing) and the feedback sent. Prints the median and 99th percentile per frame. The target is
under 2 ms per frame (DESIGN.md); for scale, the graph's stages spend about 40 ms of node time per frame. The data
is synthetic. Pin it to one core (`taskset -c 0`) for the one-core figure.
"""

from __future__ import annotations

import os

from skynav_core.names import CMD_VEL, COMPASS_ORIENTATION, HOME_VECTOR, LOCALIZATION_MATCH, SKYLINE_SH

for _variable in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS', 'NUMEXPR_NUM_THREADS'):
    os.environ[_variable] = '1'  # before numpy loads its BLAS

import argparse  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from rclpy.task import Future  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402
from skynav_route.controller import Homer, Limits, RouteFollower, Settings, TaughtRoute, View  # noqa: E402
from skynav_route.goals import ActiveGoal  # noqa: E402

from skynav_core.graph import in_process  # noqa: E402
from skynav_core.maps import Snapshot  # noqa: E402
from skynav_core.nodes import installed_nodes  # noqa: E402
from skynav_localize.mapping import build_map  # noqa: E402
from skynav_msgs.action import FollowRoute  # noqa: E402
from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch, ShCoefficients  # noqa: E402

FRAME = 100_000_000  # ns between frames
STRAIGHT = TaughtRoute(np.column_stack([np.arange(10**6 + 1) * 0.1, np.zeros(10**6 + 1)]), np.zeros(10**6 + 1))
START = 1_750_000_000_000_000_000  # ns


def percentiles(times: list[float]) -> str:
    """Return median and 99th percentile of times (s) in ms."""
    return f'median {1e3 * np.median(times):.3f} ms, 99th percentile {1e3 * np.percentile(times, 99):.3f} ms'


def bench_core(frames: int) -> None:
    """Time the controller core on scripted views."""
    rng = np.random.default_rng(0)
    rotations = Rotation.from_euler('zx', rng.normal(0, [0.3, 0.1], (frames, 2))).as_matrix()
    directions = rng.normal(size=(frames, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    for name, controller in (
        ('route following', RouteFollower(-1, 10**6, Limits(), Settings(), STRAIGHT)),
        ('homing', Homer(0, Limits(), Settings())),
    ):
        times = []
        for k in range(frames):
            view = View(
                START + k * FRAME,
                match_index=k // 10,
                match_accepted=True,
                rotation=rotations[k],
                rotation_index=k // 10,
                home_direction=directions[k],
                home_residual=0.4,
                home_index=0 if name == 'homing' else k // 10 + 6,
                odometry=0.03,
            )
            start = time.perf_counter()
            controller.step(view)
            times.append(time.perf_counter() - start)
        print(f'controller core, {name}: {percentiles(times)} per frame ({frames} frames)')


def bench_node(frames: int) -> None:
    """Time the route node's handling of whole frames in the in-process graph (a follow goal active)."""

    class Handle:  # the goal handle's part the node uses; the action's DDS traffic is not the controller's cost
        goal_id = None

        def publish_feedback(self, feedback) -> None:
            pass

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / 'bench.db'
        rng = np.random.default_rng(1)
        build_map(path, 'bench', 16, [Snapshot(k, k, rng.normal(size=289)) for k in range(100)]).close()
        specs = [s for s in installed_nodes() if s.name == 'route']
        with in_process(specs, ['-p', f'map:={path}', '-p', 'configure_peers:=false']) as graph:
            node = graph.nodes[0]
            plan = node.goal_server.plan(FollowRoute.Goal(start_index=-1, end_index=-1), FollowRoute.Result)
            plan = replace(plan, controller=RouteFollower(-1, 10**6, Limits(), Settings(), STRAIGHT))
            node.active = ActiveGoal(FollowRoute, Handle(), plan, Future())
            coefficients = list(rng.normal(size=289))
            times = []
            for k in range(frames):
                stamp = START + k * FRAME
                sec, nanosec = divmod(stamp, 1_000_000_000)
                match = PlaceMatch(map_name='bench', index=k // 10, accepted=True)
                compass = CompassEstimate(snapshot_index=k // 10)
                compass.rotation.z, compass.rotation.w = math.sin(0.05), math.cos(0.05)
                vector = HomeVector(snapshot_index=k // 10 + 6, residual=0.4)
                vector.direction.x = 1.0
                view = ShCoefficients(max_degree=16, coefficients=coefficients, fill='zero', field_of_view=3.5)
                messages = [
                    (LOCALIZATION_MATCH, match),
                    (COMPASS_ORIENTATION, compass),
                    (HOME_VECTOR, vector),
                    (SKYLINE_SH, view),
                ]
                for _, message in messages:
                    message.header.stamp.sec, message.header.stamp.nanosec = sec, nanosec
                graph.advance(stamp)
                start = time.perf_counter()
                for topic, message in messages:
                    graph.publish(topic, message)
                times.append(time.perf_counter() - start)
            assert node.published[CMD_VEL] == frames, 'one command per frame'
            node.active = None
    print(f'route node, a whole frame (4 inputs, one command): {percentiles(times)} per frame ({frames} frames)')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--frames', type=int, default=2000, help='frames to time (default 2000)')
    args = parser.parse_args()
    bench_core(args.frames)
    bench_node(args.frames)


if __name__ == '__main__':
    main()
