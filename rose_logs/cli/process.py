"""``rose-bag process LOG``: ROSE on every map snapshot; output log, Rerun recording, report, gate."""

from __future__ import annotations

import argparse
import statistics
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from rose.cli.options import (
    add_param_arguments,
    file_arg,
    local_location,
    params_from_args,
    path_arg,
)
from rose.console import stderr_is_terminal
from rose.limits import short, visible
from rose.outputs import OutputSet, counted, json_text, refuse_output_in_bag_folder, suffix_warning
from rose_logs.cli.options import (
    EXIT_GATE,
    EXIT_SALVAGED,
    UsageError,
    add_gate_arguments,
    add_session_arguments,
    add_topic_argument,
    duration_text,
    hold_opencv_to_one_thread,
    output_log_path,
    summary_then_verdict,
    unjudged_topics,
    utc_text,
)

if TYPE_CHECKING:
    from rose_logs.reader import LogReader

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "process",
        help="run ROSE on every map snapshot of a log; write a cleaned log, Rerun, a report",
        description="Replay a ROS 1 bag, ROS 2 bag (folder or .db3) or MCAP file, run ROSE on every "
        "nav_msgs/OccupancyGrid snapshot (and map_msgs/OccupancyGridUpdate), write every input message "
        "unchanged plus <map>/rose/cleaned, <map>/rose/structure_score and <map>/rose/walls to a new "
        "log, and print a summary.",
    )
    parser.add_argument(
        "input", type=path_arg, help="ROS 1 .bag, ROS 2 bag folder / .db3, or .mcap"
    )
    parser.add_argument(
        "-o",
        "--output",
        type=local_location,
        default=None,
        help="output log (default: <input>.rose.<ext> next to the input; a bag folder or .db3 <name> gives the folder <name>.rose)",
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
    add_topic_argument(parser)
    parser.add_argument("--rrd", type=file_arg, default=None, help="save a Rerun recording here")
    parser.add_argument(
        "--spawn", action="store_true", help="stream to a new Rerun viewer as the session runs"
    )
    parser.add_argument(
        "--connect",
        metavar="ADDR",
        help="stream to a running Rerun viewer (PORT, HOST:PORT or rerun+http://HOST:PORT/proxy)",
    )
    add_session_arguments(parser)
    parser.add_argument(
        "--json",
        type=file_arg,
        default=None,
        dest="json_path",
        help="write a JSON report here (strict JSON, non-finite numbers as null; '-': stdout)",
    )
    add_gate_arguments(parser, scope="snapshot")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    parser.add_argument(
        "--salvage",
        action="store_true",
        help=f"on a damaged input, keep what can be read, warn, and exit {EXIT_SALVAGED} "
        "(default: a damaged input is an error and nothing is written)",
    )
    add_param_arguments(parser)
    parser.set_defaults(func=run)


# -- output helpers ------------------------------------------------------------------------------
def _print_summary(report: Any, out: TextIO) -> None:
    start = report.start_ns
    print(
        f"input        {visible(str(report.input_path), keep_undecodable=True)} ({report.input_format}, {report.message_count} messages)",
        file=out,
    )
    print(
        f"time range   {utc_text(report.start_ns)} .. {utc_text(report.end_ns)} UTC "
        f"({duration_text(report.end_ns - report.start_ns)})",
        file=out,
    )
    if report.output_path is not None:
        print(f"output       {visible(str(report.output_path), keep_undecodable=True)}", file=out)
    if report.rrd_path is not None:
        print(f"rerun        {visible(str(report.rrd_path), keep_undecodable=True)}", file=out)
    for topic in report.map_topics:
        records = report.records_of(topic)
        print(f"\nmap topic    {visible(topic)}", file=out)
        if not records:
            print("  snapshots    0", file=out)
            continue
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
            f"  time range   +{duration_text(records[0].log_time_ns - start)} .. "
            f"+{duration_text(records[-1].log_time_ns - start)}",
            file=out,
        )
        # Smallest to largest grid by cells (then width): the range a growing SLAM map spans.
        sizes = sorted({(r.width, r.height) for r in records}, key=lambda s: (s[0] * s[1], s))
        size_text = f"{sizes[0][0]} x {sizes[0][1]}" + (
            f" .. {sizes[-1][0]} x {sizes[-1][1]}" if len(sizes) > 1 else ""
        )
        print(f"  grid         {size_text} cells", file=out)
        print(f"  W            {_w_text(records)}", file=out)
        _print_break(report, topic, out)
        first = report.first_w_above(topic)
        level = repr(float(report.failure_level))  # as given
        if first is None:
            print(f"  W > {level:<8} never", file=out)
        else:
            print(
                f"  W > {level:<8} first at snapshot {first.index}, +{duration_text(first.log_time_ns - start)} "
                f"(W = {first.structure_score:.3f})",
                file=out,
            )
    if report.skipped_messages:
        print(
            f"\nskipped      {report.skipped_messages} map message(s), copied unprocessed "
            f"({report.skipped_reasons})",
            file=out,
        )
    if report.losses:  # --salvage: what could not be read
        print(f"\nlosses       {visible(report.losses[0], keep_undecodable=True)}", file=out)
        for loss in report.losses[1:]:
            print(f"             {visible(loss, keep_undecodable=True)}", file=out)
    print(f"\nelapsed      {report.elapsed_s:.2f} s", file=out)


def _w_text(records: Sequence[Any]) -> str:
    """W's min / median / max over the snapshots W judges, and how many maps it left out: (nearly)
    empty ones, and ones it cannot read (a solid block, a thin strip)."""
    from rose_logs.session.report import MIN_JUDGED_CELLS

    scores = [r.structure_score for r in records if r.judged]
    if not scores:
        return f"none ({_unjudged_text(records)})"
    text = f"min {min(scores):.3f}  median {statistics.median(scores):.3f}  max {max(scores):.3f}"
    unreadable = sum(r.unreadable for r in records)  # the rest left out are (nearly) empty
    empty = len(records) - len(scores) - unreadable
    left_out = [
        f"{counted(count, 'map')} {why}"
        for count, why in (
            (empty, f"of fewer than {MIN_JUDGED_CELLS} occupied cells"),
            (unreadable, "W cannot read (a solid block, a thin strip)"),
        )
        if count
    ]
    if left_out:
        text += f"  ({', '.join(left_out)} left out)"
    return text


def _unjudged_text(records: Sequence[Any]) -> str:
    """Why W judged none of a topic's maps: too few occupied cells, or a form W cannot read, with
    the reason ROSE's domain check gives (the last such map's, as its record's ``degenerate``)."""
    from rose_logs.session.report import MIN_JUDGED_CELLS

    unreadable = [r for r in records if r.unreadable]
    if not unreadable:
        return f"no map has {MIN_JUDGED_CELLS} or more occupied cells"
    reason = unreadable[-1].degenerate
    if len(records) == 1:
        return f"W cannot read the map: {reason}"
    empty = len(records) - len(unreadable)
    if not empty:
        return f"W cannot read any of the {len(records)} maps; the last: {reason}"
    maps = "the map" if len(unreadable) == 1 else f"the {len(unreadable)} maps"
    which = ":" if len(unreadable) == 1 else ", the last:"
    rest = f"{empty} map{'s have' if empty > 1 else ' has'} fewer"
    return (
        f"W cannot read {maps} of {MIN_JUDGED_CELLS} or more occupied cells{which} {reason}; {rest}"
    )


def _print_break(report: Any, topic: str, out: Any) -> None:
    start = report.start_ns
    top = max(r.break_score_m for r in report.records_of(topic))
    first = report.first_break(topic)
    if first is None:
        print(
            f"  break        none (largest score {top:.2f} m, threshold "
            f"{report.break_threshold_m:g} m)",
            file=out,
        )
        return
    from rose_logs.session.breaks import region_text  # loaded with the session already

    where = "" if first.region_m is None else f", {region_text(first.region_m)}"
    print(
        f"  break        first at snapshot {first.index}, "
        f"+{duration_text(first.log_time_ns - start)} ({first.score_m:.2f} m of map contradicted since "
        f"snapshot {first.trusted_index}{where})",
        file=out,
    )


def _input_reader(args: argparse.Namespace) -> LogReader | None:
    """The input's :class:`~rose_logs.reader.LogReader` (not opened) when the output log named
    by ``-o`` is written in the input's format (no ``--format``, no suffix naming one), which
    must be known before the session: the session reads with it, and a ROS 2 bag folder's
    metadata.yaml is read once (seconds for thousands of topics). None when not needed, or when
    the input cannot be read (the session says why)."""
    from rose_logs.errors import LogReadError
    from rose_logs.formats import format_from_path
    from rose_logs.reader import LogReader

    if args.output is None or args.fmt or format_from_path(Path(args.output)) is not None:
        return None
    try:
        return LogReader(args.input, salvage=args.salvage)
    except LogReadError:
        return None


def _output_format(args: argparse.Namespace, reader: LogReader | None) -> str | None:
    """The format the output log named by ``-o`` is written in (``reader``: the input's, from
    :func:`_input_reader`); None when the input cannot be read (its own error comes later)."""
    from rose_logs.formats import format_from_path

    if args.output is None:
        return None
    fmt = args.fmt or format_from_path(Path(args.output))
    return fmt or (None if reader is None else reader.format)


def run(args: argparse.Namespace) -> int:
    from rose_logs.formats import suffix_mismatch_warning, unknown_suffix_warning
    from rose_logs.session import default_output_path

    if args.no_output and args.output is not None:
        msg = "--no-output and --output exclude each other"
        raise UsageError(msg)
    if args.no_output and args.fmt:
        msg = "--no-output and --format exclude each other"
        raise UsageError(msg)
    if args.connect is not None:
        from rose_logs.rerun.viewer import viewer_endpoint

        try:
            viewer_endpoint(args.connect)
        except ValueError as err:
            raise UsageError(f"argument --connect: {err}") from err
    reader = _input_reader(args)
    args.output = output_log_path(args.output, _output_format(args, reader))
    output = None if args.no_output else (args.output or default_output_path(args.input, args.fmt))
    for path, option, what in (
        (args.output, "-o", "output log"),
        (args.rrd, "--rrd", "Rerun recording"),
        (args.json_path, "--json", "JSON report"),
    ):
        refuse_output_in_bag_folder(path, option, what=what, inputs=[args.input])
    # Only a name the user typed: the default (input name + .rose) has the output format's suffix.
    log_warning = None
    if args.output is not None and not args.fmt:
        log_warning = unknown_suffix_warning(args.output, "in the input's format")
    elif args.output is not None:
        log_warning = suffix_mismatch_warning(args.output, args.fmt)
    warnings = [
        warning
        for warning in (
            log_warning,
            suffix_warning(args.rrd, ".rrd", "a Rerun recording"),
            suffix_warning(args.json_path, ".json", "a JSON report"),
        )
        if warning is not None
    ]
    outputs = OutputSet(inputs=[args.input], force=args.force, ends_run=True)
    if warnings:  # a typo (out.mcpa, --rrd run.txt) should not pass unnoticed
        # ... unless an output is refused anyway (the input itself, an existing file, one named
        # twice): then the refusal comes alone. These are checked now, before the input is read;
        # the warnings are said once the session has accepted every output (the log's format
        # against the input's messages too: `--format ros1 -o y.mcap` of a ROS 2 log warned of
        # the suffix, then was refused).
        folder = _output_format(args, reader) in ("db3", "mcap-dir")
        outputs.check(args.output, directory=folder)
        outputs.check(None if folder else args.output, args.rrd, args.json_path)

    def say_warnings() -> None:
        for warning in warnings:
            print(warning, file=sys.stderr)

    progress = not args.quiet and stderr_is_terminal()
    with outputs:  # the log, the recording and the report: all committed, or none
        json_out = None if args.json_path is None else outputs.stage(args.json_path)
        report = _process(args, output, progress, outputs, say_warnings, reader)
        failed = _gate_failures(args, report)
        if json_out is not None:
            data = report.to_json()
            # The verdict a pipeline acts on, beside the exit code.
            data["gates"] = {
                "fail_above": args.fail_above,
                "fail_on_break": bool(args.fail_on_break),
                "failed": failed,
            }
            outputs.fill(json_out, json_text(data).encode("utf-8"))
    out = sys.stderr if outputs.uses_stdout else sys.stdout

    def verdict() -> int:
        # Failed gates are named even when the salvage decides the exit code (4).
        # One line each, whatever the input's name holds (a newline split the line, an escape
        # sequence drove the terminal).
        for reason in failed:
            print(f"error: {short(visible(f'{args.input}: {reason}'))}", file=sys.stderr)
        if report.losses:
            # Each loss was warned about when the reader met it (a long session shows it at once).
            text = (
                f"{args.input}: damaged input ({len(report.losses)} problem(s) above), outputs "
                f"hold only what could be read (--salvage, exit {EXIT_SALVAGED})"
            )
            print(f"warning: {short(visible(text))}", file=sys.stderr)
            return EXIT_SALVAGED
        return EXIT_GATE if failed else 0

    return summary_then_verdict(lambda: _print_summary(report, out), verdict)


def _gate_failures(args: argparse.Namespace, report: Any) -> list[str]:
    """Why the requested gates fail, each gate once (empty: they pass or none was asked for)."""
    reasons = []
    if args.fail_above is not None and report.max_score > args.fail_above:
        judged = [r for r in report.records if r.judged]
        first = next(r for r in judged if r.structure_score > args.fail_above)
        worst = max(judged, key=lambda r: r.structure_score)
        when = duration_text(first.log_time_ns - report.start_ns)
        from rose_logs.session.report import score_beside_level  # loaded with the session

        first_w, level = score_beside_level(first.structure_score, args.fail_above)
        worst_w, _ = score_beside_level(worst.structure_score, args.fail_above)
        # (Its topic too when another: each topic numbers its own snapshots.)
        worst_at = "" if worst.topic == first.topic else f"{worst.topic} "
        reasons.append(
            f"W = {first_w} on {first.topic} snapshot {first.index} ({when} "
            f"into the log) exceeds --fail-above {level} first; highest: "
            f"W = {worst_w} on {worst_at}snapshot {worst.index}"
        )
    first_break = report.first_break()
    if args.fail_on_break and first_break is not None:
        reasons.append(f"{first_break.text} (--fail-on-break)")
    reasons += unjudged_topics(
        args,
        report.map_topics,
        {r.topic for r in report.records},
        {r.topic for r in report.records if r.judged},
        {r.topic for r in report.records if r.unreadable},
    )
    return reasons


def _process(
    args: argparse.Namespace,
    output: Path | None,
    progress: bool,
    outputs: Any,
    on_outputs_ready: Callable[[], None] | None = None,
    reader: LogReader | None = None,
) -> Any:
    from rose.entry import load_blas_before_work
    from rose_logs.session import process_log
    from rose_logs.session.breaks import BreakParams

    hold_opencv_to_one_thread()
    load_blas_before_work()
    rose_params = params_from_args(args)
    return process_log(
        args.input,
        output_path=output,
        output_format=args.fmt,
        force=args.force,
        topics=args.topics,
        params=rose_params,
        failure_level=args.failure_level,
        rrd_path=args.rrd,
        spawn=args.spawn,
        connect=args.connect,
        progress=progress,
        on_outputs_ready=on_outputs_ready,
        walls=args.walls,
        break_params=BreakParams.following(
            rose_params.occupied_threshold,
            **({} if args.break_threshold is None else {"threshold_m": args.break_threshold}),
        ),
        clean_method=args.clean_method,
        outputs=outputs,
        salvage=args.salvage,
        replace_rose_topics=args.replace_rose_topics,
        max_cells=args.max_cells,
        reader=reader,
    )
