# SPDX-License-Identifier: Apache-2.0
"""The chain over bundled synthetic recordings, step by step, with a readable summary: what `make demo` runs.

Each step prints the command it runs, so every result can be reproduced by hand:

  1. a map of the teach drive (`skynav map build`);
  2. the node graph over the repeat drive of the same route with that map (`skynav run --map`);
  3. what the nodes did, against the ground truth: the classification rate of every skyline mask
     and a contact sheet of inputs and masks; every place match, with a plot of the matches along
     the route; the compass's rotation errors and the home vectors' direction errors;
  3b. a colour camera: the skyline and SH nodes over the same drive seen by one synthetic colour fish-eye
     camera delivering JPEG (`skynav run`), its masks against the ground truth beside what the UV/green
     method makes of the same frames with blue standing in for UV;
  4. the whole story in the simulator: a scripted operator drives the simulated mower along a route
     while a Teach goal records its map (`skynav sim teach`);
  5. then the nodes drive the mower along that taught route on their own, from 0.3 m beside its start
     and at another time of day (`skynav sim follow`), with a plot;
  6. a small lawn: two lanes joined by point turns taught, then mowed again at another time of day, stopped half
     way and resumed where it stopped (`skynav eval mow`), with a plot of both swaths.

Outputs go to the folder given with --out (default out/demo); earlier outputs there are replaced.
Everything the demo shows is computed from synthetic recordings.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from skynav_core.names import (
    COMPASS_ORIENTATION,
    GROUND_TRUTH_POSE,
    HOME_VECTOR,
    LOCALIZATION_MATCH,
    SKYLINE_MASK,
    SKYLINE_SH,
)

HELP = 'run the chain over bundled synthetic recordings and summarise'
DEFAULT_TEACH = Path('bags/synthetic_garden_teach.mcap')
DEFAULT_REPEAT = Path('bags/synthetic_garden_repeat.mcap')
DEFAULT_COLOUR = Path('bags/synthetic_garden_colour_repeat.mcap')
TOLERANCE = 1.0  # m: a place match is correct when the snapshot lies this close to the true position
HOMING_NEAR = 0.5  # m: home vectors to a snapshot nearer than this are reported apart (cf. skynav eval homing)
HOMING_MISS = 30.0  # deg: a home vector off by more than this is a miss
SIM_SEED = 1  # the synthetic garden world the simulator's route is taught in
SIM_LENGTH = 8.0  # m of route taught in the simulator
LAWN_LANES, LAWN_LENGTH = 2, 2.5  # the demo's lawn: lanes of m, a cutting width apart (docs/lawn.md)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav demo`."""
    parser.add_argument('--out', type=Path, default=Path('out/demo'), metavar='DIR', help='output folder')
    parser.add_argument(
        '--teach',
        type=Path,
        default=DEFAULT_TEACH,
        metavar='BAG',
        help=f'teach drive to build the map from (default {DEFAULT_TEACH})',
    )
    parser.add_argument(
        '--repeat',
        type=Path,
        default=DEFAULT_REPEAT,
        metavar='BAG',
        help=f'repeat drive of the same route to run the graph over (default {DEFAULT_REPEAT})',
    )
    parser.add_argument(
        '--colour',
        type=Path,
        default=DEFAULT_COLOUR,
        metavar='BAG',
        help=f"a colour camera's recording to run the skyline over (default {DEFAULT_COLOUR})",
    )


def step(title: str, command: list[str]) -> None:
    """Print a step's title and command, run it (its output shown), and stop the demo if it fails."""
    from . import CliError

    print(f'\n== {title}\n$ {" ".join(command)}', flush=True)
    result = subprocess.run([sys.executable, '-m', 'skynav_bringup.cli', *command[1:]])
    if result.returncode != 0:
        raise CliError(f'step failed: {" ".join(command)}')


def run(args: argparse.Namespace) -> int:
    """Run the demo; return the exit code."""
    from . import CliError

    for recording in (args.teach, args.repeat, args.colour):
        if not recording.is_file():
            raise CliError(f'{recording}: no such recording (run the demo from the repository root)')
    args.out.mkdir(parents=True, exist_ok=True)
    map_file, run_bag = args.out / f'{args.teach.stem}.db', args.out / 'repeat_run.mcap'
    run_bag.unlink(missing_ok=True)
    step(
        f'1. a map of the synthetic teach drive {args.teach.name}',
        ['skynav', 'map', 'build', str(args.teach), '--out', str(map_file), '--overwrite'],
    )
    step(
        f'2. the node graph over the synthetic repeat drive {args.repeat.name}, with that map',
        ['skynav', 'run', str(args.repeat), '--map', str(map_file), '--out', str(run_bag)],
    )
    print('\n== 3. what the nodes did, against the ground truth of the recordings')
    rates = skyline_summary(args.repeat, run_bag, args.out / 'skyline_sheet.png')
    poses = ground_truth_poses(args.repeat)
    localization_summary(args.repeat, poses, run_bag, map_file, args.out / 'localization_matches.png')
    navigation_summary(poses, run_bag, map_file)
    colour_run = args.out / 'colour_run.mcap'
    colour_run.unlink(missing_ok=True)
    step(
        f'3b. a colour camera: the node graph over the synthetic colour recording {args.colour.name} (JPEG frames)',
        ['skynav', 'run', str(args.colour), '--out', str(colour_run)],
    )
    rates += skyline_summary(args.colour, colour_run, args.out / 'colour_skyline_sheet.png', compare_learned=True)
    taught = args.out / 'sim_teach'
    step(
        f'4. the simulator: a scripted operator drives a {SIM_LENGTH:g} m route while a Teach goal records its map',
        ['skynav', 'sim', 'teach', '--world', 'garden', '--seed', str(SIM_SEED), '--length', f'{SIM_LENGTH:g}']
        + ['--time', 'forenoon', '--out', str(taught)],
    )
    step(
        '5. the nodes drive the mower along the taught route, from 0.3 m beside its start, in the morning',
        ['skynav', 'sim', 'follow', str(taught / 'teach.yaml'), '--map', str(taught / 'teach.db')]
        + ['--offset', '0.3', '--time', 'morning', '--out', str(args.out)],
    )
    step(
        '6. a lawn: two lanes with point turns taught, then mowed again in the morning, stopped half way and resumed',
        ['skynav', 'eval', 'mow', '--worlds', 'garden', '--seeds', str(SIM_SEED), '--lanes', str(LAWN_LANES)]
        + ['--length', f'{LAWN_LENGTH:g}', '--out', str(args.out / 'lawn')],
    )
    print(f'\nskynav demo: done; outputs in {args.out}/ (all from synthetic recordings)')
    return 0 if rates else 1


def skyline_summary(recording: Path, run_bag: Path, sheet: Path, compare_learned: bool = False) -> list[float]:
    """Print the classification rate of every mask against ground truth, draw a contact sheet; return the rates.

    With `compare_learned`, a colour recording's frames are also segmented by the UV/green path with blue standing
    in for UV: by its thresholds learned on synthetic UV/green recordings alone, and with its fit check.
    """
    import math

    import numpy as np

    from skynav_core.images import image_to_array, stamp_ns
    from skynav_core.recording.bag import open_bag
    from skynav_skyline.classify import classification_rate
    from skynav_skyline.eval.dataset import labelled_frames
    from skynav_skyline.geometry import SkylineGeometry
    from skynav_skyline.parameters import defaults, skyline_params
    from skynav_skyline.segment import SkylineSegmenter

    frames = list(labelled_frames(recording))
    masks = {}
    with open_bag(run_bag) as bag:
        for raw in bag.messages([SKYLINE_MASK]):
            message = bag.deserialize(raw)
            masks[stamp_ns(message.header)] = image_to_array(message)
    camera = frames[0].camera  # the synthetic recordings carry camera info
    circle = camera.image_circle()
    rates = [classification_rate(masks[f.stamp], f.truth, circle) if f.stamp in masks else float('nan') for f in frames]
    colour = frames[0].rgb is not None
    print(
        f'\nskyline masks against ground truth{" (a colour camera)" if colour else ""}: {len(masks)} masks for '
        f'{len(frames)} frames (classification rate %, frame by frame)'
    )
    for row in range(0, len(rates), 10):
        print(
            f'  frames {row:3d}-{min(row + 9, len(rates) - 1):3d}: '
            + ' '.join(f'{100 * r:5.1f}' for r in rates[row : row + 10])
        )
    valid = [r for r in rates if r == r]
    print(
        f'  mean {100 * np.mean(valid):.2f} %, worst {100 * min(valid):.2f} % '
        f'(frame {int(np.nanargmin(rates))}); frames without a mask: {len(frames) - len(masks)}'
    )
    if compare_learned and colour:
        geometry = SkylineGeometry.from_camera(camera)
        for label, changes in (
            ('its learned thresholds alone', {'max_disagreement': math.inf}),
            ('with its fit check (the default)', {}),
        ):
            segmenter = SkylineSegmenter(geometry, skyline_params({**defaults(), **changes}))
            blue = [classification_rate(segmenter.segment(f.uv, f.green, *f.encoding), f.truth, circle) for f in frames]
            print(
                f'  the same frames by the UV/green path ({defaults()["method"]}), blue for UV, {label}: '
                f'mean {100 * np.mean(blue):.2f} %, worst {100 * min(blue):.2f} %'
            )
    draw_sheet(
        sheet,
        [
            (i, frames[i], masks.get(frames[i].stamp), rates[i])
            for i in np.linspace(0, len(frames) - 1, 4).round().astype(int)
        ],
        circle,
    )
    print(f'  contact sheet: {sheet}')
    return valid


def draw_sheet(path: Path, frames: list, circle) -> None:
    """Draw the inputs (UV and green, or the colour frame), the node's mask and its disagreement with ground truth."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np

    from skynav_core.colour import LINEAR_FULL_SCALE, linear_to_srgb8

    figure, axes = plt.subplots(len(frames), 4, figsize=(13, 3.2 * len(frames)), layout='constrained', squeeze=False)
    for row, (index, frame, mask, rate) in enumerate(frames):
        truth = frame.truth
        error = np.zeros(truth.shape + (3,))
        if mask is not None:
            error[(mask > 0) & (truth == 0)] = (0.9, 0.1, 0.1)
            error[(mask == 0) & (truth > 0)] = (0.1, 0.3, 0.9)
            error[(mask > 0) == (truth > 0)] = np.where(truth[(mask > 0) == (truth > 0)][:, None] > 0, 0.85, 0.25)
        error[~circle] = 0
        inputs = (
            [(frame.uv, 'UV input'), (frame.green, 'green input')]
            if frame.rgb is None
            else [(linear_to_srgb8(frame.rgb / LINEAR_FULL_SCALE), 'colour input (sRGB)'), (frame.uv, 'its blue')]
        )
        panels = [
            *inputs,
            (mask if mask is not None else np.zeros_like(truth), SKYLINE_MASK),
            (error, f'vs ground truth: {100 * rate:.1f} % right\nred: false sky, blue: false ground'),
        ]
        for column, (image, title) in enumerate(panels):
            axis = axes[row, column]
            axis.imshow(image, cmap='gray' if image.ndim == 2 else None)
            axis.set_title(f'frame {index}: {title}' if column == 0 else title, fontsize=9)
            axis.set_xticks([])
            axis.set_yticks([])
    figure.suptitle('skynav demo on a synthetic recording: the skyline node')
    figure.savefig(path, dpi=70)
    plt.close(figure)


def ground_truth_poses(recording: Path) -> dict:
    """Return {stamp (ns): (position (3,) m, quaternion (x, y, z, w))} of camera_link in map from /ground_truth/pose."""
    import numpy as np

    from skynav_core.images import stamp_ns
    from skynav_core.recording.bag import open_bag

    poses = {}
    with open_bag(recording) as bag:
        for raw in bag.messages([GROUND_TRUTH_POSE]):
            message = bag.deserialize(raw)
            p, q = message.pose.position, message.pose.orientation
            poses[stamp_ns(message.header)] = (np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w]))
    return poses


def localization_summary(recording: Path, poses: dict, run_bag: Path, map_file: Path, plot: Path) -> None:
    """Print the place matches of the run against the true positions, and plot them along the route."""
    import numpy as np

    from skynav_core.images import stamp_ns
    from skynav_core.maps import MapStore
    from skynav_core.recording.bag import open_bag
    from skynav_localize.eval.evaluation import correct_matches, plot_matches_along_route

    with open_bag(run_bag) as bag:
        matches = [bag.deserialize(raw) for raw in bag.messages([LOCALIZATION_MATCH])]
    store = MapStore.open(map_file)
    snapshots = store.positions()
    stamps = [stamp_ns(m.header) for m in matches]
    query = np.stack([poses[s][0] for s in stamps])
    matched = np.array([m.index for m in matches])
    accepted = np.array([m.accepted for m in matches])
    correct = correct_matches(matched, query, snapshots, TOLERANCE)
    error = np.linalg.norm(snapshots[np.maximum(matched, 0)] - query, axis=1)
    print(
        f'\nplace matches against the map {store.name!r} ({len(store)} snapshots): {len(matches)} views, '
        f'{int(accepted.sum())} accepted, {int((accepted & correct).sum())} of them within {TOLERANCE:g} m '
        f'of the true place (precision {100 * (accepted & correct).sum() / max(accepted.sum(), 1):.0f} %, '
        f'recall {100 * (accepted & correct).sum() / len(matches):.0f} %)'
    )
    print(
        f'  distance from the true place to the matched snapshot: median {np.median(error):.2f} m, '
        f'largest {error.max():.2f} m'
    )
    print('  frame: matched snapshot (distance to the true place in m; * = not accepted)')
    cells = [
        f'{k:3d}:{i:3d} ({e:4.2f}){" " if a else "*"}' for k, (i, e, a) in enumerate(zip(matched, error, accepted))
    ]
    for row in range(0, len(cells), 6):
        print('  ' + '  '.join(cells[row : row + 6]))
    plot_matches_along_route(
        snapshots,
        query,
        matched,
        correct,
        accepted,
        f'skynav demo: {recording.stem} against the map of the teach drive',
        True,
        plot,
    )
    store.close()
    print(f'  plot: {plot}')


def navigation_summary(poses: dict, run_bag: Path, map_file: Path) -> None:
    """Print the compass's rotation errors and the home vectors' direction errors against ground truth `poses`."""
    import numpy as np

    from skynav_core.images import stamp_ns
    from skynav_core.maps import MapStore
    from skynav_core.recording.bag import open_bag
    from skynav_core.rotations import home_direction, relative_rotation, rotation_angle

    with open_bag(run_bag) as bag:
        compass = [bag.deserialize(raw) for raw in bag.messages([COMPASS_ORIENTATION])]
        homing = [bag.deserialize(raw) for raw in bag.messages([HOME_VECTOR])]
        views = sum(1 for _ in bag.messages([SKYLINE_SH]))
    with MapStore.open(map_file) as store:
        snapshots = store.poses()

    def percentiles(values) -> str:
        return (
            (
                f'median {np.median(values):.1f} deg, 90th percentile {np.percentile(values, 90):.1f} deg, '
                f'largest {np.max(values):.1f} deg'
            )
            if len(values)
            else 'none'
        )

    rotation_errors = []
    for estimate in compass:
        _, current = poses[stamp_ns(estimate.header)]
        truth = relative_rotation(snapshots[estimate.snapshot_index, 3:], current)  # d_snapshot = R d_current
        q = estimate.rotation
        rotation_errors.append(np.degrees(rotation_angle(truth, [q.x, q.y, q.z, q.w])))
    print(
        f'\ncompass (/compass/orientation) against the matched snapshot: {len(compass)} estimates; '
        f'3D rotation error {percentiles(rotation_errors)}'
    )
    direction_error_list, distance_list, residual_list = [], [], []
    for vector in homing:
        position, current = poses[stamp_ns(vector.header)]
        offset = snapshots[vector.snapshot_index, :3] - position
        truth = home_direction(snapshots[vector.snapshot_index, :3], position, current)  # in the current camera_link
        direction = np.array([vector.direction.x, vector.direction.y, vector.direction.z])
        direction_error_list.append(np.degrees(np.arccos(np.clip(direction @ truth, -1.0, 1.0))))
        distance_list.append(np.linalg.norm(offset))
        residual_list.append(vector.residual)
    if not homing:
        print('home vectors (/homing/home_vector): none')
        return
    direction_errors = np.array(direction_error_list)
    distances = np.array(distance_list)
    residuals = np.array(residual_list)
    far = distances >= HOMING_NEAR
    print(
        f'home vectors (/homing/home_vector) to the snapshot ahead: {len(homing)} vectors, '
        f'{np.min(distances):.1f}-{np.max(distances):.1f} m from it; direction error'
    )
    print(f'  {far.sum():3d} at {HOMING_NEAR:g} m or more: {percentiles(direction_errors[far])}')
    print(f"  {(~far).sum():3d} nearer (little parallax; at the route's end): {percentiles(direction_errors[~far])}")
    print(
        f'  {(direction_errors > HOMING_MISS).sum()} of the {len(homing)} off by more than {HOMING_MISS:g} deg; '
        f'{views - len(homing)} of the {views} views got none (the views did not determine the direction, or no '
        'snapshot was matched yet)'
    )
    miss = direction_errors > HOMING_MISS
    if miss.any() and (~miss).any():
        print(
            f'  the residual (1 - confidence) flags the misses: median {np.median(residuals[~miss]):.2f} where the '
            f'error is under {HOMING_MISS:g} deg ({(~miss).sum()}), {np.median(residuals[miss]):.2f} where it is '
            f'over ({miss.sum()})'
        )
