"""Exceptions raised by the ``rose`` package."""

from __future__ import annotations

__all__ = ["MapFileError", "OutputError", "RoseError", "StdoutError"]


class RoseError(Exception):
    """Base class of every error raised by ``rose``; its message is one line for the user."""


class MapFileError(RoseError):
    """A map file (YAML, PGM, PNG) is missing, unreadable or malformed, or cannot be written."""


class OutputError(RoseError):
    """An output cannot be written: it touches an input or another output, exists, or its folder fails."""


class StdoutError(OutputError):
    """Standard output cannot be written (a full disk, an I/O error): the message names standard
    output, not the command's input, as ``standard output: cannot write (<reason>)``."""

    def __init__(self, reason: str, *, after: str = "") -> None:
        # ``after``: what it means for the run's files (``; out.mcap not written``).
        super().__init__(f"standard output: cannot write ({reason}){after}")
        self.reason = reason
        # The exit code when it cut the summary of a run that had decided another than 0 (a
        # failed gate, a salvage): set by the command (rose_logs.cli.options.summary_then_verdict).
        self.exit_code = 1
