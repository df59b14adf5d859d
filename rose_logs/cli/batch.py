"""``rose-bag batch INPUT... -o OUT``: every recording of a fleet, one table of map health."""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Callable
from typing import Any

from rose.cli.options import add_param_arguments, location, params_from_args
from rose.console import stderr_is_terminal
from rose.limits import short, visible
from rose_logs.cli.options import (
    EXIT_GATE,
    EXIT_SALVAGED,
    UsageError,
    add_gate_arguments,
    add_session_arguments,
    add_topic_argument,
    hold_opencv_to_one_thread,
    summary_then_verdict,
    unjudged_topics,
)

__all__ = ["EXIT_INTERRUPTED", "add_parser", "run"]

EXIT_INTERRUPTED = 130
"""Exit code after Ctrl-C (finished recordings are kept; a re-run resumes)."""


def _whole_number_from(low: int) -> Callable[[str], int]:
    """argparse type: a whole number of at least ``low`` (the bound said in its own message)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            msg = f"expected a whole number, got {text!r}"
            raise argparse.ArgumentTypeError(msg) from None
        if value < low:
            msg = f"must be >= {low}, got {value}"
            raise argparse.ArgumentTypeError(msg)
        return value

    return parse


_non_negative_int = _whole_number_from(0)
_positive_int = _whole_number_from(1)


def _worker_count(text: str) -> int:
    """``--workers``: 1 .. 4 per CPU (more only add start-up time and memory; far more never start)."""
    from rose_logs.batch.cluster import max_local_workers

    value = _positive_int(text)
    if value > max_local_workers():
        msg = f"must be <= {max_local_workers()} (4 per CPU of this machine), got {value}"
        raise argparse.ArgumentTypeError(msg)
    return value


#: Smallest --memory-limit: a worker's imports alone take about 100 MB (Dask's nanny kills a worker
#: over its limit before it can report anything, and the batch failed with "Stream is closed").
MIN_WORKER_MEMORY_BYTES = 200 * 1000**2


def _memory_limit(text: str) -> str | float:
    """``auto``, a fraction of RAM (0 < f <= 1) or a size such as ``2GB`` / ``512MiB``."""
    from dask.utils import parse_bytes

    if text == "auto":
        return text
    try:
        value = float(text)
    except ValueError:
        pass
    else:
        if not 0 < value <= 1:
            msg = f"a fraction must be in (0, 1], got {text!r}"
            raise argparse.ArgumentTypeError(msg)
        from distributed.system import MEMORY_LIMIT  # what Dask multiplies it by (cgroup-aware)

        _check_worker_memory(text, value * MEMORY_LIMIT)
        return value
    try:
        size = parse_bytes(text)
    except ValueError:
        msg = f"expected a size such as 2GB, a fraction of RAM or 'auto', got {text!r}"
        raise argparse.ArgumentTypeError(msg) from None
    _check_worker_memory(text, size)
    return text


def _check_worker_memory(text: str, size_bytes: float) -> None:
    if size_bytes < MIN_WORKER_MEMORY_BYTES:
        msg = (
            f"{text!r} is {size_bytes / 1e6:.3g} MB, too little to start a worker (at least "
            f"{MIN_WORKER_MEMORY_BYTES // 1000**2} MB: its imports alone take about 100 MB)"
        )
        raise argparse.ArgumentTypeError(msg)


def _storage_option(text: str) -> tuple[str, Any]:
    key, sep, value = text.partition("=")
    if not sep or not key:
        msg = f"expected KEY=VALUE, got {text!r}"
        raise argparse.ArgumentTypeError(msg)
    # Credentials stay text (a numeric password, `password=true`), unless written as a JSON
    # object (gcsfs takes its token as one).
    credential = _CREDENTIAL_KEY.search(key) is not None
    if credential and not value.lstrip().startswith("{"):
        return key, value
    lowered = value.lower()
    if lowered in ("true", "false"):
        return key, lowered == "true"
    # As fsspec reads its FSSPEC_<PROTOCOL> variables: JSON where it is JSON (numbers, null,
    # objects such as client_kwargs), else the text ("123" quoted stays a string).
    try:
        return key, json.loads(value)
    except ValueError:
        return key, value


#: Storage option names whose values are credentials (anywhere in the name: api_key_id,
#: account_name, client_id), taken as text whatever they look like.
_CREDENTIAL_KEY = re.compile(
    r"key|secret|password|passwd|token|user|account|client_id|credential|profile|sas", re.I
)


def add_parser(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "batch",
        help="process many recordings (folders, globs, s3://) locally or on a Dask cluster",
        description="Run `process` on every recording found in the inputs (files, folders searched "
        "recursively for .bag / .mcap / .db3 / .bag.active and ROS 2 bag folders, glob patterns, s3:// "
        "prefixes) and "
        "write recordings.parquet, snapshots.parquet, summary.json and report.md to OUT. Recordings "
        "finished by an earlier run with the same options are skipped.",
    )
    # Not empty: '' was the current folder, so `batch "$FLEET"` with FLEET unset batched it whole.
    parser.add_argument(
        "inputs", nargs="*", type=location, metavar="INPUT", help="file, folder, glob or URL"
    )
    parser.add_argument(
        "-o",
        "--out",
        required=True,
        type=location,
        help="output folder or URL (e.g. s3://bucket/prefix)",
    )
    parser.add_argument(
        "--from-list",
        action="append",
        default=[],
        metavar="FILE",
        help="read more inputs from FILE (a regular file of at most 64 MiB; - for standard "
        "input), one per line (# comments)",
    )
    engine = parser.add_argument_group("engine")
    engine.add_argument(
        "--workers",
        type=_worker_count,
        default=1,
        help="local worker processes, one thread each, at most 4 per CPU (default 1: in this "
        "process, no Dask, two snapshots analysed at once)",
    )
    engine.add_argument("--scheduler", default=None, help="existing Dask cluster, tcp://host:port")
    engine.add_argument(
        "--scheduler-file",
        default=None,
        help="existing Dask cluster's scheduler file (JSON with its address; waited for 10 s if "
        "it does not exist yet)",
    )
    engine.add_argument(
        "--memory-limit",
        type=_memory_limit,
        default=None,
        help="per-worker memory limit of the local cluster, e.g. 2GB (default: RAM / workers)",
    )
    engine.add_argument(
        "--retries",
        type=_non_negative_int,
        default=2,
        help="retries of a recording after an I/O error or a dead worker (default %(default)s)",
    )
    engine.add_argument(
        "--storage-option",
        type=_storage_option,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=(
            "fsspec option for remote inputs and OUT, e.g. endpoint_url=http://host:9000; a "
            "VALUE that is JSON is read as JSON (max_concurrency=2, "
            'client_kwargs=\'{"region_name": "eu-west-1"}\'; quoted, "123" stays text; keys, '
            "secrets, passwords, tokens and user names stay text)"
        ),
    )
    work = parser.add_argument_group("per recording (as `process`)")
    add_topic_argument(work)
    work.add_argument(
        "--cleaned", action="store_true", help="write each cleaned log to OUT/cleaned/<name>"
    )
    work.add_argument(
        "--rrd", action="store_true", help="write each Rerun recording to OUT/rrd/<name>.rrd"
    )
    add_session_arguments(work)
    gates = parser.add_argument_group("resume and gates")
    gates.add_argument("-f", "--force", action="store_true", help="redo every recording")
    gates.add_argument(
        "--salvage",
        action="store_true",
        help="keep what can be read of damaged recordings (as process --salvage); their rows list "
        f"the losses, exit {EXIT_SALVAGED} when any has some",
    )
    gates.add_argument(
        "--retry-errors", action="store_true", help="redo the recordings that failed before"
    )
    add_gate_arguments(gates, scope="recording")
    gates.add_argument(
        "--max-errors",
        type=_non_negative_int,
        default=0,
        metavar="N",
        help="exit 1 if more than N recordings failed (default 0: any failure); wins over "
        "the gates",
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_param_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rose_logs.batch import BatchError, RecordingOptions, read_list, run_batch

    if args.scheduler and args.scheduler_file:
        msg = "--scheduler and --scheduler-file exclude each other"
        raise UsageError(msg)
    if (args.scheduler or args.scheduler_file) and args.workers != 1:
        msg = "--workers starts a local cluster; it cannot be combined with --scheduler"
        raise UsageError(msg)
    if args.memory_limit is not None and (
        args.workers == 1 or args.scheduler or args.scheduler_file
    ):
        print(
            "warning: --memory-limit applies to the workers of a local cluster (--workers 2 or "
            "more); it is ignored here",
            file=sys.stderr,
        )
    if args.out == "-":
        # Standard output to every other command: refused as theirs are (`convert LOG -`), not
        # made into a folder named '-' in the current one.
        msg = "-: a folder output cannot go to a stream or device"
        raise BatchError(msg)
    storage_options = dict(args.storage_option)
    inputs = list(args.inputs)
    for path in args.from_list:
        inputs += read_list(path, storage_options)
    if not inputs and args.from_list:
        lists = ", ".join("standard input" if f == "-" else f for f in args.from_list)
        msg = f"{lists}: the list of inputs is empty (blank lines and # comments only)"
        raise BatchError(msg)
    if not inputs:
        msg = "no INPUT given (and no --from-list)"
        raise UsageError(msg)
    options = RecordingOptions(
        params=params_from_args(args),
        topics=None if args.topics is None else tuple(args.topics),
        failure_level=args.failure_level,
        walls=args.walls,
        cleaned=args.cleaned,
        rrd=args.rrd,
        retries=args.retries,
        salvage=args.salvage,
        clean_method=args.clean_method,
        break_threshold_m=args.break_threshold,
        max_cells=args.max_cells,
        replace_rose_topics=args.replace_rose_topics,
    )
    if args.workers == 1 and not (args.scheduler or args.scheduler_file):
        hold_opencv_to_one_thread()  # in this process, as `process` (the workers hold it too)
    report = run_batch(
        inputs,
        args.out,
        workers=args.workers,
        scheduler=args.scheduler,
        scheduler_file=args.scheduler_file,
        memory_limit=args.memory_limit,
        options=options,
        storage_options=storage_options,
        force=args.force,
        retry_errors=args.retry_errors,
        progress=not args.quiet and stderr_is_terminal(),
        gates=lambda report: {
            "fail_above": args.fail_above,
            "fail_on_break": bool(args.fail_on_break),
            "failed": _gate_failures(args, report),
        },
    )
    return summary_then_verdict(lambda: _print_summary(report), lambda: _exit_code(report, args))


def _print_summary(report: Any) -> None:
    rows = [r.row() for r in report.results]
    out = sys.stdout
    ok = sum(r["status"] == "ok" for r in rows)
    # Interrupted, the finished recordings are fewer than the fleet: say both.
    of = f" of {report.found} found" if report.interrupted and report.found else ""
    print(
        f"recordings   {len(rows)}{of} ({report.processed} processed, {report.skipped} finished "
        "before)",
        file=out,
    )
    for reason, count in report.redone:
        # A re-run with other options processes everything again: say so, and why.
        print(f"redone       {count} ({reason})", file=out)
    print(f"ok           {ok}", file=out)
    print(f"failed       {len(rows) - ok}", file=out)
    salvaged = sum(bool(r["losses"]) for r in rows)
    if salvaged:
        print(f"salvaged     {salvaged} (damaged, kept what could be read)", file=out)
    print(f"broken maps  {sum(bool(r['broke']) for r in rows)}", file=out)
    print(f"snapshots    {sum(r['snapshots'] for r in rows)}", file=out)
    print(f"output       {visible(str(report.out), keep_undecodable=True)}", file=out)
    print(f"elapsed      {report.elapsed_s:.2f} s", file=out)
    from rose_logs.batch.report import plotting_available

    if any(r["snapshots"] for r in rows) and not plotting_available():
        print(
            "note: no w_over_time.png: matplotlib is not installed (pip install 'rose-bag[plots]')",
            file=sys.stderr,
        )


#: Failed recordings named on stderr, one line each, when they fail the batch.
_LISTED_FAILURES = 10


def _exit_code(report: Any, args: argparse.Namespace) -> int:
    from rose_logs.batch.sources import printable  # loaded with the batch already

    if report.interrupted:
        print(
            f"error: interrupted; {len(report.results)} finished recordings kept in {report.out} "
            "(run again to resume)",
            file=sys.stderr,
        )
        # 128 + signal, as a shell reports it: 130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP.
        return EXIT_INTERRUPTED if report.signal is None else 128 + report.signal
    errors = report.errors
    # One line per failed recording, up to _LISTED_FAILURES (the rest are in the tables), also
    # when --max-errors tolerates them: which ones failed is the first thing to look at. Rows
    # start with their URI (error_result); printable: as the tables show odd file names.
    for row in errors[:_LISTED_FAILURES]:
        print(
            f"failed: {short(printable(row.error or f'{row.uri}: unknown error'))}",
            file=sys.stderr,
        )
    more = len(errors) - _LISTED_FAILURES
    if more > 0:
        print(f"failed: ... and {more} more (recordings.parquet, report.md)", file=sys.stderr)
    if len(errors) > args.max_errors:
        # Failed gates are named too, though the errors decide the exit code (1).
        for reason in _gate_failures(args, report):
            print(f"error: {short(reason)}", file=sys.stderr)
        print(
            f"error: {len(errors)} recording(s) failed (more than --max-errors {args.max_errors})",
            file=sys.stderr,
        )
        return 1
    salvaged = [r for r in report.results if r.losses]
    failed = _gate_failures(args, report)
    for reason in failed:  # named even when the salvage decides the exit code
        print(f"error: {short(reason)}", file=sys.stderr)
    if salvaged:  # as process --salvage: lost messages come before the gates
        print(
            "warning: "
            + short(
                f"{len(salvaged)} recording(s) damaged, kept what could be read (--salvage, "
                f"exit {EXIT_SALVAGED}); first: {printable(salvaged[0].losses[0])}"
            ),
            file=sys.stderr,
        )
        return EXIT_SALVAGED
    return EXIT_GATE if failed else 0


def _gate_failures(args: argparse.Namespace, report: Any) -> list[str]:
    """Why the requested gates fail, each gate once (empty: they pass or none was asked for)."""
    from rose_logs.batch.sources import printable
    from rose_logs.session.report import row_judged, w_judges

    reasons = []
    ok = [r for r in report.results if r.status == "ok"]
    if args.fail_above is not None:
        # w_max is None for a recording without a judged snapshot (only empty maps).
        w_max = {r.uri: r.row()["w_max"] for r in ok}  # a row per recording: a median to build
        above = [r for r in ok if w_max[r.uri] is not None and w_max[r.uri] > args.fail_above]
        if above:
            worst = max(above, key=lambda r: w_max[r.uri])
            from rose_logs.session.report import score_beside_level  # loaded with the batch

            w, level = score_beside_level(w_max[worst.uri], args.fail_above)
            reasons.append(
                f"{printable(worst.uri)}: W = {w} exceeds --fail-above {level} (the highest; "
                f"{len(above)} recording(s) above it)"
            )
    if args.fail_on_break:
        breaks = [(r, s) for r in ok for s in r.snapshots if s.get("break_start")]
        if breaks:
            recording, snapshot = breaks[0]
            reasons.append(
                f"{printable(recording.uri)}: the map breaks at {snapshot['topic']} snapshot "
                f"{snapshot['index']} ({len(breaks)} break(s) in "
                f"{len({r.uri for r, _ in breaks})} recording(s); --fail-on-break)"
            )
    for r in ok:
        analysed = {s["topic"] for s in r.snapshots}
        # As process judges them: a map W cannot read (a solid block, a thin strip: degenerate)
        # is no judged map, however many occupied cells it has.
        judged = {s["topic"] for s in r.snapshots if row_judged(s)}
        unreadable = {
            s["topic"] for s in r.snapshots if w_judges(s["occupied"]) and s.get("degenerate")
        }
        reasons += [
            f"{printable(r.uri)}: {why}"
            for why in unjudged_topics(args, r.map_topics, analysed, judged, unreadable)
        ]
    return reasons
