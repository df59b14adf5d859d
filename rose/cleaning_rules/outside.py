"""The building's edge: occupied cells next to wide unknown space (walls separate known from unknown).

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from rose.cleaning_rules.masks import _dilate, _grown_through, _padded_box, length_px
from rose.grid import UNKNOWN

if TYPE_CHECKING:
    from rose.cleaning import CleanParams
    from rose.cleaning_rules.objects import _Pieces


def _near_wide_unknown(
    unknown: npt.NDArray[np.bool_],
    res: float,
    p: CleanParams,
    blocked: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.bool_]:
    """Cells within ``p.unknown_margin_m`` of wide unknown space (:func:`wide_unknown`): exact at
    the known cells, the only ones read (the occupied cells among them). With ``blocked``, only
    those reached from it without crossing a blocked cell (:func:`_wide_and_near`)."""
    return _wide_and_near(unknown, res, p, blocked)[1]


def _wide_and_near(
    unknown: npt.NDArray[np.bool_],
    res: float,
    p: CleanParams,
    blocked: npt.NDArray[np.bool_] | None = None,
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """The wide unknown space (the outside: :func:`wide_unknown` of ``p.open_unknown_width_m``)
    and :func:`_near_wide_unknown`, from one opening of the unknown cells.

    ``blocked`` cells (the wall lines drawn so far) are not crossed on the way from the outside:
    a cell with a drawn line between it and the outside is not at the building's edge. (Blocking
    the sealing lines or the mapped floor too opened rooms of real maps whose edge walls stand
    among scattered ray returns: docs/cleaning.md, 2026-12-07.)"""
    outside = _wide(unknown, length_px(p.open_unknown_width_m, 2 * res))
    radius = round(length_px(p.unknown_margin_m, res))
    known = ~unknown
    if not known.any():
        return outside, outside
    # Dilated on the known cells' box only (``radius`` wider): the grid is padded with unknown
    # cells as wide as the wide-unknown disc, and at 1 mm per cell the margin's 301-cell disc over
    # the padded grid took 2.6 s for a 100 x 100 map.
    near = outside.copy()
    box = _padded_box(known, radius)
    near[box] = _dilate(outside[box], radius)
    if blocked is not None and radius > 0 and blocked[box].any():
        # Reached in steps to the four neighbours (a diagonal line stops them), as many as the
        # disc's steps at most: a cabinet's side against an unseen wall whose line is drawn stood
        # within the margin of the outside beyond that line, and was kept as the building's edge.
        passable = np.logical_not(blocked[box])
        reached = _grown_through(outside[box], passable, 2 * radius, connectivity=4)
        near[box] &= reached.view(bool) | outside[box]
    return outside, near


def wide_unknown(occupancy: npt.NDArray[np.int8], *, radius_px: float) -> npt.NDArray[np.bool_]:
    """Unknown cells covered by a disc of ``radius_px`` that lies wholly in unknown space.

    The morphological opening of the unknown cells by a disc: the outside of a building and unexplored
    rooms stay, the narrow shadows behind furniture and the insides of scanned objects go.

    Parameters
    ----------
    occupancy : ndarray of int8, shape (rows, cols)
        ROS grid.
    radius_px : float
        Disc radius, cells.
    """
    return _wide(occupancy == UNKNOWN, radius_px)


def _wide(unknown: npt.NDArray[np.bool_], radius_px: float) -> npt.NDArray[np.bool_]:
    """:func:`wide_unknown` of the ``unknown`` cells: the union of the openings on the four grids of
    2 x 2 blocks (:func:`_wide_on_blocks`), which does not depend on where the cells start: the
    opening of the cells by the blocks' disc scaled to cells."""
    if not unknown.any():
        return unknown.copy()
    # One grid of blocks loses up to a block of the wide space where an edge cuts its blocks, and
    # which edges it cuts depended on where the map's known cells start: a wall at 45 degrees on
    # the explored edge lay within the wall margin of it or not by that (docs/cleaning.md,
    # 2026-12-07). Each grid's blocks fit where another's stop short.
    radius = radius_px / 2
    disc = _chamfer_disc(radius) if radius < _MORPHOLOGY_MAX_RADIUS else None
    if disc is not None and 0 < int(np.count_nonzero(disc)) <= _MORPHOLOGY_MAX_CELLS:
        return _wide_on_all_blocks(unknown, disc)
    wide = _wide_on_blocks(unknown, radius_px, shift=(0, 0))
    for shift in ((0, 1), (1, 0), (1, 1)):
        wide |= _wide_on_blocks(unknown, radius_px, shift=shift)
    return wide


def _wide_on_blocks(
    unknown: npt.NDArray[np.bool_], radius_px: float, *, shift: tuple[int, int]
) -> npt.NDArray[np.bool_]:
    """The opening of the ``unknown`` cells by a disc of ``radius_px``, worked out on 2 x 2 blocks
    whose grid starts ``shift`` (rows, columns: 0 or 1 each) cells before the first row and
    column, unknown there as beyond every edge. Close to the cells' own opening by the disc, not
    equal: the blocks' disc, scaled to cells, is even-sided, and a region about as deep as the
    disc can fit it where it does not fit the cells' disc."""
    import cv2

    # A block is unknown when all its cells are: a quarter of the work. An odd last row or column
    # is repeated (a block of it alone). Rows are paired first, then the byte pairs of every paired
    # row are read as one uint16: a tenth of the cost of four strided slices.
    rows, cols = unknown.shape
    down, right = shift
    body = unknown[down:]
    half = body.shape[0] // 2
    width = cols + right
    pairs = np.empty((down + half + body.shape[0] % 2, width + width % 2), dtype=bool)
    pairs[:, :right] = True
    if down:
        pairs[0, right:width] = unknown[0]  # paired with the unknown row before the grid
    np.logical_and(
        body[0 : 2 * half : 2], body[1 : 2 * half : 2], out=pairs[down : down + half, right:width]
    )
    if body.shape[0] % 2:
        pairs[-1, right:width] = body[-1]
    if width % 2:
        pairs[:, width] = pairs[:, width - 1]
    blocks = pairs.view(np.uint16) == 0x0101
    radius = radius_px / 2
    disc = _chamfer_disc(radius) if radius < _MORPHOLOGY_MAX_RADIUS else None
    if disc is not None and 0 < int(np.count_nonzero(disc)) <= _MORPHOLOGY_MAX_CELLS:
        # The same as the distance transforms below, a third of their cost: the core blocks have no
        # known block within the disc (beyond the image: unknown, OpenCV's erosion border as the
        # transform's), the near ones a core block.
        core_u8 = cv2.erode(blocks.view(np.uint8), disc)
        if not core_u8.any():
            return np.zeros(unknown.shape, dtype=bool)
        near = cv2.dilate(core_u8, disc)
    else:
        depth = cv2.distanceTransform(blocks.view(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
        core = depth > radius
        if not core.any():
            return np.zeros(unknown.shape, dtype=bool)
        reach = cv2.distanceTransform((~core).view(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
        near = (reach <= radius).view(np.uint8)
    # Back to cells: every block value twice along the row (a uint16 of two equal bytes), then every
    # row twice (ten times cheaper than OpenCV's nearest-neighbour resize).
    wide = np.repeat((near.astype(np.uint16) * np.uint16(0x0101)).view(np.uint8), 2, axis=0)
    return wide[down : down + rows, right : right + cols].view(bool) & unknown


def _wide_on_all_blocks(
    unknown: npt.NDArray[np.bool_], disc: npt.NDArray[np.uint8]
) -> npt.NDArray[np.bool_]:
    """The union of :func:`_wide_on_blocks` over its four grids of blocks (erosion and dilation
    by ``disc``), at once: the same cells, at about half the cost.

    The 2 x 2 blocks starting at every cell of the ``unknown`` cells framed by a row and a column
    of unknown cells on each side (those before the grid are the shifted grids' unknown row and
    column, those after it make a last block of an odd row or column alone) hold the four grids
    of blocks as their four classes of (row, column) parity. ``disc`` spread to every other cell
    across and along reads only cells of a block's own class, so one erosion and one dilation by
    it are the four grids' (OpenCV's borders as theirs: unknown beyond the image for the erosion,
    nothing for the dilation). A cell lies in the block starting at it, or a row, a column, or
    both before it, in one grid each."""
    import cv2

    framed = cv2.copyMakeBorder(unknown.view(np.uint8), 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=1)
    blocks = np.logical_and(framed[:-1].view(bool), framed[1:].view(bool))
    blocks = np.logical_and(blocks[:, :-1], blocks[:, 1:])  # (rows + 1, cols + 1), from -1
    side = disc.shape[0]
    spread = np.zeros((2 * side - 1, 2 * side - 1), np.uint8)
    spread[::2, ::2] = disc
    core = cv2.erode(blocks.view(np.uint8), spread)
    if not core.any():
        return np.zeros(unknown.shape, dtype=bool)
    near = np.asarray(cv2.dilate(core, spread), dtype=np.uint8).view(bool)
    wide = np.logical_or(near[:-1], near[1:])
    wide = np.logical_or(wide[:, :-1], wide[:, 1:])
    return np.logical_and(wide, unknown, out=wide)


#: Most cells of the disc (:func:`_chamfer_disc`) that :func:`_wide` erodes and dilates by rather
#: than running two distance transforms: the morphology's cost grows with the kernel's cells, the
#: transforms' does not. Measured on the cleaning's block images: 0.44 against 1.5 ms at a radius of
#: 5 blocks (81 cells, the design resolution's), 1.05 against 1.54 at 8 (205 cells), slower at 10.
_MORPHOLOGY_MAX_CELLS = 200

#: Radius (blocks) from which the disc has more cells than that anyway (205 at 8): not built, a
#: transform over its square for nothing (a 1,000-cell radius is allowed).
_MORPHOLOGY_MAX_RADIUS = 9


@functools.lru_cache(maxsize=8, typed=True)
def _chamfer_disc(radius: float) -> npt.NDArray[np.uint8]:
    """The offsets within ``radius`` (cells) of a cell by the distance OpenCV's 5 x 5 mask distance
    transform measures, as a morphology kernel: uint8 0/1, a square of odd side centred on the cell,
    reflected (OpenCV's morphology reads its kernel as offsets from the anchor, a distance counts
    from the zero cell). Read-only (cached).

    The transform is exact for its mask: the least sum of its steps (all those of one cell to
    another lie in their bounding box, whatever the image's edges), the same for every cell. So a
    cell is within ``radius`` of the zero cells exactly where this disc dilated from them reaches,
    and further from all of them exactly where their complement's erosion by it keeps it.

    Cached by ``radius`` and its type: a Python float is compared with the float32 distances in
    float32, a NumPy float64 in float64 (as the transforms' own thresholds are), which can differ
    within about 1e-7 of a distance."""
    import cv2

    # A step of the mask is at least its chessboard length: the disc fits in ``radius`` cells.
    half = max(0, math.floor(radius))
    side = 2 * half + 1
    image = np.ones((side + 4, side + 4), np.uint8)
    image[half + 2, half + 2] = 0
    distance = cv2.distanceTransform(image, cv2.DIST_L2, cv2.DIST_MASK_5)[2:-2, 2:-2]
    disc = np.ascontiguousarray((distance <= radius)[::-1, ::-1]).view(np.uint8)
    disc.flags.writeable = False
    return disc


def unexplored_outside(unknown: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """Unknown cells joined to the grid's edge by unknown space at least three cells wide (the
    space beyond the explored part of the map), and the unknown cells next to them: not a shadow
    enclosed by what was seen, nor one that unseen specks in free space (single missed cells
    between rays) join to the outside."""
    import cv2

    from rose.labelling import fill_from_corner

    kernel = np.ones((3, 3), np.uint8)
    # A frame of unknown around the grid joins every unknown cell on the edge (three cells wide,
    # so the opening keeps it); the flood from the frame's corner clears what it reaches.
    framed = cv2.copyMakeBorder(unknown.view(np.uint8), 3, 3, 3, 3, cv2.BORDER_CONSTANT, value=1)
    wide = np.asarray(cv2.morphologyEx(framed, cv2.MORPH_OPEN, kernel), dtype=np.uint8)
    reached = wide.copy()
    fill_from_corner(reached, 4)
    outside = np.greater(wide, reached)
    return (cv2.dilate(outside.view(np.uint8), kernel).view(bool) & framed.view(bool))[3:-3, 3:-3]


def _unseen_pockets(
    pockets: npt.NDArray[np.bool_], seeds: npt.NDArray[np.uint8], free: npt.NDArray[np.bool_]
) -> npt.NDArray[np.bool_]:
    """The components (4-connected) of ``pockets`` that hold a cell of ``seeds`` (uint8 0 / 1)
    and no cell next to (4-connected) a ``free`` cell. A new array; ``pockets`` is overwritten.
    Masks of shape ``(rows, cols)``.

    Each pocket is flooded from its first seed (OpenCV's flood fill, on its cells only): the
    seeds are a few cells, the pockets thousands."""
    import cv2

    from rose.cleaning_rules.masks import _nonzero_flat
    from rose.labelling import FLOOD_FILL_MAX_SIDE, components

    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    if max(pockets.shape) > FLOOD_FILL_MAX_SIDE:
        # (too large for the flood fill: every pocket labelled)
        count, labels = components(pockets, connectivity=4)
        wanted = np.zeros(count, dtype=bool)
        wanted[labels[seeds.view(bool)]] = True
        wanted[labels[cv2.dilate(free.view(np.uint8), cross).view(bool) & pockets]] = False
        wanted[0] = False
        return wanted[labels]
    out = np.zeros(pockets.shape, dtype=bool)
    image = np.ascontiguousarray(pockets).view(np.uint8)
    rows, cols = image.shape
    for seed in _nonzero_flat(seeds).tolist():
        row, col = divmod(seed, cols)
        if image[row, col] != 1:  # (flooded from an earlier seed)
            continue
        _, _, _, (x, y, width, height) = cv2.floodFill(image, None, (col, row), 2, flags=4)
        # The free cells next to the pocket: dilated on its box a cell wider (clipped by the
        # image, as the dilation of the whole image is).
        r0, c0 = max(y - 1, 0), max(x - 1, 0)
        r1, c1 = min(y + height + 1, rows), min(x + width + 1, cols)
        beside = cv2.dilate(np.ascontiguousarray(free[r0:r1, c0:c1]).view(np.uint8), cross)
        at = (slice(y, y + height), slice(x, x + width))
        flooded = image[at] == 2
        image[at][flooded] = 3
        if not beside[y - r0 : y - r0 + height, x - c0 : x - c0 + width].view(bool)[flooded].any():
            out[at] |= flooded
    return out


def _side_by_side(
    cells: npt.NDArray[np.int64], shape: tuple[int, int], pad: int, gap: int
) -> tuple[list[tuple[tuple[slice, slice], tuple[slice, slice], npt.NDArray[np.int64]]], int]:
    """The cells at the flat indices ``cells`` (at least one, of a mask of ``shape``) in groups,
    each with its box (the group's bounding box ``pad`` cells wider, clipped to the mask), where
    that box lies in an image of the boxes side by side, ``gap`` columns apart and top-aligned,
    and the group's cells; and the width of that image. One group, its box the image, when the
    boxes side by side would not be smaller than all the cells' box.

    Groups: the cells in 8-connected blocks of ``pad`` x ``pad`` cells holding one."""
    from rose.cleaning_rules.masks import _cells_box
    from rose.labelling import components

    rows, cols = np.divmod(cells, shape[1])
    whole = _cells_box(rows, cols, shape, pad)
    width = whole[1].stop - whole[1].start
    one = [(whole, (slice(0, whole[0].stop - whole[0].start), slice(0, width)), cells)]
    side = max(pad, 1)
    blocks = np.zeros((shape[0] // side + 1, shape[1] // side + 1), dtype=np.uint8)
    blocks[rows // side, cols // side] = 1
    count, labels = components(blocks)
    if count <= 2:
        return one, width
    group = labels[rows // side, cols // side]
    order = np.argsort(group, kind="stable")
    starts = np.flatnonzero(np.r_[True, group[order][1:] != group[order][:-1]])
    row, col = rows[order], cols[order]
    # (Each group's bounding box, ``pad`` wider and clipped, as _cells_box makes it.)
    top = np.maximum(np.minimum.reduceat(row, starts) - pad, 0).tolist()
    bottom = np.minimum(np.maximum.reduceat(row, starts) + 1 + pad, shape[0]).tolist()
    first = np.maximum(np.minimum.reduceat(col, starts) - pad, 0).tolist()
    last = np.minimum(np.maximum.reduceat(col, starts) + 1 + pad, shape[1]).tolist()
    members = np.split(cells[order], starts[1:])
    boxes = []
    left = 0
    for index in range(starts.size):
        box_cols = last[index] - first[index]
        boxes.append(
            (
                (slice(top[index], bottom[index]), slice(first[index], last[index])),
                (slice(0, bottom[index] - top[index]), slice(left, left + box_cols)),
                members[index],
            )
        )
        left += box_cols + gap
    height = max(b - t for b, t in zip(bottom, top, strict=True))
    if height * (left - gap) >= (whole[0].stop - whole[0].start) * width:
        return one, width
    return boxes, left - gap


def _backing_outside(
    occupied: npt.NDArray[np.bool_],
    unknown: npt.NDArray[np.bool_],
    drawn: npt.NDArray[np.bool_],
    pieces: _Pieces,
    free: npt.NDArray[np.bool_],
    kept: npt.NDArray[np.bool_],
    pockets: npt.NDArray[np.bool_],
    *,
    depth_px: int,
    min_extent_px: float,
    line_reach_px: int,
    radius_px: float,
    edge_reach_px: int,
) -> npt.NDArray[np.bool_]:
    """Occupied cells not ``kept`` so far that have the unexplored outside right behind them: a
    wall whose removal would open the room onto it. A new array, shape ``(rows, cols)``.

    The outside: the ``unknown`` cells joined to the grid's edge through unknown space at least
    three cells wide that crosses no ``drawn`` cell (the hidden wall lines the cleaning draws),
    and the unknown cells next to them (every step 4-connected: a diagonal line closes as a
    straight one does). The cells: those next to it and within ``depth_px - 1`` steps
    (8-connected) of these through occupied cells next to no cell of an object's inside (a
    component of ``pockets`` off the outside that no ``free`` cell touches); in pieces of
    ``pieces`` (8-connected) whose box has a diagonal of ``min_extent_px`` or more (the
    building's walls, not an object); farther than ``line_reach_px`` (chessboard) from a
    ``drawn`` cell (furniture whose wall line was drawn); and farther than ``edge_reach_px``
    steps through the unknown cells off ``drawn`` from a ``free`` cell that a disc of
    ``radius_px`` centred there keeps off every occupied cell (where the room meets the outside
    already at a robot's scale: the explored edge).
    """
    import cv2

    from rose.cleaning_rules.masks import _near, _nonzero_flat
    from rose.labelling import fill_from_corner

    # The cells it could keep first (a few), filtered before the passes over the window.
    backed = np.greater(occupied, kept)
    cells = _nonzero_flat(backed.view(np.uint8))
    short = pieces.diagonals[pieces.labels.reshape(-1)[cells]] < min_extent_px
    backed.reshape(-1)[cells[short]] = False
    if drawn.any() and backed.any():
        np.greater(backed, _near(backed, drawn, line_reach_px), out=backed)
    if not backed.any():
        return backed
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    behind = np.greater(unknown, drawn).view(np.uint8)
    framed = cv2.copyMakeBorder(behind, 3, 3, 3, 3, cv2.BORDER_CONSTANT, value=1)
    wide = np.asarray(
        cv2.morphologyEx(framed, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)), dtype=np.uint8
    )
    reached = wide.copy()
    fill_from_corner(reached, 4)
    beyond = np.greater(wide, reached)[3:-3, 3:-3]
    ring = cv2.dilate(beyond.view(np.uint8), cross).view(bool) & behind.view(bool)
    touching = cv2.dilate(ring.view(np.uint8), cross).view(bool) & occupied
    if depth_px > 1:
        # Into the wall (its thickness), not through cells next to an object's inside (a
        # pocket off the outside that no free cell touches): a cabinet's sides meet the outer
        # wall.
        inner = np.greater(pockets, ring)
        # Only the pockets' cells within ``depth_px`` of both a backed cell and a touching one
        # can change the cells kept (a path of ``depth_px - 1`` steps from a touching cell to a
        # backed one, and the cross around its cells): a few cells, whose pockets are judged
        # alone (labelling every pocket cost half a millisecond per session map).
        square = np.ones((2 * depth_px + 1, 2 * depth_px + 1), np.uint8)
        relevant = np.asarray(cv2.dilate(backed.view(np.uint8), square), dtype=np.uint8)
        np.bitwise_and(relevant, cv2.dilate(touching.view(np.uint8), square), out=relevant)
        np.bitwise_and(relevant, inner.view(np.uint8), out=relevant)
        inner = _unseen_pockets(inner, relevant, free)
        through = np.greater(occupied, cv2.dilate(inner.view(np.uint8), cross).view(bool))
        through |= touching
        touching = _grown_through(touching, through, depth_px - 1).view(bool)
    backed &= touching
    if not backed.any():
        return backed
    # An object at a wall's end at the explored edge has the outside behind it too, but the room
    # meets that outside nearby: its removal opens nothing new (the freiburg-101 box at 30
    # degrees, 0.85-1.25 m through the unknown from such a place; ECN lab's step 1.8 m).
    # A backed cell's answer depends on the cells within ``pad`` of it only (a free cell at most
    # ``edge_reach_px + 2`` steps away, the occupied cells within the robot's radius of that
    # one): the backed cells, in a few groups along the walls, are looked at on their groups'
    # boxes set side by side (a fifth of their common box on the session maps).
    pad = edge_reach_px + math.ceil(radius_px) + 2
    cells = _nonzero_flat(backed.view(np.uint8))
    gap = math.ceil(radius_px) + 2  # (no dilation below reaches a neighbour's box across it)
    boxes, canvas_cols = _side_by_side(cells, backed.shape, pad, gap)
    if len(boxes) == 1:
        box, _, _ = boxes[0]
        free_c, occupied_c, room_side = free[box], occupied[box], behind[box]
    else:
        height = max(box[0].stop - box[0].start for box, _, _ in boxes)
        free_c = np.zeros((height, canvas_cols), dtype=bool)
        occupied_c = np.zeros((height, canvas_cols), dtype=bool)
        room_side = np.zeros((height, canvas_cols), dtype=np.uint8)
        for box, at, _ in boxes:
            free_c[at] = free[box]
            occupied_c[at] = occupied[box]
            room_side[at] = behind[box]
    open_free = np.greater(free_c, _dilate(occupied_c, math.ceil(radius_px)))
    reached = np.bitwise_and(cv2.dilate(open_free.view(np.uint8), cross), room_side)
    for step in range(edge_reach_px):
        grown = np.bitwise_and(cv2.dilate(reached, cross), room_side)
        # (a look for the end every fourth step: the comparison cost a third of a step)
        if step % 4 == 3 and np.array_equal(grown, reached):
            break
        reached = grown
    at_edge = cv2.dilate(reached, cross).view(bool)
    for box, at, members in boxes:
        row, col = np.divmod(members, backed.shape[1])
        edge = at_edge[row - box[0].start + at[0].start, col - box[1].start + at[1].start]
        backed.reshape(-1)[members[edge]] = False
    return backed
