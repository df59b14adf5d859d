"""Run the whole evaluation and write the report folder: markdown, CSV tables, PNG figures."""

from __future__ import annotations

import csv
import dataclasses
import logging
import math
import platform
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np

import rose
import rose_logs
from rose_logs.carmen.parse import read_carmen_log
from rose_logs.evaluation.cleaning_report import cleaning_experiment
from rose_logs.evaluation.config import PAPER_W, EvaluationConfig
from rose_logs.evaluation.experiments import (
    ClutterRun,
    DriftRun,
    Experiment3,
    correlation,
    run_clutter_experiment,
    run_drift_experiment,
    run_furniture_experiment,
    source_maps,
)
from rose_logs.evaluation.figures import have_matplotlib, plot_all, render_grid
from rose_logs.evaluation.files import text_file, write_bytes, write_png
from rose_logs.evaluation.maps import LogMap, furniture_pair
from rose_logs.evaluation.walls import WallReport, wall_experiment

__all__ = ["MARKDOWN_NAME", "EvaluationReport", "run_evaluation"]

_LOG = logging.getLogger(__name__)

MARKDOWN_NAME = "report.md"
"""The report's markdown file in its folder (the tables and figures sit beside it)."""


@dataclass(frozen=True)
class EvaluationReport:
    """What :func:`run_evaluation` wrote and its headline numbers.

    Attributes
    ----------
    out_dir : Path
        The report folder.
    markdown_path : Path
        ``report.md`` inside it.
    files : tuple of Path
        Every file written (markdown, CSV, PNG).
    run_s : float
        Wall time of the whole evaluation, seconds.
    median_by_map : dict
        Map name -> (median precision, median recall) of experiment 1.
    w_by_log : dict
        Log name -> (W with corrected poses, median W of the drifted maps).
    r_all : float
        Experiment 3: Pearson R between W and precision over all experiment-1 runs.
    """

    out_dir: Path
    markdown_path: Path
    files: tuple[Path, ...]
    run_s: float
    median_by_map: dict[str, tuple[float, float]]
    w_by_log: dict[str, tuple[float, float]]
    r_all: float


def _median(values: Sequence[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.median(finite)) if finite else math.nan


def _fmt(value: float, digits: int = 3) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.{digits}f}"


def _pct(value: float) -> str:
    return "n/a" if not math.isfinite(value) else f"{100 * value:.1f} %"


def _write_csv(path: Path, rows: Sequence[Any]) -> Path:
    with text_file(path) as fh:
        if not rows:
            fh.write("")
            return path
        fields = [f.name for f in dataclasses.fields(rows[0])]
        writer = csv.DictWriter(fh, fieldnames=fields)
        writer.writeheader()
        for row in rows:
            writer.writerow(dataclasses.asdict(row))
    return path


def _group_table(runs: Sequence[ClutterRun], key: str, title: str) -> list[str]:
    groups = list(dict.fromkeys(getattr(r, key) for r in runs))
    if key in ("size_px", "count"):
        groups = sorted(groups)
    lines = [
        f"| {title} | runs | median precision | median recall | median clutter recall | median W |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for g in groups:
        sub = [r for r in runs if getattr(r, key) == g]
        lines.append(
            f"| {g} | {len(sub)} | {_pct(_median([r.precision for r in sub]))} | "
            f"{_pct(_median([r.recall for r in sub]))} | "
            f"{_pct(_median([r.clutter_recall for r in sub]))} | "
            f"{_fmt(_median([r.structure_score for r in sub]))} |"
        )
    return lines


def _log_label(config: EvaluationConfig, name: str) -> str:
    """A log as the report names it: its name, and its file when given as one (``--logs PATH``)."""
    given = dict(config.log_files)
    return f"{name} ({given[name]})" if name in given else name


def _versions() -> str:
    import scipy

    parts = [
        f"rose {rose.__version__}",
        f"rose-bag {rose_logs.__version__}",
        f"python {platform.python_version()}",
        f"numpy {np.__version__}",
        f"scipy {scipy.__version__}",
    ]
    if have_matplotlib():
        import matplotlib

        parts.append(f"matplotlib {matplotlib.__version__}")
    return ", ".join(parts)


def _walls_section(out_dir: Path, config: EvaluationConfig) -> WallReport | None:
    """The wall-extraction experiment on ``config``'s benchmark maps, with its ROSE parameters.

    None when the configuration has no benchmark map. Errors propagate: a report without its wall
    section must not look like a finished run.
    """
    if not config.benchmark_maps:
        return None
    return wall_experiment(
        out_dir,
        names=list(config.benchmark_maps),
        maps_dir=config.benchmark_dir,
        rose_params=config.rose_params,
        plot=config.plots and have_matplotlib(),  # without it: said once, by run_evaluation
    )


def run_evaluation(
    config: EvaluationConfig,
    out_dir: str | Path,
    *,
    progress: Callable[[str], None] | None = None,
) -> EvaluationReport:
    """Run experiments 1-3, the wall experiment, experiment 4 (break detection) and the cleaning
    benchmark, and write the report.

    Parameters
    ----------
    config : EvaluationConfig
        Maps, settings, seed; :meth:`EvaluationConfig.small` or :meth:`EvaluationConfig.full`.
    out_dir : str or Path
        Report folder, created if needed; existing files of the same names are overwritten.
    progress : callable, optional
        Called with a one-line message after each stage.

    Returns
    -------
    EvaluationReport

    Raises
    ------
    rose_logs.datasets.DataSetError
        If ``config.maps_dir`` is None and the data set is not available.
    rose.MapFileError, rose_logs.carmen.parse.CarmenFormatError
        If a benchmark map or a log is missing or unreadable.
    rose_logs.evaluation.files.ReportWriteError
        If a PNG file cannot be written (its message names the file).
    """
    out = Path(out_dir)
    if config.data_logs or config.benchmark_maps:
        # Finds the data set (or raises DataSetError) before anything is written.
        _LOG.info("data: %s", config.data_root)
    # Each log is a CARMEN log with a scan, said now (one line naming the file: missing, a
    # folder, no FLASER scan), not after the experiments before its turn.
    for name in config.logs:
        read_carmen_log(config.log_path(name), max_scans=1)
    # The wall experiment needs each benchmark map's furnished drawing: said now, not after the
    # experiments before it (minutes with --config full).
    for name in config.benchmark_maps:
        furnished = config.benchmark_dir / f"{name}_furnitures.png"
        if not furnished.is_file():
            what = "is not a file" if furnished.exists() else "no such file"
            msg = f"{furnished}: {what}"
            raise rose.MapFileError(msg)
        # Both drawings decode and agree in size: said now too, not after experiment 1.
        furniture_pair(config.benchmark_dir / f"{name}.png", furnished)
    if config.plots and not have_matplotlib():
        # Said once for every plot: only the wall plot said it, the other figures were left out
        # silently.
        _LOG.warning(
            "matplotlib is not installed (the plots extra): no plots; the cleaning picture and the "
            "rasterised maps are still drawn"
        )
    out.mkdir(parents=True, exist_ok=True)
    say = progress if progress is not None else _LOG.info
    t0 = time.perf_counter()
    files: list[Path] = []
    timings: dict[str, float] = {}

    t = time.perf_counter()
    maps = source_maps(config)
    clutter_runs = run_clutter_experiment(config, maps)
    timings["experiment 1 (clutter)"] = time.perf_counter() - t
    say(f"experiment 1: {len(clutter_runs)} runs in {timings['experiment 1 (clutter)']:.1f} s")
    t = time.perf_counter()
    furniture_runs = run_furniture_experiment(config)
    timings["furniture"] = time.perf_counter() - t
    t = time.perf_counter()
    drift_runs, kept_maps = run_drift_experiment(config)
    timings["experiment 2 (drift)"] = time.perf_counter() - t
    say(f"experiment 2: {len(drift_runs)} maps in {timings['experiment 2 (drift)']:.1f} s")
    exp3 = correlation(clutter_runs)
    break_md, break_files = _break_section(config, out, say, timings)
    files.extend(break_files)

    files.append(_write_csv(out / "exp1_clutter_runs.csv", clutter_runs))
    files.append(_write_csv(out / "exp1_furniture.csv", furniture_runs))
    files.append(_write_csv(out / "exp2_drift.csv", drift_runs))
    files.append(_write_exp3_csv(out / "exp3_correlation.csv", exp3))
    files.extend(_write_map_images(out, kept_maps))
    t = time.perf_counter()
    figures = _figures(config, out, clutter_runs, drift_runs, exp3, kept_maps)
    files.extend(figures)
    timings["figures"] = time.perf_counter() - t

    t = time.perf_counter()
    wall_report = _walls_section(out, config)
    timings["wall extraction"] = time.perf_counter() - t
    if wall_report is not None:
        files.extend(wall_report.files)
    t = time.perf_counter()
    cleaning = cleaning_experiment(config, out, seeds=config.drift_seeds)
    files.extend(cleaning.files)
    timings["cleaning"] = time.perf_counter() - t
    say(f"cleaning: {len(cleaning.runs)} runs in {timings['cleaning']:.1f} s")
    run_s = time.perf_counter() - t0
    median_by_map = {
        name: (
            _median([r.precision for r in clutter_runs if r.map_name == name]),
            _median([r.recall for r in clutter_runs if r.map_name == name]),
        )
        for name in maps
    }
    w_by_log = _w_by_log(drift_runs)
    markdown = _markdown(
        config,
        clutter_runs=clutter_runs,
        furniture_runs=furniture_runs,
        drift_runs=drift_runs,
        exp3=exp3,
        median_by_map=median_by_map,
        w_by_log=w_by_log,
        figures=[f.name for f in figures],
        map_images=[p.name for p in files if p.name.startswith("map_")],
        timings=timings,
        run_s=run_s,
        wall_md=wall_report.markdown if wall_report is not None else "",
        cleaning_md=cleaning.markdown,
        break_md=break_md,
    )
    md_path = out / MARKDOWN_NAME
    write_bytes(md_path, markdown.encode("utf-8"))
    files.insert(0, md_path)
    say(f"report done in {run_s:.1f} s")
    return EvaluationReport(
        out_dir=out,
        markdown_path=md_path,
        files=tuple(files),
        run_s=run_s,
        median_by_map=median_by_map,
        w_by_log=w_by_log,
        r_all=exp3.r_all,
    )


def _break_section(
    config: EvaluationConfig, out: Path, say: Callable[[str], None], timings: dict[str, float]
) -> tuple[str, list[Path]]:
    """Experiment 4 (break detection on replayed sessions) when ``config.break_seeds`` asks for it:
    its markdown and files."""
    if config.break_seeds <= 0 or not config.logs:  # no log, no session (`--config full --logs ''`)
        return "", []
    from rose_logs.evaluation.break_report import run_break_experiment

    t = time.perf_counter()
    section = run_break_experiment(
        [config.log_path(name) for name in config.logs],
        out,
        seeds=config.break_seeds,
        workers=config.break_workers,
        plots=config.plots and have_matplotlib(),
    )
    timings["experiment 4 (breaks)"] = time.perf_counter() - t
    say(
        f"experiment 4: {len(section.sessions)} sessions in {timings['experiment 4 (breaks)']:.1f} s"
    )
    return section.markdown, list(section.files)


def _figures(
    config: EvaluationConfig,
    out: Path,
    clutter_runs: Sequence[ClutterRun],
    drift_runs: Sequence[DriftRun],
    exp3: Experiment3,
    kept_maps: Mapping[str, LogMap],
) -> list[Path]:
    """The experiments' PNG figures (none without matplotlib or with ``plots`` off)."""
    if not (config.plots and have_matplotlib()):
        return []
    return plot_all(
        out,
        clutter_runs=clutter_runs,
        drift_runs=drift_runs,
        r_all=exp3.r_all,
        maps={k.replace("@", " drift "): v.grid for k, v in kept_maps.items()},
    )


def _write_exp3_csv(path: Path, exp3: Experiment3) -> Path:
    with text_file(path) as fh:
        writer = csv.writer(fh)
        writer.writerow(["group", "value", "pearson_r"])
        writer.writerow(["all", "", exp3.r_all])
        for count, r in exp3.r_by_count.items():
            writer.writerow(["count", count, r])
        for name, r in exp3.r_by_map.items():
            writer.writerow(["map", name, r])
    return path


def _write_map_images(out: Path, kept: dict[str, Any]) -> list[Path]:
    """The rasterised logs as map_server-grey PNGs: data the drift experiment scored, not figures,
    so they are written with or without ``plots``."""
    return [
        write_png(out / f"map_{key.replace('@', '_drift')}.png", render_grid(log_map.grid))
        for key, log_map in kept.items()
    ]


def _w_by_log(drift_runs: Sequence[DriftRun]) -> dict[str, tuple[float, float]]:
    result = {}
    for log in dict.fromkeys(r.log for r in drift_runs):
        correct = [r.structure_score for r in drift_runs if r.log == log and r.drift_level == 0]
        drifted = [r.structure_score for r in drift_runs if r.log == log and r.drift_level > 0]
        result[log] = (correct[0] if correct else math.nan, _median(drifted))
    return result


def _setup_section(
    config: EvaluationConfig, *, timings: dict[str, float], run_s: float, map_images: list[str]
) -> list[str]:
    """Title, setup (seed, versions, run time, data, parameters) and ground-truth notes."""
    p = config.rose_params
    lines = [
        f"# ROSE evaluation ({config.name} configuration)",
        "",
        "Every number below was computed by this run (`rose_logs.evaluation`).",
        "",
        "## Setup",
        "",
        # Experiment 4's sessions are drifted with the seeds 0 .. --break-seeds - 1 whatever --seed.
        f"- Seed: {config.seed} (each clutter map and drifted trajectory of experiments 1 and 2 "
        "derives its own seed from it; experiment 4 drifts with the seeds 0, 1, ...; seeds are in "
        "the CSV files)",
        f"- Versions: {_versions()}",
        f"- Run time: {run_s:.1f} s in total; "
        + "; ".join(f"{k} {v:.1f} s" for k, v in timings.items()),
        f"- Radish logs (rasterised from the corrected CARMEN logs at {config.resolution_m} m): "
        f"{', '.join(_log_label(config, name) for name in config.logs) or 'none'}",
        f"- Benchmark maps (Bormann et al.): {', '.join(config.benchmark_maps) or 'none'}",
        f"- Clutter: shapes {', '.join(config.shapes)}; sizes {list(config.sizes_px)} px; "
        f"counts {list(config.counts)}; one seeded map per combination",
        f"- Drift levels: {list(config.drift_levels)} x {config.drift_seeds} seed(s) per log",
        "- ROSE parameters: "
        + ", ".join(f"{f.name}={getattr(p, f.name)!r}" for f in dataclasses.fields(p)),
        "",
        "Ground truth: every occupied cell of the original map is structure; clutter is placed only on "
        "known free cells, so every added cell is clutter and nothing else is. Precision and recall are "
        "those of the *structure* label, as in the paper (precision: kept cells that are structure; "
        "recall: structure cells kept). The clutter label's recall (clutter cells removed) is given too.",
        "",
    ]
    if map_images:
        # A log's name may hold a space or brackets (`my log.log`): the link's target is
        # percent-encoded, or Markdown ends it there.
        links = ", ".join(f"[{m}]({quote(m)})" for m in map_images)
        lines += ["Rasterised maps: " + links, ""]
    return lines


def _clutter_section(
    clutter_runs: Sequence[ClutterRun],
    median_by_map: dict[str, tuple[float, float]],
    figures: list[str],
) -> list[str]:
    """Experiment 1: clutter sensitivity per map, shape, size and count."""
    lines = ["## Experiment 1: clutter sensitivity (paper section 4.2)", ""]
    lines += [
        "Paper: median precision > 95 % for every map except csail; recall about 30 %; precision "
        "drops past about 80 obstacles or obstacles larger than 15 px.",
        "",
        "| map | source | runs | median precision | median recall | median clutter recall |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for name, (prec, rec) in median_by_map.items():
        sub = [r for r in clutter_runs if r.map_name == name]
        source = sub[0].source if sub else ""
        lines.append(
            f"| {name} | {source} | {len(sub)} | {_pct(prec)} | {_pct(rec)} | "
            f"{_pct(_median([r.clutter_recall for r in sub]))} |"
        )
    lines += ["", *_group_table(clutter_runs, "shape", "shape"), ""]
    lines += [*_group_table(clutter_runs, "size_px", "size (px)"), ""]
    lines += [*_group_table(clutter_runs, "count", "count"), ""]
    no_dirs = sum(1 for r in clutter_runs if r.directions == 0)
    lines += [f"Runs where ROSE found no dominant direction (metrics n/a): {no_dirs}.", ""]
    if "exp1_precision_recall_boxplots.png" in figures:
        lines += ["![precision and recall](exp1_precision_recall_boxplots.png)", ""]
    return lines


def _furniture_section(furniture_runs: Sequence[ClutterRun]) -> list[str]:
    """Experiment 1 on real furniture: one row per furnished / clean map pair, and the medians."""
    lines = [
        "### Real furniture (`<name>_furnitures.png` against `<name>.png`)",
        "",
        "Furniture cells: free in the clean map and darker than grey 250 in the furnished image.",
        "",
        "| map | structure cells | furniture cells | W | precision | recall | clutter precision | clutter recall |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in furniture_runs:
        lines.append(
            f"| {r.map_name} | {r.structure_cells} | {r.clutter_cells} | {_fmt(r.structure_score)} | "
            f"{_pct(r.precision)} | {_pct(r.recall)} | {_pct(r.clutter_precision)} | "
            f"{_pct(r.clutter_recall)} |"
        )
    if furniture_runs:
        lines += [
            f"| **median** | | | {_fmt(_median([r.structure_score for r in furniture_runs]))} | "
            f"{_pct(_median([r.precision for r in furniture_runs]))} | "
            f"{_pct(_median([r.recall for r in furniture_runs]))} | "
            f"{_pct(_median([r.clutter_precision for r in furniture_runs]))} | "
            f"{_pct(_median([r.clutter_recall for r in furniture_runs]))} |"
        ]
    lines += [""]
    return lines


def _drift_section(
    config: EvaluationConfig,
    drift_runs: Sequence[DriftRun],
    w_by_log: dict[str, tuple[float, float]],
    figures: list[str],
) -> list[str]:
    """Experiment 2: W of the correct and the drifted maps of each log."""
    lines = [
        "## Experiment 2: W separates correct from broken maps (paper section 4.3)",
        "",
        "Broken maps: the same scans at poses perturbed with seeded accumulated odometry drift "
        "(`rose_logs.carmen.drift`, level 1 = 2 % turn error, 0.2 deg/m heading bias, 0.5 deg/sqrt(m) heading "
        "noise, 1 % scale error, 1 cm/sqrt(m) position noise). Paper: correct 0.07..0.28, "
        "odometry-only 0.47..0.72.",
        "",
        "| log | W correct | paper correct | "
        + " | ".join(f"W drift {lvl:g} (median)" for lvl in config.drift_levels)
        + " | paper odometry-only |",
        "|---|---:|---:|" + "---:|" * len(config.drift_levels) + "---:|",
    ]
    for log, (w_ok, _) in w_by_log.items():
        paper = PAPER_W.get(log)
        cells = [
            _fmt(
                _median(
                    [r.structure_score for r in drift_runs if r.log == log and r.drift_level == lvl]
                )
            )
            for lvl in config.drift_levels
        ]
        lines.append(
            f"| {log} | {_fmt(w_ok)} | {paper[0] if paper else 'n/a'} | "
            + " | ".join(cells)
            + f" | {paper[1] if paper else 'n/a'} |"
        )
    lines += [""]
    if "exp2_structure_score.png" in figures:
        lines += ["![W correct vs drifted](exp2_structure_score.png)", ""]
    return lines


def _confidence_section(exp3: Experiment3, figures: list[str]) -> list[str]:
    """Experiment 3: correlation of W with precision."""
    lines = [
        "## Experiment 3: W as a confidence measure (paper section 4.4)",
        "",
        f"Pearson R between W and precision over {exp3.n_all} experiment-1 runs: **{_fmt(exp3.r_all)}** "
        "(paper: R < -0.7).",
        "",
        "| obstacle count | R |",
        "|---:|---:|",
        *[f"| {c} | {_fmt(r)} |" for c, r in exp3.r_by_count.items()],
        "",
        "| map | R |",
        "|---|---:|",
        *[f"| {m} | {_fmt(r)} |" for m, r in exp3.r_by_map.items()],
        "",
    ]
    if "exp3_w_vs_precision.png" in figures:
        lines += ["![W vs precision](exp3_w_vs_precision.png)", ""]
    return lines


def _files_section(
    *, figures: bool, breaks: bool = False, walls: bool = False, maps: bool = True
) -> list[str]:
    """The list of tables (and map images) written next to the report: each that was written."""
    shown = ", figures above" if figures else ""
    exp4 = (
        ", `exp4_breaks_sessions.csv` (one row per replayed session), `exp4_breaks_roc.csv`"
        if breaks
        else ""
    )
    # wall_error.csv and cleaning_runs.csv were left out of the list; map_*.png was listed without
    # a log, when none is written.
    wall = ", `wall_error.csv`" if walls else ""
    images = ", `map_*.png` (rasterised logs, map_server greys)" if maps else ""
    return [
        "## Files",
        "",
        "`exp1_clutter_runs.csv` (one row per cluttered map), `exp1_furniture.csv`, `exp2_drift.csv`, "
        f"`exp3_correlation.csv`{wall}, `cleaning_runs.csv`{exp4}{images}{shown}.",
        "",
    ]


def _markdown(
    config: EvaluationConfig,
    *,
    clutter_runs: Sequence[ClutterRun],
    furniture_runs: Sequence[ClutterRun],
    drift_runs: Sequence[DriftRun],
    exp3: Experiment3,
    median_by_map: dict[str, tuple[float, float]],
    w_by_log: dict[str, tuple[float, float]],
    figures: list[str],
    map_images: list[str],
    timings: dict[str, float],
    run_s: float,
    wall_md: str,
    cleaning_md: str = "",
    break_md: str = "",
) -> str:
    """The report: setup, the three experiments, the wall section (``wall_md``), the cleaning section
    (``cleaning_md``), experiment 4 (``break_md``), the file list."""
    lines = [
        *_setup_section(config, timings=timings, run_s=run_s, map_images=map_images),
        *(["![maps from logs](maps_from_logs.png)", ""] if "maps_from_logs.png" in figures else []),
        *_clutter_section(clutter_runs, median_by_map, figures),
        *_furniture_section(furniture_runs),
        *_drift_section(config, drift_runs, w_by_log, figures),
        *_confidence_section(exp3, figures),
    ]
    if wall_md:
        lines += [wall_md.rstrip(), ""]
    if cleaning_md:
        lines += [cleaning_md.rstrip(), ""]
    if break_md:
        lines += [break_md.rstrip(), ""]
    # Why there is no plot, said as it is: one sentence gave both reasons, and claimed them for a
    # run with nothing to plot; with --no-plots the cleaning picture is not drawn either.
    if not config.plots:
        lines += ["The plots were not drawn (`--no-plots`), nor the cleaning picture.", ""]
    elif not have_matplotlib():
        lines += [
            "The plots were not drawn (matplotlib is not installed, the plots extra); the cleaning "
            "picture needs no matplotlib.",
            "",
        ]
    lines += _files_section(
        figures=bool(figures), breaks=bool(break_md), walls=bool(wall_md), maps=bool(map_images)
    )
    return "\n".join(lines)
