"""Benchmark ``rose-bag process`` / ``info`` and a raw copy on logs of many topics.

Real robots record hundreds of topics (a sensor each, diagnostics, tf, parameters); this builds logs of
``N`` topics of small messages (``std_msgs`` Float64 / Int32 / String / Bool in turn, ``--per-topic``
messages each) plus one ``nav_msgs/OccupancyGrid`` topic ``/map`` (two Freiburg 079 stages), in each
supported format (ROS 1 .bag, ROS 2 .db3 and MCAP bag folders, a plain ROS 2 .mcap file), written with
rosbags and the ``mcap`` package (not ``rose_logs.writer``). For each log it runs, each in its own
process: ``rose-bag info``, ``rose-bag process -o OUT`` and a raw copy (every message read with
``LogReader`` and written with ``LogWriter``, no ROSE), and prints wall and user CPU seconds, and the
sha256 of the process output (every file of a folder) so outputs can be compared between versions.
Prints numbers, asserts nothing.

Usage::

    python benchmarks/bench_topics.py [--topics 100,1000,3000] [--formats ros1,db3,mcap-dir,mcap]
        [--per-topic 5] [--dir DIR] [--repeat 1] [--only-make]
"""

from __future__ import annotations

import argparse
import hashlib
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

# The Freiburg 079 stages and the session's start, as the session benchmark has them (run as a
# script, this folder is on the path).
from bench_session import MAPS, START_NS

import rose

SMALL_TYPES = (
    "std_msgs/msg/Float64",
    "std_msgs/msg/Int32",
    "std_msgs/msg/String",
    "std_msgs/msg/Bool",
)
SUFFIX = {"ros1": ".bag", "db3": "", "mcap-dir": "", "mcap": ".mcap"}


def _store(ros1: bool) -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)


def _small(store: Any, msgtype: str, k: int) -> Any:
    cls = store.types[msgtype]
    if msgtype.endswith("Float64"):
        return cls(data=float(k) * 0.5)
    if msgtype.endswith("Int32"):
        return cls(data=k)
    if msgtype.endswith("String"):
        return cls(data=f"ok {k}")
    return cls(data=bool(k % 2))


def _map(store: Any, grid: np.ndarray, t_ns: int, seq: int, ros1: bool) -> Any:
    t = store.types
    stamp = t["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=t_ns % 10**9)
    header_kw: dict[str, Any] = {"stamp": stamp, "frame_id": "map"}
    if ros1:
        header_kw["seq"] = seq
    pose = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=-10.0, y=-10.0, z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    h, w = grid.shape
    info = t["nav_msgs/msg/MapMetaData"](
        map_load_time=stamp, resolution=0.05, width=w, height=h, origin=pose
    )
    return t["nav_msgs/msg/OccupancyGrid"](
        header=t["std_msgs/msg/Header"](**header_kw), info=info, data=grid.ravel()
    )


def records(
    n_topics: int, per_topic: int, ros1: bool
) -> tuple[dict[str, str], list[tuple[int, str, bytes]]]:
    """Topic -> type, and (log time ns, topic, serialised bytes) in time order: ``per_topic`` messages
    on each of ``n_topics`` topics spread over 10 s, and two maps on ``/map`` at 2 s and 8 s."""
    store = _store(ros1)

    def ser(msg: Any, msgtype: str) -> bytes:
        if ros1:
            return bytes(store.serialize_ros1(msg, msgtype))
        return bytes(store.serialize_cdr(msg, msgtype))

    topics = {"/map": "nav_msgs/msg/OccupancyGrid"}
    out: list[tuple[int, str, bytes]] = []
    for i, name in enumerate(("map5", "map10")):
        grid = np.ascontiguousarray(rose.load_map(MAPS / f"{name}.yaml").grid[205:531, 59:954])
        t_ns = START_NS + (2 + 6 * i) * 10**9
        out.append((t_ns, "/map", ser(_map(store, grid, t_ns, i + 1, ros1), topics["/map"])))
    for i in range(n_topics):
        topic = f"/robot/sensor_{i:05d}/value"
        msgtype = SMALL_TYPES[i % len(SMALL_TYPES)]
        topics[topic] = msgtype
        for k in range(per_topic):
            # Spread over 10 s, topics interleaved (as a recorder writes them).
            t_ns = START_NS + (k * 10**10) // per_topic + i * 1000
            out.append((t_ns, topic, ser(_small(store, msgtype, k), msgtype)))
    out.sort(key=lambda r: r[0])
    return topics, out


def write_log(path: Path, fmt: str, n_topics: int, per_topic: int) -> None:
    """Write the log of ``n_topics`` small topics plus ``/map`` in ``fmt`` at ``path``."""
    ros1 = fmt == "ros1"
    topics, recs = records(n_topics, per_topic, ros1)
    store = _store(ros1)
    if fmt == "ros1":
        from rosbags.rosbag1 import Writer as Ros1Writer

        with Ros1Writer(path) as w1:
            conns = {t: w1.add_connection(t, ty, typestore=store) for t, ty in topics.items()}
            for t_ns, topic, data in recs:
                w1.write(conns[topic], t_ns, data)
    elif fmt in ("db3", "mcap-dir"):
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Ros2Writer

        plugin = StoragePlugin.MCAP if fmt == "mcap-dir" else StoragePlugin.SQLITE3
        with Ros2Writer(path, version=9, storage_plugin=plugin) as w2:
            conns2 = {t: w2.add_connection(t, ty, typestore=store) for t, ty in topics.items()}
            for t_ns, topic, data in recs:
                w2.write(conns2[topic], t_ns, data)
    else:
        from mcap.writer import Writer as McapWriter

        with path.open("wb") as f:
            w3 = McapWriter(f)
            w3.start(profile="ros2", library="bench_topics")
            schemas: dict[str, int] = {}
            channels: dict[str, int] = {}
            for topic, msgtype in topics.items():
                if msgtype not in schemas:
                    msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
                    schemas[msgtype] = w3.register_schema(msgtype, "ros2msg", msgdef.encode())
                channels[topic] = w3.register_channel(topic, "cdr", schemas[msgtype])
            for seq, (t_ns, topic, data) in enumerate(recs):
                w3.add_message(channels[topic], t_ns, data, t_ns, seq)
            w3.finish()


def tree_sha256(path: Path) -> str:
    """sha256 over every file of ``path`` (a file or a folder), names and bytes, in name order."""
    digest = hashlib.sha256()
    files = sorted(path.rglob("*")) if path.is_dir() else [path]
    for p in files:
        if p.is_file():
            digest.update(p.name.encode() + b"\0" + p.read_bytes())
    return digest.hexdigest()[:16]


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall and user CPU seconds of ``cmd`` run to completion (its output discarded)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    return wall, resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime - before


RAW_COPY = """
import sys
from rose_logs.reader import LogReader
from rose_logs.writer import LogWriter
src, dst, fmt = sys.argv[1:]
with LogReader(src) as reader, LogWriter(dst, fmt, serialization="ros1" if fmt == "ros1" else "cdr", force=True) as writer:
    handles = {c.id: writer.add_channel(c) for c in reader.channels}
    for m in reader.messages():
        writer.write_raw(handles[m.channel.id], m.log_time_ns, m.data,
                         publish_time_ns=m.publish_time_ns, sequence=m.sequence)
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--topics", default="100,1000,3000")
    parser.add_argument("--formats", default="ros1,db3,mcap-dir,mcap")
    parser.add_argument("--per-topic", type=int, default=5)
    parser.add_argument("--dir", type=Path, default=None, help="keep the logs here (reused)")
    parser.add_argument(
        "--repeat", type=int, default=1, help="runs per command; the minimum is shown"
    )
    parser.add_argument("--only-make", action="store_true")
    args = parser.parse_args()
    base = args.dir or Path(tempfile.mkdtemp(prefix="bench_topics_"))
    base.mkdir(parents=True, exist_ok=True)
    exe = [sys.executable, "-m", "rose_logs.cli"]
    print(
        f"{'N':>5} {'format':8} {'info wall/user':>15} {'process wall/user':>18} "
        f"{'copy wall/user':>15}  output sha256"
    )
    for n in (int(x) for x in args.topics.split(",")):
        for fmt in args.formats.split(","):
            src = base / f"t{n}_{fmt}{SUFFIX[fmt]}"
            if not src.exists():
                write_log(src, fmt, n, args.per_topic)
            if args.only_make:
                continue
            out = base / f"out_t{n}_{fmt}{SUFFIX[fmt]}"
            copy = base / f"copy_t{n}_{fmt}{SUFFIX[fmt]}"
            fmt_out = "mcap" if fmt == "mcap" else fmt
            runs: dict[str, list[tuple[float, float]]] = {"info": [], "process": [], "copy": []}
            for _ in range(args.repeat):
                runs["info"].append(timed([*exe, "info", str(src)]))
                runs["process"].append(
                    timed(
                        [*exe, "process", str(src), "-o", str(out), "-f", "-q", "--format", fmt_out]
                    )
                )
                runs["copy"].append(
                    timed([sys.executable, "-c", RAW_COPY, str(src), str(copy), fmt_out])
                )
            best = {k: min(v, key=lambda r: r[1]) for k, v in runs.items()}
            cells = "  ".join(
                f"{best[k][0]:6.2f}/{best[k][1]:6.2f}" for k in ("info", "process", "copy")
            )
            print(f"{n:>5} {fmt:8} {cells}  {tree_sha256(out)}", flush=True)


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
