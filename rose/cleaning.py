"""The cleaned map users get: clutter removed, walls kept, no gap a robot could drive through.

Two methods, chosen by name:

``"paper"``
    The paper's labelling as it is (:attr:`rose.RoseResult.cleaned`): every occupied cell the mixture
    threshold calls clutter is removed. Right for what the paper measures (structure precision), but
    on real SLAM maps it removes most wall cells and opens holes a planner would drive through.

``"walls"`` (the default)
    Starts from the paper's structure and keeps, in addition, every occupied cell that

    1. lies on a straight run of at least ``min_run_m``, along a dominant direction (a one-cell
       tolerance across and along the run absorbs the stair steps and dropouts of a scanned wall) or
       at any angle (probabilistic Hough): walls are long, furniture faces short; or
    2. lies within ``unknown_margin_m`` of *wide* unknown space: unknown cells a disc of diameter
       ``open_unknown_width_m`` fits in. Walls separate the known building from the unknown outside
       and from unexplored rooms; the narrow shadows a scanner leaves behind furniture, and the
       insides of scanned objects, are not wide (an object whose unseen inside is wider reads as
       an unexplored room, and its faces stay).

    Furniture against a wall hides the wall behind it; so that removing it does not open the wall,
    unknown cells on the straight line between the ends of two kept walls along a dominant direction
    (wall stretches of at least 0.25 m running along the gap, not an object's side faces across
    it), at most ``max_bridge_m`` apart, next to a removed piece and within ``hidden_wall_reach_m``
    of it (or, where such a stretch closes a hole between two pieces of the line, of cells the
    later rules remove: a cabinet's front; or, last, where the line closes the shadow of a removed
    piece: a pocket of unknown cells of at most ``min_region_m2``, next to free cells and to a
    removed cell, that the line parts from the rest of the unknown space), become walls
    (``completed``; thin lines only, never the space between two parallel
    walls; not where the line is in plain view of the room with wide unknown space beyond it,
    next to a free cell and within ``unknown_margin_m`` of it in a stretch at least
    ``2 * robot_radius_m`` plus a cell long, nor within two cells of such a cell along the line:
    a doorway beside furniture, not a hidden wall; nor behind an object standing in a doorway,
    the gap between the wall ends seen through beside it on both sides, whose removal the topology
    guard then lets open the doorway). Wall ends up to a cell apart across the line (a scanned wall's staircase, a wall at an
    angle to the grid) are joined too, by a line up to three cells thick, when each is a stretch of
    at least 0.5 m within a band three cells wide and the hidden stretch is at least 0.25 m long.
    Such lines between any two kept cells also *seal*: they close the insides of objects for rules
    2 and 3, without being drawn; and rule 2's margin is not measured across a drawn line (the
    sides of a cabinet by the unseen wall behind it stood within the margin of the outside).
    Longer furniture flush against a wall (up to 5 m, its front a straight run a scan cannot tell
    from a wall) is found by its shape along walls at any angle to the grid (read straightened
    there too): a stretch of unknown cells on a wall's line between two
    stretches of that wall facing the room, each holding a cell of a wall kept on its own merits
    (the paper's structure, rules 1 and 2) or joined to one within ``attach_reach_m`` (a door
    frame's stub; two blobs of clutter in line in a room are neither), with a front face 0.15-1 m
    in front of it and an unseen inside behind the front; the line is drawn, the front and sides
    go, and a wall meeting the front stays. Furniture in a room's corner (on maps whose walls lie
    along the grid's axes) is found the same way with the other wall's line as the second end: a
    wall's visible stretch of at least 0.5 m, its line hidden up to 5 m on to a perpendicular wall
    that runs on from the furniture's front, the front straight and 0.3-1 m from the line; both
    hidden lines are drawn.

    Three rules then tell wall pieces from objects the way a scanner sees them:

    3. *object faces*: occupied cells around a small enclosed unknown pocket (less than
       ``object_pocket_m2``, the sealing lines counting as its boundary) are the faces of a
       scanned object, whose inside stays unknown; they go unless they lie on a straight run,
       or have the unexplored outside right behind them (with ``loose_pieces``): unknown space
       joined to the map's edge through space at least three cells wide that crosses no drawn
       line, next to them or within ``unknown_margin_m`` through their wall, in an 8-connected
       piece at least ``min_run_m`` across, farther than ``hidden_wall_reach_m`` from a drawn
       line and farther than three guard windows through that space from where a robot in the
       room could drive up to it (the explored edge). Such a cell stays even when the paper calls
       it clutter: a step of an outer wall, its unseen core 0.2-0.3 m deep in front of the wide
       unknown, read as an object's faces once sealing lines closed its back, went whole;
    4. *attached pieces*: occupied cells joined to a kept wall within ``attach_reach_m`` (through
       occupied cells that are not object faces) stay: wall stubs, door frames, corners; and so do
       *partitions*, pieces seen from both sides (known free space across them along a grid row
       or column within 0.3 m or 3 cells, an unseen core between two faces included) at least 0.5 m long
       that meet a kept wall: a wall between a corner and a door, a thick wall's second face
       around its unseen core, which rule 3 reads as an object's faces (both only when
       ``attach_reach_m`` > 0);
    5. *free-standing pieces* (``loose_pieces``): a piece (joined across gaps of up to two cells)
       with no cell on a run or near wide unknown space, whose joined bounding box has a diagonal
       under ``min_run_m``, is removed, unless it closes around known free space (a small room,
       not an object) or holds a solid square 0.25 m across (a column as drawn maps show it). Like object faces, it goes even where the paper's labelling calls it
       structure (so ``kept`` need not contain the paper's structure). Pieces attached to no kept
       wall and smaller than ``min_region_m2`` (they can enclose no region the guard protects) do
       not count as obstacles for the guard, unless a drawn hidden wall line that meets a kept
       wall runs next to them, or a line the furniture-front rule drew runs within two cells of
       them (furniture against that wall, its corner shadows parting it from the wall), or they
       hide an undrawn hidden wall line (unseen cells between two kept wall ends, not in plain
       view of the room): every cell of it farther than ``robot_radius_m`` from a kept wall lies
       within a robot's width (``2 * robot_radius_m`` plus a cell) of the piece's convex hull (a
       cabinet a few cells off an outer wall unseen behind it); nor do
       scanned objects that stand close to others
       (joined with them across a gap into a larger piece), judged one by one: an 8-connected
       piece with no kept cell within the join's reach (three cells), a box under
       ``min_region_m2``, and its faces around an unseen inside (along grid rows or columns,
       on two lines or more, two of its cells with at least 0.3 m of unknown cells between
       them, reaching an object's pocket: wider than a wall's core).
    6. *walls between two doors*: a piece none of the above kept, along a dominant direction at
       most 0.3 m thick and twice as long, with known free space beyond each end for at most
       1.2 m and then a kept wall in line for at least 0.3 m, stays, whatever the paper's
       labelling says.

    Finally a topology guard (counting the completed walls, those drawn, as obstacles before and
    after: the inside of a cabinet closed by the wall line behind it is a pocket, not the unknown
    outside) finds every opening through which a disc
    of ``robot_radius_m`` would pass between two regions that the input kept apart (locally, within
    ``guard_window_m``), unless one of them is a small enclosed pocket (less than ``min_region_m2``:
    the inside of a piece of furniture), and restores the removed cells that blocked it (those
    within the disc's reach of the opening). An opening longer than four windows is also judged
    in pieces (cut along a grid of four windows), and a piece that joins two regions restores it
    whole, unless the opening meets nothing that stays and rings no hole (furniture removed in a
    row in a room: a robot went round it before).

The rules were designed and measured on cells of 0.05 m, and some of their tolerances are whole
cells (a run's cell of tolerance, the straight lines' one-cell band, a wall face a cell deep). A map
with cells from 0.1 m to under 0.15 m is cleaned on its cells split in 2 x 2 (its lengths in
metres read at half its cell size), the ROSE masks split with them; a cell is kept or completed
when any of its parts is, removed when none is kept. Coarser maps are cleaned as they are (split
further, more of their clutter went but more robot-sized gaps opened). A map with cells of 0.025 m
or less is cleaned on blocks of its cells joined up to 0.05 m (2 x 2 at 0.025 m, 5 x 5 at 0.01 m):
a block is occupied when any of its cells is, and what the rules decide for it holds for each of
its cells (on its own cells a scanned wall's wobble broke its runs, and thin walls went).

Everything is deterministic (OpenCV morphology, labelling and its probabilistic Hough transform,
which seeds itself) and never modifies the input.

Both return a :class:`CleanResult`; the paper's structure / clutter masks stay in the
:class:`rose.RoseResult`.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from rose.errors import RoseError
from rose.frozen import ReadOnlyArrays, seal
from rose.grid import OCCUPIED, as_occupancy_grid, warn_if_mask
from rose.limits import finite_number, integer_number
from rose.mapfile import DEFAULT_RESOLUTION_M, OccupancyMap, resolution_problem
from rose.params import RoseParams
from rose.result import RoseResult, check_result_for

__all__ = ["CLEAN_METHODS", "CleanMethod", "CleanParams", "CleanResult", "clean"]

_LOG = logging.getLogger(__name__)

CleanMethod = Literal["walls", "paper"]
CLEAN_METHODS: tuple[CleanMethod, ...] = ("walls", "paper")


@dataclass(frozen=True)
class CleanParams:
    """Tuning parameters of the ``"walls"`` cleaning, in metres (converted with the size of the cells
    the rules work on: the map's, or half of it for cells from 0.1 m to under 0.15 m, module notes).

    Attributes
    ----------
    min_run_m : float
        Straight occupied runs at least this long are walls.
    open_unknown_width_m : float
        Unknown space is wide (the outside, unexplored rooms) where a disc of this diameter fits in it.
    unknown_margin_m : float
        Distance from wide unknown space within which an occupied cell is a wall.
    min_region_m2 : float
        Regions of the guard smaller than this that do not reach the guard's window edge are
        enclosed pockets (the inside of a piece of furniture), not places a robot could reach.
    robot_radius_m : float
        Radius of the disc the topology guard keeps out of every wall, metres.
    guard_window_m : float
        Margin of the window around each opened patch in which the guard tells regions apart. The
        smaller it is, the stricter the guard: two sides of a wall that connect within the window
        (through a doorway nearby) count as one region, so a hole next to a doorway passes unguarded.
        Half a metre keeps such holes out at a small cost in clutter removed (measured with
        ``benchmarks/bench_cleaning.py``; numbers in the README).
    run_tolerance_px : int
        Cells of tolerance across and along a run (stair steps, dropouts), of the cells the rules
        work on (half a cell of a map with cells from 0.1 m to under 0.15 m).
    max_bridge_m : float
        Longest hidden wall completed behind removed furniture: unknown cells on the straight line
        between the ends of two kept walls along a dominant direction, at most this far apart (0:
        never, and no furniture flush against a wall is taken out either).
    hidden_wall_reach_m : float
        Hidden walls are completed only within this distance (chessboard) of removed cells: the
        depth of the furniture they hide behind (a hole between two pieces of a drawn line also
        within it of cells removed by the later rules).
    attach_reach_m : float
        Occupied cells joined to a kept wall within this distance (through occupied cells that are
        not object faces) are kept: wall stubs, door frames, corners; also partitions (module
        notes, rule 4). 0: neither.
    object_pocket_m2 : float
        Unknown pockets smaller than this, enclosed by occupied and sealing cells, are the insides
        of scanned objects; the occupied cells around them are object faces, removed unless on a
        straight run of ``min_run_m`` (0: no object faces).
    loose_pieces : bool
        Remove free-standing pieces (no cell on a run or near wide unknown, even across a gap of up
        to two cells; a joined box with a diagonal under ``min_run_m``; not closed around known
        free space) even where the paper calls them structure, and let the guard ignore pieces
        attached to no kept wall (nor next to a drawn hidden wall line meeting one, nor within
        two cells of a line the furniture-front rule drew, nor hiding an undrawn hidden wall
        line from the room) that are smaller than ``min_region_m2``.
    """

    min_run_m: float = 2.0
    open_unknown_width_m: float = 1.0
    unknown_margin_m: float = 0.15
    min_region_m2: float = 1.0
    robot_radius_m: float = 0.15
    max_bridge_m: float = 2.0
    guard_window_m: float = 0.5
    run_tolerance_px: int = 1
    attach_reach_m: float = 0.3
    hidden_wall_reach_m: float = 0.5
    object_pocket_m2: float = 2.0
    loose_pieces: bool = True

    def __post_init__(self) -> None:
        # numpy scalars as the Python numbers they stand for, as RoseParams: a float16 length
        # overflowed in the cell arithmetic (guard_window_m=np.float16(0.5) failed on a NaN).
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.generic) and not isinstance(value, np.bool_):
                object.__setattr__(self, f.name, value.item())
        lengths = [
            f.name
            for f in dataclasses.fields(self)
            if f.name not in ("run_tolerance_px", "loose_pieces")
        ]
        not_numbers = [
            f"{name} must be a finite number, got {getattr(self, name)!r}"
            for name in lengths
            if not finite_number(getattr(self, name))
        ]
        if not integer_number(self.run_tolerance_px):
            not_numbers.append(
                f"run_tolerance_px must be an integer, got {self.run_tolerance_px!r}"
            )
        if not_numbers:
            raise RoseError("; ".join(not_numbers))
        problems = [
            f"{name} must be > 0, got {getattr(self, name)}"
            for name in (
                "min_run_m",
                "open_unknown_width_m",
                "min_region_m2",
                "robot_radius_m",
                "guard_window_m",
            )
            if not getattr(self, name) > 0
        ]
        if not self.max_bridge_m >= 0:
            problems.append(f"max_bridge_m must be >= 0, got {self.max_bridge_m}")
        if not self.hidden_wall_reach_m >= 0:
            problems.append(f"hidden_wall_reach_m must be >= 0, got {self.hidden_wall_reach_m}")
        if not self.attach_reach_m >= 0:
            problems.append(f"attach_reach_m must be >= 0, got {self.attach_reach_m}")
        if not self.object_pocket_m2 >= 0:
            problems.append(f"object_pocket_m2 must be >= 0, got {self.object_pocket_m2}")
        if not isinstance(self.loose_pieces, bool | np.bool_):
            problems.append(f"loose_pieces must be True or False, got {self.loose_pieces!r}")
        if not self.unknown_margin_m >= 0:
            problems.append(f"unknown_margin_m must be >= 0, got {self.unknown_margin_m}")
        if not 0 <= self.run_tolerance_px <= 5:
            problems.append(f"run_tolerance_px must be in 0..5, got {self.run_tolerance_px}")
        if problems:
            raise RoseError("; ".join(problems))


#: Finest resolution the ``"walls"`` cleaning takes (metres per cell). Its lengths are metres: at
#: 1e-4 m the 0.15 m robot radius spans 1500 cells, and a 500 x 500 map took 76 s; at 1e-6 m OpenCV
#: asked for 90 GB. Occupancy grids are 1-10 cm per cell.
MIN_CLEAN_RESOLUTION_M = 1e-3


@dataclass(frozen=True, eq=False, repr=False)
class CleanResult(ReadOnlyArrays):
    """A cleaned map and what the cleaning did to every occupied cell (arrays read-only).

    Attributes
    ----------
    cleaned : ndarray of int8, shape (rows, cols)
        The input grid with the removed cells set to free (0) or unknown (-1), ROS convention.
    method : {"walls", "paper"}
        The method used.
    kept : ndarray of bool, shape (rows, cols)
        Occupied cells of the input that stay occupied.
    removed : ndarray of bool, shape (rows, cols)
        Occupied cells of the input that were removed (``kept | removed`` = occupied).
    rescued : ndarray of bool, shape (rows, cols)
        Kept cells that the paper's labelling calls clutter (subset of ``kept``; empty for "paper").
    guarded : ndarray of bool, shape (rows, cols)
        Rescued cells kept only by the topology guard (subset of ``rescued``).
    completed : ndarray of bool, shape (rows, cols)
        Cells unknown in the input that ``cleaned`` makes walls (100): the straight wall line hidden
        behind removed furniture (a cabinet against a wall hides the wall behind it), so that removing
        the furniture does not open the wall; drawn also where the topology guard then puts the
        furniture back (the line is still the wall). Empty for "paper".
    resolution_m : float
        The map's cell size, metres (the metric parameters were converted with half of it for
        cells from 0.1 m to under 0.15 m: module notes).
    params : CleanParams
        The parameters used.
    result : RoseResult
        The ROSE result the cleaning started from.
    """

    cleaned: npt.NDArray[np.int8]
    method: CleanMethod
    kept: npt.NDArray[np.bool_]
    removed: npt.NDArray[np.bool_]
    rescued: npt.NDArray[np.bool_]
    guarded: npt.NDArray[np.bool_]
    completed: npt.NDArray[np.bool_]
    resolution_m: float
    params: CleanParams
    result: RoseResult

    def __repr__(self) -> str:
        return (
            f"CleanResult(method={self.method!r}, shape={self.kept.shape}, "
            f"kept={self.kept_count}, removed={self.removed_count}, rescued={self.rescued_count}, "
            f"completed={self.completed_count}, resolution_m={self.resolution_m!r})"
        )

    @property
    def kept_count(self) -> int:
        """Occupied cells kept."""
        return int(np.count_nonzero(self.kept))

    @property
    def removed_count(self) -> int:
        """Occupied cells removed."""
        return int(np.count_nonzero(self.removed))

    @property
    def rescued_count(self) -> int:
        """Cells kept against the paper's labelling."""
        return int(np.count_nonzero(self.rescued))

    @property
    def completed_count(self) -> int:
        """Unknown cells made walls."""
        return int(np.count_nonzero(self.completed))

    @property
    def guarded_count(self) -> int:
        """Cells kept by the topology guard alone."""
        return int(np.count_nonzero(self.guarded))


#: Longest of the ``"walls"`` cleaning's lengths, in the cells the rules work on (the map's, split
#: in 2 x 2 from 0.1 m to under 0.15 m per cell, joined up to 0.05 m from 0.025 m down): the robot disc
#: and the unknown margin are dilations costing the square of their radius per cell (a 1000-cell
#: robot radius ran for minutes), the guard's windows the square of their margin per opened patch.
#: The wide unknown width pads the cleaning's window by as much on every side: 100 m at 5 cm per
#: cell (2,000 cells) took 1.7 s and 770 MB on a 1152 x 736 map, 1,000 cells 0.6 s and 330 MB.
#: The defaults are 3-40 cells at 5 cm per cell, and within these at the finest resolution taken
#: (:data:`MIN_CLEAN_RESOLUTION_M`).
_MAX_CELLS_OF = {
    "robot_radius_m": 200,
    "unknown_margin_m": 200,
    "guard_window_m": 500,
    "attach_reach_m": 500,
    "hidden_wall_reach_m": 500,
    "min_run_m": 10_000,
    "max_bridge_m": 10_000,
    "open_unknown_width_m": 1_000,
}


def rules_cells_text(resolution_m: float) -> str:
    """How the walls rules take a map's cells of ``resolution_m`` metres, for people: "split in 2 x
    2", "joined in 5 x 5", or "as they are"."""
    from rose.cleaning_rules import coarsening, refinement

    split, merge = refinement(resolution_m), coarsening(resolution_m)
    if split > 1:
        return f"split in {split} x {split}"
    if merge > 1:
        return f"joined in {merge} x {merge}"
    return "as they are"


def _check_cells(p: CleanParams, resolution_m: float) -> None:
    """Refuse lengths of ``p`` that span more cells than :data:`_MAX_CELLS_OF` allows, in the cells
    the rules work on for a map of ``resolution_m`` (split for coarse maps, joined for fine ones:
    module notes)."""
    from rose.cleaning_rules import rules_cell_m

    cell_m = rules_cell_m(resolution_m)
    cells = f"{cell_m:g} m per cell" + (
        f" (the map's {resolution_m:g} m cells {rules_cells_text(resolution_m)})"
        if cell_m != resolution_m
        else ""
    )
    problems = [
        f"{name} {getattr(p, name):g} m is {getattr(p, name) / cell_m:.3g} cells at {cells} "
        f"(at most {most:,})"
        for name, most in _MAX_CELLS_OF.items()
        if getattr(p, name) / cell_m > most
    ]
    if problems:
        raise RoseError("; ".join(problems) + ": the walls cleaning's cost grows with these")


def clean(
    grid: npt.ArrayLike | OccupancyMap,
    result: RoseResult | None = None,
    *,
    method: CleanMethod = "walls",
    resolution_m: float | None = None,
    params: CleanParams | None = None,
) -> CleanResult:
    """Remove clutter from an occupancy grid.

    Parameters
    ----------
    grid : array_like, shape (rows, cols), or OccupancyMap
        ROS occupancy grid (int8: -1 unknown, 0..100; row 0 at the map origin) or a boolean occupied
        mask, or a map read by :func:`rose.load_map` (its grid and resolution). Not modified.
    result : RoseResult, optional
        :func:`rose.analyze`'s result for ``grid``; computed with the defaults when omitted. Its
        ``params.clutter_value`` decides what removed cells become.
    method : {"walls", "paper"}
        ``"walls"`` keeps walls and never opens a robot-sized gap (module notes); ``"paper"`` is the
        paper's labelling.
    resolution_m : float, optional
        Cell size in metres (the lengths of ``params`` are converted with it, or with half of it
        from 0.1 m to under 0.15 m: module notes). Default: the
        OccupancyMap's resolution, or 0.05 m (the common ROS map resolution) for an array.
    params : CleanParams, optional
        Parameters of the ``"walls"`` method.

    Returns
    -------
    CleanResult

    Raises
    ------
    RoseError
        On a bad grid, method, resolution or ``params`` (a length of more cells than the rules
        take), or a ``result`` that is no RoseResult or was computed for another grid (another
        shape, or other occupied cells).
    """
    if isinstance(grid, OccupancyMap):
        if resolution_m is None:
            resolution_m = grid.resolution_m
        grid = grid.grid
    elif resolution_m is None:
        resolution_m = DEFAULT_RESOLUTION_M
    occupancy = as_occupancy_grid(grid)
    if result is None:  # analyzed below with the defaults, from the converted grid: warned here
        warn_if_mask(grid, occupancy, RoseParams().occupied_threshold)
    if isinstance(result, str):  # clean(grid, "paper"): an easy slip
        msg = f"result must be a RoseResult, got {result!r}: pass the method by name, method={result!r}"
        raise RoseError(msg)
    if method not in CLEAN_METHODS:
        msg = f"method must be one of {', '.join(CLEAN_METHODS)}, got {method!r}"
        raise RoseError(msg)
    problem = resolution_problem(resolution_m)
    if problem is not None:
        msg = f"resolution_m {problem}"
        raise RoseError(msg)
    # A Python float: a numpy scalar kept its precision in the rules' arithmetic (float16 0.05
    # overflowed there and failed on a NaN); float32 gives the same cells either way.
    resolution_m = float(resolution_m)
    if method == "walls" and resolution_m < MIN_CLEAN_RESOLUTION_M:
        msg = (
            f"resolution_m {resolution_m:g} m is finer than {MIN_CLEAN_RESOLUTION_M:g} m per cell "
            "(the cleaning's lengths would span thousands of cells): give the map's real "
            "resolution, or use the paper's labelling (--method paper)"
        )
        raise RoseError(msg)
    if params is not None and not isinstance(params, CleanParams):
        msg = f"params must be a CleanParams, got {type(params).__name__}"
        raise RoseError(msg)
    p = params if params is not None else CleanParams()
    if method == "walls":
        _check_cells(p, resolution_m)
    if result is None:
        # scipy: loaded when needed (the CLIs' parsers import this module).
        from rose.pipeline import analyze

        result = analyze(occupancy)
    check_result_for(result, occupancy)
    if method == "paper" or not result.has_structure:
        return _paper_labelling(
            occupancy, result, method=method, resolution_m=resolution_m, params=p
        )
    return _walls_cleaning(occupancy, result, resolution_m=resolution_m, params=p)


def _paper_labelling(
    occupancy: npt.NDArray[np.int8],
    result: RoseResult,
    *,
    method: CleanMethod,
    resolution_m: float,
    params: CleanParams,
) -> CleanResult:
    """The paper's labelling on ``occupancy`` itself (int8 ROS grid): its free and unknown cells
    as they are, ``result``'s clutter removed; also the ``"walls"`` method's result when ROSE found
    no structure (nothing to keep walls along)."""
    # The result's own (read-only) arrays stand in where they hold the same cells, and one empty
    # mask for the three empty ones: a session holds several results at once, and these copies
    # were a sixth of its memory (about 5 MB per 1000 x 1000 snapshot).
    cleaned = occupancy.copy()
    # copyto's mask: half the time of an assignment through a boolean index (which first lists
    # the mask's cells), the same cells set.
    np.copyto(cleaned, result.params.clutter_cell_value, where=result.clutter)
    if np.array_equal(cleaned, result.cleaned):  # the result was computed on ``occupancy``
        cleaned = result.cleaned
    nothing = np.zeros(occupancy.shape, dtype=bool)
    # Only what is made here is sealed: the result's arrays may be a caller's (a RoseResult
    # made with dataclasses.replace), which seal() made read-only for good.
    for made in (nothing, cleaned):
        if made is not result.cleaned:
            made.flags.writeable = False
    return CleanResult(
        cleaned=cleaned,
        method=method,
        # occupied & ~clutter: the structure, or every occupied cell when ROSE found none
        kept=result.structure if result.has_structure else result.occupied,
        removed=result.clutter,
        rescued=nothing,
        guarded=nothing,
        completed=nothing,
        resolution_m=resolution_m,
        params=params,
        result=result,
    )


def _walls_cleaning(
    occupancy: npt.NDArray[np.int8],
    result: RoseResult,
    *,
    resolution_m: float,
    params: CleanParams,
) -> CleanResult:
    """The ``"walls"`` method (module notes) on ``occupancy`` (int8 ROS grid), cells of
    ``resolution_m`` metres, starting from ``result`` (which found structure)."""
    from rose.cleaning_rules import wall_cells_in_window

    window, (walls_in, guarded_in, completed_in, dropped_in) = wall_cells_in_window(
        occupancy, result, resolution_m=resolution_m, params=params
    )
    # Beyond the window no cell is occupied, and the rules' masks are all False there: every mask
    # is worked out within it, into fresh zeros (their pages mapped only where written), instead
    # of in passes over the whole grid.
    kept, removed, rescued, guarded, completed = (
        np.zeros(occupancy.shape, dtype=bool) for _ in range(5)
    )
    occupied = result.occupied[window]
    kept_in = kept[window]
    np.greater(result.structure[window], dropped_in, out=kept_in)  # structure & ~dropped
    kept_in |= walls_in
    kept_in &= occupied
    removed_in = np.greater(occupied, kept_in, out=removed[window])
    np.logical_and(kept_in, result.clutter[window], out=rescued[window])
    np.logical_and(guarded_in, result.clutter[window], out=guarded[window])
    completed[window] = completed_in
    cleaned = occupancy.copy()
    # copyto's mask: no list of the mask's cells first, as an assignment through it makes.
    np.copyto(cleaned[window], result.params.clutter_cell_value, where=removed_in)
    np.copyto(cleaned[window], OCCUPIED, where=completed_in)
    if _LOG.isEnabledFor(logging.DEBUG):  # the counts cost map-sized passes
        _LOG.debug(
            "walls cleaning: %d cells kept (%d rescued, %d by the guard), %d removed, %d completed",
            int(np.count_nonzero(kept)),
            int(np.count_nonzero(rescued)),
            int(np.count_nonzero(guarded)),
            int(np.count_nonzero(removed)),
            int(np.count_nonzero(completed)),
        )
    return seal(
        CleanResult(
            cleaned=cleaned,
            method="walls",
            kept=kept,
            removed=removed,
            rescued=rescued,
            guarded=guarded,
            completed=completed,
            resolution_m=resolution_m,
            params=params,
            result=result,
        )
    )
