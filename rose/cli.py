"""The ``rose`` command (placeholder)."""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    print("error: not implemented yet", file=sys.stderr)
    return 1
