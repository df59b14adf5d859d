"""CARMEN log parsing on real logs and excerpts (``tests/data``) and on damaged lines."""

from __future__ import annotations

import gzip
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from cli_exit import exit_code
from numpy.testing import assert_allclose
from real_data import CARMEN_DIR, repo_data

from rose_logs.carmen.parse import (
    CarmenFormatError,
    beam_angles,
    parse_carmen_lines,
    parse_flaser_line,
    read_carmen_log,
)
from rose_logs.errors import LogWriteError

#: Whole logs in tests/data, and the first 400 lines of two more (``*.head400.log.gz``).
ACES = f"{CARMEN_DIR}/aces-corrected.log.gz"
FR101 = f"{CARMEN_DIR}/freiburg-101-corrected.log.gz"


def _excerpt(file_name: str, n_lines: int) -> list[str]:
    with gzip.open(repo_data(f"{CARMEN_DIR}/{file_name}"), "rt") as fh:
        return list(itertools.islice(fh, n_lines))


@pytest.mark.parametrize(
    ("file_name", "beams"),
    [
        ("aces-corrected.log.gz", 180),
        ("csail-corrected.head400.log.gz", 361),
        ("freiburg-079-corrected.head400.log.gz", 360),
    ],
)
def test_real_excerpt_parses_every_flaser_line(file_name: str, beams: int) -> None:
    lines = _excerpt(file_name, 400)
    assert len(lines) == 400
    log = parse_carmen_lines(lines)
    n_flaser = sum(line.startswith("FLASER") for line in lines)
    assert n_flaser > 0
    assert len(log.scans) == n_flaser
    assert log.malformed == 0
    assert sum(log.ignored.values()) == len(lines) - n_flaser
    scan = log.scans[0]
    assert scan.ranges_m.shape == (beams,)
    assert scan.ranges_m.dtype == np.float32
    # The corrected logs store the corrected pose twice: laser pose == odometry pose.
    assert_allclose(scan.laser_pose, scan.odom_pose)
    assert np.all(np.diff(log.stamps_ns) >= 0)


def test_first_aces_scan_values() -> None:
    # First FLASER line of aces: "FLASER 180 6.66 6.86 ... 0.89706 -0.180771 -0.454003 ... 21.0199 ..."
    log = parse_carmen_lines(_excerpt("aces-corrected.log.gz", 400))
    scan = log.scans[0]
    assert scan.ranges_m[0] == pytest.approx(6.66)
    assert scan.ranges_m[1] == pytest.approx(6.86)
    assert scan.stamp_ns == 21_019_900_000
    assert scan.line_number > 1


def test_read_gz_file_and_max_scans() -> None:
    log = read_carmen_log(repo_data(FR101), max_scans=5)
    assert len(log.scans) == 5
    assert log.laser_poses.shape == (5, 3)
    assert log.duration_s > 0


def test_plain_text_file_and_malformed_lines(tmp_path: Path) -> None:
    good = "FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n"
    lines = [
        "# comment\n",
        "PARAM robot_use_laser on nohost 0\n",
        good,
        "FLASER 3 1.0 2.0\n",  # truncated
        "FLASER x 1 2 3\n",  # bad count
        "FLASER 3 1.0 2.0 3.0 nan 0 0 0 0 0 1 h 1\n",  # non-finite pose
        "FLASER 3 1.0 abc 3.0 0 0 0 0 0 0 1 h 1\n",  # non-numeric
        "FLASER 3 1.0 -2 3.0 0 0 0 0 0 0 1 h 1\n",  # negative range
        "ODOM 0 0 0 0 0 0 1 h 1\n",
        "\n",
        good.replace("12.5", "13.0"),
    ]
    path = tmp_path / "log.txt"
    path.write_text("".join(lines))
    log = read_carmen_log(path)
    assert len(log.scans) == 2
    assert log.malformed == 5
    assert len(log.first_errors) == 5
    assert "line 4" in log.first_errors[0]
    assert log.ignored == {"#": 1, "PARAM": 1, "ODOM": 1, "": 1}
    assert log.scans[0].laser_pose == (0.5, -0.5, 0.1)
    assert log.scans[1].stamp_ns - log.scans[0].stamp_ns == 500_000_000


def test_convert_says_when_the_drift_starts_after_the_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A --drift-start past the last scan writes a correct session: the user is told, not misled."""
    from rose_logs.cli import main

    good = "FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n"
    path = tmp_path / "log.txt"
    path.write_text(good + good.replace("12.5", "13.0"))
    argv = ["convert", str(path), str(tmp_path / "s.mcap"), "--drift-level", "2"]
    assert main([*argv, "--drift-start", "5"]) == 0
    err = capsys.readouterr().err
    assert f"warning: {path}: --drift-start 5 s is after the session's last scan" in err
    assert main([*argv, "--drift-start", "0.2", "--force"]) == 0
    assert "warning" not in capsys.readouterr().err


@pytest.mark.parametrize("option", [["--drift-start", "0.2"], ["--drift-seed", "3"]])
def test_convert_warns_of_drift_options_without_a_level(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: list[str]
) -> None:
    """--drift-start / --drift-seed alone change nothing: said, not silently ignored."""
    from rose_logs.cli import main

    good = "FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n"
    path = tmp_path / "log.txt"
    path.write_text(good + good.replace("12.5", "13.0"))
    argv = ["convert", str(path), str(tmp_path / "s.mcap")]
    assert main([*argv, *option]) == 0
    assert "take effect with --drift-level only" in capsys.readouterr().err
    assert main([*argv, *option, "--drift-level", "1", "--force"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_convert_warns_of_an_output_suffix_that_names_no_format(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rose_logs.cli import main

    path = tmp_path / "log.txt"
    path.write_text("FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n")
    assert main(["convert", str(path), str(tmp_path / "s.txt")]) == 0
    assert "'.txt' names no log format" in capsys.readouterr().err
    assert (tmp_path / "s.txt" / "metadata.yaml").is_file()  # a ROS 2 bag folder, as said
    assert main(["convert", str(path), str(tmp_path / "s")]) == 0
    assert "warning" not in capsys.readouterr().err
    # --format against the suffix, as process says it (convert said nothing).
    assert main(["convert", str(path), str(tmp_path / "y.bag"), "--format", "mcap"]) == 0
    assert "written as mcap (--format), but '.bag' names ros1" in capsys.readouterr().err
    assert main(["convert", str(path), str(tmp_path / "z.mcap"), "--format", "mcap"]) == 0
    assert "warning" not in capsys.readouterr().err
    # A typo with --format given passed silently; a bag folder named as process names it did not.
    assert main(["convert", str(path), str(tmp_path / "q.mcpa"), "--format", "mcap"]) == 0
    assert "'.mcpa' names no log format (tools look for .mcap)" in capsys.readouterr().err
    assert main(["convert", str(path), str(tmp_path / "run.rose")]) == 0
    assert "warning" not in capsys.readouterr().err


def test_convert_refuses_its_input_as_output_without_a_suffix_warning_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`convert p.log p.log` warned that '.log' names no format, then refused to write over the
    input: the refusal should come first and alone, and so should that of an existing output."""
    from rose_logs.cli import main

    path = tmp_path / "p.log"
    path.write_text("FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n")
    before = path.read_bytes()
    assert main(["convert", str(path), str(path)]) == 1
    assert capsys.readouterr().err == f"error: {path}: refusing to write over the input {path}\n"
    assert path.read_bytes() == before
    (tmp_path / "s.txt").write_text("precious")
    assert main(["convert", str(path), str(tmp_path / "s.txt")]) == 1
    err = capsys.readouterr().err  # a file where the bag folder would go
    assert err == f"error: {tmp_path / 's.txt'}: is a file, not replacing it with a folder\n"


def test_convert_of_a_folder_or_missing_log_says_so_before_judging_its_outputs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """`convert . out.mcap` said `out.mcap: refusing to write inside the input .`: the output
    was fine to move, the input was never a log (`convert adir out.mcap` said so)."""
    from rose_logs.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["convert", ".", "out.mcap"]) == 1
    assert capsys.readouterr().err == "error: .: not a regular file\n"
    (tmp_path / "taken.mcap").write_bytes(b"precious")
    assert main(["convert", "missing.log", "taken.mcap"]) == 1
    err = capsys.readouterr().err
    assert err == "error: missing.log: no such file\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.mcap"]


def test_convert_of_a_log_inside_a_bag_folder_writes_nothing_into_that_bag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`convert bag/c.log bag/out.mcap` wrote into the bag folder: the check exempted a bag that
    holds the input, as for a bag given to `process`, but a CARMEN log is no part of the bag."""
    from rose_logs.cli import main

    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    log = bag / "c.log"
    log.write_text("FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n")
    for argv, output, option, what in (
        ([str(bag / "out.mcap")], bag / "out.mcap", "OUTPUT", "output log"),
        (
            [str(tmp_path / "o.mcap"), "--map-file", str(bag / "m.yaml")],
            bag / "m.yaml",
            "--map-file",
            "map file",
        ),
    ):
        assert main(["convert", str(log), *argv, "-q"]) == 1
        assert capsys.readouterr().err == (
            f"error: {output}: the {what} is inside the ROS 2 bag folder {bag} (it has "
            f"metadata.yaml): it would write into a recording; choose another {option}\n"
        )
    # Nor its image, through a symlink where it goes.
    (tmp_path / "m.pgm").symlink_to(bag / "m.pgm")
    argv = ["convert", str(log), str(tmp_path / "o.mcap"), "--map-file", str(tmp_path / "m.yaml")]
    assert main([*argv, "-q"]) == 1
    assert "m.pgm: the map's image is inside the ROS 2 bag folder" in capsys.readouterr().err
    assert sorted(p.name for p in bag.iterdir()) == ["c.log", "metadata.yaml"]


def test_convert_refuses_a_file_output_named_as_a_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``out.mcap/`` wrote the file ``out.mcap``; a db3 bag folder may end with '/'."""
    from rose_logs.cli import main

    path = tmp_path / "log.txt"
    path.write_text("FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n")
    for argv in (["o.mcap/"], ["o.bag/"], ["o/", "--format", "ros1"], ["s", "--map-file", "m/"]):
        assert exit_code(["convert", str(path), *argv]) == 2
        assert "names a folder (it ends with a separator)" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.txt"]
    assert main(["convert", str(path), f"{tmp_path}/bag/"]) == 0
    assert (tmp_path / "bag" / "metadata.yaml").is_file()


def test_convert_writes_a_ros2_bag_folder_with_mcap_storage_that_process_reads(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rose_logs.cli import main
    from rose_logs.reader import LogReader

    out = tmp_path / "session"
    argv = ["convert", str(repo_data(FR101)), str(out), "--max-scans", "60", "--format"]
    assert main([*argv, "mcap-dir", "--map-period", "5"]) == 0
    assert (out / "metadata.yaml").is_file()
    assert [p.suffix for p in out.iterdir() if p.name != "metadata.yaml"] == [".mcap"]
    with LogReader(out) as reader:
        assert reader.format == "mcap-dir"
        maps = sum(1 for m in reader.messages() if m.channel.topic == "/map")
    assert maps >= 2
    capsys.readouterr()
    assert main(["process", str(out), "--no-output", "-q", "--json", "-"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["input_format"] == "mcap-dir"
    assert len(report["snapshots"]) == maps


@pytest.mark.parametrize("x", ["999999990", "1e12", "1e300"])
def test_convert_refuses_poses_whose_map_no_tool_would_place(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], x: str
) -> None:
    """Poses of 1e12 m made a session that process then refused (origin beyond +-1e9 m); from 1e15
    m on, numpy warnings and an error blaming the output. One line naming the log and the scan."""
    from rose_logs.cli import main

    good = "FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n"
    far = good.replace("0.5 -0.5 0.1 0.5 -0.5", f"{x} -0.5 0.1 {x} -0.5")
    path = tmp_path / "log.txt"
    path.write_text(good + far.replace("12.5", "13.0"))
    out = tmp_path / "s.mcap"
    assert main(["convert", str(path), str(out), "-q"]) == 1
    err = capsys.readouterr().err
    assert err == (
        f"error: {path}: scan 2 is at ({float(x):.12g}, -0.5) m: a map around it would lie beyond "
        "+-1e+09 m of the origin, where no map is placed\n"
    )
    assert not out.exists()


def test_convert_warns_once_of_malformed_lines_naming_the_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rose_logs.cli import main

    good = "FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n"
    path = tmp_path / "log.txt"
    path.write_text(good + "FLASER x 1 2 3\n" + good.replace("12.5", "13.0"))
    assert main(["convert", str(path), str(tmp_path / "s.mcap")]) == 0
    warnings = [w for w in capsys.readouterr().err.splitlines() if w.startswith("warning:")]
    assert len(warnings) == 1, warnings
    assert warnings[0].startswith(f"warning: {path}: skipped 1 malformed FLASER lines")


def test_no_scan_is_an_error(tmp_path: Path) -> None:
    path = tmp_path / "empty.log"
    path.write_text("ODOM 0 0 0 0 0 0 1 h 1\nFLASER 2 1\n")
    with pytest.raises(CarmenFormatError, match="no FLASER scan"):
        read_carmen_log(path)


def test_a_file_that_is_not_what_its_name_says_is_named_so(tmp_path: Path) -> None:
    noise = bytes(range(256)) * 8  # binary: NUL bytes, no FLASER line
    (tmp_path / "fake.log.gz").write_bytes(noise)
    with pytest.raises(CarmenFormatError, match=r"fake.log.gz: not gzip-compressed \(its name"):
        read_carmen_log(tmp_path / "fake.log.gz")
    (tmp_path / "data.log").write_bytes(noise)
    with pytest.raises(CarmenFormatError, match=r"data.log: not a CARMEN log \(binary data"):
        read_carmen_log(tmp_path / "data.log")
    (tmp_path / "data.log.gz").write_bytes(gzip.compress(noise))  # compressed binary: the same
    with pytest.raises(CarmenFormatError, match=r"data.log.gz: not a CARMEN log \(binary data"):
        read_carmen_log(tmp_path / "data.log.gz")


def test_missing_file_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(CarmenFormatError, match=r"nope\.log\.gz: no such file"):
        read_carmen_log(tmp_path / "nope.log.gz")


def test_not_flaser_line() -> None:
    with pytest.raises(CarmenFormatError, match="not a FLASER"):
        parse_flaser_line("ODOM 0 0 0", line_number=7)


@pytest.mark.parametrize(("n", "increment_deg"), [(180, 1.0), (181, 1.0), (360, 0.5), (361, 0.5)])
def test_beam_angles(n: int, increment_deg: float) -> None:
    angles = beam_angles(n)
    assert angles.shape == (n,)
    assert angles[0] == pytest.approx(-math.pi / 2)
    assert_allclose(np.diff(angles), math.radians(increment_deg), rtol=1e-12)


# -- sessions written from a log (rose_logs.carmen.session) -------------------------------------
@pytest.mark.parametrize(
    ("name", "fmt"),
    [("s.bag", "ros1"), ("s_db3", "db3"), ("s.mcap", "mcap"), ("s_mcap_bag", "mcap-dir")],
)
def test_session_write_then_read(tmp_path: Path, name: str, fmt: str) -> None:
    from rosbags.highlevel import AnyReader

    from rose_logs.carmen.raycast import BuilderParams
    from rose_logs.carmen.session import SessionOptions, write_carmen_session

    log = read_carmen_log(repo_data(FR101), max_scans=40)
    out = tmp_path / name
    options = SessionOptions(
        builder_params=BuilderParams(resolution_m=0.2, grow_margin_m=2.0),
        map_period_s=20.0,
        pose_output="both",
    )
    # mcap-dir is never implied by a name: it is asked for.
    summary = write_carmen_session(
        log, out, options=options, fmt="mcap-dir" if fmt == "mcap-dir" else None
    )
    assert summary.scans == 40
    assert summary.format == fmt
    if fmt == "mcap-dir":  # a ROS 2 bag folder with MCAP storage
        assert sorted(p.suffix for p in out.iterdir()) == [".mcap", ".yaml"]
    with AnyReader([out]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts["/scan"] == 40 and counts["/tf"] == 40 and counts["/odom"] == 40
        assert counts["/map"] == summary.maps >= 2
        maps = [c for c in reader.connections if c.topic == "/map"]
        last = None
        for conn, _, raw in reader.messages(connections=maps):
            last = reader.deserialize(raw, conn.msgtype)
        assert last is not None
        grid = np.asarray(last.data, dtype=np.int8).reshape(last.info.height, last.info.width)
        np.testing.assert_array_equal(grid, summary.final_grid)
        assert last.info.resolution == pytest.approx(0.2)
        scans = [c for c in reader.connections if c.topic == "/scan"]
        conn, t_ns, raw = next(iter(reader.messages(connections=scans)))
        scan = reader.deserialize(raw, conn.msgtype)
        assert t_ns == log.scans[0].stamp_ns
        np.testing.assert_allclose(scan.ranges, log.scans[0].ranges_m)
    with pytest.raises(LogWriteError, match="exists already"):
        write_carmen_session(log, out)


def test_convert_command(tmp_path: Path) -> None:
    import argparse

    from rose_logs.cli.convert import add_parser as add_convert_parser

    parser = argparse.ArgumentParser()
    add_convert_parser(parser.add_subparsers())
    out = tmp_path / "drifted.bag"
    args = parser.parse_args(
        [
            "convert",
            str(repo_data(FR101)),
            str(out),
            "--max-scans", "20",
            "--resolution", "0.25",
            "--drift-level", "1",
            "--map-file", str(tmp_path / "final.yaml"),
        ]
    )  # fmt: skip
    assert args.func(args) == 0
    assert out.is_file()
    assert (tmp_path / "final.yaml").is_file()


def _on_a_terminal(argv: list[str]) -> str:
    """What ``rose-bag ARGV`` writes to stderr when stderr is a 100-column terminal."""
    import fcntl
    import os
    import pty
    import struct
    import subprocess
    import sys
    import termios

    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 100, 0, 0))
    code = "import sys; from rose_logs.cli import console; sys.exit(console())"
    process = subprocess.Popen(
        [sys.executable, "-c", code, *argv],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=follower,
    )
    os.close(follower)
    chunks = []
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # the follower side closed
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(leader)
    assert process.wait(timeout=120) == 0
    return b"".join(chunks).decode(errors="replace")


def test_convert_shows_progress_over_the_scans_on_a_terminal_unless_quiet(tmp_path: Path) -> None:
    argv = ["convert", str(repo_data(FR101)), str(tmp_path / "s.mcap"), "--max-scans", "30"]
    shown = _on_a_terminal(argv)
    assert "/30 [" in shown  # a bar over the 30 scans
    assert "scan/s" in shown
    assert "scan" not in _on_a_terminal([*argv, "--force", "-q"])


def test_convert_names_a_wrong_map_file_and_why_no_scan_was_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--map-file final.pgm`` read "used for two outputs"; a log of unreadable lines did not say
    why, and a range beyond float32 leaked numpy's overflow warning."""
    from rose_logs.cli import main

    good = "FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n"
    path = tmp_path / "log.txt"
    path.write_text(good)
    assert main(["convert", str(path), str(tmp_path / "s.mcap"), "--map-file", "final.pgm"]) == 2
    assert "final.pgm: --map-file names the map's YAML" in capsys.readouterr().err
    path.write_text(good.replace("0.5 -0.5", "inf -0.5", 1))
    assert main(["convert", str(path), str(tmp_path / "s.mcap")]) == 1
    err = capsys.readouterr().err
    assert err.strip().splitlines() == [
        f"error: {path}: no FLASER scan found (1 malformed FLASER lines; first: line 1: "
        "non-finite pose or timestamp)"
    ]
    # A log of other messages only (ODOM, ROBOTLASER1) said "0 malformed FLASER lines".
    path.write_text("ODOM 1 2 3 0 0 0 12.5 h 12.5\n" * 2 + "ROBOTLASER1 0 0 0\n# note\n")
    assert main(["convert", str(path), str(tmp_path / "s.mcap")]) == 1
    assert capsys.readouterr().err.strip().splitlines() == [
        f"error: {path}: no FLASER scan found: only FLASER lines are read; its lines start "
        "ODOM (2), ROBOTLASER1 (1)"
    ]
    path.write_text("# only a comment\n\n\x1b[31mX 1\n")  # an escape cannot drive the terminal
    assert main(["convert", str(path), str(tmp_path / "s.mcap")]) == 1
    assert "its lines start \\x1b[31mX (1)" in capsys.readouterr().err
    path.write_text("# only a comment\n\n")
    assert main(["convert", str(path), str(tmp_path / "s.mcap")]) == 1
    assert "the log is empty, or holds only comments" in capsys.readouterr().err


def test_flaser_ranges_without_a_return_and_lines_that_lie(tmp_path: Path) -> None:
    """inf, nan and a range beyond float32 are readings without a return (one such beam cost the
    whole scan); a beam count that does not match the ranges is malformed (it read ranges as the
    pose and the time); a huge count is refused before its ranges are read; a byte-order mark
    before the first line is no part of it (that scan was lost)."""
    good = "FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n"
    scan = parse_flaser_line(
        good.replace("2.0", "inf").replace("3.0", "nan").replace("1.0", "1e39")
    )
    assert np.isinf(scan.ranges_m).all() and scan.laser_pose == (0.5, -0.5, 0.1)
    assert parse_flaser_line(good.replace(" host 12.5", "")).stamp_ns == 12_500_000_000
    with pytest.raises(CarmenFormatError, match="2 beams announced, but 12 fields follow"):
        parse_flaser_line(good.replace("FLASER 3 ", "FLASER 2 "))  # the true count is 3
    with pytest.raises(CarmenFormatError, match="non-numeric value"):  # the hostname as a number
        parse_flaser_line(good.replace("FLASER 3 ", "FLASER 4 "))
    with pytest.raises(CarmenFormatError, match=r"beam count 3000000 outside 1\.\.100000"):
        parse_flaser_line("FLASER 3000000 " + "1.0 " * 10)
    path = tmp_path / "bom.log"
    path.write_text("\ufeff" + good + good.replace("12.5", "13.0"), encoding="utf-8")
    assert len(read_carmen_log(path).scans) == 2


def test_convert_max_scans_bound_reads_as_a_lower_bound(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The message gave the range 1..4611686018427387904."""
    from rose_logs.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["convert", "x.log", str(tmp_path / "s.mcap"), "--max-scans", "0"])
    assert stop.value.code == 2
    assert "expected an integer >= 1, got '0'" in capsys.readouterr().err


@pytest.mark.parametrize("value", ["99999999999999999999", "9" * 60])
def test_convert_max_scans_too_large_says_so_and_the_limit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str
) -> None:
    """It said `expected an integer >= 1`, of a number that is one."""
    from rose_logs.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["convert", "x.log", str(tmp_path / "s.mcap"), "--max-scans", value])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert f"argument --max-scans: too large, got {value[:40]!r} (at most 2**62 = 4.6e+18)" in err


def test_convert_max_range_within_the_shortest_reading_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It was exit 1 naming the output file and internal names (max_range_m > min_range_m)."""
    from rose_logs.cli import main

    path = tmp_path / "log.txt"
    path.write_text("FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n")
    assert main(["convert", str(path), str(tmp_path / "s.mcap"), "--max-range", "0.05"]) == 2
    assert "--max-range must be above the shortest reading kept, 0.05 m" in capsys.readouterr().err
    assert not (tmp_path / "s.mcap").exists()


@pytest.mark.parametrize(
    "option",
    [
        ["--map-period", "1e300"],
        ["--drift-level", "1", "--drift-start", "1e300"],
        ["--resolution", "1e300"],
        ["--resolution", "1e5"],
        ["--max-range", "1e200"],
        ["--drift-level", "1e300"],
    ],
)
def test_convert_option_values_beyond_sense_are_usage_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: list[str]
) -> None:
    """They overflowed deep inside (tracebacks), or wrote maps process refuses (1e5 m cells)."""
    from rose_logs.cli import main

    path = tmp_path / "log.txt"
    path.write_text("FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n")
    with pytest.raises(SystemExit) as stop:
        main(["convert", str(path), str(tmp_path / "s.mcap"), *option])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "expected" in err
    assert not (tmp_path / "s.mcap").exists()


def test_gzip_with_bytes_after_it_is_said_so(tmp_path: Path) -> None:
    """It read "cannot read CARMEN log (Not a gzipped file (b'ga'))" of a log zcat reads."""
    import gzip

    path = tmp_path / "log.gz"
    good = "FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n"
    path.write_bytes(gzip.compress(good.encode()) + b"garbage after the member\n")
    with pytest.raises(CarmenFormatError, match=r"corrupt gzip data .*no gzip member follow"):
        read_carmen_log(path)


def test_damaged_gzip_data_is_said_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A damaged byte inside the compressed data makes zlib's own error ("invalid distance too
    far back"), which is no OSError: ``rose-bag convert`` ended in a traceback (found by fuzzing)."""
    import gzip
    import zlib

    from real_data import CARMEN_DIR, repo_data

    from rose_logs.cli import main

    data = bytearray(repo_data(f"{CARMEN_DIR}/freiburg-079-corrected.head400.log.gz").read_bytes())
    path = tmp_path / "log.gz"
    for at in range(100, len(data) - 8):  # the first damage zlib itself refuses
        damaged = data.copy()
        damaged[at] ^= 0xFF
        try:
            gzip.decompress(bytes(damaged))
        except zlib.error:
            path.write_bytes(bytes(damaged))
            break
        except Exception:  # a CRC or length error: the gzip layer's, not zlib's; try on
            continue
    else:
        pytest.fail("no damage zlib refuses")
    with pytest.raises(CarmenFormatError, match=r"^\S+log\.gz: corrupt gzip data \(Error -3"):
        read_carmen_log(path)
    assert main(["convert", str(path), str(tmp_path / "s.mcap")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.startswith(f"error: {path}: corrupt gzip data")
    assert not (tmp_path / "s.mcap").exists()


def test_convert_refuses_a_map_file_clashing_with_the_session_before_ray_casting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The session named as the map's image, or a map inside the session's bag folder, was found
    only when the map was staged, after the whole log was ray cast."""
    from rose_logs.cli import convert, main

    path = tmp_path / "log.txt"
    path.write_text("FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n")

    def never(*_: object, **__: object) -> None:
        raise AssertionError("the log was converted before its outputs were checked")

    monkeypatch.setattr(convert, "write_carmen_session", never)
    monkeypatch.chdir(tmp_path)
    for argv, said in (
        (["out.pgm", "--format", "mcap", "--map-file", "out.yaml"], "out.pgm"),
        (["m2.yaml", "--format", "db3", "--map-file", "m2.yaml"], "m2.yaml: given for two"),
        # Not "folder bag does not exist": the map may never go inside the session's folder.
        (
            ["bag", "--map-file", "bag/m.yaml"],
            "bag/m.yaml: given for two outputs (also inside bag)",
        ),
    ):
        assert main(["convert", str(path), *argv]) in (1, 2)
        assert said in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.txt"]


def test_convert_to_a_bag_folder_with_a_map_file_in_a_symlink_loop_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A --map-file that is a symlink loop beside a bag folder output was a RuntimeError traceback
    ("Symlink loop from ..."), as it is one line beside a file output."""
    from rose_logs.cli import main

    path = tmp_path / "log.txt"
    path.write_text("FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n")
    monkeypatch.chdir(tmp_path)
    Path("a.yaml").symlink_to("b.yaml")
    Path("b.yaml").symlink_to("a.yaml")
    assert main(["convert", str(path), "bag", "--map-file", "a.yaml", "-q"]) == 1
    err = capsys.readouterr().err
    assert (
        err.startswith("error: a.yaml: ") and "Symlink loop" in err and len(err.splitlines()) == 1
    )
    assert not Path("bag").exists()


@pytest.mark.parametrize("value", ["+-5", "-+7", "--3", "+" + "9" * 60 + "-"])
def test_convert_max_scans_with_two_signs_is_no_integer(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str
) -> None:
    """`+-5` read as a number of over 40 digits ("too large"); `-+7` as no integer."""
    from rose_logs.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["convert", "x.log", str(tmp_path / "s.mcap"), f"--max-scans={value}"])
    assert stop.value.code == 2
    assert f"expected an integer >= 1, got {value[:40]!r}" in capsys.readouterr().err


@pytest.mark.parametrize("resolution", ["1e-300", "5e-324"])
def test_convert_at_cells_too_small_to_count_is_the_max_cells_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], resolution: str
) -> None:
    """`--resolution 1e-300` was an OverflowError traceback (a count of cells of 600 digits
    formatted as a float), 5e-324 another (infinitely many cells per side): the --max-cells
    error, which names the extent, as at 1e-6."""
    from rose_logs.cli import main

    path = tmp_path / "log.txt"
    path.write_text("FLASER 3 1.0 2.0 3.0 0.5 -0.5 0.1 0.5 -0.5 0.1 12.5 host 12.5\n")
    assert main(["convert", str(path), str(tmp_path / "s.mcap"), "--resolution", resolution]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}: the map could have over 1e+300 cells (")
    assert "more than --max-cells 100,000,000" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "s.mcap").exists()


def test_convert_says_a_warning_above_its_progress_bar(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """On a terminal, the nominal-speed clock's warning (said once the bar was drawn) was written
    where the bar's line ended (``0%|...| 0/28 [...]warning: ...``); it goes above the bar."""
    import re

    import rose_logs.cli.convert
    from rose_logs.cli import main

    monkeypatch.setattr(rose_logs.cli.convert, "stderr_is_terminal", lambda: True)
    log = repo_data(f"{CARMEN_DIR}/csail-corrected.head400.log.gz")  # stamps of six digits
    assert main(["convert", str(log), str(tmp_path / "s.mcap"), "--max-scans", "5"]) == 0
    err = capsys.readouterr().err
    assert "scan/s]" in err  # the bar was drawn
    said = [piece for piece in re.split(r"[\r\n]", err) if "warning:" in piece]
    assert len(said) == 1 and said[0].startswith(f"warning: {log}: the log's timestamps"), said
