"""Clutter generator, metrics and the small evaluation end to end."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from rose_logs.cli.evaluate import add_parser as add_evaluate_parser
from rose_logs.evaluation import EvaluationConfig, add_clutter, run_evaluation
from rose_logs.evaluation.clutter import SHAPES, obstacle_stamp
from rose_logs.evaluation.config import DEFAULT_MAPS_DIR
from rose_logs.evaluation.experiments import correlation, label_scores

needs_maps = pytest.mark.skipif(not DEFAULT_MAPS_DIR.is_dir(), reason="shared maps not available")


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
    import rose

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


@needs_maps
def test_small_evaluation_writes_every_artefact(tmp_path: Path) -> None:
    config = EvaluationConfig.small(sizes_px=(4, 20), counts=(20, 100), shapes=("square", "random"))
    report = run_evaluation(config, tmp_path)
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
    try:
        import rose_logs.evaluation.walls  # noqa: F401
    except ImportError:
        pass
    else:
        assert "Wall extraction" in markdown
    w_ok, w_drift = report.w_by_log["freiburg-101"]
    assert w_ok < w_drift
    assert math.isfinite(report.r_all)
    prec, _ = report.median_by_map["freiburg-101"]
    assert prec > 0.9


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
