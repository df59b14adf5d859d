"""What every ``rose-bag`` command shares: exit codes, the usage-error type, time formatting, and
the per-recording options and gates of ``process`` and ``batch``.

The ROSE tuning options themselves are defined once in :mod:`rose.cli.options` and shared with ``rose``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Collection, Iterable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from rose.cli.options import add_limit_arguments, fraction, names_folder, positive_float
from rose.console import EXIT_BROKEN_PIPE, stdout_closed
from rose.directions import FAILURE_LEVEL
from rose.errors import StdoutError
from rose_logs.cli import EXIT_GATE, EXIT_SALVAGED, UsageError

__all__ = [
    "EXIT_GATE",
    "EXIT_SALVAGED",
    "UsageError",
    "add_gate_arguments",
    "add_session_arguments",
    "add_topic_argument",
    "duration_text",
    "hold_opencv_to_one_thread",
    "output_log_path",
    "summary_then_verdict",
    "topic_arg",
    "unjudged_topics",
    "utc_text",
]


def hold_opencv_to_one_thread() -> None:
    """Run OpenCV's calls on the calling thread, for commands that process whole sessions.

    A session keeps both cores busy already (two analyses at once, the break detector and Rerun's
    logging beside them): OpenCV's own pool, and the walls cleaning's second thread that follows
    it (:func:`rose.cleaning_rules.beside._beside`), only add work there. Measured: the one-hour
    benchmark session, walls cleaning, six pairs of runs, 9 % less CPU and 6 % less wall time;
    ``rose-bag batch --workers 1`` on the 40-recording benchmark fleet, six pairs, 15 % less
    CPU and 13 % less wall time. Results are the same either way.
    """
    import cv2

    cv2.setNumThreads(1)


def output_log_path(text: str | None, fmt: str | None) -> Path | None:
    """The output log named on the command line, as a ``Path``; ``fmt`` is the format it will be
    written in, None when not known (a bag folder is assumed fine).

    Raises
    ------
    UsageError
        If the name ends with ``/`` (a folder) but the format is a single file (mcap, ros1): ``Path``
        drops the slash, so ``-o out/`` wrote the file ``out``.
    """
    if text is None:
        return None
    if names_folder(text) and fmt in ("mcap", "ros1"):
        msg = (
            f"{text}: names a folder (it ends with a separator), but the output is one {fmt} "
            "file: give a file name, "
            "or --format db3 / mcap-dir for a ROS 2 bag folder"
        )
        raise UsageError(msg)
    return Path(text)


def topic_arg(text: str) -> str:
    """argparse type: a topic name; an empty one (``-t ""``, an unset shell variable) is a usage
    error, not a topic the log lacks."""
    if not text.strip():
        msg = "a topic name cannot be empty"
        raise argparse.ArgumentTypeError(msg)
    return text


def add_topic_argument(parser: Any) -> None:
    """``-t / --topic`` (repeatable, into ``topics``): the map topics to analyse."""
    parser.add_argument(
        "-t",
        "--topic",
        action="append",
        default=None,
        dest="topics",
        type=topic_arg,
        help="map topic to analyse (repeatable; default: every OccupancyGrid topic with messages, "
        "costmaps left out unless the log has no other)",
    )


def utc_text(time_ns: int) -> str:
    """A log time (int ns since the epoch) as ``YYYY-MM-DD HH:MM:SS.mmm`` UTC."""
    return datetime.fromtimestamp(time_ns / 1e9, tz=UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]


def duration_text(ns: int) -> str:
    """A duration in ns as seconds with one decimal, e.g. ``"12.5 s"``."""
    return f"{ns / 1e9:.1f} s"


def add_session_arguments(parser: Any) -> None:
    """What is done to each snapshot of a log, the same in ``process`` and ``batch``:
    ``--walls``, ``--clean-method``, ``--failure-level``, ``--break-threshold``, ``--max-cells``,
    ``--replace-rose-topics``."""
    parser.add_argument(
        "--walls",
        action="store_true",
        help="also extract wall segments per snapshot (marker in <map>/rose/walls, Rerun lines)",
    )
    parser.add_argument(
        "--clean-method",
        choices=("walls", "paper"),
        default="walls",
        help="how <map>/rose/cleaned is made: walls = clutter removed, every wall kept, no "
        "robot-sized gap opened (default); paper = the paper's labelling as it is",
    )
    parser.add_argument(
        "--failure-level",
        type=fraction,  # W lies in [0, 1]
        default=FAILURE_LEVEL,
        help="W above which a map counts as broken (default %(default)s, the paper's)",
    )
    parser.add_argument(
        "--break-threshold",
        type=positive_float,
        default=None,
        metavar="M",
        help="break detector: metres of established map a snapshot must contradict to count as a "
        "break (default 1.25)",  # BreakParams().threshold_m (tested); imported lazily
    )
    parser.add_argument(
        "--replace-rose-topics",
        action="store_true",
        help="a log processed before: write its <map>/rose/* topics anew with these options, "
        "leaving its own out of the output log (default: such a log is refused for one)",
    )
    add_limit_arguments(parser)


def add_gate_arguments(parser: Any, *, scope: str) -> None:
    """The map-quality gates ``--fail-above`` and ``--fail-on-break`` (exit 3); ``scope`` says
    what they look at ("snapshot", "recording")."""
    parser.add_argument(
        "--fail-above",
        type=fraction,  # W lies in [0, 1]
        default=None,
        metavar="W",
        help=f"exit {EXIT_GATE} if any {scope}'s W exceeds this (map-quality gate)",
    )
    parser.add_argument(
        "--fail-on-break",
        action="store_true",
        help=f"exit {EXIT_GATE} if the break detector finds a break in any {scope} "
        "(map-quality gate)",
    )


def summary_then_verdict(summary: Callable[[], None], verdict: Callable[[], int]) -> int:
    """Print a run's ``summary`` on standard output (its files stand by then), then say its
    ``verdict`` (the failed gates' ``error:`` lines, the salvage's ``warning:``, on stderr) and
    return the exit code the verdict returns.

    Standard output failing in the summary does not lose the verdict: it is said all the same,
    and its exit code, when not 0, stands (a pipeline acting on the gate's 3 or the salvage's 4
    got 1 or 141, and no line naming the failed gates). The failure is still an error line
    (``> /dev/full``: the run exits 1 where the verdict was 0) or, for a reader that left
    (``| head``), quiet (141 where it was 0).
    """
    try:
        summary()
        sys.stdout.flush()  # failing at the command's end, it came after the verdict's code
    except StdoutError as err:
        err.exit_code = verdict() or err.exit_code
        raise
    except BrokenPipeError as err:
        if not stdout_closed(err):  # not standard output's: an error of its own
            raise
        return verdict() or EXIT_BROKEN_PIPE
    return verdict()


def unjudged_topics(
    args: Any,
    map_topics: Iterable[str],
    analysed: Collection[str],
    judged: Collection[str],
    degenerate: Collection[str] = (),
) -> list[str]:
    """Gate failures for the map topics none of whose maps W judged: none could be ``analysed``,
    or none of them had ``MIN_JUDGED_CELLS`` occupied cells (a session of all-unknown or empty
    maps) and an input ROSE can read (not a solid block or a thin strip: the ``degenerate``
    topics had such maps). With a gate asked for (:func:`add_gate_arguments`), it cannot vouch
    for them."""
    if args.fail_above is None and not args.fail_on_break:
        return []
    from rose_logs.session.report import MIN_JUDGED_CELLS  # loaded with the session already

    # Both gates fail for the same reason: one line naming them (it named neither).
    gates = ", ".join(
        name
        for name, asked in (
            ("--fail-above", args.fail_above is not None),
            ("--fail-on-break", args.fail_on_break),
        )
        if asked
    )
    cannot = f", the gate cannot judge it ({gates})"
    reasons = []
    for topic in map_topics:
        if topic not in analysed:
            reasons.append(f"{topic}: no map message could be analysed{cannot}")
        elif topic not in judged:
            reasons.append(
                f"{topic}: no map had {MIN_JUDGED_CELLS} or more occupied cells"
                + (
                    " in a form W reads (a solid block? a thin strip?)"
                    if topic in degenerate
                    else ""
                )
                + cannot
            )
    return reasons
