# SPDX-License-Identifier: Apache-2.0
"""Save every complete message of an unfinished or damaged MCAP recording into a new, finished one.

A recording cut off by kill -9 or a power loss has no index and no footer, and
its last chunk may be partial: `skynav info` calls it truncated and no reader
opens it. This walks the file record by record, keeps the messages of every
complete chunk whose checksum matches, and writes them (with their topics,
types and offered QoS) to OUT. BROKEN is the .mcap file or the hidden
.NAME.partial directory that `skynav record` left. Messages of a chunk that
was still being filled when the recorder died were never written and cannot
be saved.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = 'save the complete messages of an unfinished (killed) or damaged MCAP recording'


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of `skynav bag recover`."""
    parser.add_argument('broken', metavar='BROKEN', help='the unfinished .mcap file (or the .NAME.partial directory)')
    parser.add_argument('out', metavar='OUT.mcap', help='the recording to write (must not exist)')
    parser.add_argument('--no-compression', action='store_true', help='store chunks uncompressed (default zstd)')


def _source(path: Path) -> Path:
    """Return the MCAP file to recover: `path` itself, or the one .mcap file under a directory."""
    from . import CliError

    if path.is_file():
        return path
    if not path.exists():
        raise CliError(f'{path}: no such file or directory')
    found = sorted(path.rglob('*.mcap'))
    if len(found) != 1:
        raise CliError(f'{path}: expected one .mcap file in it, found {len(found)}')
    return found[0]


def run(args: argparse.Namespace) -> int:
    """Recover; return the exit code."""
    from rosbags.rosbag2.metadata import parse_qos

    from skynav_core.recording.bag import BagError, BagWriter
    from skynav_core.recording.mcapfile import McapError, Salvage, SalvagedChannel

    from . import CliError

    source = _source(Path(args.broken))
    salvage = Salvage(source)
    topics: dict[int, str] = {}
    refused: dict[str, str] = {}
    saved = orphans = 0
    with BagWriter(args.out, compress=not args.no_compression) as writer:
        try:
            for item in salvage.records():
                if isinstance(item, SalvagedChannel):
                    try:
                        qos = parse_qos(item.offered_qos)
                    except Exception:  # QoS text of a damaged channel: record it without offered QoS
                        qos = []
                    try:
                        writer.add_topic(item.topic, item.msgtype, qos, msgdef=item.msgdef)
                        topics[item.id] = item.topic
                    except BagError as exc:
                        refused[item.topic] = str(exc)
                elif item.channel in topics:
                    writer.write(topics[item.channel], item.log_time, item.data)
                    saved += 1
                else:
                    orphans += 1
        except McapError as exc:
            raise CliError(f'{source}: {exc}') from None
    for topic, reason in refused.items():
        print(f'skynav bag recover: warning: {topic} not saved: {reason}', file=sys.stderr)
    notes = [f'{salvage.chunks} complete chunks']
    if salvage.stopped:
        notes.append(f'read up to where {salvage.stopped}')
    if salvage.damaged:
        notes.append(f'{salvage.damaged} damaged chunks skipped')
    if orphans:
        notes.append(f'{orphans} messages of unknown or refused topics left out')
    print(
        f'skynav bag recover: saved {saved} messages on {len(topics)} topics from {source} to {writer.path} '
        f'({"; ".join(notes)})',
        file=sys.stderr,
    )
    return 0
