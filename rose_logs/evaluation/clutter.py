"""Artificial clutter for the clutter-sensitivity experiment (paper section 4.2).

Obstacles are filled shapes of ``size_px`` cells across, centred on random known-free cells:

- ``"square"``: an axis-aligned ``size x size`` square;
- ``"rectangle"``: axis-aligned, ``size`` long and ``0.25..0.5 * size`` wide, either orientation;
- ``"random"``: per obstacle one of a disc (diameter ``size``), a diamond (diagonal ``size``) or a
  five-pointed star (outer diameter ``size``, inner radius 0.45 of the outer, random rotation).

Ground truth is exact by construction: an obstacle only turns *known free* cells occupied (it never
covers a wall or unknown space), so ``structure`` is exactly the original occupied cells and
``clutter`` exactly the cells this function added. Overlapping obstacles simply merge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

__all__ = ["SHAPES", "ClutterShape", "ClutteredMap", "add_clutter", "obstacle_stamp"]

ClutterShape = Literal["square", "rectangle", "random"]
SHAPES: tuple[ClutterShape, ...] = ("square", "rectangle", "random")
_RANDOM_KINDS = ("circle", "diamond", "star")


@dataclass(frozen=True, eq=False)
class ClutteredMap:
    """A map with added clutter and its exact ground truth.

    Attributes
    ----------
    grid : ndarray of int8, shape (rows, cols)
        The input grid with clutter cells set to 100 (ROS convention).
    structure : ndarray of bool, shape (rows, cols)
        Occupied cells of the original map (ground-truth structure).
    clutter : ndarray of bool, shape (rows, cols)
        Cells added here (ground-truth clutter); disjoint from ``structure``.
    shape, count, size_px, seed :
        The request that produced it.
    """

    grid: npt.NDArray[np.int8]
    structure: npt.NDArray[np.bool_]
    clutter: npt.NDArray[np.bool_]
    shape: str
    count: int
    size_px: int
    seed: int


def obstacle_stamp(kind: str, size_px: int, rng: np.random.Generator) -> npt.NDArray[np.bool_]:
    """Boolean footprint of one obstacle, shape (h, w) with ``max(h, w) == size_px``.

    ``kind`` is ``"square"``, ``"rectangle"``, ``"circle"``, ``"diamond"`` or ``"star"``.
    """
    s = int(size_px)
    if s < 1:
        msg = f"`size_px` must be >= 1, got {size_px}"
        raise ValueError(msg)
    if kind == "square":
        return np.ones((s, s), dtype=bool)
    if kind == "rectangle":
        width = max(1, round(s * rng.uniform(0.25, 0.5)))
        out = np.ones((s, width), dtype=bool)
        return out if rng.random() < 0.5 else out.T
    centre = (s - 1) / 2.0
    yy, xx = np.mgrid[0:s, 0:s].astype(np.float64) - centre
    radius = s / 2.0
    if kind == "circle":
        return np.hypot(xx, yy) <= radius
    if kind == "diamond":
        return np.abs(xx) + np.abs(yy) <= radius
    if kind == "star":
        phase = rng.uniform(0, 2 * math.pi)
        angle = (np.arctan2(yy, xx) + phase) % (2 * math.pi / 5) / (2 * math.pi / 5)
        tri = 1.0 - 2.0 * np.abs(angle - 0.5)  # 1 at the points, 0 between them
        boundary = radius * (0.45 + 0.55 * tri)
        out = np.hypot(xx, yy) <= boundary
        out[s // 2, s // 2] = True
        return out
    msg = f"unknown obstacle kind {kind!r}"
    raise ValueError(msg)


def add_clutter(
    grid: npt.NDArray[np.int8],
    *,
    shape: ClutterShape,
    count: int,
    size_px: int,
    seed: int,
    occupied_threshold: int = 65,
) -> ClutteredMap:
    """Add ``count`` seeded obstacles of ``size_px`` cells to the free space of ``grid``.

    Parameters
    ----------
    grid : ndarray of int8, shape (rows, cols)
        ROS convention (-1 unknown, 0..100). Not modified.
    shape : {"square", "rectangle", "random"}
        Obstacle family (see module notes).
    count : int
        Number of obstacles (>= 0).
    size_px : int
        Obstacle extent in cells (>= 1).
    seed : int
        Seed: the same inputs and seed give the same map.
    occupied_threshold : int
        Cells at or above this value are structure; cells in ``0 .. occupied_threshold - 1`` are free.

    Returns
    -------
    ClutteredMap

    Raises
    ------
    ValueError
        On a bad shape, count or size, or a map without free cells.
    """
    grid = np.asarray(grid)
    if grid.ndim != 2:
        msg = f"The input map `grid` must be 2D, got shape {grid.shape}"
        raise ValueError(msg)
    if shape not in SHAPES:
        msg = f"`shape` must be one of {SHAPES}, got {shape!r}"
        raise ValueError(msg)
    if count < 0:
        msg = f"`count` must be >= 0, got {count}"
        raise ValueError(msg)
    structure = grid >= occupied_threshold
    free = (grid >= 0) & ~structure
    free_idx = np.flatnonzero(free)
    if free_idx.size == 0:
        msg = "the map has no free cell to place clutter on"
        raise ValueError(msg)
    rng = np.random.default_rng(seed)
    rows, cols = grid.shape
    painted = np.zeros(grid.shape, dtype=bool)
    centres = rng.choice(free_idx, size=count, replace=True)
    for centre in centres.tolist():
        kind = str(rng.choice(_RANDOM_KINDS)) if shape == "random" else shape
        stamp = obstacle_stamp(kind, size_px, rng)
        h, w = stamp.shape
        r0, c0 = centre // cols - h // 2, centre % cols - w // 2
        rr0, cc0 = max(r0, 0), max(c0, 0)
        rr1, cc1 = min(r0 + h, rows), min(c0 + w, cols)
        if rr1 <= rr0 or cc1 <= cc0:
            continue
        painted[rr0:rr1, cc0:cc1] |= stamp[rr0 - r0 : rr1 - r0, cc0 - c0 : cc1 - c0]
    clutter = painted & free
    out = grid.astype(np.int8, copy=True)
    out[clutter] = 100
    return ClutteredMap(
        grid=out,
        structure=structure,
        clutter=clutter,
        shape=shape,
        count=count,
        size_px=int(size_px),
        seed=seed,
    )
