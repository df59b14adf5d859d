"""Clutter generator, metrics and the small evaluation end to end."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from real_data import REPO_DATA, dataset

import rose
from rose_logs.cli.evaluate import add_parser as add_evaluate_parser
from rose_logs.datasets import ENV_VAR, DataSetError
from rose_logs.evaluation import EvaluationConfig, add_clutter, run_evaluation
from rose_logs.evaluation import walls as wall_module
from rose_logs.evaluation.clutter import SHAPES, obstacle_stamp
from rose_logs.evaluation.config import (
    BENCHMARK_SUBDIR,
    BORMANN_MAPS,
    LOGS_SUBDIR,
    RADISH_LOGS,
)
from rose_logs.evaluation.experiments import correlation, label_scores


def _room(rows: int = 120, cols: int = 150) -> np.ndarray:
    grid = np.full((rows, cols), -1, dtype=np.int8)
    grid[10:-10, 10:-10] = 0
    grid[10, 10:-10] = grid[-11, 10:-10] = 100
    grid[10:-10, 10] = grid[10:-10, -11] = 100
    grid[10:60, 70] = 100
    return grid


@pytest.mark.parametrize("shape", SHAPES)
def test_clutter_is_reproducible_and_ground_truth_exact(shape: str) -> None:
    grid = _room()
    before = grid.copy()
    a = add_clutter(grid, shape=shape, count=40, size_px=7, seed=11)  # type: ignore[arg-type]
    b = add_clutter(grid, shape=shape, count=40, size_px=7, seed=11)  # type: ignore[arg-type]
    c = add_clutter(grid, shape=shape, count=40, size_px=7, seed=12)  # type: ignore[arg-type]
    np.testing.assert_array_equal(grid, before)  # input untouched
    np.testing.assert_array_equal(a.grid, b.grid)
    assert not np.array_equal(a.grid, c.grid)
    # Exact ground truth: structure = original occupied, clutter = exactly the changed cells.
    np.testing.assert_array_equal(a.structure, before >= 65)
    np.testing.assert_array_equal(a.clutter, a.grid != before)
    assert not np.any(a.clutter & a.structure)
    assert np.all(before[a.clutter] == 0)  # only known free cells became clutter
    assert np.all(a.grid[a.clutter] == 100)
    assert a.clutter.sum() > 40


def test_clutter_more_and_bigger_means_more_cells() -> None:
    grid = _room(300, 300)
    small = add_clutter(grid, shape="square", count=20, size_px=3, seed=1).clutter.sum()
    big = add_clutter(grid, shape="square", count=20, size_px=15, seed=1).clutter.sum()
    many = add_clutter(grid, shape="square", count=100, size_px=3, seed=1).clutter.sum()
    assert big > small and many > small


@pytest.mark.parametrize("kind", ["square", "rectangle", "circle", "diamond", "star"])
@pytest.mark.parametrize("size", [2, 5, 39])
def test_stamp_extent(kind: str, size: int) -> None:
    stamp = obstacle_stamp(kind, size, np.random.default_rng(0))
    assert max(stamp.shape) == size
    assert stamp.any()


def test_clutter_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="shape"):
        add_clutter(_room(), shape="hexagon", count=1, size_px=3, seed=0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="free cell"):
        add_clutter(np.full((5, 5), 100, np.int8), shape="square", count=1, size_px=3, seed=0)


def test_label_scores_counts() -> None:
    cluttered = add_clutter(_room(), shape="square", count=10, size_px=6, seed=3)
    result = rose.analyze(cluttered.grid)
    scores = label_scores(result, cluttered.structure, cluttered.clutter)
    kept = result.structure
    expected_precision = (kept & cluttered.structure).sum() / kept.sum()
    assert scores.precision == pytest.approx(expected_precision)
    assert scores.recall == pytest.approx(
        (kept & cluttered.structure).sum() / cluttered.structure.sum()
    )
    assert 0 <= scores.clutter_recall <= 1


def _small_config(**changes: object) -> EvaluationConfig:
    """The small configuration on the repository's test data (freiburg-101 log, Freiburg79_scan)."""
    settings: dict[str, object] = {
        "maps_dir": REPO_DATA,
        "sizes_px": (4, 20),
        "counts": (20, 100),
        "shapes": ("square", "random"),
    }
    return EvaluationConfig.small(**(settings | changes))


def test_small_evaluation_writes_every_artefact(tmp_path: Path) -> None:
    report = run_evaluation(_small_config(), tmp_path)
    expected = {
        "report.md",
        "exp1_clutter_runs.csv",
        "exp1_furniture.csv",
        "exp2_drift.csv",
        "exp3_correlation.csv",
        "exp1_precision_recall_boxplots.png",
        "exp2_structure_score.png",
        "exp3_w_vs_precision.png",
        "maps_from_logs.png",
        "map_freiburg-101.png",
        "cleaning_runs.csv",
        "cleaning_before_after.png",
        "wall_error.csv",
        "wall_error.png",
    }
    names = {p.name for p in tmp_path.iterdir()}
    assert expected <= names
    assert {p.name for p in report.files} >= expected
    for path in report.files:
        assert path.stat().st_size > 0
    with (tmp_path / "exp1_clutter_runs.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 * 2 * 2 * 2  # maps x shapes x sizes x counts
    markdown = report.markdown_path.read_text()
    for needle in (
        "Seed: 2021",
        "Versions:",
        "Run time:",
        "Experiment 1",
        "Experiment 2",
        "Pearson R",
    ):
        assert needle in markdown
    # The wall section holds the row of the one benchmark map, with the numbers of wall_error.csv.
    with (tmp_path / "wall_error.csv").open() as fh:
        wall_rows = list(csv.DictReader(fh))
    assert [r["name"] for r in wall_rows] == ["Freiburg79_scan"]
    n_reference = int(wall_rows[0]["n_reference"])
    assert n_reference > 0
    section = markdown[markdown.index("## Wall extraction") :]
    assert f"| Freiburg79_scan | {n_reference} | {wall_rows[0]['baseline_n_detected']} |" in section
    w_ok, w_drift = report.w_by_log["freiburg-101"]
    assert w_ok < w_drift
    assert math.isfinite(report.r_all)
    prec, _ = report.median_by_map["freiburg-101"]
    assert prec > 0.9


def test_wall_experiment_gets_the_maps_dir_and_rose_params(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # No data set anywhere: everything must come from the configuration.
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "no-data-set-here"))
    calls: list[dict[str, object]] = []
    real = wall_module.wall_experiment

    def spy(out_dir: Path, **kwargs: object) -> wall_module.WallReport:
        calls.append(kwargs)
        return real(out_dir, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(wall_module, "wall_experiment", spy)
    monkeypatch.setattr("rose_logs.evaluation.report.wall_experiment", spy, raising=False)
    params = rose.RoseParams(threshold_mode="fixed", fixed_threshold=0.3)
    config = _small_config(rose_params=params, plots=False, logs=(), counts=(20,), sizes_px=(4,))
    run_evaluation(config, tmp_path)
    assert len(calls) == 1
    assert calls[0]["maps_dir"] == REPO_DATA / BENCHMARK_SUBDIR
    assert calls[0]["rose_params"] == params
    assert calls[0]["names"] == ["Freiburg79_scan"]


def test_wall_experiment_errors_are_not_swallowed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(out_dir: Path, **kwargs: object) -> wall_module.WallReport:
        msg = "cannot load the benchmark map"
        raise rose.MapFileError(msg)

    monkeypatch.setattr(wall_module, "wall_experiment", broken)
    monkeypatch.setattr("rose_logs.evaluation.report.wall_experiment", broken, raising=False)
    config = _small_config(plots=False, logs=(), counts=(20,), sizes_px=(4,))
    with pytest.raises(rose.MapFileError, match="cannot load the benchmark map"):
        run_evaluation(config, tmp_path)
    assert not (tmp_path / "report.md").exists()


def test_wall_experiment_runs_with_rose_params_on_a_maps_dir(tmp_path: Path) -> None:
    maps_dir = REPO_DATA / BENCHMARK_SUBDIR
    gmm = wall_module.wall_experiment(tmp_path / "a", names=["Freiburg52_scan"], maps_dir=maps_dir)
    strict = wall_module.wall_experiment(
        tmp_path / "b",
        names=["Freiburg52_scan"],
        maps_dir=maps_dir,
        rose_params=rose.RoseParams(peak_prominence=1.0, mask_half_width_px=0.5),
    )
    assert [r.name for r in gmm.rows] == ["Freiburg52_scan"]
    # The ROSE parameters reach the ROSE variant: a narrower structure strip keeps fewer walls.
    assert strict.rows[0].rose != gmm.rows[0].rose
    # The Hough baseline and the reference do not depend on ROSE's parameters.
    assert strict.rows[0].baseline == gmm.rows[0].baseline
    assert strict.rows[0].n_reference == gmm.rows[0].n_reference


def test_without_a_data_set_the_defaults_say_how_to_get_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "missing"))
    with pytest.raises(DataSetError, match=ENV_VAR):
        wall_module.wall_experiment(tmp_path / "out", names=["Freiburg52_scan"])
    assert not (tmp_path / "out").exists()
    with pytest.raises(DataSetError, match=ENV_VAR):
        run_evaluation(EvaluationConfig.small(plots=False), tmp_path / "report")
    assert not (tmp_path / "report").exists()
    assert EvaluationConfig.small(maps_dir=tmp_path).benchmark_dir == tmp_path / BENCHMARK_SUBDIR


@pytest.mark.dataset(LOGS_SUBDIR, BENCHMARK_SUBDIR)
def test_data_set_holds_every_input_of_the_full_evaluation() -> None:
    config = EvaluationConfig.full()
    assert config.data_root == dataset(".")
    for log in RADISH_LOGS:
        assert (config.logs_dir / f"{log}-corrected.log.gz").is_file(), log
    for name in BORMANN_MAPS:
        assert (config.benchmark_dir / f"{name}.png").is_file(), name
        assert (config.benchmark_dir / f"{name}_furnitures.png").is_file(), name


def test_correlation_of_perfectly_anticorrelated_runs() -> None:
    from rose_logs.evaluation.experiments import ClutterRun

    base = ClutterRun("m", "s", "square", 4, 20, 0, 10, 5, 0.1, 2, 0.9, 0.3, 0.5, 0.9, 0.01)
    runs = [
        dataclasses.replace(base, structure_score=w, precision=1 - w, count=20 * (1 + i % 2))
        for i, w in enumerate(np.linspace(0.05, 0.6, 8))
    ]
    exp3 = correlation(runs)
    assert exp3.r_all == pytest.approx(-1.0)
    assert exp3.n_all == 8


def test_seeds_apart_by_2_31_derive_different_maps() -> None:
    """`--seed 5` and `--seed 2147483653` (both accepted, 0..2**32-1) made the same clutter maps
    and drifted trajectories: the base seed was folded into 0..2**31-1. Seeds below 2**31 derive
    what they did (the CSV's seed of `--seed 5`'s first csail run)."""
    from rose_logs.evaluation.experiments import _seed

    parts = ("csail-corrected.head400", "square", 4, 20)
    assert _seed(5, *parts) == 1073809819
    assert _seed(5 + 2**31, *parts) != _seed(5, *parts)
    assert _seed(5 + 2**31, "drift", 1.0, 0) != _seed(5, "drift", 1.0, 0)
    assert 0 <= _seed(2**32 - 1, *parts) < 2**32


def test_evaluate_parser_builds_config() -> None:
    from rose_logs.cli.evaluate import config_from_args

    parser = argparse.ArgumentParser()
    add_evaluate_parser(parser.add_subparsers())
    args = parser.parse_args(
        ["evaluate", "out", "--config", "full", "--logs", "aces,intel", "--seed", "5"]
    )
    config = config_from_args(args)
    assert config.name == "full"
    assert config.logs == ("aces", "intel")
    assert config.seed == 5
    assert args.func.__module__ == "rose_logs.cli.evaluate"


def test_evaluate_command_without_data_set_is_a_one_line_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from rose_logs.cli import main

    monkeypatch.setenv(ENV_VAR, str(tmp_path / "missing"))
    assert main(["evaluate", str(tmp_path / "report"), "--no-plots"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(
        f"error: {tmp_path / 'missing'}: data-set folder ({ENV_VAR}) does not exist"
    )
    assert err.count("\n") == 1


def test_evaluate_writes_its_folder_whole_and_replaces_only_its_own_reports(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rose_logs.cli import main

    # No experiments (seconds); the committed data stand in for the data set (protected as an input).
    empty = ["--logs", "", "--maps", "", "--no-plots", "--maps-dir", str(REPO_DATA)]
    out = tmp_path / "report"
    assert main(["evaluate", str(out), *empty]) == 0
    assert capsys.readouterr().out.strip() == str(out / "report.md")
    assert (out / "report.md").is_file()
    assert main(["evaluate", str(out), *empty]) == 1  # an existing report needs --force
    assert "exists already" in capsys.readouterr().err
    (out / "stale.csv").write_text("old")
    assert main(["evaluate", str(out), *empty, "--force"]) == 0
    assert not (out / "stale.csv").exists()  # replaced whole, not merged
    other = tmp_path / "photos"
    other.mkdir()
    (other / "cat.png").write_bytes(b"x")
    assert main(["evaluate", str(other), *empty, "--force"]) == 1  # not a report: never replaced
    assert "did not write" in capsys.readouterr().err
    assert [p.name for p in other.iterdir()] == ["cat.png"]
    assert not [p for p in tmp_path.iterdir() if ".rose-tmp-" in p.name]
    # The README's `evaluate out/eval` in a fresh folder: the report's parent folders are made.
    nested = tmp_path / "out" / "deeper" / "eval"
    assert main(["evaluate", str(nested), *empty]) == 0
    assert (nested / "report.md").is_file()
    # ... but never inside the data set, which is read only: refused, and nothing made there.
    data = tmp_path / "data"
    data.mkdir()
    assert main(["evaluate", str(data / "new" / "report"), "--maps-dir", str(data)]) == 1
    assert "refusing to write inside the input" in capsys.readouterr().err
    assert list(data.iterdir()) == []


def test_a_missing_furnished_drawing_is_named_before_any_experiment(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The wall experiment needs <name>_furnitures.png; its absence was found only after
    experiments 1 and 2 had run (minutes with --config full)."""
    import shutil

    from rose_logs.cli import main

    data = tmp_path / "data"
    (data / "bormann_ipa_room_segmentation").mkdir(parents=True)
    shutil.copy(
        REPO_DATA / "bormann_ipa_room_segmentation" / "Freiburg79_scan.png",
        data / "bormann_ipa_room_segmentation",
    )
    out = tmp_path / "report"
    args = ["evaluate", str(out), "--no-plots", "--maps-dir", str(data), "--logs", ""]
    assert main([*args, "--maps", "Freiburg79_scan"]) == 1
    err = capsys.readouterr().err
    assert "Freiburg79_scan_furnitures.png: no such file" in err
    assert "experiment 1" not in err
    assert not out.exists()
