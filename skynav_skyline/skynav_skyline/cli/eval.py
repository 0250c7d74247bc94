# SPDX-License-Identifier: Apache-2.0
"""Measure sky/ground segmentation against ground truth: classification rate per method, channels, world and time.

The classification rate of an exposure is the share of pixels inside the image circle that a method
labels as /ground_truth/mask does. Every method runs with the skyline node's parameters (the shipped
defaults, or --params), so what is measured is what the node does; the default method runs once more
without the structure steps (enclosed ground, ground ring; see skynav_skyline/structure.py) when the
parameters use them. Prints one table per world (the world or landscape named in the recording's
metadata; rows: method, channels and structure steps; columns: time of day), one over all worlds, and
the default method per world without and with the structure steps; saves a plot of the log UV / log
green histogram of sky and ground pixels with the learned separators.
"""

from __future__ import annotations

import argparse
import sys

from skynav_core.evaluation import Column, add_methods_argument, text_table

from ..segment import METHODS

HELP = 'classification rate per method, world and time of day'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav skyline eval`."""
    parser.add_argument('bags', nargs='+', metavar='BAG', help='recordings with /ground_truth/mask')
    parser.add_argument('--params', metavar='FILE', help='skyline node parameters (default: the shipped ones)')
    add_methods_argument(parser, METHODS)
    parser.add_argument(
        '--channels',
        nargs='+',
        default=['uv', 'uv-green'],
        choices=('uv', 'uv-green'),
        help='channel modes to compare (default both)',
    )
    parser.add_argument(
        '--plot',
        default='skyline_eval.png',
        metavar='FILE.png',
        help='where to save the histogram plot (default skyline_eval.png)',
    )


def run(args: argparse.Namespace) -> int:
    """Evaluate; return the exit code."""
    import math
    from dataclasses import replace
    from pathlib import Path

    from skynav_core.cli import CliError
    from skynav_core.evaluation import check_methods, check_recordings

    from ..parameters import colour_params, defaults, load_parameter_file, skyline_params

    check_methods(args.methods, METHODS)
    check_recordings(args.bags)
    plot = Path(args.plot)
    if not plot.parent.is_dir():
        raise CliError(f'{plot.parent}: no such directory')
    values = load_parameter_file(args.params) if args.params else defaults()
    configurations = {}
    default_method, default_channels = (str({**defaults(), **values}[name]) for name in ('method', 'channels'))
    for method in args.methods:
        for channels in args.channels:
            try:
                params = skyline_params({**values, 'method': method, 'channels': channels})
            except ValueError as exc:
                print(f'skynav skyline eval: skipping {method} {channels}: {exc}', file=sys.stderr)
                continue
            configurations[(method, channels, structure_label(params))] = params
            if (method, channels) == (default_method, default_channels) and structure_label(params) == 'on':
                configurations[(method, channels, 'off')] = replace(params, hole_margin=0.0, ring_share=math.inf)
    if not configurations:
        raise CliError('nothing to evaluate (no usable method and channel combination)')
    colour = colour_params(values)
    configurations[(colour.method, 'colour', structure_label(colour))] = colour
    rates, samples, synthetic = evaluate(args.bags, configurations)
    print(report(rates, values))
    if comparison := structure_report(rates):
        print(comparison)
    draw_histogram(plot, samples, values, synthetic)
    print(f'skynav skyline eval: saved the histogram plot to {plot}', file=sys.stderr)
    return 0


def structure_label(params) -> str:
    """Return whether settings use the structure steps: 'on' (either), 'off' (neither)."""
    return 'on' if params.fills_holes or params.cuts_rings else 'off'


def evaluate(paths, configurations):
    """Return per-frame rates {(method, channels, structure): [(world, time, rate)]}, pixel samples, synthetic?

    Configurations keyed with channels 'colour' run on colour frames only, as the node runs colour_method; the
    others run on every frame (a colour frame's blue plane standing in for UV).
    """
    import numpy as np
    from tqdm import tqdm

    from skynav_core.recording.bag import open_bag

    from ..classify import classification_rate
    from ..eval.dataset import count_frames, labelled_frames
    from ..features import extract_features
    from ..geometry import SkylineGeometry
    from ..segment import SkylineSegmenter

    rates: dict = {key: [] for key in configurations}
    rng = np.random.default_rng(0)
    samples = {'x': [], 'y': [], 'sky': []}
    synthetic = True
    segmenters: dict = {}
    total = sum(count_frames(path) for path in paths)
    with tqdm(total=total, unit='frame', desc='evaluating', file=sys.stderr, disable=None) as bar:
        for path in paths:
            with open_bag(path) as bag:
                synthetic &= 'skynav_sim' in bag.custom_data
            for frame in labelled_frames(path):
                circle = frame.camera.image_circle()
                for key, params in configurations.items():
                    colour = key[1] == 'colour'
                    if colour and frame.rgb is None:
                        continue
                    geometry_key = (frame.camera, key)
                    if geometry_key not in segmenters:
                        segmenters[geometry_key] = SkylineSegmenter(SkylineGeometry.from_camera(frame.camera), params)
                    segmenter = segmenters[geometry_key]
                    if colour:
                        mask = segmenter.segment_colour(frame.rgb)
                    else:
                        mask = segmenter.segment(frame.uv, frame.green, *frame.encoding)
                    rates[key].append((frame.world, frame.time, classification_rate(mask, frame.truth, circle)))
                features = extract_features(frame.uv, frame.green, *frame.encoding, circle)
                trusted = features.trusted(circle, True)
                pick = rng.random(trusted.shape) < 0.05
                chosen = trusted & pick
                samples['x'].append(features.x[chosen])
                samples['y'].append(features.y[chosen])
                samples['sky'].append(frame.truth[chosen] > 127)
                bar.update()
    return rates, {k: np.concatenate(v) if v else np.zeros(0) for k, v in samples.items()}, synthetic


def report(rates: dict, values: dict) -> str:
    """Return the tables of classification rates (%) as text."""
    import numpy as np

    from ..eval.dataset import TIME_LABELS

    rates = {key: frames for key, frames in rates.items() if frames}  # colour rows: colour frames only
    first = max(rates.values(), key=len)
    worlds = list(dict.fromkeys(world for world, _, _ in first))
    times = [t for t in (*TIME_LABELS, 'all') if any(time == t for _, time, _ in first)]
    lines = [
        f'classification rate (%) of {len(first)} exposures; default: {values.get("method", "?")} '
        f'{values.get("channels", "?")} (colour frames: {values.get("colour_method", "?")}, blue standing in for UV '
        'in the UV/green rows); structure: the structure steps (enclosed ground, ground ring)'
    ]
    for world in worlds:
        count = sum(1 for w, _, _ in first if w == world)
        rows = []
        for key, values_ in rates.items():
            mine = [(t, r) for w, t, r in values_ if w == world]
            if not mine:
                continue
            cells = [
                np.mean([r for tt, r in mine if tt == t]) if any(tt == t for tt, _ in mine) else np.nan for t in times
            ]
            rows.append(rate_row(key, cells, [r for _, r in mine]))
        lines += ['', f'{world} ({count} exposures)', rate_table(times, rows)]
    rows = [
        rate_row(key, [_mean([r for w, _, r in values_ if w == world]) for world in worlds], [r for _, _, r in values_])
        for key, values_ in rates.items()
    ]
    lines += ['', 'all worlds', rate_table(worlds, rows)]
    return '\n'.join(lines)


def _mean(values: list[float]) -> float:
    """Return the mean of some rates, NaN of none."""
    import math

    return sum(values) / len(values) if values else math.nan


def rate_row(key: tuple[str, str, str], cells: list[float], everything: list[float]) -> list:
    """Return a table row: method, channels, structure, the rates (%) of the cells, their mean and worst (%)."""
    import numpy as np

    method, channels, structure = key
    return [
        f'  {method}',
        channels,
        structure,
        *(100 * c for c in cells),
        100 * np.mean(everything),
        100 * np.min(everything),
    ]


def rate_table(titles: list[str], rows: list[list]) -> str:
    """Return a table of classification rates (%): method, channels, structure, one column per title, mean, worst."""
    columns = [
        Column('method', 20, align='<'),
        Column('channels', 10, align='<'),
        Column('structure', 10),
        *(Column(title, 10, '.2f') for title in [*titles, 'mean', 'worst']),
    ]
    return text_table(columns, rows, gap='', rule=False)


def structure_report(rates: dict) -> str:
    """Return the default method's rates (%) per world without and with the structure steps ('' if not both ran)."""
    import numpy as np

    pairs = {(m, c) for m, c, s in rates if s == 'off'} & {(m, c) for m, c, s in rates if s == 'on'}
    if not pairs:
        return ''
    method, channels = sorted(pairs)[0]
    off, on = rates[(method, channels, 'off')], rates[(method, channels, 'on')]
    worlds = list(dict.fromkeys(world for world, _, _ in off))
    rows = []
    for world in [*worlds, 'all worlds']:
        before = [r for w, _, r in off if world in (w, 'all worlds')]
        after = [r for w, _, r in on if world in (w, 'all worlds')]
        rows.append(
            [
                f'  {world}',
                len(before),
                100 * np.mean(before),
                100 * np.mean(after),
                100 * np.min(before),
                100 * np.min(after),
            ]
        )
    columns = [
        Column('world', 20, align='<'),
        Column('exposures', 10, 'd'),
        *(Column(title, 10, '.2f') for title in ('mean off', 'mean on', 'worst off', 'worst on')),
    ]
    return '\n'.join(
        ['', f'{method} {channels} without -> with the structure steps', text_table(columns, rows, gap='', rule=False)]
    )


def draw_histogram(path, samples: dict, values: dict, synthetic: bool) -> None:
    """Save the 2D histograms of normalised log UV / log green of sky and ground pixels, with the separators."""
    import math

    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np

    x, y, sky = samples['x'], samples['y'], samples['sky']
    figure, axis = plt.subplots(figsize=(8, 6.5), layout='constrained')
    if x.size:
        lo = np.percentile(np.concatenate([x, y]), 0.5)
        hi = max(np.percentile(np.concatenate([x, y]), 99.9), lo + 1)
        bins = np.linspace(lo, hi, 160)
        for mask, colour, label in ((sky, 'Blues', 'sky'), (~sky, 'Oranges', 'ground')):
            counts, xe, ye = np.histogram2d(x[mask], y[mask], bins=(bins, bins))
            axis.contourf(
                0.5 * (xe[1:] + xe[:-1]),
                0.5 * (ye[1:] + ye[:-1]),
                np.log1p(counts.T),
                levels=12,
                cmap=colour,
                alpha=0.6,
            )
            axis.plot([], [], 's', color=plt.get_cmap(colour)(0.7), label=f'{label} pixels')
        line_x = np.array([lo, hi])
        threshold, angle = float(values.get('threshold', math.nan)), math.radians(float(values.get('angle_deg', 0)))
        if not math.isnan(threshold) and abs(math.sin(angle)) > 1e-6:
            axis.plot(
                line_x,
                (threshold - math.cos(angle) * line_x) / math.sin(angle),
                'k-',
                linewidth=2,
                label=f'UV/green separator (a = {math.degrees(angle):.1f} deg)',
            )
        threshold_uv = float(values.get('threshold_uv', math.nan))
        if not math.isnan(threshold_uv):
            axis.axvline(threshold_uv, color='k', linestyle='--', linewidth=2, label='UV-only threshold')
        axis.set_xlim(lo, hi)
        axis.set_ylim(lo, hi)
    axis.set_xlabel("log UV (relative to the image's 90th percentile)")
    axis.set_ylabel("log green (relative to the image's 90th percentile)")
    axis.set_title(('Synthetic recordings: ' if synthetic else '') + 'sky and ground pixels (5 % sample)')
    axis.legend(loc='lower right')
    figure.savefig(path, dpi=90)
    plt.close(figure)
