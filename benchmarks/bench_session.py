"""Benchmark ``rose-bag process`` on a long synthetic-timeline session of a growing real map.

The session: ``--snapshots`` maps (default 720, one hour at one map every 5 s) of ``--size`` x ``--size``
cells, cut from the Freiburg 079 exploration stages map2 .. map15 in order (each snapshot differs from
the previous one, so no result is reused; with ``--growing`` each cut around its known cells, the grid
growing as a SLAM map's does), plus ``sensor_msgs/LaserScan`` traffic at ``--scan-hz`` and, with ``--camera-hz``, 640 x 480 RGB
``sensor_msgs/Image`` messages (a log whose copying outweighs its maps: ``--snapshots 10 --period 10
--camera-hz 30`` is 3,000 images, 0.9 GB).

Reports, in the same run: the time of a plain raw copy of the log (read + write every message, no ROSE),
the time of ``process_log`` (copy + ROSE + derived topics, optionally + Rerun), snapshots per second and
their ratio. Prints numbers, asserts nothing.

Usage::

    python benchmarks/bench_session.py [--snapshots 720] [--size 1000] [--growing] [--rrd] [--walls]
        [--clean-method walls|paper] [--format mcap] [--camera-hz 0] [--keep DIR]

With ``--rrd`` it also prints the recording's size and the Rerun loggers' own cost per snapshot.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import resource
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

import cv2
import numpy as np

import rose
from rose.cleaning import CleanMethod
from rose_logs.derived import encode_cleaned
from rose_logs.malloc import keep_arrays_on_heap
from rose_logs.reader import LogReader
from rose_logs.session import process_log
from rose_logs.snapshots import MapSnapshot
from rose_logs.writer import LogWriter, open_output

#: The Freiburg 079 stages committed with the tests (see tests/data/README.md).
MAPS = (
    Path(__file__).resolve().parents[1]
    / "tests"
    / "data"
    / "rose2_aislabunimi"
    / "Freiburg_Building_079_partial"
)
START_NS = 1_700_000_000 * 1_000_000_000


class ThreadCpu:
    """CPU seconds per thread of this process while the block runs (Linux ``/proc``; empty elsewhere).

    Pool threads end with the session, so their times are sampled every ``period_s`` and the last
    sample of each kept; Python threads are named by their name's prefix (``rose-analyse_0`` ->
    ``rose-analyse``), the native ones (Rerun's) by their kernel name.
    """

    def __init__(self, period_s: float = 0.2) -> None:
        self.period_s = period_s
        self.seconds: dict[int, tuple[str, float]] = {}
        self._start: dict[int, tuple[str, float]] = {}
        self._names: dict[int, str] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="bench-sampler", daemon=True)

    def __enter__(self) -> ThreadCpu:
        self._start = self._sample()
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
        self.seconds = self._sample()

    def _run(self) -> None:
        while not self._stop.wait(self.period_s):
            self.seconds = self._sample()

    def _sample(self) -> dict[int, tuple[str, float]]:
        for thread in threading.enumerate():
            if thread.native_id is not None:
                self._names[thread.native_id] = thread.name.split("_")[0]
        tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
        out = dict(self.seconds)
        try:
            tasks = list(Path("/proc/self/task").iterdir())
        except OSError:
            return out
        for task in tasks:
            tid = int(task.name)
            try:
                comm = (task / "comm").read_text().strip()
                fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:  # the thread ended
                continue
            # utime and stime, fields 14 and 15 of stat (11 and 12 after the name).
            out[tid] = (
                self._names.get(tid, comm),
                (int(fields[11]) + int(fields[12])) / tick,
            )
        return out

    def by_name(self) -> list[tuple[str, float]]:
        """``(thread name, CPU seconds inside the block)``, largest first."""
        totals: dict[str, float] = {}
        for tid, (name, seconds) in self.seconds.items():
            before = self._start.get(tid, (name, 0.0))[1]
            if name != "bench-sampler":
                totals[name] = totals.get(name, 0.0) + seconds - before
        return sorted(totals.items(), key=lambda item: -item[1])


def stages(size: int) -> list[np.ndarray]:
    """The 14 exploration stages, centre-cropped / padded with unknown to ``size`` x ``size``."""
    out = []
    for n in range(2, 16):
        grid = rose.load_map(MAPS / f"map{n}.yaml").grid
        canvas = np.full((size, size), -1, dtype=np.int8)
        h, w = grid.shape
        gy, gx = max((h - size) // 2, 0), max((w - size) // 2, 0)
        cy, cx = max((size - h) // 2, 0), max((size - w) // 2, 0)
        hh, ww = min(h, size), min(w, size)
        canvas[cy : cy + hh, cx : cx + ww] = grid[gy : gy + hh, gx : gx + ww]
        out.append(canvas)
    return out


#: Unknown cells around a growing map's known ones, as SLAM maps keep a margin (2 m at 0.05 m).
GROWING_MARGIN = 40


def growing_maps(snapshots: int) -> list[tuple[np.ndarray, tuple[int, int]]]:
    """The 14 exploration stages as a SLAM map that grows: each snapshot's grid is its stage cut to
    a box around the known cells (and ``GROWING_MARGIN`` of unknown), the box growing smoothly
    from one stage's to the next over the snapshots of a stage, so the grid's shape changes by a
    few cells every ten snapshots or so (64 shapes in 720, about 400 x 900 cells), as the maps
    slam_toolbox or Cartographer publish change theirs. With
    each grid, where its cell (0, 0) lies in the stage's (rows, columns): its origin moves with
    it, so a cell stays where it is in the map frame."""
    grids = [rose.load_map(MAPS / f"map{n}.yaml").grid for n in range(2, 16)]
    boxes = []
    for grid in grids:
        rows, cols = np.nonzero(grid >= 0)
        boxes.append(np.array([rows.min(), cols.min(), rows.max() + 1, cols.max() + 1]))
    out = []
    for i in range(snapshots):
        at = i * len(grids) / snapshots
        stage = min(int(at), len(grids) - 1)
        toward = boxes[min(stage + 1, len(grids) - 1)]
        r0, c0, r1, c1 = np.rint(boxes[stage] + (at - stage) * (toward - boxes[stage])).astype(int)
        grid = grids[stage]
        canvas = np.full(
            (r1 - r0 + 2 * GROWING_MARGIN, c1 - c0 + 2 * GROWING_MARGIN), -1, dtype=np.int8
        )
        # The known part of the box (a box grown toward the next stage may reach beyond this one's
        # cells: unknown there).
        canvas[
            GROWING_MARGIN : GROWING_MARGIN + r1 - r0, GROWING_MARGIN : GROWING_MARGIN + c1 - c0
        ] = grid[r0:r1, c0:c1]
        out.append((canvas, (int(r0) - GROWING_MARGIN, int(c0) - GROWING_MARGIN)))
    return out


def build(
    path: Path,
    fmt: str,
    *,
    snapshots: int,
    size: int,
    period_s: float,
    scan_hz: float,
    camera_hz: float = 0.0,
    growing: bool = False,
) -> int:
    """Write the session; returns the number of messages. ``growing``: a map that grows
    (:func:`growing_maps`), one grid per snapshot, instead of the stages at ``size`` x ``size``."""
    maps = growing_maps(snapshots) if growing else [(grid, (0, 0)) for grid in stages(size)]
    period_ns = round(period_s * 1e9)
    scan_ns = round(1e9 / scan_hz) if scan_hz > 0 else 0
    camera_ns = round(1e9 / camera_hz) if camera_hz > 0 else 0
    rng = np.random.default_rng(0)
    count = 0
    with open_output(path, fmt, force=True) as out:
        types = out.typestore.types
        out.add_topic("/map", "nav_msgs/msg/OccupancyGrid", latching=True)
        if scan_ns:
            out.add_topic("/scan", "sensor_msgs/msg/LaserScan")
        if camera_ns:
            out.add_topic("/camera/image_raw", "sensor_msgs/msg/Image")
        ranges = rng.uniform(0.5, 20.0, (64, 360)).astype(np.float32)
        # Dim noise compresses about as much as a camera's images do (zstd: 0.7 of their size).
        image = rng.integers(0, 40, (480, 640, 3), dtype=np.uint8)
        for i in range(snapshots):
            t_map = START_NS + (i + 1) * period_ns
            stage, (row0, col0) = maps[
                i if growing else min(i * len(maps) // snapshots, len(maps) - 1)
            ]
            grid = stage.copy()
            row = i % grid.shape[0]
            grid[row, 0] = 100 - grid[row, 0] if grid[row, 0] >= 0 else 0  # always differs
            origin = (-25.0 + 0.05 * col0, -25.0 + 0.05 * row0, 0.0)  # row 0 = the origin's
            snap = MapSnapshot("/map", t_map, t_map, "map", grid, 0.05, origin)
            # In log-time order, as a recorder writes: the interval's scans and images, then its
            # map.
            interval = range(t_map - period_ns, t_map)
            sensors = sorted(
                [(t, "/scan") for t in (interval[scan_ns::scan_ns] if scan_ns else ())]
                + [
                    (t, "/camera/image_raw")
                    for t in (interval[camera_ns::camera_ns] if camera_ns else ())
                ]
            )
            for t, topic in sensors:
                stamp = types["builtin_interfaces/msg/Time"](
                    sec=t // 1_000_000_000, nanosec=t % 1_000_000_000
                )
                ros1 = {"seq": 0} if out.serialization == "ros1" else {}
                if topic == "/scan":
                    header = types["std_msgs/msg/Header"](**ros1, stamp=stamp, frame_id="laser")
                    message = types["sensor_msgs/msg/LaserScan"](
                        header=header,
                        angle_min=-np.pi,
                        angle_max=np.pi,
                        angle_increment=2 * np.pi / 360,
                        time_increment=0.0,
                        scan_time=0.1,
                        range_min=0.1,
                        range_max=30.0,
                        ranges=ranges[count % 64],
                        intensities=np.zeros(0, dtype=np.float32),
                    )
                else:
                    header = types["std_msgs/msg/Header"](**ros1, stamp=stamp, frame_id="camera")
                    message = types["sensor_msgs/msg/Image"](
                        header=header,
                        height=480,
                        width=640,
                        encoding="rgb8",
                        is_bigendian=0,
                        step=640 * 3,
                        data=np.roll(image, count, axis=1).reshape(-1),  # each frame its own
                    )
                out.write(topic, t, message)
                count += 1
            out.write("/map", t_map, encode_cleaned(snap, grid, serialization=out.serialization))
            count += 1
    return count


def raw_copy(src: Path, dst: Path, fmt: str) -> float:
    """Seconds to copy every message of ``src`` to ``dst`` unchanged (the session's copy path alone)."""
    t0 = time.perf_counter()
    reader = LogReader(src)
    with (
        reader,
        LogWriter(dst, fmt, serialization="ros1" if fmt == "ros1" else "cdr", force=True) as writer,
    ):
        handles = {c.id: writer.add_channel(c) for c in reader.channels}
        for m in reader.messages():
            writer.write_raw(
                handles[m.channel.id],
                m.log_time_ns,
                m.data,
                publish_time_ns=m.publish_time_ns,
                sequence=m.sequence,
            )
    return time.perf_counter() - t0


def rerun_logging_cost(
    size: int, *, count: int = 14, rounds: int = 4, clean_method: CleanMethod = "walls"
) -> tuple[float, float, float, float]:
    """Cost of the Rerun loggers on ``count`` analysed ``size`` x ``size`` snapshots, in one thread:
    once, and then ``rounds`` times more (the steady state of a long session: the first calls of
    each logger and archetype also pay one-time costs).

    Returns ``(first cpu ms, steady wall ms, steady cpu ms, rrd kB)`` per snapshot: the time of
    ``TopicLogger.log_snapshot`` (the conversions and the log calls; Rerun encodes, compresses and
    writes on its own threads, which the flush at the end waits for) with the snapshot's cleaning
    by ``clean_method`` shown, as a session shows it, and the saved recording's size.
    """
    if count < 1 or rounds < 1:
        msg = f"count and rounds must be >= 1, got {count} and {rounds}"
        raise ValueError(msg)
    import rerun as rr

    from rose.cleaning import clean
    from rose_logs.rerun import EntityPaths, TopicLogger, set_snapshot_time

    maps = stages(size)
    snapshots = [
        # Snapshot i shows the count distinct maps in turn, as results[i % count] is computed.
        MapSnapshot("/map", START_NS + i, START_NS + i, "map", maps[i % count % len(maps)], 0.05)
        for i in range(count * (1 + rounds))
    ]
    results = [rose.analyze(s.grid) for s in snapshots[:count]]
    cleanings = [
        clean(s.grid, r, method=clean_method)
        for s, r in zip(snapshots[:count], results, strict=True)
    ]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "cost.rrd"
        recording = rr.RecordingStream("rose_bag_bench")
        recording.set_log_time_enabled(False)
        recording.save(path)
        topic = TopicLogger(recording, EntityPaths("map"))
        topic.log_static()
        times = []
        for i, snapshot in enumerate(snapshots):
            if i in (0, count):
                times.append((time.perf_counter(), time.thread_time()))
            set_snapshot_time(
                recording, log_time_ns=snapshot.log_time_ns, start_ns=START_NS, index=i
            )
            topic.log_snapshot(snapshot, results[i % count], None, cleanings[i % count])
        times.append((time.perf_counter(), time.thread_time()))
        recording.flush()
        recording.disconnect()
        size_kb = path.stat().st_size / 1e3
    (_, c0), (w1, c1), (w2, c2) = times
    steady = count * rounds
    return (
        1e3 * (c1 - c0) / count,
        1e3 * (w2 - w1) / steady,
        1e3 * (c2 - c1) / steady,
        size_kb / len(snapshots),
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--snapshots", type=int, default=720)
    parser.add_argument("--size", type=int, default=1000)
    parser.add_argument("--period", type=float, default=5.0, help="seconds between maps")
    parser.add_argument("--scan-hz", type=float, default=10.0)
    parser.add_argument(
        "--camera-hz", type=float, default=0.0, help="also 640 x 480 RGB images at this rate"
    )
    parser.add_argument("--format", default="mcap", choices=("ros1", "db3", "mcap", "mcap-dir"))
    parser.add_argument("--rrd", action="store_true", help="also save a Rerun recording")
    parser.add_argument("--walls", action="store_true", help="also extract wall segments")
    parser.add_argument(
        "--clean-method", choices=("walls", "paper"), default="walls", help="how maps are cleaned"
    )
    parser.add_argument(
        "--growing",
        action="store_true",
        help="a map that grows (its grid cut around its known cells, a new shape every ten "
        "snapshots or so) instead of the stages at --size x --size",
    )
    parser.add_argument("--keep", type=Path, default=None, help="work here and keep the files")
    args = parser.parse_args(argv)
    keep_arrays_on_heap()  # as the rose-bag command does: measure what its users get
    os.environ.setdefault("RUST_LOG", "off")  # as rose-bag does: no native WARN lines in the report
    cv2.setNumThreads(1)  # as `rose-bag process` does (rose_logs/cli/process.py)

    work = args.keep or Path(tempfile.mkdtemp(prefix="rose-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    suffix = {"ros1": ".bag", "mcap": ".mcap"}.get(args.format, "")
    src, copy, out = (work / f"{n}{suffix}" for n in ("session", "copy", "processed"))
    try:
        t0 = time.perf_counter()
        # Built in a child process, so the peak memory below is the session's own.
        with multiprocessing.get_context("fork").Pool(1) as pool:
            messages = pool.apply(
                build,
                (src, args.format),
                {
                    "snapshots": args.snapshots,
                    "size": args.size,
                    "period_s": args.period,
                    "scan_hz": args.scan_hz,
                    "camera_hz": args.camera_hz,
                    "growing": args.growing,
                },
            )
        build_s = time.perf_counter() - t0
        size_mb = sum(p.stat().st_size for p in ([src] if src.is_file() else src.iterdir())) / 1e6
        copy_s = raw_copy(src, copy, args.format)
        t0 = time.perf_counter()
        with ThreadCpu() as threads:
            report = process_log(
                src,
                output_path=out,
                output_format=args.format,
                force=True,
                rrd_path=work / "session.rrd" if args.rrd else None,
                walls=args.walls,
                clean_method=args.clean_method,
            )
        process_s = time.perf_counter() - t0
        n = len(report.records)
        analysed = sum(not r.reused for r in report.records)
        print(f"cpu cores          {os.cpu_count()}")
        sizes = sorted({(r.height, r.width) for r in report.records}, key=lambda hw: hw[0] * hw[1])
        grids = (
            f"{len(sizes)} grid shapes, {sizes[0][0]} x {sizes[0][1]} .. {sizes[-1][0]} x {sizes[-1][1]}"
            if args.growing
            else f"{args.size} x {args.size}"
        )
        print(
            f"session            {args.format}, {n} snapshots of {grids}, "
            f"{messages} messages, {size_mb:.1f} MB, {args.snapshots * args.period / 60:.0f} min of log "
            f"(built in {build_s:.1f} s)"
        )
        print(f"raw copy           {copy_s:.2f} s")
        print(
            f"process            {process_s:.2f} s ({'with' if args.rrd else 'without'} Rerun; "
            f"{analysed} analysed, {n - analysed} reused)"
        )
        print(f"snapshots/s        {n / process_s:.1f} ({args.clean_method} cleaning)")
        busy = threads.by_name()
        if busy:
            cpu = sum(s for _, s in busy)
            print(
                f"cpu by thread      {cpu:.1f} s in {process_s:.1f} s ({cpu / process_s:.2f} cores): "
                + ", ".join(f"{name} {s:.1f}" for name, s in busy if s >= 0.05)
            )
        print(f"process / copy     {process_s / copy_s:.1f}x")
        per = sorted(r.seconds for r in report.records)
        print(
            f"per snapshot       median {1e3 * per[len(per) // 2]:.0f} ms, "
            f"max {1e3 * per[-1]:.0f} ms"
        )
        print(f"one-hour estimate  {720 / (n / process_s):.0f} s for 720 snapshots")
        peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
        print(f"peak memory        {peak_mb:.0f} MB (raw copy + process, this process)")
        if args.rrd:
            rrd_mb = (work / "session.rrd").stat().st_size / 1e6
            print(
                f"recording          {rrd_mb:.1f} MB, {1e3 * rrd_mb / n:.0f} kB per snapshot, "
                f"{720 * rrd_mb / n:.0f} MB for 720 snapshots"
            )
            first_ms, wall_ms, cpu_ms, kb = rerun_logging_cost(
                args.size, clean_method=args.clean_method
            )
            print(
                f"rerun logging      {wall_ms:.1f} ms wall, {cpu_ms:.1f} ms cpu per {args.size} x "
                f"{args.size} snapshot (loggers alone, {args.clean_method} cleaning shown, 14 "
                f"distinct maps four times over, after once: {first_ms:.1f} ms cpu; "
                f"{kb:.0f} kB each)"
            )
        load = os.getloadavg()
        print(f"load average       {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} (shared machine)")
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
