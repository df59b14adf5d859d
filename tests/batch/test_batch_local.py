"""rose_logs.batch without Dask: discovery, the per-recording function, tables, resume, CLI gates."""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq
import pytest

from rose_logs.batch import (
    BatchError,
    RecordingOptions,
    discover,
    process_recording,
    read_list,
    result_key,
    run_batch,
)
from rose_logs.batch.task import recording_id
from rose_logs.cli import EXIT_SALVAGED, main
from rose_logs.reader import LogReader
from rose_logs.session import BreakParams

FLEET_NAMES = [
    "fleet/robot_a/later.db3",
    "fleet/robot_a/run.mcap",
    "fleet/robot_b/bag_dir",
    "fleet/robot_b/nested/small.mcap",
    "fleet/robot_b/run.mcap",
]


def read_rows(path: Path) -> list[dict]:
    return pq.read_table(path).to_pylist()


# ---- discovery ------------------------------------------------------------------------------------


def test_process_recording_names_what_it_takes(tmp_path: Path) -> None:
    """A path instead of a Recording: a TypeError that says how to make one (it was an
    AttributeError on ``.uri`` deep inside)."""
    with pytest.raises(TypeError, match=r"takes a Recording, e\.g\. rose_logs\.batch\.discover"):
        process_recording("run.mcap", out=tmp_path / "out", options=RecordingOptions())  # type: ignore[arg-type]


def test_an_empty_first_map_is_no_broken_map(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A session that starts all unknown (W = 1 by convention) is judged by its real maps."""
    from fleet import copy_recording

    log = copy_recording(tmp_path / "run.mcap", "mcap", max_maps=3, empty_first=True)
    recording = discover([log])[0]
    result = process_recording(recording, out=tmp_path / "out", options=RecordingOptions())
    first = result.snapshots[0]
    assert first["occupied"] == 0 and first["structure_score"] == 1.0
    assert not first["w_above_failure"] and not first["broken"]
    row = result.row()
    assert row["snapshots"] == 3 and not row["broke"]
    assert row["w_max"] == max(s["structure_score"] for s in result.snapshots[1:]) < 0.4
    # A recording of empty maps only has no W at all (it used to crash the gate): the gate
    # cannot vouch for it, as for a recording whose maps could not be analysed.
    only_empty = copy_recording(tmp_path / "empty.mcap", "mcap", max_maps=1, empty_first=True)
    out = str(tmp_path / "gate")
    assert main(["batch", str(log), str(only_empty), "-o", out, "-q"]) == 0
    assert main(["batch", str(log), str(only_empty), "-o", out, "-q", "--fail-above", "0.4"]) == 3
    (line,) = [x for x in capsys.readouterr().err.splitlines() if x.startswith("error:")]
    assert line.startswith(f"error: {only_empty}: /map: no map had 20 or more occupied cells")
    rows = {r["uri"]: r for r in read_rows(tmp_path / "gate" / "recordings.parquet")}
    assert rows[str(only_empty)]["w_max"] is None and not rows[str(only_empty)]["broke"]


def test_a_gate_cannot_judge_a_recording_of_maps_w_cannot_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A solid block (degenerate: W does not read it) fails the gate as in `process`: batch
    counted its 10,000 occupied cells as a judged map and passed --fail-above 0.4."""
    import numpy as np
    from fleet import map_recording

    log = map_recording(tmp_path / "solid.mcap", np.full((100, 100), 100, dtype=np.int8))
    assert main(["process", str(log), "--no-output", "-q", "--fail-above", "0.4"]) == 3
    expected = (
        f"error: {log}: /map: no map had 20 or more occupied cells in a form W reads (a solid "
        "block? a thin strip?), the gate cannot judge it (--fail-above)"
    )
    capsys.readouterr()
    assert main(["batch", str(log), "-o", str(tmp_path / "out"), "-q", "--fail-above", "0.4"]) == 3
    assert expected in capsys.readouterr().err.splitlines()


def test_a_lost_summary_keeps_the_gates_exit_code(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`batch ... --fail-above 0.4 > /dev/full` exited 1: the tables were written, the gate
    failed (3), and only the summary was lost; the gate's exit code now stands."""
    import io
    import sys

    import numpy as np
    from fleet import map_recording

    class FullDevice(io.StringIO):
        def write(self, text: str) -> int:
            raise OSError(28, "No space left on device")

    log = map_recording(tmp_path / "solid.mcap", np.full((100, 100), 100, dtype=np.int8))
    monkeypatch.setattr(sys, "stdout", FullDevice())
    assert main(["batch", str(log), "-o", str(tmp_path / "out"), "-q", "--fail-above", "0.4"]) == 3
    err = capsys.readouterr().err.splitlines()
    assert err[-2].startswith(f"error: {log}: /map: no map had 20"), err
    assert err[-1].startswith("error: standard output: cannot write"), err


def test_an_unreadable_stored_result_is_redone_and_named_under_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from fleet import copy_recording

    log = copy_recording(tmp_path / "run.mcap", "mcap", max_maps=2)
    out = tmp_path / "out"
    assert main(["batch", str(log), "-o", str(out), "-q"]) == 0
    (stored,) = (out / "results").iterdir()
    stored.write_text("{cut short")
    capsys.readouterr()
    assert main(["batch", str(log), "-o", str(out), "-q"]) == 0
    captured = capsys.readouterr()
    assert "(1 processed, 0 finished before)" in captured.out
    # The file as the user finds it, not results/<key>.json relative to OUT.
    assert f"warning: {stored}: unreadable stored result, redoing the recording" in captured.err
    assert json.loads(stored.read_text())["status"] == "ok"


def test_folders_are_searched_recursively_and_a_bag_folder_is_one_recording(fleet: Path) -> None:
    recordings = discover([fleet])
    assert [r.name for r in recordings] == FLEET_NAMES
    assert [r.uri for r in recordings] == sorted(r.uri for r in recordings)
    by_name = {r.name: r for r in recordings}
    assert by_name["fleet/robot_b/bag_dir"].is_dir
    assert not by_name["fleet/robot_a/run.mcap"].is_dir
    assert by_name["fleet/robot_b/bag_dir"].size == sum(
        f.stat().st_size for f in (fleet / "robot_b" / "bag_dir").iterdir()
    )


def test_a_folder_without_recordings_among_other_inputs_is_warned_about(
    fleet: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A folder holding no recording passed without a word when other inputs held some (alone it
    stops the batch, as a pattern that matches nothing does): a mistyped robot's folder went
    unnoticed."""
    empty = tmp_path / "robot_z"
    empty.mkdir()
    with caplog.at_level("WARNING", logger="rose_logs"):
        recordings = discover([fleet / "robot_a", empty])
    assert [r.name for r in recordings] == ["robot_a/later.db3", "robot_a/run.mcap"]
    assert [r.getMessage() for r in caplog.records] == [f"{empty}: no recording found in it"]


def test_a_name_starting_with_a_tilde_of_no_user_is_taken_as_written(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`~old/run.mcap` (a folder named so here, or a list's line) and `-o ~old/out` were a
    RuntimeError traceback ("Could not determine home directory"): as in a shell, a `~user` of no
    user stays as written."""
    import shutil

    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "~rose-bag-no-such-user"
    folder.mkdir()
    shutil.copy(fleet / "robot_b" / "nested" / "small.mcap", folder / "run.mcap")
    listing = tmp_path / "inputs.txt"
    listing.write_text("~rose-bag-no-such-user/run.mcap\n")
    out = "~rose-bag-no-such-user/out"
    assert main(["batch", "~rose-bag-no-such-user/run.mcap", "-o", out, "-q"]) == 0
    assert main(["batch", "--from-list", str(listing), "-o", out, "-q", "--force"]) == 0
    (row,) = read_rows(folder / "out" / "recordings.parquet")
    assert row["uri"] == str(folder / "run.mcap") and row["status"] == "ok"


def test_a_dangling_link_in_a_folder_is_an_error_row_not_a_stopped_batch(
    fleet: Path, tmp_path: Path
) -> None:
    """One moved file on a fleet's share (a link left behind) stopped the whole batch with
    'cannot list' before any recording was processed."""
    (fleet / "robot_a" / "moved.mcap").symlink_to(tmp_path / "gone.mcap")
    # ... and a bag folder one of whose files moved.
    bag = fleet / "robot_b" / "bag_dir"
    storage = next(p for p in bag.iterdir() if p.name != "metadata.yaml")
    storage.unlink()
    storage.symlink_to(tmp_path / "gone.db3")
    # ... and a link to itself (ELOOP, not FileNotFoundError: that one stopped the batch still).
    (fleet / "robot_a" / "loop.mcap").symlink_to("loop.mcap")
    result = run_batch([fleet], tmp_path / "out")
    rows = {row.name: row for row in result.results}
    assert rows["fleet/robot_a/loop.mcap"].error.endswith(
        "loop.mcap: cannot read (Too many levels of symbolic links)"
    )
    assert rows["fleet/robot_a/moved.mcap"].status == "error"
    assert rows["fleet/robot_a/moved.mcap"].error.endswith("moved.mcap: no such file or directory")
    assert rows["fleet/robot_b/bag_dir"].error.endswith(
        f"{storage.name}: no such file or directory"
    )
    assert rows["fleet/robot_a/run.mcap"].status == "ok"


def test_an_error_row_names_a_recording_with_odd_spaces_once(tmp_path: Path) -> None:
    """A name with a newline or two spaces in a row was named twice in its error row, the
    first time with its newline (a row of two lines): the message's spaces were collapsed
    before it was compared with the name."""
    fleet = tmp_path / "fleet"
    fleet.mkdir()
    for name in ("new\nline.bag", "two  spaces.bag"):
        (fleet / name).write_bytes(b"garbage")
    result = run_batch([fleet], tmp_path / "out")
    errors = sorted(row.error for row in result.results)
    assert all("\n" not in error for error in errors)
    assert errors == [
        f"{fleet}/new line.bag: not a ROS 1 bag, ROS 2 bag or MCAP file (unrecognised header)",
        f"{fleet}/two spaces.bag: not a ROS 1 bag, ROS 2 bag or MCAP file (unrecognised header)",
    ]


def test_one_input_as_a_string_or_path_is_one_input(fleet: Path, tmp_path: Path) -> None:
    """discover('x.mcap') took each character for an input, discover(Path) was a TypeError (as
    run_batch, they are one input); options as a dict was an AttributeError deep inside."""
    run = fleet / "robot_a" / "run.mcap"
    assert [r.uri for r in discover(str(run))] == [r.uri for r in discover(run)] == [str(run)]
    for wrong in ({"rrd": True}, {}):  # an empty one too (it passed for the defaults)
        with pytest.raises(BatchError, match="options must be a RecordingOptions, got dict"):
            run_batch([run], tmp_path / "out", options=wrong)  # type: ignore[arg-type]
    assert not (tmp_path / "out").exists()


def test_globs_files_lists_and_duplicates(fleet: Path, tmp_path: Path) -> None:
    recordings = discover([str(fleet / "robot_*" / "run.mcap"), fleet / "robot_a" / "run.mcap"])
    assert [r.name for r in recordings] == ["robot_a/run.mcap", "robot_b/run.mcap"]
    listing = tmp_path / "inputs.txt"
    listing.write_text(f"# two robots\n{fleet / 'robot_a'}\n\n{fleet / 'robot_b' / 'run.mcap'}\n")
    inputs = read_list(str(listing))
    assert [r.name for r in discover(inputs)] == [
        "robot_a/later.db3",
        "robot_a/run.mcap",
        "run.mcap",
    ]


@pytest.mark.parametrize("bad", ["missing.mcap", "robot_*/*.bag"])
def test_an_input_that_names_nothing_is_an_error(fleet: Path, bad: str) -> None:
    with pytest.raises(BatchError, match=r"no such file|matches no"):
        discover([str(fleet / bad)])


def test_every_input_that_names_nothing_is_named(fleet: Path) -> None:
    """Only the first was: a fleet list with three typos took three runs to mend."""
    inputs = [str(fleet / "a.mcap"), str(fleet), str(fleet / "b.mcap"), str(fleet / "c*.bag")]
    with pytest.raises(BatchError) as info:
        discover(inputs)
    message = str(info.value)
    assert message.startswith(f"{fleet / 'a.mcap'}: no such file")
    assert "(and 2 more: " in message and "b.mcap: no such file" in message
    assert "c*.bag" in message and "\n" not in message


# ---- one recording, no Dask -------------------------------------------------------------------------


def test_process_recording_ok_and_truncated(fleet: Path, tmp_path: Path) -> None:
    truncated = fleet / "robot_a" / "cut.mcap"
    data = (fleet / "robot_a" / "run.mcap").read_bytes()
    truncated.write_bytes(data[: len(data) // 2])
    out = str(tmp_path / "out")
    options = RecordingOptions()
    good, bad = (
        next(r for r in discover([fleet]) if r.name.endswith(name))
        for name in ("robot_a/run.mcap", "cut.mcap")
    )
    ok = process_recording(good, out=out, options=options)
    assert ok.status == "ok"
    assert ok.format == "mcap"
    assert len(ok.snapshots) == 4
    assert ok.worker.endswith(f":{os.getpid()}")
    error = process_recording(bad, out=out, options=options)
    assert error.status == "error"
    assert error.error.startswith(f"{truncated}: ")
    assert error.format == "mcap"  # recognised, then unreadable: the row still says what it is
    assert "\n" not in error.error
    assert truncated.read_bytes() == data[: len(data) // 2]  # input untouched
    stored = json.loads((tmp_path / "out" / "results" / f"{error.key}.json").read_text())
    assert stored["status"] == "error"


# ---- a whole batch in-process ------------------------------------------------------------------------


def test_batch_tables_report_and_breaks(fleet: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    report = run_batch([fleet], out)
    assert report.processed == 5
    assert report.skipped == 0
    recordings = read_rows(out / "recordings.parquet")
    assert [r["name"] for r in recordings] == FLEET_NAMES
    assert [r["format"] for r in recordings] == ["db3", "mcap", "mcap-dir", "mcap", "mcap"]
    assert [r["snapshots"] for r in recordings] == [3, 4, 2, 1, 5]
    broken = [r for r in recordings if r["broke"]]
    assert [r["name"] for r in broken] == ["fleet/robot_b/run.mcap"]
    assert broken[0]["first_break_index"] == 3  # the maps were scrambled from index 3 on
    assert broken[0]["w_max"] > 0.4
    snapshots = read_rows(out / "snapshots.parquet")
    assert len(snapshots) == 15
    keys = [(s["uri"], s["topic"], s["index"]) for s in snapshots]
    assert keys == sorted(keys)
    assert [s["broken"] for s in snapshots if s["uri"].endswith("robot_b/run.mcap")] == [
        False,
        False,
        False,
        True,
        True,
    ]
    # Every snapshot the detector scores at or above its threshold is marked, not only the first
    # of a run; a break starts where the previous snapshot of the topic was not marked.
    threshold = BreakParams().threshold_m
    for previous, row in zip([None, *snapshots], snapshots, strict=False):
        assert row["break_detected"] == (row["break_score_m"] >= threshold)
        same_run = previous is not None and previous["uri"] == row["uri"]
        starts = row["break_detected"] and not (same_run and previous["break_detected"])
        assert row["break_start"] == starts
    # The JSON report's fields are all there.
    assert {s["clean_method"] for s in snapshots} == {"walls"}
    assert all(s["kept"] + s["removed"] == s["occupied"] for s in snapshots)
    assert all(s["completed"] >= 0 for s in snapshots)  # unknown cells made walls, counted
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["recordings"], summary["ok"], summary["errors"], summary["broken"]) == (
        5,
        5,
        0,
        1,
    )
    # Every option stated, defaults too (the break threshold used was missing at its default).
    assert {"clean_method": "walls", "break_threshold_m": 1.25, "salvage": False}.items() <= (
        summary["options"].items()
    )
    assert summary["options"]["max_cells"] == RecordingOptions().max_cells
    text = (out / "report.md").read_text()
    assert "fleet/robot_b/run.mcap" in text
    assert "w_over_time.png" in text
    assert (out / "w_over_time.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (out / ".staging").exists()


def test_rerun_skips_finished_recordings_and_outputs_are_identical(
    fleet: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    run_batch([fleet], out)
    tables = {n: (out / n).read_bytes() for n in ("snapshots.parquet", "summary.json", "report.md")}
    again = run_batch([fleet], out)
    assert (again.processed, again.skipped) == (0, 5)
    assert {n: (out / n).read_bytes() for n in tables} == tables
    # A changed recording (new mtime) is processed again, the others are not.
    changed = fleet / "robot_a" / "run.mcap"
    os.utime(changed, ns=(changed.stat().st_atime_ns, changed.stat().st_mtime_ns + 10**9))
    assert run_batch([fleet], out).processed == 1
    # Other options -> other keys -> everything again; --force redoes everything.
    assert run_batch([fleet], out, options=RecordingOptions(failure_level=0.3)).processed == 5
    assert run_batch([fleet], out, force=True).processed == 5


def test_retry_errors_redoes_only_the_failures(fleet: Path, tmp_path: Path) -> None:
    bad = fleet / "robot_a" / "broken.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 40)
    out = tmp_path / "out"
    first = run_batch([fleet], out)
    assert [r.status for r in first.results].count("error") == 1
    assert run_batch([fleet], out).processed == 0
    retried = run_batch([fleet], out, retry_errors=True)
    assert retried.processed == 1
    assert retried.errors[0].uri == str(bad)


def test_keys_depend_on_uri_size_version_and_options(fleet: Path) -> None:
    a, b = discover([fleet])[:2]
    options = RecordingOptions()
    assert result_key(a, options) != result_key(b, options)
    assert result_key(a, options) != result_key(a, RecordingOptions(walls=True))
    assert result_key(a, options) == result_key(a, RecordingOptions(retries=5))
    # The seed changes nothing (the README says so): a fleet is not redone for it.
    import rose

    seeded = RecordingOptions(params=rose.RoseParams(seed=7))
    assert result_key(a, options) == result_key(a, seeded)
    assert result_key(a, options) != result_key(
        a, RecordingOptions(params=rose.RoseParams(peak_prominence=0.4))
    )
    # One key per value of an option: the default written out, 2 and 2.0 are no new options.
    keyed = {t: result_key(a, RecordingOptions(break_threshold_m=t)) for t in (None, 1.25, 2, 2.0)}
    assert keyed[None] == keyed[1.25] and keyed[2] == keyed[2.0] != keyed[None]
    assert recording_id("/robots/a/run.mcap") != recording_id("/robots/b/run.mcap")


def test_a_rerun_with_other_settings_says_why_it_redoes_recordings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A batch run again with another option processed the whole fleet again without a word: it
    says which options (or the file, or the rose-bag version) changed, compared with the nearest
    earlier run of each recording."""
    from fleet import copy_recording

    a = copy_recording(tmp_path / "in" / "a.mcap", "mcap", max_maps=2)
    copy_recording(tmp_path / "in" / "b.mcap", "mcap", max_maps=2)
    out = tmp_path / "out"
    assert run_batch([a.parent], out).redone == ()  # nothing stored: nothing redone
    paper = RecordingOptions(clean_method="paper")
    assert run_batch([a.parent], out, options=paper).redone == (
        ("options changed: clean_method", 2),
    )
    assert run_batch([a.parent], out, options=paper).redone == ()  # finished: reused
    # Two earlier runs per recording: the nearest (paper) tells what changed since.
    import rose

    both = RecordingOptions(
        clean_method="paper", walls=True, params=rose.RoseParams(occupied_threshold=60)
    )
    assert run_batch([a.parent], out, options=both).redone == (
        ("options changed: params.occupied_threshold, walls", 2),
    )
    os.utime(a, ns=(1, 1))  # another version of the file
    assert main(["batch", str(a.parent), "-o", str(out), "-q"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "redone       1 (the file changed)" in lines
    assert "recordings   2 (1 processed, 1 finished before)" in lines


def test_of_earlier_runs_as_near_the_one_of_this_very_file_says_why(tmp_path: Path) -> None:
    """Run 1 on the old file, run 2 (--salvage) on the new one, run 3 as run 1: each earlier
    result differs in one thing. The order the results were listed in chose between them, and
    six like recordings were "redone 4 (options changed: salvage)", "redone 2 (the file
    changed)"."""
    from fleet import copy_recording

    logs = [copy_recording(tmp_path / "in" / f"{n}.mcap", "mcap", max_maps=1) for n in "abcdef"]
    out = tmp_path / "out"
    run_batch([tmp_path / "in"], out)
    for log in logs:
        os.utime(log, ns=(1, 1))  # another version of each file
    salvage = RecordingOptions(salvage=True)
    assert run_batch([tmp_path / "in"], out, options=salvage).redone == (
        ("the file changed; options changed: salvage", 6),
    )
    assert run_batch([tmp_path / "in"], out).redone == (("options changed: salvage", 6),)


def test_results_stored_without_their_settings_are_redone_with_a_reason(tmp_path: Path) -> None:
    """Results of rose-bag versions that did not store their settings: redone (another layout),
    and said to be of an older rose-bag or other options."""
    from fleet import copy_recording

    log = copy_recording(tmp_path / "in" / "a.mcap", "mcap", max_maps=2)
    out = tmp_path / "out"
    (stored,) = run_batch([log], out).results
    old = stored.to_json()
    del old["settings"]
    old["key"] = "0" * 32  # an older layout's key
    (out / "results" / f"{old['key']}.json").write_text(json.dumps(old, sort_keys=True))
    assert run_batch([log], out, options=RecordingOptions(walls=True)).redone == (
        ("options changed: walls", 1),  # the nearest stored result says its settings
    )
    for path in (out / "results").glob("*.json"):
        if path.stem != old["key"]:
            path.unlink()
    assert run_batch([log], out).redone == (
        ("processed before by an older rose-bag or with other options", 1),
    )


def test_cleaned_and_rrd_outputs_mirror_the_input_names(fleet: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    inputs = [fleet / "robot_a" / "run.mcap", fleet / "robot_b" / "bag_dir"]
    report = run_batch(inputs, out, options=RecordingOptions(cleaned=True, rrd=True))
    assert all(r.status == "ok" for r in report.results)
    assert (out / "cleaned" / "run.mcap").is_file()
    assert (out / "cleaned" / "bag_dir" / "metadata.yaml").is_file()
    assert (out / "rrd" / "run.mcap.rrd").stat().st_size > 0
    assert (out / "rrd" / "bag_dir.rrd").stat().st_size > 0
    rows = read_rows(out / "recordings.parquet")
    assert [r["cleaned"] for r in rows] == [  # rows sorted by URI: robot_a/... first
        str(out / "cleaned" / "run.mcap"),
        str(out / "cleaned" / "bag_dir"),
    ]


def test_a_recording_keeps_its_stored_name_when_a_later_run_lists_another_first(
    tmp_path: Path,
) -> None:
    """Day 1: a/fleet/run.mcap is fleet/run.mcap. Day 2, b/fleet/run.mcap listed first took that
    name: two rows shared one cleaned log, and b's overwrote a's (exit 0); later a was redone
    under a new name, its old log left with no row. a keeps its name and its result; b gets the
    -<hash> name; every row has its own cleaned log."""
    from fleet import copy_recording

    a = copy_recording(tmp_path / "a" / "fleet" / "run.mcap", "mcap", max_maps=2)
    b = copy_recording(tmp_path / "b" / "fleet" / "run.mcap", "mcap", max_maps=3)
    out = tmp_path / "out"
    run_batch([a.parent], out, options=RecordingOptions(cleaned=True))
    report = run_batch([b.parent, a.parent], out, options=RecordingOptions(cleaned=True))
    rows = read_rows(out / "recordings.parquet")
    assert len({r["name"] for r in rows}) == len({r["cleaned"] for r in rows}) == 2
    assert report.processed == 1  # b; a's result is reused under its name
    assert {r["uri"]: r["name"] for r in rows}[str(a)] == "fleet/run.mcap"
    for row in rows:
        with LogReader(Path(row["cleaned"])) as reader:
            maps = sum(c.message_count for c in reader.channels if c.topic == "/map")
        assert maps == row["snapshots"]


def test_separate_runs_into_one_output_never_share_a_name(tmp_path: Path) -> None:
    """Two daily folders laid out alike, each batched on its own into one output folder: day 2's
    fleet/run.mcap took the name of day 1's, wrote its cleaned log over day 1's, and day 1's row
    (reused by a third run) named day 2's log. Day 2 gets the -<hash> name; each row names its own
    log, unchanged by the later runs; the inputs' order does not rename a stored recording."""
    from fleet import copy_recording

    day1 = copy_recording(tmp_path / "day1" / "fleet" / "run.mcap", "mcap", max_maps=2)
    day2 = copy_recording(tmp_path / "day2" / "fleet" / "run.mcap", "mcap", max_maps=3)
    out, options = tmp_path / "out", RecordingOptions(cleaned=True)
    run_batch([day1.parent], out, options=options)
    (first,) = read_rows(out / "recordings.parquet")
    kept = Path(first["cleaned"]).read_bytes()
    run_batch([day2.parent], out, options=options)
    (second,) = read_rows(out / "recordings.parquet")
    assert second["name"] != first["name"] and second["cleaned"] != first["cleaned"]
    assert Path(first["cleaned"]).read_bytes() == kept
    for inputs in ([day1.parent], [day2.parent, day1.parent]):
        assert run_batch(inputs, out, options=options).processed == 0
    rows = {r["uri"]: r for r in read_rows(out / "recordings.parquet")}
    assert rows[first["uri"]]["cleaned"] == first["cleaned"]
    assert rows[second["uri"]]["cleaned"] == second["cleaned"]
    assert Path(first["cleaned"]).read_bytes() == kept


def test_a_recording_keeps_its_stored_name_when_a_smaller_run_names_it_otherwise(
    tmp_path: Path,
) -> None:
    """Run 1 over a and b (b gets the -<hash> name), run 2 over b alone (b would be plain): b was
    redone and its cleaned log overwrote a's, which run 3 then reused as a's. b keeps its name."""
    from fleet import copy_recording

    a = copy_recording(tmp_path / "a" / "fleet" / "run.mcap", "mcap", max_maps=2)
    b = copy_recording(tmp_path / "b" / "fleet" / "run.mcap", "mcap", max_maps=3)
    out, options = tmp_path / "out", RecordingOptions(cleaned=True)
    run_batch([a.parent, b.parent], out, options=options)
    first = {r["uri"]: (r["name"], r["cleaned"]) for r in read_rows(out / "recordings.parquet")}
    assert run_batch([b.parent], out, options=options).processed == 0
    assert run_batch([a.parent, b.parent], out, options=options).processed == 0
    rows = read_rows(out / "recordings.parquet")
    assert {r["uri"]: (r["name"], r["cleaned"]) for r in rows} == first
    for row in rows:
        with LogReader(Path(row["cleaned"])) as reader:
            maps = sum(c.message_count for c in reader.channels if c.topic == "/map")
        assert maps == row["snapshots"]
    # Another input root, no outputs named after the recording: its stored result is reused.
    assert run_batch([tmp_path / "b"], tmp_path / "plain").processed == 1
    assert run_batch([b.parent], tmp_path / "plain").processed == 0


def test_an_output_folder_in_or_at_a_ros2_bag_folder_is_refused(
    fleet: Path, tmp_path: Path
) -> None:
    """-o inside a bag folder that is an input wrote the tables into the recording, and changed its
    resume key: every run processed it again. -o at a bag folder wrote into that recording."""
    bag = fleet / "robot_b" / "bag_dir"
    before = sorted(p.name for p in bag.iterdir())
    with pytest.raises(BatchError, match=r"inside the recording .*bag_dir"):
        run_batch([bag], bag / "out")
    with pytest.raises(BatchError, match="is a ROS 2 bag folder"):
        run_batch([fleet / "robot_a" / "run.mcap"], bag)
    # Inside a bag folder that is no input (it wrote bag/out, and bag/new/out made bag/new).
    for out in (bag / "out", bag / "new" / "out"):
        with pytest.raises(BatchError) as caught:
            run_batch([fleet / "robot_a" / "run.mcap"], out)
        assert str(caught.value) == (
            f"{out}: the output folder is inside the ROS 2 bag folder {bag.resolve()} (it has "
            "metadata.yaml): it would write into a recording; choose another -o"
        )
    assert sorted(p.name for p in bag.iterdir()) == before


def test_process_outputs_beside_their_recordings_are_not_read_twice(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """`rose-bag process run.mcap` writes run.rose.mcap beside it: a batch over the folder counted
    it as a second recording (with --cleaned, an error row: it has /map/rose/cleaned already)."""
    import logging

    from fleet import copy_recording

    from rose_logs.session import process_log

    log = copy_recording(tmp_path / "fleet" / "run.mcap", "mcap", max_maps=2)
    process_log(log, output_path=tmp_path / "fleet" / "run.rose.mcap")
    with caplog.at_level(logging.WARNING):
        found = discover([tmp_path / "fleet"])
    assert [r.name for r in found] == ["fleet/run.mcap"]
    assert "1 recording(s) named as `rose-bag process` names its output" in caplog.text
    # Named on its own, it is an input like any other.
    assert [r.name for r in discover([tmp_path / "fleet" / "run.rose.mcap"])] == ["run.rose.mcap"]
    # Only a recording beside it makes it an output: a text file called "notes" does not.
    copy_recording(tmp_path / "other" / "notes.rose", "db3", max_maps=1)
    (tmp_path / "other" / "notes").write_text("not a recording")
    assert [r.name for r in discover([tmp_path / "other"])] == ["other/notes.rose"]
    # process --format db3 names its output of run.mcap by the format: the bag folder run.rose.
    process_log(log, output_path=tmp_path / "fleet" / "run.rose", output_format="db3")
    assert [r.name for r in discover([tmp_path / "fleet"])] == ["fleet/run.mcap"]
    # A pattern is a search as a folder is: 'fleet/*' and 'fleet/*.mcap' counted them twice.
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        for pattern in ("*", "*.mcap"):
            assert [r.name for r in discover([f"{tmp_path}/fleet/{pattern}"])] == ["run.mcap"]
    assert caplog.text.count("named as `rose-bag process` names its output") == 2
    assert [r.name for r in discover([f"{tmp_path}/fleet/*.rose*"])] == [
        "run.rose",
        "run.rose.mcap",
    ]


# ---- CLI: exit codes ------------------------------------------------------------------------------


def test_cli_gates_errors_win_over_fail_above(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = str(tmp_path / "out")
    assert main(["batch", str(fleet), "-o", out, "-q"]) == 0
    assert main(["batch", str(fleet), "-o", out, "-q", "--fail-above", "0.4"]) == 3
    err = capsys.readouterr().err
    assert "robot_b/run.mcap" in err and "(the highest; 1 recording(s) above it)" in err
    # The summary a pipeline reads says why, as the error line (it said nothing of the gates).
    gates = json.loads((tmp_path / "out" / "summary.json").read_text())["gates"]
    assert gates["fail_above"] == 0.4 and gates["fail_on_break"] is False
    (reason,) = gates["failed"]
    assert f"error: {reason}" in err.splitlines()
    assert main(["batch", str(fleet), "-o", out, "-q"]) == 0
    gates = json.loads((tmp_path / "out" / "summary.json").read_text())["gates"]
    assert gates == {"fail_above": None, "fail_on_break": False, "failed": []}
    assert main(["batch", str(fleet), "-o", out, "-q", "--fail-above", "0.0001"]) == 3
    assert f"(the highest; {len(FLEET_NAMES)} recording(s) above it)" in capsys.readouterr().err
    (fleet / "robot_a" / "zero.mcap").write_bytes(b"")
    assert main(["batch", str(fleet), "-o", out, "-q", "--fail-above", "0.4"]) == 1
    assert main(["batch", str(fleet), "-o", out, "-q", "--max-errors", "1"]) == 0
    code = main(["batch", str(fleet), "-o", out, "-q", "--max-errors", "1", "--fail-above", "0.4"])
    assert code == 3
    err = capsys.readouterr().err
    assert "zero.mcap" in err
    assert main(["batch", str(tmp_path / "nothing"), "-o", out]) == 1
    assert "no such file" in capsys.readouterr().err


def test_cli_in_process_holds_opencv_to_one_thread(fleet: Path, tmp_path: Path) -> None:
    # As `process` and the Dask workers: the session keeps both cores busy, and OpenCV's pool
    # (with the walls cleaning's second thread) only added CPU there (numbers in the helper).
    import cv2

    threads = cv2.getNumThreads()
    cv2.setNumThreads(2)
    try:
        only = fleet / "robot_b" / "nested" / "small.mcap"
        assert main(["batch", str(only), "-o", str(tmp_path / "out"), "-q"]) == 0
        assert cv2.getNumThreads() == 1
    finally:
        cv2.setNumThreads(threads)


def test_cli_names_each_failed_recording_on_its_own_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Not only the first: up to ten lines, then how many more (the rest is in the tables)."""
    inputs = tmp_path / "in"
    inputs.mkdir()
    for n in range(12):
        (inputs / f"broken_{n:02d}.mcap").write_bytes(b"")
    assert main(["batch", str(inputs), "-o", str(tmp_path / "out"), "-q"]) == 1
    err = capsys.readouterr().err.splitlines()
    failed = [line for line in err if line.startswith("failed: ")]
    assert [line.split(": ")[1] for line in failed[:10]] == [
        str(inputs / f"broken_{n:02d}.mcap") for n in range(10)
    ]
    assert failed[10] == "failed: ... and 2 more (recordings.parquet, report.md)"
    assert err[-1] == "error: 12 recording(s) failed (more than --max-errors 0)"
    # Tolerated by --max-errors, they are named all the same (only the count was shown).
    assert (
        main(["batch", str(inputs), "-o", str(tmp_path / "out"), "-q", "--max-errors", "20"]) == 0
    )
    err = capsys.readouterr().err.splitlines()
    assert [line for line in err if line.startswith("failed: ")] == failed
    assert not any(line.startswith("error: ") for line in err)


def test_ctrl_c_keeps_finished_recordings_and_exits_130(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import rose_logs.batch.engine as engine

    real = engine.process_recording
    calls = []

    def interrupted_on_third(*args: object, **kwargs: object) -> object:
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(engine, "process_recording", interrupted_on_third)
    out = tmp_path / "out"
    assert main(["batch", str(fleet), "-o", str(out), "-q"]) == 130
    assert len(read_rows(out / "recordings.parquet")) == 2
    # The summary says how far it got, not only what finished (read like the fleet's size).
    assert "recordings   2 of 5 found (2 processed" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    # And so does summary.json: 2 finished of the 5 the inputs named.
    assert summary["interrupted"] is True
    assert (summary["recordings"], summary["recordings_found"]) == (2, 5)
    monkeypatch.setattr(engine, "process_recording", real)
    resumed = run_batch([fleet], out)
    assert (resumed.processed, resumed.skipped) == (3, 2)
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["recordings"], summary["recordings_found"]) == (5, 5)


def test_two_robots_run_mcap_get_separate_rrd_files_and_recording_ids(
    fleet: Path, tmp_path: Path
) -> None:
    inputs = [fleet / "robot_a" / "run.mcap", fleet / "robot_b" / "run.mcap"]
    report = run_batch(inputs, tmp_path / "out", options=RecordingOptions(rrd=True))
    paths = [Path(r.rrd_uri) for r in report.results]
    assert len(set(paths)) == 2
    ids = [recording_id(r.uri).encode() for r in report.results]
    assert ids[0] != ids[1]
    for path, own, other in ((paths[0], ids[0], ids[1]), (paths[1], ids[1], ids[0])):
        data = path.read_bytes()
        assert own in data
        assert other not in data


def test_os_errors_are_retried_then_reported(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import rose_logs.session

    real = rose_logs.session.process_log
    failures = {"left": 1}

    def flaky(*args: object, **kwargs: object) -> object:
        if failures["left"]:
            failures["left"] -= 1
            raise ConnectionResetError(104, "connection reset by peer")
        return real(*args, **kwargs)

    monkeypatch.setattr(rose_logs.session, "process_log", flaky)
    recording = discover([fleet / "robot_a" / "run.mcap"])[0]
    out = str(tmp_path / "out")
    ok = process_recording(recording, out=out, options=RecordingOptions(retries=1))
    assert ok.status == "ok"
    failures["left"] = 3
    failed = process_recording(recording, out=out, options=RecordingOptions(retries=1))
    assert failed.status == "error"
    assert "connection reset" in failed.error
    assert failures["left"] == 1  # tried twice: once plus one retry


def test_an_output_folder_inside_the_inputs_is_not_read_back(fleet: Path) -> None:
    out = fleet / "health"
    first = run_batch([fleet], out, options=RecordingOptions(cleaned=True))
    assert (out / "cleaned" / "fleet" / "robot_a" / "run.mcap").is_file()
    again = run_batch([fleet], out, options=RecordingOptions(cleaned=True))
    assert [r.uri for r in again.results] == [r.uri for r in first.results]
    assert (again.processed, again.skipped) == (0, 5)


def test_a_users_recording_inside_the_output_folder_is_left_out_with_a_warning(
    fleet: Path, caplog: pytest.LogCaptureFixture
) -> None:
    out = fleet / "robot_b"  # holds three of the fleet's recordings
    with caplog.at_level("WARNING", logger="rose_logs"):
        report = run_batch([fleet], out, options=RecordingOptions(cleaned=True))
    assert [r.name for r in report.results] == ["fleet/robot_a/later.db3", "fleet/robot_a/run.mcap"]
    said = [r.getMessage() for r in caplog.records if "inside the output folder" in r.getMessage()]
    assert said == [
        f"{out}: 3 recording(s) inside the output folder are not processed (the batch writes "
        f"there; choose another -o to include them), first: {out / 'bag_dir'}"
    ]
    # Its own cleaned logs there are no recordings of the user's: not warned about again.
    caplog.clear()
    with caplog.at_level("WARNING", logger="rose_logs"):
        run_batch([fleet / "robot_a", out / "cleaned"], out, options=RecordingOptions(cleaned=True))
    assert not [r for r in caplog.records if "inside the output folder" in r.getMessage()]


def test_a_rerun_remakes_outputs_deleted_since(fleet: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    options = RecordingOptions(cleaned=True, rrd=True)
    run_batch([fleet / "robot_a"], out, options=options)
    cleaned = out / "cleaned" / "robot_a" / "run.mcap"
    rrd = out / "rrd" / "robot_a" / "later.db3.rrd"
    assert cleaned.is_file() and rrd.is_file()
    cleaned.unlink()
    rrd.unlink()
    again = run_batch([fleet / "robot_a"], out, options=options)
    assert (again.processed, again.skipped) == (2, 0)
    assert cleaned.is_file() and rrd.is_file()
    assert run_batch([fleet / "robot_a"], out, options=options).processed == 0


def test_usage_errors_show_the_batch_usage(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main(["batch", "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: rose-bag batch ")


def test_a_recording_rosbag_never_closed_is_found_and_reported(fleet: Path, tmp_path: Path) -> None:
    """A killed ``rosbag record`` leaves ``x.bag.active`` (no index): an error row that says what to
    do, never a recording the fleet's table silently lacks."""
    fields = b"".join(
        len(f).to_bytes(4, "little") + f for f in (b"op=\x03", b"index_pos=" + bytes(8))
    )
    record = len(fields).to_bytes(4, "little") + fields + (16).to_bytes(4, "little") + b" " * 16
    crashed = fleet / "robot_a" / "crashed.bag.active"
    crashed.write_bytes(b"#ROSBAG V2.0\n" + record)
    assert "fleet/robot_a/crashed.bag.active" in [r.name for r in discover([fleet])]
    report = run_batch([crashed], tmp_path / "out")
    (row,) = report.results
    assert row.status == "error"
    assert "index cannot be read" in row.error and "--salvage" in row.error


def test_salvage_keeps_the_readable_part_of_a_damaged_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from fleet import SAMPLE

    cut = tmp_path / "in" / "cut.mcap"
    cut.parent.mkdir()
    data = SAMPLE.read_bytes()
    cut.write_bytes(data[: len(data) * 6 // 10])  # a recording cut off: no index at its end
    assert main(["batch", str(cut), "-o", str(tmp_path / "plain"), "-q"]) == 1
    (row,) = read_rows(tmp_path / "plain" / "recordings.parquet")
    assert row["status"] == "error" and "--salvage" in row["error"] and row["losses"] == []
    capsys.readouterr()
    out = tmp_path / "salvaged"
    assert main(["batch", str(cut), "-o", str(out), "-q", "--salvage"]) == EXIT_SALVAGED
    printed = capsys.readouterr()
    assert "salvaged     1" in printed.out and "kept what could be read" in printed.err
    (row,) = read_rows(out / "recordings.parquet")
    assert row["status"] == "ok" and row["snapshots"] > 0
    assert len(row["losses"]) == 1 and str(cut) in row["losses"][0]
    assert json.loads((out / "summary.json").read_text())["salvaged"] == 1
    # The report says so too (it showed a plain "ok" row), and says the loss once.
    text = (out / "report.md").read_text()
    assert "1 recording: 1 ok, 0 failed" in text
    assert "1 damaged (what could be read kept, --salvage)" in text
    section = text.split("## Recordings with losses or warnings")[1].split("##")[0]
    assert "| cut.mcap | " in section
    assert section.count(row["losses"][0]) == 1


def test_salvage_leaves_the_keys_of_results_stored_without_it_alone() -> None:
    assert "salvage" not in RecordingOptions().key_fields()
    assert RecordingOptions(salvage=True).key_fields()["salvage"] is True


def test_one_set_of_topics_written_in_any_order_is_one_key() -> None:
    """-t /map -t /local_map, the other way round and /map twice each redid the recording."""
    keys = {
        json.dumps(RecordingOptions(topics=topics).key_fields(), sort_keys=True)
        for topics in (
            ("/map", "/local_map"),
            ("/local_map", "/map"),
            ("/map", "/local_map", "/map"),
        )
    }
    assert len(keys) == 1
    assert keys != {json.dumps(RecordingOptions(topics=("/map",)).key_fields(), sort_keys=True)}


def test_one_cell_limit_written_three_ways_is_one_key() -> None:
    """2e8, 200000000 and numpy's int gave three keys: a resumed batch redid every recording."""
    import numpy as np

    keys = {
        json.dumps(RecordingOptions(max_cells=value).key_fields(), sort_keys=True)  # type: ignore[arg-type]
        for value in (200_000_000, 2e8, np.int64(200_000_000))
    }
    assert len(keys) == 1
    assert "max_cells" not in RecordingOptions(max_cells=1e8).key_fields()  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("options", "said"),
    [
        ({"retries": 1.5}, "retries must be an integer >= 0, got 1.5"),
        ({"params": None}, "params must be a RoseParams, got NoneType"),
        ({"failure_level": 5}, "failure_level must be a number in (0, 1], got 5"),
        ({"topics": "/map"}, "topics must be a tuple of topic names or None"),
        ({"clean_method": "wall"}, "clean_method must be one of walls, paper"),
        ({"break_threshold_m": math.nan}, "break_threshold_m must be a finite number > 0 or None"),
        ({"cleaned": "yes"}, "cleaned must be True or False"),
    ],
)
def test_bad_recording_options_are_one_error_before_any_recording(
    options: dict[str, Any], said: str
) -> None:
    """retries=1.5 or params=None were raw TypeErrors out of process_recording, which "never
    raises for a bad recording"; failure_level=5 made one error row per recording."""
    with pytest.raises(BatchError, match=re.escape(said)):
        RecordingOptions(**options)


def test_numpy_options_are_the_same_options_as_pythons() -> None:
    """np.True_ made another resume key than True (every recording redone), and numpy values or
    an infinite threshold made summary.json fail after the whole batch."""
    import numpy as np

    plain = RecordingOptions(walls=True, retries=1, break_threshold_m=2.0, topics=("/map",))
    given = RecordingOptions(
        walls=np.True_,
        retries=np.int64(1),
        break_threshold_m=np.float32(2.0),
        failure_level=np.float64(0.4),
        topics=["/map"],
    )
    assert given == plain and hash(given) == hash(plain)
    assert json.dumps(given.stated(), allow_nan=False) == json.dumps(plain.stated())
    with pytest.raises(BatchError, match="break_threshold_m must be a finite number"):
        RecordingOptions(break_threshold_m=math.inf)


def test_a_local_name_holding_a_double_colon_is_a_file_not_a_url(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """fsspec reads ``a::b`` as a chain of file systems; a local file so named is still a file."""
    from fleet import SAMPLE

    odd = tmp_path / "runs" / "robot::1.mcap"
    odd.parent.mkdir()
    odd.write_bytes(SAMPLE.read_bytes())
    for given in (odd, odd.parent):
        out = tmp_path / f"out-{given.name}"
        assert main(["batch", str(given), "-o", str(out), "-q"]) == 0
        (row,) = read_rows(out / "recordings.parquet")
        assert row["status"] == "ok" and row["uri"] == str(odd)
    capsys.readouterr()
    assert main(["batch", "nosuch::thing", "-o", str(tmp_path / "x"), "-q"]) == 1
    assert "unsupported URL scheme 'nosuch'" in capsys.readouterr().err


def test_a_windows_drive_root_is_a_local_name_not_a_url_scheme(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``C:\\`` or ``C:/fleet/*`` look like a URL scheme ``c:``; fsspec takes a drive letter for a
    local path, and so do the batch's inputs and OUT (on Linux, a relative name: read where it
    exists, "no such file or folder" where it does not, never "unsupported URL scheme")."""
    from fleet import SAMPLE

    from rose_logs.batch.store import is_local

    assert all(is_local(name) for name in ("C:\\", "C:/fleet/*", "c:\\fleet", "D:"))
    monkeypatch.chdir(tmp_path)
    fleet = tmp_path / "C:" / "fleet"
    fleet.mkdir(parents=True)
    (fleet / "run.mcap").write_bytes(SAMPLE.read_bytes())
    assert main(["batch", "C:/fleet/*", "-o", "C:/out", "-q"]) == 0
    (row,) = read_rows(tmp_path / "C:" / "out" / "recordings.parquet")
    assert row["status"] == "ok" and row["uri"] == str(fleet / "run.mcap")
    capsys.readouterr()
    assert main(["batch", "E:\\", "-o", "x", "-q"]) == 1
    assert capsys.readouterr().err == "error: E:\\: no such file or folder\n"


def test_a_salvaged_active_bag_is_cleaned_into_a_complete_bag(tmp_path: Path) -> None:
    """``x.bag.active`` salvaged with ``--cleaned`` comes out as ``cleaned/.../x.bag``: a complete,
    indexed bag, named as one."""
    from rose_logs.reader import LogReader

    carmen = Path(__file__).resolve().parents[1] / "data" / "radish_carmen_corrected_logs"
    bag = tmp_path / "whole.bag"
    argv = ["convert", str(carmen / "freiburg-101-corrected.log.gz"), str(bag), "-q"]
    assert main([*argv, "--resolution", "0.1", "--map-period", "60"]) == 0  # several chunks
    data = bytearray(bag.read_bytes()[: bag.stat().st_size * 2 // 3])  # killed mid-recording
    at = data.index(b"index_pos=") + len(b"index_pos=")
    data[at : at + 8] = bytes(8)
    active = tmp_path / "robot" / "run.bag.active"
    active.parent.mkdir()
    active.write_bytes(bytes(data))
    out = tmp_path / "out"
    assert main(["batch", str(active), "-o", str(out), "-q", "--salvage", "--cleaned"]) == 4
    (row,) = read_rows(out / "recordings.parquet")
    assert row["status"] == "ok" and row["cleaned"].endswith("run.bag")
    with LogReader(Path(row["cleaned"])) as reader:
        assert "/map/rose/cleaned" in {c.topic for c in reader.channels}


def _with_nan_resolution(log: Path, bad: set[int], *, maps: int = 4) -> Path:
    """The first ``maps`` maps of the sample session, those numbered in ``bad`` (from 1) with a NaN
    resolution (malformed: skipped with a warning that names their log time)."""
    import math

    from fleet import MAP_TOPIC, SAMPLE

    from rose_logs.reader import LogReader
    from rose_logs.storage.typesys import MAP_TYPE, typestore_for
    from rose_logs.writer import open_output

    store = typestore_for("cdr")

    log.parent.mkdir(parents=True, exist_ok=True)
    with LogReader(SAMPLE) as reader, open_output(log, "mcap", serialization="cdr") as out:
        handles = {c.id: out.add_channel(c) for c in reader.channels}
        count = 0
        for message in reader.messages():
            data = message.data
            if message.channel.topic == MAP_TOPIC:
                count += 1
                if count > maps:
                    break
                if count in bad:  # the same message with info.resolution = NaN
                    msg = store.deserialize_cdr(bytes(data), MAP_TYPE)
                    msg.info.resolution = math.nan
                    data = store.serialize_cdr(msg, MAP_TYPE)
            out.write_raw(handles[message.channel.id], message.log_time_ns, data)
    return log


def test_skipped_map_messages_and_warnings_are_in_the_row_and_name_the_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recording whose second and third maps have a NaN resolution: ``process`` skips and
    reports them; the batch row says so too, and the warnings printed name the recording."""
    log = _with_nan_resolution(tmp_path / "robot" / "run.mcap", {2, 3})
    out_dir = tmp_path / "out"
    assert main(["batch", str(log), "-o", str(out_dir), "-q"]) == 0
    (row,) = read_rows(out_dir / "recordings.parquet")
    assert (row["status"], row["snapshots"], row["skipped_messages"]) == ("ok", 2, 2)
    assert row["skipped_reasons"] == "2 malformed"
    assert len(row["warnings"]) == 2 and all("resolution nan" in w for w in row["warnings"])
    said = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    assert said == [f"warning: {log}: {w}" for w in row["warnings"]]
    summary = json.loads((out_dir / "summary.json").read_text())
    assert (summary["skipped_messages"], summary["with_warnings"]) == (2, 1)
    text = (out_dir / "report.md").read_text()
    assert "; 2 map messages skipped." in text
    assert "| run.mcap | - | 2 (2 malformed) | " in text


def test_recordings_processed_side_by_side_keep_their_own_warnings(tmp_path: Path) -> None:
    """Two recordings at once in one process (threads, as on a Dask worker with several threads):
    each row holds its own recording's warnings, none of the other's; a failed recording keeps
    its warnings too; logging is as it was afterwards."""
    import logging
    import re
    from concurrent.futures import ThreadPoolExecutor

    first = _with_nan_resolution(tmp_path / "a" / "run.mcap", {2})
    second = _with_nan_resolution(tmp_path / "b" / "run.mcap", {3, 4})
    failed = _with_nan_resolution(tmp_path / "c" / "run.mcap", {1, 2}, maps=2)
    recordings = discover([first, second, failed])
    times = {}
    for rec in recordings:  # the log times of each recording's bad maps, from the logs themselves
        from rose_logs.reader import LogReader

        with LogReader(Path(rec.uri)) as reader:
            maps = [m.log_time_ns for m in reader.messages(topics=["/map"])]
        bad = {"a": {2}, "b": {3, 4}, "c": {1, 2}}[Path(rec.uri).parent.name]
        times[rec.uri] = {maps[i - 1] for i in bad}
    before = logging.getLogger("rose_logs").handlers[:], logging.getLogger("rose_logs").propagate
    options = RecordingOptions()
    with ThreadPoolExecutor(3) as pool:
        results = list(
            pool.map(
                lambda rec: process_recording(rec, out=tmp_path / "out", options=options),
                recordings,
            )
        )
    for result in results:
        said = {int(t) for w in result.warnings for t in re.findall(r"\((\d+) ns\)", w)}
        assert said == times[result.uri], result.warnings
    assert [r.status for r in results] == ["ok", "ok", "error"]
    assert (logging.getLogger("rose_logs").handlers, logging.getLogger("rose_logs").propagate) == (
        before[0],
        before[1],
    )


def test_a_warning_said_on_every_snapshot_is_kept_once_with_its_count(tmp_path: Path) -> None:
    import logging

    from rose_logs.batch.recording_log import RecordingWarnings, collecting

    said = RecordingWarnings()
    with collecting(said):
        for _ in range(14):
            logging.getLogger("rose.walls").warning("ROSE found no dominant direction")
        logging.getLogger("rose_logs.session").warning("another")
    assert said.lines() == ("ROSE found no dominant direction (14 times)", "another")


def test_process_options_and_the_break_gate_reach_every_recording(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--fail-on-break``, ``--break-threshold``, ``--clean-method`` and ``--max-cells`` work as in
    ``process``; a W level outside W's range is a usage error."""
    out = str(tmp_path / "out")
    args = ["batch", str(fleet), "-o", out, "-q"]
    assert main([*args, "--fail-on-break"]) == 3
    err = capsys.readouterr().err
    assert "robot_b/run.mcap: the map breaks at /map snapshot 3" in err
    assert "--fail-on-break" in err
    assert main([*args, "--fail-on-break", "--break-threshold", "1e6"]) == 0  # nothing that large
    paper = tmp_path / "paper"
    assert main(["batch", str(fleet), "-o", str(paper), "-q", "--clean-method", "paper"]) == 0
    assert {s["clean_method"] for s in read_rows(paper / "snapshots.parquet")} == {"paper"}
    small = tmp_path / "small"
    # Every map of the fleet is 1152 x 736: none is analysed, each recording fails saying why.
    assert main(["batch", str(fleet), "-o", str(small), "-q", "--max-cells", "800000"]) == 1
    rows = read_rows(small / "recordings.parquet")
    assert all(r["status"] == "error" and "over --max-cells" in r["error"] for r in rows)
    for bad in (["--fail-above", "2"], ["--failure-level", "1.5"]):
        with pytest.raises(SystemExit) as exit_info:
            main([*args, *bad])
        assert exit_info.value.code == 2


def test_one_input_given_as_a_string_is_one_input(tmp_path: Path) -> None:
    from fleet import copy_recording

    log = copy_recording(tmp_path / "run.mcap", "mcap", max_maps=1)
    report = run_batch(str(log), tmp_path / "out")  # type: ignore[arg-type]
    assert [r.uri for r in report.results] == [str(log)]


def test_report_md_shows_names_as_spelled_not_as_markdown(tmp_path: Path) -> None:
    """report.md escaped only ``|`` and newlines in its cells: a recording named with ``*``,
    ``_``, ``[..](..)``, ``<html>``, a backtick or a newline rendered as emphasis, a link, HTML
    or code (and a newline broke its row); each such character is now backslash-escaped, a
    newline written ``\\n``."""
    from fleet import copy_recording

    name = "a_*b*_[l](x)<i>`c`~d~&amp;|\nz.mcap"
    log = copy_recording(tmp_path / name, "mcap", max_maps=1)
    run_batch([log], tmp_path / "out")
    text = (tmp_path / "out" / "report.md").read_text(encoding="utf-8")
    (row,) = [line for line in text.splitlines() if "&amp;" in line]
    escaped = r"a\_\*b\*\_\[l\](x)\<i\>\`c\`\~d\~\&amp;\|\\nz.mcap"
    assert row.startswith(f"| {escaped} | mcap | ok | ")


def test_a_broken_recording_named_with_dollars_keeps_the_report(
    fleet: Path, tmp_path: Path
) -> None:
    """A broken recording is named in the figure's legend, where matplotlib reads text between
    two dollars as a formula: ``r$\\x$.mcap`` raised its parse error out of the batch (no
    tables, no report), ``s$1_2$`` was drawn as a formula. The label's dollars are escaped."""
    folder = tmp_path / "odd"
    folder.mkdir()
    (folder / "r$\\x$.mcap").write_bytes((fleet / "robot_b" / "run.mcap").read_bytes())
    out = tmp_path / "out"
    report = run_batch([folder], out)
    assert [r.row()["broke"] for r in report.results] == [True]
    assert (out / "w_over_time.png").is_file()
    assert "r$\\\\x$.mcap" in (out / "report.md").read_text(encoding="utf-8")


def test_a_file_name_that_is_not_utf8_is_processed_and_tabled(fleet: Path, tmp_path: Path) -> None:
    # Linux file names are bytes: Python keeps undecodable ones as surrogates, which Parquet and
    # uuid5 refuse (the whole batch failed writing its tables).
    folder = tmp_path / "odd"
    folder.mkdir()
    name = os.fsdecode(b"r\xffbot.mcap")
    (folder / name).write_bytes((fleet / "robot_a" / "run.mcap").read_bytes())
    # A broken map's recording is named in the figure's legend (matplotlib refused surrogates).
    broken = os.fsdecode(b"s\xfeb.mcap")
    (folder / broken).write_bytes((fleet / "robot_b" / "run.mcap").read_bytes())
    out = tmp_path / "out"
    report = run_batch([folder], out, options=RecordingOptions(cleaned=True))
    assert [r.status for r in report.results] == ["ok", "ok"]
    assert [r.row()["broke"] for r in report.results] == [False, True]
    assert (out / "w_over_time.png").is_file()
    rows = read_rows(out / "recordings.parquet")
    assert rows[0]["uri"] == str(folder / "r\\xffbot.mcap")
    assert rows[0]["snapshots"] > 0
    assert read_rows(out / "snapshots.parquet")[0]["uri"] == rows[0]["uri"]
    assert (out / "cleaned" / "odd" / name).is_file()  # the output keeps the real name
    # (its backslash escaped in report.md, which renders it as r\xffbot.mcap)
    assert "r\\\\xffbot.mcap" in (out / "report.md").read_text(encoding="utf-8")


def test_without_matplotlib_the_report_says_why_it_has_no_figure(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The figure was left out silently where matplotlib (the plots extra) is not installed."""
    import rose_logs.batch.report as report_module

    monkeypatch.setattr(report_module, "plotting_available", lambda: False)
    monkeypatch.setattr(report_module, "figure_png", lambda report: None)
    out = tmp_path / "out"
    assert main(["batch", str(fleet / "robot_a"), "-o", str(out), "-q"]) == 0
    assert "matplotlib is not installed" in (out / "report.md").read_text()
    assert "no w_over_time.png: matplotlib is not installed" in capsys.readouterr().err
    assert not (out / "w_over_time.png").exists()


def test_a_figure_that_cannot_be_drawn_leaves_the_tables_and_report(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A user's matplotlib settings with ``text.usetex`` and no LaTeX installed made drawing
    ``w_over_time.png`` raise (RuntimeError): the whole batch output was lost (no tables, no
    report, an earlier run's left in place). The figure is left out, a warning naming it says
    why, and report.md neither links it nor leaves an earlier run's beside it."""
    matplotlib = pytest.importorskip("matplotlib")
    out = tmp_path / "out"
    assert main(["batch", str(fleet / "robot_a"), "-o", str(out), "-q"]) == 0
    assert (out / "w_over_time.png").is_file()
    capsys.readouterr()
    monkeypatch.setitem(matplotlib.rcParams, "text.usetex", True)
    no_latex = tmp_path / "bin"  # (latex not found, also where it is installed)
    no_latex.mkdir()
    monkeypatch.setenv("PATH", str(no_latex))
    assert main(["batch", str(fleet / "robot_a"), "-o", str(out), "-q", "--force"]) == 0
    err = capsys.readouterr().err
    monkeypatch.undo()
    figure = out / "w_over_time.png"
    (line,) = [line for line in err.splitlines() if "w_over_time.png" in line]
    assert line.startswith(f"warning: {figure}: not drawn (RuntimeError: ")
    assert "latex could not be found" in line
    text = (out / "report.md").read_text(encoding="utf-8")
    assert "](w_over_time.png)" not in text
    assert "No figure: it could not be drawn (RuntimeError: " in text
    assert not figure.exists()
    rows = read_rows(out / "recordings.parquet")
    assert len(rows) == 2
    assert all(r["status"] == "ok" for r in rows)
    assert read_rows(out / "snapshots.parquet")
    assert json.loads((out / "summary.json").read_text())["recordings"] == 2


def test_the_report_figure_leaves_the_callers_matplotlib_backend_alone(tmp_path: Path) -> None:
    """run_batch called from a notebook must not switch the user's plotting backend."""
    matplotlib = pytest.importorskip("matplotlib")
    from fleet import copy_recording

    log = copy_recording(tmp_path / "run.mcap", "mcap", max_maps=2)
    chosen = matplotlib.get_backend()
    try:
        matplotlib.use("svg")
        run_batch([log], tmp_path / "out")
        assert matplotlib.get_backend() == "svg"
    finally:
        matplotlib.use(chosen)
    assert (tmp_path / "out" / "w_over_time.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_later_run_without_w_to_draw_leaves_no_figure_of_the_earlier_one(tmp_path: Path) -> None:
    """The tables, report and figure are replaced together: a run whose recordings have no W
    (every one an error row) left the earlier run's figure beside a report without one."""
    from fleet import copy_recording

    log = copy_recording(tmp_path / "run.mcap", "mcap", max_maps=2)
    out = tmp_path / "out"
    run_batch([log], out)
    assert (out / "w_over_time.png").is_file()
    run_batch([log], out, options=RecordingOptions(topics=("/nomap",)), force=True)
    assert "w_over_time.png" not in (out / "report.md").read_text(encoding="utf-8")
    assert not (out / "w_over_time.png").exists()


def test_a_gate_fails_on_a_map_topic_it_cannot_judge(tmp_path: Path, capsys) -> None:
    """As ``process``: a recording whose second map topic has only malformed maps passes no
    gate; without a gate it is an ok row."""
    from fleet import SAMPLE

    from rose_logs.reader import LogReader
    from rose_logs.writer import open_output

    log = tmp_path / "two_robots.mcap"
    with LogReader(SAMPLE) as reader, open_output(log, "mcap", serialization="cdr") as out:
        handles = {c.id: out.add_channel(c) for c in reader.channels}
        robot2 = out.add_topic("/robot2/map", "nav_msgs/msg/OccupancyGrid", latching=True)
        for message in reader.messages():
            out.write_raw(handles[message.channel.id], message.log_time_ns, message.data)
            if message.channel.topic == "/map":  # the same map, cut short: malformed
                out.write_raw(robot2, message.log_time_ns, bytes(message.data)[:-50])
    assert main(["batch", str(log), "-o", str(tmp_path / "a"), "-q"]) == 0
    code = main(["batch", str(log), "-o", str(tmp_path / "b"), "-q", "--fail-above", "0.9"])
    assert code == 3
    assert "/robot2/map: no map message could be analysed" in capsys.readouterr().err


# ---- names and outputs of odd inputs (new-user run) -------------------------------------------------


def test_inputs_spelled_with_dot_dot_are_named_below_the_folder_they_mean(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """'../..' from a robot's folder: names had '..' in them and outputs escaped cleaned/ and rrd/;
    an output folder given as '.' took the '../' inputs for its own."""
    monkeypatch.chdir(fleet / "robot_b" / "nested")
    assert [r.name for r in discover([Path("..") / ".."])] == FLEET_NAMES
    report = tmp_path / "report"
    report.mkdir()
    monkeypatch.chdir(report)
    result = run_batch(
        ["../fleet/robot_a/../robot_b/run.mcap"], ".", options=RecordingOptions(cleaned=True)
    )
    (row,) = result.results
    assert row.status == "ok" and row.name == "run.mcap"
    assert row.cleaned_uri == str(report / "cleaned" / "run.mcap")
    assert Path(row.cleaned_uri).is_file()


def test_a_bags_storage_file_is_its_bag_and_counted_once(fleet: Path) -> None:
    bag = fleet / "robot_b" / "bag_dir"
    for inputs in ([bag, bag / "bag_dir.mcap"], [str(fleet / "robot_*" / "*" / "*.mcap")]):
        recordings = discover(inputs)
        bags = [r for r in recordings if r.uri == str(bag)]
        assert len(bags) == 1 and bags[0].is_dir and bags[0].name.endswith("bag_dir"), recordings
    assert [r.name for r in discover([bag / "bag_dir.mcap"])] == ["bag_dir"]


def test_a_bag_and_the_unclosed_bag_beside_it_get_two_cleaned_logs(tmp_path: Path) -> None:
    """x.bag and x.bag.active: the salvaged one's cleaned log (x.bag) replaced the complete one's."""
    from rose_logs.batch.sources import cleaned_log_name

    robot = tmp_path / "robot"
    robot.mkdir()
    (robot / "x.bag").write_bytes(b"complete")
    (robot / "x.bag.active").write_bytes(b"unclosed")
    names = [r.name for r in discover([robot])]
    assert names[0] == "robot/x.bag"
    assert names[1].startswith("robot/x-") and names[1].endswith(".bag.active")
    assert len({cleaned_log_name(n) for n in names}) == 2


def test_a_cleaned_log_keeps_the_format_of_its_input_whatever_the_suffix(
    fleet: Path, tmp_path: Path
) -> None:
    """An MCAP file named session.bag: --cleaned asked to write ROS 2 messages as a ROS 1 bag."""
    from rose_logs.formats import detect_format

    odd = tmp_path / "odd" / "session.bag"
    odd.parent.mkdir()
    odd.write_bytes((fleet / "robot_a" / "run.mcap").read_bytes())
    (row,) = run_batch([odd], tmp_path / "out", options=RecordingOptions(cleaned=True)).results
    assert row.status == "ok", row.error
    assert detect_format(Path(row.cleaned_uri)) == "mcap"


def test_a_full_output_disk_is_no_failure_of_the_recording(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An error writing under OUT is retried and not stored: a re-run with space does the
    recording (it was stored as the recording's error, redone only by --retry-errors)."""
    import errno

    import rose_logs.session
    from rose_logs.errors import LogWriteError

    real = rose_logs.session.process_log

    def full(*args: object, **kwargs: object) -> object:
        try:
            raise OSError(errno.ENOSPC, "No space left on device")
        except OSError as err:
            msg = f"{kwargs['output_path']}: cannot write (No space left on device)"
            raise LogWriteError(msg) from err

    monkeypatch.setattr(rose_logs.session, "process_log", full)
    out = tmp_path / "out"
    options = RecordingOptions(cleaned=True, retries=1)
    (failed,) = run_batch([fleet / "robot_a" / "run.mcap"], out, options=options).results
    assert failed.status == "error" and "No space left on device" in failed.error
    # Named where it was going, not by its staging name (gone when the row is read).
    assert ".staging" not in failed.error, failed.error
    assert str(out / "cleaned" / "run.mcap") in failed.error, failed.error
    monkeypatch.setattr(rose_logs.session, "process_log", real)
    again = run_batch([fleet / "robot_a" / "run.mcap"], out, options=options)
    assert (again.processed, again.skipped) == (1, 0)
    assert again.results[0].status == "ok"


def test_a_rerun_remakes_outputs_cut_short_or_missing_a_file(fleet: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    options = RecordingOptions(cleaned=True)
    run_batch([fleet / "robot_b"], out, options=options)
    log = out / "cleaned" / "robot_b" / "run.mcap"
    storage = out / "cleaned" / "robot_b" / "bag_dir" / "bag_dir.mcap"
    whole = log.read_bytes()
    log.write_bytes(whole[:1000])
    storage.unlink()  # its metadata.yaml stays: the folder still exists
    again = run_batch([fleet / "robot_b"], out, options=options)
    assert (again.processed, again.skipped) == (2, 1)
    assert log.read_bytes() == whole and storage.is_file()
    # Said, as every finished recording done again is (it was redone without a word).
    assert again.redone == (("its --cleaned / --rrd output was deleted or changed since", 2),)


@pytest.mark.parametrize("limit", ["1KB", "0.0000001"])
def test_a_memory_limit_too_small_for_a_worker_is_a_usage_error(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], limit: str
) -> None:
    argv = ["batch", str(fleet), "-o", str(tmp_path / "o"), "--workers", "2"]
    with pytest.raises(SystemExit) as info:
        main([*argv, "--memory-limit", limit])
    assert info.value.code == 2
    assert "too little to start a worker" in capsys.readouterr().err


def test_a_list_may_come_from_standard_input_and_start_with_a_byte_order_mark(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import io
    import sys

    listing = tmp_path / "inputs.txt"
    listing.write_bytes(b"\xef\xbb\xbf" + f"{fleet / 'robot_a'}\n".encode())  # a Windows editor's
    assert read_list(str(listing)) == [str(fleet / "robot_a")]
    piped = io.TextIOWrapper(io.BytesIO(f"# found\n{fleet / 'robot_b' / 'run.mcap'}\n".encode()))
    monkeypatch.setattr(sys, "stdin", piped)
    assert read_list("-") == [str(fleet / "robot_b" / "run.mcap")]


def test_the_cleaned_logs_of_an_earlier_batch_inside_the_inputs_are_no_recordings(
    fleet: Path, tmp_path: Path
) -> None:
    """A batch's OUT kept beside the fleet: a later batch writing elsewhere counted its cleaned
    logs as recordings (4 rows instead of 2); named on their own they still are inputs."""
    run_batch([fleet / "robot_a"], fleet / "health", options=RecordingOptions(cleaned=True))
    names = [r.name for r in discover([fleet])]
    assert names == FLEET_NAMES
    cleaned = [r.name for r in discover([fleet / "health" / "cleaned"])]
    assert cleaned == ["cleaned/robot_a/later.db3", "cleaned/robot_a/run.mcap"]


def test_a_corrupt_recording_is_its_own_error_not_an_io_error_retried(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A damaged bz2 chunk is an OSError inside the reader (errno None): the recording's error,
    stored once, not retried and redone on every run as a full disk is."""
    import rose_logs.session
    from rose_logs.errors import LogReadError

    calls = {"n": 0}

    def corrupt(*args: object, **kwargs: object) -> object:
        calls["n"] += 1
        try:
            raise OSError("Invalid data stream")
        except OSError as err:
            msg = "bad.bag: corrupt or truncated log (Invalid data stream)"
            raise LogReadError(msg) from err

    monkeypatch.setattr(rose_logs.session, "process_log", corrupt)
    out = tmp_path / "out"
    options = RecordingOptions(retries=2)
    (row,) = run_batch([fleet / "robot_a" / "run.mcap"], out, options=options).results
    assert row.status == "error" and "I/O error" not in row.error and calls["n"] == 1
    again = run_batch([fleet / "robot_a" / "run.mcap"], out, options=options)
    assert (again.processed, again.skipped, calls["n"]) == (0, 1, 1)


def test_dot_dot_after_a_symlink_names_what_the_shell_names(
    tmp_path: Path, fleet: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """link/../x is the parent of the link's target, as the kernel resolves it (a textual
    normpath dropped 'link/..' and named a file that does not exist)."""
    (tmp_path / "real" / "dir").mkdir(parents=True)
    (tmp_path / "real" / "data").mkdir()
    (tmp_path / "real" / "data" / "x.mcap").write_bytes(
        (fleet / "robot_a" / "run.mcap").read_bytes()
    )
    (tmp_path / "link").symlink_to(tmp_path / "real" / "dir")
    (found,) = discover([str(tmp_path / "link" / ".." / "data" / "x.mcap")])
    assert found.uri == str(tmp_path / "real" / "data" / "x.mcap") and found.name == "x.mcap"
    monkeypatch.chdir(tmp_path)
    with pytest.raises(BatchError, match=r"^link/\.\./nope: no such file"):
        discover(["link/../nope"])  # named as typed


def test_remote_recordings_are_never_inside_a_local_output_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """realpath('s3://logs/x') is <cwd>/s3:/logs/x: with -o . every remote recording was dropped."""
    from rose_logs.batch.engine import _outside
    from rose_logs.batch.sources import Recording
    from rose_logs.batch.store import OutputStore

    monkeypatch.chdir(tmp_path)
    remote = Recording("s3://logs/robots/run.mcap", "robots/run.mcap", False, 1, "etag")
    assert _outside((remote,), OutputStore(".")) == (remote,)


def test_a_bags_metadata_is_its_bag_and_an_unclosed_bag_is_renamed_whatever_the_order(
    fleet: Path, tmp_path: Path
) -> None:
    bag = fleet / "robot_b" / "bag_dir"
    (found,) = discover([str(bag / "*")])  # metadata.yaml and the storage file: one bag
    assert found.is_dir and found.uri == str(bag)
    robot = tmp_path / "robot"
    robot.mkdir()
    (robot / "x.bag").write_bytes(b"complete")
    (robot / "x.bag.active").write_bytes(b"unclosed")
    for order in (
        [robot / "x.bag.active", robot / "x.bag"],
        [robot / "x.bag", robot / "x.bag.active"],
    ):
        names = {Path(r.uri).name: r.name for r in discover(order)}
        assert names["x.bag"] == "x.bag" and names["x.bag.active"].startswith("x-")


def test_a_list_read_from_a_closed_standard_input_is_one_error(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import sys

    monkeypatch.setattr(sys, "stdin", None)
    with pytest.raises(BatchError, match="standard input: closed"):
        read_list("-")


def test_a_remote_bags_storage_file_is_its_bag_too() -> None:
    import fsspec

    fs = fsspec.filesystem("memory")
    metadata = b"rosbag2_bagfile_information:\n  relative_file_paths: [bag1.db3]\n"
    fs.pipe("/rose-test-fleet/bag1/metadata.yaml", metadata)
    fs.pipe("/rose-test-fleet/bag1/bag1.db3", b"x")
    try:
        for inputs in (
            ["memory://rose-test-fleet/bag1", "memory://rose-test-fleet/bag1/bag1.db3"],
            ["memory://rose-test-fleet/*/*.db3"],
        ):
            (found,) = discover(inputs)
            assert found.is_dir and found.uri == "memory:///rose-test-fleet/bag1"
    finally:
        fs.rm("/rose-test-fleet", recursive=True)


def test_a_compressed_bags_storage_file_is_its_bag_too(tmp_path: Path) -> None:
    """A bag compressed file by file (rosbag2's ``.mcap.zstd`` / ``.db3.zstd``) is one recording
    however it is reached: 'fleet/*/*.mcap*' silently left it out (its storage file was neither a
    log nor a bag's file), and its storage file named alone was taken as a log of its own."""
    import fsspec

    bag = tmp_path / "fleet" / "zbag"
    bag.mkdir(parents=True)
    metadata = "rosbag2_bagfile_information:\n  relative_file_paths: [zbag_0.mcap.zstd]\n"
    (bag / "metadata.yaml").write_text(metadata)
    (bag / "zbag_0.mcap.zstd").write_bytes(b"x")
    for given in (f"{bag.parent}/*/*.mcap*", f"{bag}/*.zstd", bag / "zbag_0.mcap.zstd"):
        assert [(r.name, r.is_dir) for r in discover([given])] == [("zbag", True)], given
    fs = fsspec.filesystem("memory")
    fs.pipe("/rose-test-zbag/zbag/metadata.yaml", metadata.replace("mcap", "db3").encode())
    fs.pipe("/rose-test-zbag/zbag/zbag_0.db3.zstd", b"x")
    try:
        (found,) = discover(["memory://rose-test-zbag/*/*.zstd"])
        assert found.is_dir and found.uri == "memory:///rose-test-zbag/zbag"
    finally:
        fs.rm("/rose-test-zbag", recursive=True)


def test_an_empty_input_is_an_error_not_the_current_folder(
    fleet: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The CLI refuses an empty INPUT; discover and run_batch took it as the current folder and
    searched it whole (an unset variable's ``os.environ.get("FLEET", "")``)."""
    monkeypatch.chdir(fleet)
    with pytest.raises(BatchError, match=r"^an empty input names no file or folder"):
        discover([""])
    assert [r.name for r in discover(["."])] == FLEET_NAMES  # "." names it as before


def test_a_name_with_glob_characters_that_exists_is_taken_as_named(tmp_path: Path) -> None:
    """'run[1]' and 'b[x].mcap' were patterns that matched nothing: "matches no file or folder"
    for a folder and a file that exist. A pattern is still one where nothing has its name."""
    fleet = tmp_path / "fleet"
    (fleet / "run[1]").mkdir(parents=True)
    (fleet / "run[1]" / "a.mcap").write_bytes(b"x")
    (fleet / "b[x].mcap").write_bytes(b"x")
    assert [r.name for r in discover([fleet / "run[1]"])] == ["run[1]/a.mcap"]
    assert [r.name for r in discover([fleet / "b[x].mcap"])] == ["b[x].mcap"]
    assert [r.name for r in discover([f"{fleet}/*.mcap"])] == ["b[x].mcap"]
    with pytest.raises(BatchError, match=r"run\[2\]: matches no file or folder"):
        discover([fleet / "run[2]"])


def test_a_pattern_is_a_search_its_files_that_are_not_logs_are_left_out(fleet: Path) -> None:
    """'fleet/*' took the README.md, notes and pictures beside the logs as recordings: error rows.
    A pattern is a search, as a folder is; a file named on its own is taken whatever its suffix."""
    for other in ("README.md", "notes.txt", "map.png"):
        (fleet / other).write_text("not a log\n")
    (fleet / "robot_a" / "day.MCAP").write_bytes(b"x")  # a log's suffix in any case
    found = [r.name for r in discover([f"{fleet}/*"])]
    assert found == sorted(["robot_a/day.MCAP", *(n.removeprefix("fleet/") for n in FLEET_NAMES)])
    assert [r.name for r in discover([f"{fleet}/robot_a/*"])] == [
        "day.MCAP",
        "later.db3",
        "run.mcap",
    ]
    bag = fleet / "robot_b" / "bag_dir"
    assert [(r.name, r.is_dir) for r in discover([f"{bag}/*"])] == [("bag_dir", True)]
    assert [r.name for r in discover([fleet / "notes.txt"])] == ["notes.txt"]
    with pytest.raises(BatchError) as info:
        discover([f"{fleet}/*.txt"])
    assert str(info.value) == (
        f"{fleet}/*.txt: matches no log file or folder, only 1 other file(s) (first: notes.txt); "
        "name a file on its own to take it whatever its suffix"
    )


def test_the_root_folder_is_searched_as_any_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """'/' was stripped to '' (no folder): "/: cannot list ([Errno 2] No such file or directory:
    '')". The root has no name of its own: its recordings are named below it, as are those of a
    pattern such as '/*' (they were named by their absolute paths)."""
    from rose_logs.batch import sources

    run = tmp_path / "fleet" / "run.mcap"
    run.parent.mkdir()
    run.write_bytes(b"x")
    searched: list[str] = []

    def local_files(root: str) -> list[str]:  # not the whole machine: only the fleet is below '/'
        searched.append(root)
        if not root or not Path(root).is_dir():  # as os.walk fails (Path('') is '.')
            raise FileNotFoundError(2, "No such file or directory", root)
        return [str(run)] if str(run).startswith(root.rstrip("/") + "/") else []

    monkeypatch.setattr(sources, "_local_files", local_files)
    expected = [str(run).removeprefix("/")]
    assert [r.name for r in discover(["/"])] == expected
    assert searched == ["/"]
    assert [r.name for r in discover(["//"])] == expected
    monkeypatch.chdir("/")
    assert [r.name for r in discover(["."])] == expected
    top = "/" + expected[0].split("/")[0]  # the folder of '/*' that holds the fleet
    assert [r.name for r in discover([top[:-1] + "*"]) if r.uri == str(run)] == expected


def test_a_data_sets_own_metadata_yaml_makes_no_bag_folder(tmp_path: Path) -> None:
    """A folder whose metadata.yaml is not rosbag2's (a data set's description) was taken whole as
    one bag, an error row ("not a ROS 2 bag", as process says), and its logs were never found."""
    import fsspec

    data = tmp_path / "dataset"
    (data / "day1").mkdir(parents=True)
    (data / "metadata.yaml").write_text("name: my dataset\nlicense: CC-BY-4.0\n")
    (data / "day1" / "metadata.yaml").write_text("robot: r1\n")
    (data / "a.mcap").write_bytes(b"x")
    (data / "day1" / "b.mcap").write_bytes(b"x")
    expected = [("dataset/a.mcap", False), ("dataset/day1/b.mcap", False)]
    assert [(r.name, r.is_dir) for r in discover([data])] == expected
    assert [(r.name, r.is_dir) for r in discover([data / "day1"])] == [("day1/b.mcap", False)]
    fs = fsspec.filesystem("memory")
    fs.pipe("/rose-test-dataset/metadata.yaml", b"name: my dataset\n")
    fs.pipe("/rose-test-dataset/a.mcap", b"x")
    try:
        (found,) = discover(["memory://rose-test-dataset"])
        assert not found.is_dir and found.uri == "memory:///rose-test-dataset/a.mcap"
    finally:
        fs.rm("/rose-test-dataset", recursive=True)


def test_a_list_entry_naming_nothing_is_named_with_its_list_and_line(
    fleet: Path, tmp_path: Path
) -> None:
    listing = tmp_path / "todo.txt"
    listing.write_text(f"# fleet\n{fleet / 'robot_a'}\n\nmissing.mcap\n")
    with pytest.raises(
        BatchError, match=rf"^missing\.mcap: no such file or folder \({listing} line 4\)$"
    ):
        discover(read_list(str(listing)))
    with pytest.raises(BatchError, match=r"^missing\.mcap: no such file or folder$"):
        discover(["missing.mcap"])  # given on the command line: no line to name


def test_a_failed_recordings_warnings_are_in_the_report(tmp_path: Path) -> None:
    """summary.json counted a failed recording among those that warned; report.md showed its
    warnings nowhere."""
    log = _with_nan_resolution(tmp_path / "robot" / "all_bad.mcap", {1, 2, 3, 4})
    out_dir = tmp_path / "out"
    run_batch([log], out_dir)
    (row,) = read_rows(out_dir / "recordings.parquet")
    assert row["status"] == "error" and row["warnings"]
    failed = (out_dir / "report.md").read_text().split("## Failed recordings")[1].split("##")[0]
    assert "| all_bad.mcap |" in failed and row["warnings"][0][:40] in failed


def test_a_hard_link_is_the_same_recording(fleet: Path, tmp_path: Path) -> None:
    copy = tmp_path / "elsewhere.mcap"
    os.link(fleet / "robot_a" / "run.mcap", copy)
    found = discover([fleet / "robot_a" / "run.mcap", copy])
    assert [r.name for r in found] == ["run.mcap"]  # named by its first spelling


def test_the_batchs_error_line_is_one_short_line_however_long_the_rows_error(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A truncated bag's error made a 347-character line (the README promises at most 300); the
    whole text stays in the tables."""
    import rose_logs.session
    from rose.limits import MAX_MESSAGE_CHARS
    from rose_logs.errors import LogReadError

    long_text = "corrupt or truncated log (" + "x" * 500 + ")"

    def corrupt(*args: object, **kwargs: object) -> object:
        raise LogReadError(long_text)

    monkeypatch.setattr(rose_logs.session, "process_log", corrupt)
    out = tmp_path / "out"
    assert main(["batch", str(fleet / "robot_a" / "run.mcap"), "-o", str(out), "-q"]) == 1
    (line,) = [x for x in capsys.readouterr().err.splitlines() if x.startswith("failed:")]
    assert len(line) <= len("failed: ") + MAX_MESSAGE_CHARS and line.endswith("...")
    (row,) = read_rows(out / "recordings.parquet")
    assert long_text in row["error"]


def test_a_processed_recording_gets_its_rose_topics_written_anew_on_request(
    tmp_path: Path,
) -> None:
    """A fleet folder holding a processed log: with --cleaned it is an error row (the cleaned log
    would hold two sets of <map>/rose/*), unless replace_rose_topics writes them anew; the option
    is part of the resume key only when set."""
    from fleet import copy_recording

    from rose_logs.session import process_log

    raw = copy_recording(tmp_path / "raw" / "run.mcap", "mcap", max_maps=2)
    processed = tmp_path / "fleet" / "run.mcap"
    processed.parent.mkdir()
    process_log(raw, output_path=processed)
    run_batch([processed], tmp_path / "o1", options=RecordingOptions(cleaned=True))
    (row,) = read_rows(tmp_path / "o1" / "recordings.parquet")
    assert row["status"] == "error" and "--replace-rose-topics" in row["error"]
    options = RecordingOptions(cleaned=True, replace_rose_topics=True)
    run_batch([processed], tmp_path / "o2", options=options)
    (row,) = read_rows(tmp_path / "o2" / "recordings.parquet")
    assert row["status"] == "ok", row["error"]
    with LogReader(Path(row["cleaned"])) as reader:
        counts = {c.topic: c.message_count for c in reader.channels}
    assert counts["/map/rose/cleaned"] == counts["/map"] == row["snapshots"] == 2
    assert "replace_rose_topics" not in RecordingOptions().key_fields()
    assert options.key_fields()["replace_rose_topics"] is True


def test_the_batch_gate_decides_as_process_on_a_w_near_the_level(tmp_path: Path) -> None:
    """Batch compared a W rounded to six decimals with --fail-above (0.14689164 read 0.146892):
    a level between the two passed `process` and failed the batch."""
    from fleet import copy_recording

    log = copy_recording(tmp_path / "run.mcap", "mcap", max_maps=3)
    report = tmp_path / "r.json"
    assert main(["process", str(log), "--no-output", "-q", "--json", str(report)]) == 0
    w_max = json.loads(report.read_text())["topics"]["/map"]["w_max"]
    for level, expected in ((w_max + 1e-9, 0), (w_max - 1e-9, 3)):
        text = repr(level)
        assert main(["process", str(log), "--no-output", "-q", "--fail-above", text]) == expected
        out = str(tmp_path / f"batch-{expected}")
        assert main(["batch", str(log), "-o", out, "-q", "--fail-above", text]) == expected
        (row,) = read_rows(Path(out) / "recordings.parquet")
        assert row["w_max"] == w_max


def test_work_folders_of_dead_workers_are_removed_by_the_next_run(tmp_path: Path) -> None:
    """A worker killed by a signal left its work folder in OUT/.staging, and no later run removed
    it. A run removes the folders of dead processes of this host (at once where the process tag
    names the PID namespace, as on Linux: an interrupted batch's workers' partial logs stayed
    until a run a minute later; else untouched for a minute), and any untouched for a day; not a
    live process's, nor a folder changed lately whose pid this host cannot vouch for (a batch in
    another PID namespace lost its folder mid-recording)."""
    import subprocess
    import sys
    import time

    from fleet import copy_recording

    from rose.outputs import process_tag

    log = copy_recording(tmp_path / "in" / "run.mcap", "mcap", max_maps=1)
    gone = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    dead_pid = int(gone.stdout)
    staging = tmp_path / "out" / ".staging"
    host = process_tag()
    now = time.time()
    folders = {  # name: (seconds since its last change, removed)
        f"rose-batch-{host}-{dead_pid}-dead_idle": (120, True),
        f"rose-batch-{host}-{dead_pid}-dead_busy": (5, "_pidns" in host),
        f"rose-batch-{host}-{os.getpid()}-alive_idle": (120, False),
        f"rose-batch-otherhost-{dead_pid}-elsewhere": (3600, False),
        f"rose-batch-otherhost-{dead_pid}-elsewhere_busy": (5, False),
        f"rose-batch-otherhost-{dead_pid}-elsewhere_old": (2 * 86400, True),
        "rose-batch-k3j9xyz_": (2 * 86400, True),  # an older rose-bag's name
    }
    for name, (idle, _) in folders.items():
        part = staging / name / "cleaned" / "part.mcap"
        part.parent.mkdir(parents=True)
        part.write_bytes(b"x")
        for path in (part, part.parent, part.parent.parent):
            os.utime(path, (now - idle, now - idle))
    run_batch([log], tmp_path / "out")
    left = {p.name for p in staging.iterdir()}
    assert left == {name for name, (_, removed) in folders.items() if not removed}


def test_no_two_recordings_get_names_whose_outputs_are_one_or_nested() -> None:
    """Stored names came first, but a stored name was checked alone: a salvaged x.bag.active
    (cleaned into x.bag) kept its name beside another recording's x.bag, and both rows named one
    cleaned log. And a bag folder `robot` and a file `robot/run.mcap`: writing the folder's
    cleaned bag deleted the file's cleaned log, and every run redid one of them."""
    from rose_logs.batch.engine import _run_names
    from rose_logs.batch.sources import Recording
    from rose_logs.batch.task import RecordingResult

    def rec(uri: str, name: str, is_dir: bool = False) -> Recording:
        return Recording(uri, name, is_dir, 1, "1")

    stored_active = RecordingResult(
        uri="/b/act/x.bag.active", name="act/x.bag.active", key="k", status="error"
    )
    recordings = (rec("/a/act/x.bag", "act/x.bag"), rec("/b/act/x.bag.active", "act/x.bag.active"))
    names = _run_names(
        recordings,
        {"/b/act/x.bag.active": stored_active},
        {"act/x.bag": "/a/act/x.bag"},
        keep_stored=True,
    )
    assert names["/a/act/x.bag"] == "act/x.bag"
    assert names["/b/act/x.bag.active"].startswith("act/x-")  # made distinct
    nested = (rec("/n1/robot", "robot", is_dir=True), rec("/n2/robot/run.mcap", "robot/run.mcap"))
    for owners in ({}, {"robot/run.mcap": "/n2/robot/run.mcap"}, {"robot": "/n1/robot"}):
        names = _run_names(nested, {}, owners, keep_stored=True)
        assert len({n for n in names.values() if n == "robot" or n.startswith("robot/")}) <= 1, (
            names
        )


def test_a_recording_without_a_result_for_this_key_takes_back_the_name_its_outputs_have() -> None:
    """Options or the file changed (a new key, no result under it), and the inputs came in another
    order: discovery named H otherwise, H was redone under the new name and its old cleaned log
    stayed behind, named by no row. H takes back the name its outputs have, and K keeps its own."""
    from rose_logs.batch.engine import _run_names
    from rose_logs.batch.sources import Recording

    recordings = (
        Recording("/H/day/x.mcap", "x-a392300b.mcap", False, 1, "2"),
        Recording("/K/day/x.mcap", "x.mcap", False, 1, "2"),
    )
    owners = {"x.mcap": "/H/day/x.mcap", "x-d8a08a7b.mcap": "/K/day/x.mcap"}
    names = _run_names(recordings, {}, owners, keep_stored=True)
    assert names == {"/H/day/x.mcap": "x.mcap", "/K/day/x.mcap": "x-d8a08a7b.mcap"}


@pytest.mark.parametrize(
    ("given", "read"),
    [
        ("max_concurrency=2", ("max_concurrency", 2)),
        (
            'client_kwargs={"region_name": "eu-west-1"}',
            ("client_kwargs", {"region_name": "eu-west-1"}),
        ),
        ("anon=TRUE", ("anon", True)),
        ('version_id="123"', ("version_id", "123")),
        ("endpoint_url=http://host:9000", ("endpoint_url", "http://host:9000")),
        # credentials stay text, however they look
        ("secret=123456", ("secret", "123456")),
        ("password=2024", ("password", "2024")),
        ("token=null", ("token", "null")),
        ("aws_access_key=1e5", ("aws_access_key", "1e5")),
        ("password=true", ("password", "true")),
        ("account_name=123", ("account_name", "123")),
        ("api_key_id=123", ("api_key_id", "123")),
        ('token={"type": "service_account"}', ("token", {"type": "service_account"})),
    ],
)
def test_storage_options_are_read_as_json_except_credentials(
    given: str, read: tuple[str, Any]
) -> None:
    from rose_logs.cli.batch import _storage_option

    assert _storage_option(given) == read


def test_an_io_error_reading_a_recording_is_retried_not_stored_as_damage(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An EIO under a local recording (a failing disk, a network file system) came out of the
    reader as "corrupt or truncated", stored: no later run tried it again. As an I/O error under
    OUT, it is retried and not stored."""
    import errno

    import rose_logs.session
    from rose_logs.errors import LogReadError

    real = rose_logs.session.process_log
    calls = {"n": 0, "failing": True}

    def flaky(*args: object, **kwargs: object) -> object:
        calls["n"] += 1
        if not calls["failing"]:
            return real(*args, **kwargs)  # type: ignore[arg-type]
        try:
            raise OSError(errno.EIO, "Input/output error")
        except OSError as err:
            msg = "run.mcap: corrupt or truncated MCAP file ([Errno 5] Input/output error)"
            raise LogReadError(msg) from err

    monkeypatch.setattr(rose_logs.session, "process_log", flaky)
    monkeypatch.setattr("time.sleep", lambda seconds: None)
    out = tmp_path / "out"
    recording = fleet / "robot_a" / "run.mcap"
    (row,) = run_batch([recording], out, options=RecordingOptions(retries=1)).results
    assert calls["n"] == 2 and row.status == "error"
    assert row.error == f"{recording}: I/O error: cannot read the recording (Input/output error)"
    assert not list(out.glob("results/*.json"))
    calls["failing"] = False  # the disk is back: done again, not a stored failure
    (again,) = run_batch([recording], out, options=RecordingOptions(retries=1)).results
    assert again.status == "ok" and calls["n"] == 3


def test_a_full_disk_under_a_db3_output_is_an_io_error_retried_not_the_recordings(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """sqlite3 says "database or disk is full" in its own error: the batch stored it as the
    recording's "unexpected error" and never tried it again after space was freed."""
    import sqlite3

    from rosbags.rosbag2 import Writer

    real = Writer.write
    full = {"on": True}

    def write(self: object, *args: object, **kwargs: object) -> None:
        if full["on"]:
            err = sqlite3.OperationalError("database or disk is full")
            err.sqlite_errorcode = sqlite3.SQLITE_FULL  # type: ignore[attr-defined]
            raise err
        real(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Writer, "write", write)
    out = tmp_path / "out"
    options = RecordingOptions(cleaned=True, retries=0)
    recording = fleet / "robot_a" / "later.db3"
    (row,) = run_batch([recording], out, options=options).results
    assert row.status == "error"
    assert ": I/O error: " in row.error and "cannot write (No space left on device)" in row.error
    full["on"] = False  # space freed: tried again, not a stored failure
    (again,) = run_batch([recording], out, options=options).results
    assert again.status == "ok"


def test_a_recording_out_of_memory_is_one_line_and_tried_again(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A MemoryError was the recording's stored "unexpected error" with a traceback in the log:
    memory running short says nothing lasting about a recording, so the next run tries it again."""
    import logging

    import rose

    real = rose.analyze
    short_of_memory = {"on": True}

    def analyze(*args: object, **kwargs: object) -> object:
        if short_of_memory["on"]:
            raise MemoryError
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(rose, "analyze", analyze)
    out = tmp_path / "out"
    options = RecordingOptions(retries=0)
    recording = fleet / "robot_a" / "later.db3"
    with caplog.at_level(logging.WARNING):
        (row,) = run_batch([recording], out, options=options).results
    assert row.status == "error" and row.error.endswith(
        ": out of memory (fewer --workers, or a lower --max-cells?)"
    )
    assert not any(r.exc_info for r in caplog.records), "no traceback"
    short_of_memory["on"] = False  # memory to spare now: tried again, not a stored failure
    (again,) = run_batch([recording], out, options=options).results
    assert again.status == "ok"


def test_the_redone_scan_reads_only_results_of_other_settings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Adding one recording to a finished fleet read every stored result (a GET each on an object
    store) to say nothing; and each stored result was searched once per recording to do (1,000
    recordings: 5 s). Results under this run's keys are not read, the others once each."""
    from fleet import copy_recording

    from rose_logs.batch.store import OutputStore

    a = copy_recording(tmp_path / "in" / "a.mcap", "mcap", max_maps=2)
    out = tmp_path / "out"
    run_batch([a.parent], out)
    copy_recording(tmp_path / "in" / "b.mcap", "mcap", max_maps=2)
    read: list[int] = []
    real = OutputStore.iter_folder

    def counted(self, relative, suffix, *, skip=()):  # type: ignore[no-untyped-def]
        for data in real(self, relative, suffix, skip=skip):
            read.append(len(data))
            yield data

    monkeypatch.setattr(OutputStore, "iter_folder", counted)
    report = run_batch([a.parent], out)
    assert report.processed == 1 and report.redone == () and read == []
    # With other options both are redone: the two stored results are read once each.
    report = run_batch([a.parent], out, options=RecordingOptions(walls=True))
    assert report.redone == (("options changed: walls", 2),) and len(read) == 2


def test_a_result_that_cannot_be_stored_is_said_not_a_crashed_batch(
    fleet: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk when a finished recording's result is written: retried, then said on its row
    and not stored (the next run does it again). It escaped process_recording: in this process
    the whole batch ended with no tables."""
    import errno

    from rose_logs.batch.store import OutputStore

    real = OutputStore.write_bytes
    full = {"on": True}

    def write_bytes(self: OutputStore, relative: str, data: bytes) -> object:
        if full["on"] and relative.startswith("results/"):
            raise OSError(errno.ENOSPC, "cannot write (No space left on device)", relative)
        return real(self, relative, data)

    monkeypatch.setattr(OutputStore, "write_bytes", write_bytes)
    out = tmp_path / "out"
    options = RecordingOptions(retries=1)
    report = run_batch([fleet / "robot_a"], out, options=options)
    assert [r.status for r in report.results] == ["ok", "ok"]
    assert all("its result could not be stored" in r.warnings[-1] for r in report.results)
    assert len(read_rows(out / "recordings.parquet")) == 2
    full["on"] = False
    again = run_batch([fleet / "robot_a"], out, options=options)
    assert (again.processed, again.skipped) == (2, 0)
    assert not any(r.warnings for r in again.results)


def test_log_times_of_2_to_the_63_and_more_go_into_the_tables(tmp_path: Path) -> None:
    """Log times are unsigned 64-bit: one of 2**63 or more (valid in MCAP) overflowed the tables'
    int64 columns, a traceback after the whole batch had run."""
    from fleet import big_map_recording

    last_ns = 2**64 - 1
    log = big_map_recording(tmp_path / "in" / "late.mcap", side=120, log_times_ns=(2**63, last_ns))
    out = tmp_path / "out"
    assert main(["batch", str(log), "-o", str(out), "-q"]) == 0
    (recording,) = read_rows(out / "recordings.parquet")
    # The session's span is the log's; maps logged past 2**63 ns are copied, not analysed (their
    # time does not fit the recording's timelines), and counted.
    assert recording["end_ns"] == last_ns
    assert recording["snapshots"] == 1 and recording["skipped_messages"] == 2
    (snapshot,) = read_rows(out / "snapshots.parquet")
    assert snapshot["log_time_ns"] == recording["start_ns"] < 2**63
