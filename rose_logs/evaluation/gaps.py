"""Robot-sized gaps: erased wall patches a disc of the robot's radius can pass through.

A map is judged by what a planner would do with it. Before cleaning, the obstacles are the true wall
cells; after cleaning, the wall cells the cleaning kept. A cell is *passable* when the disc of radius
``radius_px`` centred on it holds no obstacle cell centre (unknown cells are passable: planners that
explore treat them so, and a hole from a room into unknown space is a hole). Every connected patch of
cells that became passable is a gap when, inside a window of ``margin_px`` cells around it, the cells
passable before that touch the patch belong to two or more regions: the erased wall lets the disc
cross from one side to the other where it could not before, at least not within the window (a doorway
closer than the margin does not make a hole in the wall harmless to a planner, but we are lenient).
A region of the window that does not reach the window's edge and covers less than ``pocket_px`` cells
is an enclosed pocket (the inside of a thick wall or of a piece of furniture scanned from all sides):
opening it lets no robot anywhere, so it does not count.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

# The cleaning's own test of where the robot fits: the gaps are counted for the robot it protects.
from rose.cleaning_rules import passable

__all__ = ["passable", "robot_gaps"]


def robot_gaps(
    walls: npt.NDArray[np.bool_],
    kept: npt.NDArray[np.bool_],
    *,
    radius_px: float,
    margin_px: int,
    pocket_px: float,
    added: npt.NDArray[np.bool_] | None = None,
) -> int:
    """Number of robot-sized gaps the cleaning opened in ``walls``.

    Parameters
    ----------
    walls : ndarray of bool, shape (rows, cols)
        True wall cells of the input map.
    kept : ndarray of bool, shape (rows, cols)
        Occupied cells of the cleaned map (only its wall cells matter).
    radius_px : float
        Robot radius, cells.
    margin_px : int
        Half-size of the window around each patch in which regions are told apart, cells.
    pocket_px : float
        Enclosed regions smaller than this (cells) are pockets, not regions.
    added : ndarray of bool, shape (rows, cols), optional
        Cells the cleaning made occupied that were not (completed walls): obstacles after cleaning.

    Returns
    -------
    int
    """
    import cv2

    before = passable(walls, radius_px)
    after = passable(walls & kept if added is None else (walls & kept) | added, radius_px)
    opened = after & ~before
    if not opened.any():
        return 0
    count, patches, stats, _ = cv2.connectedComponentsWithStats(
        opened.astype(np.uint8), connectivity=8
    )
    rows, cols = walls.shape
    gaps = 0
    ring_kernel = np.ones((3, 3), np.uint8)
    for index in range(1, count):
        x, y, w, h = stats[index, :4].tolist()
        r0, c0 = max(y - margin_px, 0), max(x - margin_px, 0)
        r1, c1 = min(y + h + margin_px, rows), min(x + w + margin_px, cols)
        patch = patches[r0:r1, c0:c1] == index
        window = before[r0:r1, c0:c1]
        _, regions, region_stats, _ = cv2.connectedComponentsWithStats(
            window.astype(np.uint8), connectivity=8
        )
        ring = cv2.dilate(patch.astype(np.uint8), ring_kernel).astype(bool) & ~patch
        touching = np.unique(regions[ring & window])
        touching = touching[touching > 0]
        wx, wy, ww, wh, area = (region_stats[touching, i] for i in range(5))
        edge = (wx == 0) | (wy == 0) | (wx + ww == window.shape[1]) | (wy + wh == window.shape[0])
        if int(np.count_nonzero(edge | (area >= pocket_px))) >= 2:
            gaps += 1
    return gaps
