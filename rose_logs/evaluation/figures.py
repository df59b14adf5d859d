"""PNG figures of the evaluation (matplotlib, the optional ``plots`` extra)."""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rose_logs.evaluation.config import PAPER_W
from rose_logs.evaluation.experiments import ClutterRun, DriftRun
from rose_logs.evaluation.files import save_figure

__all__ = ["have_matplotlib", "plot_all", "render_grid"]

_LOG = logging.getLogger(__name__)


def have_matplotlib() -> bool:
    """Whether matplotlib can be imported."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def render_grid(grid: npt.NDArray[np.int8], *, threshold: int = 65) -> npt.NDArray[np.uint8]:
    """A ROS grid as a map_server-style grey image, top row first (uint8, shape (rows, cols))."""
    image = np.full(grid.shape, 205, dtype=np.uint8)
    image[grid >= 0] = 254
    image[grid >= threshold] = 0
    return image[::-1]


def _boxplots(runs: Sequence[ClutterRun], path: Path) -> None:
    import matplotlib.pyplot as plt

    panels = [
        ("map_name", "Environment"),
        ("shape", "Obstacle type"),
        ("size_px", "Obstacle size (px)"),
        ("count", "Obstacle count"),
    ]
    fig, axes = plt.subplots(2, 2, figsize=(14, 9))
    for ax, (key, title) in zip(axes.ravel(), panels, strict=True):
        groups = list(dict.fromkeys(getattr(r, key) for r in runs))
        if key != "map_name" and key != "shape":
            groups = sorted(groups)
        prec = [
            [r.precision for r in runs if getattr(r, key) == g and math.isfinite(r.precision)]
            for g in groups
        ]
        rec = [
            [r.recall for r in runs if getattr(r, key) == g and math.isfinite(r.recall)]
            for g in groups
        ]
        pos = np.arange(len(groups), dtype=float)
        for data, offset, colour in ((prec, -0.18, "tab:red"), (rec, 0.18, "tab:green")):
            bp = ax.boxplot(
                data, positions=pos + offset, widths=0.3, patch_artist=True, showfliers=False
            )
            for box in bp["boxes"]:
                box.set_facecolor(colour)
                box.set_alpha(0.6)
        ax.set_xticks(
            pos, [str(g) for g in groups], rotation=60 if key == "map_name" else 0, fontsize=8
        )
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(f"{title}: precision (red), recall (green)")
        ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def _drift_plot(runs: Sequence[DriftRun], path: Path) -> None:
    import matplotlib.pyplot as plt

    logs = list(dict.fromkeys(r.log for r in runs))
    levels = sorted({r.drift_level for r in runs})
    cmap = plt.get_cmap("viridis")
    fig, ax = plt.subplots(figsize=(9, 5))
    for j, level in enumerate(levels):
        xs = [
            logs.index(r.log) + (j - len(levels) / 2) * 0.08 for r in runs if r.drift_level == level
        ]
        ys = [r.structure_score for r in runs if r.drift_level == level]
        colour = "tab:green" if level == 0 else cmap(0.3 + 0.6 * j / max(len(levels) - 1, 1))
        ax.scatter(
            xs,
            ys,
            color=colour,
            label="corrected poses" if level == 0 else f"drift level {level:g}",
            zorder=3,
        )
    for i, log in enumerate(logs):
        if log in PAPER_W:
            good, bad = PAPER_W[log]
            ax.scatter([i + 0.3], [good], marker="*", s=120, color="green", edgecolor="k", zorder=3)
            ax.scatter([i + 0.3], [bad], marker="*", s=120, color="red", edgecolor="k", zorder=3)
    ax.scatter([], [], marker="*", color="green", edgecolor="k", label="paper: SLAM map")
    ax.scatter([], [], marker="*", color="red", edgecolor="k", label="paper: odometry only")
    ax.axhspan(0.2, 0.4, color="grey", alpha=0.12)
    ax.set_xticks(range(len(logs)), logs)
    ax.set_ylim(-0.02, 1.05)
    ax.set_ylabel("structure score W")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def _scatter(runs: Sequence[ClutterRun], r_all: float, path: Path) -> None:
    import matplotlib.pyplot as plt

    counts = sorted({r.count for r in runs})
    cmap = plt.get_cmap("plasma")
    fig, ax = plt.subplots(figsize=(7, 5))
    for j, count in enumerate(counts):
        sub = [r for r in runs if r.count == count]
        ax.scatter(
            [r.structure_score for r in sub],
            [r.precision for r in sub],
            s=8,
            alpha=0.6,
            color=cmap(j / max(len(counts) - 1, 1)),
            label=f"{count} obstacles",
        )
    ax.set_xlabel("structure score W")
    ax.set_ylabel("precision (structure label)")
    ax.set_title(f"W vs precision, Pearson R = {r_all:.3f}")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def _map_panel(images: dict[str, npt.NDArray[np.int8]], path: Path) -> None:
    import matplotlib.pyplot as plt

    n = len(images)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5 * cols, 5 * rows), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, (title, grid) in zip(axes.ravel(), images.items(), strict=False):
        ax.imshow(render_grid(grid), cmap="gray", vmin=0, vmax=255, interpolation="nearest")
        ax.set_title(title)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def plot_all(
    out_dir: Path,
    *,
    clutter_runs: Sequence[ClutterRun],
    drift_runs: Sequence[DriftRun],
    r_all: float,
    maps: dict[str, npt.NDArray[np.int8]],
) -> list[Path]:
    """Write every figure into ``out_dir``; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    written = []
    if clutter_runs:
        written.append(out_dir / "exp1_precision_recall_boxplots.png")
        _boxplots(clutter_runs, written[-1])
        written.append(out_dir / "exp3_w_vs_precision.png")
        _scatter(clutter_runs, r_all, written[-1])
    if drift_runs:
        written.append(out_dir / "exp2_structure_score.png")
        _drift_plot(drift_runs, written[-1])
    if maps:
        written.append(out_dir / "maps_from_logs.png")
        _map_panel(maps, written[-1])
    _LOG.info("wrote %d figures", len(written))
    return written
