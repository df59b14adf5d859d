"""The rules of the ``"walls"`` cleaning (:func:`rose.cleaning.clean`): runs, open unknown, topology guard.

Everything works on boolean masks of shape ``(rows, cols)`` in the grid's cell space (row 0 at the map
origin); lengths are in cells here, converted from metres by the caller. OpenCV does the morphology
and labelling (imported lazily, like the wall extraction).

The package: :func:`wall_cells` (here) runs the rules in order; the rules live in
:mod:`~rose.cleaning_rules.outside` (the building's edge), :mod:`~rose.cleaning_rules.runs` (walls
as straight runs and lines), :mod:`~rose.cleaning_rules.bridges` (hidden walls between wall ends),
:mod:`~rose.cleaning_rules.fronts` (furniture against walls), :mod:`~rose.cleaning_rules.objects`
(object faces, free-standing pieces, partitions, attached stubs) and
:mod:`~rose.cleaning_rules.guard` (the topology guard), on the helpers of
:mod:`~rose.cleaning_rules.masks`, :mod:`~rose.cleaning_rules.frames` and
:mod:`~rose.cleaning_rules.beside`. Names with a leading underscore are internal to the package.
"""

from __future__ import annotations

import math
from concurrent.futures import Future
from typing import TYPE_CHECKING, TypeVar

import numpy as np
import numpy.typing as npt

from rose.cleaning_rules.beside import _beside
from rose.cleaning_rules.bridges import _bridges, _in_openings, _in_plain_view, _pairs
from rose.cleaning_rules.fronts import (
    _CORNER_DEPTH_M,
    _CORNER_MAX_M,
    _FRONT_CROSSING_M,
    _FRONT_DEPTH_M,
    _FRONT_FACE_M,
    _FRONT_MAX_M,
    _flush_fronts,
)
from rose.cleaning_rules.guard import passable, topology_guard
from rose.cleaning_rules.masks import (
    _bounds,
    _near,
    _neighbour_columns,
    _nonzero_flat,
    _padded_box,
    _touching,
    length_px,
)
from rose.cleaning_rules.objects import (
    _PARTITION_MIN_M,
    _THIN_WALL_M,
    _THIN_WALL_MIN_CELLS,
    _backed_by_outside,
    _between_doors,
    _closing_walls,
    _free_standing,
    _grow_within,
    _objects_among_others,
    _partitions,
    _Pieces,
    _pocket_faces,
)
from rose.cleaning_rules.outside import (
    _backing_outside,
    _near_wide_unknown,
    _wide_and_near,
    unexplored_outside,
    wide_unknown,
)
from rose.cleaning_rules.runs import directional_runs, straight_lines
from rose.grid import FREE, OCCUPIED, UNKNOWN, blocks_any
from rose.labelling import components, label_boxes, labels_looked_up

if TYPE_CHECKING:
    from rose.cleaning import CleanParams
    from rose.result import RoseResult


_Cell = TypeVar("_Cell", np.bool_, np.int8)

__all__ = [
    "DESIGN_RESOLUTION_M",
    "coarsening",
    "directional_runs",
    "length_px",
    "passable",
    "refinement",
    "rules_cell_m",
    "straight_lines",
    "topology_guard",
    "wall_cells",
    "wall_cells_in_window",
    "wide_unknown",
]

#: Shortest stretch of wall, along a gap, that a hidden wall is drawn from (metres): a wall's end,
#: not the side face of an object across the gap.
_BRIDGE_ANCHOR_M = 0.25

#: The cell size the rules were designed and measured at (metres), the common ROS map resolution.
#: Some of their tolerances are whole cells (a run's cell of tolerance across and along, the
#: one-cell band of the straight lines, a wall face at least a cell deep), which on coarser cells
#: span more of the building: at 0.1 m furniture standing 0.1 m from a wall joined its run, and
#: robot gaps opened where an object touched a wall. Maps with cells of two design cells to under
#: three are cleaned on each cell split in 2 x 2 (:func:`refinement`); maps with cells of half a
#: design cell or less on blocks of their cells joined (:func:`coarsening`): on 0.025 m cells a
#: scanned wall's cell of wobble is half the tolerance, its runs broke, and the rules took thin
#: walls for loose pieces.
DESIGN_RESOLUTION_M = 0.05

#: Hidden walls between wall ends a cell apart across the line (a scanned wall's staircase, a wall
#: at an angle to its rotated frame): each end a stretch at least this long within a band three
#: cells wide (twice the exact anchor: a steep wall's staircase also makes short stretches in such a
#: band), and each hidden stretch at least ``_BRIDGE_ANCHOR_M`` long (shorter ones are the notches of
#: a staircase, beside the wall, not a wall hidden behind furniture).
_STAGGERED_ANCHOR_M = 2 * _BRIDGE_ANCHOR_M

#: Pieces of occupied cells are joined across gaps of up to twice this many cells (a scanned
#: wall's dropouts, an object's faces broken by a cell or two): the free-standing pieces, the
#: walls between doors and the guard's loose pieces.
_PIECES_JOIN_PX = 1


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
    window, outs = wall_cells_in_window(occupancy, result, resolution_m=resolution_m, params=params)
    # Made after the rules, whose own arrays are the cleaning's peak memory.
    masks = _nothing_kept(occupancy.shape)
    for mask, out in zip(masks, outs, strict=True):
        mask[window] = out
    return masks


def wall_cells_in_window(
    occupancy: npt.NDArray[np.int8],
    result: RoseResult,
    *,
    resolution_m: float,
    params: CleanParams,
) -> tuple[
    tuple[slice, slice],
    tuple[
        npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]
    ],
]:
    """:func:`wall_cells`' four masks on the window of the grid outside which all of them are
    False (the known cells' bounding box, padded; empty when no cell is occupied): the window
    (rows, columns) and the masks of its shape. The caller's own work on the masks can stay
    within the window too (a session map's window is often a third of the grid)."""
    p = params
    if not result.occupied.any():
        return (slice(0, 0), slice(0, 0)), _nothing_kept((0, 0))
    # Coarse maps are cleaned on their cells split, fine ones on blocks of them joined: both at
    # about the design size (``res``); at most one of ``factor`` and ``merge`` is over 1.
    factor = refinement(resolution_m)
    merge = coarsening(resolution_m)
    res = rules_cell_m(resolution_m)
    # Everything happens near known cells: work on their bounding box, padded so that every window
    # and disc that matters fits (outside it all cells are unknown).
    pad = 2 + max(
        round(length_px(p.guard_window_m, res)) + math.ceil(length_px(p.robot_radius_m, res)),
        math.ceil(length_px(p.open_unknown_width_m, res))
        + round(length_px(p.unknown_margin_m, res)),
    )
    pad = -(-pad // factor) * merge  # in the map's cells
    rows, cols = occupancy.shape
    r0, r1, c0, c1 = _bounds(occupancy >= 0)
    r0, c0, r1, c1 = r0 - pad, c0 - pad, r1 + pad, c1 + pad
    # Whole blocks of joined cells (those past the grid's edge are unknown, as below).
    r1 += -(r1 - r0) % merge
    c1 += -(c1 - c0) % merge
    window = (slice(max(r0, 0), min(r1, rows)), slice(max(c0, 0), min(c1, cols)))
    # Beyond the grid lies unknown space, as around a map with a margin of unknown cells: a map
    # cropped tight against its outer wall must clean as the same map with that margin (its wall
    # next to a narrow strip of unknown cells at the edge was not "near wide unknown" and went).
    beyond = ((max(-r0, 0), max(r1 - rows, 0)), (max(-c0, 0), max(c1 - cols, 0)))
    cells = np.pad(occupancy[window], beyond, constant_values=UNKNOWN)
    occupied = np.pad(result.occupied[window], beyond)
    structure = np.pad(result.structure[window], beyond)
    if merge > 1:
        cells = _joined_occupancy(cells, occupied, merge)
        occupied, structure = blocks_any(occupied, merge), blocks_any(structure, merge)
    outs = _wall_cells(
        _split_cells(cells, factor),
        _split_cells(occupied, factor),
        _split_cells(structure, factor),
        result.dominant_directions,
        res=res,
        p=p,
    )
    # (A joined block's outputs hold for each of its cells: the caller keeps occupied ones only,
    # and a completed block is unknown throughout.)
    kept, restored, added, removed = (
        _split_cells(out, merge)[
            beyond[0][0] : out.shape[0] * merge - beyond[0][1],
            beyond[1][0] : out.shape[1] * merge - beyond[1][1],
        ]
        for out in _joined_outputs(outs, factor)
    )
    return window, (kept, restored, added, removed)


#: Slack in the ratios of cell sizes (:func:`refinement`, :func:`coarsening`): a ROS map message
#: carries its resolution as a float32 (relative error up to 6e-8), and 0.025 m read from one is
#: 0.0250000004 m, which made the ratio to the design size 1.99999997 and left such maps' cells
#: unjoined in ``rose-bag process``.
_FLOAT32_SLACK = 1e-6


def refinement(resolution_m: float) -> int:
    """How many times finer than ``resolution_m`` (metres per cell) the cells the walls rules
    clean a map on are, along each axis: 2 for cells of two design cells to under three
    (:data:`DESIGN_RESOLUTION_M`: from 0.1 m to under 0.15 m), else 1.

    Coarser maps are cleaned as they are. Split to the design size, the ray-cast benchmark logs at
    0.15 and 0.2 m had more of their clutter removed but more robot gaps opened than cleaned as
    they were (0.2 m: median 2, worst 7, against none): where one cell holds a wall and the object against it, no
    split tells them apart, and unsplit the rules keep such cells.
    """
    return 2 if math.floor(resolution_m / DESIGN_RESOLUTION_M + _FLOAT32_SLACK) == 2 else 1


def coarsening(resolution_m: float) -> int:
    """How many cells of ``resolution_m`` metres the walls rules join into one along each axis: the
    most whose block is no larger than :data:`DESIGN_RESOLUTION_M` (0.025 m: 2, 0.02 m: 2, 0.01 m:
    5), 1 for cells larger than half a design cell.

    Measured (``bench_cleaning.py --resolutions 0.025``, the five logs ray-cast at 0.025 m): on
    the cells as they are, wall recall 0.964 (worst 0.913), clutter removed 0.909, precision 0.954,
    robot gaps 0 (worst 1), 7.9 times ``analyze``'s time; joined in 2 x 2, 0.990 (0.970) / 0.894
    / 0.955, gaps 0 (0), 2.9 times. A real office map at 0.025 m lost 54 % of its occupied cells,
    thin walls among them, and loses 25 % joined (docs/cleaning.md, 2026-12-07).
    """
    # (A map message's resolution is a float32: 0.025 arrives as 0.0250000004, a hair more.)
    return max(1, math.floor(DESIGN_RESOLUTION_M / resolution_m + _FLOAT32_SLACK))


def rules_cell_m(resolution_m: float) -> float:
    """The size of the cells the walls rules work on for a map of ``resolution_m`` metres per cell
    (metres): the map's cells split (:func:`refinement`) or joined (:func:`coarsening`)."""
    return resolution_m / refinement(resolution_m) * coarsening(resolution_m)


def _joined_occupancy(
    cells: npt.NDArray[np.int8], occupied: npt.NDArray[np.bool_], merge: int
) -> npt.NDArray[np.int8]:
    """The ``merge`` x ``merge`` blocks of the grid ``cells`` (int8, shape a multiple of ``merge``)
    as cells: occupied when any of its cells is (``occupied``), else free when any is known, else
    unknown."""
    joined = np.where(blocks_any(cells >= 0, merge), np.int8(FREE), np.int8(UNKNOWN))
    joined[blocks_any(occupied, merge)] = OCCUPIED
    return joined


def _split_cells(mask: npt.NDArray[_Cell], factor: int) -> npt.NDArray[_Cell]:
    """Every cell of ``mask`` split into ``factor`` x ``factor`` cells of its value."""
    if factor == 1:
        return mask
    return np.repeat(np.repeat(mask, factor, axis=0), factor, axis=1)


def _joined_cells(mask: npt.NDArray[np.bool_], factor: int) -> npt.NDArray[np.bool_]:
    """:func:`_split_cells` undone on a mask of the split cells: a cell is True when any of its
    ``factor`` x ``factor`` cells is (a cell with a wall in it is kept)."""
    if factor == 1:
        return mask
    return blocks_any(mask, factor)


def _joined_outputs(
    outs: tuple[
        npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]
    ],
    factor: int,
) -> tuple[
    npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]
]:
    """:func:`_wall_cells`' masks of split cells (kept, restored by the guard, completed, removed
    whatever the paper says) for the map's cells: a cell is kept or completed when any of its parts
    is, restored by the guard only when no part is kept otherwise, removed only when no part is
    kept."""
    if factor == 1:
        return outs
    kept, restored, completed, removed = outs
    joined_kept = _joined_cells(kept, factor)
    return (
        joined_kept,
        _joined_cells(restored, factor) & ~_joined_cells(kept & ~restored, factor),
        _joined_cells(completed, factor),
        _joined_cells(removed, factor) & ~joined_kept,
    )


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
        # The side thread, in turn: the pieces (by the object rules), the wide unknown space and
        # the fronts (wanted once the bridges are drawn; they read the walls kept on their own,
        # so they are submitted once this thread has found the runs and the lines), while this
        # thread finds those and the bridges. (Submitted at the start, the fronts ran beside the
        # runs and lines: reading the kept walls made clean() 7-18 % slower, the wide unknown
        # space moved here gave half of it back. Queued behind the fronts, the wide unknown space
        # had kept this thread waiting 6-10 ms per ray-cast map.)
        pieces_job = (
            beside.submit(_Pieces.of, occupied, join_px=_PIECES_JOIN_PX, directions=directions)
            if p.loose_pieces
            else None
        )
        # The same pieces not joined across gaps, for the guard's objects judged alone (the
        # occupied cells as the joined pieces listed them: the same thread, in turn).
        apart_job = (
            beside.submit(_apart_pieces, occupied, pieces_job) if pieces_job is not None else None
        )
        # (for the free-standing pieces too)
        first_near_job = beside.submit(_wide_and_near, unknown, res, p)
        runs = directional_runs(
            occupied,
            directions,
            min_length_px=length_px(p.min_run_m, res),
            tolerance_px=p.run_tolerance_px,
        )
        # Straight lines at any angle (walls off the dominant directions, curved walls in pieces);
        # the runs are walls already, and leaving them out of Hough's input makes it 1.2-3x
        # cheaper.
        # (``a & ~b`` as ``a > b`` on booleans: one pass, no temporary; the cleaning's own passes
        # over the window were a twentieth of the calling thread's time.)
        lines = straight_lines(
            np.greater(occupied, runs), min_length_px=length_px(p.min_run_m, res)
        )
        lines |= runs
        outside, near_outside = first_near_job.result()
        keep = _kept_walls(occupied, structure, near_outside, lines)
        reach_px = round(length_px(p.attach_reach_m, res))
        # Furniture flush against a wall: its hidden wall line is drawn, as the bridges' are,
        # between two stretches of walls kept on their own or joined to one as attached pieces
        # are (a door frame's stub between a cabinet and a doorway); clutter in line in a room,
        # standing apart from the walls, is neither.
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
            # Grown here: ``keep`` changes in place later, while the side thread may still run.
            walls=_grow_within(keep, occupied, reach_px),
        )
        free = unknown | occupied  # known cells that are not occupied
        np.logical_not(free, out=free)
        completed = np.zeros(occupied.shape, dtype=bool)
        sealed_off = completed  # what closes scanned objects and the building, as walls or not
        standing_in_doorways = completed
        unreached = completed  # hidden lines out of reach of the cells removed so far
        undrawn = completed  # hidden wall lines left undrawn, hidden from the room
        if p.max_bridge_m > 0:
            # Unknown cells between collinear kept walls. Those between wall ends become the wall
            # line hidden behind furniture; all of them seal what they close off (an object's
            # inside between its faces, a cabinet's open back) but are not drawn as walls.
            # Bridged over every cell that is not occupied, the unknown ones kept below: the free
            # ones tell a gap seen through (a doorway) from a wall hidden behind furniture.
            bridges, wall_lines, staggered = _bridges(
                keep,
                np.logical_not(occupied),
                directions,
                length_px(p.max_bridge_m, res),
                (1, length_px(_BRIDGE_ANCHOR_M, res)),
                staggered_px=(
                    length_px(_STAGGERED_ANCHOR_M, res),
                    length_px(_BRIDGE_ANCHOR_M, res),
                ),
            )
            # Wall ends a cell apart across the line draw the hidden wall too (exact anchors need
            # the ends in one row of the rotated frame: a staircase at 30 or 45 degrees breaks that).
            bridges |= staggered
            wall_lines |= staggered
            spans = bridges.copy()
            bridges &= unknown
            wall_lines &= unknown
            # Only next to what goes (within a cabinet's depth): a bridge network reaching into
            # unexplored space or across racks is no wall hidden behind removed clutter.
            removed = np.greater(occupied, keep)
            hidden_reach = round(length_px(p.hidden_wall_reach_m, res))
            touching = _touching(bridges, removed)
            sealed_off = _near(touching, removed, hidden_reach)
            completed = sealed_off & wall_lines
            # (Within reach of what goes later, they are drawn at the end: _reached_later.)
            unreached = np.greater(touching & wall_lines, completed)
            # Not drawn where nothing hides it from the room and unexplored space lies beyond: a
            # doorway beside a box that hides part of it was closed for a robot by the line
            # drawn on within the box's reach. (Between two mapped rooms the line is drawn as
            # before: both sides seen, nothing beyond.) Only openings wider than the robot: an
            # unseen stretch of outer wall beside a cabinet is no doorway.
            in_view = _in_plain_view(
                completed, free, near_outside, 2 * length_px(p.robot_radius_m, res) + 1
            )
            np.greater(completed, in_view, out=completed)
            # The rest of the wall lines, undrawn: nothing removed next to them so far.
            undrawn = np.greater(
                wall_lines,
                _in_plain_view(
                    wall_lines, free, near_outside, 2 * length_px(p.robot_radius_m, res) + 1
                ),
            )
        # Furniture against a wall (a cabinet, a counter: its front a straight run when 2 m or
        # longer): the wall line hidden behind it is drawn, its front and sides go, and the walls
        # that meet it stay.
        front_lines, fronts, inside, front_walls = fronts_job.result()
        completed = completed | front_lines
        sealed_off = sealed_off | front_lines
        if p.max_bridge_m > 0:
            # Neither line is drawn behind a box standing in a doorway, the gap seen through on
            # both sides of it: drawn, it left the gaps beside it, narrower than a robot, once
            # the box went.
            in_doorways, standing_in_doorways = _in_openings(
                completed,
                spans,
                free,
                unknown,
                removed,
                occupied,
                2 * length_px(p.robot_radius_m, res) + 1,
            )
            np.greater(completed, in_doorways, out=completed)
            np.greater(undrawn, in_doorways | completed, out=undrawn)
            unreached = np.greater(unreached, _touching(unreached, in_doorways))
        sealed = bool(sealed_off.any())
        near_job: Future[npt.NDArray[np.bool_]] = Future()
        near_job.set_result(near_outside)
        if sealed:
            # The sealed cells separate the room from the unknown beyond them: furniture faces
            # in front are no longer next to the outside (a cabinet's inside, open through the
            # unscanned wall behind it, made its faces look like the building's edge). Nor
            # within the margin of the outside across a drawn line, for the walls kept and the
            # free-standing pieces' anchors (a copy of the lines: the side thread reads it while
            # this one goes on).
            near_job = beside.submit(
                _near_wide_unknown, np.greater(unknown, sealed_off), res, p, completed.copy()
            )
        dropped_job = None
        if pieces_job is not None:
            # Free-standing pieces need neither the object faces nor the attached pieces: they
            # go beside them, after the pieces and the wide unknown space they need (the same
            # thread, in turn: this one does not wait for the pieces here).
            dropped_job = beside.submit(
                _free_standing, pieces_job, lines, near_job, unknown, res, p
            )
        faces = np.zeros(occupied.shape, dtype=bool)
        pockets = faces
        if p.object_pocket_m2 > 0:
            # Object faces: a scanner sees a solid object as faces around a small unknown pocket
            # (its inside, sealed by the bridges across it). They go unless on a long straight run.
            faces, pockets = _pocket_faces(
                unknown, sealed_off, occupied, length_px(p.object_pocket_m2, res**2)
            )
        if sealed:
            keep = _kept_walls(occupied, structure, near_job.result(), lines)
        if front_lines.any():
            # The wall ends the hidden line joins are the wall, not faces of the object's inside
            # (dilated on the lines' box only: a few objects in a large map).
            box = _padded_box(front_lines, 1)
            beside_lines = cv2.dilate(front_lines[box].view(np.uint8), np.ones((3, 3), np.uint8))
            faces[box] &= ~beside_lines.view(bool)
        object_faces = np.greater(faces, lines)
        object_faces |= fronts
        # Occupied cells with the outside right behind them (no drawn line between): removed,
        # they open the room onto it. Kept whatever the object rules and the paper say: a step
        # of an outer wall (ECN's lab map), 0.2-0.3 m in front of the wide unknown, its back
        # sealed off as an object's inside, went whole, and the guard's window saw the room
        # meet the outside round the next wall's end. Only in pieces 2 m or more across, not
        # within a cabinet's depth of a drawn line, and not within three guard windows (through
        # the unknown) of where the room meets that unknown at a robot's scale: objects at the
        # explored edge and at a wall's end have the outside behind them too (measured with
        # ``bench_cleaning.py``: docs/cleaning.md, 2026-12-07).
        backed = (
            np.zeros(occupied.shape, dtype=bool)
            if apart_job is None
            else _backing_outside(
                occupied,
                unknown,
                completed | unreached,
                apart_job.result(),
                free,
                np.greater(keep, object_faces),
                pockets,
                radius_px=length_px(p.robot_radius_m, res),
                edge_reach_px=round(length_px(3 * p.guard_window_m, res)),
                depth_px=max(1, round(length_px(p.unknown_margin_m, res))),
                min_extent_px=length_px(p.min_run_m, res),
                line_reach_px=round(length_px(p.hidden_wall_reach_m, res)),
            )
        )
        np.greater(object_faces, backed, out=object_faces)
        np.greater(keep, object_faces, out=keep)
        keep |= backed
        keep |= front_walls  # walls meeting furniture fronts: kept, attach to them
        if p.attach_reach_m > 0:
            # Wall stubs, door frames, corners: occupied cells joined to a kept wall within the
            # reach, through occupied cells that are not object faces (nor fronts).
            through = np.greater(occupied, faces)
            np.greater(through, fronts, out=through)
            attached = _grow_within(keep, through, reach_px)
            np.greater(attached, keep, out=attached)
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
                free,
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
    # Loose pieces two rules below count as the guard's obstacles (returns at the explored edge,
    # pieces backed by the outside): they must not move the guard's cuts (its ``off_grid``).
    counted_loose: npt.NDArray[np.bool_] | None = None
    if pieces_job is not None and apart_job is not None:
        pieces = pieces_job.result()
        np.greater(keep, dropped, out=keep)
        # A wall between two doors: a piece nothing kept (too short for a run) that continues
        # kept walls in line across a door at each end.
        keep |= _between_doors(pieces, pieces.loose(keep), keep, free, directions, res)
        # Furniture a hidden wall line is drawn behind (next to the line, which meets a kept
        # wall) stands against that wall, not in the room: counted as the guard's obstacle as a piece joined to a kept wall
        # is. A cabinet whose corner shadows part it from the wall it stands against is no piece
        # of that wall; ignored, it went although the line behind it was drawn only in part
        # (its middle out of the hidden wall's reach of the cells removed so far) and the wall
        # opened. (Where the line is whole, its removal opens nothing the guard restores.)
        # The furniture-front rule's lines anchor what stands within two cells of them, whatever
        # they meet: that rule draws a line only behind furniture between two stretches of kept
        # wall, and a cabinet at 45 degrees, its corner shadows left undrawn as in plain view,
        # has a line that meets no kept wall, two cells from its turned sides (the straightened
        # band of a staircase wall): ignored, it went and the room opened.
        anchored = _beside_lines(keep, occupied, completed, completed & front_lines)
        # Furniture that hid a wall line left undrawn (an unseen stretch of wall between two kept
        # wall ends, out of the room's plain view, as long as a robot is wide at least) closed the
        # room with that wall before: it counts as the guard's obstacle too, when every cell of
        # the line a robot's centre could cross (farther than its radius from a kept wall) lies
        # closer than a robot's width to the piece's convex hull. A cabinet 0.1-0.15 m off an
        # outer wall unseen behind it went (as an object's faces or a free-standing piece), no
        # line was drawn (nothing removed touched it) and the room opened. (Any piece within a
        # robot's width of such a line kept clutter on the benchmark's logs: boxes in front of
        # part of a line, two of them shadowing it, a box before holes in a ragged wall.)
        robot_px = math.floor(2 * length_px(p.robot_radius_m, res) + 1)
        if undrawn.any():
            anchored = anchored | _hiding(
                occupied,
                pieces.labels,
                undrawn,
                keep,
                reach_px=robot_px,
                radius_px=math.floor(length_px(p.robot_radius_m, res)),
            )
        # Pieces attached to no kept wall at all are furniture standing in the room: the guard
        # does not count them as obstacles of the input. Only those whose box is smaller than a
        # region the guard protects, though: they can enclose nothing it would count (a closed
        # free-standing room of 1.3 m x 1.3 m was removed whole, its inside opened).
        loose = pieces.loose(anchored, max_box_area_px=min_region_px)
        # The box is the grid's: furniture turned with the map has a box up to twice as large as
        # unturned, and was counted. Boxes along the map's directions count as well, for pieces
        # seen from more than one side (a wall's step at the explored edge, unknown behind it, is
        # seen from one: the guard keeps counting it).
        turned = np.greater(
            pieces.loose(anchored, max_box_area_px=min_region_px, max_frame_area_px=min_region_px),
            loose,
        )
        if turned.any():
            loose |= pieces.seen_round(turned, unknown)
        # Scanned objects standing close together (a row or cluster of boxes, gaps of a cell or
        # two between them) join into pieces whose box is too large, and the guard kept each of
        # them for the passages between its neighbours: an object with its faces around an
        # unseen inside wider than a wall's core, and no kept wall within the join's reach, is
        # judged alone.
        loose |= _objects_among_others(
            apart_job.result(),
            loose,
            anchored,
            unknown,
            pockets,
            reach_px=2 * _PIECES_JOIN_PX + 1,
            max_box_area_px=min_region_px,
            inside_px=length_px(_THIN_WALL_M, res),
        )
        # A piece that continues a kept wall in line across a gap narrower than a robot (a dashed
        # wall's dashes past the last one kept) closed that wall for a robot: counted as the
        # guard's obstacle, not as furniture.
        if loose.any():
            np.greater(
                loose,
                _closing_walls(
                    apart_job.result(), loose, keep, free, directions, res, robot_px=robot_px
                ),
                out=loose,
            )
        # A piece at the explored edge, unexplored space that reaches the map's edge behind it,
        # closed the known space off from the unknown in the input, with the other pieces there
        # (the scattered ends of a SLAM map's rays into a room seen through its door): counted.
        if loose.any():
            apart = apart_job.result()
            returns = loose & apart.loose(anchored, max_extent_px=robot_px)
            if returns.any():
                counted_loose = apart.facing(returns, unexplored_outside(unknown))
                loose = np.greater(loose, counted_loose)
        # A piece off an outer wall whose line runs on past it, unseen behind it, the outside
        # within a robot's width of its back (a cabinet and a box side by side, 2 m or more: no
        # hidden line drawn): counted too, and kept off the cuts' grid as the returns are.
        if loose.any():
            backed = _backed_by_outside(
                apart_job.result(), loose, unknown, outside, keep & lines, robot_px=robot_px
            )
            if backed.any():
                counted_loose = backed if counted_loose is None else counted_loose | backed
                loose = np.greater(loose, backed)
        guard_obstacles = np.greater(occupied, loose)
    if standing_in_doorways.any():
        # An object standing in a doorway seen through on both sides of it kept the doorway
        # closed in the input; without it the doorway is open, as the scans through it show.
        guard_obstacles = np.greater(guard_obstacles, standing_in_doorways)
        # Nor is it kept: its cells by the wall line and the unexplored space beyond (near wide
        # unknown, a wall's end attached to them; within two cells of a door edge, on the wall's
        # run by the run's cell of tolerance) were kept and left the doorway too narrow for the
        # robot. (It is a piece of its own, the wall's cells are not among them.)
        np.greater(keep, standing_in_doorways, out=keep)
    if unreached.any():
        completed = completed | _reached_later(
            unreached,
            completed,
            np.greater(occupied, keep | removed),
            free,
            near_outside,
            reach_px=hidden_reach,
            robot_px=2 * length_px(p.robot_radius_m, res) + 1,
        )
    if undrawn.any():
        # A hidden wall line left undrawn that closes the shadow of something removed (a pocket
        # of unseen space seen into from the room): drawn. Nothing removed touched it, so it was
        # left open, and the shadow led through it out of the room (an object standing off the
        # wall, the stretch it hid unseen). Drawn last, seen only by the guard: the rules above
        # read drawn lines as what furniture stands against, and drawn earlier they changed
        # what they kept far from any such shadow (ray ends beyond the building's edge).
        # Within reach of what goes, as the lines drawn above. (Undrawn lines come from the
        # bridges only, which set that reach.)
        unkept = np.greater(occupied, keep)
        completed = completed | _near(
            _closing_lines(undrawn, completed, unknown, free, unkept, min_region_px),
            unkept,
            hidden_reach,
        )
    guarded = topology_guard(
        guard_obstacles,
        keep,
        added=completed,
        hidden=inside,
        radius_px=length_px(p.robot_radius_m, res),
        window_px=max(1, round(length_px(p.guard_window_m, res))),
        min_region_px=min_region_px,
        off_grid=counted_loose,
    )
    kept = keep | guarded
    # (Object faces a partition keeps are walls, not dropped.) What stands in a doorway goes
    # even where the paper calls it structure.
    gone = dropped | object_faces
    gone |= standing_in_doorways
    return kept, guarded, completed, np.greater(gone, kept, out=gone)


def _closing_lines(
    undrawn: npt.NDArray[np.bool_],
    completed: npt.NDArray[np.bool_],
    unknown: npt.NDArray[np.bool_],
    free: npt.NDArray[np.bool_],
    removed: npt.NDArray[np.bool_],
    max_pocket_px: float,
) -> npt.NDArray[np.bool_]:
    """The pieces (8-connected) of the ``undrawn`` hidden wall lines that close a shadow: a pocket
    of ``unknown`` cells (4-connected, the undrawn and ``completed`` lines its boundary too) of at
    most ``max_pocket_px`` cells, not reaching the image's edge, next to a piece of them, to
    ``free`` cells and to ``removed`` cells (8-neighbours). Masks of shape ``(rows, cols)``.

    Such a pocket is the unseen space behind something removed, seen into from the room and
    closed by the line: the shadow an object standing off a wall casts on it. Undrawn, the shadow
    led through the unseen stretch of wall to whatever lies beyond, and removing the object
    opened the room there (a tree in a room's corner, 0.25 m off an outer wall).
    """
    count, pockets = components(np.greater(unknown, undrawn | completed), connectivity=4)

    def next_to(mask: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
        """Flags of the pockets with a cell next to one of ``mask``'s (few) cells."""
        flags = np.zeros(count, dtype=bool)
        cells = _nonzero_flat(np.ascontiguousarray(mask).view(np.uint8))
        for labels in _neighbour_columns(pockets, cells):
            flags[labels] = True
        return flags

    wanted = next_to(undrawn)
    for edge in (pockets[0], pockets[-1], pockets[:, 0], pockets[:, -1]):
        wanted[edge] = False
    wanted[0] = False  # (no unknown cell, or a line's)
    wanted &= next_to(removed)
    if not wanted.any():
        return np.zeros(undrawn.shape, dtype=bool)
    # The few pockets left: their size, and whether a free cell is next to one.
    # (OpenCV's or numpy's lookup of bytes: half the cost of indexing booleans by the labels.)
    cells = _nonzero_flat(labels_looked_up(wanted, pockets).view(np.uint8))
    own = pockets.reshape(-1)[cells]
    wanted &= np.bincount(own, minlength=count) <= max_pocket_px
    beside_free = np.zeros(count, dtype=bool)
    beside_free[own[np.logical_or.reduce(_neighbour_columns(free.view(np.uint8), cells))]] = True
    wanted &= beside_free
    if not wanted.any():
        return np.zeros(undrawn.shape, dtype=bool)
    shadows = np.zeros(undrawn.shape, dtype=bool)
    shadows.reshape(-1)[cells[wanted[own]]] = True
    return _touching(undrawn, shadows)


def _apart_pieces(occupied: npt.NDArray[np.bool_], joined: Future[_Pieces]) -> _Pieces:
    """The 8-connected pieces of ``occupied`` not joined across gaps, their cells listed as the
    ``joined`` pieces of the same cells listed them."""
    return _Pieces.of(occupied, join_px=0, cells=joined.result().cells)


def _reached_later(
    unreached: npt.NDArray[np.bool_],
    completed: npt.NDArray[np.bool_],
    gone_later: npt.NDArray[np.bool_],
    free: npt.NDArray[np.bool_],
    open_unknown: npt.NDArray[np.bool_],
    *,
    reach_px: int,
    robot_px: float,
) -> npt.NDArray[np.bool_]:
    """Cells of the hidden wall lines left ``unreached`` (touching removed cells, but out of reach
    of them when the lines were drawn) within ``reach_px`` of the cells ``gone_later`` (removed
    after the lines were drawn: a cabinet's front, the paper's structure, goes as a free-standing
    piece or object face once the line seals its inside), in pieces (8-connected) that join two
    pieces of the ``completed`` line (a hole in it), and not in plain view
    (:func:`_in_plain_view` of the lines with them, ``free``, ``open_unknown``, ``robot_px``).
    Measured from the sides alone, the line behind a cabinet wider than twice the reach was drawn
    at its ends only and left the wall open in its middle. Masks of shape ``(rows, cols)``."""
    out = np.zeros(unreached.shape, dtype=bool)
    if not gone_later.any() or not completed.any():
        return out
    near = _near(unreached, gone_later, reach_px)
    if not near.any():
        return out
    # Only what closes a hole: pieces of them between two pieces of the line drawn (a line drawn
    # on past its end, or thicker, closes nothing). The drawn pieces labelled whole (in a box
    # holding them all): cut by a smaller box, one piece could read as two.
    box = _padded_box(near | completed, 1)
    count, pieces = components(near[box])
    drawn_count, drawn = components(completed[box])
    cells = _nonzero_flat(np.ascontiguousarray(near[box]).view(np.uint8))
    piece_of, _ = _pairs(cells, pieces.reshape(-1)[cells], drawn, drawn_count)
    joining = np.bincount(piece_of, minlength=count) >= 2
    joining[0] = False
    # Looked up at the near cells only (listed above), not at every label of the box.
    found = np.zeros(pieces.shape, dtype=bool)
    found.reshape(-1)[cells] = joining[pieces.reshape(-1)[cells]]
    out[box] = found
    if not out.any():
        return out
    np.greater(out, _in_plain_view(completed | out, free, open_unknown, robot_px), out=out)
    return out


def _hiding(
    occupied: npt.NDArray[np.bool_],
    labels: npt.NDArray[np.integer],
    lines: npt.NDArray[np.bool_],
    walls: npt.NDArray[np.bool_],
    *,
    reach_px: int,
    radius_px: int,
) -> npt.NDArray[np.bool_]:
    """The ``occupied`` cells of the pieces (``labels``, 0 none) whose convex hull (of their cells
    in the line piece's box) lies within ``reach_px`` (chessboard distance) of every cell of a
    piece (8-connected) of ``lines`` that is farther than ``radius_px`` from ``walls`` (where a
    robot's centre could cross the line were it open; a line piece with no such cell is no way
    through, nor one whose box is shorter than ``reach_px`` on both sides, a robot's width):
    what hides that stretch from the room. A new array; each line piece is looked at in
    its own box, ``reach_px`` wider (a few lines in a large map). Masks of shape
    ``(rows, cols)``."""
    import cv2

    out = np.zeros(occupied.shape, dtype=bool)
    box = _padded_box(lines, reach_px)
    count, line_labels = components(lines[box])
    cells = _nonzero_flat(np.ascontiguousarray(lines[box]).view(np.uint8))
    x, y, width, height = label_boxes(line_labels, cells, count).T.tolist()
    kernel = np.ones((2 * reach_px + 1, 2 * reach_px + 1), np.uint8)
    disc = np.ones((2 * radius_px + 1, 2 * radius_px + 1), np.uint8)
    rows, cols = line_labels.shape
    for index in range(1, count):
        if max(width[index], height[index]) < reach_px:  # narrower than a robot: no way through
            continue
        r0, c0 = max(y[index] - reach_px, 0), max(x[index] - reach_px, 0)
        r1 = min(y[index] + height[index] + reach_px, rows)
        c1 = min(x[index] + width[index] + reach_px, cols)
        at = (
            slice(box[0].start + r0, box[0].start + r1),
            slice(box[1].start + c0, box[1].start + c1),
        )
        line = line_labels[r0:r1, c0:c1] == index
        beside_walls = cv2.dilate(walls[at].view(np.uint8), disc).view(bool)
        np.greater(line, beside_walls, out=line)
        if not line.any():
            continue
        near = cv2.dilate(line.view(np.uint8), kernel).view(bool)
        pieces = labels[at] * occupied[at]
        for piece in np.unique(pieces[near]).tolist():
            if piece == 0:
                continue
            own = pieces == piece
            # The piece's convex hull: a cabinet open at the back hides the line behind its
            # inside too, not only behind its sides' ends.
            hull = np.zeros(own.shape, dtype=np.uint8)
            ys, xs = np.nonzero(own)
            points = np.stack([xs, ys], axis=1).astype(np.int32)
            cv2.fillConvexPoly(hull, cv2.convexHull(points), 1)
            covered = cv2.dilate(hull, kernel).view(bool)
            if not np.greater(line, covered).any():
                out[at] |= own
    return out


def _beside_lines(
    keep: npt.NDArray[np.bool_],
    occupied: npt.NDArray[np.bool_],
    lines: npt.NDArray[np.bool_],
    front_lines: npt.NDArray[np.bool_],
) -> npt.NDArray[np.bool_]:
    """``keep`` and the ``occupied`` cells next to (8-connected) a piece of ``lines`` (the hidden
    wall lines drawn, 8-connected pieces) within two cells of a ``keep`` cell, or within two cells
    (chessboard) of ``front_lines`` (those among them the furniture-front rule drew): the cells that
    anchor a piece to the building, through the wall line it stands in front of. (A piece of line
    that meets nothing kept is no wall's: a line drawn across the inside of a box standing in a
    doorway, between its sides; the front rule draws no such line.) Returns ``keep`` itself when
    no such line; a new array otherwise. Masks of shape ``(rows, cols)``."""
    import cv2

    lines = _touching(lines, keep)
    if not lines.any() and not front_lines.any():
        return keep
    anchored = keep.copy()
    # (a front line in a frame at an angle lies in the straightened band of a staircase wall,
    # up to two cells from the furniture's sides)
    for drawn, reach in ((lines, 1), (front_lines, 2)):
        if drawn.any():
            box = _padded_box(drawn, reach)  # (the lines' box only: a few objects in a large map)
            side = 2 * reach + 1
            beside = cv2.dilate(drawn[box].view(np.uint8), np.ones((side, side), np.uint8))
            anchored[box] |= occupied[box] & beside.view(bool)
    return anchored


def _kept_walls(
    occupied: npt.NDArray[np.bool_],
    structure: npt.NDArray[np.bool_],
    near_outside: npt.NDArray[np.bool_],
    lines: npt.NDArray[np.bool_],
) -> npt.NDArray[np.bool_]:
    """``occupied & (structure | near_outside) | lines``, in three passes into one new array."""
    keep = structure | near_outside
    keep &= occupied
    keep |= lines
    return keep
