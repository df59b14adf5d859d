"""Furniture flush against a wall or in a room's corner: the hidden wall line is drawn, the furniture's
front and sides go.

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from rose.cleaning_rules.frames import FrameNeeds, _frames, in_rotated_frame
from rose.cleaning_rules.masks import _padded_box

#: Furniture fronts (:func:`_flush_fronts`): the longest wall line hidden behind furniture against
#: a wall, between two visible stretches of that wall (metres).
_FRONT_MAX_M = 5.0


#: ... the deepest such furniture, from the wall line to its front face (metres).
_FRONT_DEPTH_M = 1.0


#: ... the thickest wall meeting the hidden line across it, between two pieces of furniture
#: (metres).
_FRONT_CROSSING_M = 0.5


#: ... a wall face: a wall end anchors the hidden line when free space lies within this of it, on
#: the furniture's side (metres: a scanned wall one to three cells thick).
_FRONT_FACE_M = 0.15


#: ... the share of the furniture's columns whose last cell before the room is occupied.
_FRONT_FACE_SHARE = 0.9


#: ... furniture in a room's corner (:func:`_corner_at`), where the hidden parts of two walls meet
#: behind it: one wall's line runs on from its visible end to the other's, which runs on from the
#: furniture's front; the longest such line (metres, as between two wall ends). Read only in frames
#: along the grid's axes: rotated onto the rows, nearest-neighbour sampling breaks a wall's rows
#: into stretches whose ends look like a wall's end (on the ray-cast logs, whose walls are 1.5-18
#: degrees off the axes, reading corners in rotated frames too cost intel 0.2-0.7 points of wall
#: recall, of its own shelves, and opened a robot gap in both intel-r30 cases).
_CORNER_MAX_M = 5.0


#: ... the shallowest such furniture, from the wall line to the far side of its front (metres), and
#: that of furniture side by side along a wall (:func:`_fronts_rows`' chains of gaps):
#: twice a wall face. One wall end is weaker evidence than two: a wall stepping or bending off
#: its line by a wall's thickness (0.2-0.25 m) next to a corner looks the same, and shallower
#: furniture (a shelf) is rare.
_CORNER_DEPTH_M = 0.3


def _flush_fronts(
    occupied: npt.NDArray[np.bool_],
    unknown: npt.NDArray[np.bool_],
    directions: npt.NDArray[np.float64],
    *,
    max_len_px: float,
    max_depth_px: float,
    anchor_px: float,
    face_px: float,
    crossing_px: float,
    wall_px: float,
    corner_px: float = 0.0,
    corner_depth_px: float = 0.0,
    walls: npt.NDArray[np.bool_] | None = None,
) -> tuple[
    npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]
]:
    """Furniture flush against a wall: the hidden wall line, the furniture's cells, its inside, and
    the walls that meet it (kept).

    Along each dominant direction: a straight stretch of unknown cells (at most ``max_len_px``;
    up to half of them free, and free cells a single beam saw running along the line count as
    unknown: :func:`_beam_along`) between two occupied stretches of at least ``anchor_px`` cells on
    one line that face free space on the same side (most of their last ``anchor_px`` cells within ``face_px`` of it),
    and, with ``walls``, each hold a cell of ``walls`` (the walls kept on their own merits and the
    occupied cells joined to them as attached pieces are, a door frame's stub: two blobs of
    clutter in line in a room, with a box beyond the gap between them, are no wall's two
    stretches),
    where every cell of the stretch has, on that side, more than ``face_px`` and at most
    ``max_depth_px`` occupied or unknown cells before free space, an occupied one last (a front
    face). That is a wall running on behind an object that stands against it: the line is the
    hidden wall, the occupied cells between it and the room are the object's front and sides,
    the unknown cells its inside. Pieces side by side along the wall, between which it shows only
    in stretches shorter than an anchor: each gap between two long stretches at most
    ``max_len_px`` apart, through such short ones on the line, is checked so, its front at least
    ``corner_depth_px`` deep. Columns reaching farther than the front, in stretches no wider
    than ``crossing_px``, are a wall meeting the object (a partition ending on its front,
    or crossing the line between two objects): its cells up to ``wall_px`` past the object are
    kept, and its sides drawn from the line to the front. In a frame at an angle to the grid, where
    a wall is a staircase, the rotated rows are read as they are and once more straightened
    (:func:`_straightened`: the wall line a band of rows), with anchors twice as long, the gap's
    end columns allowed to open to the room, and the front two cells deeper than a wall face.
    With ``corner_px``, in frames along the grid's axes, also furniture in a room's corner
    (:func:`_corner_at`): the line from one wall's visible end (at most ``corner_px``) to the line
    of a perpendicular wall that runs on from the furniture's front, the front at least
    ``corner_depth_px`` from the line; both hidden lines are drawn.
    """
    import cv2

    shape = occupied.shape
    lines, fronts, insides, stubs = (np.zeros(shape, dtype=bool) for _ in range(4))
    if not occupied.any() or directions.size == 0:
        return lines, fronts, insides, stubs
    box = _padded_box(occupied, math.ceil(max_depth_px) + 4)
    r0, c0 = box[0].start, box[1].start
    # 0 unknown (also beyond the rotated image), 1 free, 2 occupied, 3 a wall kept on its own
    # (known, plus occupied, plus kept; into one image, no boolean temporaries; C order for
    # OpenCV's output whatever the masks' order).
    occupied_box = occupied[box].view(np.uint8)
    code = np.bitwise_xor(unknown[box].view(np.uint8), np.uint8(1), order="C")
    cv2.add(code, occupied_box, dst=code)
    if walls is not None:
        cv2.add(code, cv2.bitwise_and(walls[box].view(np.uint8), occupied_box), dst=code)

    def fronts_of(rotated: npt.NDArray[np.uint8], turned: bool) -> npt.NDArray[np.uint8]:
        out = np.zeros(rotated.shape, dtype=np.uint8)  # bit 0 line, 1 front, 2 inside, 3 wall
        transposed = np.asarray(cv2.transpose(rotated), dtype=np.uint8)  # a ninth of numpy's cost
        # Rotated (a wall at an angle to the grid): the exact rows, then the straightened ones.
        for slack, transpose in ((0, False), (0, True)) + (
            ((1, False), (1, True)) if turned else ()
        ):
            # Along the rows, then along the columns (transposed: the runs need the cells of a
            # line in order); each for furniture on either side of the line.
            along = transposed if transpose else rotated
            if slack:
                # A wall at an angle to the grid is a staircase once rotated onto the rows (its
                # cells a row off here and there, its line broken): straightened by growing the
                # occupied cells a row across the line, the wall line, its anchors and the front
                # are whole rows.
                along = _straightened(along)
            _fronts_rows(
                along,
                out.T if transpose else out,
                round(max_len_px),
                round(max_depth_px),
                max(1, round(anchor_px)),
                max(1, round(face_px)),
                round(crossing_px),
                round(wall_px),
                slack=slack,
                # Corners only along the grid's axes (see _CORNER_MAX_M).
                corner_len=0 if turned else round(corner_px),
                corner_depth=round(corner_depth_px),
                walls=walls is not None,
            )
        return out

    # A hidden line with its anchors on either side and the front before it: the farthest the rule
    # looks in a frame turned in pieces (in_rotated_frame's only use of the reach). Corners are
    # looked for in unturned frames only: their length in the reach grew every piece of a thin
    # strip turned at an angle by as much on each side (a 1 x 20,000 strip of specks, nine
    # directions: clean() 3.0-3.6 s with it, 2.7-2.8 s without; same cells).
    reach = round(max_len_px + max_depth_px) + 4 * max(1, round(anchor_px), round(wall_px))
    # In a turned frame (no corners) nothing is found without a gap's anchors: occupied runs of
    # an anchor along a line, of two anchors straightened (which grows the cells by at most one).
    anchor = max(1, round(anchor_px))
    needs = FrameNeeds(runs=((0, anchor), (1, 2 * anchor)), cell_from=2)
    # The walls meeting an object found in every frame (taken out of the fronts at the end).
    masks, stub_cells = (lines, fronts, insides, stubs), []
    for angle in _frames(directions):
        out, _ = in_rotated_frame(code, angle, fronts_of, reach_px=reach, needs=needs)
        stub_cells.append(_merge_found(out, (r0, c0), unknown, occupied, masks))
    for rows, cols in stub_cells:
        fronts[rows, cols] = False  # (fronts & ~stubs)
    return lines, fronts, insides, stubs


def _merge_found(
    out: npt.NDArray[np.uint8],
    origin: tuple[int, int],
    unknown: npt.NDArray[np.bool_],
    occupied: npt.NDArray[np.bool_],
    masks: tuple[npt.NDArray[np.bool_], ...],
) -> tuple[npt.NDArray[np.int32], npt.NDArray[np.int32]]:
    """A frame's output ``out`` (:func:`_flush_fronts`' bits, in its code image's box at
    ``origin``) set in the masks ``lines, fronts, insides, stubs``: the line and the inside where
    unknown, the front and the walls meeting the object where occupied (a front neither a line nor
    such a wall). Returns the rows and columns of those walls.

    Only the cells found (a few hundred a map, or none: then nothing fell between the cells
    sampled back), looked up and set one by one: 0.1 against 0.4 ms per map for the dozen passes
    over their box (most of the map's width)."""
    import cv2

    found = cv2.findNonZero(out)
    if found is None:
        return np.empty(0, dtype=np.int32), np.empty(0, dtype=np.int32)
    x, y = found.reshape(-1, 2).T
    bits = out[y, x]
    rows, cols = y + origin[0], x + origin[1]
    seen_unknown, seen_occupied = unknown[rows, cols], occupied[rows, cols]
    line = (bits & 1).view(bool) & seen_unknown
    stub = (bits >> 3).view(bool) & seen_occupied
    front = (bits >> 1 & 1).view(bool) & seen_occupied & ~line & ~stub
    inside = (bits >> 2 & 1).view(bool) & seen_unknown & ~line
    for mask, cells in zip(masks, (line, front, inside, stub), strict=True):
        mask[rows[cells], cols[cells]] = True
    return rows[stub], cols[stub]


def _straightened(code: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
    """``code`` (0 unknown, 1 free, 2 occupied, 3 a wall kept) with every cell a row above or below
    an occupied one occupied, and then the holes of one or two cells along the rows between
    occupied cells (a morphological closing along the rows): a staircase of one or two rows
    becomes a solid band. The grown cells take the highest of their neighbours' codes (a kept
    wall's band is a kept wall's, at its ends too but where the closing's erosion meets an
    object's cell)."""
    import cv2

    _, occupied = cv2.threshold(code, 1, 0, cv2.THRESH_TOZERO)
    # A closing by three cells along the rows fills exactly the holes of one or two cells between
    # occupied cells; at the first and last columns, where OpenCV's border lets it fill a hole
    # open to the edge, the cells stay as grown (no hole there is between two occupied cells).
    # The growth across the rows and the closing's dilation along them are one dilation by a
    # 3 x 3 square, then the closing's erosion (the same cells as the growth and OpenCV's closing,
    # borders and all: 1.2 against 1.7 ms on a 1580 x 1580 frame).
    closed = cv2.erode(cv2.dilate(occupied, np.ones((3, 3), np.uint8)), np.ones((1, 3), np.uint8))
    edges = cv2.dilate(np.ascontiguousarray(occupied[:, [0, -1]]), np.ones((3, 1), np.uint8))
    closed[:, 0] = edges[:, 0]
    closed[:, -1] = edges[:, 1]
    return np.asarray(cv2.max(code, closed), dtype=np.uint8)


def _fronts_rows(
    code: npt.NDArray[np.uint8],
    out: npt.NDArray[np.uint8],
    max_len: int,
    max_depth: int,
    anchor: int,
    face: int,
    crossing: int,
    stub: int,
    *,
    slack: int = 0,
    corner_len: int = 0,
    corner_depth: int = 0,
    walls: bool = False,
) -> None:
    """:func:`_flush_fronts` along the rows of ``code`` (0 unknown, 1 free, 2 occupied, 3 a wall
    kept on its own), the furniture below or above the line; bits 0 (line), 1 (front), 2 (inside)
    and 3 (a wall meeting the object) set in ``out``. With ``walls``, a gap's two anchoring
    stretches each hold a cell coded 3. With ``corner_len``, also furniture in a room's corner
    (:func:`_corners_rows`), its hidden line at most that long and its front at least
    ``corner_depth`` cells from the line.

    Whole-image work is only the runs of the occupied cells; each candidate gap (unknown cells at
    both ends) is then checked on a few cells, and the rest on the few rows beside it."""
    import cv2

    height, width = code.shape
    flat_code = code.reshape(-1)
    # Occupied (a door frame's stub is kept only later): OpenCV's 0/1 image listed by numpy as
    # booleans, its fast path (0.13 against OpenCV's list's 0.18 ms on an 870 x 418 frame; numpy
    # on the uint8 image takes 0.7).
    _, occupied = cv2.threshold(code, 1, 1, cv2.THRESH_BINARY)
    cells = np.flatnonzero(np.asarray(occupied, dtype=np.uint8).view(bool))
    if cells.size < 2:
        return
    r = cells // width
    step = np.diff(cells)
    same_row = r[1:] == r[:-1]
    new_run = np.ones(cells.size, dtype=bool)
    new_run[1:] = (step != 1) | ~same_row
    run_id = np.cumsum(new_run) - 1
    # Per run, looked up by run where wanted (a few gaps' ends: not spread over every cell).
    run_len = np.bincount(run_id)
    # Gaps between consecutive occupied cells of one row (each must be unseen at both ends:
    # checked below, on the anchored chains' gaps only).
    left = np.flatnonzero(same_row & (step > 1) & (step - 1 <= max_len))
    # (Straightened: a band's wall stretches twice as long, as the staggered bridges' ends: a face
    # across the line at an angle makes short stretches in a band too.)
    run_anchor = anchor if slack == 0 else 2 * anchor
    # Furniture standing side by side along a wall: the wall shows between the pieces only in
    # short stretches (a few cells, shorter than an anchor), on the line of the long stretches
    # beyond the row of furniture. A chain of gaps joined by short stretches is anchored by the
    # long stretches at its two ends (the wall line visible on both sides of the row), at most
    # ``max_len`` apart as one gap's anchors: each gap of it is then checked as a gap between
    # those anchors (a single gap between two long stretches is a chain of one).
    short = (run_len < run_anchor)[run_id[left]]  # the stretch left of each gap
    short_right = (run_len < run_anchor)[run_id[left + 1]]  # and right of it
    # Gap k continues gap k - 1's chain when they share a short stretch.
    joined = np.zeros(left.size, dtype=bool)
    joined[1:] = (run_id[left[1:]] == run_id[left[:-1] + 1]) & short[1:]
    starts = np.flatnonzero(~joined)
    chain = np.cumsum(~joined) - 1
    ends = np.append(starts[1:], left.size)[: starts.size] - 1
    anchor_left = left[starts][chain]  # the chain's first wall end (last cell of its stretch)
    anchor_right = left[ends][chain] + 1  # its last (first cell of its stretch)
    anchored = ~short[starts][chain] & ~short_right[ends][chain]
    if walls:
        # A wall's two visible stretches are walls the cleaning keeps on their own (the paper's
        # structure, runs and lines, next to the wide unknown) or joined to one (a door frame's
        # stub): in a room, blobs of clutter in line (0.3-0.4 m each, longer than an anchor) with
        # a box beyond the gap between them read as a wall's stretches and its front, and a line
        # of wall was drawn across the room.
        kept_run = np.zeros(run_len.size, dtype=bool)
        kept_run[run_id[flat_code[cells] == 3]] = True
        anchored &= kept_run[run_id[anchor_left]] & kept_run[run_id[anchor_right]]
    anchored &= cells[anchor_right] - cells[anchor_left] - 1 <= max_len
    # Every gap of a chain unseen at both ends, else the chain goes. (The chains of the gaps so
    # seen are the anchored chains all of whose gaps are: a chain's first gap follows a long
    # stretch and its last one precedes one, whichever other gaps of the row are left out. So the
    # ends are looked at, and the beams looked for, on the few anchored chains' gaps only.)
    at = np.flatnonzero(anchored)
    seen_chain = np.zeros(starts.size, dtype=bool)
    seen_chain[chain[at[~_unseen_ends(code, cells, left[at])]]] = True
    anchored[at] = ~seen_chain[chain[at]]
    left, anchor_left, anchor_right = left[anchored], anchor_left[anchored], anchor_right[anchored]
    span = max_depth + 1
    if corner_len > 0 and slack == 0:
        # One wall end is weaker evidence than two: its visible stretch must be twice an anchor
        # (as a staggered bridge's ends), longer than the steps of a wall at 45 degrees.
        first = np.flatnonzero(new_run)
        long_run = run_len >= 2 * anchor
        _corners_rows(
            code,
            out,
            (cells[np.append(first[1:], cells.size)[long_run] - 1], cells[first[long_run]]),
            corner_len,
            corner_depth,
            span,
            anchor,
            face,
            crossing,
            stub,
        )
    if left.size == 0:
        return

    rows = cells[left] // width
    end_left, end_right = cells[left] % width, cells[left + 1] % width
    middle = (end_left + end_right) // 2
    # The faces are checked at the chain's anchors (a short stretch between two pieces of
    # furniture has their sides next to it, no free space along an anchor's length).
    face_end_left, face_end_right = cells[anchor_left] % width, cells[anchor_right] % width
    # A chain's gaps are weaker evidence than a gap between two long stretches (as a corner's one
    # wall end): a thick wall's face, with its unseen core, breaks into short stretches too. Their
    # front must be as deep as a corner's furniture (``corner_depth``), deeper than a wall
    # (straightened, two cells deeper, as a wall face is there: the grown rows), and parallel to
    # the line, as furniture set against a wall stands (a wall at an angle to the frame, the
    # unknown behind it read along a row, reaches the row at ever other depths).
    chained = (anchor_left != left) | (anchor_right != left + 1)
    # Cheap tests first, on a few cells of each candidate, on both sides of the line at once.
    facing = _facing_room(
        code, rows, (face_end_left, face_end_right), middle, anchor, face, slack=slack
    )
    for side, sign in enumerate((1, -1)):
        chosen = np.flatnonzero(facing[side])
        # This side as "below": the rows reversed for the other (views, no copies).
        view, written = (code, out) if sign == 1 else (code[::-1], out[::-1])
        # Most candidates fail _front_at's depth test (a front no deeper than a wall face: the
        # room reaches the line): those found so on all of them at once are not asked one by one.
        view_rows = rows[chosen] if sign == 1 else height - 1 - rows[chosen]
        chosen = chosen[
            ~_shallow_in_gap(
                view, view_rows, end_left[chosen] + 1, end_right[chosen], span, face, slack
            )
        ]
        for i in chosen.tolist():
            row = int(rows[i]) if sign == 1 else height - 1 - int(rows[i])
            _front_at(
                view,
                written,
                row,
                int(end_left[i]) + 1,
                int(end_right[i]),
                span,
                anchor,
                face,
                crossing,
                stub,
                slack=slack,
                shallowest=corner_depth + 2 * slack if chained[i] else 0,
                parallel=bool(chained[i]),
            )


def _facing_room(
    code: npt.NDArray[np.uint8],
    rows: npt.NDArray[np.int64],
    face_ends: tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]],
    middle: npt.NDArray[np.int64],
    anchor: int,
    face: int,
    *,
    slack: int,
) -> npt.NDArray[np.bool_]:
    """:func:`_fronts_rows`' cheap tests of the candidate gaps on ``rows`` (shape ``(2, N)``: the
    furniture below the line, then above it): the wall ends' last cells (``anchor``, straightened
    ``anchor + 2``, from the columns ``face_ends``: the left one's leftwards, the right one's
    rightwards) see free space within ``face`` (``face + slack``) rows on that side in half of
    them or more, and the gap's ``middle`` column none that near (``face + 1`` rows, but for a
    slit behind furniture). Both sides in one pass: half the calls on these few cells."""
    height, width = code.shape
    flat_code = code.reshape(-1)

    def free(
        at_rows: npt.NDArray[np.int64], at_cols: npt.NDArray[np.int64]
    ) -> npt.NDArray[np.bool_]:
        # Free cells looked up where wanted (rows past the edges read the edge's), by flat
        # indices (np.minimum and np.maximum: a third of np.clip's cost on these few cells; a
        # flat index, of a pair of index arrays').
        return flat_code[np.minimum(np.maximum(at_rows, 0), height - 1) * width + at_cols] == 1

    signs = np.array([1, -1], dtype=np.int64)[:, None, None]  # (side, gap, row or column)
    across = (rows[:, None] + signs * np.arange(1, face + slack + 1))[..., None]
    along = np.arange(anchor + 2 * slack)
    face_left = free(across, np.maximum(face_ends[0][:, None] - along, 0)[:, None, :])
    face_right = free(across, np.minimum(face_ends[1][:, None] + along, width - 1)[:, None, :])
    seen_left = face_left.any(axis=2).sum(axis=2)
    seen_right = face_right.any(axis=2).sum(axis=2)
    free_beside = free(rows[:, None] + signs * np.arange(1, face + 2), middle[:, None])
    # A slit behind furniture is no room (_front_at): free cells in the row next to the line
    # (straightened, in the two rows), with a cell that is not free behind them.
    if free_beside.shape[2] > 1 + slack:
        slit_beside = ~free_beside[:, :, 1 + slack]
        free_beside[:, :, : 1 + slack] &= ~slit_beside[:, :, None]
    near_middle = free_beside.any(axis=2)
    return (2 * seen_left >= anchor) & (2 * seen_right >= anchor) & ~near_middle


def _unseen_ends(
    code: npt.NDArray[np.uint8], cells: npt.NDArray[np.int64], left: npt.NDArray[np.int64]
) -> npt.NDArray[np.bool_]:
    """Which gaps between the occupied cells ``cells[left]`` and ``cells[left + 1]`` (flat indices
    of ``code``, on one row) are unseen at both ends: unknown, or a free cell a beam saw running
    along the line (:func:`_beam_along`)."""
    # Both ends of every gap at once (the few anchored chains' gaps: one call for the beams).
    ends = np.concatenate((cells[left] + 1, cells[left + 1] - 1))
    end_code = code.reshape(-1)[ends]
    unseen = end_code == 0
    free_end = np.flatnonzero(end_code == 1)
    if free_end.size:
        unseen[free_end] = _beam_along(code, *np.divmod(ends[free_end], code.shape[1]))
    return unseen[: left.size] & unseen[left.size :]


def _shallow_in_gap(
    code: npt.NDArray[np.uint8],
    rows: npt.NDArray[np.int64],
    col0: npt.NDArray[np.int64],
    col1: npt.NDArray[np.int64],
    span: int,
    face: int,
    slack: int,
) -> npt.NDArray[np.bool_]:
    """Which candidate gaps ``rows, col0:col1`` of ``code`` (the furniture below the line) fail
    :func:`_front_at`'s depth test (its front, in some column, no deeper than a wall face: ``face``
    cells, ``face + 2 * slack`` straightened), worked out for all at once as :func:`_front_at` does
    it for one, on the free cells within that depth: :func:`_front_at` returns False for each of
    them (there or at an earlier test) and writes nothing."""
    height, width = code.shape
    limit = face + 2 * slack
    length = col1 - col0
    if rows.size == 0 or span <= limit or int(length.min()) <= 0:
        return np.zeros(rows.size, dtype=bool)
    below_rows = np.minimum(span, height - 1 - rows)  # rows of _front_at's ``below``
    along = np.arange(int(length.max()))
    cols = np.minimum(col0[:, None] + along, width - 1)
    depth = np.arange(limit + 1)
    at_rows = np.minimum(np.maximum(rows[:, None] + 1 + depth, 0), height - 1)
    free = code[at_rows[:, :, None], cols[:, None, :]] == 1  # (gap, depth, column)
    free &= (depth < below_rows[:, None])[:, :, None]
    # The slits: free cells of the first slack + 1 rows with a cell that is not free behind them
    # (when ``below`` has that row).
    has_behind = (below_rows > 1 + slack)[:, None, None]
    slits = free[:, : slack + 1] & ~free[:, slack + 1 : slack + 2] & has_behind
    unslit = free.copy()
    unslit[:, : slack + 1] &= ~slits
    if not slack:
        shallow = unslit
        inside = along < length[:, None]  # the gap's columns
    else:
        # The gap's ends move in where free space reaches within a wall face (raw depths).
        first, stop = np.zeros(rows.size, dtype=np.int64), length.copy()
        at_face = free[:, : face + 1].any(axis=1)
        gaps = np.arange(rows.size)
        for _ in range(slack + 1):
            first += (stop - first > 1) & at_face[gaps, first]
            stop -= (stop - first > 1) & at_face[gaps, stop - 1]
        inside = (along >= first[:, None]) & (along < stop[:, None])
        # The slits are taken out when they are in half the columns or more.
        many = 2 * np.count_nonzero(slits.any(axis=1) & inside, axis=1) >= stop - first
        shallow = np.where(many[:, None, None], unslit, free)
    return (shallow.any(axis=1) & inside).any(axis=1)


def _beam_along(
    code: npt.NDArray[np.uint8], rows: npt.NDArray[np.int64], cols: npt.NDArray[np.int64]
) -> npt.NDArray[np.bool_]:
    """Which cells ``rows, cols`` of ``code`` (0 unknown, 1 free, 2 occupied) are free cells that
    a single beam saw running along the row: unknown in the rows above and below, and no free cell
    diagonally beside it there (a beam crossing the row leaves one); cells of the first and last
    rows are not read so."""
    height, width = code.shape
    # Read by flat indices where ``code`` is contiguous (a pair of index arrays costs several
    # times more; the furniture below the line is read in a view with the rows reversed).
    flat = code.reshape(-1) if code.flags.c_contiguous else None

    def read(
        at_rows: npt.NDArray[np.int64], at_cols: npt.NDArray[np.int64]
    ) -> npt.NDArray[np.uint8]:
        return code[at_rows, at_cols] if flat is None else flat[at_rows * width + at_cols]

    beam = (read(rows, cols) == 1) & (rows > 0) & (rows < height - 1)
    # The tests in turn, each on the cells the ones before left (most free cells have a free
    # cell above or below them: few are left for the diagonals).
    at = np.flatnonzero(beam)
    row, col = rows[at], cols[at]
    for test in range(3):
        if test == 0:
            keep = (read(row - 1, col) == 0) & (read(row + 1, col) == 0)
        else:
            side = row + (2 * test - 3)  # the row above, then the row below
            keep = (read(side, np.maximum(col - 1, 0)) != 1) & (
                read(side, np.minimum(col + 1, width - 1)) != 1
            )
        at, row, col = at[keep], row[keep], col[keep]
    out = np.zeros(rows.size, dtype=bool)
    out[at] = True
    return out


def _front_at(
    code: npt.NDArray[np.uint8],
    out: npt.NDArray[np.uint8],
    row: int,
    col0: int,
    col1: int,
    span: int,
    anchor: int,
    face: int,
    crossing: int,
    stub: int,
    *,
    slack: int = 0,
    shallowest: int = 0,
    parallel: bool = False,
) -> bool:
    """The checks of one candidate gap ``row, col0:col1`` (the furniture below it) and, when it
    passes (returns True), its line, front and inside in ``out``; with ``slack`` (a straightened
    staircase) the gap's first and last ``slack + 1`` columns may open to the room (a side face a
    column off); with ``shallowest``, the front (the depth most columns share) at least that many
    cells from the line; with ``parallel``, every column's front (but a wall meeting it) within a
    cell of that depth (in the exact rows only: asked of the straightened ones too, it lost the
    turned logs' furniture, their clutter removed 0.845 -> 0.800)."""
    height, width = code.shape
    max_depth = span - 1
    # The hidden line: no occupied cell (a wall stretch would end the gap), and at most half its
    # cells seen free: beams grazing the wall behind the furniture cross its line here and there (a
    # wall at an angle to the grid leaves cells of the line free between its steps), but a line seen
    # free for the most part is an opening, not a wall. A beam that ran along the line itself, its
    # free cells between unseen ones across it (the outside beyond, the furniture's inside before),
    # saw no opening: such cells count as unseen (:func:`_beam_along`).
    on_line = code[row, col0:col1]
    if row + 1 >= height or (on_line >= 2).any():
        return False
    if (
        2 * np.count_nonzero(on_line == 1) > on_line.size
    ):  # (rare: only then are the beams looked at)
        free_cols = np.flatnonzero(on_line == 1)
        seen = ~_beam_along(code, np.full(free_cols.size, row), col0 + free_cols)
        if 2 * np.count_nonzero(seen) > on_line.size:
            return False
    lo, hi = max(col0 - anchor, 0), min(col1 + anchor, width)
    below = code[row + 1 : row + 1 + span, lo:hi] == 1
    # Furniture rarely stands quite flush: a beam grazing the wall passes through the slit between
    # its back and the wall, a free cell next to the line with the furniture right behind it. That
    # cell is no room in front of the line (the room is wider). Straightened, where such a slit at
    # an angle to the grid is sampled one or two rows wide, only within the gap once its ends are
    # found: beside it such a cell is the room beside a side face a column off.
    slit_rows = np.zeros(below.shape, dtype=bool)
    if below.shape[0] > 1 + slack:
        slit_rows[: 1 + slack] = below[: 1 + slack] & ~below[1 + slack]
    if not slack:
        below &= ~slit_rows
    # Occupied or unknown cells below each column, down to free space (``span``: none near).
    depth = np.where(below.any(axis=0), below.argmax(axis=0), span)
    if slack:
        # A staircase's side face a column or two off the wall's end: free space reaches the line
        # there, beside the object, not in front of it.
        for _ in range(slack + 1):
            if col1 - col0 > 1 and depth[col0 - lo] <= face:
                col0 += 1
            if col1 - col0 > 1 and depth[col1 - 1 - lo] <= face:
                col1 -= 1
        inner = slice(col0 - lo, col1 - lo)
        # (A slit runs along the furniture's back: a free cell beside the line in a few columns
        # is the room reaching in at a wall's step or a corner.)
        if 2 * np.count_nonzero(slit_rows[:, inner].any(axis=0)) >= col1 - col0:
            gap = below[:, inner] & ~slit_rows[:, inner]
            depth[inner] = np.where(gap.any(axis=0), gap.argmax(axis=0), span)
    d = depth[col0 - lo : col1 - lo]
    # Deeper than a wall face everywhere (else the "front" is the wall itself, the line the
    # unknown behind it), no deeper than furniture. Straightened, by two cells more: the grown
    # row, and a wall bending off the line by a cell (a single wall is no object).
    if d.min() <= face + 2 * slack:
        return False
    deep = d > max_depth
    shallow = ~deep
    if not shallow.any():
        return False
    # A wall meeting the object: columns reaching farther than the front (the depth most
    # columns share) by more than a wall face, in a stretch no wider than a wall (a partition
    # ending on a cabinet's front, or crossing the hidden line between two objects), not at the
    # ends. Wider stretches are a deeper object, refused when they reach beyond the depth limit
    # (unless the front itself lies within a wall face of it: then they are not told apart).
    reached = d[shallow]  # the front's depth in each column that has one
    front = _median(reached)
    if front < shallowest:
        return False
    farther = np.zeros(d.size + 2, dtype=np.int8)
    farther[1:-1] = d > front + face
    edges = np.flatnonzero(farther[1:] != farther[:-1])
    starts, ends = edges[::2], edges[1::2]
    walls = ends - starts <= crossing
    stubs = np.zeros(d.size, dtype=bool)
    for start, end, wall in zip(starts.tolist(), ends.tolist(), walls.tolist(), strict=True):
        if wall:
            stubs[start:end] = True
        elif deep[start:end].any():
            return False
    if stubs[0] or stubs[-1]:
        return False
    if parallel and not slack and (np.abs(d[~deep & ~stubs] - front) > 1).any():
        return False
    # The last cell before free space is occupied: a front face, not a shadow's edge, in nine
    # columns of ten (a scan leaves single holes in a front). Walls at an angle to the grid are
    # staircases once rotated onto the rows: :func:`_flush_fronts` reads them straightened too.
    cols = np.arange(col0, col1)[shallow]
    if np.count_nonzero(code[row + reached, cols] >= 2) / cols.size < _FRONT_FACE_SHARE:
        return False
    # An inside a scanner did not see, behind the front: a solid piece reaching from the wall
    # into the room is the wall's own stub or pilaster (no scan sees into furniture).
    behind = code[row + 1 : row + 1 + front, col0:col1][:, shallow]
    if 2 * np.count_nonzero((behind == 0).any(axis=0)) < behind.shape[1]:
        return False
    out[row, col0:col1] |= 1
    # The object: the gap's columns and its side faces (up to ``face`` columns beyond each end,
    # where they too are deeper than a wall face) down to free space.
    first, last = col0, col1
    while first > lo and col0 - first < face and face < depth[first - 1 - lo] <= max_depth:
        first -= 1
    while last < hi and last - col1 < face and face < depth[last - lo] <= max_depth:
        last += 1
    reach = depth[first - lo : last - lo]
    reach = np.where(reach > max_depth, 0, reach)
    # The walls meeting it stay (a cell wider each side), and their hidden part, from the line
    # to the front, is drawn along their sides.
    wall = np.zeros(last - first, dtype=bool)
    wall[col0 - first : col1 - first] = stubs
    if stubs.any():
        wall = np.convolve(wall, np.ones(3), mode="same") > 0
        reach[wall] = 0
        for start, end in zip(starts[walls].tolist(), ends[walls].tolist(), strict=True):
            for col in (col0 + start, col0 + end - 1):
                out[row + 1 : row + 1 + front, col] |= np.where(
                    code[row + 1 : row + 1 + front, col] == 0, 1, 0
                ).astype(np.uint8)
            # The wall's cells, from the line to its end (up to a run's length past the front:
            # a longer one is a run already), where it leaves the object and the free space.
            cells = code[row + 1 : row + 1 + span + stub, col0 + start - 1 : col0 + end + 1]
            past = np.cumsum(cells == 1, axis=0) > 0
            out[row + 1 : row + 1 + cells.shape[0], col0 + start - 1 : col0 + end + 1] |= np.where(
                (cells >= 2) & ~past, 8, 0
            ).astype(np.uint8)
    if reach.max() == 0:
        return True
    block = code[row + 1 : row + 1 + int(reach.max()), first:last]
    within = np.arange(block.shape[0])[:, None] < reach
    out[row + 1 : row + 1 + block.shape[0], first:last] |= np.where(
        within, np.where(block == 0, 4, 2), 0
    ).astype(np.uint8)
    return True


def _median(values: npt.NDArray[np.int64]) -> int:
    """``int(np.median(values))`` of non-negative integers (not empty), in a sixth of its time
    (called once per candidate gap or corner)."""
    ordered = np.sort(values)
    return int(ordered[(values.size - 1) // 2] + ordered[values.size // 2]) // 2


def _corners_rows(
    code: npt.NDArray[np.uint8],
    out: npt.NDArray[np.uint8],
    anchors: tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]],
    max_len: int,
    min_depth: int,
    span: int,
    anchor: int,
    face: int,
    crossing: int,
    stub: int,
) -> None:
    """Furniture in a room's corner, along the rows of ``code``: a wall stretch (``anchors``: the
    flat indices of the last and of the first cells of the occupied runs long enough to anchor a
    line) ending in unknown cells, its line hidden behind furniture up to a perpendicular wall
    (:func:`_corner_at`), in either direction along the row, the furniture on either side of it."""
    height, width = code.shape
    flat_code = code.reshape(-1)
    # The last cell of a stretch going right, the first going left, with an unknown cell beyond.
    for step, end in zip((1, -1), anchors, strict=True):
        col = end % width
        end = end[(col < width - 1) if step == 1 else (col > 0)]
        end = end[flat_code[end + step] == 0]
        rows, beyond = end // width, end % width + step
        for sign in (1, -1):
            # Cheap tests first, on a few cells of each candidate: the wall's end faces the room
            # on this side (as both ends of a gap must: free space within a wall face of most of
            # its last ``anchor`` cells), and the furniture starts right beyond it (free space
            # there no nearer than the shallowest front, but for a cell of a scan's noise, and no
            # farther than the deepest).
            across = np.minimum(
                np.maximum(rows[:, None, None] + sign * np.arange(1, face + 1)[:, None], 0),
                height - 1,
            )
            along = np.minimum(
                np.maximum(beyond[:, None] - step * np.arange(1, anchor + 1), 0), width - 1
            )
            facing = (code[across, along[:, None, :]] == 1).any(axis=1).sum(axis=1)
            down = np.minimum(
                np.maximum(rows[:, None] + sign * np.arange(1, span + 1), 0), height - 1
            )
            free = code[down, beyond[:, None]] == 1
            depth = np.where(free.any(axis=1), free.argmax(axis=1), span)
            # The line runs on unseen for more than an anchor's length (the furniture's width, at
            # least: :func:`_corner_at`): on the Bormann maps, nearly half the candidates are not.
            ahead = np.minimum(
                np.maximum(beyond[:, None] + step * np.arange(anchor + 1), 0), width - 1
            )
            unseen = (code[rows[:, None], ahead] == 0).all(axis=1)
            chosen = (
                (2 * facing >= anchor)
                & (depth >= max(face + 1, min_depth - 1))
                & (depth < span)
                & unseen
            )
            # Rows and columns flipped so that the furniture lies below and the line runs right
            # (views, no copies).
            view, written = code[::sign, ::step], out[::sign, ::step]
            for row, start in zip(rows[chosen].tolist(), beyond[chosen].tolist(), strict=True):
                _corner_at(
                    view,
                    written,
                    row if sign == 1 else height - 1 - row,
                    start if step == 1 else width - 1 - start,
                    (max_len, min_depth, span),
                    anchor,
                    face,
                    crossing,
                    stub,
                )


def _corner_at(
    code: npt.NDArray[np.uint8],
    out: npt.NDArray[np.uint8],
    row: int,
    col0: int,
    lengths: tuple[int, int, int],
    anchor: int,
    face: int,
    crossing: int,
    stub: int,
) -> None:
    """One candidate corner: the wall along ``row`` ends at ``col0 - 1`` (facing the room below:
    :func:`_corners_rows` checked) and runs on unseen from ``col0``, with furniture below it up to
    the first column no front reaches (``col1``). That column must be the room's other wall,
    perpendicular: a stretch of at least ``anchor`` occupied cells from just past the furniture's
    front on, facing the room on the furniture's side; the corner of the two wall lines lies behind
    the furniture. The front must be parallel to the line and at least ``min_depth`` cells from it.
    Then the gap ``col0:col1`` is checked as a gap between two wall ends (:func:`_front_at`: fronts,
    depth, an unseen inside) and, when it passes, the other wall's hidden part, from the line to the
    front, is drawn too, and the first wall's visible end is kept. ``lengths``: the longest line
    (``max_len``), the shallowest front (``min_depth``) and ``span`` (the deepest front plus one),
    in cells."""
    max_len, min_depth, span = lengths
    height, width = code.shape
    if row + 1 >= height or col0 >= width:
        return
    # The unseen stretch of the line (it runs on past the corner, unseen, into the outside).
    line = code[row, col0 : col0 + max_len + 1] == 0
    n = line.size if line.all() else int(line.argmin())
    below = code[row + 1 : row + 1 + span, col0 : col0 + n] == 1
    depth = np.where(below.any(axis=0), below.argmax(axis=0), span)
    deep = np.flatnonzero(depth >= span)
    if deep.size == 0 or deep[0] < anchor:
        return
    col1 = col0 + int(deep[0])
    front = _median(depth[: deep[0]])
    # A front parallel to the line, as furniture set against a wall has, every column within a
    # cell of it (a scan's noise; a wall a few degrees off the grid, running off from the wall's
    # end, reaches the room at ever other depths), and deeper than a wall's step.
    if front < min_depth or (np.abs(depth[: deep[0]] - front) > 1).any():
        return
    # The other wall: occupied from just past the front on, an anchor's length, with free space
    # within a wall face of it on the furniture's side (a wall facing the room, not the outside).
    top = row + front + 1
    if top + anchor > height:
        return
    wall = code[top : top + anchor, col1] >= 2
    sees = (code[top : top + anchor, max(col1 - face, 0) : col1] == 1).any(axis=1)
    if not wall.all() or 2 * int(sees.sum()) < anchor:
        return
    if not _front_at(code, out, row, col0, col1, span, anchor, face, crossing, stub):
        return
    # The corner: the line on to the other wall's line, and that wall, from the line down to the
    # front (only the unknown cells are drawn: :func:`_flush_fronts` masks the line).
    out[row:top, col1] |= 1
    # The first wall's visible end is a wall (the line's anchor), up to a run's length from the
    # object and as thick as it is solid, up to a wall face (``face`` cells): kept, though the line
    # may now close off a thick wall's unknown core, which the object-face rule reads as a scanned
    # object's inside (its faces went).
    behind = (slice(max(row - face + 1, 0), row + 1), slice(max(col0 - stub, 0), col0))
    _mark_solid(out[behind][::-1, ::-1], code[behind][::-1, ::-1] >= 2)


def _mark_solid(out: npt.NDArray[np.uint8], solid: npt.NDArray[np.bool_]) -> None:
    """Bit 3 (a wall, kept) in ``out`` on the cells of ``solid`` joined to its first cell: along its
    first row while solid, and across from each of those cells while solid (a wall's length and,
    from its face, its thickness)."""
    if solid.size == 0 or not solid[0, 0]:
        return
    length = solid.shape[1] if solid[0].all() else int(solid[0].argmin())
    deep = np.cumprod(solid[:, :length], axis=0).astype(bool)
    out[:, :length] |= np.where(deep, 8, 0).astype(np.uint8)
