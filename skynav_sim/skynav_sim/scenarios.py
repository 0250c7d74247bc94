# SPDX-License-Identifier: Apache-2.0
"""Scenarios: the sequence of camera poses and daylight conditions a synthetic recording is made of.

- teach: a drive along a route through the yard;
- repeat: the same route at another time of day, shifted sideways, optionally shaken (extra tilt), and
  optionally with a detour: in the route's middle it leaves the route for a loop into the yard and comes back;
- homing: a snapshot place and a grid of places around it;
- compass: one place seen with many camera rotations (tilt up to a limit), then from places up to
  a given distance away;
- skyline: places all over the yard at every named time of day, clear and cloudy.

Every scenario is reproducible from its parameters; the route of teach and repeat depends only on
the world and `route_seed`, so a teach and a repeat drive of the same world follow the same path.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from skynav_sim.errors import SimError

from .names import SCENARIOS
from .render import CameraPose
from .robot import bump, camera_pose
from .sky import TIMES_OF_DAY
from .world import YARD_RADIUS, World

FRAME_RATE = 10.0  # Hz, the contract's recordings


@dataclass(frozen=True)
class Frame:
    """One frame to render."""

    pose: CameraPose
    hours: float  # local solar time of the daylight
    cloud_cover: float
    label: str  # what the frame is in its scenario: 'route', 'snapshot', 'grid', 'rotation', ...


@dataclass
class ScenarioParameters:
    """Everything a scenario depends on besides the world; defaults suit a teach drive."""

    hours: float = TIMES_OF_DAY['forenoon']
    cloud_cover: float = 0.0
    route_seed: int = 0
    route_length: float = 20.0  # m (teach, repeat)
    speed: float = 0.5  # m/s (teach, repeat); at FRAME_RATE it sets the spacing of frames
    offset: float = 0.0  # m, sideways shift of a repeat drive (left positive)
    shake: float = 0.0  # degrees rms of extra roll/pitch (repeat), as a mower's bouncing
    wobble: float = 0.0  # degrees rms of heading deviation from the route (repeat), as a mower steering
    spacing: float = 0.5  # m between grid places (homing)
    grid_radius: float = 3.0  # m, half side of the homing grid
    count: int = 40  # rotations and translated views each (compass); places per condition (skyline)
    max_tilt: float = 30.0  # degrees (compass rotations)
    max_translation: float = 0.5  # m (compass translated views)
    bump_tilt: float = 0.0  # degrees: each homing place (snapshot too) sits on a bump tilting the camera up to this
    detour: float = 0.0  # m: a repeat drive leaves its route in the middle for a loop reaching this far (0: none)
    reference_hours: float | None = None  # compass: the reference frame's time of day (None: `hours`, as the others)
    extra: dict = field(default_factory=dict)


def build(name: str, world: World, params: ScenarioParameters, seed: int) -> list[Frame]:
    """Return the frames of scenario `name` in `world`; `seed` drives every random choice."""
    if name not in SCENARIOS:
        raise SimError(f'unknown scenario {name!r} (known: {", ".join(SCENARIOS)})')
    rng = np.random.default_rng([seed, SCENARIOS.index(name), 7])
    return {'teach': _teach, 'repeat': _repeat, 'homing': _homing, 'compass': _compass, 'skyline': _skyline}[name](
        world, params, rng
    )


def route(world: World, route_seed: int, length: float) -> tuple[CubicSpline, float]:
    """Return a smooth route through free space, as a spline of arc length (m) -> (x, y), and its length."""
    rng = np.random.default_rng([world.seed, route_seed, 11])
    for _ in range(400):
        points = [_free_point(world, rng, YARD_RADIUS * 0.7)]
        heading = rng.uniform(0, 2 * np.pi)
        travelled = 0.0
        while travelled < length + 2:
            for _ in range(30):
                turn = rng.uniform(-0.9, 0.9)
                step = rng.uniform(2.0, 3.5)
                candidate = points[-1] + step * np.array([np.cos(heading + turn), np.sin(heading + turn)])
                if world.is_free(*candidate) and _segment_free(world, points[-1], candidate):
                    heading += turn
                    points.append(candidate)
                    travelled += step
                    break
            else:
                break
        if travelled < length + 2:
            continue
        spline, total = _arc_length_spline(np.array(points))
        samples = spline(np.linspace(0, total, int(total / 0.1) + 1))
        if world.is_free(samples[:, 0], samples[:, 1]).all():
            return spline, total
    raise SimError(f'found no free route of {length} m in this {world.style} world; try a shorter one')


def _free_point(world: World, rng: np.random.Generator, radius: float) -> np.ndarray:
    for _ in range(10000):
        p = rng.uniform(-radius, radius, 2)
        if world.is_free(*p):
            return p
    raise SimError('the yard has no free space')


def _segment_free(world: World, a: np.ndarray, b: np.ndarray) -> bool:
    t = np.linspace(0, 1, 30)[:, None]
    points = a + t * (b - a)
    return bool(world.is_free(points[:, 0], points[:, 1]).all())


def _arc_length_spline(
    points: np.ndarray, ends: tuple[np.ndarray, np.ndarray] | None = None
) -> tuple[CubicSpline, float]:
    """Return a spline through `points` parametrised by (approximate) arc length, and that length; `ends`: the
    directions it starts and ends in (natural ends when None)."""
    chord = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    bc_type: str | tuple[tuple[int, np.ndarray], ...]  # scipy's name of the ends, or each end's first derivative
    if ends is None:
        bc_type = 'natural'
    else:
        bc_type = tuple((1, np.asarray(d, float) / np.linalg.norm(d)) for d in ends)
    rough = CubicSpline(chord, points, bc_type=bc_type)
    fine = np.linspace(0, chord[-1], 2000)
    xy = rough(fine)
    arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    return CubicSpline(arc, xy, bc_type='natural'), float(arc[-1])


def _drive(
    world: World,
    params: ScenarioParameters,
    rng: np.random.Generator,
    offset: float,
    shake: float,
    label: str,
    wobble: float = 0.0,
    detour: float = 0.0,
) -> list[Frame]:
    spline, total = route(world, params.route_seed, params.route_length)
    length = min(params.route_length, total)
    start = (total - length) / 2
    if detour > 0:
        xy, heading, labels = _detour_drive(
            world, spline, start, length, detour, params.speed / FRAME_RATE, offset, label
        )
    else:
        arc = start + np.arange(0.0, length, params.speed / FRAME_RATE)
        xy, heading = _beside(spline, arc, offset)
        labels = [label] * len(arc)
    if not world.is_free(xy[:, 0], xy[:, 1]).all():
        raise SimError(f'a sideways offset of {offset} m leaves the free space of this route')
    jitter = _smooth_noise(rng, len(xy), 2, np.radians(shake)) if shake > 0 else None
    if wobble > 0:
        heading = heading + _smooth_noise(rng, len(xy), 1, np.radians(wobble))[:, 0]
    frames = []
    for k in range(len(xy)):
        extra = Rotation.from_rotvec([jitter[k, 0], jitter[k, 1], 0.0]) if jitter is not None else None
        pose = camera_pose(world.terrain, xy[k, 0], xy[k, 1], heading[k], extra)
        frames.append(Frame(pose, params.hours, params.cloud_cover, labels[k]))
    return frames


def _beside(spline: CubicSpline, arc: np.ndarray, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the points (F, 2) `offset` m to the left of the route at arc lengths `arc` (m), and its heading (rad)."""
    tangent = spline(arc, 1)
    heading = np.arctan2(tangent[..., 1], tangent[..., 0])
    normal = np.stack([-np.sin(heading), np.cos(heading)], axis=-1)
    return spline(arc) + offset * normal, heading


#: Widths (m) of a detour's loop, from where it leaves the route to where it comes back, tried widest first.
DETOUR_WIDTHS = (3.0, 2.0, 1.0)
#: Directions (degrees from the route's normal, towards its end) in which a detour's loop may run out, tried in turn.
DETOUR_ANGLES = (0.0, 20.0, -20.0, 40.0, -40.0)
#: Spacing (m) of the points along a detour's loop that must lie in free space.
DETOUR_CHECK_STEP = 0.05


def _detour_loop(
    world: World, spline: CubicSpline, middle: float, reach: float, offset: float
) -> tuple[CubicSpline, float, float, float]:
    """Return a loop through free space off the route (driven `offset` m to its left) around arc length `middle` (m),
    running out to `reach` m from the route's point there: (spline of its arc length -> (x, y), its length, and the
    route's arc lengths where it leaves and where it comes back); ValueError when the yard has no room for one."""
    for width in sorted({min(w, reach) for w in DETOUR_WIDTHS}, reverse=True):
        leave, rejoin = middle - width / 2, middle + width / 2
        (a, b, centre), _ = _beside(spline, np.array([leave, rejoin, middle]), offset)
        along = spline(middle, 1) / np.linalg.norm(spline(middle, 1))
        for side in (1.0, -1.0):
            for angle in np.radians(DETOUR_ANGLES):
                # out: the route's normal on this side, turned by angle towards the route's end; across: from the
                # leg that goes out to the leg that comes back
                out = np.cos(angle) * side * np.array([-along[1], along[0]]) + np.sin(angle) * along
                across = np.array([out[1], -out[0]])
                across *= np.sign(np.dot(across, b - a)) or 1.0
                neck, head = 0.35 * reach, reach - width / 2
                points = np.array(
                    [
                        a,
                        centre + neck * out - width / 2 * across,
                        centre + head * out - width / 2 * across,
                        centre + reach * out,
                        centre + head * out + width / 2 * across,
                        centre + neck * out + width / 2 * across,
                        b,
                    ]
                )
                loop, length = _arc_length_spline(points, (spline(leave, 1), spline(rejoin, 1)))
                samples = loop(np.linspace(0, length, int(length / DETOUR_CHECK_STEP) + 2))
                if world.is_free(samples[:, 0], samples[:, 1]).all():
                    return loop, length, leave, rejoin
    raise SimError(
        f'no free room in this world for a detour of {reach:g} m from the middle of the route; try a shorter one'
    )


def _detour_drive(
    world: World, spline: CubicSpline, start: float, length: float, reach: float, step: float, offset: float, label: str
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Return positions (F, 2), headings (F,, rad) and labels of a drive `offset` m beside the route's arc lengths
    start..start + length (m) with a loop off it in the middle, a frame every `step` m of travel; frames on the loop
    are labelled 'detour', the others `label`."""
    loop, loop_length, leave, rejoin = _detour_loop(world, spline, start + length / 2, reach, offset)
    before = leave - start
    travel = np.arange(0.0, before + loop_length + (start + length - rejoin), step)
    on_loop = (travel >= before) & (travel < before + loop_length)
    beside, heading = _beside(
        spline, np.where(travel < before, start + travel, rejoin + travel - before - loop_length), offset
    )
    along_loop = np.clip(travel - before, 0.0, loop_length)
    loop_tangent = loop(along_loop, 1)
    xy = np.where(on_loop[:, None], loop(along_loop), beside)
    heading = np.where(on_loop, np.arctan2(loop_tangent[:, 1], loop_tangent[:, 0]), heading)
    return xy, heading, ['detour' if k else label for k in on_loop]


def _smooth_noise(rng: np.random.Generator, count: int, channels: int, rms: float) -> np.ndarray:
    """Return `count` samples of smooth (about 1 s correlation at FRAME_RATE) noise with the given rms."""
    white = rng.normal(size=(count + 20, channels))
    kernel = np.hanning(int(FRAME_RATE)) / np.hanning(int(FRAME_RATE)).sum()
    smooth = np.stack([np.convolve(white[:, c], kernel, mode='same') for c in range(channels)], axis=1)[10:-10]
    return smooth / smooth.std(axis=0) * rms


def _teach(world: World, params: ScenarioParameters, rng: np.random.Generator) -> list[Frame]:
    return _drive(world, params, rng, 0.0, 0.0, 'route')


def _repeat(world: World, params: ScenarioParameters, rng: np.random.Generator) -> list[Frame]:
    return _drive(world, params, rng, params.offset, params.shake, 'route', params.wobble, params.detour)


def snapshot_place(world: World, params: ScenarioParameters) -> np.ndarray:
    """Return the place of the homing/compass snapshot: the free point nearest to the middle of the route."""
    spline, total = route(world, params.route_seed, params.route_length)
    return spline(total / 2)


def _homing(world: World, params: ScenarioParameters, rng: np.random.Generator) -> list[Frame]:
    home = snapshot_place(world, params)
    frames = [
        Frame(
            camera_pose(world.terrain, home[0], home[1], rng.uniform(0, 2 * np.pi), bump(rng, params.bump_tilt)),
            params.hours,
            params.cloud_cover,
            'snapshot',
        )
    ]
    steps = np.arange(-params.grid_radius, params.grid_radius + 1e-9, params.spacing)
    for dy in steps:
        for dx in steps:
            p = home + np.array([dx, dy])
            if (dx == 0 and dy == 0) or not world.is_free(*p):
                continue
            pose = camera_pose(world.terrain, p[0], p[1], rng.uniform(0, 2 * np.pi), bump(rng, params.bump_tilt))
            frames.append(Frame(pose, params.hours, params.cloud_cover, 'grid'))
    return frames


def _compass(world: World, params: ScenarioParameters, rng: np.random.Generator) -> list[Frame]:
    place = snapshot_place(world, params)
    reference = camera_pose(world.terrain, place[0], place[1], rng.uniform(0, 2 * np.pi))
    reference_hours = params.hours if params.reference_hours is None else params.reference_hours
    frames = [Frame(reference, reference_hours, params.cloud_cover, 'reference')]
    for _ in range(params.count):
        # Any heading, and a tilt up to max_tilt about a random horizontal axis, at the same position.
        heading = Rotation.from_euler('z', rng.uniform(0, 2 * np.pi))
        axis_angle = rng.uniform(0, 2 * np.pi)
        tilt = np.radians(params.max_tilt) * np.sqrt(rng.uniform())
        tilt_rotation = Rotation.from_rotvec(tilt * np.array([np.cos(axis_angle), np.sin(axis_angle), 0.0]))
        frames.append(
            Frame(CameraPose(reference.position, tilt_rotation * heading), params.hours, params.cloud_cover, 'rotation')
        )
    for _ in range(params.count):
        for _ in range(100):
            direction = rng.uniform(0, 2 * np.pi)
            distance = params.max_translation * np.sqrt(rng.uniform(0.04, 1.0))
            p = place + distance * np.array([np.cos(direction), np.sin(direction)])
            if world.is_free(*p):
                break
        pose = camera_pose(world.terrain, p[0], p[1], rng.uniform(0, 2 * np.pi))
        frames.append(Frame(pose, params.hours, params.cloud_cover, 'translation'))
    return frames


def _skyline(world: World, params: ScenarioParameters, rng: np.random.Generator) -> list[Frame]:
    frames = []
    for name, hours in TIMES_OF_DAY.items():
        for clouds in (0.0, 0.6):
            for _ in range(params.count):
                p = _free_point(world, rng, YARD_RADIUS)
                pose = camera_pose(world.terrain, p[0], p[1], rng.uniform(0, 2 * np.pi))
                frames.append(Frame(pose, hours, clouds, name))
    return frames


#: Scenario parameters added after recordings were bundled, with the default that leaves those recordings as they were.
_LATER_PARAMETERS = {'wobble': 0.0, 'bump_tilt': 0.0, 'detour': 0.0, 'reference_hours': None}


def describe(name: str, world: World, params: ScenarioParameters, seed: int, frames: list[Frame]) -> dict:
    """Return what a recording should say about how it was made (stored in its metadata)."""
    return {
        'scenario': name,
        'world': world.style,
        'seed': seed,
        'world_seed': world.seed,
        # Parameters added later are recorded only where used, so that older recordings regenerate byte for byte.
        'parameters': {
            k: v
            for k, v in asdict(params).items()
            if k != 'extra' and not (k in _LATER_PARAMETERS and v == _LATER_PARAMETERS[k])
        },
        'frames': [{'label': f.label, 'hours': round(f.hours, 4), 'cloud_cover': f.cloud_cover} for f in frames],
        'synthetic': True,
        **({'real_skyline': world.backdrop.source} if world.backdrop is not None else {}),
    }
