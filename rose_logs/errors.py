"""Exceptions raised by ``rose_logs``; every message is one line for the user and names the file."""

from __future__ import annotations

__all__ = ["EmptyMapError", "LogError", "LogReadError", "LogWriteError", "MapMessageError"]


class LogError(Exception):
    """Base class of every error raised by ``rose_logs``."""


class LogReadError(LogError):
    """An input log is missing, truncated, corrupt, of an unsupported format or has no map topic."""


class LogWriteError(LogError):
    """An output log cannot be written: it exists, its folder is not writable, or the format is wrong."""


class MapMessageError(LogError):
    """One map message cannot be decoded (for example data length != width * height).

    The session logs a warning and copies the message through unprocessed.
    """


class EmptyMapError(MapMessageError):
    """A map message of no cells (width or height 0, no data): valid, but nothing to analyse.

    The session copies it through unprocessed and counts it apart from malformed messages.
    """
