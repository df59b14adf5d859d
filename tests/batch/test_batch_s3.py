"""rose_logs.batch against S3: a moto server on 127.0.0.1 holds the inputs and the outputs."""

from __future__ import annotations

import io
import json
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq
import pytest

from rose_logs.batch import BatchError, RecordingOptions, run_batch
from rose_logs.cli import main

pytest.importorskip("s3fs")
moto_server = pytest.importorskip("moto.server")

BUCKET = "fleet-logs"


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@pytest.fixture
def s3(monkeypatch: pytest.MonkeyPatch) -> Iterator[dict[str, Any]]:
    """Storage options of an empty bucket on a moto server (a fresh server per test)."""
    import s3fs

    for name in ("AWS_PROFILE", "AWS_CONFIG_FILE", "AWS_SHARED_CREDENTIALS_FILE"):
        monkeypatch.delenv(name, raising=False)
    port = free_port()
    server = moto_server.ThreadedMotoServer(ip_address="127.0.0.1", port=port)
    server.start()
    options = {
        "endpoint_url": f"http://127.0.0.1:{port}",
        "key": "testing",
        "secret": "testing",
        "client_kwargs": {"region_name": "us-east-1"},
    }
    try:
        import boto3

        boto3.client(
            "s3",
            endpoint_url=options["endpoint_url"],
            aws_access_key_id="testing",
            aws_secret_access_key="testing",
            region_name="us-east-1",
        ).create_bucket(Bucket=BUCKET)
        yield options
    finally:
        s3fs.S3FileSystem.clear_instance_cache()
        server.stop()


def test_inputs_and_outputs_in_a_bucket(fleet: Path, s3: dict[str, Any]) -> None:
    import s3fs

    fs = s3fs.S3FileSystem(**s3)
    fs.put(str(fleet) + "/", f"{BUCKET}/robots/", recursive=True)
    out = f"s3://{BUCKET}/health"
    report = run_batch(
        [f"s3://{BUCKET}/robots/"], out, storage_options=s3, options=RecordingOptions(cleaned=True)
    )
    uris = [r.uri for r in report.results]
    assert uris == [
        f"s3://{BUCKET}/robots/robot_a/later.db3",
        f"s3://{BUCKET}/robots/robot_a/run.mcap",
        f"s3://{BUCKET}/robots/robot_b/bag_dir",
        f"s3://{BUCKET}/robots/robot_b/nested/small.mcap",
        f"s3://{BUCKET}/robots/robot_b/run.mcap",
    ]
    assert [r.status for r in report.results] == ["ok"] * 5
    recordings = pq.read_table(io.BytesIO(fs.cat_file(f"{BUCKET}/health/recordings.parquet")))
    assert recordings.column("uri").to_pylist() == uris
    assert recordings.column("broke").to_pylist() == [False, False, False, False, True]
    snapshots = pq.read_table(io.BytesIO(fs.cat_file(f"{BUCKET}/health/snapshots.parquet")))
    assert snapshots.num_rows == 15
    summary = json.loads(fs.cat_file(f"{BUCKET}/health/summary.json"))
    assert summary["broken"] == 1
    assert fs.exists(f"{BUCKET}/health/report.md")
    # Cleaned logs mirror the input names under the output prefix, bag folders included.
    assert fs.exists(f"{BUCKET}/health/cleaned/robots/robot_a/run.mcap")
    assert fs.exists(f"{BUCKET}/health/cleaned/robots/robot_b/bag_dir/metadata.yaml")
    # A second run finds every result by its key (URI, size, ETag, options) and skips it.
    again = run_batch(
        [f"s3://{BUCKET}/robots/"], out, storage_options=s3, options=RecordingOptions(cleaned=True)
    )
    assert (again.processed, again.skipped) == (0, 5)


def test_cli_storage_options_and_a_corrupt_object(
    fleet: Path, s3: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    import s3fs

    fs = s3fs.S3FileSystem(**s3)
    fs.put(str(fleet / "robot_a" / "run.mcap"), f"{BUCKET}/in/run.mcap")
    fs.pipe_file(f"{BUCKET}/in/cut.mcap", (fleet / "robot_a" / "run.mcap").read_bytes()[:5000])
    argv = [
        "batch",
        f"s3://{BUCKET}/in/",
        "-o",
        f"s3://{BUCKET}/out",
        "-q",
        "--storage-option",
        f"endpoint_url={s3['endpoint_url']}",
        "--storage-option",
        "key=testing",
        "--storage-option",
        "secret=testing",
        # JSON values as JSON: s3fs wants a number and a dict here (a string failed)
        "--storage-option",
        "max_concurrency=2",
        "--storage-option",
        'client_kwargs={"region_name": "us-east-1"}',
        "--max-errors",
        "1",
    ]
    assert main(argv) == 0
    rows = pq.read_table(io.BytesIO(fs.cat_file(f"{BUCKET}/out/recordings.parquet"))).to_pylist()
    assert [(r["name"], r["status"]) for r in rows] == [
        ("in/cut.mcap", "error"),
        ("in/run.mcap", "ok"),
    ]
    # The row names the object, not the downloaded copy (gone by the time anyone reads it).
    assert rows[0]["error"].startswith(f"s3://{BUCKET}/in/cut.mcap: ")
    assert "rose-batch-" not in rows[0]["error"]


def test_a_misspelt_storage_option_is_a_one_line_error(
    fleet: Path, s3: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    import s3fs

    s3fs.S3FileSystem(**s3).put(str(fleet / "robot_a" / "run.mcap"), f"{BUCKET}/in/run.mcap")
    argv = ["batch", f"s3://{BUCKET}/in/", "-o", f"s3://{BUCKET}/out", "-q"]
    argv += ["--storage-option", f"endpoint_url={s3['endpoint_url']}"]
    argv += ["--storage-option", "key=testing", "--storage-option", "secret=testing"]
    argv += ["--storage-option", "endpont_url=http://typo"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: s3://{BUCKET}/in/: cannot use the storage (TypeError: ")
    assert "endpont_url" in err and "Traceback" not in err


def test_a_mistyped_output_bucket_is_an_error_and_is_not_created(
    fleet: Path, s3: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    import s3fs

    argv = ["batch", str(fleet / "robot_a" / "run.mcap"), "-o", "s3://no-such-bucket/out", "-q"]
    argv += ["--storage-option", f"endpoint_url={s3['endpoint_url']}"]
    argv += ["--storage-option", "key=testing", "--storage-option", "secret=testing"]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err == (
        "error: s3://no-such-bucket/out: the bucket 'no-such-bucket' does not exist "
        "(it is not created for you)"
    )
    assert not s3fs.S3FileSystem(**s3).exists("no-such-bucket")


@pytest.mark.parametrize("side", ["input", "output"])
def test_an_unreachable_endpoint_is_a_one_line_error(
    fleet: Path, side: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("AWS_ACCESS_KEY_ID", "testing")
    monkeypatch.setenv("AWS_SECRET_ACCESS_KEY", "testing")
    monkeypatch.setenv("AWS_DEFAULT_REGION", "us-east-1")
    nowhere = f"http://127.0.0.1:{free_port()}"  # nothing listens there
    local_in, local_out = str(fleet / "robot_a" / "run.mcap"), str(fleet.parent / "out")
    source, out = ("s3://b/in/", local_out) if side == "input" else (local_in, "s3://b/out")
    with pytest.raises(BatchError) as caught:
        run_batch(
            [source],
            out,
            storage_options={
                "endpoint_url": nowhere,
                "config_kwargs": {"retries": {"max_attempts": 1}, "connect_timeout": 1},
            },
        )
    text = str(caught.value)
    assert "\n" not in text
    assert text.startswith(f"{source if side == 'input' else out}: cannot use the storage (")
    assert "EndpointConnectionError" in text
    assert not Path(local_out).exists()


def test_denied_access_to_the_output_bucket_is_not_called_a_missing_bucket(
    fleet: Path,
    s3: dict[str, Any],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import moto.settings

    # From now on the server checks credentials: the fixture's "testing" keys are nobody's.
    monkeypatch.setattr(moto.settings, "INITIAL_NO_AUTH_ACTION_COUNT", 0)
    argv = ["batch", str(fleet / "robot_a" / "run.mcap"), "-o", f"s3://{BUCKET}/out", "-q"]
    argv += ["--storage-option", f"endpoint_url={s3['endpoint_url']}"]
    argv += ["--storage-option", "key=testing", "--storage-option", "secret=testing"]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: s3://{BUCKET}/out: access to the bucket '{BUCKET}' denied (")
    assert "\n" not in err
