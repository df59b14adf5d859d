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

import contextlib
import logging
import os
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, NoReturn, Self

from rosbags.interfaces import Qos

from rose.errors import OutputError
from rose.limits import short
from rose.outputs import OutputSet
from rose_logs.errors import LogWriteError
from rose_logs.formats import FORMATS, LogFormat
from rose_logs.storage.base import WriteBackend
from rose_logs.storage.connections import QosStyle, default_qos, offered_qos, transient_local_qos
from rose_logs.storage.mcap import FileRecords, McapWriteBackend
from rose_logs.storage.records import Channel
from rose_logs.storage.rosbags import Ros1WriteBackend, Ros2WriteBackend
from rose_logs.storage.typesys import msgdef_for, typestore_for

__all__ = ["LogWriter", "offered_qos", "open_output", "transient_local_qos"]

_LOG = logging.getLogger(__name__)


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
    protected : sequence of Path, or one path, default ()
        Paths that must never be written or replaced (the input log); ``path`` may not equal, contain or
        lie inside any of them.
    outputs : rose.outputs.OutputSet, optional
        The run's other outputs: the log is staged there and committed with them by the caller.
        Default: a set of its own, committed by :meth:`close`.
    qos_style : {"v8", "v9"}, optional
        How ROS 2 QoS policies are spelled in the metadata written (``"v8"`` integers, which Humble needs,
        ``"v9"`` names); pass the input's (:attr:`LogReader.qos_style`) so that added topics match copied
        ones. Default ``"v9"``. For ``db3`` / ``mcap-dir`` it also picks the rosbag2 format version (8 or 9).

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
        protected: Sequence[Path] | Path = (),
        outputs: OutputSet | None = None,
        qos_style: QosStyle | None = None,
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
        if qos_style not in {None, "v8", "v9"}:
            msg = f"{self.path}: qos_style must be 'v8' or 'v9', got {qos_style!r}"
            raise LogWriteError(msg)
        self.qos_style: QosStyle = qos_style or "v9"
        self.force = force
        self._directory = fmt in ("db3", "mcap-dir")
        self._own_outputs = outputs is None
        self._outputs = OutputSet(force=force) if outputs is None else outputs
        # One path is one path: a str was protected character by character ("/", "i", ...), and a
        # Path failed as not iterable.
        for other in (protected,) if isinstance(protected, str | os.PathLike) else protected:
            self._outputs.add_input(other)
        try:
            self._outputs.check(self.path, directory=self._directory)
        except OutputError as err:
            raise LogWriteError(str(err)) from err
        parent = self.path.resolve().parent
        if not os.access(parent, os.W_OK | os.X_OK):
            msg = f"{self.path}: folder {parent} is not writable"
            raise LogWriteError(msg)
        # A hidden staging folder next to the output holds the log under its final name (ROS 2 writers
        # name the storage file after the folder); the OutputSet renames it into place.
        self.stage_path: Path | None = None
        self.tmp_path: Path | None = None
        self._backend: WriteBackend | None = None
        self._topics: dict[str, int] = {}
        self._types: dict[str, str] = {}  # topic -> pkg/msg/Name of its first connection

    # -- lifecycle -------------------------------------------------------------------------------
    def open(self) -> None:
        """Create the temporary output.

        Raises
        ------
        LogWriteError
            If it cannot be created.
        """
        try:
            staged = self._outputs.stage(self.path, directory=self._directory)
        except OutputError as err:
            raise LogWriteError(str(err)) from err
        if staged.temp is None:
            msg = f"{self.path}: a log cannot be written to a stream or device"
            raise LogWriteError(msg)
        self.stage_path, self.tmp_path = staged.stage, staged.temp
        backend: WriteBackend
        if self.format == "ros1":
            backend = Ros1WriteBackend(self.tmp_path)
        elif self.format == "mcap":
            backend = McapWriteBackend(self.tmp_path, self.serialization, self.qos_style)
        else:
            backend = Ros2WriteBackend(self.tmp_path, self.format, self.qos_style)
        try:
            backend.open()
        except Exception as err:
            backend.abort()
            self._drop_stage()
            msg = f"{self.path}: cannot create output ({short(err, 160)})"
            raise LogWriteError(msg) from err
        self._backend = backend

    def close(self) -> None:
        """Finish the log; move it to ``path`` unless an :class:`OutputSet` given to ``__init__`` commits it.

        Raises
        ------
        LogWriteError
            If finishing or renaming fails; the temporary output is removed.
        """
        backend = self._require_open()
        self._backend = None
        try:
            backend.close()
            if self._own_outputs:
                self._outputs.commit()
        except BaseException as err:
            self._drop_stage()
            if isinstance(err, LogWriteError | OutputError):
                raise LogWriteError(str(err)) from err
            # Out of memory is said as such, as while writing (the MCAP writer's thread compresses
            # chunks as they fill: its error can come out of the last call).
            if isinstance(err, Exception) and not isinstance(err, MemoryError):
                msg = f"{self.path}: cannot finish output ({short(err, 160)})"
                raise LogWriteError(msg) from err
            raise

    def abort(self) -> None:
        """Drop everything written so far (idempotent); ``path`` is left as it was. Never raises
        ``OSError``: closing what is dropped may flush its buffer onto a full disk, and that error
        would hide the one that made the caller abort."""
        backend, self._backend = self._backend, None
        try:
            if backend is not None:
                with contextlib.suppress(OSError):
                    backend.abort()
        finally:
            self._drop_stage()

    def _drop_stage(self) -> None:
        if self._own_outputs:
            self._outputs.abort()
        elif self.stage_path is not None:
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

    def _require_open(self) -> WriteBackend:
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
        try:
            handle = backend.add(channel)
        except LogWriteError as err:
            raise LogWriteError(f"{self.path}: {err}") from err
        self._topics.setdefault(channel.topic, handle)
        self._types.setdefault(channel.topic, channel.msgtype)
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
            ROS 2 offered QoS profiles; default transient local when ``latching``, else a default
            publisher's (:func:`~rose_logs.storage.connections.default_qos`), so that every ROS 2
            topic written carries a profile.
        callerid : str, optional
            ROS 1 publishing node.
        """
        from rose_logs.storage.records import normalize_msgtype

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
        own = transient_local_qos() if latching else default_qos()
        profiles = tuple(qos) if qos else (own,)
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
        latest = _LATEST_NS.get(self.format, 2**63 - 1)
        # Each time converted once, checked in turn (a call per message, no tuple of pairs).
        log_ns = int(log_time_ns)
        if not 0 <= log_ns <= latest:
            self._outside("log time", log_time_ns, latest)
        if publish_time_ns is None:
            publish_ns = log_ns
        else:
            publish_ns = int(publish_time_ns)
            if not 0 <= publish_ns <= latest:
                self._outside("publish time", publish_time_ns, latest)
        try:
            backend.write(handle, log_ns, data, publish_ns, sequence)
        except OSError as err:  # a full disk, an I/O error: name the output, not the temporary
            msg = f"{self.path}: cannot write ({err.strerror or short(err, 160)})"
            raise LogWriteError(msg) from err

    def _outside(self, name: str, value: int, latest: int) -> NoReturn:
        msg = f"{self.path}: {name} {value} ns is outside what {self.format} stores (0..{latest})"
        raise LogWriteError(msg)

    def add_file_records(self, records: FileRecords) -> None:
        """Copy an MCAP file's metadata and attachment records (:meth:`LogReader.file_records`,
        read one at a time): an MCAP output keeps them; the other formats have no place for them
        (a warning says so).

        Raises
        ------
        LogWriteError
            If they cannot be written.
        """
        backend = self._require_open()
        if not records:
            return
        if not isinstance(backend, McapWriteBackend):
            # (A mcap-dir bag's files could hold them, but rosbags' writer has no way to add
            # them: copying them would take writing the MCAP format by hand.)
            why = (
                "rosbags' writer of a mcap-dir bag cannot add them"
                if self.format == "mcap-dir"
                else f"a {self.format} log has no place for them"
            )
            _LOG.warning(
                "%s: the input's %d MCAP metadata / attachment record(s) are not copied (%s)",
                self.path,
                len(records),
                why,
            )
            return
        try:
            backend.add_file_records(records)
        except OSError as err:  # a full disk, an I/O error: name the output, not the temporary
            msg = f"{self.path}: cannot write ({err.strerror or short(err, 160)})"
            raise LogWriteError(msg) from err

    def add_custom_data(self, data: Mapping[str, str]) -> None:
        """Copy a ROS 2 bag's ``custom_data`` (:attr:`LogReader.custom_data`): a ROS 2 bag output
        keeps it in its metadata.yaml; the other formats have no place for it (a warning says so).
        """
        backend = self._require_open()
        if not data:
            return
        if not isinstance(backend, Ros2WriteBackend):
            _LOG.warning(
                "%s: the input bag's custom_data (%s) is not copied (a %s log has no place for it)",
                self.path,
                short(", ".join(data), 80),
                self.format,
            )
            return
        backend.set_custom_data(data)

    def write(self, topic: str, log_time_ns: int, message: Any) -> None:
        """Write a message on ``topic``: serialised bytes as they are, a typestore object serialised.

        Raises
        ------
        LogWriteError
            If ``topic`` was never added, or ``message`` is an object of another type than the
            topic's.
        """
        handle = self._topics.get(topic)
        if handle is None:
            msg = f"{self.path}: topic {topic} was not added (call add_topic first)"
            raise LogWriteError(msg)
        if not isinstance(message, bytes | bytearray | memoryview):
            from rose_logs.storage.records import normalize_msgtype

            msgtype = getattr(message, "__msgtype__", None)
            expected = self._types[topic]
            if msgtype is None or normalize_msgtype(msgtype) != expected:
                got = msgtype or type(message).__name__
                msg = f"{self.path}: topic {topic} holds {expected}, got a {got} message"
                raise LogWriteError(msg)
            store = self.typestore
            if self.serialization == "ros1":
                message = store.serialize_ros1(message, msgtype)
            else:
                message = store.serialize_cdr(message, msgtype)
        self.write_raw(handle, log_time_ns, message)


#: Latest time each format can store, ns: ROS 1 bags hold unsigned 32-bit seconds, ROS 2 bags signed
#: 64-bit nanoseconds (SQLite integers, metadata.yaml), MCAP unsigned 64-bit nanoseconds.
_LATEST_NS = {"ros1": (2**32 - 1) * 10**9 + 999_999_999, "mcap": 2**64 - 1}


def open_output(
    path: Path,
    fmt: LogFormat,
    *,
    serialization: str | None = None,
    force: bool = False,
    protected: Sequence[Path] | Path = (),
    outputs: OutputSet | None = None,
    qos_style: QosStyle | None = None,
) -> LogWriter:
    """A :class:`LogWriter` to use as a context manager (see the module docstring for an example)."""
    return LogWriter(
        path,
        fmt,
        serialization=serialization,
        force=force,
        protected=protected,
        outputs=outputs,
        qos_style=qos_style,
    )


def _remove(path: Path) -> None:
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif path.exists() or path.is_symlink():
            path.unlink()
    except OSError:
        _LOG.warning("could not remove temporary output %s", path)
