"""Map snapshots: one decoded occupancy grid at one point of a log."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["MapSnapshot"]


@dataclass(frozen=True, eq=False)
class MapSnapshot:
    """One full occupancy grid as it stood at ``log_time_ns`` on ``topic``.

    Attributes
    ----------
    topic : str
        Map topic the grid came from (for an update patch: the map topic it was applied to).
    log_time_ns : int
        Log (receive) time of the message that produced this snapshot, in nanoseconds.
    stamp_ns : int
        ``header.stamp`` of the map, in nanoseconds.
    frame_id : str
        ``header.frame_id`` of the map.
    grid : ndarray of int8, shape (height, width)
        ROS convention: row 0 at the origin, -1 unknown, 0..100. Read-only.
    resolution_m : float
        Cell size in metres.
    origin_position_m : tuple of float
        ``info.origin.position`` (x, y, z) in metres, map frame.
    origin_orientation_xyzw : tuple of float
        ``info.origin.orientation`` quaternion.
    map_load_time_ns : int
        ``info.map_load_time`` in nanoseconds.
    """

    topic: str
    log_time_ns: int
    stamp_ns: int
    frame_id: str
    grid: npt.NDArray[np.int8]
    resolution_m: float
    origin_position_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    origin_orientation_xyzw: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    map_load_time_ns: int = 0

    @property
    def origin_yaw_rad(self) -> float:
        """Yaw of the grid in the map frame, in radians (from the origin quaternion)."""
        x, y, z, w = self.origin_orientation_xyzw
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)`` in cells."""
        return self.grid.shape[0], self.grid.shape[1]
