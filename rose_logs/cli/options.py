"""What every ``rose-bag`` command shares: exit codes, the usage-error type, time formatting.

The ROSE tuning options themselves are defined once in :mod:`rose.cli.options` and shared with ``rose``.
"""

from __future__ import annotations

from datetime import UTC, datetime

from rose_logs.cli import EXIT_GATE, EXIT_SALVAGED, UsageError

__all__ = [
    "EXIT_GATE",
    "EXIT_SALVAGED",
    "UsageError",
    "duration_text",
    "utc_text",
]


def utc_text(time_ns: int) -> str:
    """A log time (int ns since the epoch) as ``YYYY-MM-DD HH:MM:SS.mmm`` UTC."""
    return datetime.fromtimestamp(time_ns / 1e9, tz=UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]


def duration_text(ns: int) -> str:
    """A duration in ns as seconds with one decimal, e.g. ``"12.5 s"``."""
    return f"{ns / 1e9:.1f} s"
