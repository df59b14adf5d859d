"""Live viewing: ``--connect ADDR`` streams the session to a viewer that is already running.

The "viewer" is Rerun's own gRPC receiver (``rerun --save FILE --port P`` on 127.0.0.1), which writes
what arrives to a file: every snapshot must get there while the session is processed. Skipped
without the ``rerun`` executable (it comes with rerun-sdk); ``ROSE_REQUIRE_VIEWER=1`` fails instead.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest

from rose_logs.rerun.screenshots import session_times_ns
from rose_logs.session import process_log

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"

if os.environ.get("ROSE_REQUIRE_VIEWER") != "1":
    pytestmark = pytest.mark.skipif(
        shutil.which("rerun") is None, reason="no rerun executable on PATH (pip install rerun-sdk)"
    )


def _rerun_executable() -> str:
    """The Rerun binary itself. ``rerun`` on PATH is rerun_cli's Python wrapper, which on SIGINT waits
    0.25 s for the binary (that never got the signal) and then SIGKILLs it: the receiver would not
    finish its file, and whatever it had not written yet would be lost."""
    try:
        import rerun_cli
    except ImportError:
        return "rerun"
    binary = Path(rerun_cli.__file__).parent / "rerun"
    return str(binary) if binary.is_file() else "rerun"


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _wait_listening(port: int, process: subprocess.Popen[bytes], timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert process.poll() is None, "the receiving viewer exited"
        with socket.socket() as sock:
            if sock.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.1)
    pytest.fail(f"nothing listens on port {port} after {timeout_s} s")


def _wait_received(path: Path, snapshots: int, timeout_s: float = 30.0) -> None:
    """Until the receiver's file holds ``snapshots`` snapshots (or ``timeout_s``: then the test's
    assertion says what arrived)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            if len(session_times_ns(path)) >= snapshots:
                return
        except Exception:  # not written yet, or cut mid-record: look again
            pass
        time.sleep(0.2)


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # the receiver writes the stream form
def test_connect_streams_every_snapshot_to_a_running_viewer(tmp_path: Path) -> None:
    port = _free_port()
    received = tmp_path / "received.rrd"
    viewer = subprocess.Popen(
        [_rerun_executable(), "--save", str(received), "--port", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        _wait_listening(port, viewer)
        report = process_log(SAMPLE, connect=f"127.0.0.1:{port}")
        # Our side has flushed; the receiver may still be writing what it got. A Ctrl-C before
        # that drops it (seen once on a loaded machine): give it time to write every snapshot.
        _wait_received(received, len(report.records))
    finally:
        viewer.send_signal(signal.SIGINT)  # the receiver finishes its file on Ctrl-C
        try:
            viewer.wait(timeout=30)
        except subprocess.TimeoutExpired:
            viewer.kill()
            raise
    assert report.rrd_path is None  # nothing saved by us: the data went to the viewer
    assert len(session_times_ns(received)) == len(report.records) == 14
