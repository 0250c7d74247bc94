# SPDX-License-Identifier: Apache-2.0
"""Read and write recordings: rosbag2 directories and bare rosbag2 MCAP files, as raw CDR bytes.

Reading goes through rosbags' unified reader (rosbag2 directories with mcap or
sqlite3 storage, bare ``.mcap`` and ``.db3`` files); every failure surfaces as
one :class:`BagError` with a message fit for a user. Writing produces rosbag2
MCAP with the message definitions embedded, so ``ros2 bag``, rosbags, the
``mcap`` tools and Foxglove all read it, and is atomic: data goes to a hidden
``.NAME.partial`` directory beside the target and is moved into place only
when the writer closes.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import SkynavError
from .typestore import UnknownMessageType, ensure_type, split_type, typestore

if TYPE_CHECKING:
    from rosbags.interfaces import Connection, Qos

MCAP_MAGIC = b'\x89MCAP0\r\n'


class BagError(SkynavError):
    """A recording that cannot be read or written; the message names the file and the problem."""


@dataclass(frozen=True)
class Topic:
    """One topic of a recording."""

    name: str
    msgtype: str
    count: int
    offered_qos: tuple[Qos, ...] = ()


@dataclass(frozen=True)
class RawMessage:
    """One recorded message: serialized CDR bytes and the time it was logged (ns since the epoch)."""

    topic: str
    msgtype: str
    log_time: int
    data: bytes


def _check_mcap_file(path: Path) -> None:
    """Raise BagError when a bare MCAP file is empty, foreign or truncated."""
    size = path.stat().st_size
    with path.open('rb') as stream:
        head = stream.read(len(MCAP_MAGIC))
        stream.seek(max(0, size - len(MCAP_MAGIC)))
        tail = stream.read()
    if head != MCAP_MAGIC:
        raise BagError(f'{path}: not an MCAP file (it does not start with the MCAP magic bytes)')
    if tail != MCAP_MAGIC:
        raise BagError(f'{path}: truncated MCAP file (no footer; the recording was cut off before it was closed)')


class BagReader:
    """A recording opened for reading; use as a context manager."""

    def __init__(self, path: str | Path) -> None:
        from rosbags.rosbag2 import Reader

        self.path = Path(path)
        if not self.path.exists():
            raise BagError(f'{self.path}: no such file or directory')
        if self.path.is_dir() and not (self.path / 'metadata.yaml').is_file():
            raise BagError(f'{self.path}: not a rosbag2 directory (it has no metadata.yaml)')
        if self.path.is_file() and self.path.suffix not in ('.mcap', '.db3'):
            raise BagError(f'{self.path}: not a bag (expected a rosbag2 directory, .mcap or .db3 file)')
        if self.path.is_file() and self.path.suffix == '.mcap':
            _check_mcap_file(self.path)
        self._reader = Reader(self.path)
        try:
            self._reader.open()
        except Exception as exc:  # rosbags raises several kinds for damaged files
            raise BagError(f'{self.path}: cannot read bag: {exc}') from None
        self.topics: dict[str, Topic] = {}
        self._connections: dict[str, list[Connection]] = {}
        for name, info in self._reader.topics.items():
            if info.msgtype is None:
                raise BagError(f'{self.path}: topic {name} carries more than one message type')
            self._connections[name] = list(info.connections)
            qos = tuple(q for c in info.connections for q in c.ext.offered_qos_profiles)
            self.topics[name] = Topic(name, info.msgtype, info.msgcount, qos)
            if info.msgdef.data:
                try:
                    ensure_type(info.msgtype, info.msgdef.data)
                except Exception:  # a damaged embedded definition: installed .msg files may still serve
                    pass

    @property
    def storage(self) -> str:
        """Return the storage format, 'mcap' or 'sqlite3'."""
        files = self.files
        return 'sqlite3' if files and files[0].suffix == '.db3' else 'mcap'

    @property
    def files(self) -> list[Path]:
        """Return the storage files of the recording."""
        if self.path.is_file():
            return [self.path]
        return sorted(p for p in self.path.iterdir() if p.suffix in ('.mcap', '.db3'))

    @property
    def size(self) -> int:
        """Return the size of the recording on disk in bytes."""
        return sum(p.stat().st_size for p in self.files)

    @property
    def message_count(self) -> int:
        """Return the number of messages in the recording."""
        return self._reader.message_count

    @property
    def start_time(self) -> int:
        """Return the log time of the first message (ns since the epoch)."""
        return self._reader.start_time if self.message_count else 0

    @property
    def end_time(self) -> int:
        """Return the log time of the last message (ns since the epoch)."""
        return self._reader.end_time - 1 if self.message_count else 0

    @cached_property
    def metadata(self) -> dict:
        """Return the rosbag2 metadata (rosbag2_bagfile_information) of the recording, {} when it has none.

        rosbag2 directories keep it in metadata.yaml; a bare MCAP file carries it in its
        'rosbag2' metadata record.
        """
        import yaml

        if self.path.is_dir():
            text = (self.path / 'metadata.yaml').read_text()
            return (yaml.safe_load(text) or {}).get('rosbag2_bagfile_information', {})
        if self.path.suffix != '.mcap':
            return {}
        import mcap.reader

        with self.path.open('rb') as stream:
            for record in mcap.reader.make_reader(stream).iter_metadata():
                if record.name == 'rosbag2' and 'serialized_metadata' in record.metadata:
                    return yaml.safe_load(record.metadata['serialized_metadata']) or {}
        return {}

    @property
    def custom_data(self) -> dict[str, str]:
        """Return the recording's custom_data (key -> text) as its writer set it."""
        return dict(self.metadata.get('custom_data') or {})

    @property
    def ros_distro(self) -> str:
        """Return the ROS distribution that wrote the recording, '' when it does not say."""
        return str(self.metadata.get('ros_distro') or '')

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[RawMessage]:
        """Yield the messages (of the given topics, default all) in log-time order."""
        names = list(self.topics) if topics is None else list(topics)
        if unknown := [t for t in names if t not in self.topics]:
            raise BagError(f'{self.path}: no topic {", ".join(unknown)} in this bag')
        connections = [c for t in names for c in self._connections[t]]
        stream = self._reader.messages(connections)
        count = 0
        while True:
            try:
                connection, log_time, data = next(stream)
            except StopIteration:
                return
            except Exception as exc:  # damaged chunk, bad CRC, short read, decompression failure
                raise BagError(f'{self.path}: corrupt data after {count} messages: {exc}') from None
            count += 1
            yield RawMessage(connection.topic, connection.msgtype, log_time, bytes(data))

    def deserialize(self, message: RawMessage) -> object:
        """Return the message as a rosbags dataclass."""
        return typestore().deserialize_cdr(message.data, message.msgtype)

    def close(self) -> None:
        """Close the recording."""
        if self._reader.is_open:
            self._reader.close()

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_bag(path: str | Path) -> BagReader:
    """Open a rosbag2 directory or a bare .mcap/.db3 file for reading."""
    return BagReader(path)


class BagWriter:
    """Write raw CDR messages into a rosbag2 MCAP recording, atomically; use as a context manager.

    A path ending in ``.mcap`` becomes a bare MCAP file, any other path a rosbag2
    directory. Nothing appears at the path until :meth:`close`.
    """

    def __init__(self, path: str | Path, *, compress: bool = True, overwrite: bool = False) -> None:
        from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

        self.path = Path(path)
        self.partial = self.path.with_name(f'.{self.path.name}.partial')
        if self.path.exists() and not overwrite:
            raise BagError(f'{self.path}: exists already; choose another name or remove it first')
        if self.partial.exists():
            raise BagError(
                f'{self.partial}: an earlier recording to {self.path.name} did not finish and its '
                'data is still there; move or delete it first'
            )
        if not self.path.parent.is_dir():
            raise BagError(f'{self.path.parent}: no such directory')
        # rosbags names the storage file after the bag directory: STEM/STEM.mcap, the name that
        # the file (and the file list in its embedded metadata) keeps once moved into place.
        self._staged = self.partial / self.path.stem
        self._writer = Writer(self._staged, version=9, storage_plugin=StoragePlugin.MCAP)
        if compress:
            self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        try:
            self._writer.open()
        except OSError as exc:
            shutil.rmtree(self.partial, ignore_errors=True)
            raise BagError(f'{self.path}: cannot write here: {exc.strerror}') from None
        self._connections: dict[str, Connection] = {}
        self.counts: dict[str, int] = {}
        self._overwrite = overwrite

    @property
    def topics(self) -> dict[str, str]:
        """Return the topics added so far with their message types."""
        return {name: c.msgtype for name, c in self._connections.items()}

    def set_custom_data(self, key: str, value: str) -> None:
        """Store a text under `key` in the recording's metadata (rosbag2 custom_data)."""
        self._writer.set_custom_data(key, value)

    def add_topic(self, topic: str, msgtype: str, offered_qos: Iterable[Qos] = ()) -> None:
        """Declare a topic before writing to it; its message definition is embedded in the file."""
        if topic in self._connections:
            return
        try:
            msgtype = ensure_type(msgtype)
        except (UnknownMessageType, ValueError) as exc:
            raise BagError(f'{self.path}: cannot record {topic}: {exc}') from None
        if split_type(msgtype)[1] != 'msg':  # rosbags embeds definitions of pkg/msg/ types only
            raise BagError(f'{self.path}: cannot record {topic}: a bag holds no definition of {msgtype} (an action)')
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=typestore(), offered_qos_profiles=list(offered_qos)
        )
        self.counts[topic] = 0

    def write(self, topic: str, log_time: int, data: bytes) -> None:
        """Append one serialized message logged at `log_time` (ns since the epoch)."""
        self._writer.write(self._connections[topic], log_time, data)
        self.counts[topic] += 1

    def close(self) -> Path:
        """Finish the file and move it into place; return its path."""
        if self._writer.storage is None:
            return self.path
        self._writer.close()
        source = self._staged / f'{self._staged.name}.mcap' if self.path.suffix == '.mcap' else self._staged
        if self.path.exists() and self._overwrite:
            shutil.rmtree(self.path) if self.path.is_dir() else self.path.unlink()
        source.replace(self.path)
        if self.partial.exists():
            shutil.rmtree(self.partial)
        return self.path

    def abort(self) -> None:
        """Give up the recording: nothing appears at the path and the partial data is removed.

        For generated recordings, where an incomplete file would pass for a complete one; a
        recorder of live data closes instead, to keep what it received.
        """
        if self._writer.storage is not None:
            self._writer.abort()
        shutil.rmtree(self.partial, ignore_errors=True)

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        # Close even after an error: what was written is kept, never thrown away (unless aborted).
        self.close()
