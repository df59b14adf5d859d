"""8-connected components of boolean masks with OpenCV, and lookups that touch only the labelled cells.

Shared by the ``"walls"`` cleaning (:mod:`rose.cleaning_rules`) and the break detector
(:mod:`rose.breaks`). Masks are ``(rows, cols)`` boolean or uint8 arrays; OpenCV is imported lazily,
like everywhere in :mod:`rose`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = [
    "FLOOD_FILL_MAX_SIDE",
    "component_areas",
    "components",
    "fill_from_corner",
    "label_boxes",
    "label_type",
    "labels_looked_up",
    "labels_wanted",
]


def labels_wanted(
    wanted: npt.NDArray[np.bool_], labels: npt.NDArray[np.integer], cells: npt.NDArray[np.bool_]
) -> npt.NDArray[np.bool_]:
    """``wanted[labels]`` on ``cells`` (False elsewhere), looked up at those cells only: they are few
    next to the whole image, so this is much cheaper than indexing every label."""
    at = np.flatnonzero(cells)
    out = np.zeros(labels.shape, dtype=bool)
    out.ravel()[at] = wanted[labels.ravel()[at]]
    return out


def labels_looked_up(
    wanted: npt.NDArray[np.bool_], labels: npt.NDArray[np.integer]
) -> npt.NDArray[np.bool_]:
    """``wanted[labels]`` at every cell (``wanted``: one boolean per label, shape ``(count,)``;
    every label must be below ``count``, as OpenCV's labellings give them: unchecked, a larger
    one wraps modulo 256 in the table).

    With at most 256 labels OpenCV's lookup table of the labels as bytes (the guard's regions, a
    few dozen: 0.49 against numpy's take's 1.33 ms on a 1149 x 1171 box), else numpy's take of
    bytes (the object rules' unknown pockets, thousands: a third less than indexing booleans).
    """
    import cv2

    if wanted.size <= 256:
        table = np.zeros(256, dtype=np.uint8)
        table[: wanted.size] = wanted
        # Every label is below 256: as bytes, exactly.
        return np.asarray(cv2.LUT(labels.astype(np.uint8), table), dtype=np.uint8).view(bool)
    return np.take(wanted.view(np.uint8), labels).view(bool)


def label_type(mask: npt.NDArray[np.bool_] | npt.NDArray[np.uint8], connectivity: int = 8) -> int:
    """OpenCV label type for the components of ``mask``: 16 bits (half the memory, about twice as
    fast) when the components cannot outnumber them, else 32."""
    import cv2

    rows, cols = mask.shape
    limit = np.iinfo(np.uint16).max
    if connectivity == 8:  # at most one component per 2 x 2 block
        bound = min(int(np.count_nonzero(mask)), ((rows + 1) // 2) * ((cols + 1) // 2))
        if bound < limit:
            return int(cv2.CV_16U)
    # Every component, 4- or 8-connected, holds a whole run of cells along a row: the runs (cells
    # whose left neighbour is not in the mask, two passes) bound them, and nearly always closely
    # enough. Counting them is cheap next to a 32-bit labelling of a large mask and the areas of its
    # labels (free or unknown space is often millions of cells in few components).
    cells = np.asarray(mask, dtype=bool)
    runs = np.count_nonzero(cells[:, 1:] > cells[:, :-1]) + np.count_nonzero(cells[:, :1])
    if runs < limit:
        return int(cv2.CV_16U)
    if connectivity == 8:
        return int(cv2.CV_32S)
    # 4-connectivity: every component has a first cell in raster order, one with neither its upper
    # nor its left neighbour in the mask.
    starts = cells.copy()
    starts[1:] &= ~cells[:-1]
    starts[:, 1:] &= ~cells[:, :-1]
    return int(cv2.CV_16U) if int(np.count_nonzero(starts)) < limit else int(cv2.CV_32S)


def components(
    mask: npt.NDArray[np.bool_] | npt.NDArray[np.uint8], connectivity: int = 8
) -> tuple[int, npt.NDArray[np.integer]]:
    """Count (background included) and labels of the 4- or 8-connected components of ``mask``."""
    import cv2

    count, labels = cv2.connectedComponents(
        mask.view(np.uint8), None, connectivity, label_type(mask, connectivity)
    )
    return int(count), np.asarray(labels)


#: Longest side of an image OpenCV's flood fill fills right: it keeps the coordinates of its
#: segments in 16 bits (``cv::FFillSegment``), so on a wider or taller image it leaves cells it
#: should reach unfilled (and reports a wrong bounding box). A side of exactly 65,536 cells is
#: already too long: a segment ending at the last column stores 65,536 as the column past it,
#: read as 0 (the rows beyond it were never filled). Checked with OpenCV 5.1.
FLOOD_FILL_MAX_SIDE = 65535


def fill_from_corner(image: npt.NDArray[np.uint8], connectivity: int) -> None:
    """Set to 0, in place, the cells of ``image`` (uint8 0 / 1, shape (rows, cols), 1 at (0, 0))
    that paths of 1-cells (4- or 8-connected) join to its cell (0, 0): OpenCV's flood fill from
    there, labelled instead on images with a side over :data:`FLOOD_FILL_MAX_SIDE` cells."""
    import cv2

    if max(image.shape) <= FLOOD_FILL_MAX_SIDE:
        cv2.floodFill(image, None, (0, 0), 0, flags=connectivity)
        return
    _, labels = components(image, connectivity)
    image[labels == labels[0, 0]] = 0


def component_areas(labels: npt.NDArray[np.integer], count: int) -> npt.NDArray[np.float64]:
    """Cells per label (``count`` labels, the background's included), shape ``(count,)``.

    With 16-bit labels OpenCV's histogram (exact: one bin per label, counts below 2**24 cells); it
    and the plain labelling cost a third of the labelling with statistics.
    """
    import cv2

    if labels.dtype == np.uint16 and count > 0:
        hist = cv2.calcHist([labels], [0], None, [count], [0, count])
        return np.asarray(hist, dtype=np.float64).reshape(-1)
    return np.bincount(labels.reshape(-1), minlength=count).astype(np.float64)


def label_boxes(
    labels: npt.NDArray[np.integer], cells: npt.NDArray[np.intp], count: int
) -> npt.NDArray[np.int64]:
    """Bounding boxes ``x, y, width, height`` (OpenCV's order; shape ``(count, 4)``) of the labels
    at the flat indices ``cells`` (a label with no cell there gets an empty box).

    OpenCV's labelling with statistics costs 3-5x the plain labelling on the cleaning's and the
    break detector's images (it visits every pixel again); the labelled cells are a tenth of them.
    The cells are sorted by label (stable: a radix sort for 16-bit labels) and reduced label by
    label, the rows from the flat indices' extremes: about a tenth cheaper than four of numpy's
    ``ufunc.at`` on the large calls (10,000 cells; the small ones cost the same).
    """
    boxes = np.zeros((count, 4), dtype=np.int64)
    owner = labels.reshape(-1)[cells]
    if owner.size == 0:
        return boxes
    order = np.argsort(owner, kind="stable")
    owned = owner[order]
    flat = cells[order]
    cols = flat % labels.shape[1]
    starts = np.flatnonzero(owned[1:] != owned[:-1])
    starts += 1
    starts = np.concatenate(([0], starts))
    ids = owned[starts]
    # A row is the flat index divided by the width, which keeps the order: the rows' extremes
    # are those of the flat indices, divided (no rows worked out cell by cell).
    low_r = np.minimum.reduceat(flat, starts) // labels.shape[1]
    low_c = np.minimum.reduceat(cols, starts)
    boxes[ids, 0] = low_c
    boxes[ids, 1] = low_r
    boxes[ids, 2] = np.maximum.reduceat(cols, starts) + 1 - low_c
    boxes[ids, 3] = np.maximum.reduceat(flat, starts) // labels.shape[1] + 1 - low_r
    return boxes
