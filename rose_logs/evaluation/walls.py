"""Wall extraction with and without ROSE on the furnished benchmark maps (the paper's Fig. 5).

For every building: reference walls = the Hough baseline on the clean map ``<name>.png`` (independent of
ROSE, so the reference cannot favour it); detected walls = the Hough baseline and the ROSE variant on
``<name>_furnitures.png``; both scored with :func:`rose.walls.error.wall_error`. Writes
``wall_error.csv`` and ``wall_error.png`` (log-scale, like the paper's figure) to ``out_dir``.

Run standalone: ``python -m rose_logs.evaluation.walls OUT_DIR [NAME ...]``.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import logging
import math
import sys
import time
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rose import RoseParams, analyze, load_map
from rose.walls import WallError, WallParams, extract_walls, extract_walls_hough, wall_error
from rose_logs.datasets import require_data_dir
from rose_logs.evaluation.config import BENCHMARK_SUBDIR
from rose_logs.evaluation.files import save_figure, text_file

__all__ = ["WallReport", "WallRow", "WallScore", "wall_experiment"]

_LOG = logging.getLogger(__name__)
CSV_NAME = "wall_error.csv"
PLOT_NAME = "wall_error.png"


@dataclass(frozen=True)
class WallScore:
    """One detector's walls on one map, scored against the reference.

    Attributes
    ----------
    n_detected : int
        Detected segments.
    mean_cost : float
        The paper's score, mean ``theta * |T| / 2`` over detected segments (rad * m).
    mean_rotation_deg, mean_offset_m : float
        Mean ``theta`` (degrees) and ``|T|`` (metres) over detected segments.
    n_spurious : int
        Detected segments further than the matching tolerance from every reference wall.
    n_missing : int
        Reference walls less than half covered by the detections.
    """

    n_detected: int
    mean_cost: float
    mean_rotation_deg: float
    mean_offset_m: float
    n_spurious: int
    n_missing: int

    @classmethod
    def from_error(cls, error: WallError) -> WallScore:
        """Summarise a :class:`~rose.walls.error.WallError`."""
        return cls(
            n_detected=error.n_detected,
            mean_cost=error.mean_cost,
            mean_rotation_deg=error.mean_rotation_deg,
            mean_offset_m=error.mean_offset_m,
            n_spurious=error.n_spurious,
            n_missing=error.n_missing,
        )


@dataclass(frozen=True)
class WallRow:
    """Results for one building.

    Attributes
    ----------
    name : str
        Map name (file stem without ``_furnitures``).
    n_reference : int
        Reference walls found on the clean map.
    baseline, rose : WallScore
        Hough on the furnished map, and the ROSE variant on it (ROSE's default GMM threshold).
    rose_fixed : WallScore
        The ROSE variant with ROSE's fixed threshold (``threshold_mode="fixed"``), which keeps more
        wall cells: shows how much the headline depends on ROSE's labelling.
    seconds : float
        Wall time for the map (loading, ROSE, three extractions, two scores).
    """

    name: str
    n_reference: int
    baseline: WallScore
    rose: WallScore
    rose_fixed: WallScore
    seconds: float

    @property
    def improvement(self) -> float:
        """``baseline.mean_cost / rose.mean_cost`` (inf when ROSE's cost is 0, NaN if undefined)."""
        b, r = self.baseline.mean_cost, self.rose.mean_cost
        if not (math.isfinite(b) and math.isfinite(r)):
            return math.nan
        if r == 0:
            return math.inf if b > 0 else math.nan
        return b / r


@dataclass(frozen=True)
class WallReport:
    """The wall experiment's rows, the files it wrote and its Markdown section.

    Attributes
    ----------
    rows : tuple of WallRow
    csv_path : Path
    plot_path : Path or None
        None when matplotlib is not installed or the plot was not asked for.
    markdown : str
        A ``## Wall extraction`` section with the table and a summary.
    """

    rows: tuple[WallRow, ...]
    csv_path: Path
    plot_path: Path | None
    markdown: str

    @property
    def files(self) -> tuple[Path, ...]:
        """Every file written."""
        return (self.csv_path,) + ((self.plot_path,) if self.plot_path else ())


def wall_experiment(
    out_dir: Path,
    *,
    names: list[str] | None = None,
    maps_dir: Path | None = None,
    wall_params: WallParams | None = None,
    rose_params: RoseParams | None = None,
    plot: bool = True,
) -> WallReport:
    """Run the wall experiment on the benchmark buildings and write its table and plot.

    Parameters
    ----------
    out_dir : Path
        Created if missing; receives ``wall_error.csv`` and ``wall_error.png``.
    names : list of str, optional
        Map names; default every ``<name>_furnitures.png`` in ``maps_dir`` that has ``<name>.png``.
    maps_dir : Path, optional
        Directory of the Bormann et al. room-segmentation benchmark maps; default
        ``bormann_ipa_room_segmentation/`` of the data set (``$ROSE_DATA_DIR`` or ``../shared/maps``
        beside the checkout, :func:`rose_logs.datasets.require_data_dir`).
    wall_params : WallParams, optional
        Wall-extraction parameters, the same for reference, baseline and ROSE.
    rose_params : RoseParams, optional
        ROSE parameters (:func:`rose.analyze` defaults if omitted).
    plot : bool, default True
        Write ``wall_error.png`` (needs matplotlib); False writes the table only.

    Returns
    -------
    WallReport

    Raises
    ------
    rose.MapFileError
        If a named map is missing or unreadable.
    rose_logs.datasets.DataSetError
        If ``maps_dir`` is None and the data set is not available.
    rose_logs.evaluation.files.ReportWriteError
        If the plot cannot be written.
    """
    out_dir = Path(out_dir)
    maps_dir = Path(maps_dir) if maps_dir is not None else require_data_dir() / BENCHMARK_SUBDIR
    out_dir.mkdir(parents=True, exist_ok=True)
    if names is None:
        names = sorted(
            p.name.removesuffix("_furnitures.png")
            for p in maps_dir.glob("*_furnitures.png")
            if (maps_dir / p.name.replace("_furnitures.png", ".png")).is_file()
        )
    wp = wall_params if wall_params is not None else WallParams()
    rows = tuple(_run_one(maps_dir, name, wp, rose_params) for name in names)
    csv_path = _write_csv(out_dir / CSV_NAME, rows)
    plot_path = _plot(out_dir / PLOT_NAME, rows) if plot else None
    return WallReport(
        rows=rows, csv_path=csv_path, plot_path=plot_path, markdown=_markdown(rows, plot_path)
    )


def _run_one(maps_dir: Path, name: str, wp: WallParams, rose_params: RoseParams | None) -> WallRow:
    start = time.perf_counter()
    clean = load_map(maps_dir / f"{name}.png")
    furnished = load_map(maps_dir / f"{name}_furnitures.png")
    reference = extract_walls_hough(clean, params=wp)
    baseline = extract_walls_hough(furnished, params=wp)
    params = rose_params if rose_params is not None else RoseParams()
    rose_walls = extract_walls(furnished, analyze(furnished.grid, params), params=wp)
    fixed = analyze(furnished.grid, dataclasses.replace(params, threshold_mode="fixed"))
    fixed_walls = extract_walls(furnished, fixed, params=wp)
    row = WallRow(
        name=name,
        n_reference=len(reference),
        baseline=WallScore.from_error(wall_error(baseline, reference)),
        rose=WallScore.from_error(wall_error(rose_walls, reference)),
        rose_fixed=WallScore.from_error(wall_error(fixed_walls, reference)),
        seconds=time.perf_counter() - start,
    )
    _LOG.info("%s: cost %.4g -> %.4g", name, row.baseline.mean_cost, row.rose.mean_cost)
    return row


def _columns() -> list[str]:
    score = [f.name for f in fields(WallScore)]
    return (
        ["name", "n_reference"]
        + [f"baseline_{s}" for s in score]
        + [f"rose_{s}" for s in score]
        + [f"rose_fixed_{s}" for s in score]
        + ["improvement", "seconds"]
    )


def _write_csv(path: Path, rows: tuple[WallRow, ...]) -> Path:
    score = [f.name for f in fields(WallScore)]
    with text_file(path) as file:
        writer = csv.writer(file)
        writer.writerow(_columns())
        for r in rows:
            writer.writerow(
                [r.name, r.n_reference]
                + [getattr(r.baseline, s) for s in score]
                + [getattr(r.rose, s) for s in score]
                + [getattr(r.rose_fixed, s) for s in score]
                + [f"{r.improvement:.6g}", f"{r.seconds:.3f}"]
            )
    return path


def _plot(path: Path, rows: tuple[WallRow, ...]) -> Path | None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        _LOG.warning("matplotlib is not installed: no wall plot")
        return None
    x = np.arange(len(rows))
    floor = 1e-7  # a zero cost cannot be drawn on a log axis

    def costs(pick: str) -> npt.NDArray[np.float64]:
        # NaN (no segment detected) is not drawn; max(nan, floor) kept it and a log axis of
        # nothing but NaN raised from matplotlib (a blank drawing)
        v = np.array([getattr(r, pick).mean_cost for r in rows], dtype=np.float64)
        return np.where(np.isfinite(v), np.maximum(v, floor), np.nan)

    base, rose, fixed = costs("baseline"), costs("rose"), costs("rose_fixed")
    fig, ax = plt.subplots(figsize=(13, 4.8))
    ax.scatter(x, base, color="tab:red", label="Hough on the furnished map (no ROSE)")
    ax.scatter(
        x, rose, color="tab:green", label="ROSE: cleaned map, snapped to dominant directions"
    )
    ax.scatter(x, fixed, color="tab:blue", marker="x", label="ROSE with its fixed threshold")
    ax.set_yscale("log")
    if not np.isfinite(np.concatenate([base, rose, fixed])).any():
        ax.set_ylim(floor, 1.0)  # nothing to draw: an axis all the same
    ax.set_xticks(x, [r.name for r in rows], rotation=80)
    ax.set_ylabel("mean wall error θ·|T|/2 (rad·m)")
    ax.set_title(f"Wall-line error per building (values below {floor:g} drawn at {floor:g})")
    ax.grid(axis="y", which="major", alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)


def _g(value: float) -> str:
    """A cost or factor for the report: three significant digits, ``n/a`` when there is none (no
    segment detected), as the rest of the report writes it."""
    return f"{value:.3g}" if not math.isnan(value) else "n/a"


def _markdown(rows: tuple[WallRow, ...], plot_path: Path | None) -> str:
    n_ref = sum(r.n_reference for r in rows)

    def summary(label: str, pick: str) -> str:
        scores = [getattr(r, pick) for r in rows]
        better = sum(s.mean_cost < r.baseline.mean_cost for s, r in zip(scores, rows, strict=True))
        ratios = np.array(
            [r.baseline.mean_cost / s.mean_cost for s, r in zip(scores, rows, strict=True)]
        )
        finite = ratios[np.isfinite(ratios) & (ratios > 0)]
        median = float(np.median(finite)) if finite.size else math.nan
        return (
            f"- {label}: lower cost on {better} of {len(rows)} buildings, median factor "
            f"{_g(median)}; spurious {sum(s.n_spurious for s in scores)}, missing "
            f"{sum(s.n_missing for s in scores)} of {n_ref} reference walls."
        )

    lines = [
        "## Wall extraction",
        "",
        "Reference walls: the Hough baseline on the clean map `<name>.png` (independent of ROSE). "
        "Detection on `<name>_furnitures.png`: the same Hough pipeline (baseline) and the ROSE "
        "variant (Hough on the structure cells only, snapped to the dominant directions), with "
        "ROSE's default GMM threshold and with its fixed threshold. Cost = the paper's mean "
        "θ·|T|/2 (rad·m) over detected segments; *spurious* = detected segments more than 0.25 m "
        "from every reference wall; *missing* = reference walls less than half covered. The cost "
        "has no term for missing walls and is zero for any parallel detection, so read it with "
        "the spurious and missing columns.",
        "",
        f"- Hough baseline: spurious {sum(r.baseline.n_spurious for r in rows)}, missing "
        f"{sum(r.baseline.n_missing for r in rows)} of {n_ref} reference walls.",
        summary("ROSE (GMM threshold)", "rose"),
        summary("ROSE (fixed threshold)", "rose_fixed"),
        "",
        "| map | ref | Hough n | Hough cost | Hough spur. | Hough miss. | ROSE n | ROSE cost "
        "| ROSE spur. | ROSE miss. | factor | ROSE-fixed cost | ROSE-fixed miss. |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        b, o, f = r.baseline, r.rose, r.rose_fixed
        factor = ">1e6" if r.improvement > 1e6 else _g(r.improvement)
        lines.append(
            f"| {r.name} | {r.n_reference} | {b.n_detected} | {_g(b.mean_cost)} | {b.n_spurious} "
            f"| {b.n_missing} | {o.n_detected} | {_g(o.mean_cost)} | {o.n_spurious} "
            f"| {o.n_missing} | {factor} | {_g(f.mean_cost)} | {f.n_missing} |"
        )
    lines.append("")
    lines.append(f"Table: `{CSV_NAME}`.")
    if plot_path is not None:
        lines += ["", f"![Wall error per building, log scale]({plot_path.name})"]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """``python -m rose_logs.evaluation.walls OUT_DIR [NAME ...]``: run and print the Markdown."""
    parser = argparse.ArgumentParser(prog="python -m rose_logs.evaluation.walls")
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("names", nargs="*", help="map names (default: all 20)")
    parser.add_argument(
        "--maps-dir",
        type=Path,
        default=None,
        help=f"benchmark folder (default: {BENCHMARK_SUBDIR}/ of $ROSE_DATA_DIR or ../shared/maps)",
    )
    args = parser.parse_args(argv)
    from rose import RoseError
    from rose_logs.errors import LogError

    try:
        report = wall_experiment(args.out_dir, names=args.names or None, maps_dir=args.maps_dir)
    except (RoseError, LogError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    sys.stdout.write(report.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
