"""ROSE (and optionally walls) per snapshot, reusing the previous analysis when a map did not change."""

from __future__ import annotations

import dataclasses
import logging
import time
from concurrent.futures import Executor, Future
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

import rose
from rose.cleaning import MIN_CLEAN_RESOLUTION_M, CleanMethod, CleanResult, clean
from rose.directions import degenerate_input
from rose.params import RoseParams
from rose.result import RoseResult
from rose.walls.segments import WallSet
from rose_logs.session.held_logs import ANALYSED_TOPIC, call_held
from rose_logs.snapshots import MapSnapshot

__all__ = [
    "CellCounts",
    "SnapshotAnalyser",
    "SnapshotAnalysis",
    "cell_counts",
    "same_placed_grid",
]

_LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class CellCounts:
    """A snapshot's cells as its record counts them: occupied and clutter cells, and the cells its
    cleaning removed, kept, rescued, kept by its topology guard alone and completed (0 when it was
    not cleaned).

    Counted on the analysis's thread: each count is a pass over the grid, which the session's own
    thread (reading, writing and finishing every snapshot in turn) would otherwise make.
    """

    occupied: int
    clutter: int
    removed: int = 0
    kept: int = 0
    rescued: int = 0
    guarded: int = 0
    completed: int = 0


def cell_counts(result: RoseResult, cleaning: CleanResult | None) -> CellCounts:
    """The :class:`CellCounts` of an analysis and its cleaning (None: not cleaned)."""
    occupied, clutter = result.occupied_count, result.clutter_count
    if cleaning is None:
        return CellCounts(occupied, clutter)
    # Each mask counted once (the CleanResult's *_count, by the mask's identity): the paper
    # labelling's removed and kept masks are the result's own, its three empty ones one array.
    counted = {id(result.occupied): occupied, id(result.clutter): clutter}

    def count(mask: npt.NDArray[np.bool_]) -> int:
        if id(mask) not in counted:
            counted[id(mask)] = int(np.count_nonzero(mask))
        return counted[id(mask)]

    return CellCounts(
        occupied,
        clutter,
        removed=count(cleaning.removed),
        kept=count(cleaning.kept),
        rescued=count(cleaning.rescued),
        guarded=count(cleaning.guarded),
        completed=count(cleaning.completed),
    )


@dataclass(frozen=True)
class SnapshotAnalysis:
    """What the session computes for one snapshot (``seconds``: compute time; ``degenerate``: why
    W says nothing about the map, :func:`rose.directions.degenerate_input`). A reused analysis is
    the same object again: the session's record of it counts no compute time."""

    result: RoseResult
    walls: WallSet | None
    cleaning: CleanResult | None = None
    seconds: float = 0.0
    degenerate: str | None = None
    counts: CellCounts | None = None  # None: not counted yet (see snapshot_record)
    #: What the analysis logged, kept back to be said in log order (:func:`say_held`); not part of
    #: what the analysis is (equality, repr).
    log_records: tuple[logging.LogRecord, ...] = dataclasses.field(
        default=(), compare=False, repr=False
    )


class SnapshotAnalyser:
    """rose.analyze, the cleaning and optionally wall extraction per snapshot, run on an executor;
    a topic's previous analysis is reused when its grid and placement are unchanged."""

    def __init__(
        self, params: RoseParams, *, walls: bool, clean_method: CleanMethod = "walls"
    ) -> None:
        self.params = params
        self.walls = walls
        self.clean_method = clean_method
        self.previous: dict[str, tuple[MapSnapshot, Future[SnapshotAnalysis]]] = {}
        self._too_fine_said: set[str] = set()  # topics told of the paper labelling's fallback

    def submit(
        self, snapshot: MapSnapshot, executor: Executor
    ) -> tuple[Future[SnapshotAnalysis], bool]:
        """Start analysing ``snapshot``; returns its future and whether it is a reused analysis (then
        the future is the previous snapshot's, its grid and placement unchanged)."""
        prev = self.previous.get(snapshot.topic)
        if prev is not None and same_placed_grid(prev[0], snapshot):
            return prev[1], True
        if self.clean_method == "walls" and snapshot.resolution_m < MIN_CLEAN_RESOLUTION_M:
            # Here, in log order: said by whichever analysis of the topic came first, on the
            # threads, it came with a later map when that one's analysis outran the first's.
            self._say_too_fine(snapshot.topic)
        future = executor.submit(self.analyse, snapshot)
        self.previous[snapshot.topic] = (snapshot, future)
        return future, False

    def analyse(self, snapshot: MapSnapshot) -> SnapshotAnalysis:
        """One snapshot, from scratch. No shared state: safe to run in several threads at once."""
        token = ANALYSED_TOPIC.set(snapshot.topic)
        try:
            analysis, held = call_held(lambda: self._analyse(snapshot))
            return dataclasses.replace(analysis, log_records=held)
        finally:
            ANALYSED_TOPIC.reset(token)

    def _analyse(self, snapshot: MapSnapshot) -> SnapshotAnalysis:
        started = time.perf_counter()
        result = rose.analyze(snapshot.grid, self.params)
        walls = None
        if self.walls:
            placed = rose.OccupancyMap(
                grid=snapshot.grid,
                resolution_m=snapshot.resolution_m,
                origin_xy_m=(snapshot.origin_position_m[0], snapshot.origin_position_m[1]),
                origin_yaw_rad=snapshot.origin_yaw_rad,
            )
            wall_params = rose.WallParams(occupied_threshold=self.params.occupied_threshold)
            walls = rose.extract_walls(placed, result, params=wall_params)
        method = self.clean_method
        if method == "walls" and snapshot.resolution_m < MIN_CLEAN_RESOLUTION_M:
            # W and the labels do not depend on the resolution; only the walls rules do (said by
            # submit, in log order).
            method = "paper"
        cleaning = clean(snapshot.grid, result, method=method, resolution_m=snapshot.resolution_m)
        degenerate = degenerate_input(snapshot.grid, result.occupied)
        counts = cell_counts(result, cleaning)
        seconds = time.perf_counter() - started
        return SnapshotAnalysis(
            result,
            walls,
            cleaning=cleaning,
            seconds=seconds,
            degenerate=degenerate,
            counts=counts,
        )

    def _say_too_fine(self, topic: str) -> None:
        """Warn once per topic (not once per snapshot) that its maps get the paper's labelling."""
        if topic in self._too_fine_said:
            return
        self._too_fine_said.add(topic)
        _LOG.warning(
            "%s: maps finer than %g m per cell get the paper's labelling as their cleaned map "
            "(the walls cleaning's lengths would span thousands of cells); said once per topic",
            topic,
            MIN_CLEAN_RESOLUTION_M,
        )


def same_placed_grid(a: MapSnapshot, b: MapSnapshot) -> bool:
    """Whether ``a`` and ``b`` hold equal grids with the same resolution and origin."""
    # Walls are in metres, so a reused analysis also needs the same placement.
    return (
        a.resolution_m == b.resolution_m
        and a.origin_position_m == b.origin_position_m
        and a.origin_orientation_xyzw == b.origin_orientation_xyzw
        and np.array_equal(a.grid, b.grid)
    )
