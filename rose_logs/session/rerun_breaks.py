"""The break detector in Rerun: its score as a time series and the region it found on the map.

Entities (``<root>`` is the map topic's entity root, as in :mod:`rose_logs.rerun_view`):

``<root>/break_score/erased_m`` and ``<root>/break_score/threshold_m``
    :class:`rerun.Scalars`: the break score (metres of established wall erased) and the detector's
    threshold as a constant series.
``<root>/metric/break_region``
    :class:`rerun.LineStrips3D`: the region of the score's erased walls as a rectangle in the map
    frame, metres, just above the grid map, while the snapshot is broken; cleared otherwise.

The break event itself goes to ``<root>/events`` through :func:`rose_logs.rerun_view.log_break_event`.
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from rose_logs.rerun_view import SEQUENCE_TIMELINE, TIMELINE
from rose_logs.session.breaks import BreakScore
from rose_logs.snapshots import MapSnapshot

__all__ = ["break_paths", "log_break_score"]

_REGION_COLOR = (255, 40, 40)
_REGION_HEIGHT_M = 0.03


def break_paths(entity_root: str) -> tuple[str, str, str]:
    """``(score, threshold, region)`` entity paths below ``entity_root``."""
    root = entity_root.strip("/")
    return (
        f"{root}/break_score/erased_m",
        f"{root}/break_score/threshold_m",
        f"{root}/metric/break_region",
    )


def log_break_score(
    recording: rr.RecordingStream,
    snapshot: MapSnapshot,
    verdict: BreakScore,
    *,
    threshold_m: float,
    entity_root: str = "map",
    snapshot_index: int | None = None,
) -> None:
    """Log one snapshot's break score, the threshold and (when broken) the region."""
    recording.set_time(TIMELINE, timestamp=np.datetime64(int(snapshot.log_time_ns), "ns"))
    if snapshot_index is not None:
        recording.set_time(SEQUENCE_TIMELINE, sequence=int(snapshot_index))
    score_path, threshold_path, region_path = break_paths(entity_root)
    recording.log(score_path, rr.Scalars(float(verdict.score_m)))
    recording.log(threshold_path, rr.Scalars(float(threshold_m)))
    if not verdict.broken or verdict.region_m is None:
        recording.log(region_path, rr.Clear(recursive=False))
        return
    x0, y0, x1, y1 = verdict.region_m
    z = float(snapshot.origin_position_m[2]) + _REGION_HEIGHT_M
    corners = [[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z], [x0, y0, z]]
    recording.log(
        region_path,
        rr.LineStrips3D(
            [corners],
            colors=_REGION_COLOR,
            radii=rr.Radius.ui_points(2.5),
            labels=[f"break: {verdict.score_m:.1f} m erased"],
        ),
    )
