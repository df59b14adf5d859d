"""The ``rose-bag`` command (placeholder until the log workflow lands)."""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    print("error: rose-bag is not implemented yet", file=sys.stderr)
    return 1
