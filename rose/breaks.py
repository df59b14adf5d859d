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
contradicted cells lie.

Global W (:mod:`rose.directions`) stays the paper's score of the whole map; on maps that break
mid-session it barely moves, because the intact part of the map dominates the spectrum.

Conventions: ROS grids (row 0 at the map origin, -1 unknown, 0..100); both grids share a resolution
and orientation, ``offset_px`` places the earlier grid in the later one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rose.errors import RoseError
from rose.grid import blocks_any
from rose.labelling import components, label_boxes, labels_wanted
from rose.limits import integer_number, pair_of

__all__ = [
    "MAX_KERNEL_PX",
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
        Tiles of ``tile_px`` x ``tile_px`` cells holding at least one erased or risen cell.
    peak_tiles : int
        The most such tiles in one window of ``window_px`` x ``window_px`` cells: the break score in
        tiles (times ``tile_px`` times the resolution it is a wall length in metres).
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


def _tiles(
    mask: npt.NDArray[np.bool_],
    r0: int,
    c0: int,
    tile_px: int,
    origin: tuple[int, int] = (0, 0),
) -> tuple[npt.NDArray[np.bool_], int, int]:
    """Which tiles of the lattice through the later-grid cell ``origin`` hold a ``True`` cell of
    ``mask`` (placed at ``(r0, c0)``); returns the tile flags and the later-grid cell of tile
    (0, 0)."""
    tr, tc = r0 - (r0 - origin[0]) % tile_px, c0 - (c0 - origin[1]) % tile_px
    h, w = mask.shape[0] + r0 - tr, mask.shape[1] + c0 - tc
    hp, wp = -(-h // tile_px) * tile_px, -(-w // tile_px) * tile_px
    padded = np.zeros((hp, wp), dtype=bool)
    padded[r0 - tr : r0 - tr + mask.shape[0], c0 - tc : c0 - tc + mask.shape[1]] = mask
    return blocks_any(padded, tile_px), tr, tc


def _densest_window(tiles: npt.NDArray[np.bool_], side: int) -> tuple[int, int, int]:
    """Most flagged tiles in a ``side`` x ``side`` window of tiles: ``(count, row, col)`` of its
    first tile (the first such window in row-major order)."""
    side_r, side_c = min(side, tiles.shape[0]), min(side, tiles.shape[1])
    c = np.pad(tiles.astype(np.int32).cumsum(axis=0).cumsum(axis=1), ((1, 0), (1, 0)))
    sums = c[side_r:, side_c:] - c[:-side_r, side_c:] - c[side_r:, :-side_c] + c[:-side_r, :-side_c]
    i, j = np.unravel_index(int(np.argmax(sums)), sums.shape)
    return int(sums[i, j]), int(i), int(j)


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


def _long_walls(
    walls: npt.NDArray[np.bool_], min_extent_px: int, bridge_px: int
) -> npt.NDArray[np.bool_]:
    """Wall cells whose connected wall (gaps up to ``bridge_px`` cells bridged) spans at least
    ``min_extent_px`` cells along rows or columns."""
    import cv2  # OpenCV's morphology and labelling: several times scipy.ndimage's speed here

    joined = np.ascontiguousarray(walls).view(np.uint8)
    if bridge_px > 0:
        # A (b+1)-square kernel anchored like scipy's binary_dilation (at size // 2, reflected).
        size = bridge_px + 1
        anchor = (size - 1 - size // 2, size - 1 - size // 2)
        joined = np.asarray(
            cv2.dilate(joined, np.ones((size, size), np.uint8), anchor=anchor), dtype=np.uint8
        )
    count, labels = components(joined)
    if count <= 1:  # label 0 is the background
        return np.zeros_like(walls)
    # The extent of each (bridged) wall: the longer side of its bounding box, in cells.
    boxes = label_boxes(labels, np.flatnonzero(joined), count)
    keep = np.maximum(boxes[:, 2], boxes[:, 3]) >= min_extent_px
    keep[0] = False
    return labels_wanted(keep, labels, walls)


def _erased_box(
    placed: npt.NDArray[np.int8],
    later: npt.NDArray[np.integer],
    tolerance_px: int,
    occupied_threshold: int,
    free_threshold: int,
    min_extent_px: int = 0,
    bridge_px: int = 0,
) -> tuple[npt.NDArray[np.bool_], int, int]:
    """Erased cells within their bounding box: ``(mask, row0, col0)`` in ``later``'s cells
    (``placed``: the earlier grid in ``later``'s cells, :func:`placed_grid`)."""
    walls = placed >= occupied_threshold
    candidates = walls & (later >= 0) & (later <= free_threshold)
    rows = np.flatnonzero(candidates.any(axis=1))
    if rows.size == 0:
        return np.zeros((0, 0), dtype=bool), 0, 0
    cols = np.flatnonzero(candidates.any(axis=0))
    # Only candidates can be erased: work in their bounding box plus the tolerance (and plus the
    # wall extent when walls must be long, so that the walls through the box are seen whole).
    margin = max(tolerance_px, min_extent_px + bridge_px)
    r0, r1 = max(int(rows[0]) - margin, 0), int(rows[-1]) + margin + 1
    c0, c1 = max(int(cols[0]) - margin, 0), int(cols[-1]) + margin + 1
    near_wall = _dilate_square((later[r0:r1, c0:c1] >= occupied_threshold), tolerance_px)
    erased = candidates[r0:r1, c0:c1] & ~near_wall
    if min_extent_px > 1 and erased.any():
        erased &= _long_walls(walls[r0:r1, c0:c1], min_extent_px, bridge_px)
    return erased, r0, c0


def _placed(
    earlier: npt.NDArray[np.integer], later: npt.NDArray[np.integer], offset_px: tuple[int, int]
) -> npt.NDArray[np.int8]:
    return placed_grid(earlier.astype(np.int8, copy=False), later.shape, offset_px)


def _risen_box(
    placed: npt.NDArray[np.int8],
    later: npt.NDArray[np.integer],
    rise_points: int,
    rise_margin_px: int,
    free_threshold: int,
    min_extent_px: int,
    bridge_px: int,
) -> tuple[npt.NDArray[np.bool_], int, int]:
    """Risen cells within their bounding box: ``(mask, row0, col0)`` in ``later``'s cells
    (``placed``: the earlier grid in ``later``'s cells, :func:`placed_grid`)."""
    if rise_points > 100:  # off
        return np.zeros((0, 0), dtype=bool), 0, 0
    was_free = (placed >= 0) & (placed <= free_threshold)
    # Only known later cells (0..100) rise: unknown (-1) never, nor values outside the ROS range.
    # On those and the free earlier cells the difference lies in -50..100: int8 holds it (elsewhere
    # it may wrap, and is masked out).
    later8 = later.astype(np.int8, copy=False)
    candidates = (later8 - placed) >= rise_points
    candidates &= was_free
    candidates &= later >= 0  # on the given values: a cast to int8 could wrap them into range
    candidates &= later <= 100
    rows = np.flatnonzero(candidates.any(axis=1))
    if rows.size == 0:
        return np.zeros((0, 0), dtype=bool), 0, 0
    cols = np.flatnonzero(candidates.any(axis=0))
    margin = max(rise_margin_px, min_extent_px + bridge_px)
    r0, r1 = max(int(rows[0]) - margin, 0), int(rows[-1]) + margin + 1
    c0, c1 = max(int(cols[0]) - margin, 0), int(cols[-1]) + margin + 1
    # Deep in free space: no earlier cell that is not known free (wall, unknown, uncertain; nor the
    # grid's edge) within the margin, so that walls seen a cell off and the frontier of exploration
    # do not count. The box reaches `margin` beyond every candidate unless the grid ends first, so
    # only the grid's own edge is within the reach of `outside`.
    near_other = _dilate_square(~was_free[r0:r1, c0:c1], rise_margin_px, outside=True)
    risen = candidates[r0:r1, c0:c1] & ~near_other
    if min_extent_px > 1 and risen.any():
        # Pieces are made of risen cells only (gaps bridged): their box, a bridge wider, is enough
        # and often far smaller than the candidates' (scattered single cells everywhere).
        rows, cols = np.flatnonzero(risen.any(axis=1)), np.flatnonzero(risen.any(axis=0))
        pad = bridge_px + 1
        a0, a1 = max(int(rows[0]) - pad, 0), int(rows[-1]) + pad + 1
        b0, b1 = max(int(cols[0]) - pad, 0), int(cols[-1]) + pad + 1
        pieces = np.zeros_like(risen)
        pieces[a0:a1, b0:b1] = _long_walls(risen[a0:a1, b0:b1], min_extent_px, bridge_px)
        risen = pieces
    return risen, r0, c0


def _union(
    *boxes: tuple[npt.NDArray[np.bool_], int, int],
) -> tuple[npt.NDArray[np.bool_], int, int]:
    """Masks placed at ``(row0, col0)`` as one mask over their common bounding box."""
    present = [(m, r, c) for m, r, c in boxes if m.size]
    if not present:
        return np.zeros((0, 0), dtype=bool), 0, 0
    r0 = min(r for _, r, _ in present)
    c0 = min(c for _, _, c in present)
    r1 = max(r + m.shape[0] for m, r, _ in present)
    c1 = max(c + m.shape[1] for m, _, c in present)
    out = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    for m, r, c in present:
        out[r - r0 : r - r0 + m.shape[0], c - c0 : c - c0 + m.shape[1]] |= m
    return out, r0, c0


def _full(
    later: npt.NDArray[np.integer], box: tuple[npt.NDArray[np.bool_], int, int]
) -> npt.NDArray[np.bool_]:
    mask, r0, c0 = box
    out = np.zeros(later.shape, dtype=bool)
    out[r0 : r0 + mask.shape[0], c0 : c0 + mask.shape[1]] = mask
    return out


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
    box = _risen_box(
        _placed(earlier, later, offset_px),
        later,
        rise_points,
        rise_margin_px,
        free_threshold,
        min_extent_px,
        bridge_px,
    )
    return _full(later, box)


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
    box = _erased_box(
        _placed(earlier, later, offset_px),
        later,
        tolerance_px,
        occupied_threshold,
        free_threshold,
        min_extent_px,
        bridge_px,
    )
    return _full(later, box)


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
        ``(row, col)`` of a ``later`` cell that is a tile's first (any cell of the lattice, inside
        the grid or not): the map frame's origin keeps the tiles, so the score and region, of grids
        of one map alike however they grew.

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
    established = int(np.count_nonzero(earlier >= occupied_threshold))
    placed = _placed(earlier, later, offset_px)
    erased = _erased_box(
        placed,
        later,
        tolerance_px,
        occupied_threshold,
        free_threshold,
        min_extent_px,
        bridge_px,
    )
    risen = _risen_box(
        placed,
        later,
        rise_points,
        rise_margin_px,
        free_threshold,
        min_extent_px,
        bridge_px,
    )
    erased_px, risen_px = int(np.count_nonzero(erased[0])), int(np.count_nonzero(risen[0]))
    if erased_px + risen_px == 0:
        return WallContradiction(0, 0, 0, 0, established, None, tile_px, window_px)
    contradicted, r0, c0 = _union(erased, risen)
    origin = (int(tile_origin_px[0]), int(tile_origin_px[1]))
    tiles, tr, tc = _tiles(contradicted, r0, c0, tile_px, origin)
    side = max(-(-window_px // tile_px), 1)
    peak, wi, wj = _densest_window(tiles, side)
    # The contradicted cells inside the window, in later-grid cells.
    wr0, wc0 = tr + wi * tile_px, tc + wj * tile_px
    br0, bc0 = max(wr0 - r0, 0), max(wc0 - c0, 0)
    br1, bc1 = wr0 + side * tile_px - r0, wc0 + side * tile_px - c0
    inside = contradicted[br0:br1, bc0:bc1]
    rr = np.flatnonzero(inside.any(axis=1))
    cc = np.flatnonzero(inside.any(axis=0))
    region = (
        r0 + br0 + int(rr[0]),
        c0 + bc0 + int(cc[0]),
        r0 + br0 + int(rr[-1]),
        c0 + bc0 + int(cc[-1]),
    )
    return WallContradiction(
        erased_px, risen_px, int(tiles.sum()), peak, established, region, tile_px, window_px
    )
