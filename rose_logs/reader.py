"""Open any supported log and iterate its raw messages in log-time order.

Supported inputs (:func:`detect_format`):

- ``"ros1"``: ROS 1 bag v2.0 (``.bag``), plain or with bz2 / lz4 chunks (rosbags);
- ``"db3"``: ROS 2 bag folder with sqlite3 storage, or a bare ``.db3`` file (rosbags);
- ``"mcap-dir"``: ROS 2 bag folder with MCAP storage (rosbags);
- ``"mcap"``: a bare MCAP file with the ``ros2`` (CDR) or ``ros1`` profile (the ``mcap`` package,
  because rosbags refuses ros1-profile MCAP and the raw reader keeps channel metadata and publish times).

Messages are never decoded here: :class:`RawMessage` carries the serialised bytes, so copying is byte for
byte and memory stays flat in the number of messages. Decoding map messages is :mod:`rose_logs.messages`.
"""

from __future__ import annotations

import logging
from collections.abc import Collection, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO, Literal, Self

from rosbags.interfaces import Qos

from rose_logs.errors import LogError, LogReadError

__all__ = [
    "Channel",
    "LogFormat",
    "LogReader",
    "RawMessage",
    "detect_format",
    "normalize_msgtype",
    "ros1_msgtype",
]

_LOG = logging.getLogger(__name__)

LogFormat = Literal["ros1", "db3", "mcap", "mcap-dir"]

_ROS1_MAGIC = b"#ROSBAG V2.0\n"
_MCAP_MAGIC = b"\x89MCAP0\r\n"
_SQLITE_MAGIC = b"SQLite format 3\x00"


def normalize_msgtype(name: str) -> str:
    """Message type in rosbags' form ``pkg/msg/Name`` (ROS 1 names ``pkg/Name`` gain ``/msg/``)."""
    parts = name.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return name


def ros1_msgtype(name: str) -> str:
    """Message type in ROS 1 form ``pkg/Name`` (``pkg/msg/Name`` loses ``/msg/``)."""
    parts = name.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        return f"{parts[0]}/{parts[2]}"
    return name


@dataclass(frozen=True, eq=False)
class Channel:
    """One connection (ROS 1) / topic (ROS 2) / channel (MCAP) of a log, with everything needed to copy it.

    Attributes
    ----------
    id : int
        Reader-local id, unique within one :class:`LogReader`.
    topic : str
        Topic name.
    msgtype : str
        Message type, normalised to ``pkg/msg/Name`` for ROS 1 and ROS 2 alike.
    message_encoding : str
        ``"ros1"`` or ``"cdr"`` for ROS data; MCAP may hold others (copied, never decoded).
    msgdef : str
        Message definition text as stored in the log ("" when the log has none).
    msgdef_encoding : str
        ``"ros1msg"``, ``"ros2msg"``, ``"ros2idl"`` or ``""``.
    digest : str
        ROS 1 md5sum or ROS 2 RIHS01 hash, ``""`` when unknown.
    message_count : int
        Messages on this channel (from the log's index).
    callerid : str or None
        ROS 1 publishing node.
    latching : int or None
        ROS 1 latching flag (1 latched, 0 not, None unknown).
    offered_qos_profiles : tuple of rosbags.interfaces.Qos
        ROS 2 QoS offered by the publishers (ROS 2 bag folders and .db3 files).
    metadata : mapping of str to str
        Raw MCAP channel metadata (for example ``offered_qos_profiles`` as YAML, ``latching``); empty for
        other formats.
    schema_name : str
        MCAP schema name as stored (``pkg/Name`` or ``pkg/msg/Name``); ``""`` for other formats.
    """

    id: int
    topic: str
    msgtype: str
    message_encoding: str
    msgdef: str = ""
    msgdef_encoding: str = ""
    digest: str = ""
    message_count: int = 0
    callerid: str | None = None
    latching: int | None = None
    offered_qos_profiles: tuple[Qos, ...] = ()
    metadata: Mapping[str, str] = field(default_factory=dict)
    schema_name: str = ""


@dataclass(frozen=True, slots=True, eq=False)
class RawMessage:
    """One serialised message.

    Attributes
    ----------
    channel : Channel
        Where it was recorded.
    log_time_ns : int
        Receive time, nanoseconds since the epoch (the bag timestamp).
    data : bytes or memoryview
        Serialised message, exactly as stored.
    publish_time_ns : int
        MCAP publish time; the log time for formats without one.
    sequence : int
        MCAP sequence number; 0 for formats without one.
    """

    channel: Channel
    log_time_ns: int
    data: bytes | memoryview
    publish_time_ns: int
    sequence: int = 0


def detect_format(path: Path) -> LogFormat:
    """Storage format of ``path`` from its content (magic bytes, ``metadata.yaml``).

    Raises
    ------
    LogReadError
        If ``path`` does not exist, cannot be read or is no supported log.
    """
    path = Path(path)
    if not path.exists():
        msg = f"{path}: no such file or directory"
        raise LogReadError(msg)
    if path.is_dir():
        meta = path / "metadata.yaml"
        if not meta.is_file():
            msg = f"{path}: folder without metadata.yaml, not a ROS 2 bag"
            raise LogReadError(msg)
        try:
            text = meta.read_text(encoding="utf-8")
        except OSError as err:
            msg = f"{meta}: cannot read ({err.strerror})"
            raise LogReadError(msg) from err
        if "storage_identifier: mcap" in text:
            return "mcap-dir"
        return "db3"
    try:
        with path.open("rb") as f:
            head = f.read(16)
    except OSError as err:
        msg = f"{path}: cannot read ({err.strerror})"
        raise LogReadError(msg) from err
    if head.startswith(_ROS1_MAGIC):
        return "ros1"
    if head.startswith(_MCAP_MAGIC):
        return "mcap"
    if head.startswith(_SQLITE_MAGIC):
        return "db3"
    what = "empty file" if not head else "unrecognised header"
    msg = f"{path}: not a ROS 1 bag, ROS 2 bag or MCAP file ({what})"
    raise LogReadError(msg)


def _corrupt(path: Path, err: BaseException) -> LogReadError:
    detail = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
    return LogReadError(f"{path}: corrupt or truncated log ({detail})")


class LogReader:
    """Raw, log-time-ordered access to any supported log.

    Parameters
    ----------
    path : Path
        Log file or ROS 2 bag folder. Never modified.

    Notes
    -----
    ``__init__`` only validates; :meth:`open` reads the index. Use as a context manager::

        with LogReader(path) as reader:
            for message in reader.messages():
                ...
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.format: LogFormat = detect_format(self.path)
        self._backend: _RosbagsBackend | _McapBackend | None = None

    # -- lifecycle -------------------------------------------------------------------------------
    def open(self) -> None:
        """Open the log and read its index.

        Raises
        ------
        LogReadError
            If the log is corrupt, truncated or unsupported.
        """
        backend: _RosbagsBackend | _McapBackend
        backend = (
            _McapBackend(self.path)
            if self.format == "mcap"
            else _RosbagsBackend(self.path, self.format)
        )
        try:
            backend.open()
        except LogError:
            backend.close()
            raise
        except Exception as err:  # library errors of every kind: wrap at the boundary
            backend.close()
            raise _corrupt(self.path, err) from err
        self._backend = backend

    def close(self) -> None:
        """Close the log (idempotent)."""
        if self._backend is not None:
            self._backend.close()
            self._backend = None

    def __enter__(self) -> Self:
        self.open()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- index -----------------------------------------------------------------------------------
    @property
    def _open_backend(self) -> _RosbagsBackend | _McapBackend:
        if self._backend is None:
            msg = f"{self.path}: reader is not open"
            raise LogReadError(msg)
        return self._backend

    @property
    def channels(self) -> tuple[Channel, ...]:
        """Every channel of the log, in the log's order."""
        return self._open_backend.channels

    @property
    def message_count(self) -> int:
        """Total number of messages."""
        return sum(c.message_count for c in self.channels)

    @property
    def start_ns(self) -> int:
        """Log time of the first message, ns (0 for an empty log)."""
        return self._open_backend.start_ns

    @property
    def end_ns(self) -> int:
        """Log time of the last message, ns (0 for an empty log)."""
        return self._open_backend.end_ns

    @property
    def serialization(self) -> str:
        """``"ros1"`` or ``"cdr"``: the ROS serialisation of this log's messages."""
        encodings = {c.message_encoding for c in self.channels} & {"ros1", "cdr"}
        if len(encodings) == 1:
            return encodings.pop()
        if self.format == "ros1":
            return "ros1"
        if self.format == "mcap" and self._open_backend.profile == "ros1":
            return "ros1"
        return "cdr"

    def messages(self, *, topics: Collection[str] | None = None) -> Iterator[RawMessage]:
        """Every message (or those on ``topics``), in log-time order.

        Raises
        ------
        LogReadError
            If the log turns out to be truncated or corrupt while reading.
        """
        backend = self._open_backend
        try:
            yield from backend.messages(None if topics is None else set(topics))
        except LogError:
            raise
        except Exception as err:
            raise _corrupt(self.path, err) from err


# -- backends ------------------------------------------------------------------------------------
class _RosbagsBackend:
    """ROS 1 bags and ROS 2 bags (folder, bare .db3) through rosbags."""

    profile = ""

    def __init__(self, path: Path, fmt: LogFormat) -> None:
        self.path = path
        self.format = fmt
        self.reader: Any = None
        self.channels: tuple[Channel, ...] = ()
        self._by_conn: dict[int, Channel] = {}
        self.start_ns = 0
        self.end_ns = 0

    def open(self) -> None:
        if self.format == "ros1":
            from rosbags.rosbag1 import Reader as Reader1

            self.reader = Reader1(self.path)
        else:
            from rosbags.rosbag2 import Reader as Reader2

            self.reader = Reader2(self.path)
        self.reader.open()
        channels = []
        for conn in self.reader.connections:
            ext = conn.ext
            ros1 = self.format == "ros1"
            fmt = conn.msgdef.format.name.lower() if conn.msgdef.data else ""
            channel = Channel(
                id=len(channels),
                topic=conn.topic,
                msgtype=normalize_msgtype(conn.msgtype),
                message_encoding="ros1" if ros1 else ext.serialization_format,
                msgdef=conn.msgdef.data,
                msgdef_encoding=("ros1msg" if ros1 else f"ros2{fmt}") if fmt else "",
                digest=conn.digest or "",
                message_count=max(int(conn.msgcount), 0),
                callerid=ext.callerid if ros1 else None,
                latching=ext.latching if ros1 else None,
                offered_qos_profiles=() if ros1 else tuple(ext.offered_qos_profiles),
            )
            channels.append(channel)
            self._by_conn[id(conn)] = channel
        self.channels = tuple(channels)
        if sum(c.message_count for c in channels):
            self.start_ns = int(self.reader.start_time)
            # rosbags reports the end as "1 ns after the last message"
            self.end_ns = max(self.start_ns, int(self.reader.end_time) - 1)

    def messages(self, topics: set[str] | None) -> Iterator[RawMessage]:
        by_conn = self._by_conn
        conns = None
        if topics is not None:
            conns = [c for c in self.reader.connections if c.topic in topics]
            if not conns:
                return
        for conn, timestamp, data in self.reader.messages(connections=conns or ()):
            yield RawMessage(by_conn[id(conn)], int(timestamp), data, int(timestamp))

    def close(self) -> None:
        if self.reader is not None:
            try:
                self.reader.close()
            except Exception:  # closing a half-open reader must not mask the real error
                _LOG.debug("closing %s failed", self.path, exc_info=True)
            self.reader = None


class _McapBackend:
    """Bare MCAP files (ros1 or ros2 profile) through the ``mcap`` package."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.stream: BinaryIO | None = None
        self.reader: Any = None
        self.channels: tuple[Channel, ...] = ()
        self._by_id: dict[int, Channel] = {}
        self.start_ns = 0
        self.end_ns = 0
        self.profile = ""

    def open(self) -> None:
        from mcap.reader import make_reader

        self.stream = self.path.open("rb")
        self.reader = make_reader(self.stream)
        self.profile = self.reader.get_header().profile
        summary = self.reader.get_summary()
        if summary is None:
            msg = (
                f"{self.path}: MCAP file without summary (truncated or still being recorded?); "
                "try `mcap recover`"
            )
            raise LogReadError(msg)
        counts = summary.statistics.channel_message_counts if summary.statistics else {}
        channels = []
        for channel_id in sorted(summary.channels):
            ch = summary.channels[channel_id]
            schema = summary.schemas.get(ch.schema_id)
            name = schema.name if schema is not None else ""
            encoding = schema.encoding if schema is not None else ""
            data = bytes(schema.data) if schema is not None else b""
            channel = Channel(
                id=len(channels),
                topic=ch.topic,
                msgtype=normalize_msgtype(name) if ch.message_encoding in {"ros1", "cdr"} else name,
                message_encoding=ch.message_encoding,
                msgdef=data.decode("utf-8", errors="replace"),
                msgdef_encoding=encoding,
                digest=ch.metadata.get("md5sum", "") or ch.metadata.get("type_hash", ""),
                message_count=int(counts.get(channel_id, 0)),
                callerid=ch.metadata.get("callerid"),
                latching=int(ch.metadata["latching"])
                if ch.metadata.get("latching", "").isdigit()
                else None,
                metadata=dict(ch.metadata),
                schema_name=name,
            )
            channels.append(channel)
            self._by_id[channel_id] = channel
        self.channels = tuple(channels)
        if summary.statistics and summary.statistics.message_count:
            self.start_ns = int(summary.statistics.message_start_time)
            self.end_ns = int(summary.statistics.message_end_time)

    def messages(self, topics: set[str] | None) -> Iterator[RawMessage]:
        by_id = self._by_id
        for _schema, ch, msg in self.reader.iter_messages(topics=topics, log_time_order=True):
            yield RawMessage(by_id[ch.id], msg.log_time, msg.data, msg.publish_time, msg.sequence)

    def close(self) -> None:
        if self.stream is not None:
            self.stream.close()
            self.stream = None
        self.reader = None
