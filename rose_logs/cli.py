"""The ``rose-bag`` command: ``process``, ``info`` (and ``convert`` / ``evaluate`` from their modules).

Exit codes: 0 success, 1 error (one line ``error: <file>: <problem>`` on stderr), 2 usage error,
3 ``--fail-above`` gate failed. Tracebacks only with ``--debug``.
"""

from __future__ import annotations

import argparse
import json
import logging
import statistics
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from rose.cli import add_param_arguments, params_from_args, positive_float
from rose.directions import FAILURE_LEVEL
from rose.errors import RoseError
from rose_logs.errors import LogError

__all__ = ["build_parser", "main"]

_LOG = logging.getLogger("rose_logs")
EXIT_GATE = 3


# -- parser --------------------------------------------------------------------------------------
def _add_process_parser(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "process",
        help="run ROSE on every map snapshot of a log; write a cleaned log, Rerun, a report",
        description="Replay a ROS 1 bag, ROS 2 bag (folder or .db3) or MCAP file, run ROSE on every "
        "nav_msgs/OccupancyGrid snapshot (and map_msgs/OccupancyGridUpdate), write every input message "
        "unchanged plus <map>/rose/cleaned, <map>/rose/structure_score and <map>/rose/walls to a new "
        "log, and print a summary.",
    )
    parser.add_argument("input", type=Path, help="ROS 1 .bag, ROS 2 bag folder / .db3, or .mcap")
    parser.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="output log (default: <input>.rose.<ext> next to the input)",
    )
    parser.add_argument(
        "--no-output", action="store_true", help="write no output log (report / Rerun only)"
    )
    parser.add_argument(
        "--format",
        choices=("ros1", "db3", "mcap", "mcap-dir"),
        default=None,
        dest="fmt",
        help="output format (default: from the output suffix, else the input's)",
    )
    parser.add_argument(
        "-f", "--force", action="store_true", help="replace an existing output / recording"
    )
    parser.add_argument(
        "-t",
        "--topic",
        action="append",
        default=None,
        dest="topics",
        help="map topic to analyse (repeatable; default: every OccupancyGrid topic)",
    )
    parser.add_argument("--rrd", type=Path, default=None, help="save a Rerun recording here")
    parser.add_argument(
        "--spawn", action="store_true", help="stream to a new Rerun viewer as the session runs"
    )
    parser.add_argument(
        "--connect",
        metavar="ADDR",
        help="stream to a running Rerun viewer (PORT, HOST:PORT or rerun+http://HOST:PORT/proxy)",
    )
    parser.add_argument(
        "--walls",
        action="store_true",
        help="also extract wall segments per snapshot (marker in <map>/rose/walls, Rerun lines)",
    )
    parser.add_argument(
        "--json", type=Path, default=None, dest="json_path", help="write a JSON report here"
    )
    parser.add_argument(
        "--failure-level",
        type=positive_float,
        default=FAILURE_LEVEL,
        help="W above which a map counts as broken (%(default)s, the paper's)",
    )
    parser.add_argument(
        "--fail-above",
        type=positive_float,
        default=None,
        metavar="W",
        help=f"exit {EXIT_GATE} if any snapshot's W exceeds this (map-quality gate)",
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_param_arguments(parser)
    parser.set_defaults(func=_run_process)


def _add_info_parser(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "info",
        help="map topics, message counts, grid sizes and resolutions, time range of a log",
    )
    parser.add_argument("input", type=Path, help="ROS 1 .bag, ROS 2 bag folder / .db3, or .mcap")
    parser.set_defaults(func=_run_info)


def build_parser() -> argparse.ArgumentParser:
    """The ``rose-bag`` argument parser with every sub-command."""
    parser = argparse.ArgumentParser(
        prog="rose-bag",
        description="ROSE structure extraction and decluttering of occupancy-grid maps in robot logs.",
    )
    parser.add_argument(
        "--debug", action="store_true", help="debug logging and tracebacks on errors"
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    _add_process_parser(subparsers)
    _add_info_parser(subparsers)
    try:
        from rose_logs.carmen_session import add_convert_parser

        add_convert_parser(subparsers)
    except ImportError:  # the converter is optional
        _LOG.debug("convert command unavailable", exc_info=True)
    try:
        from rose_logs.evaluation.cli import add_evaluate_parser

        add_evaluate_parser(subparsers)
    except ImportError:
        _LOG.debug("evaluate command unavailable", exc_info=True)
    return parser


# -- output helpers ------------------------------------------------------------------------------
def _iso(time_ns: int) -> str:
    return datetime.fromtimestamp(time_ns / 1e9, tz=UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]


def _seconds(ns: int) -> str:
    return f"{ns / 1e9:.1f} s"


def _print_summary(report: Any) -> None:
    start = report.start_ns
    out = sys.stdout
    print(
        f"input        {report.input_path} ({report.input_format}, {report.message_count} messages)",
        file=out,
    )
    print(
        f"time range   {_iso(report.start_ns)} .. {_iso(report.end_ns)} UTC "
        f"({_seconds(report.end_ns - report.start_ns)})",
        file=out,
    )
    if report.output_path is not None:
        print(f"output       {report.output_path}", file=out)
    if report.rrd_path is not None:
        print(f"rerun        {report.rrd_path}", file=out)
    for topic in report.map_topics:
        records = report.records_of(topic)
        print(f"\nmap topic    {topic}", file=out)
        if not records:
            print("  snapshots    0", file=out)
            continue
        scores = [r.structure_score for r in records]
        reused = sum(r.reused for r in records)
        updates = sum(r.from_update for r in records)
        extra = ", ".join(
            part
            for part in (
                f"{reused} unchanged" if reused else "",
                f"{updates} from updates" if updates else "",
            )
            if part
        )
        print(f"  snapshots    {len(records)}" + (f" ({extra})" if extra else ""), file=out)
        print(
            f"  time range   +{_seconds(records[0].log_time_ns - start)} .. "
            f"+{_seconds(records[-1].log_time_ns - start)}",
            file=out,
        )
        sizes = sorted({(r.width, r.height) for r in records})
        size_text = f"{sizes[0][0]} x {sizes[0][1]}" + (
            f" .. {sizes[-1][0]} x {sizes[-1][1]}" if len(sizes) > 1 else ""
        )
        print(f"  grid         {size_text} cells", file=out)
        print(
            f"  W            min {min(scores):.3f}  median {statistics.median(scores):.3f}  "
            f"max {max(scores):.3f}",
            file=out,
        )
        first = report.first_break(topic)
        level = f"{report.failure_level:g}"
        if first is None:
            print(f"  W > {level:<8} never", file=out)
        else:
            print(
                f"  W > {level:<8} first at snapshot {first.index}, +{_seconds(first.log_time_ns - start)} "
                f"(W = {first.structure_score:.3f})",
                file=out,
            )
    if report.skipped_messages:
        print(
            f"\nskipped      {report.skipped_messages} malformed map message(s), copied unprocessed",
            file=out,
        )
    print(f"\nelapsed      {report.elapsed_s:.2f} s", file=out)


def _write_json(path: Path, payload: dict[str, Any]) -> None:
    from rose.mapfile import write_atomically

    text = json.dumps(payload, indent=2, allow_nan=False, default=float).encode("utf-8")
    write_atomically(path, lambda f: f.write(text))


# -- commands ------------------------------------------------------------------------------------
def _run_process(args: argparse.Namespace) -> int:
    from rose_logs.session import default_output_path, process_log

    if args.no_output and args.output is not None:
        msg = "--no-output and --output exclude each other"
        raise _UsageError(msg)
    output = None if args.no_output else (args.output or default_output_path(args.input))
    progress = not args.quiet and sys.stderr.isatty()
    report = process_log(
        args.input,
        output_path=output,
        output_format=args.fmt,
        force=args.force,
        topics=args.topics,
        params=params_from_args(args),
        failure_level=args.failure_level,
        rrd_path=args.rrd,
        spawn=args.spawn,
        connect=args.connect,
        progress=progress,
        walls=args.walls,
    )
    if args.json_path is not None:
        _write_json(args.json_path, report.to_json())
    _print_summary(report)
    if args.fail_above is not None and report.max_score > args.fail_above:
        worst = max(report.records, key=lambda r: r.structure_score)
        print(
            f"error: {args.input}: W = {worst.structure_score:.3f} on {worst.topic} snapshot "
            f"{worst.index} exceeds --fail-above {args.fail_above:g}",
            file=sys.stderr,
        )
        return EXIT_GATE
    return 0


def _run_info(args: argparse.Namespace) -> int:
    from rose_logs.errors import MapMessageError
    from rose_logs.messages import decode_map
    from rose_logs.reader import LogReader
    from rose_logs.session import find_map_topics

    with LogReader(args.input) as reader:
        channels = reader.channels
        map_topics = find_map_topics(channels)
        print(f"file         {args.input}")
        print(f"format       {reader.format} ({reader.serialization})")
        print(f"messages     {reader.message_count}")
        if reader.message_count:
            print(
                f"time range   {_iso(reader.start_ns)} .. {_iso(reader.end_ns)} UTC "
                f"({_seconds(reader.end_ns - reader.start_ns)})"
            )
        counts: dict[str, int] = {}
        types: dict[str, str] = {}
        for c in channels:
            counts[c.topic] = counts.get(c.topic, 0) + c.message_count
            types[c.topic] = c.msgtype
        width = max((len(t) for t in counts), default=5)
        print("\ntopics")
        for topic in sorted(counts):
            mark = "  [map]" if topic in map_topics else ""
            print(f"  {topic:<{width}}  {counts[topic]:>8}  {types[topic]}{mark}")
        stats: dict[str, dict[str, Any]] = {
            t: {"sizes": set(), "res": set(), "frames": set(), "bad": 0} for t in map_topics
        }
        for message in reader.messages(topics=map_topics):
            topic = message.channel.topic
            if message.channel.msgtype != "nav_msgs/msg/OccupancyGrid":
                continue
            try:
                snap = decode_map(
                    message.data,
                    serialization=message.channel.message_encoding,
                    topic=topic,
                    log_time_ns=message.log_time_ns,
                )
            except MapMessageError:
                stats[topic]["bad"] += 1
                continue
            stats[topic]["sizes"].add((snap.shape[1], snap.shape[0]))
            stats[topic]["res"].add(round(snap.resolution_m, 6))
            stats[topic]["frames"].add(snap.frame_id)
        for topic in map_topics:
            s = stats[topic]
            print(f"\nmap topic    {topic}")
            sizes = sorted(s["sizes"])
            if sizes:
                print(
                    f"  grid sizes   {', '.join(f'{w} x {h}' for w, h in sizes[:6])}"
                    + (" ..." if len(sizes) > 6 else "")
                )
                print(f"  resolution   {', '.join(f'{r:g}' for r in sorted(s['res']))} m")
                print(f"  frame        {', '.join(sorted(s['frames']))}")
            if s["bad"]:
                print(f"  malformed    {s['bad']}")
        if not map_topics:
            print("\nno nav_msgs/OccupancyGrid topic")
    return 0


class _UsageError(Exception):
    pass


def _configure_logging(debug: bool) -> None:
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_LevelFormatter())
    root = logging.getLogger("rose_logs")
    root.handlers[:] = [handler]
    root.setLevel(logging.DEBUG if debug else logging.WARNING)
    root.propagate = False


class _LevelFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        return f"{record.levelname.lower()}: {record.getMessage()}"


def main(argv: list[str] | None = None) -> int:
    """Run ``rose-bag`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    _configure_logging(args.debug)
    try:
        return int(args.func(args))
    except _UsageError as err:
        parser.print_usage(sys.stderr)
        print(f"rose-bag: error: {err}", file=sys.stderr)
        return 2
    except (LogError, RoseError) as err:
        if args.debug:
            raise
        print(f"error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("error: interrupted, nothing written", file=sys.stderr)
        return 130
    except OSError as err:
        if args.debug:
            raise
        where = f"{err.filename}: " if err.filename else ""
        print(f"error: {where}{err.strerror or err}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
