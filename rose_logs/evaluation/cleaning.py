"""The cleaning benchmark: furnished maps with exact wall / clutter ground truth, scored per method.

Two kinds of map, both as a SLAM system would produce them:

- **SLAM-like Bormann buildings** (:func:`slam_like_pair`): the room-segmentation benchmark's clean
  and furnished drawings (every pixel darker than grey 250 an obstacle), with every occupied cell farther than
  ``layer_px`` cells from free space turned unknown. That hollows the painted outside, thick walls and solid
  furniture blocks alike: a scanner sees faces, never insides. Walls are the cells occupied in both
  the clean and the furnished map; clutter the cells occupied in the furnished map only.
- **Ray-cast furniture** (:mod:`rose_logs.evaluation.raycast`): CARMEN logs re-rendered with seeded
  virtual objects in the beams' way, so furniture shows as a real scanner sees it (faces, unknown
  shadows behind).

Metrics per map and method (:func:`score_cleaning`): wall recall (wall cells kept), clutter removal
(clutter cells removed), precision (kept cells that are walls, among the kept wall and clutter cells),
robot-sized gaps (:func:`rose_logs.evaluation.gaps.robot_gaps`) and the time of the whole cleaning
relative to :func:`rose.analyze` alone.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

import rose
from rose.cleaning import CleanMethod, clean
from rose.cleaning_rules import length_px
from rose_logs.evaluation.gaps import robot_gaps
from rose_logs.evaluation.maps import _grey

__all__ = [
    "CleaningCase",
    "CleaningRun",
    "CleaningSummary",
    "bormann_cases",
    "furnish_grid",
    "run_cleaning",
    "score_cleaning",
    "slam_like_pair",
    "summarise_cleaning",
]

_LOG = logging.getLogger(__name__)
#: Bormann's benchmark images are 5 cm per cell (no YAML upstream).
BORMANN_RESOLUTION_M = 0.05
#: Grey levels below this are obstacles in a benchmark drawing, as Bormann et al. read them: walls,
#: the grey or black outside and the anti-aliased wall edges alike.
_OBSTACLE_GREY_BELOW = 250
#: Grey levels by which a furniture cell is darker in the furnished drawing than in the clean one.
_FURNITURE_MIN_STEP = 10
#: Drawings with fewer wall cells than this (after hollowing) have no usable ground truth and are
#: skipped.
_MIN_WALL_CELLS = 1000


@dataclass(frozen=True, eq=False)
class CleaningCase:
    """One furnished map with exact ground truth.

    Attributes
    ----------
    name : str
        Map name.
    kind : str
        ``"bormann"`` or ``"raycast"``.
    grid : ndarray of int8, shape (rows, cols)
        The furnished map, ROS convention.
    walls, clutter : ndarray of bool, shape (rows, cols)
        Occupied cells of ``grid`` that are walls / clutter (disjoint). Occupied cells in neither
        (scan noise) are left out of every metric.
    resolution_m : float
        Cell size, metres.
    """

    name: str
    kind: str
    grid: npt.NDArray[np.int8]
    walls: npt.NDArray[np.bool_]
    clutter: npt.NDArray[np.bool_]
    resolution_m: float


@dataclass(frozen=True)
class CleaningRun:
    """The scores of one method on one case."""

    name: str
    kind: str
    method: str
    wall_cells: int
    clutter_cells: int
    wall_recall: float
    clutter_removal: float
    precision: float
    robot_gaps: int
    analyze_s: float
    clean_s: float

    @property
    def time_ratio(self) -> float:
        """Time of analyze plus cleaning over analyze alone."""
        return (self.analyze_s + self.clean_s) / self.analyze_s if self.analyze_s > 0 else math.nan


@dataclass(frozen=True)
class CleaningSummary:
    """Medians and worst cases of one method on one kind of map."""

    kind: str
    method: str
    maps: int
    wall_recall_median: float
    wall_recall_worst: float
    clutter_removal_median: float
    clutter_removal_worst: float
    precision_median: float
    precision_worst: float
    gaps_median: float
    gaps_worst: int
    time_ratio_median: float
    time_ratio_worst: float


def slam_like(grid: npt.NDArray[np.int8], *, layer_px: int = 2) -> npt.NDArray[np.int8]:
    """``grid`` with occupied cells farther than ``layer_px`` cells from free space made unknown.

    Distances are chessboard (8-neighbourhood) steps, so the kept layer is ``layer_px`` cells thick.
    """
    import cv2

    free = (grid >= 0) & (grid < 65)
    near = cv2.dilate(free.astype(np.uint8), np.ones((2 * layer_px + 1,) * 2, np.uint8)) > 0
    out = grid.copy()
    out[(grid >= 65) & ~near] = -1
    return out


def furnished_pair(
    clean_path: Path, furniture_path: Path
) -> tuple[npt.NDArray[np.int8], npt.NDArray[np.bool_]]:
    """The furnished Bormann map (clean map + furniture cells at 100) and the clean map's walls.

    Every pixel of the clean drawing darker than ``_OBSTACLE_GREY_BELOW`` is an obstacle (Bormann et
    al.'s reading), not map_server's trinary thresholds: the drawings paint walls and the outside in
    greys map_server reads as unknown, and their anti-aliased wall edges would leave an unknown seam
    between a room and its wall (office_g kept 3 % of its walls after hollowing). Furniture cells are
    free in the clean drawing and darker, by more than ``_FURNITURE_MIN_STEP`` grey levels, in the
    furnished one; comparing the two images keeps the wall edges, identical in both, out of the
    clutter. The grid has no unknown cells; :func:`slam_like` makes the far obstacle cells unknown.
    """
    grey_clean = _grey(clean_path)
    grey_furnished = _grey(furniture_path)
    if grey_furnished.shape != grey_clean.shape:
        msg = (
            f"{furniture_path}: shape {grey_furnished.shape} differs from {clean_path} "
            f"{grey_clean.shape}"
        )
        raise rose.MapFileError(msg)
    walls = grey_clean < _OBSTACLE_GREY_BELOW
    darker = grey_clean.astype(np.int16) - grey_furnished.astype(np.int16) > _FURNITURE_MIN_STEP
    furniture = ~walls & darker
    grid = np.where(walls | furniture, 100, 0).astype(np.int8)
    return grid, walls


def slam_like_pair(clean_path: Path, furniture_path: Path, *, layer_px: int = 2) -> CleaningCase:
    """A Bormann building with its furniture, as a SLAM map would show it (module notes)."""
    furnished, structure = furnished_pair(clean_path, furniture_path)
    grid = slam_like(furnished, layer_px=layer_px)
    occupied = grid >= 65
    return CleaningCase(
        name=Path(clean_path).stem,
        kind="bormann",
        grid=grid,
        walls=occupied & structure,
        clutter=occupied & ~structure,
        resolution_m=BORMANN_RESOLUTION_M,
    )


def bormann_cases(folder: Path, *, names: Sequence[str] | None = None) -> list[CleaningCase]:
    """Every ``<name>.png`` with a ``<name>_furnitures.png`` in ``folder`` (sorted), as cases."""
    folder = Path(folder)
    cases = []
    for furnished in sorted(folder.glob("*_furnitures.png")):
        name = furnished.name.removesuffix("_furnitures.png")
        if names is not None and name not in names:
            continue
        case = slam_like_pair(folder / f"{name}.png", furnished)
        if int(np.count_nonzero(case.walls)) < _MIN_WALL_CELLS:
            _LOG.warning("%s: fewer than %d wall cells, skipped", name, _MIN_WALL_CELLS)
            continue
        cases.append(case)
    return cases


def furnish_grid(
    grid: npt.NDArray[np.int8],
    *,
    count: int,
    seed: int,
    resolution_m: float,
    name: str = "furnished",
    min_wall_extent_m: float = 3.0,
) -> CleaningCase:
    """A SLAM map with scanned-looking furniture painted in: a quick case that needs no log.

    Objects (hollow boxes 0.3..1.2 m with unknown insides, four-legged tables, round bins drawn as
    rings) go on free cells at least 1 m from occupied and unknown cells; there are no shadows (the
    ray-cast cases have them). Walls are the occupied cells of ``grid`` in 8-connected components at
    least ``min_wall_extent_m`` across (the bounding box diagonal), so a map's own small clutter is
    left out of the metrics; clutter is the painted cells.
    """
    import cv2

    rng = np.random.default_rng(seed)
    res = resolution_m
    occupied = grid >= 65
    free = (grid >= 0) & ~occupied
    clear = cv2.distanceTransform(free.view(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * res
    out = grid.copy()
    clutter = np.zeros(grid.shape, dtype=bool)
    candidates = np.flatnonzero(clear > 1.0)
    for _ in range(count if candidates.size else 0):
        row, col = divmod(int(candidates[rng.integers(candidates.size)]), grid.shape[1])
        kind = rng.integers(3)
        stamp = np.zeros(grid.shape, np.uint8)
        if kind == 0:
            half = rng.uniform(0.15, 0.6, size=2) / res
            angle = float(rng.uniform(0, 180))
            box = cv2.boxPoints(((col, row), (2 * half[0], 2 * half[1]), angle))
            inside = np.zeros_like(stamp)
            cv2.fillPoly(inside, [np.round(box).astype(np.int32)], 1)
            cv2.polylines(stamp, [np.round(box).astype(np.int32)], True, 1, 1)
            out[inside.astype(bool) & ~stamp.astype(bool) & free] = -1
        elif kind == 1:
            du, dv = (round(v / res) for v in rng.uniform(0.3, 0.8, size=2))
            for dr, dc in ((-dv, -du), (-dv, du), (dv, -du), (dv, du)):
                stamp[row + dr, col + dc] = 1
        else:
            cv2.circle(stamp, (col, row), max(2, round(rng.uniform(0.12, 0.25) / res)), 1, 1)
        cells = stamp.astype(bool) & free
        out[cells] = 100
        clutter |= cells
    _, labels, stats, _ = cv2.connectedComponentsWithStats(occupied.view(np.uint8), connectivity=8)
    large = np.hypot(stats[:, 2], stats[:, 3]) * res >= min_wall_extent_m
    large[0] = False
    return CleaningCase(
        name=name,
        kind="painted",
        grid=out,
        walls=large[labels] & occupied,
        clutter=clutter & (out >= 65),
        resolution_m=res,
    )


def score_cleaning(
    case: CleaningCase,
    kept: npt.NDArray[np.bool_],
    *,
    method: str,
    analyze_s: float,
    clean_s: float,
    completed: npt.NDArray[np.bool_] | None = None,
    robot_radius_m: float = 0.15,
    gap_margin_m: float = 0.5,
    pocket_m2: float = 1.0,
) -> CleaningRun:
    """Score the occupied cells ``kept`` by a cleaning against the case's ground truth.

    ``completed`` (cells the cleaning made walls that were not occupied) count as obstacles for the
    robot-gap metric; recall, removal and precision are about the input's occupied cells only.
    """
    walls, clutter = case.walls, case.clutter
    wall_n = int(np.count_nonzero(walls))
    clutter_n = int(np.count_nonzero(clutter))
    kept_walls = int(np.count_nonzero(kept & walls))
    kept_clutter = int(np.count_nonzero(kept & clutter))
    gaps = robot_gaps(
        walls,
        kept,
        radius_px=length_px(robot_radius_m, case.resolution_m),
        margin_px=max(1, round(gap_margin_m / case.resolution_m)),
        pocket_px=pocket_m2 / case.resolution_m**2,
        added=completed,
    )
    return CleaningRun(
        name=case.name,
        kind=case.kind,
        method=method,
        wall_cells=wall_n,
        clutter_cells=clutter_n,
        wall_recall=kept_walls / wall_n if wall_n else math.nan,
        clutter_removal=1.0 - kept_clutter / clutter_n if clutter_n else math.nan,
        precision=(
            kept_walls / (kept_walls + kept_clutter) if kept_walls + kept_clutter else math.nan
        ),
        robot_gaps=gaps,
        analyze_s=analyze_s,
        clean_s=clean_s,
    )


def run_cleaning(
    cases: Iterable[CleaningCase], *, methods: Sequence[CleanMethod] = ("paper", "walls")
) -> list[CleaningRun]:
    """Analyze every case once, clean it with every method, score each."""
    runs = []
    for case in cases:
        started = time.perf_counter()
        result = rose.analyze(case.grid)
        analyze_s = time.perf_counter() - started
        for method in methods:
            started = time.perf_counter()
            cleaned = clean(case.grid, result, method=method, resolution_m=case.resolution_m)
            clean_s = time.perf_counter() - started
            run = score_cleaning(
                case,
                cleaned.kept,
                method=method,
                analyze_s=analyze_s,
                clean_s=clean_s,
                completed=cleaned.completed,
            )
            _LOG.info(
                "%s %s: walls %.3f clutter %.3f precision %.3f gaps %d time x%.2f",
                case.name,
                method,
                run.wall_recall,
                run.clutter_removal,
                run.precision,
                run.robot_gaps,
                run.time_ratio,
            )
            runs.append(run)
    return runs


def summarise_cleaning(runs: Sequence[CleaningRun]) -> list[CleaningSummary]:
    """Medians and worst cases per (kind, method), in first-seen order."""
    groups: dict[tuple[str, str], list[CleaningRun]] = {}
    for run in runs:
        groups.setdefault((run.kind, run.method), []).append(run)
    out = []
    for (kind, method), group in groups.items():

        def values(attr: str, group: list[CleaningRun] = group) -> npt.NDArray[np.float64]:
            data = np.array([getattr(r, attr) for r in group], dtype=np.float64)
            return data[np.isfinite(data)]

        def median(attr: str) -> float:
            data = values(attr)
            return float(np.median(data)) if data.size else math.nan

        def lowest(attr: str) -> float:
            data = values(attr)
            return float(data.min()) if data.size else math.nan

        def highest(attr: str) -> float:
            data = values(attr)
            return float(data.max()) if data.size else math.nan

        out.append(
            CleaningSummary(
                kind=kind,
                method=method,
                maps=len(group),
                wall_recall_median=median("wall_recall"),
                wall_recall_worst=lowest("wall_recall"),
                clutter_removal_median=median("clutter_removal"),
                clutter_removal_worst=lowest("clutter_removal"),
                precision_median=median("precision"),
                precision_worst=lowest("precision"),
                gaps_median=median("robot_gaps"),
                gaps_worst=int(highest("robot_gaps")),
                time_ratio_median=median("time_ratio"),
                time_ratio_worst=highest("time_ratio"),
            )
        )
    return out
