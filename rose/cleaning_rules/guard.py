"""The topology guard: no robot-sized passage opened between regions the input kept apart.

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from rose.cleaning_rules.masks import (
    _cells_box,
    _neighbour_columns,
    _nonzero_flat,
    _padded_box,
)
from rose.labelling import (
    component_areas,
    components,
    fill_from_corner,
    label_boxes,
    labels_looked_up,
)


def passable(obstacles: npt.NDArray[np.bool_], radius_px: float) -> npt.NDArray[np.bool_]:
    """Cells farther than ``radius_px`` (centre to centre) from every obstacle cell."""
    if not obstacles.any():
        return np.ones(obstacles.shape, dtype=bool)
    return ~_blocked(obstacles, radius_px)


def _blocked(obstacles: npt.NDArray[np.bool_], radius_px: float) -> npt.NDArray[np.bool_]:
    """Cells within ``radius_px`` (centre to centre) of an obstacle cell: not :func:`passable`."""
    return _disc_maximum(obstacles.view(np.uint8), radius_px).view(bool)


def _disc_maximum(image: npt.NDArray[np.uint8], radius_px: float) -> npt.NDArray[np.uint8]:
    """The largest value of ``image`` within ``radius_px`` (centre to centre) of every cell (0
    outside the image)."""
    import cv2

    reach = math.floor(radius_px)
    offsets = np.arange(-reach, reach + 1)
    disc = (offsets[:, None] ** 2 + offsets[None, :] ** 2 <= radius_px**2).astype(np.uint8)
    return np.asarray(cv2.dilate(image, disc), dtype=np.uint8)


def topology_guard(
    occupied: npt.NDArray[np.bool_],
    keep: npt.NDArray[np.bool_],
    *,
    radius_px: float,
    added: npt.NDArray[np.bool_] | None = None,
    hidden: npt.NDArray[np.bool_] | None = None,
    window_px: int,
    min_region_px: float,
    off_grid: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.bool_]:
    """Removed cells to restore so that no robot-sized passage opens between separate regions.

    Removing ``occupied & ~keep`` (and adding the obstacles ``added``) makes some cells passable for
    a disc of ``radius_px``. Each connected patch of them is checked in a window of ``window_px``
    cells around it: if the cells that were passable before (``added`` counting as obstacles before
    too: hidden walls, there but unseen; ``hidden`` counting as obstacles before only: the unseen
    insides of removed furniture, which the cleaned map leaves unknown) and touch the patch belong
    to two or more regions of the
    window that are not small enclosed pockets (a pocket does not reach the window's
    edge and covers less than ``min_region_px``), every removed cell within ``radius_px + 1`` of the
    patch is restored: those are the cells that kept the disc out of it. A pocket counts with the
    patches it touches (one patch with them), so that a passage through it is judged whole. A patch
    longer than four windows is also judged in pieces (cut along a grid of four windows; every
    piece, also one ringed by formerly passable cells alone), and one piece joining two regions
    restores the whole patch's cells (a wall erased along metres between rooms that a door
    in its window joins anyway is a new passage all the same), unless the whole patch stands
    free: ringed by formerly passable cells alone and ringing no hole (furniture removed in a row
    in a room, which a robot went round before).
    Patches surrounded by formerly passable cells (a free-standing object) are skipped without
    labelling; the rest cost one small labelling each. The grid of the cuts starts at the corner
    of the box of the opened cells (padded); the cells that only removed ``off_grid`` obstacles
    open do not move it.

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        Cells of ``occupied & ~keep`` to restore.
    """
    import cv2

    restore = np.zeros(occupied.shape, dtype=bool)
    after = occupied & keep
    if np.count_nonzero(after) == np.count_nonzero(occupied):  # nothing removed
        return restore
    if added is not None:
        after |= added
    # The added obstacles (hidden walls) were there before too, only unseen: regions they close off
    # are told apart as such (the inside of a cabinet against a wall, closed by the wall line behind
    # it, is a pocket, not the unknown outside). What opens is the same either way: the added
    # obstacles block after as well.
    before = occupied if added is None else occupied | added
    if hidden is not None:
        # A removed object's inside closes off what its faces did before, but not after: the
        # cleaned map leaves it unknown, which a planner may cross (a corner cabinet drawn over
        # the walls opened the room to the outside through its inside).
        before = before | hidden
    # Both dilations in one: 1 on the obstacles removed, 2 on those that stay (``after`` is within
    # ``before``). The disc's maximum is 0 where passable before, 2 where blocked after, and 1
    # where only removed cells blocked: passable after, not before.
    blocking = _disc_maximum(np.add(before.view(np.uint8), after.view(np.uint8)), radius_px)
    opened = blocking == 1
    if not opened.any():
        return restore
    # Everything the guard looks at lies within a window (plus the restoring reach) of an opened
    # patch: work on their bounding box (windows clipped by it are clipped as by the map).
    reach = math.ceil(radius_px) + 1
    box = _padded_box(opened, window_px + reach + 2)
    # Formerly passable cells (``blocking`` 0) are looked up where needed (the ring cells and the
    # windows), not over the whole box.
    blocking, opened = blocking[box], np.ascontiguousarray(opened[box])
    opened_cells = _nonzero_flat(opened.view(np.uint8))
    # A pocket links the patches around it: a removed object's unseen inside, opened on one side
    # to the room and on another to the outside, is a passage (a corner cabinet drawn over both
    # walls), though no patch alone touches two regions.
    linked = _linked_through_pockets(blocking, opened, min_region_px)
    count, patches = components(linked)
    linked_cells = _nonzero_flat(linked.view(np.uint8))
    boxes = label_boxes(patches, linked_cells, count)
    on_patch = patches.reshape(-1)[opened_cells]
    # The rings of the patches and of their pieces below: the same cells (cut, the patches keep
    # their cells), listed once.
    ring = _ring_cells(linked)
    rings = _rings(patches, ring, count)
    seeds = _separating_cells(
        patches, count, boxes, rings, on_patch, blocking, window_px, min_region_px
    )
    # A long opening is also judged in pieces: judged whole, its window spanned rooms that a door
    # somewhere in it joined anyway, and a wall erased along metres between a corridor and a room
    # passed as no new passage. Every piece is judged (a piece in the middle of an erased wall has
    # only the two rooms around it, which reads as a free-standing object), and one that joins two
    # regions brings its whole opening back (restored in part, the rest of the wall stayed open).
    # Not the pieces of a free-standing opening, though (furniture and scan clutter removed
    # together in a room, met by nothing that stays): the cells around it were passable before
    # and join along it, so a robot went round it before; a piece's window, cut across by the rest
    # of the opening, saw two regions (a row of boxes among scan speckle came back whole). Unless
    # it rings a hole: what it encloses was kept apart from the room around.
    # Where the cuts fall decides, for a patch cut near an object's end, whether a piece's window
    # sees round the object (on the ray-cast benchmark the clutter removed moves by 0.01-0.03 with
    # the grid): obstacles a rule adds far away (the returns at the explored edge) must not move it.
    grid_corner = (box[0].start, box[1].start)
    if off_grid is not None and off_grid.any():
        # Those cells are opened cells too, whose discs lie in the working box: dilated there,
        # not over the whole map (cells off ``opened``, at the box's edge, miss what lies beyond).
        opened_on_grid = opened & (
            _disc_maximum(
                np.add(
                    np.greater(before[box], off_grid[box]).view(np.uint8),
                    after[box].view(np.uint8),
                ),
                radius_px,
            )
            == 1
        )
        if opened_on_grid.any():
            on_grid_box = _padded_box(opened_on_grid, window_px + reach + 2)
            grid_corner = (box[0].start + on_grid_box[0].start, box[1].start + on_grid_box[1].start)
    cut_count, cut = _cut_long_patches(
        patches,
        boxes,
        linked_cells,
        4 * window_px,
        shift=(box[0].start - grid_corner[0], box[1].start - grid_corner[1]),
    )
    if cut_count != count:
        on_piece = cut.reshape(-1)[opened_cells]
        parent = np.zeros(cut_count, dtype=np.int64)
        parent[on_piece] = on_patch
        judged = _in_pieces(patches, linked, boxes, blocking, np.unique(parent[count:]))
        # Only the pieces are judged, and their rings are within those of the patches cut: the
        # ring cells beside a long patch are looked at again, not all of them.
        long = np.maximum(boxes[:, 2], boxes[:, 3]) > 4 * window_px
        long[0] = False
        pieces = _separating_cells(
            cut,
            cut_count,
            label_boxes(cut, linked_cells, cut_count),
            _rings(cut, np.unique(rings[0][long[rings[1]]]), cut_count),
            on_piece,
            blocking,
            window_px,
            min_region_px,
            only=(np.arange(cut_count) >= count) & judged[parent],  # (the rest: judged above)
        )
        joined = np.zeros(count, dtype=bool)
        joined[on_patch[pieces]] = True
        seeds |= joined[on_patch]
    if not seeds.any():
        return restore
    # The removed cells within reach of a separating patch (dilated on the patches' box only): the
    # ones that kept the disc out of it. Whole removed pieces would also bring back furniture that
    # merely touches a wall hole, diagonally, as rasterised walls at an angle often do.
    reach_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1, 2 * reach + 1))
    near, zone = _drawn_box(opened_cells[seeds], opened.shape, reach)
    zone = cv2.dilate(zone, reach_kernel).view(bool)
    removal = np.greater(occupied[box][near], keep[box][near])  # occupied & ~keep in one pass
    restore[box][near] = zone & removal
    return restore


def _linked_through_pockets(
    blocking: npt.NDArray[np.uint8], opened: npt.NDArray[np.bool_], min_region_px: float
) -> npt.NDArray[np.bool_]:
    """``opened`` with the pockets: the regions of cells passable before (``blocking`` 0) smaller
    than ``min_region_px`` that do not reach the image's edge (beyond it they may go on)."""
    count, regions = components(blocking == 0)
    pocket = component_areas(regions, count) < min_region_px
    pocket[0] = False
    pocket[np.concatenate([regions[0], regions[-1], regions[:, 0], regions[:, -1]])] = False
    if not pocket.any():
        return opened
    return opened | labels_looked_up(pocket, regions)


def _separating_cells(
    patches: npt.NDArray[np.integer],
    count: int,
    boxes: npt.NDArray[np.int64],
    rings: tuple[npt.NDArray[np.intp], npt.NDArray[np.int64]],
    on_patch: npt.NDArray[np.integer],
    blocking: npt.NDArray[np.uint8],
    window_px: int,
    min_region_px: float,
    *,
    only: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.bool_]:
    """Which opened cells (``on_patch``: the patch of each) lie in a patch that joins two regions of
    its window (:func:`_separating_patches`); ``rings``: the cells around the patches and their
    patch (:func:`_rings`; with ``only``, those of the patches in it suffice). Patches ringed by
    formerly passable cells alone (a free-standing object) are not looked at; with ``only`` (per
    label), exactly those patches are, however ringed."""
    ring_cells, ring_patches = rings
    formerly = blocking[np.divmod(ring_cells, patches.shape[1])] == 0
    blocked = np.bincount(on_patch, minlength=count) > 0
    if only is None:
        walled = np.zeros(count, dtype=bool)
        walled[ring_patches[~formerly]] = True
        blocked &= walled
    else:
        blocked &= only
    blocked[0] = False
    # No labelling of the ring arcs first to skip the patches whose ring is one arc: the windows'
    # labelling finds one region for them anyway, and labelling the arcs over the whole box cost
    # more than the windows it spared.
    if not blocked.any():
        return np.zeros(on_patch.shape, dtype=bool)
    separating = _separating_patches(
        blocking,
        boxes,
        blocked,
        ring_cells[formerly],
        ring_patches[formerly],
        window_px,
        min_region_px,
    )
    return separating[on_patch]


def _in_pieces(
    patches: npt.NDArray[np.integer],
    linked: npt.NDArray[np.bool_],
    boxes: npt.NDArray[np.int64],
    blocking: npt.NDArray[np.uint8],
    long: npt.NDArray[np.integer],
) -> npt.NDArray[np.bool_]:
    """Per label of ``patches`` (``boxes`` of them, background 0): whether the patch, one of the
    ``long`` ones, is judged in pieces: its ring (the cells off ``linked`` next to it) holds a cell
    that was not passable before (``blocking`` not 0: the opening meets an obstacle that stays),
    or it rings a hole (cells it closes off from the outside of its box, 8-connected as the
    regions are)."""
    import cv2

    judged = np.zeros(len(boxes), dtype=bool)
    rows, cols = patches.shape
    kernel = np.ones((3, 3), np.uint8)
    # The long patches are few: each is looked at in its box, a cell wider (its ring).
    for label in long[long > 0].tolist():
        x, y, width, height = boxes[label].tolist()
        top, left = max(y - 1, 0), max(x - 1, 0)
        bottom, right = min(y + height + 1, rows), min(x + width + 1, cols)
        mine = (patches[top:bottom, left:right] == label).view(np.uint8)
        ring = cv2.dilate(mine, kernel).view(bool) & ~linked[top:bottom, left:right]
        if np.any(blocking[top:bottom, left:right][ring]):
            judged[label] = True
            continue
        # The patch in its box, a cell of margin around: the margin and all that reaches it are
        # outside; any other cell not of the patch lies in a hole.
        inside = np.ones((height + 2, width + 2), dtype=np.uint8)
        inside[1:-1, 1:-1] = patches[y : y + height, x : x + width] != label
        fill_from_corner(inside, 8)  # (OpenCV's flood fill, right on any size)
        judged[label] = bool(inside.any())
    return judged


def _cut_long_patches(
    patches: npt.NDArray[np.integer],
    boxes: npt.NDArray[np.int64],
    cells: npt.NDArray[np.intp],
    tile_px: int,
    *,
    shift: tuple[int, int] = (0, 0),
) -> tuple[int, npt.NDArray[np.integer]]:
    """``patches`` with every patch whose box is longer than ``tile_px`` cut along a grid of
    ``tile_px`` cells from the cell ``-shift`` of ``patches`` (``cells``: the patches' flat
    indices); returns the new count (with the background) and labels. Shorter patches keep their
    labels; the pieces get new ones (the long patches' own labels are left without cells)."""
    long = np.maximum(boxes[:, 2], boxes[:, 3]) > tile_px
    long[0] = False
    if not long.any():
        return len(boxes), patches
    owner = patches.reshape(-1)[cells]
    in_long = long[owner]
    cut_cells = cells[in_long]
    rows, cols = np.divmod(cut_cells, patches.shape[1])
    tile_rows, tile_cols = (rows + shift[0]) // tile_px, (cols + shift[1]) // tile_px
    tile_rows -= tile_rows.min()
    tile_cols -= tile_cols.min()
    tiles = tile_rows * (int(tile_cols.max()) + 1) + tile_cols
    key = owner[in_long].astype(np.int64) * (int(tiles.max()) + 1) + tiles
    piece = _ranks(key)
    cut_count = len(boxes) + int(piece.max()) + 1
    # The labels' own type when the pieces' labels fit in it (16 bits nearly always: a copy, no
    # conversion to 32 bits; the rings read either alike).
    fits = cut_count <= np.iinfo(patches.dtype).max + 1
    out = patches.copy() if fits else patches.astype(np.int32)
    out.reshape(-1)[cut_cells] = len(boxes) + piece.astype(out.dtype)
    return cut_count, out


def _ranks(values: npt.NDArray[np.int64]) -> npt.NDArray[np.intp]:
    """The rank of each of ``values`` (non-negative, at least one) among the distinct ones, from 0
    (``np.unique``'s inverse). When they span not much more than their number (the cut pieces'
    keys: a few thousand, below 20,000), counted in a table of them all instead of sorted: a
    seventh of the cost."""
    span = int(values.max()) + 1
    if span > 4 * values.size + 65536:
        return np.unique(values, return_inverse=True)[1]
    present = np.zeros(span, dtype=bool)
    present[values] = True
    rank = np.cumsum(present, dtype=np.intp)
    rank -= 1
    return rank[values]


def _drawn_box(
    cells: npt.NDArray[np.int64], shape: tuple[int, int], pad: int
) -> tuple[tuple[slice, slice], npt.NDArray[np.uint8]]:
    """The bounding box of ``cells`` (flat indices into ``shape``, ascending, at least one), ``pad``
    cells wider on every side and clipped to ``shape`` (:func:`_cells_box`), and the cells drawn
    with 1 in an uint8 image of that box."""
    rows, cols = np.divmod(cells, shape[1])
    box = _cells_box(rows, cols, shape, pad)
    image = np.zeros((box[0].stop - box[0].start, box[1].stop - box[1].start), dtype=np.uint8)
    image[rows - box[0].start, cols - box[1].start] = 1
    return box, image


def _ring_cells(opened: npt.NDArray[np.bool_]) -> npt.NDArray[np.intp]:
    """Flat indices (ascending) of the cells outside ``opened`` (C-contiguous) with an 8-neighbour
    in it: the rings of its patches, however labelled (:func:`_rings`)."""
    import cv2

    grown = cv2.dilate(opened.view(np.uint8), np.ones((3, 3), np.uint8))
    # grown & ~opened in one pass, listed by OpenCV.
    return _nonzero_flat(np.greater(grown, opened.view(np.uint8)).view(np.uint8))


def _rings(
    patches: npt.NDArray[np.integer], cells: npt.NDArray[np.intp], count: int
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.int64]]:
    """The ring of every patch (``count`` labels, 0 the background): each of the ring ``cells``
    (:func:`_ring_cells` of the patches' cells) with an 8-neighbour in a patch, once per patch it
    touches (a cell between two patches is in both rings).

    Returns
    -------
    cells : ndarray of intp, shape (N,)
        Flat indices into ``patches``.
    labels : ndarray of int64, shape (N,)
        The patch of each entry.
    """
    # The labels of every ring cell's 8 neighbours (ring cells are few next to the whole image).
    around = _neighbour_columns(patches, cells)
    top = around[0].copy()
    for column in around[1:]:
        np.maximum(top, column, out=top)
    # Cells next to two patches are rare: only they need every (cell, patch) pair sorted out. A
    # neighbour's label minus one, unsigned, is the largest value for the background: the least one
    # below ``top - 1`` is another patch's (the labels are 16 or 32 bits).
    unsigned = np.dtype(f"u{patches.dtype.itemsize}")
    least = (around[0] - 1).view(unsigned)
    for column in around[1:]:
        np.minimum(least, (column - 1).view(unsigned), out=least)
    contested = least < (top - 1).view(unsigned)
    patch = top.astype(np.int64)
    if not contested.any():
        return cells, patch
    shared = cells[contested]
    labels = np.stack([column[contested] for column in around], axis=1).astype(np.int64)
    keys = np.sort((shared[:, None] * count + labels)[labels > 0])
    # Unique (numpy's unique costs 3x the sort on these few keys).
    keys = keys[np.concatenate(([True], keys[1:] != keys[:-1]))]
    return (
        np.concatenate([cells[~contested], keys // count]),
        np.concatenate([patch[~contested], keys % count]),
    )


def _separating_patches(
    blocking: npt.NDArray[np.uint8],
    boxes: npt.NDArray[np.int64],
    blocked: npt.NDArray[np.bool_],
    ring_cells: npt.NDArray[np.intp],
    ring_patches: npt.NDArray[np.int64],
    window_px: int,
    min_region_px: float,
) -> npt.NDArray[np.bool_]:
    """Which ``blocked`` patches touch, with their ring (``ring_cells`` of ``ring_patches``, from
    :func:`_rings`), two or more regions of the cells passable before (``blocking`` 0; in a window
    of ``window_px`` cells around the patch) that are not small enclosed pockets (a pocket does not
    reach the window's edge and covers less than ``min_region_px``).

    All windows are copied into one mosaic, one empty cell apart, and labelled in one call.
    """

    count = boxes.shape[0]
    separating = np.zeros(count, dtype=bool)
    rows, cols = blocking.shape
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
    ox, oy, mosaic_shape = _shelves(heights, widths)
    mosaic = np.zeros(mosaic_shape, dtype=bool)
    # (Python ints in the loop: indexing numpy arrays item by item costs several times more.)
    sources = zip(r0.tolist(), c0.tolist(), heights.tolist(), widths.tolist(), strict=True)
    for (y0, x0, h_i, w_i), top_i, left_i in zip(sources, oy.tolist(), ox.tolist(), strict=True):
        window = blocking[y0 : y0 + h_i, x0 : x0 + w_i]
        np.logical_not(window, out=mosaic[top_i : top_i + h_i, left_i : left_i + w_i])
    # Plain labels, the regions on their window's frame and the few areas needed: a fraction of
    # the cost of OpenCV's statistics.
    region_count, regions = components(mosaic)
    on_frame = np.zeros(region_count, dtype=bool)
    on_frame[regions.reshape(-1)[_frame_cells(oy, ox, heights, widths, mosaic.shape[1])]] = True
    on_frame[0] = False
    slot = np.full(count, -1, dtype=np.int64)
    slot[ids] = np.arange(ids.size)
    where = slot[ring_patch]
    keep = where >= 0
    where, cells = where[keep], ring_idx[keep]
    labels = regions[cells // cols - r0[where] + oy[where], cells % cols - c0[where] + ox[where]]
    # Every region lies in one window (they are apart in the mosaic): the regions touched, each
    # counted once for its window, without sorting (window, region) pairs.
    touched = np.zeros(region_count, dtype=bool)
    touched[labels] = True
    touched[0] = False
    window_of = np.zeros(region_count, dtype=np.int64)
    window_of[labels] = where
    open_regions = np.bincount(window_of[touched & on_frame], minlength=ids.size)
    # A touched region off the frame counts when large: only those in windows with fewer than two
    # on the frame and more touched need their area.
    touching = np.bincount(window_of[touched], minlength=ids.size)
    undecided = (open_regions < 2) & (touching >= 2)
    pockets = np.flatnonzero(touched & ~on_frame & undecided[window_of])
    large = _large_regions(
        regions, pockets, region_count, min_region_px, oy, ox, heights, widths, window_of[pockets]
    )
    open_regions += np.bincount(window_of[pockets[large]], minlength=ids.size)
    separating[ids] = open_regions >= 2
    return separating


#: Regions whose area is counted in their window one by one, at most; more take a histogram of
#: the whole mosaic (real maps: about 10 per map, at most 33).
_COUNTED_ONE_BY_ONE = 64


def _large_regions(
    regions: npt.NDArray[np.integer],
    labels: npt.NDArray[np.intp],
    count: int,
    min_area: float,
    top: npt.NDArray[np.int64],
    left: npt.NDArray[np.int64],
    heights: npt.NDArray[np.int64],
    widths: npt.NDArray[np.int64],
    windows: npt.NDArray[np.int64],
) -> npt.NDArray[np.bool_]:
    """Which regions ``labels`` of the mosaic ``regions`` (``count`` labels) cover ``min_area``
    cells or more, each counted in its window (``windows``, placed at ``top, left``, of ``heights,
    widths`` cells), where it lies whole."""
    if labels.size > _COUNTED_ONE_BY_ONE:
        return component_areas(regions, count)[labels] >= min_area
    large = np.zeros(labels.size, dtype=bool)
    for i, (label, w) in enumerate(zip(labels.tolist(), windows.tolist(), strict=True)):
        window = regions[top[w] : top[w] + heights[w], left[w] : left[w] + widths[w]]
        large[i] = np.count_nonzero(window == label) >= min_area
    return large


def _shelves(
    heights: npt.NDArray[np.int64], widths: npt.NDArray[np.int64]
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], tuple[int, int]]:
    """Shelf packing of windows of ``heights, widths`` (cells) into a mosaic about square, one empty
    cell between them: left to right in rows of the mosaic, the tallest first (shelves of windows
    of alike heights, and a partly empty last shelf only as wide as the mosaic is tall: on the
    benchmark maps the mosaics have 43 % fewer cells than 1024 cells wide with the windows in their
    order, and their labelling costs by the cell).

    Returns
    -------
    left, top : ndarray of int64, shape (N,)
        Where each window goes.
    shape : tuple of int
        The mosaic's ``(rows, cols)``.
    """
    area = int(((widths + 1) * (heights + 1)).sum())
    width = max(int(widths.max()) + 1, math.isqrt(area) + 1)
    order = np.argsort(-heights, kind="stable").tolist()
    left, top = [0] * heights.size, [0] * heights.size
    cursor_x = cursor_y = shelf = 0
    # (Python ints in the loop: indexing numpy arrays item by item costs several times more.)
    for i, w_i, h_i in zip(order, widths[order].tolist(), heights[order].tolist(), strict=True):
        if cursor_x + w_i + 1 > width:
            cursor_x, cursor_y, shelf = 0, cursor_y + shelf + 1, 0
        left[i], top[i] = cursor_x, cursor_y
        cursor_x += w_i + 1
        shelf = max(shelf, h_i)
    return (
        np.array(left, dtype=np.int64),
        np.array(top, dtype=np.int64),
        (cursor_y + shelf + 1, width),
    )


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
