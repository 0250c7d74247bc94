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

import os
import re
import shutil
import sys
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING, Any

import mcap.reader
import yaml
from rosbags.interfaces import ConnectionExtRosbag2
from rosbags.rosbag2 import CompressionFormat, CompressionMode, Reader, StoragePlugin

from ..errors import SkynavError
from .mcapfile import CheckedWriter, McapError, check_mcap
from .typestore import BadMessageType, UnknownMessageType, ensure_type, split_type, typestore

if TYPE_CHECKING:
    from rosbags.interfaces import Connection, Qos

MCAP_MAGIC = b'\x89MCAP0\r\n'
# A recorded topic name: absolute, '/'-separated identifiers (hidden ones may start with '_').
TOPIC_NAME = re.compile(r'(/[A-Za-z_][A-Za-z0-9_]*)+')
# What a command's --skip-damaged sets: readers leave out damaged chunks (and say how many messages) instead of failing.
_skip_damaged = False


class BagError(SkynavError):
    """A recording that cannot be read or written; the message names the file and the problem."""


def set_skip_damaged(skip: bool) -> None:
    """Make readers opened from now on skip damaged chunks (counting their messages) instead of refusing the bag."""
    global _skip_damaged  # noqa: PLW0603 - a command line's choice, for every bag the command opens
    _skip_damaged = skip


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
        raise BagError(
            f'{path}: truncated MCAP file (no footer; the recording was cut off before it was closed); '
            '`skynav bag recover` saves its complete messages'
        )


# rosbag2_bagfile_information: the type of each field skynav relies on (a dict: the same for its fields;
# a list: the type of every item). Fields it does not name are left to rosbags.
_TIME = {'nanoseconds_since_epoch': int}
_DURATION = {'nanoseconds': int}
METADATA_FIELDS: dict[str, Any] = {
    'version': int,
    'storage_identifier': str,
    'relative_file_paths': [str],
    'duration': _DURATION,
    'starting_time': _TIME,
    'message_count': int,
    'topics_with_message_count': [
        {
            'message_count': int,
            'topic_metadata': {'name': str, 'type': str, 'serialization_format': str, 'type_description_hash': str},
        }
    ],
    'compression_format': str,
    'compression_mode': str,
    'files': [{'path': str, 'starting_time': _TIME, 'duration': _DURATION, 'message_count': int}],
    'custom_data': {str: str},
    'ros_distro': str,
}


def _check_fields(value: object, spec: Any, field: str, where: str) -> None:
    """Raise BagError naming the field when `value` does not have the shape `spec` describes."""
    problem = ''
    if spec is int:
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            problem = 'a count'
    elif spec is str:
        if not isinstance(value, str):
            problem = 'a text'
    elif isinstance(spec, list):
        if not isinstance(value, list):
            problem = 'a list'
        else:
            for index, item in enumerate(value):
                _check_fields(item, spec[0], f'{field}[{index}]', where)
    elif str in spec:  # a mapping of texts to texts (custom_data); rosbag2 writes {} or leaves it out
        if value is not None and (
            not isinstance(value, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in value.items())
        ):
            problem = 'a mapping of texts to texts'
    elif not isinstance(value, dict):
        problem = 'a mapping'
    else:
        for key, item_spec in spec.items():
            if key in value:
                _check_fields(value[key], item_spec, f'{field}.{key}' if field else key, where)
    if problem:
        raise BagError(f'{where}: metadata field {field} is {str(value)[:40]!r}, not {problem}')


def check_metadata(metadata: object, where: str) -> dict:
    """Return rosbag2 metadata (rosbag2_bagfile_information) after checking its fields; BagError when malformed."""
    if not isinstance(metadata, dict):
        raise BagError(f'{where}: its metadata is not a mapping')
    _check_fields(metadata, METADATA_FIELDS, '', where)
    for name in metadata.get('relative_file_paths', []) + [f.get('path', '') for f in metadata.get('files', [])]:
        path = PurePosixPath(name)
        if path.is_absolute() or '..' in path.parts or '\\' in name:
            raise BagError(f'{where}: metadata names a storage file outside the bag: {name[:80]!r}')
    return metadata


def _load_yaml(text: str | bytes, where: str) -> object:
    """Return a YAML document; BagError when it does not parse."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        problem = str(exc).splitlines()[0]
        raise BagError(f'{where}: its metadata is not YAML ({problem})') from None


def _warn(text: str) -> None:
    """Print a warning of a command reading a bag (one line on stderr)."""
    print(f'skynav: warning: {text}', file=sys.stderr)


class BagReader:
    """A recording opened for reading; use as a context manager."""

    def __init__(self, path: str | Path, skip_damaged: bool | None = None, warn: Callable[[str], None] = _warn) -> None:
        """Open `path`; with `skip_damaged` (default: the command line's --skip-damaged) damaged chunks are left out."""

        self.path = Path(path)
        self.skip_damaged = _skip_damaged if skip_damaged is None else skip_damaged
        self.skipped = 0  # messages left out with the damaged chunks that held them
        if not self.path.exists():
            raise BagError(f'{self.path}: no such file or directory')
        if self.path.is_dir() and not (self.path / 'metadata.yaml').is_file():
            raise BagError(f'{self.path}: not a rosbag2 directory (it has no metadata.yaml)')
        if self.path.is_file() and self.path.suffix not in ('.mcap', '.db3'):
            raise BagError(f'{self.path}: not a bag (expected a rosbag2 directory, .mcap or .db3 file)')
        if self.path.is_file() and self.path.suffix == '.mcap':
            _check_mcap_file(self.path)
        damaged: dict[Path, set[int]] = {}
        for file in self.files if self.storage == 'mcap' else []:
            try:
                check = check_mcap(file)
            except McapError as exc:
                raise BagError(f'{file}: {exc}; `skynav bag recover` saves the messages of its intact chunks') from None
            if check.damaged and not self.skip_damaged:
                raise BagError(f'{file}: {check.describe()}; --skip-damaged reads the rest')
            if check.damaged:
                damaged[file.resolve()] = {chunk.offset for chunk in check.damaged}
                self.skipped += sum(chunk.messages for chunk in check.damaged)
                warn(f'{file}: skipping {check.describe()}')
        _ = self.metadata  # checked before rosbags reads it
        self._reader = Reader(self.path)
        try:
            self._reader.open()
        except Exception as exc:  # rosbags raises several kinds for damaged files
            raise BagError(f'{self.path}: cannot read bag: {_one_line(exc)}') from None
        for storage in getattr(self._reader.storage, 'storages', [self._reader.storage]):
            if offsets := damaged.get(Path(storage.path).resolve()):
                storage.chunks = [c for c in storage.chunks if c.chunk_start_offset not in offsets]
        self.topics: dict[str, Topic] = {}
        self._connections: dict[str, list[Connection]] = {}
        for name, info in self._reader.topics.items():
            if not TOPIC_NAME.fullmatch(name):
                raise BagError(f'{self.path}: not a topic name: {name[:80]!r}')
            if info.msgtype is None:
                raise BagError(f'{self.path}: topic {name} carries more than one message type')
            try:
                split_type(info.msgtype)
            except BadMessageType as exc:
                raise BagError(f'{self.path}: topic {name}: {exc}') from None
            self._connections[name] = list(info.connections)
            qos = tuple(
                q
                for c in info.connections
                if isinstance(c.ext, ConnectionExtRosbag2)
                for q in c.ext.offered_qos_profiles
            )
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
        'rosbag2' metadata record. Its fields are checked (BagError when malformed).
        """
        if self.path.is_dir():
            where = self.path / 'metadata.yaml'
            document = _load_yaml(where.read_bytes(), str(where))
            if not isinstance(document, dict) or not isinstance(document.get('rosbag2_bagfile_information'), dict):
                raise BagError(f'{where}: not rosbag2 metadata (no rosbag2_bagfile_information mapping)')
            return check_metadata(document['rosbag2_bagfile_information'], str(where))
        if self.path.suffix != '.mcap':
            return {}

        try:
            with self.path.open('rb') as stream:
                for record in mcap.reader.make_reader(stream).iter_metadata():
                    if record.name == 'rosbag2' and 'serialized_metadata' in record.metadata:
                        document = _load_yaml(record.metadata['serialized_metadata'], str(self.path))
                        return {} if document is None else check_metadata(document, str(self.path))
        except BagError:
            raise
        except Exception as exc:  # the mcap library raises several kinds for damaged files
            raise BagError(f'{self.path}: cannot read its metadata: {_one_line(exc)}') from None
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
                raise BagError(f'{self.path}: corrupt data after {count} messages: {_one_line(exc)}') from None
            count += 1
            yield RawMessage(connection.topic, connection.msgtype, log_time, bytes(data))

    def deserialize(self, message: RawMessage) -> Any:
        """Return the message as a rosbags dataclass; BagError when its bytes do not decode as its type."""
        try:
            return typestore().deserialize_cdr(message.data, message.msgtype)
        except Exception as exc:  # rosbags raises several kinds for bytes that do not fit the type
            raise BagError(
                f'{self.path}: a {message.msgtype} message on {message.topic} (logged at {message.log_time} ns) '
                f'does not decode: {_one_line(exc)}'
            ) from None

    def close(self) -> None:
        """Close the recording."""
        if self._reader.is_open:
            self._reader.close()

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _one_line(exc: BaseException) -> str:
    """Return an exception's message on one line."""
    return ' '.join(str(exc).split()) or type(exc).__name__


def open_bag(path: str | Path, skip_damaged: bool | None = None) -> BagReader:
    """Open a rosbag2 directory or a bare .mcap/.db3 file for reading (see BagReader for `skip_damaged`)."""
    return BagReader(path, skip_damaged)


class BagWriter:
    """Write raw CDR messages into a rosbag2 MCAP recording, atomically; use as a context manager.

    A path ending in ``.mcap`` becomes a bare MCAP file, any other path a rosbag2
    directory. Nothing appears at the path until :meth:`close`.
    """

    def __init__(self, path: str | os.PathLike, *, compress: bool = True, overwrite: bool = False) -> None:

        self.path = Path(path)
        self.partial = self.path.with_name(f'.{self.path.name}.partial')
        if self.path.exists() and not overwrite:
            raise BagError(f'{self.path}: exists already; choose another name or remove it first')
        if self.partial.exists():
            raise BagError(
                f'{self.partial}: an earlier recording to {self.path.name} did not finish and its '
                f'data is still there (`skynav bag recover {self.partial} SAVED.mcap` saves its messages); '
                'move or delete it first'
            )
        if not self.path.parent.is_dir():
            raise BagError(f'{self.path.parent}: no such directory')
        # rosbags names the storage file after the bag directory: STEM/STEM.mcap, the name that
        # the file (and the file list in its embedded metadata) keeps once moved into place.
        self._staged = self.partial / self.path.stem
        self._writer = CheckedWriter(self._staged, version=9, storage_plugin=StoragePlugin.MCAP)
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

    def add_topic(self, topic: str, msgtype: str, offered_qos: Iterable[Qos] = (), msgdef: str = '') -> None:
        """Declare a topic before writing to it; its message definition (installed, or `msgdef`) is embedded."""
        if topic in self._connections:
            return
        if not TOPIC_NAME.fullmatch(topic):
            raise BagError(f'{self.path}: cannot record {topic[:80]!r}: not an absolute topic name')
        try:
            msgtype = ensure_type(msgtype, msgdef)
        except (UnknownMessageType, ValueError) as exc:
            raise BagError(f'{self.path}: cannot record {topic}: {exc}') from None
        if split_type(msgtype)[1] != 'msg':  # rosbags embeds definitions of pkg/msg/ types only
            raise BagError(f'{self.path}: cannot record {topic}: a bag holds no definition of {msgtype} (an action)')
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=typestore(), offered_qos_profiles=list(offered_qos)
        )
        self.counts[topic] = 0

    def write(self, topic: str, log_time: int, data: bytes | memoryview) -> None:
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
