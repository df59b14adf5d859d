"""Errors and safety: one-line errors, non-zero exit, no partial output, input untouched."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from cli_exit import exit_code
from conftest import START_NS, MapMsg, build_log, log_path, read_all, session_maps, tree_bytes

from rose_logs.cli import main
from rose_logs.errors import LogReadError, LogWriteError
from rose_logs.session import process_log


def _run(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _assert_one_line_error(err: str, *needles: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    assert "Traceback" not in err
    for needle in needles:
        assert needle in lines[0]


def _leftovers(folder: Path, keep: set[str]) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


@pytest.fixture
def mcap_log(tmp_path: Path, fr079) -> Path:
    return build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:2])).path


def test_missing_file(tmp_path: Path, capsys) -> None:
    code, _, err = _run(capsys, "process", tmp_path / "nope.bag", "-o", tmp_path / "o.bag")
    assert code == 1
    _assert_one_line_error(err, "nope.bag", "no such file")
    assert _leftovers(tmp_path, set()) == []


def test_a_report_to_a_closed_standard_output_is_one_line_before_any_work(
    tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch, mcap_log: Path
) -> None:
    """Started with standard output closed (``>&-``: sys.stdout is None), ``--json -`` ended in
    an AttributeError traceback when the report was written, after the work."""
    import sys

    monkeypatch.setattr(sys, "stdout", None)
    code, _, err = _run(capsys, "process", mcap_log, "--no-output", "--json", "-", "-q")
    assert code == 1
    _assert_one_line_error(err, "standard output: cannot write (it is closed)")
    assert _leftovers(tmp_path, {"in.mcap"}) == []


@pytest.mark.parametrize("command", [["info"], ["process", "--no-output", "-q"]])
def test_a_command_that_prints_its_result_refuses_a_closed_standard_output_before_any_work(
    command: list[str], tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch, mcap_log: Path
) -> None:
    """Started with standard output closed (``>&-``: sys.stdout is None), `info` printed nothing
    with exit 0: a command whose result is what it prints is refused first (`process` writing
    no log, report or recording too)."""
    import sys

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "stdout", None)
    code, _, err = _run(capsys, command[0], mcap_log, *command[1:])
    assert code == 1
    _assert_one_line_error(err, "standard output: cannot write (it is closed)")
    assert _leftovers(tmp_path, {"in.mcap"}) == []


@pytest.mark.parametrize(
    ("command", "written"),
    [
        (["process", "-o", "out.mcap"], "out.mcap"),
        (["process", "--no-output", "--json", "r.json"], "r.json"),
        (["batch", "-o", "out", "-q"], "out"),
    ],
)
def test_a_command_that_writes_files_runs_without_a_standard_output(
    command: list[str],
    written: str,
    tmp_path: Path,
    capsys,
    monkeypatch: pytest.MonkeyPatch,
    mcap_log: Path,
) -> None:
    """Under ``pythonw`` sys.stdout is None, and every command was refused, `process -o
    out.mcap` too: one whose result is its files runs (its summary goes nowhere), exit 0."""
    import sys

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "stdout", None)
    code, _, err = _run(capsys, command[0], mcap_log, *command[1:])
    assert code == 0, err
    assert sys.stdout is None  # as it was
    assert (tmp_path / written).exists()
    assert "error" not in err


@pytest.mark.parametrize(
    ("command", "written"),
    [
        (["process", "-o", "out.mcap"], "out.mcap"),
        (["batch", "-o", "out"], "out"),
    ],
)
def test_a_command_that_writes_files_runs_under_pythonw(
    command: list[str],
    written: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    mcap_log: Path,
) -> None:
    """Under ``pythonw`` sys.stderr is None as well as sys.stdout: without -q, `process -o
    out.mcap` and `batch` asked ``sys.stderr.isatty()`` whether to draw a progress bar, an
    AttributeError after the standard output's check let them run."""
    import sys

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "stdout", None)
    monkeypatch.setattr(sys, "stderr", None)
    assert main([command[0], str(mcap_log), *command[1:]]) == 0
    assert (tmp_path / written).exists()


def test_an_input_that_is_a_symlink_loop_is_one_line(tmp_path: Path, capsys) -> None:
    """Path.resolve() of a link to itself raised RuntimeError (Python < 3.13) while the outputs
    were checked: a traceback before the read could say what is wrong."""
    loop = tmp_path / "loop.mcap"
    loop.symlink_to(loop.name)
    for outputs in (["--no-output"], ["-o", tmp_path / "o.mcap"]):
        code, _, err = _run(capsys, "process", loop, *outputs)
        assert code == 1
        _assert_one_line_error(err, "loop.mcap", "Too many levels of symbolic links")
    assert _leftovers(tmp_path, {"loop.mcap"}) == []


@pytest.mark.parametrize("content", [b"", b"hello, not a bag at all\n" * 10])
def test_unrecognised_file(tmp_path: Path, capsys, content: bytes) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(content)
    code, _, err = _run(capsys, "process", bad, "-o", tmp_path / "o.mcap")
    assert code == 1
    _assert_one_line_error(err, "bad.mcap", "not a ROS 1 bag")
    assert _leftovers(tmp_path, {"bad.mcap"}) == []


@pytest.mark.parametrize("kind", ["ros1", "mcap-ros2", "mcap-ros1", "db3"])
@pytest.mark.parametrize("damage", ["truncate", "corrupt"])
def test_truncated_or_corrupt_log(tmp_path: Path, capsys, fr079, kind: str, damage: str) -> None:
    built = build_log(log_path(tmp_path, kind), kind, session_maps(fr079[:2]))
    target = next(built.path.glob("*.db3")) if built.path.is_dir() else built.path
    data = bytearray(target.read_bytes())
    if damage == "truncate":
        data = data[: len(data) // 2]
    else:
        start = len(data) // 3
        data[start : start + 4096] = bytes(range(256)) * 16
    target.write_bytes(bytes(data))
    before = tree_bytes(built.path)
    out = log_path(tmp_path, kind, "out")
    code, _, err = _run(capsys, "process", built.path, "-o", out)
    assert tree_bytes(built.path) == before
    if code == 0:  # damage inside a map's cells (ROS 1 has no checksums): said in a warning
        assert "warning: " in err
        assert "outside -1..100" in err or "not analysed" in err
        return
    assert code == 1
    _assert_one_line_error(err, built.path.name)
    assert ",)" not in err  # a library's args tuple is shown as its text, not as a Python repr
    assert not out.exists()
    assert _leftovers(tmp_path, {built.path.name}) == []


def _damaged(data: bytearray, rng: np.random.Generator) -> str:
    """Damage ``data`` in place as disks, copies and downloads do; returns the kind of damage."""
    kind = str(rng.choice(["flip", "truncate", "zero", "insert", "delete"]))
    at = int(rng.integers(0, len(data)))
    span = int(rng.integers(1, 4097))
    if kind == "flip":
        for where in rng.integers(0, len(data), int(rng.integers(1, 5))):
            data[int(where)] ^= 1 << int(rng.integers(0, 8))
    elif kind == "truncate":
        del data[at:]
    elif kind == "zero":
        data[at : at + span] = bytes(len(data[at : at + span]))
    elif kind == "insert":  # a block written twice
        data[at:at] = data[at : at + span]
    else:
        del data[at : at + span]
    return kind


@pytest.mark.parametrize("kind", ["mcap-ros2", "ros1", "db3"])
@pytest.mark.parametrize("seed", range(8))
def test_randomly_damaged_logs_fail_in_one_line_or_are_read(
    tmp_path: Path, capsys, fr079, kind: str, seed: int
) -> None:
    """Damage at random places (bits flipped, cut short, zeroed, a block written twice or lost),
    with and without --salvage: either one error line naming the log, no output and exit 1, or
    outputs that read; never a traceback, and the input as it was. Fuzzing the sample log this way
    found two tracebacks' worth of errors that named no file."""
    from rose_logs.reader import LogReader

    built = build_log(log_path(tmp_path, kind), kind, session_maps(fr079))
    target = next(built.path.glob("*.db3")) if built.path.is_dir() else built.path
    rng = np.random.default_rng([seed, len(kind)])
    data = bytearray(target.read_bytes())
    damage = _damaged(data, rng)
    target.write_bytes(bytes(data))
    before = tree_bytes(built.path)
    out, recording = log_path(tmp_path, kind, "out"), tmp_path / "out.rrd"
    salvage = ["--salvage"] if seed % 2 else []
    code, _, err = _run(capsys, "process", built.path, "-o", out, "--rrd", recording, *salvage)
    assert tree_bytes(built.path) == before, damage
    assert "Traceback" not in err, (damage, err)
    if code in (0, 4):  # read (what could be, under --salvage: exit 4, said in warnings)
        assert code == 0 or salvage, (damage, err)
        with LogReader(out) as reader:
            assert reader.message_count > 0
        assert recording.exists()
        return
    assert code == 1, (damage, err)
    last = err.strip().splitlines()[-1]
    assert last.startswith("error: ") and built.path.name in last, (damage, err)
    assert not out.exists() and not recording.exists()
    assert _leftovers(tmp_path, {built.path.name}) == []


def test_no_map_topic(tmp_path: Path, capsys, fr079) -> None:
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", [MapMsg(START_NS, fr079[0], topic="/map")])
    code, _, err = _run(
        capsys, "process", built.path, "--topic", "/scan", "-o", tmp_path / "o.mcap"
    )
    assert code == 1
    _assert_one_line_error(err, "/scan", "not nav_msgs/OccupancyGrid")


def test_no_map_topic_at_all(tmp_path: Path, capsys) -> None:
    from rose_logs.writer import open_output

    path = tmp_path / "scans.mcap"
    with open_output(path, "mcap") as out:
        out.add_topic("/chatter", "std_msgs/msg/String")
        out.write("/chatter", START_NS, out.typestore.types["std_msgs/msg/String"](data="hi"))
    code, _, err = _run(capsys, "process", path, "-o", tmp_path / "o.mcap")
    assert code == 1
    _assert_one_line_error(err, "no nav_msgs/OccupancyGrid topic", "/chatter")
    assert not (tmp_path / "o.mcap").exists()


def test_a_robot_namespace_called_rose_is_a_map_like_any_other(
    tmp_path: Path, capsys, fr079
) -> None:
    """Only ``<map>/rose/cleaned`` (our own output) is skipped, not every topic with ``/rose/``."""
    maps = [MapMsg(START_NS, fr079[0], topic="/rose/map")]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    out = tmp_path / "o.mcap"
    code, _, err = _run(capsys, "process", built.path, "-o", out, "-q")
    assert code == 0, err
    assert {"/rose/map", "/rose/map/rose/cleaned"} <= set(read_all(out))
    # Our own cleaned map is not analysed again, and asking for it says why.
    code, _, err = _run(capsys, "process", out, "-t", "/rose/map/rose/cleaned", "--no-output")
    assert code == 1
    _assert_one_line_error(err, "/rose/map/rose/cleaned", "own cleaned map")


def test_a_map_in_an_encoding_we_cannot_read_is_named(tmp_path: Path, capsys) -> None:
    from mcap.writer import Writer

    path = tmp_path / "json.mcap"
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start()
        schema = writer.register_schema("nav_msgs/msg/OccupancyGrid", "jsonschema", b"{}")
        channel = writer.register_channel("/map", "json", schema)
        writer.add_message(channel, START_NS, b"{}", START_NS)
        writer.finish()
    code, _, err = _run(capsys, "process", path, "--no-output")
    assert code == 1
    _assert_one_line_error(err, "json.mcap", "/map is encoded as json", "cdr and ros1")


def test_output_names_need_not_be_utf8(tmp_path: Path, mcap_log: Path) -> None:
    """Linux file names are bytes: names that are not UTF-8 are read, written and printed (as the
    bytes they are) like any other, on a strict UTF-8 terminal too."""
    odd = os.fsdecode(b"o\xfe")
    (tmp_path / "in").mkdir()
    log = mcap_log.rename(tmp_path / "in" / os.fsdecode(b"run\xff.mcap"))
    outputs = [tmp_path / f"{odd}.{suffix}" for suffix in ("mcap", "json", "rrd")]
    argv = ["process", log, "-o", outputs[0], "--json", outputs[1], "--rrd", outputs[2]]
    env = {**os.environ, "LC_ALL": "C.UTF-8", "PYTHONIOENCODING": ""}
    done = subprocess.run(
        [sys.executable, "-m", "rose_logs.cli", *map(str, argv)],
        capture_output=True,
        env=env,
        check=False,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr.decode(errors="replace")
    assert all(path.stat().st_size > 0 for path in outputs)
    assert b"run\xff.mcap" in done.stdout


@pytest.mark.parametrize("encoding", ["ascii", "latin-1"])
def test_names_a_terminal_cannot_show_are_escaped(
    tmp_path: Path, mcap_log: Path, encoding: str
) -> None:
    """``café`` or ``地图`` on a stream that cannot hold them (``PYTHONIOENCODING=ascii``): a
    traceback came after the outputs were written (exit 1 with its outputs in place)."""
    log = mcap_log.rename(tmp_path / "地图café.mcap")
    out = tmp_path / "out.mcap"
    env = {**os.environ, "PYTHONIOENCODING": encoding}
    done = subprocess.run(
        [sys.executable, "-m", "rose_logs.cli", "process", str(log), "-o", str(out)],
        capture_output=True,
        env=env,
        check=False,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr.decode(errors="replace")
    assert b"Traceback" not in done.stderr and out.stat().st_size > 0
    assert b"\\u5730\\u56fe" in done.stdout  # 地图, backslash-escaped


def test_output_named_after_the_current_folder(
    tmp_path: Path, capsys, fr079, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``rose-bag process .`` inside a ROS 2 bag folder writes the folder's ``.rose`` sibling."""
    build_log(tmp_path / "run", "db3", session_maps(fr079[:1]))
    monkeypatch.chdir(tmp_path / "run")
    code, _, err = _run(capsys, "process", ".", "-q")
    assert code == 0, err
    assert "/map/rose/cleaned" in read_all(tmp_path / "run.rose")


@pytest.mark.parametrize("kind", ["ros1", "mcap-ros2"])
def test_malformed_map_message_is_copied_with_a_warning(
    tmp_path: Path, capsys, fr079, kind
) -> None:
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0]),
        MapMsg(START_NS + 2_000_000_000, fr079[1], bad_length=True),
        MapMsg(START_NS + 3_000_000_000, fr079[2][:0, :]),  # zero-area map
        MapMsg(START_NS + 4_000_000_000, fr079[2]),
    ]
    built = build_log(log_path(tmp_path, kind), kind, maps)
    out = log_path(tmp_path, kind, "out")
    code, stdout, err = _run(capsys, "process", built.path, "-o", out, "--quiet")
    assert code == 0
    warnings = [line for line in err.splitlines() if line.startswith("warning: ")]
    assert len(warnings) == 1 and "width x height" in warnings[0]
    # A map of no cells is valid: counted as empty, said as information, not as malformed.
    assert "1 malformed, 1 empty" in stdout
    code, _, err = _run(capsys, "process", built.path, "-o", out, "--force", "--debug")
    assert code == 0
    assert "info: /map: empty map (895 x 0 cells) at +2.0 s" in err, err
    got = read_all(out)
    assert got["/map"] == read_all(built.path)["/map"]  # copied through, unprocessed
    assert len(got["/map/rose/cleaned"]) == 2


def test_a_log_of_empty_maps_only_is_processed_not_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Maps of no cells are valid: a log holding only those was an error ("no map message could be
    analysed"); it is copied whole with the empty maps counted, and a gate says it cannot judge."""
    maps = [MapMsg(START_NS + i * 1_000_000_000, np.zeros((0, 0), dtype=np.int8)) for i in range(3)]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    out = tmp_path / "out.mcap"
    code, stdout, err = _run(capsys, "process", built.path, "-o", out, "--rrd", tmp_path / "r.rrd")
    assert code == 0, err
    assert "3 empty" in stdout and "warning" not in err
    assert read_all(out)["/map"] == read_all(built.path)["/map"]
    code, _, err = _run(capsys, "process", built.path, "--no-output", "--fail-above", "0.3")
    assert code == 3 and "no map message could be analysed, the gate cannot judge it" in err


def test_a_gate_fails_on_a_map_topic_it_cannot_judge(tmp_path: Path, capsys, fr079) -> None:
    """Two robots' maps, one topic all malformed: the run itself succeeds with warnings, but a
    quality gate cannot vouch for the topic it never saw a map of; both gates' reasons are said."""
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0]),
        MapMsg(START_NS + 2_000_000_000, fr079[1], topic="/robot2/map", bad_length=True),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    code, _, err = _run(capsys, "process", built.path, "--no-output")
    assert code == 0
    code, _, err = _run(
        capsys, "process", built.path, "--no-output", "--fail-above", "0.01", "--fail-on-break"
    )
    assert code == 3
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert any("exceeds --fail-above" in line for line in errors)
    assert any("/robot2/map: no map message could be analysed, the gate" in line for line in errors)


def test_a_gate_fails_on_a_topic_whose_maps_w_never_judged(tmp_path: Path, capsys) -> None:
    """Maps that were analysed but are all unknown (or of a few occupied cells) leave W without a
    judgement: a gate cannot vouch for them either (the run passed every gate before)."""
    unknown = np.full((60, 80), -1, dtype=np.int8)
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps([unknown, unknown]))
    assert _run(capsys, "process", built.path, "--no-output")[0] == 0
    for gate in (["--fail-above", "0.4"], ["--fail-on-break"]):
        code, _, err = _run(capsys, "process", built.path, "--no-output", *gate)
        assert code == 3
        assert (
            f"/map: no map had 20 or more occupied cells, the gate cannot judge it ({gate[0]})"
            in err
        )
    # Both gates: one line naming both (it named neither).
    code, _, err = _run(
        capsys, "process", built.path, "--no-output", "--fail-above", "0.4", "--fail-on-break"
    )
    assert code == 3
    assert "the gate cannot judge it (--fail-above, --fail-on-break)" in err


def _with_declared_map(source: Path, target: Path, topic: str) -> Path:
    """``source`` (an MCAP file of ROS 2 messages) copied to ``target`` with one more map topic,
    ``topic``, declared but holding no message."""
    from rose_logs.reader import LogReader
    from rose_logs.writer import open_output

    with LogReader(source) as reader, open_output(target, "mcap", serialization="cdr") as out:
        handles = {c.id: out.add_channel(c) for c in reader.channels}
        out.add_topic(topic, "nav_msgs/msg/OccupancyGrid", latching=True)
        for m in reader.messages():
            out.write_raw(handles[m.channel.id], m.log_time_ns, m.data)
    return target


def test_a_map_topic_declared_but_never_published_is_no_map_of_the_session(
    tmp_path: Path, capsys, fr079
) -> None:
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:2]))
    log = _with_declared_map(built.path, tmp_path / "declared.mcap", "/robot2/map")
    code, out_text, err = _run(capsys, "process", log, "--no-output", "--fail-above", "0.9")
    assert code == 0
    assert "/robot2/map" not in out_text
    # ... but said: a gate passing a recording whose costmap never came out did not mention it.
    assert (
        "warning: /robot2/map: a map topic the log declares but holds no message on: not "
        "analysed, and no gate judges it" in err.splitlines()
    )
    # info lists it and says why it is no map of the session (it printed an empty section).
    code, out_text, _ = _run(capsys, "info", log)
    assert code == 0
    section = out_text.split("map topic    /robot2/map\n", 1)[1].split("\n")[0]
    assert section.startswith("  no messages")


def test_a_map_topic_declared_only_and_named_with_topic_is_warned_of(
    tmp_path: Path, capsys, fr079
) -> None:
    """`-t /map -t /robot2/map`, the second declared but never published: the summary said
    "snapshots 0" for it, exit 0, without a word (named alone, it is an error)."""
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:2]))
    log = _with_declared_map(built.path, tmp_path / "declared.mcap", "/robot2/map")
    code, _, err = _run(capsys, "process", log, "--no-output", "-t", "/map", "-t", "/robot2/map")
    assert code == 0
    assert (
        "warning: /robot2/map: named with --topic, but the log declares it and holds no message "
        "on it: nothing to analyse (a gate asked for fails on it)" in err.splitlines()
    )
    # The gate cannot vouch for a map it was asked to judge and never saw.
    args = ("--no-output", "-t", "/map", "-t", "/robot2/map", "--fail-above", "0.9")
    assert _run(capsys, "process", log, *args)[0] == 3


def test_a_log_whose_map_topic_holds_no_message_says_so(tmp_path: Path, capsys) -> None:
    """It said "no map message on /map could be analysed (none)"."""
    from rose_logs.writer import open_output

    log = tmp_path / "empty.mcap"
    with open_output(log, "mcap", serialization="cdr") as out:
        out.add_topic("/map", "nav_msgs/msg/OccupancyGrid", latching=True)
    code, _, err = _run(capsys, "process", log, "--no-output")
    assert code == 1
    assert err.splitlines()[-1].endswith(
        "no map message on /map could be analysed (it holds none: declared only)"
    )


def test_a_log_whose_map_messages_were_all_lost_says_so_not_declared_only(
    tmp_path: Path, capsys, fr079
) -> None:
    """With --salvage, a damaged chunk holding the only map: the error said "declared only",
    under the warning that the map's message was lost."""
    from mcap.reader import make_reader

    log = build_log(tmp_path / "in.mcap", "mcap-ros2", [MapMsg(START_NS, fr079[0])]).path
    with log.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    first = min(c.chunk_start_offset for c in summary.chunk_indexes)
    data = bytearray(log.read_bytes())
    data[first + 200] ^= 0xFF  # inside the chunk holding the map (its CRC no longer matches)
    log.write_bytes(bytes(data))
    code, _, err = _run(capsys, "process", log, "--no-output", "--salvage")
    assert code == 1
    assert err.splitlines()[-1].endswith(
        "no map message on /map could be analysed (the damage above lost them)"
    )


def test_only_malformed_maps_is_an_error_without_output(tmp_path: Path, capsys, fr079) -> None:
    built = build_log(
        tmp_path / "in.mcap", "mcap-ros2", [MapMsg(START_NS, fr079[0], bad_length=True)]
    )
    code, _, err = _run(capsys, "process", built.path, "-o", tmp_path / "o.mcap")
    assert code == 1
    assert "no map message on /map could be analysed" in err.splitlines()[-1]
    assert _leftovers(tmp_path, {"in.mcap"}) == []


def test_a_map_placed_beyond_any_real_origin_is_skipped_as_malformed(
    tmp_path: Path, capsys, fr079
) -> None:
    """x = 1e308 is finite, but no cell position can be computed from it (walls came out null)."""
    maps = [MapMsg(START_NS, fr079[0]), MapMsg(START_NS + 1, fr079[1], origin_xy_m=(1e308, 0.0))]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    code, _, err = _run(capsys, "process", built.path, "--no-output", "--walls")
    assert code == 0
    assert "beyond +-1e+09 m" in err


def test_maps_over_the_cell_limit_are_named_so_and_warned_about_in_one_line(
    tmp_path: Path, capsys, fr079
) -> None:
    """A session of maps over --max-cells is not "malformed"; its warnings must not flood the
    terminal (a one-hour session has 720 snapshots): the first few one by one, the rest counted."""
    maps = [MapMsg(START_NS + i * 1_000_000_000, fr079[0]) for i in range(6)]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    code, _, err = _run(capsys, "process", built.path, "--no-output", "--max-cells", "1000")
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 5, err  # 3 warnings, 1 for the other 3, the error
    assert all("exceeds the limit" in line for line in lines[:3])
    # When, as the summary says it (session time) and as tools take it (log time, ns).
    assert f"at +1.0 s ({START_NS + 1_000_000_000} ns)" in lines[1]
    assert lines[3] == "warning: 3 more map messages over --max-cells, copied unprocessed"
    assert lines[4].endswith("no map message on /map could be analysed (6 over --max-cells)")
    assert "malformed" not in err


def test_an_output_suffix_that_names_no_format_is_warned_about(
    tmp_path: Path, capsys, mcap_log: Path
) -> None:
    """`-o out.mcpa` (a typo) writes the input's format under that name: said, not silent."""
    code, _, err = _run(capsys, "process", mcap_log, "-o", tmp_path / "out.mcpa", "-q")
    assert code == 0
    assert "warning: " in err and "'.mcpa' names no log format" in err
    # With --format too: the name is still one tools do not open as MCAP.
    code, _, err = _run(capsys, "process", mcap_log, "-o", tmp_path / "o2.mcpa", "--format", "mcap")
    assert code == 0 and "'.mcpa' names no log format (tools look for .mcap)" in err
    code, _, err = _run(capsys, "process", mcap_log, "-o", tmp_path / "o3.mcap", "-q")
    assert code == 0 and "warning" not in err
    # --format against the suffix: a db3 bag folder named .mcap that tools would open as MCAP.
    out = tmp_path / "o4.mcap"
    code, _, err = _run(capsys, "process", mcap_log, "-o", out, "--format", "db3", "-q")
    assert code == 0 and out.is_dir()
    assert f"warning: {out}: written as db3 (--format), but '.mcap' names mcap" in err
    code, _, err = _run(capsys, "process", mcap_log, "--no-output", "--format", "mcap")
    assert code == 2 and "--no-output and --format exclude each other" in err


def test_an_output_refused_anyway_gets_no_suffix_warning_first(
    tmp_path: Path, capsys, mcap_log: Path
) -> None:
    """`process p.log -o p.log` warned that '.log' names no format, then refused to write over
    the input: the refusal comes first and alone."""
    renamed = tmp_path / "p.log"
    renamed.write_bytes(mcap_log.read_bytes())
    code, _, err = _run(capsys, "process", renamed, "-o", renamed)
    assert code == 1
    _assert_one_line_error(err, "refusing to write over the input")
    code, _, err = _run(capsys, "process", mcap_log, "-o", mcap_log, "--format", "db3")
    assert code == 1
    _assert_one_line_error(err, "refusing to write over the input")


def test_an_output_log_the_session_refuses_gets_no_suffix_warning_first(
    tmp_path: Path, capsys, mcap_log: Path
) -> None:
    """`process run.mcap --format ros1 -o y.mcap` (ROS 2 messages) warned that '.mcap' names mcap,
    then refused the format: the refusal comes alone. So for an input processed before."""
    here = tmp_path / "out"
    here.mkdir()
    code, _, err = _run(capsys, "process", mcap_log, "--format", "ros1", "-o", here / "y.mcap")
    assert code == 1
    _assert_one_line_error(err, "cannot store ROS 2 (CDR) messages in format 'ros1'")
    done = here / "done.mcap"
    assert _run(capsys, "process", mcap_log, "-o", done, "-q")[0] == 0
    code, _, err = _run(capsys, "process", done, "--format", "db3", "-o", here / "again.mcap")
    assert code == 1
    _assert_one_line_error(err, "(processed before?)")
    assert sorted(p.name for p in here.iterdir()) == ["done.mcap"]
    # Accepted, the output gets its warning (before the summary).
    out = here / "y.bag"
    code, _, err = _run(capsys, "process", mcap_log, "--format", "mcap", "-o", out, "-q")
    assert code == 0
    assert err == f"warning: {out}: written as mcap (--format), but '.bag' names ros1\n"


@pytest.mark.parametrize(
    ("option", "name", "said"),
    [
        ("--rrd", "run.txt", "a Rerun recording written under a '.txt' name (expected .rrd)"),
        ("--rrd", "run", "a Rerun recording written under a name without a suffix (expected .rrd)"),
        ("--json", "report.rrd", "a JSON report written under a '.rrd' name (expected .json)"),
    ],
)
def test_a_recording_or_report_named_with_another_suffix_is_warned_about(
    tmp_path: Path, capsys, mcap_log: Path, option: str, name: str, said: str
) -> None:
    """`--rrd run.txt` (a file `rerun` does not open as a recording) and `--json report.rrd` were
    written without a word, where a log output's odd suffix is warned about."""
    out = tmp_path / name
    code, _, err = _run(capsys, "process", mcap_log, "--no-output", option, out, "-q")
    assert code == 0 and out.is_file()
    assert f"warning: {out}: {said}\n" in err


def test_a_recording_and_report_with_their_suffixes_get_no_warning(
    tmp_path: Path, capsys, mcap_log: Path
) -> None:
    code, _, err = _run(
        capsys,
        "process",
        mcap_log,
        "-o",
        tmp_path / "o.mcap",
        "--rrd",
        tmp_path / "r.RRD",
        "--json",
        tmp_path / "r.json",
        "-q",
    )
    assert code == 0 and "warning" not in err
    code, _, err = _run(capsys, "process", mcap_log, "--no-output", "--json", "-", "-q")
    assert code == 0 and "warning" not in err


@pytest.mark.parametrize(
    ("argv", "refusal"),
    [
        (["--rrd", "{log}"], "refusing to write over the input"),
        (["--json", "{tmp}/old.txt"], "exists already"),
        (["--rrd", "{tmp}/x.txt", "--json", "{tmp}/x.txt"], "given for two outputs"),
        (["-o", "{tmp}/x.txt", "--rrd", "{tmp}/x.txt"], "given for two outputs"),
    ],
)
def test_a_recording_or_report_refused_anyway_gets_no_suffix_warning_first(
    tmp_path: Path, capsys, mcap_log: Path, argv: list[str], refusal: str
) -> None:
    """As for the log: the refusal comes first and alone."""
    (tmp_path / "old.txt").write_text("keep")
    argv = [a.format(log=mcap_log, tmp=tmp_path) for a in argv]
    code, _, err = _run(capsys, "process", mcap_log, *argv, "-q")
    assert code == 1
    _assert_one_line_error(err, refusal)
    assert (tmp_path / "old.txt").read_text() == "keep"


def test_existing_output_needs_force(tmp_path: Path, capsys, mcap_log: Path) -> None:
    out = tmp_path / "out.mcap"
    out.write_bytes(b"precious")
    code, _, err = _run(capsys, "process", mcap_log, "-o", out)
    assert code == 1
    _assert_one_line_error(err, "out.mcap", "exists already", "--force")
    assert out.read_bytes() == b"precious"
    code, _, _ = _run(capsys, "process", mcap_log, "-o", out, "--force", "--quiet")
    assert code == 0
    assert "/map/rose/cleaned" in read_all(out)
    assert _leftovers(tmp_path, {"in.mcap", "out.mcap"}) == []


def test_existing_folder_output_replaced_with_force(tmp_path: Path, capsys, fr079) -> None:
    built = build_log(tmp_path / "in", "db3", session_maps(fr079[:1]))
    out = tmp_path / "out"
    assert _run(capsys, "process", built.path, "-o", out, "-q")[0] == 0
    assert _run(capsys, "process", built.path, "-o", out)[0] == 1
    assert _run(capsys, "process", built.path, "-o", out, "-f", "-q")[0] == 0
    assert "/map/rose/cleaned" in read_all(out)
    assert _leftovers(tmp_path, {"in", "out"}) == []


def test_force_never_deletes_a_folder_that_is_no_bag(tmp_path: Path, capsys, fr079) -> None:
    built = build_log(tmp_path / "in", "db3", session_maps(fr079[:1]))
    out = tmp_path / "photos"
    out.mkdir()
    (out / "old.txt").write_text("old")
    code, _, err = _run(capsys, "process", built.path, "-o", out, "-f")
    assert code == 1
    _assert_one_line_error(err, "photos", "not a ROS 2 bag")
    assert (out / "old.txt").read_text() == "old"


def test_output_never_replaces_the_input(tmp_path: Path, capsys, mcap_log: Path) -> None:
    before = mcap_log.read_bytes()
    code, _, err = _run(capsys, "process", mcap_log, "-o", mcap_log, "--force")
    assert code == 1
    _assert_one_line_error(err, "refusing to write over the input")
    assert mcap_log.read_bytes() == before


def test_a_storage_file_of_a_bag_is_read_but_its_bag_folder_is_never_written(
    tmp_path: Path, capsys, fr079
) -> None:
    """``process bag/bag.db3``: any output inside the bag folder (its metadata.yaml, a nested
    bag) would damage the input bag; the default output goes beside the folder."""
    built = build_log(tmp_path / "bag", "db3", session_maps(fr079[:2]))
    storage = next(built.path.glob("*.db3"))
    before = tree_bytes(built.path)
    for extra in (
        ["--no-output", "--json", built.path / "metadata.yaml", "--force"],
        ["-o", built.path / "nested.mcap"],
        ["--no-output", "--rrd", built.path / "run.rrd"],
    ):
        code, _, err = _run(capsys, "process", storage, *extra)
        assert code == 1
        _assert_one_line_error(err, "refusing to write inside the input")
    code, _, _ = _run(capsys, "process", storage)
    assert code == 0
    assert (tmp_path / f"{storage.stem}.rose" / "metadata.yaml").is_file()
    assert tree_bytes(built.path) == before


def test_missing_output_folder(tmp_path: Path, capsys, mcap_log: Path) -> None:
    code, _, err = _run(capsys, "process", mcap_log, "-o", tmp_path / "no" / "such" / "o.mcap")
    assert code == 1
    _assert_one_line_error(err, "does not exist")


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores directory permissions")
def test_unwritable_folder_by_permissions(tmp_path: Path, capsys, mcap_log: Path) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        code, _, err = _run(capsys, "process", mcap_log, "-o", locked / "o.mcap")
    finally:
        locked.chmod(0o700)
    assert code == 1
    _assert_one_line_error(err, "not writable")


def test_unwritable_folder(tmp_path: Path, capsys, mcap_log: Path) -> None:
    # /proc refuses new files even for root
    code, _, err = _run(capsys, "process", mcap_log, "-o", "/proc/rose-out.mcap")
    assert code == 1
    _assert_one_line_error(err, "rose-out.mcap")
    assert not Path("/proc/rose-out.mcap").exists()


def test_a_viewer_that_is_not_running_is_an_error_before_any_work(
    tmp_path: Path, capsys, mcap_log: Path
) -> None:
    """Rerun's stream connects lazily: without a check first, the whole session ran and then the
    run failed at the final flush, its log and report thrown away."""
    import socket

    with socket.socket() as sock:  # a port nothing listens on once the socket is closed
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    out, report = tmp_path / "o.mcap", tmp_path / "r.json"
    code, _, err = _run(
        capsys, "process", mcap_log, "-o", out, "--json", report, "--connect", f"127.0.0.1:{port}"
    )
    assert code == 1
    _assert_one_line_error(err, f"the Rerun viewer at 127.0.0.1:{port}; is it running?")
    assert "refused" in err.lower()
    assert _leftovers(tmp_path, {mcap_log.name}) == []


@pytest.mark.skipif(sys.platform.startswith(("darwin", "win")), reason="X11 / Wayland only")
def test_spawn_without_a_display_is_an_error_before_any_work(
    tmp_path: Path, capsys, mcap_log: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The spawned viewer died at once without a display, and the run failed 28 s later."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    out = tmp_path / "o.mcap"
    code, _, err = _run(capsys, "process", mcap_log, "-o", out, "--spawn")
    assert code == 1
    _assert_one_line_error(err, "--spawn needs a display for the Rerun viewer")
    assert _leftovers(tmp_path, {mcap_log.name}) == []


def test_spawn_whose_viewer_does_not_start_is_an_error_before_any_work(
    tmp_path: Path, capsys, mcap_log: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A display set but unusable: the viewer died at start, the whole session ran, and its
    outputs were lost at the final flush (exit 1 after the work)."""
    import socket

    import rerun as rr

    from rose_logs.rerun import sink

    with socket.socket() as sock:  # the spawned viewer's port, with nothing listening on it
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setattr(sink, "SPAWNED_VIEWER", f"127.0.0.1:{port}")
    monkeypatch.setattr(rr.RecordingStream, "spawn", lambda self, **_: None)  # a viewer that died
    out, report = tmp_path / "o.mcap", tmp_path / "r.json"
    code, _, err = _run(capsys, "process", mcap_log, "-o", out, "--json", report, "--spawn")
    assert code == 1
    _assert_one_line_error(err, "--spawn: the Rerun viewer did not start")
    assert _leftovers(tmp_path, {mcap_log.name}) == []


def test_format_mismatch_is_an_error(tmp_path: Path, fr079) -> None:
    built = build_log(tmp_path / "in.bag", "ros1", session_maps(fr079[:1]))
    with pytest.raises(LogWriteError, match="cannot store ROS 1 messages"):
        process_log(built.path, output_path=tmp_path / "out", output_format="db3")
    assert _leftovers(tmp_path, {"in.bag"}) == []


def test_interrupted_run_leaves_nothing(tmp_path: Path, mcap_log: Path) -> None:
    def stop(*_: object) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        process_log(
            mcap_log, output_path=tmp_path / "o.mcap", rrd_path=tmp_path / "s.rrd", on_snapshot=stop
        )
    assert _leftovers(tmp_path, {"in.mcap"}) == []


def test_ctrl_c_is_taken_between_two_messages_not_where_it_lands(
    tmp_path: Path, mcap_log: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """A Ctrl-C raised where it landed could stop the main thread while it held a Future's lock:
    an analysis thread then waited on it for ever and the run hung (1 Ctrl-C in about 20, seen in
    a batch). It is held until the message in hand is done, then ends the run as before."""
    import os
    import signal

    import rose_logs.session.loop as loop

    real = loop._Loop._drain
    seen: list[str] = []

    def drain(self: loop._Loop, limit: int) -> None:
        if not seen:
            os.kill(os.getpid(), signal.SIGINT)  # lands in the loop's own work
            seen.append("after the signal")
        real(self, limit)
        seen.append("drained")

    monkeypatch.setattr(loop._Loop, "_drain", drain)
    out = tmp_path / "o.mcap"
    assert main(["process", str(mcap_log), "-o", str(out), "-q"]) == 130
    assert seen == ["after the signal", "drained"]  # that message finished, no other began
    assert "interrupted" in capsys.readouterr().err
    assert _leftovers(tmp_path, {"in.mcap"}) == []


def test_a_second_ctrl_c_ends_the_run_at_once(
    tmp_path: Path, mcap_log: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """The first Ctrl-C waits for the message in hand; a slow read or write held it for as long as
    it took, and a second one did nothing. The second ends the run where it lands."""
    import os
    import signal

    import rose_logs.session.loop as loop

    seen: list[str] = []

    def drain(self: loop._Loop, limit: int) -> None:
        os.kill(os.getpid(), signal.SIGINT)
        seen.append("held")
        os.kill(os.getpid(), signal.SIGINT)
        seen.append("after the second")

    monkeypatch.setattr(loop._Loop, "_drain", drain)
    out = tmp_path / "o.mcap"
    assert main(["process", str(mcap_log), "-o", str(out), "-q"]) == 130
    assert seen == ["held"]
    assert "interrupted" in capsys.readouterr().err
    assert _leftovers(tmp_path, {"in.mcap"}) == []


def test_a_signal_inside_the_reading_library_is_an_interrupt_not_a_corrupt_log(
    tmp_path: Path, mcap_log: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """A SIGTERM that lands while the MCAP library creates a class comes back wrapped in its
    RuntimeError (seen in the hostile corpus): the run must exit 143, not call the log corrupt."""
    import signal

    from rose.signals import Terminated
    from rose_logs.storage.mcap import McapReadBackend

    def interrupted(self: object, topics: object) -> object:
        try:
            raise Terminated(signal.SIGTERM)
        except Terminated as err:
            msg = "Error calling __set_name__ on 'Field' instance 'data' in 'Chunk'"
            raise RuntimeError(msg) from err
        yield  # a generator, like the real one

    monkeypatch.setattr(McapReadBackend, "messages", interrupted)
    out = tmp_path / "o.mcap"
    assert main(["process", str(mcap_log), "-o", str(out), "-q"]) == 143
    assert "interrupted" in capsys.readouterr().err
    assert _leftovers(tmp_path, {"in.mcap"}) == []


def test_reader_error_names_the_file(tmp_path: Path) -> None:
    from rose_logs.reader import LogReader

    with pytest.raises(LogReadError, match=r"x\.bag: no such file"):
        LogReader(tmp_path / "x.bag")


def test_reader_and_session_say_what_is_wrong_with_their_topics_and_flags(mcap_log: Path) -> None:
    """``topics=b"/map"`` read the numbers of its bytes as topics: no message, silently, from
    LogReader.messages, and an AttributeError from process_log (``[None]`` too); ``salvage="no"``
    salvaged; LogReader(None) failed in pathlib."""
    import rose
    from rose_logs.reader import LogReader

    with LogReader(mcap_log) as reader:
        assert sum(1 for _ in reader.messages(topics="/map")) > 0
        assert sum(1 for _ in reader.messages(topics=("/map",))) > 0
        for bad, words in ((b"/map", "got bytes"), (5, "got int"), ([None], "got None")):
            with pytest.raises(TypeError, match=f"topics must be .*{words}"):
                next(reader.messages(topics=bad))  # type: ignore[arg-type]
            with pytest.raises(rose.RoseError, match=f"topics must be .*{words}"):
                process_log(mcap_log, topics=bad)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="salvage must be True or False, got 'no'"):
        LogReader(mcap_log, salvage="no")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="path must be a log's file or folder name, got NoneType"):
        LogReader(None)  # type: ignore[arg-type]
    assert LogReader(os.fsencode(mcap_log), salvage=np.bool_(True)).path == mcap_log


def test_a_session_refuses_arguments_of_the_wrong_kind_before_any_work(
    mcap_log: Path, tmp_path: Path
) -> None:
    """on_snapshot=5 failed after the first snapshot was analysed ('int' object is not
    callable), output_path=5 in pathlib, outputs=5 with an AttributeError, salvage="no"
    salvaged; each is now a RoseError naming the argument, and nothing is written. (A reader
    the caller made, ``reader``, must be of the input and its ``salvage``.)"""
    import rose
    from rose_logs.reader import LogReader

    out = tmp_path / "o.mcap"
    for kwargs, words in (
        ({"on_snapshot": 5}, "on_snapshot must be callable, got int"),
        ({"on_outputs_ready": "yes"}, "on_outputs_ready must be callable, got str"),
        ({"output_path": 5}, "output_path must be a file or folder name"),
        ({"output_path": out, "rrd_path": 5}, "rrd_path must be a file name"),
        ({"output_path": out, "outputs": 5}, "outputs must be a rose.outputs.OutputSet"),
        ({"output_path": out, "salvage": "no"}, "salvage must be True or False"),
        ({"output_path": out, "reader": 5}, "reader must be a LogReader of input_path"),
        (
            {"output_path": out, "reader": LogReader(mcap_log, salvage=True)},
            "reader must be a LogReader of input_path, made with the same salvage",
        ),
    ):
        with pytest.raises(rose.RoseError, match=words):
            process_log(mcap_log, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(rose.RoseError, match="input_path must be a file or folder name"):
        process_log(None)  # type: ignore[arg-type]
    assert _leftovers(tmp_path, {"in.mcap"}) == []


def test_a_writer_protects_one_path_given_alone(mcap_log: Path) -> None:
    """protected="in.mcap" was protected character by character (refused as "inside the input
    /"), and protected=Path("in.mcap") failed as not iterable."""
    from rose_logs.writer import open_output

    for protected in (str(mcap_log), mcap_log, [mcap_log]):
        with pytest.raises(LogWriteError, match=f"refusing to write over the input {mcap_log}$"):
            open_output(mcap_log, "mcap", force=True, protected=protected)


def test_debug_shows_traceback(tmp_path: Path) -> None:
    with pytest.raises(LogReadError):
        main(["--debug", "process", str(tmp_path / "nope.mcap")])


def test_a_snapshot_whose_results_cannot_be_encoded_keeps_the_numbering(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fr079, broken_grid
) -> None:
    """Snapshot 2's results cannot be written to the output log: it is counted as skipped there,
    but it is still analysed and recorded, so the break detector's trusted snapshot (which it is)
    and the records name the same snapshots."""
    import rose_logs.session.loop as loop

    real = loop.encode_score
    calls = []

    def fails_on_the_third(*args: object, **kwargs: object) -> bytes:
        calls.append(1)
        if len(calls) == 3:
            raise ValueError("a value out of range")
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(loop, "encode_score", fails_on_the_third)
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps([*fr079, broken_grid]))
    report = process_log(built.path, output_path=tmp_path / "out.mcap").to_json()
    assert [s["index"] for s in report["snapshots"]] == [0, 1, 2, 3]
    first = report["topics"]["/map"]["first_break"]
    assert (first["index"], first["trusted_index"]) == (3, 2)
    assert report["skipped_reasons"] == "1 not encodable"


def test_a_wrong_clean_method_is_one_error_before_the_log_is_read(tmp_path: Path, fr079) -> None:
    """It made every map fail on its own and ended blaming the log ("no map message could be
    analysed")."""
    import rose

    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:1]))
    with pytest.raises(
        rose.RoseError, match="clean_method must be one of walls, paper, got 'Paper'"
    ):
        process_log(built.path, clean_method="Paper")  # type: ignore[arg-type]
    with pytest.raises(rose.RoseError, match="params must be a RoseParams"):
        process_log(built.path, params={"peak_prominence": 0.3})  # type: ignore[arg-type]


def test_one_topic_given_as_a_string_is_one_topic(tmp_path: Path, fr079) -> None:
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[:1]))
    assert process_log(built.path, topics="/map").map_topics == ("/map",)  # type: ignore[arg-type]


@pytest.mark.parametrize("fmt", ["ros1", "db3", "mcap"])
def test_writer_refuses_a_message_of_another_type_or_an_unstorable_time(
    tmp_path: Path, fmt: str
) -> None:
    """A String written on a Float32 topic used to land as Float32(2.8e-45); negative or too late
    times were bare struct / SQLite errors. Both are LogWriteErrors naming the output."""
    from rose_logs.writer import open_output

    path = tmp_path / {"ros1": "out.bag", "db3": "out", "mcap": "out.mcap"}[fmt]
    with open_output(path, fmt) as out:  # type: ignore[arg-type]
        types = out.typestore.types
        out.add_topic("/x", "std_msgs/msg/Float32")
        out.write("/x", START_NS, types["std_msgs/msg/Float32"](data=1.0))
        with pytest.raises(
            LogWriteError, match="holds std_msgs/msg/Float32, got a std_msgs/msg/String"
        ):
            out.write("/x", START_NS, types["std_msgs/msg/String"](data="a"))
        for time_ns in (-5, 2**64):
            with pytest.raises(LogWriteError, match=f"{path}: log time"):
                out.write("/x", time_ns, types["std_msgs/msg/Float32"](data=1.0))
    assert [t for t, _ in read_all(path)["/x"]] == [START_NS]


def test_an_output_that_is_a_folder_is_named_so_without_advising_force(
    tmp_path: Path, capsys, mcap_log: Path
) -> None:
    """--json to a folder said 'exists already (use --force ...)', and with --force 'is a
    directory': the second answer comes first now."""
    folder = tmp_path / "adir"
    folder.mkdir()
    assert main(["process", str(mcap_log), "--no-output", "--json", str(folder)]) == 1
    err = capsys.readouterr().err
    assert f"{folder}: is a directory" in err and "--force" not in err


@pytest.mark.parametrize(
    ("extra", "written"),
    [
        (["-o", "out/"], None),
        (["-o", "out.mcap/"], None),
        (["--no-output", "--rrd", "out/"], None),
        (["--no-output", "--json", "out/"], None),
        (["-o", "out/", "--format", "mcap-dir"], "out"),
    ],
)
def test_an_output_file_named_as_a_folder_is_a_usage_error(
    tmp_path: Path, capsys, mcap_log: Path, monkeypatch, extra: list[str], written: str | None
) -> None:
    """``-o out/`` wrote the MCAP file ``out`` (the slash was dropped): a name ending in '/' is a
    folder, which only a ROS 2 bag output can be."""
    monkeypatch.chdir(tmp_path)
    if written is None:
        assert exit_code(["process", str(mcap_log), "-q", *extra]) == 2
        assert (
            "names a folder (it ends with a separator)" in capsys.readouterr().err.splitlines()[-1]
        )
        assert _leftovers(tmp_path, {"in.mcap"}) == []
    else:
        code, _, err = _run(capsys, "process", mcap_log, "-q", *extra)
        assert code == 0, err
        assert (tmp_path / written / "metadata.yaml").is_file()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"failure_level": -1.0}, "failure_level"),
        ({"failure_level": float("nan")}, "failure_level"),
        ({"analysis_threads": 0}, "analysis_threads"),
        ({"max_cells": 0}, "max_cells"),  # every map refused as too large, one warning each
        ({"max_cells": 2.5}, "max_cells"),
        ({"max_cells": float("nan")}, "max_cells"),
    ],
)
def test_process_log_refuses_bad_parameters_before_reading(
    tmp_path: Path, kwargs: dict, match: str
) -> None:
    """The Python API takes what the CLI takes (failure level in (0, 1]), as RoseErrors, before
    the input is read: a missing input is not even looked at."""
    import rose

    with pytest.raises(rose.RoseError, match=match):
        process_log(tmp_path / "missing.mcap", **kwargs)


def test_two_map_topics_that_would_share_their_outputs_are_named(
    tmp_path: Path, capsys, fr079
) -> None:
    """/map and /map/ both derive /map/rose/*: the error says so (it said the input had been
    processed before), and --topic picks one."""
    maps = [MapMsg(START_NS + 1, fr079[0]), MapMsg(START_NS + 2, fr079[1], topic="/map/")]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    code, _, err = _run(capsys, "process", built.path, "-o", tmp_path / "o.mcap", "-q")
    assert code == 1
    assert "map topics /map and /map/ would both be written to /map/rose/cleaned" in err
    assert not (tmp_path / "o.mcap").exists()
    code, _, _ = _run(capsys, "process", built.path, "-o", tmp_path / "o.mcap", "-q", "-t", "/map/")
    assert code == 0
    # /map and /Map have outputs of their own, but one set of Rerun entities (map/...).
    maps = [MapMsg(START_NS + 1, fr079[0]), MapMsg(START_NS + 2, fr079[1], topic="/Map")]
    built = build_log(tmp_path / "cased.mcap", "mcap-ros2", maps)
    code, _, err = _run(capsys, "process", built.path, "--no-output", "--rrd", tmp_path / "r.rrd")
    assert code == 1
    assert "map topics /Map and /map would both be recorded under the Rerun entity map" in err
    assert not (tmp_path / "r.rrd").exists()


def test_a_mistyped_topic_gets_a_suggestion(tmp_path: Path, capsys, fr079) -> None:
    """``-t map`` (no slash) or a typo names the close map topic, ``-t`` of an update topic names
    the map it updates."""
    patch = fr079[1][:10, :10]
    maps = [
        MapMsg(START_NS + 1, fr079[0]),
        MapMsg(START_NS + 2, patch, topic="/map_updates", xy=(0, 0)),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    for typed in ("map", "/mpa"):
        code, _, err = _run(capsys, "process", built.path, "--no-output", "-t", typed)
        assert code == 1
        _assert_one_line_error(err, f"no topic {typed} (map topics: /map); did you mean /map?")
    code, _, err = _run(capsys, "process", built.path, "--no-output", "-t", "/map_updates")
    assert code == 1
    _assert_one_line_error(err, "(it updates /map: pass --topic /map)")


@pytest.mark.parametrize("fmt", ["mcap", "db3", "ros1"])
def test_dropping_an_output_never_hides_the_error_that_dropped_it(tmp_path: Path, fmt: str) -> None:
    """On a nearly full disk closing the dropped log flushed its buffer and failed again: that
    second OSError replaced the first, and the run blamed the input ('fr079.mcap: No space left')."""
    from rose_logs.writer import open_output

    out = open_output(tmp_path / f"o.{fmt}", fmt)
    out.open()
    out.add_topic("/chatter", "std_msgs/msg/String")
    out.write("/chatter", START_NS, out.typestore.types["std_msgs/msg/String"](data="hi"))
    backend = out._backend
    assert backend is not None

    def full_disk() -> None:
        raise OSError(28, "No space left on device")

    backend.abort = full_disk  # type: ignore[method-assign]
    out.abort()  # no OSError
    out.abort()  # idempotent
    assert list(tmp_path.iterdir()) == []


def _db3_with_unmerged_writes(folder: Path) -> Path:
    """The bag's last messages moved into a write-ahead log, as a recorder that died left them
    (rosbag2's `resilient` preset keeps the database in WAL mode); returns the storage file."""
    import sqlite3

    storage = next(folder.glob("*.db3"))
    db = sqlite3.connect(storage)
    rows = db.execute("select id, topic_id, timestamp, data from messages order by id").fetchall()
    db.execute("delete from messages where id > ?", (rows[len(rows) // 2][0],))
    db.commit()
    db.execute("pragma journal_mode=wal")
    db.close()
    code = (
        "import os, pickle, sqlite3, sys\n"
        "db = sqlite3.connect(sys.argv[1]); db.execute('pragma wal_autocheckpoint=0')\n"
        "db.executemany('insert into messages values (?,?,?,?)', pickle.loads(sys.stdin.buffer.read()))\n"
        "db.commit(); os._exit(0)\n"  # dies: the WAL is never checkpointed
    )
    import pickle

    later = rows[len(rows) // 2 + 1 :]
    subprocess.run(
        [sys.executable, "-c", code, str(storage)], input=pickle.dumps(later), check=True
    )
    assert storage.with_name(storage.name + "-wal").stat().st_size > 32
    return storage


@pytest.mark.parametrize("with_metadata", [True, False])
def test_a_db3_bag_with_writes_in_its_wal_is_an_error_naming_it(
    tmp_path: Path, capsys, fr079, with_metadata: bool
) -> None:
    """rosbags opens the database immutable, without its -wal: half the messages were lost
    silently (Humble writes metadata.yaml only on close), or the bag was called damaged."""
    folder = build_log(tmp_path / "bag", "db3", session_maps(fr079[:2])).path
    storage = _db3_with_unmerged_writes(folder)
    if not with_metadata:
        (folder / "metadata.yaml").unlink()
    before = tree_bytes(folder)
    given = folder if with_metadata else storage
    code, _, err = _run(capsys, "process", given, "--no-output", "-q")
    assert code == 1
    _assert_one_line_error(err, f"{storage.name}-wal holds", "did not close", "sqlite3")
    assert tree_bytes(folder) == before


def test_a_storage_file_its_metadata_does_not_list_is_warned_about(
    tmp_path: Path, capsys, fr079
) -> None:
    """A split bag whose metadata.yaml was written before its last file: that file's messages
    were skipped without a word."""
    import shutil

    folder = build_log(tmp_path / "bag", "db3", session_maps(fr079[:2])).path
    storage = next(folder.glob("*.db3"))
    shutil.copy(storage, folder / "bag_9.db3")
    code, _, err = _run(capsys, "process", folder, "--no-output", "-q")
    assert code == 0
    assert "storage file bag_9.db3 is not listed in metadata.yaml" in err


@pytest.mark.parametrize("kind", ["cut short", "not a database", "a folder"])
def test_a_damaged_storage_file_its_metadata_does_not_list_is_warned_about_not_read(
    tmp_path: Path, capsys, fr079, kind: str
) -> None:
    """The last file of a split bag, written after its metadata.yaml and cut short by a recorder
    that did not close (or any unlisted file of a storage suffix that is no database): rose-bag
    reads only the listed files, but checked the types of every file in the folder and called
    the whole bag "corrupt or truncated log (database disk image is malformed)"."""
    folder = build_log(tmp_path / "bag", "db3", session_maps(fr079[:2])).path
    storage = next(folder.glob("*.db3"))
    extra = folder / "bag_9.db3"
    if kind == "cut short":
        extra.write_bytes(storage.read_bytes()[: storage.stat().st_size // 2])
    elif kind == "not a database":
        extra.write_bytes(b"\x00" * 4096)
    else:
        extra.mkdir()
    code, _, err = _run(capsys, "process", folder, "--no-output", "-q")
    assert code == 0, err
    assert "storage file bag_9.db3 is not listed in metadata.yaml" in err
    assert "corrupt" not in err


def test_control_characters_of_a_topic_name_do_not_reach_the_terminal(
    tmp_path: Path, capsys, fr079
) -> None:
    """Warning and error lines printed a topic's escape sequences and newlines raw: the screen
    cleared, and a forged `error:` line appeared."""
    topic = "/map\x1b[2J\nerror: fake"
    maps = [MapMsg(START_NS + 1_000_000_000, fr079[0], topic=topic)]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    code, _, err = _run(capsys, "process", built.path, "--no-output", "-q", "--fail-above", "0.01")
    assert code == 3
    assert "\x1b" not in err and "\\x1b[2J" in err
    assert all(line.startswith(("error: ", "warning: ")) for line in err.splitlines()), err
    assert not any(line.startswith("error: fake") for line in err.splitlines())


def test_an_output_hard_linked_to_a_file_of_the_input_bag_folder_is_refused(
    tmp_path: Path, capsys, fr079
) -> None:
    folder = build_log(tmp_path / "bag", "db3", session_maps(fr079[:1])).path
    before = tree_bytes(folder)
    linked = tmp_path / "report.json"
    os.link(folder / "metadata.yaml", linked)
    code, _, err = _run(capsys, "process", folder, "--no-output", "--json", linked, "--force")
    assert code == 1
    assert "report.json" in err
    assert tree_bytes(folder) == before


def test_an_update_of_a_map_over_max_cells_is_named_as_an_update(tmp_path: Path, capsys) -> None:
    """The skipped update was reported as a map message, at the update's time."""
    big = np.zeros((600, 600), dtype=np.int8)
    big[100:500, 100] = 100
    maps = [
        MapMsg(START_NS + 1_000_000_000, big),
        MapMsg(START_NS + 2_000_000_000, big[:10, :10], topic="/map_updates", xy=(0, 0)),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    _, _, err = _run(capsys, "process", built.path, "--no-output", "-q", "--max-cells", "300000")
    said = [line for line in err.splitlines() if "600 x 600" in line]
    assert len(said) == 2, err
    assert "/map: map of 600 x 600" in said[0] and "at +0.0 s" in said[0]
    assert "/map: map updated by a grid update of 600 x 600" in said[1] and "at +1.0 s" in said[1]


def test_costmaps_are_left_out_unless_named_or_alone(tmp_path: Path, capsys, fr079) -> None:
    """A Nav2 recording's costmaps are OccupancyGrids too: analysed by default, a person walking
    through the local costmap failed the break gate. They are left out with a warning beside a
    map, analysed when named with --topic, and when the log holds nothing else."""
    from dataclasses import replace

    maps = session_maps(fr079[:2])
    person = np.zeros((80, 80), dtype=np.int8)
    moved = person.copy()
    person[10:30, 10:30] = 100  # an inflated obstacle here, then there
    moved[50:70, 50:70] = 100
    costmaps = [
        replace(m, grid=g, topic="/local_costmap/costmap")
        for m, g in zip(maps, (person, moved), strict=True)
    ]
    built = build_log(tmp_path / "nav.mcap", "mcap-ros2", [*maps, *costmaps])
    code, out_text, err = _run(capsys, "process", built.path, "--no-output", "--json", "-")
    assert code == 0
    assert {s["topic"] for s in json.loads(out_text)["snapshots"]} == {"/map"}
    assert (
        "warning: /local_costmap/costmap: a costmap (a planner's obstacles: people, inflation), "
        "not analysed; name it with --topic to analyse it" in err.splitlines()
    )
    named = _run(
        capsys,
        "process",
        built.path,
        "--no-output",
        "--json",
        "-",
        "-t",
        "/local_costmap/costmap",
    )
    assert {s["topic"] for s in json.loads(named[1])["snapshots"]} == {"/local_costmap/costmap"}
    code, out_text, _ = _run(capsys, "info", built.path)
    assert "[map: a costmap, analysed only with --topic]" in out_text
    alone = build_log(tmp_path / "costmap.mcap", "mcap-ros2", costmaps)
    code, out_text, err = _run(capsys, "process", alone.path, "--no-output", "--json", "-")
    assert code == 0 and "not analysed" not in err
    assert len(json.loads(out_text)["snapshots"]) == 2


def test_info_marks_costmaps_as_process_picks_them(tmp_path: Path, capsys, fr079) -> None:
    """/map declared but empty and a published costmap: process analyses the costmap (the only
    published map), and info said it would not (it counted the declared /map)."""
    from dataclasses import replace

    costmaps = [replace(m, topic="/local_costmap/costmap") for m in session_maps(fr079[:2])]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", costmaps)
    log = _with_declared_map(built.path, tmp_path / "declared.mcap", "/map")
    code, out_text, _ = _run(capsys, "process", log, "--no-output", "--json", "-")
    assert code == 0
    assert {s["topic"] for s in json.loads(out_text)["snapshots"]} == {"/local_costmap/costmap"}
    code, out_text, _ = _run(capsys, "info", log)
    assert "analysed only with --topic" not in out_text


@pytest.mark.parametrize("fmt", ["ros1", "mcap-dir", "db3"])
def test_an_aborted_log_whose_close_fails_releases_its_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fmt: str
) -> None:
    """rosbags closes its file after writing the index: a close that failed on a full disk left
    the deleted output open, holding its disk space, until the process ended (a batch's later
    recordings then found the disk full too)."""
    import errno

    from rose_logs.storage.rosbags import Ros1WriteBackend, Ros2WriteBackend

    backend = (
        Ros1WriteBackend(tmp_path / "out.bag")
        if fmt == "ros1"
        else Ros2WriteBackend(tmp_path / "out", fmt)  # type: ignore[arg-type]
    )
    backend.open()
    writer = backend.writer
    holder = writer if fmt == "ros1" else writer.storage
    handle = getattr(holder, "conn" if fmt == "db3" else "bio")

    def full_disk(*args: object, **kwargs: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(writer, "close", full_disk)
    backend.abort()
    if fmt == "db3":
        with pytest.raises(Exception, match="closed"):
            handle.execute("SELECT 1")
    else:
        assert handle.closed
    assert backend.writer is None


def test_too_few_open_files_for_rerun_is_one_line_before_rerun_loads(
    tmp_path: Path, mcap_log: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Under ``ulimit -n 8`` loading Rerun panicked in its native runtime: the process aborted
    (exit 134, a Rust backtrace) and left the session's temporary outputs. Now: one line naming
    the recording, before Rerun loads, and nothing left."""
    resource = pytest.importorskip("resource")
    import rose_logs.session.sinks as sinks

    opened = sinks._open_files()
    if opened is None:
        pytest.skip("the number of open files is not known here")
    limits = (opened + 2, opened + 2)  # `ulimit -n` sets both
    monkeypatch.setattr(resource, "getrlimit", lambda _which: limits)
    raised: list[object] = []
    monkeypatch.setattr(resource, "setrlimit", lambda *args: raised.append(args))
    existing = tmp_path / "s.rrd"
    existing.write_bytes(b"old")
    with pytest.raises(LogWriteError) as err:
        process_log(mcap_log, output_path=tmp_path / "o.mcap", rrd_path=existing, force=True)
    message = f"error: {err.value}"
    _assert_one_line_error(message, f"{existing}: cannot open the Rerun recording (too few open")
    assert raised == []
    assert existing.read_bytes() == b"old"
    assert _leftovers(tmp_path, {"in.mcap", "s.rrd"}) == []


@pytest.mark.skipif(sys.platform == "win32", reason="no ulimit -f")
@pytest.mark.parametrize(
    ("limit", "said"),
    [
        # Its first write failed: Rerun waited for its dead file writer for ever (a hang, deaf to
        # SIGTERM); now refused before it starts.
        (1024, "files written are limited to 1024 bytes, ulimit -f"),
        # It failed as it grew: said, but not why.
        (64 * 1024, "files written are limited to 65536 bytes (ulimit -f)"),
    ],
)
def test_a_file_size_limit_too_small_for_the_recording_is_one_line(
    tmp_path: Path, mcap_log: Path, limit: int, said: str
) -> None:
    import resource

    existing = tmp_path / "s.rrd"
    existing.write_bytes(b"old")
    argv = ["process", str(mcap_log), "--no-output", "--rrd", str(existing), "--force"]
    done = subprocess.run(
        [sys.executable, "-m", "rose_logs.cli", *argv],
        capture_output=True,
        text=True,
        preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit)),
        timeout=120,
    )
    assert done.returncode == 1, done.stderr
    _assert_one_line_error(done.stderr, f"{existing}: cannot write the Rerun recording (", said)
    assert existing.read_bytes() == b"old"
    assert _leftovers(tmp_path, {"in.mcap", "s.rrd"}) == []


@pytest.mark.parametrize(("written", "named"), [(10**6, False), (10**12, True), (None, True)])
def test_a_file_size_limit_is_named_only_when_the_recording_reached_it(
    monkeypatch: pytest.MonkeyPatch, written: int | None, named: bool
) -> None:
    """A recording that failed far below a generous ``ulimit -f`` failed for another reason: the
    limit was named whenever one was set, sending users after the wrong cause."""
    import rose_logs.session.sinks as sinks

    monkeypatch.setattr(sinks, "_file_size_limit", lambda: 10**12)
    said = sinks.rerun_failure("r.rrd", None, RuntimeError("writer stopped"), written=written)
    assert ("limited to 1000000000000 bytes (ulimit -f)" in said) is named, said


def test_too_few_open_files_for_rerun_raises_the_soft_limit_when_the_hard_one_allows(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    resource = pytest.importorskip("resource")
    import rose_logs.session.sinks as sinks

    monkeypatch.setattr(sinks, "_open_files", lambda: 10)
    monkeypatch.setattr(resource, "getrlimit", lambda _which: (12, 4096))
    raised: list[object] = []
    monkeypatch.setattr(resource, "setrlimit", lambda *args: raised.append(args))
    sinks._check_files_for_rerun("r.rrd")
    assert raised == [(resource.RLIMIT_NOFILE, (10 + sinks.RERUN_FILES, 4096))]


@pytest.mark.parametrize(
    ("raised", "said"),
    [
        (RuntimeError("can't start new thread"), "out of memory (a thread could not start)"),
        (
            ImportError("/x/cv2.abi3.so: failed to map segment from shared object", name="cv2"),
            "out of memory (library cv2 could not be loaded)",
        ),
    ],
)
def test_address_space_running_out_is_one_line(
    tmp_path: Path, mcap_log: Path, monkeypatch: pytest.MonkeyPatch, capsys, raised, said
) -> None:
    """Under ``ulimit -v`` a thread that cannot start, or a native library loaded on demand that
    cannot be mapped, was a traceback: now one line, exit 1, nothing left."""

    def fail(*_: object, **__: object) -> None:
        raise raised

    monkeypatch.setattr("rose_logs.session.process_log", fail)
    out = tmp_path / "o.mcap"
    assert main(["process", str(mcap_log), "-o", str(out)]) == 1
    _assert_one_line_error(capsys.readouterr().err, said)
    assert _leftovers(tmp_path, {"in.mcap"}) == []


def test_zstd_out_of_memory_writing_the_output_is_one_line(
    tmp_path: Path, mcap_log: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """Under ``ulimit -v`` zstd failing to allocate as the MCAP output's chunk was compressed
    (``ZstdError: cannot compress: Allocation error : not enough memory``) was a traceback: now
    one line, exit 1, nothing left."""
    import zstandard

    def fail(*_: object, **__: object) -> bytes:
        raise zstandard.ZstdError("cannot compress: Allocation error : not enough memory")

    monkeypatch.setattr(zstandard, "compress", fail)
    out = tmp_path / "o.mcap"
    assert main(["process", str(mcap_log), "-o", str(out)]) == 1
    _assert_one_line_error(capsys.readouterr().err, "out of memory")
    assert _leftovers(tmp_path, {"in.mcap"}) == []


def _zstd_out_of_memory() -> Exception:
    import zstandard

    return zstandard.ZstdError("cannot decompress: Allocation error : not enough memory")


@pytest.mark.parametrize("salvage", [False, True], ids=["plain", "salvage"])
@pytest.mark.parametrize("raised", [MemoryError, _zstd_out_of_memory], ids=["MemoryError", "zstd"])
def test_memory_running_out_while_reading_is_not_a_corrupt_log(
    tmp_path: Path, mcap_log: Path, monkeypatch: pytest.MonkeyPatch, capsys, salvage, raised
) -> None:
    """Memory running out as a chunk of a sound log was read (``ulimit -v``) was said "corrupt or
    truncated log; --salvage keeps what can be read", and ``--salvage`` skipped the chunk as
    damaged and went on: a sound file called broken, or maps lost without a word of why. Now
    "out of memory", one line, exit 1, nothing written, salvaging or not."""

    def fail(*_: object, **__: object) -> None:
        raise raised()

    monkeypatch.setattr("mcap.stream_reader.breakup_chunk", fail)
    monkeypatch.setattr("rose_logs.errors.memory_short", lambda _bytes: True)
    out = tmp_path / "o.mcap"
    argv = ["process", str(mcap_log), "-o", str(out)] + (["--salvage"] if salvage else [])
    assert main(argv) == 1
    err = capsys.readouterr().err
    _assert_one_line_error(err, "in.mcap", "out of memory")
    assert "corrupt" not in err
    assert _leftovers(tmp_path, {"in.mcap"}) == []


def test_an_allocation_failing_with_memory_to_spare_is_damage(
    tmp_path: Path, mcap_log: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """A length field damaged to terabytes fails its allocation on any machine: that is a
    corrupt log (rosbags reading a record of 2**40 bytes was said "out of memory")."""

    def fail(*_: object, **__: object) -> None:
        raise MemoryError

    monkeypatch.setattr("mcap.stream_reader.breakup_chunk", fail)
    monkeypatch.setattr("rose_logs.errors.memory_short", lambda _bytes: False)
    code, _, err = _run(capsys, "process", mcap_log, "-o", tmp_path / "o.mcap")
    assert code == 1
    _assert_one_line_error(err, "in.mcap", "corrupt or truncated log")
    assert _leftovers(tmp_path, {"in.mcap"}) == []


@pytest.mark.parametrize("salvage", [False, True], ids=["plain", "salvage"])
def test_a_decompressor_that_cannot_be_loaded_is_no_damage(
    tmp_path: Path, mcap_log: Path, salvage: bool
) -> None:
    """zstd's library failing to load (``failed to map segment`` under ``ulimit -v``): mcap reads
    on without it, and every chunk of a sound log was "unsupported compression type zstandard",
    a corrupt log (``--salvage`` skipped them all, exit 4). Now the library's failure, one line."""
    code = (
        "import sys\n"
        "class Refuse:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'zstandard':\n"
        "            raise ImportError('zstandard: failed to map segment', name='zstandard')\n"
        "sys.meta_path.insert(0, Refuse())\n"
        "from rose_logs.cli import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    argv = ["info", str(mcap_log)] + (["--salvage"] if salvage else [])
    done = subprocess.run(
        [sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 1, done.stdout + done.stderr
    _assert_one_line_error(done.stderr, "out of memory (library zstandard could not be loaded)")


@pytest.mark.skipif(sys.platform == "win32", reason="no ulimit -v")
def test_memory_is_short_under_a_tight_address_space_limit_only() -> None:
    code = (
        "import resource, sys; from rose.limits import memory_short; "
        "print(memory_short(256 << 20)); "
        "used = int(open('/proc/self/status').read().split('VmSize:')[1].split()[0]) * 1024; "
        "resource.setrlimit(resource.RLIMIT_AS, (used + (64 << 20), resource.RLIM_INFINITY)); "
        "print(memory_short(256 << 20))"
    )
    if not Path("/proc/self/status").exists():
        pytest.skip("no /proc here")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "True"]


@pytest.mark.parametrize("kind", ["ros1", "db3"])
def test_memory_running_out_while_reading_a_rosbags_log_is_not_a_corrupt_log(
    tmp_path: Path, capsys, fr079, monkeypatch: pytest.MonkeyPatch, kind: str
) -> None:
    """As above, for the logs rosbags reads (a ROS 1 bag, a ROS 2 sqlite3 bag)."""
    import rosbags.rosbag1
    import rosbags.rosbag2

    built = build_log(log_path(tmp_path, kind), kind, session_maps(fr079[:2]))

    def fail(*_: object, **__: object) -> None:
        raise MemoryError

    reader = rosbags.rosbag1.Reader if kind == "ros1" else rosbags.rosbag2.Reader
    monkeypatch.setattr(reader, "messages", fail)
    monkeypatch.setattr("rose_logs.errors.memory_short", lambda _bytes: True)
    # A ROS 1 bag salvaged is read chunk by chunk by our own reader.
    monkeypatch.setattr("rose_logs.storage.ros1_stream.chunk_messages", fail)
    for salvage in ([], ["--salvage"]):
        out = log_path(tmp_path, kind, "out")
        code, _, err = _run(capsys, "process", built.path, "-o", out, *salvage)
        assert code == 1, err
        _assert_one_line_error(err, built.path.name, "out of memory")
        assert "corrupt" not in err
        assert _leftovers(tmp_path, {built.path.name}) == []


def test_other_runtime_and_import_errors_stay_tracebacks(
    mcap_log: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def fail(*_: object, **__: object) -> None:
        raise RuntimeError("a bug")

    monkeypatch.setattr("rose_logs.session.process_log", fail)
    with pytest.raises(RuntimeError, match="a bug"):
        main(["process", str(mcap_log), "--no-output"])


def test_rerun_failing_to_start_says_one_line_and_no_finaliser_traceback(
    tmp_path: Path, mcap_log: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """Rerun's native recording failing to start (no thread for its batcher under ``ulimit -v``):
    its RecordingStream finaliser then printed "Exception ignored ... no attribute 'inner'"."""
    import gc

    import rerun_bindings

    def fail(**_: object) -> None:
        raise RuntimeError("Failed to spawn the underlying batcher")

    monkeypatch.setattr(rerun_bindings, "new_recording", fail)
    unraisable: list[object] = []
    monkeypatch.setattr(sys, "unraisablehook", unraisable.append)
    code = main(["process", str(mcap_log), "--no-output", "--rrd", str(tmp_path / "r.rrd")])
    gc.collect()
    assert code == 1
    _assert_one_line_error(capsys.readouterr().err, "r.rrd: cannot open the Rerun recording")
    assert unraisable == []
    assert _leftovers(tmp_path, {"in.mcap"}) == []


def test_a_recursion_error_is_still_an_input_nested_too_deeply(
    tmp_path: Path, mcap_log: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """A RecursionError is a RuntimeError too: once RuntimeErrors that are not the memory running
    out were shown as tracebacks, it was one (and said "out of memory" before that), not the
    one-line "input nested too deeply"."""

    def fail(*_: object, **__: object) -> None:
        raise RecursionError("maximum recursion depth exceeded")

    monkeypatch.setattr("rose_logs.session.process_log", fail)
    assert main(["process", str(mcap_log), "-o", str(tmp_path / "o.mcap")]) == 1
    _assert_one_line_error(capsys.readouterr().err, "input nested too deeply")


def _failing_disk(monkeypatch: pytest.MonkeyPatch, path: Path, start: int, end: int) -> None:
    """Reads of ``path`` (opened binary through ``Path.open``) at offsets ``start`` to ``end`` fail
    with EIO, as on a failing disk or a network file system that went away."""
    import errno

    real_open = Path.open

    class FailingDisk:
        def __init__(self, stream) -> None:  # type: ignore[no-untyped-def]
            self.stream = stream

        def __getattr__(self, name: str) -> object:
            return getattr(self.stream, name)

        def __enter__(self) -> FailingDisk:
            return self

        def __exit__(self, *_: object) -> None:
            self.stream.close()

        def _check(self) -> None:
            if start <= self.stream.tell() < end:
                raise OSError(errno.EIO, "Input/output error")

        def read(self, size: int = -1) -> bytes:
            self._check()
            return self.stream.read(size)

        def readinto(self, buffer) -> int:  # type: ignore[no-untyped-def]
            self._check()
            return self.stream.readinto(buffer)

    def failing_open(opened: Path, mode: str = "r", *args: object, **kwargs: object) -> object:
        stream = real_open(opened, mode, *args, **kwargs)  # type: ignore[call-overload]
        return FailingDisk(stream) if opened == path and "b" in mode else stream

    monkeypatch.setattr(Path, "open", failing_open)


@pytest.mark.parametrize("salvage", [False, True])
def test_an_io_error_of_the_storage_under_a_log_is_no_damage(
    tmp_path: Path,
    mcap_log: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    salvage: bool,
) -> None:
    """An EIO from a failing disk or a network file system part way through a sound log was
    "corrupt or truncated MCAP file", and ``--salvage`` kept what came before it as from a
    damaged file (exit 4): now one line naming the file and the I/O error, exit 1, no output."""

    _failing_disk(monkeypatch, mcap_log, mcap_log.stat().st_size // 2, mcap_log.stat().st_size)
    out = tmp_path / "o.mcap"
    code, _, err = _run(capsys, "process", mcap_log, "-o", out, *(["--salvage"] * salvage))
    assert code == 1, err
    _assert_one_line_error(err, f"{mcap_log}: ", "Input/output error")
    assert "corrupt" not in err and "damage" not in err
    assert not out.exists()


@pytest.mark.parametrize("salvage", [False, True])
def test_an_io_error_under_a_ros1_bags_chunks_is_no_damage(
    tmp_path: Path,
    fr079,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    salvage: bool,
) -> None:
    """The ROS 1 sibling of the test above: with --salvage, a ROS 1 bag's chunks are read through
    its index by read_chunk, which took an EIO there for a chunk that does not read, skipped it
    as damaged and exited 4 with the messages around it. One line, exit 1, no output."""
    import struct

    from rose_logs.storage.ros1_stream import read_index

    bag = build_log(tmp_path / "in.bag", "ros1", session_maps(fr079[:2])).path
    data = bag.read_bytes()
    chunk = read_index(bag).chunks[-1].pos  # the data of the last chunk does not read
    header_end = chunk + 4 + struct.unpack_from("<I", data, chunk)[0]
    start = header_end + 4  # (rosbags reads every chunk's header, and its index data, on open)
    end = start + struct.unpack_from("<I", data, header_end)[0]
    _failing_disk(monkeypatch, bag, start, end)
    out = tmp_path / "o.bag"
    code, _, err = _run(capsys, "process", bag, "-o", out, *(["--salvage"] * salvage))
    assert code == 1, err
    _assert_one_line_error(err, f"{bag}: ", "Input/output error")
    assert "corrupt" not in err and "damage" not in err
    assert not out.exists()
