"""Ray-cast furniture cases: CARMEN logs re-rendered with virtual objects in the beams' way.

The map built from the original scans gives the walls; seeded objects
(:mod:`rose_logs.carmen.furniture`) are placed on its free space, every beam is cut at the first object it
meets, and the map is built again from the cut beams with the same log-odds ray casting. Walls are
the cells occupied in both maps and outside the objects; clutter the occupied cells of the furnished
map on an object (its footprint grown by one cell, where the cut beams end). The logs' maps hold real
clutter too (people, chairs, desks); occupied components of the original map less than 3 m across are left out of the walls
(and of every metric).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import numpy.typing as npt

import rose
from rose_logs.carmen.furniture import (
    Furniture,
    place_furniture,
    rasterise_furniture,
    shorten_ranges,
)
from rose_logs.carmen.parse import beam_angles
from rose_logs.carmen.raycast import BuilderParams, OccupancyGridBuilder, ScanBatch
from rose_logs.evaluation.cleaning import CleaningCase
from rose_logs.evaluation.maps import read_log

__all__ = ["raycast_case"]

_LOG = logging.getLogger(__name__)
#: One object per this many square metres of free space (bounded below and above).
_M2_PER_OBJECT = 12.0
_MIN_OBJECTS, _MAX_OBJECTS = 20, 150

#: The cell size of the benchmark's ray-cast maps (metres); cases at other sizes are named for theirs.
_BENCHMARK_RESOLUTION_M = 0.05

#: The logs' own maps hold real clutter (people, chairs): small occupied components of the map built
#: from the original scans are neither wall nor clutter and stay out of the metrics.
_MIN_WALL_EXTENT_M = 3.0


def _build(
    ranges: npt.NDArray[np.float32],
    angles: npt.NDArray[np.float64],
    poses: npt.NDArray[np.float64],
    params: BuilderParams,
) -> tuple[npt.NDArray[np.int8], npt.NDArray[np.int64]]:
    builder = OccupancyGridBuilder(params)
    builder.integrate(ScanBatch(ranges, angles, poses))
    origin_cell = np.round(np.array(builder.origin_xy_m) / params.resolution_m).astype(np.int64)
    return builder.grid(), origin_cell


def _in_frame(
    grid: npt.NDArray[np.int8],
    origin_cell: npt.NDArray[np.int64],
    lo: npt.NDArray[np.int64],
    shape: tuple[int, int],
) -> npt.NDArray[np.int8]:
    """``grid`` (placed at world cell ``origin_cell``) on a window at ``lo`` of ``shape``, -1 elsewhere."""
    out = np.full(shape, -1, dtype=np.int8)
    dx, dy = (origin_cell - lo).tolist()
    rows, cols = grid.shape
    r0, c0 = max(dy, 0), max(dx, 0)
    r1, c1 = min(dy + rows, shape[0]), min(dx + cols, shape[1])
    out[r0:r1, c0:c1] = grid[r0 - dy : r1 - dy, c0 - dx : c1 - dx]
    return out


def _turn_xy(rows: npt.ArrayLike, angle: float) -> npt.NDArray[np.float64]:
    """A float64 copy of ``rows`` (N, k >= 2) with columns 0 and 1 (x, y metres) rotated by
    ``angle`` (radians, counter-clockwise) about the world origin; the other columns as they are."""
    turned = np.array(rows, dtype=np.float64)
    c, s = math.cos(angle), math.sin(angle)
    x, y = turned[:, 0].copy(), turned[:, 1].copy()
    turned[:, 0] = c * x - s * y
    turned[:, 1] = s * x + c * y
    return turned


def _rotated(poses: npt.NDArray[np.float64], angle: float) -> npt.NDArray[np.float64]:
    """Poses ``(N, 3)`` (x, y metres, heading radians) rotated by ``angle`` about the world origin."""
    if angle == 0:
        return poses
    turned = _turn_xy(poses, angle)
    turned[:, 2] += angle
    return turned


def _rotated_furniture(furniture: Furniture, angle: float) -> Furniture:
    """``furniture`` rotated by ``angle`` (radians, counter-clockwise) about the world origin, as
    :func:`_rotated` turns the poses."""
    if angle == 0:
        return furniture
    rects = _turn_xy(np.reshape(furniture.rects, (-1, 5)), angle)
    rects[:, 4] += angle
    circles = _turn_xy(np.reshape(furniture.circles, (-1, 3)), angle)
    return Furniture(rects=rects, circles=circles, kinds=furniture.kinds)


def _large_components(
    occupied: npt.NDArray[np.bool_], resolution_m: float
) -> npt.NDArray[np.bool_]:
    """Occupied cells of 8-connected components at least ``_MIN_WALL_EXTENT_M`` across (bounding box)."""
    import cv2

    _, labels, stats, _ = cv2.connectedComponentsWithStats(occupied.view(np.uint8), connectivity=8)
    extent = np.hypot(stats[:, 2], stats[:, 3]) * resolution_m
    large = extent >= _MIN_WALL_EXTENT_M
    large[0] = False
    return large[labels]


def raycast_case(
    log_path: Path,
    *,
    seed: int,
    resolution_m: float = _BENCHMARK_RESOLUTION_M,
    objects: int | None = None,
    name: str | None = None,
    rotation_deg: float = 0.0,
    paired: bool = False,
) -> CleaningCase:
    """A furnished ray-cast map of a CARMEN log with exact wall / clutter ground truth.

    Parameters
    ----------
    log_path : Path
        CARMEN log (``FLASER`` lines, corrected poses).
    seed : int
        Seed of the objects.
    resolution_m : float
        Cell size, metres. Cases at other sizes than 0.05 m are of a kind of their own
        (``raycast-10cm``, ``raycast-r30deg-10cm``) and named ``<name>-10cm``.
    objects : int, optional
        Objects to place; by default one per 12 m² of free space, 20..150.
    name : str, optional
        Case name; ``<log>-s<seed>`` by default (``<log>-r<angle>-s<seed>`` when rotated).
    rotation_deg : float
        Rotate the whole log (every pose about the world origin) counter-clockwise by this angle,
        degrees: the building's walls then lie at other angles to the grid, as a map whose frame is
        not aligned with the building has them. Rotated cases are of kind ``raycast-r<angle>deg``.
    paired : bool
        With ``rotation_deg``: place the objects on the unrotated map (the very objects of the
        unrotated case of the same seed) and turn them with the log, so that the rotated case
        differs from the unrotated one by the rotation alone. Otherwise the objects are placed
        on the rotated map, where the same seed draws other positions, kinds and sizes. Paired
        cases are of kind ``raycast-r<angle>deg-paired`` and named ``<log>-r<angle>p-s<seed>``.
    """
    log = read_log(Path(log_path))
    ranges = np.stack([s.ranges_m for s in log.scans])
    angles = beam_angles(ranges.shape[1])
    turn = math.radians(rotation_deg)
    poses = _rotated(log.laser_poses, turn)
    params = BuilderParams(resolution_m=resolution_m)
    clean, clean_origin = _build(ranges, angles, poses, params)
    paired = paired and rotation_deg != 0
    # Where the objects are placed: the rotated map, or the unrotated one when paired.
    placed_on, placed_origin, placed_poses = clean, clean_origin, poses
    if paired:
        placed_poses = log.laser_poses
        placed_on, placed_origin = _build(ranges, angles, placed_poses, params)
    if objects is None:
        free_m2 = float(np.count_nonzero((placed_on >= 0) & (placed_on < 50))) * resolution_m**2
        objects = int(np.clip(round(free_m2 / _M2_PER_OBJECT), _MIN_OBJECTS, _MAX_OBJECTS))
    directions = rose.analyze(placed_on).dominant_directions
    origin_m = (placed_origin * resolution_m).astype(np.float64)
    furniture = place_furniture(
        placed_on,
        origin_xy_m=(float(origin_m[0]), float(origin_m[1])),
        resolution_m=resolution_m,
        poses=placed_poses,
        directions=directions,
        count=objects,
        seed=seed,
    )
    # A beam's range does not depend on the frame: cut where placed, the cut ranges hold rotated.
    cut = shorten_ranges(
        ranges,
        angles,
        placed_poses,
        furniture,
        max_range_m=params.max_range_m,
        min_range_m=params.min_range_m,
    )
    if paired:
        furniture = _rotated_furniture(furniture, turn)
    furnished, furnished_origin = _build(cut, angles, poses, params)
    # One window holding the known cells of both maps.
    lo = np.minimum(clean_origin, furnished_origin)
    hi = np.maximum(
        clean_origin + np.array(clean.shape[::-1]),
        furnished_origin + np.array(furnished.shape[::-1]),
    )
    shape = (int(hi[1] - lo[1]), int(hi[0] - lo[0]))
    clean_w = _in_frame(clean, clean_origin, lo, shape)
    furnished_w = _in_frame(furnished, furnished_origin, lo, shape)
    known = (clean_w >= 0) | (furnished_w >= 0)
    rows = np.flatnonzero(known.any(axis=1))
    cols = np.flatnonzero(known.any(axis=0))
    margin = 10
    r0, r1 = max(int(rows[0]) - margin, 0), min(int(rows[-1]) + margin + 1, shape[0])
    c0, c1 = max(int(cols[0]) - margin, 0), min(int(cols[-1]) + margin + 1, shape[1])
    clean_w, furnished_w = clean_w[r0:r1, c0:c1], furnished_w[r0:r1, c0:c1]
    window_origin = ((lo[0] + c0) * resolution_m, (lo[1] + r0) * resolution_m)
    footprint = rasterise_furniture(
        furniture, clean_w.shape, origin_xy_m=window_origin, resolution_m=resolution_m
    )
    import cv2

    footprint = cv2.dilate(footprint.view(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    occupied = furnished_w >= 65
    clutter = occupied & footprint
    walls = occupied & _large_components(clean_w >= 65, resolution_m) & ~footprint
    turned = f"-r{rotation_deg:g}" if rotation_deg else ""
    # Cells of another size than the benchmark's 0.05 m: a kind of its own.
    cells = "" if resolution_m == _BENCHMARK_RESOLUTION_M else f"-{resolution_m * 100:g}cm"
    label = name or (
        f"{Path(log_path).name.split('-corrected')[0]}{turned}{'p' if paired else ''}-s{seed}"
        f"{cells}"
    )
    _LOG.info(
        "%s: %d objects (%s), %d wall cells, %d clutter cells",
        label,
        len(furniture.kinds),
        ", ".join(f"{k} {furniture.kinds.count(k)}" for k in sorted(set(furniture.kinds))),
        int(np.count_nonzero(walls)),
        int(np.count_nonzero(clutter)),
    )
    return CleaningCase(
        name=label,
        kind=((f"raycast{turned}deg" + ("-paired" if paired else "")) if turned else "raycast")
        + cells,
        grid=furnished_w,
        walls=walls,
        clutter=clutter,
        resolution_m=resolution_m,
    )
