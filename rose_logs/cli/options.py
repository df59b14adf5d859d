"""What every ``rose-bag`` command shares: exit codes, the usage-error type, JSON output.

The ROSE tuning options themselves are defined once in :mod:`rose.cli.options` and shared with ``rose``.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from rose.cli.options import add_param_arguments, params_from_args, positive_float

__all__ = [
    "EXIT_GATE",
    "UsageError",
    "add_param_arguments",
    "duration_text",
    "params_from_args",
    "positive_float",
    "utc_text",
    "write_json",
]

EXIT_GATE = 3
"""Exit code of a failed quality gate (``--fail-above``)."""


class UsageError(Exception):
    """A combination of options that argparse cannot check; exits 2 like argparse's own errors."""


def write_json(path: Path, payload: dict[str, Any]) -> None:
    """Write ``payload`` as strict JSON (no NaN / Infinity), atomically."""
    from rose.mapfile import write_atomically

    text = json.dumps(payload, indent=2, allow_nan=False, default=float).encode("utf-8")
    write_atomically(path, lambda f: f.write(text))


def utc_text(time_ns: int) -> str:
    """A log time (int ns since the epoch) as ``YYYY-MM-DD HH:MM:SS.mmm`` UTC."""
    return datetime.fromtimestamp(time_ns / 1e9, tz=UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]


def duration_text(ns: int) -> str:
    """A duration in ns as seconds with one decimal, e.g. ``"12.5 s"``."""
    return f"{ns / 1e9:.1f} s"
