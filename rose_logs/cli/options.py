"""What every ``rose-bag`` command shares: exit codes, the usage-error type, JSON output.

The ROSE tuning options themselves are defined once in :mod:`rose.cli.options` and shared with ``rose``.
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from rose.cli.options import add_param_arguments, params_from_args, positive_float
from rose_logs.cli import EXIT_GATE, EXIT_SALVAGED, UsageError

__all__ = [
    "EXIT_GATE",
    "EXIT_SALVAGED",
    "UsageError",
    "add_param_arguments",
    "duration_text",
    "params_from_args",
    "positive_float",
    "utc_text",
    "write_json",
]


def write_json(path: Path, payload: dict[str, Any]) -> None:
    """Write ``payload`` as strict JSON (non-finite numbers as null), atomically, replacing ``path``."""
    from rose.outputs import OutputSet

    with OutputSet(force=True) as outputs:
        outputs.write_json(path, payload)


def utc_text(time_ns: int) -> str:
    """A log time (int ns since the epoch) as ``YYYY-MM-DD HH:MM:SS.mmm`` UTC."""
    return datetime.fromtimestamp(time_ns / 1e9, tz=UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]


def duration_text(ns: int) -> str:
    """A duration in ns as seconds with one decimal, e.g. ``"12.5 s"``."""
    return f"{ns / 1e9:.1f} s"
