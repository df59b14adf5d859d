"""What storage backends exchange: channels (topic, type, definition, QoS, metadata) and raw messages.

Also the two spellings of a ROS message type name (ROS 1 ``pkg/Name``, ROS 2 ``pkg/msg/Name``).
"""

from __future__ import annotations

import heapq
import os
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

from rosbags.interfaces import Qos

from rose.limits import short

__all__ = [
    "Channel",
    "RawMessage",
    "merged_by_log_time",
    "normalize_msgtype",
    "parse_latching",
    "read_at",
    "read_part_way",
    "ros1_msgtype",
]


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


def parse_latching(text: str | None) -> int | None:
    """ROS 1 latching flag from connection-header / MCAP metadata text: 1, 0 or None when unknown.

    Both spellings in use are accepted: ``"1"`` / ``"0"`` (the ROS 1 connection header, and MCAP files
    converted from bags) and ``"true"`` / ``"false"`` (the MCAP registry's ``ros1`` profile), in any case
    and with surrounding blanks.
    """
    if text is None:
        return None
    value = text.strip().lower()
    if value in {"1", "true"}:
        return 1
    if value in {"0", "false"}:
        return 0
    return None


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
    schema_data : bytes
        MCAP schema data as stored, copied as it is: a protobuf or flatbuffer schema is binary, no
        text (``msgdef`` is its UTF-8 reading); ``b""`` for other formats.
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
    schema_data: bytes = b""


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


def merged_by_log_time(files: Iterable[Iterator[RawMessage]]) -> Iterator[RawMessage]:
    """The messages of the storage files of one log (``files``: each file's, in log-time order)
    in log-time order, a file's before a later file's of the same time. A recording split in
    time (rosbag2's ``--max-bag-size``) reads as its files one after the other; files listed
    out of their time order, or overlapping in time, came out of order: a map snapshot before
    the one it follows (a break found where there is none, a time range ending before it
    starts)."""
    iterators = list(files)
    if len(iterators) == 1:
        yield from iterators[0]
        return
    yield from heapq.merge(*iterators, key=_log_time)


def _log_time(message: RawMessage) -> int:
    return message.log_time_ns


#: The most bytes one ``os.pread`` is asked for (Linux returns at most 0x7ffff000).
_PREAD_MOST = 2**30


def read_at(f: BinaryIO, count: int, offset: int) -> bytes:
    """``count`` bytes of the file ``f`` from ``offset`` (fewer at its end). On POSIX ``pread``
    calls that leave the file's position as it was (threads may read one file so): one, up to
    1 GiB; elsewhere (Windows has no pread) a seek and a read."""
    if not hasattr(os, "pread"):
        f.seek(offset)
        return bytes(f.read(count) or b"")
    # One call reads at most 2 GiB (Linux; macOS refuses more): a chunk that large, read in parts.
    parts: list[bytes] = []
    while count > 0:
        part = os.pread(f.fileno(), min(count, _PREAD_MOST), offset)
        if not part:
            break
        parts.append(part)
        count -= len(part)
        offset += len(part)
    return parts[0] if len(parts) == 1 else b"".join(parts)


def read_part_way(path: Path, read: int, why: str) -> str:
    """The loss of the storage file ``path`` of a split bag whose reading failed (``why``) after
    ``read`` of its messages, under ``--salvage``, which reads the bag's other files on."""
    kept = (
        f"cannot be read past its first {read} messages"
        if read
        else "none of its messages can be read"
    )
    return f"{path}: {kept} ({short(why, 120)}); the bag's other files are read"
