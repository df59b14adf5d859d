"""Hidden walls: unknown cells between collinear kept walls, the wall line behind removed furniture.

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from rose.cleaning_rules.frames import FrameNeeds, _frames, in_rotated_frame
from rose.cleaning_rules.masks import _bounds, _neighbour_columns, _nonzero_flat, _padded_box
from rose.cleaning_rules.runs import (
    _close_runs,
    _covered,
    _dense,
    _fragmented,
    _groups,
    _open,
    _open_runs,
    _order_by,
    _run_cells,
    _runs,
)
from rose.labelling import components, label_boxes, labels_looked_up


def bridge_gaps(
    walls: npt.NDArray[np.bool_],
    fillable: npt.NDArray[np.bool_],
    directions: npt.NDArray[np.float64],
    *,
    max_gap_px: float,
    min_anchor_px: float = 1,
) -> npt.NDArray[np.bool_]:
    """Cells of ``fillable`` on the straight line between two wall pieces along a dominant direction.

    A morphological closing with a line of ``max_gap_px`` cells along every direction (in the
    rotated frames of :func:`directional_runs`) joins collinear wall pieces across gaps shorter
    than the line; the pieces are the cells of ``walls`` on straight stretches of at least
    ``min_anchor_px`` cells along that direction. Only ``fillable`` cells are filled.

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        A subset of ``fillable & ~walls``.
    """
    (bridges,) = _bridges(walls, fillable, directions, max_gap_px, (min_anchor_px,))
    return bridges


#: Cells a hidden wall line is thick at most (staggered ends are joined by lines up to three
#: cells thick): what lies within this many cells less one of a cell of it in plain view of the
#: room, along the line's cells, is in view too (the line's far rows are seen through its near
#: row).
_LINE_THICKNESS_PX = 3


def _in_plain_view(
    lines: npt.NDArray[np.bool_],
    free: npt.NDArray[np.bool_],
    open_unknown: npt.NDArray[np.bool_],
    min_opening_px: float,
) -> npt.NDArray[np.bool_]:
    """Cells of hidden wall ``lines`` that nothing hides: the line's cells next to (8-connected) a
    ``free`` cell and to ``open_unknown`` (within the unknown margin of wide unknown space), in
    pieces (8-connected) whose bounding box's longer side is at least ``min_opening_px`` cells,
    and the line's cells within two cells of them (across a line up to three cells thick). Such a
    stretch is an opening into unexplored space seen from the room (a doorway), not a wall
    hidden behind furniture. A shorter one is no opening a robot could use (the unseen corner
    of an outer wall beside a cabinet): left undrawn, it opened the wall once the cabinet went."""
    import cv2

    out = np.zeros(lines.shape, dtype=bool)
    if not lines.any():
        return out
    box = _padded_box(lines, _LINE_THICKNESS_PX)
    ring = np.ones((3, 3), np.uint8)
    beside_free = cv2.dilate(free[box].view(np.uint8), ring).view(bool)
    seen = lines[box] & beside_free & open_unknown[box]
    if not seen.any():
        return out
    # The plain labelling and the boxes of the few seen cells: OpenCV's statistics visit every
    # cell of the box again (4.8 ms a call on the benchmark maps, a fortieth of the cleaning).
    count, labels = components(seen)
    _, _, width, height = label_boxes(labels, _nonzero_flat(seen.view(np.uint8)), count).T
    wide = np.maximum(width, height) >= min_opening_px
    wide[0] = False  # the background
    seen = labels_looked_up(wide, labels)
    if seen.any():
        side = 2 * (_LINE_THICKNESS_PX - 1) + 1
        grown = cv2.dilate(seen.view(np.uint8), np.ones((side, side), np.uint8)).view(bool)
        out[box] = grown & lines[box]
    return out


def _in_openings(
    lines: npt.NDArray[np.bool_],
    spans: npt.NDArray[np.bool_],
    free: npt.NDArray[np.bool_],
    unknown: npt.NDArray[np.bool_],
    removed: npt.NDArray[np.bool_],
    occupied: npt.NDArray[np.bool_],
    robot_px: float,
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Cells of hidden wall ``lines`` that stand in a doorway seen through: pieces of the line
    (8-connected, joined through the gap's unseen cells and their object's sides: the
    ``removed`` cells next to ``spans`` within two cells of the line, and the kept ones there of a
    small piece beside a line piece with a stretch seen through on one side so far,
    :func:`_small_pieces`) with a stretch of the gap seen through beside the object on two
    sides.

    ``spans`` are the cells between the wall ends the lines join, whatever they are (not
    ``occupied``). A stretch of its ``free`` cells (8-connected) with no ``unknown`` cell of it
    among their 8 neighbours is seen through when it parts two regions of the cells that are
    neither occupied nor spans (8-connected, in its box ``robot_px`` cells wider), each region
    reaching that box's edge: scans went across the wall line there, the room on one side, free
    or unexplored space on the other. Free cells in front of a wall that steps back by a cell or
    two meet the wall behind them, not a region beyond; a recess closed within a robot's width
    of the line (a wall stepping back beside a cabinet) is a pocket, not space beyond; a free
    cell in front of an unseen wall touches the unseen line. A piece between two
    such stretches is the unseen back of something standing in a doorway, a box whose sides
    left the gaps beside it narrower than a robot: drawn, the line closed the doorway once the
    box went. A cabinet against a wall has wall, seen or unseen, on at least one side of it.
    Both stretches must be narrower than ``robot_px`` cells along the line (a wider one is a
    passage beside the object already) and lie on the piece's line, one past each end of it.
    Masks of shape ``(rows, cols)``.

    Returns
    -------
    lines : ndarray of bool, shape (rows, cols)
        The cells of ``lines`` not to draw.
    objects : ndarray of bool, shape (rows, cols)
        The ``occupied`` pieces (8-connected) whose sides those are, each within the doorway's
        reach and standing out of the wall's band by more than a cell: what stood in the
        doorway, no obstacle the topology guard should keep the doorway closed by.
    """
    import cv2

    out = np.zeros(lines.shape, dtype=bool)
    objects = np.zeros(lines.shape, dtype=bool)
    if not lines.any():
        return out, objects
    reach = max(math.ceil(robot_px), _LINE_THICKNESS_PX)  # (how far a gap's regions are seen)
    box = _padded_box(lines, reach + 2)
    if spans.any():
        # (The box of both, from the two boxes: no mask of the union made.)
        (r0, r1), (c0, c1) = ((b.start, b.stop) for b in _padded_box(spans, reach + 2))
        box = (
            slice(min(box[0].start, r0), max(box[0].stop, r1)),
            slice(min(box[1].start, c0), max(box[1].stop, c1)),
        )
    ring = np.ones((3, 3), np.uint8)
    span, line = spans[box], lines[box]
    # (Masks of the box made in place or into one scratch image where they can: each new one
    # is a fresh allocation the kernel fills page by page, on the benchmark maps several times
    # the cost of the pass itself.)
    pieces = span & unknown[box]  # the unseen span cells; the line and its sides join them below
    scratch = cv2.dilate(pieces.view(np.uint8), ring)  # next to an unseen span cell
    through = span & free[box]
    np.greater(through, scratch.view(bool), out=through)
    if not through.any():
        return out, objects
    beside_span = cv2.dilate(span.view(np.uint8), ring).view(bool)
    # The object's sides: removed cells beside the gap and within two cells of the line (a side
    # a cell or two thick; farther on, removed cells chain other clutter to it).
    cv2.dilate(line.view(np.uint8), np.ones((5, 5), np.uint8), dst=scratch)  # near the line
    beside_span &= scratch.view(bool)  # (beside the gap and near the line: for the kept sides too)
    # (Listed from the removed cells: no image of the sides.)
    side_cells = _nonzero_flat(removed[box].view(np.uint8))
    side_cells = side_cells[beside_span.reshape(-1)[side_cells]]
    near_through = cv2.dilate(through.view(np.uint8), ring, dst=scratch).view(bool)
    # Only the sides beside a gap seen through have a stretch among their neighbours.
    beside_gap = near_through.reshape(-1)[side_cells]
    if not beside_gap.any():
        return out, objects  # (no gap seen through beside an object: nearly every map)
    stretches, gaps = components(through)
    count, labels, side_owner, piece_of, stretch_of = _side_pairs(
        line, side_cells, beside_gap, pieces, gaps, stretches
    )
    # A box within two cells of a door edge: its side there joins the wall's straight run (the
    # runs' cell of tolerance) and is kept, not removed. Such kept cells are its sides too when
    # their occupied piece is small (lies within the reach of the line beside it), unlike the
    # wall end a hidden line meets. Only beside a piece with a gap on one side so far (the
    # other gap is beside the kept side).
    one = np.bincount(piece_of, minlength=count) == 1
    one[0] = False
    kept_sides = np.zeros(0, dtype=bool)  # (not looked at)
    if one.any():
        kept_sides = beside_span  # (in place: only a scratch image from here on)
        kept_sides &= near_through
        kept_sides &= occupied[box]
        np.greater(kept_sides, removed[box], out=kept_sides)
    if one.any() and kept_sides.any():
        small, owner = _small_pieces(
            kept_sides, occupied[box], labels, pieces, one, math.ceil(robot_px) + 1
        )
        if small.size:
            # Joined to the piece beside them (a cell or two from it, across the run's band).
            labels.reshape(-1)[small] = owner
            side_cells = np.concatenate([side_cells, small])
            side_owner = np.concatenate([side_owner, owner.astype(side_owner.dtype)])
            more_pieces, more_stretches = _pairs(small, owner, gaps, stretches)
            pairs = np.unique(
                np.concatenate([piece_of, more_pieces]) * stretches
                + np.concatenate([stretch_of, more_stretches])
            )
            piece_of, stretch_of = np.divmod(pairs, stretches)
    line_cells = _nonzero_flat(line.view(np.uint8))  # (OpenCV lists a view's cells as well)
    gap_cells = _nonzero_flat(through.view(np.uint8))
    # Each piece's and stretch's cells looked up by label (not one pass over all per lookup).
    line_of = _by_label(line_cells, labels.reshape(-1)[line_cells], count)
    gap_of = _by_label(gap_cells, gaps.reshape(-1)[gap_cells], stretches)
    width = line.shape[1]
    # Or one stretch runs along the piece's line cells, beside each of them, and on past both of
    # its ends: the wall line behind the piece is seen through (a box standing in front of a
    # doorway, its back's unseen row bridged from a wall end beside the doorway's free cells):
    # drawn, the line closed the doorway's mouth once the box went.
    along = np.array(
        [
            _alongside(
                np.divmod(line_of(piece), width),
                np.divmod(gap_of(stretch), width),
            )
            for piece, stretch in zip(piece_of.tolist(), stretch_of.tolist(), strict=True)
        ],
        dtype=bool,
    )
    # Only pieces with two stretches beside them need theirs looked at (few: each in its box).
    two = np.bincount(piece_of, minlength=count) >= 2
    candidates = np.unique(stretch_of[two[piece_of] | along])
    if candidates.size == 0:
        return out, objects
    open_cells = np.logical_or(occupied[box], span, out=beside_span)  # (no longer needed)
    open_cells |= line
    np.logical_not(open_cells, out=open_cells)
    seen = np.zeros(stretches, dtype=bool)
    seen[candidates] = _parting(gaps, stretches, candidates, open_cells, reach, cells=gap_cells)
    by_seen = seen[stretch_of]
    piece_of, stretch_of, along = piece_of[by_seen], stretch_of[by_seen], along[by_seen]
    wanted = np.zeros(count, dtype=bool)
    wanted[piece_of[along]] = True
    two = np.bincount(piece_of, minlength=count) >= 2
    two[0] = False
    two &= ~wanted
    alongside = wanted.copy()
    # And the stretches lie on the piece's line, one past each of its ends, each narrower than
    # the robot (``robot_px`` cells, its width and a cell): the doorway's gaps on either side of
    # what stands in it, which the line left closed, not gaps around clutter that meets the line
    # nor free cells on a line across a room.
    for piece in np.flatnonzero(two).tolist():
        ends = [np.divmod(gap_of(g), width) for g in stretch_of[piece_of == piece]]
        wanted[piece] = _on_both_ends(np.divmod(line_of(piece), width), ends, robot_px)
    if not wanted.any():
        return out, objects
    # The whole object, not only its sides beside the gap (labelled over the map: it may reach
    # past the gaps' box, and this is rare), when it lies within the doorway's reach: the box of
    # its line piece and the gaps, as much again on every side. Its occupied cells, not only
    # those removed so far: its front, kept here as the paper's structure and removed later as
    # an object face, was an obstacle the guard kept the doorway closed by. A piece joined to a
    # wall reaches past the doorway and is not taken.
    count, pieces_occupied = components(occupied)
    occupied_cells = _nonzero_flat(np.ascontiguousarray(occupied).view(np.uint8))
    extents = label_boxes(pieces_occupied, occupied_cells, count)
    standing = np.zeros(count, dtype=bool)
    for piece in np.flatnonzero(wanted).tolist():
        mine = np.concatenate(
            [line_of(piece), side_cells[side_owner == piece]]
            + [gap_of(g) for g in stretch_of[piece_of == piece]]
        )
        rows, cols = np.divmod(mine, width)
        reach = max(int(rows.max() - rows.min()), int(cols.max() - cols.min())) + 1
        r0, r1 = rows.min() + box[0].start - reach, rows.max() + box[0].start + reach
        c0, c1 = cols.min() + box[1].start - reach, cols.max() + box[1].start + reach
        side_rows, side_cols = np.divmod(side_cells[side_owner == piece], width)
        owners = np.unique(pieces_occupied[side_rows + box[0].start, side_cols + box[1].start])
        x, y, w, h = (extents[owners, i] for i in range(4))
        inside = (y >= r0) & (y + h - 1 <= r1) & (x >= c0) & (x + w - 1 <= c1)
        # And it stands out of the wall's band (the gaps beside it lie across the wall's
        # thickness) by more than a cell: a stretch of wall flush with the wall's faces between
        # two narrow gaps seen through, its core unseen, is no box (it went, and the wall opened).
        line_rows, line_cols = np.divmod(line_of(piece), width)
        gap_rows, gap_cols = np.divmod(
            np.concatenate([gap_of(g) for g in stretch_of[piece_of == piece]]),
            width,
        )
        centre, axis = _axis(line_rows, line_cols, (gap_rows, gap_cols))
        band = _across(gap_rows, gap_cols, centre, axis)
        for owner in owners[inside].tolist():
            # (Its own box: the reach's may start before the map's first row or column.)
            ox, oy, ow, oh = extents[owner].tolist()
            own_rows, own_cols = np.nonzero(pieces_occupied[oy : oy + oh, ox : ox + ow] == owner)
            off = _across(own_rows + oy - box[0].start, own_cols + ox - box[1].start, centre, axis)
            standing[owner] = off.min() < band.min() - 1 or off.max() > band.max() + 1
        if alongside[piece] and _on_the_wall(
            pieces_occupied, owners[~inside], (r0, r1, c0, c1), box, centre, axis, band
        ):
            # An object joined to the wall the doorway is in (a box whose side stands on the
            # door's wall end) is not taken: without the line across its back its inside opened
            # onto the doorway, no pocket, and the whole box was kept. Drawn, it goes.
            wanted[piece] = False
    standing[0] = False
    out[box] = wanted[labels] & line
    objects = standing[pieces_occupied]
    return out, objects


def _by_label(
    cells: npt.NDArray[np.int64], owners: npt.NDArray[np.integer], count: int
) -> Callable[[int], npt.NDArray[np.int64]]:
    """The ``cells`` of each label (of ``count``) by their ``owners``, in their order: the lookup
    of a label's cells (``cells[owners == label]``), the cells grouped once by a stable sort."""
    order = np.argsort(owners, kind="stable")
    grouped = cells[order]
    starts = np.searchsorted(owners[order], np.arange(count + 1)).tolist()
    return lambda label: grouped[starts[label] : starts[label + 1]]


def _on_the_wall(
    pieces: npt.NDArray[np.integer],
    owners: npt.NDArray[np.integer],
    window: tuple[int, int, int, int],
    box: tuple[slice, slice],
    centre: npt.NDArray[np.float64],
    axis: npt.NDArray[np.float64],
    band: npt.NDArray[np.float64],
) -> bool:
    """For :func:`_in_openings`: whether any of the occupied ``pieces`` labelled ``owners`` has
    cells within ``window`` (first and last row, first and last column of the map, clipped to
    it) and within ``band`` (offsets across the line through ``centre`` along ``axis``, in the
    cells of ``box``): a wall the gap is in, not only something standing in front of it."""
    owners = owners[owners > 0]  # (not the background)
    if owners.size == 0:
        return False
    r0, r1 = max(window[0], 0), min(window[1] + 1, pieces.shape[0])
    c0, c1 = max(window[2], 0), min(window[3] + 1, pieces.shape[1])
    rows, cols = np.nonzero(np.isin(pieces[r0:r1, c0:c1], owners))
    off = _across(rows + r0 - box[0].start, cols + c0 - box[1].start, centre, axis)
    return bool(np.any((off >= band.min()) & (off <= band.max())))


def _side_pairs(
    line: npt.NDArray[np.bool_],
    side_cells: npt.NDArray[np.int64],
    beside_gap: npt.NDArray[np.bool_],
    pieces: npt.NDArray[np.bool_],
    gaps: npt.NDArray[np.integer],
    stretches: int,
) -> tuple[
    int,
    npt.NDArray[np.integer],
    npt.NDArray[np.integer],
    npt.NDArray[np.int64],
    npt.NDArray[np.int64],
]:
    """For :func:`_in_openings`: the pieces of the ``line`` joined with its object's sides (their
    cells, flat indices ascending: ``side_cells``; ``beside_gap``: which of them have a cell seen
    through, ``gaps > 0``, among their 8 neighbours) and the gap's unseen span cells (``pieces``,
    joined with the others in place: a line drawn in two halves is one object's back), their count
    and labels, the sides' pieces, and every (piece, stretch) pair that touches at a side (the
    stretch labels, ``gaps``, of the sides' 8 neighbours; the sides' cells are few). A stretch
    that meets only the line itself is no gap beside an object (fills across a room, between
    pieces in line, meet the unseen insides of what stands in it)."""
    pieces |= line
    pieces.reshape(-1)[side_cells] = True
    count, labels = components(pieces)
    side_owner = labels.reshape(-1)[side_cells]
    # (Only the sides beside a gap: the others' neighbours are no stretch.)
    piece_of, stretch_of = _pairs(side_cells[beside_gap], side_owner[beside_gap], gaps, stretches)
    return count, labels, side_owner, piece_of, stretch_of


def _pairs(
    cells: npt.NDArray[np.intp],
    owners: npt.NDArray[np.integer],
    gaps: npt.NDArray[np.integer],
    stretches: int,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """The distinct (owner, stretch) pairs of the ``cells`` (flat indices into ``gaps``) with their
    ``owners`` and the stretch labels (``gaps``, ``stretches`` labels) of their 8 neighbours."""
    rows, cols = np.divmod(cells, gaps.shape[1])
    if cells.size == 0 or (
        rows.min() > 0
        and rows.max() < gaps.shape[0] - 1
        and cols.min() > 0
        and cols.max() < gaps.shape[1] - 1
    ):
        # (No cell on the box's edge, nearly always: no padded copy of the labels.)
        around = _neighbour_columns(gaps, cells)
    else:
        padded = np.pad(gaps, 1)  # (the neighbours of a cell on the box's edge)
        around = _neighbour_columns(padded, (rows + 1) * padded.shape[1] + cols + 1)
    pairs = np.concatenate([owners.astype(np.int64) * stretches + column for column in around])
    pairs = np.unique(pairs[np.concatenate(around) > 0])
    piece_of, stretch_of = np.divmod(pairs, stretches)
    return piece_of, stretch_of


def _small_pieces(
    cells: npt.NDArray[np.bool_],
    occupied: npt.NDArray[np.bool_],
    labels: npt.NDArray[np.integer],
    labelled: npt.NDArray[np.bool_],
    wanted: npt.NDArray[np.bool_],
    margin: int,
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.int64]]:
    """The ``cells`` whose piece of ``occupied`` (8-connected) lies within the reach of a
    ``wanted`` piece of ``labels`` within two cells of them: that piece's bounding box ``margin``
    cells wider on every side (the gaps beside its object), as much again on every side (as the
    objects standing in a doorway, :func:`_in_openings`). A wall's end reaches farther. Each piece
    of ``occupied`` is labelled in that window only (such cells are on most maps: labelled over
    the whole box, twice, they cost 6 ms a map). ``labelled``: the mask ``labels`` labels (its
    cells list those with a label, a pass over bytes, not over labels). Masks of shape
    ``(rows, cols)``.

    Returns the flat indices of those cells and, for each, the wanted piece it is beside."""
    height, width = cells.shape
    at = _nonzero_flat(np.ascontiguousarray(cells).view(np.uint8))
    found: list[npt.NDArray[np.intp]] = []
    owners: list[npt.NDArray[np.int64]] = []
    rows, cols = np.divmod(at, width)
    # The wanted pieces within two cells of each cell (5 x 5 windows clipped by the box).
    offsets = [(dr, dc) for dr in range(-2, 3) for dc in range(-2, 3)]
    if at.size and (
        rows.min() > 1 and rows.max() < height - 2 and cols.min() > 1 and cols.max() < width - 2
    ):
        # No cell within two of the box's edge (nearly always): flat offsets, no clipping.
        flat_labels = labels.reshape(-1)
        around = np.stack([flat_labels[at + (dr * width + dc)] for dr, dc in offsets])
    else:
        around = np.stack(
            [
                labels[np.clip(rows + dr, 0, height - 1), np.clip(cols + dc, 0, width - 1)]
                for dr, dc in offsets
            ]
        )
    around = np.where(wanted[around], around, 0)
    pieces = np.unique(around[around > 0])
    # The boxes of those pieces only, from their cells (few next to all the labelled ones).
    labelled_cells = _nonzero_flat(labelled.view(np.uint8))
    chosen = np.zeros(wanted.size, dtype=bool)
    chosen[pieces] = True
    boxes = label_boxes(
        labels, labelled_cells[chosen[labels.reshape(-1)[labelled_cells]]], wanted.size
    )
    for piece in pieces.tolist():
        near = (around == piece).any(axis=0)
        x, y, w, h = boxes[piece].tolist()
        x, y, w, h = x - margin, y - margin, w + 2 * margin, h + 2 * margin
        reach = max(w, h)
        # The window one cell wider than the reach: a piece touching its edge reaches past it.
        r0, r1 = max(y - reach - 1, 0), min(y + h + reach + 1, height)
        c0, c1 = max(x - reach - 1, 0), min(x + w + reach + 1, width)
        local_count, local = components(occupied[r0:r1, c0:c1])
        # The labels on the window's edges within the box (at the box's edge the window ends
        # with it, as the whole box's labelling did).
        edges = [local[0]] if r0 > 0 else []
        edges += [local[-1]] if r1 < height else []
        edges += [local[:, 0]] if c0 > 0 else []
        edges += [local[:, -1]] if c1 < width else []
        mine = local[rows[near] - r0, cols[near] - c0]
        # (A flag per label, not ``np.isin``'s sort of the edges' labels.)
        on_edge = np.zeros(local_count, dtype=bool)
        if edges:
            on_edge[np.concatenate(edges)] = True
        small = ~on_edge[mine]
        mine_small = at[near][small]
        found.append(mine_small)
        owners.append(np.full(mine_small.size, piece, dtype=np.int64))
    if not found:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.int64)
    # A cell beside two pieces: the first (its side in either).
    flat, first = np.unique(np.concatenate(found), return_index=True)
    return flat, np.concatenate(owners)[first]


def _axis(
    rows: npt.NDArray[np.int64],
    cols: npt.NDArray[np.int64],
    around: tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]] | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The centre (row, col) and the long axis (a unit vector, row and col) of the cells
    ``rows, cols`` (two or more, or one with ``around``): their principal axis. Cells spread
    alike every way (a square piece, 2 x 2 across a box's inside two cells wide) have none, and
    cells no longer along it than a line is thick (``_LINE_THICKNESS_PX``: 1 x 2 across an
    inside a cell wide) have none of their own, nor has a single cell: then the axis is that of
    them with the cells ``around`` them (rows, cols: the gaps beside a line piece), when given.
    (The solver's pick for equal spreads is its first unit vector, along the columns whichever
    way the wall ran: a box in a doorway was found upright and missed transposed; a line piece
    across a wall is longest across it.)"""
    points = np.stack([rows, cols], axis=1).astype(np.float64)
    if points.shape[0] < 2 and around is not None:
        # (A single cell: the axis of the cells around it with it.)
        more = np.concatenate([points, np.stack(around, axis=1).astype(np.float64)])
        _, vectors = np.linalg.eigh(np.cov(more, rowvar=False))
        return points.mean(axis=0), vectors[:, -1]
    spreads, vectors = np.linalg.eigh(np.cov(points, rowvar=False))
    if around is not None and around[0].size:
        along = points @ vectors[:, -1]
        stubby = float(along.max() - along.min()) + 1 <= _LINE_THICKNESS_PX
        if stubby or spreads[1] - spreads[0] <= 1e-9 * spreads[1]:
            more = np.stack(around, axis=1).astype(np.float64)
            _, vectors = np.linalg.eigh(np.cov(np.concatenate([points, more]), rowvar=False))
    return points.mean(axis=0), vectors[:, -1]  # (eigenvalues ascending: the long axis last)


def _across(
    rows: npt.NDArray[np.int64],
    cols: npt.NDArray[np.int64],
    centre: npt.NDArray[np.float64],
    axis: npt.NDArray[np.float64],
) -> npt.NDArray[np.float64]:
    """Signed distances (cells) of the cells ``rows, cols`` from the line through ``centre``
    along ``axis`` (of :func:`_axis`)."""
    return (rows - centre[0]) * axis[1] - (cols - centre[1]) * axis[0]


def _alongside(
    piece: tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]],
    stretch: tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]],
) -> bool:
    """Whether the ``stretch`` (rows, cols) lies beside every cell of the line ``piece`` (rows,
    cols), within ``_LINE_THICKNESS_PX - 1`` cells (across a line up to that thick), on the
    piece's line (no cell farther across it than that), and has cells past both ends of the
    piece along its long axis (:func:`_axis`): the wall line is seen through behind the whole
    piece, not only at its ends."""
    import cv2

    if piece[0].size == 0 or stretch[0].size == 0:
        return False
    near = _LINE_THICKNESS_PX - 1
    if (
        stretch[0].min() > piece[0].min() + near
        or stretch[0].max() < piece[0].max() - near
        or stretch[1].min() > piece[1].min() + near
        or stretch[1].max() < piece[1].max() - near
    ):
        return False  # (most pairs: the stretch is beside one end of the piece only)
    # Every piece cell within ``near`` cells (either way) of a stretch cell: the stretch's cells
    # in the piece's box ``near`` wider, grown by ``near`` on a raster of that box (cell pairs
    # grew as their product: 0.5 GB and seconds for a 100 m line along a long doorway's cells).
    top, left = piece[0].min() - near, piece[1].min() - near
    shape = (int(piece[0].max() + near - top + 1), int(piece[1].max() + near - left + 1))
    rows, cols = stretch[0] - top, stretch[1] - left
    inside = (rows >= 0) & (rows < shape[0]) & (cols >= 0) & (cols < shape[1])
    cells = np.zeros(shape, dtype=np.uint8)
    cells[rows[inside], cols[inside]] = 1
    grown = cv2.dilate(cells, np.ones((2 * near + 1, 2 * near + 1), np.uint8))
    if not grown[piece[0] - top, piece[1] - left].all():
        return False
    if piece[0].size + stretch[0].size < 3:
        return False  # (a cell beside a cell: no stretch past both ends)
    centre, axis = _axis(*piece, stretch)
    # On the line, too: every stretch cell within ``near`` cells across it of the piece's cells.
    # Free space that sealing spans cover row after row (a corridor bridged across between its
    # side walls) is one stretch as wide as the room: it lies beside a line piece in a wall
    # across the corridor's end, and that wall was taken for a box in a doorway and went.
    off_piece, off_stretch = _across(*piece, centre, axis), _across(*stretch, centre, axis)
    if off_stretch.min() < off_piece.min() - near or off_stretch.max() > off_piece.max() + near:
        return False
    ends = (np.stack(piece, axis=1) - centre) @ axis
    past = (np.stack(stretch, axis=1) - centre) @ axis
    return bool(past.min() < ends.min() and past.max() > ends.max())


def _on_both_ends(
    piece: tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]],
    stretches: list[tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]],
    max_length_px: float,
) -> bool:
    """Whether, of the ``stretches`` (rows, cols of each), one lies past each end of the straight
    ``piece`` (rows, cols) along its long axis (its cells' principal axis), centred within
    ``_LINE_THICKNESS_PX - 1`` cells of that axis and shorter along it than ``max_length_px``
    cells (measured from its end next to the piece, as far as its cells on the axis follow on
    without a break of more than a cell and a half)."""
    if piece[0].size < 2:
        return False
    around = (
        (
            np.concatenate([rows for rows, _ in stretches]),
            np.concatenate([cols for _, cols in stretches]),
        )
        if stretches
        else None
    )
    centre, axis = _axis(*piece, around)
    sides = set()
    for rows, cols in stretches:
        offset = np.array([rows.mean(), cols.mean()]) - centre
        if abs(offset[0] * axis[1] - offset[1] * axis[0]) > _LINE_THICKNESS_PX - 1:
            continue
        # Its length on the axis itself (its cells within a cell and a half of it): at an angle
        # to the grid a band three cells thick reaches farther along the line at its edges.
        cells = np.stack([rows, cols], axis=1) - centre
        on_axis = np.abs(cells[:, 0] * axis[1] - cells[:, 1] * axis[0]) <= 1.5
        past = bool(offset @ axis > 0)
        along = np.sort(cells[on_axis] @ axis)
        if not along.size:
            continue
        # From its end next to the piece, as far as its cells on the axis follow on without a
        # break: at an angle to the grid the free notches of the wall's staircase beside the
        # gap join it (8-connected) and reach on along the line.
        steps = np.diff(along) if past else -np.diff(along[::-1])
        breaks = np.flatnonzero(steps > 1.5)
        cells_in = along.size if breaks.size == 0 else int(breaks[0]) + 1
        span = along[:cells_in] if past else along[::-1][:cells_in]
        if abs(float(span[-1] - span[0])) + 1 < max_length_px:
            sides.add(past)
    return len(sides) == 2


def _parting(
    labels: npt.NDArray[np.integer],
    count: int,
    wanted: npt.NDArray[np.int64],
    open_cells: npt.NDArray[np.bool_],
    pad: int,
    *,
    cells: npt.NDArray[np.intp] | None = None,
) -> npt.NDArray[np.bool_]:
    """For each label of ``wanted`` (of ``labels``, an 8-connected labelling, ``count`` labels with
    the background): whether its cells touch (8-connected) two or more regions of ``open_cells``
    (8-connected) in the label's bounding box ``pad`` cells wider, clipped to the image, that
    each reach that box's edge. A region closed within the box is a pocket (a recess in a wall
    beside the label, walled all round): no space beyond the line that scans went across to;
    unless another label (another stretch seen through) lies between it and a region that
    reaches the edge, which it then counts as (:func:`_pockets_seen_into`). ``cells``: the
    labelled cells' flat indices, ascending, when the caller has them (else listed here)."""
    import cv2

    out = np.zeros(wanted.size, dtype=bool)
    height, width = labels.shape
    if cells is None:
        cells = _nonzero_flat(np.ascontiguousarray(labels > 0).view(np.uint8))
    # The boxes of the wanted labels only, from their cells (few next to all the labelled ones).
    chosen = np.zeros(count, dtype=bool)
    chosen[wanted] = True
    boxes = label_boxes(labels, cells[chosen[labels.reshape(-1)[cells]]], count)[wanted]
    ring = np.ones((3, 3), np.uint8)
    # (The labels looked at are few: a doorway's two gaps per object standing in one.)
    for i, (label, (x, y, w, h)) in enumerate(zip(wanted.tolist(), boxes.tolist(), strict=True)):
        r0, r1 = max(y - pad, 0), min(y + h + pad, height)
        c0, c1 = max(x - pad, 0), min(x + w + pad, width)
        window = labels[r0:r1, c0:c1]
        mine = window == label
        count_here, regions = components(open_cells[r0:r1, c0:c1])
        beside = cv2.dilate(mine.view(np.uint8), ring).view(bool)
        touching = np.unique(regions[beside & ~mine])
        touching = touching[touching > 0]
        edge = np.concatenate([regions[0], regions[-1], regions[:, 0], regions[:, -1]])
        reaching = np.zeros(count_here, dtype=bool)
        reaching[edge] = True
        reaching[0] = False
        groups = {int(r) for r in touching if reaching[r]}
        if len(groups) < 2 and not reaching[touching].all():
            # (Two regions reaching the edge decide already: the pockets only add regions.)
            groups |= _pockets_seen_into(window, label, regions, reaching, touching, ring)
        out[i] = len(groups) >= 2
    return out


def _pockets_seen_into(
    window: npt.NDArray[np.integer],
    label: int,
    regions: npt.NDArray[np.integer],
    reaching: npt.NDArray[np.bool_],
    touching: npt.NDArray[np.integer],
    ring: npt.NDArray[np.uint8],
) -> set[int]:
    """For :func:`_parting`: the regions reaching the window's edge (of ``regions``, ``reaching``)
    that a closed region of ``touching`` is joined to across another stretch seen through (a
    label of ``window`` other than ``label``): such a region is no pocket, scans went into it
    across that stretch (a bridge of free cells from a cabinet's front to a box beside a doorway
    closed the gap between them off from the room). Its region beyond that stretch is the
    one it belongs to."""
    import cv2

    found: set[int] = set()
    pockets = touching[~reaching[touching]]
    # Only the stretches beside such a pocket (a window holds many, a pocket few).
    # (A flag per region looked up, not ``np.isin`` over the window.)
    is_pocket = np.zeros(len(reaching), dtype=bool)
    is_pocket[pockets] = True
    near = cv2.dilate(labels_looked_up(is_pocket, regions).view(np.uint8), ring).view(bool)
    others = np.unique(window[near & (window > 0) & (window != label)])
    for other in others.tolist():
        beside = cv2.dilate((window == other).view(np.uint8), ring).view(bool)
        across = np.unique(regions[beside])
        if np.isin(pockets, across).any():
            found.update(int(r) for r in across if reaching[r])
    return found


def _bridges(
    walls: npt.NDArray[np.bool_],
    fillable: npt.NDArray[np.bool_],
    directions: npt.NDArray[np.float64],
    max_gap_px: float,
    anchors_px: tuple[float, ...],
    *,
    staggered_px: tuple[float, float] | None = None,
) -> list[npt.NDArray[np.bool_]]:
    """:func:`bridge_gaps` for each shortest anchor of ``anchors_px`` (ascending), rotating the map
    once; which fills are thin enough is decided on the first anchor's (the smallest: the most
    fill; an even anchor's opening shifts its pieces a cell on, so a later anchor may still fill a
    cell the first does not, just past one of its fills).

    With ``staggered_px = (anchor, min_fill)`` one more output: the fills between wall ends up to a
    cell apart across the line (:func:`_staggered_cells`), at most three cells thick.

    The anchors are exact stretches in the rotated frame: a wall one cell thin at an angle to its
    frame can come out of the rotation dashed, and then anchors nothing (no hidden wall is drawn
    there; the guard keeps the furniture instead). A cell of tolerance brought the dashes back but
    also every wall's staircase: on the 30-degree benchmark logs robot gaps rose from 0.5 (2) to
    1 (3) with nothing gained. The staggered fills (``staggered_px``) take a cell of tolerance
    across the line only, with longer anchors and no fills shorter than ``min_fill``."""
    bits = len(anchors_px) + (staggered_px is not None)
    if bits > 8:
        msg = "at most 8 anchors (one bit each)"
        raise ValueError(msg)
    outs = [np.zeros(walls.shape, dtype=bool) for _ in range(bits)]
    if not walls.any() or directions.size == 0:
        return outs
    length = max(3, round(max_gap_px)) | 1
    r0, r1, c0, c1 = _bounds(walls)
    crop = walls[r0:r1, c0:c1]
    anchors = [max(1, round(a)) for a in anchors_px]
    stagger = (
        None
        if staggered_px is None
        else (max(1, round(staggered_px[0])), max(1, round(staggered_px[1])))
    )
    # Every frame's fills of the crop, one bit per output, split into the outputs once at the end.
    frames = iter(_frames(directions))
    found = _crop_fills(crop, next(frames), length, anchors, stagger)
    for angle in frames:
        found |= _crop_fills(crop, angle, length, anchors, stagger)
    # The filled cells are few: looked up and drawn one by one, only the open fillable ones.
    cells = _nonzero_flat(found)
    rows, cols = np.divmod(cells, found.shape[1])
    # Flat indices into the map's masks (C-contiguous here: a flat lookup costs less than a pair
    # of index arrays).
    flat = (rows + r0) * walls.shape[1] + (cols + c0)
    fill_bits = found.reshape(-1)[cells]
    fillable_flat = np.ascontiguousarray(fillable).reshape(-1)
    walls_flat = np.ascontiguousarray(walls).reshape(-1)
    wanted = np.greater(fillable_flat[flat], walls_flat[flat])  # fillable & ~walls
    flat, fill_bits = flat[wanted], fill_bits[wanted]
    for bit, out in enumerate(outs):
        on = (fill_bits & np.uint8(1 << bit)) != 0
        out.reshape(-1)[flat[on]] = True
    return outs


def _crop_fills(
    crop: npt.NDArray[np.bool_],
    angle: float,
    length: int,
    anchors: list[int],
    stagger: tuple[int, int] | None,
) -> npt.NDArray[np.uint8]:
    """:func:`_frame_fills` of ``crop`` rotated by ``angle`` (:func:`in_rotated_frame`), back in the crop's
    cells: an image of ``crop``'s shape, one bit per output."""
    # Nothing is filled without two wall cells on a line within ``length`` of each other (any
    # anchor's closing fills between two), or a wall cell within ``length`` of the image's edge
    # (OpenCV's closing fills from it to the edge); the staggered fills need an anchor's run in
    # the walls grown across the line (two grown cells when the anchor is a single cell).
    pairs = [(0, length)]
    runs = []
    if stagger is not None:
        if stagger[0] > 1:
            runs.append((1, stagger[0]))
        else:
            pairs.append((1, length))
    fills, _ = in_rotated_frame(
        crop.view(np.uint8),
        angle,
        lambda rotated, _turned: _frame_fills(rotated, length, anchors, stagger),
        # A fill and its anchors on either side; a staggered fill's longer anchors.
        reach_px=length + 2 * max(anchors + ([stagger[0]] if stagger else [])) + 2,
        needs=FrameNeeds(runs=tuple(runs), pairs=tuple(pairs), edge_px=length + 1),
    )
    return fills


def _frame_fills(
    rotated: npt.NDArray[np.uint8],
    length: int,
    anchors: list[int],
    stagger: tuple[int, int] | None,
) -> npt.NDArray[np.uint8]:
    """:func:`_bridges`' fills of one rotated frame (C-contiguous, 0 or 1), bit ``i`` for
    ``anchors[i]`` and, with ``stagger = (anchor, min_fill)``, the next bit for the staggered
    fills, along the rows and the columns."""
    cells = _nonzero_flat(rotated)  # listed once for both orientations
    fills = np.zeros(rotated.shape, dtype=np.uint8)
    for vertical in (False, True):
        _draw(fills, _gaps(rotated, cells, vertical, length, anchors))
        if stagger is not None:
            # Drawn straight into the bit after the anchors' (no shifted copies).
            staggered = _staggered_cells(rotated, vertical, length, *stagger)
            fills.reshape(-1)[staggered] |= np.uint8(1 << len(anchors))
    return fills


#: Fills of one orientation of a rotated frame: the flat indices of each anchor's cells (bit ``i``
#: for ``anchors[i]``, the runs' way), or an image of the bits (OpenCV's way, :func:`_dense` or
#: fragmented walls).
_Gaps = list[npt.NDArray[np.int64]] | npt.NDArray[np.uint8]


def _draw(fills: npt.NDArray[np.uint8], gaps: _Gaps) -> None:
    """Adds ``gaps`` (of :func:`_gaps`) to ``fills``, an image of the same frame."""
    if isinstance(gaps, np.ndarray):
        fills |= gaps
        return
    flat = fills.reshape(-1)
    for bit, cells in enumerate(gaps):
        flat[cells] |= np.uint8(1 << bit)


def _closed_gaps(
    rotated: npt.NDArray[np.uint8], vertical: bool, length: int, anchors: list[int]
) -> npt.NDArray[np.uint8]:
    """:func:`_bridges`' fills of one orientation of a rotated frame (along the columns when
    ``vertical``, else the rows), bit ``i`` for ``anchors[i]`` (at most 8): the closing with a line
    of ``length`` cells of the pieces on straight stretches of ``anchor`` cells along it, less the
    walls and the fills four or more cells thick across it (:func:`_gaps` drawn). The rules call
    :func:`_gaps` itself; this image of its cells is what the tests compare with OpenCV's way."""
    rotated = np.ascontiguousarray(rotated)
    gaps = _gaps(rotated, _nonzero_flat(rotated), vertical, length, anchors)
    if isinstance(gaps, np.ndarray):
        return gaps
    fills = np.zeros(rotated.shape, dtype=np.uint8)
    _draw(fills, gaps)
    return fills


def _gaps(
    rotated: npt.NDArray[np.uint8],
    cells: npt.NDArray[np.int64],
    vertical: bool,
    length: int,
    anchors: list[int],
) -> _Gaps:
    """:func:`_closed_gaps` of ``rotated`` (C-contiguous) and its non-zero ``cells`` (flat indices,
    ascending). The first anchor's cells come ascending.

    Worked out on the runs of the wall cells along the lines (the same cells as OpenCV's closings
    and openings with line kernels, :func:`_close_runs`): the walls are a few percent of the
    image, and OpenCV's line closings of the whole image cost several times more.
    """
    shape = rotated.shape
    extent = shape[not vertical]  # cells along a line
    if _dense(cells, rotated):
        return _closed_gaps_of_image(rotated, vertical, length, anchors)
    walls = _runs(cells, shape, vertical)
    closed_walls = _close_runs(walls, length, extent)  # the most any anchor closes
    if _fragmented(walls, rotated) or _covered(closed_walls) > _FRAGMENTED_CLOSED * rotated.size:
        return _closed_gaps_of_image(rotated, vertical, length, anchors)
    is_wall = rotated.reshape(-1)
    gaps: list[npt.NDArray[np.int64]] = []
    thick: npt.NDArray[np.uint8] | None = None
    for anchor in anchors:
        # Only wall pieces running along the gap anchor a bridge: the side faces of an object,
        # across it, would join its two sides through its inside.
        closed_runs = (
            closed_walls
            if anchor == 1
            else _close_runs(_open_runs(walls, anchor, extent), length, extent)
        )
        closed = _run_cells(closed_runs, shape, vertical)
        fill = closed[is_wall[closed] == 0]
        if thick is not None:  # a later anchor: none of the first one's thick fills
            gaps.append(fill[thick.reshape(-1)[fill] == 0])
            continue
        # A wall line is thin: drop fills four or more cells thick across the line (the space
        # between two parallel walls, not a wall). The first anchor (all walls, the most fill)
        # decides for every anchor. Closed along the columns, ``fill`` is in column
        # order: a stable reordering by row sorts it.
        if vertical:
            fill = fill[_order_by(fill // shape[1], shape[0])]
        wide, past = _thick(fill, shape, not vertical)
        if len(anchors) > 1:  # the later anchors' fills look their cells up
            # The opening's cell after each thick run too: not this fill's, but a later (even)
            # anchor's can hold it (its pieces shifted a cell on by their own opening).
            thick = np.zeros(shape, dtype=np.uint8)
            thick.reshape(-1)[fill[wide]] = 1
            thick.reshape(-1)[past] = 1
        gaps.append(fill[~wide])
    return gaps


def _thick(
    fill: npt.NDArray[np.int64], shape: tuple[int, int], vertical: bool
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.int64]]:
    """Which cells of ``fill`` (flat indices into ``shape``, ascending) OpenCV's opening with a line
    of 4 cells along the columns when ``vertical`` (else the rows) keeps, as :func:`_open_runs`:
    in runs of 4 or more cells, every cell but the first (the even line's anchor is a cell off the
    middle: the opening is the run shifted on by a cell, and the cell after a run is not in
    ``fill``). Worked out on the runs, with no image to draw them in and look them up. Also the flat
    indices of the cells just after those runs (within the image), which the opening covers too."""
    cols = shape[1]
    if fill.size == 0:
        return np.zeros(0, dtype=bool), np.zeros(0, dtype=np.int64)
    row, col = np.divmod(fill, cols)
    order = _order_by(col, cols) if vertical else None
    line, pos = (col[order], row[order]) if order is not None else (row, col)
    first, last = _groups(line, pos[1:] != pos[:-1] + 1)
    lengths = last - first + 1
    wide = np.repeat(lengths >= 4, lengths)
    wide[first] = False
    # The cell after each run of 4 or more, within the image (a cell further along its line).
    ends = last[(lengths >= 4) & (pos[last] + 1 < shape[not vertical])]
    past = (fill if order is None else fill[order])[ends] + (cols if vertical else 1)
    if order is None:
        return wide, past
    unsorted = np.empty_like(wide)
    unsorted[order] = wide
    return unsorted, past


def _staggered_cells(
    rotated: npt.NDArray[np.uint8],
    vertical: bool,
    length: int,
    anchor: int,
    min_fill: int,
) -> npt.NDArray[np.int64]:
    """Flat indices of the fills of :func:`_closed_gaps` (one anchor) of the walls grown by a cell
    across the line (along the columns when ``vertical``, else the rows): fills between two wall
    ends up to a cell apart across it, less the grown walls (never the cells beside a wall), only
    in stretches of at least ``min_fill`` cells along the line (a staircase's notches are
    shorter)."""
    import cv2

    band: npt.NDArray[np.uint8] = np.ascontiguousarray(
        cv2.dilate(rotated, np.ones((1, 3) if vertical else (3, 1), np.uint8)), dtype=np.uint8
    )
    gaps = _gaps(band, _nonzero_flat(band), vertical, length, [anchor])
    # Ascending either way (the image's listed by OpenCV), as _runs needs them.
    fill = _nonzero_flat(gaps) if isinstance(gaps, np.ndarray) else gaps[0]
    line, start, end = _runs(fill, band.shape, vertical)
    long_enough = end - start + 1 >= min_fill
    runs = (line[long_enough], start[long_enough], end[long_enough])
    return _run_cells(runs, band.shape, vertical)


def _closed_gaps_of_image(
    rotated: npt.NDArray[np.uint8], vertical: bool, length: int, anchors: list[int]
) -> npt.NDArray[np.uint8]:
    """:func:`_closed_gaps` with OpenCV's morphology of the whole image: the same cells, cheaper
    than the runs when many cells are occupied (:func:`_dense`)."""
    import cv2

    along, across = ((length, 1), (1, 4)) if vertical else ((1, length), (4, 1))
    out = np.zeros(rotated.shape, dtype=np.uint8)
    thick: npt.NDArray[np.uint8] | None = None
    for bit, anchor in enumerate(anchors):
        pieces = (
            rotated if anchor == 1 else _open(rotated, (anchor, 1) if vertical else (1, anchor))
        )
        closing = cv2.morphologyEx(pieces, cv2.MORPH_CLOSE, np.ones(along, np.uint8))
        # 0 or 1 each: a > b is a & ~b, one pass instead of two.
        fill = np.greater(closing, rotated).view(np.uint8)
        if thick is None:  # as in _closed_gaps: the first anchor's fills decide
            thick = _open(fill, across)
        out |= np.greater(fill, thick).view(np.uint8) << np.uint8(bit)
    return out


#: Share of the image that closed runs may cover before OpenCV's closing is cheaper (a flat index
#: per closed cell; real maps: at most 10 %, 2 %-occupied speckle: nearly all of it).
_FRAGMENTED_CLOSED = 0.25
