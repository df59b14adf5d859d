"""Cross-checks of a ROS 2 bag folder: does ``metadata.yaml`` agree with the storage files it describes?
And did a log file change while it was read (:class:`FileState`)?

rosbags takes topic names and types from ``metadata.yaml``; a file that declares ``/scan`` as
``nav_msgs/msg/OccupancyGrid`` would make every scan a malformed map. The storage files record the
type of each topic themselves (the sqlite3 ``topics`` table, MCAP schemas), so a disagreement is
detected here and reported as a corrupt log. Storage files are opened read-only (sqlite3
``immutable=1``: no journal or lock file is created next to the input).
"""

from __future__ import annotations

import dataclasses
import os
import sqlite3
from collections.abc import Collection
from pathlib import Path
from urllib.parse import quote

from rose_logs.storage.records import normalize_msgtype

__all__ = ["FileState", "storage_types", "storage_types_by_file", "type_mismatches"]


def _sqlite_types(path: Path) -> dict[str, str]:
    uri = f"file:{quote(str(path.resolve()))}?mode=ro&immutable=1"
    conn = sqlite3.connect(uri, uri=True)
    try:
        rows = conn.execute("SELECT name, type FROM topics").fetchall()
    finally:
        conn.close()
    return {str(name): normalize_msgtype(str(kind)) for name, kind in rows}


def _mcap_types(path: Path) -> dict[str, str]:
    from rose_logs.storage.mcap import load_decompressors

    load_decompressors()
    from mcap.reader import SeekingReader

    with path.open("rb") as stream:
        size = path.stat().st_size
        summary = SeekingReader(stream, record_size_limit=max(size, 1)).get_summary()
    if summary is None:
        return {}
    types = {}
    for channel in summary.channels.values():
        schema = summary.schemas.get(channel.schema_id)
        if schema is not None and channel.message_encoding in {"cdr", "ros1"}:
            types[channel.topic] = normalize_msgtype(schema.name)
    return types


def storage_types(folder: Path, *, skip: Collection[str] = ()) -> dict[str, str]:
    """Topic -> message type as recorded by the storage files of a ROS 2 bag folder (but those
    named in ``skip``: files that do not open, left out by ``--salvage``).

    Raises
    ------
    sqlite3.Error, OSError, mcap errors
        If a storage file cannot be read (the caller reports a corrupt log).
    """
    types: dict[str, str] = {}
    for _, stored in storage_types_by_file(folder, skip=skip):
        types.update(stored)
    return types


def storage_types_by_file(
    folder: Path, *, skip: Collection[str] = ()
) -> list[tuple[Path, dict[str, str]]]:
    """Each storage file of a ROS 2 bag folder (but those named in ``skip``) with its topic ->
    message type, in name order: a split bag's files are checked each on its own (merged, a
    later file's type of a topic hid an earlier one's).

    Raises
    ------
    sqlite3.Error, OSError, mcap errors
        If a storage file cannot be read (the caller reports a corrupt log).
    """
    files: list[tuple[Path, dict[str, str]]] = []
    for path in sorted(folder.iterdir()):
        if path.name in skip:
            continue
        if path.suffix == ".db3":
            files.append((path, _sqlite_types(path)))
        elif path.suffix == ".mcap":
            files.append((path, _mcap_types(path)))
    return files


def type_mismatches(declared: dict[str, str], stored: dict[str, str]) -> list[str]:
    """``"<topic>: metadata.yaml says A, the storage B"`` for every topic whose types disagree."""
    return [
        f"{topic}: metadata.yaml says {kind or 'no type'}, the storage {stored[topic] or 'no type'}"
        for topic, kind in sorted(declared.items())
        if topic in stored and normalize_msgtype(kind) != stored[topic]
    ]


#: Bytes of a log file's start, and of its end as it was, compared to tell it changed: a ROS 1
#: bag's header record (4096 bytes) holds where its index is, an MCAP file's end its summary.
_COMPARED = 4096
#: How an SQLite database file begins (a ``.db3`` bag's storage file, whatever its name).
_SQLITE_MAGIC = b"SQLite format 3\x00"
#: The names of a ROS 2 bag folder's storage files end so.
_STORAGE = (".db3", ".mcap", ".db3.zstd", ".mcap.zstd")


@dataclasses.dataclass(frozen=True)
class FileState:
    """What a log file was when it was opened, to tell whether another program changed it
    while it was read (:meth:`changed`): overwritten, truncated or replaced, its reading
    fails as damage (or salvages another file's bytes), which the log is not. A file that only
    grew (a recording still being written, its start and what was its end unchanged) has not
    changed. An SQLite database (a ``.db3`` storage file) written to has: rosbags reads it
    ``immutable``, without SQLite's locks, so a recording's transactions (rosbag2 rewrites its
    header at each) change the pages under the reading (read as 'database disk image is
    malformed', or messages missing and out of order)."""

    path: Path
    device: int
    inode: int
    size: int  # bytes
    mtime_ns: int  # its last modification, ns since the epoch
    head: bytes  # its first :data:`_COMPARED` bytes
    tail: bytes  # its last :data:`_COMPARED` bytes, at :attr:`size`

    @classmethod
    def of(cls, path: Path) -> FileState | None:
        """The state of the regular file ``path`` now (None: a folder, or no file to read)."""
        if not path.is_file():  # (a FIFO is not opened: that would wait for a writer)
            return None
        try:
            with path.open("rb") as stream:
                info = os.fstat(stream.fileno())
                head = stream.read(_COMPARED)
                stream.seek(max(info.st_size - _COMPARED, 0))
                tail = stream.read(_COMPARED)
        except OSError:
            return None
        return cls(path, info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns, head, tail)

    @classmethod
    def of_log(cls, path: Path) -> list[FileState]:
        """The state of the log ``path``'s files now: the file, or a ROS 2 bag folder's storage
        files and metadata.yaml."""
        if not path.is_dir():
            state = cls.of(path)
            return [] if state is None else [state]
        try:
            names = sorted(entry.name for entry in path.iterdir())
        except OSError:
            return []
        return [
            state
            for name in names
            if name == "metadata.yaml" or name.endswith(_STORAGE)
            if (state := cls.of(path / name)) is not None
        ]

    def changed(self) -> str | None:
        """How the file changed since this state, in words (None: it did not, or only grew).
        A write inside it, its size and ends as they were, shows in its modification time
        alone: a ROS 1 bag has no checksum, and a map's bytes written over read as a map."""
        now = FileState.of(self.path)
        if now is None:
            return "it is gone"
        if (now.device, now.inode) != (self.device, self.inode):
            return "another file took its name"
        if now.size < self.size:
            return f"cut from {self.size:,} to {now.size:,} bytes"
        if now.size == self.size and now.mtime_ns == self.mtime_ns:
            return None
        # Grown, or written in place: compared at its ends (a file written over by another
        # differs there; one that grew, a recording still being written, does not).
        try:
            with self.path.open("rb") as stream:
                stream.seek(max(self.size - _COMPARED, 0))
                tail = stream.read(len(self.tail))
        except OSError:
            return "it can no longer be read"
        if now.head != self.head or tail != self.tail:
            if self.head.startswith(_SQLITE_MAGIC) and now.head.startswith(_SQLITE_MAGIC):
                # (Each transaction rewrites the header: a recording, or a database copied over.)
                return "written to as an SQLite database"
            return "written over"
        return "written to" if now.size == self.size else None
