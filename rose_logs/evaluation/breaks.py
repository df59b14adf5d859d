"""Experiment 4 (ours): does the break detector find breaks that start mid-session, when and where?

Sessions are replayed in memory from the Radish logs (:mod:`rose_logs.evaluation.break_sessions`):
per log the correct session (corrected poses) and sessions whose odometry starts drifting at a
fraction of the log (drift levels x start fractions x seeds). Every snapshot gets

- the break score of :class:`rose_logs.session.breaks.BreakDetector` against the previous snapshot.
  Until a detector fires, its trusted snapshot *is* the previous one, so the first alarm of a detector
  with threshold ``t`` is the first snapshot whose score here is ``>= t``: one pass gives the whole
  ROC over the threshold;
- the paper's global W (:func:`rose.analyze`), scored the same way (first snapshot with W ``>= t``);
- a check of the region: the share of the contradicted cells inside the reported region that the
  drift made: erased walls that the correct session's map at the same time still has, and risen
  evidence where that map is free.

Outcomes at a threshold: a correct session with any alarm is a false alarm; a drifted session with
an alarm before the drift starts is a false alarm too; otherwise its first alarm after the start is a
detection, ``delay_s`` after the start.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

import rose
from rose.breaks import erased_walls, placed_grid, risen_evidence
from rose.params import RoseParams
from rose_logs.carmen.parse import CarmenLog, read_carmen_log
from rose_logs.evaluation.break_sessions import (
    SessionGrid,
    SessionSpec,
    log_clock_ns,
    session_grids,
)
from rose_logs.session.breaks import BreakDetector, BreakParams
from rose_logs.snapshots import MapSnapshot

__all__ = [
    "DELAY_TARGET_S",
    "BreakCase",
    "BreakOutcome",
    "CostSummary",
    "GroupRow",
    "HeldOutRow",
    "SessionScores",
    "break_cases",
    "cost_summary",
    "group_table",
    "leave_one_log_out",
    "outcome",
    "quiet_threshold",
    "roc",
    "score_case",
    "score_cases",
]

_LOG = logging.getLogger(__name__)

DELAY_TARGET_S = 150.0
"""The issue's target: a break of level >= 2 found within this many seconds of its start."""


@dataclass(frozen=True)
class BreakCase:
    """One session of the experiment.

    Attributes
    ----------
    spec : SessionSpec
        Log, drift level, start (seconds), seed, period.
    start_fraction : float
        Drift start as a fraction of the log's duration (0 for a correct session).
    duration_s : float
        Length of the log on the session clock, seconds.
    """

    spec: SessionSpec
    start_fraction: float
    duration_s: float

    @property
    def correct(self) -> bool:
        """True for a session on the corrected poses."""
        return self.spec.drift_level == 0

    @property
    def label(self) -> str:
        """``log L<level> @<fraction> s<seed>``."""
        s = self.spec
        if self.correct:
            return f"{s.name} correct"
        return f"{s.name} L{s.drift_level:g} @{self.start_fraction:g} s{s.drift_seed}"


@dataclass(frozen=True, eq=False)
class SessionScores:
    """Per-snapshot scores of one session (snapshot 0 is never scored: nothing to compare with).

    Attributes
    ----------
    case : BreakCase
    times_s : ndarray of float64, shape (N,)
        Snapshot times since the first scan, seconds.
    break_scores_m : ndarray of float64, shape (N,)
        Break score against the previous snapshot, metres (0 for snapshot 0).
    structure_scores : ndarray of float64, shape (N,)
        Global W.
    regions_m : tuple of (tuple of float or None)
        Region of each snapshot's score, map frame, metres.
    region_hits : ndarray of float64, shape (N,)
        Share of the contradicted cells in the region that the drift made (NaN when
        no region, or for correct sessions).
    detector_s, rose_s : ndarray of float64, shape (N,)
        CPU time (``time.process_time``) of the detector's update and of :func:`rose.analyze` per
        snapshot, seconds.
    grid_cells : ndarray of int64, shape (N,)
        Cells per snapshot.
    """

    case: BreakCase
    times_s: npt.NDArray[np.float64]
    break_scores_m: npt.NDArray[np.float64]
    structure_scores: npt.NDArray[np.float64]
    regions_m: tuple[tuple[float, float, float, float] | None, ...]
    region_hits: npt.NDArray[np.float64]
    detector_s: npt.NDArray[np.float64]
    rose_s: npt.NDArray[np.float64]
    grid_cells: npt.NDArray[np.int64]


@dataclass(frozen=True)
class BreakOutcome:
    """What a detector with one threshold does on one session.

    Attributes
    ----------
    false_alarm : bool
        An alarm on a correct session, or before the drift started.
    detected : bool
        A drifted session's first alarm came after the start.
    delay_s : float
        Seconds from the drift start to that alarm (inf when not detected).
    index : int or None
        Snapshot of the first alarm.
    """

    false_alarm: bool
    detected: bool
    delay_s: float
    index: int | None


@functools.lru_cache(maxsize=2)
def _log(path: Path, max_scans: int | None = None) -> CarmenLog:
    return read_carmen_log(path, max_scans=max_scans)


@functools.lru_cache(maxsize=1)
def _correct_session(
    path: Path, map_period_s: float, max_scans: int | None, resolution_m: float
) -> tuple[SessionGrid, ...]:
    spec = SessionSpec(
        path, map_period_s=map_period_s, max_scans=max_scans, resolution_m=resolution_m
    )
    return tuple(session_grids(_log(path, max_scans), spec))


def break_cases(
    log_paths: Sequence[Path],
    *,
    levels: Sequence[float] = (1.0, 2.0, 4.0),
    start_fractions: Sequence[float] = (0.25, 0.5),
    seeds: Sequence[int] = (0, 1, 2),
    map_period_s: float = 30.0,
    max_scans: int | None = None,
    resolution_m: float = 0.05,
) -> list[BreakCase]:
    """The correct session and every drifted session of each log, in a fixed order (``max_scans``:
    only the first scans of each log; ``resolution_m``: the maps' cell size)."""
    cases = []
    for path in log_paths:
        clock = log_clock_ns(_log(Path(path), max_scans))
        duration = float(clock[-1]) / 1e9
        correct = SessionSpec(
            Path(path), map_period_s=map_period_s, max_scans=max_scans, resolution_m=resolution_m
        )
        cases.append(BreakCase(correct, 0.0, duration))
        for level in levels:
            for fraction in start_fractions:
                for seed in seeds:
                    spec = SessionSpec(
                        Path(path),
                        drift_level=float(level),
                        drift_start_s=round(duration * fraction, 3),
                        drift_seed=int(seed),
                        map_period_s=map_period_s,
                        max_scans=max_scans,
                        resolution_m=resolution_m,
                    )
                    cases.append(BreakCase(spec, float(fraction), duration))
    return cases


def _snapshot(grid: SessionGrid) -> MapSnapshot:
    x, y = grid.origin_xy_m
    return MapSnapshot(
        topic="/map",
        log_time_ns=grid.time_ns,
        stamp_ns=grid.time_ns,
        frame_id="map",
        grid=grid.grid,
        resolution_m=grid.resolution_m,
        origin_position_m=(x, y, 0.0),
    )


def _offset(a: SessionGrid, b: SessionGrid) -> tuple[int, int]:
    """(row, col) of ``a``'s cell (0, 0) in ``b``."""
    res = b.resolution_m
    return (
        round((a.origin_xy_m[1] - b.origin_xy_m[1]) / res),
        round((a.origin_xy_m[0] - b.origin_xy_m[0]) / res),
    )


def _region_hit(
    detector: BreakDetector,
    trusted: SessionGrid,
    current: SessionGrid,
    truth: SessionGrid,
    region_m: tuple[float, float, float, float],
) -> float:
    """Share of the contradicted cells inside the region that the drift made: erased walls that
    the correct map keeps as walls, and risen evidence where the correct map is free."""
    p = detector.params
    res = current.resolution_m
    cells = p.in_cells(res)
    pieces = {
        "min_extent_px": cells.min_extent_px,
        "bridge_px": cells.bridge_px,
        "free_threshold": p.free_threshold,
    }
    walls = {
        "tolerance_px": cells.tolerance_px,
        "occupied_threshold": p.occupied_threshold,
        **pieces,
    }
    rises = {"rise_points": p.rise_points, "rise_margin_px": cells.rise_margin_px, **pieces}
    from_trusted, from_truth = _offset(trusted, current), _offset(truth, current)
    erased = erased_walls(trusted.grid, current.grid, offset_px=from_trusted, **walls)
    lost = erased_walls(truth.grid, current.grid, offset_px=from_truth, **walls)
    risen = risen_evidence(trusted.grid, current.grid, offset_px=from_trusted, **rises)
    truth_placed = placed_grid(truth.grid, current.grid.shape, from_truth)
    truly_free = (truth_placed >= 0) & (truth_placed <= p.free_threshold)
    x0, y0, x1, y1 = region_m
    ox, oy = current.origin_xy_m
    c0, c1 = math.floor((x0 - ox) / res + 1e-6), math.ceil((x1 - ox) / res - 1e-6)
    r0, r1 = math.floor((y0 - oy) / res + 1e-6), math.ceil((y1 - oy) / res - 1e-6)
    box = (slice(r0, r1), slice(c0, c1))
    total = int(np.count_nonzero(erased[box] | risen[box]))
    if total == 0:
        return math.nan
    made = (erased[box] & lost[box]) | (risen[box] & truly_free[box])
    return float(np.count_nonzero(made)) / total


def score_case(
    case: BreakCase,
    *,
    break_params: BreakParams | None = None,
    rose_params: RoseParams | None = None,
    structure_scores: bool = True,
) -> SessionScores:
    """Replay one session and score every snapshot (see module notes).

    ``structure_scores=False`` skips ROSE: W is NaN and ``rose_s`` 0.
    """
    log = _log(case.spec.log_path, case.spec.max_scans)
    params = break_params if break_params is not None else BreakParams()
    # An infinite threshold keeps the previous snapshot trusted: every score is against it.
    detector = BreakDetector(dataclasses.replace(params, threshold_m=math.inf))
    rose_params = rose_params if rose_params is not None else RoseParams()
    truth: tuple[SessionGrid, ...] = ()
    if not case.correct:
        spec = case.spec
        truth = _correct_session(
            spec.log_path, spec.map_period_s, spec.max_scans, spec.resolution_m
        )
    times, scores, w, regions, hits, det_s, rose_s, cells = [], [], [], [], [], [], [], []
    previous: SessionGrid | None = None
    for i, grid in enumerate(session_grids(log, case.spec)):
        t0 = time.process_time()  # CPU time: wall time is meaningless on a shared machine
        verdict = detector.update(_snapshot(grid))
        t1 = time.process_time()
        w_i = math.nan
        if structure_scores:
            w_i = float(rose.analyze(grid.grid, rose_params).structure_score)
        t2 = time.process_time()
        hit = math.nan
        if verdict.region_m is not None and previous is not None and i < len(truth):
            hit = _region_hit(detector, previous, grid, truth[i], verdict.region_m)
        times.append(grid.time_ns / 1e9)
        scores.append(verdict.score_m)
        w.append(w_i)
        regions.append(verdict.region_m)
        hits.append(hit)
        det_s.append(t1 - t0)
        rose_s.append(t2 - t1)
        cells.append(grid.grid.size)
        previous = grid
    _LOG.info("%s: %d snapshots", case.label, len(times))
    return SessionScores(
        case=case,
        times_s=np.array(times),
        break_scores_m=np.array(scores),
        structure_scores=np.array(w),
        regions_m=tuple(regions),
        region_hits=np.array(hits),
        detector_s=np.array(det_s),
        rose_s=np.array(rose_s),
        grid_cells=np.array(cells, dtype=np.int64),
    )


def _score_one(args: tuple[BreakCase, BreakParams | None, RoseParams | None]) -> SessionScores:
    case, bp, rp = args
    return score_case(case, break_params=bp, rose_params=rp)


def score_cases(
    cases: Sequence[BreakCase],
    *,
    break_params: BreakParams | None = None,
    rose_params: RoseParams | None = None,
    workers: int = 1,
) -> list[SessionScores]:
    """:func:`score_case` for every case, in order (``workers`` > 1: in that many processes)."""
    jobs = [(c, break_params, rose_params) for c in cases]
    if workers <= 1:
        return [_score_one(j) for j in jobs]
    with ProcessPoolExecutor(workers) as pool:
        return list(pool.map(_score_one, jobs, chunksize=1))


def outcome(
    scores: SessionScores, threshold: float, *, values: npt.NDArray[np.float64] | None = None
) -> BreakOutcome:
    """What a detector firing at ``values >= threshold`` does (default values: the break scores)."""
    v = scores.break_scores_m if values is None else values
    fired = np.flatnonzero(v[1:] >= threshold) + 1  # snapshot 0 has nothing to compare with
    if fired.size == 0:
        return BreakOutcome(False, False, math.inf, None)
    first = int(fired[0])
    if scores.case.correct:
        return BreakOutcome(True, False, math.inf, first)
    start = scores.case.spec.drift_start_s
    if scores.times_s[first] < start:
        return BreakOutcome(True, False, math.inf, first)
    return BreakOutcome(False, True, float(scores.times_s[first] - start), first)


def roc(
    sessions: Sequence[SessionScores], *, use_w: bool = False
) -> list[tuple[float, float, float, float]]:
    """``(threshold, false-alarm rate, detection rate, detection rate within 150 s)`` per threshold.

    The false-alarm rate is over correct sessions; detection rates over drifted sessions. Thresholds
    are every distinct score (plus infinity: never fire), in increasing order.
    """

    def values(s: SessionScores) -> npt.NDArray[np.float64]:
        return s.structure_scores if use_w else s.break_scores_m

    thresholds = sorted({float(x) for s in sessions for x in values(s)[1:]} | {math.inf})
    correct = [s for s in sessions if s.case.correct]
    drifted = [s for s in sessions if not s.case.correct]
    rows = []
    for t in thresholds:
        fa = [outcome(s, t, values=values(s)).false_alarm for s in correct]
        out = [outcome(s, t, values=values(s)) for s in drifted]
        rows.append(
            (
                t,
                float(np.mean(fa)) if fa else math.nan,
                float(np.mean([o.detected for o in out])) if out else math.nan,
                float(np.mean([o.delay_s <= DELAY_TARGET_S for o in out])) if out else math.nan,
            )
        )
    return rows


@dataclass(frozen=True)
class GroupRow:
    """Outcomes of one group of sessions (a drift level and start fraction) at one threshold.

    Attributes
    ----------
    level, start_fraction : float
        Drift level and start (0, 0: the correct sessions).
    sessions : int
    false_alarms : int
        Sessions with an alarm before the drift start (every alarm, for correct sessions).
    detected : int
        Drifted sessions whose first alarm came after the start.
    within_target : int
        Of those, detected within :data:`DELAY_TARGET_S`.
    median_delay_s, max_delay_s : float
        Over the detected sessions (NaN when none).
    region_hits : int
        Detections whose region holds mostly (>= 50 %) walls the correct map keeps.
    """

    level: float
    start_fraction: float
    sessions: int
    false_alarms: int
    detected: int
    within_target: int
    median_delay_s: float
    max_delay_s: float
    region_hits: int


def _values(s: SessionScores, use_w: bool) -> npt.NDArray[np.float64]:
    return s.structure_scores if use_w else s.break_scores_m


def group_table(
    sessions: Sequence[SessionScores], threshold: float, *, use_w: bool = False
) -> list[GroupRow]:
    """One :class:`GroupRow` per (level, start fraction), correct sessions first."""
    keys = sorted({(s.case.spec.drift_level, s.case.start_fraction) for s in sessions})
    rows = []
    for level, fraction in keys:
        group = [
            s
            for s in sessions
            if (s.case.spec.drift_level, s.case.start_fraction) == (level, fraction)
        ]
        outs = [(s, outcome(s, threshold, values=_values(s, use_w))) for s in group]
        delays = [o.delay_s for _, o in outs if o.detected]
        hits = sum(
            1
            for s, o in outs
            if o.detected and o.index is not None and s.region_hits[o.index] >= 0.5
        )
        rows.append(
            GroupRow(
                level=level,
                start_fraction=fraction,
                sessions=len(group),
                false_alarms=sum(o.false_alarm for _, o in outs),
                detected=len(delays),
                within_target=sum(d <= DELAY_TARGET_S for d in delays),
                median_delay_s=float(np.median(delays)) if delays else math.nan,
                max_delay_s=float(np.max(delays)) if delays else math.nan,
                region_hits=0 if use_w else hits,
            )
        )
    return rows


def quiet_threshold(sessions: Sequence[SessionScores], *, use_w: bool = False) -> float:
    """The smallest threshold that raises no false alarm on ``sessions`` (just above the largest
    score of a correct session or of a drifted one before its start)."""
    top = 0.0
    for s in sessions:
        v = _values(s, use_w)[1:]
        if not s.case.correct:
            v = v[s.times_s[1:] < s.case.spec.drift_start_s]
        if v.size:
            top = max(top, float(v.max()))
    return float(np.nextafter(top, math.inf))


@dataclass(frozen=True)
class HeldOutRow:
    """Leave-one-log-out: the threshold chosen on the other logs, applied to one log.

    Attributes
    ----------
    log : str
    threshold : float
        :func:`quiet_threshold` of the other logs' sessions.
    false_alarms : int
        Sessions of this log with a false alarm at that threshold.
    drifted, detected, within_target : int
        Drifted sessions of this log, detected, detected within :data:`DELAY_TARGET_S`.
    """

    log: str
    threshold: float
    false_alarms: int
    drifted: int
    detected: int
    within_target: int


def leave_one_log_out(
    sessions: Sequence[SessionScores], *, use_w: bool = False
) -> list[HeldOutRow]:
    """For each log: the quiet threshold of the other logs, and what it does on this log."""
    logs = list(dict.fromkeys(s.case.spec.name for s in sessions))
    rows = []
    for log in logs:
        train = [s for s in sessions if s.case.spec.name != log]
        test = [s for s in sessions if s.case.spec.name == log]
        if not train:
            continue
        threshold = quiet_threshold(train, use_w=use_w)
        outs = [(s, outcome(s, threshold, values=_values(s, use_w))) for s in test]
        rows.append(
            HeldOutRow(
                log=log,
                threshold=threshold,
                false_alarms=sum(o.false_alarm for _, o in outs),
                drifted=sum(not s.case.correct for s, _ in outs),
                detected=sum(o.detected for _, o in outs),
                within_target=sum(o.delay_s <= DELAY_TARGET_S for _, o in outs),
            )
        )
    return rows


@dataclass(frozen=True)
class CostSummary:
    """What the detector costs beside ROSE, CPU seconds per snapshot (snapshot 0 excluded).

    Attributes
    ----------
    snapshots : int
    detector_median_s, rose_median_s : float
        Median CPU time per snapshot.
    ratio_of_totals : float
        Total detector time / total ROSE time.
    ratio_p90 : float
        90th percentile of the per-snapshot ratio.
    """

    snapshots: int
    detector_median_s: float
    rose_median_s: float
    ratio_of_totals: float
    ratio_p90: float


def cost_summary(sessions: Sequence[SessionScores]) -> CostSummary:
    """:class:`CostSummary` over every scored snapshot."""
    det = np.concatenate([np.zeros(0), *(s.detector_s[1:] for s in sessions)])
    ros = np.concatenate([np.zeros(0), *(s.rose_s[1:] for s in sessions)])
    if det.size == 0:  # sessions of one snapshot each (a log shorter than a map period)
        return CostSummary(0, math.nan, math.nan, math.nan, math.nan)
    ratio = det / np.maximum(ros, 1e-9)
    return CostSummary(
        snapshots=int(det.size),
        detector_median_s=float(np.median(det)),
        rose_median_s=float(np.median(ros)),
        ratio_of_totals=float(det.sum() / max(ros.sum(), 1e-12)),
        ratio_p90=float(np.percentile(ratio, 90)),
    )
