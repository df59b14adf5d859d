"""Wall segments as data: :class:`WallSet` / :class:`WallSegment` and cell <-> metre geometry.

Coordinates
-----------
Cell coordinates are ``(col, row)`` in the grid's index space: integer values are cell centres, row 0 is
the map origin (ROS convention), and angles in cell space are counter-clockwise from +col towards +row.
Map-frame coordinates are metres: the centre of cell ``(c, r)`` is at
``origin_xy_m + R(origin_yaw_rad) @ ((c + 0.5) * resolution_m, (r + 0.5) * resolution_m)``, exactly as
``nav_msgs/OccupancyGrid`` places cells, so segments in metres can be drawn over the map in RViz,
Foxglove or Rerun without further transforms.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt

from rose.errors import RoseError
from rose.frozen import ReadOnlyArrays
from rose.limits import finite_number, integer_number, pair_of
from rose.mapfile import DEFAULT_RESOLUTION_M

__all__ = [
    "WallMethod",
    "WallSegment",
    "WallSet",
    "axial_difference",
    "cells_to_metres",
    "segment_orientations",
]

WallMethod = Literal["hough", "rose"]


@dataclass(frozen=True)
class WallSegment:
    """One wall segment, in cells and in the map frame.

    Attributes
    ----------
    start_px, end_px : tuple of float
        Endpoints ``(col, row)`` in cell coordinates (integer = cell centre, row 0 = map origin).
    start_m, end_m : tuple of float
        Endpoints ``(x, y)`` in the map frame, in metres.
    length_m : float
        Length in metres.
    orientation_rad : float
        Orientation of the line in the map frame, in ``[0, pi)``, counter-clockwise from +x.
    """

    start_px: tuple[float, float]
    end_px: tuple[float, float]
    start_m: tuple[float, float]
    end_m: tuple[float, float]
    length_m: float
    orientation_rad: float


@dataclass(frozen=True, eq=False, repr=False)
class WallSet(ReadOnlyArrays):
    """Wall segments of one map, with the map placement needed to express them in metres.

    Endpoints are ordered so that ``end - start`` points along the segment's orientation.

    Attributes
    ----------
    endpoints_px : ndarray of float64, shape (N, 2, 2)
        ``endpoints_px[i, 0]`` is the start and ``endpoints_px[i, 1]`` the end of segment ``i``, each
        ``(col, row)`` in cell coordinates.
    shape : tuple of int
        ``(rows, cols)`` of the grid the walls were found in.
    resolution_m : float
        Cell size in metres.
    origin_xy_m : tuple of float
        Map-frame position, in metres, of the outer corner of cell (0, 0).
    origin_yaw_rad : float
        Rotation of the grid in the map frame, in radians.
    method : {"hough", "rose"}
        Which pipeline produced the walls.
    dominant_directions : ndarray of float64, shape (K,)
        ROSE's dominant directions in cell space, radians in ``[0, pi)`` (empty for ``"hough"``).
    """

    endpoints_px: npt.NDArray[np.float64]
    shape: tuple[int, int]
    resolution_m: float = DEFAULT_RESOLUTION_M
    origin_xy_m: tuple[float, float] = (0.0, 0.0)
    origin_yaw_rad: float = 0.0
    method: WallMethod = "hough"
    dominant_directions: npt.NDArray[np.float64] = field(default_factory=lambda: np.empty(0))

    def __post_init__(self) -> None:
        # A copy: the set is read-only, and the caller's array must stay writable.
        try:
            endpoints = np.array(self.endpoints_px, dtype=np.float64)
        except (TypeError, ValueError) as err:
            msg = f"endpoints_px must be numbers of shape (N, 2, 2): {err}"
            raise RoseError(msg) from None
        if endpoints.size == 0:
            endpoints = endpoints.reshape(0, 2, 2)
        if endpoints.ndim != 3 or endpoints.shape[1:] != (2, 2):
            msg = f"endpoints_px must have shape (N, 2, 2), got {endpoints.shape}"
            raise RoseError(msg)
        if not np.isfinite(endpoints).all():
            msg = "endpoints_px must be finite numbers of cells"
            raise RoseError(msg)
        shape = self.shape
        if not pair_of(shape, lambda v: integer_number(v) and v >= 0):  # type: ignore[operator]
            msg = f"shape must be two whole numbers of cells (rows, cols), got {shape!r}"
            raise RoseError(msg)
        if self.method not in ("hough", "rose"):
            msg = f"method must be 'hough' or 'rose', got {self.method!r}"
            raise RoseError(msg)
        try:  # a copy too: the caller's array stays theirs
            directions = np.array(np.ravel(self.dominant_directions), dtype=np.float64)
        except (TypeError, ValueError) as err:
            msg = f"dominant_directions must be numbers (radians): {err}"
            raise RoseError(msg) from None
        if not np.isfinite(directions).all():
            msg = "dominant_directions must be finite numbers of radians"
            raise RoseError(msg)
        if not finite_number(self.resolution_m) or not self.resolution_m > 0:
            msg = f"resolution_m must be a positive number of metres, got {self.resolution_m!r}"
            raise RoseError(msg)
        origin = self.origin_xy_m
        if not pair_of(origin, finite_number):
            msg = f"origin_xy_m must be two finite numbers (x, y) in metres, got {origin!r}"
            raise RoseError(msg)
        if not finite_number(self.origin_yaw_rad):
            msg = f"origin_yaw_rad must be a finite number of radians, got {self.origin_yaw_rad!r}"
            raise RoseError(msg)
        # Our copies (numpy then refuses a writable view of them).
        endpoints.flags.writeable = directions.flags.writeable = False
        object.__setattr__(self, "endpoints_px", endpoints)
        object.__setattr__(self, "shape", (int(shape[0]), int(shape[1])))
        object.__setattr__(self, "dominant_directions", directions)
        # Python floats of its own: a list given as the origin was held as it was, and changing
        # it afterwards moved every wall in metres (numpy scalars too, as the other fields).
        object.__setattr__(self, "resolution_m", float(self.resolution_m))
        object.__setattr__(self, "origin_xy_m", (float(origin[0]), float(origin[1])))
        object.__setattr__(self, "origin_yaw_rad", float(self.origin_yaw_rad))
        super().__post_init__()

    def __len__(self) -> int:
        return int(self.endpoints_px.shape[0])

    def __repr__(self) -> str:
        return (
            f"WallSet(method={self.method!r}, segments={len(self)}, shape={self.shape}, "
            f"resolution_m={self.resolution_m:g}, origin_xy_m={self.origin_xy_m}, "
            f"origin_yaw_rad={self.origin_yaw_rad:g})"
        )

    def __iter__(self) -> Iterator[WallSegment]:
        return iter(self.segments)

    @property
    def endpoints_m(self) -> npt.NDArray[np.float64]:
        """Endpoints in the map frame, metres, shape (N, 2, 2), float64 (same layout as ``endpoints_px``)."""
        return cells_to_metres(
            self.endpoints_px,
            resolution_m=self.resolution_m,
            origin_xy_m=self.origin_xy_m,
            origin_yaw_rad=self.origin_yaw_rad,
        )

    @property
    def line_list_m(self) -> npt.NDArray[np.float64]:
        """Endpoints as consecutive pairs, shape (2N, 2), metres, map frame (a LINE_LIST's points)."""
        return self.endpoints_m.reshape(-1, 2)

    @property
    def lengths_px(self) -> npt.NDArray[np.float64]:
        """Segment lengths in cells, shape (N,)."""
        return np.hypot(*(self.endpoints_px[:, 1] - self.endpoints_px[:, 0]).T)

    @property
    def lengths_m(self) -> npt.NDArray[np.float64]:
        """Segment lengths in metres, shape (N,)."""
        return self.lengths_px * self.resolution_m

    @property
    def orientations_rad(self) -> npt.NDArray[np.float64]:
        """Line orientations in the map frame, radians in ``[0, pi)``, shape (N,)."""
        return _half_turn(segment_orientations(self.endpoints_px) + self.origin_yaw_rad)

    @property
    def segments(self) -> tuple[WallSegment, ...]:
        """The walls as :class:`WallSegment` records, longest first order preserved from the set."""
        px, m = self.endpoints_px, self.endpoints_m
        lengths, angles = self.lengths_m, self.orientations_rad
        return tuple(
            WallSegment(
                start_px=(float(px[i, 0, 0]), float(px[i, 0, 1])),
                end_px=(float(px[i, 1, 0]), float(px[i, 1, 1])),
                start_m=(float(m[i, 0, 0]), float(m[i, 0, 1])),
                end_m=(float(m[i, 1, 0]), float(m[i, 1, 1])),
                length_m=float(lengths[i]),
                orientation_rad=float(angles[i]),
            )
            for i in range(len(self))
        )


def cells_to_metres(
    points_px: npt.ArrayLike,
    *,
    resolution_m: float,
    origin_xy_m: tuple[float, float],
    origin_yaw_rad: float,
) -> npt.NDArray[np.float64]:
    """Map cell coordinates ``(col, row)`` (integer = cell centre) to map-frame metres ``(x, y)``.

    Parameters
    ----------
    points_px : array_like, shape (..., 2)
        Points in cell coordinates.
    resolution_m, origin_xy_m, origin_yaw_rad
        The map's placement, as in ``nav_msgs/MapMetaData``.

    Returns
    -------
    ndarray of float64, shape (..., 2)
    """
    local = (np.asarray(points_px, dtype=np.float64) + 0.5) * resolution_m
    c, s = math.cos(origin_yaw_rad), math.sin(origin_yaw_rad)
    rotation = np.array([[c, -s], [s, c]])
    return local @ rotation.T + np.asarray(origin_xy_m, dtype=np.float64)


def segment_orientations(endpoints: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Line orientation of each segment, radians in ``[0, pi)``.

    Parameters
    ----------
    endpoints : array_like, shape (N, 2, 2)
        Segments as ``[start, end]`` points ``(x, y)`` in any Cartesian frame.

    Returns
    -------
    ndarray of float64, shape (N,)
    """
    e = np.asarray(endpoints, dtype=np.float64)
    d = e[:, 1] - e[:, 0]
    return _half_turn(np.arctan2(d[:, 1], d[:, 0]))


def _half_turn(angles: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Line orientations (radians) folded into ``[0, pi)``, float64 of the same shape.

    ``np.mod`` alone leaves ``pi`` itself for an angle a hair below a multiple of pi (``-1e-20 %
    pi`` is ``pi`` in floating point): that is 0.
    """
    folded = np.mod(np.asarray(angles, dtype=np.float64), math.pi)
    return np.where(folded >= math.pi, 0.0, folded)


def axial_difference(a: npt.ArrayLike, b: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Smallest angle between line orientations, radians in [0, pi/2] (broadcasting)."""
    d = np.mod(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64), math.pi)
    return np.minimum(d, math.pi - d)
