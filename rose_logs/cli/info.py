"""``rose-bag info LOG``: map topics, message counts, grid sizes and the time range of a log."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from rose.cli.options import path_arg
from rose.limits import visible
from rose_logs.cli.options import EXIT_SALVAGED, duration_text, utc_text
from rose_logs.storage.records import Channel, ros1_msgtype

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "info",
        help="map topics, message counts, grid sizes and resolutions, time range of a log",
        description="Describe a log without analysing it: its map topics, message counts, grid "
        "sizes and resolutions, and time range (a ROS 1 bag, a ROS 2 bag folder or storage file, "
        "or an MCAP file).",
    )
    parser.add_argument(
        "input", type=path_arg, help="ROS 1 .bag, ROS 2 bag folder / .db3, or .mcap"
    )
    parser.add_argument(
        "--salvage",
        action="store_true",
        help=f"on a damaged log, describe what can be read, list the losses and exit {EXIT_SALVAGED} "
        "(default: a damaged log is an error), as process --salvage reads it",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rose_logs.errors import EmptyMapError, MapMessageError
    from rose_logs.reader import LogReader
    from rose_logs.session import find_map_topics
    from rose_logs.session.topics import publishers
    from rose_logs.snapshots import decode_map

    # Everything is read before anything is printed: a log damaged half-way is an error line, not
    # half a report followed by one.
    with LogReader(args.input, salvage=args.salvage) as reader:
        channels = reader.channels
        map_topics = find_map_topics(channels)
        stats: dict[str, dict[str, Any]] = {
            t: {"sizes": {}, "res": set(), "frames": set(), "bad": 0, "empty": 0}
            for t in map_topics
        }
        read: dict[str, int] = dict.fromkeys(map_topics, 0)  # what the map topics hold
        # --salvage reads every topic, as process --salvage does: read for the map topics alone,
        # a loss counted and said only theirs (a split bag's file lost part way held /scan too).
        for message in reader.messages(topics=None if args.salvage else map_topics):
            topic = message.channel.topic
            if topic not in read:
                continue
            read[topic] += 1
            if message.channel.msgtype != "nav_msgs/msg/OccupancyGrid":
                continue
            try:
                snap = decode_map(
                    message.data,
                    serialization=message.channel.message_encoding,
                    topic=topic,
                    log_time_ns=message.log_time_ns,
                )
            except MapMessageError as err:
                # A map of no cells is a valid message (process counts it as empty), not a bad one.
                stats[topic]["empty" if isinstance(err, EmptyMapError) else "bad"] += 1
                continue
            stats[topic]["sizes"].setdefault((snap.shape[1], snap.shape[0]), None)  # as they came
            stats[topic]["last"] = (snap.shape[1], snap.shape[0])
            stats[topic]["res"].add(snap.resolution_decimal_m)
            stats[topic]["frames"].add(snap.frame_id)
        # Names escaped as the topics' are: a newline in a file name split the line.
        print(f"file         {visible(str(args.input), keep_undecodable=True)}")
        print(f"format       {reader.format} ({reader.serialization})")
        declared = " (declared)" if reader.losses and reader.counts_declared else ""
        # The map topics as read (an index can undercount them: a warning says so), the other
        # topics as declared (only --salvage reads them, to count their losses). After a loss
        # the counts stay as declared, and the loss says how many were read.
        if reader.losses:
            read = {}
        total = reader.message_count + sum(read.values())
        total -= sum(c.message_count for c in channels if c.topic in read)
        print(f"messages     {total}{declared}")
        if reader.message_count:
            print(
                f"time range   {utc_text(reader.start_ns)} .. {utc_text(reader.end_ns)} UTC "
                f"({duration_text(reader.end_ns - reader.start_ns)}){declared}"
            )
        _print_topics(channels, map_topics, read)
        for topic in map_topics:
            _print_map_topic(topic, stats[topic], publishers(channels, topic))
        if not map_topics:
            print("\nno nav_msgs/OccupancyGrid topic")
        if reader.losses:
            print(f"\nlosses       {visible(reader.losses[0], keep_undecodable=True)}")
            for loss in reader.losses[1:]:
                print(f"             {visible(loss, keep_undecodable=True)}")
            return EXIT_SALVAGED
    return 0


def _print_topics(
    channels: Sequence[Channel], map_topics: Sequence[str], read: dict[str, int]
) -> None:
    """Each topic with its message count (``read`` for the map topics, else declared) and type(s),
    map topics marked."""
    counts: dict[str, int] = {}
    types: dict[str, list[str]] = {}  # a topic may carry several types, one per connection
    for c in channels:
        counts[c.topic] = counts.get(c.topic, 0) + c.message_count
        known = types.setdefault(c.topic, [])
        # As the log spells it: pkg/Name in a ROS 1 bag or ros1 MCAP, pkg/msg/Name for ROS 2.
        name = ros1_msgtype(c.msgtype) if c.message_encoding == "ros1" else c.msgtype
        if name not in known:
            known.append(name)
    counts.update(read)
    width = max((len(visible(t)) for t in counts), default=5)
    from rose_logs.session.topics import default_map_topics

    # As process picks them by default: costmaps only when the log publishes no other map.
    skipped = set(default_map_topics(channels)[2])
    print("\ntopics")
    for topic in sorted(counts):
        mark = "  [map]" if topic in map_topics else ""
        if topic in skipped:
            mark = "  [map: a costmap, analysed only with --topic]"
        kinds = ", ".join(visible(t) for t in sorted(types[topic]))
        print(f"  {visible(topic):<{width}}  {counts[topic]:>8}  {kinds}{mark}")


def _print_map_topic(topic: str, s: dict[str, Any], nodes: Sequence[str]) -> None:
    """Grid sizes (in the order they came), resolutions and frames of a map topic's messages, and
    its publishers when the log names them (ROS 1)."""
    print(f"\nmap topic    {visible(topic)}")
    if nodes:
        several = "  (analysed as one session)" if len(nodes) > 1 else ""
        print(f"  publishers   {', '.join(visible(n) for n in nodes)}{several}")
    sizes = [f"{w} x {h}" for w, h in s["sizes"]]
    if sizes:
        # In the order they came, so a growing map's last size shows.
        shown = sizes if len(sizes) <= 6 else [*sizes[:3], "...", *sizes[-3:]]
        more = f" ({len(sizes)} sizes)" if len(sizes) > 6 else ""
        last = "{} x {}".format(*s["last"])
        if last != sizes[-1]:  # back to an earlier size at the end
            more += f", last {last}"
        print(f"  grid sizes   {', '.join(shown)}{more}")
        print(f"  resolution   {', '.join(f'{r:g}' for r in sorted(s['res']))} m")
        frames = (repr(f) if not f.strip() else visible(f) for f in sorted(s["frames"]))
        print(f"  frame        {', '.join(frames)}")
    if s["bad"]:
        print(f"  malformed    {s['bad']}")
    if s["empty"]:
        print(f"  empty        {s['empty']}")
    if not sizes and not s["bad"] and not s["empty"]:
        print("  no messages  (declared only: not a map of the session)")
