"""A ROS 2 SQLite bag's messages in log-time order without sorting its messages table.

rosbags' :meth:`~rosbags.rosbag2.storage_sqlite3.Sqlite3Reader.messages` asks SQLite for the
wanted rows ``ORDER BY timestamp``. A bag with rosbag2's ``timestamp_idx`` index is read through
it; one without (older rosbag2, or an index dropped) is sorted whole before its first message: a
temporary B-tree of every wanted row, data included, on the temporary disk (1 KB messages: as
many bytes as the bag; a bag larger than the free space of ``/tmp`` fails) and a wait of the
whole sort before anything is read. Such a bag was nearly always written in time order, rows
inserted as the messages came: :func:`ordered_messages` then reads its rows in the table's own
order (by rowid, nothing sorted, nothing held), giving the messages in the order the sort gives
them (SQLite's sort is stable: ties in the order its plan scans the rows, which is asked of
SQLite for rosbags' own query). Rows out of time order, a time that is no integer, a plan not
known here, or a bag with the index: rosbags' reading, as before.
"""

from __future__ import annotations

import heapq
from collections.abc import Collection, Iterator
from operator import itemgetter
from typing import Any, Literal

__all__ = ["ordered_messages"]

#: rosbags' query (pinned below 0.12) with its IN list of ``{}`` placeholders; SQLite's plan of it
#: says whether it sorts and in which order it scans the rows it sorts.
_ROSBAGS_QUERY = (
    "SELECT topics.id,messages.timestamp,messages.data FROM messages JOIN topics "
    "ON messages.topic_id=topics.id WHERE topics.id IN ({}) ORDER BY timestamp"
)
_SORTS = "USE TEMP B-TREE FOR ORDER BY"
_BY_TOPIC = "SEARCH topics USING INTEGER PRIMARY KEY (rowid=?)"
_SCAN = "SCAN messages"
_TIME = itemgetter(1)

_Scan = Literal["rowid", "topic"]


def ordered_messages(
    storage: Any,
    connections: Collection[Any],
    start: int | None = None,
    stop: int | None = None,
) -> Iterator[tuple[Any, int, Any]]:
    """rosbags' ``storage.messages(connections, start, stop)`` of a SQLite storage file (rosbags'
    ``Sqlite3Reader``, open): the same (connection, log time ns, data) tuples in the same order,
    read in the table's row order where SQLite would sort the whole table for it (see the module
    notes). ``start`` / ``stop`` (not used by rose-bag): rosbags' reading."""
    rosbags = type(storage).messages
    ids = sorted({int(conn.id) for conn in connections})
    plain = not ids or start is not None or stop is not None
    sorted_by = None if plain else _sorted_scan(storage.dbconn, ids)
    read_by = None if sorted_by is None else _unsorted_scan(storage.dbconn, ids, sorted_by)
    if read_by is None:
        yield from rosbags(storage, connections, start, stop)
        return
    by_id = {conn.id: conn for conn in storage.connections}
    query = "SELECT topic_id, timestamp, data FROM messages WHERE topic_id {} ORDER BY rowid"
    if read_by == "rowid":
        rows = storage.dbconn.execute(query.format(_in_list(ids)), ids)
    else:  # a topic's rows after another's, sorted stably: merged by time, ties in topic order
        rows = heapq.merge(
            *(storage.dbconn.execute(query.format("= ?"), (cid,)) for cid in ids), key=_TIME
        )
    for cid, timestamp, data in rows:
        yield by_id[cid], timestamp, data


def _in_list(ids: list[int]) -> str:
    return f"IN ({','.join('?' * len(ids))})"


def _sorted_scan(db: Any, ids: list[int]) -> _Scan | None:
    """How SQLite runs rosbags' query for the topics ``ids`` when it sorts the rows (no index of
    the messages' times to read them by): ``"rowid"``, the table scanned once, its rows sorted
    in their order; ``"topic"``, each topic's rows in turn (ids ascending: SQLite's IN list),
    each in row order. None: it reads through an index, already in order (or a plan not known
    here, whose order of ties is not known either)."""
    query = _ROSBAGS_QUERY.format(",".join("?" * len(ids)))
    plan = [str(row[3]) for row in db.execute(f"EXPLAIN QUERY PLAN {query}", ids)]
    if _SORTS not in plan:
        return None
    loops = [step for step in plan if step != _SORTS]
    if loops == [_SCAN, _BY_TOPIC]:
        return "rowid"
    if loops == [_BY_TOPIC, _SCAN]:
        return "topic"
    return None


def _unsorted_scan(db: Any, ids: list[int], sorted_by: _Scan) -> _Scan | None:
    """How to read the rows of the topics ``ids`` in the order SQLite's sort of them, scanned
    ``sorted_by``, gives, without sorting: ``"rowid"``, in row order (their integer times do
    not decrease in it, and the sort scans them so, or no two topics share a time); ``"topic"``,
    each topic's in row order merged by time (each topic's times do not decrease); None: sorted
    (rosbags' reading). One pass over the table's topics and times (no message data read beyond
    its pages)."""
    rows = db.execute(
        f"SELECT topic_id, timestamp FROM messages WHERE topic_id {_in_list(ids)} ORDER BY rowid",
        ids,
    )
    in_order = each_in_order = True
    shared = False  # two topics' rows of the same time, next to each other (in order: any)
    last_topic, last = -1, -(2**63)
    latest: dict[int, int] = {}
    for cid, timestamp in rows:
        if type(timestamp) is not int:
            return None
        if timestamp < last:
            in_order = False
        elif timestamp == last and cid != last_topic:
            shared = True
        if timestamp < latest.get(cid, timestamp):
            each_in_order = False
            if not in_order:
                return None
        last_topic, last, latest[cid] = cid, timestamp, timestamp
    if in_order and (sorted_by == "rowid" or not shared):
        return "rowid"
    return "topic" if sorted_by == "topic" and each_in_order else None
