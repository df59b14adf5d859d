"""Mask helpers the cleaning's rules share: lengths in cells, bounding boxes, dilation, neighbours.

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from rose.labelling import components


def _flat_index(
    line: npt.NDArray[np.int64], pos: npt.NDArray[np.int64], shape: tuple[int, int], vertical: bool
) -> npt.NDArray[np.int64]:
    """Flat indices of the cells at ``pos`` along ``line`` (a column when ``vertical``, else a row)."""
    return pos * shape[1] + line if vertical else line * shape[1] + pos


def _nonzero_flat(image: npt.NDArray[np.uint8]) -> npt.NDArray[np.int64]:
    """Flat indices (ascending) of the non-zero cells of a C-contiguous image (OpenCV's list of
    them: a tenth of the cost of numpy's for a uint8 image)."""
    import cv2

    points = cv2.findNonZero(image)
    if points is None:
        return np.empty(0, dtype=np.int64)
    points = points.reshape(-1, 2).astype(np.int64)
    return points[:, 1] * image.shape[1] + points[:, 0]


def _grown_through(
    start: npt.NDArray[np.bool_] | npt.NDArray[np.uint8],
    through: npt.NDArray[np.bool_] | npt.NDArray[np.uint8],
    steps: int,
    *,
    connectivity: int = 8,
) -> npt.NDArray[np.uint8]:
    """``start`` grown ``steps`` steps to the 8 (or 4) neighbours into ``through`` cells (0/1
    uint8, same shape): after each step only cells of ``through`` remain (``start``'s own cells
    too); after none, ``start`` as it is."""
    import cv2

    step = _SQUARE if connectivity == 8 else _CROSS
    grown, cells = start.view(np.uint8), through.view(np.uint8)
    for _ in range(steps):
        grown = np.bitwise_and(cv2.dilate(grown, step), cells)
    return grown


#: The 8-neighbours and the cell itself.
_SQUARE = np.ones((3, 3), np.uint8)

#: The 4-neighbours and the cell itself.
_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)


def _touching(pieces: npt.NDArray[np.bool_], other: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """The 8-connected components of ``pieces`` within two cells of ``other``."""
    out = np.zeros(pieces.shape, dtype=bool)
    # The pieces' cells are few: listed once (OpenCV's list, a tenth of numpy's cost), they give
    # the bounding box and are looked up one by one instead of in passes over the box.
    cells = _nonzero_flat(np.ascontiguousarray(pieces).view(np.uint8))
    if cells.size == 0 or not other.any():
        return out
    rows, cols = np.divmod(cells, pieces.shape[1])
    # Only the pieces' bounding box matters (plus two cells for the reach of ``other``).
    box = _cells_box(rows, cols, pieces.shape, 2)
    count, labels = components(pieces[box])
    near = _dilate(other[box], 2)
    inside = (rows - box[0].start, cols - box[1].start)
    own = labels[inside]
    wanted = np.zeros(count, dtype=bool)
    wanted[own[near[inside]]] = True
    out[rows, cols] = wanted[own]
    return out


def _cells_box(
    rows: npt.NDArray[np.int64], cols: npt.NDArray[np.int64], shape: tuple[int, int], pad: int
) -> tuple[slice, slice]:
    """The bounding box of the cells at ``rows, cols`` (at least one, in any order) of a mask of
    ``shape``, ``pad`` cells wider on every side, clipped to the mask (as :func:`_padded_box`)."""
    return slice(max(int(rows.min()) - pad, 0), min(int(rows.max()) + 1 + pad, shape[0])), slice(
        max(int(cols.min()) - pad, 0), min(int(cols.max()) + 1 + pad, shape[1])
    )


def _near(
    cells: npt.NDArray[np.bool_], other: npt.NDArray[np.bool_], reach: int
) -> npt.NDArray[np.bool_]:
    """Cells of ``cells`` with a cell of ``other`` within ``reach`` cells (chessboard distance).
    Dilated on the bounding box of ``cells`` only (``reach`` wider): the same at every cell of it."""
    import cv2

    out = np.zeros(cells.shape, dtype=bool)
    # Few cells: listed once, they give the box and are looked up one by one (as in _touching).
    at = _nonzero_flat(np.ascontiguousarray(cells).view(np.uint8))
    if at.size == 0:
        return out
    rows, cols = np.divmod(at, cells.shape[1])
    box = _cells_box(rows, cols, cells.shape, reach)
    side = 2 * reach + 1
    grown = cv2.dilate(other[box].view(np.uint8), np.ones((side, side), np.uint8)).view(bool)
    out[rows, cols] = grown[rows - box[0].start, cols - box[1].start]
    return out


def length_px(length_m: float, res: float) -> float:
    """``length_m`` in cells, rounded to 1e-6 so that a resolution stored as float32 (0.05 ->
    0.0500000007) converts exactly like the decimal one."""
    return round(length_m / res, 6)


def _dilate(mask: npt.NDArray[np.bool_], radius_px: int) -> npt.NDArray[np.bool_]:
    import cv2

    if radius_px <= 0:
        return mask.copy()
    size = 2 * radius_px + 1
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    return cv2.dilate(mask.view(np.uint8), kernel).view(bool)


def _padded_box(mask: npt.NDArray[np.bool_], pad: int) -> tuple[slice, slice]:
    """The bounding box of the True cells of ``mask`` (it must have one), ``pad`` cells wider on
    every side, clipped to ``mask``."""
    r0, r1, c0, c1 = _bounds(mask)
    rows, cols = mask.shape
    return slice(max(r0 - pad, 0), min(r1 + pad, rows)), slice(
        max(c0 - pad, 0), min(c1 + pad, cols)
    )


def _bounds(mask: npt.NDArray[np.bool_]) -> tuple[int, int, int, int]:
    """``r0, r1, c0, c1`` of the bounding box of the True cells (``mask`` must have one)."""
    import cv2

    # OpenCV's bounding rectangle of the non-zero pixels: one pass, not two reductions.
    x, y, width, height = cv2.boundingRect(mask.view(np.uint8))
    return y, y + height, x, x + width


def _neighbour_columns(
    labels: npt.NDArray[np.integer], cells: npt.NDArray[np.intp]
) -> list[npt.NDArray[np.integer]]:
    """The labels of the 8 neighbours of each cell: one array of shape ``(N,)`` per neighbour
    (reductions over the 8 run as 7 elementwise passes, several times cheaper than numpy's
    reduction over rows of 8).

    ``cells`` are flat indices into ``labels``, ascending (as :func:`numpy.flatnonzero` gives
    them). On the image border a neighbour is clipped onto the cell's own row or column: that only
    repeats a neighbour or the cell itself.
    """
    rows, cols = labels.shape
    flat = labels.reshape(-1)
    row, col = np.divmod(cells, cols)
    inner = cells.size == 0 or (
        row[0] > 0 and row[-1] < rows - 1 and int(col.min()) > 0 and int(col.max()) < cols - 1
    )
    offsets = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc]
    return [
        flat[cells + (dr * cols + dc)]
        if inner
        else flat[np.clip(row + dr, 0, rows - 1) * cols + np.clip(col + dc, 0, cols - 1)]
        for dr, dc in offsets
    ]


def _any_of_8(flags: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """``flags.any(axis=1)`` of a C-contiguous ``(N, 8)`` boolean array, each row read as one uint64
    (numpy's reduction over rows of 8 costs several times more)."""
    return flags.view(np.uint64).reshape(-1) != 0
