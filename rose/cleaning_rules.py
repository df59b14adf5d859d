"""The rules of the ``"walls"`` cleaning (:func:`rose.cleaning.clean`): runs, open unknown, topology guard.

Everything works on boolean masks of shape ``(rows, cols)`` in the grid's cell space (row 0 at the map
origin); lengths are in cells here, converted from metres by the caller. OpenCV does the morphology
and labelling (imported lazily, like the wall extraction).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from concurrent.futures import Executor, Future
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, ParamSpec, TypeVar

import numpy as np
import numpy.typing as npt

from rose.grid import UNKNOWN
from rose.labelling import (
    component_areas,
    components,
    label_boxes,
    labels_wanted,
)

if TYPE_CHECKING:
    from collections.abc import Callable

    from rose.cleaning import CleanParams
    from rose.result import RoseResult

_P = ParamSpec("_P")
_T = TypeVar("_T")

__all__ = [
    "directional_runs",
    "length_px",
    "passable",
    "straight_lines",
    "topology_guard",
    "wall_cells",
    "wide_unknown",
]

#: Shortest stretch of wall, along a gap, that a hidden wall is drawn from (metres): a wall's end,
#: not the side face of an object across the gap.
_BRIDGE_ANCHOR_M = 0.25

#: Hidden walls between wall ends a cell apart across the line (a scanned wall's staircase, a wall
#: at an angle to its rotated frame): each end a stretch at least this long within a band three
#: cells wide (twice the exact anchor: a steep wall's staircase also makes short stretches in such a
#: band), and each hidden stretch at least ``_BRIDGE_ANCHOR_M`` long (shorter ones are the notches of
#: a staircase, beside the wall, not a wall hidden behind furniture).
_STAGGERED_ANCHOR_M = 2 * _BRIDGE_ANCHOR_M

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

#: Directions closer than this to a right angle of each other share one rotated frame.
_PAIR_TOLERANCE_RAD = math.radians(3.0)


def wall_cells(
    occupancy: npt.NDArray[np.int8],
    result: RoseResult,
    *,
    resolution_m: float,
    params: CleanParams,
) -> tuple[
    npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]
]:
    """Occupied cells the ``"walls"`` cleaning keeps, those among them only the guard keeps, the
    unknown cells completed as hidden walls, and the cells removed whatever the paper says.

    Returns
    -------
    walls : ndarray of bool, shape (rows, cols)
        Kept cells (the paper's structure among them, except the ``dropped`` cells).
    guarded : ndarray of bool, shape (rows, cols)
        Cells restored by the topology guard.
    completed : ndarray of bool, shape (rows, cols)
        Unknown cells to make walls: the wall line hidden behind removed furniture.
    dropped : ndarray of bool, shape (rows, cols)
        Object faces and occupied cells of free-standing pieces: removed even where the paper
        calls them structure.
    """
    p = params
    res = resolution_m
    if not result.occupied.any():
        return _nothing_kept(occupancy.shape)
    # Everything happens near known cells: work on their bounding box, padded so that every window
    # and disc that matters fits (outside it all cells are unknown).
    pad = 2 + max(
        round(length_px(p.guard_window_m, res)) + math.ceil(length_px(p.robot_radius_m, res)),
        math.ceil(length_px(p.open_unknown_width_m, res))
        + round(length_px(p.unknown_margin_m, res)),
    )
    rows, cols = occupancy.shape
    r0, r1, c0, c1 = _bounds(occupancy >= 0)
    r0, c0, r1, c1 = r0 - pad, c0 - pad, r1 + pad, c1 + pad
    window = (slice(max(r0, 0), min(r1, rows)), slice(max(c0, 0), min(c1, cols)))
    # Beyond the grid lies unknown space, as around a map with a margin of unknown cells: a map
    # cropped tight against its outer wall must clean as the same map with that margin (its wall
    # next to a narrow strip of unknown cells at the edge was not "near wide unknown" and went).
    beyond = ((max(-r0, 0), max(r1 - rows, 0)), (max(-c0, 0), max(c1 - cols, 0)))
    kept, restored, added, removed = (
        out[beyond[0][0] : out.shape[0] - beyond[0][1], beyond[1][0] : out.shape[1] - beyond[1][1]]
        for out in _wall_cells(
            np.pad(occupancy[window], beyond, constant_values=UNKNOWN),
            np.pad(result.occupied[window], beyond),
            np.pad(result.structure[window], beyond),
            result.dominant_directions,
            res=res,
            p=p,
        )
    )
    # Made after the rules, whose own arrays are the cleaning's peak memory.
    walls, guarded, completed, dropped = _nothing_kept(occupancy.shape)
    walls[window] = kept
    guarded[window] = restored
    completed[window] = added
    dropped[window] = removed
    return walls, guarded, completed, dropped


def _nothing_kept(
    shape: tuple[int, int],
) -> tuple[
    npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]
]:
    """:func:`wall_cells`' four masks, all False."""
    # Fresh zeros, not copies: the pages of a large array are only mapped where written.
    return (
        np.zeros(shape, dtype=bool),
        np.zeros(shape, dtype=bool),
        np.zeros(shape, dtype=bool),
        np.zeros(shape, dtype=bool),
    )


def _wall_cells(
    occupancy: npt.NDArray[np.int8],
    occupied: npt.NDArray[np.bool_],
    structure: npt.NDArray[np.bool_],
    directions: npt.NDArray[np.float64],
    *,
    res: float,
    p: CleanParams,
) -> tuple[
    npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]
]:
    import cv2

    unknown = occupancy == UNKNOWN
    with _beside() as beside:
        near_job = beside.submit(_near_wide_unknown, unknown, res, p)
        pieces_job = beside.submit(_Pieces.of, occupied, join_px=1) if p.loose_pieces else None
        # Furniture flush against a wall: its hidden wall line is drawn, as the bridges' are.
        fronts_job = beside.submit(
            _flush_fronts,
            occupied,
            unknown,
            directions,
            max_len_px=length_px(_FRONT_MAX_M, res) if p.max_bridge_m > 0 else 0.0,
            max_depth_px=length_px(_FRONT_DEPTH_M, res),
            anchor_px=length_px(_BRIDGE_ANCHOR_M, res),
            face_px=length_px(_FRONT_FACE_M, res),
            crossing_px=length_px(_FRONT_CROSSING_M, res),
            wall_px=length_px(p.min_run_m, res),
            corner_px=length_px(_CORNER_MAX_M, res) if p.max_bridge_m > 0 else 0.0,
            corner_depth_px=length_px(_CORNER_DEPTH_M, res),
        )
        runs = directional_runs(
            occupied,
            directions,
            min_length_px=length_px(p.min_run_m, res),
            tolerance_px=p.run_tolerance_px,
        )
        # Straight lines at any angle (walls off the dominant directions, curved walls in pieces);
        # the runs are walls already, and leaving them out of Hough's input makes it 1.2-3x
        # cheaper.
        lines = runs | straight_lines(occupied & ~runs, min_length_px=length_px(p.min_run_m, res))
        near_outside = near_job.result()
        keep = occupied & (structure | near_outside) | lines
        completed = np.zeros(occupied.shape, dtype=bool)
        sealed_off = completed  # what closes scanned objects and the building, as walls or not
        if p.max_bridge_m > 0:
            # Unknown cells between collinear kept walls. Those between wall ends become the wall
            # line hidden behind furniture; all of them seal what they close off (an object's
            # inside between its faces, a cabinet's open back) but are not drawn as walls.
            bridges, wall_lines, staggered = _bridges(
                keep,
                unknown,
                directions,
                length_px(p.max_bridge_m, res),
                (1, length_px(_BRIDGE_ANCHOR_M, res)),
                beside,
                staggered_px=(
                    length_px(_STAGGERED_ANCHOR_M, res),
                    length_px(_BRIDGE_ANCHOR_M, res),
                ),
            )
            # Wall ends a cell apart across the line draw the hidden wall too (exact anchors need
            # the ends in one row of the rotated frame: a staircase at 30 or 45 degrees breaks that).
            bridges |= staggered
            wall_lines |= staggered
            # Only next to what goes (within a cabinet's depth): a bridge network reaching into
            # unexplored space or across racks is no wall hidden behind removed clutter.
            removed = occupied & ~keep
            sealed_off = _near(
                _touching(bridges, removed), removed, round(length_px(p.hidden_wall_reach_m, res))
            )
            completed = sealed_off & wall_lines
        # Furniture against a wall (a cabinet, a counter: its front a straight run when 2 m or
        # longer): the wall line hidden behind it is drawn, its front and sides go, and the walls
        # that meet it stay.
        front_lines, fronts, inside, front_walls = fronts_job.result()
        completed = completed | front_lines
        sealed_off = sealed_off | front_lines
        sealed = bool(sealed_off.any())
        if sealed:
            # The sealed cells separate the room from the unknown beyond them: furniture faces
            # in front are no longer next to the outside (a cabinet's inside, open through the
            # unscanned wall behind it, made its faces look like the building's edge).
            near_job = beside.submit(_near_wide_unknown, unknown & ~sealed_off, res, p)
        dropped_job = None
        if pieces_job is not None:
            # Free-standing pieces need neither the object faces nor the attached pieces: they
            # go beside them, after the wide unknown space they need (the same thread, in turn).
            pieces = pieces_job.result()
            dropped_job = beside.submit(_free_standing, pieces, lines, near_job, unknown, res, p)
        faces = np.zeros(occupied.shape, dtype=bool)
        pockets = faces
        if p.object_pocket_m2 > 0:
            # Object faces: a scanner sees a solid object as faces around a small unknown pocket
            # (its inside, sealed by the bridges across it). They go unless on a long straight run.
            faces, pockets = _pocket_faces(
                unknown, sealed_off, occupied, length_px(p.object_pocket_m2, res**2)
            )
        if sealed:
            keep = occupied & (structure | near_job.result()) | lines
        if front_lines.any():
            # The wall ends the hidden line joins are the wall, not faces of the object's inside
            # (dilated on the lines' box only: a few objects in a large map).
            box = _padded_box(front_lines, 1)
            beside_lines = cv2.dilate(front_lines[box].view(np.uint8), np.ones((3, 3), np.uint8))
            faces[box] &= ~beside_lines.view(bool)
        object_faces = faces & ~lines | fronts
        keep &= ~object_faces
        keep |= front_walls  # walls meeting furniture fronts: kept, attach to them
        faces = faces | fronts
        if p.attach_reach_m > 0:
            # Wall stubs, door frames, corners: occupied cells joined to a kept wall within the
            # reach, through occupied cells that are not object faces.
            attached = _grow_within(
                keep, occupied & ~faces, round(length_px(p.attach_reach_m, res))
            )
            attached &= ~keep
            keep |= attached
            # Partitions: pieces seen from both sides (free space across them within a wall's
            # thickness) that meet a kept wall, a wall between a corner and a door shorter than a
            # run. A thick wall shows two faces around its unseen core, which the object rule
            # takes for an object's faces around its inside: object faces count here too. A
            # scanned object is deeper, its inside unknown up to a back against a wall or seen
            # from the room, so no row or column crosses it from free space to free space.
            keep |= _partitions(
                occupied,
                keep,
                ~unknown & ~occupied,
                pockets,
                attached=attached,
                min_length_px=length_px(_PARTITION_MIN_M, res),
                max_thickness_px=max(length_px(_THIN_WALL_M, res), _THIN_WALL_MIN_CELLS),
            )
        dropped = (
            np.zeros(occupied.shape, dtype=bool) if dropped_job is None else dropped_job.result()
        )
    min_region_px = length_px(p.min_region_m2, res**2)
    guard_obstacles = occupied
    if pieces_job is not None:
        keep &= ~dropped
        # Pieces attached to no kept wall at all are furniture standing in the room: the guard
        # does not count them as obstacles of the input. Only those whose box is smaller than a
        # region the guard protects, though: they can enclose nothing it would count (a closed
        # free-standing room of 1.3 m x 1.3 m was removed whole, its inside opened).
        guard_obstacles = occupied & ~pieces.loose(keep, max_box_area_px=min_region_px)
    guarded = topology_guard(
        guard_obstacles,
        keep,
        added=completed | inside,
        radius_px=length_px(p.robot_radius_m, res),
        window_px=max(1, round(length_px(p.guard_window_m, res))),
        min_region_px=min_region_px,
    )
    kept = keep | guarded
    # (Object faces a partition keeps are walls, not dropped.)
    return kept, guarded, completed, (dropped | object_faces) & ~kept


class _Inline(Executor):
    """An executor that runs every call at once, in the calling thread."""

    def submit(self, fn: Callable[_P, _T], /, *args: _P.args, **kwargs: _P.kwargs) -> Future[_T]:
        future: Future[_T] = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as err:  # raised by result(), as from a thread
            future.set_exception(err)
        return future


@contextmanager
def _beside() -> Iterator[Executor]:
    """Where the cleaning runs the steps that need no result of the steps in between: one more
    thread, its jobs in the order submitted (a job may wait for an earlier one's result).

    OpenCV and numpy let go of the GIL, so a second thread runs them on a second core (the Hough
    transform, the distance transforms and the labellings use one core each): on two cores, 17 %
    less wall time than in turn over the 29 benchmark maps, none when the cores are busy anyway.
    Only when OpenCV may use several threads, though: batch workers and `rose-bag process` (whose
    session keeps the cores busy) hold it to one, and so does a one-core machine. Also in turn once the interpreter is shutting down
    (a thread that outlives the main one, an atexit handler), when no new thread may start.
    """
    import cv2

    if cv2.getNumThreads() <= 1:
        yield _Inline()
        return
    try:
        from rose.threads import threads_in_this_context

        # In the caller's context: what the jobs log belongs to its work (a batch's recording).
        pool = threads_in_this_context(1, "rose-clean")
        pool.submit(int).result()
    except RuntimeError:  # "cannot schedule new futures after interpreter shutdown" and kin
        yield _Inline()
        return
    try:
        yield pool
    except BaseException:
        pool.shutdown(wait=True, cancel_futures=True)  # the queued jobs' results are not wanted
        raise
    pool.shutdown(wait=True)


def _free_standing(
    pieces: _Pieces,
    lines: npt.NDArray[np.bool_],
    near_outside: Future[npt.NDArray[np.bool_]],
    unknown: npt.NDArray[np.bool_],
    res: float,
    p: CleanParams,
) -> npt.NDArray[np.bool_]:
    """Occupied cells of free-standing pieces: no cell on a run or ``lines`` or near wide unknown
    (``near_outside``, a job submitted before this one) even across a gap of up to two cells, and
    a joined box with a diagonal shorter than a wall run: clutter, whatever the paper's labelling
    says."""
    import cv2

    occupied = pieces.occupied
    anchored = lines | (occupied & near_outside.result())
    # A solid square (0.25 m) is a drawn column or wall, not the faces a scanner sees of an object.
    side = max(3, math.ceil(length_px(_SOLID_MIN_M, res)))
    solid = cv2.erode(occupied.view(np.uint8), np.ones((side, side), np.uint8), borderValue=0)
    dropped = pieces.loose(anchored | solid.view(bool), length_px(p.min_run_m, res))
    # ... unless it closes around known free space: a small room or shaft, not an object (a
    # scanned object's inside stays unknown).
    return dropped & ~pieces.around_free(dropped, ~unknown)


def _near_wide_unknown(
    unknown: npt.NDArray[np.bool_], res: float, p: CleanParams
) -> npt.NDArray[np.bool_]:
    """Cells within ``p.unknown_margin_m`` of wide unknown space (:func:`wide_unknown`): exact at
    the known cells, the only ones read (the occupied cells among them)."""
    outside = _wide(unknown, length_px(p.open_unknown_width_m, 2 * res))
    radius = round(length_px(p.unknown_margin_m, res))
    known = ~unknown
    if not known.any():
        return outside
    # Dilated on the known cells' box only (``radius`` wider): the grid is padded with unknown
    # cells as wide as the wide-unknown disc, and at 1 mm per cell the margin's 301-cell disc over
    # the padded grid took 2.6 s for a 100 x 100 map.
    near = outside.copy()
    box = _padded_box(known, radius)
    near[box] = _dilate(outside[box], radius)
    return near


def _thin_runs(
    solid: npt.NDArray[np.bool_], free: npt.NDArray[np.bool_], max_px: float
) -> npt.NDArray[np.bool_]:
    """Cells of ``solid`` in a run along a grid row or column of at most ``max_px`` cells with a
    ``free`` cell just before and just after it: a wall at most that thick, seen from both sides.
    Worked out on the solid cells' runs (few next to the whole image)."""
    shape = solid.shape
    out = np.zeros(shape, dtype=bool)
    cells = np.flatnonzero(solid)
    flat_free, flat_out = free.reshape(-1), out.reshape(-1)
    for vertical in (False, True):
        line, first, last = _runs(cells, shape, vertical)
        extent = shape[0] if vertical else shape[1]
        thin = (last - first + 1 <= max_px) & (first > 0) & (last < extent - 1)
        line, first, last = line[thin], first[thin], last[thin]
        seen = (
            flat_free[_flat_index(line, first - 1, shape, vertical)]
            & flat_free[_flat_index(line, last + 1, shape, vertical)]
        )
        flat_out[_run_cells((line[seen], first[seen], last[seen]), shape, vertical)] = True
    return out


def _flat_index(
    line: npt.NDArray[np.int64], pos: npt.NDArray[np.int64], shape: tuple[int, int], vertical: bool
) -> npt.NDArray[np.int64]:
    """Flat indices of the cells at ``pos`` along ``line`` (a column when ``vertical``, else a row)."""
    return pos * shape[1] + line if vertical else line * shape[1] + pos


def _in_free_square(free: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """Cells of ``free`` in some 2 x 2 square of free cells."""
    square = free[:-1, :-1] & free[1:, :-1] & free[:-1, 1:] & free[1:, 1:]
    out = np.zeros(free.shape, dtype=bool)
    out[:-1, :-1] |= square
    out[1:, :-1] |= square
    out[:-1, 1:] |= square
    out[1:, 1:] |= square
    return out


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
    touch ``walls`` and span at least ``min_length_px`` cells, with the candidates next to them.

    Thin cells (:func:`_thin_runs`) are the candidates and ``cores`` cells (unknown pockets: an
    object's inside or a thick wall's unseen core) on a run of occupied and core cells at most
    ``max_thickness_px`` long between two free cells: a wall seen from both sides, solid or with
    an unseen core. ``free``: known cells that are not occupied (a probabilistic grid's free space
    is 0..20, not only 0). ``attached``: cells of ``walls`` the attach rule kept (within its reach
    of a wall); thin ones count towards a piece's length, so that a partition 0.5 m long stays
    whole, not only its first ``attach_reach_m``."""
    candidates = occupied & ~walls
    out = np.zeros(candidates.shape, dtype=bool)
    if not candidates.any() or not walls.any():
        return out
    # A free cell next to a pocket counts only in a 2 x 2 square of free cells: single free cells
    # there are slivers between an object's inside and its face, or a beam that got into the
    # inside, not the room behind a wall (without this, a cabinet's front at 10 degrees to the
    # grid stayed, and ray-cast boxes whose insides beams crossed).
    room = free & (~_dilate(cores, 1) | _in_free_square(free))
    thin = _thin_runs(occupied | cores, room, max_thickness_px)
    sided = thin & (candidates | cores)
    if attached is not None:
        sided |= thin & attached
    if not sided.any():
        return out
    box = _padded_box(sided, 1)
    count, labels = components(sided[box])
    at = np.flatnonzero(sided[box])
    boxes = label_boxes(labels, at, count)
    long_enough = np.maximum(boxes[:, 2], boxes[:, 3]) >= min_length_px
    # Pieces with a cell on or next to (4-neighbours) a wall, looked up around their cells only.
    touching = np.zeros(count, dtype=bool)
    near_walls = walls[box][_cross(at, labels.shape)].any(axis=1)
    touching[labels.reshape(-1)[at[near_walls]]] = True
    wanted = long_enough & touching
    wanted[0] = False
    pieces = labels_wanted(wanted, labels, sided[box]) & candidates[box]
    # A run along a row misses the cells of a ragged face that stick out of it: the candidate
    # cells next to a piece belong to it (4-neighbours, looked up around the piece's cells).
    beside = _cross(np.flatnonzero(pieces), pieces.shape)
    pieces[beside] |= candidates[box][beside]
    out[box] = pieces
    return out


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
    cells = unknown & ~sealing
    faces = np.zeros(occupied.shape, dtype=bool)
    if not cells.any() or not occupied.any():
        return faces, faces.copy()
    count, labels = components(cells, connectivity=4)
    pocket = component_areas(labels, count) < max_area_px
    pocket[0] = False
    # Looked up around the occupied cells only (few next to the whole image); an occupied cell's
    # own label is 0, the background, so a border cell's repeated neighbours change nothing.
    at = np.flatnonzero(occupied)
    near = _any_of_8(pocket[_neighbour_labels(labels, at)])
    faces.reshape(-1)[at[near]] = True
    return faces, labels_wanted(pocket, labels, cells)


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
    waiting = np.flatnonzero(flat == 1)
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

    @classmethod
    def of(cls, occupied: npt.NDArray[np.bool_], *, join_px: int) -> _Pieces:
        import cv2

        grown = occupied
        if join_px > 0:
            kernel = np.ones((3, 3), np.uint8)
            grown = cv2.dilate(occupied.view(np.uint8), kernel, iterations=join_px).view(bool)
        count, labels = components(grown)
        cells = np.flatnonzero(occupied)
        owners = labels.reshape(-1)[cells]
        # A joined piece is its occupied cells grown by ``join_px`` (clipped by the image), and so
        # is its box: boxed from the occupied cells (fewer than the grown ones). The background's
        # box (no occupied cell) stays empty.
        x, y, width, height = label_boxes(labels, cells, count).T
        grow = join_px * (width > 0)
        rows, cols = occupied.shape
        left, top = np.maximum(x - grow, 0), np.maximum(y - grow, 0)
        width = (np.minimum(x + width + grow, cols) - left).astype(np.float64)
        height = (np.minimum(y + height + grow, rows) - top).astype(np.float64)
        return cls(occupied, labels, cells, owners, np.hypot(width, height), width * height)

    def loose(
        self,
        anchored: npt.NDArray[np.bool_],
        max_extent_px: float = math.inf,
        max_box_area_px: float = math.inf,
    ) -> npt.NDArray[np.bool_]:
        """Occupied cells of pieces with no ``anchored`` cell whose (joined) bounding box has a
        diagonal shorter than ``max_extent_px`` and an area under ``max_box_area_px``."""
        attached = (self.diagonals >= max_extent_px) | (self.box_areas >= max_box_area_px)
        attached[self.owners[anchored.reshape(-1)[self.cells]]] = True
        attached[0] = True
        out = np.zeros(self.occupied.shape, dtype=bool)
        out.reshape(-1)[self.cells] = ~attached[self.owners]
        return out

    def around_free(
        self, cells: npt.NDArray[np.bool_], known: npt.NDArray[np.bool_]
    ) -> npt.NDArray[np.bool_]:
        """Cells of ``cells`` (occupied) in pieces next to a hole of ``cells`` (other cells that
        4-connected paths cannot leave without crossing ``cells``) holding a known non-occupied
        cell."""
        out = np.zeros(cells.shape, dtype=bool)
        if not cells.any():
            return out
        import cv2

        # Only the box of ``cells`` matters (a cell wider: its rim is outside space, which
        # reaches the image's edge past no cell). Flood the outside from a one-cell frame around
        # it: what stays unflooded of the other cells are the holes (one pass; no labelling
        # unless a hole holds known free space).
        box = _padded_box(cells, 1)
        image = cv2.copyMakeBorder(
            (~cells[box]).view(np.uint8), 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=1
        )
        cv2.floodFill(image, None, (0, 0), 0, flags=4)
        holes = image[1:-1, 1:-1].view(bool)
        free_holes = holes & known[box] & ~self.occupied[box]
        if not free_holes.any():
            return out
        count, parts = components(holes, connectivity=4)
        wanted = np.zeros(count, dtype=bool)
        wanted[parts[free_holes]] = True
        wanted[0] = False
        hole_cells = labels_wanted(wanted, parts, holes)
        # (Holes never reach the box's edge: their rim lies in it.)
        rim = cv2.dilate(hole_cells.view(np.uint8), np.ones((3, 3), np.uint8)).view(bool)
        labels = self.labels[box]
        enclosing = np.zeros(self.diagonals.size, dtype=bool)
        enclosing[labels[rim & cells[box]]] = True
        enclosing[0] = False
        out[box] = labels_wanted(enclosing, labels, cells[box])
        return out


def _touching(pieces: npt.NDArray[np.bool_], other: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """The 8-connected components of ``pieces`` within two cells of ``other``."""

    out = np.zeros(pieces.shape, dtype=bool)
    if not pieces.any() or not other.any():
        return out
    # Only the pieces' bounding box matters (plus two cells for the reach of ``other``).
    box = _padded_box(pieces, 2)
    count, labels = components(pieces[box])
    near = _dilate(other[box], 2)
    wanted = np.zeros(count, dtype=bool)
    wanted[labels[near & pieces[box]]] = True
    wanted[0] = False
    out[box] = labels_wanted(wanted, labels, pieces[box])
    return out


def _near(
    cells: npt.NDArray[np.bool_], other: npt.NDArray[np.bool_], reach: int
) -> npt.NDArray[np.bool_]:
    """Cells of ``cells`` with a cell of ``other`` within ``reach`` cells (chessboard distance).
    Dilated on the bounding box of ``cells`` only (``reach`` wider): the same at every cell of it."""
    import cv2

    out = np.zeros(cells.shape, dtype=bool)
    if not cells.any():
        return out
    box = _padded_box(cells, reach)
    side = 2 * reach + 1
    grown = cv2.dilate(other[box].view(np.uint8), np.ones((side, side), np.uint8)).view(bool)
    out[box] = cells[box] & grown
    return out


def length_px(length_m: float, res: float) -> float:
    """``length_m`` in cells, rounded to 1e-6 so that a resolution stored as float32 (0.05 ->
    0.0500000007) converts exactly like the decimal one."""
    return round(length_m / res, 6)


def _dilate(mask: npt.NDArray[np.bool_], radius_px: int) -> npt.NDArray[np.bool_]:
    import cv2

    if radius_px <= 0:
        return mask.copy()
    size = 2 * radius_px + 1
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    return cv2.dilate(mask.view(np.uint8), kernel).view(bool)


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
    """:func:`wide_unknown` of the ``unknown`` cells."""
    import cv2

    if not unknown.any():
        return unknown.copy()
    # On a grid of 2 x 2 blocks (a block is unknown when all its cells are): a quarter of the work,
    # and only ever less unknown space, never more. An odd last row or column is repeated (a block
    # of it alone). Rows are paired first, then the byte pairs of every paired row are read as one
    # uint16: a tenth of the cost of four strided slices.
    rows, cols = unknown.shape
    half = rows // 2
    pairs = np.empty((half + rows % 2, cols + cols % 2), dtype=bool)
    np.logical_and(unknown[0 : 2 * half : 2], unknown[1 : 2 * half : 2], out=pairs[:half, :cols])
    if rows % 2:
        pairs[half, :cols] = unknown[-1]
    if cols % 2:
        pairs[:, cols] = pairs[:, cols - 1]
    blocks = pairs.view(np.uint16) == 0x0101
    radius = radius_px / 2
    depth = cv2.distanceTransform(blocks.view(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
    core = depth > radius
    if not core.any():
        return np.zeros(unknown.shape, dtype=bool)
    reach = cv2.distanceTransform((~core).view(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
    near = (reach <= radius).view(np.uint8)
    # Back to cells: every block value twice along the row (a uint16 of two equal bytes), then every
    # row twice (ten times cheaper than OpenCV's nearest-neighbour resize).
    wide = np.repeat((near.astype(np.uint16) * np.uint16(0x0101)).view(np.uint8), 2, axis=0)
    return wide[:rows, :cols].view(bool) & unknown


def directional_runs(
    mask: npt.NDArray[np.bool_],
    directions: npt.NDArray[np.float64],
    *,
    min_length_px: float,
    tolerance_px: int = 1,
) -> npt.NDArray[np.bool_]:
    """Cells of ``mask`` on straight runs at least ``min_length_px`` long along any direction.

    ``mask`` is rotated so that a direction lies along the columns, dilated by ``tolerance_px`` (so a
    run may step sideways and skip up to ``2 * tolerance_px`` cells), opened with a line of
    ``min_length_px`` cells along the rows and the columns (the direction at right angles comes for
    free when the map has one), and rotated back.

    Parameters
    ----------
    mask : ndarray of bool, shape (rows, cols)
    directions : ndarray of float64, shape (K,)
        Line orientations in radians, counter-clockwise from +col towards +row, in ``[0, pi)``.
    min_length_px : float
        Shortest run, cells.
    tolerance_px : int
        Cells of tolerance across and along a run.

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        A subset of ``mask``.
    """
    out = np.zeros(mask.shape, dtype=bool)
    if not mask.any() or directions.size == 0:
        return out
    r0, r1, c0, c1 = _bounds(mask)
    crop = mask[r0:r1, c0:c1]
    length = max(3, round(min_length_px)) | 1  # odd: an even line is off by one cell after opening
    for angle in _frames(directions):
        out[r0:r1, c0:c1] |= _runs_in_frame(crop, angle, length, tolerance_px)
    return out & mask


def _frames(directions: npt.NDArray[np.float64]) -> list[float]:
    """One rotation per group of directions at right angles to each other, in ``[0, pi/2)``."""
    frames: list[float] = []
    for angle in np.mod(directions, math.pi / 2).tolist():
        if all(
            min(abs(angle - f), math.pi / 2 - abs(angle - f)) > _PAIR_TOLERANCE_RAD for f in frames
        ):
            frames.append(angle)
    return frames


def _runs_in_frame(
    crop: npt.NDArray[np.bool_], angle: float, length: int, tolerance_px: int
) -> npt.NDArray[np.bool_]:
    import cv2

    rows, cols = crop.shape
    rotated, matrix = _rotate(crop.view(np.uint8), angle)
    if tolerance_px > 0:
        box = np.ones((2 * tolerance_px + 1, 2 * tolerance_px + 1), np.uint8)
        rotated = np.asarray(cv2.dilate(rotated, box), dtype=np.uint8)
    # The openings with a line along the rows and the columns, from the runs of the few occupied
    # cells (a fifth of the cost of two OpenCV openings of the whole rotated image).
    rotated = np.ascontiguousarray(rotated)
    cells = _nonzero_flat(rotated)
    along_rows = None if _dense(cells, rotated) else _runs(cells, rotated.shape, False)
    if along_rows is None or _fragmented(along_rows, rotated):
        runs = _open(rotated, (1, length)) | _open(rotated, (length, 1))
    else:
        runs = np.zeros(rotated.shape, dtype=np.uint8)
        for vertical in (False, True):
            lines = _runs(cells, rotated.shape, vertical) if vertical else along_rows
            long_runs = _open_runs(lines, length, rotated.shape[not vertical])
            runs.reshape(-1)[_run_cells(long_runs, rotated.shape, vertical)] = 1
    # 0 or 1 in every cell: read as booleans without a copy.
    if matrix is None:
        return runs.view(bool)
    back = cv2.warpAffine(
        runs, matrix, (cols, rows), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP
    )
    return np.asarray(cv2.dilate(back, np.ones((3, 3), np.uint8)), dtype=np.uint8).view(bool)


def _padded_box(mask: npt.NDArray[np.bool_], pad: int) -> tuple[slice, slice]:
    """The bounding box of the True cells of ``mask`` (it must have one), ``pad`` cells wider on
    every side, clipped to ``mask``."""
    r0, r1, c0, c1 = _bounds(mask)
    rows, cols = mask.shape
    return slice(max(r0 - pad, 0), min(r1 + pad, rows)), slice(
        max(c0 - pad, 0), min(c1 + pad, cols)
    )


def _bounds(mask: npt.NDArray[np.bool_]) -> tuple[int, int, int, int]:
    """``r0, r1, c0, c1`` of the bounding box of the True cells (``mask`` must have one)."""
    import cv2

    # OpenCV's bounding rectangle of the non-zero pixels: one pass, not two reductions.
    x, y, width, height = cv2.boundingRect(mask.view(np.uint8))
    return y, y + height, x, x + width


def _rotate(
    source: npt.NDArray[np.uint8], angle: float
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float64] | None]:
    """``source`` rotated so that ``angle`` lies along the columns, and the forward affine matrix
    (None when ``angle`` is within half a degree of an axis and nothing was rotated)."""
    import cv2

    if min(angle, math.pi / 2 - angle) < math.radians(0.5):
        return source, None
    rows, cols = source.shape
    c, s = math.cos(angle), math.sin(angle)
    corners = np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], dtype=np.float64)
    u = corners[:, 0] * c + corners[:, 1] * s
    v = -corners[:, 0] * s + corners[:, 1] * c
    matrix = np.array([[c, s, -u.min()], [-s, c, -v.min()]], dtype=np.float64)
    size = (math.ceil(u.max() - u.min()) + 1, math.ceil(v.max() - v.min()) + 1)
    rotated = cv2.warpAffine(source, matrix, size, flags=cv2.INTER_NEAREST)
    return np.asarray(rotated, dtype=np.uint8), matrix


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


def _bridges(
    walls: npt.NDArray[np.bool_],
    fillable: npt.NDArray[np.bool_],
    directions: npt.NDArray[np.float64],
    max_gap_px: float,
    anchors_px: tuple[float, ...],
    beside: Executor | None = None,
    *,
    staggered_px: tuple[float, float] | None = None,
) -> list[npt.NDArray[np.bool_]]:
    """:func:`bridge_gaps` for each shortest anchor of ``anchors_px`` (ascending), rotating the map
    once; which fills are thin enough is decided on the first anchor's (the smallest: the most
    fill), so a larger anchor never fills more than it does.

    With ``staggered_px = (anchor, min_fill)`` one more output: the fills between wall ends up to a
    cell apart across the line (:func:`_staggered_gaps`), at most three cells thick.

    The anchors are exact stretches in the rotated frame: a wall one cell thin at an angle to its
    frame can come out of the rotation dashed, and then anchors nothing (no hidden wall is drawn
    there; the guard keeps the furniture instead). A cell of tolerance brought the dashes back but
    also every wall's staircase: on the 30-degree benchmark logs robot gaps rose from 0.5 (2) to
    1 (3) with nothing gained. The staggered fills (``staggered_px``) take a cell of tolerance
    across the line only, with longer anchors and no fills shorter than ``min_fill``.

    ``beside`` works out the gaps along the columns while this thread does the rows' (in turn when
    omitted)."""
    import cv2

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
    rows, cols = crop.shape
    anchors = [max(1, round(a)) for a in anchors_px]
    side = beside if beside is not None else _Inline()
    for angle in _frames(directions):
        rotated, matrix = _rotate(crop.view(np.uint8), angle)
        rotated = np.ascontiguousarray(rotated)  # the crop itself when not rotated
        # The rows' and the columns' gaps need nothing of each other.
        across_job = side.submit(_closed_gaps, rotated, True, length, anchors)
        staggered_job = None
        if staggered_px is not None:
            stagger = (max(1, round(staggered_px[0])), max(1, round(staggered_px[1])))
            # Drawn straight into the bit after the anchors' (no shifted copies).
            bit = 1 << len(anchors)
            staggered_job = side.submit(_staggered_gaps, rotated, True, length, *stagger, bit)
            staggered = _staggered_gaps(rotated, False, length, *stagger, bit)
        fills = _closed_gaps(rotated, False, length, anchors)
        fills |= across_job.result()
        if staggered_job is not None:
            fills |= staggered
            fills |= staggered_job.result()
        if matrix is not None:
            # Nearest-neighbour sampling copies values: every anchor's fills, one bit each, go
            # back in one warp.
            back = cv2.warpAffine(
                fills, matrix, (cols, rows), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP
            )
            fills = np.asarray(back, dtype=np.uint8)
        filled = np.empty_like(fills)
        for bit, out in enumerate(outs):
            np.bitwise_and(fills, np.uint8(1 << bit), out=filled)
            np.logical_or(out[r0:r1, c0:c1], filled, out=out[r0:r1, c0:c1])
    open_cells = fillable & ~walls
    for out in outs:
        out &= open_cells
    return outs


def _closed_gaps(
    rotated: npt.NDArray[np.uint8], vertical: bool, length: int, anchors: list[int]
) -> npt.NDArray[np.uint8]:
    """:func:`_bridges`' fills of one orientation of a rotated frame (along the columns when
    ``vertical``, else the rows), bit ``i`` for ``anchors[i]`` (at most 8): the closing with a line
    of ``length`` cells of the pieces on straight stretches of ``anchor`` cells along it, less the
    walls and the fills four or more cells thick across it.

    Worked out on the runs of the wall cells along the lines (the same cells as OpenCV's closings
    and openings with line kernels, :func:`_close_runs`): the walls are a few percent of the
    image, and OpenCV's line closings of the whole image cost several times more.
    """
    shape = rotated.shape
    extent = shape[not vertical]  # cells along a line
    cells = _nonzero_flat(rotated)
    if _dense(cells, rotated):
        return _closed_gaps_of_image(rotated, vertical, length, anchors)
    walls = _runs(cells, shape, vertical)
    closed_walls = _close_runs(walls, length, extent)  # the most any anchor closes
    if _fragmented(walls, rotated) or _covered(closed_walls) > _FRAGMENTED_CLOSED * rotated.size:
        return _closed_gaps_of_image(rotated, vertical, length, anchors)
    is_wall = rotated.reshape(-1)
    out = np.zeros(shape, dtype=np.uint8)
    thick: npt.NDArray[np.uint8] | None = None
    for bit, anchor in enumerate(anchors):
        # Only wall pieces running along the gap anchor a bridge: the side faces of an object,
        # across it, would join its two sides through its inside.
        closed_runs = (
            closed_walls
            if anchor == 1
            else _close_runs(_open_runs(walls, anchor, extent), length, extent)
        )
        closed = _run_cells(closed_runs, shape, vertical)
        fill = closed[is_wall[closed] == 0]
        if thick is None:
            # A wall line is thin: drop fills four or more cells thick across the line (the space
            # between two parallel walls, not a wall). Fewer anchors only ever fill less: the
            # first (all walls) decides for every anchor.
            # Runs along the rows need their cells in ascending order (along the columns, _runs
            # orders them itself). Closed along the columns, ``fill`` is in column order: a stable
            # reordering by row sorts it.
            if vertical:
                fill = fill[_order_by(fill // shape[1], shape[0])]
            across = _runs(fill, shape, not vertical)
            thick = np.zeros(shape, dtype=np.uint8)
            thick.reshape(-1)[
                _run_cells(_open_runs(across, 4, shape[vertical]), shape, not vertical)
            ] = 1
        out.reshape(-1)[fill[thick.reshape(-1)[fill] == 0]] |= np.uint8(1 << bit)
    return out


def _staggered_gaps(
    rotated: npt.NDArray[np.uint8],
    vertical: bool,
    length: int,
    anchor: int,
    min_fill: int,
    value: int = 1,
) -> npt.NDArray[np.uint8]:
    """:func:`_closed_gaps` (one anchor, ``value`` or 0 per cell) of the walls grown by a cell
    across the line (along the columns when ``vertical``, else the rows): fills between two wall
    ends up to a cell apart across it, less the grown walls (never the cells beside a wall), only
    in stretches of at least ``min_fill`` cells along the line (a staircase's notches are
    shorter)."""
    import cv2

    band: npt.NDArray[np.uint8] = np.ascontiguousarray(
        cv2.dilate(rotated, np.ones((1, 3) if vertical else (3, 1), np.uint8)), dtype=np.uint8
    )
    fills = np.ascontiguousarray(_closed_gaps(band, vertical, length, [anchor]))
    line, start, end = _runs(_nonzero_flat(fills), fills.shape, vertical)
    long_enough = end - start + 1 >= min_fill
    out = np.zeros(fills.shape, dtype=np.uint8)
    runs = (line[long_enough], start[long_enough], end[long_enough])
    out.reshape(-1)[_run_cells(runs, fills.shape, vertical)] = value
    return out


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


def _open(image: npt.NDArray[np.uint8], kernel_shape: tuple[int, int]) -> npt.NDArray[np.uint8]:
    """Morphological opening with a ``kernel_shape`` box; outside the image counts as empty."""
    import cv2

    kernel = np.ones(kernel_shape, np.uint8)
    opened = cv2.morphologyEx(
        image, cv2.MORPH_OPEN, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0
    )
    return np.asarray(opened, dtype=np.uint8)


#: Share of occupied cells above which the line morphology is OpenCV's without looking at the runs
#: (finding the runs of millions of cells costs more than OpenCV's passes; real maps: at most 5 %).
_DENSE_CELLS = 0.1

#: Runs per cell of the image above which the line morphology is done on the whole image by OpenCV
#: rather than on the runs: the runs' index arrays grow with the runs and what they close, OpenCV's
#: cost with the image. Walls make long runs (real maps: at most 1.5 % of the cells start a run,
#: where the runs are faster); speckle makes a run of nearly every cell (a 40 %-occupied random map
#: cleaned 4x slower on the runs).
_FRAGMENTED_RUNS = 0.025

#: Share of the image that closed runs may cover before OpenCV's closing is cheaper (a flat index
#: per closed cell; real maps: at most 10 %, 2 %-occupied speckle: nearly all of it).
_FRAGMENTED_CLOSED = 0.25


def _dense(cells: npt.NDArray[np.int64], image: npt.NDArray[np.uint8]) -> bool:
    """Whether ``cells`` (the non-zero cells of ``image``) are too many for the run versions."""
    return cells.size > _DENSE_CELLS * image.size


def _fragmented(runs: _Runs, image: npt.NDArray[np.uint8]) -> bool:
    """Whether ``image`` has too many ``runs`` (its runs along one axis) for the run versions."""
    return runs[0].size > _FRAGMENTED_RUNS * image.size


def _covered(runs: _Runs) -> int:
    """Number of cells in ``runs``."""
    _, start, end = runs
    return int((end - start + 1).sum())


_Runs = tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64]]


def _nonzero_flat(image: npt.NDArray[np.uint8]) -> npt.NDArray[np.int64]:
    """Flat indices (ascending) of the non-zero cells of a C-contiguous image (OpenCV's list of
    them: a tenth of the cost of numpy's for a uint8 image)."""
    import cv2

    points = cv2.findNonZero(image)
    if points is None:
        return np.empty(0, dtype=np.int64)
    points = points.reshape(-1, 2).astype(np.int64)
    return points[:, 1] * image.shape[1] + points[:, 0]


def _runs(cells: npt.NDArray[np.int64], shape: tuple[int, int], vertical: bool) -> _Runs:
    """The maximal runs of ``cells`` (flat indices, ascending) along the rows, or the columns
    when ``vertical``: the line (row or column) of each, and its first and last cell along it."""
    cols = shape[1]
    if vertical:
        row, col = np.divmod(cells, cols)
        order = _order_by(col, cols)
        line, pos = col[order], row[order]
    else:
        line, pos = np.divmod(cells, cols)
    if line.size == 0:
        return line, pos, pos
    first, last = _groups(line, pos[1:] != pos[:-1] + 1)
    return line[first], pos[first], pos[last]


def _order_by(major: npt.NDArray[np.int64], size: int) -> npt.NDArray[np.intp]:
    """The stable order of items by ``major`` (values in ``[0, size)``): with the items in order
    within each value, the order of a full sort. Keys of 16 bits take numpy's radix sort, a fifth
    of the cost of sorting flat indices (64 bits) on the cleaning's images."""
    if size <= np.iinfo(np.uint16).max + 1:
        return np.argsort(major.astype(np.uint16), kind="stable")
    return np.argsort(major, kind="stable")


def _groups(
    line: npt.NDArray[np.int64], apart: npt.NDArray[np.bool_]
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """Where each group of consecutive items (``line`` non-empty) starts and ends (inclusive): a new
    group at each new line and wherever ``apart`` (shape ``line.size - 1``: item ``i + 1`` is apart
    from item ``i``) holds."""
    starts = np.empty(line.size, dtype=bool)
    starts[0] = True
    np.logical_or(apart, line[1:] != line[:-1], out=starts[1:])
    first = np.flatnonzero(starts)
    return first, np.append(first[1:], line.size) - 1


def _run_cells(runs: _Runs, shape: tuple[int, int], vertical: bool) -> npt.NDArray[np.int64]:
    """Flat indices of the cells of ``runs`` (along the columns when ``vertical``)."""
    line, start, end = runs
    lengths = end - start + 1
    offsets = np.arange(int(lengths.sum()), dtype=np.int64)
    pos = np.repeat(start - (np.cumsum(lengths) - lengths), lengths) + offsets
    along = np.repeat(line, lengths)
    return _flat_index(along, pos, shape, vertical)


def _open_runs(runs: _Runs, size: int, extent: int) -> _Runs:
    """OpenCV's opening with a line of ``size`` cells along the runs (lines of ``extent`` cells,
    empty outside the image): the runs at least ``size`` long, one cell on for an even ``size``
    (OpenCV's anchor is off the middle then)."""
    line, start, end = runs
    keep = end - start + 1 >= size
    shift = 2 * (size // 2) - size + 1
    return line[keep], start[keep] + shift, np.minimum(end[keep] + shift, extent - 1)


def _close_runs(runs: _Runs, size: int, extent: int) -> _Runs:
    """OpenCV's closing with a line of ``size`` cells along the runs (lines of ``extent`` cells)
    and its default borders: empty for the dilation, full for the erosion, so that a gap between
    a run and the image's edge closes too when the dilation reaches the edge."""
    line, start, end = runs
    if line.size == 0:
        return runs
    before = size // 2
    after = size - 1 - before
    low = np.maximum(start - after, 0)
    high = np.minimum(end + before, extent - 1)
    # Dilated runs that meet merge (the dilation keeps their order along a line).
    first, last = _groups(line, low[1:] > high[:-1] + 1)
    low, high = low[first], high[last]
    low = np.where(low == 0, 0, low + before)
    high = np.where(high == extent - 1, extent - 1, high - after)
    keep = low <= high
    return line[first][keep], low[keep], high[keep]


def straight_lines(
    mask: npt.NDArray[np.bool_], *, min_length_px: float, max_gap_px: int = 2
) -> npt.NDArray[np.bool_]:
    """Cells of ``mask`` on straight segments at least ``min_length_px`` long, at any angle.

    OpenCV's probabilistic Hough transform (deterministic) finds the segments, with gaps of up to
    ``max_gap_px`` cells; they are drawn three cells wide and intersected with ``mask``.
    """
    import cv2

    out = np.zeros(mask.shape, dtype=np.uint8)
    if not mask.any():
        return out.astype(bool)
    length = max(2, round(min_length_px))
    # On the mask's bounding box: the transform's votes depend on where the cells lie in its image,
    # so the same cells give the same segments however much empty space is around them.
    box = _padded_box(mask, 0)
    segments = cv2.HoughLinesP(
        mask[box].view(np.uint8) * np.uint8(255),
        1.0,
        math.pi / 180,
        threshold=max(2, length // 2),
        minLineLength=length,
        maxLineGap=max_gap_px,
    )
    if segments is not None:
        lines = segments.reshape(-1, 1, 2, 2).astype(np.int32)
        cv2.polylines(out[box], list(lines), isClosed=False, color=1, thickness=3)
    return out.view(bool) & mask  # drawn with 1: read as booleans without a copy


def passable(obstacles: npt.NDArray[np.bool_], radius_px: float) -> npt.NDArray[np.bool_]:
    """Cells farther than ``radius_px`` (centre to centre) from every obstacle cell."""
    if not obstacles.any():
        return np.ones(obstacles.shape, dtype=bool)
    return ~_blocked(obstacles, radius_px)


def _blocked(obstacles: npt.NDArray[np.bool_], radius_px: float) -> npt.NDArray[np.bool_]:
    """Cells within ``radius_px`` (centre to centre) of an obstacle cell: not :func:`passable`."""
    import cv2

    reach = math.floor(radius_px)
    offsets = np.arange(-reach, reach + 1)
    disc = (offsets[:, None] ** 2 + offsets[None, :] ** 2 <= radius_px**2).astype(np.uint8)
    return cv2.dilate(obstacles.view(np.uint8), disc).view(bool)


def topology_guard(
    occupied: npt.NDArray[np.bool_],
    keep: npt.NDArray[np.bool_],
    *,
    radius_px: float,
    added: npt.NDArray[np.bool_] | None = None,
    window_px: int,
    min_region_px: float,
) -> npt.NDArray[np.bool_]:
    """Removed cells to restore so that no robot-sized passage opens between separate regions.

    Removing ``occupied & ~keep`` (and adding the obstacles ``added``) makes some cells passable for
    a disc of ``radius_px``. Each connected patch of them is checked in a window of ``window_px``
    cells around it: if the cells that were passable before (``added`` counting as obstacles before
    too: hidden walls, there but unseen) and touch the patch belong to two or more regions of the
    window that are not small enclosed pockets (a pocket does not reach the window's
    edge and covers less than ``min_region_px``), every removed cell within ``radius_px + 1`` of the
    patch is restored: those are the cells that kept the disc out of it. Patches surrounded by
    formerly passable cells (a free-standing object) are skipped without labelling; the rest cost
    one small labelling each.

    Returns
    -------
    ndarray of bool, shape (rows, cols)
        Cells of ``occupied & ~keep`` to restore.
    """
    import cv2

    removal = occupied & ~keep
    restore = np.zeros(occupied.shape, dtype=bool)
    if not removal.any():
        return restore
    after = occupied & keep if added is None else (occupied & keep) | added
    # The added obstacles (hidden walls) were there before too, only unseen: regions they close off
    # are told apart as such (the inside of a cabinet against a wall, closed by the wall line behind
    # it, is a pocket, not the unknown outside). What opens is the same either way: the added
    # obstacles block after as well.
    blocked_before = _blocked(occupied if added is None else occupied | added, radius_px)
    # Passable after, not before (booleans: a > b is a & ~b, one pass).
    opened = np.greater(blocked_before, _blocked(after, radius_px))
    if not opened.any():
        return restore
    # Everything the guard looks at lies within a window (plus the restoring reach) of an opened
    # patch: work on their bounding box (windows clipped by it are clipped as by the map).
    reach = math.ceil(radius_px) + 1
    box = _padded_box(opened, window_px + reach + 2)
    before, opened = ~blocked_before[box], opened[box]
    count, patches = components(opened)
    boxes = label_boxes(patches, np.flatnonzero(opened), count)
    ring_cells, ring_patches = _rings(patches, opened, count)
    formerly = before.reshape(-1)[ring_cells]
    # Patches whose ring is all formerly passable are free-standing objects: nothing to check.
    blocked = np.zeros(count, dtype=bool)
    blocked[ring_patches[~formerly]] = True
    blocked[0] = False
    ring_cells, ring_patches = ring_cells[formerly], ring_patches[formerly]
    # A patch whose formerly passable ring cells are one connected arc joins nothing (it opens into
    # one region only): only patches with two or more arcs need a labelled window. An arc that
    # also runs along another patch's ring proves nothing (it may leave this patch's window).
    touched = np.zeros(opened.shape, dtype=bool)
    touched.reshape(-1)[ring_cells] = True
    arcs_count, arcs = components(touched)
    pairs = np.unique(ring_patches * arcs_count + arcs.reshape(-1)[ring_cells])
    arc_of, patch_of = pairs % arcs_count, pairs // arcs_count
    shared = np.bincount(arc_of, minlength=arcs_count)[arc_of] >= 2
    several = np.bincount(patch_of, minlength=count) >= 2
    several[patch_of[shared]] = True
    blocked &= several
    if not blocked.any():
        return restore
    separating = _separating_patches(
        before, boxes, blocked, ring_cells, ring_patches, window_px, min_region_px
    )
    if not separating.any():
        return restore
    # The removed cells within reach of a separating patch (dilated on the patches' box only): the
    # ones that kept the disc out of it. Whole removed pieces would also bring back furniture that
    # merely touches a wall hole, diagonally, as rasterised walls at an angle often do.
    reach_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1, 2 * reach + 1))
    seeds = labels_wanted(separating, patches, opened)
    near = _padded_box(seeds, reach)
    zone = np.zeros(seeds.shape, dtype=bool)
    zone[near] = cv2.dilate(seeds[near].view(np.uint8), reach_kernel).astype(bool)
    restore[box] = zone & removal[box]
    return restore


def _rings(
    patches: npt.NDArray[np.integer], opened: npt.NDArray[np.bool_], count: int
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.int64]]:
    """The ring of every patch (``count`` labels, 0 the background): each cell outside ``opened``
    with an 8-neighbour in a patch, once per patch it touches (a cell between two patches is in
    both rings).

    Returns
    -------
    cells : ndarray of intp, shape (N,)
        Flat indices into ``patches``.
    labels : ndarray of int64, shape (N,)
        The patch of each entry.
    """
    import cv2

    grown = cv2.dilate(opened.view(np.uint8), np.ones((3, 3), np.uint8))
    cells = np.flatnonzero(grown.view(bool) & ~opened)
    # The labels of every ring cell's 8 neighbours (ring cells are few next to the whole image).
    around = _neighbour_labels(patches, cells)
    top = around.max(axis=1)
    # Cells next to two patches are rare: only they need every (cell, patch) pair sorted out.
    contested = _any_of_8((around > 0) & (around != top[:, None]))
    top = top.astype(np.int64)
    if not contested.any():
        return cells, top
    shared, labels = cells[contested], around[contested].astype(np.int64)
    keys = np.unique((shared[:, None] * count + labels)[labels > 0])
    return (
        np.concatenate([cells[~contested], keys // count]),
        np.concatenate([top[~contested], keys % count]),
    )


def _neighbour_labels(
    labels: npt.NDArray[np.integer], cells: npt.NDArray[np.intp]
) -> npt.NDArray[np.integer]:
    """The labels of the 8 neighbours of each cell, shape ``(N, 8)``.

    ``cells`` are flat indices into ``labels``, ascending (as :func:`numpy.flatnonzero` gives
    them). On the image border a neighbour is clipped onto the cell's own row or column: that only
    repeats a neighbour or the cell itself.
    """
    rows, cols = labels.shape
    flat = labels.reshape(-1)
    row, col = np.divmod(cells, cols)
    inner = cells.size == 0 or (
        row[0] > 0 and row[-1] < rows - 1 and int(col.min()) > 0 and int(col.max()) < cols - 1
    )
    offsets = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc]
    return np.stack(
        [
            flat[cells + (dr * cols + dc)]
            if inner
            else flat[np.clip(row + dr, 0, rows - 1) * cols + np.clip(col + dc, 0, cols - 1)]
            for dr, dc in offsets
        ],
        axis=1,
    )


def _any_of_8(flags: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """``flags.any(axis=1)`` of a C-contiguous ``(N, 8)`` boolean array, each row read as one uint64
    (numpy's reduction over rows of 8 costs several times more)."""
    return flags.view(np.uint64).reshape(-1) != 0


def _separating_patches(
    before: npt.NDArray[np.bool_],
    boxes: npt.NDArray[np.int64],
    blocked: npt.NDArray[np.bool_],
    ring_cells: npt.NDArray[np.intp],
    ring_patches: npt.NDArray[np.int64],
    window_px: int,
    min_region_px: float,
) -> npt.NDArray[np.bool_]:
    """Which ``blocked`` patches touch, with their ring (``ring_cells`` of ``ring_patches``, from
    :func:`_rings`), two or more regions of ``before`` (in a window of ``window_px`` cells around
    the patch) that are not small enclosed pockets (a pocket does not reach the window's edge and
    covers less than ``min_region_px``).

    All windows are copied into one mosaic, one empty cell apart, and labelled in one call.
    """

    count = boxes.shape[0]
    separating = np.zeros(count, dtype=bool)
    rows, cols = before.shape
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
    # Shelf packing: windows left to right in rows of the mosaic, one empty cell between them.
    width = max(int(widths.max()) + 1, 1024)
    ox = np.zeros(ids.size, dtype=np.int64)
    oy = np.zeros(ids.size, dtype=np.int64)
    cursor_x = cursor_y = shelf = 0
    for i in range(ids.size):
        if cursor_x + int(widths[i]) + 1 > width:
            cursor_x, cursor_y, shelf = 0, cursor_y + shelf + 1, 0
        ox[i], oy[i] = cursor_x, cursor_y
        cursor_x += int(widths[i]) + 1
        shelf = max(shelf, int(heights[i]))
    mosaic = np.zeros((cursor_y + shelf + 1, width), dtype=np.uint8)
    view = before.view(np.uint8)
    for i in range(ids.size):
        mosaic[oy[i] : oy[i] + heights[i], ox[i] : ox[i] + widths[i]] = view[
            r0[i] : r1[i], c0[i] : c1[i]
        ]
    # Plain labels, areas from a histogram and the regions on their window's frame: a third of
    # the cost of OpenCV's statistics.
    region_count, regions = components(mosaic)
    areas = component_areas(regions, region_count)
    on_frame = np.zeros(region_count, dtype=bool)
    on_frame[regions.reshape(-1)[_frame_cells(oy, ox, heights, widths, mosaic.shape[1])]] = True
    on_frame[0] = False
    slot = np.full(count, -1, dtype=np.int64)
    slot[ids] = np.arange(ids.size)
    where = slot[ring_patch]
    keep = where >= 0
    where, cells = where[keep], ring_idx[keep]
    labels = regions[cells // cols - r0[where] + oy[where], cells % cols - c0[where] + ox[where]]
    touched = labels > 0
    pairs = np.unique(where[touched] * region_count + labels[touched])
    window_of, label = pairs // region_count, pairs % region_count
    open_regions = np.bincount(
        window_of[on_frame[label] | (areas[label] >= min_region_px)], minlength=ids.size
    )
    separating[ids] = open_regions >= 2
    return separating


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
#: ... the shallowest such furniture, from the wall line to the far side of its front (metres):
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
) -> tuple[
    npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]
]:
    """Furniture flush against a wall: the hidden wall line, the furniture's cells, its inside, and
    the walls that meet it (kept).

    Along each dominant direction: a straight stretch of unknown cells (at most ``max_len_px``)
    between two occupied stretches of at least ``anchor_px`` cells on one line that face free
    space on the same side (most of their last ``anchor_px`` cells within ``face_px`` of it),
    where every cell of the stretch has, on that side, more than ``face_px`` and at most
    ``max_depth_px`` occupied or unknown cells before free space, an occupied one last (a front
    face). That is a wall running on behind an object that stands against it: the line is the
    hidden wall, the occupied cells between it and the room are the object's front and sides,
    the unknown cells its inside. Columns reaching farther than the front, in stretches no wider
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
    # 0 unknown (also beyond the rotated image), 1 free, 2 occupied.
    code = (~unknown[box]).view(np.uint8) + occupied[box].view(np.uint8)
    rows, cols = code.shape
    for angle in _frames(directions):
        rotated, matrix = _rotate(code, angle)
        out = np.zeros(rotated.shape, dtype=np.uint8)  # bit 0 line, 1 front, 2 inside, 3 wall
        transposed = np.asarray(cv2.transpose(rotated), dtype=np.uint8)  # a ninth of numpy's cost
        # Rotated (a wall at an angle to the grid): the exact rows, then the straightened ones.
        for slack, transpose in ((0, False), (0, True)) + (
            ((1, False), (1, True)) if matrix is not None else ()
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
                corner_len=round(corner_px) if matrix is None else 0,
                corner_depth=round(corner_depth_px),
            )
        if matrix is not None:
            out = np.asarray(
                cv2.warpAffine(
                    out, matrix, (cols, rows), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP
                ),
                dtype=np.uint8,
            )
        if not out.any():
            continue
        # Only where something was found (a few objects in a large map).
        y0, y1, x0, x1 = _bounds(out.view(bool))
        out = out[y0:y1, x0:x1]
        found = (slice(r0 + y0, r0 + y1), slice(c0 + x0, c0 + x1))
        line = (out & 1).view(bool) & unknown[found]
        lines[found] |= line
        stub = (out >> 3).view(bool) & occupied[found]
        stubs[found] |= stub
        fronts[found] |= (out >> 1 & 1).view(bool) & occupied[found] & ~line & ~stub
        insides[found] |= (out >> 2 & 1).view(bool) & unknown[found] & ~line
    return lines, fronts & ~stubs, insides, stubs


def _straightened(code: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
    """``code`` (0 unknown, 1 free, 2 occupied) with every cell a row above or below an occupied
    one occupied, and then the holes of one or two cells along the rows between occupied cells (a
    morphological closing along the rows): a staircase of one or two rows becomes a solid band."""
    import cv2

    _, occupied = cv2.threshold(code, 1, 2, cv2.THRESH_BINARY)
    grown: npt.NDArray[np.uint8] = np.asarray(
        cv2.dilate(occupied, np.ones((3, 1), np.uint8)), dtype=np.uint8
    )
    closed = grown.copy()
    closed[:, 1:-1] |= grown[:, :-2] & grown[:, 2:]
    # Holes of two cells: the same pairs three columns apart close both of their cells.
    apart = grown[:, :-3] & grown[:, 3:]
    closed[:, 1:-2] |= apart
    closed[:, 2:-1] |= apart
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
) -> None:
    """:func:`_flush_fronts` along the rows of ``code`` (0 unknown, 1 free, 2 occupied), the
    furniture below or above the line; bits 0 (line), 1 (front), 2 (inside) and 3 (a wall meeting
    the object) set in ``out``. With ``corner_len``, also furniture in a room's corner
    (:func:`_corners_rows`), its hidden line at most that long and its front at least
    ``corner_depth`` cells from the line.

    Whole-image work is only the runs of the occupied cells; each candidate gap (unknown cells at
    both ends) is then checked on a few cells, and the rest on the few rows beside it."""
    height, width = code.shape
    flat_code = code.reshape(-1)
    cells = np.flatnonzero(flat_code >= 2)  # occupied: a door frame's stub is kept only later
    if cells.size < 2:
        return
    r = cells // width
    step = np.diff(cells)
    same_row = r[1:] == r[:-1]
    new_run = np.ones(cells.size, dtype=bool)
    new_run[1:] = (step != 1) | ~same_row
    run_id = np.cumsum(new_run) - 1
    run_len = np.bincount(run_id)[run_id]
    # Gaps between consecutive occupied cells of one row, unknown at both ends.
    left = np.flatnonzero(same_row & (step > 1) & (step - 1 <= max_len))
    left = left[(flat_code[cells[left] + 1] == 0) & (flat_code[cells[left + 1] - 1] == 0)]
    # (Straightened: a band's wall stretches twice as long, as the staggered bridges' ends: a face
    # across the line at an angle makes short stretches in a band too.)
    run_anchor = anchor if slack == 0 else 2 * anchor
    left = left[(run_len[left] >= run_anchor) & (run_len[left + 1] >= run_anchor)]
    span = max_depth + 1
    if corner_len > 0 and slack == 0:
        # One wall end is weaker evidence than two: its visible stretch must be twice an anchor
        # (as a staggered bridge's ends), longer than the steps of a wall at 45 degrees.
        last = np.append(new_run[1:], True)
        long_run = run_len >= 2 * anchor
        _corners_rows(
            code,
            out,
            (cells[last & long_run], cells[new_run & long_run]),
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

    def free(
        at_rows: npt.NDArray[np.int64], at_cols: npt.NDArray[np.int64]
    ) -> npt.NDArray[np.bool_]:
        # Free cells looked up where wanted (rows past the edges read the edge's).
        return code[np.clip(at_rows, 0, height - 1), at_cols] == 1

    rows = cells[left] // width
    end_left, end_right = cells[left] % width, cells[left + 1] % width
    middle = (end_left + end_right) // 2
    for sign in (1, -1):
        # Cheap tests first, on a few cells of each candidate: the wall ends' last cells see
        # free space within ``face`` on this side, the gap's middle column none that near.
        across = rows[:, None, None] + sign * np.arange(1, face + slack + 1)[:, None]
        along = np.arange(anchor + 2 * slack)
        face_left = free(across, np.maximum(end_left[:, None] - along, 0)[:, None, :])
        face_right = free(across, np.minimum(end_right[:, None] + along, width - 1)[:, None, :])
        face_left = face_left.any(axis=1).sum(axis=1)
        face_right = face_right.any(axis=1).sum(axis=1)
        beside = rows[:, None] + sign * np.arange(1, face + 2)
        near_middle = free(beside, middle[:, None]).any(axis=1)
        chosen = np.flatnonzero(
            (2 * face_left >= anchor) & (2 * face_right >= anchor) & ~near_middle
        )
        # This side as "below": the rows reversed for the other (views, no copies).
        view, written = (code, out) if sign == 1 else (code[::-1], out[::-1])
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
            )


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
) -> bool:
    """The checks of one candidate gap ``row, col0:col1`` (the furniture below it) and, when it
    passes (returns True), its line, front and inside in ``out``; with ``slack`` (a straightened
    staircase) the gap's first and last ``slack + 1`` columns may open to the room (a side face a
    column off)."""
    height, width = code.shape
    max_depth = span - 1
    if row + 1 >= height or (code[row, col0:col1] != 0).any():
        return False
    lo, hi = max(col0 - anchor, 0), min(col1 + anchor, width)
    below = code[row + 1 : row + 1 + span, lo:hi] == 1
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
    d = depth[col0 - lo : col1 - lo]
    # Deeper than a wall face everywhere (else the "front" is the wall itself, the line the
    # unknown behind it), no deeper than furniture. Straightened, by two cells more: the grown
    # row, and a wall bending off the line by a cell (a single wall is no object).
    if d.min() <= face + 2 * slack:
        return False
    deep = d > max_depth
    if deep.all():
        return False
    # A wall meeting the object: columns reaching farther than the front (the depth most
    # columns share) by more than a wall face, in a stretch no wider than a wall (a partition
    # ending on a cabinet's front, or crossing the hidden line between two objects), not at the
    # ends. Wider stretches are a deeper object, refused when they reach beyond the depth limit
    # (unless the front itself lies within a wall face of it: then they are not told apart).
    front = _median(d[~deep])
    farther = np.concatenate([[False], d > front + face, [False]])
    edges = np.flatnonzero(np.diff(farther.view(np.int8)))
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
    # The last cell before free space is occupied: a front face, not a shadow's edge, in nine
    # columns of ten (a scan leaves single holes in a front). Walls at an angle to the grid are
    # staircases once rotated onto the rows: :func:`_flush_fronts` reads them straightened too.
    cols = np.arange(col0, col1)[~deep]
    if (code[row + d[~deep], cols] >= 2).mean() < _FRONT_FACE_SHARE:
        return False
    # An inside a scanner did not see, behind the front: a solid piece reaching from the wall
    # into the room is the wall's own stub or pilaster (no scan sees into furniture).
    behind = code[row + 1 : row + 1 + front, col0:col1][:, ~deep]
    if not (behind == 0).any(axis=0).mean() >= 0.5:
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
            across = np.clip(
                rows[:, None, None] + sign * np.arange(1, face + 1)[:, None], 0, height - 1
            )
            along = np.clip(beyond[:, None] - step * np.arange(1, anchor + 1), 0, width - 1)
            facing = (code[across, along[:, None, :]] == 1).any(axis=1).sum(axis=1)
            down = np.clip(rows[:, None] + sign * np.arange(1, span + 1), 0, height - 1)
            free = code[down, beyond[:, None]] == 1
            depth = np.where(free.any(axis=1), free.argmax(axis=1), span)
            # The line runs on unseen for more than an anchor's length (the furniture's width, at
            # least: :func:`_corner_at`): on the Bormann maps, nearly half the candidates are not.
            ahead = np.clip(beyond[:, None] + step * np.arange(anchor + 1), 0, width - 1)
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
