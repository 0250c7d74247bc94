# SPDX-License-Identifier: Apache-2.0
"""Closed-loop homing and route following in the simulator, with the real skynav nodes in the loop.

A simulated robot is a node of the in-process graph: each cycle it renders the view from its pose
and publishes it on the camera topics like a camera; the skyline, SH, (localize,) compass and
warping nodes answer before the call returns, and the robot drives a step.

Homing: it turns towards the home vector, halves its step when successive home vectors point back
(it passed home) and stops when the warping node reports no confident direction several times in
a row (the views agree: home) or after a step limit.

Route following: it steers along the route's direction at the matched snapshot (the compass turns
the snapshot's forward axis into the current view), pulled towards a snapshot further on by the
home vector in proportion to its confidence, until the place match reaches the route's end.

Everything here is synthetic and deterministic: the same inputs drive the same paths.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from skynav_core.camera import EquidistantCamera
from skynav_core.graph import in_process
from skynav_core.images import fill_image
from skynav_core.node import SkynavNode
from skynav_core.nodes import NodeSpec, installed_nodes
from skynav_core.rotations import as_matrix

from .recording import CAMERA_FRAME, start_stamp
from .render import Renderer
from .robot import bump, camera_pose
from .scenarios import FRAME_RATE
from .sensor import Sensor
from .sky import Sky
from .world import World

STEP = 0.25  # m: the robot's drive per cycle while far from home
MIN_STEP = 0.04  # m: steps are halved on overshoot, down to this
UNSURE_RESIDUAL = 0.97  # HomeVector.residual above this: no confident direction
UNSURE_TO_STOP = 3  # consecutive unsure home vectors that end a run (at home)
SUCCESS_RADIUS = 0.3  # m: a run succeeds when it ends this close to home
ROUTE_HOMING_GAIN = 2.0  # weight of a fully confident home vector against the route direction


@dataclass
class Run:
    """One closed-loop run."""

    start: np.ndarray  # (2,) m
    goal: np.ndarray  # (2,) m
    path: list[np.ndarray] = field(default_factory=list)  # robot positions (x, y), start first
    residuals: list[float] = field(default_factory=list)
    stopped: str = ''  # why the run ended: 'home', 'steps', 'blocked', 'lost'

    @property
    def final_error(self) -> float:
        """Return the distance (m) from the last position to the goal."""
        return float(np.linalg.norm(self.path[-1] - self.goal))

    @property
    def success(self) -> bool:
        """Return whether the run ended within SUCCESS_RADIUS of the goal."""
        return self.final_error <= SUCCESS_RADIUS

    @property
    def path_ratio(self) -> float:
        """Return the driven length over the straight-line distance from start to goal."""
        driven = float(np.sum(np.linalg.norm(np.diff(np.array(self.path), axis=0), axis=1)))
        return driven / max(float(np.linalg.norm(self.start - self.goal)), 1e-9)


class SimRobotNode(SkynavNode):
    """The simulated robot in the in-process graph: publishes camera frames, listens to the home vector."""

    def __init__(self, **kwargs) -> None:
        super().__init__('sim_robot', **kwargs)
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import CameraInfo, Image

        from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch

        self.image_type, self.info_type, self.pose_type = Image, CameraInfo, PoseStamped
        for topic in ('/camera/uv/image_raw', '/camera/green/image_raw'):
            self.output(topic, Image)
        self.output('/camera/uv/camera_info', CameraInfo)
        self.home_vector = None
        self.compass = None
        self.match = None
        self.input('/homing/home_vector', HomeVector, lambda m: setattr(self, 'home_vector', m))
        self.input('/compass/orientation', CompassEstimate, lambda m: setattr(self, 'compass', m))
        self.input('/localization/match', PlaceMatch, lambda m: setattr(self, 'match', m))

    def publish_frame(
        self, stamp: int, uv: np.ndarray, green: np.ndarray, encoding: str, camera: EquidistantCamera
    ) -> None:
        """Publish one exposure as the camera topics carry it."""
        sec, nanosec = divmod(stamp, 1_000_000_000)
        info = self.info_type()
        for key, value in camera.camera_info_fields().items():
            setattr(info, key, value)
        messages = [
            ('/camera/uv/camera_info', info),
            ('/camera/uv/image_raw', fill_image(self.image_type(), uv, encoding)),
            ('/camera/green/image_raw', fill_image(self.image_type(), green, encoding)),
        ]
        self.home_vector = self.compass = None
        for topic, message in messages:
            message.header.stamp.sec, message.header.stamp.nanosec = sec, nanosec
            message.header.frame_id = CAMERA_FRAME
            self.emit(topic, message)


class Simulation:
    """A world, a camera and the light of one moment, rendered for a moving robot."""

    def __init__(
        self,
        world: World,
        camera: EquidistantCamera,
        hours: float,
        seed: int,
        encoding: str = 'mono8',
        bump_tilt: float = 0.0,
    ) -> None:
        """Prepare the renderer; `bump_tilt` (degrees) tilts every view by up to that much more (robot.bump)."""
        self.world, self.camera, self.encoding, self.seed = world, camera, encoding, seed
        self.bump_tilt = bump_tilt
        self.renderer = Renderer(world, camera)
        self.sky = Sky(hours, 0.0, cloud_seed=seed)
        self.sensor = Sensor()
        self.frames = 0
        self.hours = hours

    def capture(self, x: float, y: float, heading: float) -> tuple[np.ndarray, np.ndarray, object]:
        """Render the robot's view at (x, y) facing `heading`; return UV, green and the camera pose."""
        rng = np.random.default_rng([self.seed, self.frames, 97])
        pose = camera_pose(self.world.terrain, x, y, heading, bump(rng, self.bump_tilt))
        view = self.renderer.render(pose, self.sky)
        self.frames += 1
        return (
            self.sensor.capture(view.uv, view.inside, self.encoding, rng),
            self.sensor.capture(view.green, view.inside, self.encoding, rng),
            pose,
        )

    def stamp(self) -> int:
        """Return the stamp of the next frame (ns), FRAME_RATE apart."""
        return start_stamp(self.hours) + int(self.frames * 1e9 / FRAME_RATE)


def graph_specs() -> list[NodeSpec]:
    """Return the installed nodes of the homing loop and the simulated robot."""
    specs = [s for s in installed_nodes() if s.name in ('skyline', 'sh', 'localize', 'compass', 'warping')]
    return specs + [NodeSpec('sim_robot', 'skynav_sim', 'skynav_sim.closed_loop:SimRobotNode')]


def ground_direction(pose, direction) -> np.ndarray:
    """Return a camera_link direction turned into map and projected on the ground: a unit (x, y)."""
    world = pose.rotation.apply(direction)[:2]
    return world / max(float(np.linalg.norm(world)), 1e-9)


def route_direction(pose, compass) -> np.ndarray:
    """Return the taught route's direction at the compass's snapshot, on the ground in map (unit x, y).

    The snapshot was taken driving along its camera's +x; R (d_snapshot = R d_current) carries that
    axis into the current view as R^T e_x, the first row of R.
    """
    q = compass.rotation
    return ground_direction(pose, as_matrix([q.x, q.y, q.z, q.w])[0])


def drive(
    simulation: Simulation,
    robot: SimRobotNode,
    start: np.ndarray,
    heading: float,
    goal: np.ndarray,
    max_steps: int,
    done: Callable[[SimRobotNode], str] | None = None,
    homing: bool = True,
) -> Run:
    """Drive the robot by its home vectors from `start` until it stops; return the run.

    Homing (`homing`): towards the home vector; halve the step when home was passed, stop when the
    direction stays unsure. Route following: fixed steps along the route's direction from the
    compass, pulled towards the snapshot ahead by the home vector as far as it is confident, until
    `done` says the route ended.
    """
    run = Run(np.asarray(start, float), np.asarray(goal, float), [np.asarray(start, float)])
    position, step, unsure, previous = np.asarray(start, float), STEP, 0, None
    for _ in range(max_steps):
        uv, green, pose = simulation.capture(*position, heading)
        robot.publish_frame(simulation.stamp(), uv, green, simulation.encoding, simulation.camera)
        vector = robot.home_vector
        if done is not None and (reason := done(robot)):
            run.stopped = reason
            break
        if vector is None or (not homing and robot.compass is None):  # the nodes rejected the view or have no target
            run.stopped = 'lost'
            break
        run.residuals.append(float(vector.residual))
        ground = ground_direction(pose, [vector.direction.x, vector.direction.y, vector.direction.z])
        if homing:
            unsure = unsure + 1 if vector.residual > UNSURE_RESIDUAL else 0
            if unsure >= UNSURE_TO_STOP:
                run.stopped = 'home'
                break
            if previous is not None and ground @ previous < 0:  # it points back: home was passed
                step = max(step / 2, MIN_STEP)
            previous = ground
        else:
            steer = route_direction(pose, robot.compass) + ROUTE_HOMING_GAIN * (1.0 - vector.residual) * ground
            ground = steer / max(float(np.linalg.norm(steer)), 1e-9)
        target = position + step * ground
        if not simulation.world.is_free(*target):
            run.stopped = 'blocked'
            break
        heading = float(np.arctan2(ground[1], ground[0]))
        position = target
        run.path.append(position.copy())
    else:
        run.stopped = 'steps'
    return run


def home_runs(
    world: World,
    camera: EquidistantCamera,
    goal: np.ndarray,
    starts: list[tuple[np.ndarray, float]],
    map_path,
    hours: float,
    seed: int,
    max_steps: int,
    progress: Callable[[Run], None] | None = None,
    ros_args: list[str] | None = None,
    bump_tilt: float = 0.0,
) -> list[Run]:
    """Home from each start to the one snapshot of the map at `goal` (views bumped up to bump_tilt degrees)."""
    runs = []
    arguments = ['-p', f'map:={map_path}', '-p', 'reference:=index', '-p', 'target:=index', *(ros_args or [])]
    for start, heading in starts:
        simulation = Simulation(world, camera, hours, seed, bump_tilt=bump_tilt)
        with in_process([s for s in graph_specs() if s.name != 'localize'], arguments) as graph:
            robot = graph.nodes[-1]
            run = drive(simulation, robot, start, heading, goal, max_steps)
        runs.append(run)
        if progress is not None:
            progress(run)
    return runs


def snapshot_map(
    world: World,
    camera: EquidistantCamera,
    place: np.ndarray,
    heading: float,
    hours: float,
    seed: int,
    path,
    name: str = 'home',
    ros_args: list[str] | None = None,
    bump_tilt: float = 0.0,
):
    """Render the view at `place`, run it through the skyline and SH nodes, and store it as a one-snapshot map."""
    from skynav_core.maps import Snapshot
    from skynav_localize.mapping import build_map

    simulation = Simulation(world, camera, hours, seed, bump_tilt=bump_tilt)
    specs = [s for s in installed_nodes() if s.name in ('skyline', 'sh')]
    specs.append(NodeSpec('sim_robot', 'skynav_sim', 'skynav_sim.closed_loop:SimRobotNode'))
    with in_process(specs, ros_args) as graph:
        graph.keep_outputs = True
        robot = graph.nodes[-1]
        uv, green, pose = simulation.capture(*place, heading)
        stamp = simulation.stamp()
        robot.publish_frame(stamp, uv, green, simulation.encoding, camera)
        sh = [o.message for o in graph.outputs if o.topic == '/skyline/sh']
    if not sh:
        raise RuntimeError('the skyline and SH nodes gave no coefficients for the snapshot view')
    message = sh[0]
    coefficients = np.asarray(message.coefficients)
    snapshot = Snapshot(0, stamp, coefficients, np.concatenate([pose.position, pose.quaternion]))
    return build_map(
        path, name, int(message.max_degree), [snapshot], created_from='skynav sim home (synthetic)', overwrite=True
    )


def random_starts(
    world: World, goal: np.ndarray, count: int, min_distance: float, max_distance: float, rng: np.random.Generator
) -> list[tuple[np.ndarray, float]]:
    """Return `count` free start places (and headings) between min and max distance (m) from the goal."""
    starts = []
    for _ in range(count * 200):
        if len(starts) == count:
            break
        distance = rng.uniform(min_distance, max_distance)
        angle = rng.uniform(0, 2 * np.pi)
        place = goal + distance * np.array([np.cos(angle), np.sin(angle)])
        if world.is_free(*place):
            starts.append((place, float(rng.uniform(0, 2 * np.pi))))
    return starts


ROUTE_LOOKAHEAD = 6  # snapshots ahead of the matched one that route following homes to (0.6-1.2 m here)


def follow_route(
    world: World,
    camera: EquidistantCamera,
    map_path,
    start: np.ndarray,
    heading: float,
    hours: float,
    seed: int,
    max_steps: int,
    ros_args: list[str] | None = None,
) -> tuple[Run, np.ndarray]:
    """Follow the route of a map from `start`: localize, home to a snapshot further on, step, repeat.

    Returns the run and the route (snapshot positions x, y in m).
    """
    from skynav_core.maps import MapStore

    store = MapStore.open(map_path)
    route = store.positions()[:, :2]
    last = len(store) - 1
    store.close()
    arguments = [
        '-p',
        f'map:={map_path}',
        '-p',
        'reference:=match',
        '-p',
        'target:=next',
        '-p',
        f'lookahead:={ROUTE_LOOKAHEAD}',
        *(ros_args or []),
    ]

    def at_end(robot: SimRobotNode) -> str:
        match = robot.match
        return 'end' if match is not None and match.accepted and match.index >= last - 1 else ''

    simulation = Simulation(world, camera, hours, seed)
    with in_process(graph_specs(), arguments) as graph:
        run = drive(simulation, graph.nodes[-1], start, heading, route[-1], max_steps, at_end, homing=False)
    return run, route


def route_deviation(run: Run, route: np.ndarray) -> np.ndarray:
    """Return each position's distance (m) to the nearest point of the route's polyline."""
    points = np.array(run.path)
    a, b = route[:-1], route[1:]
    ab = b - a
    t = np.clip(
        np.einsum('pij,ij->pi', points[:, None] - a, ab) / np.maximum(np.einsum('ij,ij->i', ab, ab), 1e-12), 0, 1
    )
    nearest = a + t[..., None] * ab
    return np.min(np.linalg.norm(points[:, None] - nearest, axis=2), axis=1)
