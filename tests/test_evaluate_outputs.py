"""``rose-bag evaluate``'s figures: a PNG that cannot be written fails the run, ``--no-plots`` writes none.

The runs use the repository's test data without logs (one benchmark map, one clutter setting):
seconds each.
"""

from __future__ import annotations

import errno
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from real_data import REPO_DATA

from rose_logs.cli import main
from rose_logs.evaluation.cleaning import bormann_cases
from rose_logs.evaluation.cleaning_report import cleaning_figure
from rose_logs.evaluation.config import BENCHMARK_SUBDIR
from rose_logs.evaluation.files import ReportWriteError, write_png

#: No logs (no rasterised maps, no drift experiment): the quickest run that still writes figures.
QUICK = [
    "--maps-dir",
    str(REPO_DATA),
    "--logs",
    "",
    "--maps",
    "Freiburg79_scan",
    "--sizes",
    "4",
    "--counts",
    "20",
]


def _no_report_left(folder: Path, out: Path) -> None:
    assert not out.exists()
    assert not [p.name for p in folder.iterdir() if ".rose-" in p.name]  # no staging folder either


def test_an_unwritable_picture_is_a_one_line_error_and_no_report(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # OpenCV fails the way it does on a full disk: no exception, only a False. Whichever of its
    # calls writes the PNG, the run must notice (it used to report success and link a missing file).
    import cv2

    monkeypatch.setattr(cv2, "imwrite", lambda *args, **kwargs: False)
    monkeypatch.setattr(cv2, "imencode", lambda *args, **kwargs: (False, None))
    out = tmp_path / "report"
    assert main(["evaluate", str(out), *QUICK]) == 1
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    errors = [line for line in lines if line.startswith("error:")]
    # Named as the user asked for it, not inside the (removed) temporary folder.
    assert errors == [
        f"error: {out / 'cleaning_before_after.png'}: cannot write (cannot encode the image)"
    ]
    assert "report done" not in captured.err
    assert "Traceback" not in captured.err
    assert captured.out == ""  # no report path printed
    _no_report_left(tmp_path, out)


@pytest.mark.skipif(sys.platform == "win32", reason="needs POSIX resource limits")
def test_a_full_disk_while_writing_figures_is_a_one_line_error_with_the_os_reason(
    tmp_path: Path,
) -> None:
    # A file-size limit makes the first PNG (tens of kB) fail for real, as a full disk does, while
    # the CSV tables (under 1 kB) still fit. Before: "libpng error: Write Error", exit 0, a report
    # linking a missing image (or, for a matplotlib figure, an error naming no file).
    import resource

    def limit_file_size() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, resource.RLIM_INFINITY))

    out = tmp_path / "report"
    done = subprocess.run(
        [sys.executable, "-m", "rose_logs.cli", "evaluate", str(out), *QUICK],
        capture_output=True,
        text=True,
        preexec_fn=limit_file_size,  # the limit is the child's only
        timeout=300,
        check=False,
    )
    assert done.returncode == 1, done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    reason = os.strerror(errno.EFBIG)
    assert len(errors) == 1, done.stderr
    assert re.fullmatch(
        rf"error: {re.escape(str(out))}/[\w.-]+\.png: cannot write \({re.escape(reason)}\)",
        errors[0],
    ), errors[0]
    assert "libpng" not in done.stderr
    assert "Traceback" not in done.stderr
    assert done.stdout == ""
    _no_report_left(tmp_path, out)


def test_a_picture_that_cannot_be_written_raises_naming_the_file(tmp_path: Path) -> None:
    case = bormann_cases(REPO_DATA / BENCHMARK_SUBDIR, names=["Freiburg79_scan"])[0]
    path = tmp_path / "missing-folder" / "cleaning_before_after.png"
    with pytest.raises(ReportWriteError) as info:
        cleaning_figure(case, path)
    assert str(info.value) == f"{path}: cannot write ({os.strerror(errno.ENOENT)})"
    assert info.value.path == path


def test_write_png_writes_a_readable_png(tmp_path: Path) -> None:
    import cv2

    image = np.arange(12, dtype=np.uint8).reshape(3, 4)
    path = write_png(tmp_path / "a.png", image)
    assert np.array_equal(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), image)


def test_tables_of_the_report_that_cannot_be_written_name_their_file(tmp_path: Path) -> None:
    """A CSV or the markdown on a full disk raised an OSError without a file name: "error: No space
    left on device"."""
    import csv

    from rose_logs.evaluation.files import text_file

    path = tmp_path / "missing-folder" / "runs.csv"
    with pytest.raises(ReportWriteError) as info, text_file(path) as fh:
        csv.writer(fh).writerow(["a", "b"])
    assert str(info.value) == f"{path}: cannot write ({os.strerror(errno.ENOENT)})"
    ok = tmp_path / "runs.csv"
    with text_file(ok) as fh:
        csv.writer(fh).writerow(["a", "b"])
    assert ok.read_bytes() == b"a,b\r\n"  # as csv writes through open(path, "w", newline="")


def test_no_plots_writes_no_figure_and_links_only_written_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # --help promises no figures; wall_error.png and cleaning_before_after.png used to be written.
    out = tmp_path / "report"
    assert main(["evaluate", str(out), *QUICK, "--no-plots"]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in out.glob("*.png")) == []
    markdown = (out / "report.md").read_text()
    links = re.findall(r"\]\(([^)]+)\)", markdown)
    assert [link for link in links if not (out / link).is_file()] == []
    assert "The plots were not drawn" in markdown
    assert (out / "wall_error.csv").is_file()  # the tables are still there
    assert (out / "cleaning_runs.csv").is_file()


def test_help_says_which_pictures_no_plots_keeps(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "wall_error.png" in help_text
    assert "cleaning_before_after.png" in help_text
    assert "map_*.png are data and still written" in help_text


def test_a_report_folder_inside_a_ros2_bag_folder_is_refused_before_any_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`evaluate SOMEBAG/report` (or `SOMEBAG/new/report`, whose `new` it made) wrote the report
    into the recording, which `process` and `rose clean` refuse for their outputs."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    for out in (bag / "report", bag / "new" / "report"):
        assert main(["evaluate", str(out), *QUICK, "--no-plots"]) == 1
        err = capsys.readouterr().err
        assert err == (
            f"error: {out}: the report folder is inside the ROS 2 bag folder {bag} (it has "
            "metadata.yaml): it would write into a recording; choose another OUT_DIR\n"
        )
        assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml"]


#: The measured times, the only part of a report that differs between two runs (README).
TIMING_COLUMNS = {"rose_s", "build_s", "analyze_s", "clean_s", "time_ratio", "seconds"}


def _without_times(path: Path) -> list[list[str]]:
    """A report file's rows with the measured times blanked: CSV columns by name, the markdown's
    run-time line, the cleaning table's last cell and experiment 4's cost line."""
    import csv

    text = path.read_text(encoding="utf-8")
    if path.suffix == ".csv":
        rows = list(csv.reader(text.splitlines()))
        timed = {k for k, name in enumerate(rows[0] if rows else []) if name in TIMING_COLUMNS}
        return [["-" if k in timed else v for k, v in enumerate(row)] for row in rows]
    lines = []
    for line in text.splitlines():
        if line.startswith(("- Run time:", "Cost (CPU time")):
            line = "-"
        elif line.startswith("| ") and line.endswith(") |") and "time" not in line:
            line = line.rsplit("|", 2)[0]  # a cleaning row: median (worst) time ratio last
        lines.append([line])
    return lines


def test_two_runs_write_the_same_report_but_for_the_measured_times(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    first, second = tmp_path / "a", tmp_path / "b"
    assert main(["evaluate", str(first), *QUICK]) == 0
    assert main(["evaluate", str(second), *QUICK]) == 0
    capsys.readouterr()
    names = sorted(p.name for p in first.iterdir())
    assert names == sorted(p.name for p in second.iterdir())
    for name in names:
        if name.endswith(".png"):  # figures hold no time
            assert (first / name).read_bytes() == (second / name).read_bytes(), name
        else:
            assert _without_times(first / name) == _without_times(second / name), name


def test_without_matplotlib_one_warning_says_no_plots(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Only the wall plot said it was left out; the experiments' figures went silently.
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` raises ImportError
    out = tmp_path / "report"
    assert main(["evaluate", str(out), *QUICK]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "matplotlib" in line]
    assert warnings == [
        "warning: matplotlib is not installed (the plots extra): no plots; the cleaning picture "
        "and the rasterised maps are still drawn"
    ]
    assert sorted(p.name for p in out.glob("*.png")) == ["cleaning_before_after.png"]


def test_the_file_list_names_every_table_written_and_no_map_image_without_a_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # wall_error.csv and cleaning_runs.csv were missing from "## Files"; map_*.png was listed by a
    # run without a log, which writes none.
    out = tmp_path / "report"
    assert main(["evaluate", str(out), *QUICK, "--no-plots"]) == 0
    capsys.readouterr()
    listed = (out / "report.md").read_text().split("## Files", 1)[1]
    named = set(re.findall(r"`([^`]+)`", listed))
    assert named == {p.name for p in out.glob("*.csv")}


@pytest.mark.parametrize(
    ("options", "said"),
    [
        (["--no-plots"], "The plots were not drawn (`--no-plots`), nor the cleaning picture."),
        ([], None),  # nothing to plot: it said "`--no-plots` or matplotlib missing"
    ],
)
def test_the_report_says_why_there_is_no_plot_only_when_it_is_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: list[str], said: str | None
) -> None:
    out = tmp_path / "report"
    argv = ["evaluate", str(out), "--maps-dir", str(REPO_DATA), "--logs", "", "--maps", ""]
    assert main([*argv, *options]) == 0
    capsys.readouterr()
    lines = [ln for ln in (out / "report.md").read_text().splitlines() if "not drawn" in ln]
    assert lines == ([said] if said else [])
