"""What the loop keeps of each map message: the report's record of an analysed snapshot, the text
of a return to an earlier map, and the messages copied unprocessed (counted by reason)."""

from __future__ import annotations

import logging
from typing import Any

from rose.cleaning import CleanResult
from rose.directions import map_frame_deg
from rose_logs.session.analysis import CellCounts, SnapshotAnalysis, cell_counts
from rose_logs.session.breaks import BreakScore
from rose_logs.session.report import SnapshotRecord
from rose_logs.snapshots import MapSnapshot

__all__ = ["WARN_FIRST", "Skips", "cleaning_counts", "returned_text", "snapshot_record"]

WARN_FIRST = 3
"""Warnings of one kind (map messages skipped for one reason, a topic's break detector restarted)
said one by one; the rest are counted in one line at the end of the session."""


class Skips:
    """Map messages copied unprocessed, by reason: the first few of each reason are warned about
    one by one, the rest in one line (a one-hour session of maps over ``--max-cells`` would
    otherwise print 720 warnings). Said through ``log`` (the loop's logger)."""

    def __init__(self, log: logging.Logger) -> None:
        self.by_reason: dict[str, int] = {}
        # Per reason, its first message: (log time, place in the reading).
        self._first: dict[str, tuple[int, int]] = {}
        self._log = log

    def add(self, reason: str, text: str, *, at_ns: int, read: int) -> None:
        """Count a message logged at ``at_ns``, the ``read``-th read, skipped for ``reason``
        (messages of one log time are in the order read)."""
        count = self.by_reason.get(reason, 0) + 1
        self.by_reason[reason] = count
        at = (at_ns, read)
        self._first[reason] = min(self._first.get(reason, at), at)
        if count <= WARN_FIRST:
            self._log.log(_level_of(reason), "%s, copied unprocessed", text)

    def _in_log_order(self) -> list[tuple[str, int]]:
        """The reasons by their first message in the log. A snapshot not analysable or not
        encodable is counted when its analysis is taken, after the messages read meanwhile: in
        the order counted, the reasons came in another order from run to run."""
        return sorted(self.by_reason.items(), key=lambda item: self._first[item[0]])

    def warn_rest(self) -> None:
        for reason, count in self._in_log_order():
            if count > WARN_FIRST:
                self._log.log(
                    _level_of(reason),
                    "%d more map messages %s, copied unprocessed",
                    count - WARN_FIRST,
                    reason,
                )

    @property
    def total(self) -> int:
        return sum(self.by_reason.values())

    def describe(self) -> str:
        """``"14 over --max-cells"``, ``"2 malformed, 1 not analysable"``; ``"none"`` when empty."""
        return ", ".join(f"{n} {reason}" for reason, n in self._in_log_order()) or "none"


def _level_of(reason: str) -> int:
    """How a skipped map message is said: an empty map is valid (info), the rest are not."""
    return logging.INFO if reason == "empty" else logging.WARNING


def snapshot_record(
    snapshot: MapSnapshot,
    analysis: SnapshotAnalysis,
    index: int,
    verdict: BreakScore,
    *,
    reused: bool,
    from_update: bool,
) -> SnapshotRecord:
    """The report's record of one snapshot (``seconds`` filled in by the caller)."""
    result = analysis.result
    counts = analysis.counts or cell_counts(result, analysis.cleaning)
    height, width = snapshot.shape
    return SnapshotRecord(
        topic=snapshot.topic,
        index=index,
        log_time_ns=snapshot.log_time_ns,
        stamp_ns=snapshot.stamp_ns,
        width=width,
        height=height,
        resolution_m=snapshot.resolution_m,
        structure_score=float(result.structure_score),
        directions_deg=tuple(
            map_frame_deg(result.dominant_directions, yaw_rad=snapshot.origin_yaw_rad)
        ),
        threshold=float(result.threshold),
        occupied_count=counts.occupied,
        clutter_count=counts.clutter,
        seconds=0.0,
        reused=reused,
        from_update=from_update,
        break_score_m=verdict.score_m,
        break_region_m=verdict.region_m,
        break_detected=verdict.broken,
        degenerate=analysis.degenerate,
        **cleaning_counts(analysis.cleaning, counts),
    )


def cleaning_counts(cleaning: CleanResult | None, counts: CellCounts) -> dict[str, Any]:
    """The record's fields of a snapshot's cleaning (none when it was not cleaned)."""
    if cleaning is None:
        return {}
    return {
        "clean_method": cleaning.method,
        "removed_count": counts.removed,
        "kept_count": counts.kept,
        "rescued_count": counts.rescued,
        "guarded_count": counts.guarded,
        "completed_count": counts.completed,
    }


def returned_text(verdict: BreakScore) -> str | None:
    """What the detector found when a snapshot returned to its anchor's map (None if it did not):
    a loop closure undoing a drift, not a break."""
    if verdict.returned_from is None:
        return None
    within = "" if verdict.threshold_m is None else f", under {verdict.threshold_m:.2f} m"
    return (
        f"contradicts snapshot {verdict.returned_from} ({verdict.returned_from_m:.2f} m) but "
        f"agrees with snapshot {verdict.trusted_index} ({verdict.score_m:.2f} m{within}): it "
        "returned to that map (a loop closure undoing a drift?), not a break"
    )
