"""Throughput of ``rose-bag batch``: a generated fleet with --workers 1 and --workers 2, same run.

Run: python benchmarks/bench_batch.py [--recordings 40] [--keep DIR]. Builds a fleet from the bundled
sample session (mcap files, db3 and mcap bag folders; 1 to 14 growing Freiburg 079 maps each), then
processes it in-process (--workers 1, with one and with two analysis threads) and on a local Dask
cluster of 2 workers (one thread each), and prints
recordings/s, snapshots/s, the speed-up, the cluster's fixed start-up (start + first task on each
worker) and the load average (the machine may be shared). Speed-ups are given end to end and in the
steady state: snapshots per second from the first finished recording to the last, which leaves out
the fixed start-up (printed on its own) and the final tables.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from rose_logs.batch import run_batch
from rose_logs.batch.cluster import local_client
from rose_logs.batch.task import RecordingOptions
from rose_logs.cli.options import hold_opencv_to_one_thread
from rose_logs.malloc import MALLOC_ENV, keep_arrays_on_heap
from rose_logs.reader import LogReader
from rose_logs.writer import open_output

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "fr079_session.mcap"
FORMATS = ("mcap", "db3", "mcap-dir")
SUFFIX = {"mcap": ".mcap", "db3": "", "mcap-dir": ""}


def copy_maps(destination: Path, fmt: str, max_maps: int) -> None:
    """The sample session up to its ``max_maps``-th map, in ``fmt``."""
    destination.parent.mkdir(parents=True, exist_ok=True)
    with (
        LogReader(SAMPLE) as reader,
        open_output(destination, fmt, serialization=reader.serialization) as out,
    ):
        handles = {c.id: out.add_channel(c) for c in reader.channels}
        maps = 0
        for message in reader.messages():
            if message.channel.topic == "/map":
                if maps == max_maps:
                    break
                maps += 1
            out.write_raw(handles[message.channel.id], message.log_time_ns, message.data)


def build_fleet(root: Path, count: int) -> None:
    for i in range(count):
        fmt = FORMATS[i % len(FORMATS)]
        maps = 1 + (i * 5) % 14  # 1..14 maps, mixed
        copy_maps(root / f"robot{i % 4}" / f"run{i:03d}{SUFFIX[fmt]}", fmt, maps)


def _ready() -> int:
    import rose_logs.batch.task  # noqa: F401 - what the first task imports

    return os.getpid()


def startup_s(workers: int) -> float:
    """Seconds from nothing to a local cluster whose workers have imported the task code."""
    start = time.perf_counter()
    with local_client(workers) as client:
        client.run(_ready)
        return time.perf_counter() - start


@dataclass(frozen=True)
class Run:
    """One batch run: end to end, and its steady state (first to last finished recording)."""

    elapsed_s: float
    recordings: int
    snapshots: int
    task_cpu_s: float
    steady_s: float  # from the first finished recording to the last
    steady_snapshots: int  # snapshots of the recordings finished in that span

    @property
    def steady_rate(self) -> float:
        """Snapshots per second once running: start-up and the final tables left out."""
        return self.steady_snapshots / self.steady_s


def measure(fleet: Path, out: Path, workers: int, *, analysis_threads: int = 2) -> Run:
    finished: list[tuple[float, int]] = []

    def on_result(result: object, done: int, total: int) -> None:
        finished.append((time.perf_counter(), len(getattr(result, "snapshots", ()))))

    start = time.perf_counter()
    options = RecordingOptions(analysis_threads=analysis_threads)
    report = run_batch(
        [fleet], out, workers=workers, force=True, options=options, on_result=on_result
    )
    elapsed = time.perf_counter() - start
    snapshots = sum(len(r.snapshots) for r in report.results)
    errors = len(report.errors)
    task_s = sum(r.cpu_seconds for r in report.results)
    if errors:
        print(f"  {errors} recordings failed: {report.errors[0].error}")
    steady_s = finished[-1][0] - finished[0][0]
    steady_snapshots = sum(count for _, count in finished[1:])
    return Run(elapsed, len(report.results), snapshots, task_s, steady_s, steady_snapshots)


_CPU_RUN = """
import json, sys
from rose_logs.batch import run_batch
report = run_batch([sys.argv[1]], sys.argv[2], force=True, write_tables=False)
print(json.dumps(sum(r.cpu_seconds for r in report.results)))
"""


def malloc_comparison(fleet: Path, work: Path) -> None:
    """Task CPU of the fleet, in-process, under three malloc settings (each in a fresh process)."""
    settings = {
        "glibc default": {},
        "Dask's MALLOC_TRIM_THRESHOLD_=65536": {"MALLOC_TRIM_THRESHOLD_": "65536"},
        "ours (rose_logs.malloc)": MALLOC_ENV,
    }
    base = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    for label, extra in settings.items():
        out = work / f"malloc-{len(extra)}"
        result = subprocess.run(
            [sys.executable, "-c", _CPU_RUN, str(fleet), str(out)],
            env={**base, **extra},
            capture_output=True,
            text=True,
            check=True,
        )
        cpu_s = json.loads(result.stdout.strip().splitlines()[-1])
        print(f"  task CPU with {label:<38} {cpu_s:6.2f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recordings", type=int, default=40)
    parser.add_argument("--keep", type=Path, default=None, help="build the fleet here and keep it")
    parser.add_argument(
        "--malloc", action="store_true", help="also compare malloc settings (task CPU, in-process)"
    )
    args = parser.parse_args()
    # As the rose-bag command does (the Dask workers get the same settings): the in-process runs
    # measure what users get.
    keep_arrays_on_heap()
    hold_opencv_to_one_thread()  # as `rose-bag batch --workers 1` does (the workers hold it too)
    work = Path(tempfile.mkdtemp(prefix="bench-batch-"))
    try:
        fleet = args.keep or work / "fleet"
        if not fleet.exists():
            build_fleet(fleet, args.recordings)
        print(f"fleet: {args.recordings} recordings ({', '.join(FORMATS)}), {fleet}")
        print(f"load average before: {os.getloadavg()}, {os.cpu_count()} cores")
        rows = {}
        # In-process with one analysis thread is the one-core baseline; in-process by default
        # analyses two snapshots at once; Dask workers run one thread each.
        runs = {"1, one thread": (1, 1), "1": (1, 2), "2": (2, 1)}
        for label, (workers, threads) in runs.items():
            run = measure(fleet, work / f"out{len(rows)}", workers, analysis_threads=threads)
            rows[label] = run
            print(
                f"--workers {label:<13} {run.elapsed_s:6.2f} s  "
                f"{run.recordings / run.elapsed_s:6.2f} recordings/s  "
                f"{run.snapshots / run.elapsed_s:6.1f} snapshots/s  "
                f"steady {run.steady_rate:6.1f} snapshots/s  "
                f"(task CPU {run.task_cpu_s:.2f} s, {run.snapshots} snapshots)"
            )
        one, inproc, two = rows["1, one thread"], rows["1"], rows["2"]
        print(
            f"speed-up with 2 workers, end to end: {one.elapsed_s / two.elapsed_s:.2f}x over one "
            f"thread, {inproc.elapsed_s / two.elapsed_s:.2f}x over in-process (two analysis "
            "threads)"
        )
        print(
            f"speed-up with 2 workers, steady state (start-up and tables left out): "
            f"{two.steady_rate / one.steady_rate:.2f}x over one thread, "
            f"{two.steady_rate / inproc.steady_rate:.2f}x over in-process"
        )
        print(f"local cluster start-up (2 workers, code imported): {startup_s(2):.2f} s")
        if args.malloc:
            print("malloc settings, the same fleet in-process:")
            malloc_comparison(fleet, work)
        print(f"load average after: {os.getloadavg()}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
