"""The cleaning benchmark as a section of the evaluation report: table, CSV, before / after figure."""

from __future__ import annotations

import csv
import dataclasses
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

import rose
from rose.cleaning import clean
from rose_logs.evaluation.cleaning import (
    CleaningCase,
    CleaningRun,
    CleaningSummary,
    bormann_cases,
    run_cleaning,
    summarise_cleaning,
)
from rose_logs.evaluation.config import EvaluationConfig
from rose_logs.evaluation.files import text_file, write_png

__all__ = [
    "CleaningReport",
    "cleaning_cases",
    "cleaning_experiment",
    "cleaning_figure",
    "render_cleaning",
    "summary_markdown",
]

_LOG = logging.getLogger(__name__)

#: Colours (BGR, for OpenCV) of the before / after figure.
_FREE, _UNKNOWN = (255, 255, 255), (200, 200, 200)
_WALL_KEPT, _WALL_LOST = (0, 0, 0), (255, 0, 255)
_CLUTTER_KEPT, _CLUTTER_GONE = (40, 40, 230), (150, 225, 150)
_OTHER = (120, 120, 120)
_COMPLETED = (230, 140, 30)


@dataclass(frozen=True)
class CleaningReport:
    """What :func:`cleaning_experiment` computed and wrote."""

    runs: tuple[CleaningRun, ...]
    summaries: tuple[CleaningSummary, ...]
    markdown: str
    files: tuple[Path, ...]


def cleaning_cases(config: EvaluationConfig, *, seeds: int = 1) -> list[CleaningCase]:
    """SLAM-like Bormann maps of ``config.benchmark_maps`` and ray-cast furniture in ``config.logs``."""
    from rose_logs.evaluation.raycast import raycast_case

    cases: list[CleaningCase] = []
    # Only with maps to clean: benchmark_dir looks the data set up, which an evaluation of no map
    # and no log (`--logs '' --maps ''`) does not need (it failed there, after the experiments).
    if config.benchmark_maps and config.benchmark_dir.is_dir():
        cases += bormann_cases(config.benchmark_dir, names=config.benchmark_maps)
    for log in config.logs:
        path = config.log_path(log)
        if not path.is_file():
            _LOG.warning("%s: missing, no ray-cast furniture case", path)
            continue
        for k in range(seeds):
            cases.append(raycast_case(path, seed=config.seed + k, resolution_m=config.resolution_m))
    return cases


def render_cleaning(
    case: CleaningCase,
    kept: npt.NDArray[np.bool_] | None,
    completed: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.uint8]:
    """BGR picture of a case (image rows top first): free white, unknown grey, and per occupied cell
    kept / removed wall and clutter colours (``kept`` None: the input, walls black, clutter red);
    ``completed`` walls (unknown cells the cleaning made walls) in blue."""
    grid = case.grid
    image = np.empty((*grid.shape, 3), dtype=np.uint8)
    image[:] = _UNKNOWN
    image[(grid >= 0) & (grid < 65)] = _FREE
    image[grid >= 65] = _OTHER
    if kept is None:
        image[case.walls] = _WALL_KEPT
        image[case.clutter] = _CLUTTER_KEPT
    else:
        image[case.walls & kept] = _WALL_KEPT
        image[case.walls & ~kept] = _WALL_LOST
        image[case.clutter & kept] = _CLUTTER_KEPT
        image[case.clutter & ~kept] = _CLUTTER_GONE
    if completed is not None:
        image[completed] = _COMPLETED
    return image[::-1].copy()


def cleaning_figure(
    case: CleaningCase,
    path: Path,
    *,
    width_px: int = 1400,
    window: tuple[float, float, float, float] | None = None,
) -> Path:
    """Input / paper / walls side by side (or stacked, for wide maps), labelled, ``width_px`` wide.

    ``window`` ``(top, bottom, left, right)`` crops the picture to fractions of the occupied cells'
    bounding box (image rows top first); the whole box when None.
    """
    import cv2

    result = rose.analyze(case.grid)
    panels = [("input: walls black, clutter red", render_cleaning(case, None))]
    for method in ("paper", "walls"):
        cleaned = clean(case.grid, result, method=method, resolution_m=case.resolution_m)
        panels.append((f"{method}", render_cleaning(case, cleaned.kept, cleaned.completed)))
    # Crop to the occupied cells (image rows are flipped: row 0 of the image is the last grid row).
    rows = np.flatnonzero(case.grid.max(axis=1) >= 65)
    cols = np.flatnonzero(case.grid.max(axis=0) >= 65)
    if rows.size:
        n = case.grid.shape[0]
        r0, r1 = max(n - 1 - int(rows[-1]) - 5, 0), min(n - int(rows[0]) + 5, n)
        c0, c1 = max(int(cols[0]) - 5, 0), int(cols[-1]) + 6
        if window is not None:
            top, bottom, left, right = window
            r0, r1 = r0 + round(top * (r1 - r0)), r0 + round(bottom * (r1 - r0))
            c0, c1 = c0 + round(left * (c1 - c0)), c0 + round(right * (c1 - c0))
        panels = [(label, image[r0:r1, c0:c1]) for label, image in panels]
    height, width = panels[0][1].shape[:2]
    stacked = width > 1.5 * height
    labelled = []
    for label, image in panels:
        scale = width_px / width if stacked else width_px / (len(panels) * width)
        interpolation = cv2.INTER_NEAREST if scale >= 1 else cv2.INTER_AREA
        resized = np.asarray(
            cv2.resize(image, None, fx=scale, fy=scale, interpolation=interpolation), np.uint8
        )
        band = np.full((26, resized.shape[1], 3), 255, np.uint8)
        cv2.putText(band, label, (6, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1)
        labelled.append(np.vstack([band, resized]))
    if stacked:
        picture = np.vstack(labelled)
    else:
        height = min(p.shape[0] for p in labelled)
        picture = np.hstack([p[:height] for p in labelled])
    return write_png(path, picture)


def _write_csv(path: Path, runs: Sequence[CleaningRun]) -> Path:
    with text_file(path) as fh:
        writer = csv.writer(fh)
        names = [f.name for f in dataclasses.fields(CleaningRun)] + ["time_ratio"]
        writer.writerow(names)
        for run in runs:
            writer.writerow([*dataclasses.astuple(run), run.time_ratio])
    return path


def _fmt(value: float) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.3f}"


def summary_markdown(summaries: Sequence[CleaningSummary]) -> list[str]:
    """Markdown table: medians (worst) per kind of map and method."""
    lines = [
        "| maps | method | n | wall recall | clutter removed | precision | robot gaps | time / analyze |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for s in summaries:
        lines.append(
            f"| {s.kind} | {s.method} | {s.maps} | {_fmt(s.wall_recall_median)} "
            f"({_fmt(s.wall_recall_worst)}) | {_fmt(s.clutter_removal_median)} "
            f"({_fmt(s.clutter_removal_worst)}) | {_fmt(s.precision_median)} "
            f"({_fmt(s.precision_worst)}) | {s.gaps_median:g} ({s.gaps_worst}) | "
            f"{s.time_ratio_median:.2f} ({s.time_ratio_worst:.2f}) |"
        )
    return lines


def cleaning_experiment(
    config: EvaluationConfig, out_dir: Path, *, seeds: int = 1
) -> CleaningReport:
    """Run the cleaning benchmark, write ``cleaning_runs.csv`` and, unless ``config.plots`` is off,
    ``cleaning_before_after.png``."""
    out = Path(out_dir)
    cases = cleaning_cases(config, seeds=seeds)
    runs = run_cleaning(cases)
    summaries = summarise_cleaning(runs)
    files = [_write_csv(out / "cleaning_runs.csv", runs)]
    figure = None
    shown = next((c for c in cases if c.kind == "raycast"), cases[0] if cases else None)
    if shown is not None and config.plots:
        figure = cleaning_figure(shown, out / "cleaning_before_after.png")
        files.append(figure)
    lines = [
        "## Cleaning: walls kept, clutter removed, no gaps (`rose.clean`)",
        "",
        "SLAM-like Bormann buildings (outside, thick walls and furniture hollowed to the 2-cell layer "
        "a scanner sees) and CARMEN logs re-rendered with ray-cast virtual furniture (faces only, "
        "unknown shadows behind). Wall recall: wall cells kept; clutter removed: clutter cells "
        "removed; precision: kept cells that are walls; robot gaps: erased wall patches a 0.15 m "
        "disc passes through between regions the walls kept apart; time: analyze + cleaning over "
        "analyze. Median (worst) per kind of map.",
        "",
        *summary_markdown(summaries),
        "",
    ]
    if figure is not None and shown is not None:
        lines += [
            f"Before / after on `{shown.name}` (walls kept black, walls lost magenta, clutter kept "
            "red, clutter removed green, hidden walls completed blue):",
            "",
            f"![cleaning before and after]({figure.name})",
            "",
        ]
    lines += ["Per map: `cleaning_runs.csv`.", ""]
    return CleaningReport(tuple(runs), tuple(summaries), "\n".join(lines), tuple(files))
