"""``rose-bag`` command: process on the sample, info, JSON report, gate, topic selection."""

from __future__ import annotations

import io
import json
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import START_NS, MapMsg, build_log, session_maps

from rose_logs.cli import EXIT_GATE, main
from rose_logs.session import default_output_path

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
MAP15 = (
    Path(__file__).resolve().parents[2]
    / "tests/data/rose2_aislabunimi/Freiburg_Building_079_partial/map15.yaml"
)


def test_process_sample_with_rerun_and_json(tmp_path: Path, capsys) -> None:
    out, rrd, report = tmp_path / "cleaned.mcap", tmp_path / "session.rrd", tmp_path / "r.json"
    code = main(["process", str(SAMPLE), "-o", str(out), "--rrd", str(rrd), "--json", str(report)])
    stdout = capsys.readouterr().out
    assert code == 0
    assert out.is_file() and rrd.is_file()
    assert re.search(r"^  snapshots    14$", stdout, re.M)
    data = json.loads(report.read_text())
    assert len(data["snapshots"]) == 14
    # The summary's W line and break line say what the JSON report says.
    scores = [s["structure_score"] for s in data["snapshots"]]
    expected_w = (
        f"  W            min {min(scores):.3f}  median {statistics.median(scores):.3f}  "
        f"max {max(scores):.3f}"
    )
    assert expected_w in stdout.splitlines()
    assert max(scores) < 0.4
    assert "  W > 0.4      never" in stdout.splitlines()
    first = data["snapshots"][0]
    assert {
        "stamp_ns",
        "width",
        "height",
        "structure_score",
        "directions_deg",
        "threshold",
        "occupied",
        "clutter",
        "seconds",
    } <= set(first)
    assert (first["width"], first["height"]) == (1152, 736)
    assert data["topics"]["/map"]["first_break"] is None


def test_info(capsys) -> None:
    from mcap.reader import make_reader

    assert main(["info", str(SAMPLE)]) == 0
    out = capsys.readouterr().out
    # Counts from the MCAP's own summary section, read with the mcap package (not rose_logs).
    with SAMPLE.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None and summary.statistics is not None
    per_topic = {
        summary.channels[cid].topic: n
        for cid, n in summary.statistics.channel_message_counts.items()
    }
    assert re.search(rf"^messages     {summary.statistics.message_count}$", out, re.M)
    assert re.search(rf"^  /clock +{per_topic['/clock']}  rosgraph_msgs/msg/Clock$", out, re.M)
    assert re.search(
        rf"^  /map +{per_topic['/map']}  nav_msgs/msg/OccupancyGrid  \[map\]$", out, re.M
    )
    assert "  grid sizes   1152 x 736" in out.splitlines()
    assert "  resolution   0.05 m" in out.splitlines()


def test_info_counts_map_topics_as_read_when_the_index_undercounts_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An MCAP whose statistics say 2 of its 6 maps: info warned of 6, then printed 2."""
    import struct
    import zlib

    grids = [np.full((30, 40), -1, dtype=np.int8) for _ in range(6)]
    path = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(grids), scans_per_map=0).path
    data = bytearray(path.read_bytes())
    pos = 8  # after the magic: records are opcode (1 byte), length (8 bytes), content
    while data[pos] != 0x0B:  # the Statistics record
        pos += 9 + struct.unpack_from("<Q", data, pos + 1)[0]
    entries = pos + 9 + 8 + 2 + 4 * 4 + 8 + 8 + 4  # its channel message counts: (u16, u64) each
    assert struct.unpack_from("<Q", data, entries + 2)[0] == 6
    struct.pack_into("<Q", data, entries + 2, 2)
    # A writer that miscounts writes the summary's CRC over its wrong counts (a CRC that does not
    # match is damage, read around: test_formats).
    summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 4 - 16)[0]
    struct.pack_into("<I", data, len(data) - 12, zlib.crc32(data[summary_start : len(data) - 12]))
    path.write_bytes(bytes(data))
    assert main(["info", str(path)]) == 0
    out, err = capsys.readouterr()
    assert "/map has 6 messages, its index says 2" in err
    assert "messages     6\n" in out and re.search(r"/map\s+6\s", out)


def test_info_counts_empty_maps_as_empty_not_malformed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A map of no cells is valid (process counts it as empty); info called it malformed."""
    maps = [
        MapMsg(START_NS + 1_000_000_000, np.zeros((0, 0), dtype=np.int8)),
        MapMsg(START_NS + 2_000_000_000, np.zeros((30, 40), dtype=np.int8)),
        MapMsg(START_NS + 3_000_000_000, np.zeros((30, 40), dtype=np.int8), bad_length=True),
    ]
    path = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=0).path
    assert main(["info", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "  empty        1" in lines and "  malformed    1" in lines
    only_empty = build_log(tmp_path / "empty.mcap", "mcap-ros2", maps[:1], scans_per_map=0).path
    assert main(["info", str(only_empty)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "  empty        1" in lines
    assert not any(line.startswith(("  malformed", "  no messages")) for line in lines)


def test_a_topic_named_with_a_newline_stays_on_its_line_in_the_summaries(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    grid = np.full((30, 40), -1, dtype=np.int8)
    maps = [MapMsg(START_NS + 5_000_000_000, grid, topic="/ma\np")]
    path = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=0).path
    assert main(["info", str(path)]) == 0
    assert "\nmap topic    /ma\\np\n" in capsys.readouterr().out
    assert main(["process", str(path), "--no-output", "-q"]) == 0
    assert "\nmap topic    /ma\\np\n" in capsys.readouterr().out


def test_a_log_named_with_a_newline_stays_on_its_line_in_the_summaries(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """info's ``file`` line and process's ``input`` / ``output`` lines printed the name raw: a
    newline in it split the line (topics and error lines were escaped already)."""
    grid = np.full((30, 40), -1, dtype=np.int8)
    maps = [MapMsg(START_NS + 5_000_000_000, grid)]
    path = build_log(tmp_path / "i\nn.mcap", "mcap-ros2", maps, scans_per_map=0).path
    assert main(["info", str(path)]) == 0
    assert capsys.readouterr().out.startswith(f"file         {tmp_path}/i\\nn.mcap\nformat ")
    out = tmp_path / "o\nut.mcap"
    assert main(["process", str(path), "-o", str(out), "-q"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith(f"input        {tmp_path}/i\\nn.mcap (mcap, ")
    assert f"output       {tmp_path}/o\\nut.mcap" in lines
    assert out.is_file()


def test_info_prints_a_name_that_is_not_utf8_as_its_bytes(
    tmp_path: Path, capsysbinary: pytest.CaptureFixture[bytes]
) -> None:
    """Names that do not print are escaped, but bytes that are not UTF-8 are printed as they are
    on standard output (the README)."""
    grid = np.full((30, 40), -1, dtype=np.int8)
    maps = [MapMsg(START_NS + 5_000_000_000, grid)]
    raw = tmp_path / os.fsdecode(b"r\xffx.mcap")
    build_log(raw, "mcap-ros2", maps, scans_per_map=0)
    assert main(["info", str(raw)]) == 0
    expected = b"file         " + os.fsencode(raw) + b"\nformat "
    assert capsysbinary.readouterr().out.startswith(expected)


def test_info_shows_a_maps_sizes_in_the_order_they_came(tmp_path: Path, capsys) -> None:
    """Eight sizes: the first three and the last three as they came (the six smallest hid a
    growing map's final size)."""
    grids = [np.zeros((10 + n, 20 + n), dtype=np.int8) for n in range(8)]
    order = (7, 6, 5, 4, 0, 1, 2, 3)  # not sorted by size
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps([grids[n] for n in order]))
    assert main(["info", str(built.path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    expected = [f"{20 + n} x {10 + n}" for n in order]
    shown = ", ".join([*expected[:3], "...", *expected[-3:]])
    assert f"  grid sizes   {shown} (8 sizes)" in lines
    # A map that ends at a size it had before says so.
    back = build_log(
        tmp_path / "back.mcap", "mcap-ros2", session_maps([grids[0], grids[1], grids[0]])
    )
    assert main(["info", str(back.path)]) == 0
    assert "  grid sizes   20 x 10, 21 x 11, last 20 x 10" in capsys.readouterr().out.splitlines()


def test_the_command_keeps_map_arrays_on_the_heap(monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    # rose-bag tunes malloc once per process (rose_logs.malloc): 15 % less wall time on a batch.
    import platform

    import rose_logs.cli
    from rose_logs.malloc import keep_arrays_on_heap

    calls: list[bool] = []
    monkeypatch.setattr(rose_logs.cli, "keep_arrays_on_heap", lambda: calls.append(True) or True)
    assert main(["info", str(SAMPLE)]) == 0
    assert calls == [True]
    if platform.libc_ver()[0] == "glibc":
        assert keep_arrays_on_heap()


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc/self/status (glibc on Linux)")
def test_free_heap_goes_back_to_the_system() -> None:
    """The heap the arrays of a finished session left free is given back (the Rerun footer was
    built on top of it: the session's peak)."""
    import platform

    if platform.libc_ver()[0] != "glibc":
        pytest.skip("glibc's malloc_trim")
    script = """
import numpy as np
from rose_logs.malloc import keep_arrays_on_heap, release_free_heap
def rss_mib():
    return next(int(l.split()[1]) // 1024 for l in open("/proc/self/status") if l.startswith("VmRSS"))
keep_arrays_on_heap()
arrays = [np.ones(2**20, np.uint8) for _ in range(100)]  # 100 MiB on the heap, then freed
last = arrays[-1]  # the heap's top stays in use: glibc's own trimming cannot give the rest back
del arrays
held = rss_mib()
assert release_free_heap()
print(held, rss_mib())
"""
    held, after = map(
        int,
        subprocess.run(
            [sys.executable, "-c", script], check=True, capture_output=True, text=True
        ).stdout.split(),
    )
    assert held - after > 80, (held, after)


def test_gate_and_json_break(tmp_path: Path, capsys, fr079, broken_grid) -> None:
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps([fr079[0], broken_grid]))
    report = tmp_path / "r.json"
    code = main(
        ["process", str(built.path), "--no-output", "--json", str(report), "--fail-above", "0.4"]
    )
    out, err = capsys.readouterr()
    assert code == EXIT_GATE
    data = json.loads(report.read_text())
    first_w = data["topics"]["/map"]["first_w_above"]
    assert first_w["index"] == 1
    # The gate names the first snapshot past the level (when the map broke), then the worst.
    w = first_w["structure_score"]
    assert (
        f"W = {w:.3f} on /map snapshot 1 (5.0 s into the log) exceeds --fail-above 0.4 first; "
        f"highest: W = {w:.3f} on snapshot 1" in err
    )
    # The summary names the same snapshot, 5 s after the log's first message (the first map).
    assert (
        f"  W > 0.4      first at snapshot 1, +5.0 s (W = {first_w['structure_score']:.3f})"
        in out.splitlines()
    )
    assert main(["process", str(built.path), "--no-output", "--fail-above", "0.9", "-q"]) == 0


def test_the_gate_names_the_topic_of_the_highest_w_when_another(
    tmp_path: Path, capsys, fr079, broken_grid
) -> None:
    """Two map topics, the first past the level on one, the highest W on the other: the message
    said "highest: ... on snapshot 1" of the first topic, which has no such W."""
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], topic="/robot2/map"),
        MapMsg(START_NS + 2_000_000_000, fr079[0]),
        MapMsg(START_NS + 3_000_000_000, broken_grid),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    code = main(["process", str(built.path), "--no-output", "--fail-above", "0.01"])
    _, err = capsys.readouterr()
    assert code == EXIT_GATE
    line = next(line for line in err.splitlines() if "exceeds --fail-above" in line)
    assert "on /robot2/map snapshot 0" in line
    assert re.search(r"highest: W = [0-9.]+ on /map snapshot 1$", line), line


def test_a_failed_gate_is_one_line_whatever_the_inputs_name(tmp_path: Path, capsys, fr079) -> None:
    """The gate's error line printed the input's name raw: a newline in it split the line."""
    named = tmp_path / "nl\nname.mcap"
    build_log(named, "mcap-ros2", session_maps(fr079[:1]))
    assert main(["process", str(named), "--no-output", "-q", "--fail-above", "0.01"]) == EXIT_GATE
    lines = capsys.readouterr().err.splitlines()
    assert lines and all(line.startswith(("error: ", "warning: ")) for line in lines), lines
    assert any("nl\\nname.mcap: W = " in line for line in lines)  # as in every other line


def test_fail_on_break_gate_and_json_first_break(
    tmp_path: Path, capsys, fr079, broken_grid
) -> None:
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps([*fr079, broken_grid]))
    report = tmp_path / "r.json"
    args = ["process", str(built.path), "--no-output", "-q", "--json", str(report)]
    assert main(args) == 0  # no gate asked for
    assert main([*args, "--force", "--fail-on-break"]) == EXIT_GATE
    out, err = capsys.readouterr()
    assert "map breaks at snapshot 3" in err and "--fail-on-break" in err
    assert "break        first at snapshot 3" in out
    data = json.loads(report.read_text())
    first = data["topics"]["/map"]["first_break"]
    assert first["index"] == 3 and first["trusted_index"] == 2
    assert first["log_time_ns"] == data["snapshots"][3]["log_time_ns"]
    assert first["time_s"] == data["snapshots"][3]["time_s"]
    region = first["region_m"]
    assert region["x_min"] < region["x_max"] and region["y_min"] < region["y_max"]
    # Cell edges in metres without the float32 resolution's noise, and the summary says the same.
    assert all(round(v, 3) == v for v in region.values())
    said = re.search(r"x (\S+)\.\.(\S+) m, y (\S+)\.\.(\S+) m\)", out)
    assert said is not None and "e" not in said.group(0)  # no exponent (UTM northings)
    x0, x1, y0, y1 = (float(v) for v in said.groups())
    assert (x0, y0, x1, y1) == tuple(region[k] for k in ("x_min", "y_min", "x_max", "y_max"))
    # The gate's error line (the event text, also in Rerun) gives the region as the summary does.
    assert said.group(0)[:-1] in err
    scores = [s["break_score_m"] for s in data["snapshots"]]
    assert all(round(v, 3) == v for v in scores)  # mm: no 400.000006
    assert max(scores[:3]) < data["break_threshold_m"] <= scores[3]
    # Numbers as written in the messages and rounded alike: the float32 0.05 reads 0.05.
    assert data["topics"]["/map"]["break_score_max_m"] == max(scores)
    assert {s["resolution_m"] for s in data["snapshots"]} == {0.05}
    assert data["topics"]["/map"]["first_w_above"]["index"] == 3
    gates = data["gates"]
    assert gates["fail_on_break"] and gates["fail_above"] is None
    (reason,) = gates["failed"]
    assert f"error: {built.path}: {reason}" in err  # as the error line says it


def test_topic_selection_and_rose_params(tmp_path: Path, capsys, fr079) -> None:
    maps = [
        MapMsg(START_NS, fr079[0], topic="/map"),
        MapMsg(START_NS + 1, fr079[1], topic="/local_map"),
    ]
    built = build_log(tmp_path / "in.bag", "ros1", maps)
    code = main(
        [
            "process",
            str(built.path),
            "-t",
            "/local_map",
            "--threshold-mode",
            "fixed",
            "--clutter-value",
            "unknown",
            "-q",
        ]
    )
    stdout = capsys.readouterr().out
    assert code == 0
    assert "map topic    /local_map" in stdout
    assert "map topic    /map\n" not in stdout
    assert default_output_path(built.path).is_file()
    assert main(["process", str(built.path), "-t", "/nope", "--no-output"]) == 1
    assert "no topic /nope" in capsys.readouterr().err


def test_a_map_in_a_log_gets_the_w_and_threshold_rose_score_gives_it(
    tmp_path: Path, capsys
) -> None:
    """The same map read from a file and from a log: equal W and threshold in both JSON reports
    (rose-bag's were unrounded, rose's six decimals: equal values compared unequal, and a gate
    read from one decided otherwise than from the other)."""
    import rose
    from rose.cli import main as rose_main

    assert rose_main(["score", "--json", str(MAP15)]) == 0
    from_file = json.loads(capsys.readouterr().out)
    from_file = from_file[0] if isinstance(from_file, list) else from_file
    built = build_log(
        tmp_path / "in.mcap", "mcap-ros2", [MapMsg(START_NS, rose.load_map(MAP15).grid)]
    )
    report = tmp_path / "r.json"
    assert main(["process", str(built.path), "--no-output", "--json", str(report), "-q"]) == 0
    (snapshot,) = json.loads(report.read_text())["snapshots"]
    assert snapshot["structure_score"] == from_file["structure_score"]
    assert snapshot["threshold"] == from_file["threshold"]
    assert snapshot["structure_score"] == rose.analyze(rose.load_map(MAP15).grid).structure_score


def test_the_default_output_name_has_the_suffix_of_the_format_asked_for(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # --format mcap on a ROS 1 bag wrote MCAP into in.rose.bag, and --format db3 on an MCAP file a
    # bag folder named in.rose.mcap: names that tools open as the wrong format.
    from rose_logs.formats import detect_format

    maps = session_maps([np.full((40, 40), -1, dtype=np.int8)])
    bag = build_log(tmp_path / "in.bag", "ros1", maps).path
    assert main(["process", str(bag), "--format", "mcap", "-q"]) == 0
    assert detect_format(tmp_path / "in.rose.mcap") == "mcap"
    assert not (tmp_path / "in.rose.bag").exists()
    mcap = build_log(tmp_path / "m.mcap", "mcap-ros2", maps).path
    assert main(["process", str(mcap), "--format", "db3", "-q"]) == 0
    assert detect_format(tmp_path / "m.rose") == "db3"
    assert main(["process", str(mcap), "-q"]) == 0  # no --format: the input's suffix
    assert detect_format(tmp_path / "m.rose.mcap") == "mcap"
    capsys.readouterr()


def test_usage_errors_exit_2(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["process"])
    assert exc.value.code == 2
    with pytest.raises(SystemExit) as exc:
        main(["process", "x.bag", "--peak-prominence", "2"])
    assert exc.value.code == 2


@pytest.mark.parametrize(
    ("argv", "usage"),
    [
        (["process", "x.mcap", "--bogus"], "rose-bag process"),
        (["info", "x.mcap", "--bogus"], "rose-bag info"),
        (["convert", "x.log", "x.mcap", "--bogus"], "rose-bag convert"),
        (["evaluate", "out", "--bogus"], "rose-bag evaluate"),
        (["batch", "x", "-o", "out", "--bogus"], "rose-bag batch"),
        (["--bogus", "info", "x.mcap"], "rose-bag"),  # before the command: the top level's
    ],
)
def test_an_unknown_option_is_a_usage_error_of_the_parser_it_follows(
    argv: list[str], usage: str, capsys
) -> None:
    """`rose-bag process x.mcap --bogus` showed the top-level usage (`rose-bag [-h] ... COMMAND`)."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usage: {usage} [-h]")
    assert err.splitlines()[-1] == f"{usage}: error: unrecognized arguments: --bogus"


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["process", "x.bag", "-o", ""], "expected a path, got an empty string"),
        (["process", "x.bag", "--json", ""], "expected a path, got an empty string"),
        (["batch", "x.bag", "-o", ""], "expected a path, got an empty string"),
        # `batch "$FLEET" -o out` with FLEET unset batched the current folder whole.
        (["batch", "", "-o", "out"], "argument INPUT: expected a path, got an empty string"),
        (["process", "x.bag", "--max-cells", "1.5"], "whole number of cells"),
        (["process", "x.bag", "--connect", "99999"], "rose-bag process: error: argument --connect"),
    ],
)
def test_bad_values_are_usage_errors_naming_the_command(
    argv: list[str], said: str, tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An empty output path read as the current folder ("refusing to write over the input", or
    batch tables written into it), and so did an empty batch input; 1.5 cells were silently 1."""
    monkeypatch.chdir(tmp_path)
    try:
        code = main(argv)
    except SystemExit as stop:
        code = stop.code
    assert code == 2
    assert said in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["rose-bag", "info", "s3://x/y.mcap"], "only rose-bag batch reads URLs"),
        (["rose-bag", "process", "s3://x/y.mcap", "--no-output"], "only rose-bag batch reads URLs"),
        (["rose-bag", "process", "x.mcap", "-o", "s3://x/o.mcap"], "only rose-bag batch writes"),
        (["rose-bag", "process", "x.mcap", "--json", "http://x/r.json"], "only rose-bag batch"),
        (["rose-bag", "convert", "http://x/a.log", "a.mcap"], "only rose-bag batch reads URLs"),
        (["rose-bag", "convert", "a.log", "s3://x/a.mcap"], "only rose-bag batch writes"),
        (["rose-bag", "evaluate", "s3://x/e2"], "only rose-bag batch writes"),
        (["rose", "score", "http://x/map.yaml"], "maps are read from local files"),
        (["rose", "clean", "https://x/map.yaml", "-o", "o.yaml"], "maps are read from local"),
        (["rose", "walls", "file:///x/map.yaml"], "maps are read from local files"),
        (["rose", "clean", "m.yaml", "-o", "s3://x/o.yaml"], "only rose-bag batch writes"),
    ],
)
def test_a_url_outside_batch_is_a_usage_error_naming_it_as_typed(
    argv: list[str], said: str, tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`rose-bag info s3://x/y.mcap` said `s3:/x/y.mcap: no such file or directory`: a path the user
    never typed (Path folds the //), and no word of which command reads URLs."""
    from rose.cli import main as rose_main

    monkeypatch.chdir(tmp_path)
    run = main if argv[0] == "rose-bag" else rose_main
    with pytest.raises(SystemExit) as stop:
        run(argv[1:])
    assert stop.value.code == 2
    url = next(a for a in argv if "://" in a)
    last = capsys.readouterr().err.splitlines()[-1]
    assert last.startswith(f"{argv[0]} {argv[1]}: error: argument ")
    assert f": {url}: a URL; " in last
    assert said in last
    assert list(tmp_path.iterdir()) == []


def test_debug_is_taken_after_the_command_too(tmp_path: Path, capsys, fr079) -> None:
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:1]))
    assert main(["process", str(built.path), "--no-output", "--debug"]) == 0
    assert "debug: " in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv",
    [
        ["rose-bag", "process", "x.bag", "--smoothing", "1e9"],
        ["rose", "score", "m.yaml", "--angular-resolution", "1e-9"],
        ["rose", "score", "m.yaml", "--angular-resolution", "100"],
        ["rose", "score", "m.yaml", "--mask-half-width", "1e300"],
    ],
)
def test_out_of_range_rose_options_are_usage_errors(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """Checked before any file is opened (x.bag and m.yaml do not exist), with the usage."""
    import rose.cli

    command, *args = argv
    with pytest.raises(SystemExit) as exc:
        main(args) if command == "rose-bag" else rose.cli.main(args)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: ") and f"{command} {args[0]}: error: " in err
    # Named by the option the user typed, with its range (was the parameter's internal name).
    assert f"argument {args[2]}: expected a number in " in err and "_deg" not in err


class _ClosedPipe(io.StringIO):
    """Standard output whose reader went away (``| head``), for text and bytes alike."""

    def write(self, text: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")

    def fileno(self) -> int:
        raise io.UnsupportedOperation("no file descriptor")

    @property
    def buffer(self) -> _ClosedPipe:
        return self


@pytest.mark.parametrize(
    "argv",
    [
        ["rose-bag", "info", "{sample}"],
        ["rose-bag", "process", "{sample}", "--no-output", "--json", "-"],
        ["rose", "score", "{map15}"],
        ["rose", "clean", "{map15}", "-o", "{tmp}/c.yaml", "--json", "-"],
        ["rose", "walls", "{map15}", "--geojson", "-"],
    ],
)
def test_a_closed_standard_output_ends_quietly_with_141(
    argv: list[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """`rose-bag info LOG | head -1`: no error line, exit 128 + SIGPIPE, as other tools; the same
    when the report streamed to standard output (``--json -``) finds no reader."""
    import rose.cli

    monkeypatch.setattr(sys, "stdout", _ClosedPipe())
    command, *args = (a.format(sample=SAMPLE, map15=MAP15, tmp=tmp_path) for a in argv)
    code = main(args) if command == "rose-bag" else rose.cli.main(args)
    assert code == 141
    assert capsys.readouterr().err == ""


def test_without_a_standard_error_the_summary_stays_out_of_the_report(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Started with standard error closed (``2>&-``: sys.stderr is None), the summary that
    ``--json -`` sends to standard error, and the failed gate's `error:` line, were printed to
    standard output after the report (``print(file=None)``): the JSON there no longer parsed."""
    monkeypatch.setattr(sys, "stderr", None)
    argv = ["process", str(SAMPLE), "--no-output", "--json", "-", "-q", "--fail-above", "0.01"]
    assert main(argv) == EXIT_GATE
    assert sys.stderr is None  # as it was
    report = json.loads(capsys.readouterr().out)
    assert len(report["gates"]["failed"]) == 1


class _PipeClosingMidWrite(_ClosedPipe):
    """A reader that leaves after 1,000 bytes: the write that spans that point takes part of its
    data and reports the count (as an unbuffered stream does, ``python -u``), the next breaks."""

    taken = 0

    def write(self, data: Any) -> int:
        if self.taken >= 1000:
            raise BrokenPipeError(32, "Broken pipe")
        count = min(len(data), 1000 - self.taken)
        self.taken += count
        return count


def test_a_reader_leaving_mid_report_is_141_not_a_cut_report(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--json - | head -1`` on a long session exited 0 with the report cut: the short count of
    the write was not looked at."""
    monkeypatch.setattr(sys, "stdout", _PipeClosingMidWrite())
    assert main(["process", str(SAMPLE), "--no-output", "--json", "-", "-q"]) == 141
    assert capsys.readouterr().err == ""


def test_an_unbuffered_standard_output_whose_reader_leaves_is_141_not_a_cut_report(
    tmp_path: Path,
) -> None:
    """``PYTHONUNBUFFERED=1 rose score --json MAPS... | head -c 10`` exited 0 with the JSON cut:
    unbuffered, the write the reader left in took part of the report and reported no error. A
    real pipe, a real unbuffered interpreter; the report (over 64 kB) fills the pipe first."""
    image = np.full((40, 40), 254, np.uint8)
    image[5, :] = 0
    import cv2

    cv2.imwrite(str(tmp_path / "room.png"), image)
    env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONPATH=str(Path(__file__).parents[2]))
    with subprocess.Popen(
        [sys.executable, "-c", "import rose.cli as c; c.console()", "score", "--json"]
        + [str(tmp_path / "room.png")] * 400,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    ) as child:
        assert child.stdout is not None and child.stderr is not None
        assert child.stdout.read(10) == b"[\n  {\n    "
        child.stdout.close()  # the reader leaves (| head -c 10)
        err = child.stderr.read()
        assert child.wait(timeout=120) == 141, err
    assert err == b""


class _StuckPipe(_ClosedPipe):
    """A stream that takes nothing and reports no error."""

    def write(self, data: Any) -> int:
        return 0


def test_a_stream_that_takes_nothing_is_an_error_not_a_hang(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(sys, "stdout", _StuckPipe())
    assert main(["process", str(SAMPLE), "--no-output", "--json", "-", "-q"]) == 1
    assert (
        "standard output: cannot write (the stream takes no more data)" in capsys.readouterr().err
    )


class _FullDevice(_ClosedPipe):
    """Standard output on a full disk (``> /dev/full``): every write fails, without a file name."""

    def write(self, data: Any) -> int:
        raise OSError(28, "No space left on device")


@pytest.mark.parametrize(
    "argv",
    [
        ["rose-bag", "info", "{sample}"],
        ["rose-bag", "process", "{sample}", "--no-output"],
        ["rose-bag", "process", "{sample}", "--no-output", "--json", "-"],
        ["rose", "score", "{map15}"],
        ["rose", "score", "{map15}", "--json"],
        ["rose", "walls", "{map15}", "--geojson", "-"],
    ],
)
def test_a_full_standard_output_is_named_not_the_input(
    argv: list[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """`rose score m.yaml > /dev/full` said `m.yaml: No space left on device`: the error has no file
    name, and the command's input was put in its place."""
    import rose.cli

    monkeypatch.setattr(sys, "stdout", _FullDevice())
    command, *args = (a.format(sample=SAMPLE, map15=MAP15, tmp=tmp_path) for a in argv)
    code = main(args) if command == "rose-bag" else rose.cli.main(args)
    assert code == 1
    err = capsys.readouterr().err.splitlines()
    assert err[-1] == "error: standard output: cannot write (No space left on device)", err


@pytest.mark.parametrize(
    ("argv", "written"),
    [
        (
            [
                "rose-bag",
                "process",
                "{sample}",
                "-q",
                "-o",
                "{tmp}/o.mcap",
                "--json",
                "{tmp}/r.json",
            ],
            ["r.json", "o.mcap"],
        ),
        (["rose", "clean", "{map15}", "-o", "{tmp}/c.yaml"], ["c.pgm", "c.yaml"]),
    ],
)
def test_a_full_standard_output_after_the_files_says_they_are_complete(
    argv: list[str],
    written: list[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The summary is printed after the outputs stand: failing (``> /dev/full``) it said only
    `standard output: cannot write`, exit 1, which read as if nothing had been written."""
    import rose.cli

    monkeypatch.setattr(sys, "stdout", _FullDevice())
    command, *args = (a.format(sample=SAMPLE, map15=MAP15, tmp=tmp_path) for a in argv)
    code = main(args) if command == "rose-bag" else rose.cli.main(args)
    assert code == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(written)
    names = ", ".join(str(tmp_path / name) for name in written)
    assert capsys.readouterr().err.splitlines()[-1] == (
        "error: standard output: cannot write (No space left on device); the outputs are "
        f"complete ({names}): only the summary is lost"
    )


@pytest.mark.parametrize("stdout", [_FullDevice, _ClosedPipe])
def test_a_lost_summary_keeps_the_gates_exit_code_and_lines(
    stdout: type[io.StringIO],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """`process --fail-above 0.1 --json r.json > /dev/full` (or `| head -1`) exited 1 (141) with
    the report written: a pipeline acting on the gate's 3 lost it, and the line naming the
    failed gate was never said (with unbuffered output the summary's first line failed)."""
    monkeypatch.setattr(sys, "stdout", stdout())
    report = tmp_path / "r.json"
    argv = ["process", str(SAMPLE), "-q", "--no-output", "--json", str(report)]
    code = main([*argv, "--fail-above", "0.1"])
    assert code == EXIT_GATE
    assert json.loads(report.read_text())["gates"]["failed"]
    err = capsys.readouterr().err.splitlines()
    assert any(line.startswith(f"error: {SAMPLE}: W = ") for line in err), err
    if stdout is _FullDevice:  # the summary's loss is said, the outputs complete
        assert err[-1].endswith(f"the outputs are complete ({report}): only the summary is lost")
        # No gate failed: the lost summary is the error (exit 1), as before.
        assert main([*argv, "--force"]) == 1


@pytest.mark.parametrize(
    ("argv", "staged"),
    [
        (
            ["rose-bag", "process", "{sample}", "-q", "-o", "{tmp}/o.mcap", "--json", "-"],
            ["o.mcap"],
        ),
        (["rose", "clean", "{map15}", "-o", "{tmp}/c.yaml", "--json", "-"], ["c.pgm", "c.yaml"]),
    ],
)
def test_a_full_standard_output_before_the_files_says_they_are_not_written(
    argv: list[str],
    staged: list[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """An output ``-`` is written before the files are placed: failing, it leaves none, and the
    line said only `standard output: cannot write`, as when the files were written before the
    summary failed (the test above): which it was could not be told."""
    import rose.cli

    monkeypatch.setattr(sys, "stdout", _FullDevice())
    command, *args = (a.format(sample=SAMPLE, map15=MAP15, tmp=tmp_path) for a in argv)
    code = main(args) if command == "rose-bag" else rose.cli.main(args)
    assert code == 1
    assert list(tmp_path.iterdir()) == []
    names = ", ".join(str(tmp_path / name) for name in staged)
    assert capsys.readouterr().err.splitlines()[-1] == (
        "error: standard output: cannot write (No space left on device); the outputs were not "
        f"written ({names})"
    )


def _run_buffered(command: list[str], stdout: Any) -> subprocess.CompletedProcess[str]:
    """``command`` (``["rose" | "rose-bag", *args]``) as its console script runs it, from this
    checkout, with standard output ``stdout`` buffered (no ``PYTHONUNBUFFERED``)."""
    module = "rose.cli" if command[0] == "rose" else "rose_logs.cli"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[2])
    return subprocess.run(
        [sys.executable, "-c", f"import {module} as c; c.console()", *command[1:]],
        stdout=stdout,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        timeout=120,
        check=False,
    )


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
@pytest.mark.parametrize(
    "command", [["rose", "score", str(MAP15)], ["rose-bag", "info", str(SAMPLE)]]
)
def test_a_full_disk_under_buffered_standard_output_is_one_error_line(command: list[str]) -> None:
    """Buffered (the default, not ``python -u``), the report was written at exit: Python printed
    "Exception ignored ... OSError" and exited 120."""
    with Path("/dev/full").open("w") as full:
        done = _run_buffered(command, full)
    assert done.returncode == 1, done.stderr
    assert done.stderr == "error: standard output: cannot write (No space left on device)\n"


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
@pytest.mark.parametrize(
    "command",
    [
        ["rose", "--help"],
        ["rose", "--version"],
        ["rose", "score", "--help"],
        ["rose-bag", "--help"],
        ["rose-bag", "--version"],
        ["rose-bag", "process", "--help"],
    ],
)
def test_help_and_version_on_a_full_standard_output_are_one_error_line(
    command: list[str],
) -> None:
    """argparse prints ``--help`` and ``--version`` and exits, before the command's own handling of
    standard output: Python's flush at exit printed "Exception ignored ... OSError" and exited
    120, and with the reader gone (``| true``) "BrokenPipeError", exit 120, instead of 141."""
    with Path("/dev/full").open("w") as full:
        done = _run_buffered(command, full)
    assert done.returncode == 1, done.stderr
    assert done.stderr == "error: standard output: cannot write (No space left on device)\n"
    reader, writer = os.pipe()
    os.close(reader)  # the reader left before anything was written
    try:
        done = _run_buffered(command, writer)
    finally:
        os.close(writer)
    assert (done.returncode, done.stderr) == (141, "")


def test_processing_a_processed_log_names_the_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    once, twice = tmp_path / "once.mcap", tmp_path / "twice.mcap"
    assert main(["process", str(SAMPLE), "-o", str(once), "-q"]) == 0
    capsys.readouterr()
    assert main(["process", str(once), "-o", str(twice), "-q"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: {once}: has topic /map/rose/cleaned already")
    assert not twice.exists()


def by_topic(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """Every message of the log at ``path``: topic -> (log time, data), in log order."""
    from rose_logs.reader import LogReader

    topics: dict[str, list[tuple[int, bytes]]] = {}
    with LogReader(path) as reader:
        for message in reader.messages():
            topics.setdefault(message.channel.topic, []).append(
                (message.log_time_ns, bytes(message.data))
            )
    return topics


def test_a_processed_log_gets_its_rose_topics_written_anew_on_request(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Re-cleaning a processed log with other options: --replace-rose-topics leaves the input's
    own <map>/rose/* messages out and writes new ones, as processing the original log would."""
    once, again, direct = (tmp_path / f"{n}.mcap" for n in ("once", "again", "direct"))
    paper = ["--clean-method", "paper", "-q"]
    assert main(["process", str(SAMPLE), "-o", str(once), "-q"]) == 0
    capsys.readouterr()
    assert main(["process", str(once), "-o", str(again), *paper]) == 1
    assert "--replace-rose-topics leaves it out and writes this run's" in capsys.readouterr().err
    assert main(["process", str(once), "-o", str(again), "--replace-rose-topics", *paper]) == 0
    assert main(["process", str(SAMPLE), "-o", str(direct), *paper]) == 0
    got, want, first = by_topic(again), by_topic(direct), by_topic(once)
    assert got == want
    assert len(got["/map/rose/cleaned"]) == len(got["/map"]) == 14
    assert got["/map/rose/cleaned"] != first["/map/rose/cleaned"]  # walls cleaning, then paper


def test_the_rose_topics_of_maps_not_analysed_are_replaced_too(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fr079
) -> None:
    """A log processed for /map, processed again for /local_map: refused without
    --replace-rose-topics (the output would hold /map/rose/* of the first run beside this run's,
    made with other options); with it, /map/rose/* is left out too, as processing the original log
    for /local_map would."""
    maps = [
        MapMsg(START_NS, fr079[0], topic="/map"),
        MapMsg(START_NS + 1, fr079[1], topic="/local_map"),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps).path
    once, again, direct = (tmp_path / f"{n}.mcap" for n in ("once", "again", "direct"))
    second = ["-t", "/local_map", "--clean-method", "paper", "-q"]
    assert main(["process", str(built), "-t", "/map", "-o", str(once), "-q"]) == 0
    capsys.readouterr()
    assert main(["process", str(once), "-o", str(again), *second]) == 1
    assert f"error: {once}: has topic /map/rose/cleaned already" in capsys.readouterr().err
    assert not again.exists()
    assert main(["process", str(once), "-o", str(again), "--replace-rose-topics", *second]) == 0
    assert main(["process", str(built), "-o", str(direct), *second]) == 0
    got = by_topic(again)
    assert got == by_topic(direct)
    assert "/local_map/rose/cleaned" in got and "/map/rose/cleaned" not in got


@pytest.mark.parametrize("prefixes", [("/robot1", "/robot2"), ("", "")])
def test_an_mcap_mixing_ros1_and_ros2_channels_is_read_by_each_channels_encoding(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fr079, prefixes: tuple[str, str]
) -> None:
    """A merged MCAP file (``mcap merge`` of a ROS 1 and a ROS 2 recording): each map decodes by its
    own channel's encoding (the ROS 1 one was read as CDR and skipped as malformed); an output log,
    which holds one kind, is refused in one line. Also when both recordings' maps share a topic
    (two recordings of one robot)."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    ros1 = build_log(tmp_path / "r1.mcap", "mcap-ros1", [MapMsg(START_NS, fr079[0])]).path
    ros2 = build_log(tmp_path / "r2.mcap", "mcap-ros2", [MapMsg(START_NS + 1, fr079[1])]).path
    merged = tmp_path / "merged.mcap"
    with merged.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="test")
        for source, prefix in zip((ros1, ros2), prefixes, strict=True):
            with source.open("rb") as f:
                reader = make_reader(f)
                summary = reader.get_summary()
                assert summary is not None
                schemas = {
                    i: writer.register_schema(s.name, s.encoding, s.data)
                    for i, s in summary.schemas.items()
                }
                channels = {
                    i: writer.register_channel(
                        prefix + c.topic, c.message_encoding, schemas[c.schema_id], c.metadata
                    )
                    for i, c in summary.channels.items()
                }
                for _, channel, message in reader.iter_messages():
                    writer.add_message(
                        channels[channel.id], message.log_time, message.data, message.publish_time
                    )
        writer.finish()
    report = tmp_path / "r.json"
    assert main(["process", str(merged), "--no-output", "--json", str(report), "-q"]) == 0
    topics = json.loads(report.read_text())["topics"]
    maps = [f"{prefix}/map" for prefix in prefixes]
    assert sum(topics[t]["snapshots"] for t in set(maps)) == 2
    assert "cannot decode" not in capsys.readouterr().err
    out = tmp_path / "out.mcap"
    assert main(["process", str(merged), "-o", str(out), "-q"]) == 1
    err = capsys.readouterr().err
    assert (
        err.startswith(f"error: {merged}: mixes ROS 1 and ROS 2 messages") and err.count("\n") == 1
    )
    assert not out.exists()


def test_empty_first_maps_do_not_trip_the_w_gate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fr079
) -> None:
    """A SLAM session starts with an all-unknown map (W = 1 by convention): it is no failure."""
    import numpy as np

    empty = np.full_like(fr079[0], -1)
    log = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps([empty, fr079[0]])).path
    report = tmp_path / "r.json"
    code = main(["process", str(log), "--no-output", "--json", str(report), "--fail-above", "0.4"])
    assert code == 0, capsys.readouterr().err
    data = json.loads(report.read_text())
    first, second = data["snapshots"]
    assert first["structure_score"] == 1.0 and first["occupied"] == 0
    topic = data["topics"]["/map"]
    assert topic["w_max"] == second["structure_score"] < 0.4
    assert topic["first_w_above"] is None
    assert "(1 map of fewer than 20 occupied cells left out)" in capsys.readouterr().out
    assert topic["snapshots"] == 2
    # Nor does a map of one occupied cell: no direction to find, W = 1 by convention.
    speck = empty.copy()
    speck[5, 5] = 100
    log = build_log(tmp_path / "speck.mcap", "mcap-ros2", session_maps([speck, fr079[0]])).path
    assert main(["process", str(log), "--no-output", "--fail-above", "0.4"]) == 0


def test_maps_w_cannot_read_are_left_out_of_w_and_the_gate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fr079
) -> None:
    """A solid block reads W = 0.009 ("strong structure") and passed --fail-above 0.4: like a map
    of a few occupied cells, W says nothing about it (rose clean said so, rose-bag did not)."""
    import numpy as np

    solid = np.full((100, 100), 100, dtype=np.int8)
    log = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps([solid, fr079[0]])).path
    report = tmp_path / "r.json"
    code = main(["process", str(log), "--no-output", "--json", str(report), "--fail-above", "0.4"])
    assert code == 0, capsys.readouterr().err
    first, second = json.loads(report.read_text())["snapshots"]
    assert first["structure_score"] < 0.05 and "occupied cells fill the grid" in first["degenerate"]
    assert second["degenerate"] is None
    assert json.loads(report.read_text())["topics"]["/map"]["w_min"] == second["structure_score"]
    assert "(1 map W cannot read (a solid block, a thin strip) left out)" in capsys.readouterr().out
    alone = build_log(tmp_path / "solid.mcap", "mcap-ros2", session_maps([solid])).path
    assert main(["process", str(alone), "--no-output", "--fail-above", "0.4"]) == EXIT_GATE
    assert "in a form W reads (a solid block? a thin strip?), the gate cannot judge it" in (
        capsys.readouterr().err
    )


def test_the_summary_says_why_w_read_none_of_the_maps(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A solid 60 x 50 block or a thin strip has plenty of occupied cells, yet the summary said
    `W none (no map with 20 or more occupied cells W can read)`: it gives the domain check's reason,
    as the JSON's `degenerate` does."""
    import numpy as np

    solid = np.full((50, 60), 100, dtype=np.int8)
    strip = np.zeros((8, 200), dtype=np.int8)
    strip[0] = strip[-1] = 100
    empty = np.full((50, 60), -1, dtype=np.int8)

    def w_line(name: str, grids: list[Any]) -> str:
        log = build_log(tmp_path / f"{name}.mcap", "mcap-ros2", session_maps(grids)).path
        report = tmp_path / f"{name}.json"
        assert main(["process", str(log), "--no-output", "--json", str(report)]) == 0
        (line,) = [s for s in capsys.readouterr().out.splitlines() if s.startswith("  W  ")]
        last = [s["degenerate"] for s in json.loads(report.read_text())["snapshots"]][-1]
        assert last is None or last in line
        return line.split(None, 1)[1]

    assert w_line("solid", [solid]) == (
        "none (W cannot read the map: occupied cells fill the grid (220 cell sides on its "
        "border, 0 inside it))"
    )
    assert w_line("strip", [strip]) == (
        "none (W cannot read the map: a side of 8 cells (fewer than 16, too thin for a 2D "
        "spectrum))"
    )
    assert w_line("both", [solid, strip]).startswith(
        "none (W cannot read any of the 2 maps; the last: a side of 8 cells"
    )
    assert w_line("mixed", [empty, solid]) == (
        "none (W cannot read the map of 20 or more occupied cells: occupied cells fill the grid "
        "(220 cell sides on its border, 0 inside it); 1 map has fewer)"
    )
    assert w_line("empty", [empty]) == "none (no map has 20 or more occupied cells)"


def test_a_library_warning_repeated_by_every_snapshot_is_said_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--walls`` on snapshots without a dominant direction: the library's warning reads like the
    command's own (``warning: ...``), names the map topic and comes once, not once per snapshot."""
    import numpy as np

    grids = []
    for i in range(3):  # one occupied cell each, in another place: nothing is reused
        grid = np.zeros((40, 40), np.int8)
        grid[10 + i, 20] = 100
        grids.append(grid)
    log = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(grids)).path
    assert main(["process", str(log), "--no-output", "--walls", "-q"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: /map: ROSE found no dominant direction") == 1, err
    assert err.count("ROSE found") == 1, err


def test_the_grid_range_runs_from_the_smallest_map_to_the_largest(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import numpy as np

    grids = [np.zeros((1, 50), np.int8), np.zeros((40, 3), np.int8)]  # 50 x 1, then 3 x 40 cells
    log = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(grids)).path
    assert main(["process", str(log), "--no-output", "-q"]) == 0
    assert "grid         50 x 1 .. 3 x 40 cells" in capsys.readouterr().out


def test_info_lists_every_type_a_topic_carries(tmp_path: Path, capsys, fr079) -> None:
    """Two connections on /map, a map and a string: both types are listed, not the last one."""
    from conftest import _map_message, typestore
    from rosbags.rosbag2 import Writer

    store = typestore("cdr")
    bag = tmp_path / "mixed"
    with Writer(bag, version=8) as writer:
        grids = writer.add_connection("/map", "nav_msgs/msg/OccupancyGrid", typestore=store)
        text = writer.add_connection("/map", "std_msgs/msg/String", typestore=store)
        _, data = _map_message(store, "cdr", MapMsg(START_NS, fr079[0]), 1)
        writer.write(grids, START_NS, data)
        hello = store.types["std_msgs/msg/String"](data="hello")
        writer.write(text, START_NS + 1, bytes(store.serialize_cdr(hello, "std_msgs/msg/String")))
    assert main(["info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert re.search(
        r"^  /map +2  nav_msgs/msg/OccupancyGrid, std_msgs/msg/String  \[map\]$", out, re.M
    )


def test_process_help_gives_the_break_detectors_own_default(capsys) -> None:
    from rose_logs.session import BreakParams

    with pytest.raises(SystemExit):
        main(["process", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert f"break (default {BreakParams().threshold_m:g})" in help_text


@pytest.mark.parametrize("command", ["process", "batch"])
def test_the_topic_options_help_says_costmaps_are_left_out(command: str, capsys) -> None:
    """--topic's default left out costmaps and topics without messages, and its help said every
    OccupancyGrid topic."""
    with pytest.raises(SystemExit):
        main([command, "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "default: every OccupancyGrid topic with messages, costmaps left out" in help_text


def test_info_spells_types_as_the_log_does(tmp_path: Path, capsys, fr079) -> None:
    """A ROS 1 bag's types are pkg/Name (info showed the ROS 2 spelling)."""
    built = build_log(tmp_path / "in.bag", "ros1", session_maps(fr079[:1]))
    assert main(["info", str(built.path)]) == 0
    out = capsys.readouterr().out
    assert "nav_msgs/OccupancyGrid  [map]" in out and "nav_msgs/msg/" not in out


def test_a_ros2_log_named_bag_gets_a_default_output_it_can_be_written_in(tmp_path: Path) -> None:
    """An MCAP file named .bag got 'run.rose.bag', ROS 1, which cannot hold its CDR messages: the
    run failed on a name the user never gave. It keeps its own format now."""
    misnamed = tmp_path / "run.bag"
    misnamed.write_bytes(SAMPLE.read_bytes())
    assert main(["process", str(misnamed), "-q"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.bag", "run.rose.mcap"]


def test_a_snapshots_seconds_count_its_analysis_once() -> None:
    """The record's seconds counted the wait for the analysis on top of the analysis's own time:
    in one analysis thread (no two snapshots computed at once) they added up to twice the run."""
    from rose_logs.session import process_log

    report = process_log(SAMPLE, analysis_threads=1)
    total = sum(record.seconds for record in report.records)
    # One snapshot's outputs are written while the next one is analysed: on a busy machine the
    # records may add up to a little more than the run (0.9 of it idle), never twice (1.8 before).
    assert 0 < total <= 1.4 * report.elapsed_s


@pytest.mark.parametrize(
    ("score", "level", "shown"),
    [
        (0.5, 0.4, ("0.500", "0.4")),
        (0.1470001, 0.147, ("0.1470001", "0.147")),  # not "W = 0.147 exceeds 0.147"
        (0.14649, 0.1464, ("0.1465", "0.1464")),  # not "W = 0.146 exceeds 0.1464"
        (0.4000000000000001, 0.4, ("0.4000000000000001", "0.4")),
        (0.14689164, 0.1468918, ("0.14689", "0.1468918")),  # the level as given, not 0.146892
    ],
)
def test_a_gate_message_shows_w_on_its_side_of_the_level(
    score: float, level: float, shown: tuple[str, str]
) -> None:
    from rose_logs.session.report import score_beside_level

    assert score_beside_level(score, level) == shown


def test_maps_finer_than_a_millimetre_are_cleaned_by_the_paper_with_one_warning(
    tmp_path: Path, capsys, fr079
) -> None:
    """The fallback was said once per snapshot (ten lines for ten maps); other warnings once per
    topic."""
    maps = [MapMsg(START_NS + k * 1_000_000_000, fr079[0], resolution_m=0.0005) for k in range(3)]
    maps[1] = MapMsg(START_NS + 1_000_000_000, fr079[1], resolution_m=0.0005)
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    report = tmp_path / "r.json"
    assert main(["process", str(built.path), "--no-output", "-q", "--json", str(report)]) == 0
    warnings = [x for x in capsys.readouterr().err.splitlines() if "finer than 0.001 m" in x]
    assert len(warnings) == 1 and warnings[0].startswith("warning: /map: maps finer than")
    snapshots = json.loads(report.read_text())["snapshots"]
    assert len(snapshots) == 3 and all(s["completed"] == 0 for s in snapshots)


#: What a warning line of ``rose-bag process`` is, by the words that tell it (see _warning_kinds).
_WARNING_WORDS = {
    "not comparable with trusted snapshot 0": "not comparable",
    "paper's labelling as their cleaned map": "cleaning",
    "break detector's longest length": "detector",
    ": map data has": "malformed",
    "said by /c's analysis": "/c analysis",
}


def _warning_kinds(stderr: str) -> list[str]:
    """The ``warning:`` lines of ``stderr`` as their kinds (:data:`_WARNING_WORDS`), in order; a
    line of no known kind as it is."""
    lines = [line for line in stderr.splitlines() if line.startswith("warning:")]
    return [next((k for w, k in _WARNING_WORDS.items() if w in line), line) for line in lines]


def _read_scans_slowly(monkeypatch: pytest.MonkeyPatch, seconds: float) -> None:
    """Make the session pause ``seconds`` at every /scan message it reads (the analyses run ahead)."""
    import time

    from rose_logs.session.loop import _Loop

    step = _Loop._step

    def slow_reading(self, message):  # type: ignore[no-untyped-def]
        if message.channel.topic == "/scan":
            time.sleep(seconds)
        return step(self, message)

    monkeypatch.setattr(_Loop, "_step", slow_reading)


def _said_by_session(
    log: Path, loggers: tuple[str, ...] = ("rose", "rose_logs"), into: list[str] | None = None
) -> list[str]:
    """The messages of WARNING and above that ``process_log`` on ``log`` says on ``loggers`` (and
    their children), in order, also put in ``into`` as said (to read them when it raises)."""
    import logging

    from rose_logs.session import process_log

    said: list[str] = [] if into is None else into

    class Said(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            said.append(record.getMessage())

    handler = Said(logging.WARNING)
    for name in loggers:
        logging.getLogger(name).addHandler(handler)
    try:
        process_log(log, progress=False)
    finally:
        for name in loggers:
            logging.getLogger(name).removeHandler(handler)
    return said


def test_warnings_of_the_analysis_threads_are_said_in_log_order(
    tmp_path: Path, capsys, monkeypatch, fr079
) -> None:
    """The analyses run ahead of the log order, on threads, and the break detector on its own: the
    warnings they gave (a map too fine for the walls cleaning or for the detector) came as the
    threads ran, before or after those the session gives in log order, so ``rose-bag batch``'s
    ``warnings`` column and report.md differed from run to run. Here the analysis of the second
    map is slow: the third map's, too fine for both, ran meanwhile and said so first."""
    import time

    from rose_logs.session.analysis import SnapshotAnalyser

    analyse = SnapshotAnalyser._analyse

    def slow_at_0_1_m(self, snapshot):
        if snapshot.resolution_m == 0.1:
            time.sleep(1.0)
        return analyse(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", slow_at_0_1_m)
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0]),
        MapMsg(START_NS + 2_000_000_000, fr079[0], resolution_m=0.1),  # not comparable
        MapMsg(START_NS + 3_000_000_000, fr079[0], resolution_m=1e-5),  # too fine for both
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=0)
    assert main(["process", str(built.path), "--no-output", "-q"]) == 0
    kinds = _warning_kinds(capsys.readouterr().err)
    assert kinds[:3] == ["not comparable", "cleaning", "detector"], kinds


@pytest.mark.parametrize("slow", ["analysis", "reading"])
def test_warnings_said_while_reading_wait_for_the_analyses_before_them(
    tmp_path: Path, capsys, monkeypatch, fr079, slow: str
) -> None:
    """What the session says as it reads a message (a malformed map skipped) came at once, and what
    the analysis of a map before it logged (on its thread, held) when the session took its
    results: the malformed map was said first when the analysis was slower than the reading, last
    when the reading was slower, so the order differed from run to run. Said in log order now: the
    map too fine's warnings, then the skipped map's, then what a logger of ``rose`` that no list
    named says in the second analysis."""
    import logging
    import time

    from rose_logs.session.analysis import SnapshotAnalyser

    analyse = SnapshotAnalyser._analyse

    def slow_analysis(self, snapshot):
        if snapshot.topic == "/a" and slow == "analysis":
            time.sleep(1.0)
        if snapshot.topic == "/c":
            logging.getLogger("rose.a_module_loaded_later").warning("said by /c's analysis")
        return analyse(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", slow_analysis)
    if slow == "reading":
        _read_scans_slowly(monkeypatch, 0.5)
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], resolution_m=1e-5, topic="/a"),
        MapMsg(START_NS + 2_000_000_000, fr079[0], topic="/b", bad_length=True),
        MapMsg(START_NS + 3_000_000_000, fr079[0], topic="/c"),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=1)
    assert main(["process", str(built.path), "--no-output", "-q"]) == 0
    kinds = _warning_kinds(capsys.readouterr().err)
    assert kinds == ["cleaning", "detector", "malformed", "/c analysis"], kinds


def test_a_topic_too_fine_for_the_walls_cleaning_is_said_with_its_first_map(
    tmp_path: Path, capsys, monkeypatch, fr079
) -> None:
    """Said once per topic by whichever of its analyses came first, on two threads: when the
    second map's analysis outran the first's, it was said with the second map, after what was
    said of the maps between (here a malformed map), so the order differed from run to run."""
    import time

    from rose_logs.session.analysis import SnapshotAnalyser

    analyse = SnapshotAnalyser._analyse

    def first_slow(self, snapshot):
        if snapshot.log_time_ns == START_NS + 1_000_000_000:
            time.sleep(1.0)
        return analyse(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", first_slow)
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], resolution_m=1e-5, topic="/a"),
        MapMsg(START_NS + 2_000_000_000, fr079[0], topic="/b", bad_length=True),
        MapMsg(START_NS + 3_000_000_000, fr079[1], resolution_m=1e-5, topic="/a"),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=0)
    assert main(["process", str(built.path), "--no-output", "-q"]) == 0
    kinds = _warning_kinds(capsys.readouterr().err)
    assert kinds == ["cleaning", "detector", "malformed"], kinds


@pytest.mark.parametrize("slow", ["analysis", "reading"])
def test_the_reasons_of_skipped_maps_are_in_log_order(
    tmp_path: Path, capsys, monkeypatch, fr079, slow: str
) -> None:
    """A map not analysable is counted when the session takes its analysis, after the messages read
    meanwhile: the report's reasons ("1 malformed, 1 not analysable") came in the order counted,
    which was the analysis's pace against the reading's, not the log's."""
    import time

    import rose
    from rose_logs.session.analysis import SnapshotAnalyser

    analyse = SnapshotAnalyser._analyse

    def failing(self, snapshot):
        if snapshot.topic == "/a":
            if slow == "analysis":
                time.sleep(1.0)
            raise rose.RoseError("too thin")
        return analyse(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", failing)
    if slow == "reading":
        _read_scans_slowly(monkeypatch, 0.3)
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], topic="/a"),
        MapMsg(START_NS + 2_000_000_000, fr079[0], topic="/b", bad_length=True),
        MapMsg(START_NS + 3_000_000_000, fr079[0], topic="/c"),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=1)
    report = tmp_path / "r.json"
    assert main(["process", str(built.path), "--no-output", "-q", "--json", str(report)]) == 0
    assert json.loads(report.read_text())["skipped_reasons"] == "1 not analysable, 1 malformed"


def test_the_reasons_of_skipped_maps_of_one_log_time_are_in_the_order_read(
    tmp_path: Path, monkeypatch, fr079
) -> None:
    """Two map messages of one log time (two topics, or a simulated clock): ordered by log time
    only, their reasons came in the order counted, which was the analysis's pace against the
    reading's ("1 malformed, 1 not analysable" here, where the map not analysable came first)."""
    import time

    import rose
    from rose_logs.session import process_log
    from rose_logs.session.analysis import SnapshotAnalyser

    analyse = SnapshotAnalyser._analyse

    def failing(self, snapshot):
        if snapshot.topic == "/a":
            time.sleep(0.5)
            raise rose.RoseError("too thin")
        return analyse(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", failing)
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], topic="/a"),
        MapMsg(START_NS + 1_000_000_000, fr079[0], topic="/b", bad_length=True),
        MapMsg(START_NS + 2_000_000_000, fr079[0], topic="/c"),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=0)
    report = process_log(built.path, progress=False)
    assert report.to_json()["skipped_reasons"] == "1 not analysable, 1 malformed"


def test_an_interrupted_session_still_says_what_it_read(
    tmp_path: Path, capsys, monkeypatch, fr079
) -> None:
    """What the session says while reading waits for the analyses before it: a Ctrl-C while they
    run must not lose it (the malformed map read after a slow analysis was skipped unsaid)."""
    import os
    import signal
    import time

    from rose_logs.session.analysis import SnapshotAnalyser
    from rose_logs.session.loop import _Loop

    analyse, drain = SnapshotAnalyser._analyse, _Loop._drain

    def slow(self, snapshot):
        time.sleep(1.0)
        return analyse(self, snapshot)

    def interrupted(self, limit):
        if any(item.snapshot.topic == "/b" for item in self.queue if hasattr(item, "snapshot")):
            os.kill(os.getpid(), signal.SIGINT)
        return drain(self, limit)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", slow)
    monkeypatch.setattr(_Loop, "_drain", interrupted)
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], topic="/a"),
        MapMsg(START_NS + 2_000_000_000, fr079[0], topic="/b", bad_length=True),
        MapMsg(START_NS + 3_000_000_000, fr079[0], topic="/b"),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=0)
    assert main(["process", str(built.path), "--no-output", "-q"]) == 130
    err = capsys.readouterr().err
    assert "warning: /b: map data has" in err and "interrupted" in err, err


def test_what_a_failing_break_detector_logged_is_said_once_in_order(
    tmp_path: Path, monkeypatch, fr079
) -> None:
    """The break detector logs, then raises: the session fails with its error, and what it logged
    of that snapshot (held on its thread) is said still, once, in log order, as an analysis's is
    through its error. It was dropped."""
    import logging
    import time

    from rose_logs.session.analysis import SnapshotAnalyser
    from rose_logs.session.breaks import BreakDetector

    analyse, update = SnapshotAnalyser._analyse, BreakDetector.update

    def analysed(self, snapshot):
        logging.getLogger("rose.some_step").warning("analysed %s", snapshot.topic)
        if snapshot.topic == "/b":
            time.sleep(0.5)  # /c is read meanwhile
        return analyse(self, snapshot)

    def scored(self, snapshot):
        logging.getLogger("rose_logs.session.breaks").warning("scored %s", snapshot.topic)
        if snapshot.topic == "/b":
            raise RuntimeError("the detector failed")
        return update(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", analysed)
    monkeypatch.setattr(BreakDetector, "update", scored)
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], topic="/a"),
        MapMsg(START_NS + 2_000_000_000, fr079[0], topic="/b"),
        MapMsg(START_NS + 3_000_000_000, fr079[0], topic="/c", bad_length=True),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=0)
    said: list[str] = []
    with pytest.raises(RuntimeError, match="the detector failed"):
        _said_by_session(built.path, into=said)
    said = [x.split(":")[0] for x in said]
    assert said == ["analysed /a", "scored /a", "analysed /b", "scored /b", "/c"], said


def test_an_input_whose_name_says_no_format_gets_its_contents_suffix(tmp_path: Path) -> None:
    """``run`` or ``run.log`` holding MCAP: the default output was ``run.rose`` or
    ``run.rose.log``, a name that says nothing of what it holds; a suffix that names no format is
    part of the name (``run.1`` and ``run.2`` get two outputs)."""
    import shutil

    cases = (
        ("run", "run.rose.mcap"),
        ("run.log", "run.log.rose.mcap"),
        ("run.1", "run.1.rose.mcap"),
        ("run.2", "run.2.rose.mcap"),
        ("x.", "x.rose.mcap"),
    )
    for name, expected in cases:
        (tmp_path / expected).unlink(missing_ok=True)
        log = tmp_path / name
        shutil.copyfile(SAMPLE, log)
        assert default_output_path(log) == tmp_path / expected
        assert main(["process", str(log), "-q"]) == 0
        assert (tmp_path / expected).is_file()


def test_an_input_whose_name_says_no_format_keeps_its_whole_name_with_format(
    tmp_path: Path,
) -> None:
    """With ``--format``, ``run.1`` and ``run.2`` were both named ``run.rose.mcap`` (the second run
    refused: it exists) and ``run.log`` ``run.rose``: a suffix that names no format is part of the
    name whatever the output format."""
    import shutil

    cases = (
        ("run", "mcap", "run.rose.mcap"),
        ("run.1", "mcap", "run.1.rose.mcap"),
        ("run.2", "mcap", "run.2.rose.mcap"),
        ("run.log", "db3", "run.log.rose"),
        ("run.log", "mcap-dir", "run.log.rose"),
        ("x.", "mcap", "x.rose.mcap"),
        ("run.mcap", "mcap", "run.rose.mcap"),
        ("run.mcap", "db3", "run.rose"),
    )
    for name, fmt, expected in cases:
        log = tmp_path / name
        shutil.copyfile(SAMPLE, log)
        assert default_output_path(log, fmt) == tmp_path / expected
    for name in ("run.1", "run.2"):
        assert main(["process", str(tmp_path / name), "--format", "mcap", "-q"]) == 0
        assert (tmp_path / f"{name}.rose.mcap").is_file()


def test_a_log_named_as_another_format_or_left_active_gets_its_contents_suffix(
    tmp_path: Path,
) -> None:
    """An MCAP or ROS 1 file named ``.db3`` was written to ``x.rose``, a file without a format's
    suffix (a bare ``.db3`` names a folder); ``run.bag.active`` (rosbag never closed it) gave
    ``run.bag.active.rose.bag``, which a later batch read as a recording."""
    import shutil

    shutil.copyfile(SAMPLE, tmp_path / "mcap_inside.db3")
    grids = [np.zeros((40, 40), np.int8)]
    bag = build_log(tmp_path / "r.bag", "ros1", session_maps(grids), scans_per_map=0).path
    shutil.copyfile(bag, tmp_path / "ros1_inside.db3")
    shutil.copyfile(bag, tmp_path / "run.bag.active")
    cases = (
        ("mcap_inside.db3", "mcap_inside.rose.mcap"),
        ("ros1_inside.db3", "ros1_inside.rose.bag"),
        ("run.bag.active", "run.rose.bag"),
    )
    for name, expected in cases:
        assert default_output_path(tmp_path / name) == tmp_path / expected
        assert main(["process", str(tmp_path / name), "-q"]) == 0
        assert (tmp_path / expected).is_file()
    assert not (tmp_path / "mcap_inside.rose").exists()


def test_an_empty_topic_name_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as done:
        main(["process", str(SAMPLE), "-t", "", "--no-output"])
    assert done.value.code == 2
    assert "a topic name cannot be empty" in capsys.readouterr().err


def test_a_bags_metadata_given_as_the_input_points_to_its_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = tmp_path / "run"
    assert main(["process", str(SAMPLE), "--format", "db3", "-o", str(bag), "-q"]) == 0
    capsys.readouterr()
    assert main(["process", str(bag / "metadata.yaml"), "--no-output", "-q"]) == 1
    err = capsys.readouterr().err
    assert err.strip().endswith(f"a ROS 2 bag's metadata: give its folder, {bag}")
    assert main(["process", str(bag), "--no-output", "-q"]) == 0
    # A data set's own metadata.yaml: no folder to give (it was named, and then refused as "not
    # a ROS 2 bag").
    (tmp_path / "metadata.yaml").write_text("name: my data set\n")
    assert main(["process", str(tmp_path / "metadata.yaml"), "--no-output", "-q"]) == 1
    err = capsys.readouterr().err
    assert err.strip().endswith("; nor a ROS 2 bag's metadata (no rosbag2_bagfile_information)")


def _right_half_drifted(cells: int) -> np.ndarray:
    """The 300 x 360 floor plan with its right half ``cells`` cells further right."""
    from tests.synthetic import right_half_drifted, ros_floor_plan

    return right_half_drifted(ros_floor_plan(), cells)


def test_a_map_returning_to_its_anchor_is_said_and_no_break(tmp_path: Path, capsys) -> None:
    """A redrawn map whose right half drifts 0.15 m a snapshot at 10 Hz, then snaps back (a loop
    closure): the snapshot back contradicts the drifted map, which failed the break gate; it agrees
    with the anchor, so it is no break, and the drift the detector had not flagged is a warning."""
    grids = [*(_right_half_drifted(3 * i) for i in range(5)), _right_half_drifted(0)]
    maps = [MapMsg(START_NS + i * 100_000_000, g) for i, g in enumerate(grids)]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    code = main(["process", str(built.path), "--no-output", "--fail-on-break"])
    _, err = capsys.readouterr()
    assert code == 0
    (line,) = [x for x in err.splitlines() if "returned to that map" in x]
    assert line.startswith("warning: /map: the map at +0.5 s")
    assert "contradicts snapshot 4 (" in line and "but agrees with snapshot 0 (" in line
    assert "m, under 2.50 m): it returned" in line  # the anchor's score, and its threshold


def test_a_drift_in_a_session_too_short_for_the_anchor_breaks_at_its_end(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Seven maps in 0.6 s, the right half 0.15 m further each: each agrees with the one before,
    and the anchor was compared every eighth snapshot or 10 s only, so the 0.9 m drift passed
    the break gate. The last snapshot is compared with the anchor at the session's end, and the
    break is reported as any other: the gate, the summary, the JSON report's first break and
    the snapshot's record."""
    maps = [MapMsg(START_NS + i * 100_000_000, _right_half_drifted(3 * i)) for i in range(7)]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    report = tmp_path / "r.json"
    argv = ["process", str(built.path), "--no-output", "--fail-on-break", "--json", str(report)]
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == EXIT_GATE, err
    assert "break        first at snapshot 6, +0.6 s" in out and "since snapshot 0" in out
    (line,) = [x for x in err.splitlines() if x.startswith("error:")]
    assert "map breaks at snapshot 6:" in line and "(threshold 2.5 m) since snapshot 0" in line
    data = json.loads(report.read_text())
    first = data["topics"]["/map"]["first_break"]
    assert first["index"] == 6 and first["trusted_index"] == 0 and first["break_score_m"] >= 2.5
    records = data["snapshots"]
    assert [r["break_detected"] for r in records] == [False] * 6 + [True]
    assert records[-1]["break_score_m"] == first["break_score_m"]
    # A map every 10 s: the schedule compares each with the anchor, and finds the drift before
    # the end, as before.
    slow = [MapMsg(START_NS + i * 10_000_000_000, _right_half_drifted(3 * i)) for i in range(7)]
    built = build_log(tmp_path / "slow.mcap", "mcap-ros2", slow)
    argv = ["process", str(built.path), "--no-output", "--fail-on-break", "-q"]
    assert main(argv) == EXIT_GATE
    out, _ = capsys.readouterr()
    found = re.search(r"break        first at snapshot (\d+),", out)
    assert found is not None and int(found.group(1)) < 6, out


@pytest.mark.parametrize("command", ["process", "convert"])
def test_an_output_log_inside_a_ros2_bag_folder_is_refused(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`process run.mcap -o SOMEBAG/x.mcap` exited 0 and wrote into the bag, whose every later read
    warned `storage file x.mcap is not listed in metadata.yaml`."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    carmen = SAMPLE.parents[1] / "tests/data/radish_carmen_corrected_logs"
    for output, fmt in ((bag / "x.mcap", "mcap"), (bag / "y", "db3")):
        if command == "process":
            argv = ["process", str(SAMPLE), "-o", str(output), "--format", fmt, "-q"]
        else:
            log = carmen / "csail-corrected.head400.log.gz"
            argv = ["convert", str(log), str(output), "--format", fmt, "-q"]
        assert main(argv) == 1
        err = capsys.readouterr().err
        option = "-o" if command == "process" else "OUTPUT"
        assert err == (
            f"error: {output}: the output log is inside the ROS 2 bag folder {bag.resolve()} (it "
            f"has metadata.yaml): it would write into a recording; choose another {option}\n"
        )
    assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml"]


@pytest.mark.parametrize(
    ("option", "name", "what"),
    [
        ("--rrd", "run.rrd", "Rerun recording"),
        ("--json", "report.json", "JSON report"),
        ("--map-file", "map.yaml", "map file"),
    ],
)
def test_a_recording_report_or_map_inside_a_ros2_bag_folder_is_refused(
    option: str, name: str, what: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`process run.mcap --json SOMEBAG/report.json` (or `--rrd`, or `convert --map-file`) exited 0
    and put the file into the recording, where the output log was refused: the file went
    wherever the bag went, and `-o SOMEBAG --force` deleted it with the bag."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    output = bag / name
    if option == "--map-file":
        log = SAMPLE.parents[1] / "tests/data/radish_carmen_corrected_logs"
        log = log / "csail-corrected.head400.log.gz"
        argv = ["convert", str(log), str(tmp_path / "out.mcap"), option, str(output), "-q"]
    else:
        argv = ["process", str(SAMPLE), "--no-output", option, str(output), "-q"]
    assert main(argv) == 1
    assert capsys.readouterr().err == (
        f"error: {output}: the {what} is inside the ROS 2 bag folder {bag.resolve()} (it "
        f"has metadata.yaml): it would write into a recording; choose another {option}\n"
    )
    assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml"]
    assert not (tmp_path / "out.mcap").exists()
    # Beside the bag, the same run writes it.
    argv[argv.index(str(output))] = str(tmp_path / name)
    assert main(argv) == 0
    assert (tmp_path / name).is_file()


def test_a_report_inside_the_input_bag_folder_is_still_said_to_be_inside_the_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The input's own bag folder is the input: the refusal says so, not "another recording"."""
    bag = tmp_path / "in"
    assert main(["process", str(SAMPLE), "--format", "db3", "-o", str(bag), "-q"]) == 0
    capsys.readouterr()
    for option, name in (("--json", "r.json"), ("--rrd", "r.rrd")):
        argv = ["process", str(bag), "--no-output", option, str(bag / name), "-q"]
        assert main(argv) == 1
        err = capsys.readouterr().err
        assert err == f"error: {bag / name}: refusing to write inside the input {bag}\n"
    assert sorted(p.name for p in bag.iterdir()) == ["in.db3", "metadata.yaml"]


def _db3_bag_with_metadata_edited(tmp_path: Path, pattern: str, replacement: str) -> Path:
    """The sample as a ROS 2 bag folder ``tmp_path/run`` whose metadata.yaml has the one line
    ``pattern`` matches replaced."""
    bag = tmp_path / "run"
    assert main(["process", str(SAMPLE), "--format", "db3", "-o", str(bag), "-q"]) == 0
    metadata = bag / "metadata.yaml"
    text, count = re.subn(pattern, replacement, metadata.read_text())
    assert count == 1
    metadata.write_text(text)
    return bag


def test_a_metadata_yaml_without_a_key_rosbags_reads_is_said_so_in_our_words(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`info bag` said `corrupt or truncated log (A metadata key is missing
    KeyError('topics_with_message_count').)`: nothing was cut, the metadata lacks a key."""
    bag = _db3_bag_with_metadata_edited(tmp_path, r"(?m)^  message_count: \d+\n", "")
    capsys.readouterr()
    for command in (["info"], ["process", "--no-output"]):
        assert main([command[0], str(bag), *command[1:]]) == 1
        assert capsys.readouterr().err == (
            f"error: {bag}: its metadata.yaml lacks the key 'message_count' that rosbag2 "
            "metadata holds (written by hand, or cut short?)\n"
        )


def test_a_storage_file_missing_from_a_bag_folder_is_said_so_in_our_words(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`info bag` said `corrupt or truncated log (Some database files are missing:
    ['/full/path/run_0.db3'])`: nothing is corrupt, a file the metadata lists is gone."""
    bag = tmp_path / "run"
    assert main(["process", str(SAMPLE), "--format", "db3", "-o", str(bag), "-q"]) == 0
    stored = next(bag.glob("*.db3"))
    stored.unlink()
    capsys.readouterr()
    for command in (["info"], ["process", "--no-output"]):
        assert main([command[0], str(bag), *command[1:]]) == 1
        assert capsys.readouterr().err == (
            f"error: {bag}: storage file {stored.name}, listed in its metadata.yaml, is missing "
            "(moved or deleted?)\n"
        )


def test_a_bag_of_a_newer_rosbag2_version_is_said_so_in_our_words(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It passed on rosbags's `(Rosbag2 version 99 not supported; please report issue.)` after
    `corrupt or truncated log`: the bag is neither, and the issue is not rosbags's to hear of."""
    from rosbags.rosbag2.writer import Writer

    bag = _db3_bag_with_metadata_edited(tmp_path, r"(?m)^  version: \d+$", "  version: 99")
    capsys.readouterr()
    for command in (["info"], ["process", "--no-output"]):
        assert main([command[0], str(bag), *command[1:]]) == 1
        err = capsys.readouterr().err
        assert err.startswith(
            f"error: {bag}: its metadata.yaml is of rosbag2 version 99, newer than rose-bag reads "
            "(rosbags "
        )
        assert err.endswith(f" reads up to version {Writer.VERSION_LATEST})\n")
        assert "report issue" not in err and "corrupt" not in err


def test_a_users_filter_on_our_logger_sees_a_held_record_once(
    tmp_path: Path, monkeypatch, fr079
) -> None:
    """A program's own filter on one of our loggers (here one letting each message through once,
    put there before any session ran) saw a held record twice, as it was logged and as it was said:
    the second time it dropped it, and the skipped map was never said."""
    import logging

    seen: list[str] = []

    def once(record: logging.LogRecord) -> bool:
        message = record.getMessage()
        seen.append(message)
        return seen.count(message) == 1

    logger = logging.getLogger("rose_logs.session.loop")
    monkeypatch.setattr(logger, "filters", [once])  # as in a process where no session ran yet
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], topic="/a"),
        MapMsg(START_NS + 2_000_000_000, fr079[0], topic="/b", bad_length=True),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=0)
    said = _said_by_session(built.path, loggers=(logger.name,))
    assert [x[:16] for x in said] == ["/b: map data has"], said
    assert len(seen) == 1, seen


def test_a_record_made_from_a_dict_while_records_are_held_is_made() -> None:
    """``logging.makeLogRecord`` (a socket server's way of rebuilding records) makes a record
    named None before it fills it in: while a session held records, our record factory read that
    name as a string and raised AttributeError in the program's own code."""
    import logging

    from rose_logs.session.held_logs import held_log_records

    with held_log_records():
        record = logging.makeLogRecord({"name": "rose.x", "msg": "hello"})
    assert (record.name, record.getMessage()) == ("rose.x", "hello")


def test_a_held_record_says_its_arguments_as_they_were_when_logged(
    tmp_path: Path, monkeypatch, fr079
) -> None:
    """A record held on an analysis thread was formatted when said: an argument changed meanwhile
    (a list here) was said as it had become, not as it was logged."""
    import logging

    from rose_logs.session.analysis import SnapshotAnalyser

    analyse = SnapshotAnalyser._analyse

    def analysed(self, snapshot):
        state = ["as logged"]
        logging.getLogger("rose.some_step").warning("state %s", state)
        state[0] = "changed later"
        return analyse(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", analysed)
    built = build_log(
        tmp_path / "in.mcap", "mcap-ros2", [MapMsg(START_NS + 1, fr079[0])], scans_per_map=0
    )
    said = _said_by_session(built.path, loggers=("rose",))
    assert said == ["state ['as logged']"], said


def test_a_session_failing_as_it_says_what_it_held_ends_its_threads(
    tmp_path: Path, monkeypatch, fr079
) -> None:
    """A program's filter on our logger that raises on a held record: the session fails with its
    error, said when the session says the record (at the end too), and its threads end. The
    saying at the end came before the threads' shutdown, which it skipped: the analysis and break
    detector threads of every such session stayed for the life of the process."""
    import logging
    import threading

    from rose_logs.session import process_log

    def refuse(record: logging.LogRecord) -> bool:
        if record.getMessage().startswith("/b: map data"):
            raise RuntimeError("the filter failed")
        return True

    logger = logging.getLogger("rose_logs.session.loop")
    monkeypatch.setattr(logger, "filters", [refuse])
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], topic="/a"),
        MapMsg(START_NS + 2_000_000_000, fr079[0], topic="/b", bad_length=True),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=0)
    before = set(threading.enumerate())
    with pytest.raises(RuntimeError, match="the filter failed"):
        process_log(built.path, progress=False)
    left = [t.name for t in set(threading.enumerate()) - before if t.name.startswith("rose-")]
    assert left == [], left


def test_a_session_failing_part_way_through_what_it_read_says_none_of_it_twice(
    tmp_path: Path, monkeypatch, fr079
) -> None:
    """What the session said reading a map (its cells out of range, its origin tilted), held
    behind the slow analysis of the map before it, then said: a program's filter raising on the
    second record failed the session, and what was still queued was said as the run ended, the
    first record again, so it was said twice."""
    import logging
    import math
    import time

    from rose_logs.session.analysis import SnapshotAnalyser

    analyse = SnapshotAnalyser._analyse

    def slow(self, snapshot):
        if snapshot.topic == "/a":
            time.sleep(0.5)
        return analyse(self, snapshot)

    def refuse(record: logging.LogRecord) -> bool:
        if "tilted" in record.getMessage():
            raise RuntimeError("the filter failed")
        return True

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", slow)
    logger = logging.getLogger("rose_logs.session.loop")
    monkeypatch.setattr(logger, "filters", [refuse])
    grid = fr079[0].copy()
    grid[0, 0] = 120  # out of range
    half = math.radians(10) / 2
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], topic="/a"),
        MapMsg(
            START_NS + 2_000_000_000,
            grid,
            topic="/b",
            orientation_xyzw=(math.sin(half), 0.0, 0.0, math.cos(half)),
        ),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps, scans_per_map=0)
    said: list[str] = []
    with pytest.raises(RuntimeError, match="the filter failed"):
        _said_by_session(built.path, loggers=(logger.name,), into=said)
    assert [x for x in said if "outside -1..100" in x] == [said[0]], said


def test_a_held_record_is_said_as_the_loggers_level_let_it_through_when_logged(
    tmp_path: Path, monkeypatch, fr079
) -> None:
    """The README's word: a logger's level (and ``logging.disable``) apply when a record is logged,
    not when the session says it held: one logged before the level was raised is said, one after
    it is not, although both are said (or not) after the change."""
    import logging

    from rose_logs.session.analysis import SnapshotAnalyser

    analyse = SnapshotAnalyser._analyse
    step = logging.getLogger("rose.some_step")
    monkeypatch.setattr(step, "level", logging.NOTSET)

    def analysed(self, snapshot):
        step.warning("before the level was raised")
        step.setLevel(logging.ERROR)
        step.warning("after it")
        return analyse(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", analysed)
    built = build_log(
        tmp_path / "in.mcap", "mcap-ros2", [MapMsg(START_NS + 1, fr079[0])], scans_per_map=0
    )
    try:
        said = _said_by_session(built.path, loggers=("rose",))
    finally:
        step.setLevel(logging.NOTSET)
    assert said == ["before the level was raised"], said


def test_a_warning_said_while_the_progress_bar_is_drawn_goes_above_it(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    fr079: list[np.ndarray],
) -> None:
    """On a terminal, `process` wrote a warning said mid-session where the bar's line ended
    (``52%|...| 125/240 msg [...]warning: /map: map data has ...``); `batch` put its lines above
    its bar already. Each line now starts a line of its own, the bar drawn again under it."""
    import rose_logs.cli.process

    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0]),
        MapMsg(START_NS + 2_000_000_000, fr079[1], bad_length=True),
        MapMsg(START_NS + 3_000_000_000, fr079[2]),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    monkeypatch.setattr(rose_logs.cli.process, "stderr_is_terminal", lambda: True)
    assert main(["process", str(built.path), "--no-output"]) == 0
    err = capsys.readouterr().err
    assert "msg [" in err  # the bar was drawn
    pieces = re.split(r"[\r\n]", err)
    said = [p for p in pieces if "warning:" in p]
    assert len(said) == 1 and said[0].startswith("warning: /map: map data has"), said


def test_lines_said_above_the_bar_keep_their_handlers_level_and_filters(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """While the bar is drawn, the console handlers stay, their stream wrapped: tqdm's redirect
    put a handler of its own in their place, without their level, and (tqdm 4.66 and before)
    without their filters: rose-bag's once-per-message filter of the library's lines, lost for
    process's whole session."""
    import logging

    from tqdm import tqdm

    from rose_logs.session.held_logs import said_above_bar

    logger = logging.getLogger("rose.test_above_bar")
    handler = logging.StreamHandler(sys.stderr)
    handler.setLevel(logging.WARNING)
    handler.addFilter(lambda record: "hidden" not in record.getMessage())
    root = logging.getLogger("rose")
    root.addHandler(handler)
    old_level = root.level
    root.setLevel(logging.INFO)
    try:
        with tqdm(total=2, file=sys.stderr) as bar, said_above_bar(True):
            bar.update(1)
            logger.info("below the handler's level")
            logger.warning("hidden by its filter")
            logger.warning("said")
        assert handler.stream is sys.stderr  # as it was
    finally:
        root.removeHandler(handler)
        root.setLevel(old_level)
    said = [line for line in re.split(r"[\r\n]", capsys.readouterr().err) if line.strip()]
    assert [line for line in said if "|" not in line] == ["said"], said
