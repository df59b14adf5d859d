"""ROSE (and optionally walls) per snapshot, reusing the previous analysis when a map did not change."""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

import rose
from rose.cleaning import CleanMethod, CleanResult, clean
from rose.params import RoseParams
from rose.result import RoseResult
from rose.walls.segments import WallSet
from rose_logs.snapshots import MapSnapshot

__all__ = ["SnapshotAnalyser", "SnapshotAnalysis", "same_placed_grid"]

_LOG = logging.getLogger(__name__)

_DECODABLE = {"ros1", "cdr"}


@dataclass(frozen=True)
class SnapshotAnalysis:
    """What the session computes for one snapshot."""

    result: RoseResult
    walls: WallSet | None
    reused: bool
    cleaning: CleanResult | None = None


class SnapshotAnalyser:
    """rose.analyze (and optionally wall extraction) per snapshot, reusing the previous analysis of a
    topic when its grid and placement are unchanged."""

    def __init__(
        self, params: RoseParams, *, walls: bool, clean_method: CleanMethod = "walls"
    ) -> None:
        self.params = params
        self.walls = walls
        self.clean_method = clean_method
        self.previous: dict[str, tuple[MapSnapshot, SnapshotAnalysis]] = {}

    def __call__(self, snapshot: MapSnapshot) -> SnapshotAnalysis:
        prev = self.previous.get(snapshot.topic)
        if prev is not None and same_placed_grid(prev[0], snapshot):
            return dataclasses.replace(prev[1], reused=True)
        result = rose.analyze(snapshot.grid, self.params)
        walls = None
        if self.walls:
            placed = rose.OccupancyMap(
                grid=snapshot.grid,
                resolution_m=snapshot.resolution_m,
                origin_xy_m=(snapshot.origin_position_m[0], snapshot.origin_position_m[1]),
                origin_yaw_rad=snapshot.origin_yaw_rad,
            )
            walls = rose.extract_walls(placed, result)
        cleaning = clean(
            snapshot.grid, result, method=self.clean_method, resolution_m=snapshot.resolution_m
        )
        analysis = SnapshotAnalysis(result, walls, reused=False, cleaning=cleaning)
        self.previous[snapshot.topic] = (snapshot, analysis)
        return analysis


def same_placed_grid(a: MapSnapshot, b: MapSnapshot) -> bool:
    # Walls are in metres, so a reused analysis also needs the same placement.
    return (
        a.resolution_m == b.resolution_m
        and a.origin_position_m == b.origin_position_m
        and a.origin_orientation_xyzw == b.origin_orientation_xyzw
        and np.array_equal(a.grid, b.grid)
    )
