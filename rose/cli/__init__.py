"""The ``rose`` command: ROSE on single map files.

``rose clean MAP -o OUT.yaml`` writes the decluttered map; ``rose score MAP...`` prints W and the
dominant directions; ``rose walls MAP`` prints wall segments. One module per command, the shared ROSE
options in :mod:`rose.cli.options`; errors are one line on stderr with exit code 1 (2 for usage errors).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import re
import sys
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn

from rose import __version__
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
from rose.limits import MAX_MESSAGE_CHARS, short, visible
from rose.signals import (
    install_signal_handlers,
    reraise_interrupt_behind,
    run_interruptible,
    signal_handlers_kept,
    signals_deferred,
)

__all__ = [
    "CommandParser",
    "LevelFormatter",
    "add_param_arguments",
    "build_parser",
    "console",
    "directions_deg",
    "error_text",
    "fraction",
    "input_name",
    "main",
    "non_negative_float",
    "out_of_memory",
    "params_from_args",
    "positive_float",
    "result_summary",
    "unexpected",
]


def build_parser() -> argparse.ArgumentParser:
    """The ``rose`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="rose",
        description="ROSE structure extraction and decluttering for map files.",
        epilog=exit_status_text(),
        formatter_class=argparse.RawDescriptionHelpFormatter,  # the epilog's lines as they are
        allow_abbrev=False,
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(
        dest="command", required=True, metavar="COMMAND", parser_class=CommandParser
    )
    # Imported here, inside main's handlers: numpy / scipy take seconds to load on a busy machine.
    from rose.cli import clean, score, walls

    for command in (clean, score, walls):
        command.add_parser(commands)
    for command_parser in commands.choices.values():  # usage errors show the command's usage
        command_parser.set_defaults(command_parser=command_parser)
        # Also after the command, as rose-bag takes it; not given there, the top level's stands.
        command_parser.add_argument(
            "--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks"
        )
    return parser


def exit_status_text(*extra: str) -> str:
    """The exit codes, as the top-level ``--help`` lists them for scripts: those every command
    shares, with a command's ``extra`` lines (``"3    ..."``) after the usage error's."""
    lines = [
        "0    success",
        "1    error, said in one line on stderr: error: <file>: <problem>",
        "2    usage error",
        *extra,
        "130  interrupted: Ctrl-C (SIGINT); 143 SIGTERM, 129 SIGHUP",
        "141  standard output closed early (| head)",
    ]
    return "exit status:\n" + "\n".join(f"  {line}" for line in lines)


class CommandParser(argparse.ArgumentParser):
    """A command's parser (``rose clean``, ``rose-bag process``): arguments it does not know are its
    usage error, with its usage line, not the top-level parser's (``rose clean m.yaml --bogus``).
    Options are taken by their full names only (``--jso`` was read as ``--json``): an abbreviation
    that works today would change meaning when an option is added."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        self._given = list(sys.argv[1:] if args is None else args)
        parsed, extras = super().parse_known_args(args, namespace)
        if extras:  # as ArgumentParser.parse_args says it (exit 2)
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return parsed, extras

    def error(self, message: str) -> NoReturn:
        # argparse checks required arguments before it looks at unknown ones: `rose clean --bogus`
        # said only that map and -o were missing, hiding the mistyped option.
        unknown = _unknown_options(self, getattr(self, "_given", []))
        if unknown and message.startswith("the following arguments are required"):
            message = f"unrecognized arguments: {' '.join(unknown)}"
        super().error(message)


_NEGATIVE_NUMBER = re.compile(r"^-\d+$|^-\d*\.\d+$")


def _unknown_options(parser: argparse.ArgumentParser, args: Sequence[str]) -> list[str]:
    """The arguments in ``args`` that look like options ``parser`` does not know (``--bogus``,
    ``-z``; not negative numbers, ``-`` or anything after ``--``)."""
    known = parser._option_string_actions  # argparse has no public table of its option strings
    unknown = []
    for token in args:
        if token == "--":
            break
        if not token.startswith("-") or token == "-" or _NEGATIVE_NUMBER.match(token):
            continue
        name = token.split("=", 1)[0]
        # A short option with its value or further flags attached (-o5, -qv) is known by its start.
        if name in known or (not token.startswith("--") and token[:2] in known):
            continue
        unknown.append(token)
    return unknown


_OPTIONS = {
    "add_param_arguments",
    "directions_deg",
    "fraction",
    "non_negative_float",
    "params_from_args",
    "positive_float",
    "result_summary",
}


def __getattr__(name: str) -> Any:
    if name in _OPTIONS:
        return getattr(importlib.import_module("rose.cli.options"), name)
    msg = f"module 'rose.cli' has no attribute {name!r}"
    raise AttributeError(msg)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``rose`` command; return the exit code.

    0 success, 1 error (one line ``error: <file>: <problem>`` on stderr, no output written; but
    standard output failing after the files were written says they are complete), 2 usage
    error, 130 / 143 / 129 interrupted by SIGINT / SIGTERM / SIGHUP (temporary files removed).
    """
    # An in-process caller keeps its own handlers; without a standard error, what the command
    # says there goes nowhere (not into its standard output).
    with signal_handlers_kept(), stderr_discarded():
        install_signal_handlers()
        return run_interruptible(lambda: _run(argv))


def _run(argv: Sequence[str] | None) -> int:
    # A console script held the signals while the command loaded (rose.entry): now they are ours.
    raise_held_start_signal()
    with signals_deferred():  # an interrupted import would be an ImportError, not exit 130
        print_any_file_name()
        parser = build_parser()
    from rose.cli.options import check_params, parse_args  # loaded with the commands already

    args = parse_args(parser, argv)

    check_params(args.command_parser, args)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(LevelFormatter())
    # Not for `rose score`'s several maps: the first one's name would be wrong for the others.
    single = input_name(args) if getattr(args, "maps", None) is None else None
    handler.addFilter(_InputNamed(single))
    written: list[Path] = []  # the files the command committed (an error after them names them)
    try:
        from rose.outputs import committed_outputs, refuse_closed_stdout  # loaded already

        if _needs_stdout(args):  # else, without a standard output, its summary goes nowhere
            refuse_closed_stdout()
        with (
            committed_outputs() as written,
            stdout_discarded(),
            logging_routed({"": handler}, logging.WARNING),
            stdout_errors_named(),
        ):
            return int(args.func(args))
    except (RoseError, OSError, MemoryError, RecursionError, RuntimeError, ImportError) as err:
        reraise_interrupt_behind(err)  # a signal inside a library: exit 130 / 143, not "error"
        if unexpected(err):
            raise
        if isinstance(err, OSError) and stdout_closed(err):  # `| head`: stop quietly
            return EXIT_BROKEN_PIPE
        if args.debug:
            raise
        print(f"error: {error_text(err, where=input_name(args), written=written)}", file=sys.stderr)
        return 1


#: The options of each command that name the files it writes (``-``: standard output).
_FILE_OPTIONS = {"clean": ("output", "json"), "walls": ("geojson", "svg")}


def _needs_stdout(args: argparse.Namespace) -> bool:
    """Whether the command writes its result to standard output: an output named ``-``, or a
    command whose result is what it prints (``score``; ``walls`` without an export). Under
    ``pythonw`` (no standard output) every command was refused, ``clean -o map.yaml`` too."""
    names = _FILE_OPTIONS.get(args.command)
    if names is None:
        return True
    paths = [getattr(args, name, None) for name in names]
    given = [str(path) for path in paths if path is not None]
    return not given or "-" in given


@contextlib.contextmanager
def logging_routed(routes: Mapping[str, logging.Handler], level: int) -> Iterator[None]:
    """While the block runs, the records of each named logger (``""``: the root) at ``level`` and
    above go to its handler alone (not on to its parents); afterwards every logger is as it was.

    A command run twice in one process (``main`` called in-process) wrote its warnings to the
    first run's stream through a handler left on the root logger.
    """
    saved = []
    for name, handler in routes.items():
        logger = logging.getLogger(name)
        saved.append((logger, logger.handlers[:], logger.level, logger.propagate))
        logger.handlers[:] = [handler]
        logger.setLevel(level)
        logger.propagate = False
    try:
        yield
    finally:
        for logger, handlers, old_level, propagate in saved:
            logger.handlers[:] = handlers
            logger.setLevel(old_level)
            logger.propagate = propagate


class LevelFormatter(logging.Formatter):
    """``warning: <message>``, like every other line the commands print (``rose`` and ``rose-bag``)."""

    def format(self, record: logging.LogRecord) -> str:
        # A name from a log (a topic, a frame) may hold a newline or an escape sequence: one line,
        # and nothing that drives the terminal.
        return f"{record.levelname.lower()}: {visible(record.getMessage())}"


class _InputNamed(logging.Filter):
    """Puts the command's input in front of the library's messages that do not name a file
    (``warning: ROSE found no dominant direction ...`` said nothing of which map)."""

    def __init__(self, name: str | None) -> None:
        super().__init__()
        self._name = name

    def filter(self, record: logging.LogRecord) -> bool:
        from_library = record.name.startswith("rose.") and not record.name.startswith("rose.cli")
        if self._name and from_library:
            message = record.getMessage()
            if not message.startswith(self._name):
                record.msg, record.args = f"{self._name}: {message}", None
        return True


def unexpected(err: BaseException) -> bool:
    """Whether ``err``, caught as a RuntimeError or ImportError, is a bug to show as a traceback:
    not the memory running out (:func:`out_of_memory`), nor a RecursionError (a RuntimeError
    too: an input nested too deeply)."""
    return (
        isinstance(err, RuntimeError | ImportError)
        and not isinstance(err, RecursionError)
        and not out_of_memory(err)
    )


def out_of_memory(err: BaseException) -> bool:
    """Whether ``err`` is the memory (address space, ``ulimit -v``) running out where Python does not
    say MemoryError: a thread whose stack cannot be mapped, a native library loaded on demand that
    cannot be (both were a traceback)."""
    if type(err) is RuntimeError:
        return str(err) == "can't start new thread"
    if isinstance(err, ImportError):
        text = str(err)
        return "failed to map segment" in text or "cannot allocate memory" in text.lower()
    return False


def input_name(args: object) -> str | None:
    """The input a command was given (``input``, ``map``, ``log`` or the first of ``maps``), for errors."""
    for name in ("input", "map", "log"):
        value = getattr(args, name, None)
        if value is not None:
            return str(value)
    maps = getattr(args, "maps", None)
    return str(maps[0]) if maps else None


def error_text(
    err: BaseException, *, where: str | None = None, written: Sequence[Path] = ()
) -> str:
    """One short line for an error: OS errors with their file name; the algorithm's own errors
    (:class:`RoseError` itself, which know no file) prefixed with ``where`` (the command's input);
    file and log errors as they are (they name their file). Standard output failing after the
    command's files were ``written`` (its summary, printed after them) names them as complete."""
    if isinstance(err, StdoutError) and written:
        from rose.outputs import outputs_named  # loaded with the commands already

        # Fewer names where four long ones would fill the line: its cut took "only the summary
        # is lost" (a batch's four tables in a deep folder).
        for most in (4, 3, 2, 1):
            line = (
                f"{err}; the outputs are complete ({outputs_named(list(written), most)}): "
                "only the summary is lost"
            )
            if len(" ".join(line.split())) <= MAX_MESSAGE_CHARS:
                break
        return visible(short(line))
    return visible(_error_text(err, where=where))


def _error_text(err: BaseException, *, where: str | None = None) -> str:
    prefix = f"{where}: " if where else ""
    if isinstance(err, OSError) and not isinstance(err, RoseError):
        if err.filename:
            prefix = f"{err.filename}: "
        return short(f"{prefix}{err.strerror or err}")
    if isinstance(err, MemoryError):
        return short(f"{prefix}out of memory (lower --max-cells?)")
    if isinstance(err, RecursionError):  # (a RuntimeError too: asked first)
        return short(f"{prefix}input nested too deeply")
    if isinstance(err, RuntimeError):  # out_of_memory: a thread's stack
        return short(f"{prefix}out of memory (a thread could not start)")
    if isinstance(err, ImportError):  # out_of_memory: a native library
        return short(f"{prefix}out of memory (library {err.name or err.path} could not be loaded)")
    if type(err) is RoseError and where is not None and where not in str(err):
        return short(f"{prefix}{err}")
    return short(err)


def console() -> None:
    """The command as its console script runs it (through :mod:`rose.entry`): :func:`main`, then
    exit with its code (late signals ignored)."""
    from rose.console import buffer_unbuffered_stdout
    from rose.signals import exit_after

    buffer_unbuffered_stdout()
    exit_after(main())
