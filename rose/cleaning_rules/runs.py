"""Walls as runs: straight stretches of occupied cells along the dominant directions, straight lines at
any angle, and the run algebra the rules share (runs of cells along rows, opened and closed).

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from rose.cleaning_rules.frames import FrameNeeds, _frames, in_rotated_frame
from rose.cleaning_rules.masks import _bounds, _flat_index, _nonzero_flat, _padded_box


def directional_runs(
    mask: npt.NDArray[np.bool_],
    directions: npt.NDArray[np.float64],
    *,
    min_length_px: float,
    tolerance_px: int = 1,
) -> npt.NDArray[np.bool_]:
    """Cells of ``mask`` on straight runs at least ``min_length_px`` long along any direction.

    ``mask`` is rotated so that a direction lies along the columns, dilated by ``tolerance_px`` (so a
    run may step sideways and skip up to ``2 * tolerance_px`` cells), opened with a line of
    ``min_length_px`` cells along the rows and the columns (the direction at right angles comes for
    free when the map has one), and rotated back.

    Parameters
    ----------
    mask : ndarray of bool, shape (rows, cols)
    directions : ndarray of float64, shape (K,)
        Line orientations in radians, counter-clockwise from +col towards +row, in ``[0, pi)``.
    min_length_px : float
        Shortest run, cells.
    tolerance_px : int
        Cells of tolerance across and along a run.

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        A subset of ``mask``.
    """
    out = np.zeros(mask.shape, dtype=bool)
    if not mask.any() or directions.size == 0:
        return out
    r0, r1, c0, c1 = _bounds(mask)
    crop = mask[r0:r1, c0:c1]
    length = max(3, round(min_length_px)) | 1  # odd: an even line is off by one cell after opening
    for angle in _frames(directions):
        out[r0:r1, c0:c1] |= _runs_in_frame(crop, angle, length, tolerance_px)
    return out & mask


def _runs_in_frame(
    crop: npt.NDArray[np.bool_], angle: float, length: int, tolerance_px: int
) -> npt.NDArray[np.bool_]:
    import cv2

    def runs_of(rotated: npt.NDArray[np.uint8], _turned: bool) -> npt.NDArray[np.uint8]:
        if tolerance_px > 0:
            box = np.ones((2 * tolerance_px + 1, 2 * tolerance_px + 1), np.uint8)
            rotated = np.asarray(cv2.dilate(rotated, box), dtype=np.uint8)
        # The openings with a line along the rows and the columns, from the runs of the few
        # occupied cells (a fifth of the cost of two OpenCV openings of the whole rotated image).
        rotated = np.ascontiguousarray(rotated)
        cells = _nonzero_flat(rotated)
        along_rows = None if _dense(cells, rotated) else _runs(cells, rotated.shape, False)
        if along_rows is None or _fragmented(along_rows, rotated):
            return _open(rotated, (1, length)) | _open(rotated, (length, 1))
        runs = np.zeros(rotated.shape, dtype=np.uint8)
        for vertical in (False, True):
            lines = _runs(cells, rotated.shape, vertical) if vertical else along_rows
            long_runs = _open_runs(lines, length, rotated.shape[not vertical])
            runs.reshape(-1)[_run_cells(long_runs, rotated.shape, vertical)] = 1
        return runs

    runs, turned = in_rotated_frame(
        crop.view(np.uint8),
        angle,
        runs_of,
        reach_px=length + 2 * tolerance_px + 2,
        # Nothing without a run of ``length`` cells along a line of the grown image.
        needs=FrameNeeds(runs=((tolerance_px, length),)),
    )
    # 0 or 1 in every cell: read as booleans without a copy.
    if not turned:
        return runs.view(bool)
    return np.asarray(cv2.dilate(runs, np.ones((3, 3), np.uint8)), dtype=np.uint8).view(bool)


def _open(image: npt.NDArray[np.uint8], kernel_shape: tuple[int, int]) -> npt.NDArray[np.uint8]:
    """Morphological opening with a ``kernel_shape`` box; outside the image counts as empty."""
    import cv2

    kernel = np.ones(kernel_shape, np.uint8)
    opened = cv2.morphologyEx(
        image, cv2.MORPH_OPEN, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0
    )
    return np.asarray(opened, dtype=np.uint8)


#: Share of occupied cells above which the line morphology is OpenCV's without looking at the runs
#: (finding the runs of millions of cells costs more than OpenCV's passes; real maps: at most 5 %).
_DENSE_CELLS = 0.1


#: Runs per cell of the image above which the line morphology is done on the whole image by OpenCV
#: rather than on the runs: the runs' index arrays grow with the runs and what they close, OpenCV's
#: cost with the image. Walls make long runs (real maps: at most 1.5 % of the cells start a run,
#: where the runs are faster); speckle makes a run of nearly every cell (a 40 %-occupied random map
#: cleaned 4x slower on the runs).
_FRAGMENTED_RUNS = 0.025


def _dense(cells: npt.NDArray[np.int64], image: npt.NDArray[np.uint8]) -> bool:
    """Whether ``cells`` (the non-zero cells of ``image``) are too many for the run versions."""
    return cells.size > _DENSE_CELLS * image.size


def _fragmented(runs: _Runs, image: npt.NDArray[np.uint8]) -> bool:
    """Whether ``image`` has too many ``runs`` (its runs along one axis) for the run versions."""
    return runs[0].size > _FRAGMENTED_RUNS * image.size


def _covered(runs: _Runs) -> int:
    """Number of cells in ``runs``."""
    _, start, end = runs
    return int((end - start + 1).sum())


_Runs = tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64]]


def _runs(cells: npt.NDArray[np.int64], shape: tuple[int, int], vertical: bool) -> _Runs:
    """The maximal runs of ``cells`` (flat indices, ascending) along the rows, or the columns
    when ``vertical``: the line (row or column) of each, and its first and last cell along it."""
    cols = shape[1]
    if vertical:
        row, col = np.divmod(cells, cols)
        order = _order_by(col, cols)
        line, pos = col[order], row[order]
    else:
        line, pos = np.divmod(cells, cols)
    if line.size == 0:
        return line, pos, pos
    first, last = _groups(line, pos[1:] != pos[:-1] + 1)
    return line[first], pos[first], pos[last]


def _order_by(major: npt.NDArray[np.int64], size: int) -> npt.NDArray[np.intp]:
    """The stable order of items by ``major`` (values in ``[0, size)``): with the items in order
    within each value, the order of a full sort. Keys of 16 bits take numpy's radix sort, a fifth
    of the cost of sorting flat indices (64 bits) on the cleaning's images."""
    if size <= np.iinfo(np.uint16).max + 1:
        return np.argsort(major.astype(np.uint16), kind="stable")
    return np.argsort(major, kind="stable")


def _groups(
    line: npt.NDArray[np.int64], apart: npt.NDArray[np.bool_]
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """Where each group of consecutive items (``line`` non-empty) starts and ends (inclusive): a new
    group at each new line and wherever ``apart`` (shape ``line.size - 1``: item ``i + 1`` is apart
    from item ``i``) holds."""
    starts = np.empty(line.size, dtype=bool)
    starts[0] = True
    np.logical_or(apart, line[1:] != line[:-1], out=starts[1:])
    first = np.flatnonzero(starts)
    return first, np.append(first[1:], line.size) - 1


def _run_cells(runs: _Runs, shape: tuple[int, int], vertical: bool) -> npt.NDArray[np.int64]:
    """Flat indices of the cells of ``runs`` (along the columns when ``vertical``)."""
    line, start, end = runs
    lengths = end - start + 1
    offsets = np.arange(int(lengths.sum()), dtype=np.int64)
    pos = np.repeat(start - (np.cumsum(lengths) - lengths), lengths) + offsets
    along = np.repeat(line, lengths)
    return _flat_index(along, pos, shape, vertical)


def _open_runs(runs: _Runs, size: int, extent: int) -> _Runs:
    """OpenCV's opening with a line of ``size`` cells along the runs (lines of ``extent`` cells,
    empty outside the image): the runs at least ``size`` long, one cell on for an even ``size``
    (OpenCV's anchor is off the middle then)."""
    line, start, end = runs
    keep = end - start + 1 >= size
    shift = 2 * (size // 2) - size + 1
    return line[keep], start[keep] + shift, np.minimum(end[keep] + shift, extent - 1)


def _close_runs(runs: _Runs, size: int, extent: int) -> _Runs:
    """OpenCV's closing with a line of ``size`` cells along the runs (lines of ``extent`` cells)
    and its default borders: empty for the dilation, full for the erosion, so that a gap between
    a run and the image's edge closes too when the dilation reaches the edge."""
    line, start, end = runs
    if line.size == 0:
        return runs
    before = size // 2
    after = size - 1 - before
    low = np.maximum(start - after, 0)
    high = np.minimum(end + before, extent - 1)
    # Dilated runs that meet merge (the dilation keeps their order along a line).
    first, last = _groups(line, low[1:] > high[:-1] + 1)
    low, high = low[first], high[last]
    low = np.where(low == 0, 0, low + before)
    high = np.where(high == extent - 1, extent - 1, high - after)
    keep = low <= high
    return line[first][keep], low[keep], high[keep]


def straight_lines(
    mask: npt.NDArray[np.bool_], *, min_length_px: float, max_gap_px: int = 2
) -> npt.NDArray[np.bool_]:
    """Cells of ``mask`` on straight segments at least ``min_length_px`` long, at any angle.

    OpenCV's probabilistic Hough transform (deterministic) finds the segments on ``mask`` grown by
    one cell (a band around walls that step or bend by a cell), with gaps of up to ``max_gap_px``
    cells in that band (up to ``max_gap_px + 2`` between cells of ``mask``); they are drawn three
    cells wide and intersected with ``mask``. The same cells give the same segments wherever they
    lie in ``mask``.
    """
    import cv2

    out = np.zeros(mask.shape, dtype=np.uint8)
    if not mask.any():
        return out.astype(bool)
    length = max(2, round(min_length_px))
    # On the mask's bounding box in a frame of one empty cell, whatever lies around it (the map's
    # edge too): the transform's votes depend on where the cells lie in its image, so the same
    # cells give the same segments wherever they are.
    box = _padded_box(mask, 0)
    # Grown by a cell all round (into the frame): a wall at an angle to the grid is a staircase, and
    # a SLAM map's walls bend by a cell or two over a few metres; the transform's one-cell bins and
    # the one-cell corridor it follows a segment along broke such a wall into pieces shorter than
    # a run. The band is two cells longer than the wall: the transform's length is set so that it
    # still counts the mask's cells. Its gaps are the band's: where a bend leaves the band, or a
    # gap of the mask's cells up to two cells longer (asked to count the mask's gaps, the transform
    # lost most of what the band gained: ray-cast wall recall 0.938 against 0.951).
    # (0 or 1: the transform takes any non-zero cell.)
    framed = cv2.copyMakeBorder(mask[box].view(np.uint8), 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0)
    image = cv2.dilate(framed, np.ones((3, 3), np.uint8))
    segments = cv2.HoughLinesP(
        image,
        1.0,
        math.pi / 180,
        threshold=max(2, length // 2),
        minLineLength=length + 2,
        maxLineGap=max_gap_px,
    )
    if segments is not None:
        drawn = np.zeros(image.shape, dtype=np.uint8)
        lines = segments.reshape(-1, 1, 2, 2).astype(np.int32)
        cv2.polylines(drawn, list(lines), isClosed=False, color=1, thickness=3)
        # Drawn with 1: read as booleans without a copy.
        out[box] = drawn[1:-1, 1:-1].view(bool) & mask[box]
    return out.view(bool)
