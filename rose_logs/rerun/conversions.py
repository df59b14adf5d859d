"""Pure numpy conversions from a snapshot and its ROSE result to what the viewer draws.

No Rerun here, so everything is tested directly. Conventions: ROS grids store row 0 at the map origin
(the bottom row on screen) while image buffers store the top row first; every image made here is in
image row order (north up) and every 2D position is in pixels of such an image, ``u`` right and
``v`` down, a pixel ``(i, j)`` covering ``[j, j + 1] x [i, i + 1]``. Cells ``(x, y)`` of the grid
frame (x along columns, y along rows) become pixels ``(x, rows - y)``.

The per-cell images cover a *window* of the grid, ``(x_min, y_min, x_max, y_max)`` in cells
(exclusive max): :func:`image_window` gives the known cells' box, since a SLAM grid is mostly
unknown space that would cost as much to send as its map. Cell ``(x, y)`` is then pixel
``(x - x_min, y_max - y)`` of the window's image.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from dataclasses import field as dataclasses_field

import numpy as np
import numpy.typing as npt

from rose.directions import local_maxima, map_frame_deg, peak_prominences
from rose.grid import blocks_max, true_bounds
from rose.result import RoseResult
from rose_logs.rerun.amplitude_layout import (
    LABEL_BOTTOM_PX,
    LABEL_GAP_PX,
    LABEL_TOP_PX,
    PEAK_LABEL_CLEARANCE_PX,
    PEAK_LABEL_PX,
    AmplitudeFrame,
    label_width_px,
)
from rose_logs.rerun.style import (
    AMPLITUDE_PLOT_HEIGHT,
    CLASS_CLUTTER,
    CLASS_COMPLETED,
    CLASS_FREE,
    CLASS_OCCUPIED,
    CLASS_RESCUED,
    CLASS_STRUCTURE,
    CLASS_UNKNOWN,
    DISPLAY_LEVELS,
    DISPLAY_MAX_PX,
    SCORE_DISPLAY_MIN,
    SPECTRUM_DISPLAY_PX,
)

# Viridis (matplotlib's, public domain) at 9 evenly spaced points: perceptually uniform, readable in grey.
_VIRIDIS = np.array(
    [
        (68, 1, 84),
        (71, 44, 122),
        (59, 81, 139),
        (44, 113, 142),
        (33, 145, 140),
        (39, 173, 129),
        (92, 200, 99),
        (170, 220, 50),
        (253, 231, 37),
    ],
    dtype=np.float64,
)

__all__ = [
    "DIRECTION_LABEL_CLEARANCE_PX",
    "DIRECTION_LABEL_EDGE_PX",
    "DIRECTION_LABEL_HEIGHT_PX",
    "DIRECTION_LABEL_WIDTH_PX",
    "SCORE_BAR_HEIGHT_PX",
    "SCORE_BAR_LABELS_GAP_PX",
    "SCORE_BAR_MIN_PX",
    "SCORE_BAR_ROOM_PX",
    "SCORE_BAR_TOP_PX",
    "AmplitudePlot",
    "OccupiedCells",
    "PeakLabelBoxes",
    "ScreenEnds",
    "SpectrumPooling",
    "amplitude_plot",
    "colour_levels",
    "direction_label_positions",
    "direction_segments_cells",
    "display_factor",
    "display_spectrum",
    "image_window",
    "known_bounds_cells",
    "masked_score_image",
    "occupied_cells",
    "peak_label_boxes",
    "pool_classes",
    "pool_scores",
    "pooled_score_image",
    "pooled_window",
    "quantise_unit",
    "score_bar_width",
    "score_classes",
    "score_levels",
    "score_to_unit",
    "screen_ends",
    "segmentation_image",
    "spectrum_pooling",
    "spectrum_strip_segments",
    "spread_labels",
    "view_units_per_px",
]


#: ``(x_min, y_min, x_max, y_max)`` in grid cells, exclusive max: the part of a grid an image covers.
Window = tuple[int, int, int, int]


@dataclass(frozen=True)
class OccupiedCells:
    """The occupied cells of a result, found once per snapshot and shared by the conversions.

    Attributes
    ----------
    grid_index : ndarray of intp, shape (N,)
        Flat indices in grid (ROS) row order.
    image_index : ndarray of intp, shape (N,)
        Flat indices in the image (north-up) row order of ``window``.
    bounds : tuple of int or None
        ``(x_min, y_min, x_max, y_max)`` in cells (exclusive max) around the occupied cells, None
        when there are none: the walls bound what was mapped.
    window : Window
        The part of the grid the images cover (the whole grid unless given).
    row, col : ndarray of intp, shape (N,)
        Grid row and column of each cell (``divmod(grid_index, cols)``), kept for the images'
        pooling (an integer division of every index less).
    """

    grid_index: npt.NDArray[np.intp]
    image_index: npt.NDArray[np.intp]
    bounds: tuple[int, int, int, int] | None
    window: Window
    row: npt.NDArray[np.intp]
    col: npt.NDArray[np.intp]


def image_window(grid: npt.NDArray[np.int8]) -> Window:
    """The window of ``grid`` its images cover: the known cells' box, the whole grid when no cell
    is known (an image needs a pixel)."""
    rows, cols = grid.shape
    return known_bounds_cells(grid) or (0, 0, cols, rows)


def occupied_cells(result: RoseResult, window: Window | None = None) -> OccupiedCells:
    """:class:`OccupiedCells` of ``result`` (the occupied mask's rows of ``window`` searched, the
    rest only counted), indexed for images of ``window`` (default: the whole grid), which must
    hold every occupied cell."""
    rows, cols = result.occupied.shape
    x0, y0, x1, y1 = window = window or (0, 0, cols, rows)
    # The window's rows alone (a contiguous band, a quarter to a third of a SLAM map's grid); the
    # other rows are only checked for an occupied cell (fast: no indices).
    low, high = max(y0, 0), max(y1, y0, 0)
    grid_index = np.flatnonzero(result.occupied[low:high])
    # divmod's values (the indices are >= 0), by floor division by a scalar: half its time.
    row = grid_index // cols
    col = grid_index - row * cols
    row += low
    grid_index += low * cols
    bounds = None
    outside = bool(result.occupied[:low].any() or result.occupied[high:].any())
    if grid_index.size or outside:
        if outside:  # found by the whole mask, for the message
            row, col = np.divmod(np.flatnonzero(result.occupied), cols)
        bounds = (int(col.min()), int(row[0]), int(col.max()) + 1, int(row[-1]) + 1)
        if outside or bounds[0] < x0 or bounds[2] > x1:
            msg = f"window {window} does not hold the occupied cells' box {bounds}"
            raise ValueError(msg)
    image_index = (y1 - 1 - row) * (x1 - x0) + (col - x0)
    return OccupiedCells(grid_index, image_index, bounds, window, row, col)


def segmentation_image(
    grid: npt.NDArray[np.int8],
    result: RoseResult,
    occupied: OccupiedCells | None = None,
    *,
    rescued: npt.NDArray[np.bool_] | None = None,
    removed: npt.NDArray[np.bool_] | None = None,
    completed: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.uint8]:
    """Class id of every cell of the window of ``occupied`` (the whole grid without it), image
    row order (north up).

    Parameters
    ----------
    grid : ndarray of int8, shape (rows, cols)
        The analysed grid (ROS convention, -1 unknown).
    result : RoseResult
        ROSE's result for ``grid``.
    occupied : OccupiedCells, optional
        ``occupied_cells(result)``, when the caller has it already.
    rescued : ndarray of bool, shape (rows, cols), optional
        Grid order: clutter cells the cleaning kept as walls (:attr:`rose.cleaning.CleanResult.rescued`),
        shown as ``CLASS_RESCUED``. Read on the occupied cells only.
    removed : ndarray of bool, shape (rows, cols), optional
        Grid order: occupied cells the cleaning removed (:attr:`rose.cleaning.CleanResult.removed`),
        shown as ``CLASS_CLUTTER``, also where the paper says structure (free-standing pieces).
        Read on the occupied cells only.
    completed : ndarray of bool, shape (rows, cols), optional
        Grid order: unknown cells the cleaning made walls, the wall line hidden behind removed
        clutter (:attr:`rose.cleaning.CleanResult.completed`), shown as ``CLASS_COMPLETED``.

    Returns
    -------
    ndarray of uint8, shape (window rows, window cols)
        ``CLASS_FREE`` for known cells that are not occupied, ``CLASS_UNKNOWN``, and for occupied cells
        ``CLASS_STRUCTURE`` / ``CLASS_CLUTTER`` (``CLASS_RESCUED``), or ``CLASS_OCCUPIED`` when ROSE
        found no structure.
    """
    cells = occupied or occupied_cells(result)
    grid_index, image_index = cells.grid_index, cells.image_index
    x0, y0, x1, y1 = cells.window
    # Comparing the row-reversed view writes the image rows directly: free 1, unknown 1 + 1.
    classes = (grid[y0:y1, x0:x1][::-1] < 0).view(np.uint8)
    classes += np.uint8(CLASS_FREE)
    values: npt.NDArray[np.uint8]
    if result.has_structure:
        # structure 4, clutter 5: the occupied cells are partitioned into the two.
        values = np.uint8(CLASS_CLUTTER) - result.structure.ravel()[grid_index].view(np.uint8)
    else:
        values = np.full(grid_index.shape, CLASS_OCCUPIED, dtype=np.uint8)
    # The cleaning's changes to occupied cells, read on those cells alone: a few per cent of the
    # window, where masking the whole window cost 0.1-0.2 ms per mask and snapshot.
    if rescued is not None:
        values[rescued.ravel()[grid_index]] = np.uint8(CLASS_RESCUED)
    if removed is not None:
        values[removed.ravel()[grid_index]] = np.uint8(CLASS_CLUTTER)
    classes.ravel()[image_index] = values
    if completed is not None:  # unknown cells: the window's mask (copyto: a third cheaper)
        np.copyto(classes, np.uint8(CLASS_COMPLETED), where=completed[y0:y1, x0:x1][::-1])
    return classes


# A pooled pixel shows the highest-ranked class of its block, unknown lowest: a wall, a clutter
# cell or a drawn wall line in a block of free space stays visible however far the map is shrunk.
# Walls outrank clutter (a wall's line stays whole where furniture touches it).
_CLASS_RANK = np.zeros(256, dtype=np.uint8)
_RANKED_CLASSES = (
    CLASS_UNKNOWN,
    CLASS_FREE,
    CLASS_OCCUPIED,
    CLASS_CLUTTER,
    CLASS_STRUCTURE,
    CLASS_RESCUED,
    CLASS_COMPLETED,
)
_CLASS_RANK[list(_RANKED_CLASSES)] = np.arange(len(_RANKED_CLASSES), dtype=np.uint8)
_RANKED = np.array(_RANKED_CLASSES, dtype=np.uint8)


def display_factor(window: Window, max_px: int = DISPLAY_MAX_PX) -> int:
    """Cells per side of a pixel of ``window``'s images in the 2D views: 1 while the window's longer
    side is at most ``max_px`` cells, else the smallest whole factor that brings it there."""
    if max_px < 1:
        msg = f"max_px must be >= 1, got {max_px}"
        raise ValueError(msg)
    x0, y0, x1, y1 = window
    return max(1, math.ceil(max(x1 - x0, y1 - y0) / max_px))


def pooled_window(window: Window, factor: int) -> Window:
    """``window`` grown at its right (``x_max``) and top (``y_max``) to whole blocks of ``factor``
    cells: the cells a pooled image (:func:`pool_classes`) covers, its lower-left corner unmoved."""
    x0, y0, x1, y1 = window
    return (
        x0,
        y0,
        x0 + factor * math.ceil((x1 - x0) / factor),
        y0 + factor * math.ceil((y1 - y0) / factor),
    )


def _padded(image: npt.NDArray[np.uint8], factor: int, fill: int) -> npt.NDArray[np.uint8]:
    """``image`` (image row order) padded with ``fill`` to whole blocks of ``factor``: rows on top
    (the window's y_max side, :func:`pooled_window`), columns on the right."""
    rows, cols = image.shape
    top, right = -rows % factor, -cols % factor
    if not top and not right:
        return image
    return np.pad(image, ((top, 0), (0, right)), constant_values=fill)


def pool_classes(image: npt.NDArray[np.uint8], factor: int) -> npt.NDArray[np.uint8]:
    """A :func:`segmentation_image` shrunk ``factor`` times per side: each pixel the highest-ranked
    class of its block (drawn walls, clutter kept as walls, structure, clutter, occupied, free,
    unknown), the blocks those of
    :func:`pooled_window`. Returns ``image`` itself for ``factor`` 1."""
    if factor == 1:
        return image
    ranks = _CLASS_RANK[_padded(image, factor, CLASS_UNKNOWN)]
    return _RANKED[blocks_max(ranks, factor)]


def pool_scores(image: npt.NDArray[np.uint8], factor: int) -> npt.NDArray[np.uint8]:
    """A :func:`masked_score_image` shrunk ``factor`` times per side: each pixel the lowest score
    level of the occupied cells in its block (the clutter the view is for stays visible), 0
    (transparent) where it has none. Returns ``image`` itself for ``factor`` 1."""
    if factor == 1:
        return image
    # As uint8, -level is 256 - level for levels 1..255 and 0 for 0: the largest negated level
    # is the lowest level, and a block of 0s stays 0.
    negated = np.negative(_padded(image, factor, 0))
    return np.negative(blocks_max(negated, factor))


def score_to_unit(scores: npt.NDArray[np.floating]) -> npt.NDArray[np.float32]:
    """Cell scores mapped to the colour map's ``[0, 1]``: ``SCORE_DISPLAY_MIN`` -> 0, 1 -> 1 (clipped)."""
    unit = (np.asarray(scores, dtype=np.float32) - np.float32(SCORE_DISPLAY_MIN)) * np.float32(
        1.0 / (1.0 - SCORE_DISPLAY_MIN)
    )
    return np.clip(np.nan_to_num(unit, nan=0.0), 0.0, 1.0)


def quantise_unit(
    unit: npt.NDArray[np.float32], *, levels: int = DISPLAY_LEVELS
) -> npt.NDArray[np.uint8]:
    """Values in ``[0, 1]`` as ``levels`` uint8 values evenly spaced over ``1..255``.

    0 is never produced: depth images treat 0 as "no data", which is how masked cells are shown.
    """
    if not 2 <= levels <= 255:
        msg = f"levels must be in 2..255, got {levels}"
        raise ValueError(msg)
    return _quantised(np.clip(unit, 0.0, 1.0), levels)


def _quantised(unit: npt.NDArray[np.floating], levels: int) -> npt.NDArray[np.uint8]:
    """:func:`quantise_unit` of ``unit``, already in ``[0, 1]``, worked out in place (a scratch
    array of the caller's: four fewer temporaries)."""
    unit *= np.float32(levels - 1)
    np.rint(unit, out=unit)
    unit *= np.float32(254.0 / (levels - 1))
    np.rint(unit, out=unit)
    unit += 1
    return unit.astype(np.uint8)


def colour_levels(levels: int = DISPLAY_LEVELS) -> npt.NDArray[np.uint8]:
    """The score colour map (viridis) at ``levels`` evenly spaced values, RGBA, shape (levels, 4)."""
    positions = np.linspace(0.0, 1.0, len(_VIRIDIS))
    at = np.linspace(0.0, 1.0, levels)
    rgb = np.stack([np.interp(at, positions, _VIRIDIS[:, c]) for c in range(3)], axis=-1)
    return np.concatenate([np.rint(rgb), np.full((levels, 1), 255.0)], axis=-1).astype(np.uint8)


def score_levels(
    scores: npt.NDArray[np.floating], *, levels: int = DISPLAY_LEVELS
) -> npt.NDArray[np.intp]:
    """Index ``0 .. levels - 1`` of each score's colour (``SCORE_DISPLAY_MIN`` -> 0, 1 -> top)."""
    return np.rint(score_to_unit(scores) * np.float32(levels - 1)).astype(np.intp)


def _score_ids(scores: npt.NDArray[np.floating], levels: int) -> npt.NDArray[np.uint8]:
    """``1 + score_levels(scores, levels=levels)`` as uint8, from one float32 scratch array worked
    in place. ``fmax`` / ``fmin`` with 0 and 1 give what ``nan_to_num`` (NaN 0) and ``clip`` gave
    (+inf 1, -inf 0); a signed zero no longer matters once rounded to a level."""
    unit = np.subtract(scores, np.float32(SCORE_DISPLAY_MIN), dtype=np.float32)
    unit *= np.float32(1.0 / (1.0 - SCORE_DISPLAY_MIN))
    np.fmax(unit, np.float32(0.0), out=unit)
    np.fmin(unit, np.float32(1.0), out=unit)
    unit *= np.float32(levels - 1)
    np.rint(unit, out=unit)
    ids = unit.astype(np.uint8)  # levels - 1 <= 254: exact
    ids += np.uint8(1)
    return ids


def masked_score_image(
    result: RoseResult, occupied: OccupiedCells | None = None, *, levels: int = DISPLAY_LEVELS
) -> npt.NDArray[np.uint8]:
    """Occupied cells' score level as class ids ``1 .. levels``; every other cell 0 (transparent),
    over the window of ``occupied`` (the whole grid without it).

    Returns
    -------
    ndarray of uint8, shape (window rows, window cols)
        Image row order; ``1 + score_levels(score)`` on occupied cells (see :func:`score_classes`).
    """
    if not 2 <= levels <= 255:
        msg = f"levels must be in 2..255, got {levels}"
        raise ValueError(msg)
    cells = occupied or occupied_cells(result)
    x0, y0, x1, y1 = cells.window
    image = np.zeros((y1 - y0, x1 - x0), dtype=np.uint8)
    grid_index, image_index = cells.grid_index, cells.image_index
    image.ravel()[image_index] = _score_ids(result.cell_scores.ravel()[grid_index], levels)
    return image


def pooled_score_image(
    result: RoseResult,
    occupied: OccupiedCells | None = None,
    factor: int = 1,
    *,
    levels: int = DISPLAY_LEVELS,
) -> npt.NDArray[np.uint8]:
    """``pool_scores(masked_score_image(result, occupied, levels=levels), factor)``, from the
    occupied cells alone: each pooled pixel the lowest level of its block's occupied cells
    (``np.maximum.at`` of the negated levels, as :func:`pool_scores`), without the window's
    full-size image (a third less time on a 1000 x 1000 grid pooled 3 times)."""
    if factor == 1:
        return masked_score_image(result, occupied, levels=levels)
    if not 2 <= levels <= 255:
        msg = f"levels must be in 2..255, got {levels}"
        raise ValueError(msg)
    cells = occupied or occupied_cells(result)
    x0, y0, x1, y1 = cells.window
    rows, cols = y1 - y0, x1 - x0
    top = -rows % factor  # padding rows on top, as _padded
    pooled_rows, pooled_cols = (rows + top) // factor, -(-cols // factor)
    # The image row and column of each cell (as divmod(image_index, cols) gives them).
    row = (y1 - 1 + top) - cells.row
    row //= factor
    row *= pooled_cols
    col = cells.col - x0
    col //= factor
    row += col
    level = _score_ids(result.cell_scores.ravel()[cells.grid_index], levels)
    negated = np.zeros(pooled_rows * pooled_cols, dtype=np.uint8)
    np.maximum.at(negated, row, np.negative(level, out=level))
    return np.negative(negated).reshape(pooled_rows, pooled_cols)


def score_classes(levels: int = DISPLAY_LEVELS) -> list[tuple[int, str, tuple[int, int, int, int]]]:
    """``(class id, label, RGBA)`` of the score levels: id 0 transparent, ids ``1 .. levels`` viridis.

    The label is the range of scores the level stands for, shown when hovering a cell.
    """
    colours = colour_levels(levels)
    step = (1.0 - SCORE_DISPLAY_MIN) / (levels - 1)
    classes = [(0, "not occupied", (0, 0, 0, 0))]
    for level in range(levels):
        centre = SCORE_DISPLAY_MIN + level * step
        low, high = max(centre - step / 2, SCORE_DISPLAY_MIN), min(centre + step / 2, 1.0)
        label = f"score {low:.2f} .. {high:.2f}"
        if level == 0:
            label = f"score <= {high:.2f}"
        elif level == levels - 1:
            label = f"score >= {low:.2f}"
        r, g, b, a = (int(c) for c in colours[level])
        classes.append((level + 1, label, (r, g, b, a)))
    return classes


def _block_rows(
    blocks: npt.NDArray[np.intp], factor: int, first: int, last: int
) -> list[npt.NDArray[np.intp]]:
    """Rows of blocks ``blocks`` of ``factor`` consecutive rows counted from row ``first``, the
    ``j``-th row of every block in the ``j``-th array; a block cut short by row ``last``
    (inclusive) repeats it (a maximum over the block is the same)."""
    starts = first + blocks * factor
    return [np.minimum(starts + j, last) for j in range(factor)]


def _max_of(
    array: npt.NDArray[np.float32], rows: list[npt.NDArray[np.intp]], axis: int = 0
) -> npt.NDArray[np.float32]:
    """Element-wise maximum of ``array``'s rows (``axis`` 0) or columns (1) ``rows[j]`` over j."""
    out = array[:, rows[0]] if axis else array[rows[0]]
    for more in rows[1:]:
        np.maximum(out, array[:, more] if axis else array[more], out=out)
    return out


def _median(values: npt.NDArray[np.float32]) -> float:
    """``np.median(values)`` of finite ``values`` from one partition (the mean of the two middle
    values of an even count, in their dtype, as numpy's): np.median's checks and copies cost
    twice the partition on a display spectrum's 3,700 values."""
    flat = values.ravel()
    mid = flat.size // 2
    if flat.size % 2:
        return float(np.partition(flat, mid)[mid])
    middle = np.partition(flat, (mid - 1, mid))[mid - 1 : mid + 1]
    return float(np.mean(middle))


@dataclass(frozen=True)
class SpectrumPooling:
    """The spectrum rows and columns :func:`display_spectrum` pools into each display pixel, for
    one spectrum shape and display size (:func:`spectrum_pooling`).

    Attributes
    ----------
    padded_shape : tuple of int
        ``(rows_padded, cols_padded)``.
    half_cols : int
        Columns of the half spectrum.
    size : int
        The display size.
    rows : list of ndarray of intp, shape (size + 1,)
        The ``j``-th row of each display row's block, one array per ``j``.
    cols : list of ndarray of intp, shape (size // 2 + 1,)
        The ``j``-th column of each right-half display column's block, one array per ``j``.
    """

    padded_shape: tuple[int, int]
    half_cols: int
    size: int
    rows: list[npt.NDArray[np.intp]]
    cols: list[npt.NDArray[np.intp]]


def spectrum_pooling(
    padded_shape: tuple[int, int], half_cols: int, *, size: int = SPECTRUM_DISPLAY_PX
) -> SpectrumPooling:
    """:class:`SpectrumPooling` of a ``padded_shape`` spectrum's half (``half_cols`` columns) shown
    ``size + 1`` pixels square (``size`` even)."""
    rows_p, cols_p = padded_shape
    half, half_rows = size // 2, rows_p // 2
    bins = np.arange(half + 1)
    # Max-pool by the integer number of spectrum cells per display pixel (thin spectral lines
    # survive), then take the pooled cell of each display pixel's frequency (nearest): display
    # pixel b from the centre is b / size cycles per cell on either axis. Only the blocks that are
    # taken are pooled, straight from the spectrum (rows then columns).
    f_rows = max(1, rows_p // size)
    # Rows: v = r / rows_p for r <= rows_p / 2 (v >= 0), else (r - rows_p) / rows_p (v < 0): the
    # non-negative half pooled from row 0 to half_rows, the negative from half_rows to the end.
    m_pos = np.minimum(np.rint(bins * rows_p / size).astype(np.intp), half_rows)
    m_neg = np.clip(np.rint(bins[1:] * rows_p / size).astype(np.intp), 1, rows_p - half_rows)
    # Display row i holds v = (half - i) / size: +v up.
    positive = _block_rows((m_pos // f_rows)[::-1], f_rows, 0, half_rows)
    negative = _block_rows((rows_p - m_neg - half_rows) // f_rows, f_rows, half_rows, rows_p - 1)
    rows = [np.concatenate(pair) for pair in zip(positive, negative, strict=True)]
    # Columns: u = k / cols_p -> display columns half .. size.
    f_cols = max(1, cols_p // size)
    k = np.minimum(np.rint(bins * cols_p / size).astype(np.intp), half_cols - 1)
    cols = _block_rows(k // f_cols, f_cols, 0, half_cols - 1)
    return SpectrumPooling((int(rows_p), int(cols_p)), int(half_cols), size, rows, cols)


def display_spectrum(
    spectrum_half: npt.NDArray[np.float32],
    padded_shape: tuple[int, int],
    *,
    size: int = SPECTRUM_DISPLAY_PX,
    levels: int = DISPLAY_LEVELS,
    pooling: SpectrumPooling | None = None,
) -> npt.NDArray[np.uint8]:
    """Log-amplitude spectrum at display resolution, square, DC at the centre pixel.

    Both frequency axes are resampled to ``size + 1`` pixels spanning ``[-1/2, 1/2]`` cycles per cell
    (block maximum, so thin spectral lines survive), which keeps angles physical on non-square maps:
    a spectral line of walls at angle ``theta`` is drawn at ``theta + pi/2``. The vertical frequency
    grows upwards, like the north-up map images. Built from the half-plane (no full spectrum).

    Parameters
    ----------
    spectrum_half : ndarray of float32, shape (rows_padded, cols_padded // 2 + 1)
        :attr:`RoseResult.spectrum_half` (unshifted real-FFT amplitude).
    padded_shape : tuple of int
        ``(rows_padded, cols_padded)``.
    size : int
        Even display size; the image is ``size + 1`` pixels square.
    levels : int
        Grey levels, see :func:`quantise_unit`. The log amplitude is stretched from its median (the
        noise floor, shown darkest) to its maximum.
    pooling : SpectrumPooling, optional
        ``spectrum_pooling(padded_shape, spectrum_half.shape[1], size=size)``, when the caller
        keeps it (a session's spectra keep their shape).

    Returns
    -------
    ndarray of uint8, shape (size + 1, size + 1)
        Values in ``1..255`` (0 is never used).
    """
    if size < 2 or size % 2:
        msg = f"size must be even and >= 2, got {size}"
        raise ValueError(msg)
    if not 2 <= levels <= 255:
        msg = f"levels must be in 2..255, got {levels}"
        raise ValueError(msg)
    half_cols = spectrum_half.shape[1]
    if pooling is None:
        pooling = spectrum_pooling(padded_shape, half_cols, size=size)
    want = (tuple(padded_shape), half_cols, size)
    made_for = (pooling.padded_shape, pooling.half_cols, pooling.size)
    if made_for != want:
        msg = f"pooling is for (padded shape, columns, size) {made_for}, got {want}"
        raise ValueError(msg)
    half = size // 2
    rows_binned = _max_of(spectrum_half, pooling.rows)  # (size + 1, cols_p // 2 + 1)
    # Display columns half .. size (a copy, worked in place); the left half (u < 0) is their point
    # mirror about the centre pixel, so the log, the stretch and the quantisation run on this half
    # alone.
    right = _max_of(rows_binned, pooling.cols, axis=1)  # (size + 1, half + 1)
    # log(1 + a): numpy's float32 log is vectorised, its log1p is not (6x slower); amplitudes are
    # >= 0 and the result is quantised to 8 bits, so log1p's extra precision near 0 is invisible.
    right += np.float32(1.0)
    np.log(right, out=right)
    floor = _median(right[::3, ::3])  # the noise floor; a subsample is plenty
    top = float(right.max())  # the mirrored half holds the same values
    image = np.empty((size + 1, size + 1), dtype=np.uint8)
    if not math.isfinite(top) or top <= floor:
        image.fill(1)
        return image
    right -= np.float32(floor)
    right *= np.float32(1.0 / (top - floor))
    np.clip(right, 0.0, 1.0, out=right)  # quantise_unit's, in place
    image[:, half:] = _quantised(right, levels)
    image[:, :half] = image[::-1, :half:-1]
    return image


def direction_segments_cells(
    directions_rad: npt.NDArray[np.float64],
    shape: tuple[int, int],
    *,
    bounds: tuple[float, float, float, float] | None = None,
) -> npt.NDArray[np.float64]:
    """Segments through the centre of a box along each direction, in continuous cell coordinates.

    Parameters
    ----------
    directions_rad : ndarray of float64, shape (K,)
        Line orientations in radians, counter-clockwise from the grid's +x (columns) axis.
    shape : tuple of int
        Grid ``(rows, cols)``; the box when ``bounds`` is None.
    bounds : tuple of float, optional
        ``(x_min, y_min, x_max, y_max)`` in cells, e.g. the known part of the map
        (:class:`OccupiedCells`): the lines cross what was mapped, not the empty grid around it.

    Returns
    -------
    ndarray of float64, shape (K, 2, 2)
        ``[k, end, (x, y)]`` in cells of the grid frame; both ends on the box's border, the second
        one in the direction ``(cos, sin)`` of the angle.
    """
    rows, cols = shape
    x0, y0, x1, y1 = (0.0, 0.0, float(cols), float(rows)) if bounds is None else bounds
    centre = np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0])
    half_box = np.array([(x1 - x0) / 2.0, (y1 - y0) / 2.0])
    theta = np.asarray(directions_rad, dtype=np.float64)
    unit = np.empty((*theta.shape, 2))  # (K, 2)
    unit[..., 0], unit[..., 1] = np.cos(theta), np.sin(theta)
    with np.errstate(divide="ignore"):
        reach = half_box / np.abs(unit)  # inf along an axis the line is parallel to
    half_length = reach.min(axis=1, keepdims=True)
    return _through(centre, half_length * unit)


@dataclass(frozen=True)
class ScreenEnds:
    """The direction lines' ends on screen, what :func:`direction_label_positions` needs of them
    whatever the view (:func:`screen_ends`).

    Attributes
    ----------
    turn : ndarray of float64, shape (2, 2)
        Grid frame -> screen (y up): the rotation by the origin's yaw.
    ends : ndarray of float64, shape (K, 2, 2)
        The segments' ends on screen.
    end : ndarray of float64, shape (K, 2)
        Each line's end lower on screen (the first if level).
    level : ndarray of float64, shape (K,)
        cos(slope) on screen: 1 for a level line, 0 for an upright one.
    out : ndarray of float64, shape (K,)
        -1, 0 or 1: the side of the lower end from the line's middle, along x.
    """

    turn: npt.NDArray[np.float64]
    ends: npt.NDArray[np.float64]
    end: npt.NDArray[np.float64]
    level: npt.NDArray[np.float64]
    out: npt.NDArray[np.float64]


def screen_ends(segments: npt.NDArray[np.float64], *, yaw_rad: float = 0.0) -> ScreenEnds:
    """:class:`ScreenEnds` of ``segments`` (K, 2, 2), grid frame, turned by ``yaw_rad``."""
    cos_yaw, sin_yaw = math.cos(yaw_rad), math.sin(yaw_rad)
    turn = np.array([[cos_yaw, -sin_yaw], [sin_yaw, cos_yaw]])  # grid frame -> screen (y up)
    ends = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2) @ turn.T  # (K, 2, 2)
    lower = np.argmin(ends[:, :, 1], axis=1)  # the end lower on screen (the first if level)
    end = ends[np.arange(len(ends)), lower]  # (K, 2)
    run = ends[:, 1] - ends[:, 0]
    # np.linalg.norm's and mean's own arithmetic, without their Python wrappers.
    length = np.sqrt(np.add.reduce(run * run, axis=1))
    level = np.divide(np.abs(run[:, 0]), length, out=np.ones_like(length), where=length > 0)
    # Out from the map by as much of half a label as the line is level: a flat line's label
    # beside its end, off the map (on a map narrower than a label, centred under the end, it
    # reached over the other lines), a steep one's under its end.
    out = np.sign(end[:, 0] - np.add.reduce(ends[:, :, 0], axis=1) / 2)
    return ScreenEnds(turn, ends, end, level, out)


def direction_label_positions(
    segments: npt.NDArray[np.float64],
    *,
    yaw_rad: float = 0.0,
    x_range: tuple[float, float] | None = None,
    y_range: tuple[float, float] | None = None,
    label_width: float = 0.0,
    label_height: float = 0.0,
    clearance: float = 0.0,
    screen: ScreenEnds | None = None,
) -> npt.NDArray[np.float64]:
    """Where to put each direction's label; Rerun draws a label under its point, centred, a fixed
    number of screen pixels wide (labels at the centre would all overlap: every line passes there).

    Each label hangs under its line's lower end on screen (the views show the map frame north up:
    the grid frame turned by ``yaw_rad``), where no part of the line is lower, so the line stays
    above the label whatever its direction. The point is ``clearance`` times the cosine of the
    line's slope below that end (a flat line ran along the label's top edge, and at 0.8 of the way
    to an end a line a few degrees from flat ran down through its label; a steep one leaves
    nothing above the label but its end) and, horizontally, out from the end by half the label's
    width ``label_width`` times that cosine (a flat line's label beside its end, off the map: on a
    map narrower than a label, a label centred under the end reached over the other lines) unless
    the label would reach out of ``x_range`` (what the view shows, on screen): then just inside
    it (a flat line ends at the side of a wide map, and half its label hung out of the view).

    With ``label_height``, up to :data:`SPREAD_MAX_LABELS` labels are then kept off each other
    and off the lines (:func:`spread_labels`): two nearly parallel steep lines (80 and 100
    degrees) hung their labels one over the other under the map. Sizes and ranges are in the units of ``segments``
    (cells: a view's pixels times its cells per pixel, :func:`view_units_per_px`).

    Parameters
    ----------
    segments : ndarray of float64, shape (K, 2, 2)
        ``[k, end, (x, y)]``, grid frame, y up (:func:`direction_segments_cells`).
    x_range, y_range : tuple of float, optional
        ``(left, right)`` and ``(bottom, top)`` of what the view shows, on screen: the grid frame
        turned by ``yaw_rad``, y up. None: anywhere.
    screen : ScreenEnds, optional
        ``screen_ends(segments, yaw_rad=yaw_rad)``, when the caller has it (the views of one
        snapshot share it).

    Returns
    -------
    ndarray of float64, shape (K, 2)
        In the coordinates of ``segments``.
    """
    geometry = screen or screen_ends(segments, yaw_rad=yaw_rad)
    ends, end, level, out = geometry.ends, geometry.end, geometry.level, geometry.out
    x = end[:, 0] + out * level * label_width / 2
    if x_range is not None:
        left, right = x_range[0] + label_width / 2, x_range[1] - label_width / 2
        if left > right:
            x = np.full_like(x, (left + right) / 2)
        else:  # np.clip's arithmetic without its wrapper (two labels: the wrapper cost more)
            np.minimum(np.maximum(x, left, out=x), right, out=x)
    anchors = np.empty((len(x), 2))
    anchors[:, 0], anchors[:, 1] = x, end[:, 1] - clearance * level
    if label_height > 0 and len(anchors) <= SPREAD_MAX_LABELS:
        view = None
        if x_range is not None and y_range is not None:
            view = (x_range[0], y_range[0], x_range[1], y_range[1])
        anchors = spread_labels(anchors, ends, (label_width, label_height), view=view)
    return anchors @ geometry.turn  # back to the grid frame (turn is orthonormal)


#: Without a view, :func:`spread_labels` tries places as far as three labels' widths and heights
#: either way.
_SPREAD_REACH = 3
_SPREAD_BATCH = 256
#: Steps either way, across and up, of the search over the whole view (coarser than the near one
#: on a large view): a label with no free place tried every place of a fine grid over the view,
#: 9.5 ms a snapshot for 8 directions, 22 ms for 14.
_SPREAD_VIEW_STEPS = (40, 24)
#: More directions than this (a noisy map can have 14) keep their own places: the search for
#: free places costs a few milliseconds per label that finds none, and so many labels do not all
#: fit in a view anyway.
SPREAD_MAX_LABELS = 4


def spread_labels(
    anchors: npt.NDArray[np.float64],
    lines: npt.NDArray[np.float64],
    size: tuple[float, float],
    *,
    view: tuple[float, float, float, float] | None = None,
) -> npt.NDArray[np.float64]:
    """Labels kept apart. First, labels under every line (a steep line's, under the map) that
    would overlap stand side by side, in the order of their own places across, centred where
    they were (:func:`_side_by_side`): three steep lines at 80, 90 and 100 degrees keep their
    labels in a row under the map in their ends' order. Then each label in turn goes to the place
    nearest its own (its own first) where its box overlaps no label placed before it, no line runs
    through it and it stays in ``view``; a label with no such place keeps its own, moved into
    ``view`` (centred in it if larger).

    A label at ``(x, y)`` covers ``x - width / 2 .. x + width / 2`` across and ``y - height .. y``
    (Rerun hangs it under its point). Places tried: steps of a quarter of its width across and of
    half its height up and down, three widths either way; then over the whole view (a map's lines
    can fill it but under the map), in steps of at least a 40th of its width and a 24th of its
    height. On screen, y up; any units.

    Parameters
    ----------
    anchors : ndarray of float64, shape (K, 2)
        The labels' own places.
    lines : ndarray of float64, shape (L, 2, 2)
        Segments no label may cover.
    size : tuple of float
        ``(width, height)`` of a label.
    view : tuple of float, optional
        ``(left, bottom, right, top)`` the labels must stay in.

    Returns
    -------
    ndarray of float64, shape (K, 2)
    """
    width, height = size
    result = np.array(anchors, dtype=np.float64).reshape(-1, 2)
    if len(result) == 0 or width <= 0 or height <= 0:
        return result
    step_x, step_y = width / 4, height / 2
    near = 4 * _SPREAD_REACH  # steps: three widths across, six half heights up and down
    reaches = [(near, 2 * _SPREAD_REACH)]
    far_step = (step_x, step_y)
    if view is not None:
        # Then as far as the far side of the view (a map's lines can fill it but under the
        # map), in steps no finer than the near ones and at most _SPREAD_VIEW_STEPS either way.
        far_step = (
            max(step_x, (view[2] - view[0]) / _SPREAD_VIEW_STEPS[0]),
            max(step_y, (view[3] - view[1]) / _SPREAD_VIEW_STEPS[1]),
        )
        reaches.append(
            (
                math.ceil((view[2] - view[0]) / far_step[0]),
                math.ceil((view[3] - view[1]) / far_step[1]),
            )
        )
    segments = np.asarray(lines, dtype=np.float64).reshape(-1, 2, 2)
    tol = 1e-9 * max(width, height, 1.0)
    placed: list[list[float]] = []  # the boxes of the labels placed, as boxes_at's rows

    def boxes_at(points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Label boxes ``(C, 4)``: left, bottom, right, top, of labels at ``points`` (C, 2)."""
        x, y = points[:, 0], points[:, 1]
        return np.stack([x - width / 2, y - height, x + width / 2, y], axis=-1)

    def box_at(point: npt.NDArray[np.float64]) -> list[float]:
        """The label box at ``point`` (2,), as a row of :func:`boxes_at`, in plain floats."""
        x, y = float(point[0]), float(point[1])
        return [x - width / 2, y - height, x + width / 2, y]

    def first_free(boxes: npt.NDArray[np.float64]) -> int | None:
        """The first of ``boxes`` in the view, off the labels placed and off every line."""
        free = np.ones(len(boxes), dtype=bool)
        if view is not None:
            free &= (boxes[:, 0] >= view[0] - tol) & (boxes[:, 2] <= view[2] + tol)
            free &= (boxes[:, 1] >= view[1] - tol) & (boxes[:, 3] <= view[3] + tol)
        for box in placed:
            free &= ~_overlapping(boxes, box, tol)
        free[free] = ~_crossed(boxes[free], segments, tol)
        return int(np.argmax(free)) if free.any() else None

    # This call's offsets by reach and step.
    steps: dict[tuple[tuple[int, int], tuple[float, float]], npt.NDArray[np.float64]] = {}

    def nearest_free(point: npt.NDArray[np.float64]) -> npt.NDArray[np.float64] | None:
        """The free place nearest ``point`` (2,), trying a few hundred at a time: a whole view
        holds thousands."""
        for reach, step in zip(reaches, ((step_x, step_y), far_step), strict=False):
            if (reach, step) not in steps:
                steps[reach, step] = _nearest_first(reach, step)
            offsets = steps[reach, step]
            for start in range(0, len(offsets), _SPREAD_BATCH):
                candidates = point + offsets[start : start + _SPREAD_BATCH]
                best = first_free(boxes_at(candidates))
                if best is not None:
                    return candidates[best]
        return None

    result = _side_by_side(result, segments, width, view)
    for k in range(len(result)):
        # Its own place first: nearly always free, and then no other place is even made (one
        # box: in plain floats, numpy's calls cost more than the arithmetic).
        if not _free_box(box_at(result[k]), placed, segments, view, tol):
            moved = nearest_free(result[k])
            # No free place: at least in view (a row of labels side by side wider than the view
            # left its outer ones out of it, cut off or not drawn at all).
            result[k] = _into_view(result[k], size, view) if moved is None else moved
        placed.append(box_at(result[k]))
    return result


def _into_view(
    point: npt.NDArray[np.float64],
    size: tuple[float, float],
    view: tuple[float, float, float, float] | None,
) -> npt.NDArray[np.float64]:
    """A label's point ``(x, y)`` moved the least that its box (``size``: width, height, hung
    under the point) is in ``view`` (left, bottom, right, top); centred in it along an axis the
    label is larger than it along. None: ``point`` as it is."""
    if view is None:
        return point
    width, height = size
    moved = point.copy()
    for axis, low, high in (
        (0, view[0] + width / 2, view[2] - width / 2),
        (1, view[1] + height, view[3]),
    ):
        moved[axis] = (low + high) / 2 if low > high else min(max(moved[axis], low), high)
    return moved


def _side_by_side(
    anchors: npt.NDArray[np.float64],
    lines: npt.NDArray[np.float64],
    width: float,
    view: tuple[float, float, float, float] | None,
) -> npt.NDArray[np.float64]:
    """``anchors`` (K, 2) with those under every one of ``lines`` (L, 2, 2) moved across so that
    no two of them overlap: overlapping neighbours form a group, laid out ``width`` apart in their
    order across, centred on their own places' mean, and kept in ``view`` across (groups that then
    overlap merge)."""
    result = anchors.copy()
    if len(lines) == 0:
        return result
    floor = float(lines[..., 1].min())
    row = np.flatnonzero(result[:, 1] <= floor + 1e-9 * max(abs(floor), 1.0))
    if len(row) < 2:
        return result
    row = row[np.argsort(result[row, 0], kind="stable")]
    own = result[row, 0].copy()
    groups: list[list[int]] = []  # positions in ``row``

    def lay_out(group: list[int]) -> npt.NDArray[np.float64]:
        half = (len(group) - 1) / 2 * width  # from the group's centre to its outer labels'
        centre = float(own[group].mean())
        if view is not None:  # the whole group in view, if it fits
            low, high = view[0] + width / 2 + half, view[2] - width / 2 - half
            centre = min(max(centre, low), high) if low <= high else (low + high) / 2
        return np.linspace(centre - half, centre + half, len(group), dtype=np.float64)

    for i in range(len(row)):
        groups.append([i])
        # Merge back while the last group reaches into the one before it.
        while len(groups) > 1:
            before, last = lay_out(groups[-2]), lay_out(groups[-1])
            if last[0] - before[-1] >= width * (1 - 1e-9):
                break
            groups[-2:] = [groups[-2] + groups[-1]]
    for group in groups:
        result[row[group], 0] = lay_out(group)
    return result


def _nearest_first(reach: tuple[int, int], step: tuple[float, float]) -> npt.NDArray[np.float64]:
    """Offsets ``(C, 2)`` up to ``reach`` steps of ``step`` either way across and up, nearest
    first ((0, 0) leads; a stable sort keeps the grid's order among equal distances)."""
    dx, dy = (
        v.ravel()
        for v in np.meshgrid(
            np.arange(-reach[0], reach[0] + 1) * step[0],
            np.arange(-reach[1], reach[1] + 1) * step[1],
        )
    )
    order = np.argsort(np.hypot(dx, dy), kind="stable")
    return np.stack([dx[order], dy[order]], axis=-1)


def _overlapping(
    boxes: npt.NDArray[np.float64], box: Sequence[float] | npt.NDArray[np.float64], tol: float
) -> npt.NDArray[np.bool_]:
    """Whether each of ``boxes`` (C, 4: left, bottom, right, top) shares some area with ``box``
    (boxes that only touch do not)."""
    return (
        (boxes[:, 0] < box[2] - tol)
        & (box[0] < boxes[:, 2] - tol)
        & (boxes[:, 1] < box[3] - tol)
        & (box[1] < boxes[:, 3] - tol)
    )


def _free_box(
    box: list[float],
    placed: list[list[float]],
    lines: npt.NDArray[np.float64],
    view: tuple[float, float, float, float] | None,
    tol: float,
) -> bool:
    """One label box (left, bottom, right, top) in ``view``, off the ``placed`` boxes and off every
    one of ``lines`` (L, 2, 2): :func:`_overlapping` and :func:`_crossed` for a single box."""
    left, bottom, right, top = box
    if view is not None and not (
        left >= view[0] - tol
        and right <= view[2] + tol
        and bottom >= view[1] - tol
        and top <= view[3] + tol
    ):
        return False
    for o_left, o_bottom, o_right, o_top in placed:
        if (
            left < o_right - tol
            and o_left < right - tol
            and bottom < o_top - tol
            and o_bottom < top - tol
        ):
            return False
    low, high = (left + tol, bottom + tol), (right - tol, top - tol)
    for (x0, y0), (x1, y1) in lines.tolist():
        enter, leave = 0.0, 1.0
        for start, d, a_side, b_side in (
            (x0, x1 - x0, low[0], high[0]),
            (y0, y1 - y0, low[1], high[1]),
        ):
            a, b = a_side - start, b_side - start
            if abs(d) <= tol:  # parallel to this axis: through only strictly between its sides
                if not (a < 0 < b):
                    enter, leave = 1.0, 0.0
                    break
                continue
            t0, t1 = a / d, b / d
            enter, leave = max(enter, min(t0, t1)), min(leave, max(t0, t1))
        if leave - enter > 1e-9:
            return False
    return True


def _crossed(
    boxes: npt.NDArray[np.float64], lines: npt.NDArray[np.float64], tol: float
) -> npt.NDArray[np.bool_]:
    """Whether some of ``lines`` (L, 2, 2) runs through the inside of each of ``boxes`` (C, 4):
    each segment clipped to each box shrunk by ``tol`` (Liang-Barsky) keeps some length (a line
    ending on a box's edge, as a steep line at its label's top, does not)."""
    if len(lines) == 0:
        return np.zeros(len(boxes), dtype=bool)
    start = lines[np.newaxis, :, 0]  # (1, L, 2)
    run = lines[np.newaxis, :, 1] - lines[np.newaxis, :, 0]
    low = boxes[:, np.newaxis, :2] + tol  # (C, 1, 2)
    high = boxes[:, np.newaxis, 2:] - tol
    enter = np.zeros((len(boxes), len(lines)))
    leave = np.ones_like(enter)
    inside = np.ones_like(enter, dtype=bool)
    for axis in (0, 1):
        d = np.broadcast_to(run[..., axis], enter.shape)
        a = low[..., axis] - start[..., axis]  # (C, L): the box's sides from the start
        b = high[..., axis] - start[..., axis]
        along = np.abs(d) <= tol
        # Parallel to this axis: through the box only strictly between its two sides.
        inside &= ~along | ((a < 0) & (b > 0))
        safe = np.where(along, 1.0, d)
        t0, t1 = a / safe, b / safe
        enter = np.where(along, enter, np.maximum(enter, np.minimum(t0, t1)))
        leave = np.where(along, leave, np.minimum(leave, np.maximum(t0, t1)))
    return np.any(inside & (leave - enter > 1e-9), axis=1)


#: The direction labels' size and room in a map view, screen pixels: "walls 176.2°" is 81 wide
#: and its box 23 high from 1 pixel under its point (Rerun 0.41); the line (1.5 points) and the
#: label need about 8 pixels between them to stay apart; labels keep 6 pixels from a view's edges.
DIRECTION_LABEL_WIDTH_PX = 90.0
DIRECTION_LABEL_HEIGHT_PX = 24.0
DIRECTION_LABEL_CLEARANCE_PX = 8.0
DIRECTION_LABEL_EDGE_PX = 6.0


#: The colour bar under the cells in the scores view, screen pixels, in the smallest view of the
#: layout (:func:`rose_logs.rerun.blueprint.scores_units_per_px`): the threshold's label (a
#: direction label's size) 4 under the cells' box, the bar's top 31 under it, the bar 8 high, the
#: scale's labels 4 under it and 6 from the view's lower edge. As fractions of the map's height
#: (0.45 of it under the map) the labels were cut at the view's lower edge on a tall map at
#: 1024 x 768 with the events view and at 1280 x 720.
SCORE_BAR_TOP_PX = 31.0
SCORE_BAR_HEIGHT_PX = 8.0
SCORE_BAR_LABELS_GAP_PX = 4.0
SCORE_BAR_ROOM_PX = (
    SCORE_BAR_TOP_PX
    + SCORE_BAR_HEIGHT_PX
    + SCORE_BAR_LABELS_GAP_PX
    + DIRECTION_LABEL_HEIGHT_PX
    + DIRECTION_LABEL_EDGE_PX
)
#: The bar is at least this many pixels wide: its end labels ("score ≤ -0.5", "1 (best cell)",
#: about 80 pixels each) are centred on its ends and keep 8 pixels apart; they, and the
#: threshold's label, reach half a label's width (:data:`DIRECTION_LABEL_WIDTH_PX`) out of its ends.
SCORE_BAR_MIN_PX = DIRECTION_LABEL_WIDTH_PX + 8.0


def score_bar_width(width: float, per_px: float) -> float:
    """Width of the colour bar under a box ``width`` wide in a view of ``per_px`` units per screen
    pixel (same units): 0.6 of the box's width, at least :data:`SCORE_BAR_MIN_PX` pixels."""
    return max(0.6 * width, SCORE_BAR_MIN_PX * per_px)


def view_units_per_px(framed: tuple[float, float], view_px: tuple[float, float]) -> float:
    """Units (cells, metres) per screen pixel of a view ``view_px`` (width, height) pixels that
    shows a box ``framed`` (width, height) whole: Rerun fits it keeping its aspect."""
    return max(framed[0] / view_px[0], framed[1] / view_px[1])


def known_bounds_cells(grid: npt.NDArray[np.int8]) -> tuple[int, int, int, int] | None:
    """``(x_min, y_min, x_max, y_max)`` in cells (exclusive max) of the known cells; None if none.

    Grid frame: x along columns, y along rows (row 0 at the origin).
    """
    bounds = true_bounds(grid >= 0)
    if bounds is None:
        return None
    r0, r1, c0, c1 = bounds
    return c0, r0, c1, r1


def cells_to_pixels(points: npt.NDArray[np.float64], rows: int) -> npt.NDArray[np.float64]:
    """Grid-frame cell coordinates ``(..., (x, y))`` -> image pixels ``(..., (u, v))``, ``v = rows - y``."""
    v = rows - points[..., 1]
    # Filled in place: np.stack's checks cost more than these few values' arithmetic.
    pixels = np.empty((*v.shape, 2), dtype=np.result_type(points.dtype, v.dtype))
    pixels[..., 0], pixels[..., 1] = points[..., 0], v
    return pixels


def spectrum_strip_segments(
    directions_rad: npt.NDArray[np.float64], *, size: int = SPECTRUM_DISPLAY_PX
) -> npt.NDArray[np.float64]:
    """The kept spectrum strips as segments through DC in :func:`display_spectrum` pixels.

    Walls at ``theta`` give the spectral line at ``theta + pi/2``; on screen ``v`` points down.

    Returns
    -------
    ndarray of float64, shape (K, 2, 2)
        ``[k, end, (u, v)]``, ends on the image border, centred on the DC pixel's centre.
    """
    centre = size / 2 + 0.5
    theta = np.asarray(directions_rad, dtype=np.float64) + math.pi / 2
    unit = np.empty((*theta.shape, 2))
    unit[..., 0], unit[..., 1] = np.cos(theta), -np.sin(theta)
    reach = (size / 2 + 0.5) / np.maximum(np.abs(unit).max(axis=1, keepdims=True), 1e-12)
    return _through(centre, reach * unit)


def _through(
    centre: float | npt.NDArray[np.float64], half: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """Segments ``(K, 2, 2)`` from ``centre - half`` to ``centre + half`` (``half`` (K, 2)),
    filled in place (np.stack costs more than the arithmetic)."""
    segments = np.empty((len(half), 2, 2))
    np.subtract(centre, half, out=segments[:, 0])
    np.add(centre, half, out=segments[:, 1])
    return segments


#: Degrees this close below 180 are 0 (far below the 0.1-degree labels; float noise of a yaw).
_WRAP_DEG = 1e-6


def _folded_deg(angles_rad: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Line orientations in degrees in ``[0, 180)``, as :func:`rose.directions.fold_deg` folds
    them: a hair below 0 (a yaw of -90 degrees on a 90-degree wall) is 0, not 179.99999998."""
    folded = np.mod(np.degrees(angles_rad), 180.0)
    folded[folded > 180.0 - _WRAP_DEG] = 0.0
    return folded


@dataclass(frozen=True)
class PeakLabelBoxes:
    """The peaks' labels as boxes in the amplitude plot's units (x degrees; y ``-height * s``,
    down on screen), at the most units per pixel of the views they are laid out for
    (:func:`peak_label_boxes`), so that labels apart there stay apart in a larger view.

    Attributes
    ----------
    width, height : float
        A label's box.
    clearance : float
        From the lower edge of a label's box up to its peak (or any peak under it).
    x_min, x_max : float
        Leftmost and rightmost centre of a label: right of the s axis's tick labels, in what every
        view shows (more than its frame across: the views are wider than the frame).
    y_min : float
        Highest top of a label's box (the frame's top and its edge).
    top : float
        The frame's top (the view's visual bounds).
    high_row, x_min_high : float
        A label whose point is at ``high_row`` or higher ends above the s axis's labels: its
        leftmost centre is ``x_min_high`` (in view), not ``x_min``. Default: no such row.
    """

    width: float
    height: float
    clearance: float
    x_min: float
    x_max: float
    y_min: float
    top: float
    high_row: float = -math.inf
    x_min_high: float = -math.inf

    def left_limit(self, y: float) -> float:
        """The leftmost centre of a label whose point is at ``y``."""
        return self.x_min if y > self.high_row + 1e-9 else min(self.x_min_high, self.x_min)


def peak_label_boxes(frame: AmplitudeFrame) -> PeakLabelBoxes:
    """The peaks' label boxes in the amplitude view's ``frame`` (:func:`amplitude_frame`): labels
    :data:`~rose_logs.rerun.amplitude_layout.PEAK_LABEL_PX` wide at its units per pixel, kept
    :data:`~rose_logs.rerun.amplitude_layout.LABEL_GAP_PX` off the s axis's labels and the
    view's edges."""
    per_px = frame.per_px
    width = PEAK_LABEL_PX * per_px
    edge = LABEL_GAP_PX * per_px
    return PeakLabelBoxes(
        width=width,
        height=(LABEL_BOTTOM_PX - LABEL_TOP_PX) * per_px,
        clearance=PEAK_LABEL_CLEARANCE_PX * per_px,
        x_min=frame.axis_labels_right + edge + width / 2,
        x_max=frame.shown_right - edge - width / 2,
        y_min=frame.y_range[0] + edge,
        top=frame.y_range[0],
        # Rerun hangs a box from 1 to 24 pixels under its point.
        high_row=frame.axis_labels_top - LABEL_BOTTOM_PX * per_px,
        x_min_high=frame.x_range[0] + edge + width / 2,
    )


#: Peaks this near 0° (degrees) are labelled over the curve's other end, at 180°, where it rises
#: to them again.
PEAK_LABEL_WRAP_DEG = 10.0


def _label_anchors(
    peaks: npt.NDArray[np.float64], boxes: PeakLabelBoxes
) -> npt.NDArray[np.float64]:
    """Where the labels of ``peaks`` (shape (K, 2), plot units) hang (the top centre of each
    label's box: Rerun draws a label under its point).

    Each label stands over its peak, clear of it (a peak near 0° over the curve's other end at
    180°: the s axis's labels are at 0), in the view and right of the s axis's labels, or over
    them in the row over a peak at s = 1 (the box ends above them). Labels that would overlap
    across (peaks less than a label's width apart: 101 degrees at 1280 x 720)
    stand side by side in their peaks' order, the group centred on its peaks' mean (in the view),
    in the row over its highest peak. So two close peaks' labels each stand over their own peak
    in the smallest view (a label's width apart there), and within 45 (k - 1) pixels across in a
    view k times larger (pairs from about 55 degrees on: further left the s axis's labels leave
    no room for both around them); and the labels move as their peaks do: a peak moving by ``d`` moves its
    group's labels by at most ``d`` across, the row follows the group's highest peak. Before,
    they were placed one by one, in the order (left to right or highest first) that moved them
    least: the second a label's width away (150 pixels at 1920 x 1080), and the two swapped
    places when the peaks' heights crossed. Only a label whose place is taken (by another group's
    label, or over a bar of a peak outside its group) goes to the nearest free place beside the
    labels and bars in the way or right of the plot, in the same row, else a row higher, else
    lower."""
    b = boxes
    half = b.width / 2
    xs, ys = peaks[:, 0].tolist(), peaks[:, 1].tolist()  # plain floats: a few labels
    peaks_xy = list(zip(xs, ys, strict=True))
    # A peak too near 0° for its label (the y axis's labels are there) is also at 180°, where the
    # curve rises to it again: its label goes over that end (held at x_min it stood over a peak
    # at 90° and read as that peak's).
    wants = [
        x + 180.0 if x < min(b.x_min, PEAK_LABEL_WRAP_DEG) and x + 180.0 <= b.x_max else x
        for x in xs
    ]
    over = [max(y - b.clearance - b.height, b.y_min) for y in ys]  # each peak's row
    targets = [(min(max(x, b.left_limit(y)), b.x_max), y) for x, y in zip(wants, over, strict=True)]

    def free(x: float, y: float, placed: list[tuple[float, float]]) -> bool:
        if not b.left_limit(y) - 1e-9 <= x <= b.x_max + 1e-9:
            return False
        for px, py in placed:
            if abs(px - x) < b.width - 1e-9 and abs(py - y) < b.height - 1e-9:
                return False
        bottom = y + b.height + b.clearance
        for peak_x, peak_y in peaks_xy:  # (a loop: a generator cost more than the test)
            if abs(peak_x - x) < half - 1e-9 and bottom > peak_y + 1e-9:
                return False
        return True

    def nearest_free(i: int, placed: list[tuple[float, float]]) -> tuple[float, float]:
        """The free place nearest label ``i``'s target: rows from over its peak upwards, then
        (no room above) downwards; beside a label or a peak's bar in the way, or right of the
        plot (past 180 degrees nothing is drawn under a label)."""
        want_x, want_y = targets[i]
        rows = [want_y - r * b.height for r in range(len(xs) + 1)]
        rows = [y for y in rows if y >= b.y_min - 1e-9] or [want_y]
        rows += [want_y + r * b.height for r in range(1, len(xs) + 1)]
        for y in rows:
            candidates = [want_x, b.x_max, b.left_limit(y)]
            for px, _ in placed:
                candidates += [px + b.width, px - b.width]
            for peak_x in xs:
                candidates += [peak_x + half + b.clearance / 3, peak_x - half - b.clearance / 3]
            best: tuple[float, float] | None = None
            for x in candidates:
                cost = abs(x - want_x)
                if (best is None or cost < best[0]) and free(x, y, placed):
                    best = (cost, x)
            if best is not None:
                return best[1], y
        return want_x, want_y

    def lay_out(group: list[int]) -> list[tuple[float, float]]:
        """A group's labels side by side, centred on their targets' mean, in view if they fit,
        in the row over the group's highest peak."""
        spread = (len(group) - 1) / 2 * b.width  # from the group's centre to its outer labels
        y = min(targets[i][1] for i in group)
        # Their own places' mean: a peak near the s axis wants a place a row over the highest
        # peak may have over its labels.
        centre = sum(min(max(wants[i], b.left_limit(y)), b.x_max) for i in group) / len(group)
        low, high = b.left_limit(y) + spread, b.x_max - spread
        centre = min(max(centre, low), high) if low <= high else (low + high) / 2
        return [(centre - spread + j * b.width, y) for j in range(len(group))]

    order = sorted(range(len(xs)), key=lambda k: (targets[k][0], k))
    groups: list[list[int]] = []
    for i in order:
        groups.append([i])
        # Merge back while the last group reaches into the one before it.
        while len(groups) > 1:
            before, last = lay_out(groups[-2]), lay_out(groups[-1])
            if last[0][0] - before[-1][0] >= b.width * (1 - 1e-9):
                break
            groups[-2:] = [groups[-2] + groups[-1]]
    out = [(0.0, 0.0)] * len(xs)
    placed: list[tuple[float, float]] = []
    for group in groups:
        for i, (x, y) in zip(group, lay_out(group), strict=True):
            out[i] = (x, y) if free(x, y, placed) else nearest_free(i, placed)
            placed.append(out[i])
    return np.array(out, dtype=np.float64).reshape(-1, 2)


#: Where the prominence threshold's label ("t = 0.5", about 40 degrees wide at the default layout)
#: stands on its line when no peak is near: between the peaks of walls at 0° and 45°, right of the
#: y axis's tick labels.
THRESHOLD_LABEL_DEG = 22.5
#: How far (degrees) the threshold label's centre keeps from every peak: half its width and a
#: little more, so that no peak's bar runs through it (at 22.5° it covered the bar of a building
#: turned by 20°).
THRESHOLD_LABEL_CLEAR_DEG = 25.0


def threshold_label_deg(peaks_deg: npt.NDArray[np.float64]) -> float:
    """Centre (degrees) of the threshold's label on its line: :data:`THRESHOLD_LABEL_DEG` unless a
    peak is nearer than :data:`THRESHOLD_LABEL_CLEAR_DEG` (on the half circle: a peak at 179° rises
    from 0° too), else the middle of the gap between peaks where it is farthest from them (kept
    as far from the plot's ends as the default)."""
    peaks = np.mod(np.asarray(peaks_deg, dtype=np.float64).ravel(), 180.0)

    def clearance(x: float) -> float:
        if peaks.size == 0:
            return math.inf
        d = np.abs(peaks - x)
        return float(np.minimum(d, 180.0 - d).min())

    if clearance(THRESHOLD_LABEL_DEG) >= THRESHOLD_LABEL_CLEAR_DEG:
        return THRESHOLD_LABEL_DEG
    edges = np.concatenate([[0.0], np.sort(peaks), [180.0]])
    lo, hi = THRESHOLD_LABEL_DEG, 180.0 - THRESHOLD_LABEL_DEG
    candidates = np.clip((edges[:-1] + edges[1:]) / 2, lo, hi)
    return max(candidates.tolist(), key=lambda x: (clearance(x), -x))


def threshold_strips(level: float, label_deg: float) -> list[list[tuple[float, float]]]:
    """The threshold line at ``level`` (plot units) across 0..180 degrees in pieces, the first
    centred on ``label_deg``: Rerun centres a strip's label on it, and the label goes on the
    first."""
    half = min(label_deg, 180.0 - label_deg)
    strips = [[(label_deg - half, level), (label_deg + half, level)]]
    if label_deg - half > 0.0:
        strips.append([(0.0, level), (label_deg - half, level)])
    if label_deg + half < 180.0:
        strips.append([(label_deg + half, level), (180.0, level)])
    return strips


#: Half the width (degrees) of the tick on each peak's bar at its base + t, the height the bar must
#: reach for the peak to be kept.
THRESHOLD_TICK_DEG = 4.0


def _rejected_peaks(
    scaled: npt.NDArray[np.float64], threshold: float, kept: npt.NDArray[np.intp]
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.float64]]:
    """Bins and prominences (units of ``s``) of the local maxima of the circular ``scaled`` curve
    that rise to ``threshold`` or above, as :func:`rose.directions.find_direction_peaks` finds
    them before it compares prominences, less the ``kept`` peaks' bins: the peaks a reader could
    take for dominant that are not. Prominences are worked out for those alone (each peak's is
    its own; most snapshots have none left)."""
    n = scaled.size
    tripled = np.concatenate([scaled, scaled, scaled])
    peaks = local_maxima(tripled)
    peaks = peaks[(peaks >= n) & (peaks < 2 * n)]
    peaks = peaks[tripled[peaks] >= threshold]
    # Plain Python sets: np.isin's set-up cost more than comparing a handful of bins.
    known = set(kept.tolist())
    peaks = peaks[np.array([peak - n not in known for peak in peaks.tolist()], dtype=bool)]
    return (peaks - n).astype(np.intp), peak_prominences(tripled, peaks)


def threshold_ticks(
    bars: npt.NDArray[np.float64],
    threshold_height: float,
    *,
    label_width: float = 0.0,
    left: float = -math.inf,
    right: float = math.inf,
) -> list[list[tuple[float, float]]]:
    """The prominence threshold as a tick on each bar (shape (K, 2, 2), ``[k, (top, base), (x,
    y)]``, plot units) at its base + ``threshold_height`` (plot units, up): a peak is kept when its
    bar reaches above its tick. Empty without bars.

    The first bar's tick (the most prominent peak's) carries the threshold's label, which Rerun
    centres on the strip: the label, ``label_width`` wide with its gaps, stands beside the bar on
    the side with more room (left only if it fits right of ``left``, and of the s axis at 0),
    within ``left`` .. ``right`` (the s axis's labels' edge, what every view shows), and the tick
    reaches from the bar to past it. A tick of a fixed 56 degrees put the label over "0.5" at the
    s axis in a small window, where the label is 60 degrees wide."""
    ticks: list[list[tuple[float, float]]] = []
    xs = bars[:, 0, 0]
    for k, (x, base) in enumerate(bars[:, 1].tolist()):
        level = base - threshold_height
        low, high = x - THRESHOLD_TICK_DEG, x + THRESHOLD_TICK_DEG
        if k == 0:
            others = np.delete(xs, k)
            room_right = min([180.0 - x, *(others[others > x] - x).tolist()])
            room_left = min([x, *(x - others[others < x]).tolist()])
            half = label_width / 2
            centre = x - half
            if room_right >= room_left or centre - half < max(left, 0.0):
                centre = min(max(x, left) + half, right - half)
            reach = abs(centre - x) + THRESHOLD_TICK_DEG
            low, high = centre - reach, centre + reach
        else:
            low, high = max(low, 0.0), min(high, 180.0)
        ticks.append([(low, level), (high, level)])
    return ticks


@dataclass(frozen=True)
class AmplitudePlot:
    """The scaled cumulative amplitude as plot geometry (x: degrees, y: ``-AMPLITUDE_PLOT_HEIGHT * s``).

    Attributes
    ----------
    curve : ndarray of float64, shape (B + 1, 2)
        ``s`` over the direction bins, closed at 180 degrees (= 0).
    peaks : ndarray of float64, shape (K, 2)
        Each dominant direction at its refined angle and its bin's ``s``.
    prominence_bars : ndarray of float64, shape (K, 2, 2)
        Vertical segments from each peak down by its prominence (to its base).
    rejected_bars : ndarray of float64, shape (R, 2, 2)
        The same for the local maxima that rise above ``s = t`` but are not kept (their prominence
        is below ``t``): a line at ``s = t`` showed them crossing it as if they were dominant.
    threshold_strips : list of list of (float, float)
        The threshold ``t`` as drawn: a tick on every bar at its base + ``t`` (the first, labelled,
        longer: :func:`threshold_ticks`); without any bar (a flat curve, ``t`` above 1), a line
        at ``s = t`` in pieces around its label (:func:`threshold_strips`).
    peak_labels : list of str
    label_anchors : ndarray of float64, shape (K, 2)
        Where each peak's label hangs (Rerun draws a label under its point): above the peak, so
        that neither the peak's bar nor the curve runs through it, clear of the y axis and of the
        other labels (:func:`_label_anchors`).
    threshold : float
        The prominence threshold ``t`` (a fraction of max - min, so a level of ``s``).
    threshold_label_deg : float
        Where the threshold's label stands on its line, clear of the peaks
        (:func:`threshold_label_deg`).
    """

    curve: npt.NDArray[np.float64]
    peaks: npt.NDArray[np.float64]
    prominence_bars: npt.NDArray[np.float64]
    peak_labels: list[str]
    label_anchors: npt.NDArray[np.float64]
    threshold: float
    threshold_label_deg: float = THRESHOLD_LABEL_DEG
    rejected_bars: npt.NDArray[np.float64] = dataclasses_field(
        default_factory=lambda: np.empty((0, 2, 2))
    )
    threshold_strips: list[list[tuple[float, float]]] = dataclasses_field(default_factory=list)


def _bars(
    x: npt.NDArray[np.float64], top: npt.NDArray[np.float64], base: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """Vertical bars ``(K, 2, 2)`` at ``x`` from ``top`` down to ``base`` (each (K,))."""
    bars = np.empty((len(x), 2, 2))
    bars[:, :, 0] = x[:, np.newaxis]
    bars[:, 0, 1], bars[:, 1, 1] = top, base
    return bars


def amplitude_plot(
    result: RoseResult, *, yaw_rad: float = 0.0, label_boxes: PeakLabelBoxes | None = None
) -> AmplitudePlot:
    """Plot geometry of the paper's scaled scores ``s = (A - min) / (max - min)`` per direction, in
    map-frame degrees: ROSE's grid-frame directions turned by the origin's ``yaw_rad``, as the map
    views and every report label them. ``label_boxes``: the peaks' label boxes (None: the default
    layout's, :data:`rose_logs.rerun.blueprint.PEAK_LABEL_BOXES`)."""
    if label_boxes is None:
        from rose_logs.rerun import blueprint  # (it imports this module)

        label_boxes = blueprint.PEAK_LABEL_BOXES
    amplitude = np.asarray(result.cumulative_amplitude, dtype=np.float64)
    low, high = (float(amplitude.min()), float(amplitude.max())) if amplitude.size else (0.0, 0.0)
    span = high - low
    scaled = (amplitude - low) / span if span > 0 else np.zeros_like(amplitude)
    degrees = _folded_deg(np.asarray(result.direction_bins, dtype=np.float64) + yaw_rad)
    # Turned by the yaw, the curve starts somewhere round the half circle: sort it from 0 degrees
    # and close it at 0 and 180 with the value between its last and first bins.
    order = np.argsort(degrees, kind="stable")
    degrees, in_order = degrees[order], scaled[order]
    if degrees.size and degrees[0] > 0.0:
        gap = degrees[0] + 180.0 - degrees[-1]
        wrap = in_order[-1] + (in_order[0] - in_order[-1]) * (180.0 - degrees[-1]) / gap
        degrees, in_order = np.insert(degrees, 0, 0.0), np.insert(in_order, 0, wrap)
    height = AMPLITUDE_PLOT_HEIGHT
    # The small arrays below are filled in place: np.stack and np.append cost more than the
    # arithmetic (a few dozen values), and more again in a logging thread whose code is cold.
    curve = np.empty((len(degrees) + 1, 2))  # closed at 180 degrees with its first value
    curve[:-1, 0], curve[-1, 0] = degrees, 180.0
    curve[:-1, 1], curve[-1:, 1] = -height * in_order, -height * in_order[:1]
    peaks_idx = np.asarray(result.peak_indices, dtype=np.intp)
    peak_s = scaled[peaks_idx]
    directions = np.asarray(result.dominant_directions, dtype=np.float64)
    peak_deg = _folded_deg(directions + yaw_rad)
    prominence = np.asarray(result.peak_prominences, dtype=np.float64)
    bars = _bars(peak_deg, -height * peak_s, -height * (peak_s - prominence))
    peaks = bars[:, 0].copy()
    threshold = float(result.params.peak_prominence)
    rejected, rejected_prominence = _rejected_peaks(scaled, threshold, peaks_idx)
    rejected_bars = np.empty((0, 2, 2))
    if rejected.size:  # seldom: most snapshots keep every peak above the threshold
        rejected_deg = _folded_deg(
            np.asarray(result.direction_bins, dtype=np.float64)[rejected] + yaw_rad
        )
        rejected_s = scaled[rejected]
        rejected_bars = _bars(
            rejected_deg, -height * rejected_s, -height * (rejected_s - rejected_prominence)
        )
    # The threshold's label in pixels: its box and gaps at the boxes' units per pixel, between
    # the s axis's labels and what every view shows.
    per_px = label_boxes.width / PEAK_LABEL_PX
    label_width = (label_width_px(f"t = {threshold:g}") + 2 * LABEL_GAP_PX) * per_px
    left, right = (
        label_boxes.x_min - label_boxes.width / 2,
        label_boxes.x_max + label_boxes.width / 2,
    )
    label_deg = max(threshold_label_deg(peak_deg), left + label_width / 2)
    every_bar = np.concatenate([bars, rejected_bars])
    ticks = (
        threshold_ticks(
            every_bar, height * threshold, label_width=label_width, left=left, right=right
        )
        if every_bar.size
        else threshold_strips(-height * threshold, label_deg)
    )
    # Short: the view is a third of the window wide, and two peaks 90° apart are a quarter of it
    # apart ("3.0° (prominence 0.71)" covered "100.0° (prominence 1.00)"). The view's title says
    # what p is.
    labels = [
        f"{deg:.1f}° p {prom:.2f}"
        for deg, prom in zip(
            map_frame_deg(directions, yaw_rad=yaw_rad, digits=1), prominence, strict=True
        )
    ]
    return AmplitudePlot(
        curve=curve,
        peaks=peaks,
        prominence_bars=bars,
        peak_labels=labels,
        label_anchors=_label_anchors(peaks, label_boxes),
        threshold=threshold,
        threshold_label_deg=label_deg,
        rejected_bars=rejected_bars,
        threshold_strips=ticks,
    )
