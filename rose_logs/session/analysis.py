"""ROSE (and optionally walls) per snapshot, reusing the previous analysis when a map did not change."""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, Future
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

import rose
from rose.cleaning import MIN_CLEAN_RESOLUTION_M, CleanMethod, CleanResult, clean
from rose.directions import degenerate_input
from rose.params import RoseParams
from rose.result import RoseResult
from rose.walls.segments import WallSet
from rose_logs.snapshots import MapSnapshot

__all__ = [
    "ANALYSED_TOPIC",
    "SnapshotAnalyser",
    "SnapshotAnalysis",
    "call_held",
    "held_by",
    "held_log_records",
    "said_at_once",
    "same_placed_grid",
    "say_held",
]

_LOG = logging.getLogger(__name__)
_T = TypeVar("_T")

#: The map topic this thread is analysing, so that the library's messages underneath (``ROSE found no
#: dominant direction ...``) can be said with it (``rose_logs.cli``'s log handler does).
ANALYSED_TOPIC: ContextVar[str | None] = ContextVar("rose_analysed_topic", default=None)

#: Where the records logged in this context go while :func:`held_log_records` holds them.
_HELD: ContextVar[list[logging.LogRecord] | None] = ContextVar(
    "rose_held_log_records", default=None
)

#: The hierarchies held: every logger of ``rose`` (the library underneath: the walls extraction,
#: the cleaning) and of ``rose_logs`` (the session, the reader, the break detector, ...).
_HELD_ROOTS = ("rose", "rose_logs")


class _Hold(logging.Filter):
    """Keeps a record back (in the list of its context) while :func:`held_log_records` holds them."""

    def filter(self, record: logging.LogRecord) -> bool:
        held = _HELD.get()
        if held is None:
            return True
        # Its message as it is now: formatted when said, arguments changed meanwhile (a list, an
        # object's state) were said as they had become. One that does not format is said as
        # logged (the handler reports the error, as it would have).
        with contextlib.suppress(Exception):
            record.msg, record.args = record.getMessage(), None
        held.append(record)
        return False


_HOLD = _Hold()
_HOLD_LOCK = threading.Lock()
_made_record = logging.getLogRecordFactory()


def _record_held_by_its_logger(*args: Any, **kwargs: Any) -> logging.LogRecord:
    """logging's record factory, putting the filter on a held hierarchy's logger before it handles
    a record made while records are held.

    A logger's filters see only the records logged on it, not those of its children propagating
    up: each logger needs its own. A list of names missed the loggers not on it, and those made
    later (a module imported on an analysis thread); the logger that makes a record is filtered
    here before it handles it, whichever it is."""
    record = _made_record(*args, **kwargs)
    if _HELD.get() is not None and record.name.partition(".")[0] in _HELD_ROOTS:
        logger = logging.getLogger(record.name)
        if _HOLD not in logger.filters:
            with _HOLD_LOCK:
                if _HOLD not in logger.filters:
                    # First, so that the logger's own filters see a held record once, as it is
                    # said: after them, they saw it twice (and one letting each message through
                    # once dropped it). A new list: a thread going through the old one is unmoved.
                    logger.filters = [_HOLD, *logger.filters]
    return record


logging.setLogRecordFactory(_record_held_by_its_logger)


@contextlib.contextmanager
def held_log_records() -> Iterator[list[logging.LogRecord]]:
    """Inside the block, what ``rose`` and ``rose_logs`` log in this context is kept in the list
    yielded instead of said: a session's threads run ahead of its log order, and their warnings (a
    topic's maps too fine for the walls cleaning or the break detector, ROSE found no dominant
    direction), said as they came, came in another order from run to run, in ``rose-bag batch``'s
    tables too. The session says them (:func:`say_held`) when it takes the snapshot's results, in
    log order; so too what it says itself while reading the messages after it."""
    held: list[logging.LogRecord] = []
    token = _HELD.set(held)
    try:
        yield held
    finally:
        _HELD.reset(token)


def call_held(call: Callable[[], _T]) -> tuple[_T, tuple[logging.LogRecord, ...]]:
    """``call()`` and what it logged, held (:func:`held_log_records`). If it raises, what it
    logged goes with the error (:func:`held_by`), to be said still."""
    with held_log_records() as held:
        try:
            value = call()
        except BaseException as err:
            err.held_log_records = tuple(held)  # type: ignore[attr-defined]
            raise
    return value, tuple(held)


def held_by(error: BaseException) -> tuple[logging.LogRecord, ...]:
    """What the call that raised ``error`` logged, held (:func:`call_held`)."""
    return getattr(error, "held_log_records", ())


def say_held(records: Sequence[logging.LogRecord], topic: str | None = None) -> None:
    """Say ``records`` kept back by :func:`held_log_records`, in order, as the analysis of ``topic``
    (the library's messages then name it, as when they are said at once; None: as logged outside
    any analysis). Said, not held again, inside a block that holds."""
    held = _HELD.set(None)
    analysed = ANALYSED_TOPIC.set(topic) if topic is not None else None
    try:
        for record in records:
            logging.getLogger(record.name).handle(record)
    finally:
        if analysed is not None:
            ANALYSED_TOPIC.reset(analysed)
        _HELD.reset(held)


@contextlib.contextmanager
def said_at_once() -> Iterator[None]:
    """Inside the block, records are said as they come, even inside a block that holds them."""
    token = _HELD.set(None)
    try:
        yield
    finally:
        _HELD.reset(token)


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
        seconds = time.perf_counter() - started
        return SnapshotAnalysis(
            result, walls, cleaning=cleaning, seconds=seconds, degenerate=degenerate
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
