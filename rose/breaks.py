"""What a map alone says about a break: an earlier map that a later map contradicts.

A map *breaks* mid-session when the pose estimate goes wrong: from then on the robot writes what it
sees where it believes it is. Log-odds mapping does not add a second, inconsistent set of walls; it
changes evidence, a few scans at a time. Two contradictions are measured, each in *wall-like pieces*
(connected cells, small gaps bridged, at least ``min_extent_px`` long, so people, chairs and furniture
blobs that come and go do not count):

*erased walls*
    An established wall cell (occupied in the earlier grid, part of such a piece there) that the
    later grid holds free, with no occupied cell within ``tolerance_px`` in the later grid (so a wall
    that moved by a cell or two, as walls do between two correct snapshots, does not count).
*risen evidence*
    A cell deep in the earlier grid's known free space (no earlier cell that is not known free,
    i.e. wall, unknown or uncertain, within ``rise_margin_px``) whose occupancy rose by at least ``rise_points`` percentage points, in a
    piece of such cells (in the later grid). Rays from a wrong pose end in space mapped free: the
    evidence rises there long before the cells read as occupied, since a free cell needs several
    net hits (and a clamped wall several net misses) to flip.

A break contradicts the map along whole walls. So contradicted cells are counted by the tiles of
``tile_px`` cells they touch (a length along the walls, in tile sides), the score is the most such
tiles inside one square window of ``window_px`` cells, and the region is where that window's
contradicted cells lie. Tiles are laid on the lattice phase that needs the fewest of them there
(a wall a few cells thick across a tile boundary is not counted twice), so the score depends
neither on where the grid's origin lies nor on the grid's orientation.

Global W (:mod:`rose.directions`) stays the paper's score of the whole map; on maps that break
mid-session it barely moves, because the intact part of the map dominates the spectrum.

Conventions: ROS grids (row 0 at the map origin, -1 unknown, 0..100); both grids share a resolution
and orientation, ``offset_px`` places the earlier grid in the later one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from rose.errors import RoseError
from rose.labelling import FLOOD_FILL_MAX_SIDE, components, label_boxes
from rose.limits import integer_number, pair_of

__all__ = [
    "MAX_KERNEL_PX",
    "EarlierGridMemo",
    "WallContradiction",
    "contradicted_walls",
    "erased_walls",
    "placed_grid",
    "risen_evidence",
]


#: Longest tolerance, bridge, margin or tile taken, cells: they are square kernels of about twice
#: that side, or blocks of that side (10**6 cells asked for terabytes).
MAX_KERNEL_PX = 1000


@dataclass(frozen=True)
class WallContradiction:
    """What of an earlier grid a later grid contradicts (module notes).

    Attributes
    ----------
    erased_px : int
        Established wall cells that the later grid holds free, far from any wall.
    risen_px : int
        Cells deep in the earlier grid's free space where the later grid's evidence rose.
    contradicted_tiles : int
        Tiles of ``tile_px`` x ``tile_px`` cells holding at least one erased or risen cell (on the
        lattice phase of ``peak_tiles``).
    peak_tiles : int
        The most such tiles in one window of ``window_px`` x ``window_px`` cells, on the lattice
        phase where that is fewest: the break score in tiles (times ``tile_px`` times the
        resolution it is a wall length in metres).
    established_px : int
        Occupied cells of the earlier grid.
    region_px : tuple of int or None
        ``(row_min, col_min, row_max, col_max)`` (inclusive) of the contradicted cells in that
        window, in the later grid's cells; None when nothing was contradicted.
    tile_px, window_px : int
        Tile and window sides, cells.
    """

    erased_px: int
    risen_px: int
    contradicted_tiles: int
    peak_tiles: int
    established_px: int
    region_px: tuple[int, int, int, int] | None
    tile_px: int
    window_px: int


def placed_grid(
    earlier: npt.NDArray[np.int8], shape: tuple[int, int], offset_px: tuple[int, int]
) -> npt.NDArray[np.int8]:
    """``earlier`` in a grid of ``shape`` with its cell (0, 0) at ``offset_px``; -1 elsewhere."""
    out = np.full(shape, -1, dtype=np.int8)
    r0, c0 = offset_px
    h, w = earlier.shape
    rs, cs = max(r0, 0), max(c0, 0)
    re, ce = min(r0 + h, shape[0]), min(c0 + w, shape[1])
    if rs < re and cs < ce:
        out[rs:re, cs:ce] = earlier[rs - r0 : re - r0, cs - c0 : ce - c0]
    return out


class _Cells(NamedTuple):
    """Contradicted cells of one kind, in the later grid's cells: ``rows`` and ``cols`` (intp, one
    entry a cell, each cell once) and ``box``, ``(row0, row1, col0, col1)`` (ends exclusive) where
    they were looked for (their candidates' bounding box plus a margin), None when there was no
    candidate. The boxes place the tiles (:func:`_fewest_tiles`): the score's window, and which of two
    windows as dense comes first, depend on them."""

    rows: npt.NDArray[np.intp]
    cols: npt.NDArray[np.intp]
    box: tuple[int, int, int, int] | None


_NO_CELLS = _Cells(np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp), None)


class EarlierGridMemo:
    """What :func:`contradicted_walls` found of an earlier grid alone, kept for its next
    comparisons of that grid: a detector compares its trusted snapshot, and its anchor, with many
    later ones, whose erased cells are mostly the same. The grid placed in the later grid's cells
    (:func:`placed_grid`, when it is not the grid itself); whether cells of its walls lie on long
    walls (each cell's wall is measured once: flood fills or labelling, :func:`_on_long_walls`);
    from its second comparison on, the cells near one that is not known free (the risen cells'
    margin: one dilation of the whole grid, then read at the candidates, when they are too many to
    look at their windows).

    One per earlier grid, which must not change meanwhile; forgotten when given another grid (by
    identity), another placement (the later grid's shape, the offset) or other parameters.
    """

    def __init__(self) -> None:
        self._grid: npt.NDArray[np.int8] | None = None
        self._key: tuple[object, ...] = ()
        self._uses = 0  # comparisons with this grid and key
        # Flat indices of the cells (in the later grid's cells; ascending) and their verdicts.
        self._cells = np.zeros(0, dtype=np.intp)
        self._long = np.zeros(0, dtype=bool)
        self._near_other: npt.NDArray[np.bool_] | None = None
        self._placed: npt.NDArray[np.int8] | None = None  # the grid in the later grid's cells

    def _use(self, grid: npt.NDArray[np.int8], key: tuple[object, ...]) -> None:
        """Start over unless the memo is of ``grid`` (the earlier grid) and ``key`` already."""
        if grid is not self._grid or key != self._key:
            self._grid, self._key, self._uses = grid, key, 0
            self._cells, self._long = self._cells[:0], self._long[:0]
            self._near_other = self._placed = None
        self._uses += 1

    def _near_other_cells(
        self,
        placed: npt.NDArray[np.int8],
        free_threshold: int,
        rise_margin_px: int,
        build: bool,
    ) -> npt.NDArray[np.bool_] | None:
        """Cells of the whole (placed) grid within ``rise_margin_px`` of one that is not known
        free, or of the grid's edge (:func:`_risen_cells`), made if ``build`` (a box would be
        dilated otherwise); None until then, and at the first comparison (a box around the
        candidates costs less, when the grid is compared once)."""
        if self._near_other is None and build and self._uses >= 2:
            not_free = placed.view(np.uint8) > free_threshold
            self._near_other = _dilate_square(not_free, rise_margin_px, outside=True)
        return self._near_other

    def _look_up(
        self, cells: npt.NDArray[np.intp]
    ) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
        """For the flat indices ``cells``: whether each is known, and its verdict (False where
        not known)."""
        at = np.searchsorted(self._cells, cells)
        known = np.zeros(cells.size, dtype=bool)
        inside = at < self._cells.size
        known[inside] = self._cells[at[inside]] == cells[inside]
        verdict = np.zeros(cells.size, dtype=bool)
        verdict[known] = self._long[at[known]]
        return known, verdict

    def _add(self, cells: npt.NDArray[np.intp], verdicts: npt.NDArray[np.bool_]) -> None:
        """Keep the verdicts of the flat indices ``cells`` (none of them known yet)."""
        merged = np.concatenate([self._cells, cells])
        order = np.argsort(merged, kind="stable")
        self._cells = merged[order]
        self._long = np.concatenate([self._long, verdicts])[order]


def _mask(shape: tuple[int, int], cells: _Cells) -> npt.NDArray[np.bool_]:
    """``cells`` as a boolean mask of ``shape``."""
    out = np.zeros(shape, dtype=bool)
    out[cells.rows, cells.cols] = True
    return out


def _densest_window(tiles: npt.NDArray[np.bool_], side: int) -> tuple[int, int, int]:
    """Most flagged tiles in a ``side`` x ``side`` window of tiles: ``(count, row, col)`` of its
    first tile (the first such window in row-major order)."""
    import cv2

    side_r, side_c = min(side, tiles.shape[0]), min(side, tiles.shape[1])
    # Summed-area table, a zero row and column first (int32): OpenCV's in one pass.
    c = cv2.integral(np.ascontiguousarray(tiles).view(np.uint8))
    sums = c[side_r:, side_c:] - c[:-side_r, side_c:] - c[side_r:, :-side_c] + c[:-side_r, :-side_c]
    i, j = np.unravel_index(int(np.argmax(sums)), sums.shape)
    return int(sums[i, j]), int(i), int(j)


#: Lattice phases tried along each axis at most (:func:`_fewest_tiles`): every phase of tiles up to
#: this many cells a side (0.25 m tiles down to 1 cm cells), every few cells beyond.
_MAX_PHASES = 25

#: What placing a cell on one phase's tiles costs, in box cells dilated by a small tile
#: (:func:`_fewest_tiles`; measured: about 6 ns and 2 ns).
_PLACE_COST = 3


def _fewest_tiles(
    cells: _Cells,
    box: tuple[int, int, int, int],
    tile_px: int,
    side: int,
    origin: tuple[int, int],
) -> tuple[int, int, int, int]:
    """The densest window of ``side`` x ``side`` tiles (:func:`_densest_window`) on the lattice
    phase that needs the fewest tiles there: ``(peak, tiles, row, col)``, the window's tiles, all
    flagged tiles of that phase and the later-grid cell of the window's first tile. ``cells`` lie
    in ``box`` (``(row0, row1, col0, col1)``, ends exclusive, which also bounds the tiles: the
    window's place among equal ones depends on it); phases are tried from the lattice through
    ``origin``, and the first of equal peaks is kept.

    On one fixed lattice a wall two or three cells thick that lies across a tile boundary touched
    twice the tiles of one inside a row of tiles: the score of the same map doubled with its
    origin's absolute value modulo a tile (a correct growing map broke at some origins, not at
    others). The fewest tiles over the phases do not depend on the origin, nor on the map's
    orientation, and measure a thick wall by its length."""
    import cv2

    r0, r1, c0, c1 = box
    step = -(-tile_px // _MAX_PHASES)
    phases = [(dr, dc) for dr in range(0, tile_px, step) for dc in range(0, tile_px, step)]
    # Many cells (a break on 1-cm cells: 625 phases; 4.7 million cells placed on each took 22 s
    # per comparison) are placed once: flags of the cells that start a tile holding one (the box's
    # cells dilated by a tile towards its first cell, in a tile of margin), every phase's tiles a
    # strided view of them. Few cells in a large box are placed on each phase's tiles: dilating
    # the box by a large tile costs more (a box cell's dilation costs once more per 240 cells
    # of tile). Either way the same tiles.
    shape = (r1 - r0 + 2 * tile_px, c1 - c0 + 2 * tile_px)
    dense = cells.rows.size * len(phases) * _PLACE_COST > shape[0] * shape[1] * (1 + tile_px / 240)
    starts: npt.NDArray[np.bool_] | None = None
    if dense:
        flags: npt.NDArray[np.uint8] = np.zeros(shape, dtype=np.uint8)
        flags[cells.rows - (r0 - tile_px), cells.cols - (c0 - tile_px)] = 1
        for kernel in ((tile_px, 1), (1, tile_px)) if tile_px > 1 else ():
            flags = np.asarray(
                cv2.dilate(flags, np.ones(kernel, np.uint8), anchor=(0, 0), borderValue=0),
                dtype=np.uint8,
            )
        starts = flags.view(bool)
    best: tuple[int, int, int, int] | None = None
    for dr, dc in phases:
        # The lattice through (origin + phase): its first tile at or before the box's first cell.
        tr = r0 - (r0 - origin[0] - dr) % tile_px
        tc = c0 - (c0 - origin[1] - dc) % tile_px
        rows, cols = -(-(r1 - tr) // tile_px), -(-(c1 - tc) // tile_px)
        if starts is not None:
            y, x = tr - (r0 - tile_px), tc - (c0 - tile_px)
            tiles = starts[y : y + rows * tile_px : tile_px, x : x + cols * tile_px : tile_px]
        else:
            tiles = np.zeros((rows, cols), dtype=bool)
            tiles[(cells.rows - tr) // tile_px, (cells.cols - tc) // tile_px] = True
        peak, wi, wj = _densest_window(tiles, side)
        if best is None or peak < best[0]:
            best = (peak, int(np.count_nonzero(tiles)), tr + wi * tile_px, tc + wj * tile_px)
    assert best is not None  # tile_px >= 1: one phase at least
    return best


def _require_cell(value: object, name: str) -> None:
    """RoseError unless ``value`` is a cell: two integers ``(row, col)``."""
    if not pair_of(value, integer_number):
        msg = f"{name} must be two integers (row, col), got {value!r}"
        raise RoseError(msg)


def _check(
    earlier: npt.ArrayLike,
    later: npt.ArrayLike,
    offset_px: tuple[int, int],
    tolerance_px: int,
    min_extent_px: int = 0,
    bridge_px: int = 0,
    rise_points: int = 1,
    rise_margin_px: int = 0,
    occupied_threshold: int | None = None,
    free_threshold: int = 0,
) -> tuple[npt.NDArray[np.int8], npt.NDArray[np.int8]]:
    """The two grids as int8 arrays, after checking them and the lengths; RoseError otherwise.

    Grids are integer ROS grids. Values outside -1..100 are kept (such cells are neither free nor
    known occupancy, so nothing rises to them); floats (NaN casts to garbage) and boolean masks
    (which would read as all free) are refused.
    """
    grids = []
    for name, grid in (("earlier", earlier), ("later", later)):
        array = np.asarray(grid)
        if array.ndim != 2:
            msg = f"{name} grid must be 2-D, got shape {array.shape}"
            raise RoseError(msg)
        if array.dtype.kind not in "iu":  # by kind: numpy counts timedelta64 among integers
            msg = f"{name} grid must hold int8 ROS occupancy (-1, 0..100), got dtype {array.dtype}"
            raise RoseError(msg)
        # (int8 holds nothing else: two passes saved per grid and snapshot.)
        if array.dtype != np.int8 and array.size and (array.min() < -128 or array.max() > 127):
            msg = (
                f"{name} grid must hold int8 ROS occupancy (-1, 0..100), got values in "
                f"[{array.min()}, {array.max()}]"
            )
            raise RoseError(msg)
        grids.append(array.astype(np.int8, copy=False))
    _require_cell(offset_px, "offset_px")
    kernels = {
        "tolerance_px": tolerance_px,
        "bridge_px": bridge_px,
        "rise_margin_px": rise_margin_px,
    }
    for name, value in kernels.items():
        if not integer_number(value) or not 0 <= value <= MAX_KERNEL_PX:
            msg = f"{name} must be an integer in 0..{MAX_KERNEL_PX}, got {value!r}"
            raise RoseError(msg)
    if not integer_number(min_extent_px) or min_extent_px < 0:
        msg = f"min_extent_px must be an integer >= 0, got {min_extent_px!r}"
        raise RoseError(msg)
    if not integer_number(free_threshold) or not 0 <= free_threshold <= 100:
        msg = f"free_threshold must be an integer in 0..100, got {free_threshold!r}"
        raise RoseError(msg)
    if occupied_threshold is not None and not (
        integer_number(occupied_threshold) and free_threshold < occupied_threshold <= 100
    ):
        msg = (
            "occupied_threshold must be an integer above free_threshold and at most 100, got "
            f"{occupied_threshold!r} (free_threshold {free_threshold})"
        )
        raise RoseError(msg)
    if not integer_number(rise_points) or not 1 <= rise_points <= 101:
        msg = f"rise_points must be an integer in 1..101 (101: off), got {rise_points!r}"
        raise RoseError(msg)
    return grids[0], grids[1]


def _grown(
    bounds: tuple[int, int, int, int], margin: int, shape: tuple[int, ...]
) -> tuple[int, int, int, int]:
    """``bounds`` (``(row0, row1, col0, col1)``, ends exclusive) grown by ``margin`` cells on every
    side and cut to a grid of ``shape``."""
    r0, r1, c0, c1 = bounds
    return (
        max(r0 - margin, 0),
        min(r1 + margin, shape[0]),
        max(c0 - margin, 0),
        min(c1 + margin, shape[1]),
    )


def _dilate_square(
    mask: npt.NDArray[np.bool_], radius_px: int, *, outside: bool = False
) -> npt.NDArray[np.bool_]:
    """``mask`` grown by ``radius_px`` cells in chessboard distance (``outside`` the image counts
    as that value)."""
    import cv2

    if radius_px <= 0:
        return mask.copy()
    kernel = np.ones((2 * radius_px + 1, 2 * radius_px + 1), np.uint8)
    return cv2.dilate(
        np.ascontiguousarray(mask).view(np.uint8),
        kernel,
        borderType=cv2.BORDER_CONSTANT,
        borderValue=int(outside),
    ).astype(bool)


def _bridged(walls: npt.NDArray[np.bool_], bridge_px: int) -> npt.NDArray[np.uint8]:
    """``walls`` (bool, shape (rows, cols)) with gaps up to ``bridge_px`` cells bridged: uint8 0 / 1,
    C-contiguous (a view of ``walls`` when nothing is bridged and it is contiguous)."""
    import cv2  # OpenCV's morphology and labelling: several times scipy.ndimage's speed here

    joined = np.ascontiguousarray(walls).view(np.uint8)
    if bridge_px > 0:
        # A (b+1)-square kernel anchored like scipy's binary_dilation (at size // 2, reflected).
        size = bridge_px + 1
        anchor = (size - 1 - size // 2, size - 1 - size // 2)
        joined = np.asarray(
            cv2.dilate(joined, np.ones((size, size), np.uint8), anchor=anchor), dtype=np.uint8
        )
    return joined


def _long_labels(
    walls: npt.NDArray[np.bool_], min_extent_px: int, bridge_px: int
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.integer]]:
    """The connected walls of ``walls`` (bool, shape (rows, cols); gaps up to ``bridge_px`` cells
    bridged): whether each spans at least ``min_extent_px`` cells along rows or columns (shape
    (labels,), the background's False), and the labels (shape of ``walls``, 0 off the walls)."""
    joined = _bridged(walls, bridge_px)
    count, labels = components(joined)
    if count <= 1:  # label 0 is the background
        return np.zeros(count, dtype=bool), labels
    # The extent of each (bridged) wall: the longer side of its bounding box, in cells. Through a
    # boolean view (the cells are 0 or 1): numpy finds the nonzero cells of a boolean array several
    # times faster than of a uint8 one (70 vs 540 us on a 360 x 840 box of walls).
    boxes = label_boxes(labels, np.flatnonzero(joined.view(np.bool_)), count)
    keep = np.maximum(boxes[:, 2], boxes[:, 3]) >= min_extent_px
    keep[0] = False
    return keep, labels


#: Cells of one box looked up by flood fills (:func:`_long_at`); more are labelled. A fill is
#: numbered in its mask's byte; 255 at most.
_MAX_FILLS = 255


def _long_at(
    walls: npt.NDArray[np.bool_],
    rows: npt.NDArray[np.intp],
    cols: npt.NDArray[np.intp],
    min_extent_px: int,
    bridge_px: int,
) -> npt.NDArray[np.bool_]:
    """Whether the wall cells ``(rows[i], cols[i])`` of ``walls`` (bool, shape (rows, cols)) lie on
    long walls of it (:func:`_long_labels`), shape (cells,).

    Few cells: a flood fill of the bridged walls from each (one per wall), whose bounding box OpenCV
    returns; it visits that wall's cells only, where labelling visits every cell of the box and
    then the walls' cells again for their boxes (35 us at least, 5-10 for a fill).
    """
    import cv2

    # (OpenCV's flood fill goes wrong on a side over FLOOD_FILL_MAX_SIDE: it filled a short piece
    # 65,536 columns away as part of a long wall.)
    if rows.size > _MAX_FILLS or max(walls.shape) > FLOOD_FILL_MAX_SIDE:
        keep, labels = _long_labels(walls, min_extent_px, bridge_px)
        return keep[labels[rows, cols]]
    joined = _bridged(walls, bridge_px)
    mask = np.zeros((joined.shape[0] + 2, joined.shape[1] + 2), dtype=np.uint8)
    # Cells equal to the seed's (1), 8-connected; the mask is marked with the fill's number.
    flags = 8 | cv2.FLOODFILL_MASK_ONLY | cv2.FLOODFILL_FIXED_RANGE
    long_fill = [False]  # per fill number (0: none)
    out = np.zeros(rows.size, dtype=bool)
    for i, (r, c) in enumerate(zip(rows.tolist(), cols.tolist(), strict=True)):
        fill = int(mask[r + 1, c + 1])
        if not fill:
            fill = len(long_fill)
            _, _, _, (_, _, width, height) = cv2.floodFill(
                joined, mask, (c, r), 1, 0, 0, flags | (fill << 8)
            )
            long_fill.append(max(width, height) >= min_extent_px)
        out[i] = long_fill[fill]
    return out


#: At most this many boxes are looked up apart for the cells :func:`_on_long_walls` is given;
#: more, and one box over them all.
_MAX_CLUSTERS = 64


def _on_long_walls(
    walls_in: Callable[[int, int, int, int], npt.NDArray[np.bool_]],
    shape: tuple[int, int],
    rows: npt.NDArray[np.intp],
    cols: npt.NDArray[np.intp],
    min_extent_px: int,
    bridge_px: int,
) -> npt.NDArray[np.bool_]:
    """Whether each cell ``(rows[i], cols[i])`` of the walls of a grid of ``shape`` (the cells are
    walls) lies on a long wall (:func:`_long_labels`), shape (cells,). The walls are read in the
    boxes below only: ``walls_in(row0, row1, col0, col1)`` (ends exclusive) is a box's, bool.

    Each cell's wall is labelled in a box reaching ``reach = min_extent_px + bridge_px`` cells beyond
    it (or to the grid's edge); any such box gives the same answer, the whole grid's included. A
    wall that leaves the box, bridged or not, is labelled through cells that the bridging sees
    whole (farther than ``bridge_px`` from the box's edge) until a cell at least
    ``reach - bridge_px`` = ``min_extent_px`` rows or columns away from the cell: long in the box
    as in the grid. A wall that does not leave it is the grid's wall.

    So the cells are looked up in few small boxes instead of one over them all (erased cells are a
    few dozen in some clusters across a wide box): the cells grouped by blocks of ``2 reach + 1``
    (cells in blocks that do not touch are farther apart than two reaches), each group of touching
    blocks in its cells' bounding box plus the reach; in one such box over all the cells when the
    groups are many or their boxes would cover more.
    """
    import cv2

    reach = min_extent_px + bridge_px

    def box_around(at: npt.NDArray[np.intp]) -> tuple[int, int, int, int]:
        """The bounding box of the cells ``at`` (indices into rows and cols) plus the reach."""
        r, c = rows[at], cols[at]
        return _grown(
            (int(r.min()), int(r.max()) + 1, int(c.min()), int(c.max()) + 1), reach, shape
        )

    box_of_all = box_around(np.arange(rows.size))
    boxes = [(box_of_all, np.arange(rows.size))]
    block = 2 * reach + 1
    br, bc = rows // block, cols // block
    br -= br.min()
    bc -= bc.min()
    coarse = np.zeros((int(br.max()) + 1, int(bc.max()) + 1), dtype=np.uint8)
    coarse[br, bc] = 1
    count, groups = cv2.connectedComponents(coarse, None, 8, cv2.CV_32S)
    if 2 < count <= _MAX_CLUSTERS + 1:  # at least two groups (label 0 is the background)
        group = groups[br, bc]
        order = np.argsort(group, kind="stable")
        starts = np.flatnonzero(np.diff(group[order])) + 1
        split = np.split(order, starts)
        grouped = [(box_around(at), at) for at in split]
        area = sum((r1 - r0) * (c1 - c0) for (r0, r1, c0, c1), _ in grouped)
        r0, r1, c0, c1 = box_of_all
        if area < (r1 - r0) * (c1 - c0):
            boxes = grouped
    on_long = np.zeros(rows.size, dtype=bool)
    for (r0, r1, c0, c1), at in boxes:
        walls = walls_in(r0, r1, c0, c1)
        on_long[at] = _long_at(walls, rows[at] - r0, cols[at] - c0, min_extent_px, bridge_px)
    return on_long


#: Gathering a cell's window costs about this many times a cell of a dilation (OpenCV's, of a
#: box around the cells; 2.4 vs 0.5 ns): :func:`_far_cells` gathers when that is cheaper.
_GATHER_COST = 5


def _far_cells(
    grid: npt.NDArray[np.int8],
    rows: npt.NDArray[np.intp],
    cols: npt.NDArray[np.intp],
    radius_px: int,
    cells: Callable[[npt.NDArray[np.int8]], npt.NDArray[np.bool_]],
    *,
    outside: bool = False,
    near_map: Callable[[bool], npt.NDArray[np.bool_] | None] | None = None,
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """The cells ``(rows[i], cols[i])`` of ``grid`` (int8, shape (rows, cols); ``rows`` ascending)
    with no True cell of ``cells(grid)`` within ``radius_px`` (chessboard distance; ``outside``
    the grid counts as ``outside``), as rows and columns. ``near_map(build)``: the whole grid's
    answer when known (read at the cells), made first if ``build`` and it is worth it (asked so
    where a box would be dilated).

    Few cells (a few dozen among hundreds of thousands in their box): each one's window gathered,
    its rows and columns clipped to the grid (a clipped index is the window's cell at the grid's
    edge: the window's cells in the grid are read, and only they). Many: their bounding box plus
    the radius dilated (:func:`_dilate_square`). Alike, cell for cell.
    """
    t0, t1, u0, u1 = _grown(
        (int(rows[0]), int(rows[-1]) + 1, int(cols.min()), int(cols.max()) + 1),
        radius_px,
        grid.shape,
    )
    side = 2 * radius_px + 1
    dilate = rows.size * side * side * _GATHER_COST >= (t1 - t0) * (u1 - u0)
    whole = None if near_map is None else near_map(dilate)
    if whole is not None:
        near = whole[rows, cols]
    elif dilate:
        dilated = _dilate_square(cells(grid[t0:t1, u0:u1]), radius_px, outside=outside)
        near = dilated[rows - t0, cols - u0]
    else:
        height, width = grid.shape
        reach = np.arange(-radius_px, radius_px + 1)
        at_rows = np.clip(rows[:, None] + reach, 0, height - 1) * width
        at_cols = np.clip(cols[:, None] + reach, 0, width - 1)
        at = (at_rows[:, :, None] + at_cols[:, None, :]).reshape(rows.size, -1)
        near = np.any(cells(grid.reshape(-1).take(at)), axis=1)
        if outside:  # windows reaching past the grid's edge
            near |= (rows < radius_px) | (rows >= height - radius_px)
            near |= (cols < radius_px) | (cols >= width - radius_px)
    return rows[~near], cols[~near]


class _Changed(NamedTuple):
    """The cells where two grids of one shape differ, by words of 8 cells (the grids' bytes, C
    order, compared as 64-bit words): ``starts``, the flat index of each differing word's first
    cell (ascending); ``placed`` and ``later``, those words' cells in either grid (int8, shape
    (words, 8)). The last ``size % 8`` cells make a word of their own, filled up with cells unknown
    in both grids (equal: never a candidate)."""

    starts: npt.NDArray[np.intp]
    placed: npt.NDArray[np.int8]
    later: npt.NDArray[np.int8]

    def cells(
        self, mask: npt.NDArray[np.bool_], cols: int
    ) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
        """Rows and columns (row-major order) of the cells ``mask`` (shape (words, 8)) flags, in a
        grid of ``cols`` columns."""
        at = np.flatnonzero(mask)
        return np.divmod(self.starts[at >> 3] + (at & 7), cols)


def _changed_words(placed: npt.NDArray[np.int8], later: npt.NDArray[np.int8]) -> _Changed | None:
    """The words where ``placed`` and ``later`` (int8, one shape) differ (:class:`_Changed`); None
    when they are equal.

    Every candidate is such a cell (a wall turned free, a rise of at least a point), and two
    snapshots of a session differ in a small part of the grid (17 000 to 200 000 of 2 million
    cells, 30 s apart): the candidates are looked for in those words only, instead of the whole
    grid (several passes over it, each 25-40 us per million cells). Comparing the words is one
    pass at 8 cells a step (28 us for 1000 x 1000 cells).
    """
    flat_p = np.ascontiguousarray(placed).reshape(-1)
    flat_l = np.ascontiguousarray(later).reshape(-1)
    n = flat_l.size // 8 * 8
    words_p, words_l = flat_p[:n].view(np.uint64), flat_l[:n].view(np.uint64)
    at = np.flatnonzero(words_p != words_l)
    starts = at * 8
    cells_p = words_p[at].view(np.int8).reshape(-1, 8)
    cells_l = words_l[at].view(np.int8).reshape(-1, 8)
    if n < flat_l.size and not np.array_equal(flat_p[n:], flat_l[n:]):
        tail_p, tail_l = np.full((1, 8), -1, dtype=np.int8), np.full((1, 8), -1, dtype=np.int8)
        tail_p[0, : flat_p.size - n], tail_l[0, : flat_l.size - n] = flat_p[n:], flat_l[n:]
        starts = np.append(starts, n)
        cells_p, cells_l = np.concatenate([cells_p, tail_p]), np.concatenate([cells_l, tail_l])
    if not starts.size:
        return None
    return _Changed(starts, cells_p, cells_l)


def _erased_cells(
    placed: npt.NDArray[np.int8],
    later: npt.NDArray[np.int8],
    changed: _Changed | None,
    tolerance_px: int,
    occupied_threshold: int,
    free_threshold: int,
    min_extent_px: int = 0,
    bridge_px: int = 0,
    memo: EarlierGridMemo | None = None,
) -> _Cells:
    """Erased cells in ``later``'s cells (``placed``: the earlier grid in ``later``'s cells,
    :func:`placed_grid`; both int8, one shape; ``changed``: :func:`_changed_words` of them;
    ``memo``: the long walls found in comparisons before, of the grid ``placed`` places, kept up
    to date)."""
    if changed is None:
        return _NO_CELLS
    # Known free in the later grid (0..free_threshold) in one comparison: read as unsigned bytes,
    # -1..-128 are 255..128, above every threshold (0..100). A wall earlier: a changed cell.
    candidates = changed.later.view(np.uint8) <= free_threshold
    candidates &= changed.placed >= occupied_threshold
    rows, cols = changed.cells(candidates, later.shape[1])
    if not rows.size:
        return _NO_CELLS
    bounds = (int(rows[0]), int(rows[-1]) + 1, int(cols.min()), int(cols.max()) + 1)
    # Only candidates can be erased: the box is their bounding box plus the tolerance (and plus
    # the wall extent when walls must be long, where they are seen whole).
    box = _grown(bounds, max(tolerance_px, min_extent_px + bridge_px), later.shape)
    # A candidate and not near a wall: walls within the tolerance of a candidate lie in its
    # bounding box plus the tolerance.
    rows, cols = _far_cells(
        later, rows, cols, tolerance_px, lambda cells: cells >= occupied_threshold
    )
    if min_extent_px > 1 and rows.size:
        # A cell's verdict is its wall's in the whole grid, whichever cells are looked up with it.
        cells = rows * later.shape[1] + cols
        if memo is not None:
            known, on_long = memo._look_up(cells)
        else:
            known, on_long = np.zeros(rows.size, dtype=bool), np.zeros(rows.size, dtype=bool)
        new = ~known
        if new.any():
            on_long[new] = _on_long_walls(
                lambda r0, r1, c0, c1: placed[r0:r1, c0:c1] >= occupied_threshold,
                later.shape,
                rows[new],
                cols[new],
                min_extent_px,
                bridge_px,
            )
            if memo is not None:
                memo._add(cells[new], on_long[new])
        rows, cols = rows[on_long], cols[on_long]
    return _Cells(rows, cols, box)


def _placed(
    earlier: npt.NDArray[np.integer], later: npt.NDArray[np.integer], offset_px: tuple[int, int]
) -> npt.NDArray[np.int8]:
    """``earlier`` in ``later``'s cells (:func:`placed_grid`): ``earlier`` itself when it lies on
    them exactly (the common case of a map that did not grow; read only, a copy saved)."""
    earlier8 = earlier.astype(np.int8, copy=False)
    if earlier8.shape == later.shape and offset_px[0] == 0 and offset_px[1] == 0:
        return earlier8
    return placed_grid(earlier8, later.shape, offset_px)


def _risen_cells(
    placed: npt.NDArray[np.int8],
    later: npt.NDArray[np.int8],
    changed: _Changed | None,
    rise_points: int,
    rise_margin_px: int,
    free_threshold: int,
    min_extent_px: int,
    bridge_px: int,
    memo: EarlierGridMemo | None = None,
) -> _Cells:
    """Risen cells in ``later``'s cells (``placed``: the earlier grid in ``later``'s cells,
    :func:`placed_grid`; both int8, one shape; ``changed``: :func:`_changed_words` of them;
    ``memo``: what comparisons before found of the grid ``placed`` places)."""
    if rise_points > 100 or changed is None:  # off, or nothing rose
        return _NO_CELLS
    # Known free earlier (0..free_threshold) and known later (0..100, so unknown -1 never rises,
    # nor values outside the ROS range) in one comparison each: read as unsigned bytes, -1..-128
    # are 255..128. On those cells the difference lies in -50..100: int8 holds it (elsewhere it may
    # wrap, and is masked out). A rise is a changed cell.
    candidates = np.subtract(changed.later, changed.placed) >= rise_points
    candidates &= changed.placed.view(np.uint8) <= free_threshold
    candidates &= changed.later.view(np.uint8) <= 100
    rows, cols = changed.cells(candidates, later.shape[1])
    if not rows.size:
        return _NO_CELLS
    bounds = (int(rows[0]), int(rows[-1]) + 1, int(cols.min()), int(cols.max()) + 1)
    box = _grown(bounds, max(rise_margin_px, min_extent_px + bridge_px), later.shape)
    # Deep in free space: no earlier cell that is not known free (wall, unknown, uncertain; nor the
    # grid's edge) within the margin, so that walls seen a cell off and the frontier of exploration
    # do not count. Those cells lie in the candidates' bounding box plus the margin, which reaches
    # beyond every candidate unless the grid ends first: only the grid's own edge is within the
    # reach of `outside`.
    rows, cols = _far_cells(  # a candidate, not near another cell
        placed,
        rows,
        cols,
        rise_margin_px,
        lambda cells: cells.view(np.uint8) > free_threshold,
        outside=True,
        near_map=(
            None
            if memo is None
            else lambda build: memo._near_other_cells(placed, free_threshold, rise_margin_px, build)
        ),
    )
    if min_extent_px > 1:
        # Pieces are made of risen cells only (gaps bridged), looked up as erased walls are, in
        # small boxes around the cells (:func:`_on_long_walls`, flood fills when they are few):
        # the boxes reach past the cells by the wall extent at most.
        if not rows.size:
            return _Cells(_NO_CELLS.rows, _NO_CELLS.cols, box)
        reach = min_extent_px + bridge_px
        bounds = (int(rows[0]), int(rows[-1]) + 1, int(cols.min()), int(cols.max()) + 1)
        r0, r1, c0, c1 = _grown(bounds, reach, later.shape)
        risen = np.zeros((r1 - r0, c1 - c0), dtype=bool)
        risen[rows - r0, cols - c0] = True
        on_long = _on_long_walls(
            lambda b0, b1, d0, d1: risen[b0 - r0 : b1 - r0, d0 - c0 : d1 - c0],
            later.shape,
            rows,
            cols,
            min_extent_px,
            bridge_px,
        )
        return _Cells(rows[on_long], cols[on_long], box)
    return _Cells(rows, cols, box)


def _union_box(*boxes: tuple[int, int, int, int] | None) -> tuple[int, int, int, int] | None:
    """The bounding box of ``boxes`` (``(row0, row1, col0, col1)``, ends exclusive; None: none)."""
    present = [b for b in boxes if b is not None]
    if not present:
        return None
    return (
        min(b[0] for b in present),
        max(b[1] for b in present),
        min(b[2] for b in present),
        max(b[3] for b in present),
    )


def risen_evidence(
    earlier: npt.NDArray[np.integer],
    later: npt.NDArray[np.integer],
    *,
    offset_px: tuple[int, int] = (0, 0),
    rise_points: int = 15,
    rise_margin_px: int = 4,
    min_extent_px: int = 20,
    bridge_px: int = 2,
    free_threshold: int = 50,
) -> npt.NDArray[np.bool_]:
    """Cells of ``later`` deep in ``earlier``'s free space whose occupancy rose (module notes).

    Parameters are those of :func:`contradicted_walls`.

    Returns
    -------
    ndarray of bool, shape of ``later``
        Known free in ``earlier`` (0..``free_threshold``) with no other cell of ``earlier`` (wall,
        unknown, uncertain) within ``rise_margin_px`` (chessboard distance), at least ``rise_points`` higher
        in ``later``, in pieces at least ``min_extent_px`` long.
    """
    earlier, later = _check(
        earlier,
        later,
        offset_px,
        0,
        min_extent_px,
        bridge_px,
        rise_points,
        rise_margin_px,
        free_threshold=free_threshold,
    )
    placed = _placed(earlier, later, offset_px)
    cells = _risen_cells(
        placed,
        later,
        _changed_words(placed, later),
        rise_points,
        rise_margin_px,
        free_threshold,
        min_extent_px,
        bridge_px,
    )
    return _mask(later.shape, cells)


def erased_walls(
    earlier: npt.NDArray[np.integer],
    later: npt.NDArray[np.integer],
    *,
    offset_px: tuple[int, int] = (0, 0),
    tolerance_px: int = 6,
    min_extent_px: int = 20,
    bridge_px: int = 2,
    occupied_threshold: int = 65,
    free_threshold: int = 50,
) -> npt.NDArray[np.bool_]:
    """Cells of ``later`` where ``earlier`` had a wall that ``later`` erased.

    Parameters are those of :func:`contradicted_walls`.

    Returns
    -------
    ndarray of bool, shape of ``later``
        Occupied in ``earlier`` and part of a wall at least ``min_extent_px`` long there, free in
        ``later``, no occupied cell of ``later`` within ``tolerance_px`` (chessboard distance).
    """
    earlier, later = _check(
        earlier,
        later,
        offset_px,
        tolerance_px,
        min_extent_px,
        bridge_px,
        occupied_threshold=occupied_threshold,
        free_threshold=free_threshold,
    )
    placed = _placed(earlier, later, offset_px)
    cells = _erased_cells(
        placed,
        later,
        _changed_words(placed, later),
        tolerance_px,
        occupied_threshold,
        free_threshold,
        min_extent_px,
        bridge_px,
    )
    return _mask(later.shape, cells)


def contradicted_walls(
    earlier: npt.NDArray[np.integer],
    later: npt.NDArray[np.integer],
    *,
    offset_px: tuple[int, int] = (0, 0),
    tolerance_px: int = 6,
    min_extent_px: int = 20,
    bridge_px: int = 2,
    tile_px: int = 5,
    window_px: int = 200,
    occupied_threshold: int = 65,
    free_threshold: int = 50,
    rise_points: int = 15,
    rise_margin_px: int = 4,
    tile_origin_px: tuple[int, int] = (0, 0),
    established_px: int | None = None,
    memo: EarlierGridMemo | None = None,
) -> WallContradiction:
    """What of ``earlier`` ``later`` contradicts: erased walls and risen evidence (module notes).

    Parameters
    ----------
    earlier, later : ndarray of int8, shape (rows, cols)
        Two grids of one map (ROS convention), same resolution and orientation. Not modified.
    offset_px : tuple of int
        ``(row, col)`` of ``earlier``'s cell (0, 0) in ``later`` (a growing map moves its origin by
        whole cells); cells of ``earlier`` outside ``later`` are ignored.
    tolerance_px : int
        A wall cell still counts as present when ``later`` has an occupied cell within this many
        cells (chessboard distance).
    min_extent_px : int
        Only pieces whose connected cells span at least this many cells (along rows or columns,
        after bridging gaps) count, of established walls and of risen cells: people, chair legs and
        furniture blobs do not. 0 or 1: every cell counts.
    bridge_px : int
        Gaps of up to this many cells along a piece are bridged before measuring its extent (walls
        of log-odds maps are broken into pieces where few beams hit them).
    tile_px : int
        Side of the tiles contradicted cells are counted in, cells: a wall erased along its length
        touches many tiles.
    window_px : int
        Side of the square window the score counts tiles in, cells.
    occupied_threshold : int
        Occupancy (percent) from which a cell is a wall.
    free_threshold : int
        Occupancy (percent) up to which a known cell counts as free.
    rise_points : int
        Rise of occupancy (percentage points) from which a free cell's evidence counts as risen;
        101 turns risen evidence off (erased walls only).
    rise_margin_px : int
        Risen cells count only farther than this (chessboard distance) from every cell of
        ``earlier`` that is not known free (wall, unknown, uncertain).
    tile_origin_px : tuple of int
        ``(row, col)`` of a ``later`` cell (inside the grid or not) that the lattice phases are
        tried from (the score is the fewest tiles over the phases; of equal ones, the first from
        there places the region): the map frame's origin, so that the region of grids of one map
        stays where it was however they grew.
    established_px : int, optional
        The occupied cells of ``earlier`` (at ``occupied_threshold``) when the caller counted them
        already (a detector compares one trusted grid with several later ones); taken as given.
        Counted when None.
    memo : EarlierGridMemo, optional
        What comparisons before found of ``earlier`` alone (which of its wall cells lie on long
        walls; the cells near one not known free), kept up to date: one memo per earlier grid (a
        memo of another grid, placement or parameters starts over), so that a detector's
        comparisons of one trusted grid measure each of its walls once.

    Returns
    -------
    WallContradiction

    Raises
    ------
    RoseError
        On grids that are not 2-D, an offset that is not two integers, a non-positive window, a
        tile outside 1..``MAX_KERNEL_PX`` or a tolerance, bridge or margin outside 0..``MAX_KERNEL_PX``.
    """
    earlier, later = _check(
        earlier,
        later,
        offset_px,
        tolerance_px,
        min_extent_px,
        bridge_px,
        rise_points,
        rise_margin_px,
        occupied_threshold=occupied_threshold,
        free_threshold=free_threshold,
    )
    # A tile is a block of cells allocated whole (10**6 cells asked for 931 GiB); the window only
    # counts tiles.
    if not integer_number(tile_px) or not 1 <= tile_px <= MAX_KERNEL_PX:
        msg = f"tile_px must be an integer in 1..{MAX_KERNEL_PX}, got {tile_px!r}"
        raise RoseError(msg)
    if not integer_number(window_px) or window_px < 1:
        msg = f"window_px must be an integer >= 1, got {window_px!r}"
        raise RoseError(msg)
    _require_cell(tile_origin_px, "tile_origin_px")
    if established_px is not None and not (integer_number(established_px) and established_px >= 0):
        msg = f"established_px must be an integer >= 0 or None, got {established_px!r}"
        raise RoseError(msg)
    if established_px is None:
        established_px = int(np.count_nonzero(earlier >= occupied_threshold))
    if memo is None:
        placed = _placed(earlier, later, offset_px)
    else:
        memo._use(
            earlier,
            (
                later.shape,
                tuple(offset_px),
                occupied_threshold,
                free_threshold,
                rise_margin_px,
                min_extent_px,
                bridge_px,
            ),
        )
        if memo._placed is None:
            memo._placed = _placed(earlier, later, offset_px)
        placed = memo._placed
    changed = _changed_words(placed, later)
    erased = _erased_cells(
        placed,
        later,
        changed,
        tolerance_px,
        occupied_threshold,
        free_threshold,
        min_extent_px,
        bridge_px,
        memo,
    )
    risen = _risen_cells(
        placed,
        later,
        changed,
        rise_points,
        rise_margin_px,
        free_threshold,
        min_extent_px,
        bridge_px,
        memo,
    )
    erased_px, risen_px = int(erased.rows.size), int(risen.rows.size)
    box = _union_box(erased.box, risen.box)
    if erased_px + risen_px == 0 or box is None:
        return WallContradiction(0, 0, 0, 0, established_px, None, tile_px, window_px)
    # Erased cells were walls earlier and risen ones free: no cell is both.
    contradicted = _Cells(
        np.concatenate([erased.rows, risen.rows]), np.concatenate([erased.cols, risen.cols]), box
    )
    origin = (int(tile_origin_px[0]), int(tile_origin_px[1]))
    side = max(-(-window_px // tile_px), 1)
    peak, total, wr0, wc0 = _fewest_tiles(contradicted, box, tile_px, side, origin)
    # The contradicted cells inside the window, in later-grid cells.
    rows, cols = contradicted.rows, contradicted.cols
    inside = (rows >= wr0) & (rows < wr0 + side * tile_px)
    inside &= (cols >= wc0) & (cols < wc0 + side * tile_px)
    rows, cols = rows[inside], cols[inside]
    region = (int(rows.min()), int(cols.min()), int(rows.max()), int(cols.max()))
    return WallContradiction(
        erased_px, risen_px, total, peak, established_px, region, tile_px, window_px
    )
