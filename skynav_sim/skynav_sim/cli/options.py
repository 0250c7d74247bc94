# SPDX-License-Identifier: Apache-2.0
"""Arguments shared by `skynav sim bag` and `skynav sim preview` (world, scenario, camera, daylight), by
`skynav eval follow|home` (worlds, seeds, times, clouds) and by the closed-loop commands (the mower's base and its
camera's mount)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the closed loop loads rclpy: only when a command runs
    from ..closed_loop import Base

DEFAULT_DISTORTION = '0.015,-0.002,0.0,0.0'
MAX_FOV = 220.0  # degrees (docs/interfaces.md)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the scenario, world, camera and daylight options."""
    from ..names import SCENARIOS, WORLDS

    parser.add_argument('scenario', metavar='SCENARIO', choices=SCENARIOS, help=f'one of {", ".join(SCENARIOS)}')
    parser.add_argument(
        '--world',
        choices=WORLDS,
        default='garden',
        help='synthetic world style, or a real Stellarium landscape (fetched on first use) under the '
        'synthetic sky (default garden)',
    )
    parser.add_argument('--seed', type=int, default=0, help='world and scenario seed (default 0)')
    camera = parser.add_argument_group('camera')
    camera.add_argument('--size', default='640x480', metavar='WxH', help='image size in pixels (default 640x480)')
    camera.add_argument(
        '--fov',
        type=float,
        default=200.0,
        metavar='DEG',
        help=f'field of view of the image circle, up to {MAX_FOV:g} degrees (default 200)',
    )
    camera.add_argument(
        '--distortion',
        default=DEFAULT_DISTORTION,
        metavar='K1,K2,K3,K4',
        help=f'Kannala-Brandt coefficients D (default {DEFAULT_DISTORTION})',
    )
    add_camera_argument(camera)
    camera.add_argument(
        '--encoding',
        default=None,
        metavar='ENCODING',
        help='image encoding: mono8, mono16 or 32FC1 of the UV/green pair (default mono16); rgb8, bgr8, rgba8, bgra8, '
        'bayer_rggb8, bayer_bggr8, bayer_gbrg8, bayer_grbg8 or their 16-bit forms of a colour camera (default rgb8; '
        '8-bit sRGB, 16-bit linear); rgb8 or rgb16 (PNG only) of a colour-compressed one (default rgb8)',
    )
    camera.add_argument(
        '--codec',
        choices=('jpeg', 'png'),
        default='jpeg',
        help="colour-compressed: image_transport's compressed format (default jpeg)",
    )
    camera.add_argument(
        '--jpeg-quality',
        type=int,
        default=None,
        metavar='Q',
        help='colour-compressed JPEG: quality 1-100 (default 95, as image_transport)',
    )
    light = parser.add_argument_group('daylight')
    light.add_argument(
        '--time',
        default='forenoon',
        metavar='TIME',
        help='local solar time: hours (0-24) or dawn, sunrise, morning, forenoon, noon',
    )
    light.add_argument('--clouds', type=float, default=0.0, metavar='COVER', help='cloud cover 0-1 (default 0)')
    drive = parser.add_argument_group('teach and repeat drives')
    drive.add_argument('--route-seed', type=int, default=0, help='which route through the world (default 0)')
    drive.add_argument('--length', type=float, default=20.0, metavar='M', help='route length (default 20 m)')
    drive.add_argument('--speed', type=float, default=0.5, metavar='M/S', help='speed; frames at 10 Hz (default 0.5)')
    drive.add_argument('--offset', type=float, default=0.0, metavar='M', help='sideways shift, left positive')
    drive.add_argument('--shake', type=float, default=0.0, metavar='DEG', help='extra roll/pitch rms')
    drive.add_argument(
        '--wobble', type=float, default=0.0, metavar='DEG', help='heading deviation from the route, rms (repeat drives)'
    )
    drive.add_argument(
        '--detour',
        type=float,
        default=0.0,
        metavar='M',
        help='repeat drives: leave the route in its middle for a loop reaching M m from it, then '
        'come back and drive on (default 0: no detour)',
    )
    grid = parser.add_argument_group('homing grid and compass set')
    grid.add_argument('--spacing', type=float, default=0.5, metavar='M', help='homing grid spacing (default 0.5)')
    grid.add_argument('--grid-radius', type=float, default=3.0, metavar='M', help='homing grid half side (3)')
    grid.add_argument(
        '--count',
        type=int,
        default=40,
        help='compass views of each kind / skyline places per time and cloud condition (default 40)',
    )
    grid.add_argument('--max-tilt', type=float, default=30.0, metavar='DEG', help='compass tilt limit (30)')
    grid.add_argument('--max-translation', type=float, default=0.5, metavar='M', help='compass translation limit (0.5)')
    grid.add_argument(
        '--reference-time',
        default=None,
        metavar='TIME',
        help="compass: the reference frame's time of day (as --time; default: --time)",
    )
    grid.add_argument(
        '--bump-tilt',
        type=float,
        default=0.0,
        metavar='DEG',
        help='homing: each place sits on a bump that tilts the camera up to DEG more (default 0)',
    )


#: The UV/green pair's default encoding (today's recordings) and a colour camera's.
DEFAULT_ENCODING = {'uv-green': 'mono16', 'colour': 'rgb8', 'colour-compressed': 'rgb8'}


def add_camera_argument(parser) -> None:
    """Add --camera: the UV/green pair (default), or one colour camera delivering raw or compressed frames."""
    parser.add_argument(
        '--camera',
        choices=('uv-green', 'colour', 'colour-compressed'),
        default='uv-green',
        help='the UV/green pair on /camera/{uv,green}/image_raw (default); one colour camera on /camera/image_raw; '
        'or one on /camera/image_raw/compressed (JPEG at quality 95 unless --codec or --jpeg-quality, where a '
        'command has them, say otherwise), all synthetic',
    )


def camera_output(args: argparse.Namespace):
    """Return the CameraOutput the options --camera, --encoding, --codec and --jpeg-quality describe (a command
    without them: its --camera with the defaults); raise ValueError for an impossible one."""
    from ..colour_sensor import DEFAULT_JPEG_QUALITY
    from ..recording import CameraOutput

    kind = getattr(args, 'camera', 'uv-green')
    encoding = getattr(args, 'encoding', None) or DEFAULT_ENCODING[kind]
    quality = getattr(args, 'jpeg_quality', None)
    if quality is not None and not (kind == 'colour-compressed' and getattr(args, 'codec', 'jpeg') == 'jpeg'):
        raise ValueError('--jpeg-quality is for --camera colour-compressed with --codec jpeg')
    return CameraOutput(
        kind, encoding, getattr(args, 'codec', 'jpeg'), DEFAULT_JPEG_QUALITY if quality is None else quality
    )


def camera(args: argparse.Namespace):
    """Return the camera the options describe; raise ValueError for an impossible one."""
    import numpy as np

    from skynav_core.camera import EquidistantCamera

    try:
        width, height = (int(v) for v in args.size.lower().split('x'))
    except ValueError:
        raise ValueError(f'--size {args.size!r} is not WIDTHxHEIGHT, e.g. 640x480') from None
    if not (16 <= width <= 8192 and 16 <= height <= 8192):
        raise ValueError(f'--size {args.size} is out of range (16 to 8192 pixels a side)')
    if not 0 < args.fov <= MAX_FOV:
        raise ValueError(
            f'--fov {args.fov:g} is impossible: a fish-eye sees more than 0 and at most {MAX_FOV:g} degrees'
        )
    try:
        k = tuple(float(v) for v in args.distortion.split(','))
    except ValueError:
        k = ()
    if len(k) != 4:
        raise ValueError(f'--distortion {args.distortion!r} is not four numbers k1,k2,k3,k4')
    half = np.radians(args.fov) / 2
    theta = np.linspace(0, half, 512)
    probe = EquidistantCamera(width, height, 1.0, 1.0, 0.0, 0.0, k)
    if np.any(np.diff(probe.distort(theta)) <= 0):
        raise ValueError(
            f'--distortion {args.distortion} folds the image: r(theta) must grow up to {args.fov / 2:g} degrees'
        )
    return EquidistantCamera.for_field_of_view(width, height, np.radians(args.fov), k)


def scenario(args: argparse.Namespace):
    """Return (world, frames, description) of the options; raise ValueError for impossible ones."""
    from ..scenarios import ScenarioParameters, build, describe
    from ..sky import parse_time
    from ..world import generate

    if not 0 <= args.clouds <= 1:
        raise ValueError(f'--clouds {args.clouds} is not a cover between 0 and 1')
    for name in ('length', 'speed', 'spacing', 'grid_radius', 'max_translation'):
        if getattr(args, name) <= 0:
            raise ValueError(f'--{name.replace("_", "-")} must be positive')
    if args.count < 1:
        raise ValueError('--count must be at least 1')
    if args.detour < 0:
        raise ValueError('--detour must be 0 (none) or positive')
    for name in ('max_tilt', 'bump_tilt'):
        if not 0 <= getattr(args, name) <= 90:
            raise ValueError(f'--{name.replace("_", "-")} must be between 0 and 90 degrees')
    params = ScenarioParameters(
        hours=parse_time(args.time),
        cloud_cover=args.clouds,
        route_seed=args.route_seed,
        route_length=args.length,
        speed=args.speed,
        offset=args.offset,
        shake=args.shake,
        wobble=args.wobble,
        spacing=args.spacing,
        grid_radius=args.grid_radius,
        count=args.count,
        max_tilt=args.max_tilt,
        max_translation=args.max_translation,
        bump_tilt=args.bump_tilt,
        detour=args.detour,
        reference_hours=None if getattr(args, 'reference_time', None) is None else parse_time(args.reference_time),
    )
    world = generate(args.world, args.seed)
    frames = build(args.scenario, world, params, args.seed)
    return world, frames, describe(args.scenario, world, params, args.seed, frames)


def add_closed_loop_arguments(parser: argparse.ArgumentParser, seeds: tuple[int, ...], what: str) -> None:
    """Add the options of a closed-loop evaluation: world styles, seeds, the two times of day and the cloud cover."""
    from ..names import STYLES

    parser.add_argument(
        '--worlds', nargs='+', default=list(STYLES), metavar='STYLE', help=f'world styles (default {" ".join(STYLES)})'
    )
    parser.add_argument(
        '--seeds',
        nargs='+',
        type=int,
        default=list(seeds),
        metavar='N',
        help=f'world seeds (default {" ".join(map(str, seeds))})',
    )
    parser.add_argument('--teach-time', default='forenoon', metavar='TIME', help='time of the teach (forenoon)')
    parser.add_argument('--time', default='morning', metavar='TIME', help=f'time of the {what} (default morning)')
    parser.add_argument(
        '--clouds', type=float, default=0.5, metavar='COVER', help=f'cloud cover of the {what}, 0-1 (default 0.5)'
    )
    parser.add_argument('--size', default='320x240', metavar='WxH', help='camera image size (default 320x240)')
    add_camera_argument(parser)
    add_odometry_argument(parser)
    add_mount_arguments(parser)


def add_base_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the simulated mower's base: --slip, --odometry-noise and --no-odom; its camera's mount."""
    parser.add_argument('--slip', type=float, default=0.05, help="the mower's wheel slip, a share (default 0.05)")
    parser.add_argument(
        '--odometry-noise', type=float, default=0.02, help="the mower's odometry noise, a share (default 0.02)"
    )
    add_camera_argument(parser)
    add_odometry_argument(parser)
    add_mount_arguments(parser)


def add_odometry_argument(parser: argparse.ArgumentParser) -> None:
    """Add --no-odom: the simulated mower has no wheel odometry."""
    parser.add_argument(
        '--no-odom',
        action='store_true',
        help='the mower publishes no /odom, as a robot without wheel odometry (teaching then spaces snapshots by '
        "view change and takes the route's shape from the operator's velocity commands)",
    )


#: How the graph learns of the camera's mount on the simulated mower (closed_loop.Base.declare_mount).
MOUNT_DECLARATIONS = ('tf_static', 'parameter', 'none')


def add_mount_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the simulated robot's own options: --mount-rpy, the camera's mount on the mower, --declare-mount, how the
    graph learns it, and --namespace, the graph's."""
    from skynav_core.cli import add_namespace

    add_namespace(parser, 'the simulated graph (its nodes, actions and /clock); e.g. two simulations on one domain')
    parser.add_argument(
        '--mount-rpy',
        type=float,
        nargs=3,
        default=None,
        metavar=('ROLL', 'PITCH', 'YAW'),
        help="the camera turned on the mower: camera_link in base_link, degrees about the fixed axes X, Y, Z (REP-103's"
        ' RPY; default 0 0 0)',
    )
    parser.add_argument(
        '--declare-mount',
        choices=MOUNT_DECLARATIONS,
        default=MOUNT_DECLARATIONS[0],
        help='how the graph learns of the mount: the mower publishes it on /tf_static (default), the parameter '
        "camera_mount_rpy_deg, or none (the nodes take the camera to be on the base's axes: what the mount is worth)",
    )


def describe_mount(base: Base) -> str:
    """Return the words a closed-loop command's header adds for a mounted camera ('' for one on the base's axes)."""
    if not any(base.mount_rpy_deg) and base.declare_mount == 'tf_static':
        return ''
    roll, pitch, yaw = base.mount_rpy_deg
    told = {'tf_static': 'on /tf_static', 'parameter': 'by camera_mount_rpy_deg', 'none': 'NOT declared'}
    return f', the camera mounted roll {roll:g}, pitch {pitch:g}, yaw {yaw:g} deg ({told[base.declare_mount]})'


def base(args: argparse.Namespace) -> Base:
    """Return the simulated mower's base of the arguments (the evaluations have no --slip or --odometry-noise, `skynav
    sim home` no --no-odom); CliError (exit 2) for a mount that is not finite."""
    import math

    from skynav_core.cli import CliError

    from ..closed_loop import Base

    mount = tuple(getattr(args, 'mount_rpy', None) or Base.mount_rpy_deg)
    if not all(math.isfinite(v) for v in mount):
        raise CliError('--mount-rpy must be three finite angles in degrees', exit_code=2)
    return Base(
        getattr(args, 'slip', Base.slip),
        getattr(args, 'odometry_noise', Base.odometry_noise),
        odometry=not getattr(args, 'no_odom', False),
        mount_rpy_deg=(mount[0], mount[1], mount[2]),
        declare_mount=getattr(args, 'declare_mount', Base.declare_mount),
        camera=camera_output(args),
        namespace=getattr(args, 'namespace', ''),
    )


def add_start_argument(parser: argparse.ArgumentParser) -> None:
    """Add --from, the FollowRoute goal's start_index."""
    parser.add_argument(
        '--from',
        dest='start_index',
        type=int,
        default=0,
        choices=(0, -1),
        help="the goal's start snapshot (default 0: the mower stands at the route's start and the goal says so, as "
        'when it leaves its dock; -1: wherever localization places it)',
    )


def check_closed_loop_arguments(args: argparse.Namespace) -> tuple[float, float]:
    """Raise CliError (exit 2) for unknown worlds, no seeds, a cloud cover or a time that is malformed; return the
    teach's and the run's time of day (h)."""
    from skynav_core.cli import CliError
    from skynav_core.evaluation import check_positive

    from ..names import STYLES
    from ..sky import parse_time

    if unknown := [w for w in args.worlds if w not in STYLES]:
        raise CliError(f'unknown world {", ".join(unknown)} (one of {", ".join(STYLES)})', exit_code=2)
    check_positive(len(args.seeds), '--seeds')
    if not 0 <= args.clouds <= 1:
        raise CliError('--clouds must be a cover within 0..1', exit_code=2)
    try:
        return parse_time(args.teach_time), parse_time(args.time)
    except ValueError as exc:
        raise CliError(str(exc), exit_code=2) from None


def closed_loop_camera(args: argparse.Namespace):
    """Return the camera of a closed-loop evaluation (--size, the default field of view and distortion); raise
    CliError (exit 2) for a malformed size."""
    from skynav_core.cli import CliError

    try:
        return camera(argparse.Namespace(size=args.size, fov=200.0, distortion=DEFAULT_DISTORTION))
    except ValueError as exc:
        raise CliError(str(exc), exit_code=2) from None
