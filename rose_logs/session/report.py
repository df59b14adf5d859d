"""What a session found, as records: one per snapshot, one per break, and the whole report (JSON-ready)."""

from __future__ import annotations

import logging
import math
import statistics
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rose.directions import MIN_JUDGED_CELLS, w_judges
from rose.params import RoseParams
from rose_logs.session.breaks import DetectedBreak
from rose_logs.snapshots import float32_decimal

__all__ = [
    "MIN_JUDGED_CELLS",
    "BreakEvent",
    "SessionReport",
    "SnapshotRecord",
    "row_judged",
    "score_beside_level",
    "w_judges",
]

_LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class SnapshotRecord:
    """What one snapshot was and what ROSE found (one line of the JSON report).

    Attributes
    ----------
    topic : str
        Map topic.
    index : int
        Position of the snapshot on its topic, from 0.
    log_time_ns, stamp_ns : int
        Log time of the message and ``header.stamp``, ns.
    width, height : int
        Grid size in cells.
    resolution_m : float
        Cell size, metres.
    structure_score : float
        W (1 by convention for a map without occupied cells: see :attr:`judged`).
    directions_deg : tuple of float
        Dominant wall orientations in degrees in ``[0, 180)``, map frame (CCW from the map's x
        axis: the grid's column axis turned by the origin's yaw).
    threshold : float
        Cell-score threshold (NaN when nothing was classified).
    occupied_count, clutter_count : int
        Occupied cells and those labelled clutter.
    seconds : float
        Wall time spent on this snapshot (analysis and every sink), seconds.
    reused : bool
        True when the grid equalled the previous one and its result was reused.
    from_update : bool
        True when the snapshot came from an ``OccupancyGridUpdate``.
    break_score_m : float
        Break score (:mod:`rose_logs.session.breaks`): length, metres, of established map that this
        snapshot contradicts in one window (walls erased, obstacle evidence risen in free space)
        compared with the last trusted snapshot.
    break_region_m : tuple of float or None
        ``(x_min, y_min, x_max, y_max)`` of those contradicted cells, map frame, metres.
    break_detected : bool
        The break detector marks this snapshot broken (``break_score_m`` at or above its threshold;
        at or above twice it when the score is against the anchor, so a snapshot returning to the
        anchor's map may score above the threshold unbroken).
    clean_method : str
        How ``<map>/rose/cleaned`` was made (``"walls"`` or ``"paper"``, see :func:`rose.cleaning.clean`).
    removed_count, kept_count : int
        Occupied cells the cleaning removed / kept.
    rescued_count : int
        Kept cells the paper's labelling calls clutter.
    guarded_count : int
        Kept cells the cleaning's topology guard alone put back (removed, they opened a gap a robot
        could pass; 0 for the paper's labelling).
    completed_count : int
        Unknown cells the cleaning made walls (wall lines hidden behind what its rules took for
        clutter, also where the topology guard put that clutter back).
    degenerate : str or None
        Why ROSE's input cannot show a building's structure (a solid block, a strip too thin for a
        2D spectrum: :func:`rose.directions.degenerate_input`), so that W says nothing about it.
    """

    topic: str
    index: int
    log_time_ns: int
    stamp_ns: int
    width: int
    height: int
    resolution_m: float
    structure_score: float
    directions_deg: tuple[float, ...]
    threshold: float
    occupied_count: int
    clutter_count: int
    seconds: float
    reused: bool
    from_update: bool
    break_score_m: float = 0.0
    break_region_m: tuple[float, float, float, float] | None = None
    break_detected: bool = False
    clean_method: str = "paper"
    removed_count: int = 0
    kept_count: int = 0
    rescued_count: int = 0
    guarded_count: int = 0
    completed_count: int = 0
    degenerate: str | None = None

    @property
    def judged(self) -> bool:
        """Whether W says something about this snapshot (:func:`row_judged`)."""
        return w_judges(self.occupied_count) and self.degenerate is None

    @property
    def unreadable(self) -> bool:
        """Enough occupied cells, but in a form W cannot read (:attr:`degenerate`)."""
        return w_judges(self.occupied_count) and self.degenerate is not None

    def to_json(self, *, start_ns: int) -> dict[str, Any]:
        """JSON-ready dict; ``time_s`` is seconds since ``start_ns``; NaN becomes null."""
        return {
            "topic": self.topic,
            "index": self.index,
            "log_time_ns": self.log_time_ns,
            "stamp_ns": self.stamp_ns,
            "time_s": round((self.log_time_ns - start_ns) / 1e9, 9),
            "width": self.width,
            "height": self.height,
            "resolution_m": float32_decimal(self.resolution_m),
            "structure_score": _score_json(self.structure_score),
            "directions_deg": list(self.directions_deg),
            "threshold": _score_json(self.threshold),
            "occupied": self.occupied_count,
            "clutter": self.clutter_count,
            "seconds": round(self.seconds, 6),
            "reused": self.reused,
            "from_update": self.from_update,
            "break_score_m": round(self.break_score_m, 3),  # mm: float32 resolutions add 1e-6 noise
            "break_region_m": _region_json(self.break_region_m),
            "break_detected": self.break_detected,
            "clean_method": self.clean_method,
            "removed": self.removed_count,
            "kept": self.kept_count,
            "rescued": self.rescued_count,
            "guarded": self.guarded_count,
            "completed": self.completed_count,
            "degenerate": self.degenerate,
        }


def row_judged(row: Mapping[str, Any]) -> bool:
    """Whether W says something about the snapshot of a JSON record (:meth:`SnapshotRecord.to_json`):
    enough occupied cells (:func:`w_judges`) and an input ROSE can read (no ``degenerate`` reason;
    records stored before it existed have none)."""
    return w_judges(row["occupied"]) and not row.get("degenerate")


def score_beside_level(score: float, level: float) -> tuple[str, str]:
    """``score`` and a gate's ``level`` as a message shows them side by side: the level as given,
    the score with three decimals or as many more as it takes to read on the same side of the level
    as it is ("W = 0.147 exceeds --fail-above 0.147", or "W = 0.146 exceeds 0.1464", left the user
    to guess)."""
    for digits in range(3, 17):
        shown = float(f"{score:.{digits}f}")
        if shown != level and (shown > level) == (score > level):
            return f"{score:.{digits}f}", repr(float(level))
    return repr(float(score)), repr(float(level))


def _score_json(value: float) -> float | None:
    """A score (W, a threshold) as ``rose score --json`` gives it: unrounded (the gates compare
    the unrounded W, and a batch's medians are taken from these), NaN as null."""
    return None if math.isnan(value) else value


def _region_json(region: tuple[float, float, float, float] | None) -> dict[str, float] | None:
    if region is None:
        return None
    return dict(
        zip(("x_min", "y_min", "x_max", "y_max"), (round(v, 3) for v in region), strict=True)
    )


@dataclass(frozen=True)
class BreakEvent:
    """A snapshot where W rose above the failure level (the paper's score; see
    :class:`~rose_logs.session.breaks.DetectedBreak` for the break detector's breaks)."""

    topic: str
    index: int
    log_time_ns: int
    structure_score: float
    text: str


@dataclass(frozen=True)
class SessionReport:
    """Everything a session produced except the output files.

    Attributes
    ----------
    input_path : Path
        The log read.
    input_format : str
        Its format (see :data:`rose_logs.reader.LogFormat`).
    output_path : Path or None
        The log written, if any.
    rrd_path : Path or None
        The Rerun recording saved, if any.
    map_topics : tuple of str
        Map topics analysed.
    records : tuple of SnapshotRecord
        One per snapshot, in log-time order.
    breaks : tuple of BreakEvent
        Every rise of W above ``failure_level``.
    detected_breaks : tuple of DetectedBreak
        Every break the break detector found (start of a run of broken snapshots), per topic.
    break_threshold_m : float
        The break detector's threshold, metres.
    failure_level : float
        The level used.
    message_count : int
        Messages in the input.
    start_ns, end_ns : int
        Log time of the first and last input message, ns.
    skipped_messages : int
        Map or update messages that could not be analysed (copied through unprocessed).
    skipped_reasons : str
        Those messages by reason, e.g. ``"2 malformed, 14 over --max-cells"`` (empty when none).
    elapsed_s : float
        Wall time of the whole session, seconds.
    params : RoseParams
        The ROSE parameters used.
    losses : tuple of str
        With ``salvage``: what could not be read (a corrupt chunk, fewer messages than declared).
        Empty otherwise (a loss without ``salvage`` is an error).
    """

    input_path: Path
    input_format: str
    output_path: Path | None
    rrd_path: Path | None
    map_topics: tuple[str, ...]
    records: tuple[SnapshotRecord, ...]
    breaks: tuple[BreakEvent, ...]
    failure_level: float
    message_count: int
    start_ns: int
    end_ns: int
    skipped_messages: int
    elapsed_s: float
    params: RoseParams = field(default_factory=RoseParams)
    detected_breaks: tuple[DetectedBreak, ...] = ()
    break_threshold_m: float = math.nan
    skipped_reasons: str = ""
    losses: tuple[str, ...] = ()

    def records_of(self, topic: str) -> tuple[SnapshotRecord, ...]:
        """The records of one map topic."""
        return tuple(r for r in self.records if r.topic == topic)

    def first_break(self, topic: str | None = None) -> DetectedBreak | None:
        """The break detector's first break (of ``topic``, or of any topic), None if none."""
        for event in self.detected_breaks:
            if topic is None or event.topic == topic:
                return event
        return None

    def first_w_above(self, topic: str | None = None) -> BreakEvent | None:
        """The first rise of W above the failure level (of ``topic`` or any), None if never."""
        for event in self.breaks:
            if topic is None or event.topic == topic:
                return event
        return None

    @property
    def max_score(self) -> float:
        """Largest W of the session's judged snapshots (NaN without any)."""
        return max((r.structure_score for r in self.records if r.judged), default=math.nan)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready report: session summary plus one record per snapshot."""
        topics = {}
        for topic in self.map_topics:
            scores = [r.structure_score for r in self.records_of(topic) if r.judged]
            above = self.first_w_above(topic)
            first = self.first_break(topic)
            topics[topic] = {
                "snapshots": len(self.records_of(topic)),
                "w_min": _score_json(min(scores, default=math.nan)),
                "w_median": _score_json(statistics.median(scores) if scores else math.nan),
                "w_max": _score_json(max(scores, default=math.nan)),
                "break_score_max_m": max(
                    (round(r.break_score_m, 3) for r in self.records_of(topic)), default=None
                ),
                "first_break": None
                if first is None
                else {
                    "index": first.index,
                    "log_time_ns": first.log_time_ns,
                    "time_s": round((first.log_time_ns - self.start_ns) / 1e9, 9),
                    "break_score_m": round(first.score_m, 3),
                    "region_m": _region_json(first.region_m),
                    "trusted_index": first.trusted_index,
                },
                "breaks": sum(1 for b in self.detected_breaks if b.topic == topic),
                "first_w_above": None
                if above is None
                else {
                    "index": above.index,
                    "log_time_ns": above.log_time_ns,
                    "time_s": round((above.log_time_ns - self.start_ns) / 1e9, 9),
                    "structure_score": _score_json(above.structure_score),
                },
            }
        return {
            "input": str(self.input_path),
            "input_format": self.input_format,
            "output": None if self.output_path is None else str(self.output_path),
            "rrd": None if self.rrd_path is None else str(self.rrd_path),
            "failure_level": self.failure_level,
            "break_threshold_m": None
            if math.isnan(self.break_threshold_m)
            else self.break_threshold_m,
            "message_count": self.message_count,
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "skipped_messages": self.skipped_messages,
            "skipped_reasons": self.skipped_reasons,
            "losses": list(self.losses),
            "elapsed_s": round(self.elapsed_s, 6),
            "params": {k: getattr(self.params, k) for k in self.params.__dataclass_fields__},
            "topics": topics,
            "snapshots": [r.to_json(start_ns=self.start_ns) for r in self.records],
        }
