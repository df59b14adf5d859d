"""Exceptions raised by the ``rose`` package."""

from __future__ import annotations

__all__ = ["MapFileError", "OutputError", "RoseError"]


class RoseError(Exception):
    """Base class of every error raised by ``rose``; its message is one line for the user."""


class MapFileError(RoseError):
    """A map file (YAML, PGM, PNG) is missing, unreadable or malformed, or cannot be written."""


class OutputError(RoseError):
    """An output cannot be written: it touches an input or another output, exists, or its folder fails."""
