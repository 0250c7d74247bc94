# SPDX-License-Identifier: Apache-2.0
"""Closed-loop homing and route following in the simulator, driven only through the robot's interfaces.

The simulated mower is a node of the in-process graph (skynav_core.graph), like a robot on its topics: each
frame it publishes /clock, /odom and the camera topics of its view; the skyline, SH, (localize,) compass,
warping and route nodes answer before the call returns, the route node's /cmd_vel reply among them, and the
mower obeys that command for one frame period (skynav_sim.mower: wheel slip, odometry noise) before the next
frame. So the simulation steps exactly as fast as the graph answers, on sim time: a result never depends on
the machine's speed. The goal (Home or FollowRoute) goes to the route node through its action server, as
`skynav home|follow` send it; the route node's steering (skynav_route.controller) is the only steering. Ground
truth is used to render the view and to score the run, never inside the loop.

Everything here is synthetic and deterministic: the same inputs drive the same paths.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from geometry_msgs.msg import TransformStamped, Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from std_msgs.msg import Bool
from tf2_msgs.msg import TFMessage

from skynav_core.actions import error_name
from skynav_core.camera import EquidistantCamera
from skynav_core.graph import InProcessGraph, in_process
from skynav_core.images import fill_image, stamp_ns
from skynav_core.maps import MapStore, Snapshot
from skynav_core.motion import fill_velocity_command
from skynav_core.mount import mount_from_rpy_deg
from skynav_core.names import (
    BASE_FRAME,
    BUMPER,
    CAMERA_FRAME,
    CLOCK,
    CMD_VEL,
    COLOUR_CAMERA_INFO,
    COLOUR_COMPRESSED,
    COLOUR_IMAGE,
    COMPASS_NODE,
    FOLLOW_ROUTE_ACTION,
    GREEN_IMAGE,
    HOME_ACTION,
    LOCALIZE_NODE,
    ODOM,
    ODOM_FRAME,
    ROUTE_NODE,
    SH_NODE,
    SKYLINE_NODE,
    SKYLINE_SH,
    TEACH_ACTION,
    TF_STATIC,
    UV_CAMERA_INFO,
    UV_IMAGE,
    WARPING_NODE,
)
from skynav_core.namespaces import relative, remap_arguments
from skynav_core.node import TF_STATIC_QOS, SkynavNode
from skynav_core.nodes import NodeSpec, installed_nodes
from skynav_core.rotations import as_quaternion
from skynav_localize.mapping import build_map
from skynav_msgs.action import FollowRoute, Home, Teach

from .drive_eval import cross_track, path_length
from .mower import Mower, Pose2D
from .recording import CameraOutput, Exposure, expose, start_stamp
from .render import CameraPose, Renderer
from .robot import CAMERA_HEIGHT, base_positions, bump, camera_pose
from .scenarios import route as planned_route
from .sensor import Sensor
from .sky import Sky
from .world import World

FRAME_PERIOD = 0.2  # s of sim time between camera frames while driving (5 Hz)
SPEED = 0.4  # m/s: the goals' speed limit in the simulator (0.08 m per frame)
SUCCESS_RADIUS = 0.3  # m: a homing run succeeds when it ends this close to home
COMMAND_TIMEOUT = 0.5  # s: the mower's base stops when no command came for this long
GOAL_WAIT = 60.0  # s of wall time for the action server to appear and take the goal
RESULT_WAIT = 10.0  # s of wall time for a goal's result once the robot stands still
ROUTE_LOOKAHEAD = 6  # snapshots ahead of the matched one the warping node homes to (the route node's default)
GRAPH_NODES = (SKYLINE_NODE, SH_NODE, LOCALIZE_NODE, COMPASS_NODE, WARPING_NODE, ROUTE_NODE)


@dataclass
class Run:
    """One closed-loop run."""

    start: np.ndarray  # (2,) m
    goal: np.ndarray  # (2,) m
    path: list[np.ndarray] = field(default_factory=list)  # true mower positions (x, y), one per frame, start first
    headings: list[float] = field(default_factory=list)  # true headings (rad, map frame), one per position
    tilts: list[float] = field(default_factory=list)  # camera tilt from the vertical (degrees), one per camera frame
    confidences: list[float] = field(default_factory=list)  # the goal's feedback, one per processed frame
    feedback: list[Any] = field(default_factory=list)  # the goal's feedback messages, the first before any frame
    stopped: str = ''  # why the run ended: 'reached', an error code's name (LOST, BLOCKED, ...) or 'frames'
    result: Any = None  # the action's result
    commands: int = 0  # /cmd_vel messages the mower received
    stopped_frames: int = 0  # frames the mower stood still while the goal ran

    @property
    def final_error(self) -> float:
        """Return the distance (m) from the last position to the goal."""
        return float(np.linalg.norm(self.path[-1] - self.goal))

    @property
    def success(self) -> bool:
        """Return whether the run ended within SUCCESS_RADIUS of the goal."""
        return self.final_error <= SUCCESS_RADIUS

    @property
    def driven(self) -> float:
        """Return the length (m) of the true path."""
        return path_length(np.array(self.path))

    @property
    def path_ratio(self) -> float:
        """Return the driven length over the straight-line distance from start to goal."""
        return self.driven / max(float(np.linalg.norm(self.start - self.goal)), 1e-9)


class SimMowerNode(SkynavNode):
    """The simulated mower in the in-process graph: camera, /odom, /bumper and /clock out, /cmd_vel in."""

    def __init__(self, **kwargs) -> None:
        super().__init__('sim_mower', **kwargs)
        for topic in (UV_IMAGE, GREEN_IMAGE):
            self.output(topic, Image)
        self.output(UV_CAMERA_INFO, CameraInfo)
        self.output(COLOUR_IMAGE, Image)  # a colour camera, when the simulation has one
        self.output(COLOUR_COMPRESSED, CompressedImage)
        self.output(COLOUR_CAMERA_INFO, CameraInfo)
        self.output(ODOM, Odometry)
        self.output(BUMPER, Bool)
        self.output(CLOCK, Clock)
        self.output(TF_STATIC, TFMessage, TF_STATIC_QOS)
        self.commands: list[tuple[int, float, float]] = []  # (stamp ns, forward m/s, turn rad/s) of each command
        self.input(CMD_VEL, TwistStamped, self.on_command)

    def on_command(self, message: TwistStamped | Twist) -> None:
        """Take a velocity command: a TwistStamped, or a Twist (the route node's cmd_vel_stamped false) at the graph's
        time."""
        twist, stamp = (message.twist, stamp_ns(message.header)) if hasattr(message, 'header') else (message, None)
        self.commands.append((self.now_ns() if stamp is None else stamp, float(twist.linear.x), float(twist.angular.z)))

    def publish_clock(self, stamp: int) -> None:
        """Publish the sim time (ns)."""
        message = Clock()
        message.clock.sec, message.clock.nanosec = divmod(stamp, 1_000_000_000)
        self.emit(CLOCK, message)

    def publish_odometry(self, stamp: int, pose: Pose2D) -> None:
        """Publish the wheel odometry: base_link's pose in frame odom."""
        message = Odometry()
        message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
        message.header.frame_id, message.child_frame_id = ODOM_FRAME, BASE_FRAME
        message.pose.pose.position.x, message.pose.pose.position.y = pose.x, pose.y
        message.pose.pose.orientation.z = float(np.sin(pose.heading / 2))
        message.pose.pose.orientation.w = float(np.cos(pose.heading / 2))
        self.emit(ODOM, message)

    def publish_mount(self, stamp: int, mount: np.ndarray) -> None:
        """Publish base_link -> camera_link (the camera CAMERA_HEIGHT above the base, turned by `mount` (3, 3)) on
        /tf_static, as a robot_state_publisher does from a URDF."""
        transform = TransformStamped(child_frame_id=CAMERA_FRAME)
        transform.header.stamp.sec, transform.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
        transform.header.frame_id = BASE_FRAME
        transform.transform.translation.z = CAMERA_HEIGHT
        q = transform.transform.rotation
        q.x, q.y, q.z, q.w = (float(v) for v in as_quaternion(mount))
        self.emit(TF_STATIC, TFMessage(transforms=[transform]))

    def publish_bumper(self, contact: bool) -> None:
        """Publish whether the mower's bumper touches an object."""
        self.emit(BUMPER, Bool(data=bool(contact)))

    def publish_frame(self, stamp: int, exposure: Exposure, output: CameraOutput, camera: EquidistantCamera) -> None:
        """Publish one exposure of the camera `output` as its topics carry it."""
        sec, nanosec = divmod(stamp, 1_000_000_000)
        info = CameraInfo()
        for key, value in camera.camera_info_fields().items():
            setattr(info, key, value)
        messages: list[tuple[str, Any]] = [(output.info_topic, info)]
        for topic, pixels in exposure.images.items():
            messages.append((topic, fill_image(Image(), pixels, output.encoding)))
        for topic, (format_text, data) in exposure.compressed.items():
            messages.append((topic, CompressedImage(format=format_text, data=data)))
        for topic, message in messages:
            message.header.stamp.sec, message.header.stamp.nanosec = sec, nanosec
            message.header.frame_id = CAMERA_FRAME
            self.emit(topic, message)

    def command(self, stamp: int) -> tuple[float, float]:
        """Return the command the base obeys at `stamp` (ns): the latest, unless older than COMMAND_TIMEOUT."""
        if not self.commands or stamp - self.commands[-1][0] > COMMAND_TIMEOUT * 1e9:
            return 0.0, 0.0
        return self.commands[-1][1], self.commands[-1][2]


class Simulation:
    """A world, a camera and the light of one moment, rendered for a moving robot."""

    def __init__(
        self,
        world: World,
        camera: EquidistantCamera,
        hours: float,
        seed: int,
        encoding: str = 'mono8',
        output: CameraOutput | None = None,
        bump_tilt: float = 0.0,
        clouds: float = 0.0,
        mount: np.ndarray | None = None,
    ) -> None:
        """Prepare the renderer of the camera `output` (None: the UV/green pair in `encoding`); `bump_tilt` (degrees)
        tilts every view by up to that much more (robot.bump);
        `clouds` is the cloud cover (0 clear .. 1 overcast); `mount` (3, 3) turns the camera on the robot
        (camera_link in base_link; None: the base's axes)."""
        self.world, self.camera, self.encoding, self.seed = world, camera, encoding, seed
        self.output = output or CameraOutput('uv-green', encoding)
        self.bump_tilt = bump_tilt
        # a camera on the base's axes is not composed with an identity rotation: scipy renormalises the product,
        # which moves the pose by an ulp, and the closed loop amplifies such a change into another path
        on_axes = mount is None or np.array_equal(mount, np.eye(3))
        self.mount = None if on_axes else Rotation.from_matrix(mount)
        self.renderer = Renderer(world, camera, self.output.bands)
        self.sky = Sky(hours, clouds, cloud_seed=seed)
        self.sensor = Sensor()
        self.frames = 0
        self.hours = hours

    def capture(self, x: float, y: float, heading: float) -> tuple[Exposure, CameraPose]:
        """Render the robot's view at (x, y) facing `heading`; return what its camera delivers and the camera pose."""
        rng = np.random.default_rng([self.seed, self.frames, 97])
        pose = camera_pose(self.world.terrain, x, y, heading, bump(rng, self.bump_tilt), self.mount)
        view = self.renderer.render(pose, self.sky)
        self.frames += 1
        return expose(view, self.output, rng, self.sensor), pose

    def stamp(self) -> int:
        """Return the stamp of the next frame (ns), FRAME_PERIOD apart."""
        return start_stamp(self.hours) + int(round(self.frames * FRAME_PERIOD * 1e9))


def graph_specs(names: tuple[str, ...] = GRAPH_NODES) -> list[NodeSpec]:
    """Return the installed nodes of the loop (by name) and the simulated mower."""
    specs = [s for s in installed_nodes() if s.name in names]
    return specs + [NodeSpec('sim_mower', 'skynav_sim', 'skynav_sim.closed_loop:SimMowerNode')]


def spin_until(executor: SingleThreadedExecutor, done: Callable[[], bool], seconds: float) -> bool:
    """Spin the executor until `done()` or `seconds` of wall time passed; return done()."""
    deadline = time.monotonic() + seconds
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)
    return done()


def drive_goal(
    graph: InProcessGraph,
    simulation: Simulation,
    mower: Mower,
    action: tuple[type, str],
    goal: Any,
    goal_place: np.ndarray,
    max_frames: int,
    progress: Callable[[], None] | None = None,
    odometry: bool = True,
    mount: np.ndarray | None = None,
    cancel_at: int | None = None,
) -> Run:
    """Send one goal to the route node and let the mower drive until its result (or `max_frames`); return the run.

    `progress` is called once per camera frame; without `odometry` the base publishes no /odom; a `mount` (3, 3)
    is published on /tf_static before the goal; once the feedback's matched snapshot reaches `cancel_at` the goal is
    canceled (a user's Ctrl-C).
    """
    robot = graph.nodes[-1]
    assert isinstance(robot, SimMowerNode)  # the last node of the graph this module builds
    context = robot.context
    executor = SingleThreadedExecutor(context=context)
    client_node = Node('sim_goal_client', context=context)
    for node in [*graph.nodes, client_node]:
        executor.add_node(node)
    client = ActionClient(client_node, action[0], relative(action[1]))  # in the graph's namespace
    run = Run(mower.pose.position, np.asarray(goal_place, float), [mower.pose.position], [mower.pose.heading])
    feedback: list[Any] = []
    if mount is not None:
        graph.advance(simulation.stamp())
        robot.publish_mount(simulation.stamp(), mount)
    try:
        if not spin_until(executor, client.server_is_ready, GOAL_WAIT):
            raise RuntimeError(f'no action server {action[1]} in the simulated graph')
        sent = client.send_goal_async(goal, feedback_callback=lambda m: feedback.append(m.feedback))
        if not spin_until(executor, sent.done, GOAL_WAIT) or not sent.result().accepted:
            raise RuntimeError(f'the route node did not take the {action[0].__name__} goal')
        result = sent.result().get_result_async()
        # the first feedback says the graph is set up for the goal (before any frame)
        spin_until(executor, lambda: bool(feedback) or result.done(), GOAL_WAIT)

        def answered_since(heard: int) -> Callable[[], bool]:
            """Return whether feedback beyond the first `heard` messages, or the result, came."""
            return lambda: len(feedback) > heard or result.done()

        for _ in range(max_frames):
            if result.done():
                break
            if cancel_at is not None and feedback and feedback[-1].matched_index >= cancel_at:
                run.stopped = 'canceled'
                break
            stamp = simulation.stamp()
            graph.advance(stamp)
            robot.publish_clock(stamp)
            if odometry:
                robot.publish_odometry(stamp, mower.odometry)
            exposure, pose = simulation.capture(mower.pose.x, mower.pose.y, mower.pose.heading)
            run.tilts.append(float(np.degrees(np.arccos(np.clip(pose.rotation.as_matrix()[2, 2], -1.0, 1.0)))))
            answered, heard = len(robot.commands), len(feedback)
            robot.publish_frame(stamp, exposure, simulation.output, simulation.camera)
            run.commands = len(robot.commands)
            linear, angular = robot.command(stamp)
            if len(robot.commands) > answered:  # lockstep: its feedback too before the next frame
                spin_until(executor, answered_since(heard), RESULT_WAIT)
                run.stopped_frames += linear == 0.0 and angular == 0.0
            executor.spin_once(timeout_sec=0)
            if result.done():
                break
            mower.drive(linear, angular, FRAME_PERIOD)
            robot.publish_bumper(mower.blocked)
            run.path.append(mower.pose.position)
            run.headings.append(mower.pose.heading)
            if progress is not None:
                progress()
            if mower.blocked:  # the route node ends the goal (BLOCKED)
                spin_until(executor, result.done, RESULT_WAIT)
                break
        if result.done():
            response = result.result().result
            run.result = response
            run.stopped = 'reached' if response.error_code == 0 else error_name(response)
        else:
            run.stopped = run.stopped or 'frames'
            handle = sent.result()
            cancel = handle.cancel_goal_async()
            spin_until(executor, cancel.done, RESULT_WAIT)
            spin_until(executor, result.done, RESULT_WAIT)
            run.result = result.result().result if result.done() else None
        run.confidences = [float(f.confidence) for f in feedback]
        run.feedback = feedback
        run.commands = len(robot.commands)
    finally:
        executor.remove_node(client_node)
        for node in graph.nodes:
            executor.remove_node(node)
        client.destroy()
        client_node.destroy_node()
        executor.shutdown()
    return run


@dataclass(frozen=True)
class Base:
    """The simulated mower's base: wheel slip and odometry noise (shares of each step's motion), its seed, whether
    it has wheel odometry (publishes /odom), its camera's mount (roll, pitch, yaw in degrees, fixed axes X, Y, Z:
    camera_link in base_link, rendered) and how the graph learns of it: the robot publishes it on /tf_static, the
    nodes get the parameter camera_mount_rpy_deg, or nothing tells them (they take the camera on the base's axes)."""

    slip: float = 0.05
    odometry_noise: float = 0.02
    seed: int = 0
    odometry: bool = True
    camera: CameraOutput = CameraOutput()  # what the mower's camera delivers (default: the UV/green pair, mono8)
    mount_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    declare_mount: str = 'tf_static'
    namespace: str = ''  # the graph's namespace (skynav_core.namespaces): its nodes, actions and /clock under it

    @property
    def mount(self) -> np.ndarray:
        """Return the camera's mount (3, 3): camera_link's rotation in base_link."""
        return mount_from_rpy_deg(list(self.mount_rpy_deg))

    @property
    def published_mount(self) -> np.ndarray | None:
        """Return the mount the robot publishes on /tf_static (None when the graph learns it otherwise)."""
        return self.mount if self.declare_mount == 'tf_static' else None

    def mount_arguments(self) -> list[str]:
        """Return the graph's ROS arguments that declare the mount by parameter (none unless so declared)."""
        if self.declare_mount != 'parameter':
            return []
        return ['-p', f'camera_mount_rpy_deg:=[{", ".join(repr(float(v)) for v in self.mount_rpy_deg)}]']

    def ros_arguments(self) -> list[str]:
        """Return the graph's ROS arguments of this robot: its mount (mount_arguments) and its namespace."""
        return [*self.mount_arguments(), *remap_arguments(self.namespace)]


def home_runs(
    world: World,
    camera: EquidistantCamera,
    goal: np.ndarray,
    starts: list[tuple[np.ndarray, float]],
    map_path,
    hours: float,
    seed: int,
    max_frames: int,
    progress: Callable[[Run], None] | None = None,
    ros_args: list[str] | None = None,
    bump_tilt: float = 0.0,
    base: Base = Base(),
    clouds: float = 0.0,
) -> list[Run]:
    """Home from each start to snapshot 0 of the map at `goal` with a Home goal (views bumped up to bump_tilt deg,
    under a sky of `clouds` cover)."""
    runs = []
    arguments = ['-p', f'map:={map_path}', *base.ros_arguments(), *(ros_args or [])]
    for k, (start, heading) in enumerate(starts):
        simulation = Simulation(
            world, camera, hours, seed, output=base.camera, bump_tilt=bump_tilt, clouds=clouds, mount=base.mount
        )
        mower = Mower(
            world,
            Pose2D(float(start[0]), float(start[1]), float(heading)),
            np.random.default_rng([base.seed, seed, k]),
            base.slip,
            base.odometry_noise,
        )
        with in_process(graph_specs(tuple(n for n in GRAPH_NODES if n != LOCALIZE_NODE)), arguments) as graph:
            goal_message = Home.Goal(map_path='', index=0, max_speed=SPEED)
            run = drive_goal(
                graph,
                simulation,
                mower,
                (Home, HOME_ACTION),
                goal_message,
                goal,
                max_frames,
                odometry=base.odometry,
                mount=base.published_mount,
            )
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
    mount: np.ndarray | None = None,
    output: CameraOutput | None = None,
):
    """Render the view at `place` (the camera turned on the robot by `mount`, 3x3; the camera `output`, None: the
    UV/green pair), run it through the skyline and SH nodes, and store it as a one-snapshot map."""
    simulation = Simulation(world, camera, hours, seed, output=output, bump_tilt=bump_tilt, mount=mount)
    specs = [s for s in installed_nodes() if s.name in (SKYLINE_NODE, SH_NODE)]
    specs.append(NodeSpec('sim_mower', 'skynav_sim', 'skynav_sim.closed_loop:SimMowerNode'))
    with in_process(specs, ros_args) as graph:
        graph.keep_outputs = True
        robot = graph.nodes[-1]
        assert isinstance(robot, SimMowerNode)  # the last node of the graph built here
        exposure, pose = simulation.capture(float(place[0]), float(place[1]), heading)
        stamp = simulation.stamp()
        robot.publish_frame(stamp, exposure, simulation.output, camera)
        sh = [o.message for o in graph.outputs if o.topic == SKYLINE_SH]
    if not sh:
        raise RuntimeError('the skyline and SH nodes gave no coefficients for the snapshot view')
    message = sh[0]
    coefficients = np.asarray(message.coefficients)
    snapshot = Snapshot(0, stamp, coefficients, np.concatenate([pose.position, pose.quaternion]))
    return build_map(
        path, name, int(message.max_degree), [snapshot], created_from='skynav sim home (synthetic)', overwrite=True
    )


LINE_STEP = 0.05  # m between the places along a straight line looked at for an object in the way


def clear_line(world: World, start: np.ndarray, goal: np.ndarray) -> bool:
    """Return whether the mower's body could drive straight from start to goal (m) without touching an object."""
    steps = max(int(np.ceil(np.linalg.norm(np.asarray(goal) - start) / LINE_STEP)), 1)
    places = np.linspace(start, goal, steps + 1)
    return not any(world.collides(float(x), float(y)) for x, y in places)


def random_starts(
    world: World, goal: np.ndarray, count: int, min_distance: float, max_distance: float, rng: np.random.Generator
) -> list[tuple[np.ndarray, float]]:
    """Return `count` free start places (and headings) between min and max distance (m) from the goal."""
    starts: list[tuple[np.ndarray, float]] = []
    for _ in range(count * 200):
        if len(starts) == count:
            break
        distance = rng.uniform(min_distance, max_distance)
        angle = rng.uniform(0, 2 * np.pi)
        place = goal + distance * np.array([np.cos(angle), np.sin(angle)])
        if world.is_free(*place):
            starts.append((place, float(rng.uniform(0, 2 * np.pi))))
    return starts


def follow_route(
    world: World,
    camera: EquidistantCamera,
    map_path,
    start: np.ndarray,
    heading: float,
    hours: float,
    seed: int,
    max_frames: int,
    ros_args: list[str] | None = None,
    base: Base = Base(),
    bump_tilt: float = 0.0,
    route: np.ndarray | None = None,
    clouds: float = 0.0,
    progress: Callable[[], None] | None = None,
    start_index: int = 0,
    cancel_at: int | None = None,
) -> tuple[Run, np.ndarray]:
    """Follow the route of a map from `start` with a FollowRoute goal from snapshot `start_index` (-1: wherever
    localization places the robot) to its last snapshot.

    Returns the run and the route (snapshot places x, y of base_link in m: from the map's camera_link poses unless
    `route` gives the true ones of a taught map; for scoring only, the loop never sees them). The sky has `clouds`
    cover; `progress` is called once per camera frame; the goal is canceled once it passes snapshot `cancel_at`.
    """
    if route is None:
        with MapStore.open(map_path) as store:
            route = base_positions(store.poses(), base.mount)
    arguments = ['-p', f'map:={map_path}', *base.ros_arguments(), *(ros_args or [])]
    simulation = Simulation(
        world, camera, hours, seed, output=base.camera, bump_tilt=bump_tilt, clouds=clouds, mount=base.mount
    )
    mower = Mower(
        world,
        Pose2D(float(start[0]), float(start[1]), float(heading)),
        np.random.default_rng([base.seed, seed]),
        base.slip,
        base.odometry_noise,
    )
    goal = FollowRoute.Goal(map_path='', start_index=start_index, end_index=-1, max_speed=SPEED)
    with in_process(graph_specs(), arguments) as graph:
        run = drive_goal(
            graph,
            simulation,
            mower,
            (FollowRoute, FOLLOW_ROUTE_ACTION),
            goal,
            route[-1],
            max_frames,
            progress,
            base.odometry,
            base.published_mount,
            cancel_at,
        )
    return run, route


def route_deviation(run: Run, route: np.ndarray) -> np.ndarray:
    """Return each position's distance (m) to the nearest point of the route's polyline (all of it)."""
    return cross_track(np.array(run.path), route, np.inf, np.inf)[0]


TELEOP_SPEED = 0.3  # m/s: the scripted operator's driving speed while teaching
TELEOP_LOOKAHEAD = 0.5  # m: the operator steers towards the planned path this far ahead of its nearest point
TELEOP_GAIN = 2.0  # rad/s of turn rate per rad of heading error
TELEOP_MAX_TURN = 1.0  # rad/s: the joystick's largest turn rate
TELEOP_END = 0.2  # m before the planned path's end where the operator ends teaching
TELEOP_FRAMES_PER_METRE = 20  # frames (4 s) per metre of route before a teach drive is given up


def teleoperate(pose: Pose2D, spline: Callable, total: float, reached: float) -> tuple[float, float, float]:
    """Return the operator's command (m/s, rad/s) towards the planned path and the arc length (m) reached on it.

    The operator sees the mower and the planned path (the teacher, not skynav): it steers towards the path's
    point TELEOP_LOOKAHEAD beyond the nearest one (searched near the arc length `reached` so far, in m), as a
    person with a joystick would. Positions in the world's map frame.
    """
    arcs = np.linspace(max(reached - 0.5, 0.0), min(reached + 1.5, total), 41)
    nearest = float(arcs[int(np.argmin(np.linalg.norm(spline(arcs) - pose.position, axis=1)))])
    target = spline(min(nearest + TELEOP_LOOKAHEAD, total))
    error = float(np.arctan2(target[1] - pose.y, target[0] - pose.x)) - pose.heading
    error = float(np.arctan2(np.sin(error), np.cos(error)))
    linear = TELEOP_SPEED * max(0.0, float(np.cos(error)))
    return linear, float(np.clip(TELEOP_GAIN * error, -TELEOP_MAX_TURN, TELEOP_MAX_TURN)), nearest


@dataclass
class Teaching:
    """What a simulated teach drive left: the Teach result and the true pose of every frame (for scoring only)."""

    result: Any = None
    status: int = 0  # the goal's end (action_msgs GoalStatus)
    stamps: list[int] = field(default_factory=list)  # ns, one per camera frame
    poses: list[np.ndarray] = field(default_factory=list)  # true (x, y, heading) per frame, m and rad (map frame)
    feedback: list[Any] = field(default_factory=list)  # the goal's feedback


def teach_route(
    world: World,
    camera: EquidistantCamera,
    hours: float,
    seed: int,
    length: float,
    map_path,
    base: Base = Base(),
    route_seed: int = 0,
    ros_args: list[str] | None = None,
    progress: Callable[[], None] | None = None,
) -> Teaching:
    """Drive `length` m of a planned free route by scripted teleoperation while a Teach goal records the map
    (teach_drive); RuntimeError when the graph does not take the goal or the drive fails."""
    spline, total = planned_route(world, route_seed, length)
    start, ahead = spline(0.0), spline(0.3) - spline(0.0)
    end = min(length, total - TELEOP_END)  # m along the planned path
    reached = 0.0

    def operator(pose: Pose2D) -> tuple[float, float] | None:
        nonlocal reached
        if reached >= end:
            return None
        linear, angular, reached = teleoperate(pose, spline, total, reached)
        return linear, angular

    first = Pose2D(float(start[0]), float(start[1]), float(np.arctan2(ahead[1], ahead[0])))
    frames = int(TELEOP_FRAMES_PER_METRE * end)
    return teach_drive(world, camera, hours, seed, map_path, first, operator, frames, base, ros_args, progress)


def teach_drive(
    world: World,
    camera: EquidistantCamera,
    hours: float,
    seed: int,
    map_path,
    start: Pose2D,
    operator: Callable[[Pose2D], tuple[float, float] | None],
    max_frames: int,
    base: Base = Base(),
    ros_args: list[str] | None = None,
    progress: Callable[[], None] | None = None,
) -> Teaching:
    """Let a scripted operator drive the mower from `start` while a Teach goal records the map at `map_path`.

    The graph (skyline, SH, localize: it serves /skynav/teach) runs in process; the mower publishes /clock, /odom
    (when its base has odometry) and its camera each frame and obeys the operator's commands on /cmd_vel
    (skynav_sim.mower: slip, odometry noise), which the localize node hears too. `operator` answers each true pose
    with a command (m/s, rad/s), or None when the drive is done: then it cancels the goal, which finishes the map
    (the usual end of teaching). RuntimeError when the graph does not take the goal, the drive hits an obstacle or
    it takes more than `max_frames` frames. `progress` is called once per camera frame.
    """
    mower = Mower(world, start, np.random.default_rng([base.seed, seed, 5]), base.slip, base.odometry_noise)
    simulation = Simulation(world, camera, hours, seed, output=base.camera, mount=base.mount)
    teaching = Teaching()
    arguments = [*base.ros_arguments(), *(ros_args or [])]
    with in_process(graph_specs((SKYLINE_NODE, SH_NODE, LOCALIZE_NODE)), arguments) as graph:
        robot = graph.nodes[-1]
        assert isinstance(robot, SimMowerNode)  # the last node of the graph this module builds
        executor = SingleThreadedExecutor(context=robot.context)
        client_node = Node('sim_teach_client', context=robot.context)
        for node in [*graph.nodes, client_node]:
            executor.add_node(node)
        client = ActionClient(client_node, Teach, relative(TEACH_ACTION))  # in the graph's namespace
        try:
            graph.advance(simulation.stamp())  # the goal starts at the first frame's time (sim time)
            if base.published_mount is not None:
                robot.publish_mount(simulation.stamp(), base.published_mount)
            if not spin_until(executor, client.server_is_ready, GOAL_WAIT):
                raise RuntimeError('no /skynav/teach action server in the simulated graph')
            goal = Teach.Goal(map_path=str(map_path), map_name='', spacing=0.0, max_length=0.0, overwrite=True)
            sent = client.send_goal_async(goal, feedback_callback=lambda m: teaching.feedback.append(m.feedback))
            if not spin_until(executor, sent.done, GOAL_WAIT) or not sent.result().accepted:
                raise RuntimeError('the localize node did not take the Teach goal')
            result = sent.result().get_result_async()
            # the first feedback (0 snapshots) says teaching has begun
            spin_until(executor, lambda: bool(teaching.feedback) or result.done(), GOAL_WAIT)
            while not result.done():
                command = operator(mower.pose)
                if command is None:
                    break
                if len(teaching.stamps) >= max_frames:
                    raise RuntimeError(f'the scripted operator did not finish its drive in {max_frames} frames')
                stamp = simulation.stamp()
                graph.advance(stamp)
                robot.publish_clock(stamp)
                if base.odometry:
                    robot.publish_odometry(stamp, mower.odometry)
                exposure, _ = simulation.capture(mower.pose.x, mower.pose.y, mower.pose.heading)
                robot.publish_frame(stamp, exposure, simulation.output, simulation.camera)
                teaching.stamps.append(stamp)
                teaching.poses.append(np.array([mower.pose.x, mower.pose.y, mower.pose.heading]))
                executor.spin_once(timeout_sec=0)
                joystick = fill_velocity_command(TwistStamped(), stamp, *command)
                graph.publish(CMD_VEL, joystick)
                mower.drive(*robot.command(stamp), FRAME_PERIOD)
                if progress is not None:
                    progress()
                if mower.blocked:
                    raise RuntimeError('the scripted teach drive hit an obstacle')
            if not result.done():
                sent.result().cancel_goal_async()  # the operator ends teaching: the map is finished
            if not spin_until(executor, result.done, GOAL_WAIT):
                raise RuntimeError('the Teach goal did not end after its cancel')
            teaching.result, teaching.status = result.result().result, result.result().status
        finally:
            for node in [*graph.nodes, client_node]:
                executor.remove_node(node)
            client.destroy()
            client_node.destroy_node()
            executor.shutdown()
    return teaching


def truth_at(stamps: np.ndarray, frame_stamps: np.ndarray, frame_poses: np.ndarray) -> np.ndarray:
    """Return the true pose of the frame stamped like each of `stamps` (ns); NaN rows for stamps of no frame."""
    order = np.argsort(frame_stamps)
    sorted_stamps = frame_stamps[order]
    where = np.clip(np.searchsorted(sorted_stamps, stamps), 0, len(sorted_stamps) - 1)
    found = sorted_stamps[where] == stamps
    poses = np.full((len(stamps), frame_poses.shape[1]), np.nan)
    poses[found] = frame_poses[order[where[found]]]
    return poses
