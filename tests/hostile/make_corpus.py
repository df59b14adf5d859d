"""Generate a corpus of hostile and unlucky inputs and run both CLIs on every case.

Usage: ``python tests/hostile/make_corpus.py [DIR] [--jobs N]`` prints one line per failing case and a
summary; exit status 1 if any case fails. ``tests/hostile/test_corpus.py`` runs the same corpus in CI.

Every case is a command line of ``rose`` or ``rose-bag`` in its own folder, run in a subprocess with a
timeout and an address-space limit. Whatever the outcome, it must show

- no traceback (stderr never contains ``Traceback``), no hang (timeout), an allowed exit code;
- unchanged inputs (SHA-256 of every input file before and after);
- no partial output: no ``.rose-tmp-`` / ``.rose-old-`` entry left, no output file after a failed run
  (or the pre-existing one unchanged), every output after a successful one;
- no silent loss: a damaged log that exits 0 must report every message of the undamaged log;
- a peak resident memory (``ru_maxrss`` of the child) below 1 GiB when the input is rejected.

Classes covered (issue 10): non-finite JSON, output protection, commit-all-or-none, signals, concurrent
runs, message loss (truncations, byte flips, zeroed blocks, corrupt metadata), tracebacks, memory
(YAML bombs, huge image headers, huge convert extents), FIFOs, accepted garbage (hostile map messages).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import math
import os
import random
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[2]
TIMEOUT_S = 90.0
ADDRESS_LIMIT = (
    8 << 30
)  # a ceiling only: Rerun's threads reserve GiBs of address space they never touch
REJECTED_RSS_LIMIT = 1 << 30
START_NS = 1_700_000_000_000_000_000
# The console scripts' own entry (exit_after): a signal once the outputs are committed, e.g. during
# interpreter shutdown, must not turn a finished run into one killed by SIGTERM (exit -15).
ENTRY = {
    "rose": "from rose.entry import rose; rose()",
    "rose-bag": "from rose.entry import rose_bag; rose_bag()",
}
OK, ERROR, USAGE, GATE, SALVAGED = 0, 1, 2, 3, 4
LEFTOVER_MARKS = (".rose-tmp-", ".rose-old-")


# -- cases ------------------------------------------------------------------------------------------------
@dataclass
class Case:
    """One command line and what its outcome may be.

    ``expect``: allowed exit codes. ``inputs``: files / folders that must stay byte-identical.
    ``outputs``: must not exist (or keep their pre-existing bytes) after an exit other than 0/3/4 and
    must exist after 0. ``complete_messages``: for a damaged log, the message count of the undamaged
    one (exit 0 must report all of them in ``report.json``). ``signal``: (signal number, delay s),
    the delay counted from the moment the command installed its signal handlers (start-up), or with
    ``None`` from the moment a temporary output exists (mid-run).
    ``copies``: run this many identical processes at once (concurrency). ``check``: an extra check
    returning a problem text or None.
    """

    name: str
    cls: str
    argv: list[str]
    folder: Path
    expect: set[int]
    inputs: list[Path] = field(default_factory=list)
    outputs: list[Path] = field(default_factory=list)
    complete_messages: int | None = None
    signal: tuple[int, float | None] | None = None
    copies: int = 1
    check: Callable[[Result], str | None] | None = None


@dataclass
class Result:
    case: Case
    codes: list[int]
    stderr: str
    stdout: str
    seconds: float
    max_rss: int
    timed_out: bool
    problems: list[str] = field(default_factory=list)


# -- data -----------------------------------------------------------------------------------------------
def floor_plan(rows: int = 90, cols: int = 120, seed: int = 0) -> np.ndarray:
    """An int8 ROS grid: free inside, walls of rooms, a few specks of clutter, unknown outside."""
    grid = np.full((rows, cols), -1, np.int8)
    grid[5:-5, 5:-5] = 0
    for r in (5, rows // 2, rows - 6):
        grid[r, 5:-5] = 100
    for c in (5, cols // 3, 2 * cols // 3, cols - 6):
        grid[5:-5, c] = 100
    grid[rows // 2, cols // 3 + 3 : cols // 3 + 9] = 0  # a door
    rng = np.random.default_rng(seed)
    specks = rng.integers(8, min(rows, cols) - 8, size=(12, 2))
    grid[specks[:, 0], specks[:, 1]] = 100
    return grid


def map_message(
    types: Any,
    ros1: bool,
    grid: np.ndarray,
    *,
    t_ns: int,
    resolution: float = 0.05,
    position: tuple[float, float, float] = (-3.0, -2.0, 0.0),
    quaternion: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0),
    stamp: tuple[int, int] | None = None,
    shape: tuple[int, int] | None = None,
) -> Any:
    sec, nanosec = stamp if stamp is not None else divmod(t_ns, 1_000_000_000)
    header_kw = {"seq": 1} if ros1 else {}
    header = types["std_msgs/msg/Header"](
        **header_kw,
        stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
        frame_id="map",
    )
    height, width = shape if shape is not None else grid.shape
    point = types["geometry_msgs/msg/Point"](x=position[0], y=position[1], z=position[2])
    quat = types["geometry_msgs/msg/Quaternion"](*quaternion)
    info = types["nav_msgs/msg/MapMetaData"](
        map_load_time=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=0),
        resolution=resolution,
        width=width,
        height=height,
        origin=types["geometry_msgs/msg/Pose"](position=point, orientation=quat),
    )
    return types["nav_msgs/msg/OccupancyGrid"](header=header, info=info, data=grid.ravel())


def scan_message(types: Any, ros1: bool, t_ns: int, seed: int) -> Any:
    header_kw = {"seq": seed} if ros1 else {}
    sec, nanosec = divmod(t_ns, 1_000_000_000)
    rng = np.random.default_rng(seed)
    return types["sensor_msgs/msg/LaserScan"](
        header=types["std_msgs/msg/Header"](
            **header_kw,
            stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
            frame_id="laser",
        ),
        angle_min=-1.57,
        angle_max=1.57,
        angle_increment=0.0174,
        time_increment=0.0,
        scan_time=0.1,
        range_min=0.1,
        range_max=30.0,
        ranges=rng.uniform(0.5, 10.0, 181).astype(np.float32),
        intensities=np.zeros(0, np.float32),
    )


def write_session(
    path: Path,
    fmt: str,
    *,
    serialization: str | None = None,
    maps: Sequence[dict[str, Any]] | None = None,
    scans_per_map: int = 4,
    map_log_times: Sequence[int] | None = None,
) -> int:
    """A session log with maps on /map and scans on /scan; returns the number of messages."""
    from rose_logs.writer import open_output

    maps = maps if maps is not None else [{}, {}, {}]
    count = 0
    with open_output(path, fmt, serialization=serialization) as out:
        types = out.typestore.types
        ros1 = out.serialization == "ros1"
        out.add_topic("/map", "nav_msgs/msg/OccupancyGrid", latching=True)
        out.add_topic("/scan", "sensor_msgs/msg/LaserScan")
        for i, overrides in enumerate(maps):
            t = START_NS + (i + 1) * 5_000_000_000
            log_t = map_log_times[i] if map_log_times is not None else t
            kw = {"grid": floor_plan(seed=i), "t_ns": t} | overrides
            out.write("/map", log_t, map_message(types, ros1, **kw))
            count += 1
            for k in range(scans_per_map):
                ts = t + (k + 1) * 100_000_000
                out.write("/scan", ts, scan_message(types, ros1, ts, i * 10 + k + 1))
                count += 1
    return count


def storage_file(path: Path) -> Path:
    """The file holding the messages: the log itself, or the storage file of a bag folder."""
    if path.is_dir():
        return next(p for p in sorted(path.iterdir()) if p.suffix in (".db3", ".mcap"))
    return path


def write_map_files(folder: Path, stem: str = "floor", image: str | None = None) -> Path:
    import cv2

    grid = floor_plan(120, 160)
    picture = np.full(grid.shape, 205, np.uint8)
    picture[grid == 0] = 254
    picture[grid == 100] = 0
    image = image or f"{stem}.pgm"
    cv2.imwrite(str(folder / image), np.flipud(picture))
    yaml_path = folder / f"{stem}.yaml"
    yaml_path.write_text(
        f"image: {image}\nresolution: 0.05\norigin: [-1.0, -2.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    return yaml_path


def carmen_log(path: Path, *, n: int = 40, stamp0: float = 1000.0, x0: float = 0.0) -> Path:
    lines = []
    rng = np.random.default_rng(3)
    for i in range(n):
        ranges = " ".join(f"{v:.2f}" for v in rng.uniform(1.0, 6.0, 181))
        x, y, th = x0 + 0.05 * i, 0.02 * i, 0.01 * i
        lines.append(
            f"FLASER 181 {ranges} {x:.3f} {y:.3f} {th:.3f} {x:.3f} {y:.3f} {th:.3f} "
            f"{stamp0 + 0.2 * i:.3f} host {stamp0 + 0.2 * i:.3f}"
        )
    path.write_text("\n".join(lines) + "\n")
    return path


def alias_bomb(levels: int = 9) -> str:
    """A "billion laughs" YAML of about 1 KB: 9**levels strings once the aliases are expanded."""
    lines = ["a: &a [" + ",".join(["lol"] * 9) + "]"]
    for i in range(1, levels):
        prev, name = chr(96 + i), chr(97 + i)
        lines.append(f"{name}: &{name} [" + ",".join([f"*{prev}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def png_header(width: int, height: int) -> bytes:
    """A PNG whose IHDR declares ``width x height`` followed by nothing usable."""
    import struct
    import zlib

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    return (
        b"\x89PNG\r\n\x1a\n"
        + struct.pack(">I", len(ihdr))
        + chunk
        + struct.pack(">I", zlib.crc32(chunk))
        + b"\x00" * 64
    )


# -- corpus ---------------------------------------------------------------------------------------------
LOG_KINDS = {  # name -> (writer format, serialisation, file name)
    "ros1": ("ros1", None, "in.bag"),
    "db3": ("db3", None, "in"),
    "mcap-dir": ("mcap-dir", None, "in"),
    "mcap": ("mcap", None, "in.mcap"),
    "mcap-ros1": ("mcap", "ros1", "in.mcap"),
}


class Corpus:
    """Builds the case folders under ``root``; :attr:`cases` lists them."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.cases: list[Case] = []
        self.base = root / "_base"
        self.base.mkdir(parents=True, exist_ok=True)
        self.counts: dict[str, int] = {}
        self.mounts: list[Path] = []
        for kind, (fmt, ser, name) in LOG_KINDS.items():
            folder = self.base / kind
            folder.mkdir(exist_ok=True)
            self.counts[kind] = write_session(folder / name, fmt, serialization=ser)

    def folder(self, name: str) -> Path:
        path = self.root / name
        if path.exists():
            shutil.rmtree(path)
        path.mkdir(parents=True)
        return path

    def copy_log(self, kind: str, folder: Path) -> Path:
        name = LOG_KINDS[kind][2]
        source = self.base / kind / name
        target = folder / name
        if source.is_dir():
            shutil.copytree(source, target)
        else:
            shutil.copy2(source, target)
        return target

    def add(self, case: Case) -> None:
        self.cases.append(case)


def _report_complete(total: int) -> Callable[[Result], str | None]:
    def check(result: Result) -> str | None:
        if result.codes != [OK]:
            return None
        report = result.case.folder / "report.json"
        data = json.loads(report.read_text())
        if data["message_count"] != total:
            return f"silent loss: exit 0 with {data['message_count']} of {total} messages"
        return None

    return check


def _damage_cases(corpus: Corpus) -> None:
    """Truncations, byte flips (CRC-detectable in MCAP chunks), zeroed blocks, for every format."""
    rng = random.Random(10)
    for kind in LOG_KINDS:
        ext = ".bag" if kind == "ros1" else ("" if kind in ("db3", "mcap-dir") else ".mcap")
        size = storage_file(corpus.base / kind / LOG_KINDS[kind][2]).stat().st_size
        damages: list[tuple[str, Callable[[bytearray], bytearray]]] = [
            ("trunc50", lambda b: b[: len(b) // 2]),
            ("trunc90", lambda b: b[: len(b) * 9 // 10]),
            ("trunc-1", lambda b: b[:-1]),
            ("zero4k", lambda b: b[: len(b) // 3] + bytearray(4096) + b[len(b) // 3 + 4096 :]),
        ]
        for i in range(3):
            pos = rng.randrange(64, size - 64)

            def flip(b: bytearray, pos: int = pos) -> bytearray:
                b[pos] ^= 0xFF
                return b

            damages.append((f"flip{i}", flip))
        for label, damage in damages:
            for salvage in (False, True) if label in ("trunc90", "zero4k") else (False,):
                name = f"loss-{kind}-{label}" + ("-salvage" if salvage else "")
                folder = corpus.folder(name)
                log = corpus.copy_log(kind, folder)
                target = storage_file(log)
                target.write_bytes(bytes(damage(bytearray(target.read_bytes()))))
                out = folder / f"out{ext}"
                argv = ["rose-bag", "process", str(log), "-o", str(out), "--json"]
                argv += [str(folder / "report.json"), "-q"]
                corpus.add(
                    Case(
                        name,
                        "6 loss",
                        argv + (["--salvage"] if salvage else []),
                        folder,
                        {OK, ERROR, SALVAGED} if salvage else {OK, ERROR},
                        inputs=[log],
                        outputs=[out, folder / "report.json"],
                        complete_messages=corpus.counts[kind],
                        check=_report_complete(corpus.counts[kind]),
                    )
                )


def _metadata_cases(corpus: Corpus) -> None:
    edits: dict[str, Callable[[str], str]] = {
        "count-up": lambda t: t.replace("message_count: 12", "message_count: 20"),
        "scan-as-map": lambda t: t.replace(
            "sensor_msgs/msg/LaserScan", "nav_msgs/msg/OccupancyGrid"
        ),
        "alias-bomb": lambda t: alias_bomb() + t,
        "deep": lambda _t: "[" * 5000 + "]" * 5000 + "\n",
        "bigint": lambda t: t.replace("message_count: 12", "message_count: " + "9" * 5000),
        "not-yaml": lambda _t: "rosbag2_bagfile_information: {unclosed\n",
        "empty": lambda _t: "",
    }
    for kind in ("db3", "mcap-dir"):
        for label, edit in edits.items():
            name = f"meta-{kind}-{label}"
            folder = corpus.folder(name)
            log = corpus.copy_log(kind, folder)
            meta = log / "metadata.yaml"
            meta.write_text(edit(meta.read_text()))
            out = folder / "out"
            corpus.add(
                Case(
                    name,
                    "6 loss / 8 memory",
                    ["rose-bag", "process", str(log), "-o", str(out), "-q"],
                    folder,
                    {ERROR},
                    inputs=[log],
                    outputs=[out],
                )
            )
        name = f"meta-{kind}-missing-storage"
        folder = corpus.folder(name)
        log = corpus.copy_log(kind, folder)
        storage_file(log).unlink()
        corpus.add(
            Case(
                name,
                "6 loss",
                ["rose-bag", "info", str(log)],
                folder,
                {ERROR},
                inputs=[log],
            )
        )


def _hostile_map_cases(corpus: Corpus) -> None:
    """Map messages no real map has: each is skipped with a warning, the rest analysed (class 10)."""
    bad: dict[str, dict[str, Any]] = {
        "res-zero": {"resolution": 0.0},
        "res-negative": {"resolution": -0.05},
        "res-huge": {"resolution": 3e38},
        "res-nan": {"resolution": math.nan},
        "origin-nan": {"position": (math.nan, 0.0, 0.0)},
        "quat-zero": {"quaternion": (0.0, 0.0, 0.0, 0.0)},
        "quat-nan": {"quaternion": (math.nan, 0.0, 0.0, 1.0)},
        "nanosec-big": {"stamp": (2**31 - 1, 1_500_000_000)},
        "stamp-int32-max": {"stamp": (2**31 - 1, 999_999_999)},
        "shape-mismatch": {"shape": (10, 10)},
    }
    for label, overrides in bad.items():
        for kind in ("mcap", "ros1") if label in ("nanosec-big", "res-huge") else ("mcap",):
            name = f"garbage-map-{kind}-{label}"
            folder = corpus.folder(name)
            fmt, ser, file_name = LOG_KINDS[kind]
            log = folder / file_name
            write_session(log, fmt, serialization=ser, maps=[{}, overrides, {}])
            out = folder / f"out{log.suffix}"
            valid_only = label == "stamp-int32-max"
            corpus.add(
                Case(
                    name,
                    "10 garbage / 7 traceback",
                    ["rose-bag", "process", str(log), "-o", str(out), "-q"],
                    folder,
                    {OK},
                    inputs=[log],
                    outputs=[out],
                    check=None if valid_only else _warned("copied unprocessed"),
                )
            )
    # log time >= 2**63 with --rrd (only MCAP can hold it)
    folder = corpus.folder("garbage-logtime-2p63-rrd")
    log = folder / "in.mcap"
    write_session(log, "mcap", map_log_times=[START_NS, 2**63 + 5, 2**64 - 1])
    corpus.add(
        Case(
            "garbage-logtime-2p63-rrd",
            "7 traceback",
            ["rose-bag", "process", str(log), "--no-output", "--rrd", str(folder / "r.rrd"), "-q"],
            folder,
            {OK},
            inputs=[log],
            outputs=[folder / "r.rrd"],
            check=_warned("outside 0 .. 2**63"),
        )
    )
    # a map larger than --max-cells: skipped, not analysed
    folder = corpus.folder("garbage-map-over-max-cells")
    log = folder / "in.mcap"
    write_session(log, "mcap", maps=[{}, {"grid": np.zeros((400, 500), np.int8)}])
    corpus.add(
        Case(
            "garbage-map-over-max-cells",
            "8 memory",
            ["rose-bag", "process", str(log), "--no-output", "--max-cells", "50000", "-q"],
            folder,
            {OK},
            inputs=[log],
            check=_warned("exceeds the limit"),
        )
    )
    # all maps malformed: an error, nothing written
    folder = corpus.folder("garbage-all-maps-bad")
    log = folder / "in.mcap"
    write_session(log, "mcap", maps=[{"resolution": 0.0}, {"quaternion": (0.0, 0.0, 0.0, 0.0)}])
    corpus.add(
        Case(
            "garbage-all-maps-bad",
            "10 garbage",
            ["rose-bag", "process", str(log), "-o", str(folder / "o.mcap"), "-q"],
            folder,
            {ERROR},
            inputs=[log],
            outputs=[folder / "o.mcap"],
        )
    )


def _warned(text: str) -> Callable[[Result], str | None]:
    def check(result: Result) -> str | None:
        return None if text in result.stderr else f"no warning containing {text!r}"

    return check


def _info_cases(corpus: Corpus) -> None:
    # MCAP without statistics / summary: counts must be right, or an error.
    from mcap.writer import Writer

    for label, kw in {
        "no-statistics": {"use_statistics": False},
        "no-summary-offsets": {"use_summary_offsets": False},
    }.items():
        folder = corpus.folder(f"info-mcap-{label}")
        source = corpus.base / "mcap" / "in.mcap"
        from mcap.reader import make_reader

        log = folder / "in.mcap"
        with source.open("rb") as src, log.open("wb") as dst:
            reader = make_reader(src)
            summary = reader.get_summary()
            writer = Writer(dst, **kw)
            writer.start(profile="ros2", library="corpus")
            schema_ids = {
                sid: writer.register_schema(s.name, s.encoding, s.data)
                for sid, s in summary.schemas.items()
            }
            channel_ids = {
                cid: writer.register_channel(
                    c.topic, c.message_encoding, schema_ids[c.schema_id], c.metadata
                )
                for cid, c in summary.channels.items()
            }
            for _s, channel, message in reader.iter_messages():
                writer.add_message(
                    channel_ids[channel.id], message.log_time, message.data, message.publish_time
                )
            writer.finish()
        total = corpus.counts["mcap"]

        def counted(result: Result, total: int = total) -> str | None:
            if f"messages     {total}" not in result.stdout:
                return f"info does not report {total} messages"
            return None

        corpus.add(
            Case(
                f"info-mcap-{label}",
                "10 garbage",
                ["rose-bag", "info", str(log)],
                folder,
                {OK},
                inputs=[log],
                check=counted,
            )
        )


def _fifo_cases(corpus: Corpus) -> None:
    folder = corpus.folder("fifo")
    fifo = folder / "pipe.mcap"
    os.mkfifo(fifo)
    (folder / "bag").mkdir()
    os.mkfifo(folder / "bag" / "metadata.yaml")
    yaml_path = write_map_files(folder)
    os.mkfifo(folder / "fifo.pgm")
    (folder / "to-fifo.yaml").write_text("image: fifo.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    os.mkfifo(folder / "pipe.log")
    for name, argv in {
        "fifo-info": ["rose-bag", "info", str(fifo)],
        "fifo-process": ["rose-bag", "process", str(fifo), "--no-output"],
        "fifo-bag-metadata": ["rose-bag", "info", str(folder / "bag")],
        "fifo-rose-image": ["rose", "score", str(folder / "to-fifo.yaml")],
        "fifo-rose-direct": ["rose", "score", str(folder / "fifo.pgm")],
        "fifo-convert": ["rose-bag", "convert", str(folder / "pipe.log"), str(folder / "o.mcap")],
        "dev-zero-info": ["rose-bag", "info", "/dev/zero"],
        "dev-zero-rose": ["rose", "score", "/dev/zero"],
    }.items():
        corpus.add(Case(name, "9 fifo", argv, folder, {ERROR}, inputs=[yaml_path]))


def _map_file_cases(corpus: Corpus) -> None:
    """Hostile map_server files for ``rose``: YAML bombs, numbers, images."""
    texts = {
        "alias-bomb": alias_bomb() + "image: floor.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n",
        "deep": "image: floor.pgm\nresolution: 0.05\norigin: " + "[" * 3000 + "]" * 3000 + "\n",
        "bigint": "image: floor.pgm\nresolution: " + "7" * 5000 + "\norigin: [0, 0, 0]\n",
        "bigint-4000": "image: floor.pgm\nresolution: 0.05\norigin: [" + "7" * 4000 + ", 0, 0]\n",
        "yaw-inf": "image: floor.pgm\nresolution: 0.05\norigin: [0, 0, .inf]\n",
        "origin-nan": "image: floor.pgm\nresolution: 0.05\norigin: [.nan, 0, 0]\n",
        "res-zero": "image: floor.pgm\nresolution: 0\norigin: [0, 0, 0]\n",
        "res-huge": "image: floor.pgm\nresolution: 3e38\norigin: [0, 0, 0]\n",
        "image-dir": "image: .\nresolution: 0.05\norigin: [0, 0, 0]\n",
        "image-long-name": f"image: {'x' * 300}.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n",
        "binary": "\x00\xff\xfe garbage",
    }
    for label, text in texts.items():
        folder = corpus.folder(f"mapfile-{label}")
        write_map_files(folder)
        bad = folder / "bad.yaml"
        bad.write_bytes(text.encode("utf-8", "surrogateescape"))
        for command in ("score", "walls", "clean"):
            argv = ["rose", command, str(bad)]
            outputs = []
            if command == "clean":
                argv += ["-o", str(folder / "o.yaml"), "--json", str(folder / "o.json")]
                outputs = [folder / "o.yaml", folder / "o.pgm", folder / "o.json"]
            corpus.add(
                Case(
                    f"mapfile-{label}-{command}",
                    "7 traceback / 8 memory",
                    argv,
                    folder,
                    {ERROR},
                    inputs=[bad, folder / "floor.pgm"],
                    outputs=outputs,
                )
            )
    images = {
        "png-40000x40000": png_header(40000, 40000),
        "png-2p31": png_header(2**31 - 1, 2**31 - 1),
        "pgm-huge": b"P5\n50000 50000\n255\n" + b"\x00" * 100,
        "pgm-truncated": b"P5\n100 100\n255\n" + b"\x00" * 100,
        "png-truncated": png_header(100, 100)[:30],
        "empty": b"",
    }
    for label, data in images.items():
        folder = corpus.folder(f"image-{label}")
        image = folder / ("m.pgm" if "pgm" in label else "m.png")
        image.write_bytes(data)
        corpus.add(
            Case(
                f"image-{label}",
                "8 memory",
                ["rose", "score", str(image)],
                folder,
                {ERROR},
                inputs=[image],
            )
        )
    folder = corpus.folder("mapfile-name-too-long")
    corpus.add(
        Case(
            "mapfile-name-too-long",
            "7 traceback",
            ["rose", "score", str(folder / ("y" * 300 + ".yaml"))],
            folder,
            {ERROR},
        )
    )


def _json_cases(corpus: Corpus) -> None:
    """Maps whose threshold is not finite (a grid of pillars, a full-width wall): JSON stays strict."""
    import cv2

    folder = corpus.folder("json-nonfinite")
    pillars = np.full((64, 64), 254, np.uint8)
    pillars[::8, ::8] = 0
    cv2.imwrite(str(folder / "pillars.png"), pillars)
    wall = np.full((60, 80), 254, np.uint8)
    wall[30, :] = 0
    cv2.imwrite(str(folder / "wall.png"), wall)
    nan_yaml = folder / "nan.yaml"
    nan_yaml.write_text("image: wall.png\nresolution: 0.05\norigin: [.nan, 0, 0]\n")
    inputs = [folder / "pillars.png", folder / "wall.png", nan_yaml]

    def strict(name: str) -> Callable[[Result], str | None]:
        def check(result: Result) -> str | None:
            text = result.stdout if name == "-" else (folder / name).read_text()
            if name == "-":
                text = text[text.index("[") :] if "[" in text else text
            try:
                json.loads(text, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
            except ValueError as err:
                return f"invalid JSON in {name}: {err}"
            return None

        return check

    for image in ("pillars.png", "wall.png"):
        stem = image.split(".")[0]
        corpus.add(
            Case(
                f"json-score-{stem}",
                "1 json",
                ["rose", "score", "--json", str(folder / image)],
                folder,
                {OK},
                inputs=inputs,
                check=strict("-"),
            )
        )
        corpus.add(
            Case(
                f"json-clean-{stem}",
                "1 json",
                [
                    "rose",
                    "clean",
                    str(folder / image),
                    "-o",
                    str(folder / f"c-{stem}.yaml"),
                    "--json",
                    str(folder / f"c-{stem}.json"),
                ],
                folder,
                {OK},
                inputs=inputs,
                outputs=[folder / f"c-{stem}.yaml", folder / f"c-{stem}.json"],
                check=strict(f"c-{stem}.json"),
            )
        )
    corpus.add(
        Case(
            "json-walls-nan-origin",
            "1 json",
            ["rose", "walls", str(nan_yaml), "--geojson", str(folder / "w.geojson")],
            folder,
            {ERROR},
            inputs=inputs,
            outputs=[folder / "w.geojson"],
        )
    )
    # rose-bag process --json on a session whose maps are pillars / a full-width wall
    log = folder / "in.mcap"
    pillar_grid = np.zeros((64, 64), np.int8)
    pillar_grid[::8, ::8] = 100
    wall_grid = np.zeros((60, 80), np.int8)
    wall_grid[30, :] = 100
    write_session(log, "mcap", maps=[{"grid": pillar_grid}, {"grid": wall_grid}])
    inputs.append(log)
    corpus.add(
        Case(
            "json-process-nonfinite",
            "1 json",
            [
                "rose-bag",
                "process",
                str(log),
                "-o",
                str(folder / "p.mcap"),
                "--json",
                str(folder / "p.json"),
                "-q",
            ],
            folder,
            {OK},
            inputs=inputs,
            outputs=[folder / "p.mcap", folder / "p.json"],
            check=strict("p.json"),
        )
    )


def _output_cases(corpus: Corpus) -> None:
    """Every output checked against every input and each other; existing outputs need --force."""
    labels = [
        "json-is-input",
        "rrd-is-input",
        "json-is-output",
        "rrd-is-json",
        "json-exists",
        "output-dir-force",
        "output-is-folder",
        "clean-image-is-input",
        "clean-json-is-image",
        "clean-json-exists",
        "walls-geojson-is-input",
        "convert-over-input",
        "convert-mapfile-over-input",
        "rrd-missing-dir",
        "rrd-stream",
    ]
    for label in labels:
        folder = corpus.folder(f"out-{label}")
        log = corpus.copy_log("mcap", folder)
        yaml_path = write_map_files(folder, "floor", image="plan.pgm")
        precious = folder / "precious.json"
        precious.write_text('{"keep": true}\n')
        photos = folder / "photos"
        photos.mkdir()
        (photos / "holiday.jpg").write_bytes(b"\xff\xd8 not really")
        carmen = carmen_log(folder / "run.pgm")  # a CARMEN log whose name is --map-file's image
        inputs = [log, yaml_path, folder / "plan.pgm", precious, photos, carmen]
        process = ["rose-bag", "process", str(log), "-q"]
        argv = {
            "json-is-input": [*process, "--no-output", "--json", str(log)],
            "rrd-is-input": [*process, "--no-output", "--rrd", str(log)],
            "json-is-output": [
                *process,
                "-o",
                str(folder / "o.mcap"),
                "--json",
                str(folder / "o.mcap"),
            ],
            "rrd-is-json": [
                *process,
                "--no-output",
                "--rrd",
                str(folder / "x"),
                "--json",
                str(folder / "x"),
            ],
            "json-exists": [*process, "--no-output", "--json", str(precious)],
            "output-dir-force": [*process, "-o", str(photos), "--format", "mcap-dir", "--force"],
            "output-is-folder": [*process, "-o", str(folder), "--force"],
            "clean-image-is-input": [
                "rose",
                "clean",
                str(yaml_path),
                "-o",
                str(folder / "plan.yaml"),
            ],
            "clean-json-is-image": [
                "rose",
                "clean",
                str(yaml_path),
                "-o",
                str(folder / "c.yaml"),
                "--json",
                str(folder / "plan.pgm"),
                "--force",
            ],
            "clean-json-exists": [
                "rose",
                "clean",
                str(yaml_path),
                "-o",
                str(folder / "c.yaml"),
                "--json",
                str(precious),
            ],
            "walls-geojson-is-input": [
                "rose",
                "walls",
                str(yaml_path),
                "--geojson",
                str(yaml_path),
                "-f",
            ],
            "convert-over-input": ["rose-bag", "convert", str(carmen), str(carmen), "--force"],
            "convert-mapfile-over-input": [
                "rose-bag",
                "convert",
                str(carmen),
                str(folder / "c.mcap"),
                "--map-file",
                str(folder / "run.yaml"),
                "--force",
            ],
            "rrd-missing-dir": [*process, "--no-output", "--rrd", str(folder / "no" / "r.rrd")],
            "rrd-stream": [*process, "--no-output", "--rrd", "-"],
        }[label]
        corpus.add(
            Case(
                f"out-{label}",
                "2 protect",
                argv,
                folder,
                {ERROR},
                inputs=inputs,
                outputs=[
                    folder / "o.mcap",
                    folder / "c.yaml",
                    folder / "c.mcap",
                    folder / "x",
                    folder / "run.yaml",
                ],
            )
        )
    # streams: -, /dev/stdout, /dev/null are written in place, never replaced
    for label, target in {
        "dash": "-",
        "dev-stdout": "/dev/stdout",
        "dev-null": "/dev/null",
    }.items():
        sub = corpus.folder(f"out-stream-{label}")
        sub_log = corpus.copy_log("mcap", sub)

        def valid(result: Result, label: str = label) -> str | None:
            if label == "dev-null":
                return None if Path("/dev/null").is_char_device() else "/dev/null replaced"
            try:
                json.loads(result.stdout)
            except ValueError as err:
                return f"stdout is not the JSON report ({err})"
            return None

        corpus.add(
            Case(
                f"out-stream-{label}",
                "2 protect",
                ["rose-bag", "process", str(sub_log), "--no-output", "--json", target, "-q"],
                sub,
                {OK},
                inputs=[sub_log],
                check=valid,
            )
        )
    # commit together: a failing second output leaves no first one
    sub = corpus.folder("out-all-or-none")
    sub_log = corpus.copy_log("mcap", sub)
    (sub / "r.rrd").mkdir()  # the recording cannot replace a directory
    corpus.add(
        Case(
            "out-all-or-none",
            "3 commit",
            [
                "rose-bag",
                "process",
                str(sub_log),
                "-o",
                str(sub / "o.mcap"),
                "--json",
                str(sub / "o.json"),
                "--rrd",
                str(sub / "r.rrd"),
                "--force",
                "-q",
            ],
            sub,
            {ERROR},
            inputs=[sub_log, sub / "r.rrd"],
            outputs=[sub / "o.mcap", sub / "o.json"],
        )
    )
    # a stale temporary of a dead process is removed by the next run
    sub = corpus.folder("out-stale-temp")
    sub_log = corpus.copy_log("mcap", sub)
    from rose.outputs import process_tag  # the name a run on this host and namespace gives

    stale = sub / f".o.mcap.rose-tmp-{process_tag()}-999999999-deadbeef"
    stale.mkdir()
    (stale / "o.mcap").write_bytes(b"half written")
    corpus.add(
        Case(
            "out-stale-temp",
            "4 signals",
            ["rose-bag", "process", str(sub_log), "-o", str(sub / "o.mcap"), "-q"],
            sub,
            {OK},
            inputs=[sub_log],
            outputs=[sub / "o.mcap"],
        )
    )


def _signal_cases(corpus: Corpus) -> None:
    """Signals during start-up (imports) and mid-run (temporaries open): exit 130 / 143 / 129, nothing left."""
    folder = corpus.folder("signals-base")
    big = folder / "big.mcap"
    write_session(big, "mcap", maps=[{"grid": floor_plan(400, 500, seed=i)} for i in range(40)])
    for label, (signum, delay, codes) in {
        # Counted from main()'s install_signal_handlers, not from exec: on a loaded 2-core machine
        # interpreter start-up alone can pass 0.5 s, and a signal before main() kills the process
        # (SIGTERM: exit -15) or is a KeyboardInterrupt traceback from `import` (SIGINT). 0.05 s
        # later the sub-commands' libraries are still loading.
        "sigint-early": (signal.SIGINT, 0.05, {130}),
        "sigterm-early": (signal.SIGTERM, 0.05, {143}),
        "sigterm-mid": (signal.SIGTERM, None, {143}),
        "sighup-mid": (signal.SIGHUP, None, {129}),
        "sigint-mid": (signal.SIGINT, None, {130}),
    }.items():
        if signal.getsignal(signum) == signal.SIG_IGN:
            # Run under nohup (SIGHUP ignored, and so in every command started): the commands keep
            # it ignored, as the user asked, and finish.
            codes = {0}
        sub = corpus.folder(f"signal-{label}")
        log = sub / "big.mcap"
        shutil.copy2(big, log)
        corpus.add(
            Case(
                f"signal-{label}",
                "4 signals",
                [
                    "rose-bag",
                    "process",
                    str(log),
                    "-o",
                    str(sub / "o.mcap"),
                    "--rrd",
                    str(sub / "o.rrd"),
                    "--json",
                    str(sub / "o.json"),
                    "-q",
                ],
                sub,
                codes,
                inputs=[log],
                outputs=[sub / "o.mcap", sub / "o.rrd", sub / "o.json"],
                signal=(signum, delay),
            )
        )
    shutil.rmtree(folder)


def _concurrent_cases(corpus: Corpus) -> None:
    """Two runs writing the same outputs at once: one winner, the other a clean error or the same file."""
    for label, force in (("force", True), ("no-force", False)):
        sub = corpus.folder(f"concurrent-{label}")
        log = corpus.copy_log("mcap", sub)
        argv = ["rose-bag", "process", str(log), "-o", str(sub / "o.mcap"), "--rrd"]
        argv += [str(sub / "o.rrd"), "-q"] + (["--force"] if force else [])

        def complete(result: Result) -> str | None:
            from rose_logs.reader import LogReader

            if OK not in result.codes:
                return "no run succeeded"
            try:
                with LogReader(result.case.folder / "o.mcap") as reader:
                    n = sum(1 for _ in reader.messages())
            except Exception as err:
                return f"output corrupt: {err}"
            rrd = result.case.folder / "o.rrd"
            if not rrd.is_file() or rrd.stat().st_size < 1000:
                return "recording missing or truncated"
            return None if n > 0 else "output empty"

        corpus.add(
            Case(
                f"concurrent-{label}",
                "5 concurrent",
                argv,
                sub,
                {OK} if force else {OK, ERROR},
                inputs=[log],
                copies=2,
                check=complete,
            )
        )


def _option_cases(corpus: Corpus) -> None:
    """Bad option values are usage errors (exit 2); convert's hostile CARMEN logs are errors."""
    folder = corpus.folder("options")
    log = corpus.copy_log("mcap", folder)
    yaml_path = write_map_files(folder)
    carmen = carmen_log(folder / "run.log")
    carmen_neg = carmen_log(folder / "neg.log", stamp0=-50.0)
    carmen_huge = carmen_log(folder / "huge.log", stamp0=1e12)
    carmen_far = carmen_log(folder / "far.log", n=3)
    text = carmen_far.read_text().splitlines()
    text[-1] = text[-1].replace(" 0.100 0.040 0.020 0.100", " 1000000.100 0.040 0.020 0.100", 1)
    carmen_far.write_text("\n".join(text) + "\n")
    inputs = [log, yaml_path, carmen, carmen_neg, carmen_huge, carmen_far]
    out = folder / "o.mcap"
    usage = {
        "seed-negative": ["rose", "score", str(yaml_path), "--seed", "-1"],
        "seed-2p33": ["rose", "score", str(yaml_path), "--seed", str(2**33)],
        "bag-seed-2p33": ["rose-bag", "process", str(log), "--no-output", "--seed", str(2**33)],
        "occupied-threshold": ["rose", "score", str(yaml_path), "--occupied-threshold", "500"],
        "max-cells-zero": ["rose", "score", str(yaml_path), "--max-cells", "0"],
        "fail-above-nan": ["rose-bag", "process", str(log), "--no-output", "--fail-above", "nan"],
        "convert-drift-nan": ["rose-bag", "convert", str(carmen), str(out), "--drift-level", "nan"],
        "convert-period-inf": ["rose-bag", "convert", str(carmen), str(out), "--map-period", "inf"],
        "convert-max-scans-0": ["rose-bag", "convert", str(carmen), str(out), "--max-scans", "0"],
        "convert-resolution-0": ["rose-bag", "convert", str(carmen), str(out), "--resolution", "0"],
        "convert-seed-huge": [
            "rose-bag",
            "convert",
            str(carmen),
            str(out),
            "--drift-seed",
            "9" * 50,
        ],
        "walls-min-length-neg": ["rose", "walls", str(yaml_path), "--min-length", "-1"],
    }
    for label, argv in usage.items():
        corpus.add(
            Case(f"usage-{label}", "7 usage", argv, folder, {USAGE}, inputs=inputs, outputs=[out])
        )
    errors = {
        "convert-negative-stamps": ["rose-bag", "convert", str(carmen_neg), str(out)],
        "convert-1e12-stamps": ["rose-bag", "convert", str(carmen_huge), str(out)],
        "convert-pose-1e6": ["rose-bag", "convert", str(carmen_far), str(out)],
        "convert-resolution-1e-6": [
            "rose-bag",
            "convert",
            str(carmen),
            str(out),
            "--resolution",
            "1e-6",
        ],
        "walls-max-cells": ["rose", "walls", str(yaml_path), "--max-cells", "100"],
    }
    for label, argv in errors.items():
        corpus.add(
            Case(
                f"error-{label}",
                "7 traceback / 8 memory",
                argv,
                folder,
                {ERROR},
                inputs=inputs,
                outputs=[out],
            )
        )
    corpus.add(
        Case(
            "ok-convert",
            "baseline",
            ["rose-bag", "convert", str(carmen), str(folder / "conv.mcap"), "--map-period", "2"],
            folder,
            {OK},
            inputs=inputs,
            outputs=[folder / "conv.mcap"],
        )
    )


def _disk_full_cases(corpus: Corpus) -> None:
    """--rrd / -o / --json on a full file system (a 256 KiB tmpfs each; skipped if mount fails)."""
    folder = corpus.folder("disk-full")
    log = folder / "in.mcap"
    rng = np.random.default_rng(5)
    noisy = [{"grid": rng.integers(-1, 101, (300, 400)).astype(np.int8)} for _ in range(3)]
    write_session(log, "mcap", maps=noisy)
    for label, extra in {
        "rrd": ["--no-output", "--rrd", "r.rrd"],
        "output": ["-o", "o.mcap"],
        "json-after-big-log": ["-o", "o.mcap", "--json", "r.json"],
    }.items():
        mount = corpus.root / f"full-{label}"
        mount.mkdir()
        done = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mount)],
            capture_output=True,
            check=False,
        )
        if done.returncode != 0:
            mount.rmdir()
            continue
        corpus.mounts.append(mount)
        argv = ["rose-bag", "process", str(log), "-q"]
        argv += [str(mount / a) if "." in a else a for a in extra]
        corpus.add(
            Case(
                f"disk-full-{label}",
                "7 traceback / 3 commit",
                argv,
                mount,
                {ERROR},
                inputs=[log],
                outputs=[mount / "r.rrd", mount / "o.mcap", mount / "r.json"],
            )
        )


def build_corpus(root: Path) -> Corpus:
    """Write every case under ``root`` (emptied first); return the corpus."""
    if root.exists():
        _unmount_all(root)
        shutil.rmtree(root)
    root.mkdir(parents=True)
    corpus = Corpus(root)
    for make in (
        _damage_cases,
        _metadata_cases,
        _hostile_map_cases,
        _info_cases,
        _fifo_cases,
        _map_file_cases,
        _json_cases,
        _output_cases,
        _signal_cases,
        _concurrent_cases,
        _option_cases,
        _disk_full_cases,
    ):
        make(corpus)
    return corpus


def _unmount_all(root: Path) -> None:
    for mount in root.glob("full-*"):
        if mount.is_mount():
            subprocess.run(["umount", str(mount)], check=False, capture_output=True)


# -- running --------------------------------------------------------------------------------------------
def in_quick_set(case: Case) -> bool:
    """The subset CI runs (every class, fewer repetitions): about half the corpus."""
    name = case.name
    if name.startswith("loss-"):
        keep = any(f"-{d}" in name for d in ("trunc90", "zero4k", "flip0"))
        salvage_ok = "salvage" not in name or "-mcap-dir-" in name or "-mcap-zero" in name
        return keep and salvage_ok
    if name.startswith("meta-mcap-dir-"):
        return any(k in name for k in ("scan-as-map", "count-up", "alias-bomb"))
    if name.startswith("garbage-map-ros1-"):
        return False
    if name.startswith("mapfile-") and not name.endswith(("-score", "name-too-long")):
        return any(k in name for k in ("alias-bomb-clean", "yaw-inf-walls", "origin-nan-walls"))
    return True


def _digest(path: Path) -> str:
    sha = hashlib.sha256()
    if path.is_dir():
        for p in sorted(path.rglob("*")):
            sha.update(p.relative_to(path).as_posix().encode())
            if p.is_file():
                sha.update(p.read_bytes())
    elif path.is_file():
        sha.update(path.read_bytes())
    else:
        sha.update(b"<missing>" if not os.path.lexists(path) else b"<special>")
    return sha.hexdigest()


def _limit() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_LIMIT, ADDRESS_LIMIT))
    os.setsid()
    # A background job inherits SIGINT ignored, and Python then keeps ignoring it: restore the default.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class _PeakWatcher:
    """Peak resident memory of a child after it executed our command (``VmHWM``, polled).

    ``ru_maxrss`` would not do: a child forked from a large parent (pytest) starts with the parent's
    pages resident, and Linux keeps that high-water mark across ``exec``.
    """

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.peak_bytes = 0
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._poll, daemon=True)
        self._thread.start()

    def _poll(self) -> None:
        proc = Path(f"/proc/{self.pid}")
        while not self._done.is_set():
            try:
                if b"from rose" in (proc / "cmdline").read_bytes():  # exec done: ENTRY runs
                    for line in (proc / "status").read_text().splitlines():
                        if line.startswith("VmHWM:"):
                            kib = int(line.split()[1])
                            self.peak_bytes = max(self.peak_bytes, kib * 1024)
            except (OSError, ValueError):  # gone, or a zombie without memory
                pass
            self._done.wait(0.02)

    def stop(self) -> None:
        self._done.set()
        self._thread.join()


def _spawn(case: Case, index: int) -> tuple[int, str, str, int, bool]:
    env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTEST_CURRENT_TEST", None)
    out_path = case.folder.parent / f".{case.name}.{index}.out"
    err_path = case.folder.parent / f".{case.name}.{index}.err"
    with out_path.open("wb") as out, err_path.open("wb") as err:
        proc = subprocess.Popen(
            [sys.executable, "-c", ENTRY[case.argv[0]], *case.argv[1:]],
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=err,
            cwd=case.folder,
            env=env,
            preexec_fn=_limit,
        )
        timed_out = threading.Event()
        watcher = _PeakWatcher(proc.pid)

        def kill() -> None:
            timed_out.set()
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)

        timer = threading.Timer(TIMEOUT_S, kill)
        timer.start()
        if case.signal is not None:
            signum, delay = case.signal
            if delay is None:
                _wait_for_temporaries(case.folder, proc)
            else:
                _wait_for_handlers(proc)
                time.sleep(delay)
            with contextlib.suppress(ProcessLookupError):
                os.kill(proc.pid, signum)
        _pid, status, _usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        timer.cancel()
        watcher.stop()
    code = proc.returncode
    stdout = out_path.read_text(errors="replace")
    stderr = err_path.read_text(errors="replace")
    out_path.unlink()
    err_path.unlink()
    return code, stdout, stderr, watcher.peak_bytes, timed_out.is_set()


def _wait_for_handlers(proc: subprocess.Popen[bytes]) -> None:
    """Return once ``proc`` catches SIGTERM (the CLI's ``main`` installed its handlers) or ended."""
    bit = 1 << (signal.SIGTERM - 1)
    while os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is None:
        with contextlib.suppress(OSError, ValueError):
            for line in Path(f"/proc/{proc.pid}/status").read_text().splitlines():
                if line.startswith("SigCgt:") and int(line.split()[1], 16) & bit:
                    return
        time.sleep(0.002)


def _wait_for_temporaries(folder: Path, proc: subprocess.Popen[bytes]) -> None:
    """Return once a temporary output exists in ``folder`` (the run is writing) or ``proc`` ended."""
    # WNOWAIT: look without reaping, os.wait4 below collects the exit status and resource usage.
    while os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is None:
        if any(any(m in p.name for m in LEFTOVER_MARKS) for p in folder.iterdir()):
            return
        time.sleep(0.01)


def run_case(case: Case) -> Result:
    """Run ``case`` (``copies`` processes at once) and check every promise; problems in the result."""
    before = {p: _digest(p) for p in case.inputs}
    existing = {p: _digest(p) for p in case.outputs if os.path.lexists(p)}
    started = time.perf_counter()
    if case.copies > 1:
        with ThreadPoolExecutor(case.copies) as pool:
            runs = list(pool.map(lambda i: _spawn(case, i), range(case.copies)))
    else:
        runs = [_spawn(case, 0)]
    result = Result(
        case=case,
        codes=[r[0] for r in runs],
        stdout="".join(r[1] for r in runs),
        stderr="".join(r[2] for r in runs),
        seconds=time.perf_counter() - started,
        max_rss=max(r[3] for r in runs),
        timed_out=any(r[4] for r in runs),
    )
    problems = result.problems
    if result.timed_out:
        problems.append(f"hang: killed after {TIMEOUT_S:.0f} s")
    if "Traceback" in result.stderr:
        problems.append("traceback: " + result.stderr.strip().splitlines()[-1][:200])
    unexpected = [c for c in result.codes if c not in case.expect]
    if unexpected and not result.timed_out:
        problems.append(
            f"exit {unexpected} not in {sorted(case.expect)}: {_last_line(result.stderr)}"
        )
    for path, digest in before.items():
        if _digest(path) != digest:
            problems.append(f"modified input: {path.name}")
    leftovers = [
        p.name for p in case.folder.rglob(".*") if any(m in p.name for m in LEFTOVER_MARKS)
    ]
    if leftovers:
        problems.append(f"partial output: temporaries left {leftovers[:3]}")
    failed = all(c not in (OK, GATE, SALVAGED) for c in result.codes)
    for path in case.outputs:
        if failed and os.path.lexists(path) and existing.get(path) != _digest(path):
            problems.append(f"partial output: {path.name} written by a failed run")
        if result.codes == [OK] and not os.path.lexists(path):
            problems.append(f"missing output: {path.name}")
    if failed and ERROR in result.codes:
        line = _last_line(result.stderr)
        if not line.startswith("error: ") or len(line) > 400:
            problems.append(f"error message not one short line: {line[:120]!r}")
    if failed and result.max_rss > REJECTED_RSS_LIMIT:
        problems.append(f"memory: {result.max_rss / 2**20:.0f} MiB for a rejected input")
    if case.check is not None and not result.timed_out:
        try:
            extra = case.check(result)
        except Exception as err:
            extra = f"check failed: {type(err).__name__}: {err}"
        if extra:
            problems.append(extra)
    return result


def _last_line(text: str) -> str:
    lines = [line for line in text.strip().splitlines() if line.strip()]
    return lines[-1] if lines else ""


def run_corpus(corpus: Corpus, *, jobs: int = 2) -> list[Result]:
    """Run every case, ``jobs`` folders at a time (signal and concurrency cases alone).

    Cases that share a folder run one after the other: the leftover and partial-output checks look at
    the whole folder, so a neighbour's temporary file mid-run must not count against a case.
    """
    solo = [c for c in corpus.cases if c.signal is not None or c.copies > 1]
    by_folder: dict[Path, list[Case]] = {}
    for case in corpus.cases:
        if case not in solo:
            by_folder.setdefault(case.folder, []).append(case)
    with ThreadPoolExecutor(jobs) as pool:
        groups = list(pool.map(lambda cases: [run_case(c) for c in cases], by_folder.values()))
    results = [r for group in groups for r in group]
    results += [run_case(c) for c in solo]
    return results


def summary(results: Sequence[Result]) -> str:
    kinds = ("traceback", "hang", "modified input", "partial output", "silent loss", "memory")
    lines = [f"{len(results)} cases, {sum(len(r.case.argv) > 0 for r in results)} commands"]
    failed = [r for r in results if r.problems]
    for kind in kinds:
        n = sum(any(p.startswith(kind) for p in r.problems) for r in results)
        lines.append(f"  {kind:<15} {n}")
    lines.append(f"  {'other problems':<15} {sum(1 for r in failed) - 0}")
    rejected = [r for r in results if all(c not in (OK, GATE, SALVAGED) for c in r.codes)]
    if rejected:
        worst = max(rejected, key=lambda r: r.max_rss)
        lines.append(
            f"  peak RSS of a rejected input: {worst.max_rss / 2**20:.0f} MiB ({worst.case.name})"
        )
    worst_all = max(results, key=lambda r: r.max_rss)
    lines.append(
        f"  peak RSS of any case: {worst_all.max_rss / 2**20:.0f} MiB ({worst_all.case.name})"
    )
    codes: dict[int, int] = {}
    for r in results:
        for c in r.codes:
            codes[c] = codes.get(c, 0) + 1
    lines.append("  exit codes: " + ", ".join(f"{c}: {n}" for c, n in sorted(codes.items())))
    slowest = sorted(results, key=lambda r: -r.seconds)[:5]
    lines.append("  slowest: " + ", ".join(f"{r.case.name} {r.seconds:.1f} s" for r in slowest))
    for r in failed:
        lines.append(f"FAIL {r.case.name}: {'; '.join(r.problems)}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "root", type=Path, nargs="?", default=Path(tempfile.gettempdir()) / "rose-hostile-corpus"
    )
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("-k", default=None, help="only cases whose names contain one of A,B,...")
    parser.add_argument("--quick", action="store_true", help="the CI subset (in_quick_set)")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    corpus = build_corpus(args.root)
    if args.quick:
        corpus.cases = [c for c in corpus.cases if in_quick_set(c)]
    if args.k:
        keys = args.k.split(",")
        corpus.cases = [c for c in corpus.cases if any(k in c.name for k in keys)]
    built = time.perf_counter() - started
    try:
        results = run_corpus(corpus, jobs=args.jobs)
    finally:
        _unmount_all(args.root)
    print(summary(results))
    print(f"built in {built:.1f} s, ran in {time.perf_counter() - started - built:.1f} s")
    return 1 if any(r.problems for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
