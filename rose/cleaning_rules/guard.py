"""The topology guard: no robot-sized passage opened between regions the input kept apart.

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from rose.cleaning_rules.masks import _any_of_8, _neighbour_labels, _padded_box
from rose.labelling import (
    component_areas,
    components,
    label_boxes,
    labels_wanted,
)


def passable(obstacles: npt.NDArray[np.bool_], radius_px: float) -> npt.NDArray[np.bool_]:
    """Cells farther than ``radius_px`` (centre to centre) from every obstacle cell."""
    if not obstacles.any():
        return np.ones(obstacles.shape, dtype=bool)
    return ~_blocked(obstacles, radius_px)


def _blocked(obstacles: npt.NDArray[np.bool_], radius_px: float) -> npt.NDArray[np.bool_]:
    """Cells within ``radius_px`` (centre to centre) of an obstacle cell: not :func:`passable`."""
    import cv2

    reach = math.floor(radius_px)
    offsets = np.arange(-reach, reach + 1)
    disc = (offsets[:, None] ** 2 + offsets[None, :] ** 2 <= radius_px**2).astype(np.uint8)
    return cv2.dilate(obstacles.view(np.uint8), disc).view(bool)


def topology_guard(
    occupied: npt.NDArray[np.bool_],
    keep: npt.NDArray[np.bool_],
    *,
    radius_px: float,
    added: npt.NDArray[np.bool_] | None = None,
    window_px: int,
    min_region_px: float,
) -> npt.NDArray[np.bool_]:
    """Removed cells to restore so that no robot-sized passage opens between separate regions.

    Removing ``occupied & ~keep`` (and adding the obstacles ``added``) makes some cells passable for
    a disc of ``radius_px``. Each connected patch of them is checked in a window of ``window_px``
    cells around it: if the cells that were passable before (``added`` counting as obstacles before
    too: hidden walls, there but unseen) and touch the patch belong to two or more regions of the
    window that are not small enclosed pockets (a pocket does not reach the window's
    edge and covers less than ``min_region_px``), every removed cell within ``radius_px + 1`` of the
    patch is restored: those are the cells that kept the disc out of it. Patches surrounded by
    formerly passable cells (a free-standing object) are skipped without labelling; the rest cost
    one small labelling each.

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        Cells of ``occupied & ~keep`` to restore.
    """
    import cv2

    removal = occupied & ~keep
    restore = np.zeros(occupied.shape, dtype=bool)
    if not removal.any():
        return restore
    after = occupied & keep if added is None else (occupied & keep) | added
    # The added obstacles (hidden walls) were there before too, only unseen: regions they close off
    # are told apart as such (the inside of a cabinet against a wall, closed by the wall line behind
    # it, is a pocket, not the unknown outside). What opens is the same either way: the added
    # obstacles block after as well.
    blocked_before = _blocked(occupied if added is None else occupied | added, radius_px)
    # Passable after, not before (booleans: a > b is a & ~b, one pass).
    opened = np.greater(blocked_before, _blocked(after, radius_px))
    if not opened.any():
        return restore
    # Everything the guard looks at lies within a window (plus the restoring reach) of an opened
    # patch: work on their bounding box (windows clipped by it are clipped as by the map).
    reach = math.ceil(radius_px) + 1
    box = _padded_box(opened, window_px + reach + 2)
    before, opened = ~blocked_before[box], opened[box]
    count, patches = components(opened)
    boxes = label_boxes(patches, np.flatnonzero(opened), count)
    ring_cells, ring_patches = _rings(patches, opened, count)
    formerly = before.reshape(-1)[ring_cells]
    # Patches whose ring is all formerly passable are free-standing objects: nothing to check.
    blocked = np.zeros(count, dtype=bool)
    blocked[ring_patches[~formerly]] = True
    blocked[0] = False
    ring_cells, ring_patches = ring_cells[formerly], ring_patches[formerly]
    # A patch whose formerly passable ring cells are one connected arc joins nothing (it opens into
    # one region only): only patches with two or more arcs need a labelled window. An arc that
    # also runs along another patch's ring proves nothing (it may leave this patch's window).
    touched = np.zeros(opened.shape, dtype=bool)
    touched.reshape(-1)[ring_cells] = True
    arcs_count, arcs = components(touched)
    pairs = np.unique(ring_patches * arcs_count + arcs.reshape(-1)[ring_cells])
    arc_of, patch_of = pairs % arcs_count, pairs // arcs_count
    shared = np.bincount(arc_of, minlength=arcs_count)[arc_of] >= 2
    several = np.bincount(patch_of, minlength=count) >= 2
    several[patch_of[shared]] = True
    blocked &= several
    if not blocked.any():
        return restore
    separating = _separating_patches(
        before, boxes, blocked, ring_cells, ring_patches, window_px, min_region_px
    )
    if not separating.any():
        return restore
    # The removed cells within reach of a separating patch (dilated on the patches' box only): the
    # ones that kept the disc out of it. Whole removed pieces would also bring back furniture that
    # merely touches a wall hole, diagonally, as rasterised walls at an angle often do.
    reach_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1, 2 * reach + 1))
    seeds = labels_wanted(separating, patches, opened)
    near = _padded_box(seeds, reach)
    zone = np.zeros(seeds.shape, dtype=bool)
    zone[near] = cv2.dilate(seeds[near].view(np.uint8), reach_kernel).astype(bool)
    restore[box] = zone & removal[box]
    return restore


def _rings(
    patches: npt.NDArray[np.integer], opened: npt.NDArray[np.bool_], count: int
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.int64]]:
    """The ring of every patch (``count`` labels, 0 the background): each cell outside ``opened``
    with an 8-neighbour in a patch, once per patch it touches (a cell between two patches is in
    both rings).

    Returns
    -------
    cells : ndarray of intp, shape (N,)
        Flat indices into ``patches``.
    labels : ndarray of int64, shape (N,)
        The patch of each entry.
    """
    import cv2

    grown = cv2.dilate(opened.view(np.uint8), np.ones((3, 3), np.uint8))
    cells = np.flatnonzero(grown.view(bool) & ~opened)
    # The labels of every ring cell's 8 neighbours (ring cells are few next to the whole image).
    around = _neighbour_labels(patches, cells)
    top = around.max(axis=1)
    # Cells next to two patches are rare: only they need every (cell, patch) pair sorted out.
    contested = _any_of_8((around > 0) & (around != top[:, None]))
    top = top.astype(np.int64)
    if not contested.any():
        return cells, top
    shared, labels = cells[contested], around[contested].astype(np.int64)
    keys = np.unique((shared[:, None] * count + labels)[labels > 0])
    return (
        np.concatenate([cells[~contested], keys // count]),
        np.concatenate([top[~contested], keys % count]),
    )


def _separating_patches(
    before: npt.NDArray[np.bool_],
    boxes: npt.NDArray[np.int64],
    blocked: npt.NDArray[np.bool_],
    ring_cells: npt.NDArray[np.intp],
    ring_patches: npt.NDArray[np.int64],
    window_px: int,
    min_region_px: float,
) -> npt.NDArray[np.bool_]:
    """Which ``blocked`` patches touch, with their ring (``ring_cells`` of ``ring_patches``, from
    :func:`_rings`), two or more regions of ``before`` (in a window of ``window_px`` cells around
    the patch) that are not small enclosed pockets (a pocket does not reach the window's edge and
    covers less than ``min_region_px``).

    All windows are copied into one mosaic, one empty cell apart, and labelled in one call.
    """

    count = boxes.shape[0]
    separating = np.zeros(count, dtype=bool)
    rows, cols = before.shape
    # The ring cells of every blocked patch (flat indices) and their patch.
    wanted = blocked[ring_patches]
    ring_idx, ring_patch = ring_cells[wanted], ring_patches[wanted]
    sizes = np.bincount(ring_patch, minlength=count)
    ids = np.flatnonzero(blocked & (sizes >= 2))
    if ids.size == 0:
        return separating
    x, y, w, h = (boxes[ids, i] for i in range(4))
    r0, c0 = np.maximum(y - window_px, 0), np.maximum(x - window_px, 0)
    r1, c1 = np.minimum(y + h + window_px, rows), np.minimum(x + w + window_px, cols)
    heights, widths = r1 - r0, c1 - c0
    # Shelf packing: windows left to right in rows of the mosaic, one empty cell between them.
    width = max(int(widths.max()) + 1, 1024)
    ox = np.zeros(ids.size, dtype=np.int64)
    oy = np.zeros(ids.size, dtype=np.int64)
    cursor_x = cursor_y = shelf = 0
    for i in range(ids.size):
        if cursor_x + int(widths[i]) + 1 > width:
            cursor_x, cursor_y, shelf = 0, cursor_y + shelf + 1, 0
        ox[i], oy[i] = cursor_x, cursor_y
        cursor_x += int(widths[i]) + 1
        shelf = max(shelf, int(heights[i]))
    mosaic = np.zeros((cursor_y + shelf + 1, width), dtype=np.uint8)
    view = before.view(np.uint8)
    for i in range(ids.size):
        mosaic[oy[i] : oy[i] + heights[i], ox[i] : ox[i] + widths[i]] = view[
            r0[i] : r1[i], c0[i] : c1[i]
        ]
    # Plain labels, areas from a histogram and the regions on their window's frame: a third of
    # the cost of OpenCV's statistics.
    region_count, regions = components(mosaic)
    areas = component_areas(regions, region_count)
    on_frame = np.zeros(region_count, dtype=bool)
    on_frame[regions.reshape(-1)[_frame_cells(oy, ox, heights, widths, mosaic.shape[1])]] = True
    on_frame[0] = False
    slot = np.full(count, -1, dtype=np.int64)
    slot[ids] = np.arange(ids.size)
    where = slot[ring_patch]
    keep = where >= 0
    where, cells = where[keep], ring_idx[keep]
    labels = regions[cells // cols - r0[where] + oy[where], cells % cols - c0[where] + ox[where]]
    touched = labels > 0
    pairs = np.unique(where[touched] * region_count + labels[touched])
    window_of, label = pairs // region_count, pairs % region_count
    open_regions = np.bincount(
        window_of[on_frame[label] | (areas[label] >= min_region_px)], minlength=ids.size
    )
    separating[ids] = open_regions >= 2
    return separating


def _frame_cells(
    top: npt.NDArray[np.int64],
    left: npt.NDArray[np.int64],
    heights: npt.NDArray[np.int64],
    widths: npt.NDArray[np.int64],
    stride: int,
) -> npt.NDArray[np.int64]:
    """Flat indices (rows of ``stride`` cells) of the first and last row and column of every
    window ``top, left, heights, widths`` (cells; a cell may come twice)."""
    n = top.size
    along = np.repeat(np.arange(n), widths)
    cols = left[along] + np.arange(along.size) - np.repeat(np.cumsum(widths) - widths, widths)
    down = np.repeat(np.arange(n), heights)
    rows = top[down] + np.arange(down.size) - np.repeat(np.cumsum(heights) - heights, heights)
    return np.concatenate(
        [
            top[along] * stride + cols,
            (top[along] + heights[along] - 1) * stride + cols,
            rows * stride + left[down],
            rows * stride + left[down] + widths[down] - 1,
        ]
    )
