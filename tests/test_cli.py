"""The ``rose`` command: outputs, summaries and one-line errors."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
from pathlib import Path

import numpy as np
import pytest
from synthetic import add_clutter, floor_plan

import rose
from rose.cli import main


@pytest.fixture
def cluttered_map(tmp_path: Path) -> Path:
    cluttered, _ = add_clutter(floor_plan(angle_deg=15.0), blobs=30, specks=200, seed=1)
    grid = np.where(cluttered, 100, 0).astype(np.int8)
    path = tmp_path / "in.yaml"
    rose.save_map(path, rose.OccupancyMap(grid=grid, resolution_m=0.05, origin_xy_m=(-1.0, -2.0)))
    return path


def test_clean_writes_map_and_report(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out" / "clean.yaml"
    out.parent.mkdir()
    assert (
        main(["clean", str(cluttered_map), "-o", str(out), "--json", str(tmp_path / "r.json")]) == 0
    )
    cleaned = rose.load_map(out)
    source = rose.load_map(cluttered_map)
    expected = rose.clean(source.grid, resolution_m=source.resolution_m).cleaned
    np.testing.assert_array_equal(cleaned.grid, expected)
    assert cleaned.origin_xy_m == (-1.0, -2.0)
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["clutter_cells"] > 0
    assert report["method"] == "walls"
    assert report["removed_cells"] > 0
    assert report["kept_cells"] + report["removed_cells"] == report["occupied_cells"]
    assert len(report["dominant_directions_deg"]) == 2
    printed = capsys.readouterr().out
    assert "W " in printed and "directions" in printed and "removed" in printed


def test_clean_gives_no_verdict_on_a_few_occupied_cells(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 16-cell map read "structured: decluttering can be trusted"; rose-bag leaves maps of fewer
    than 20 occupied cells out of W's judgement, and so does rose now."""
    grid = np.zeros((40, 40), dtype=np.int8)
    grid[10, 10:26] = 100
    few = tmp_path / "few.yaml"
    rose.save_map(few, rose.OccupancyMap(grid=grid, resolution_m=0.05))
    assert main(["clean", str(few), "-o", str(tmp_path / "c1.yaml")]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("W "))
    assert "only 16 occupied cells (fewer than 20): W says nothing about this map" in line
    assert main(["clean", str(cluttered_map), "-o", str(tmp_path / "c2.yaml")]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("W "))
    assert "says nothing" not in line


@pytest.mark.parametrize(
    ("grid", "caveat"),
    [
        # Every cell occupied: the spectrum is the grid's rectangle (W 0.016).
        (np.full((40, 50), 100, np.int8), "occupied cells fill the grid (180 cell sides on its "),
        # A strip one cell wide: no 2D spectrum to tell directions apart (W 0.007).
        (np.full((1, 300), 100, np.int8), "a side of 1 cell (fewer than 16, too thin for a 2D "),
        (np.full((300, 1), 100, np.int8), "a side of 1 cell (fewer than 16, too thin for a 2D "),
        # A solid block amid unknown cells: no free space, the outline of a blob (W 0.090).
        (np.pad(np.full((40, 50), 100, np.int8), 30, constant_values=-1), "only 0 free cells "),
    ],
)
def test_clean_gives_no_verdict_on_a_degenerate_map(
    grid: np.ndarray, caveat: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A solid map or a 1 x 300 strip read "structured: decluttering can be trusted": outside
    ROSE's domain (README), their low W says nothing about a building."""
    path = tmp_path / "m.yaml"
    rose.save_map(path, rose.OccupancyMap(grid=grid, resolution_m=0.05))
    assert main(["clean", str(path), "-o", str(tmp_path / "c.yaml")]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("W "))
    assert caveat in line and line.endswith(": W says nothing about this map)"), line
    assert "trusted" not in line


def test_score_does_not_claim_structure_in_a_degenerate_map(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A solid block read `"has_structure": true` (its rectangle's direction) and a plain table row
    whose low W passed for a building's: as `rose clean` and rose-bag's records, its `degenerate`
    says why W says nothing, and `has_structure` is not judged (null). A map with no direction at
    all keeps `false`. A map of a few occupied cells is not judged either (as `rose clean` says),
    and an all-unknown map is no degenerate input (its reason read "only 0 free cells")."""
    block, blank, few = (tmp_path / f"{n}.yaml" for n in ("block", "blank", "few"))
    rose.save_map(block, rose.OccupancyMap(grid=np.full((40, 50), 100, np.int8), resolution_m=0.05))
    rose.save_map(blank, rose.OccupancyMap(grid=np.full((40, 50), -1, np.int8), resolution_m=0.05))
    sparse = np.zeros((40, 50), np.int8)
    sparse[20, 10:15] = 100
    rose.save_map(few, rose.OccupancyMap(grid=sparse, resolution_m=0.05))
    assert main(["score", "--json", str(block), str(blank), str(few)]) == 0
    solid, unknown, five = json.loads(capsys.readouterr().out)
    assert solid["has_structure"] is None and solid["dominant_directions_deg"] == [0.0]
    assert solid["degenerate"].startswith("occupied cells fill the grid (180 cell sides")
    assert unknown["has_structure"] is False and unknown["degenerate"] is None
    assert five["has_structure"] is None and five["degenerate"] is None
    assert main(["clean", str(block), "-o", str(tmp_path / "c.yaml"), "--json", "-"]) == 0
    cleaned = json.loads(capsys.readouterr().out)  # the summary went to stderr
    assert cleaned["has_structure"] is None and cleaned["degenerate"] == solid["degenerate"]
    assert main(["score", str(block), str(blank), str(few)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[1][-1] for line in lines[1:4]] == ["*"] * 3  # W marked in every row
    assert lines[-3:] == [
        f"* {block}: {solid['degenerate']}: W says nothing about this map",
        f"* {blank}: no occupied cells: W says nothing about this map",
        f"* {few}: only 5 occupied cells (fewer than 20): W says nothing about this map",
    ]


def test_the_note_under_the_table_gives_the_reason_the_json_gives(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 10 x 10 map of 5 occupied cells is outside ROSE's domain (a side under 16 cells) and has
    fewer than 20 occupied cells: the table's note said the count, the JSON's `degenerate` the
    side. The note now gives the cause first, as the JSON; inside the domain it gives the count."""
    paths = []
    for side in (10, 40):
        grid = np.zeros((side, side), np.int8)
        grid[4, 2:7] = 100
        paths.append(tmp_path / f"m{side}.yaml")
        rose.save_map(paths[-1], rose.OccupancyMap(grid=grid, resolution_m=0.05))
    assert main(["score", "--json", *map(str, paths)]) == 0
    small, _ = json.loads(capsys.readouterr().out)
    assert main(["score", *map(str, paths)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-2:] == [
        f"* {paths[0]}: {small['degenerate']}: W says nothing about this map",
        f"* {paths[1]}: only 5 occupied cells (fewer than 20): W says nothing about this map",
    ]
    assert small["degenerate"].startswith("a side of 10 cells")


@pytest.mark.parametrize(
    ("grid", "caveat"),
    [
        (np.full((40, 50), 100, np.int8), "occupied cells fill the grid (180 cell sides on its "),
        (np.full((1, 300), 100, np.int8), "a side of 1 cell (fewer than 16, too thin for a 2D "),
        (np.pad(np.full((40, 50), 100, np.int8), 30, constant_values=-1), "only 0 free cells "),
        (np.full((40, 50), -1, np.int8), "no occupied cells"),
    ],
)
def test_walls_says_when_the_map_is_outside_roses_domain(
    grid: np.ndarray, caveat: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`rose walls` on a solid block printed its rectangle as four walls, and nothing else:
    `rose clean` and `rose score` say W says nothing about such a map, and so does `walls` now,
    under its table (not on a building's map, nor for the Hough baseline, which uses no W)."""
    path = tmp_path / "m.yaml"
    rose.save_map(path, rose.OccupancyMap(grid=grid, resolution_m=0.05))
    assert main(["walls", str(path)]) == 0
    last = capsys.readouterr().out.splitlines()[-1]
    assert last.startswith(f"note: {path}: {caveat}"), last
    assert last.endswith(": W says nothing about this map"), last
    assert main(["walls", str(path), "--hough"]) == 0
    assert "note:" not in capsys.readouterr().out
    building = Path(__file__).parent / "data/rose2_aislabunimi/Freiburg_Building_079_partial"
    assert main(["walls", str(building / "map15.yaml")]) == 0
    assert "note:" not in capsys.readouterr().out


def test_the_real_maps_get_no_degenerate_input_caveat() -> None:
    """The caveat must not fall on a real map: every map of tests/data, the snapshots of the sample
    session, and a drawn map whose outside is occupied (lab_ipa, 82 % of its cells)."""
    from real_data import REPO_DATA

    from rose.directions import degenerate_input
    from rose_logs.reader import LogReader
    from rose_logs.snapshots import decode_map

    images = sorted(REPO_DATA.rglob("*.png"))
    grids = [rose.load_map(p).grid for p in sorted(REPO_DATA.rglob("*.yaml"))]
    grids += [rose.load_map(p).grid for p in images if not p.with_suffix(".yaml").exists()]
    sample = Path(__file__).resolve().parents[1] / "sample_data" / "fr079_session.mcap"
    with LogReader(sample) as reader:
        grids += [
            decode_map(m.data, serialization=reader.serialization, topic="/map", log_time_ns=0).grid
            for m in reader.messages(topics={"/map"})
        ]
    assert len(grids) == 37
    threshold = rose.RoseParams().occupied_threshold
    caveats = [degenerate_input(g, g >= threshold) for g in grids]
    assert caveats == [None] * len(grids)


def test_clean_to_a_symlinked_yaml_checks_the_image_it_will_write(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The image goes beside the link's target (save_map): the early check looked beside the link
    and refused a stale file there that this run would never write."""
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "real.yaml").write_text("x")
    link = tmp_path / "lnk.yaml"
    link.symlink_to("sub/real.yaml")
    (tmp_path / "lnk.pgm").write_text("stale, not ours")
    assert main(["clean", str(cluttered_map), "-o", str(link), "--force"]) == 0
    assert (
        rose.load_map(tmp_path / "sub" / "real.yaml").grid.shape
        == rose.load_map(cluttered_map).grid.shape
    )
    assert (tmp_path / "lnk.pgm").read_text() == "stale, not ours"


def test_main_in_process_leaves_the_callers_signal_handlers(
    cluttered_map: Path, tmp_path: Path
) -> None:
    """Run from a notebook or a test, the command must not leave its own SIGTERM / SIGHUP handlers
    behind."""
    names = ("SIGINT", "SIGTERM", "SIGHUP")
    before = {name: signal.getsignal(getattr(signal, name)) for name in names}
    assert main(["clean", str(cluttered_map), "-o", str(tmp_path / "clean.yaml")]) == 0
    assert {name: signal.getsignal(getattr(signal, name)) for name in names} == before


def test_main_in_process_twice_says_each_runs_warnings_on_its_own_stderr(tmp_path: Path) -> None:
    """The first run's logging handler stayed on the root logger: the second run's warnings went
    to the first run's stream, named after its input."""
    import contextlib
    import io
    import logging

    from rose_logs.cli import main as rose_bag_main

    source = Path(__file__).parent / "data" / "rose2_aislabunimi" / "Freiburg_Building_079_partial"
    (tmp_path / "map15.png").write_bytes((source / "map15.png").read_bytes())
    for name in ("a", "b"):  # no negate / thresholds: a warning naming the file
        (tmp_path / f"{name}.yaml").write_text(
            "image: map15.png\nresolution: 0.05\norigin: [0, 0, 0]\n"
        )
    loggers = [logging.getLogger(name) for name in ("", "rose", "rose_logs")]
    before = [(lg.handlers[:], lg.level, lg.propagate) for lg in loggers]
    said = {}
    for name in ("a", "b"):
        said[name] = io.StringIO()
        with contextlib.redirect_stderr(said[name]), contextlib.redirect_stdout(io.StringIO()):
            assert main(["score", str(tmp_path / f"{name}.yaml")]) == 0
    for name in ("a", "b"):
        assert said[name].getvalue().count("warning:") == 1
        assert f"{name}.yaml: no negate" in said[name].getvalue()
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        assert rose_bag_main(["info", str(source / "map15.yaml")]) != 0
    assert [(lg.handlers[:], lg.level, lg.propagate) for lg in loggers] == before


def test_clean_method_paper_is_the_papers_labelling(cluttered_map: Path, tmp_path: Path) -> None:
    paper, walls = tmp_path / "paper.yaml", tmp_path / "walls.yaml"
    assert main(["clean", str(cluttered_map), "-o", str(paper), "--method", "paper"]) == 0
    assert main(["clean", str(cluttered_map), "-o", str(walls), "--method", "walls"]) == 0
    grid = rose.load_map(cluttered_map).grid
    np.testing.assert_array_equal(rose.load_map(paper).grid, rose.analyze(grid).cleaned)
    # The default is the walls cleaning, not the paper's labelling.
    walls_grid = rose.load_map(walls).grid
    np.testing.assert_array_equal(walls_grid, rose.clean(grid, resolution_m=0.05).cleaned)
    assert not np.array_equal(walls_grid, rose.load_map(paper).grid)
    # rose-bag process's spelling of the option works here too.
    again = tmp_path / "again.yaml"
    assert main(["clean", str(cluttered_map), "-o", str(again), "--clean-method", "paper"]) == 0
    np.testing.assert_array_equal(rose.load_map(again).grid, rose.load_map(paper).grid)
    with pytest.raises(SystemExit) as exit_info:
        main(["clean", str(cluttered_map), "-o", str(paper), "--method", "tidy"])
    assert exit_info.value.code == 2


def test_clean_parameters_reach_the_algorithm(cluttered_map: Path, tmp_path: Path) -> None:
    out = tmp_path / "unknown.yaml"
    assert main(["clean", str(cluttered_map), "-o", str(out), "--clutter-value", "unknown"]) == 0
    original = rose.load_map(cluttered_map).grid
    cleaned = rose.load_map(out).grid
    removed = (original == 100) & (cleaned != 100)
    assert removed.any() and np.all(cleaned[removed] == -1)


def test_score_prints_a_table_and_json(
    cluttered_map: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["score", str(cluttered_map)]) == 0
    assert str(cluttered_map) in capsys.readouterr().out
    assert main(["score", "--json", str(cluttered_map)]) == 0
    records = json.loads(capsys.readouterr().out)
    assert records[0]["structure_score"] < 0.2


def test_score_scores_every_good_map_and_reports_the_bad_ones(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`rose score maps/*.yaml` must not lose the table to one bad file: rows for the good maps, one
    error line per bad one, exit 1; in JSON the bad map is a record with its error."""
    missing = tmp_path / "missing.yaml"
    assert main(["score", str(missing), str(cluttered_map)]) == 1
    captured = capsys.readouterr()
    assert str(cluttered_map) in captured.out and str(missing) not in captured.out
    errors = captured.err.strip().splitlines()
    assert errors[0].startswith(f"error: {missing}: ")
    assert errors[-1] == "error: 1 of 2 maps could not be scored"
    assert main(["score", "--json", str(cluttered_map), str(missing)]) == 1
    captured = capsys.readouterr()
    records = json.loads(captured.out)
    # The count as without --json (the README's "a last one counting them").
    assert captured.err.strip().splitlines()[-1] == "error: 1 of 2 maps could not be scored"
    assert [r["map"] for r in records] == [str(cluttered_map), str(missing)]
    assert "structure_score" in records[0] and "error" not in records[0]
    assert records[1]["error"].startswith(f"{missing}: ")


def test_names_with_newlines_and_tabs_keep_the_tables_and_summaries_one_line_each(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A map file named with a newline or a tab (valid names) printed raw broke `rose score`'s
    table into extra rows and `rose clean`'s summary and warnings into extra lines: such names
    are printed escaped (``\\n``, ``\\t``), as the error lines and `rose-bag info` print them."""
    image = cluttered_map.with_suffix(".pgm")
    odd = tmp_path / "nl\nx.pgm"
    tabbed = tmp_path / "tab\tb.pgm"
    odd.write_bytes(image.read_bytes())
    tabbed.write_bytes(image.read_bytes())
    assert main(["score", str(odd), str(tabbed)]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert len(rows) == 3 and rows[0].startswith("map ")
    assert rows[1].startswith(f"{tmp_path}/nl\\nx.pgm ")
    assert rows[2].startswith(f"{tmp_path}/tab\\tb.pgm ")
    out = tmp_path / "o\nut.yaml"
    report = tmp_path / "r\n.txt"
    assert main(["clean", str(odd), "-o", str(out), "--json", str(report)]) == 0
    captured = capsys.readouterr()
    labels = ("map ", "W ", "directions ", "threshold ", "occupied ", "method ", "removed ")
    labels += ("kept ", "completed ", "written ", "time ")
    assert [line.split(" ")[0] + " " for line in captured.out.splitlines()] == list(labels)
    assert "nl\\nx.pgm" in captured.out and "o\\nut.yaml + o\\nut.pgm + " in captured.out
    warnings = captured.err.splitlines()
    assert len(warnings) == 2 and all(w.startswith("warning: ") for w in warnings)
    assert out.is_file()  # the file itself under its real name


def test_a_name_that_is_not_utf8_is_printed_as_its_bytes(
    cluttered_map: Path, tmp_path: Path, capsysbinary: pytest.CaptureFixture[bytes]
) -> None:
    """The table escapes names that do not print, but a name that is not UTF-8 is printed as its
    bytes on standard output (the README), not as the \\udcXX escapes of the error lines."""
    undecodable = tmp_path / os.fsdecode(b"r\xffx.pgm")
    undecodable.write_bytes(cluttered_map.with_suffix(".pgm").read_bytes())
    assert main(["score", str(undecodable)]) == 0
    assert os.fsencode(tmp_path) + b"/r\xffx.pgm " in capsysbinary.readouterr().out


def test_directions_are_reported_in_the_map_frame(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A map whose origin is rotated has its walls that much further round in the map frame, where
    `rose walls` reports them too."""
    source = rose.load_map(cluttered_map)
    turned = tmp_path / "turned.yaml"
    rose.save_map(turned, dataclasses.replace(source, origin_yaw_rad=0.5))
    assert main(["score", "--json", str(cluttered_map), str(turned)]) == 0
    plain, rotated = (r["dominant_directions_deg"] for r in json.loads(capsys.readouterr().out))
    expected = sorted((d + np.degrees(0.5)) % 180 for d in plain)
    np.testing.assert_allclose(sorted(rotated), expected, atol=0.011)
    assert main(["walls", str(turned)]) == 0
    angles = [float(line.split()[-1]) for line in capsys.readouterr().out.splitlines()[2:]]
    # Walls of the rotated floor plan lie along the reported directions (within a degree).
    assert angles and all(
        min(abs((a - d + 90) % 180 - 90) for d in rotated) < 1.0 for a in angles
    ), (angles, rotated)


def test_a_bare_image_takes_its_resolution_from_the_option(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A bare image has no resolution: without --resolution the default is said, with it the output
    YAML and every metre-based rule use it; a YAML map keeps its own."""
    image = rose.load_map(cluttered_map).image_path
    report = tmp_path / "a.json"
    assert main(["clean", str(image), "-o", str(tmp_path / "a.yaml"), "--json", str(report)]) == 0
    assert "no map YAML, assuming 0.05 m/cell" in capsys.readouterr().err
    assert rose.load_map(tmp_path / "a.yaml").resolution_m == pytest.approx(0.05)
    # ... and the report says the cell size was assumed (the rules' lengths are metres).
    assert json.loads(report.read_text())["resolution_assumed"] is True
    argv = ["clean", str(image), "-o", str(tmp_path / "b.yaml"), "--resolution", "0.1"]
    assert main([*argv, "--json", str(report), "--force"]) == 0
    said = capsys.readouterr()
    assert "warning" not in said.err
    summary = json.loads(report.read_text())
    assert summary["resolution_m"] == 0.1 and summary["resolution_assumed"] is False
    # 0.1 m cells are twice the rules' design size: cleaned on the cells split in 2 x 2.
    assert summary["rules_cell_m"] == 0.05
    assert "split in 2 x 2" in said.out
    # 0.025 m cells are half of it: cleaned on the cells joined in 2 x 2.
    argv = ["clean", str(image), "-o", str(tmp_path / "f.yaml"), "--resolution", "0.025"]
    assert main([*argv, "--json", str(report), "--force"]) == 0
    assert json.loads(report.read_text())["rules_cell_m"] == 0.05
    assert "joined in 2 x 2" in capsys.readouterr().out
    assert rose.load_map(tmp_path / "b.yaml").resolution_m == pytest.approx(0.1)
    # The cleaning's lengths are metres: at 0.1 m per cell it keeps another set of cells.
    a, b = (rose.load_map(tmp_path / n).grid for n in ("a.yaml", "b.yaml"))
    assert not np.array_equal(a, b)
    assert (
        main(["clean", str(cluttered_map), "-o", str(tmp_path / "c.yaml"), "--resolution", "1"])
        == 1
    )
    assert "--resolution is for bare images" in capsys.readouterr().err
    # Beyond what a map file may declare is a usage error before any work (1e300 overflowed inside
    # the cleaning; 1e5 ran it all, then failed to save).
    for huge in ("1e300", "1e5"):
        with pytest.raises(SystemExit) as stop:
            main(["clean", str(image), "-o", str(tmp_path / "d.yaml"), "--resolution", huge])
        assert stop.value.code == 2
        assert "up to 10000" in capsys.readouterr().err
    assert not (tmp_path / "d.yaml").exists()
    # W does not depend on the resolution: rose score neither takes nor warns about one.
    assert main(["score", str(image)]) == 0
    assert "warning" not in capsys.readouterr().err


def test_clean_reports_the_unknown_cells_it_made_walls(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Cells the cleaning adds (a wall line hidden behind removed furniture) are counted, so removed,
    kept and completed add up to what the output holds."""
    # A real SLAM map (Freiburg 079, last exploration stage): clutter in front of walls.
    path = Path(__file__).parent / "data/rose2_aislabunimi/Freiburg_Building_079_partial/map15.yaml"
    out = tmp_path / "c.yaml"
    assert main(["clean", str(path), "-o", str(out), "--json", str(tmp_path / "r.json")]) == 0
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["completed_cells"] > 0
    assert f"completed    {report['completed_cells']} " in capsys.readouterr().out
    cleaned = rose.load_map(out).grid
    occupied_out = int(np.count_nonzero(cleaned >= 65))
    assert occupied_out == report["kept_cells"] + report["completed_cells"]


def test_a_map_without_occupied_cells_gets_no_verdict_on_w(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """W = 1 by convention for an empty map: not "decluttering has likely failed"."""
    path = tmp_path / "empty.yaml"
    rose.save_map(path, rose.OccupancyMap(grid=np.full((20, 20), -1, np.int8), resolution_m=0.05))
    assert main(["clean", str(path), "-o", str(tmp_path / "c.yaml")]) == 0
    out = capsys.readouterr().out
    assert "no occupied cells" in out and "failed" not in out


def test_library_warnings_print_like_the_commands_own(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`warning: ...`, lower case, as everywhere else (Python's default says `WARNING:`), naming
    the map (it said "ROSE found no dominant direction" without saying which map)."""
    import logging

    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    root.handlers = []  # as in a fresh process: the command sets its own
    try:
        grid = np.zeros((40, 40), np.int8)
        grid[20, 20] = 100  # a speck: ROSE finds no dominant direction to snap walls to
        path = tmp_path / "speck.yaml"
        rose.save_map(path, rose.OccupancyMap(grid=grid, resolution_m=0.05))
        main(["walls", str(path)])
    finally:
        root.handlers, root.level = handlers, level
    err = capsys.readouterr().err
    assert f"warning: {path}: ROSE found no dominant direction" in err, err
    assert "WARNING" not in err


@pytest.mark.parametrize(
    "make_args",
    [
        lambda d, m: ["clean", str(d / "missing.yaml"), "-o", str(d / "o.yaml")],
        lambda d, m: ["clean", str(m), "-o", str(d / "no" / "dir" / "o.yaml")],
        lambda d, m: ["clean", str(m), "-o", str(m)],
        lambda d, m: ["clean", str(m), "-o", str(d / "o.txt")],
        lambda d, m: ["score", str(d / "junk.png")],
    ],
    ids=["missing-input", "missing-dir", "overwrite-input", "not-yaml", "bad-image"],
)
def test_errors_are_one_line_with_exit_1(
    make_args, cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "junk.png").write_bytes(b"junk")
    before = cluttered_map.read_bytes()
    assert main(make_args(tmp_path, cluttered_map)) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1
    assert cluttered_map.read_bytes() == before
    assert not (tmp_path / "o.yaml").exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["clean"],
        ["score", "m.yaml", "--peak-prominence", "7"],
        ["score", "m.yaml", "--smoothing", "-1"],
        ["score", "m.yaml", "--occupied-threshold", "0"],
        ["score", "m.yaml", "--seed", "-1"],
        ["score", "m.yaml", "--seed", str(2**33)],
        ["score", "m.yaml", "--max-cells", "0"],
        ["clean", "m.yaml", "-o", "o.yaml", "--fixed-threshold", "nan"],
        # A name ending in '/' is a folder: Path dropped the slash and wrote the file 'out'.
        ["clean", "m.yaml", "-o", "out/"],
        ["clean", "m.yaml", "-o", "o.yaml", "--json", "out/"],
        ["walls", "m.yaml", "--svg", "out/"],
    ],
)
def test_usage_error_exits_2(argv: list[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2


@pytest.mark.parametrize(
    "command", [["score", "-"], ["clean", "-", "-o", "o.yaml"], ["walls", "-"]]
)
def test_a_map_named_dash_is_no_standard_input(
    command: list[str],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """`rose score - < map.pgm` said `error: -: no such file`, though `-` is standard output
    for every output: now a usage error saying inputs are files. A file called '-' is read."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as info:
        main(command)
    assert info.value.code == 2
    assert capsys.readouterr().err.endswith(
        "'-': inputs are read from files, not standard input (./- names a file called '-')\n"
    )
    (tmp_path / "-").write_bytes(b"")
    assert main(command) == 1
    assert "error: -: not a readable image" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "usage"),
    [
        (["clean", "m.yaml", "-o", "o.yaml", "--bogus"], "rose clean"),
        (["score", "m.yaml", "--bogus"], "rose score"),
        (["walls", "m.yaml", "--bogus"], "rose walls"),
        (["--bogus", "score", "m.yaml"], "rose"),  # before the command: the top level's
    ],
)
def test_an_unknown_option_is_a_usage_error_of_the_parser_it_follows(
    argv: list[str], usage: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """`rose clean map.yaml --bogus` showed the top-level usage (`rose [-h] ... COMMAND ...`)."""
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usage: {usage} [-h]")
    assert err.splitlines()[-1] == f"{usage}: error: unrecognized arguments: --bogus"


@pytest.mark.parametrize(
    ("argv", "usage", "unknown"),
    [
        (["clean", "--bogus"], "rose clean", "--bogus"),
        (["clean", "-5", "-z"], "rose clean", "-z"),
        (["rose-bag", "process", "--bogus=3"], "rose-bag process", "--bogus=3"),
    ],
)
def test_an_unknown_option_is_named_even_when_a_required_argument_is_missing(
    argv: list[str], usage: str, unknown: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """argparse checks required arguments first: `rose clean --bogus` only said that map and -o
    were missing, hiding the mistyped option (a negative number is a value, not an option)."""
    from rose_logs.cli import main as rose_bag

    run, args = (rose_bag, argv[1:]) if argv[0] == "rose-bag" else (main, argv)
    with pytest.raises(SystemExit) as info:
        run(args)
    assert info.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == (
        f"{usage}: error: unrecognized arguments: {unknown}"
    )


def test_a_missing_required_argument_is_still_named_without_unknown_options(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as info:
        main(["clean", "-5", "-f"])
    assert info.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == (
        "rose clean: error: the following arguments are required: -o/--output"
    )


def test_options_are_taken_by_their_full_names_only(
    cluttered_map: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`rose score --jso m.yaml` ran as `--json`: an abbreviation that works today changes meaning
    once an option sharing its start is added."""
    from rose_logs.cli import main as rose_bag

    for run, argv in (
        (main, ["score", "--jso", str(cluttered_map)]),
        (rose_bag, ["--deb", "info", str(cluttered_map)]),
    ):
        with pytest.raises(SystemExit) as info:
            run(argv)
        assert info.value.code == 2
        assert "unrecognized arguments: --" in capsys.readouterr().err


def test_clean_warns_of_a_json_report_named_with_another_suffix(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--json report.rrd` was written silently; a report refused anyway is refused alone."""
    report = tmp_path / "report.rrd"
    argv = ["clean", str(cluttered_map), "-o", str(tmp_path / "c.yaml"), "--json", str(report)]
    assert main(argv) == 0
    said = f"warning: {report}: a JSON report written under a '.rrd' name (expected .json)\n"
    assert capsys.readouterr().err == said
    assert json.loads(report.read_text())["method"] == "walls"
    assert main([*argv[:3], str(tmp_path / "c2.yaml"), *argv[4:]]) == 1  # exists already
    err = capsys.readouterr().err
    assert err.startswith(f"error: {report}: exists already") and "warning" not in err
    for name in (str(tmp_path / "r.JSON"), "-"):
        assert main([*argv[:3], str(tmp_path / f"c{len(name)}.yaml"), "--json", name]) == 0
        assert "warning" not in capsys.readouterr().err


def test_walls_warns_of_drawings_named_with_another_suffix(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`rose walls --geojson w.svg` (or `--svg w.json`) was written silently."""
    for option, name, said in (
        ("--geojson", "w.svg", "GeoJSON written under a '.svg' name (expected .geojson or .json)"),
        ("--svg", "w.json", "an SVG drawing written under a '.json' name (expected .svg)"),
    ):
        assert main(["walls", str(cluttered_map), option, str(tmp_path / name)]) == 0
        assert capsys.readouterr().err == f"warning: {tmp_path / name}: {said}\n"
    for option, name in (("--geojson", "a.geojson"), ("--geojson", "b.JSON"), ("--svg", "c.svg")):
        assert main(["walls", str(cluttered_map), option, str(tmp_path / name)]) == 0
        assert "warning" not in capsys.readouterr().err


@pytest.mark.parametrize(
    ("command", "option", "name", "what"),
    [
        ("clean", "-o", "c.yaml", "output map"),
        ("clean", "--json", "r.json", "JSON report"),
        ("walls", "--geojson", "w.geojson", "GeoJSON file"),
        ("walls", "--svg", "w.svg", "SVG drawing"),
    ],
)
def test_an_output_inside_a_ros2_bag_folder_is_refused(
    command: str,
    option: str,
    name: str,
    what: str,
    cluttered_map: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """`rose clean MAP -o SOMEBAG/c.yaml` (or `--json`, or `rose walls --geojson / --svg` there)
    exited 0 and put files into the recording, which `rose-bag process` refuses for its outputs."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    output = bag / name
    argv = [command, str(cluttered_map), option, str(output)]
    if option == "--json":
        argv += ["-o", str(tmp_path / "c.yaml")]
    assert main(argv) == 1
    assert capsys.readouterr().err == (
        f"error: {output}: the {what} is inside the ROS 2 bag folder {bag.resolve()} (it "
        f"has metadata.yaml): it would write into a recording; choose another {option}\n"
    )
    assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml"]
    assert not (tmp_path / "c.yaml").exists()
    # A map beside its bag's metadata is no excuse: its folder is still the recording.
    moved = bag / "in.yaml"
    rose.save_map(moved, rose.load_map(cluttered_map))
    argv[1] = str(moved)
    assert main(argv) == 1
    assert "inside the ROS 2 bag folder" in capsys.readouterr().err
    # Beside the bag, the same run writes it.
    argv[argv.index(str(output))] = str(tmp_path / name)
    argv[1] = str(cluttered_map)
    assert main(argv) == 0
    assert (tmp_path / name).is_file()


def test_a_map_image_symlinked_into_a_bag_folder_is_refused(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`rose clean MAP -o c.yaml` with c.pgm a symlink into a bag folder wrote the image there (a
    symlink is followed): only the YAML's folder was checked."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (tmp_path / "c.pgm").symlink_to(bag / "c.pgm")
    assert main(["clean", str(cluttered_map), "-o", str(tmp_path / "c.yaml")]) == 1
    assert capsys.readouterr().err == (
        f"error: {tmp_path / 'c.pgm'}: the output map's image is inside the ROS 2 bag folder "
        f"{bag} (it has metadata.yaml): it would write into a recording; choose another -o\n"
    )
    assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml"]
    assert not (tmp_path / "c.yaml").exists()


def test_an_unwritable_output_folder_is_refused_before_the_map_is_analysed(
    cluttered_map: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """`rose clean BIG -o ro/c.yaml` (a read-only mount) analysed and cleaned the whole map, then
    failed staging its output: the check before the work did not ask whether it could write."""
    import rose.pipeline

    locked = tmp_path / "ro"
    locked.mkdir()
    writable = os.access

    def access(path: object, mode: int, **kwargs: object) -> bool:
        if Path(str(path)) == locked and mode & os.W_OK:
            return False  # as a read-only mount says (root passes any permission bits)
        return writable(path, mode, **kwargs)  # type: ignore[arg-type]

    def never(*_: object, **__: object) -> None:
        raise AssertionError("analysed before the outputs were checked")

    monkeypatch.setattr(os, "access", access)
    monkeypatch.setattr(rose.pipeline, "analyze", never)
    for argv in (
        ["clean", str(cluttered_map), "-o", str(locked / "c.yaml")],
        ["walls", str(cluttered_map), "--svg", str(locked / "w.svg")],
    ):
        assert main(argv) == 1
        name = argv[-1]
        assert capsys.readouterr().err == f"error: {name}: folder {locked} is not writable\n"
    assert list(locked.iterdir()) == []


def test_an_output_under_a_file_is_no_output_in_a_bag(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`-o notes.txt/c.yaml` said "inside the ROS 2 bag folder notes.txt": the bag check took the
    file for a folder whose metadata.yaml could not be read."""
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    assert main(["clean", str(cluttered_map), "-o", str(notes / "c.yaml")]) == 1
    assert (
        capsys.readouterr().err == f"error: {notes / 'c.yaml'}: {notes} is a file, not a folder\n"
    )


def test_a_folder_whose_metadata_yaml_is_no_bags_takes_outputs(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A maps folder with a data set's own metadata.yaml is no recording, even beside a log it
    does not name: its maps are cleaned beside it. A bag folder whose metadata.yaml is cut short
    still is one (it names its .db3)."""
    maps = tmp_path / "maps"
    maps.mkdir()
    (maps / "metadata.yaml").write_text("title: floor plans\nlicense: CC-BY-4.0\n")
    (maps / "run_0.db3").write_bytes(b"")
    assert main(["clean", str(cluttered_map), "-o", str(maps / "c.yaml")]) == 0
    assert (maps / "c.pgm").is_file()
    (maps / "metadata.yaml").write_text("  relative_file_paths:\n  - run_0.db3\n")
    assert main(["walls", str(cluttered_map), "--svg", str(maps / "w.svg")]) == 1
    assert "inside the ROS 2 bag folder" in capsys.readouterr().err
    assert not (maps / "w.svg").exists()


def test_a_map_yaml_without_origin_is_read_with_a_warning(tmp_path: Path) -> None:
    """map_server refuses a map YAML without `origin`; we take [0, 0, 0], and now say so once, as a
    `warning:` line (in a process of its own: pytest holds the logging of this one)."""
    import subprocess
    import sys

    grid = np.zeros((40, 40), dtype=np.int8)
    grid[5:35, 5] = grid[5, 5:35] = 100
    rose.save_map(tmp_path / "saved.yaml", rose.OccupancyMap(grid=grid, resolution_m=0.05))
    path = tmp_path / "map.yaml"
    path.write_text(
        "image: saved.pgm\nresolution: 0.05\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    done = subprocess.run(
        [sys.executable, "-m", "rose.cli", "score", str(path), str(tmp_path / "saved.yaml")],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    said = f"warning: {path}: no origin, using [0, 0, 0] (map_server requires it)\n"
    assert done.stderr == said  # the saved map, which has every key, gets none
    assert rose.load_map(path).origin_xy_m == (0.0, 0.0)


@pytest.mark.parametrize("command", ["score", "clean", "walls"])
def test_a_raw_map_reads_grey_values_past_100_as_unknown(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    """As Nav2 reads them (they were refused as values outside 0..100)."""
    import cv2

    cv2.imwrite(str(tmp_path / "m.pgm"), np.array([[0, 254], [205, 100]], dtype=np.uint8))
    (tmp_path / "raw.yaml").write_text(
        "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nmode: raw\n"
    )
    np.testing.assert_array_equal(rose.load_map(tmp_path / "raw.yaml").grid, [[-1, 100], [0, -1]])
    argv = [command, str(tmp_path / "raw.yaml")] + (
        ["-o", str(tmp_path / "c.yaml")] if command == "clean" else []
    )
    assert main(argv) == 0, capsys.readouterr().err
    assert (tmp_path / "c.yaml").exists() == (command == "clean")


def test_a_map_without_a_dominant_direction_is_kept_and_said_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One occupied cell: W = 1 by convention, nothing labelled; "decluttering has likely failed"
    would misread it, and "1 cells" reads badly."""
    grid = np.zeros((5, 5), np.int8)
    grid[2, 2] = 100
    path = tmp_path / "speck.yaml"
    rose.save_map(path, rose.OccupancyMap(grid=grid, resolution_m=0.05))
    assert main(["clean", str(path), "-o", str(tmp_path / "c.yaml")]) == 0
    out = capsys.readouterr().out
    assert "no dominant direction: nothing labelled" in out and "failed" not in out
    assert "occupied     1 cell\n" in out
    assert "kept         1 cell (" in out
    assert "completed    0 unknown cells made walls" in out
    assert (rose.load_map(tmp_path / "c.yaml").grid == grid).all()


def test_fixed_threshold_takes_what_the_api_takes(
    cluttered_map: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # RoseParams takes fixed_threshold in [0, 1]; the option refused 0.
    assert (
        main(["score", str(cluttered_map), "--threshold-mode", "fixed", "--fixed-threshold", "0"])
        == 0
    )
    with pytest.raises(SystemExit) as stop:
        main(["score", str(cluttered_map), "--fixed-threshold", "1.5"])
    assert stop.value.code == 2
    assert "expected a number in [0, 1]" in capsys.readouterr().err


def test_a_fixed_threshold_alone_selects_the_fixed_mode(
    cluttered_map: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--fixed-threshold was silently ignored without --threshold-mode fixed."""

    def threshold(*extra: str) -> float:
        assert main(["score", str(cluttered_map), "--json", *extra]) == 0
        report = json.loads(capsys.readouterr().out)
        return (report[0] if isinstance(report, list) else report)["threshold"]

    assert threshold("--fixed-threshold", "0.42") == 0.42
    assert threshold("--threshold-mode", "fixed", "--fixed-threshold", "0.42") == 0.42
    assert threshold() != 0.42  # the mixture's own
    with pytest.raises(SystemExit) as stop:
        main(["score", str(cluttered_map), "--threshold-mode", "gmm", "--fixed-threshold", "0.4"])
    assert stop.value.code == 2
    assert "--fixed-threshold needs --threshold-mode fixed" in capsys.readouterr().err


def test_debug_is_taken_after_the_command_too(capsys: pytest.CaptureFixture[str]) -> None:
    """As rose-bag takes it (the README says before or after the command)."""
    assert main(["score", "no-such-map.yaml", "--debug"]) == 1
    err = capsys.readouterr().err
    assert "no such file" in err
    assert "Traceback (most recent call last)" in err  # score's per-map errors too
    assert main(["score", "no-such-map.yaml"]) == 1
    assert "Traceback" not in capsys.readouterr().err


def test_clean_writes_every_kept_wall_as_occupied_at_the_threshold_given(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Walls of occupancy 56 (a scale map), cleaned with --occupied-threshold 50: map_saver's cut at
    65 wrote every kept wall as unknown."""
    import cv2

    image = np.full((200, 300), 254, np.uint8)
    for wall in (np.s_[5:7, 5:-5], np.s_[-7:-5, 5:-5], np.s_[5:-5, 5:7], np.s_[5:-5, -7:-5]):
        image[wall] = 140
    image[5:-5, 150:152] = 140
    cv2.imwrite(str(tmp_path / "grey.pgm"), image)
    (tmp_path / "grey.yaml").write_text("image: grey.pgm\nmode: scale\nresolution: 0.05\n")
    assert set(np.unique(rose.load_map(tmp_path / "grey.yaml").grid)) == {0, 56}
    out, report = tmp_path / "c.yaml", tmp_path / "c.json"
    argv = ["clean", str(tmp_path / "grey.yaml"), "-o", str(out), "--json", str(report)]
    assert main([*argv, "--occupied-threshold", "50"]) == 0
    kept = json.loads(report.read_text())["kept_cells"]
    cleaned = rose.load_map(out).grid
    assert kept > 2000 and np.count_nonzero(cleaned == 100) == kept


def test_clean_with_a_threshold_above_65_keeps_the_inputs_walls_of_65_and_more(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--occupied-threshold 90: cells of 70, which ROSE did not count as occupied, were written as
    unknown; map_saver's 65 still makes them walls."""
    import cv2

    image = np.full((60, 80), 254, np.uint8)
    image[5, 5:75] = image[55, 5:75] = image[5:56, 5] = image[5:56, 75] = 0
    image[30, 20:60] = 124  # occupancy 70 in scale mode
    cv2.imwrite(str(tmp_path / "m.pgm"), image)
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.05\nmode: scale\n")
    seventy = rose.load_map(tmp_path / "m.yaml").grid == 70
    assert seventy.sum() == 40
    out = tmp_path / "c.yaml"
    argv = ["clean", str(tmp_path / "m.yaml"), "-o", str(out), "--occupied-threshold", "90"]
    assert main(argv) == 0
    assert (rose.load_map(out).grid[seventy] == 100).all()


def test_walls_min_length_past_any_map_is_a_usage_error(
    cluttered_map: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """1e308 m overflowed to inf cells: exit 1 and an internal name, blaming the map file."""
    with pytest.raises(SystemExit) as stop:
        main(["walls", str(cluttered_map), "--min-length", "1e308"])
    assert stop.value.code == 2
    assert "argument --min-length: expected a number in [0, 1000000], got '1e308'" in (
        capsys.readouterr().err
    )


@pytest.mark.parametrize("value", ["0", "-0.5", "7"])
def test_a_fraction_out_of_range_names_its_range_on_either_side(
    value: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """--peak-prominence 0 said 'expected a positive number', 7 'expected a number in (0, 1]'."""
    with pytest.raises(SystemExit):
        main(["score", "m.yaml", "--peak-prominence", value])
    assert f"expected a number in (0, 1], got '{value}'" in capsys.readouterr().err


def test_a_range_message_prints_its_bound_in_full() -> None:
    """2**31 s was printed 2.14748e+09: 2147483000 looked out of range, and was not."""
    import argparse

    from rose.cli.options import float_in, float_up_to

    with pytest.raises(argparse.ArgumentTypeError, match=r"\(0, 2147483648\], got '3e9'"):
        float_up_to(2.0**31)("3e9")
    assert float_up_to(2.0**31)("2147483000") == 2147483000.0
    with pytest.raises(argparse.ArgumentTypeError, match=r"\[0\.25, 7\.5\]"):
        float_in(0.25, 7.5)("8")


def test_clean_to_standard_output_says_why_it_cannot(
    cluttered_map: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`rose clean m.yaml -o -` said `-: the output map must be a .yaml file`."""
    assert main(["clean", str(cluttered_map), "-o", "-"]) == 1
    err = capsys.readouterr().err
    assert (
        err
        == "error: -: a map cannot go to standard output (it is a YAML file and its image beside it)\n"
    )


def test_clean_names_every_file_it_wrote(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The summary's `written` line left out the JSON report."""
    out, report = tmp_path / "c.yaml", tmp_path / "c.json"
    assert main(["clean", str(cluttered_map), "-o", str(out), "--json", str(report)]) == 0
    (written,) = [
        line for line in capsys.readouterr().out.splitlines() if line.startswith("written")
    ]
    assert written.split()[1:] == [str(out), "+", "c.pgm", "+", str(report)]
    assert main(["clean", str(cluttered_map), "-o", str(tmp_path / "d.yaml"), "--json", "-"]) == 0
    (written,) = [
        line for line in capsys.readouterr().err.splitlines() if line.startswith("written")
    ]
    assert written.split()[-1] == "d.pgm"  # the report went to standard output


def test_clean_summary_gives_the_threshold_to_six_decimals(
    cluttered_map: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The JSON reports carry the unrounded threshold; the summary still reads it to 1e-6 (it
    printed 0.9382514154204894 once the JSON stopped rounding)."""
    import re

    assert main(["clean", str(cluttered_map), "-o", str(tmp_path / "c.yaml")]) == 0
    (line,) = [x for x in capsys.readouterr().out.splitlines() if x.startswith("threshold ")]
    assert re.fullmatch(r"threshold    \d\.\d{6}", line), line


def test_a_room_whose_walls_are_the_grids_border_is_no_degenerate_input() -> None:
    """A map cropped to its walls (one-cell walls on the grid's border, a free room inside) read
    "occupied cells fill the grid (1000 cell sides on its border, 992 inside it)"; a solid block
    filling the grid still does."""
    from rose.directions import degenerate_input

    room = np.zeros((200, 300), np.int8)
    room[[0, -1], :] = room[:, [0, -1]] = 100
    assert degenerate_input(room, room == 100) is None
    block = np.full((40, 50), 100, np.int8)
    assert degenerate_input(block, block == 100).startswith("occupied cells fill the grid")


def test_score_gives_the_same_reason_in_its_table_and_json_for_a_thin_map(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An 8 x 2 map: the table said "no dominant direction" where JSON said "a side of 2 cells"."""
    path = tmp_path / "thin.yaml"
    thin = np.zeros((2, 8), np.int8)
    thin[0] = 100
    rose.save_map(path, rose.OccupancyMap(grid=thin, resolution_m=0.05))
    assert main(["score", "--json", str(path)]) == 0
    (record,) = json.loads(capsys.readouterr().out)
    assert record["degenerate"].startswith("a side of 2 cells")
    assert main(["score", str(path)]) == 0
    footnote = capsys.readouterr().out.splitlines()[-1]
    assert footnote.startswith(f"* {path}: {record['degenerate']}: W says nothing about this map")


def test_every_command_describes_itself_and_shows_debug(capsys: pytest.CaptureFixture[str]) -> None:
    """`rose clean`, `rose score` and `rose-bag info` had no description; --debug, taken after any
    command, showed in none of their helps."""
    from rose.cli import build_parser as rose_parser
    from rose_logs.cli import build_parser as rose_bag_parser

    for parser in (rose_parser(), rose_bag_parser()):
        commands = next(a for a in parser._actions if a.dest == "command").choices
        for name, command in commands.items():
            assert command.description, name
            assert "--debug" in command.format_help(), name


@pytest.mark.parametrize(
    "command",
    [
        ["score"],
        ["score", "--json"],
        ["walls"],
        ["walls", "--svg", "-"],
        ["clean", "-o", "out.yaml", "--json", "-"],
    ],
)
def test_a_command_that_writes_to_a_closed_standard_output_is_refused_before_any_work(
    command: list[str],
    cluttered_map: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Started with standard output closed (``>&-``: sys.stdout is None), `score` (table or
    JSON) and `clean` printed nothing and exited 0, `walls` was an AttributeError traceback: a
    command whose result goes there (its printout, an output ``-``) is refused first."""
    import sys

    import rose.pipeline

    def analyze(*_args: object, **_kwargs: object) -> None:
        raise AssertionError("analysed with no standard output to print to")

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(rose.pipeline, "analyze", analyze)
    monkeypatch.setattr(sys, "stdout", None)
    assert main([command[0], str(cluttered_map), *command[1:]]) == 1
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["error: standard output: cannot write (it is closed)"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.pgm", "in.yaml"]


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs Linux's /proc")
@pytest.mark.parametrize("closed", [1, 2], ids=["stdout", "stderr"])
def test_a_closed_standard_stream_is_not_handed_to_an_output_file(
    closed: int, cluttered_map: Path, tmp_path: Path
) -> None:
    """Started with standard output or error closed (``>&-``, ``2>&-``), a command that writes
    files runs; the closed descriptor is taken by /dev/null first, else the output file opened
    next became standard output or error, for a child or native code (Rerun's warnings) to write
    into."""
    import os
    import subprocess
    import sys

    code = (
        "import os; from rose.cli import main; "
        f"rc = main(['clean', {str(cluttered_map)!r}, '-o', 'out.yaml']); "
        "links = [os.readlink(f'/proc/self/fd/{fd}') for fd in (1, 2)]; "
        "open('result.txt', 'w').write(' '.join([str(rc), *links]))"
    )
    subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        preexec_fn=lambda: os.close(closed),  # the child starts without that stream
        check=False,
    )
    assert (tmp_path / "result.txt").read_text() == f"0 {os.devnull} {os.devnull}"
    assert (tmp_path / "out.yaml").is_file()


@pytest.mark.parametrize(
    ("command", "written"),
    [
        (["clean", "-o", "out.yaml"], ["out.pgm", "out.yaml"]),
        (["clean", "-o", "out.yaml", "--json", "r.json"], ["out.pgm", "out.yaml", "r.json"]),
        (["walls", "--svg", "w.svg"], ["w.svg"]),
        (["walls", "--geojson", "w.geojson"], ["w.geojson"]),
    ],
)
def test_a_command_that_writes_files_runs_without_a_standard_output(
    command: list[str],
    written: list[str],
    cluttered_map: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Under ``pythonw`` sys.stdout is None, and every command was refused, `clean -o map.yaml`
    too: one whose result is its files runs (its summary goes nowhere), exit 0."""
    import sys

    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.chdir(out)
    monkeypatch.setattr(sys, "stdout", None)
    assert main([command[0], str(cluttered_map), *command[1:]]) == 0
    assert sys.stdout is None  # as it was
    assert sorted(p.name for p in out.iterdir()) == written
    assert capsys.readouterr().err == ""


def test_score_says_clutter_value_has_no_effect_on_it() -> None:
    """`rose score --help` said --clutter-value is "what clutter cells become in the cleaned map",
    but score writes no map: the option changes none of its output."""
    from rose.cli import build_parser

    commands = next(a for a in build_parser()._actions if a.dest == "command").choices
    score_help = " ".join(commands["score"].format_help().split())
    assert "--clutter-value {free,unknown} no effect here: this command writes no map" in score_help
    clean_help = " ".join(commands["clean"].format_help().split())
    assert "what clutter cells become in the cleaned map (default free)" in clean_help


def test_without_a_standard_error_nothing_meant_for_it_goes_into_standard_output(
    cluttered_map: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Started with standard error closed (``2>&-``, ``pythonw``: sys.stderr is None), ``print(...,
    file=sys.stderr)`` writes to standard output: `rose score --json good bad` put its `error:`
    lines before the JSON there, which then did not parse."""
    import sys

    bad = tmp_path / "bad.pgm"
    bad.write_bytes(b"not an image")
    monkeypatch.setattr(sys, "stderr", None)
    assert main(["score", "--json", str(cluttered_map), str(bad)]) == 1
    assert sys.stderr is None  # as it was
    records = json.loads(capsys.readouterr().out)
    assert [r["map"] for r in records] == [str(cluttered_map), str(bad)]
    assert "error" in records[1]


def test_the_top_level_help_lists_the_exit_codes() -> None:
    """The exit codes a script acts on (3 a failed gate, 4 a salvaged log, 130 / 143 an
    interrupt, 141 a reader that left) were in the README only: `--help` said none."""
    from rose.cli import build_parser as rose_parser
    from rose_logs.cli import EXIT_GATE, EXIT_SALVAGED
    from rose_logs.cli import build_parser as rose_bag_parser

    rose_help = rose_parser().format_help()
    rose_bag_help = rose_bag_parser().format_help()
    for text in (rose_help, rose_bag_help):
        codes = [line.split()[0] for line in text.split("exit status:\n")[1].splitlines()]
        assert codes[:3] == ["0", "1", "2"] and codes[-2:] == ["130", "141"], codes
    assert f"\n  {EXIT_GATE}    --fail-above or --fail-on-break gate failed\n" in rose_bag_help
    assert f"\n  {EXIT_SALVAGED}    --salvage with messages lost" in rose_bag_help
    assert "gate" not in rose_help  # `rose` has none


def test_a_lost_summary_line_keeps_its_end_with_long_output_names() -> None:
    """Four long output names (a batch's tables in a deep folder) filled the 300 characters:
    the cut took "only the summary is lost"; fewer are named (and how many more)."""
    from rose.cli import error_text
    from rose.errors import StdoutError

    folder = "/srv/someone/projects/fleet-health/2024-06-01/nightly-run/out"
    names = ("recordings.parquet", "snapshots.parquet", "summary.json", "report.md", "w.png")
    written = [Path(f"{folder}/{name}") for name in names]
    line = error_text(StdoutError("No space left on device"), written=written)
    assert len(line) <= 300 and line.endswith("and 3 more): only the summary is lost"), line
    assert line.startswith("standard output: cannot write (No space left on device); the ")
