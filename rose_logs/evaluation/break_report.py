"""Experiment 4 in the evaluation report: break detection tables, CSV files and figures."""

from __future__ import annotations

import csv
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rose.directions import FAILURE_LEVEL
from rose_logs.evaluation.break_sessions import session_grids
from rose_logs.evaluation.breaks import (
    DELAY_TARGET_S,
    GroupRow,
    SessionScores,
    break_cases,
    cost_summary,
    group_table,
    leave_one_log_out,
    outcome,
    quiet_threshold,
    roc,
    score_cases,
)
from rose_logs.evaluation.files import save_figure, text_file
from rose_logs.session.breaks import BreakParams

__all__ = ["BreakSection", "run_break_experiment"]

_LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class BreakSection:
    """What :func:`run_break_experiment` wrote.

    Attributes
    ----------
    markdown : str
        The report section.
    files : tuple of Path
        CSV tables and PNG figures.
    sessions : tuple of SessionScores
        The scored sessions.
    """

    markdown: str
    files: tuple[Path, ...]
    sessions: tuple[SessionScores, ...]


def _fmt_s(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{value:.0f}"


def _group_lines(rows: Sequence[GroupRow], *, regions: bool) -> list[str]:
    head = "| drift level | start | sessions | false alarms | detected | within 150 s | median delay s | max delay s |"
    sep = "|---:|---:|---:|---:|---:|---:|---:|---:|"
    if regions:
        head += " region right |"
        sep += "---:|"
    lines = [head, sep]
    for r in rows:
        level = "correct" if r.level == 0 else f"{r.level:g}"
        start = "-" if r.level == 0 else f"{r.start_fraction:g}"
        line = (
            f"| {level} | {start} | {r.sessions} | {r.false_alarms} | {r.detected} | "
            f"{r.within_target} | {_fmt_s(r.median_delay_s)} | {_fmt_s(r.max_delay_s)} |"
        )
        if regions:
            line += f" {r.region_hits} |"
        lines.append(line)
    return lines


def _write_sessions_csv(path: Path, sessions: Sequence[SessionScores], threshold: float) -> Path:
    with text_file(path) as fh:
        writer = csv.writer(fh)
        writer.writerow(
            [
                "log",
                "drift_level",
                "start_fraction",
                "drift_start_s",
                "seed",
                "snapshots",
                "false_alarm",
                "detected",
                "delay_s",
                "alarm_index",
                "region_hit",
                "break_score_max_m",
                "w_max",
                "w_delay_s_at_0_4",
            ]
        )
        for s in sessions:
            o = outcome(s, threshold)
            w = outcome(s, FAILURE_LEVEL, values=s.structure_scores)
            hit = s.region_hits[o.index] if o.index is not None else math.nan
            writer.writerow(
                [
                    s.case.spec.name,
                    s.case.spec.drift_level,
                    s.case.start_fraction,
                    s.case.spec.drift_start_s,
                    s.case.spec.drift_seed,
                    s.times_s.size,
                    o.false_alarm,
                    o.detected,
                    o.delay_s,
                    "" if o.index is None else o.index,
                    hit,
                    float(s.break_scores_m.max()),
                    float(s.structure_scores.max()),
                    w.delay_s,
                ]
            )
    return path


def _write_roc_csv(path: Path, sessions: Sequence[SessionScores]) -> Path:
    with text_file(path) as fh:
        writer = csv.writer(fh)
        writer.writerow(["score", "threshold", "false_alarm_rate", "detection_rate", "within_150s"])
        for use_w, name in ((False, "break_score_m"), (True, "global_w")):
            for row in roc(sessions, use_w=use_w):
                writer.writerow([name, *row])
    return path


def _roc_figure(path: Path, sessions: Sequence[SessionScores], threshold: float) -> Path:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    for use_w, label, color in ((False, "break score", "C3"), (True, "global W (paper)", "C0")):
        rows = roc(sessions, use_w=use_w)
        fa = [r[1] for r in rows]
        ax.step(fa, [r[2] for r in rows], where="post", color=color, label=f"{label}: detected")
        ax.step(
            fa, [r[3] for r in rows], where="post", color=color, ls="--", label=f"{label}: <= 150 s"
        )
    o = [outcome(s, threshold) for s in sessions if not s.case.correct]
    fa_default = np.mean([outcome(s, threshold).false_alarm for s in sessions if s.case.correct])
    ax.plot(
        [fa_default], [np.mean([x.detected for x in o])], "ko", label=f"default {threshold:g} m"
    )
    ax.set_xlabel("false-alarm rate (correct sessions)")
    ax.set_ylabel("detection rate (drifted sessions)")
    ax.set_xlim(-0.02, 1.02)
    ax.set_ylim(-0.02, 1.02)
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title("ROC over the threshold")
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def _example_figure(path: Path, scores: SessionScores, threshold: float) -> Path | None:
    """The map at the first alarm with the region, beside the score and W over time."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    o = outcome(scores, threshold)
    region = None if o.index is None else scores.regions_m[o.index]
    if o.index is None or region is None:
        return None
    spec = scores.case.spec
    from rose_logs.evaluation.breaks import _log  # the cached parsed log

    grids = list(session_grids(_log(spec.log_path, spec.max_scans), spec))
    snap = grids[o.index]
    res = snap.resolution_m
    rows, cols = snap.grid.shape
    ox, oy = snap.origin_xy_m
    image = np.where(snap.grid < 0, 0.75, 1.0 - snap.grid / 100.0)
    fig, (ax_map, ax_t) = plt.subplots(1, 2, figsize=(12, 5.5), width_ratios=(1.1, 1.0))
    ax_map.imshow(
        image,
        origin="lower",
        cmap="gray",
        vmin=0,
        vmax=1,
        extent=(ox, ox + cols * res, oy, oy + rows * res),
    )
    x0, y0, x1, y1 = region
    pad = 0.5
    ax_map.add_patch(
        Rectangle(
            (x0 - pad, y0 - pad), x1 - x0 + 2 * pad, y1 - y0 + 2 * pad, fill=False, ec="red", lw=2
        )
    )
    ax_map.set_title(
        f"{scores.case.label}: snapshot {o.index} at {scores.times_s[o.index]:.0f} s "
        f"(drift from {spec.drift_start_s:.0f} s)",
        fontsize=9,
    )
    known = np.argwhere(snap.grid >= 0)
    if known.size:
        (r0, c0), (r1, c1) = known.min(axis=0), known.max(axis=0)
        ax_map.set_xlim(ox + c0 * res - 1, ox + (c1 + 1) * res + 1)
        ax_map.set_ylim(oy + r0 * res - 1, oy + (r1 + 1) * res + 1)
    ax_map.set_xlabel("x, m")
    ax_map.set_ylabel("y, m")
    ax_t.plot(
        scores.times_s, scores.break_scores_m, "C3.-", label="break score vs previous snapshot"
    )
    ax_t.axhline(threshold, color="C3", ls=":", label=f"threshold {threshold:g} m")
    ax_t.axvline(spec.drift_start_s, color="k", ls="--", label="drift starts")
    ax_t.set_xlabel("session time, s")
    ax_t.set_ylabel("break score (map contradicted), m")
    ax_w = ax_t.twinx()
    ax_w.plot(scores.times_s, scores.structure_scores, "C0.-", label="global W")
    ax_w.set_ylabel("W")
    ax_w.set_ylim(0, max(0.45, float(scores.structure_scores.max()) * 1.1))
    ax_w.axhline(FAILURE_LEVEL, color="C0", ls=":")
    lines = ax_t.get_legend_handles_labels()
    lines_w = ax_w.get_legend_handles_labels()
    ax_t.legend(lines[0] + lines_w[0], lines[1] + lines_w[1], fontsize=8, loc="upper left")
    fig.tight_layout()
    return save_figure(fig, path, dpi=100)


def _pick_example(sessions: Sequence[SessionScores], threshold: float) -> SessionScores | None:
    """A level-4 session started at half time, detected, with the region right (first such)."""
    for s in sessions:
        o = outcome(s, threshold)
        if (
            s.case.spec.drift_level >= 4
            and o.detected
            and o.index is not None
            and s.region_hits[o.index] >= 0.5
            and s.case.start_fraction >= 0.5
        ):
            return s
    return next((s for s in sessions if outcome(s, threshold).detected), None)


def run_break_experiment(
    log_paths: Sequence[Path],
    out_dir: Path,
    *,
    seeds: int = 3,
    levels: Sequence[float] = (1.0, 2.0, 4.0),
    start_fractions: Sequence[float] = (0.25, 0.5),
    map_period_s: float = 30.0,
    break_params: BreakParams | None = None,
    workers: int = 1,
    plots: bool = True,
) -> BreakSection:
    """Score the sessions, write ``exp4_breaks_sessions.csv``, ``exp4_breaks_roc.csv`` and figures,
    and return the markdown section."""
    params = break_params if break_params is not None else BreakParams()
    cases = break_cases(
        log_paths,
        levels=levels,
        start_fractions=start_fractions,
        seeds=range(seeds),
        map_period_s=map_period_s,
    )
    sessions = score_cases(cases, break_params=params, workers=workers)
    threshold = params.threshold_m
    files = [
        _write_sessions_csv(out_dir / "exp4_breaks_sessions.csv", sessions, threshold),
        _write_roc_csv(out_dir / "exp4_breaks_roc.csv", sessions),
    ]
    figures = []
    if plots:
        figures.append(_roc_figure(out_dir / "exp4_breaks_roc.png", sessions, threshold))
        example = _pick_example(sessions, threshold)
        if example is not None:
            fig = _example_figure(out_dir / "exp4_break_example.png", example, threshold)
            if fig is not None:
                figures.append(fig)
    files.extend(figures)
    w_quiet = quiet_threshold(sessions, use_w=True)
    cost = cost_summary(sessions)
    md = [
        "## Experiment 4 (ours): finding breaks that start mid-session",
        "",
        f"Sessions replayed from the logs as `rose-bag convert --map-period {map_period_s:g}` writes "
        f"them: the correct session of each log and drift levels {', '.join(f'{x:g}' for x in levels)} "
        f"starting at {', '.join(f'{x:g}' for x in start_fractions)} of the log, {seeds} seed(s) each "
        f"({len(sessions)} sessions). Break detector: tolerance {params.tolerance_m:g} m, "
        f"walls >= {params.min_wall_m:g} m (gaps <= {params.bridge_m:g} m bridged), "
        f"risen evidence >= {params.rise_points} points at >= {params.rise_margin_m:g} m from "
        f"walls and unknown space, "
        f"tiles {params.tile_m:g} m, window {params.window_m:g} m, threshold {threshold:g} m. "
        "A false alarm is an alarm on a correct session or before the drift starts; delays are from "
        f"the drift start to the first alarm (target: level >= 2 within {DELAY_TARGET_S:g} s). "
        "'Region right': at least half of the contradicted cells in the reported region are the "
        "drift's doing: erased walls the correct session's map still has at that time, or risen "
        "evidence where that map is free.",
        "",
        f"### Break score, threshold {threshold:g} m",
        "",
        *_group_lines(group_table(sessions, threshold), regions=True),
        "",
        f"### The paper's global W at its failure level {FAILURE_LEVEL:g}",
        "",
        *_group_lines(group_table(sessions, FAILURE_LEVEL, use_w=True), regions=False),
        "",
        f"### Global W at the lowest level without false alarms here ({w_quiet:.3f})",
        "",
        *_group_lines(group_table(sessions, w_quiet, use_w=True), regions=False),
        "",
        "### Leave one log out",
        "",
    ]
    held_out = [
        (name, r)
        for use_w, name in ((False, "break score"), (True, "global W"))
        for r in leave_one_log_out(sessions, use_w=use_w)
    ]
    if held_out:
        md += [
            "The lowest threshold without false alarms on the other logs, applied to the held-out "
            "log.",
            "",
            "| held-out log | score | threshold | false alarms | drifted | detected | within 150 s |",
            "|---|---|---:|---:|---:|---:|---:|",
            *(
                f"| {r.log} | {name} | {r.threshold:.3f} | {r.false_alarms} | {r.drifted} | "
                f"{r.detected} | {r.within_target} |"
                for name, r in held_out
            ),
        ]
    else:  # a table of headers alone said nothing
        md.append("Needs sessions of two logs or more.")
    md += [
        "",
        f"Cost (CPU time per snapshot, {cost.snapshots} snapshots): detector median "
        f"{1e3 * cost.detector_median_s:.1f} ms, ROSE median {1e3 * cost.rose_median_s:.1f} ms; "
        f"detector / ROSE over all snapshots {100 * cost.ratio_of_totals:.1f} %.",
        "",
    ]
    md += [f"![{f.stem}]({f.name})" for f in figures]
    _LOG.info("experiment 4: %d sessions", len(sessions))
    return BreakSection("\n".join(md) + "\n", tuple(files), tuple(sessions))
