"""The session's outputs, opened before its first message: the output log (its writer, and its
connections: the input's channels and the derived topics) and the Rerun recording; and the line that
says why a recording could not be finished."""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from rose.limits import short
from rose.outputs import OutputSet
from rose_logs.derived import derived_topics
from rose_logs.errors import LogWriteError
from rose_logs.formats import LogFormat, format_from_path
from rose_logs.reader import LogReader
from rose_logs.session.topics import rose_topics_in
from rose_logs.storage.connections import offered_qos
from rose_logs.storage.records import Channel
from rose_logs.storage.typesys import FLOAT32_TYPE, MAP_TYPE, MARKER_ARRAY_TYPE
from rose_logs.writer import LogWriter

__all__ = [
    "DERIVED_CALLERID",
    "output_writer",
    "prepare_output",
    "rerun_failure",
    "rerun_sink",
]

if TYPE_CHECKING:
    from rose_logs.rerun import RerunSink

#: The ROS 1 publisher (``callerid``) of the topics rose-bag adds to a log.
DERIVED_CALLERID = "/rose_bag"


def output_writer(
    reader: LogReader,
    input_path: Path,
    output_path: Path | None,
    output_format: LogFormat | None,
    *,
    force: bool,
    outputs: OutputSet | None = None,
) -> LogWriter | None:
    """The (unopened) output log: the input's serialisation and QoS spelling, the input protected."""
    if output_path is None:
        return None
    fmt = output_format or format_from_path(output_path) or reader.format
    return LogWriter(
        output_path,
        fmt,
        serialization=reader.serialization,
        force=force,
        protected=(input_path,),
        qos_style=reader.qos_style,
        outputs=outputs,
    )


def rerun_sink(
    input_path: Path,
    rrd_path: Path | None,
    map_topics: Sequence[str],
    *,
    spawn: bool,
    connect: str | None,
    recording_id: str | None,
    start_ns: int,
    failure_level: float,
    shown_as: Path | str | None = None,
) -> RerunSink:
    """The Rerun recording of a session: one entity root per map topic; the id ``recording_id``, else
    derived from the input's full path and content (:func:`rose_logs.rerun.recording_id_for`).
    ``shown_as``: the recording's name in errors (the user's path, when ``rrd_path`` is where it is
    staged)."""
    _check_files_for_rerun(shown_as or rrd_path or connect or "Rerun viewer")  # before it loads
    if rrd_path is not None:
        _check_file_size_for_rerun(shown_as or rrd_path)
    from rose_logs.rerun import RerunSink, recording_id_for  # rerun loads only when used
    from rose_logs.rerun.paths import entity_root_for_topic
    from rose_logs.rerun.viewer import ViewerNotStarted, viewer_unreachable

    roots: dict[str, str] = {}
    for topic in map_topics:
        other = roots.setdefault(entity_root_for_topic(topic), topic)
        if other != topic:  # /map and /Map, or /map and /map/: one set of Rerun entities
            msg = (
                f"{input_path}: map topics {other} and {topic} would both be recorded under the "
                f"Rerun entity {entity_root_for_topic(topic)}; pick one with --topic"
            )
            raise LogWriteError(msg)
    if connect is not None:
        try:
            reason = viewer_unreachable(connect)
        except ValueError as err:  # not an address
            raise LogWriteError(f"{connect}: cannot open the Rerun recording ({err})") from err
        if reason is not None:
            raise LogWriteError(rerun_failure(None, connect, OSError(reason)))
    if spawn and _no_display():
        # The spawned viewer would die at once and the session fail only at its final flush.
        msg = (
            "--spawn needs a display for the Rerun viewer (DISPLAY and WAYLAND_DISPLAY are unset); "
            "save a recording with --rrd FILE, or stream to a viewer elsewhere with --connect ADDR"
        )
        raise LogWriteError(msg)
    try:
        return RerunSink(
            rrd_path=None if rrd_path is None else Path(rrd_path),
            spawn=spawn,
            connect=connect,
            topics=map_topics,
            recording_id=recording_id or recording_id_for(input_path),
            start_ns=start_ns,
            failure_level=failure_level,
        )
    except ViewerNotStarted as err:
        msg = (
            f"--spawn: {err}; save a recording with --rrd FILE, or stream to a viewer elsewhere "
            "with --connect ADDR"
        )
        raise LogWriteError(msg) from err
    except (ValueError, OSError, RuntimeError) as err:
        where = shown_as or rrd_path or connect or "Rerun viewer"
        msg = f"{where}: cannot open the Rerun recording ({err})"
        raise LogWriteError(msg) from err


#: Open files Rerun's native side needs beyond ours (its runtime's epoll, event and signal pipes,
#: the recording, the sockets): with fewer, it panics and aborts the process (exit 134, a Rust
#: backtrace, the session's temporary outputs left behind) or fails in warnings.
RERUN_FILES = 8


def _open_files() -> int | None:
    """How many files this process has open (None: not known here)."""
    for folder in ("/proc/self/fd", "/dev/fd"):
        try:
            return sum(1 for _ in Path(folder).iterdir()) - 1  # less the listing's own
        except FileNotFoundError:
            continue
        except OSError:  # EMFILE: no file left to list them with, all are open
            return _soft_open_files_limit()
    return None


def _soft_open_files_limit() -> int | None:
    try:
        import resource
    except ImportError:  # Windows
        return None
    soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    return None if soft == resource.RLIM_INFINITY else int(soft)


def _check_files_for_rerun(where: object) -> None:
    """Refuse, in one line and before Rerun loads, a limit of open files (``ulimit -n``) that leaves
    Rerun fewer than :data:`RERUN_FILES`, after raising the soft limit towards the hard one."""
    try:
        import resource
    except ImportError:  # Windows
        return
    opened = _open_files()
    if opened is None:
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY or soft - opened >= RERUN_FILES:
        return
    wanted = opened + RERUN_FILES
    if hard == resource.RLIM_INFINITY or hard >= wanted:
        try:
            resource.setrlimit(resource.RLIMIT_NOFILE, (wanted, hard))
        except (OSError, ValueError):
            pass
        else:
            return
    msg = (
        f"{where}: cannot open the Rerun recording (too few open files allowed: {opened} open of "
        f"at most {soft}, ulimit -n; Rerun needs about {RERUN_FILES} more)"
    )
    raise LogWriteError(msg)


#: The fewest bytes a recording file may be allowed to grow to (``ulimit -f``): its header and
#: static data. Under a limit that its first write passes, a larger recording fails as it grows,
#: in one line; under one that its first write fails (``ulimit -f 1``), Rerun waited for its
#: dead file writer for ever and the run hung, deaf to SIGTERM.
MIN_RECORDING_BYTES = 64 * 1024


def _check_file_size_for_rerun(where: object) -> None:
    """Refuse, in one line, a limit of the size of written files below :data:`MIN_RECORDING_BYTES`."""
    limit = _file_size_limit()
    if limit is not None and limit < MIN_RECORDING_BYTES:
        msg = (
            f"{where}: cannot write the Rerun recording (files written are limited to {limit} "
            "bytes, ulimit -f)"
        )
        raise LogWriteError(msg)


def _file_size_limit() -> int | None:
    """The soft limit of the size of written files in bytes (``ulimit -f``); None when none."""
    try:
        import resource
    except ImportError:  # Windows
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    return None if soft == resource.RLIM_INFINITY else int(soft)


def prepare_output(
    writer: LogWriter | None,
    channels: Sequence[Channel],
    map_topics: Sequence[str],
    input_path: Path,
    *,
    replace: bool = False,
) -> tuple[dict[int, int], dict[str, tuple[int, int, int]]]:
    """Output connections: input channel id -> handle, and map topic -> derived handles.

    The input's own ``<map>/rose/*`` channels (:func:`rose_topics_in`: of every map in it, analysed
    or not) refuse it without ``replace`` (the output would hold results of two runs, with two sets
    of options); with ``replace`` they get no handle (their messages are left out:
    :meth:`rose_logs.session.loop._Loop._copy`), and the analysed maps' are written anew: the
    output of the log as it was before any run.
    """
    if writer is None:
        return {}, {}
    first_of: dict[str, str] = {}
    for c in channels:
        if c.message_encoding in {"ros1", "cdr"}:
            first_of.setdefault(c.message_encoding, c.topic)
    if len(first_of) > 1:
        msg = (
            f"{input_path}: mixes ROS 1 and ROS 2 messages ({first_of['ros1']} and "
            f"{first_of['cdr']}, as a merged MCAP file may); an output log holds one kind: "
            "--no-output reads it, or write each kind's topics from a log of their own"
        )
        raise LogWriteError(msg)
    earlier = rose_topics_in(channels, map_topics)
    if earlier and not replace:
        msg = (
            f"{input_path}: has topic {earlier[0]} already (processed before?); "
            "--replace-rose-topics leaves it out and writes this run's"
        )
        raise LogWriteError(msg)
    left_out = set(earlier)
    handles = {c.id: writer.add_channel(c) for c in channels if c.topic not in left_out}
    derived = {}
    owners: dict[str, str] = {}  # derived topic -> the map topic it is made from
    for topic in map_topics:
        names = derived_topics(topic)
        for name in names.names:
            if name in owners:  # /map and /map/ (a trailing slash is dropped)
                msg = (
                    f"{input_path}: map topics {owners[name]} and {topic} would both be written "
                    f"to {name}; pick one with --topic"
                )
                raise LogWriteError(msg)
            owners[name] = topic
        source = next(c for c in channels if c.topic == topic)
        qos = offered_qos(source)
        latched = (
            bool(source.latching)
            or any(q.durability.name == "TRANSIENT_LOCAL" for q in qos)
            or "transient_local" in source.metadata.get("offered_qos_profiles", "")
        )
        # Published by rose-bag, not by the map's node (ROS 1 names the publisher of every
        # connection: /map/rose/* were the SLAM node's, also for another node's maps on /map).
        derived[topic] = (
            writer.add_topic(
                names.cleaned,
                MAP_TYPE,
                latching=latched,
                qos=qos or None,
                callerid=DERIVED_CALLERID,
            ),
            writer.add_topic(names.structure_score, FLOAT32_TYPE, callerid=DERIVED_CALLERID),
            writer.add_topic(
                names.walls, MARKER_ARRAY_TYPE, latching=latched, callerid=DERIVED_CALLERID
            ),
        )
    return handles, derived


def _no_display() -> bool:
    """Linux or BSD without an X11 or Wayland display (macOS and Windows always have one)."""
    if sys.platform.startswith(("darwin", "win")):
        return False
    return not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def rerun_failure(
    rrd_path: Path | str | None,
    connect: str | None,
    err: BaseException,
    *,
    written: int | None = None,
) -> str:
    """One line for a Rerun recording that could not be finished, naming where it was going
    (``written``: bytes of its partial file, None when unknown; a
    :class:`~rose_logs.rerun.viewer.ViewerLost` names the viewer, the file being whole)."""
    from rose_logs.rerun.viewer import ViewerLost  # no Rerun import

    if rrd_path is not None and not isinstance(err, ViewerLost):
        # Rerun says only that its file writer stopped; a full disk is the usual reason.
        why = f"{short(err, 160)}{_full(Path(rrd_path))}{_limited(written)}"
        return f"{rrd_path}: cannot write the Rerun recording ({why})"
    viewer = f"the Rerun viewer at {connect}" if connect is not None else "the spawned Rerun viewer"
    return f"cannot stream to {viewer}; is it running? ({short(err, 160)})"


#: A partial recording this close to ``ulimit -f`` (or closer) stopped at the limit: the kernel
#: fills a file up to it before the write that would pass it fails.
_AT_LIMIT_BYTES = 1 << 20


def _limited(written: int | None) -> str:
    """``"; files written are limited to 2048000 bytes (ulimit -f)"`` when a partial file of
    ``written`` bytes (None: unknown) reached such a limit, else ``""`` (a recording that failed
    far below a generous limit failed for another reason)."""
    limit = _file_size_limit()
    if limit is None or (written is not None and written < limit - _AT_LIMIT_BYTES):
        return ""
    return f"; files written are limited to {limit} bytes (ulimit -f)"


def _full(path: Path) -> str:
    """``"; its file system is full (12 kB free)"`` when less than a MiB is free where ``path``
    goes (the recording's partial file is still there), else ``""``."""
    try:
        stat = os.statvfs(path.parent)
    except (OSError, AttributeError):  # no such folder any more; statvfs is POSIX only
        return ""
    free = stat.f_bavail * stat.f_frsize
    return f"; its file system is full ({free // 1000} kB free)" if free < 2**20 else ""
