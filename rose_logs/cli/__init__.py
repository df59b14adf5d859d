"""The ``rose-bag`` command: ``process``, ``info``, ``convert``, ``evaluate`` and ``batch``, one module each.

Exit codes: 0 success, 1 error (one line ``error: <file>: <problem>`` on stderr), 2 usage error,
3 ``--fail-above`` gate failed. Tracebacks only with ``--debug``.
"""

from __future__ import annotations

import argparse
import logging
import sys

from rose.errors import RoseError
from rose_logs.cli import batch, convert, evaluate, info, process
from rose_logs.cli.options import EXIT_GATE, UsageError
from rose_logs.errors import LogError

__all__ = ["EXIT_GATE", "build_parser", "main"]


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
    for command in (process, info, convert, evaluate, batch):
        command.add_parser(subparsers)
    return parser


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
    except UsageError as err:
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
