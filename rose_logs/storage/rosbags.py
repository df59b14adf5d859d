"""ROS 1 bags and ROS 2 bags (folder, bare .db3, MCAP folder) through rosbags: reading and writing."""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import functools
import io
import itertools
import logging
import os
import re
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path, PurePath
from typing import TYPE_CHECKING, Any, Literal

from rose.limits import short
from rose_logs.errors import LogReadError, reraise_unless_damage
from rose_logs.formats import BagMetadata, LogFormat
from rose_logs.storage.base import WriteBackend
from rose_logs.storage.connections import (
    KnownDefinitions,
    QosStyle,
    offered_qos,
    qos_style,
    require_definition,
    warn_no_definition,
)
from rose_logs.storage.mcap import (
    FileRecords,
    McapReadBackend,
    SkippedChunk,
    storage_file_records,
)
from rose_logs.storage.records import (
    Channel,
    RawMessage,
    merged_by_log_time,
    normalize_msgtype,
    read_part_way,
)

__all__ = [
    "Ros1WriteBackend",
    "Ros2WriteBackend",
    "RosbagsReadBackend",
    "bag_custom_data",
    "mcap_storage_files",
]

if TYPE_CHECKING:
    from rose_logs.storage.ros1_stream import BagIndex

_LOG = logging.getLogger(__name__)
#: Most bytes of ROS 1 chunks (decompressed) overlapping in time that are held at once to read each
#: chunk once (see RosbagsReadBackend._ros1_index_if_chunks_overlap); beyond, rosbags' reading.
MAX_OVERLAP_BYTES = 256 * 2**20
_HOT_JOURNAL = bytes.fromhex("d9d505f920a163d7")  # a rollback journal's header while it is live


class RosbagsReadBackend:
    """ROS 1 bags and ROS 2 bags (folder, bare .db3) through rosbags."""

    profile = ""

    def __init__(
        self,
        path: Path,
        fmt: LogFormat,
        *,
        metadata: BagMetadata | None = None,
        skip_unopened: bool = False,
    ) -> None:
        self.path = path
        self.format = fmt
        #: A bag folder's metadata.yaml as :func:`~rose_logs.formats.read_format` read it (None:
        #: a file): what its checks, storage files and ``custom_data`` are taken from.
        self.metadata = metadata
        #: ``--salvage``, a ROS 2 bag folder of several SQLite files: a file that does not open
        #: (its header or tables damaged) is noted in :attr:`unopened` (its path, why) and read
        #: as holding nothing, and the bag opens with the others (else it is an error).
        self.skip_unopened = skip_unopened
        self.unopened: list[tuple[Path, str]] = []
        self.reader: Any = None
        self.channels: tuple[Channel, ...] = ()
        self._by_conn: dict[int, Channel] = {}
        self.start_ns = 0
        self.end_ns = 0
        self.qos_style: QosStyle | None = None
        #: ``--salvage`` (ROS 1, ROS 2 folder of MCAP files): a chunk that cannot be read is
        #: skipped and said in :attr:`skipped_chunks`, and the chunks after it are read (else it
        #: is an error).
        self.skip_damaged_chunks = False
        self.skipped_chunks: list[SkippedChunk] = []
        #: ``--salvage``, a ROS 2 bag of several storage files: each file that could not be read
        #: to its end, in words (the other files are read).
        self.damaged_files: list[str] = []

    def open(self) -> None:
        if self.path.is_dir():
            self._refuse_folder_storage()
        if self.format == "db3":
            self._refuse_unmerged_wal()
        if self.format == "ros1":
            from rose_logs.storage.ros1_index import LazyIndexReader

            self.reader = LazyIndexReader(self.path)
        else:
            from rosbags.rosbag2 import Reader as Reader2

            self.reader = Reader2(self.path)
            if self.skip_unopened and self.path.is_dir():
                self._tolerate_unopened_files()
        self.reader.open()
        if self.format == "ros1":
            self._check_ros1_index()
        else:
            self._read_sqlite_unsorted()
        channels: list[Channel] = []
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
        if self.format != "ros1":
            information = self.metadata.information if self.metadata else None
            self.qos_style = _bag_qos_style(information)
            if self.path.is_dir():
                self._check_types()
                self._warn_unlisted_storage(information)
        from_storage = self.path.is_dir() and self._times_from_storage()  # a ROS 2 bag folder
        if not from_storage and any(c.message_count for c in channels):
            self.start_ns = int(self.reader.start_time)
            # rosbags reports the end as "1 ns after the last message"
            self.end_ns = max(self.start_ns, int(self.reader.end_time) - 1)
        if self.format == "ros1":
            self._ros1_times_from_entries()

    def _ros1_entry_spans(self) -> dict[int, tuple[int, int]]:
        """The first and last message time (ns) of each chunk of this ROS 1 bag (by its byte
        position), as its index entries (every connection's) give them."""
        return self.reader.entry_spans({int(conn.id) for conn in self.reader.connections})

    def _ros1_times_from_entries(self) -> None:
        """Take a ROS 1 bag's time range from its chunk infos (rosbags' range) and its index
        entries together: a bag's writer gives a chunk's info the times of its first and last
        message, which its entries hold too; where they disagree (said), a time damaged in one
        of them is left out (:func:`agreed_span`): a chunk info's end damaged to 2106 made a
        session of seconds span 83 years."""
        from rose_logs.storage.ros1_stream import agreed_span

        spans = self._ros1_entry_spans()
        damaged = []
        starts: list[int] = []
        ends: list[int] = []
        for info in self.reader.chunk_infos:
            listed = (int(info.start_time), int(info.end_time) - 1)  # rosbags adds 1 ns
            entries = spans.get(info.pos)
            if entries is not None and entries != listed:
                damaged.append((info.pos, listed, entries))
            if entries is not None or listed[0] <= listed[1]:  # (a chunk of no message: no)
                first, last = agreed_span(listed, entries, widest=False)
                starts.append(first)
                ends.append(last)
        if not damaged or not starts:
            return
        pos, listed, entries = damaged[0]
        _LOG.warning(
            "%s: the chunk info of %d chunk(s) gives other times than its messages' index "
            "entries (the chunk at byte %d: %d..%d ns, its entries %d..%d ns): a chunk's time "
            "range is taken where they agree",
            self.path,
            len(damaged),
            pos,
            *listed,
            *entries,
        )
        self.start_ns, self.end_ns = min(starts), max(ends)

    def _read_sqlite_unsorted(self) -> None:
        """Make rosbags' readers of this bag's SQLite files read a file without an index of its
        messages' times in its rows' order where that is their time order, rather than have
        SQLite sort the whole table (:func:`~rose_logs.storage.sqlite_order.ordered_messages`)."""
        from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

        from rose_logs.storage.sqlite_order import ordered_messages

        storages = self.storage_readers() if self.path.is_dir() else [self.reader.storage]
        for storage in storages:
            inner = getattr(storage, "inner", storage)  # (a _TolerantStorage's)
            if isinstance(inner, Sqlite3Reader):  # this instance's, which rosbags' Reader calls
                vars(inner)["messages"] = functools.partial(ordered_messages, inner)

    def _times_from_storage(self) -> bool:
        """Take the time range of a bag folder as its storage files hold it: their first and
        last message's timestamps, which rosbags reads from each file when it opens it (a SQLite
        file's messages table, an MCAP file's statistics), as for a bare file. rosbags gives the
        range metadata.yaml states (starting_time, duration): one that lies shifted every session
        time of the report (a starting_time of 2020 put the snapshots of a 2023 recording at
        +100000005 s), one past 2**63 made a traceback. False (nothing taken) when no file
        states a range (MCAP files without statistics): metadata.yaml's stands."""
        starts: list[int] = []
        ends: list[int] = []
        for storage in self.storage_readers():
            meta = getattr(storage, "metadata", None)  # none: a file that did not open (salvage)
            start: Any = getattr(meta, "start_time", None)
            end: Any = getattr(meta, "end_time", None)
            if _valid_time(start) and _valid_time(end) and start < end:  # (an empty file: no)
                starts.append(start)
                ends.append(end - 1)  # "1 ns after the last message", as above
        if not starts:
            return False
        self.start_ns, self.end_ns = min(starts), max(ends)
        return True

    def _tolerate_unopened_files(self) -> None:
        """Make rosbags' reader of this bag folder open its SQLite files as
        :class:`_TolerantStorage` (see :attr:`skip_unopened`)."""
        storage = self.reader.storage  # rosbags' DirectoryReader (pinned below 0.12)
        plugins = dict(storage.STORAGE_PLUGINS)
        plain = plugins["sqlite3"]
        unopened = self.unopened
        plugins["sqlite3"] = lambda path: _TolerantStorage(plain(path), unopened)
        storage.STORAGE_PLUGINS = plugins

    def _refuse_folder_storage(self) -> None:
        """Refuse a bag folder whose metadata.yaml lists a storage file that is a folder (a copy
        that made one of the file's name, a path mixed up): SQLite said "disk I/O error" and the
        MCAP reader "Is a directory", both read as "corrupt or truncated log"."""
        paths = (
            None if self.metadata is None else self.metadata.information.get("relative_file_paths")
        )
        if not isinstance(paths, list):
            return  # read and judged by rosbags
        for name in paths:
            storage = self.path / PurePath(str(name)).name  # as rosbags finds it: by its name
            if storage.is_dir():
                msg = (
                    f"{storage}: a folder, not a file, where the bag's metadata.yaml lists a "
                    "storage file"
                )
                raise LogReadError(msg)

    def _refuse_unmerged_wal(self) -> None:
        """Refuse a SQLite bag with writes beside its database file, left by a recorder that did
        not close: a write-ahead log (``x.db3-wal``, rosbag2's ``resilient`` preset) holds its last
        messages, a hot rollback journal (``x.db3-journal``) the pages its open transaction
        overwrote. rosbags opens the database ``immutable``, without either: the first loses
        messages unsaid (a bag without metadata.yaml), the second reads as corrupt."""
        files = [self.path] if self.path.is_file() else sorted(self.path.glob("*.db3"))
        for storage in files:
            for side, what in (
                ("-wal", "writes that may not be in"),  # unless checkpointed at the very end
                ("-journal", "an unfinished write of"),
            ):
                extra = storage.with_name(storage.name + side)
                try:
                    with extra.open("rb") as stream:
                        head = stream.read(8)
                    size = extra.stat().st_size
                except OSError:
                    continue
                pending = size > 32 if side == "-wal" else head == _HOT_JOURNAL
                if pending:
                    msg = (
                        f"{self.path}: {extra.name} holds {size:,} bytes of {what} "
                        f"{storage.name} (a recording that did not close), which rose-bag does "
                        f"not read: copy the files and open the copy once with sqlite3 "
                        f"(sqlite3 COPY.db3 'PRAGMA integrity_check'), which completes it"
                    )
                    raise LogReadError(msg)

    def _check_ros1_index(self) -> None:
        """Refuse a bag whose index leaves chunks or messages out (rosbags reads what it lists)."""
        from rose_logs.storage.ros1_stream import damaged_index, unindexed_messages

        infos = getattr(self.reader, "chunk_infos", [])
        listed = {int(c.pos): dict(c.connection_counts) for c in infos}
        known = {int(c.id) for c in self.reader.connections}
        problem = unindexed_messages(self.path, listed, connections=known)
        if problem is not None:
            msg = f"{self.path}: {damaged_index(problem, through_chunk_infos=False)}"
            raise LogReadError(msg)

    def _warn_unlisted_storage(self, information: dict[str, Any] | None) -> None:
        """Say so when the bag folder holds a storage file its metadata.yaml (``information``)
        does not list (a split recording whose metadata was written before its last file):
        rosbags, like rosbag2, reads the listed files only, and that file's messages would go
        unsaid."""
        paths = None if information is None else information.get("relative_file_paths")
        if not isinstance(paths, list):
            return  # read and judged by rosbags already
        listed = {Path(str(f)).name for f in paths}
        storage = (".db3", ".mcap", ".db3.zstd", ".mcap.zstd")
        for entry in sorted(self.path.iterdir()):
            if entry.name.endswith(storage) and entry.name not in listed:
                _LOG.warning(
                    "%s: storage file %s is not listed in metadata.yaml: its messages are not "
                    "read (ros2 bag reindex rebuilds the metadata)",
                    self.path,
                    entry.name,
                )

    def _check_types(self) -> None:
        """Refuse a bag folder whose metadata.yaml declares other types than its storage records."""
        from rose_logs.storage.integrity import storage_types_by_file, type_mismatches

        kinds: dict[str, list[str]] = {}
        for channel in self.channels:
            kinds.setdefault(channel.topic, []).append(channel.msgtype)
        skip = {path.name for path, _ in self.unopened}
        # Only the storage files rosbags reads, those metadata.yaml lists (by name): an unlisted
        # one (a split's last file written after the metadata, cut short by a recorder that did
        # not close) is warned about and not read, and made the whole bag "corrupt or truncated".
        information = self.metadata.information if self.metadata else None
        paths = None if information is None else information.get("relative_file_paths")
        if isinstance(paths, list):
            listed = {PurePath(str(name)).name for name in paths}
            skip |= {entry.name for entry in self.path.iterdir() if entry.name not in listed}
        files = storage_types_by_file(self.path, skip=skip)
        # Each file on its own: a split bag's first file of another type was not seen (rosbags
        # then skips its messages, said as a damaged log), a later file's type hid it. A topic
        # listed with several types agrees with any of them.
        problems: list[str] = []
        for path, stored in files:
            declared = {
                topic: next((k for k in listed if k == stored.get(topic)), listed[-1])
                for topic, listed in kinds.items()
            }
            for problem in type_mismatches(declared, stored):
                problem = f"{problem} in {path.name}" if len(files) > 1 else problem
                if problem not in problems:
                    problems.append(problem)
        if problems:
            msg = (
                f"{self.path}: metadata.yaml disagrees with the storage ({'; '.join(problems[:3])})"
            )
            raise LogReadError(msg)

    def messages(self, topics: set[str] | None) -> Iterator[RawMessage]:
        by_conn = self._by_conn
        conns = None
        if topics is not None:
            conns = [c for c in self.reader.connections if c.topic in topics]
            if not conns:
                return
        if self.format == "ros1" and self.skip_damaged_chunks:
            yield from self._around_damaged_chunks(conns)
            return
        if self.format == "mcap-dir" and self.skip_damaged_chunks:
            yield from self._mcap_around_damaged_chunks(topics)
            return
        if len(self.storage_readers()) > 1:  # a split bag: its files merged by log time
            yield from self._file_by_file(topics, salvage=self.skip_damaged_chunks)
            return
        ended = self._ros1_record_ended() if self.format == "ros1" else None
        try:
            index = self._ros1_index_if_chunks_overlap(conns) if self.format == "ros1" else None
            if index is not None:
                yield from self._through_chunk_infos(index, conns, None)
                return
            for conn, timestamp, data in self.reader.messages(connections=conns or ()):
                if not isinstance(data, bytes | memoryview) or not _valid_time(timestamp):
                    raise LogReadError(self._damaged_row(conn.topic, timestamp, data))
                if ended is not None and not ended():
                    msg = f"{self.path}: a message record's data length is damaged"
                    raise LogReadError(msg)  # _failed_read names the chunk
                yield RawMessage(by_conn[id(conn)], int(timestamp), data, int(timestamp))
        except Exception as err:
            reraise_unless_damage(err)
            problem = self._failed_read(err) if self.format == "ros1" else None
            if problem is None:
                raise
            msg = f"{self.path}: {problem}"
            raise LogReadError(msg) from err

    def _ros1_record_ended(self) -> Callable[[], bool]:
        """A check of whether the message rosbags just read from a ROS 1 bag's chunk ends where
        the chunk's next record starts (or the chunk does). rosbags reads as many bytes as a
        message record's data length says: a damaged length gave the message cut short (or with
        the next record's bytes), no error, where ``--salvage`` said the chunk damaged
        (:func:`record_follows`). Made once per reading, each chunk's size taken once: it runs
        for every message."""
        from rose_logs.storage.ros1_stream import record_follows

        sized: list[Any] = [None, 0]  # the chunk last checked (held: its id stays its own), size

        def ended() -> bool:
            current = getattr(self.reader, "current_chunk", None)  # rosbags' (pinned below 0.12)
            chunk = current[1] if isinstance(current, tuple) and len(current) == 2 else None
            if not isinstance(chunk, io.BytesIO):
                return True  # another rosbags: unchecked, as before
            if chunk is not sized[0]:
                sized[0], sized[1] = chunk, chunk.getbuffer().nbytes
            # rosbags seeks to each message's index offset before reading it: the position is
            # free.
            return record_follows(chunk, sized[1])

        return ended

    def _failed_read(self, err: Exception) -> str | None:
        """Why rosbags failed (``err``) to read a ROS 1 bag's messages, in words: the first chunk
        that cannot be read, else, when every chunk reads, index entries that do not match the
        messages they point to (rosbags fails an assertion on a message's time, or reads a
        record where no message starts). None: no index to find the chunks by, or a failure
        of the system (the first error stands)."""
        from rose_logs.storage.ros1_stream import (
            IndexDamage,
            IndexMismatch,
            damaged_index,
            first_damaged_chunk,
            read_index,
        )

        try:
            damaged = first_damaged_chunk(self.path, read_index(self.path), headers_only=False)
        except (IndexDamage, OSError):
            return None
        if damaged is not None:
            return damaged
        if isinstance(err, OSError):
            return None
        # Our chunk by chunk reading's (overlapping chunks) says where, in its own words.
        where = str(err) if isinstance(err, IndexMismatch) else rosbags_text(err)
        problem = f"an index entry does not match the message it points to: {where}"
        return damaged_index(problem, through_chunk_infos=True)

    def _around_damaged_chunks(self, conns: list[Any] | None) -> Iterator[RawMessage]:
        """A ROS 1 bag's messages read chunk by chunk through its index, in rosbags' order,
        skipping the chunks that cannot be read (:attr:`skipped_chunks`): a flipped byte in one
        chunk loses that chunk's messages, not the rest of the bag."""
        from rose_logs.storage.ros1_stream import IndexDamage, read_index

        try:
            index = read_index(self.path)
        except IndexDamage:  # rosbags read it: read as rosbags does (stopping at a damaged chunk)
            self.skip_damaged_chunks = False
            yield from self.messages(None if conns is None else {c.topic for c in conns})
            return
        yield from self._through_chunk_infos(index, conns, self.skipped_chunks)

    def _through_chunk_infos(
        self, index: BagIndex, conns: list[Any] | None, skipped: list[SkippedChunk] | None
    ) -> Iterator[RawMessage]:
        """A ROS 1 bag's messages (of ``conns``, all when None) read chunk by chunk through its
        ``index``, in rosbags' order, each chunk read once (:func:`chunk_messages`; ``skipped``:
        where the chunks that cannot be read are said, None: an error)."""
        from rose_logs.storage.ros1_stream import agreed_span, chunk_messages

        # Each chunk's times as its info or its index entries give them, a time damaged in one
        # of them left out (:func:`agreed_span`): a chunk is read at its start, and a message
        # outside its times has a damaged time.
        spans = self._ros1_entry_spans()
        chunks = []
        for chunk in index.chunks:
            first, last = agreed_span((chunk.start_ns, chunk.end_ns), spans.get(chunk.pos))
            chunks.append(dataclasses.replace(chunk, start_ns=first, end_ns=last))
        index = dataclasses.replace(index, chunks=tuple(chunks))
        by_id = {conn.id: self._by_conn[id(conn)] for conn in self.reader.connections}
        wanted = {conn.id for conn in (conns or self.reader.connections)}
        with self.path.open("rb") as stream:
            for conn_id, time_ns, data in chunk_messages(stream, index, wanted, skipped):
                yield RawMessage(by_id[conn_id], time_ns, data, time_ns)

    def _ros1_index_if_chunks_overlap(self, conns: list[Any] | None) -> BagIndex | None:
        """The index of a ROS 1 bag whose chunks (those holding ``conns``) overlap in time, as a
        bag written topic after topic (a merge script) has them, to read it chunk by chunk
        (:meth:`_through_chunk_infos`); None when they follow each other, as a recorder writes
        them, or would hold more than :data:`MAX_OVERLAP_BYTES` decompressed at once.

        rosbags reads in log-time order through every message's index entry and keeps one
        chunk decompressed: where chunks overlap it decompressed a chunk again at nearly every
        message (5,000 scans and 5,000 strings in bz2 chunks: 275 s, against 3 s read once)."""
        from rose_logs.storage.ros1_stream import IndexDamage, decompressed_sizes, read_index

        wanted = {conn.id for conn in (conns or self.reader.connections)}
        infos = sorted(
            (
                info
                for info in self.reader.chunk_infos
                if any(n and cid in wanted for cid, n in info.connection_counts.items())
            ),
            key=lambda info: (info.start_time, info.pos),
        )
        if all(a.end_time <= b.start_time for a, b in itertools.pairwise(infos)):
            return None
        if not self._chunk_infos_hold_their_entries(infos, wanted):
            return None  # rosbags orders by the index entries alone: as it does
        try:
            index = read_index(self.path)
        except IndexDamage:  # rosbags read it: read as rosbags does
            return None
        chunks = [
            chunk
            for chunk in index.chunks
            if any(n and conn in wanted for conn, n in chunk.counts.items())
        ]
        # What is held is decompressed: a bz2 chunk of a map's zeros stores a hundredth of it.
        sizes = decompressed_sizes(self.path, index, chunks)
        if sizes is None:
            return None  # rosbags' reading says what is wrong, as before
        # The chunks read and not yet handed out at once, their decompressed bytes.
        events = sorted(
            [(chunk.start_ns, 0, size) for chunk, size in zip(chunks, sizes, strict=True)]
            + [(chunk.end_ns, 1, -size) for chunk, size in zip(chunks, sizes, strict=True)]
        )
        held = peak = 0
        for _time, _order, size in events:
            held += size
            peak = max(peak, held)
        if peak > MAX_OVERLAP_BYTES:
            return None  # rosbags' reading: slow, in constant memory
        return index

    def _chunk_infos_hold_their_entries(self, infos: list[Any], wanted: set[int]) -> bool:
        """Whether each of ``infos`` (rosbags' chunk infos) spans the times of the index entries
        (of the connections ``wanted``) in its chunk: the chunk by chunk reading reads a chunk at
        its info's start time, and a later one (a flipped byte in the index) handed its messages
        out late, out of order, where rosbags orders by the entries alone. From the spans the
        reader noted as it opened the bag (:meth:`LazyIndexReader.entry_spans`)."""
        spans = self.reader.entry_spans(wanted)
        return all(
            info.start_time <= first and last <= info.end_time
            for info in infos
            for first, last in [spans.get(info.pos, (info.start_time, info.end_time))]
        )

    def _mcap_around_damaged_chunks(self, topics: set[str] | None) -> Iterator[RawMessage]:
        """A ROS 2 bag folder's messages read from its MCAP files as a bare MCAP file is salvaged
        (through its chunk index, skipping the chunks that cannot be read, said in
        :attr:`skipped_chunks` with the file they are in), as this bag's channels, the files'
        messages merged by log time (:func:`merged_by_log_time`). rosbags stops at the first
        damaged chunk: a flipped bit early in an hour's recording lost the rest of the hour (and,
        in a split bag, every file after it). A file whose index does not read is read by rosbags
        as without ``--salvage``, up to the damage (in a split bag, the other files are read); a
        bag whose messages are compressed one by one is read by rosbags, file by file when there
        are several."""
        files = mcap_storage_files(self.path, self.metadata)
        storages = self.storage_readers()
        if not files or len(files) != len(storages):
            if len(storages) > 1:  # messages compressed one by one: rosbags reads each file
                yield from self._file_by_file(topics, salvage=True)
                return
            self.skip_damaged_chunks = False
            yield from self.messages(topics)
            return
        yield from merged_by_log_time(
            self._mcap_file_around_damaged_chunks(storage, path, topics, salvage=len(files) > 1)
            for storage, path in zip(storages, files, strict=True)
        )

    def sole_storage_file(self) -> Path | None:
        """The one storage file of this bag folder, as its metadata.yaml lists it (None: a bare
        file, or a bag of several files or of none that reads): an error reading such a bag is
        about that file."""
        if not self.path.is_dir() or self.metadata is None:
            return None
        names = self.metadata.information.get("relative_file_paths")
        if not isinstance(names, list) or len(names) != 1:
            return None
        return self.path / PurePath(str(names[0])).name

    def storage_readers(self) -> list[Any]:
        """rosbags' readers of this bag folder's storage files, one a file, in metadata.yaml's
        order (none for a bare file)."""
        if not self.path.is_dir():
            return []
        return list(getattr(self.reader.storage, "storages", None) or [])

    def _file_by_file(self, topics: set[str] | None, *, salvage: bool) -> Iterator[RawMessage]:
        """A bag of several storage files that rosbags reads, file by file, their messages
        merged by log time (:func:`merged_by_log_time`; rosbags reads one file after the other,
        in metadata.yaml's order). With ``salvage``, a file that fails part way is said in
        :attr:`damaged_files` and the other files are read (rosbags' reading stopped there: a
        damaged first file lost the whole bag); else its error is raised."""
        yield from merged_by_log_time(
            self._rosbags_file(storage, path, topics, salvage=salvage)
            for storage, path in self._storage_files()
        )

    def _storage_files(self) -> list[tuple[Any, Path]]:
        """rosbags' reader of each storage file of this bag folder (:meth:`storage_readers`)
        and the file in the folder it reads (the one compressed, ``x.mcap.zstd``, where it reads
        a temporary decompressed copy)."""
        information = self.metadata.information if self.metadata else {}
        names = [str(name) for name in information.get("relative_file_paths") or ()]
        files = []
        for storage in self.storage_readers():
            stored = PurePath(str(storage.path)).name  # (a temporary copy of a .zstd file)
            name = next(
                (n for n in names if PurePath(n).name in (stored, f"{stored}.zstd")), stored
            )
            files.append((storage, self.path / PurePath(name).name))
        return files

    def file_records(self) -> FileRecords:
        """The metadata and attachment records of this bag folder's MCAP files (none for other
        bags), one file's after the other's, rosbag2's bookkeeping record the first file's
        (:func:`storage_file_records`): as a bare MCAP file's (:meth:`McapReadBackend.file_records`).
        A file that did not open (``--salvage``) holds none."""
        if self.format != "mcap-dir":
            return FileRecords(0, lambda: iter(()))
        opened = [
            Path(storage.path)  # (the decompressed copy, if any)
            for storage, _ in self._storage_files()
            if getattr(storage, "inner", storage) is not None  # (see _TolerantStorage)
        ]
        return FileRecords.joined(
            [storage_file_records(path, bookkeeping=i == 0) for i, path in enumerate(opened)]
        )

    def _rosbags_file(
        self, storage: Any, path: Path, topics: set[str] | None, *, salvage: bool
    ) -> Iterator[RawMessage]:
        """The messages of one storage file ``path`` of this bag folder, read by rosbags
        (``storage``: its reader of it), as this bag's channels. A failure part way is raised
        (naming the file, in a bag of several), or, with ``salvage`` (a bag of several files),
        said in :attr:`damaged_files` (the caller reads the other files)."""
        ours = self._storage_channels_ours(storage)
        conns = [
            conn
            for conn in storage.connections
            if int(conn.id) in ours and (topics is None or conn.topic in topics)
        ]
        if not conns:
            return
        decompress = None
        if str(self.reader.compression_mode or "").lower() == "message":
            from rosbags.rosbag2 import reader as rosbags_reader  # its zstd, as it reads them

            decompress = rosbags_reader.zstd.decompress
        read = 0
        try:
            for conn, timestamp, stored in storage.messages(conns):
                data = stored if decompress is None else decompress(stored)
                if not isinstance(data, bytes | memoryview) or not _valid_time(timestamp):
                    raise LogReadError(self._damaged_row(conn.topic, timestamp, data))
                read += 1
                yield RawMessage(ours[int(conn.id)], int(timestamp), data, int(timestamp))
        except Exception as err:
            reraise_unless_damage(err)
            files = len(self.storage_readers())
            if not salvage and files < 2:
                raise
            why = short(library_text(err).removeprefix(f"{self.path}: "), 120)
            if not salvage:  # the error names the file, not only the bag
                msg = (
                    f"{path}: corrupt or truncated ({why}; {read} of its messages read before "
                    f"it), one of the bag's {files} files; --salvage keeps what can be read of "
                    "it and reads the others"
                )
                raise LogReadError(msg) from err
            self.damaged_files.append(read_part_way(path, read, why))

    def _mcap_file_around_damaged_chunks(
        self, storage: Any, path: Path, topics: set[str] | None, *, salvage: bool
    ) -> Iterator[RawMessage]:
        """The messages of one MCAP file ``path`` of this bag folder (rosbags' reader of it:
        ``storage``), skipping its damaged chunks; read by rosbags when its index does not read
        (:meth:`_rosbags_file`, up to the damage, said with ``salvage``: a bag of several files,
        whose others are read). A failure part way that is no damaged chunk (a file without
        chunks) is said in :attr:`damaged_files` too with ``salvage``: raised, it ended the
        merge, and the other files' later messages were lost with it."""
        ours = self._storage_channels_ours(storage)
        inner = McapReadBackend(path)
        try:
            inner.open()
            indexed = True
        except Exception as err:  # its index is damaged: rosbags' reading stands
            inner.close()
            reraise_unless_damage(err)
            indexed = False
        if not indexed:
            yield from self._rosbags_file(storage, path, topics, salvage=salvage)
            return
        # The file's channel id of each of the inner reader's channels.
        file_ids = {channel.id: file_id for file_id, channel in inner._by_id.items()}
        inner.skip_damaged_chunks = True
        read = 0
        try:
            for message in inner.messages(topics):
                channel = ours.get(file_ids.get(message.channel.id, -1))
                if channel is None:  # not in metadata.yaml: rosbags does not read it either
                    continue
                # The log time as publish time, as rosbags gives it: the same output either way.
                time_ns = message.log_time_ns
                read += 1
                yield RawMessage(channel, time_ns, message.data, time_ns)
        except Exception as err:
            reraise_unless_damage(err)
            if not salvage:
                raise
            why = library_text(err).removeprefix(f"{path}: ")
            self.damaged_files.append(read_part_way(path, read, why))
        finally:
            self.skipped_chunks.extend(
                dataclasses.replace(chunk, file=inner.path) for chunk in inner.skipped_chunks
            )
            inner.close()

    def _storage_channels_ours(self, storage: Any) -> dict[int, Channel]:
        """Our channel of each channel id of a storage file of this bag folder (``storage``:
        rosbags' reader of it), as rosbags maps them (the first of metadata.yaml's topics of the
        same name, type and QoS, a hash that does not differ): a topic's channels offered with
        different QoS stay apart."""
        listed = list(self.reader.connections)
        ours: dict[int, Channel] = {}
        for conn in storage.connections:
            match = next(
                (
                    other
                    for other in listed
                    if other.topic == conn.topic
                    and other.msgtype == conn.msgtype
                    and other.ext == conn.ext
                    and (not conn.digest or not other.digest or other.digest == conn.digest)
                ),
                None,
            )
            if match is not None:
                ours[int(conn.id)] = self._by_conn[id(match)]
        return ours

    def _damaged_row(self, topic: str, timestamp: object, data: object) -> str:
        """What is wrong with a message a SQLite bag stores (its columns take any type: a NULL or
        a text where the message's bytes belong, a time that is no ROS time)."""
        if not _valid_time(timestamp):
            return f"{self.path}: a message on {topic} has no valid time ({_stored(timestamp)})"
        return (
            f"{self.path}: the message on {topic} at {timestamp} ns holds {_stored(data)}, "
            "not its bytes"
        )

    def close(self) -> None:
        if self.reader is not None:
            try:
                self.reader.close()
            except Exception:  # closing a half-open reader must not mask the real error
                _LOG.debug("closing %s failed", self.path, exc_info=True)
            self.reader = None


class _TolerantStorage:
    """rosbags' reader of one storage file of a bag folder (``inner``) whose failure to open is
    noted in ``unopened`` (its path, why) instead of raised: the file then holds no connection
    and no message (see :attr:`RosbagsReadBackend.skip_unopened`)."""

    def __init__(self, inner: Any, unopened: list[tuple[Path, str]]) -> None:
        self.inner: Any = inner
        self.unopened = unopened
        self.path = inner.path

    def open(self) -> None:
        try:
            self.inner.open()
        except Exception as err:
            with contextlib.suppress(Exception):
                self.inner.close()
            reraise_unless_damage(err)
            why = library_text(err).replace(f" {self.path}", "")  # (the error names it)
            self.unopened.append((Path(self.path), why))
            self.inner = None

    @property
    def connections(self) -> list[Any]:
        return [] if self.inner is None else list(self.inner.connections)

    def messages(self, *args: Any, **kwargs: Any) -> Iterator[Any]:
        if self.inner is not None:
            yield from self.inner.messages(*args, **kwargs)

    def close(self) -> None:
        if self.inner is not None:
            self.inner.close()

    def __getattr__(self, name: str) -> Any:  # anything else rosbags asks of its storage
        return getattr(self.inner, name)


def library_text(err: BaseException) -> str:
    """A library error as text. rosbags formats a wrapped error's args tuple into its message
    ("...: ('Header could not be read from file.',)"): show the text, not the Python repr."""
    text = _ONE_ITEM_TUPLE.sub(lambda m: m.group(2), str(err))
    return text if text.strip() else type(err).__name__


_ONE_ITEM_TUPLE = re.compile(r"""\((['"])(.*?)\1,\)""")


def rosbags_text(err: BaseException) -> str:
    """What rosbags said of a ROS 1 bag it could not read, shortened. An internal check of it
    that failed (a bare ``AssertionError``), a text field it could not decode, or another Python
    error escaping it is said as such, not as its class name or bare value alone."""
    text = library_text(err).removeprefix("Bag index looks damaged: ")
    if isinstance(err, AssertionError) and not str(err).strip():
        return "an assertion in rosbags failed"
    if isinstance(err, UnicodeDecodeError):
        return "a text field that is not UTF-8"
    if type(err).__name__ != "ReaderError":  # not rosbags' own words
        text = f"{type(err).__name__} in rosbags: {text}"
    return short(text, 120)


def _valid_time(value: object) -> bool:
    """Whether a SQLite row's timestamp is a log time: an integer of nanoseconds in 0 .. 2**63."""
    return type(value) is int and 0 <= value < 2**63


def _stored(value: object) -> str:
    """A SQLite value in words, for an error: NULL, a text, a number (shortened)."""
    if value is None:
        return "NULL"
    if isinstance(value, str):
        return f"the text {short(repr(value), 40)}"
    if isinstance(value, int | float):
        return f"the number {short(repr(value), 40)}"
    return f"a {type(value).__name__}"


def bag_custom_data(metadata: BagMetadata | None) -> dict[str, str]:
    """``custom_data`` of a ROS 2 bag folder's metadata.yaml (``metadata``, as
    :func:`~rose_logs.formats.read_format` read it; None: a file) (``ros2 bag record
    --custom-data``: text the user attached to the bag), in its order; empty when it has none.
    Values as spelled (rosbag2 reads them as text: ``true``, ``042`` or a date are no bool,
    number or date)."""
    import yaml

    if metadata is None or not metadata.information.get("custom_data"):
        return {}  # most bags: metadata.yaml not parsed a second time (3,000 topics: 1.3 s)
    parsed = metadata.information["custom_data"]
    if isinstance(parsed, dict) and all(
        isinstance(item, str) for pair in parsed.items() for item in pair
    ):
        # Keys and values all read as text: their spelling, as the text parse would give it
        # (a scalar read as text is its own spelling, quotes and escapes taken as both take them).
        return dict(parsed)
    try:  # the bytes read once (the file now may be another's), parsed as text
        text = metadata.data.decode("utf-8")
        data = yaml.load(text, Loader=yaml.BaseLoader)["rosbag2_bagfile_information"]
        data = data["custom_data"]
    except (ValueError, KeyError, TypeError, yaml.YAMLError):
        return {}
    if not isinstance(data, dict):  # null: none
        return {}
    return {str(key): value for key, value in data.items() if isinstance(value, str)}


def mcap_storage_files(path: Path, metadata: BagMetadata | None) -> list[Path]:
    """The MCAP storage files the ROS 2 bag folder ``path``'s metadata.yaml (``metadata``, as
    :func:`~rose_logs.formats.read_format` read it; None: a file) lists, in its order,
    as rosbags finds them (by name, in the folder); none when one of them is no plain MCAP file
    (a whole file compressed, ``.mcap.zstd``), when its messages are compressed one by one
    (compression mode "message": the file's messages are zstd data, which rosbags decompresses),
    or the list does not read."""
    if metadata is None:
        return []
    information = metadata.information
    mode = str(information.get("compression_mode") or "").lower()
    if mode not in ("", "none"):
        return []
    names = information.get("relative_file_paths")
    if not isinstance(names, list) or not names:
        return []
    files = [path / PurePath(str(name)).name for name in names]
    return files if all(f.name.endswith(".mcap") for f in files) else []


def _bag_qos_style(information: dict[str, Any] | None) -> QosStyle | None:
    """How a bag's metadata.yaml (its ``rosbag2_bagfile_information``) spells QoS (None: no
    folder / no QoS).

    From the first topic with offered QoS profiles, else from the format version (<= 8: integers).
    """
    if information is None:
        return None
    try:
        for topic in information.get("topics_with_message_count") or ():
            style = qos_style(topic["topic_metadata"].get("offered_qos_profiles") or "")
            if style is not None:
                return style
        return "v8" if int(information["version"]) <= 8 else "v9"
    except (KeyError, TypeError, ValueError, AttributeError):
        return None


@contextlib.contextmanager
def _sqlite_as_os_errors() -> Iterator[None]:
    """A full disk or a failing one under a db3 output, which sqlite3 reports as its own error
    ("database or disk is full"), raised as the ``OSError`` it is: a batch retries it and names it
    as an MCAP output's ("cannot write (No space left on device)"), not as the recording's error."""
    import sqlite3

    try:
        yield
    except sqlite3.Error as err:
        code = getattr(err, "sqlite_errorcode", None)
        primary = -1 if code is None else int(code) & 0xFF  # extended codes: in the low byte
        number = {sqlite3.SQLITE_FULL: errno.ENOSPC, sqlite3.SQLITE_IOERR: errno.EIO}.get(primary)
        if number is None:
            raise
        raise OSError(number, os.strerror(number)) from err


class _IndexedConnections(list[Any]):
    """A rosbags writer's ``connections`` (rosbags internals, pinned below 0.12) whose two scans
    are answered from indexes, so that neither grows with the topics.

    rosbags' ``write`` checks each message's connection is ``in`` the list (a scan of the
    connections before it, per message) and ``add_connection`` compares the new connection with
    every one added (a scan per connection: quadratic in the topics). Membership is by identity
    first (the connections the writer returned), anything else compared as a list does; while
    :attr:`topic` is set, iteration gives that topic's connections only, the only ones rosbags'
    check can find alike (it compares the topic too). Only ``append`` is indexed: rosbags' writers
    add connections with it and remove none.
    """

    def __init__(self) -> None:
        super().__init__()
        self._ids: set[int] = set()  # the items are held by the list, so their ids stay theirs
        self._by_topic: dict[str, list[Any]] = {}
        self.topic: str | None = None

    def append(self, item: Any) -> None:
        super().append(item)
        self._ids.add(id(item))
        self._by_topic.setdefault(item.topic, []).append(item)

    def __contains__(self, item: object) -> bool:
        return id(item) in self._ids or super().__contains__(item)

    def __iter__(self) -> Iterator[Any]:
        if self.topic is None:
            return super().__iter__()
        return iter(self._by_topic.get(self.topic, ()))


class _RosbagsWriteBackend(WriteBackend):
    ros_version: int

    def __init__(self, path: Path) -> None:
        self.path = path
        self.writer: Any = None
        self.connections: list[Any] = []
        self.definitions = KnownDefinitions()

    def add(self, channel: Channel) -> int:
        msgdef, digest = self.definitions(channel, self.ros_version)
        return self._dedup(
            lambda existing: self._same(existing, channel, msgdef, digest),
            lambda: self._add_connection(channel, msgdef, digest),
        )

    def _add_connection(self, channel: Channel, msgdef: str, digest: str) -> Any:
        """Register ``channel`` with the rosbags writer; return the new connection."""
        raise NotImplementedError

    def _same(self, existing: Any, channel: Channel, msgdef: str, digest: str) -> bool:
        """Whether the rosbags connection ``existing`` is the one :meth:`_add_connection` would
        add for ``channel``, in every argument rosbags compares to refuse it twice."""
        raise NotImplementedError

    @contextlib.contextmanager
    def _checked_alone(self, topic: str) -> Iterator[None]:
        """While rosbags adds a connection of ``topic``, its check for the same connection added
        twice sees that topic's connections alone (:class:`_IndexedConnections`)."""
        self.writer.connections.topic = topic
        try:
            yield
        finally:
            self.writer.connections.topic = None

    def _index_connections(self) -> None:
        """Give the opened rosbags writer an :class:`_IndexedConnections` (it has none yet)."""
        if self.writer.connections:
            raise RuntimeError("the rosbags writer holds connections already")
        self.writer.connections = _IndexedConnections()

    def _dedup(self, same: Callable[[Any], bool], create: Callable[[], Any]) -> int:
        from rosbags.rosbag1 import WriterError as Ros1WriterError
        from rosbags.rosbag2 import WriterError as Ros2WriterError

        try:
            self.connections.append(create())
        except (Ros1WriterError, Ros2WriterError) as err:
            if "once" not in str(err):  # "Connection(s) can only be added once ..."
                raise
            # The same connection twice (a ROS 1 node that reconnected, channels of a merged MCAP
            # file): share the one alike in every argument, not the first of its topic and type,
            # which may be another publisher's or of other QoS (its messages were moved there).
            for existing in list(self.connections):
                if same(existing):
                    self.connections.append(existing)
                    return len(self.connections) - 1
            raise
        return len(self.connections) - 1

    def write(
        self, handle: int, log_time_ns: int, data: bytes | memoryview, publish_ns: int, seq: int
    ) -> None:
        with _sqlite_as_os_errors():
            self.writer.write(self.connections[handle], log_time_ns, data)

    def close(self) -> None:
        with _sqlite_as_os_errors():
            self.writer.close()

    def abort(self) -> None:
        if self.writer is not None:
            try:
                self.writer.close()
            except Exception:  # the output is deleted anyway
                _LOG.debug("closing an aborted writer failed", exc_info=True)
                # rosbags closes its file last, after writing the index: a close that failed
                # (a full disk) left it open, and the deleted output kept its disk space until
                # the process ended (a batch's later recordings found the disk still full).
                _release_files(self.writer)
            self.writer = None


def _release_files(writer: Any) -> None:
    """Close the files a rosbags writer holds (a ROS 1 bag's, a ROS 2 storage's MCAP file or
    SQLite connection), whatever state a failed close left them in."""
    for holder in (writer, getattr(writer, "storage", None)):
        for name in ("bio", "conn"):
            handle = getattr(holder, name, None)
            if handle is not None:
                with contextlib.suppress(Exception):  # a flush onto the full disk fails again
                    handle.close()


class Ros1WriteBackend(_RosbagsWriteBackend):
    ros_version = 1
    _chunks_written = 0  # chunks of the writer whose index entries are counted only

    def open(self) -> None:
        from rosbags.rosbag1 import Writer

        self.writer = Writer(self.path)
        self.writer.open()
        self._index_connections()
        self._chunks_written = 0

    def write(
        self, handle: int, log_time_ns: int, data: bytes | memoryview, publish_ns: int, seq: int
    ) -> None:
        super().write(handle, log_time_ns, data, publish_ns, seq)
        if len(self.writer.chunks) - 1 > self._chunks_written:
            self._count_only_written_chunks()

    def _count_only_written_chunks(self) -> None:
        """Keep only how many messages of each connection a written chunk holds: rosbags keeps
        every message's time and place (about 130 bytes) of every chunk until the bag closes,
        where its chunk infos need their number alone; a bag of 1.2 million messages held
        150 MB of them. The writer's chunks (rosbags' internals, pinned below 0.12): each
        written one but the last, which is the one filling."""
        chunks = self.writer.chunks
        for chunk in chunks[self._chunks_written : len(chunks) - 1]:
            for cid, entries in chunk.connections.items():
                chunk.connections[cid] = range(len(entries))  # len() is all that is read
        self._chunks_written = len(chunks) - 1

    def _add_connection(self, channel: Channel, msgdef: str, digest: str) -> Any:
        require_definition(channel, msgdef)
        with self._checked_alone(channel.topic):
            return self.writer.add_connection(
                channel.topic,
                channel.msgtype,
                msgdef=msgdef,
                md5sum=digest,
                callerid=channel.callerid,
                latching=channel.latching,
            )

    def _same(self, existing: Any, channel: Channel, msgdef: str, digest: str) -> bool:
        return (
            (existing.topic, existing.msgtype) == (channel.topic, channel.msgtype)
            and (existing.msgdef.data, existing.digest) == (msgdef, digest)
            and (existing.ext.callerid, existing.ext.latching)
            == (channel.callerid, channel.latching)
        )


class Ros2WriteBackend(_RosbagsWriteBackend):
    ros_version = 2

    def __init__(self, path: Path, fmt: LogFormat, qos_style: QosStyle = "v9") -> None:
        super().__init__(path)
        self.format = fmt
        self.qos_style = qos_style

    def open(self) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if self.format == "mcap-dir" else StoragePlugin.SQLITE3
        # rosbag2 format 8 spells QoS policies as integers (what Humble reads), format 9 as names.
        version: Literal[8, 9] = 8 if self.qos_style == "v8" else 9
        self.writer = Writer(self.path, version=version, storage_plugin=plugin)
        self.writer.open()
        self._index_connections()

    def set_custom_data(self, data: Mapping[str, str]) -> None:
        """Key-value text for the bag's metadata.yaml ``custom_data`` (:func:`bag_custom_data`)."""
        for key, value in data.items():
            self.writer.set_custom_data(key, value)

    def _add_connection(self, channel: Channel, msgdef: str, digest: str) -> Any:
        storage = self.writer.storage
        if not msgdef:
            warn_no_definition(channel)
            # rosbags would store an empty ros2msg definition, which its readers parse as a type
            # without fields whose hash then mismatches (they refuse the bag): store none instead,
            # as Humble's rosbag2 does.
            storage.add_msgtype = functools.partial(_add_type_without_definition, storage)
        try:
            with self._checked_alone(channel.topic):
                return self.writer.add_connection(
                    channel.topic,
                    channel.msgtype,
                    msgdef=msgdef,
                    rihs01=digest or "RIHS01_" + "0" * 64,
                    serialization_format=channel.message_encoding,
                    offered_qos_profiles=offered_qos(channel),
                )
        finally:
            storage.__dict__.pop("add_msgtype", None)

    def _same(self, existing: Any, channel: Channel, msgdef: str, digest: str) -> bool:
        # rosbags tells ROS 2 connections apart by topic, type, serialisation and QoS.
        return (
            (existing.topic, existing.msgtype) == (channel.topic, channel.msgtype)
            and existing.ext.serialization_format == channel.message_encoding
            and list(existing.ext.offered_qos_profiles) == offered_qos(channel)
        )


def _add_type_without_definition(storage: Any, connection: Any) -> None:
    """Register ``connection``'s type with a rosbags storage writer without a definition: no
    ``message_definitions`` row in SQLite, a schema without encoding or data in MCAP (read back as
    ``MessageDefinitionFormat.NONE``)."""
    from rosbags.rosbag2.storage_mcap import McapWriter, Schema, write_schema

    # rosbags internals (pinned below 0.12): the MCAP storage's schema list and open chunk.
    if isinstance(storage, McapWriter):
        storage.schemas.append(Schema(len(storage.schemas) + 1, connection.msgtype, "", ""))
        write_schema(storage.chunk.bio, storage.schemas[-1])
