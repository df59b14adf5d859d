"""Both command packages import their sub-commands plainly: a broken import is an error, not a lost command."""

from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

import pytest


@pytest.mark.parametrize(
    ("package", "command"),
    [
        ("rose_logs.cli", "process"),
        ("rose_logs.cli", "info"),
        ("rose_logs.cli", "convert"),
        ("rose_logs.cli", "evaluate"),
        ("rose.cli", "clean"),
        ("rose.cli", "score"),
        ("rose.cli", "walls"),
    ],
)
def test_broken_subcommand_import_is_not_hidden(
    monkeypatch: pytest.MonkeyPatch, package: str, command: str
) -> None:
    module = importlib.import_module(package)
    # ``None`` in sys.modules makes ``import package.command`` raise ImportError. The sub-commands
    # load when the parser is built (inside main's handlers, so start-up stays interruptible).
    monkeypatch.setitem(sys.modules, f"{package}.{command}", None)
    monkeypatch.delattr(module, command, raising=False)
    with pytest.raises(ImportError, match=f"{package}.{command}"):
        module.build_parser()


@pytest.mark.parametrize(
    ("package", "commands"),
    [
        ("rose_logs.cli", {"process", "info", "convert", "evaluate"}),
        ("rose.cli", {"clean", "score", "walls"}),
    ],
)
def test_every_subcommand_is_registered(package: str, commands: set[str]) -> None:
    import argparse

    parser = importlib.import_module(package).build_parser()
    (subparsers,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    assert commands <= set(subparsers.choices)


def test_cli_modules_load_no_numerics_before_main() -> None:
    """The CLIs install their signal handlers before numpy / scipy load (over a second on a busy
    machine), so a Ctrl-C during start-up is a clean exit 130 and not a traceback."""
    import subprocess

    code = (
        "import sys, rose.cli, rose_logs.cli; "
        "print(sorted(m for m in ('numpy', 'scipy', 'cv2', 'rerun') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize("package", ["rose_logs.cli", "rose.cli"])
def test_the_parsers_load_no_scipy(package: str) -> None:
    """``--help`` and usage errors answer without loading scipy and the whole of ROSE (``rose-bag
    --help`` 0.68 -> 0.33 s and 93 -> 38 MB, ``rose --help`` 0.8 -> 0.21 s): the parsers need only
    option definitions and configurations; each command loads what it runs."""
    import subprocess

    code = (
        f"import sys; from {package} import build_parser; build_parser(); "
        "print(sorted(m for m in ('scipy', 'cv2', 'rerun', 'matplotlib') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_rose_bag_info_loads_no_scipy() -> None:
    """``rose-bag info`` reads the log's topics and messages, not ROSE: 0.8 -> 0.47 s, 103 -> 51 MB."""
    import subprocess

    sample = Path(__file__).resolve().parents[1] / "sample_data" / "fr079_session.mcap"
    code = (
        "import sys; from rose_logs.cli import main\n"
        f"try:\n    main(['info', {str(sample)!r}])\nexcept SystemExit as done:\n"
        "    assert not done.code, done.code\n"
        "print(sorted(m for m in ('scipy', 'cv2', 'rerun') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "/map" in done.stdout  # it did read the log
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_public_clean_is_the_function_after_its_module_loads() -> None:
    import rose
    import rose.cleaning  # a submodule named like a public function would replace it

    assert callable(rose.clean)
    assert rose.clean is rose.cleaning.clean


@pytest.mark.parametrize(("command", "package"), [("rose-bag", "rose_logs"), ("rose", "rose")])
def test_version_is_the_one_pyproject_declares(command: str, package: str) -> None:
    import subprocess
    import tomllib
    from pathlib import Path

    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    version = tomllib.loads(pyproject.read_text())["project"]["version"]
    shown = subprocess.run(
        [sys.executable, "-c", f"import sys; from {package}.cli import console; sys.exit(console())",
         "--version"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert (shown.returncode, shown.stdout) == (0, f"{command} {version}\n")


def test_the_modules_the_docs_name_load_on_first_use_after_a_plain_import() -> None:
    """``import rose; rose.spectrum.padded_shape(...)`` raised AttributeError unless something had
    imported rose.spectrum first."""
    import subprocess
    import sys

    import rose

    code = (
        "import rose; print(rose.spectrum.padded_shape((736, 1152)), rose.breaks.__name__); "
        f"print(all(hasattr(rose, m) for m in {sorted(rose._SUBMODULES)!r}))"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.split("\n")[1] == "True"
    assert "rose.breaks" in run.stdout
    assert not hasattr(rose, "no_such_module")
    # Every module of the package, and every one its docstring names, is served.
    package = Path(rose.__file__).parent
    # (Subpackages of the method too; `cli` is the command line, not served.)
    modules = {p.stem for p in package.glob("*.py") if p.stem != "__init__"} | {
        p.parent.name for p in package.glob("*/__init__.py") if p.parent.name != "cli"
    }
    named = set(re.findall(r"``rose\.(\w+)``", rose.__doc__ or ""))
    assert named and named <= modules == set(rose._SUBMODULES)
    assert modules <= set(dir(rose))
