"""rose_logs.evaluation.breaks: outcomes, ROC, thresholds, and one real replayed session."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from real_data import CARMEN_DIR, repo_data

from rose_logs.carmen.clock import scan_clock_ns
from rose_logs.carmen.parse import read_carmen_log
from rose_logs.carmen.raycast import BuilderParams
from rose_logs.carmen.session import SessionOptions, write_carmen_session
from rose_logs.evaluation.break_sessions import SessionSpec, session_grids
from rose_logs.evaluation.breaks import (
    BreakCase,
    SessionScores,
    _correct_session,
    break_cases,
    group_table,
    leave_one_log_out,
    outcome,
    quiet_threshold,
    roc,
    score_case,
)


def _scores(name: str, level: float, start_s: float, values: list[float]) -> SessionScores:
    n = len(values)
    spec = SessionSpec(Path(f"{name}-corrected.log.gz"), drift_level=level, drift_start_s=start_s)
    return SessionScores(
        case=BreakCase(spec, 0.5 if level else 0.0, 30.0 * n),
        times_s=30.0 * np.arange(1, n + 1),
        break_scores_m=np.array(values, dtype=float),
        structure_scores=np.full(n, 0.1),
        regions_m=tuple(None for _ in values),
        region_hits=np.full(n, math.nan),
        detector_s=np.full(n, 0.001),
        rose_s=np.full(n, 0.01),
        grid_cells=np.full(n, 100, dtype=np.int64),
    )


def test_outcomes_false_alarms_and_delays() -> None:
    correct = _scores("a", 0, 0, [0.0, 0.5, 1.0])
    assert outcome(correct, 1.0).false_alarm and not outcome(correct, 1.5).false_alarm
    drifted = _scores("a", 2, 50.0, [0.0, 0.8, 0.2, 2.0, 3.0])  # times 30, 60, ... 150 s
    assert outcome(drifted, 1.0) == outcome(drifted, 2.0)
    found = outcome(drifted, 1.0)
    assert (found.detected, found.index, found.delay_s) == (True, 3, 120.0 - 50.0)
    early = outcome(drifted, 0.5)  # fires at 60 s, after the start: detected with a 10 s delay
    assert early.detected and early.delay_s == 10.0
    before = _scores("a", 2, 100.0, [0.0, 0.8, 0.2, 2.0])
    assert outcome(before, 0.5).false_alarm  # at 60 s, before the drift started at 100 s
    assert outcome(drifted, 5.0) == outcome(drifted, math.inf)


def test_roc_quiet_threshold_and_leave_one_log_out() -> None:
    sessions = [
        _scores("a", 0, 0, [0.0, 1.0]),
        _scores("a", 4, 40.0, [0.0, 0.5, 4.0]),
        _scores("b", 0, 0, [0.0, 2.0]),
        _scores("b", 4, 40.0, [0.0, 0.5, 1.5]),
    ]
    rows = roc(sessions)
    assert rows[-1][0] == math.inf and rows[-1][1:3] == (0.0, 0.0)
    assert all(a[1] >= b[1] and a[2] >= b[2] for a, b in itertools.pairwise(rows))
    assert quiet_threshold(sessions) == pytest.approx(2.0) and quiet_threshold(sessions) > 2.0
    held = {r.log: r for r in leave_one_log_out(sessions)}
    assert held["a"].threshold > 2.0 and held["a"].detected == 1 and held["a"].false_alarms == 0
    assert held["b"].threshold > 1.0 and held["b"].false_alarms == 1  # b's correct session: 2.0
    table = group_table(sessions, 1.2)
    assert [(r.level, r.sessions, r.false_alarms, r.detected) for r in table] == [
        (0.0, 2, 1, 0),
        (4.0, 2, 0, 2),
    ]


def test_replay_matches_the_converter(tmp_path: Path) -> None:
    path = repo_data(f"{CARMEN_DIR}/aces-corrected.log.gz")
    log = read_carmen_log(path, max_scans=80)
    spec = SessionSpec(path, drift_level=2.0, drift_start_s=40.0, drift_seed=1, map_period_s=30.0)
    grids = list(session_grids(log, spec))
    written = write_carmen_session(
        log,
        tmp_path / "s.mcap",
        options=SessionOptions(
            map_period_s=30.0, drift_level=2.0, drift_start_s=40.0, drift_seed=1
        ),
    )
    assert len(grids) == written.maps
    np.testing.assert_array_equal(grids[-1].grid, written.final_grid)
    assert grids[-1].origin_xy_m == written.final_origin_xy_m
    clock, name, _ = scan_clock_ns(log)
    assert name == "log" and np.all(np.diff(clock) > 0)


def test_replay_at_another_cell_size_matches_the_converter_at_it(tmp_path: Path) -> None:
    path = repo_data(f"{CARMEN_DIR}/aces-corrected.log.gz")
    log = read_carmen_log(path, max_scans=60)
    spec = SessionSpec(path, map_period_s=30.0, resolution_m=0.1)
    grids = list(session_grids(log, spec))
    written = write_carmen_session(
        log,
        tmp_path / "s.mcap",
        options=SessionOptions(map_period_s=30.0, builder_params=BuilderParams(resolution_m=0.1)),
    )
    assert grids[-1].resolution_m == 0.1
    np.testing.assert_array_equal(grids[-1].grid, written.final_grid)
    # ... and the cases of the benchmark carry the cell size.
    cases = break_cases(
        [path], levels=(1.0,), start_fractions=(0.5,), seeds=(0,), max_scans=60, resolution_m=0.1
    )
    assert {case.spec.resolution_m for case in cases} == {0.1}
    # The drifted case's region is checked against the correct session at its own cell size.
    scores = score_case(cases[1], structure_scores=False)
    truth = _correct_session(path, 30.0, 60, 0.1)
    assert truth[-1].resolution_m == 0.1 and len(truth) == len(scores.times_s)


def test_a_real_break_is_found_near_its_start_and_in_place() -> None:
    path = repo_data(f"{CARMEN_DIR}/freiburg-101-corrected.log.gz")
    # The first 140 scans (about 430 s) hold the start at a quarter of them and 150 s after it.
    cases = break_cases([path], levels=(4.0,), start_fractions=(0.25,), seeds=(0,), max_scans=140)
    correct, drifted = (score_case(c, structure_scores=False) for c in cases)
    assert not outcome(correct, 1.25).false_alarm
    found = outcome(drifted, 1.25)
    assert found.detected and found.delay_s <= 150.0
    assert found.index is not None and drifted.region_hits[found.index] >= 0.5
