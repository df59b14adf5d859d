"""``rose-bag``'s exit code for tests that call its ``main`` in the test process."""

from __future__ import annotations


def exit_code(argv: list[str]) -> int | str | None:
    """The exit code of ``rose-bag ARGV``: returned, or argparse's (it exits on its own usage
    errors)."""
    from rose_logs.cli import main

    try:
        return main(argv)
    except SystemExit as stop:
        return stop.code
