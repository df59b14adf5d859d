"""Occupancy-grid conventions shared by every stage.

Grids follow ROS ``nav_msgs/OccupancyGrid``: a 2D ``int8`` array of shape ``(rows, cols)``, row 0 at the
map origin (the bottom of the map when drawn with y up), ``-1`` unknown, ``0..100`` occupancy probability
in percent. Boolean arrays are accepted as occupied masks.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import numpy.typing as npt

from rose.errors import RoseError

__all__ = [
    "FREE",
    "OCCUPIED",
    "UNKNOWN",
    "as_occupancy_grid",
    "blocks_any",
    "blocks_max",
    "occupied_mask",
    "true_bounds",
    "warn_if_mask",
]

UNKNOWN = -1
FREE = 0
OCCUPIED = 100


def as_occupancy_grid(grid: npt.ArrayLike) -> npt.NDArray[np.int8]:
    """Return ``grid`` as an ``int8`` occupancy grid of the same shape (a copy when converted).

    A boolean array becomes ``100`` where True and ``0`` elsewhere. Integer or float arrays must hold
    values in ``-1..100`` (floats are truncated toward zero, as a cast to int8).

    Raises
    ------
    RoseError
        If ``grid`` is not 2D or holds values outside ``-1..100`` (NaN included), or is a float
        grid of probabilities or a 0/1 float mask (nothing above 1): as percent, all free; or a
        masked array with masked cells (``grid.filled(-1)`` makes them unknown).
    """
    if isinstance(grid, str | bytes | os.PathLike):
        msg = (
            f"The input grid must be an array, got the path {grid!r}; read a map file with "
            "rose.load_map(path) and pass its .grid (or the OccupancyMap where one is taken)."
        )
        raise RoseError(msg)
    if hasattr(grid, "grid") and hasattr(grid, "resolution_m"):  # an OccupancyMap
        msg = "The input grid must be an array, got an OccupancyMap: pass its .grid."
        raise RoseError(msg)
    if np.ma.is_masked(grid):
        # np.asarray keeps what lies under the mask: masked cells were read as their values.
        msg = (
            "The input grid is a masked array with masked cells, whose values would be read as "
            "they are: pass grid.filled(-1) to make them unknown."
        )
        raise RoseError(msg)
    try:
        array = np.asarray(grid)
    except ValueError as err:  # ragged nested lists
        msg = f"The input grid must be a 2D array, got {type(grid).__name__} ({err})."
        raise RoseError(msg) from err
    if array.ndim != 2:
        msg = f"The input grid must be 2D, got an array of shape {array.shape}."
        raise RoseError(msg)
    if array.dtype == np.bool_:
        return np.where(array, np.int8(OCCUPIED), np.int8(FREE))
    # By kind: numpy counts timedelta64 among the integers (a grid of durations was read).
    if array.dtype.kind not in "iuf":
        msg = f"The input grid must be boolean or numeric, got dtype {array.dtype}."
        raise RoseError(msg)
    if np.issubdtype(array.dtype, np.floating) and array.size and np.isnan(array.max()):
        msg = "The input grid must hold -1 (unknown) or 0..100 (occupancy), got NaN."
        raise RoseError(msg)
    if array.size and (array.min() < UNKNOWN or array.max() > OCCUPIED):
        msg = (
            "The input grid must hold -1 (unknown) or 0..100 (occupancy), "
            f"got values in [{array.min()}, {array.max()}]."
        )
        raise RoseError(msg)
    if np.issubdtype(array.dtype, np.floating) and array.size and 0 < array.max() <= 1.0:
        # Probabilities, or a 0/1 mask as floats: read as percent, a free map.
        msg = (
            "The input grid holds occupancy probabilities in 0..1 (floats, nothing above 1), but "
            "it takes percent (0..100, -1 unknown): pass np.where(grid < 0, -1, grid * 100)."
        )
        raise RoseError(msg)
    return array.astype(np.int8, copy=False)


def occupied_mask(grid: npt.NDArray[np.int8], *, occupied_threshold: int) -> npt.NDArray[np.bool_]:
    """Boolean mask of occupied cells: occupancy ``>= occupied_threshold`` (unknown cells are never occupied).

    Parameters
    ----------
    grid : ndarray of int8, shape (rows, cols)
        Occupancy grid in ROS convention.
    occupied_threshold : int
        Smallest occupancy (percent, 1..100) that counts as occupied.
    """
    if not 1 <= occupied_threshold <= OCCUPIED:
        msg = f"occupied_threshold must be in 1..100, got {occupied_threshold}."
        raise RoseError(msg)
    return grid >= occupied_threshold


#: Rows scanned at a time for the last row holding a True cell (:func:`true_bounds`).
_ROW_BLOCK = 32


def true_bounds(mask: npt.NDArray[np.bool_]) -> tuple[int, int, int, int] | None:
    """``(row0, row1, col0, col1)`` (ends exclusive) of the True cells of ``mask`` (bool, shape
    (rows, cols)); None when it has none.

    Twice as fast as ``flatnonzero(mask.any(axis=1))`` and ``(axis=0)`` on SLAM maps' grids (40
    vs 95 us on 1000 x 1000 cells): ``argmax`` and ``any`` stop at the first True cell, so the
    first row is found from the start, the last one by blocks of rows from the end, and the columns
    are reduced over the rows between only.
    """
    if mask.size == 0:
        return None
    cols_n = mask.shape[1]
    flat = mask.reshape(-1)  # a view of a contiguous mask
    first = int(flat.argmax())
    if not flat[first]:
        return None
    r0 = first // cols_n
    end = mask.shape[0]
    while True:  # ends at row r0 at the latest, which holds a True cell
        start = max(end - _ROW_BLOCK, r0)
        block = mask[start:end]
        if block.any():
            rows = np.any(block, axis=1)
            r1 = end - int(rows[::-1].argmax())
            break
        end = start
    cols = np.any(mask[r0:r1], axis=0)
    return r0, r1, int(cols.argmax()), cols_n - int(cols[::-1].argmax())


def blocks_any(mask: npt.NDArray[np.bool_], factor: int) -> npt.NDArray[np.bool_]:
    """Whether each ``factor`` x ``factor`` block of ``mask`` holds a True cell.

    ``mask``: shape (rows, cols), both multiples of ``factor`` (any dtype: non-zero is True);
    returns shape (rows / factor, cols / factor), block (i, j) covering rows ``i factor ..`` and
    columns ``j factor ..``. The OR runs over whole rows (one strided slice per row of a block,
    then per column): numpy's ``any`` over the block axes of a 4-D view is over 10x slower.
    """
    mask = np.asarray(mask, dtype=np.bool_)  # no copy of a bool mask; bytes of 0 / 1 below
    return blocks_max(mask.view(np.uint8), factor).view(np.bool_)  # the largest of 0 / 1: any


def blocks_max(image: npt.NDArray[np.uint8], factor: int) -> npt.NDArray[np.uint8]:
    """The largest value of each ``factor`` x ``factor`` block of ``image`` (shape (rows, cols),
    both multiples of ``factor``), shape (rows / factor, cols / factor), as :func:`blocks_any`."""
    rows, cols = image.shape
    if factor < 1 or rows % factor or cols % factor:
        msg = f"image shape {image.shape} is not a multiple of the block size {factor}"
        raise ValueError(msg)
    block_rows = image[0::factor].copy()
    for k in range(1, factor):
        np.maximum(block_rows, image[k::factor], out=block_rows)
    blocks = block_rows[:, 0::factor].copy()
    for k in range(1, factor):
        np.maximum(blocks, block_rows[:, k::factor], out=blocks)
    return blocks


def warn_if_mask(
    given: npt.ArrayLike,
    occupancy: npt.NDArray[np.int8],
    occupied_threshold: int,
    *,
    stacklevel: int = 3,
) -> None:
    """Warn of a 0/1 mask passed as integers (``mask.astype(np.uint8)``, a usual slip; -1 for its
    unknown cells too): read as percent it is all free. ROS grids are int8 and have unknown cells around the known part, so
    grids from logs and map files (int8) are never warned about."""
    dtype = getattr(given, "dtype", None)
    if dtype is None or dtype == np.int8 or dtype == np.bool_ or occupied_threshold <= 1:
        return
    # -1 too: a mask with its unknown cells (np.where(grid < 0, -1, mask)) is as free.
    if occupancy.size and occupancy.max() == 1:
        warnings.warn(
            "The input grid holds only 0 and 1 (and -1, unknown), read as occupancy in percent: "
            "all free. For a 0/1 occupied mask, pass grid.astype(bool), or with unknown cells "
            "np.where(grid < 0, -1, grid * 100).",
            UserWarning,
            stacklevel=stacklevel,
        )
