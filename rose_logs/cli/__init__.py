"""The ``rose-bag`` command: ``process``, ``info``, ``convert``, ``evaluate`` and ``batch``, one module each.

Exit codes: 0 success, 1 error (one line ``error: <file>: <problem>`` on stderr), 2 usage error,
3 ``--fail-above`` or ``--fail-on-break`` gate failed, 4 ``--salvage`` with messages lost,
130 / 143 / 129 interrupted by SIGINT / SIGTERM / SIGHUP, 141 standard output closed early.
Tracebacks only with ``--debug``.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys
from pathlib import Path

from rose.cli import (
    CommandParser,
    LevelFormatter,
    error_text,
    exit_status_text,
    input_name,
    logging_routed,
    unexpected,
)
from rose.console import (
    EXIT_BROKEN_PIPE,
    print_any_file_name,
    stderr_discarded,
    stdout_closed,
    stdout_discarded,
    stdout_errors_named,
)
from rose.entry import raise_held_start_signal
from rose.errors import RoseError, StdoutError
from rose.signals import (
    install_signal_handlers,
    reraise_interrupt_behind,
    run_interruptible,
    signal_handlers_kept,
    signals_deferred,
)
from rose_logs import __version__
from rose_logs.errors import LogError
from rose_logs.malloc import keep_arrays_on_heap

__all__ = ["EXIT_GATE", "EXIT_SALVAGED", "build_parser", "console", "main"]

EXIT_GATE = 3
"""Exit code of a failed quality gate (``--fail-above``, ``--fail-on-break``)."""

EXIT_SALVAGED = 4
"""Exit code of ``--salvage`` when messages were lost: the outputs hold what could be read."""


class UsageError(Exception):
    """A combination of options that argparse cannot check; exits 2 like argparse's own errors."""


def build_parser() -> argparse.ArgumentParser:
    """The ``rose-bag`` argument parser with every sub-command."""
    parser = argparse.ArgumentParser(
        prog="rose-bag",
        description="ROSE structure extraction and decluttering of occupancy-grid maps in robot logs.",
        epilog=exit_status_text(
            f"{EXIT_GATE}    --fail-above or --fail-on-break gate failed",
            f"{EXIT_SALVAGED}    --salvage with messages lost: the outputs hold what could be read",
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,  # the epilog's lines as they are
        allow_abbrev=False,
    )
    parser.add_argument(
        "--debug", action="store_true", help="debug logging and tracebacks on errors"
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(
        dest="command", metavar="COMMAND", required=True, parser_class=CommandParser
    )
    # Imported here, inside main's handlers: the libraries take seconds to load on a busy machine.
    from rose_logs.cli import batch, convert, evaluate, info, process

    for command in (process, info, convert, evaluate, batch):
        command.add_parser(subparsers)
    for command_parser in subparsers.choices.values():  # usage errors show the command's usage
        command_parser.set_defaults(command_parser=command_parser)
        # Also after the command (rose-bag process x --debug); not given there, the top level's
        # value stands.
        command_parser.add_argument(
            "--debug",
            action="store_true",
            default=argparse.SUPPRESS,
            help="debug logging and tracebacks on errors",
        )
    return parser


#: The options of each command that name the files or folders it writes (``-``: standard output).
_FILE_OPTIONS = {
    "process": ("output", "rrd", "json_path"),
    "convert": ("output",),
    "evaluate": ("out_dir",),
    "batch": ("out",),
}


def _needs_stdout(args: argparse.Namespace) -> bool:
    """Whether the command writes its result to standard output: an output named ``-``, or a
    command whose result is what it prints (``info``; ``process`` writing no log, report or
    recording, nor streaming to a viewer). Under ``pythonw`` (no standard output) every command
    was refused, ``process run.mcap -o out.mcap`` too."""
    names = _FILE_OPTIONS.get(args.command)
    if names is None:
        return True
    if any(str(getattr(args, name, None)) == "-" for name in names):
        return True
    if args.command == "process":
        streamed = args.spawn or args.connect is not None
        return args.no_output and args.rrd is None and args.json_path is None and not streamed
    return False


def _logging(debug: bool) -> contextlib.AbstractContextManager[None]:
    """``warning: ...`` lines on stderr for our logs and for the ``rose`` library underneath, while
    the command runs.

    A session calls the library once per snapshot: its messages (``ROSE found no dominant
    direction ...``) are said once per map topic, naming it, not once per snapshot.
    """
    ours = logging.StreamHandler(sys.stderr)
    ours.setFormatter(LevelFormatter())
    library = logging.StreamHandler(sys.stderr)
    library.setFormatter(LevelFormatter())
    library.addFilter(_OncePerMessage())
    level = logging.DEBUG if debug else logging.WARNING
    return logging_routed({"rose_logs": ours, "rose": library}, level)


class _OncePerMessage(logging.Filter):
    """Lets each distinct message through once; one said while a session analyses a map topic
    gets the topic in front."""

    def __init__(self) -> None:
        super().__init__()
        self._seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        from rose_logs.session.held_logs import ANALYSED_TOPIC

        message = record.getMessage()
        topic = ANALYSED_TOPIC.get()
        if topic is not None:
            message = f"{topic}: {message}"
            record.msg, record.args = message, None
        if message in self._seen:
            return False
        self._seen.add(message)
        return True


def main(argv: list[str] | None = None) -> int:
    """Run ``rose-bag`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code.

    0 success, 1 error (one line on stderr, nothing written; but standard output failing after the
    files were written says they are complete, and leaves a gate's or salvage's code as it was),
    2 usage error, 3 ``--fail-above`` or ``--fail-on-break`` gate, 4 ``--salvage`` with messages
    lost, 130 / 143 / 129 interrupted by SIGINT / SIGTERM / SIGHUP, 141 standard output closed
    early.
    """
    # An in-process caller keeps its own handlers; without a standard error, what the command
    # says there goes nowhere (not into its standard output).
    with signal_handlers_kept(), stderr_discarded():
        install_signal_handlers()
        return run_interruptible(lambda: _run(argv))


def _run(argv: list[str] | None) -> int:
    # Inside run_interruptible: keep_arrays_on_heap runs `ldconfig -p` (ctypes.util.find_library),
    # and a signal landing there must be exit 130 / 143, not a traceback.
    # A console script held the signals while the command loaded (rose.entry): now they are ours.
    raise_held_start_signal()
    with signals_deferred():  # an interrupted import would be an ImportError, not exit 130
        print_any_file_name()
        keep_arrays_on_heap()  # map-sized arrays stay on the heap: far fewer page faults (module notes)
        # Rerun's native logger prints multi-line ERROR records to stderr (e.g. a failed flush on a
        # full disk) that our one-line errors already report: keep it quiet unless the user set RUST_LOG.
        os.environ.setdefault("RUST_LOG", "off")
        parser = build_parser()
    from rose.cli.options import check_params, parse_args  # loaded with the commands already

    args = parse_args(parser, argv)

    check_params(getattr(args, "command_parser", parser), args)
    written: list[Path] = []  # the files the command committed (an error after them names them)
    try:
        from rose.outputs import committed_outputs, refuse_closed_stdout  # loaded already

        if _needs_stdout(args):  # else, without a standard output, its summary goes nowhere
            refuse_closed_stdout()
        # Standard output's errors name it, not the input.
        with (
            committed_outputs() as written,
            stdout_discarded(),
            _logging(args.debug),
            stdout_errors_named(),
        ):
            return int(args.func(args))
    except UsageError as err:
        command_parser = getattr(args, "command_parser", parser)
        command_parser.print_usage(sys.stderr)
        print(f"{command_parser.prog}: error: {error_text(err)}", file=sys.stderr)  # as argparse
        return 2
    except (
        LogError,
        RoseError,
        OSError,
        MemoryError,
        RecursionError,
        RuntimeError,
        ImportError,
    ) as err:
        reraise_interrupt_behind(err)  # a signal inside a library: exit 130 / 143, not "error"
        if unexpected(err):
            raise
        if isinstance(err, OSError) and stdout_closed(err):  # `| head`: stop quietly
            return EXIT_BROKEN_PIPE
        if args.debug:
            raise
        print(f"error: {error_text(err, where=input_name(args), written=written)}", file=sys.stderr)
        # The summary failed after the run decided its exit code (a gate, a salvage): kept.
        return err.exit_code if isinstance(err, StdoutError) else 1


def console() -> None:
    """The command as its console script runs it (through :mod:`rose.entry`): :func:`main`, then
    exit with its code (late signals ignored)."""
    from rose.console import buffer_unbuffered_stdout
    from rose.signals import exit_after

    buffer_unbuffered_stdout()
    exit_after(main())
