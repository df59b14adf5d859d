"""Which topics a session analyses (map topics, their updates, our own derived topics) and output names."""

from __future__ import annotations

import contextlib
import difflib
import logging
from collections.abc import Sequence
from pathlib import Path

from rose.limits import short
from rose.outputs import enclosing_bag_folder
from rose_logs.derived import derived_topics
from rose_logs.errors import LogReadError, LogWriteError
from rose_logs.formats import (
    ACTIVE_BAG,
    LogFormat,
    detect_format,
    format_from_path,
    processed_name,
)
from rose_logs.storage.records import Channel
from rose_logs.storage.typesys import MAP_TYPE, UPDATE_TYPE, msgdef_for

__all__ = [
    "default_map_topics",
    "default_output_path",
    "find_map_topics",
    "is_costmap",
    "is_derived_topic",
    "orphan_updates",
    "publishers",
    "rose_topics_in",
    "select_topics",
    "update_targets",
    "warn_shared_map_topics",
    "warn_unknown_definitions",
]


_LOG = logging.getLogger(__name__)

_DECODABLE = {"ros1", "cdr"}
#: The map topics we add ourselves end so (only ``<map>/rose/cleaned`` is an OccupancyGrid).
_DERIVED_MAP_SUFFIX = derived_topics("").cleaned


def is_derived_topic(topic: str) -> bool:
    """Whether ``topic`` is our own cleaned map (``<map>/rose/cleaned``), never analysed again.

    Only the exact suffix counts: ``/rose/map`` (a robot called rose) is a map like any other.
    """
    return topic.endswith(_DERIVED_MAP_SUFFIX)


def rose_topics_in(channels: Sequence[Channel], map_topics: Sequence[str] = ()) -> list[str]:
    """Topics of ``channels`` that are ``<map>/rose/*`` outputs of a run before, sorted: those of
    every map of the log (``map_topics`` and the maps in ``channels``), and all three of any
    cleaned map (``<map>/rose/cleaned``) whose map is not in the log."""
    maps = {*map_topics, *(c.topic for c in channels if c.msgtype == MAP_TYPE)}
    maps |= {t[: -len(_DERIVED_MAP_SUFFIX)] for t in maps if is_derived_topic(t)}
    ours = {name for topic in maps for name in derived_topics(topic).names}
    return sorted({c.topic for c in channels if c.topic in ours})


def find_map_topics(channels: Sequence[Channel]) -> tuple[str, ...]:
    """Topics of type ``nav_msgs/OccupancyGrid`` (ROS 1 or ROS 2), sorted, without our derived topics."""
    return tuple(
        sorted(
            {
                c.topic
                for c in channels
                if c.msgtype == MAP_TYPE
                and c.message_encoding in _DECODABLE
                and not is_derived_topic(c.topic)
            }
        )
    )


def update_targets(
    channels: Sequence[Channel], map_topics: Sequence[str] | None = None
) -> dict[str, str]:
    """Update topic -> map topic, for the updates of the analysed ``map_topics`` (default: all).

    An update topic belongs to ``<map>_updates``'s map by name (to none if that map is not in the
    log), else to the log's only map topic.
    The owner is decided among every ``OccupancyGrid`` topic of the log (those we cannot decode
    too), so that picking one map (``--topic``) never hands it another map's patches; updates of
    maps not analysed are left out.
    """
    grids = _grid_topics(channels)
    wanted = set(find_map_topics(channels) if map_topics is None else map_topics)
    owners = {c.topic: _owner(c.topic, grids) for c in _update_channels(channels)}
    return {topic: owner for topic, owner in owners.items() if owner in wanted}


def orphan_updates(channels: Sequence[Channel]) -> tuple[Channel, ...]:
    """Update channels whose map cannot be told (``<map>_updates`` without its map in the log, or
    another name and several map topics)."""
    grids = _grid_topics(channels)
    return tuple(c for c in _update_channels(channels) if _owner(c.topic, grids) is None)


def _grid_topics(channels: Sequence[Channel]) -> list[str]:
    return sorted(
        {c.topic for c in channels if c.msgtype == MAP_TYPE and not is_derived_topic(c.topic)}
    )


def _update_channels(channels: Sequence[Channel]) -> list[Channel]:
    return [c for c in channels if c.msgtype == UPDATE_TYPE and c.message_encoding in _DECODABLE]


def _owner(topic: str, grids: Sequence[str]) -> str | None:
    """The map topic an update topic patches: ``<map>_updates``'s map (None when that map is not in
    the log: another costmap's patches, ``/local_costmap/costmap_updates`` beside ``/map``, must
    not land on the only map), else the only map."""
    if topic.endswith("_updates"):
        named = topic.removesuffix("_updates")
        return named if named in grids else None
    return grids[0] if len(grids) == 1 else None


def default_output_path(input_path: Path, fmt: LogFormat | None = None) -> Path:
    """``run.mcap`` -> ``run.rose.mcap``, ``run.bag`` (or ``run.bag.active``) -> ``run.rose.bag``,
    folder ``run`` -> ``run.rose``; with an output format ``fmt``, that format's suffix
    (:func:`rose_logs.formats.processed_name`).

    A path without a name of its own (``.``, ``bags/..``) is named by its absolute form. A storage
    file inside a ROS 2 bag folder gets its output beside that folder, never inside the input bag.
    A log named as another format (an MCAP file named ``.bag`` or ``.db3``) keeps its own format
    and gets its suffix: ``run.rose.bag`` could not hold its messages, and the caller named no
    output. A file whose name says no format
    gets its content's suffix, or ``fmt``'s, after its whole name (``run`` holding MCAP ->
    ``run.rose.mcap``, ``run.1`` -> ``run.1.rose.mcap``, ``run.1`` as ``db3`` -> ``run.1.rose``).
    """
    path = Path(input_path)
    named = "ros1" if path.name.lower().endswith(ACTIVE_BAG) else format_from_path(path)
    if fmt is None and not path.is_dir():
        # The content's format, so that the output's name says what it holds: a name may say no
        # format (``run``, ``run.log``) or another one (an MCAP file named ``.bag`` or ``.db3``:
        # a bare ``.db3`` names a folder ``run.rose``, and a file of another format was written
        # there under that name).
        with contextlib.suppress(LogReadError):  # unreadable: the reader says so, naming the input
            detected = detect_format(path)
            if detected != named:
                fmt = detected
    # A suffix that names no format is part of the name, with --format too: ``run.1`` and
    # ``run.2`` get two outputs, not both ``run.rose.mcap``.
    whole = fmt is not None and named is None and not path.is_dir()
    if path.name in ("", ".", ".."):
        path = path.resolve()
    if not path.name:
        msg = f"{input_path}: no file name to name the output after; give one with -o"
        raise LogWriteError(msg)
    # (processed_name cuts the last suffix: an empty one, when the name is kept whole.)
    name = processed_name(
        path.name.rstrip(".") + "." if whole else path.name, is_dir=path.is_dir(), fmt=fmt
    )
    folder = path.parent
    bag = enclosing_bag_folder(path)
    if bag is not None and folder.absolute() == bag:  # beside the input bag, not inside it
        folder = bag.parent
    return folder / name


def select_topics(
    path: Path, channels: Sequence[Channel], topics: Sequence[str] | str | None
) -> tuple[str, ...]:
    """The map topics to analyse: ``topics`` (each checked: a map topic of the log), else every
    published ``OccupancyGrid`` topic but costmaps (:func:`is_costmap`; all of them when the log
    holds nothing else), each left out with a warning.

    Raises
    ------
    LogReadError
        A named topic that is not in the log or is no map; no map topic at all.
    """
    found = find_map_topics(channels)
    if isinstance(topics, str):  # one name is one topic, not one-character topics
        topics = (topics,)
    if topics:
        known = {c.topic: c for c in channels}
        for topic in topics:
            if topic not in known:
                msg = f"{path}: no topic {topic} (map topics: {', '.join(found) or 'none'})"
                guess = difflib.get_close_matches(f"/{topic.lstrip('/')}", found, n=1)
                if guess:
                    msg += f"; did you mean {guess[0]}?"
                raise LogReadError(msg)
            if topic not in found:
                msg = f"{path}: topic {topic} {_why_not_a_map(known[topic])}"
                owner = update_targets(channels).get(topic)
                if owner is not None:
                    msg += f" (it updates {owner}: pass --topic {owner})"
                raise LogReadError(msg)
        named = tuple(dict.fromkeys(topics))
        # Named, it is analysed (a gate fails on it: it cannot vouch for it), but its summary's
        # "snapshots 0" passed without a word beside the named maps the log holds (named alone,
        # or with others as empty, the run is an error that says so).
        declared_only = default_map_topics(channels)[1]
        empty = [t for t in named if t in declared_only]
        for topic in empty if len(empty) < len(named) else ():
            _LOG.warning(
                "%s: named with --topic, but the log declares it and holds no message on it: "
                "nothing to analyse (a gate asked for fails on it)",
                topic,
            )
        return named
    if not found:
        names = ", ".join(sorted({c.topic for c in channels})) or "none"
        msg = f"{path}: no nav_msgs/OccupancyGrid topic (topics: {names})"
        unreadable = [c for c in channels if c.msgtype == MAP_TYPE]
        if unreadable:
            msg += f"; {unreadable[0].topic} {_why_not_a_map(unreadable[0])}"
        raise LogReadError(msg)
    chosen, declared_only, costmaps = default_map_topics(channels)
    for topic in declared_only:
        _LOG.warning(
            "%s: a map topic the log declares but holds no message on: not analysed, "
            "and no gate judges it",
            topic,
        )
    for topic in costmaps:
        _LOG.warning(
            "%s: a costmap (a planner's obstacles: people, inflation), not analysed; "
            "name it with --topic to analyse it",
            topic,
        )
    return chosen


def default_map_topics(
    channels: Sequence[Channel],
) -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
    """The map topics analysed when none is named, and those left out: declared but holding no
    message, and costmaps (:func:`is_costmap`).

    A map topic declared but never published is no map of the session (its summary would say
    "snapshots 0", and a gate would fail on it), unless no topic has a message at all. A
    navigation stack's costmaps are OccupancyGrids too, but of a planner's obstacles: people
    walking by, inflated around every wall (analysed by default, a Nav2 recording's local costmap
    failed the break gate on a person passing), unless they are all the log's published maps.
    """
    found = find_map_topics(channels)
    published = {c.topic for c in channels if c.message_count > 0}
    chosen = tuple(t for t in found if t in published) or found
    declared_only = tuple(t for t in found if t not in chosen)
    maps = tuple(t for t in chosen if not is_costmap(t))
    if not maps:
        return chosen, declared_only, ()
    return maps, declared_only, tuple(t for t in chosen if t not in maps)


def is_costmap(topic: str) -> bool:
    """Whether ``topic`` names a navigation stack's costmap (a name part containing ``costmap``:
    Nav2's ``/local_costmap/costmap``, move_base's ``/move_base/global_costmap/costmap``)."""
    return any("costmap" in part.lower() for part in topic.split("/"))


def _why_not_a_map(channel: Channel) -> str:
    """Why ``channel`` is not analysed, as the end of a sentence that starts with its topic."""
    if channel.msgtype != MAP_TYPE:
        return f"is {channel.msgtype}, not nav_msgs/OccupancyGrid"
    if channel.message_encoding not in _DECODABLE:
        return (
            f"is encoded as {channel.message_encoding or 'nothing'}; "
            f"rose-bag reads {' and '.join(sorted(_DECODABLE))}"
        )
    return "is rose-bag's own cleaned map, not analysed again"


def publishers(channels: Sequence[Channel], topic: str) -> list[str]:
    """The nodes that published maps on ``topic`` (connections with messages), sorted, as far as
    the log records them: a ROS 1 connection's ``callerid``, kept in a ROS 1 bag and in an MCAP
    channel's metadata; ROS 2 bags name no publisher (empty)."""
    return sorted(
        {
            c.callerid
            for c in channels
            if c.topic == topic and c.msgtype == MAP_TYPE and c.callerid and c.message_count > 0
        }
    )


def warn_shared_map_topics(channels: Sequence[Channel], map_topics: Sequence[str]) -> None:
    """Warn of each map topic more than one node published maps on (a map_server beside a SLAM
    node): their maps alternate in one session, and each switch looks like a break."""
    for topic in map_topics:
        nodes = publishers(channels, topic)
        if len(nodes) > 1:
            _LOG.warning(
                "%s: maps from %d publishers (%s) are analysed as one session: the break "
                "detector compares one's maps with the other's (-t picks no publisher)",
                topic,
                len(nodes),
                short(", ".join(nodes), 120),
            )


def warn_unknown_definitions(channels: Sequence[Channel], topics: Sequence[str]) -> None:
    """Warn of each ROS 1 connection on ``topics`` (maps and their updates) whose md5sum is not
    ROS's for its type: another definition under the standard name (a fork of ``nav_msgs``). Its
    messages are read with ROS's definition; those that do not decode are skipped as malformed,
    but some may decode into other values."""
    wanted = set(topics)
    said: set[tuple[str, str]] = set()  # several publishers of a topic: one connection each
    for c in channels:
        if c.topic not in wanted or c.message_encoding != "ros1" or c.digest in ("", "*"):
            continue
        if c.msgtype not in (MAP_TYPE, UPDATE_TYPE) or (c.topic, c.digest) in said:
            continue
        said.add((c.topic, c.digest))
        standard = msgdef_for(c.msgtype, "ros1")[1]
        if c.digest != standard:
            _LOG.warning(
                "%s: the log declares %s with md5sum %s, not ROS's %s (another definition under "
                "that name); read with ROS's definition, its maps may be misread",
                c.topic,
                c.msgtype.replace("/msg/", "/"),
                short(c.digest, 40),
                standard,
            )
