"""rose_logs.batch on Dask (127.0.0.1 only): local cluster, existing cluster, dead workers."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import pyarrow.parquet as pq
import pytest

from rose_logs.batch import RecordingOptions, discover, result_key, run_batch
from rose_logs.cli import main

distributed = pytest.importorskip("distributed")

REPO = Path(__file__).resolve().parents[2]
TIMING = {"seconds", "cpu_seconds"}


def rows_without_timing(path: Path) -> list[dict[str, Any]]:
    return [
        {k: v for k, v in row.items() if k not in TIMING} for row in pq.read_table(path).to_pylist()
    ]


@pytest.fixture(scope="module")
def serial_out(fleet_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The fleet processed in this process: the reference of the Dask runs."""
    out = tmp_path_factory.mktemp("serial") / "out"
    report = run_batch([fleet_dir], out)
    assert {r.worker for r in report.results} == {f"{socket.gethostname()}:{os.getpid()}"}
    return out


def test_local_cluster_of_two_workers_equals_in_process(
    fleet_dir: Path, tmp_path: Path, serial_out: Path
) -> None:
    parallel = run_batch([fleet_dir], tmp_path / "parallel", workers=2)
    for table in ("recordings.parquet", "snapshots.parquet"):
        assert rows_without_timing(tmp_path / "parallel" / table) == rows_without_timing(
            serial_out / table
        )
    for name in ("summary.json", "report.md"):
        assert (tmp_path / "parallel" / name).read_bytes() == (serial_out / name).read_bytes()
    workers = {r.worker for r in parallel.results}
    assert len(workers) == 2  # two distinct worker processes did work...
    assert not any(w.endswith(f":{os.getpid()}") for w in workers)  # ... none of them this one


# ---- an existing cluster: dask scheduler + 2 dask workers as subprocesses ---------------------------


@pytest.fixture
def external_cluster(tmp_path: Path) -> Iterator[tuple[str, Path]]:
    """``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1: (address, scheduler file)."""
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
    }
    scheduler_file = tmp_path / "scheduler.json"
    common = ["--no-dashboard", "--host", "127.0.0.1"]
    processes = [
        subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--port", "0", *common,
             "--scheduler-file", str(scheduler_file)],
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )
    ]  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while not scheduler_file.exists():
            if time.monotonic() > deadline:
                pytest.fail("dask scheduler did not start")
            time.sleep(0.1)
        address = json.loads(scheduler_file.read_text())["address"]
        processes += [
            subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                 "--nworkers", "1", *common],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            )
            for _ in range(2)
        ]  # fmt: skip
        with distributed.Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=90)
        yield address, scheduler_file
    finally:
        for process in reversed(processes):
            os.kill(process.pid, signal.SIGTERM)
        for process in processes:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.kill(process.pid, signal.SIGKILL)
                process.wait()


def test_existing_cluster_by_address_and_scheduler_file(
    fleet_dir: Path, tmp_path: Path, external_cluster: tuple[str, Path], serial_out: Path
) -> None:
    address, scheduler_file = external_cluster
    out = tmp_path / "out"
    code = main(["batch", str(fleet_dir), "-o", str(out), "-q", "--scheduler", address])
    assert code == 0
    assert rows_without_timing(out / "recordings.parquet") == rows_without_timing(
        serial_out / "recordings.parquet"
    )
    results = [json.loads(p.read_text()) for p in sorted((out / "results").glob("*.json"))]
    assert len({r["worker"] for r in results}) == 2
    with distributed.Client(address, timeout="30s") as client:
        # Workers we did not start are tuned in place: they share the cores, one OpenCV thread each.
        assert set(client.run(cv2.getNumThreads).values()) == {1}
    one = fleet_dir / "robot_a" / "run.mcap"
    argv = [
        "batch",
        str(one),
        "-o",
        str(tmp_path / "one"),
        "-q",
        "--scheduler-file",
        str(scheduler_file),
    ]
    assert main(argv) == 0
    (result,) = [json.loads(p.read_text()) for p in (tmp_path / "one" / "results").glob("*.json")]
    assert result["status"] == "ok"
    assert result["worker"] in {r["worker"] for r in results}


# ---- faults: a worker killed mid-task, a memory limit exceeded -------------------------------------


@pytest.fixture(scope="module")
def fragile_client() -> Iterator[Any]:
    """Two local workers, 600 MB each, no retries after a worker death."""
    from rose_logs.batch.cluster import local_client

    with local_client(2, memory_limit="600MB", retries=0) as client:
        yield client


def test_local_workers_run_opencv_on_one_thread(fragile_client: Any) -> None:
    # Before any task: the workers start with it (OpenCV would otherwise use every core in each
    # worker, and two workers on two cores spent a third more CPU).
    if (os.cpu_count() or 1) < 2:
        pytest.skip("one core: OpenCV's default is one thread already, nothing to tell apart")
    assert set(fragile_client.run(cv2.getNumThreads).values()) == {1}


def _a_retry_warning_as_printed() -> str:
    """On a worker: what a recording's retry warning (``process_recording``'s) prints on stderr."""
    import io
    import logging

    saved, sys.stderr = sys.stderr, io.StringIO()
    try:
        logging.getLogger("rose_logs.batch.task").warning(
            "%s: %s (attempt %d of %d, retrying)", "/fleet/run.mcap", "[Errno 5] I/O error", 1, 3
        )
        return sys.stderr.getvalue()
    finally:
        sys.stderr = saved


def test_a_workers_retry_warning_is_a_warning_line(fragile_client: Any) -> None:
    # A worker process has no handler for rose_logs' warnings: Python's last resort printed the
    # bare message, the one line of the batch without the warning: prefix.
    from rose_logs.batch.workerenv import tune_worker_process

    fragile_client.run(tune_worker_process)  # as the batch does before its first task
    printed = set(fragile_client.run(_a_retry_warning_as_printed).values())
    assert printed == {"warning: /fleet/run.mcap: [Errno 5] I/O error (attempt 1 of 3, retrying)\n"}


def _kill_when_running(client: Any, task_key: str, done: threading.Event) -> None:
    pids = client.run(os.getpid)
    deadline = time.monotonic() + 120
    while not done.is_set() and time.monotonic() < deadline:
        for address, keys in client.processing().items():
            if task_key in keys:
                time.sleep(0.3)  # let it get going
                os.kill(pids[address], signal.SIGKILL)
                return
        time.sleep(0.02)


def test_a_worker_killed_mid_task_is_an_error_row(
    fleet: Path, long_recording: Path, tmp_path: Path, fragile_client: Any
) -> None:
    inputs = [long_recording, fleet / "robot_a" / "run.mcap"]
    long_key = result_key(discover([long_recording])[0], RecordingOptions(retries=0))
    done = threading.Event()
    killer = threading.Thread(
        target=_kill_when_running, args=(fragile_client, f"rose-bag-{long_key}", done)
    )
    killer.start()
    try:
        report = run_batch(
            inputs, tmp_path / "out", client=fragile_client, options=RecordingOptions(retries=0)
        )
    finally:
        done.set()
        killer.join()
    by_name = {r.name: r for r in report.results}
    assert by_name["long.mcap"].status == "error"
    assert "worker" in by_name["long.mcap"].error
    assert by_name["run.mcap"].status == "ok"
    # Not stored (it was, so a re-run with a higher memory limit reported the old death again):
    # the next run tries it again; the other recording's result is kept.
    stored = {p.name for p in (tmp_path / "out" / "results").iterdir()}
    assert stored == {f"{by_name['run.mcap'].key}.json"}


def test_a_recording_over_the_memory_limit_is_an_error_row(
    fleet: Path, big_recording: Path, tmp_path: Path, fragile_client: Any
) -> None:
    # Both workers up (the previous test killed one; its nanny restarts it): with one worker, the
    # small recording queued behind the big one dies with it (seen once on a loaded machine).
    fragile_client.wait_for_workers(2, timeout=120)
    inputs = [big_recording, fleet / "robot_b" / "nested" / "small.mcap"]
    report = run_batch(
        inputs,
        tmp_path / "out",
        client=fragile_client,
        memory_limit="600MB",
        options=RecordingOptions(retries=0),
    )
    by_name = {r.name: r for r in report.results}
    assert by_name["big.mcap"].status == "error"
    assert "died" in by_name["big.mcap"].error
    assert by_name["big.mcap"].error.startswith(f"{by_name['big.mcap'].uri}: ")
    assert "600MB" in by_name["big.mcap"].error
    assert by_name["small.mcap"].status == "ok"


def test_tearing_a_cluster_down_quiets_every_dask_and_tornado_logger() -> None:
    """distributed.client and tornado.application have levels of their own: quieting only their
    parents left their ERROR lines (tracebacks after Ctrl-C) on the terminal."""
    import logging

    import distributed  # noqa: F401 - configures its loggers

    from rose_logs.batch.cluster import _dask_quiet

    chatty = [logging.getLogger(n) for n in ("distributed.client", "tornado.application")]
    logging.getLogger("tornado.application").setLevel(logging.ERROR)
    assert all(logger.isEnabledFor(logging.ERROR) for logger in chatty)
    with _dask_quiet():
        assert not any(logger.isEnabledFor(logging.ERROR) for logger in chatty)
    assert all(logger.isEnabledFor(logging.ERROR) for logger in chatty)
