# SPDX-License-Identifier: Apache-2.0
"""MCAP checksums: written by BagWriter, checked before reading, damage named or skipped; unfinished files salvaged."""

from __future__ import annotations

import mcap.reader
import pytest
from mcap.records import Channel, Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk

from skynav_core.names import SKYLINE_SH
from skynav_core.recording.bag import BagError, BagReader, BagWriter, open_bag
from skynav_core.recording.mcapfile import CHUNK_PERIOD, Salvage, SalvagedChannel, SalvagedMessage
from skynav_core.recording.typestore import typestore
from skynav_testing import sample_messages, write_sample_bag

FRAMES = 25  # 2.4 s at 10 Hz: three chunks of at most CHUNK_PERIOD


@pytest.fixture(scope='module', params=['zstd', 'uncompressed'])
def bag(request, tmp_path_factory):
    """Return the path of a sample bag of several chunks and its chunk indexes: zstd chunks (whose frames carry
    checksums of their own) or uncompressed ones (`skynav record --no-compression`: only the chunk's CRC)."""
    path = tmp_path_factory.mktemp('mcap') / 'sample.mcap'
    if request.param == 'zstd':
        write_sample_bag(path, frames=FRAMES)
    else:
        with BagWriter(path, compress=False) as writer:
            for topic, msgtype, t, message in sample_messages(FRAMES):
                writer.add_topic(topic, msgtype)
                writer.write(topic, t, typestore().serialize_cdr(message, msgtype))
    with path.open('rb') as stream:
        chunks = mcap.reader.make_reader(stream).get_summary().chunk_indexes
    assert len(chunks) == 3 and all(c.message_end_time - c.message_start_time <= CHUNK_PERIOD for c in chunks)
    assert {c.compression for c in chunks} == {'zstd' if request.param == 'zstd' else ''}
    return path, chunks


def damaged(path, tmp_path, offset: int, name: str = 'broken.mcap'):
    """Return a copy of `path` with the byte at `offset` changed."""
    data = bytearray(path.read_bytes())
    data[offset] ^= 0x5A
    broken = tmp_path / name
    broken.write_bytes(bytes(data))
    return broken


def chunk_messages(path) -> list[list[tuple[str, int, bytes]]]:
    """Return the messages of each chunk, in file order, as the mcap library reads them."""
    with path.open('rb') as stream:
        records = list(StreamReader(stream, emit_chunks=True).records)
    topics = {r.id: r.topic for r in records if isinstance(r, Channel)}
    chunks = [breakup_chunk(r) for r in records if isinstance(r, Chunk)]
    topics |= {r.id: r.topic for chunk in chunks for r in chunk if isinstance(r, Channel)}
    return [[(topics[r.channel_id], r.log_time, r.data) for r in chunk if isinstance(r, Message)] for chunk in chunks]


def read_all(path, **kwargs) -> list[tuple[str, int, bytes]]:
    with open_bag(path, **kwargs) as reader:
        return [(m.topic, m.log_time, m.data) for m in reader.messages()]


def test_a_damaged_chunk_is_named_with_its_topics_and_time_range(bag, tmp_path):
    path, chunks = bag
    middle = chunks[1]
    broken = damaged(path, tmp_path, middle.chunk_start_offset + middle.chunk_length // 2)
    with pytest.raises(BagError) as info:
        read_all(broken)
    start = (middle.message_start_time - chunks[0].message_start_time) / 1e9
    end = (middle.message_end_time - chunks[0].message_start_time) / 1e9
    text = str(info.value)
    assert '\n' not in text and '1 damaged chunk (checksum mismatch)' in text and '--skip-damaged' in text
    assert f'logged {start:.3f}-{end:.3f} s into the recording' in text and SKYLINE_SH in text


def test_skip_damaged_reads_the_rest_and_counts_what_it_left_out(bag, tmp_path):
    path, chunks = bag
    middle = chunks[1]
    broken = damaged(path, tmp_path, middle.chunk_start_offset + middle.chunk_length // 2)
    intact = read_all(path)
    lost = chunk_messages(path)[1]
    warnings = []
    with BagReader(broken, skip_damaged=True, warn=warnings.append) as reader:
        kept = [(m.topic, m.log_time, m.data) for m in reader.messages()]
        assert reader.skipped == len(lost) > 0
    assert kept == [m for m in intact if m not in lost]
    assert len(warnings) == 1 and f'skipping 1 damaged chunk (checksum mismatch): {len(lost)} messages' in warnings[0]


def test_damaged_index_and_data_outside_chunks_are_refused(bag, tmp_path):
    path, chunks = bag
    size = path.stat().st_size
    with pytest.raises(BagError, match='damaged index'):  # a byte of the summary (a channel's topic name)
        read_all(damaged(path, tmp_path, size - 200, 'summary.mcap'))
    index_start = chunks[0].chunk_start_offset + chunks[0].chunk_length  # the first chunk's message indexes
    with pytest.raises(BagError, match='damaged outside its messages'):
        read_all(damaged(path, tmp_path, index_start + 20, 'index.mcap'))


def test_salvage_keeps_every_complete_chunk_of_a_cut_off_file(bag, tmp_path):
    path, chunks = bag
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(path.read_bytes()[: chunks[2].chunk_start_offset + chunks[2].chunk_length // 2])
    salvage = Salvage(cut)
    items = list(salvage.records())
    topics = {c.id: c.topic for c in items if isinstance(c, SalvagedChannel)}
    saved = [(topics[m.channel], m.log_time, m.data) for m in items if isinstance(m, SalvagedMessage)]
    first, second, _ = chunk_messages(path)
    assert saved == first + second
    assert (salvage.chunks, salvage.damaged, salvage.stopped) == (2, 0, 'the last record is cut off')
