# SPDX-License-Identifier: Apache-2.0
"""Damaged and crafted maps against every command and node that reads one: the same answer, or one line; never a crash.

A map built from a bundled bag (with the baselines' descriptors, so every table is there) is damaged in two ways:

- byte flips: one bit of one byte, at an offset drawn from a fixed seed (FLIP_SEEDS), anywhere in the file;
- crafted files (CRAFTED): a header or a row changed with SQL to what a hostile file could declare (a huge degree,
  an object dtype, an absurd shape, a count that is no number, a pose that is text, descriptor settings of the wrong
  type), with the checksums that cover it recomputed, so that the bounds, not the checksums, must refuse it.

Each map goes through `skynav map info`, `skynav eval localization --map` (every method, so every descriptor is
read) and `skynav eval compass --map`, run in this process like the `skynav` command runs them, and through the
localize, compass and warping nodes as `skynav launch` and `skynav run` start them, fed a few views. A command
either exits 0 with the very output it gives for the intact map, or exits 1 with one line on stderr, never a
traceback; a node never fails an input and never dies: with a map it refuses it says so once (the 'parameters'
count) and serves without one. `skynav run --map` (a subprocess, slower) runs over a short bag for a few of them.
The recordings the evaluations read are processed once (recording_views is memoised here): what is fuzzed is the
map side.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import random
import re
import shutil
import sqlite3
import zlib
from pathlib import Path

import pytest
from matplotlib.figure import Figure
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message

from skynav_bringup.cli import main
from skynav_core import views
from skynav_core.graph import in_process, type_name
from skynav_core.maps import MapError, MapStore, _meta_crc
from skynav_core.names import CAMERA_FRAME, COMPASS_ORIENTATION, HOME_VECTOR, LOCALIZATION_MATCH, SKYLINE_SH
from skynav_core.nodes import NodeSpec
from skynav_core.recording.bag import RawMessage, open_bag
from skynav_msgs.msg import CompassEstimate, HomeVector, PlaceMatch, ShCoefficients
from skynav_testing import one_line_error, run_skynav

pytestmark = pytest.mark.heavy(65)

BAGS = Path(__file__).resolve().parents[1] / 'bags'
BAG = BAGS / 'synthetic_garden_compass.mcap'  # short (31 exposures), with ground truth: map and queries alike
FLIP_SEEDS = range(28)  # one flipped bit each
RUN_SEEDS = range(1)  # of them, the ones `skynav run --map` also reads (a subprocess each)
NODES = [
    NodeSpec('localize', 'skynav_localize', 'skynav_localize.node:LocalizeNode'),
    NodeSpec('compass', 'skynav_compass', 'skynav_compass.node:CompassNode'),
    NodeSpec('warping', 'skynav_warping', 'skynav_warping.node:WarpingNode'),
]
FED_VIEWS = 3  # views fed to the nodes per map
NODE_ARGUMENTS = ['-p', 'reference:=index', '-p', 'target:=index', '-p', 'index:=3']  # snapshot 3, as damaged
#: What a map decides: the topics of the localize, compass and warping nodes, with their types.
MAP_TOPICS = {
    LOCALIZATION_MATCH: PlaceMatch,
    COMPASS_ORIENTATION: CompassEstimate,
    HOME_VECTOR: HomeVector,
}
QUERY_VIEWS = 8  # views the evaluations query per map


def recompute_meta_checksum(db: sqlite3.Connection) -> None:
    """Make the meta table's checksum agree with its rows again (a crafted file would)."""
    meta = dict(db.execute('SELECT key, value FROM meta'))
    db.execute("UPDATE meta SET value = ? WHERE key = 'meta_checksum'", (str(_meta_crc(meta)),))


def set_meta(key: str, value: object):
    def craft(db: sqlite3.Connection) -> None:
        db.execute('UPDATE meta SET value = ? WHERE key = ?', (value, key))
        if isinstance(value, str):
            recompute_meta_checksum(db)

    return craft


def set_descriptor(column: str, value: str, name: str = 'raw_uv', index: int = 3):
    def craft(db: sqlite3.Connection) -> None:
        db.execute(f'UPDATE descriptors SET {column} = ? WHERE snapshot_idx = ? AND name = ?', (value, index, name))

    return craft


def text_pose(db: sqlite3.Connection) -> None:
    db.execute("UPDATE snapshots SET x = 'north' WHERE idx = 1")


def damaged_orb(db: sqlite3.Connection) -> None:
    """A flipped byte in an ORB descriptor, with its checksum made to match (the dtype and shape still fit)."""
    (data,) = db.execute("SELECT data FROM descriptors WHERE snapshot_idx = 2 AND name = 'orb'").fetchone()
    data = bytes([data[0] ^ 0xFF]) + data[1:]
    db.execute(
        "UPDATE descriptors SET data = ?, checksum = ? WHERE snapshot_idx = 2 AND name = 'orb'",
        (data, zlib.crc32(data)),
    )


#: The crafted maps every reader refuses when it opens them (a header or a snapshot row is wrong).
REFUSED_AT_OPEN = {'max_degree_100000', 'max_degree_negative', 'schema_version_lots', 'max_degree_blob', 'pose_text'}
CRAFTED = {
    'max_degree_100000': set_meta('max_degree', '100000'),
    'max_degree_negative': set_meta('max_degree', '-3'),
    'schema_version_lots': set_meta('schema_version', 'lots'),
    'max_degree_blob': set_meta('max_degree', b'16'),
    'settings_list': set_meta('descriptor_settings', '[1, 2]'),
    'settings_huge_image': set_meta(
        'descriptor_settings', '{"descriptor_version": 2, "raw_uv_size": [99999, 99999], "orb_features": 500}'
    ),
    'dtype_object': set_descriptor('dtype', '|O'),
    'dtype_structured': set_descriptor('dtype', '<f4,<f4'),
    'shape_99999x99999': set_descriptor('shape', '99999,99999'),
    'shape_negative': set_descriptor('shape', '-1'),
    'pose_text': text_pose,
    'orb_rechecksummed': damaged_orb,  # passes every check; the evaluation reads the stored bow-orb vectors
}


@pytest.fixture(scope='module')
def clean_map(tmp_path_factory, memoised_recordings) -> Path:
    path = tmp_path_factory.mktemp('fuzz') / 'garden.db'
    assert main(['map', 'build', str(BAG), '--out', str(path), '--baselines']) == 0
    with MapStore.open(path) as store:
        assert store.descriptor_names() == ['bow-orb', 'orb', 'raw_uv'] and store.has_poses
    return path


@pytest.fixture(scope='module')
def damaged_maps(clean_map) -> dict[str, Path]:
    """Every damaged map by name: 'flip<seed>' and the crafted ones."""
    folder = clean_map.parent / 'damaged'
    folder.mkdir()
    data = clean_map.read_bytes()
    maps = {}
    for seed in FLIP_SEEDS:
        rng = random.Random(seed)
        flipped = bytearray(data)
        flipped[rng.randrange(len(flipped))] ^= 1 << rng.randrange(8)
        maps[f'flip{seed}'] = folder / f'flip{seed}.db'
        maps[f'flip{seed}'].write_bytes(bytes(flipped))
    for name, craft in CRAFTED.items():
        path = folder / f'{name}.db'
        shutil.copy(clean_map, path)
        with sqlite3.connect(path) as db:
            craft(db)
        db.close()
        maps[name] = path
    return maps


@pytest.fixture(scope='module')
def memoised_recordings():
    """Process the recording once for the map build and all the evaluations (views with images and masks), and
    save no plot: what is fuzzed is the map side, and drawing is 70 % of an evaluation's time."""
    original, cache = views.recording_views, {}

    def memoised(path, ros_args=None, images=True, progress=None, masks=False):
        key = (str(path), tuple(ros_args or ()))
        if key not in cache:
            cache[key] = original(path, ros_args, images=True, masks=True)
        return cache[key]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(views, 'recording_views', memoised)
        patch.setattr(Figure, 'savefig', lambda figure, *args, **kwargs: None)
        yield cache


@pytest.fixture(scope='module')
def short_queries(clean_map, memoised_recordings):
    """From here on the evaluations query QUERY_VIEWS views of the recording (the map holds all of them)."""
    for key, recording in memoised_recordings.items():
        memoised_recordings[key] = dataclasses.replace(recording, views=recording.views[:QUERY_VIEWS])


def commands(path: Path, plots: Path) -> dict[str, list[str]]:
    """Every map-reading command line of `skynav` (in process) for one map."""
    return {
        'map info': ['map', 'info', str(path)],
        'eval localization': ['eval', 'localization', str(BAG), '--map', str(path), '--plots', str(plots)],
        'eval compass': [
            *('eval', 'compass', str(BAG), '--map', str(path), '--index', '3'),
            *('--methods', 'fft-masked', '--plots', str(plots)),
        ],
    }


def answer(command: str, out: str, path: Path) -> str:
    """Return what a command answered: its stdout with the map's path as MAP, no file size, no CPU times."""
    out = out.replace(str(path), 'MAP')
    if command == 'map info':  # a file SQLite rewrote (the crafted ones) may have grown
        out = re.sub(r'^File: .*$', 'File: MAP', out, flags=re.MULTILINE)
    if command == 'eval compass':
        out = re.sub(r' +[0-9.]+$', '', out, flags=re.MULTILINE)  # the last column: ms per estimate (or the tilt)
    return out


def run_command(argv: list[str], capsys) -> tuple[int, str, str]:
    """Run `skynav ARGV` in this process; return its exit code, stdout and stderr (the map's path made MAP)."""
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope='module')
def plots(tmp_path_factory) -> Path:
    """The one folder the evaluations save their plots in (its name is in their output)."""
    return tmp_path_factory.mktemp('plots')


@pytest.fixture(scope='module')
def clean_outputs(clean_map, short_queries, plots) -> dict[str, str]:
    """What every command prints for the intact map (its path written MAP)."""
    outputs = {}
    for name, argv in commands(clean_map, plots).items():
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):  # capsys is per test
            code = main(argv)
        assert code == 0, err.getvalue()
        outputs[name] = answer(name, out.getvalue(), clean_map)
    return outputs


def sh_messages(count: int) -> list[ShCoefficients]:
    """The first views of the bag as the SH node publishes them."""
    recording = views.recording_views(BAG, images=False)
    messages = []
    for view in recording.views[:count]:
        message = ShCoefficients(
            max_degree=view.max_degree,
            coefficients=view.coefficients.tolist(),
            fill=view.fill,
            field_of_view=float(view.field_of_view),
        )
        message.header.stamp.sec, message.header.stamp.nanosec = divmod(view.stamp, 10**9)
        message.header.frame_id = CAMERA_FRAME
        messages.append(message)
    return messages


def test_every_damaged_map_gives_the_same_answer_or_one_line(
    clean_map, damaged_maps, clean_outputs, short_queries, plots, capsys
):
    codes = {}
    for name, path in damaged_maps.items():
        for command, argv in commands(path, plots).items():
            code, out, err = run_command(argv, capsys)  # an exception here is the traceback a user would see
            assert 'Traceback' not in err, (name, command, err)
            if code == 0:
                assert answer(command, out, path) == clean_outputs[command], (name, command)
            else:
                assert code == 1 and one_line_error(err), (name, command, code, err)
                assert err.startswith(f'skynav {command}: error: {path}'), (name, command, err)
            codes[name, command] = code
    refused = {command: {name for name in CRAFTED if codes[name, command]} for command in clean_outputs}
    assert refused['map info'] == refused['eval compass'] == REFUSED_AT_OPEN
    # the raw UV descriptor of snapshot 3 and the settings are read by the baselines' evaluation, by nothing else
    assert refused['eval localization'] == set(CRAFTED) - {'orb_rechecksummed'}  # ORB: not read (bow-orb stored)
    flips_refused = {name for name in damaged_maps if name.startswith('flip') and codes[name, 'eval localization']}
    assert 0 < len(flips_refused) < len(FLIP_SEEDS)  # some flips hit what is read, some what is not


def feed_views(graph, messages: list[ShCoefficients], offset_ns: int = 0) -> None:
    """Feed views on /skyline/sh as a recording would (stamps moved on by offset_ns, to keep them in order)."""
    for message in messages:
        stamp = message.header.stamp.sec * 10**9 + message.header.stamp.nanosec + offset_ns
        message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 10**9)
        graph.feed(RawMessage(SKYLINE_SH, type_name(message), stamp, serialize_message(message)))


def has_map(node) -> bool:
    """Return whether a localize, compass or warping node holds a map."""
    return (node.snapshots.store if hasattr(node, 'snapshots') else node.store) is not None


def opens(path: Path) -> bool:
    """Return whether MapStore opens a map (what every node does first)."""
    try:
        MapStore.open(path).close()
    except MapError:
        return False
    return True


@pytest.mark.parametrize('name', sorted(REFUSED_AT_OPEN))
def test_a_node_started_with_a_refused_map_says_so_once_and_serves_without_one(damaged_maps, name):
    messages = sh_messages(FED_VIEWS)
    with in_process(NODES, [*NODE_ARGUMENTS, '-p', f'map:={damaged_maps[name]}']) as graph:  # started: alive
        graph.keep_outputs = True
        feed_views(graph, messages)
        nodes = {node.get_name(): node for node in graph.nodes}
        for node in nodes.values():
            assert not has_map(node) and node.rejected['parameters'] == 1 and node.errors == 0, node.get_name()
        assert nodes['compass'].rejected['no_map'] == FED_VIEWS
        matches = [o.message for o in graph.outputs if o.topic == LOCALIZATION_MATCH]
        assert [m.index for m in matches] == [-1] * FED_VIEWS  # localize answers every view, without a map


def test_the_nodes_never_fail_on_a_damaged_map_set_at_run_time(clean_map, damaged_maps):
    messages = sh_messages(1)  # one view per map: an estimate of the warping node takes ~0.3 s
    with in_process(NODES, [*NODE_ARGUMENTS, '-p', f'map:={clean_map}']) as graph:
        graph.keep_outputs = True
        nodes = {node.get_name(): node for node in graph.nodes}
        for round, (name, path) in enumerate(damaged_maps.items(), start=1):
            results = {n: node.set_parameters([Parameter('map', value=str(path))])[0] for n, node in nodes.items()}
            usable = opens(path)
            for node_name, result in results.items():
                assert result.successful == usable, (name, node_name, result.reason)
                if not usable:  # refused in one line; the node keeps the map it had
                    assert '\n' not in result.reason and has_map(nodes[node_name]), (name, node_name)
            before = len(graph.outputs)
            feed_views(graph, messages, offset_ns=round * 10**9)
            assert all(node.errors == 0 for node in nodes.values()), name
            matches = [o for o in graph.outputs[before:] if o.topic == LOCALIZATION_MATCH]
            assert len(matches) == len(messages), name


@pytest.fixture(scope='module')
def clean_run(clean_map, tmp_path_factory) -> list[tuple[str, bytes]]:
    """The messages `skynav run --map` writes with the intact map."""
    out = tmp_path_factory.mktemp('run') / 'clean.mcap'
    clean = run_skynav('run', str(BAG), '--map', str(clean_map), '--out', str(out))
    assert clean.returncode == 0, clean.stderr
    return messages_of(out)


@pytest.mark.parametrize('name', [f'flip{seed}' for seed in RUN_SEEDS] + ['max_degree_100000', 'settings_list'])
def test_run_with_a_damaged_map_gives_the_same_messages_or_one_line(damaged_maps, clean_run, tmp_path, name):
    damaged = run_skynav('run', str(BAG), '--map', str(damaged_maps[name]), '--out', str(tmp_path / 'out.mcap'))
    assert 'Traceback' not in damaged.stderr
    if damaged.returncode == 0:
        assert messages_of(tmp_path / 'out.mcap') == clean_run
    else:
        assert damaged.returncode == 1 and one_line_error(damaged.stderr), damaged.stderr


def messages_of(path: Path) -> dict[str, list]:
    """Return the messages of the topics a map decides (localize, compass, warping), decoded, by topic, in order.

    Decoded, not as bytes: the CDR padding bytes rclpy writes are not always the same from run to run.
    """
    with open_bag(path) as bag:
        topics = [topic for topic in MAP_TOPICS if topic in bag.topics]
        found = {topic: [] for topic in MAP_TOPICS}
        for message in bag.messages(topics):
            found[message.topic].append(deserialize_message(message.data, MAP_TOPICS[message.topic]))
        return found
