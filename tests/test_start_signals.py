"""A signal while a command is still loading its modules (before its ``main`` installs its handlers):
exit 130 / 143 without a traceback, through ``python -m`` and the console scripts; a program that only
imports the packages keeps Python's own handling."""

from __future__ import annotations

import ast
import os
import signal
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# A sitecustomize that sends a signal to its own process as soon as rose.signals starts loading: the
# signal lands inside the command's imports, every time (no timing to hit).
_HOOK = """
import os, signal, sys

class _SignalOnLoad:
    def find_spec(self, name, path=None, target=None):
        if name == "rose.signals":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.{signal})
        return None

sys.meta_path.insert(0, _SignalOnLoad())
"""

# What pip writes for a [project.scripts] entry.
_SCRIPT = """import re
import sys
from {module} import {function}
if __name__ == '__main__':
    sys.argv[0] = re.sub(r'(-script\\.pyw|\\.exe)?$', '', sys.argv[0])
    sys.exit({function}())
"""


def _run(
    tmp_path: Path, args: list[str], signal_name: str = "SIGINT"
) -> subprocess.CompletedProcess[str]:
    (tmp_path / "sitecustomize.py").write_text(_HOOK.format(signal=signal_name))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    return subprocess.run(
        [sys.executable, *args], capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120
    )


def _console_script(tmp_path: Path, command: str) -> Path:
    entry = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"][command]
    module, function = entry.split(":")
    script = tmp_path / command
    script.write_text(_SCRIPT.format(module=module, function=function))
    return script


_COMMANDS = [
    ("rose-bag", "rose_logs.cli", ["info", "missing.mcap"]),
    ("rose", "rose.cli", ["score", "missing.yaml"]),
]


@pytest.mark.parametrize(("command", "module", "args"), _COMMANDS)
@pytest.mark.parametrize("how", ["python -m", "console script"])
def test_ctrl_c_while_the_command_loads_exits_130_without_a_traceback(
    tmp_path: Path, command: str, module: str, args: list[str], how: str
) -> None:
    start = ["-m", module] if how == "python -m" else [str(_console_script(tmp_path, command))]
    done = _run(tmp_path, [*start, *args])
    assert "Traceback" not in done.stderr
    assert (done.returncode, done.stderr) == (130, "error: interrupted, nothing written\n")


@pytest.mark.parametrize(("command", "module", "args"), _COMMANDS)
def test_sigterm_while_the_command_loads_exits_143(
    tmp_path: Path, command: str, module: str, args: list[str]
) -> None:
    done = _run(tmp_path, [str(_console_script(tmp_path, command)), *args], "SIGTERM")
    assert (done.returncode, done.stderr) == (143, "error: interrupted, nothing written\n")


@pytest.mark.parametrize("module", ["rose_logs.cli", "rose.cli"])
def test_a_program_importing_the_packages_keeps_pythons_ctrl_c(tmp_path: Path, module: str) -> None:
    done = _run(tmp_path, ["-c", f"import {module}; print('imported')"])
    assert "imported" not in done.stdout
    assert done.stderr.rstrip().endswith("KeyboardInterrupt")


def test_importing_the_packages_changes_no_signal_handler(tmp_path: Path) -> None:
    code = (
        "import signal; before = [signal.getsignal(s) for s in (2, 15, 1)]; "
        "import rose, rose_logs, rose.entry, rose.cli, rose_logs.cli; "
        "print(before == [signal.getsignal(s) for s in (2, 15, 1)])"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    assert done.stdout == "True\n"


@pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="no SIGHUP")
def test_a_signal_ignored_at_start_stays_ignored(tmp_path: Path) -> None:
    """``nohup rose-bag ...``: a SIGHUP while it loads is not held (and so not acted on)."""
    script = _console_script(tmp_path, "rose-bag")
    (tmp_path / "sitecustomize.py").write_text(_HOOK.format(signal="SIGHUP"))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    done = subprocess.run(
        [sys.executable, str(script), "info", "missing.mcap"],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
        timeout=120,
        preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN),
    )
    assert done.returncode == 1
    assert done.stderr.startswith("error: missing.mcap")


# Says, as the process ends, how many threads each OpenBLAS loaded runs.
_BLAS_THREADS_HOOK = """
import atexit, sys

def _say():
    from threadpoolctl import threadpool_info

    counts = [i["num_threads"] for i in threadpool_info() if i["internal_api"] == "openblas"]
    print("openblas threads", counts, file=sys.stderr)

atexit.register(_say)
"""


def _address_limit(limit: int) -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (limit, resource.RLIM_INFINITY))


@pytest.mark.skipif(sys.platform == "win32", reason="no ulimit -v")
@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="OpenBLAS runs one thread anyway")
@pytest.mark.parametrize("start", ["-m", "console script"])
def test_under_an_address_space_limit_openblas_runs_one_thread(tmp_path: Path, start: str) -> None:
    """Under ``ulimit -v``, OpenBLAS started a thread per core as numpy and scipy loaded, each
    with a buffer mapped: a thread that could not start made it raise SIGINT (``rose-bag process``
    said "interrupted, nothing written", exit 130, under ulimit -v 350000 on two cores), a buffer
    that could not be mapped made it retry for ever (the run hung at 600000, deaf to SIGTERM).
    The commands hold it to one thread under a limit; without one, or with OPENBLAS_NUM_THREADS
    set, nothing changes."""
    pytest.importorskip("threadpoolctl")
    (tmp_path / "sitecustomize.py").write_text(_BLAS_THREADS_HOOK)
    sample = ROOT / "sample_data" / "fr079_session.mcap"
    if start == "-m":
        argv = [sys.executable, "-m", "rose_logs.cli", "info", str(sample)]
    else:
        code = "import sys; from rose.entry import rose_bag; sys.argv[0] = 'rose-bag'; rose_bag()"
        argv = [sys.executable, "-c", code, "info", str(sample)]
    # OpenBLAS also reads OMP_NUM_THREADS (and GOTO_NUM_THREADS), which a batch test run before in
    # this process may have set (tune_worker_process): none of them here.
    blas = {"OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "GOTO_NUM_THREADS"}
    base = {k: v for k, v in os.environ.items() if k not in blas}
    env = {**base, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}

    def threads(limit: int | None, extra: dict[str, str] | None = None) -> list[int]:
        done = subprocess.run(
            argv,
            capture_output=True,
            text=True,
            env={**env, **(extra or {})},
            cwd=tmp_path,
            preexec_fn=None if limit is None else lambda: _address_limit(limit),
            timeout=120,
        )
        assert done.returncode == 0, done.stderr
        said = done.stderr.strip().splitlines()[-1]
        assert said.startswith("openblas threads ["), done.stderr
        counts: list[int] = ast.literal_eval(said.removeprefix("openblas threads "))
        return counts

    limited = threads(16 << 30)  # far more than the command needs
    assert limited and set(limited) == {1}, limited
    assert max(threads(None)) > 1
    assert max(threads(16 << 30, {"OPENBLAS_NUM_THREADS": "2"})) > 1


@pytest.mark.skipif(sys.platform == "win32", reason="no ulimit -v")
def test_under_an_address_space_limit_scipys_openblas_loads_before_the_work() -> None:
    """Loaded on demand by the first analysis, when the log's buffers and the session's threads
    already took the address space, scipy's OpenBLAS could not map its buffer and retried for
    ever: ``rose-bag process`` hung at 100 % CPU under ``ulimit -v 400000`` on 1000 x 1000 maps.
    Under a limit the analysing commands load it before the work, or say they are out of memory
    where it would not fit (a load that may never end is not tried); start-up does not load it
    (loaded by every command, it hung ``--version`` and ``info`` at limits where they ran)."""
    code = (
        "import resource, sys\n"
        "from rose.entry import blas_threads_within_address_limit, load_blas_before_work\n"
        "blas_threads_within_address_limit()\n"
        "print('scipy.special' in sys.modules)\n"
        "if len(sys.argv) > 1:\n"
        "    used = int(open('/proc/self/status').read().split('VmSize:')[1].split()[0]) << 10\n"
        "    resource.setrlimit(resource.RLIMIT_AS, (used + (16 << 20), resource.RLIM_INFINITY))\n"
        "try:\n"
        "    load_blas_before_work()\n"
        "except MemoryError:\n"
        "    print('MemoryError')\n"
        "print('scipy.special' in sys.modules)\n"
    )

    def run(limit: int | None, *, tight: bool = False) -> list[str]:
        done = subprocess.run(
            [sys.executable, "-c", code, *(["tight"] if tight else [])],
            capture_output=True,
            text=True,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
            preexec_fn=None if limit is None else lambda: _address_limit(limit),
            timeout=120,
        )
        assert done.returncode == 0, done.stderr
        return done.stdout.split()

    assert run(16 << 30) == ["False", "True"]
    assert run(None) == ["False", "False"]
    if Path("/proc/self/status").exists():
        assert run(16 << 30, tight=True) == ["False", "MemoryError", "False"]
