"""Open any supported log and iterate its raw messages in log-time order.

Supported inputs (:func:`detect_format`):

- ``"ros1"``: ROS 1 bag v2.0 (``.bag``), plain or with bz2 / lz4 chunks (rosbags);
- ``"db3"``: ROS 2 bag folder with sqlite3 storage, or a bare ``.db3`` file (rosbags);
- ``"mcap-dir"``: ROS 2 bag folder with MCAP storage (rosbags);
- ``"mcap"``: a bare MCAP file with the ``ros2`` (CDR) or ``ros1`` profile (the ``mcap`` package,
  because rosbags refuses ros1-profile MCAP and the raw reader keeps channel metadata and publish times).

Messages are never decoded here: :class:`RawMessage` carries the serialised bytes, so copying is byte for
byte and memory stays flat in the number of messages. Decoding map messages is :mod:`rose_logs.snapshots`.

An MCAP file written without a summary section (optional in MCAP) is read record by record, its
messages sorted by log time when the file has them out of order. With ``salvage``, an MCAP file whose
end is missing and a ROS 1 bag whose index cannot be used are read record by record from their start
instead (:mod:`rose_logs.storage.mcap`, :mod:`rose_logs.storage.ros1_stream`); MCAP messages come
sorted by log time too, a ROS 1 bag's in file order. A complete MCAP file or ROS 1 bag with a damaged chunk loses
that chunk only: its index leads past it to the chunks after it (an MCAP file of no chunks is
salvaged in file order, up to its damage; a ROS 1 bag is read chunk by chunk through its index's
chunk infos, in rosbags' order, also when rosbags cannot open it for a damaged chunk record or
index entry). A ROS 2 bag folder of MCAP storage is read, when a file of it is damaged, file by
file, each as it would be on its own (:meth:`LogReader._damaged_mcap_storage`,
:meth:`rose_logs.storage.rosbags.RosbagsReadBackend._mcap_around_damaged_chunks`). The files of
a ROS 2 bag split over several are merged by log time, damaged or not (rosbags reads them one
after the other, in metadata.yaml's order, which need not be their time order).
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Collection, Iterable, Iterator
from pathlib import Path, PurePath
from types import TracebackType
from typing import Any, Self

from rose.limits import short
from rose_logs.errors import LogError, LogReadError, reraise_unless_damage
from rose_logs.formats import LogFormat, mcap_cut_short, read_format
from rose_logs.storage.connections import QosStyle
from rose_logs.storage.integrity import FileState
from rose_logs.storage.mcap import (
    DamagedSummaryError,
    FileRecords,
    McapFilesReadBackend,
    McapReadBackend,
    McapStreamReadBackend,
)
from rose_logs.storage.records import Channel, RawMessage
from rose_logs.storage.ros1_stream import (
    IndexDamage,
    Ros1IndexedReadBackend,
    Ros1StreamReadBackend,
    damaged_index,
    first_damaged_chunk,
    unindexed_messages,
)
from rose_logs.storage.rosbags import (
    RosbagsReadBackend,
    bag_custom_data,
    library_text,
    mcap_storage_files,
    rosbags_text,
)

__all__ = ["Channel", "LogReader", "MessageLossError", "RawMessage", "topic_names"]

_LOG = logging.getLogger(__name__)

_Backend = (
    RosbagsReadBackend
    | McapReadBackend
    | McapFilesReadBackend
    | Ros1StreamReadBackend
    | Ros1IndexedReadBackend
)


def _opened(backend: McapStreamReadBackend | Ros1StreamReadBackend) -> bool:
    """Open ``backend``; False (and closed) when even reading from the start fails."""
    try:
        backend.open()
    except Exception as err:
        backend.close()
        reraise_unless_damage(err)
        return False
    return True


def _unsupported(err: BaseException) -> bool:
    """Whether rosbags refused a ROS 1 bag for a feature it does not read (encryption), not for
    damage."""
    return "encryption" in str(err).lower()


def _corrupt(path: Path, err: BaseException) -> LogReadError:
    newer = _NEWER_BAG.search(str(err))
    if newer is not None:  # rosbags's words were "...not supported; please report issue."
        return LogReadError(
            f"{path}: its metadata.yaml is of rosbag2 version {newer.group(1)}, newer than "
            f"rose-bag reads ({_rosbags_reads()})"
        )
    missing = _MISSING_KEY.search(str(err))
    if missing is not None:  # rosbags's words: "A metadata key is missing KeyError('...')."
        return LogReadError(
            f"{path}: its metadata.yaml lacks the key {short(missing.group(1), 80)!r} that "
            "rosbag2 metadata holds (written by hand, or cut short?)"
        )
    absent = _MISSING_FILES.search(str(err))
    if absent is not None:  # rosbags's words: "Some database files are missing: ['/a/b.db3']"
        names = _listed_names(absent.group(1))
        files, are = ("files", "are") if len(names) > 1 else ("file", "is")
        return LogReadError(
            f"{path}: storage {files} {short(', '.join(names), 120)}, listed in its "
            f"metadata.yaml, {are} missing (moved or deleted?)"
        )
    return LogReadError(f"{path}: corrupt or truncated log ({short(library_text(err), 160)})")


def _listed_names(text: str) -> list[str]:
    """The file names in rosbags's list of paths (a Python list's repr; as it is if it is none)."""
    import ast

    try:
        paths = ast.literal_eval(text)
    except (ValueError, SyntaxError, MemoryError, RecursionError):
        return [text]
    if not isinstance(paths, list) or not paths:
        return [text]
    return [PurePath(str(p)).name for p in paths]


#: rosbags's error for a storage file that metadata.yaml lists and the folder lacks.
_MISSING_FILES = re.compile(r"Some database files are missing: (\[.*\])")
#: rosbags's error for a ``metadata.yaml`` version it does not know.
_NEWER_BAG = re.compile(r"Rosbag2 version (\d+) not supported")
#: rosbags's error for a ``metadata.yaml`` without a key it reads.
_MISSING_KEY = re.compile(r"A metadata key is missing KeyError\('([^']*)'\)")


def _rosbags_reads() -> str:
    """Which rosbag2 metadata versions the installed rosbags reads: up to the one it writes."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        from rosbags.rosbag2.writer import Writer

        latest = f"up to version {int(Writer.VERSION_LATEST)}"
    except (ImportError, AttributeError, TypeError, ValueError):
        latest = "older versions"
    try:
        return f"rosbags {version('rosbags')} reads {latest}"
    except PackageNotFoundError:
        return f"rosbags reads {latest}"


def topic_names(topics: Collection[str] | str | None) -> tuple[str, ...] | None:
    """``topics`` as a tuple of names, in order (one name is one topic, not its characters); None
    for every topic.

    Raises
    ------
    TypeError
        If ``topics`` is neither a name nor names (str): ``b"/map"`` was read as the numbers of its
        bytes and matched no topic, silently.
    """
    if topics is None:
        return None
    if isinstance(topics, str):
        return (topics,)
    if isinstance(topics, bytes | bytearray) or not isinstance(topics, Iterable):
        msg = f"topics must be a topic name or names (str), got {type(topics).__name__}"
        raise TypeError(msg)
    names = tuple(topics)
    for name in names:
        if not isinstance(name, str):
            msg = f"topics must be topic names (str), got {name!r} among them"
            raise TypeError(msg)
    return names


class MessageLossError(LogReadError):
    """Fewer messages could be read than the log's index / metadata declares (or a chunk is corrupt)."""


class LogReader:
    """Raw, log-time-ordered access to any supported log.

    Parameters
    ----------
    path : path-like
        Log file or ROS 2 bag folder (str, bytes or path). Never modified.
    salvage : bool, default False
        What to do when messages are lost (a corrupt chunk, a failed MCAP CRC, fewer messages than the
        index / ``metadata.yaml`` / MCAP statistics declare): False raises :class:`MessageLossError`
        from :meth:`messages`; True stops reading there, records the problem in :attr:`losses` and
        ends the iteration normally (the caller must report it).

    Raises
    ------
    TypeError
        If ``path`` is no file name or ``salvage`` not True or False.

    Notes
    -----
    Every message read is counted per channel and, once a full pass ends, compared with the count the
    log declares, so no loss goes unnoticed.
    ``__init__`` only validates; :meth:`open` reads the index. Use as a context manager::

        with LogReader(path) as reader:
            for message in reader.messages():
                ...
    """

    def __init__(self, path: Path, *, salvage: bool = False) -> None:
        if not isinstance(path, str | bytes | os.PathLike):
            msg = f"path must be a log's file or folder name, got {type(path).__name__}"
            raise TypeError(msg)
        if salvage not in (True, False):  # salvage="no" salvaged (numpy's bools are taken)
            msg = f"salvage must be True or False, got {salvage!r}"
            raise TypeError(msg)
        self.path = Path(os.fsdecode(path))
        # The files' states before metadata.yaml is read: a change after it (which rosbags, opening
        # the bag, would read as another bag than the one checked here) is then seen.
        self._states = FileState.of_log(self.path)  # the log's files as read
        # A bag folder's metadata.yaml, read here once for everything after (parsing is slow).
        self.format: LogFormat
        self.format, self._metadata = read_format(self.path)
        self.salvage = salvage
        self.losses: list[str] = []
        self.read_count = 0
        self._backend: _Backend | None = None

    # -- lifecycle -------------------------------------------------------------------------------
    def open(self) -> None:
        """Open the log and read its index.

        Raises
        ------
        LogReadError
            If the log is corrupt, truncated or unsupported.
        """
        backend: _Backend
        backend = (
            McapReadBackend(self.path)
            if self.format == "mcap"
            else RosbagsReadBackend(self.path, self.format, metadata=self._metadata)
        )
        try:
            backend.open()
        except Exception as err:  # library errors of every kind: wrap at the boundary
            backend.close()
            reraise_unless_damage(err)
            changed = self._changed()
            if changed is not None:
                raise LogReadError(changed) from err
            salvaged: (
                McapStreamReadBackend
                | McapFilesReadBackend
                | RosbagsReadBackend
                | Ros1StreamReadBackend
                | Ros1IndexedReadBackend
                | None
            ) = None
            if self.format == "mcap":
                salvaged = self._without_summary(err)
            elif self.format == "ros1":
                salvaged = self._around_damaged_chunks(err)
            elif self.format == "mcap-dir":
                salvaged = self._damaged_mcap_storage(err)
            elif self.format == "db3":
                salvaged = self._around_unopened_files(err)
            if salvaged is None and self.salvage:
                salvaged = self._salvage_stream()
            if salvaged is None:
                # Ours say what is wrong, naming the file; a damaged summary's says only that
                # (record by record, the file did not read to its end either).
                if isinstance(err, LogError) and not isinstance(err, DamagedSummaryError):
                    raise
                raise self._unreadable(err) from err
            backend = salvaged
        if self.salvage and (
            type(backend) is McapReadBackend
            or isinstance(backend, RosbagsReadBackend | McapFilesReadBackend)
        ):
            backend.skip_damaged_chunks = True
        changed = self._changed()
        if changed is not None:  # metadata.yaml rewritten after it was read: rosbags read another
            backend.close()
            raise LogReadError(changed)
        self._backend = backend

    def _unreadable(
        self, err: BaseException, storage: Path | None = None, of_files: int = 1
    ) -> LogReadError:
        """The error for a log that cannot be opened (``err``: the library's); ``storage``: the
        damaged MCAP file of a ROS 2 bag folder, which it names, one of ``of_files``."""
        mcap = self.format == "mcap" or storage is not None
        if not mcap and self.format != "ros1":
            return _corrupt(self.path, err)
        where = storage or self.path
        remedy = (
            "nothing before the damage can be read either"
            if self.salvage
            else "--salvage (process, info, batch) keeps the messages before the damage, if any can be read"
        )
        one_of = f" (one of the bag's {of_files} files)" if of_files > 1 else ""
        if mcap and mcap_cut_short(where):
            # The library reads the footer from wherever the file now ends: its error is about a
            # record length of garbage ("HEADER record has length 29245...").
            return LogReadError(
                f"{where}: truncated MCAP file{one_of}, cut short: its end, which holds the "
                f"index, is missing (a recording that was not closed, or a copy that stopped?); "
                f"{remedy}"
            )
        what = (
            f"MCAP file{one_of}, its index at the end cannot be read"
            if mcap
            else "ROS 1 bag, its index cannot be read (a recording that was not closed?)"
        )
        return LogReadError(
            f"{where}: corrupt or truncated {what} ({short(library_text(err), 120)}); {remedy}"
        )

    def _without_summary(
        self, err: BaseException, storage: Path | None = None
    ) -> McapStreamReadBackend | None:
        """An MCAP file (the log, or ``storage``: a ROS 2 bag folder's) the indexed reader could
        not open (``err``) that is complete all the same (every record up to its footer reads: no
        summary, a damaged one, or no closing magic bytes), read record by record; None when it
        is truncated or damaged instead (the first error stands)."""
        where = storage or self.path
        backend = McapStreamReadBackend(where)
        if not _opened(backend) or not backend.complete:
            backend.close()
            return None
        if isinstance(err, DamagedSummaryError):
            _LOG.warning("%s: %s; read record by record, no message lost", where, err)
        else:
            _LOG.info("%s: no summary section (optional in MCAP): read record by record", where)
        return backend

    def _damaged_mcap_storage(
        self, err: BaseException
    ) -> McapStreamReadBackend | McapFilesReadBackend | Ros1StreamReadBackend | None:
        """A ROS 2 bag folder of MCAP storage that rosbags could not open (``err``) because an
        MCAP file of it is damaged: each damaged file read as it would be on its own (complete
        without a summary: record by record; cut short or damaged: with ``--salvage``, its
        readable start, the loss naming it), else the bare file's error, naming it. rosbags' own
        error ("File end magic is invalid.") named no file and no remedy, and ``--salvage`` kept
        nothing.

        A bag split over several files is read file by file, their messages merged by log time
        (:class:`McapFilesReadBackend`), the intact ones through their index; under ``--salvage`` a file of which nothing can be
        read is a loss naming it, the others are read. None when every MCAP file reads (the
        first error stands: metadata.yaml, or an error of ours, which says what is wrong), and
        when one is missing (rosbags says which)."""
        if isinstance(err, LogError):
            return None
        files = mcap_storage_files(self.path, self._metadata)
        if not all(storage.is_file() for storage in files):
            return None  # rosbags' error names the files that are missing
        probes: list[tuple[Path, McapReadBackend | None, BaseException | None]] = []
        parts: list[McapReadBackend] = []
        try:
            for storage in files:
                probe = McapReadBackend(storage)
                try:
                    probe.open()
                except Exception as failure:  # this file is a damaged one
                    probe.close()
                    reraise_unless_damage(failure)
                    probes.append((storage, None, failure))
                else:
                    probes.append((storage, probe, None))
            if all(probe is not None for _, probe, _ in probes):
                for _, opened, _ in probes:
                    assert opened is not None
                    opened.close()
                return None
            if len(files) == 1:
                storage, _, damage = probes[0]
                assert damage is not None
                return self._damaged_mcap_file(err, damage, storage)
            for storage, opened, damage in probes:
                if opened is not None:
                    parts.append(opened)
                    continue
                assert damage is not None
                part = self._damaged_mcap_file(err, damage, storage, of_files=len(files))
                if part is not None:
                    parts.append(part)
        except BaseException:
            for backend in [p for _, p, _ in probes if p is not None] + parts:
                backend.close()
            raise
        if not parts:  # (every file is damaged and none has a message to keep)
            storage, _, damage = next(probe for probe in probes if probe[1] is None)
            assert damage is not None
            raise self._unreadable(damage, storage, of_files=len(files)) from err
        return McapFilesReadBackend(parts)

    def _damaged_mcap_file(
        self, err: BaseException, damage: BaseException, storage: Path, of_files: int = 1
    ) -> McapStreamReadBackend | None:
        """The MCAP file ``storage`` of a ROS 2 bag folder (one of ``of_files``) that does not
        open through its index (``damage``; rosbags' error ``err``), read as it would be on its
        own; its error when it cannot be. None: a file of a split bag of which ``--salvage``
        reads nothing, said as a loss (the bag's other files are read)."""
        salvaged = self._without_summary(damage, storage)
        if salvaged is None and self.salvage:
            stream = self._salvage_stream(storage)
            assert stream is None or isinstance(stream, McapStreamReadBackend)
            salvaged = stream
            if salvaged is None and of_files > 1:
                problem = (
                    f"{self._unreadable(damage, storage, of_files)}; the bag's other files are read"
                )
                self._lose(problem)
                return None
        if salvaged is None:
            raise self._unreadable(damage, storage, of_files) from err
        return salvaged

    def _around_unopened_files(self, err: BaseException) -> RosbagsReadBackend | None:
        """A ROS 2 bag folder of several SQLite files that rosbags could not open (``err``)
        because one of them does not open (its header or tables damaged): with ``--salvage``,
        the bag read from its other files, each file that does not open a loss naming it (the
        whole bag was refused), else an error naming that file and what ``--salvage`` reads.
        None when that is not why (the first error stands), or no file opens."""
        if isinstance(err, LogError) or not self.path.is_dir():
            return None
        backend = RosbagsReadBackend(
            self.path, self.format, metadata=self._metadata, skip_unopened=True
        )
        try:
            backend.open()
        except Exception as failure:  # another damage: the first error stands
            backend.close()
            reraise_unless_damage(failure)
            return None
        files = len(backend.storage_readers())
        if not backend.unopened or len(backend.unopened) >= files or not self.salvage:
            backend.close()
            if not backend.unopened or len(backend.unopened) >= files:
                return None
            path, why = backend.unopened[0]
            msg = (
                f"{path}: cannot be opened ({short(why, 120)}), one of the bag's {files} files; "
                "--salvage reads the others"
            )
            raise LogReadError(msg) from err
        for path, why in backend.unopened:
            problem = (
                f"{path}: cannot be opened ({short(why, 120)}); none of its messages are read, "
                "the bag's other files are"
            )
            self._lose(problem)
        return backend

    def _around_damaged_chunks(self, err: BaseException) -> Ros1IndexedReadBackend | None:
        """A ROS 1 bag that rosbags could not open (``err``) whose index is intact: a chunk's
        record damaged (rosbags reads every chunk's header to open a bag), or the index data
        records after one. An error naming the damaged chunk, or with ``--salvage`` the bag read
        chunk by chunk through its index's chunk infos, around the damaged chunks.

        Without ``--salvage``, a bag that was closed (its header places its index inside the
        file) whose index is damaged is an error saying so: its index records do not read, or
        leave chunks out, or, every chunk's record intact, rosbags could not read them (an
        index data record after a chunk: rosbags fails an assertion, a bare ``AssertionError``).
        None when there is no index to read (the first error stands, or ``--salvage`` reads the
        bag record by record), or, with ``--salvage``, when the index leaves chunks out."""
        backend = Ros1IndexedReadBackend(self.path)
        try:
            backend.open()
            assert backend.index is not None
            problem = first_damaged_chunk(self.path, backend.index, headers_only=True)
            listed = {c.pos: c.counts for c in backend.index.chunks}
            known = {c.conn for c in backend.index.connections}
            unlisted = unindexed_messages(
                self.path, listed, connections=known, skip_damaged_chunks=True
            )
        except Exception as failure:  # the index is damaged too, or the file went away
            backend.close()
            reraise_unless_damage(failure)
            said = isinstance(err, LogError)  # an error of ours, which says what is wrong
            if isinstance(failure, IndexDamage) and failure.in_index and not (self.salvage or said):
                msg = f"{self.path}: {damaged_index(str(failure), through_chunk_infos=False)}"
                raise LogReadError(msg) from err
            return None
        if unlisted is not None:
            backend.close()
            if self.salvage or isinstance(err, LogError):  # (that error says it already)
                return None
            msg = f"{self.path}: {damaged_index(unlisted, through_chunk_infos=False)}"
            raise LogReadError(msg) from err
        if problem is None and not self.salvage:
            backend.close()
            # An error of ours says it already; an encrypted bag is no damage: rosbags' words.
            if isinstance(err, LogError) or _unsupported(err):
                return None
            msg = f"{self.path}: {damaged_index(rosbags_text(err), through_chunk_infos=True)}"
            raise LogReadError(msg) from err
        if not self.salvage:
            backend.close()
            msg = f"{self.path}: {problem}"
            raise LogReadError(msg)
        if problem is None:  # index data records damaged: the chunks may all read
            _LOG.warning(
                "%s: the bag's index could not be used (%s); read chunk by chunk through its "
                "chunk infos",
                self.path,
                rosbags_text(err),
            )
        return backend

    def _salvage_stream(
        self, storage: Path | None = None
    ) -> McapStreamReadBackend | Ros1StreamReadBackend | None:
        """The readable start of an MCAP file (the log, or ``storage``: a ROS 2 bag folder's)
        whose end is missing or damaged, or of a ROS 1 bag without a readable index (None for
        other formats, or when not even that can be read); the damage goes to :attr:`losses`."""
        backend: McapStreamReadBackend | Ros1StreamReadBackend
        name = storage or self.path
        if storage is not None or self.format == "mcap":
            backend = McapStreamReadBackend(name)
            where = "the end of the file is missing or damaged"
        elif self.format == "ros1":
            backend = Ros1StreamReadBackend(self.path)
            where = "the bag's index is missing or damaged"
        else:
            return None
        if not _opened(backend):
            return None
        if not backend.channels:
            backend.close()
            return None
        read = sum(c.message_count for c in backend.channels)
        mcap_sorted = isinstance(backend, McapStreamReadBackend) and backend.sorted_by_time
        order = "sorted by log time" if mcap_sorted else "in file order"
        if backend.complete:
            # Only the header's pointer to the index was wrong: nothing is lost.
            _LOG.warning("%s: %s, read record by record, %s", name, backend.damage, order)
            return backend
        problem = f"{name}: {where} ({backend.damage}); kept the {read} messages before it, {order}"
        self._lose(problem)
        return backend

    def _lose(self, problem: str) -> None:
        """Keep a loss (one line naming the file) in :attr:`losses`, and say it as it happens (a
        warning: the command does not repeat it)."""
        self.losses.append(problem)
        _LOG.warning("%s", problem)

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
    def _open_backend(self) -> _Backend:
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
    def qos_style(self) -> QosStyle | None:
        """How the input spells ROS 2 QoS policies (``"v8"`` integers, ``"v9"`` names); None if unknown."""
        return self._open_backend.qos_style

    @property
    def counts_declared(self) -> bool:
        """Whether :attr:`message_count` and the time range are what the log's index declares (an
        MCAP or ROS 1 log salvaged record by record counts what it read; a split ROS 2 bag read
        file by file declares them when a file of it is read through its index)."""
        backend = self._open_backend
        if isinstance(backend, McapFilesReadBackend):
            return backend.counts_declared
        return not isinstance(backend, McapStreamReadBackend | Ros1StreamReadBackend)

    @property
    def custom_data(self) -> dict[str, str]:
        """A ROS 2 bag folder's ``custom_data`` (its metadata.yaml's key-value text, ``ros2 bag
        record --custom-data``); empty for other logs, and for a bag without any."""
        if self.format not in ("db3", "mcap-dir"):
            return {}
        return bag_custom_data(self._metadata)

    def file_records(self) -> FileRecords:
        """An MCAP file's metadata and attachment records (``mcap.records.Metadata`` and
        ``Attachment``), or those of a ROS 2 bag folder's MCAP files, one file's after the
        other's (none for other logs; rosbag2's own record of the bag's metadata left out), read
        one at a time as they are iterated: they belong to no channel, and an MCAP output copies
        them. Records that cannot be read are left out with a warning (the messages are what
        the log is read for)."""
        backend = self._open_backend
        if not isinstance(backend, McapReadBackend | McapFilesReadBackend | RosbagsReadBackend):
            return FileRecords(0, lambda: iter(()))
        try:
            records = backend.file_records()
        except Exception as err:
            self._unreadable_file_records(err)
            return FileRecords(0, lambda: iter(()))
        return FileRecords(len(records), lambda: self._readable(records))

    def _readable(self, records: Iterable[Any]) -> Iterator[Any]:
        """``records`` up to the first that cannot be read (said in a warning)."""
        read = 0
        try:
            for record in records:
                read += 1
                yield record
        except Exception as err:
            self._unreadable_file_records(err, read)

    def _unreadable_file_records(self, err: Exception, read: int = 0) -> None:
        reraise_unless_damage(err)
        _LOG.warning(
            "%s: its metadata and attachment records cannot be read (%s): %s",
            self.path,
            short(err, 160),
            f"those after the first {read} not copied" if read else "not copied",
        )

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

    def messages(self, *, topics: Collection[str] | str | None = None) -> Iterator[RawMessage]:
        """Every message (or those on ``topics``: names, or one name), in log-time order (in file
        order for a ROS 1 bag salvaged record by record, see the module notes).

        Raises
        ------
        LogReadError
            If the log turns out to be truncated or corrupt while reading, or a file of it
            changed while it was read (another program wrote to it).
        TypeError
            If ``topics`` is neither a topic name nor names (str), on the first message asked for.
        """
        backend = self._open_backend
        names = topic_names(topics)
        wanted = None if names is None else set(names)
        counts: dict[int, int] = {}
        self.read_count = 0
        changed: str | None = None  # a file changed under the reader: nothing is a loss
        try:
            for message in backend.messages(wanted):
                key = message.channel.id
                counts[key] = counts.get(key, 0) + 1
                self.read_count += 1
                yield message
        except (LogError, Exception) as err:
            reraise_unless_damage(err)  # a signal inside the library, not a corrupt log
            changed = self._changed()
            if changed is not None:
                raise LogReadError(changed) from err
            error = err if isinstance(err, LogError) else _corrupt(self._read_from(backend), err)
            if not self.salvage:
                if isinstance(err, LogError):
                    if "--salvage" in str(err) or self.read_count == 0:
                        raise  # said already, or nothing before it to keep
                    kept = f"--salvage keeps the {self.read_count} message(s) before it"
                    raise LogReadError(f"{error}; {kept}") from err
                salvage = "--salvage keeps what can be read"
                raise LogReadError(f"{error}; {salvage}") from err
            problem = f"{short(error, 200)}; stopped after {self.read_count} messages"
            self._lose(problem)
            return
        else:
            # Read to the end, salvaged or not: what was read may mix two files' bytes.
            changed = self._changed()
            if changed is not None:
                raise LogReadError(changed)
        finally:
            if changed is None:  # (also when the caller stopped early, or was interrupted)
                self._note_skipped_chunks(backend)
        self._check_counts(counts, wanted)

    def _changed(self) -> str | None:
        """The error for a file of the log (the log, a bag folder's storage file or metadata)
        that changed since it was opened (overwritten, written to, cut short, replaced:
        :meth:`FileState.changed`), None when none did. Its reading failed as damage (or
        ``--salvage`` kept what it could of two files' bytes, or it read as sound), which the
        log is not."""
        for state in self._states:
            how = state.changed()
            if how is not None:
                return (
                    f"{state.path}: the file changed while it was read ({how}: another program "
                    "writes it?); read it again once it no longer changes"
                )
        return None

    def _read_from(self, backend: object) -> Path:
        """The file a failure reading messages through ``backend`` is about: a ROS 2 bag folder's
        storage file when it has one (its error named the folder, not the damaged file), or the
        file of a split bag read file by file whose reading failed, else the log."""
        if isinstance(backend, McapFilesReadBackend) and backend.failed_file is not None:
            return backend.failed_file
        sole = backend.sole_storage_file() if isinstance(backend, RosbagsReadBackend) else None
        return sole if sole is not None else self.path

    def _note_skipped_chunks(self, backend: object) -> None:
        """The damaged chunks a salvaging MCAP or ROS 1 reader skipped, and the files of a split
        ROS 2 bag it read part way, as losses (each said once)."""
        if not isinstance(
            backend,
            McapReadBackend
            | McapFilesReadBackend
            | RosbagsReadBackend
            | Ros1IndexedReadBackend
            | Ros1StreamReadBackend,
        ):
            return
        skipped = backend.skipped_chunks
        for chunk in skipped:
            if chunk.one_message:
                self._lose(
                    f"{chunk.file or self.path}: skipped a message of the chunk at byte "
                    f"{chunk.offset} of {chunk.file_size} ({chunk.reason}): it is lost, the "
                    "chunk's other messages are read"
                )
                continue
            first, last = ((t - self.start_ns) / 1e9 for t in (chunk.start_ns, chunk.end_ns))
            problem = (
                f"{chunk.file or self.path}: skipped a damaged chunk at byte {chunk.offset} of {chunk.file_size} "
                f"({chunk.reason}): its messages from +{first:.1f} s to +{last:.1f} s "
                f"({chunk.start_ns}..{chunk.end_ns} ns) are lost, the rest is read"
            )
            self._lose(problem)
        skipped.clear()
        if isinstance(backend, RosbagsReadBackend | McapFilesReadBackend):
            # files of a split bag read part way
            for problem in backend.damaged_files:
                self._lose(problem)
            backend.damaged_files.clear()

    def _check_counts(self, counts: dict[int, int], topics: set[str] | None) -> None:
        """Compare messages read per channel with the declared counts; a shortfall is a loss."""
        short_channels = []
        for channel in self.channels:
            if topics is not None and channel.topic not in topics:
                continue
            read = counts.get(channel.id, 0)
            if read < channel.message_count:
                short_channels.append(f"{channel.topic} {read} of {channel.message_count}")
            elif read > channel.message_count:
                _LOG.warning(
                    "%s: %s has %d messages, its index says %d",
                    self.path,
                    channel.topic,
                    read,
                    channel.message_count,
                )
        if not short_channels:
            return
        declared = sum(
            c.message_count for c in self.channels if topics is None or c.topic in topics
        )
        problem = (
            f"{self.path}: read {self.read_count} of {declared} messages the log declares "
            f"({short(', '.join(short_channels), 160)}): the log is damaged"
        )
        if not self.salvage:
            raise MessageLossError(problem + " (--salvage keeps what can be read)")
        self._lose(problem)
