# SPDX-License-Identifier: Apache-2.0
"""Bundled bags with flipped bytes: every bag-reading command exits 0 with unchanged output, or 1 with one line.

Each seed flips 1-3 bytes of a bundled bag (zstd chunks, as bundled) or of an
uncompressed copy, then runs one bag-reading command on it in process (the
`skynav` main, as the console script runs it) and `skynav info`. A run that
exits 0 must print what the intact bag gives (computed only when needed);
any other outcome must be exit code 1 and one line of error. A traceback
fails the test.
"""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import mcap.reader
import numpy as np
import pytest

from skynav_core.names import UV_CAMERA_INFO
from skynav_core.recording.bag import BagWriter, open_bag
from skynav_testing import BAGS, one_line_error, run_skynav

COMPASS = BAGS / 'synthetic_garden_compass.mcap'
HOMING = BAGS / 'synthetic_park_homing.mcap'
SEEDS = range(30)  # per file kind: 30 zstd-compressed and 30 uncompressed corrupted files
# The bag-reading commands, taking turns over the seeds: (name, bag it reads, arguments; {bag}, {out}, {map}).
COMMANDS = [
    ('run', COMPASS, ['run', '{bag}', '--out', '{out}/run.mcap', '--nodes', 'skyline']),
    ('map build', COMPASS, ['map', 'build', '{bag}', '--out', '{out}/built.db']),
    ('replay', COMPASS, ['replay', '{bag}', '--rate', '0', '--topics', UV_CAMERA_INFO]),
    (
        'eval localization',
        COMPASS,
        ['eval', 'localization', '{bag}', '--map', '{map}', '--methods', 'amplitude', '--plots', '{out}/plots'],
    ),
    ('eval compass', COMPASS, ['eval', 'compass', '{bag}', '--methods', 'fft-masked', '--plots', '{out}/plots']),
    ('eval homing', HOMING, ['eval', 'homing', '{bag}', '--methods', '3d-warping', '--plots', '{out}/plots']),
]


def flip(source: Path, target: Path, seed: int) -> list[int]:
    """Write `source` to `target` with 1-3 bytes changed (offsets drawn with `seed`); return the offsets."""
    data = bytearray(source.read_bytes())
    rng = np.random.default_rng(seed)
    offsets = sorted(int(o) for o in rng.integers(0, len(data), seed % 3 + 1))
    for offset in offsets:
        data[offset] ^= int(rng.integers(1, 256))
    target.write_bytes(bytes(data))
    return offsets


@pytest.fixture(scope='module')
def workspace(tmp_path_factory, skynav_main):
    """Return a folder with uncompressed copies of the bags and a small map (built from the intact compass bag)."""
    root = tmp_path_factory.mktemp('fuzz')
    for source in (COMPASS, HOMING):
        with open_bag(source) as bag, BagWriter(root / f'plain_{source.name}', compress=False) as writer:
            writer.set_custom_data('skynav_sim', bag.custom_data['skynav_sim'])
            for topic in bag.topics.values():
                writer.add_topic(topic.name, topic.msgtype, topic.offered_qos)
            for message in bag.messages():
                writer.write(message.topic, message.log_time, message.data)
    code, _, err = skynav_main(['map', 'build', str(COMPASS), '--out', str(root / 'compass.db')])
    assert code == 0, err
    return root


@cache
def reference(call, arguments: tuple[str, ...]) -> tuple[int, str]:
    """Return (exit code, stdout) of a command on the intact bag: what an undamaged run must print."""
    code, out, _ = call(list(arguments))
    return code, out


def fill(arguments: list[str], bag: Path, out: Path, map_path: Path) -> list[str]:
    """Return the command's arguments with its bag, output folder and map filled in."""
    return [a.format(bag=bag, out=out, map=map_path) for a in arguments]


@pytest.mark.parametrize('compressed', [True, False], ids=['zstd', 'uncompressed'])
def test_flipped_bytes_give_the_same_result_or_one_line(workspace, tmp_path, compressed, skynav_main):
    outcomes = {'refused': 0, 'unchanged': 0}
    for seed in SEEDS:
        name, source, arguments = COMMANDS[seed % len(COMMANDS)]
        intact = source if compressed else workspace / f'plain_{source.name}'
        broken = tmp_path / f'seed{seed}' / intact.name
        broken.parent.mkdir()
        offsets = flip(intact, broken, seed)
        for command, args in ((name, arguments), ('info', ['info', '{bag}'])):
            code, out, err = skynav_main(fill(args, broken, broken.parent, workspace / 'compass.db'))
            where = f'seed {seed}, bytes {offsets} of {intact.name}, skynav {command}'
            assert 'Traceback' not in out + err, where
            if code == 0:
                clean = tmp_path / f'clean{seed}'
                clean.mkdir(exist_ok=True)
                expected = reference(skynav_main, tuple(fill(args, intact, clean, workspace / 'compass.db')))
                assert expected[0] == 0 and out.replace(str(broken), str(intact)) == expected[1], where
                outcomes['unchanged'] += 1
            else:
                assert code == 1 and one_line_error(err), (where, code, err)
                outcomes['refused'] += 1
    # Every flip lands somewhere a checksum covers: each of them is refused, none read as if intact.
    assert outcomes['refused'] == 2 * len(SEEDS), outcomes


def test_skip_damaged_reads_the_rest_and_says_how_many_it_left_out(tmp_path, skynav_main):
    with COMPASS.open('rb') as stream:
        chunk = mcap.reader.make_reader(stream).get_summary().chunk_indexes[1]
    data = bytearray(COMPASS.read_bytes())
    data[chunk.chunk_start_offset + chunk.chunk_length // 2] ^= 0xFF
    broken = tmp_path / COMPASS.name
    broken.write_bytes(bytes(data))
    code, _, err = skynav_main(['info', str(broken)])
    assert code == 1 and one_line_error(err) and 'damaged chunk' in err, err
    code, out, err = skynav_main(['info', '--skip-damaged', str(broken)])
    skipped = int(re.search(r'skipping 1 damaged chunk \(checksum mismatch\): (\d+) messages', err).group(1))
    assert code == 0 and f'Unreadable:        {skipped} messages in damaged chunks' in out, err
    # no reader: the default would wait 30 s for the graph's nodes
    result = run_skynav('replay', '--skip-damaged', str(broken), '--rate', '0', '--wait-for-subscribers', '0')
    with open_bag(COMPASS) as bag:
        total = bag.message_count
    assert result.returncode == 0 and f'published {total - skipped} messages' in result.stderr, result.stderr
