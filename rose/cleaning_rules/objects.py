"""Scanned objects and pieces: faces around unknown pockets, free-standing pieces, partitions seen from
both sides, the wall stubs attached to kept walls, and the objects the topology guard judges one by
one.

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import math
from concurrent.futures import Future
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from rose.cleaning_rules.masks import (
    _any_of_8,
    _cells_box,
    _dilate,
    _flat_index,
    _grown_through,
    _nonzero_flat,
    _padded_box,
    length_px,
)
from rose.cleaning_rules.runs import _run_cells, _runs
from rose.labelling import (
    component_areas,
    components,
    fill_from_corner,
    label_boxes,
    labels_looked_up,
)

if TYPE_CHECKING:
    from collections.abc import Callable

    from rose.cleaning import CleanParams


#: Shortest partition kept (metres, :func:`_partitions`): door frames and wall pieces between a
#: corner and a door, shorter than a run; a scanned table leg or chair is smaller.
_PARTITION_MIN_M = 0.5


#: Thickest partition (metres, :func:`_partitions`): both faces and the unseen core between them,
#: counted along a grid row or column from the known free cells on one side to those on the other.
#: Interior walls are 0.1-0.3 m thick; a scanner sees a thick one as two faces around an unknown
#: core, which looks like an object's faces around its inside, and the object rules took such
#: walls (and hollow wall ends, door jambs) for furniture. Furniture is rarely less than 0.3 m
#: deep and a scanned object's inside is unknown up to its back, which is against a wall or seen
#: from the room: across a cabinet no row or column runs from free space to free space within
#: 0.3 m. Along a grid axis a wall at an angle is thicker (1.15x at 30 degrees). Measured
#: (``bench_cleaning.py``): 0.25 m kept 260 fewer wall cells on the logs turned by 30 degrees;
#: 0.4 m kept 313 more Bormann furniture cells (worst clutter removed at 30 degrees 0.717 ->
#: 0.693) for no more ray-cast wall recall.
_THIN_WALL_M = 0.3


#: Occupied cells that are no thin run between a partition's thin cells and the wall it meets
#: (:func:`_partitions`): an unknown pocket beside a wall stub, or an unseen corner at its foot,
#: breaks its thin runs for a cell or two.
_MEETING_PX = 2


#: Thickest partition in cells at any resolution (:func:`_partitions`): on a coarse grid a thin wall
#: rasterises up to 3 cells thick (0.6 m at 0.2 m per cell), as the rule before ``_THIN_WALL_M``
#: read it at every resolution; at 0.05 m per cell ``_THIN_WALL_M`` is 6 cells and decides.
_THIN_WALL_MIN_CELLS = 3


#: Side of the solid square that makes a free-standing piece a drawn column, not an object
#: (metres, at least 3 cells; :func:`_free_standing`): thicker than a scanned surface. A scanner
#: sees an object's faces, one to three cells thick in a SLAM map, and the two faces of a thin
#: object (a shelf, a chair's rim) meet in a solid strip of a few cells: 3 x 3 cells (0.15 m) kept
#: 4,560 furniture cells of the 19 Bormann benchmark buildings (10 wall cells). A solid piece is
#: left to the paper's labelling (kept where it says structure); an I-beam drawn as its flanges (the
#: nav2 depot's, 0.55 m across, flanges 0.1-0.15 m thick) is no solid square and goes as an object.
_SOLID_MIN_M = 0.25


#: Widest door (metres, :func:`_between_doors`): single doors are 0.7-1.0 m wide, wide ones 1.2 m.
_DOOR_MAX_M = 1.2


#: Dashes followed one after another from a kept wall (:func:`_closing_walls`).
_DASHES_MAX = 8


#: Wall in line beyond a door that makes a piece between two doors a wall (metres,
#: :func:`_between_doors`): a stretch a table's edge lined up with a wall rarely continues.
_DOOR_ANCHOR_M = 0.3


def _free_standing(
    pieces_job: Future[_Pieces],
    lines: npt.NDArray[np.bool_],
    near_outside: Future[npt.NDArray[np.bool_]],
    unknown: npt.NDArray[np.bool_],
    res: float,
    p: CleanParams,
) -> npt.NDArray[np.bool_]:
    """Occupied cells of free-standing pieces (``pieces_job``'s): no cell on a run or ``lines`` or
    near wide unknown (``near_outside``; both jobs submitted before this one) even across a gap of
    up to two cells, and a joined box with a diagonal shorter than a wall run: clutter, whatever
    the paper's labelling says."""
    import cv2

    pieces = pieces_job.result()
    occupied = pieces.occupied
    anchored = lines | (occupied & near_outside.result())
    # A solid square (0.25 m) is a drawn column or wall, not the faces a scanner sees of an object.
    side = max(3, math.ceil(length_px(_SOLID_MIN_M, res)))
    solid = cv2.erode(occupied.view(np.uint8), np.ones((side, side), np.uint8), borderValue=0)
    dropped = pieces.loose(anchored | solid.view(bool), length_px(p.min_run_m, res))
    # ... unless it closes around known free space: a small room or shaft, not an object (a
    # scanned object's inside stays unknown).
    return dropped & ~pieces.around_free(dropped, ~unknown)


def _between_doors(
    pieces: _Pieces,
    removed: npt.NDArray[np.bool_],
    walls: npt.NDArray[np.bool_],
    free: npt.NDArray[np.bool_],
    directions: npt.NDArray[np.float64],
    res: float,
) -> npt.NDArray[np.bool_]:
    """Cells of the pieces of ``removed`` (whole pieces of ``pieces``) that continue a wall across
    two doors: :func:`_in_line` with known ``free`` cells beyond each end for at most
    ``_DOOR_MAX_M``. A pier between two doors of a partition is such a piece; furniture rarely
    lines up with walls at both ends across doorways (``bench_cleaning.py``: no furniture cell of
    the benchmarks kept by it; with pieces as long as thick, 52 cells of office_e's chairs were)."""
    door = max(2, math.ceil(length_px(_DOOR_MAX_M, res)))
    return _in_line(
        pieces, removed, walls, free, directions, res, gap_px=door, ends=2, dashed=False
    )


def _closing_walls(
    pieces: _Pieces,
    loose: npt.NDArray[np.bool_],
    walls: npt.NDArray[np.bool_],
    free: npt.NDArray[np.bool_],
    directions: npt.NDArray[np.float64],
    res: float,
    *,
    robot_px: int,
) -> npt.NDArray[np.bool_]:
    """Cells of the pieces of ``loose`` that continue a wall across a gap a robot cannot pass
    (:func:`_in_line` with free cells beyond one end for fewer than ``robot_px``, the wall dashed
    or not, the piece a dash of any length), one dash after another: a dashed wall's dashes past
    the last one kept. The topology guard counts them as obstacles of the input, not as
    furniture: taken for furniture, a dashed wall's last 0.55 m went and joined a 3.5 m² room to a
    lab (a real map at 0.05 m, docs/cleaning.md, 2026-12-07)."""
    return _in_line(
        pieces,
        loose,
        walls,
        free,
        directions,
        res,
        gap_px=robot_px - 1,
        ends=1,
        dashed=True,
        rounds=_DASHES_MAX,
    )


def _in_line(
    pieces: _Pieces,
    removed: npt.NDArray[np.bool_],
    walls: npt.NDArray[np.bool_],
    free: npt.NDArray[np.bool_],
    directions: npt.NDArray[np.float64],
    res: float,
    *,
    gap_px: int,
    ends: int,
    dashed: bool,
    rounds: int = 1,
) -> npt.NDArray[np.bool_]:
    """Cells of the pieces of ``removed`` (whole pieces of ``pieces``) along a dominant direction at
    most ``_THIN_WALL_M`` thick and at least 4 cells and twice as long as thick, with known
    ``free`` cells beyond ``ends`` of their ends (1: either, 2: both) for at most ``gap_px`` cells
    and then ``walls`` in line for ``_DOOR_ANCHOR_M``: every cell of it, or with ``dashed`` half
    of them (a dashed wall's dashes and gaps). With ``rounds`` more than one, again and again (at
    most ``rounds`` times, until a round finds nothing) with the cells found so far among the
    ``walls`` and no longer among the ``removed`` cells.

    The pieces' geometry along each direction is worked out once, and so are the cells past
    their ends and what ``walls`` and ``free`` hold there (:class:`_Rays`): the pieces left in a
    round are the same cells, in the same order, as in the first, and only the cells found so far
    change between rounds. They are read by flat index with the walls, not merged into a full-map
    copy of them each round."""
    out = np.zeros(removed.shape, dtype=bool)
    in_removed = removed.reshape(-1)[pieces.cells]
    if directions.size == 0 or not in_removed.any() or gap_px < 1:
        return out
    cells, _, starts, stops = _cells_by_piece(pieces.cells, pieces.owners, in_removed)
    sizes = stops - starts
    rows, cols = np.divmod(cells, removed.shape[1])
    anchor = max(2, math.ceil(length_px(_DOOR_ANCHOR_M, res)))
    thin = max(_THIN_WALL_MIN_CELLS, length_px(_THIN_WALL_M, res))
    steps = np.arange(1, gap_px + anchor + 1, dtype=np.float64)
    # The masks read by flat index at the cells looked at (C order; a copy only for another one).
    walls_flat, free_flat = walls.reshape(-1), free.reshape(-1)
    # Per direction: the pieces of the right shape, where each one's row of rays is (-1: none),
    # and the rays past both ends of each (beyond the high end forwards, the low end backwards).
    frames = []
    for angle in directions:
        along = np.array([math.cos(angle), math.sin(angle)])  # (col, row): the wall's direction
        across = np.array([-along[1], along[0]])
        a = cols * along[0] + rows * along[1]
        n = cols * across[0] + rows * across[1]
        low, high = np.minimum.reduceat(a, starts), np.maximum.reduceat(a, starts)
        width = np.maximum.reduceat(n, starts) - np.minimum.reduceat(n, starts) + 1
        # (A hair of slack: the projections of cells on a grid axis carry rounding errors.)
        length = high - low + 1 + 1e-6
        # (A dash may be as short as a cell, but no thicker than long.)
        shortest = np.maximum(width, 1) if dashed else np.maximum(2 * width, 4)
        shaped = np.flatnonzero((width <= thin + 1e-6) & (length >= shortest))
        if shaped.size == 0:
            continue
        row_of = np.full(starts.size, -1, dtype=np.intp)
        row_of[shaped] = np.arange(shaped.size)
        middle = np.add.reduceat(n, starts)[shaped] / sizes[shaped]
        rays = _Rays.past(
            np.concatenate([high[shaped], low[shaped]]),
            np.tile(middle, 2),
            steps,
            np.repeat([True, False], shaped.size),
            along,
            across,
            walls_flat,
            free_flat,
            walls.shape,
        )
        frames.append((row_of, shaped.size, rays))
    pending = np.ones(starts.size, dtype=bool)  # pieces not found in an earlier round
    found_flat: npt.NDArray[np.bool_] | None = None  # the cells found so far, flat
    for _ in range(rounds):
        kept = np.zeros(starts.size, dtype=bool)
        for row_of, shaped_count, rays in frames:
            candidate = np.flatnonzero((row_of >= 0) & pending & ~kept)
            if candidate.size == 0:
                continue
            # Both ends in one look: the high ends' rays first, then the low ends'.
            slots = row_of[candidate]
            found = _door_then_wall(
                rays
                if slots.size == shaped_count  # (all of them, in order)
                else rays.picked(np.concatenate([slots, slots + shaped_count])),
                gap_px,
                anchor,
                min_hits=-(-anchor // 2) if dashed else anchor,
                also=found_flat,
            )
            hits = found[: candidate.size].astype(np.intp) + found[candidate.size :]
            kept[candidate[hits >= ends]] = True
        if not kept.any():
            break
        pending &= ~kept
        if found_flat is None:
            found_flat = np.zeros(walls_flat.size, dtype=bool)
        found_flat[cells[np.repeat(kept, sizes)]] = True
    if found_flat is not None:
        out.reshape(-1)[cells[np.repeat(~pending, sizes)]] = True
    return out


@dataclass(frozen=True)
class _Rays:
    """Rays of cells past pieces' ends, each ``steps`` cells along the wall direction and three
    cells across it (the line and a cell either side): their flat indices ``at`` (0 off the
    grid), shape ``(N, steps, 3)``; which are ``walls`` cells (``on_wall``, not off the grid);
    which cells of the line are ``free`` (``open_``, shape ``(N, steps)``); and which are on the
    grid (``inside``; None when all are)."""

    at: npt.NDArray[np.intp]
    inside: npt.NDArray[np.bool_] | None
    on_wall: npt.NDArray[np.bool_]
    open_: npt.NDArray[np.bool_]

    @classmethod
    def past(
        cls,
        end: npt.NDArray[np.float64],
        middle: npt.NDArray[np.float64],
        steps: npt.NDArray[np.float64],
        forwards: npt.NDArray[np.bool_],
        along: npt.NDArray[np.float64],
        across: npt.NDArray[np.float64],
        walls: npt.NDArray[np.bool_],
        free: npt.NDArray[np.bool_],
        shape: tuple[int, int],
    ) -> _Rays:
        """The rays past pieces ending at ``end`` (along the wall direction) on the line
        ``middle`` (across it), forwards or backwards along the direction as ``forwards`` says.
        ``walls`` and ``free``: masks of ``shape`` flattened (C order)."""
        # (end - steps is end + -steps, exactly.)
        t = np.where(forwards[:, None], end[:, None] + steps, end[:, None] - steps)[:, :, None]
        s = middle[:, None, None] + np.array([-1.0, 0.0, 1.0])
        col = t * along[0] + s * across[0]
        row = t * along[1] + s * across[1]
        np.rint(col, out=col)
        np.rint(row, out=row)
        rows, cols = shape
        # The flat index worked out in floats (whole numbers far below 2**53: exact), converted
        # once.
        flat = row * cols
        flat += col
        at = flat.astype(np.intp)
        inside: npt.NDArray[np.bool_] | None = None
        if not (row.min() >= 0 and row.max() < rows and col.min() >= 0 and col.max() < cols):
            inside = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
            at[~inside] = 0
        on_wall = walls[at]
        open_ = free[at[:, :, 1]]
        if inside is not None:
            on_wall &= inside
            open_ &= inside[:, :, 1]
        return cls(at, inside, on_wall, open_)

    def picked(self, index: npt.NDArray[np.intp]) -> _Rays:
        """The rays at ``index``, in that order."""
        return _Rays(
            self.at[index],
            None if self.inside is None else self.inside[index],
            self.on_wall[index],
            self.open_[index],
        )


def _door_then_wall(
    rays: _Rays,
    door: int,
    anchor: int,
    *,
    min_hits: int,
    also: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.bool_]:
    """For each of the ``rays`` past a piece's end: whether its line's cells are free for at most
    ``door`` cells and then wall cells (of the ray's walls, or of ``also``: more wall cells, a
    flattened mask as theirs, or None) in ``min_hits`` of the next ``anchor`` cells, within a
    cell of the line."""
    on_wall = rays.on_wall
    if also is not None:
        more = also[rays.at]
        if rays.inside is not None:
            more &= rays.inside
        on_wall = on_wall | more
    wall = on_wall[:, :, 0] | on_wall[:, :, 1] | on_wall[:, :, 2]
    size = wall.shape[1]
    hit = np.argmax(wall, axis=1)
    reached = wall.any(axis=1) & (hit >= 1) & (hit <= door)
    before = np.arange(size)[None, :] < hit[:, None]
    clear = np.all(rays.open_ | ~before, axis=1)
    after = (np.arange(size)[None, :] >= hit[:, None]) & (
        np.arange(size)[None, :] < hit[:, None] + anchor
    )
    anchored = np.sum(wall & after, axis=1) >= min_hits
    return reached & clear & anchored


def _thin_runs(
    solid: npt.NDArray[np.bool_],
    seen: Callable[[npt.NDArray[np.int64]], npt.NDArray[np.bool_]],
    max_px: float,
) -> npt.NDArray[np.int64]:
    """Flat indices of the cells of ``solid`` in a run along a grid row or column of at most
    ``max_px`` cells with a free cell just before and just after it: a wall at most that thick,
    seen from both sides (a cell in such a run along both axes is listed twice). ``seen`` tells
    which of the cells at the given flat indices are free (asked about the runs' ends only).
    Worked out on the solid cells' runs (few next to the whole image)."""
    shape = solid.shape
    cells = _nonzero_flat(np.ascontiguousarray(solid).view(np.uint8))
    out = []
    for vertical in (False, True):
        line, first, last = _runs(cells, shape, vertical)
        extent = shape[0] if vertical else shape[1]
        thin = (last - first + 1 <= max_px) & (first > 0) & (last < extent - 1)
        line, first, last = line[thin], first[thin], last[thin]
        before = seen(_flat_index(line, first - 1, shape, vertical))
        line, first, last = line[before], first[before], last[before]
        after = seen(_flat_index(line, last + 1, shape, vertical))
        out.append(_run_cells((line[after], first[after], last[after]), shape, vertical))
    return np.concatenate(out)


def _room_at(
    free: npt.NDArray[np.bool_], cores: npt.NDArray[np.bool_], cells: npt.NDArray[np.int64]
) -> npt.NDArray[np.bool_]:
    """Which of ``cells`` (flat indices into C-contiguous masks) are ``free`` and, if next to
    (4-neighbours of) a ``cores`` cell, in a 2 x 2 square of free cells."""
    room = free.reshape(-1)[cells]
    at = cells[room]
    flat, index, width = _framed(cores, at)
    near = (
        flat[index] | flat[index - width] | flat[index + width] | flat[index - 1] | flat[index + 1]
    )
    if near.any():
        flat, index, width = _framed(free, at[near])
        up, down = flat[index - width], flat[index + width]
        left, right = flat[index - 1], flat[index + 1]
        square = (
            up & left & flat[index - width - 1]
            | up & right & flat[index - width + 1]
            | down & left & flat[index + width - 1]
            | down & right & flat[index + width + 1]
        )
        near[near] = ~square
        room[room] = ~near
    return room


def _framed(
    mask: npt.NDArray[np.bool_], cells: npt.NDArray[np.int64]
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.int64], int]:
    """``flat, at, width``: ``flat[at + dr * width + dc]`` is ``mask`` (C-contiguous) ``dr`` rows
    and ``dc`` columns (at most one each) from each of ``cells`` (flat indices into it), False past
    its edge. ``mask`` itself unless a cell is on its edge (then a copy in a frame of one cell)."""
    rows, cols = mask.shape
    row, col = np.divmod(cells, cols)
    if cells.size == 0 or (
        row.min() > 0 and row.max() < rows - 1 and col.min() > 0 and col.max() < cols - 1
    ):
        return mask.reshape(-1), cells, cols
    return np.pad(mask, 1).reshape(-1), (row + 1) * (cols + 2) + col + 1, cols + 2


def _partitions(
    occupied: npt.NDArray[np.bool_],
    walls: npt.NDArray[np.bool_],
    free: npt.NDArray[np.bool_],
    cores: npt.NDArray[np.bool_],
    *,
    min_length_px: float,
    max_thickness_px: float,
    attached: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.bool_]:
    """Occupied cells not in ``walls`` (the candidates) in 8-connected pieces of thin cells that
    meet ``walls`` (:func:`_meeting_walls`) and span at least ``min_length_px`` cells, or are
    straight and hold or touch ``attached`` cells, or continue such a piece across an unknown
    pocket beside it (:func:`_continued`), with the candidates next to them.

    Thin cells (:func:`_thin_runs`) are the candidates and ``cores`` cells (unknown pockets: an
    object's inside or a thick wall's unseen core) on a run of occupied and core cells at most
    ``max_thickness_px`` long between two free cells: a wall seen from both sides, solid or with
    an unseen core. ``free``: known cells that are not occupied (a probabilistic grid's free space
    is 0..20, not only 0). ``attached``: cells of ``walls`` the attach rule kept (within its reach
    of a wall); thin ones count towards a piece's length, so that a partition 0.5 m long stays
    whole, not only its first ``attach_reach_m``. A shorter piece that holds or touches some of
    them is kept whole too when it is straight (no wider than ``max_thickness_px`` across): the attach rule keeps
    its first ``attach_reach_m`` anyway, and the rest alone was cut off it (a wall stub's end,
    where the paper's scores fade; a door frame 5-18 cm short). A round bin against a wall is
    not straight: the attach rule keeps its side at the wall, as before."""
    import cv2

    out = np.zeros(occupied.shape, dtype=bool)
    candidates = occupied & ~walls
    if not candidates.any() or not walls.any():
        return out
    # A free cell next to a pocket counts only in a 2 x 2 square of free cells: single free cells
    # there are slivers between an object's inside and its face, or a beam that got into the
    # inside, not the room behind a wall (without this, a cabinet's front at 10 degrees to the
    # grid stayed, and ray-cast boxes whose insides beams crossed). Looked up at the runs' ends
    # only (a few thousand cells).
    thin = _thin_runs(
        occupied | cores, lambda cells: _room_at(free, cores, cells), max_thickness_px
    )
    # The thin cells among the candidates, the cores and the attached walls.
    sides = candidates | cores
    if attached is not None:
        sides |= attached
    thin = thin[sides.reshape(-1)[thin]]
    if thin.size == 0:
        return out
    row, col = np.divmod(thin, occupied.shape[1])
    box = _cells_box(row, col, occupied.shape, 1 + _MEETING_PX)
    sided = np.zeros(occupied[box].shape, dtype=bool)
    sided[row - box[0].start, col - box[1].start] = True
    count, labels = components(sided)
    at = _nonzero_flat(sided.view(np.uint8))
    owners = labels.reshape(-1)[at]
    boxes = label_boxes(labels, at, count)
    long_enough = np.maximum(boxes[:, 2], boxes[:, 3]) >= min_length_px
    if attached is not None:
        # Holding attached cells or next to one (4-neighbours): a wall stub's end may meet the
        # attached part across a row that is no thin run (free space beside it only next to an
        # unknown pocket, which the sliver guard does not count).
        partly = np.zeros(count, dtype=bool)
        near_attached = cv2.dilate(attached[box].view(np.uint8), _CROSS).view(bool)
        partly[owners[near_attached.reshape(-1)[at]]] = True
        partly[0] = False
        np.greater(partly, long_enough, out=partly)
        long_enough |= _straight_pieces(at, owners, partly, labels.shape[1], max_thickness_px)
    wanted = long_enough & _meeting_walls(walls[box], occupied[box], at, owners, long_enough)
    if attached is not None:
        # Across the rows by a pocket only: there the free side does not count (the sliver
        # guard), so they are no thin run. Elsewhere a piece parted from the kept ones is
        # furniture beside them (joined across any occupied cells, it kept 30-degree clutter
        # 0.852 -> 0.847 on the benchmark).
        by_pockets = cv2.dilate(cores[box].view(np.uint8), np.ones((5, 5), np.uint8)).view(bool)
        wanted |= _continued(
            attached[box],
            occupied[box] & by_pockets,
            at,
            owners,
            wanted,
            labels.shape[1],
            max_thickness_px,
        )
    candidates = candidates[box]
    cells = at[wanted[owners] & candidates.reshape(-1)[at]]
    pieces = np.zeros(sided.shape, dtype=bool)
    pieces.reshape(-1)[cells] = True
    # A run along a row misses the cells of a ragged face that stick out of it: the candidate
    # cells next to a piece belong to it (4-neighbours, looked up around the piece's cells).
    beside = _cross(cells, labels.shape)
    pieces[beside] |= candidates[beside]
    out[box] = pieces
    return out


def _straight_pieces(
    at: npt.NDArray[np.intp],
    owners: npt.NDArray[np.integer],
    wanted: npt.NDArray[np.bool_],
    width: int,
    max_thickness_px: float,
) -> npt.NDArray[np.bool_]:
    """Which labelled pieces are straight: the ``wanted`` ones (bool per label) whose cells (flat
    indices ``at`` into an image ``width`` cells wide, labels ``owners``) fit in a rectangle at any
    angle at most ``max_thickness_px`` cells across (the rectangle of the cells' centres plus a
    cell)."""
    out = np.zeros(wanted.shape, dtype=bool)
    if not wanted.any():
        return out
    cells, labels, starts, ends = _cells_by_piece(at, owners, wanted[owners])
    if cells.size == 0:
        return out
    rows, cols = np.divmod(cells, width)
    # A piece whose centres' axis-aligned box has an area at most ``(max_thickness_px - 1)**2``
    # is straight without OpenCV's rectangle: the smallest-area rectangle is no larger, and its
    # narrower side at most the square root of its area (a hundredth to spare for its float32
    # sums). Most pieces are (about 150 of 180 a map).
    span = np.maximum.reduceat(rows, starts) - np.minimum.reduceat(rows, starts)
    span *= np.maximum.reduceat(cols, starts) - np.minimum.reduceat(cols, starts)
    sure = span * 1.01 <= (max_thickness_px - 1) ** 2
    out[labels[starts[sure]]] = True
    # The centres of the other pieces' cells made once: made piece by piece they cost as much as
    # the rectangles.
    points = _centres(rows, cols)
    for start, end in zip(starts[~sure].tolist(), ends[~sure].tolist(), strict=True):
        out[labels[start]] = _centres_width(points[start:end]) <= max_thickness_px
    return out


def _continued(
    attached: npt.NDArray[np.bool_],
    through: npt.NDArray[np.bool_],
    at: npt.NDArray[np.intp],
    owners: npt.NDArray[np.integer],
    wanted: npt.NDArray[np.bool_],
    width: int,
    max_thickness_px: float,
) -> npt.NDArray[np.bool_]:
    """Which labelled pieces (cells ``at``, flat indices into an image ``width`` cells wide,
    labels ``owners``) not ``wanted`` continue a kept stub: joined through up to
    :data:`_MEETING_PX` ``through`` cells to ``attached`` cells or to a piece kept so
    (``wanted``, or continuing one), and in line with what they are joined to nearby: the two
    together no wider (:func:`_width_of`) than the wider of them alone plus a cell, nor than
    ``max_thickness_px``. A stub's end beyond an unknown pocket beside it:
    the rows by the pocket are no thin run (its free side does not count there), so the end was
    a piece of its own, too short for a partition and touching nothing kept. A round bin's far
    face, joined to its kept near face round its inside, is no stub's end: not in line."""
    import cv2

    out = np.zeros(wanted.shape, dtype=bool)
    seeds = attached.copy()
    seeds.reshape(-1)[at[wanted[owners]]] = True
    left = ~wanted
    left[0] = False
    cells, labels, starts, ends = _cells_by_piece(at, owners, left[owners])
    if cells.size == 0:  # (no piece to continue one)
        return out
    rows, cols = np.divmod(cells, width)
    points = _centres(rows, cols)  # (made once, as in _straight_pieces)
    # The pieces' boxes at once: a piece's own four reductions cost more than all of these.
    low_rows, low_cols = np.minimum.reduceat(rows, starts), np.minimum.reduceat(cols, starts)
    high_rows, high_cols = np.maximum.reduceat(rows, starts), np.maximum.reduceat(cols, starts)
    margin = _MEETING_PX + 1
    grown_from = seeds
    grow_box = (slice(0, seeds.shape[0]), slice(0, seeds.shape[1]))
    while True:
        # Only the pieces joined to a seed (the new ones after the first round) through at
        # least one of the ``through`` cells: those touching one were judged by the caller.
        # Each is then looked at in its own window.
        joined = _grown_through(grown_from, through[grow_box], _MEETING_PX)
        reached = cv2.dilate(joined, _CROSS).view(bool)
        top, left_col = grow_box[0].start, grow_box[1].start
        in_box = (
            (rows >= top)
            & (rows < grow_box[0].stop)
            & (cols >= left_col)
            & (cols < grow_box[1].stop)
        )
        hits = np.zeros(rows.shape, dtype=bool)
        hits[in_box] = reached[rows[in_box] - top, cols[in_box] - left_col]
        close = _pieces_with(starts, hits)
        found = []
        for k in np.flatnonzero(close):
            label = labels[starts[k]]
            if not left[label]:
                continue
            r, c = rows[starts[k] : ends[k]], cols[starts[k] : ends[k]]
            alone = _centres_width(points[starts[k] : ends[k]])
            if alone > max_thickness_px:  # bent: no straighter with more cells
                left[label] = False
                continue
            # The piece's window with a thin wall's width to spare (the seed's cells in line with
            # it) beyond the joining cells' reach.
            r0, c0, window = _window_of(
                int(low_rows[k]),
                int(high_rows[k]),
                int(low_cols[k]),
                int(high_cols[k]),
                math.ceil(max_thickness_px) + margin,
            )
            piece = np.zeros(seeds[window].shape, dtype=np.uint8)
            piece[r - r0, c - c0] = 1
            reach = _grown_through(piece, through[window], _MEETING_PX) | piece
            near = cv2.dilate(reach, _CROSS).view(bool) & seeds[window]
            if not near.any():
                continue
            # The seed cells joined to the piece: their 8-connected parts in the window.
            count, parts = components(seeds[window])
            touched = np.zeros(count, dtype=bool)
            touched[parts[near]] = True
            touched[0] = False
            seed = touched[parts]
            # In line: no wider together than the wider of the two alone (a cell to spare for
            # a staircase), within a thin wall's width. A stub's end continues its kept foot; a
            # cabinet's side meets the kept face it stands at an angle to.
            line = _width(seed | reach.view(bool))  # (the piece is within its reach)
            # (The seed's own width only when the piece's alone does not decide.)
            if line <= max_thickness_px and (
                line <= alone + 1 or line <= max(_width(seed), alone) + 1
            ):
                found.append(k)
        if not found:
            return out
        for k in found:
            label = labels[starts[k]]
            out[label] = True
            left[label] = False
        # The next round grows from the pieces found only: within the joining cells' reach and
        # the cross (a cell) of them, on their box that much wider, not over the whole image.
        new_rows = np.concatenate([rows[starts[k] : ends[k]] for k in found])
        new_cols = np.concatenate([cols[starts[k] : ends[k]] for k in found])
        seeds[new_rows, new_cols] = True
        grow_box = _cells_box(new_rows, new_cols, seeds.shape, margin)
        grown_from = np.zeros(
            (grow_box[0].stop - grow_box[0].start, grow_box[1].stop - grow_box[1].start),
            dtype=bool,
        )
        grown_from[new_rows - grow_box[0].start, new_cols - grow_box[1].start] = True


def _window_around(
    rows: npt.NDArray[np.integer], cols: npt.NDArray[np.integer], pad: int
) -> tuple[int, int, tuple[slice, slice]]:
    """``(r0, c0, window)``: the box of the cells at ``rows``, ``cols`` with ``pad`` cells more on
    every side (clipped at 0; slicing clips the far side), its first row and column."""
    return _window_of(int(rows.min()), int(rows.max()), int(cols.min()), int(cols.max()), pad)


def _window_of(
    low_row: int, high_row: int, low_col: int, high_col: int, pad: int
) -> tuple[int, int, tuple[slice, slice]]:
    """:func:`_window_around` cells whose rows are ``low_row..high_row`` and columns
    ``low_col..high_col``."""
    r0, c0 = max(low_row - pad, 0), max(low_col - pad, 0)
    return r0, c0, (slice(r0, high_row + pad + 1), slice(c0, high_col + pad + 1))


def _pieces_with(
    starts: npt.NDArray[np.intp], hits: npt.NDArray[np.bool_]
) -> npt.NDArray[np.bool_]:
    """Which pieces hold a hit: ``hits`` per cell of pieces laid end to end (:func:`_cells_by_piece`:
    piece ``k`` from ``starts[k]``), a bool per piece."""
    out = np.zeros(len(starts), dtype=bool)
    out[np.searchsorted(starts, np.flatnonzero(hits), side="right") - 1] = True
    return out


def _width(mask: npt.NDArray[np.bool_]) -> float:
    """:func:`_width_of` the ``True`` cells of ``mask``."""
    return _width_of(*np.nonzero(mask))


def _width_of(row: npt.NDArray[np.integer], col: npt.NDArray[np.integer]) -> float:
    """Width of the cells at ``row``, ``col``: the narrower side of the smallest rectangle at any
    angle around their centres, plus a cell (cells)."""
    return _centres_width(_centres(row, col))


def _centres(row: npt.NDArray[np.integer], col: npt.NDArray[np.integer]) -> npt.NDArray[np.float32]:
    """The centres of the cells at ``row``, ``col`` as OpenCV's points: ``(x, y)`` = ``(col, row)``,
    float32, shape ``(N, 2)``."""
    return np.stack([col, row], axis=1).astype(np.float32)


def _centres_width(points: npt.NDArray[np.float32]) -> float:
    """:func:`_width_of` the cells whose :func:`_centres` are ``points`` (cells)."""
    import cv2

    (_, _), (w, h), _ = cv2.minAreaRect(points)
    return float(min(w, h)) + 1.0


def _cells_by_piece(
    at: npt.NDArray[np.intp], owners: npt.NDArray[np.integer], chosen: npt.NDArray[np.bool_]
) -> tuple[
    npt.NDArray[np.intp], npt.NDArray[np.integer], npt.NDArray[np.intp], npt.NDArray[np.intp]
]:
    """The ``chosen`` cells of ``at`` (bool per cell; labels ``owners``) grouped by piece:
    ``(cells, labels, starts, ends)``, piece ``k``'s cells ``cells[starts[k]:ends[k]]``, its label
    ``labels[starts[k]]``; pieces in label order, cells in their order in ``at``."""
    cells, labels = at[chosen], owners[chosen]
    order = np.argsort(labels, kind="stable")
    cells, labels = cells[order], labels[order]
    starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
    return cells, labels, starts, np.r_[starts[1:], len(cells)]


def _meeting_walls(
    walls: npt.NDArray[np.bool_],
    occupied: npt.NDArray[np.bool_],
    at: npt.NDArray[np.intp],
    owners: npt.NDArray[np.integer],
    eligible: npt.NDArray[np.bool_],
) -> npt.NDArray[np.bool_]:
    """Which labelled pieces (cells ``at``, flat indices into ``walls``' image, labels ``owners``)
    meet ``walls``: a cell on or next to (4-neighbours) a wall, or joined to one through up to
    :data:`_MEETING_PX` ``occupied`` cells that are no thin run (beside an unknown pocket the free
    space does not count, and a partition's foot at an unseen corner is thicker than the limit).
    An ``eligible`` piece that meets them counts as a wall for the others: a stub broken twice
    by pockets is met piece by piece from the wall it stands on. Label 0 never meets."""
    import cv2

    near_walls = cv2.dilate(walls.view(np.uint8), _CROSS).view(bool).reshape(-1)[at]
    met = np.zeros(eligible.shape, dtype=bool)
    met[owners[near_walls]] = True
    met[0] = False
    pending = eligible & ~met
    if not pending.any():
        return met
    walls = walls.copy()
    walls.reshape(-1)[at[(eligible & met)[owners]]] = True
    cells, labels, starts, ends = _cells_by_piece(at, owners, pending[owners])
    rows, cols = np.divmod(cells, walls.shape[1])
    margin = _MEETING_PX + 1
    reach_square = np.ones((2 * margin + 1, 2 * margin + 1), np.uint8)
    left = np.arange(len(starts))
    # (The pieces left as flags: numpy's setdiff1d of the ones found sorted them every round.)
    alive = np.ones(len(starts), dtype=bool)
    while left.size:
        # Most pieces are far from every wall: only those with a wall within the margin are
        # looked at, each in its own small window (a growth over the whole image per round cost
        # 10-15 % of the cleaning).
        near = cv2.dilate(walls.view(np.uint8), reach_square).view(bool)[rows, cols]
        close = _pieces_with(starts, near)
        found = []
        for k in left[close[left]]:
            r, c = rows[starts[k] : ends[k]], cols[starts[k] : ends[k]]
            r0, c0, window = _window_around(r, c, margin)
            reach = _grown_through(walls[window], occupied[window], _MEETING_PX)
            if cv2.dilate(reach, _CROSS)[r - r0, c - c0].any():
                found.append(k)
        if not found:
            break
        for k in found:
            met[labels[starts[k]]] = True
            walls[rows[starts[k] : ends[k]], cols[starts[k] : ends[k]]] = True
        alive[found] = False
        left = np.flatnonzero(alive)
    return met


#: The 4-neighbours and the cell itself: a 3 x 3 elliptic kernel.
_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)


def _cross(
    cells: npt.NDArray[np.intp], shape: tuple[int, int]
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """Row and column indices of each cell (flat indices into an image of ``shape``) and of its 4
    neighbours, shape ``(N, 5)``: the cross a 3 x 3 elliptic kernel dilates by. A neighbour past
    the image's edge is the cell itself (one of the five anyway)."""
    rows, cols = shape
    row, col = np.divmod(cells, cols)
    up, down = np.maximum(row - 1, 0), np.minimum(row + 1, rows - 1)
    left, right = np.maximum(col - 1, 0), np.minimum(col + 1, cols - 1)
    return (
        np.stack([row, up, down, row, row], axis=1),
        np.stack([col, col, col, left, right], axis=1),
    )


def _pocket_faces(
    unknown: npt.NDArray[np.bool_],
    sealing: npt.NDArray[np.bool_],
    occupied: npt.NDArray[np.bool_],
    max_area_px: float,
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Occupied cells next to (8-neighbours of) a pocket, and the pockets' cells. A pocket is a
    4-connected component of unknown cells (the ``sealing`` cells are a boundary) smaller than
    ``max_area_px``: the inside of a scanned object, or the unseen core of a thick wall."""
    import cv2

    cells = np.greater(unknown, sealing)
    if not cells.any() or not occupied.any():
        return np.zeros(occupied.shape, dtype=bool), np.zeros(occupied.shape, dtype=bool)
    count, labels = components(cells, connectivity=4)
    pocket = component_areas(labels, count) < max_area_px
    pocket[0] = False
    large = np.flatnonzero(~pocket[1:]) + 1
    if large.size <= _FEW_LARGE:
        # The unknown cells without the few large regions (2-4 on the session maps: the outside
        # and unexplored rooms), compared one by one: half the cost of the lookup. (Not by
        # OpenCV's compare with a number: on an image of 4 x 1 cells it reads the number as a
        # 4-vector.)
        kept = cells.copy()
        for label in large.tolist():
            np.greater(kept, labels == label, out=kept)
        pockets = kept.view(np.uint8)
    else:
        # Unknown cells are most of the image here: a lookup at every cell (0, the background, is
        # no pocket) is a third of the cost of one at the unknown cells only (labels_wanted).
        pockets = labels_looked_up(pocket, labels).view(np.uint8)
    # The occupied cells with a pocket among their 8 neighbours: the pockets dilated by the ring
    # around a cell (half the cost of looking the neighbours' labels up at the occupied cells).
    faces = cv2.dilate(pockets, _RING).view(bool) & occupied
    # On the image's edge a cell counts itself among its neighbours (those past the edge clipped
    # onto the image, as the 8-neighbour lookups of the rules do). Only a cell both occupied and
    # in a pocket can gain by it, which the cleaning never passes; kept so that the function is
    # the lookup's exactly.
    for edge in ((0, slice(None)), (-1, slice(None)), (slice(None), 0), (slice(None), -1)):
        faces[edge] |= pockets[edge].view(bool) & occupied[edge]
    return faces, pockets.view(bool)


#: Large unknown regions (:func:`_pocket_faces`) taken off the unknown cells one by one, at most
#: (two passes of OpenCV's each); more take a lookup of every label.
_FEW_LARGE = 8


#: The 8 neighbours of a cell, not the cell itself.
_RING = np.array([[1, 1, 1], [1, 0, 1], [1, 1, 1]], np.uint8)


def _backed_by_outside(
    pieces: _Pieces,
    loose: npt.NDArray[np.bool_],
    unknown: npt.NDArray[np.bool_],
    outside: npt.NDArray[np.bool_],
    straight_walls: npt.NDArray[np.bool_],
    *,
    robot_px: int,
) -> npt.NDArray[np.bool_]:
    """Cells of ``loose`` (pieces of ``pieces``) in pieces between the room and the outside where a
    wall runs on past them: within ``robot_px`` cells of ``straight_walls`` (kept cells on straight
    runs), and next to ``unknown`` cells within ``robot_px`` steps (through unknown cells) of
    ``outside`` (the wide unknown space).

    The wall behind them was not seen, and no hidden line was drawn there (an unseen stretch longer
    than a bridge, behind a cabinet and a box side by side; a wall holed too often for a bridge's
    anchor): they kept the room apart from the outside. Kept cells that are no straight wall (the
    returns along an open explored edge, kept as the building's edge) do not count: a box standing
    there closes nothing."""
    none = np.zeros(loose.shape, dtype=bool)
    if not straight_walls.any() or not outside.any():
        return none
    near_walls = pieces.facing(loose, _dilate(straight_walls, robot_px))
    if not near_walls.any():
        return near_walls
    # The unknown cells a robot's width from the outside, grown only within ``robot_px + 1``
    # cells of the candidates (a path of ``robot_px`` steps from a cell next to them stays
    # there): grown over the whole grid, every unseen shadow and object inside was a cell to
    # look at.
    # (On the candidates' groups' boxes side by side, ``pad`` wider, a third of their common
    # box: within ``pad`` of its cells a group's box sees every cell that matters to them. The
    # cells a box grows are never more than over the whole image, so their union is exact next
    # to the candidates, the only cells read.)
    from rose.cleaning_rules.outside import _side_by_side

    pad = 2 * robot_px + 3
    boxes, width = _side_by_side(
        _nonzero_flat(near_walls.view(np.uint8)), near_walls.shape, pad, robot_px + 3
    )
    height = max(box[0].stop - box[0].start for box, _, _ in boxes)
    candidates = np.zeros((height, width), dtype=bool)
    seeds = np.zeros((height, width), dtype=bool)
    through = np.zeros((height, width), dtype=bool)
    for box, at, _ in boxes:
        candidates[at] = near_walls[box]
        seeds[at] = outside[box]
        through[at] = unknown[box]
    around = _dilate(candidates, robot_px + 1)
    grown = _grow_within(seeds & around, through & around, robot_px)
    behind = none
    for box, at, _ in boxes:
        behind[box] |= grown[at]
    return pieces.facing(near_walls, behind)


def _grow_within(
    seed: npt.NDArray[np.bool_], mask: npt.NDArray[np.bool_], steps: int
) -> npt.NDArray[np.bool_]:
    """Cells of ``mask`` within ``steps`` 8-connected steps of ``seed`` through ``mask``.

    Step by step from the cells reached last only: a step reaches a few hundred cells, and a
    dilation of the whole image per step cost several times more."""
    out = seed & mask
    if steps <= 0:
        return out
    rows, cols = mask.shape
    # 0 outside ``mask``, 1 not reached yet, 2 reached; a frame of zeros around the image, so
    # that the 8 neighbours of a cell are flat offsets from it.
    width = cols + 2
    state = np.zeros((rows + 2, width), dtype=np.uint8)
    np.add(mask.view(np.uint8), out.view(np.uint8), out=state[1:-1, 1:-1])
    flat = state.reshape(-1)
    around = np.array([-width - 1, -width, -width + 1, -1, 1, width - 1, width, width + 1])
    waiting = _nonzero_flat(np.equal(state, 1).view(np.uint8))
    reached = waiting[_any_of_8(flat[waiting[:, None] + around] == 2)]
    for step in range(steps):
        if reached.size == 0:
            break
        flat[reached] = 2
        if step + 1 < steps:
            # Only cells next to those just reached can be reached by the next step.
            near = (reached[:, None] + around).reshape(-1)
            reached = np.unique(near[flat[near] == 1])
    return state[1:-1, 1:-1] == 2


@dataclass(frozen=True)
class _Pieces:
    """The 8-connected pieces of occupied cells, joined across gaps of up to ``2 * join_px``
    cells, labelled once for several questions."""

    occupied: npt.NDArray[np.bool_]
    labels: npt.NDArray[np.integer]
    cells: npt.NDArray[np.intp]  # flat indices of the occupied cells (fewer than the image's)
    owners: npt.NDArray[np.integer]  # the joined piece of each of them
    diagonals: npt.NDArray[np.float64]  # of each joined piece's bounding box, cells
    box_areas: npt.NDArray[np.float64]  # of the same boxes, cells
    # The smaller of each box's area and that of its box along a dominant direction of the map,
    # cells (a piece's box in the map's own frame: the grid's box of a piece turned with the map
    # is up to twice as large).
    frame_areas: npt.NDArray[np.float64]

    @classmethod
    def of(
        cls,
        occupied: npt.NDArray[np.bool_],
        *,
        join_px: int,
        directions: npt.NDArray[np.float64] | None = None,
        cells: npt.NDArray[np.intp] | None = None,
    ) -> _Pieces:
        """The pieces of ``occupied``; with ``directions`` (the map's dominant directions) their
        boxes along those directions too (:attr:`frame_areas`). ``cells``: the flat indices of the
        occupied cells, ascending, when listed already (other pieces' :attr:`cells`)."""
        import cv2

        grown = occupied
        if join_px > 0:
            kernel = np.ones((3, 3), np.uint8)
            grown = cv2.dilate(occupied.view(np.uint8), kernel, iterations=join_px).view(bool)
        count, labels = components(grown)
        if cells is None:
            cells = _nonzero_flat(np.ascontiguousarray(occupied).view(np.uint8))
        owners = labels.reshape(-1)[cells]
        # A joined piece is its occupied cells grown by ``join_px`` (clipped by the image), and so
        # is its box: boxed from the occupied cells (fewer than the grown ones). The background's
        # box (no occupied cell) stays empty. The cells sorted by piece once, for these boxes
        # and those along the directions: a third of the cost of label_boxes' four ufunc.at.
        rows, cols = occupied.shape
        x, y, box_width, box_height = np.zeros((4, count), dtype=np.int64)
        order = np.argsort(owners, kind="stable")
        owned = owners[order]
        row, col = np.divmod(cells[order], cols)
        starts: npt.NDArray[np.intp] = np.empty(0, dtype=np.intp)
        if owned.size:
            starts = np.flatnonzero(np.r_[True, owned[1:] != owned[:-1]])
        ids = owned[starts]
        if owned.size:
            # (A piece's rows ascend: the cells do, and the sort is stable.)
            ends = np.r_[starts[1:], owned.size] - 1
            y[ids] = row[starts]
            box_height[ids] = row[ends] + 1 - row[starts]
            first = np.minimum.reduceat(col, starts)
            x[ids] = first
            box_width[ids] = np.maximum.reduceat(col, starts) + 1 - first
        grow = join_px * (box_width > 0)
        left, top = np.maximum(x - grow, 0), np.maximum(y - grow, 0)
        width = (np.minimum(x + box_width + grow, cols) - left).astype(np.float64)
        height = (np.minimum(y + box_height + grow, rows) - top).astype(np.float64)
        areas = width * height
        framed = areas
        if directions is not None and directions.size:
            along = _frame_box_areas(row, col, starts, ids, count, directions, join_px)
            framed = np.minimum(areas, along)
        return cls(occupied, labels, cells, owners, np.hypot(width, height), areas, framed)

    def loose(
        self,
        anchored: npt.NDArray[np.bool_],
        max_extent_px: float = math.inf,
        max_box_area_px: float = math.inf,
        max_frame_area_px: float = 0,
    ) -> npt.NDArray[np.bool_]:
        """Occupied cells of pieces with no ``anchored`` cell whose (joined) bounding box has a
        diagonal shorter than ``max_extent_px`` and an area under ``max_box_area_px``, or whose
        box along the map's directions (:attr:`frame_areas`) is under ``max_frame_area_px``."""
        attached = (self.diagonals >= max_extent_px) | (
            (self.box_areas >= max_box_area_px) & (self.frame_areas >= max_frame_area_px)
        )
        attached[self.owners[anchored.reshape(-1)[self.cells]]] = True
        attached[0] = True
        out = np.zeros(self.occupied.shape, dtype=bool)
        out.reshape(-1)[self.cells] = ~attached[self.owners]
        return out

    def seen_round(
        self, cells: npt.NDArray[np.bool_], unknown: npt.NDArray[np.bool_]
    ) -> npt.NDArray[np.bool_]:
        """Cells of ``cells`` (occupied cells, some of the pieces') in pieces whose ring (the cells
        next to their ``cells``, not occupied) is free for more than half: seen from more than one
        side, as furniture standing in a room is, not one face of a wall with unknown space
        behind."""
        out = np.zeros(cells.shape, dtype=bool)
        if not cells.any():
            return out
        import cv2

        box = _padded_box(cells, 1)
        inner = cells[box]
        ring = cv2.dilate(inner.view(np.uint8), np.ones((3, 3), np.uint8)).view(bool)
        ring &= ~self.occupied[box]
        # The ring lies in the pieces as joined (grown by at least one cell), so it bears their
        # labels.
        labels = self.labels[box]
        count = self.diagonals.size
        around = np.bincount(labels[ring], minlength=count)
        free = np.bincount(labels[ring & ~unknown[box]], minlength=count)
        seen = 2 * free > around
        seen[0] = False
        out[box] = inner & seen[labels]
        return out

    def facing(
        self, cells: npt.NDArray[np.bool_], space: npt.NDArray[np.bool_]
    ) -> npt.NDArray[np.bool_]:
        """Cells of ``cells`` (occupied cells, some of the pieces') in pieces one of whose
        ``cells`` is next to (8-connected) a cell of ``space``."""
        out = np.zeros(cells.shape, dtype=bool)
        # The cells are few (a few hundred, spread over most of the image): listed once, their
        # neighbours and labels are looked up by flat offsets, not in passes over their box
        # (0.57 against about 0.1 ms per call on the session maps).
        at = _nonzero_flat(np.ascontiguousarray(cells).view(np.uint8))
        if at.size == 0:
            return out
        rows, cols = cells.shape
        if at[0] < cols or at[-1] >= (rows - 1) * cols or not _off_sides(at, cols):
            return self._facing_on_box(cells, space)
        flat = np.ascontiguousarray(space).reshape(-1)
        near = flat[at - cols - 1]
        for offset in (-cols, -cols + 1, -1, 0, 1, cols - 1, cols, cols + 1):
            near |= flat[at + offset]
        owners = self.labels.reshape(-1)[at]
        facing = np.zeros(self.diagonals.size, dtype=bool)
        facing[owners[near]] = True
        facing[0] = False
        out.reshape(-1)[at] = facing[owners]
        return out

    def _facing_on_box(
        self, cells: npt.NDArray[np.bool_], space: npt.NDArray[np.bool_]
    ) -> npt.NDArray[np.bool_]:
        """:meth:`facing` in passes over the box of ``cells`` (some on the image's edge, where
        the flat offsets would wrap)."""
        import cv2

        out = np.zeros(cells.shape, dtype=bool)
        box = _padded_box(cells, 1)
        inner = cells[box]
        near = cv2.dilate(space[box].view(np.uint8), np.ones((3, 3), np.uint8)).view(bool)
        labels = self.labels[box]
        facing = np.zeros(self.diagonals.size, dtype=bool)
        facing[labels[inner & near]] = True
        facing[0] = False
        out[box] = inner & facing[labels]
        return out

    def around_free(
        self, cells: npt.NDArray[np.bool_], known: npt.NDArray[np.bool_]
    ) -> npt.NDArray[np.bool_]:
        """Cells of ``cells`` (occupied cells, some of the pieces') in pieces next to a hole of
        ``cells`` (other cells that 4-connected paths cannot leave without crossing ``cells``)
        holding a known non-occupied cell."""
        out = np.zeros(cells.shape, dtype=bool)
        if not cells.any():
            return out
        import cv2

        # Only the box of ``cells`` matters (a cell wider: its rim is outside space, which
        # reaches the image's edge past no cell). Flood the outside from a one-cell frame around
        # it: what stays unflooded of the other cells are the holes (one pass; no labelling
        # unless a hole holds known free space).
        box = _padded_box(cells, 1)
        image = np.asarray(  # (uint8 as it is: typed for fill_from_corner, no copy)
            cv2.copyMakeBorder(
                (~cells[box]).view(np.uint8), 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=1
            ),
            dtype=np.uint8,
        )
        fill_from_corner(image, 4)  # (OpenCV's flood fill, right on any size)
        # The holes are few cells (up to about 150 on the session maps) spread over much of the
        # pieces' box: listed, and labelled on a compact image of them (:func:`_compacted`), not
        # over their box (0.27 ms a call). Their rim lies in the box (holes never reach its edge:
        # the frame's flood would have reached them), so their 8 neighbours are in the image.
        hole = _nonzero_flat(image)
        if hole.size == 0:
            return out
        row, col = np.divmod(hole, image.shape[1])
        row += box[0].start - 1
        col += box[1].start - 1
        free_holes = known[row, col] & ~self.occupied[row, col]
        if not free_holes.any():
            return out
        small_row, rows_used = _compacted(row)
        small_col, cols_used = _compacted(col)
        small = np.zeros((rows_used, cols_used), dtype=np.uint8)
        small[small_row, small_col] = 1
        count, parts = components(small, connectivity=4)
        part = parts[small_row, small_col]
        wanted = np.zeros(count, dtype=bool)
        wanted[part[free_holes]] = True
        wanted[0] = False
        in_wanted = wanted[part]
        # The rim: the cells of ``cells`` among the wanted holes' 8 neighbours.
        offsets = np.array([-1, -1, -1, 0, 0, 1, 1, 1]), np.array([-1, 0, 1, -1, 1, -1, 0, 1])
        rim = row[in_wanted, None] + offsets[0], col[in_wanted, None] + offsets[1]
        enclosing = np.zeros(self.diagonals.size, dtype=bool)
        enclosing[self.labels[rim][cells[rim]]] = True
        enclosing[0] = False
        # Looked up at the occupied cells (``cells`` are some of them).
        out.reshape(-1)[self.cells] = enclosing[self.owners] & cells.reshape(-1)[self.cells]
        return out


def _compacted(values: npt.NDArray[np.integer]) -> tuple[npt.NDArray[np.intp], int]:
    """Each of ``values`` (rows or columns of some cells) renumbered from 0, the values in use in
    their order with one unused value kept between two that are not consecutive, and how many
    numbers that takes: cells placed so in a small image are 4- and 8-neighbours exactly when they
    were."""
    used, index = np.unique(values, return_inverse=True)
    compact = np.arange(used.size)
    compact[1:] += np.cumsum(np.diff(used) > 1)
    return compact[index], int(compact[-1]) + 1


def _off_sides(at: npt.NDArray[np.intp], cols: int) -> bool:
    """Whether none of the cells at the flat indices ``at`` (of an image ``cols`` wide) lies in
    the first or last column: their 8 neighbours are then flat offsets that do not wrap."""
    column = at % cols
    return bool(column.min() > 0 and column.max() < cols - 1)


def _objects_among_others(
    pieces: _Pieces,
    loose: npt.NDArray[np.bool_],
    anchored: npt.NDArray[np.bool_],
    unknown: npt.NDArray[np.bool_],
    pockets: npt.NDArray[np.bool_],
    *,
    reach_px: int,
    max_box_area_px: float,
    inside_px: float,
) -> npt.NDArray[np.bool_]:
    """Occupied cells of scanned objects standing apart from kept walls, each judged alone even
    where it stands close to others.

    ``pieces`` are the 8-connected pieces of the occupied cells, not joined across gaps. An object
    is a piece, none of whose cells is ``loose`` already, with a bounding box under
    ``max_box_area_px``, its faces around an unseen inside (along grid rows, or along grid
    columns, two of its cells with at least ``inside_px`` cells between them, all unknown:
    nothing seen between two faces, on two lines or more, and some of them in an object
    ``pocket``), and no ``anchored`` cell within ``reach_px`` cells (Chebyshev) of it.

    Joined across gaps of a cell or two (as the guard's loose pieces are), boxes standing close
    together make one piece whose box is too large to be loose, and the guard kept each of them
    for the passages between its neighbours. Judged alone, each is an object: a scanner sees it
    as faces around its unseen inside, and an inside at least 0.3 m across (``_THIN_WALL_M``) is
    no wall's core. On two lines or more: between two hits of a ragged piece at the explored
    edge an unknown stretch on one line is a notch, not an inside (Freiburg 079 stage 3 lost 83
    cells of its explored edge with one line). docs/cleaning.md has the measurements.
    """
    out = np.zeros(loose.shape, dtype=bool)
    count = pieces.box_areas.size
    if count <= 1 or not pockets.any():
        return out
    small = pieces.box_areas < max_box_area_px
    small[0] = False
    small[pieces.owners[loose.reshape(-1)[pieces.cells]]] = False
    chosen = small[pieces.owners]
    cells = pieces.cells[chosen]
    owners = pieces.owners[chosen]
    if cells.size < 2:
        return out
    unseen = unknown.reshape(-1)
    pocket = pockets.reshape(-1)
    cols = loose.shape[1]
    good = np.zeros(count, dtype=bool)
    for step in (1, cols):
        # The pieces' cells in order along each row (``step`` 1) or column (``step`` cols); two
        # in a row of the same piece with ``inside_px`` cells or more between them, none of
        # the piece's, may be two faces with its inside between them.
        if step == 1:
            line, flat, owner = cells // cols, cells, owners
        else:
            # (By column, then row: the cells ascend, so a stable sort by column alone.)
            order = np.argsort(cells % cols, kind="stable")
            flat, owner = cells[order], owners[order]
            line = flat % cols
        gap = (flat[1:] - flat[:-1]) // step - 1
        pair = np.flatnonzero(
            (line[1:] == line[:-1]) & (owner[1:] == owner[:-1]) & (gap >= inside_px)
        )
        if pair.size == 0:
            continue
        length = gap[pair]
        which = np.repeat(np.arange(pair.size), length)
        first = np.repeat(flat[pair] + step - step * (np.cumsum(length) - length), length)
        between = first + step * np.arange(int(length.sum()))
        all_unseen = np.bincount(which, unseen[between], pair.size) == length
        in_pocket = np.bincount(which, pocket[between], pair.size) > 0
        # Lines (not pairs) with such a stretch, per piece.
        lines = line.max() + 1
        across = np.bincount(
            np.unique(owner[pair][all_unseen].astype(np.int64) * lines + line[pair][all_unseen])
            // lines,
            minlength=count,
        )
        reaching = np.zeros(count, dtype=bool)
        reaching[owner[pair][all_unseen & in_pocket]] = True
        good |= reaching & (across >= 2)
    good[0] = False
    if not good.any():
        return out
    out.reshape(-1)[cells[good[owners]]] = True
    # No anchored cell within reach: looked at on the objects' box only (a few of the cells).
    import cv2

    box = _padded_box(out, reach_px)
    size = 2 * reach_px + 1
    near = cv2.dilate(anchored[box].view(np.uint8), np.ones((size, size), np.uint8)).view(bool)
    good[np.unique(pieces.labels[box][near & out[box]])] = False
    good[0] = False
    # Looked up at the objects' cells only (a few), not at every label of their box.
    at = _nonzero_flat(out.view(np.uint8))
    out.reshape(-1)[at] = good[pieces.labels.reshape(-1)[at]]
    return out


def _frame_box_areas(
    rows: npt.NDArray[np.int64],
    cols: npt.NDArray[np.int64],
    starts: npt.NDArray[np.intp],
    ids: npt.NDArray[np.integer],
    count: int,
    directions: npt.NDArray[np.float64],
    join_px: int,
) -> npt.NDArray[np.float64]:
    """The area of each piece's box along each of ``directions`` (the cells at ``rows``, ``cols``,
    sorted by piece: piece ``ids[i]``'s from ``starts[i]`` on; grown by ``join_px``), the smallest
    of them; infinite for a label that owns no cell."""
    out = np.full(count, np.inf)
    if rows.size == 0:
        return out
    r = rows.astype(np.float64)
    c = cols.astype(np.float64)
    for angle in directions:
        cos, sin = math.cos(angle), math.sin(angle)
        along = c * cos + r * sin
        across = r * cos - c * sin
        width = np.maximum.reduceat(along, starts) - np.minimum.reduceat(along, starts)
        height = np.maximum.reduceat(across, starts) - np.minimum.reduceat(across, starts)
        areas = (width + 1 + 2 * join_px) * (height + 1 + 2 * join_px)
        out[ids] = np.minimum(out[ids], areas)
    return out
