"""Write logs in any supported format: raw copies of input channels and new topics, atomically.

Formats (``fmt``), the same names as :data:`rose_logs.reader.LogFormat`:

- ``"ros1"``: ROS 1 bag file (rosbags), ROS 1 serialisation;
- ``"db3"``: ROS 2 bag folder with sqlite3 storage (rosbags), CDR;
- ``"mcap-dir"``: ROS 2 bag folder with MCAP storage (rosbags), CDR;
- ``"mcap"``: a bare MCAP file (the ``mcap`` package), profile ``ros2`` for CDR or ``ros1`` for ROS 1
  serialisation.

Everything is written to a hidden temporary path next to the output and renamed onto it by
:meth:`LogWriter.close`; :meth:`LogWriter.abort` (or an exception inside ``with``) removes it, so an
interrupted run never leaves a half-written file under the output name.

Example: a new session from scratch (what a converter does)::

    from rose_logs.writer import open_output

    with open_output(Path("run.mcap"), "mcap") as out:
        types = out.typestore.types
        out.add_topic("/map", "nav_msgs/msg/OccupancyGrid", latching=True)
        out.add_topic("/scan", "sensor_msgs/msg/LaserScan")
        out.write("/scan", t_ns, types["sensor_msgs/msg/LaserScan"](...))  # serialised for you
        out.write("/map", t_ns, raw_bytes)                                 # or already serialised

Copying a log (what ``rose-bag process`` does) uses :meth:`LogWriter.add_channel`, which keeps the input's
type, definition, hash, QoS / latching and MCAP channel metadata, and :meth:`LogWriter.write_raw`.
"""

from __future__ import annotations

import logging
import os
import shutil
from collections.abc import Sequence
from io import StringIO
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO, Self

from rosbags.interfaces import Qos

from rose_logs.errors import LogWriteError
from rose_logs.messages import msgdef_for, typestore_for
from rose_logs.reader import Channel, LogFormat, ros1_msgtype

__all__ = [
    "FORMATS",
    "LogWriter",
    "format_from_path",
    "offered_qos",
    "open_output",
    "transient_local_qos",
]

_LOG = logging.getLogger(__name__)

FORMATS: tuple[LogFormat, ...] = ("ros1", "db3", "mcap", "mcap-dir")
_SEPARATOR = "=" * 80


def format_from_path(path: Path) -> LogFormat | None:
    """Format implied by an output name: ``.bag`` -> ros1, ``.mcap`` -> mcap, ``.db3`` -> db3, else None."""
    return {".bag": "ros1", ".mcap": "mcap", ".db3": "db3"}.get(Path(path).suffix.lower())  # type: ignore[return-value]


def transient_local_qos(depth: int = 1) -> Qos:
    """The QoS a latched ROS 2 map publisher offers (reliable, transient local, keep last ``depth``)."""
    from rosbags.interfaces import QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    zero = QosTime(sec=0, nsec=0)
    return Qos(
        history=QosHistory.KEEP_LAST,
        depth=depth,
        reliability=QosReliability.RELIABLE,
        durability=QosDurability.TRANSIENT_LOCAL,
        deadline=zero,
        lifespan=zero,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=zero,
        avoid_ros_namespace_conventions=False,
    )


def _is_within(a: Path, b: Path) -> bool:
    return a == b or b in a.parents


class LogWriter:
    """A new log at ``path``, written through a temporary path and renamed on :meth:`close`.

    Parameters
    ----------
    path : Path
        Output file (``ros1``, ``mcap``) or folder (``db3``, ``mcap-dir``).
    fmt : {"ros1", "db3", "mcap", "mcap-dir"}
        Storage format.
    serialization : {"ros1", "cdr"}, optional
        Serialisation of the messages; default ``"ros1"`` for ``fmt="ros1"``, ``"cdr"`` otherwise. Only
        ``"mcap"`` accepts both.
    force : bool, default False
        Replace an existing ``path`` (only once the new log is complete).
    protected : sequence of Path, default ()
        Paths that must never be written or replaced (the input log); ``path`` may not equal, contain or
        lie inside any of them.

    Raises
    ------
    LogWriteError
        On an unknown format, a format / serialisation mismatch, an existing output without ``force``,
        a protected path, or a missing or unwritable output folder.
    """

    def __init__(
        self,
        path: Path,
        fmt: LogFormat,
        *,
        serialization: str | None = None,
        force: bool = False,
        protected: Sequence[Path] = (),
    ) -> None:
        self.path = Path(path)
        if fmt not in FORMATS:
            msg = (
                f"{self.path}: unknown output format {fmt!r} (expected one of {', '.join(FORMATS)})"
            )
            raise LogWriteError(msg)
        serialization = serialization or ("ros1" if fmt == "ros1" else "cdr")
        if serialization not in {"ros1", "cdr"}:
            msg = f"{self.path}: serialization must be 'ros1' or 'cdr', got {serialization!r}"
            raise LogWriteError(msg)
        if (fmt == "ros1") != (serialization == "ros1") and fmt != "mcap":
            kind = "ROS 1" if serialization == "ros1" else "ROS 2 (CDR)"
            msg = f"{self.path}: cannot store {kind} messages in format {fmt!r}; use 'mcap' or " + (
                "'ros1'" if serialization == "ros1" else "'db3' / 'mcap-dir'"
            )
            raise LogWriteError(msg)
        self.format: LogFormat = fmt
        self.serialization = serialization
        resolved = self.path.resolve()
        for other in protected:
            other_resolved = Path(other).resolve()
            if _is_within(resolved, other_resolved) or _is_within(other_resolved, resolved):
                msg = f"{self.path}: refusing to write over the input {other}"
                raise LogWriteError(msg)
        if self.path.exists() and not force:
            msg = f"{self.path}: exists already (use --force to replace it)"
            raise LogWriteError(msg)
        parent = resolved.parent
        if not parent.is_dir():
            msg = f"{self.path}: folder {parent} does not exist"
            raise LogWriteError(msg)
        if not os.access(parent, os.W_OK | os.X_OK):
            msg = f"{self.path}: folder {parent} is not writable"
            raise LogWriteError(msg)
        self.force = force
        # A hidden staging folder next to the output holds the log under its final name (ROS 2 writers
        # name the storage file after the folder), then one rename moves it into place.
        self.stage_path = parent / f".{self.path.name}.rose-tmp-{os.getpid()}"
        self.tmp_path = self.stage_path / self.path.name
        self._backend: _Backend | None = None
        self._topics: dict[str, int] = {}

    # -- lifecycle -------------------------------------------------------------------------------
    def open(self) -> None:
        """Create the temporary output.

        Raises
        ------
        LogWriteError
            If it cannot be created.
        """
        _remove(self.stage_path)
        try:
            self.stage_path.mkdir()
        except OSError as err:
            msg = f"{self.path}: cannot write in {self.stage_path.parent} ({err.strerror})"
            raise LogWriteError(msg) from err
        backend: _Backend
        if self.format == "ros1":
            backend = _Ros1Backend(self.tmp_path)
        elif self.format == "mcap":
            backend = _McapBackend(self.tmp_path, self.serialization)
        else:
            backend = _Ros2Backend(self.tmp_path, self.format)
        try:
            backend.open()
        except Exception as err:
            backend.abort()
            _remove(self.stage_path)
            msg = f"{self.path}: cannot create output ({err})"
            raise LogWriteError(msg) from err
        self._backend = backend

    def close(self) -> None:
        """Finish the log and move it to ``path`` (replacing an existing one when ``force``).

        Raises
        ------
        LogWriteError
            If finishing or renaming fails; the temporary output is removed.
        """
        backend = self._require_open()
        self._backend = None
        try:
            backend.close()
            if self.path.exists() or self.path.is_symlink():
                if not self.force:
                    msg = f"{self.path}: appeared while writing, not replacing it"
                    raise LogWriteError(msg)
                if self.path.is_dir() and not self.path.is_symlink():
                    backup = self.path.with_name(f".{self.path.name}.rose-old-{os.getpid()}")
                    self.path.rename(backup)
                    self.tmp_path.rename(self.path)
                    shutil.rmtree(backup)
                    _remove(self.stage_path)
                    return
                if self.tmp_path.is_dir():
                    self.path.unlink()
            self.tmp_path.replace(self.path)
            _remove(self.stage_path)
        except LogWriteError:
            _remove(self.stage_path)
            raise
        except Exception as err:
            _remove(self.stage_path)
            msg = f"{self.path}: cannot finish output ({err})"
            raise LogWriteError(msg) from err

    def abort(self) -> None:
        """Drop everything written so far (idempotent); ``path`` is left as it was."""
        if self._backend is not None:
            self._backend.abort()
            self._backend = None
        _remove(self.stage_path)

    def __enter__(self) -> Self:
        self.open()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def _require_open(self) -> _Backend:
        if self._backend is None:
            msg = f"{self.path}: writer is not open"
            raise LogWriteError(msg)
        return self._backend

    # -- connections -----------------------------------------------------------------------------
    @property
    def typestore(self) -> Any:
        """rosbags typestore of this writer's serialisation (build messages with ``.types[...]``)."""
        return typestore_for(self.serialization)

    def add_channel(self, channel: Channel) -> int:
        """Add a connection that copies ``channel`` of an input log; returns its handle for :meth:`write_raw`.

        Type, definition, hash, QoS / latching / caller id and MCAP channel metadata are kept.

        Raises
        ------
        LogWriteError
            If the channel's serialisation does not fit this writer.
        """
        backend = self._require_open()
        if channel.message_encoding != self.serialization and (
            self.format != "mcap" or channel.message_encoding in {"ros1", "cdr"}
        ):
            msg = (
                f"{self.path}: topic {channel.topic} is {channel.message_encoding!r}-encoded, "
                f"format {self.format!r} holds {self.serialization!r} messages"
            )
            raise LogWriteError(msg)
        handle = backend.add(channel)
        self._topics.setdefault(channel.topic, handle)
        return handle

    def add_topic(
        self,
        topic: str,
        msgtype: str,
        *,
        latching: bool = False,
        qos: Sequence[Qos] | None = None,
        callerid: str | None = None,
    ) -> int:
        """Add a new topic of a type the typestore knows; returns its handle.

        Parameters
        ----------
        topic : str
            Topic name; must not exist yet in this writer.
        msgtype : str
            ``pkg/msg/Name`` (ROS 1 names ``pkg/Name`` are accepted).
        latching : bool, default False
            ROS 1: latched connection. ROS 2: offer transient-local QoS (unless ``qos`` is given).
        qos : sequence of Qos, optional
            ROS 2 offered QoS profiles.
        callerid : str, optional
            ROS 1 publishing node.
        """
        from rose_logs.reader import normalize_msgtype

        if topic in self._topics:
            msg = f"{self.path}: topic {topic} exists already in the output"
            raise LogWriteError(msg)
        msgtype = normalize_msgtype(msgtype)
        try:
            msgdef, digest = msgdef_for(msgtype, self.serialization)
        except Exception as err:
            msg = f"{self.path}: unknown message type {msgtype} for topic {topic}"
            raise LogWriteError(msg) from err
        ros1 = self.serialization == "ros1"
        profiles = tuple(qos) if qos is not None else ((transient_local_qos(),) if latching else ())
        channel = Channel(
            id=-1,
            topic=topic,
            msgtype=msgtype,
            message_encoding=self.serialization,
            msgdef=msgdef,
            msgdef_encoding="ros1msg" if ros1 else "ros2msg",
            digest=digest,
            callerid=callerid if ros1 else None,
            latching=(1 if latching else 0) if ros1 else None,
            offered_qos_profiles=() if ros1 else profiles,
        )
        return self.add_channel(channel)

    def has_topic(self, topic: str) -> bool:
        """Whether ``topic`` was added (by :meth:`add_topic` or :meth:`add_channel`)."""
        return topic in self._topics

    # -- messages --------------------------------------------------------------------------------
    def write_raw(
        self,
        handle: int,
        log_time_ns: int,
        data: bytes | memoryview,
        *,
        publish_time_ns: int | None = None,
        sequence: int = 0,
    ) -> None:
        """Write one serialised message, byte for byte, on the connection ``handle``.

        ``publish_time_ns`` and ``sequence`` are kept by MCAP only (publish time defaults to the log time).
        """
        backend = self._require_open()
        backend.write(
            handle,
            int(log_time_ns),
            data,
            int(log_time_ns if publish_time_ns is None else publish_time_ns),
            sequence,
        )

    def write(self, topic: str, log_time_ns: int, message: Any) -> None:
        """Write a message on ``topic``: serialised bytes as they are, a typestore object serialised.

        Raises
        ------
        LogWriteError
            If ``topic`` was never added.
        """
        handle = self._topics.get(topic)
        if handle is None:
            msg = f"{self.path}: topic {topic} was not added (call add_topic first)"
            raise LogWriteError(msg)
        if not isinstance(message, bytes | bytearray | memoryview):
            msgtype = message.__msgtype__
            store = self.typestore
            if self.serialization == "ros1":
                message = store.serialize_ros1(message, msgtype)
            else:
                message = store.serialize_cdr(message, msgtype)
        self.write_raw(handle, log_time_ns, message)


def open_output(
    path: Path,
    fmt: LogFormat,
    *,
    serialization: str | None = None,
    force: bool = False,
    protected: Sequence[Path] = (),
) -> LogWriter:
    """A :class:`LogWriter` to use as a context manager (see the module docstring for an example)."""
    return LogWriter(path, fmt, serialization=serialization, force=force, protected=protected)


def _remove(path: Path) -> None:
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif path.exists() or path.is_symlink():
            path.unlink()
    except OSError:
        _LOG.warning("could not remove temporary output %s", path)


# -- message definitions -------------------------------------------------------------------------
def _definitions(channel: Channel, ros_version: int) -> tuple[str, str]:
    """``(msgdef, digest)`` for an output connection of ``channel``; computed when the input lacked one."""
    serialization = "ros1" if ros_version == 1 else "cdr"
    wanted = "ros1msg" if ros_version == 1 else "ros2"
    if channel.msgdef and channel.digest and channel.msgdef_encoding.startswith(wanted):
        return channel.msgdef, channel.digest
    if channel.msgdef and channel.msgdef_encoding.startswith(wanted):
        try:
            from rosbags.typesys import Stores, get_types_from_msg, get_typestore

            store = get_typestore(Stores.EMPTY)
            for name, text in _split_msgdef(channel.msgtype, channel.msgdef):
                store.register(get_types_from_msg(text, name))
            if ros_version == 1:
                return store.generate_msgdef(channel.msgtype)
            return channel.msgdef, store.hash_rihs01(channel.msgtype)
        except Exception:  # fall back to the built-in definitions below
            _LOG.debug("could not hash the definition of %s", channel.msgtype, exc_info=True)
    try:
        return msgdef_for(channel.msgtype, serialization)
    except Exception as err:
        msg = f"no usable message definition for {channel.msgtype} on {channel.topic}"
        raise LogWriteError(msg) from err


def _split_msgdef(msgtype: str, text: str) -> list[tuple[str, str]]:
    from rose_logs.reader import normalize_msgtype

    parts = [(msgtype, "")]
    for line in text.splitlines():
        if line.strip() == _SEPARATOR:
            parts.append(("", ""))
        elif line.startswith("MSG: ") and not parts[-1][0]:
            parts[-1] = (normalize_msgtype(line[5:].strip()), "")
        else:
            name, body = parts[-1]
            parts[-1] = (name, body + line + "\n")
    return [(n, b) for n, b in parts if n]


def _qos_yaml(profiles: Sequence[Qos]) -> str:
    from rosbags.rosbag2.metadata import dump_qos_v9
    from ruamel.yaml import YAML

    if not profiles:
        return ""
    stream = StringIO()
    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    yaml.dump(dump_qos_v9(list(profiles)), stream)
    return stream.getvalue().strip()


def offered_qos(channel: Channel) -> list[Qos]:
    """ROS 2 QoS profiles of ``channel``, from a ROS 2 bag or parsed from MCAP channel metadata."""
    if channel.offered_qos_profiles:
        return list(channel.offered_qos_profiles)
    text = channel.metadata.get("offered_qos_profiles", "")
    if text:
        from rosbags.rosbag2.metadata import parse_qos

        try:
            return parse_qos(text)
        except Exception:  # QoS is metadata; a bad string must not stop the copy
            _LOG.warning("%s: unreadable offered_qos_profiles, not copied", channel.topic)
    return []


# -- backends ------------------------------------------------------------------------------------
class _Backend:
    def open(self) -> None: ...
    def add(self, channel: Channel) -> int: ...  # type: ignore[empty-body]
    def write(
        self, handle: int, log_time_ns: int, data: bytes | memoryview, publish_ns: int, seq: int
    ) -> None: ...
    def close(self) -> None: ...
    def abort(self) -> None: ...


class _RosbagsBackendBase(_Backend):
    ros_version: int

    def __init__(self, path: Path) -> None:
        self.path = path
        self.writer: Any = None
        self.connections: list[Any] = []

    def add(self, channel: Channel) -> int:
        msgdef, digest = _definitions(channel, self.ros_version)
        return self._dedup(
            (channel.topic, channel.msgtype),
            lambda: self._add_connection(channel, msgdef, digest),
        )

    def _add_connection(self, channel: Channel, msgdef: str, digest: str) -> Any:
        """Register ``channel`` with the rosbags writer; return the new connection."""
        raise NotImplementedError

    def _dedup(self, conn_args: tuple[Any, ...], create: Any) -> int:
        try:
            self.connections.append(create())
        except Exception as err:
            if "once" not in str(err):
                raise
            # The same connection twice (a ROS 1 node that reconnected): share the existing one.
            for existing in list(self.connections):
                if (existing.topic, existing.msgtype) == conn_args:
                    self.connections.append(existing)
                    return len(self.connections) - 1
            raise
        return len(self.connections) - 1

    def write(
        self, handle: int, log_time_ns: int, data: bytes | memoryview, publish_ns: int, seq: int
    ) -> None:
        self.writer.write(self.connections[handle], log_time_ns, data)

    def close(self) -> None:
        self.writer.close()

    def abort(self) -> None:
        if self.writer is not None:
            try:
                self.writer.close()
            except Exception:  # the output is deleted anyway
                _LOG.debug("closing an aborted writer failed", exc_info=True)
            self.writer = None


class _Ros1Backend(_RosbagsBackendBase):
    ros_version = 1

    def open(self) -> None:
        from rosbags.rosbag1 import Writer

        self.writer = Writer(self.path)
        self.writer.open()

    def _add_connection(self, channel: Channel, msgdef: str, digest: str) -> Any:
        return self.writer.add_connection(
            channel.topic,
            channel.msgtype,
            msgdef=msgdef,
            md5sum=digest,
            callerid=channel.callerid,
            latching=channel.latching,
        )


class _Ros2Backend(_RosbagsBackendBase):
    ros_version = 2

    def __init__(self, path: Path, fmt: LogFormat) -> None:
        super().__init__(path)
        self.format = fmt

    def open(self) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if self.format == "mcap-dir" else StoragePlugin.SQLITE3
        self.writer = Writer(self.path, version=9, storage_plugin=plugin)
        self.writer.open()

    def _add_connection(self, channel: Channel, msgdef: str, digest: str) -> Any:
        return self.writer.add_connection(
            channel.topic,
            channel.msgtype,
            msgdef=msgdef,
            rihs01=digest or "RIHS01_" + "0" * 64,
            serialization_format=channel.message_encoding,
            offered_qos_profiles=offered_qos(channel),
        )


class _McapBackend(_Backend):
    def __init__(self, path: Path, serialization: str) -> None:
        self.path = path
        self.serialization = serialization
        self.stream: BinaryIO | None = None
        self.writer: Any = None
        self.schemas: dict[tuple[str, str, str], int] = {}
        self.channels: list[int] = []

    def open(self) -> None:
        from mcap.writer import Writer

        self.stream = self.path.open("wb")
        self.writer = Writer(self.stream)
        self.writer.start(
            profile="ros1" if self.serialization == "ros1" else "ros2", library="rose-bag"
        )

    def add(self, channel: Channel) -> int:
        ros1 = channel.message_encoding == "ros1"
        if channel.schema_name or channel.message_encoding not in {"ros1", "cdr"}:
            name, encoding, data = channel.schema_name, channel.msgdef_encoding, channel.msgdef
        else:
            data, _digest = _definitions(channel, 1 if ros1 else 2)
            name = ros1_msgtype(channel.msgtype) if ros1 else channel.msgtype
            encoding = "ros1msg" if ros1 else (channel.msgdef_encoding or "ros2msg")
        key = (name, encoding, data)
        schema_id = self.schemas.get(key)
        if schema_id is None:
            schema_id = self.writer.register_schema(name, encoding, data.encode("utf-8"))
            self.schemas[key] = schema_id
        metadata = dict(channel.metadata)
        if not metadata:
            if ros1:
                if channel.callerid is not None:
                    metadata["callerid"] = channel.callerid
                if channel.latching is not None:
                    metadata["latching"] = str(int(channel.latching))
                if channel.digest:
                    metadata["md5sum"] = channel.digest
            else:
                qos = _qos_yaml(offered_qos(channel))
                if qos:
                    metadata["offered_qos_profiles"] = qos
        channel_id = self.writer.register_channel(
            channel.topic, channel.message_encoding, schema_id, metadata
        )
        self.channels.append(channel_id)
        return len(self.channels) - 1

    def write(
        self, handle: int, log_time_ns: int, data: bytes | memoryview, publish_ns: int, seq: int
    ) -> None:
        self.writer.add_message(self.channels[handle], log_time_ns, data, publish_ns, seq)

    def close(self) -> None:
        self.writer.finish()
        if self.stream is not None:
            self.stream.close()
            self.stream = None

    def abort(self) -> None:
        if self.stream is not None:
            self.stream.close()
            self.stream = None
        self.writer = None
