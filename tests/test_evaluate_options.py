"""``rose-bag evaluate`` option values: out-of-range ones are usage errors before anything runs."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import pytest
from real_data import REPO_DATA

from rose_logs.cli import build_parser, main
from rose_logs.cli.evaluate import config_from_args
from rose_logs.evaluation.config import BENCHMARK_SUBDIR, LOGS_SUBDIR


@pytest.mark.parametrize(
    ("option", "value", "problem"),
    [
        ("--sizes", "0", "1..200"),  # was a ValueError traceback from the clutter generator
        ("--sizes", "4,-5", "1..200"),
        ("--sizes", "100000", "1..200"),  # was accepted: one obstacle of 1e10 cells
        ("--counts", "-3", "1..1000"),
        ("--counts", "0", "1..1000"),
        ("--counts", "100000000", "1..1000"),  # was accepted: 1e8 obstacles per map
        ("--counts", ",".join(["20"] * 51), "at most 50 values"),
        ("--sizes", "4,x", "comma-separated integers"),
        ("--sizes", ",", "at least one integer"),  # was an empty experiment
        # An empty item: ran with counts 1 and 2, silently.
        ("--counts", "1,,2", "an empty item in '1,,2' (two commas in a row, or one at an end)"),
        ("--counts", "20,", "an empty item"),
        ("--sizes", " ,4", "an empty item"),
        ("--logs", "aces,,intel", "an empty item"),
        ("--maps", "Freiburg79_scan,", "an empty item"),
        ("--seed", "-1", "0..4294967295"),  # was a traceback after ~10 s of work
        ("--seed", str(2**32), "0..4294967295"),
        ("--break-seeds", "-1", "0..20"),
        ("--break-seeds", "1000", "0..20"),
    ],
)
def test_out_of_range_values_are_usage_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str, value: str, problem: str
) -> None:
    out = tmp_path / "report"
    with pytest.raises(SystemExit) as info:
        main(["evaluate", str(out), "--no-plots", f"{option}={value}"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}: " in err
    assert problem in err
    assert "Traceback" not in err
    assert not out.exists()


def test_values_at_the_bounds_are_accepted() -> None:
    args = build_parser().parse_args(
        [
            "evaluate",
            "out",
            "--sizes",
            "1,200",
            "--counts",
            "1,1000",
            "--seed",
            str(2**32 - 1),
            "--break-seeds",
            "20",
        ]
    )
    config = config_from_args(args)
    assert config.sizes_px == (1, 200)
    assert config.counts == (1, 1000)
    assert config.seed == 2**32 - 1
    assert config.break_seeds == 20


def test_help_states_the_bounds(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    for bound in ("1..200", "1..1000", "0..2**32-1", "0..20", "at most 50 values"):
        assert bound in help_text


def test_nothing_to_evaluate_is_said(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # Both lists empty (an unset shell variable?) ran every experiment on nothing and reported
    # empty tables silently; one empty list alone skips that part, as documented.
    out = tmp_path / "report"
    (tmp_path / "data").mkdir()  # the data folder never holds the report
    args = [
        "evaluate",
        str(out),
        "--no-plots",
        "--logs",
        ",",
        "--maps",
        "",
        "--maps-dir",
        str(tmp_path / "data"),
    ]
    assert main(args) == 0
    assert "--logs and --maps are both empty: no experiment runs" in capsys.readouterr().err


def test_lists_are_taken_once_and_logs_by_their_file_names_too() -> None:
    args = build_parser().parse_args(
        [
            "evaluate",
            "out",
            "--logs",
            "aces,aces-corrected.log.gz,intel-corrected",
            "--sizes",
            "4,4",
            "--maps",
            "Freiburg79_scan.png,Freiburg79_scan,lab_ipa_furnitures.png",
        ]
    )
    config = config_from_args(args)
    assert config.logs == ("aces", "intel")  # a log named twice ran, and was tabled, twice
    assert config.sizes_px == (4,)
    # Map file names looked for Freiburg79_scan.png_furnitures.png.
    assert config.benchmark_maps == ("Freiburg79_scan", "lab_ipa")


def test_a_missing_data_folder_is_named_and_an_empty_report_folder_is_replaceable(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["evaluate", str(tmp_path / "r"), "--maps-dir", str(tmp_path / "nope")]) == 1
    err = capsys.readouterr().err.strip()
    assert err == f"error: {tmp_path / 'nope'}: no such data folder (--maps-dir)"
    (tmp_path / "a_file").write_text("x")  # said "no such data folder" of a file that exists
    assert main(["evaluate", str(tmp_path / "r"), "--maps-dir", str(tmp_path / "a_file")]) == 1
    err = capsys.readouterr().err.strip()
    assert err == f"error: {tmp_path / 'a_file'}: is a file, not a data folder (--maps-dir)"
    empty = tmp_path / "empty"
    empty.mkdir()
    data = tmp_path / "data"
    data.mkdir()
    argv = ["evaluate", str(empty), "--no-plots", "--logs", "", "--maps", "", "--force"]
    assert main([*argv, "--maps-dir", str(data)]) == 0  # was refused: not a report folder
    assert (empty / "report.md").is_file()
    # Without --force too: an empty folder holds nothing to overwrite (was "exists already").
    shutil.rmtree(empty)
    empty.mkdir()
    assert main([*argv[:-1], "--maps-dir", str(data)]) == 0
    assert (empty / "report.md").is_file()


def test_a_report_of_no_experiment_is_never_written_into_the_data_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """With nothing to read from it (`--logs '' --maps ''`) the data folder was no input: the
    report went into $ROSE_DATA_DIR (or --maps-dir), which is read, never written."""
    data = tmp_path / "data"
    data.mkdir()
    monkeypatch.setenv("ROSE_DATA_DIR", str(data))
    argv = ["--no-plots", "--logs", "", "--maps", ""]
    for extra in ([], ["--maps-dir", str(data)]):
        assert main(["evaluate", str(data / "report"), *argv, *extra]) == 1
        err = capsys.readouterr().err
        assert err.endswith(f"refusing to write inside the input {data}\n"), err
        assert list(data.iterdir()) == []
    monkeypatch.setenv("ROSE_DATA_DIR", str(tmp_path / "nope"))  # none found: nothing to protect
    assert main(["evaluate", str(tmp_path / "report"), *argv]) == 0


def test_force_replaces_only_a_folder_that_holds_an_evaluation_report_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A folder of the user's with a report.md of its own (and a chapters/ folder) was replaced
    whole, its other files lost."""
    mine = tmp_path / "thesis"
    (mine / "chapters").mkdir(parents=True)
    (mine / "report.md").write_text("# My thesis\n")
    (mine / "chapters" / "ch1.tex").write_text("\\chapter{One}\n")
    argv = ["evaluate", str(mine), "--no-plots", "--logs", "", "--maps", "", "--force"]
    data = tmp_path / "data"
    data.mkdir()
    assert main([*argv, "--maps-dir", str(data)]) == 1
    assert "thesis: is a directory this command did not write" in capsys.readouterr().err
    assert (mine / "chapters" / "ch1.tex").is_file()
    assert (mine / "report.md").read_text() == "# My thesis\n"
    report = tmp_path / "report"
    report.mkdir()
    assert main([*argv[:1], str(report), *argv[2:], "--maps-dir", str(data)]) == 0
    assert main([*argv[:1], str(report), *argv[2:], "--maps-dir", str(data)]) == 0  # again
    (report / "notes.txt").write_text("mine")
    assert main([*argv[:1], str(report), *argv[2:], "--maps-dir", str(data)]) == 1
    assert (report / "notes.txt").read_text() == "mine"


def test_a_furnished_drawing_of_another_size_is_said_before_any_experiment(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It was a ValueError traceback, after experiment 1 had run."""
    import shutil

    import cv2

    from rose_logs.evaluation.config import BENCHMARK_SUBDIR

    data = tmp_path / "maps"
    shutil.copytree(REPO_DATA / BENCHMARK_SUBDIR, data / BENCHMARK_SUBDIR)
    furnished = data / BENCHMARK_SUBDIR / "Freiburg79_scan_furnitures.png"
    cv2.imwrite(str(furnished), cv2.imread(str(furnished), cv2.IMREAD_GRAYSCALE)[:-5])
    out = tmp_path / "report"
    argv = ["evaluate", str(out), "--maps-dir", str(data), "--logs", "", "--no-plots"]
    assert main([*argv, "--maps", "Freiburg79_scan"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: {furnished}: shape ") and err.count("\n") == 1
    assert not out.exists()


def test_experiment_4_comes_before_the_file_list_which_names_its_tables(tmp_path: Path) -> None:
    """Experiment 4 was appended after "## Files", which left its tables out; with one log its
    leave-one-out table was headers alone."""
    out = tmp_path / "report"
    argv = ["evaluate", str(out), "--maps-dir", str(REPO_DATA), "--logs", "freiburg-101"]
    argv += ["--maps", "", "--sizes", "2", "--counts", "20", "--break-seeds", "1", "--no-plots"]
    assert main(argv) == 0
    text = (out / "report.md").read_text()
    headings = [line for line in text.splitlines() if line.startswith("## ")]
    assert headings[-2].startswith("## Experiment 4") and headings[-1] == "## Files"
    files = text.split("## Files", 1)[1]
    assert "`exp4_breaks_sessions.csv`" in files and (out / "exp4_breaks_sessions.csv").is_file()
    assert "### Leave one log out\n\nNeeds sessions of two logs or more." in text


def test_a_failed_evaluation_leaves_no_folder_it_made(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`evaluate new/a/b/eval` makes the report's parent folders; a run that failed left them."""
    import shutil

    from rose_logs.evaluation.config import BENCHMARK_SUBDIR

    data = tmp_path / "maps"
    shutil.copytree(REPO_DATA / BENCHMARK_SUBDIR, data / BENCHMARK_SUBDIR)
    (data / BENCHMARK_SUBDIR / "Freiburg79_scan_furnitures.png").write_bytes(b"not a png")
    out = tmp_path / "new" / "a" / "b" / "eval"
    argv = ["evaluate", str(out), "--maps-dir", str(data), "--logs", "", "--no-plots"]
    assert main([*argv, "--maps", "Freiburg79_scan"]) == 1
    assert "Freiburg79_scan_furnitures.png" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["maps"]


def test_nothing_to_evaluate_needs_no_data_set(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # No log and no map read nothing of the data set, but the cleaning benchmark looked it up after
    # experiments 1-2 had run: "the real data set was not found", exit 1.
    monkeypatch.setenv("ROSE_DATA_DIR", str(tmp_path / "nope"))
    out = tmp_path / "report"
    assert main(["evaluate", str(out), "--no-plots", "--logs", "", "--maps", ""]) == 0
    assert "error" not in capsys.readouterr().err
    assert (out / "report.md").is_file()


def test_a_report_inside_a_symlinked_data_sub_folder_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The data folder's benchmark sub-folder a symlink to a shared copy: only the data folder was
    # protected, and the report was written inside the benchmark's real folder.
    shared = tmp_path / "shared_benchmark"
    shared.mkdir()
    for image in (REPO_DATA / BENCHMARK_SUBDIR).glob("Freiburg79_scan*.png"):
        shutil.copy(image, shared / image.name)
    data = tmp_path / "data"
    data.mkdir()
    (data / BENCHMARK_SUBDIR).symlink_to(shared)
    before = sorted(p.name for p in shared.iterdir())
    for out in (shared / "report", shared / "new" / "report"):
        argv = ["evaluate", str(out), "--maps-dir", str(data), "--logs", "", "--maps"]
        assert main([*argv, "Freiburg79_scan", "--sizes", "4", "--counts", "20", "--no-plots"]) == 1
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert err == f"error: {out}: refusing to write inside the input {data / BENCHMARK_SUBDIR}"
        assert sorted(p.name for p in shared.iterdir()) == before  # no folder made there either


def test_a_missing_data_folder_is_an_error_also_with_nothing_to_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # --logs '' --maps '' read nothing, and a --maps-dir that does not exist was taken silently.
    out = tmp_path / "report"
    argv = ["evaluate", str(out), "--no-plots", "--logs", "", "--maps", ""]
    assert main([*argv, "--maps-dir", str(tmp_path / "nope")]) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err == f"error: {tmp_path / 'nope'}: no such data folder (--maps-dir)"
    assert not out.exists()


def test_logs_names_a_cut_log_by_its_file_name(tmp_path: Path) -> None:
    """--logs looked for NAME-corrected.log.gz only: the cut logs of tests/data
    (csail-corrected.head400.log.gz), or a log of one's own, could not be named at all
    ("csail-corrected.head400-corrected.log.gz: no such file")."""
    out = tmp_path / "report"
    argv = ["evaluate", str(out), "--maps-dir", str(REPO_DATA), "--maps", "", "--no-plots"]
    argv += ["--logs", "csail-corrected.head400.log.gz,freiburg-079-corrected.head400"]
    argv += ["--sizes", "2", "--counts", "20", "--break-seeds", "1"]
    assert main(argv) == 0
    text = (out / "report.md").read_text()
    assert "csail-corrected.head400, freiburg-079-corrected.head400" in text
    assert (out / "map_csail-corrected.head400.png").is_file()
    config = config_from_args(build_parser().parse_args(["evaluate", "o", "--logs", "aces"]))
    radish = dataclasses.replace(config, maps_dir=REPO_DATA)
    # A Radish log keeps its own name first; a missing one is named as the Radish file.
    assert radish.log_path("aces").name == "aces-corrected.log.gz"
    assert radish.log_path("csail").name == "csail-corrected.log.gz"
    assert radish.log_path("csail-corrected.head400").name == "csail-corrected.head400.log.gz"


def test_logs_takes_carmen_logs_anywhere_by_their_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """--logs /some/dir/intel.log was looked for in the data folder as a name: it ran, then
    failed writing map_/some/dir/intel.png, and a missing file was named as
    .../nothere-corrected.log.gz. A path, absolute or relative (or a file in the current
    folder), is read where it is, named by its file; a missing file, a folder or a file that is
    no CARMEN log is a one-line error naming it, before any experiment."""
    monkeypatch.setenv("ROSE_DATA_DIR", str(tmp_path / "nope"))  # no data set needed
    elsewhere = tmp_path / "some" / "dir"
    elsewhere.mkdir(parents=True)
    log = elsewhere / "intel.log.gz"
    shutil.copy(REPO_DATA / LOGS_SUBDIR / "csail-corrected.head400.log.gz", log)
    monkeypatch.chdir(tmp_path)
    base = ["--maps", "", "--no-plots", "--sizes", "2", "--counts", "20"]
    runs = [(str(log), tmp_path / "r_abs"), ("some/dir/intel.log.gz", tmp_path / "r_rel")]
    for given, out in runs:
        assert main(["evaluate", str(out), *base, "--logs", given]) == 0, capsys.readouterr().err
        assert (out / "map_intel.png").is_file()
        assert f"intel ({given})" in (out / "report.md").read_text()
    monkeypatch.chdir(elsewhere)
    out = tmp_path / "r_here"
    assert main(["evaluate", str(out), *base, "--logs", "intel.log.gz"]) == 0
    assert (out / "map_intel.png").is_file()
    capsys.readouterr()
    (elsewhere / "notes.log").write_text("hello\n")
    for given, problem in (
        (str(elsewhere / "gone.log"), "no such file"),
        ("gone.log", "no such file, here, and no data folder to look in"),
        ("notes.log", "no FLASER scan found"),
        (str(elsewhere), "not a regular file"),
    ):
        out = tmp_path / "r_bad"
        assert main(["evaluate", str(out), *base, "--logs", given]) == 1
        err = capsys.readouterr().err
        assert err.startswith(f"error: {given}: ") and problem in err, err
        assert len(err.splitlines()) == 1 and "experiment" not in err
        assert not out.exists()
    # Two logs of one name would write each other's map: a usage error.
    with pytest.raises(SystemExit) as info:
        main(["evaluate", str(out), *base, "--logs", f"intel,{log}"])
    assert info.value.code == 2
    assert "two logs named 'intel'" in capsys.readouterr().err
    # A log named x@1.0 and x's map at drift 1.0 were one map (map_x_drift1.0.png): refused.
    shutil.copy(log, drifted_name := elsewhere / "intel@1.0.log.gz")
    with pytest.raises(SystemExit) as info:
        main(["evaluate", str(out), *base, "--logs", f"{log},{drifted_name}"])
    assert info.value.code == 2 and "'@' names a log's drifted maps" in capsys.readouterr().err
    assert not out.exists()
    config = config_from_args(build_parser().parse_args(["evaluate", "o", "--logs", f"aces,{log}"]))
    assert config.logs == ("aces", "intel") and config.log_files == (("intel", log),)
    assert config.data_logs == ("aces",) and config.log_path("intel") == log
    # One file by an absolute and a relative path (here: the current folder) is one log, run once.
    twice = f"{log},intel.log.gz"
    config = config_from_args(build_parser().parse_args(["evaluate", "o", "--logs", twice]))
    assert config.log_files == (("intel", log),)


def test_help_says_logs_takes_paths(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "paths to CARMEN logs anywhere" in help_text


def test_a_log_named_with_a_space_gets_a_working_link_and_its_report_is_replaceable(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A log named `my log.log`: the report linked `(map_my log.png)`, which Markdown ends at the
    space, and `--force` refused the report it wrote itself ("a directory this command did not
    write"): its map's name was no report file's."""
    monkeypatch.setenv("ROSE_DATA_DIR", str(tmp_path / "nope"))  # no data set needed
    log = tmp_path / "my log (2).log.gz"
    shutil.copy(REPO_DATA / LOGS_SUBDIR / "csail-corrected.head400.log.gz", log)
    out = tmp_path / "report"
    argv = ["evaluate", str(out), "--maps", "", "--no-plots", "--sizes", "2", "--counts", "20"]
    argv += ["--logs", str(log)]
    assert main(argv) == 0
    assert (out / "map_my log (2).png").is_file()
    text = (out / "report.md").read_text()
    assert "[map_my log (2).png](map_my%20log%20%282%29.png)" in text
    assert main([*argv, "--force"]) == 0


def test_the_report_says_experiment_4_does_not_derive_its_seeds_from_seed(tmp_path: Path) -> None:
    """The setup said every drifted trajectory derives its seed from --seed; experiment 4's sessions
    are drifted with the seeds 0 .. --break-seeds - 1 whatever it is."""
    import csv

    out = tmp_path / "report"
    argv = ["evaluate", str(out), "--maps-dir", str(REPO_DATA), "--maps", "", "--no-plots"]
    argv += ["--logs", "csail-corrected.head400.log.gz", "--sizes", "2", "--counts", "20"]
    assert main([*argv, "--break-seeds", "1", "--seed", "7"]) == 0
    with (out / "exp4_breaks_sessions.csv").open() as fh:
        assert {row["seed"] for row in csv.DictReader(fh)} == {"0"}
    setup = next(line for line in (out / "report.md").open() if line.startswith("- Seed: 7 "))
    assert "experiment 4 drifts with the seeds 0, 1, ..." in setup


def test_a_log_or_report_folder_in_a_symlink_loop_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--logs ./loop` and a report folder that is a symlink loop were RuntimeError tracebacks
    ("Symlink loop from ..."): one line each, nothing written."""
    monkeypatch.setenv("ROSE_DATA_DIR", str(tmp_path / "nope"))  # no data set needed
    monkeypatch.chdir(tmp_path)
    Path("loop").symlink_to("loop2")
    Path("loop2").symlink_to("loop")
    for argv, problem in (
        (["evaluate", "report", "--maps", "", "--logs", "./loop"], "loop: cannot read"),
        (["evaluate", "loop", "--maps", "", "--logs", ""], "loop: not a usable output path"),
    ):
        assert main(argv) == 1
        (line,) = [x for x in capsys.readouterr().err.splitlines() if not x.startswith("warning")]
        assert line.startswith(f"error: {problem}"), line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["loop", "loop2"]
