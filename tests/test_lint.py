"""The repository's own checks, so that the README's one test command runs them: ruff and mypy.

Each tool runs as a subprocess from the repository root with the configuration in ``pyproject.toml``;
a finding fails the test with the tool's output. A tool that is not installed skips its test (the
``test`` extra installs both).
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(module: str, *args: str) -> None:
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} is not installed (pip install -e '.[test]')")
    done = subprocess.run(
        [sys.executable, "-m", module, *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    if done.returncode != 0:
        pytest.fail(
            f"{' '.join((module, *args))} exited {done.returncode}:\n{done.stdout}{done.stderr}",
            pytrace=False,
        )


def test_ruff_check() -> None:
    _run("ruff", "check", "--no-cache", ".")


def test_ruff_format() -> None:
    _run("ruff", "format", "--check", "--no-cache", ".")


def test_mypy() -> None:
    # Files and options from [tool.mypy] in pyproject.toml (rose/ and rose_logs/).
    _run("mypy")
