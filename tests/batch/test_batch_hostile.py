"""rose-bag batch against hostile options and signals: scheduler files, input lists, duplicate
spellings, worker counts, Ctrl-C and SIGTERM while a local Dask cluster runs."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq
import pytest
from fleet import SAMPLE

import rose_logs.batch.cluster as cluster
import rose_logs.batch.engine as engine
from rose_logs.batch import discover, run_batch
from rose_logs.cli import main

needs_dask = pytest.mark.skipif(
    importlib.util.find_spec("distributed") is None, reason="needs dask.distributed"
)


def one_error_line(err: str, culprit: Path | str) -> str:
    """The single ``error: <culprit>: ...`` line of ``err`` (fails otherwise)."""
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"error: {culprit}: "), err
    return lines[0]


# ---- --scheduler-file and --scheduler ---------------------------------------------------------------


def _write(path: Path, content: bytes | str | None) -> Path:
    if isinstance(content, str):
        path.write_text(content)
    elif isinstance(content, bytes):
        path.write_bytes(content)
    return path


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        (None, "no such scheduler file"),
        ("{}", "not a Dask scheduler file"),
        ("hello, not JSON", "not a Dask scheduler file"),
        (bytes(range(256)), "not a Dask scheduler file"),
        ('{"address": 8786}', "not a Dask scheduler file"),
        ('["tcp://127.0.0.1:8786"]', "not a Dask scheduler file"),
    ],
)
def test_a_bad_scheduler_file_is_a_one_line_error_before_anything_runs(
    fleet: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    content: bytes | str | None,
    problem: str,
) -> None:
    monkeypatch.setattr(cluster, "SCHEDULER_FILE_WAIT_S", 0.2)  # a missing file: short wait
    path = _write(tmp_path / "scheduler.json", content)
    out = tmp_path / "out"
    argv = ["batch", str(fleet / "robot_a"), "-o", str(out), "-q", "--scheduler-file", str(path)]
    started = time.monotonic()
    assert main(argv) == 1
    assert time.monotonic() - started < 5
    assert problem in one_error_line(capsys.readouterr().err, path)
    assert not out.exists()  # nothing written


@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_a_scheduler_file_that_is_no_regular_file_is_refused_without_blocking(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    path = tmp_path / "scheduler.json"
    if kind == "fifo":
        os.mkfifo(path)  # opening it would wait for a writer forever
    else:
        path.mkdir()
    argv = ["batch", str(fleet), "-o", str(tmp_path / "out"), "-q", "--scheduler-file", str(path)]
    assert main(argv) == 1
    assert "not a regular file" in one_error_line(capsys.readouterr().err, path)


def test_a_scheduler_file_appearing_late_is_waited_for(tmp_path: Path) -> None:
    path = tmp_path / "scheduler.json"
    writer = threading.Timer(0.3, path.write_text, args=('{"address": "tcp://127.0.0.1:8786"}',))
    writer.start()
    try:
        assert cluster.scheduler_address(path, wait_s=10) == "tcp://127.0.0.1:8786"
    finally:
        writer.cancel()


@pytest.fixture
def silent_listener() -> Iterator[str]:
    """A TCP port that accepts connections and never says anything (no Dask scheduler)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    accepted: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        server.settimeout(0.1)
        while not stop.is_set():
            try:
                accepted.append(server.accept()[0])
            except OSError:
                continue

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join()
        for conn in accepted:
            conn.close()
        server.close()


def _unused_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@needs_dask
@pytest.mark.parametrize("peer", ["nobody", "silent"])
def test_a_scheduler_that_does_not_answer_is_a_one_line_error_in_bounded_time(
    fleet: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    silent_listener: str,
    peer: str,
) -> None:
    monkeypatch.setattr(engine, "CONNECT_TIMEOUT_S", 1.0)
    address = silent_listener if peer == "silent" else f"tcp://127.0.0.1:{_unused_port()}"
    path = _write(tmp_path / "scheduler.json", json.dumps({"address": address}))
    out = tmp_path / "out"
    argv = ["batch", str(fleet / "robot_a"), "-o", str(out), "-q", "--scheduler-file", str(path)]
    started = time.monotonic()
    assert main(argv) == 1  # Dask alone waits forever for a silent peer's handshake
    assert time.monotonic() - started < 15
    line = one_error_line(capsys.readouterr().err, path)
    assert f"cannot connect to the Dask scheduler {address}" in line
    assert not out.exists()
    assert main(["batch", str(fleet), "-o", str(out), "-q", "--scheduler", address]) == 1
    one_error_line(capsys.readouterr().err, address)


# ---- --from-list ------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["device", "fifo", "folder", "huge"])
def test_an_input_list_that_is_no_reasonable_file_is_refused_unread(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    if kind == "device":
        path = Path("/dev/zero")  # endless: read whole, it ran until the OOM killer came
    elif kind == "fifo":
        path = tmp_path / "list.fifo"
        os.mkfifo(path)
    elif kind == "folder":
        path = tmp_path
    else:
        path = tmp_path / "list.txt"
        with path.open("wb") as f:
            f.truncate(64 * 1024 * 1024 + 1)  # sparse: instant, no disk used
    assert main(["batch", "--from-list", str(path), "-o", str(tmp_path / "out"), "-q"]) == 1
    line = one_error_line(capsys.readouterr().err, path)
    assert ("larger than 64 MiB" if kind == "huge" else "not a regular file") in line


def test_an_empty_input_list_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    empty = tmp_path / "todo.txt"
    empty.write_text("# nothing yet\n\n")
    assert main(["batch", "--from-list", str(empty), "-o", str(tmp_path / "out"), "-q"]) == 1
    assert "is empty" in one_error_line(capsys.readouterr().err, empty)


# ---- one file, several spellings --------------------------------------------------------------------


def test_one_file_under_several_spellings_is_one_recording(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(fleet)
    (tmp_path / "link.mcap").symlink_to(fleet / "robot_a" / "run.mcap")
    spellings = ["robot_a/run.mcap", "./robot_a/../robot_a/run.mcap", str(tmp_path / "link.mcap")]
    (recording,) = discover(spellings)
    assert recording.uri == str(fleet / "robot_a" / "run.mcap")  # the first spelling names it
    (linked,) = discover(spellings[::-1])
    assert linked.uri == str(tmp_path / "link.mcap")
    # A folder and a symlink to it inside another input: each recording once.
    (tmp_path / "mirror").symlink_to(fleet / "robot_b")
    assert len(discover([fleet, tmp_path / "mirror"])) == 5
    report = run_batch(spellings, tmp_path / "out")
    assert [r.name for r in report.results] == ["run.mcap"]


def test_symlinked_folders_are_searched_and_a_link_to_a_folder_above_ends_no_search(
    fleet: Path, tmp_path: Path
) -> None:
    # A fleet whose day folders live on another disk, linked in: their recordings are found,
    # named through the link. A link back to the fleet (a loop) adds nothing and ends.
    elsewhere = tmp_path / "disk2" / "robot_c"
    elsewhere.mkdir(parents=True)
    shutil.copy(fleet / "robot_a" / "run.mcap", elsewhere / "extra.mcap")
    (fleet / "robot_c").symlink_to(elsewhere, target_is_directory=True)
    (fleet / "robot_a" / "loop").symlink_to(fleet, target_is_directory=True)
    found = discover([fleet])
    names = [r.name for r in found]
    assert "fleet/robot_c/extra.mcap" in names
    assert len(found) == 6  # the five of the fleet and the linked one, each once
    assert not any("/loop/" in name for name in names)
    # A link beside the folder it names (sorting before it) does not take its recordings' names.
    (fleet / "again").symlink_to(fleet / "robot_a", target_is_directory=True)
    assert [r.name for r in discover([fleet])] == names


def test_a_folder_that_cannot_be_listed_is_skipped_with_a_warning_not_the_end_of_the_batch(
    fleet: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A disk's lost+found (mode 700, root's) made a batch over the disk a "cannot list" error;
    a whole input that cannot be listed still is one."""
    import errno
    import logging

    from rose_logs.batch.errors import BatchError

    locked = fleet / "lost+found"
    locked.mkdir()
    listing = os.scandir

    def scandir(path: object = ".") -> object:
        if Path(os.fsdecode(path)) in (locked, fleet / "robot_a"):
            raise PermissionError(errno.EACCES, "Permission denied", os.fspath(path))
        return listing(path)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "scandir", scandir)
    with caplog.at_level(logging.WARNING):
        found = discover([fleet])
    assert found and not any(r.name.startswith("fleet/robot_a/") for r in found)
    assert f"{locked}: cannot list (Permission denied), not searched" in caplog.text
    with pytest.raises(BatchError, match="cannot list"):
        discover([fleet / "robot_a"])


# ---- --workers --------------------------------------------------------------------------------------


def test_a_worker_count_beyond_four_per_cpu_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    limit = 4 * (os.cpu_count() or 1)
    argv = ["batch", str(SAMPLE), "-o", str(tmp_path / "out"), "--workers", str(limit + 1)]
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert f"must be <= {limit}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


# ---- signals while a local cluster runs (subprocesses, their own process group) ----------------------


def _start_batch(inputs: Path, out: Path, *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "rose_logs.cli", "batch", str(inputs), "-o", str(out), "-q", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # the test sends signals to its whole group, as a terminal does
    )


def _finish(process: subprocess.Popen[str], timeout: float = 60) -> tuple[int, str]:
    try:
        _, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        pytest.fail("the batch did not stop")
    return process.returncode, err


def _wait_for(condition: object, process: subprocess.Popen[str], timeout: float = 60) -> None:
    deadline = time.monotonic() + timeout
    while not condition():  # type: ignore[operator]
        if process.poll() is not None or time.monotonic() > deadline:
            os.killpg(process.pid, signal.SIGKILL)
            pytest.fail(f"gave up waiting: {process.communicate()[1][-2000:]}")
        time.sleep(0.05)


@needs_dask
def test_ctrl_c_on_a_local_cluster_keeps_every_finished_result_quietly(tmp_path: Path) -> None:
    folder = tmp_path / "fleet"
    folder.mkdir()
    for i in range(6):
        shutil.copy(SAMPLE, folder / f"s{i}.mcap")
    out = tmp_path / "out"
    process = _start_batch(folder, out, "--workers", "2", "--cleaned")
    _wait_for(lambda: any((out / "results").glob("*.json")), process)
    os.killpg(process.pid, signal.SIGINT)  # Ctrl-C at a terminal: every process of the group
    code, err = _finish(process)
    assert code == 130
    assert "Traceback" not in err
    assert "leaked semaphore" not in err
    assert err.strip().splitlines() == [
        line for line in err.strip().splitlines() if line.startswith("error: interrupted")
    ]
    results = [json.loads(p.read_text()) for p in (out / "results").glob("*.json")]
    assert 1 <= len(results) < 6
    rows = pq.read_table(out / "recordings.parquet").to_pylist()
    # Every result a worker finished is in the tables, also those not yet collected.
    assert sorted(r["uri"] for r in rows) == sorted(r["uri"] for r in results)
    assert all(Path(r["cleaned"]).is_file() for r in rows)
    assert json.loads((out / "summary.json").read_text())["recordings"] == len(results)


def _has_child(pid: int) -> bool:
    """Whether process ``pid`` has started a child process (Linux)."""
    try:
        tasks = list(Path(f"/proc/{pid}/task").iterdir())
        return any((task / "children").read_text().strip() for task in tasks)
    except OSError:
        return False


@needs_dask
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
def test_sigterm_while_the_local_cluster_starts_exits_143_quietly(tmp_path: Path) -> None:
    process = _start_batch(SAMPLE, tmp_path / "out", "--workers", "2")
    _wait_for(lambda: _has_child(process.pid), process)  # the cluster is starting its processes
    os.kill(process.pid, signal.SIGTERM)
    code, err = _finish(process)
    assert code == 143
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err


@needs_dask
def test_a_taken_dashboard_port_is_no_warning(tmp_path: Path) -> None:
    # Port 8787 held, as by another Dask cluster or a notebook's: Dask warned and moved the
    # scheduler's HTTP server (the tool shows no dashboard).
    import socket

    held = socket.socket()
    try:
        held.bind(("127.0.0.1", 8787))
        held.listen()
    except OSError:
        pass  # taken already: the condition holds anyway
    try:
        process = _start_batch(SAMPLE, tmp_path / "out", "--workers", "2")
        code, err = _finish(process)
    finally:
        held.close()
    assert code == 0, err
    assert "8787" not in err and "Warning" not in err, err


# ---- signals in this process ------------------------------------------------------------------------


def test_sigterm_exits_143_and_keeps_the_finished_recordings(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from rose.signals import Terminated

    real = engine.process_recording
    calls: list[int] = []

    def terminated_on_second(*args: object, **kwargs: object) -> object:
        calls.append(1)
        if len(calls) == 2:
            raise Terminated(signal.SIGTERM)
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(engine, "process_recording", terminated_on_second)
    out = tmp_path / "out"
    assert main(["batch", str(fleet), "-o", str(out), "-q"]) == 143  # was 130 for any signal
    assert len(pq.read_table(out / "recordings.parquet")) == 1


def test_a_signal_while_the_tables_are_written_waits_for_them(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import rose_logs.batch.tables as tables

    real = tables.write_outputs

    def interrupted(*args: object, **kwargs: object) -> None:
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C just as the tables are being written
        real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(tables, "write_outputs", interrupted)
    out = tmp_path / "out"
    report = run_batch([fleet / "robot_a"], out)
    assert (report.interrupted, report.signal) == (True, signal.SIGINT)
    assert len(report.results) == 2
    assert len(pq.read_table(out / "recordings.parquet")) == 2
    assert (out / "report.md").is_file()  # written to the end, after the first table


def test_a_signal_once_the_tables_are_placed_still_reaches_the_caller(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """run_batch is a library call: a Ctrl-C that lands while the committed tables' temporaries are
    removed must come back as an interrupted batch, not be dropped as after a command's last write."""
    import rose.outputs as outputs

    real, sent = outputs._remove_tree, []

    def remove_tree(path: Path) -> None:
        if ".rose-tmp-" in path.name and not sent and not any(path.iterdir()):
            sent.append(path)  # the first staging folder emptied by the commit: all files placed
            os.kill(os.getpid(), signal.SIGINT)
        real(path)

    monkeypatch.setattr(outputs, "_remove_tree", remove_tree)
    out = tmp_path / "out"
    report = run_batch([fleet / "robot_a"], out)
    assert sent
    assert (report.interrupted, report.signal) == (True, signal.SIGINT)
    assert (out / "report.md").is_file()  # the tables stand


def test_the_tables_leave_other_hosts_temporaries_alone(fleet: Path, tmp_path: Path) -> None:
    """Hosts sharing OUT write their own temporaries there; a process id that is not alive here may
    be alive on another host."""
    out = tmp_path / "out"
    out.mkdir()
    foreign = out / ".snapshots.parquet.rose-tmp-4000000-abcd1234"
    foreign.mkdir()
    run_batch([fleet / "robot_a"], out)
    assert foreign.is_dir()
    assert (out / "snapshots.parquet").is_file()


# ---- URLs fsspec cannot open ------------------------------------------------------------------------

#: A protocol registered for these tests whose backend package does not exist, as for ``gcs://``
#: without gcsfs (whichever backends happen to be installed here).
MISSING = "rosetestfs"


@pytest.fixture
def missing_backend(monkeypatch: pytest.MonkeyPatch) -> str:
    from fsspec.registry import known_implementations

    monkeypatch.setitem(
        known_implementations,
        MISSING,
        {"class": "rose_no_such_backend.FileSystem", "err": "Install rose_no_such_backend"},
    )
    return MISSING


@pytest.mark.parametrize("where", ["input", "output", "list entry", "list file"])
@pytest.mark.parametrize(
    ("scheme", "problem"),
    [
        ("foo", "unsupported URL scheme 'foo'"),
        (MISSING, "needs the rose_no_such_backend package (pip install rose_no_such_backend)"),
    ],
)
def test_a_url_fsspec_cannot_open_is_a_one_line_error_before_anything_runs(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    missing_backend: str,
    where: str,
    scheme: str,
    problem: str,
) -> None:
    url = f"{scheme}://bucket/robots/run.mcap"
    out = tmp_path / "out"
    listing = tmp_path / "todo.txt"
    listing.write_text(f"# one robot\n{url}\n")
    argv = {
        "input": [url, "-o", str(out)],
        "output": [str(SAMPLE), "-o", url],
        # A bad line is a bad input like a missing file: the whole batch stops, naming the line.
        "list entry": ["--from-list", str(listing), "-o", str(out)],
        "list file": ["--from-list", url, "-o", str(out)],
    }[where]
    assert main(["batch", *argv, "-q"]) == 1  # was a traceback (ValueError / ImportError)
    line = f" ({listing} line 2)" if where == "list entry" else ""  # which line of which list
    assert one_error_line(capsys.readouterr().err, url) == f"error: {url}: {problem}{line}"
    assert not out.exists()


@pytest.mark.skipif(importlib.util.find_spec("gcsfs") is not None, reason="gcsfs is installed")
def test_gcs_without_gcsfs_says_what_to_install(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["batch", "gcs://bucket/robots/", "-o", str(tmp_path / "out"), "-q"]) == 1
    line = one_error_line(capsys.readouterr().err, "gcs://bucket/robots/")
    assert line.endswith(": needs the gcsfs package (pip install gcsfs)")


# ---- a full disk or a failed upload while the tables are written -------------------------------------

TABLES = ("recordings.parquet", "snapshots.parquet", "summary.json", "report.md")


def _contents(out: Path) -> dict[str, bytes]:
    return {name: (out / name).read_bytes() for name in TABLES}


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_a_full_disk_while_the_tables_are_written_replaces_none_of_them(
    fleet: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import io

    out = tmp_path / "out"
    assert main(["batch", str(fleet / "robot_a"), "-o", str(out), "-q"]) == 0
    before = _contents(out)
    real_open = io.open

    def full_for_snapshots(file: Any, mode: str = "r", *args: Any, **kwargs: Any) -> Any:
        """Files opened to write snapshots.parquet (its temporary) go to /dev/full: every write
        fails with ENOSPC, from the kernel, after recordings.parquet was written."""
        name = Path(f"/proc/self/fd/{file}").readlink() if isinstance(file, int) else file
        if "w" in mode and "snapshots.parquet" in os.fsdecode(name):
            if isinstance(file, int):  # os.fdopen of a temporary created by os.open
                os.close(file)
            return real_open("/dev/full", "wb")
        return real_open(file, mode, *args, **kwargs)

    monkeypatch.setattr(io, "open", full_for_snapshots)
    # A second robot: the tables would change (two more recordings).
    assert main(["batch", str(fleet), "-o", str(out), "-q"]) == 1
    line = one_error_line(capsys.readouterr().err, out / "snapshots.parquet")
    assert line.endswith(
        ": cannot write (No space left on device)"
    )  # was "error: No space left..."
    assert _contents(out) == before  # recordings.parquet was replaced without its snapshots
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [*TABLES, "results", "w_over_time.png"]
    )  # no temporaries left
    # The recordings finished before the tables failed are kept: a re-run only writes the tables.
    monkeypatch.setattr(io, "open", real_open)
    again = run_batch([fleet], out)
    assert (again.processed, again.skipped) == (0, 5)
    assert len(pq.read_table(out / "recordings.parquet")) == 5


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_a_result_that_cannot_be_stored_names_its_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import errno
    import io

    from rose_logs.batch.store import OutputStore

    real_open = io.open

    def full(file: Any, mode: str = "r", *args: Any, **kwargs: Any) -> Any:
        if isinstance(file, int) or "w" in mode:  # the temporary, whichever way it is opened
            if isinstance(file, int):
                os.close(file)
            return real_open("/dev/full", "wb")
        return real_open(file, mode, *args, **kwargs)

    store = OutputStore(str(tmp_path / "out"))
    store.prepare()
    monkeypatch.setattr(io, "open", full)
    with pytest.raises(OSError, match=r"cannot write \(No space left on device\)") as info:
        store.write_bytes("results/key.json", b"{}")
    monkeypatch.setattr(io, "open", real_open)
    assert info.value.errno == errno.ENOSPC  # still an OSError: the batch retries or reports it
    assert info.value.filename == str(tmp_path / "out" / "results" / "key.json")
    assert list((tmp_path / "out" / "results").iterdir()) == []  # no temporary left


def test_a_failed_upload_of_a_table_restores_the_previous_objects(
    fleet: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import fsspec
    from fsspec.implementations.memory import MemoryFileSystem

    from rose_logs.batch import BatchError

    out = f"memory://rose-batch-test-{os.getpid()}/health"  # an object store without a server
    memory = fsspec.filesystem("memory")
    try:
        run_batch([fleet / "robot_a"], out)
        before = {name: memory.cat_file(f"{out}/{name}") for name in TABLES}
        real_pipe = MemoryFileSystem.pipe_file

        def failing_for_snapshots(self: object, path: str, *args: object, **kwargs: object) -> None:
            if path.endswith("snapshots.parquet"):
                raise ConnectionResetError(104, "Connection reset by peer")
            real_pipe(self, path, *args, **kwargs)  # type: ignore[arg-type]

        monkeypatch.setattr(MemoryFileSystem, "pipe_file", failing_for_snapshots)
        with pytest.raises(
            BatchError, match=r"snapshots\.parquet: cannot write \(Connection reset"
        ):
            run_batch([fleet], out)
        assert {name: memory.cat_file(f"{out}/{name}") for name in TABLES} == before
    finally:
        memory.rm(f"memory://rose-batch-test-{os.getpid()}", recursive=True)


@pytest.mark.parametrize("leftover", [False, True])
def test_an_output_folder_that_cannot_be_written_is_one_error_before_any_recording(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], leftover: bool
) -> None:
    out = tmp_path / "locked"
    out.mkdir()
    if leftover:  # a killed run's staging folder (writable itself) proves nothing about OUT
        (out / ".staging").mkdir()
    before = sorted(p.name for p in out.iterdir())
    # Immutable: refused even to root (the suite may run as root, for whom mode bits are no lock).
    if subprocess.run(["chattr", "+i", str(out)], capture_output=True).returncode != 0:
        pytest.skip("chattr +i is not available here")
    try:
        code = main(["batch", str(fleet / "robot_a" / "run.mcap"), "-o", str(out), "-q"])
    finally:
        subprocess.run(["chattr", "-i", str(out)], check=True)
    err = capsys.readouterr().err
    assert code == 1
    assert err.strip() == (
        f"error: {out}: cannot write to the output folder (Operation not permitted)"
    )
    assert sorted(p.name for p in out.iterdir()) == before


def test_an_output_that_is_a_file_is_named_so(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "afile"
    out.write_text("mine")
    assert main(["batch", str(fleet / "robot_a" / "run.mcap"), "-o", str(out), "-q"]) == 1
    assert capsys.readouterr().err.strip() == (
        f"error: {out}: not a folder (the output of a batch is a folder)"
    )
    assert out.read_text() == "mine"
    # A file where the results go is refused before any recording runs (it failed after them).
    out = tmp_path / "out"
    out.mkdir()
    (out / "results").write_text("mine")
    assert main(["batch", str(fleet / "robot_a" / "run.mcap"), "-o", str(out), "-q"]) == 1
    assert capsys.readouterr().err.strip() == (
        f"error: {out / 'results'}: not a folder (the batch keeps each recording's result in "
        "this folder)"
    )
    assert sorted(p.name for p in out.iterdir()) == ["results"]
    # ... and so is a dangling link there (writing into it failed after the recordings, too).
    (out / "results").unlink()
    (out / "results").symlink_to(tmp_path / "gone")
    assert main(["batch", str(fleet / "robot_a" / "run.mcap"), "-o", str(out), "-q"]) == 1
    assert "results: not a folder" in capsys.readouterr().err


def test_an_output_of_standard_output_is_refused_as_by_the_other_commands(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`-o -` made a folder named '-' in the current one; `convert LOG -` and `evaluate -` refuse
    it, as a folder output cannot go to standard output."""
    monkeypatch.chdir(tmp_path)
    assert main(["batch", str(fleet / "robot_a" / "run.mcap"), "-o", "-", "-q"]) == 1
    captured = capsys.readouterr()
    assert captured.err.strip() == "error: -: a folder output cannot go to a stream or device"
    assert captured.out == ""
    assert not (tmp_path / "-").exists()


def test_an_output_in_a_symlink_loop_is_not_called_a_bag_folder(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`-o loop` (a symlink loop) was refused as "a ROS 2 bag folder (it has metadata.yaml)"."""
    out = tmp_path / "loop"
    out.symlink_to(tmp_path / "loop2")
    (tmp_path / "loop2").symlink_to(out)
    assert main(["batch", str(fleet / "robot_a" / "run.mcap"), "-o", str(out), "-q"]) == 1
    err = capsys.readouterr().err
    assert err.strip() == f"error: {out}: not a folder (the output of a batch is a folder)"
