"""Break detection over a session: every snapshot against the last snapshot that was trusted.

Per map topic, :class:`BreakDetector` keeps the *last trusted snapshot* (the latest one whose break
score stayed below the threshold). Every new snapshot is compared with it by
:func:`rose.breaks.contradicted_walls`: the break score is the length, in metres, of established map
the new snapshot contradicts inside the densest ``window_m`` square (counted in pieces of
``tile_m``): established walls it erased, and obstacle evidence that rose deep in established free
space. A person or a chair leg makes one or two pieces, a break whole walls. A score at or above
``threshold_m`` marks the snapshot broken, and the trusted snapshot stays where it was, so the
score of every later snapshot is measured against the map as it was before the break. The first
broken snapshot after a trusted one starts a break (:attr:`BreakScore.started`).

A drift too slow to break between two snapshots (a map redrawn from a pose graph moves its old
walls with it: each snapshot agrees with the one before) is caught by an *anchor*: an older trusted
snapshot, at most ``anchor_s`` of log time behind, which the snapshots are compared with too (every
``anchor_s / 6`` and every eighth snapshot at least, every snapshot while a drift it found
lasts, and a topic's last snapshot at its end if that was not: :meth:`BreakDetector.finish`)
and which breaks them at twice ``threshold_m`` (a log-odds map's own growth over a minute
contradicts more than over a few seconds); the anchor moves up to a snapshot that agrees with both
once it is ``anchor_s`` old. A snapshot that contradicts the last
trusted one but agrees with the anchor (under twice ``threshold_m`` and at most half its score
against the trusted one), where the anchor knew most of the contradicted cells, is the map
returning to the anchor's (a loop closure undoing a drift): not a break
(:attr:`BreakScore.returned_from`). Where the anchor knew nothing (space mapped since), agreeing
with it means nothing: a break.

Snapshots that cannot be compared with the trusted one (another resolution, a rotated origin, an
origin shifted by a fraction of a cell) restart the comparison: score 0, and they become trusted.
So does every snapshot after one without a single occupied cell (a blank map a node publishes
while it starts): a map with no wall establishes nothing, and its free space would make every
wall drawn later a break.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import weakref
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from rose.breaks import MAX_KERNEL_PX, EarlierGridMemo, WallContradiction, contradicted_walls
from rose.errors import RoseError
from rose.limits import finite_number, integer_number, short
from rose_logs.snapshots import MapSnapshot

__all__ = [
    "BreakDetector",
    "BreakLengthsPx",
    "BreakParams",
    "BreakParamsError",
    "BreakScore",
    "DetectedBreak",
    "metres_text",
    "region_text",
]

_LOG = logging.getLogger(__name__)


class BreakLengthsPx(NamedTuple):
    """:class:`BreakParams`' lengths in cells of one resolution (:meth:`BreakParams.in_cells`),
    named as :func:`rose.breaks.contradicted_walls` takes them."""

    tolerance_px: int
    min_extent_px: int
    bridge_px: int
    tile_px: int
    window_px: int
    rise_margin_px: int


class BreakParamsError(RoseError, ValueError):
    """A :class:`BreakParams` value out of range (a :class:`rose.RoseError`, as the other
    parameters' errors, and a ``ValueError``)."""


@dataclass(frozen=True)
class BreakParams:
    """Parameters of :class:`BreakDetector`.

    Attributes
    ----------
    threshold_m : float
        Contradicted length (metres, in one window) from which a snapshot is broken.
    tolerance_m : float
        A wall that moved by at most this much (metres) is not erased; a cell at least when
        positive (:meth:`in_cells`).
    min_wall_m : float
        Only pieces at least this long (connected cells, gaps up to ``bridge_m`` bridged) count, of
        established walls and of risen evidence; people and furniture blobs do not.
    bridge_m : float
        Gaps along a wall up to this long are bridged before measuring it, metres.
    tile_m : float
        Contradicted cells are measured in pieces of this length (tiles of this side), metres.
    window_m : float
        Side of the square window the contradicted length is counted in, metres.
    occupied_threshold : int
        Occupancy (percent) from which a cell is a wall.
    free_threshold : int
        Occupancy (percent) up to which a known cell counts as free.
    rise_points : int
        A free cell whose occupancy rose by at least this many percentage points holds risen
        evidence (101: off, erased walls only).
    rise_margin_m : float
        Risen evidence counts only farther than this from every cell that was not known free
        (walls, unknown, uncertain), metres; a cell at least when positive (:meth:`in_cells`).
    anchor_s : float
        How far behind (log time, seconds) the anchor, the older trusted snapshot every snapshot is
        also compared with, may fall before it moves up (module notes); ``inf``: no anchor.
    """

    threshold_m: float = 1.25
    tolerance_m: float = 0.3
    min_wall_m: float = 1.0
    bridge_m: float = 0.1
    tile_m: float = 0.25
    window_m: float = 10.0
    occupied_threshold: int = 65
    free_threshold: int = 50
    rise_points: int = 15
    rise_margin_m: float = 0.2
    anchor_s: float = 60.0

    @classmethod
    def following(cls, occupied_threshold: int, **overrides: Any) -> BreakParams:
        """The defaults (and ``overrides``) with walls from ``occupied_threshold``, ROSE's own
        parameter, so that the detector and ROSE agree on what is occupied; free space stays below
        it."""
        free = min(cls.free_threshold, occupied_threshold - 1)
        return cls(occupied_threshold=occupied_threshold, free_threshold=free, **overrides)

    def in_cells(self, resolution_m: float) -> BreakLengthsPx:
        """The lengths in cells of ``resolution_m`` metres, to the nearest cell; a positive
        tolerance or rise margin is at least one cell: a wall that moves by less than a cell
        still hops to the next cell when it lay near a cell's edge (at 0.5 m per cell the 0.2 m
        margin rounded to none, and a wall redrawn 0.2 m over was a 4 m break)."""

        def near(length_m: float) -> int:
            cells = round(length_m / resolution_m)
            return max(cells, 1) if length_m > 0 else cells

        return BreakLengthsPx(
            tolerance_px=near(self.tolerance_m),
            min_extent_px=round(self.min_wall_m / resolution_m),
            bridge_px=round(self.bridge_m / resolution_m),
            tile_px=max(round(self.tile_m / resolution_m), 1),
            window_px=max(round(self.window_m / resolution_m), 1),
            rise_margin_px=near(self.rise_margin_m),
        )

    def __post_init__(self) -> None:
        for name, value in dataclasses.asdict(self).items():
            # A number (an infinite threshold never breaks: the evaluation's replays use one).
            infinite = name in ("threshold_m", "anchor_s") and value == math.inf
            if not (finite_number(value) or infinite):
                msg = f"{name} must be a finite number, got {value!r}"
                raise BreakParamsError(msg)
        for name in ("occupied_threshold", "free_threshold", "rise_points"):
            if not integer_number(getattr(self, name)):
                msg = f"{name} must be an integer, got {getattr(self, name)!r}"
                raise BreakParamsError(msg)
        if not (
            self.threshold_m > 0
            and self.window_m > 0
            and self.tile_m > 0
            and self.tolerance_m >= 0
            and self.min_wall_m >= 0
            and self.bridge_m >= 0
            and self.rise_margin_m >= 0
            and self.anchor_s > 0
        ):
            msg = (
                "break parameters need threshold_m, window_m, tile_m, anchor_s > 0 and "
                f"tolerance_m, min_wall_m, bridge_m, rise_margin_m >= 0, got {self.threshold_m}, "
                f"{self.window_m}, {self.tile_m}, {self.anchor_s}, {self.tolerance_m}, "
                f"{self.min_wall_m}, {self.bridge_m}, {self.rise_margin_m}"
            )
            raise BreakParamsError(msg)
        if not 1 <= self.rise_points <= 101:
            msg = f"rise_points must be in 1..101 (101: off), got {self.rise_points}"
            raise BreakParamsError(msg)
        if not 0 <= self.free_threshold < self.occupied_threshold <= 100:
            msg = (
                "need 0 <= free_threshold < occupied_threshold <= 100, got "
                f"{self.free_threshold}, {self.occupied_threshold}"
            )
            raise BreakParamsError(msg)


@dataclass(frozen=True)
class BreakScore:
    """The break detector's verdict on one snapshot.

    Attributes
    ----------
    score_m : float
        Contradicted length (erased walls, risen evidence) in the densest window, metres (0 when
        not compared).
    broken : bool
        ``score_m >= threshold_m``.
    started : bool
        Broken while the previous snapshot of the topic was not: the start of a break.
    trusted_index : int or None
        Snapshot index (on the topic) of the trusted snapshot compared with; None for the first
        snapshot and after a restart.
    region_m : tuple of float or None
        ``(x_min, y_min, x_max, y_max)`` of the contradicted cells in the densest window, map
        frame, metres (cell outer edges); None when nothing was contradicted.
    contradicted_m : float
        Contradicted length over the whole map, metres (same measure as ``score_m``).
    incomparable_with : int or None
        The trusted snapshot this one could not be compared with (another cell size, frame or
        orientation, or on coarse cells an origin off the trusted grid's cells): the detector
        starts again from this one, and a break across the change is not seen. None otherwise.
    returned_from : int or None
        The last trusted snapshot, which this one contradicts (by ``returned_from_m``) although
        it agrees with the anchor, ``trusted_index``: the map returned to the anchor's, as a loop
        closure undoing a drift does; not a break (the scores are against the anchor). None
        otherwise.
    returned_from_m : float
        With ``returned_from``: the score against it, metres (else 0).
    threshold_m : float or None
        The threshold the verdict was judged at when not the detector's: twice it, against the
        anchor (an anchor's break or a return). None otherwise.
    incomparable_why : str
        With ``incomparable_with``: what differs, e.g. ``"cell size 0.1 m, trusted 0.05 m"``
        (else empty).
    """

    score_m: float
    broken: bool
    started: bool
    trusted_index: int | None
    region_m: tuple[float, float, float, float] | None
    contradicted_m: float
    incomparable_with: int | None = None
    returned_from: int | None = None
    returned_from_m: float = 0.0
    threshold_m: float | None = None
    incomparable_why: str = ""


@dataclass(frozen=True)
class DetectedBreak:
    """A break the detector found: the first broken snapshot after a trusted one.

    Attributes
    ----------
    topic : str
        Map topic.
    index : int
        Snapshot index on the topic.
    log_time_ns : int
        Log time of that snapshot, nanoseconds.
    score_m : float
        Its break score, metres.
    region_m : tuple of float or None
        ``(x_min, y_min, x_max, y_max)`` of the contradicted cells, map frame, metres.
    trusted_index : int or None
        The last trusted snapshot it was compared with.
    text : str
        One line for people (event logs, summaries), starting with the topic.
    """

    topic: str
    index: int
    log_time_ns: int
    score_m: float
    region_m: tuple[float, float, float, float] | None
    trusted_index: int | None
    text: str

    @classmethod
    def from_score(
        cls, snapshot: MapSnapshot, index: int, verdict: BreakScore, threshold_m: float
    ) -> DetectedBreak:
        """The event of a snapshot whose verdict ``started`` a break (``threshold_m``: the
        detector's; the verdict's own when it has one, twice it against the anchor)."""
        if verdict.threshold_m is not None:
            threshold_m = verdict.threshold_m
        event = cls(
            topic=snapshot.topic,
            index=index,
            log_time_ns=snapshot.log_time_ns,
            score_m=verdict.score_m,
            region_m=verdict.region_m,
            trusted_index=verdict.trusted_index,
            text="",
        )
        text = f"{snapshot.topic}: {event._describe(f' (threshold {threshold_m:g} m)')}"
        return dataclasses.replace(event, text=text)

    @property
    def detail(self) -> str:
        """The event for its topic's events view in Rerun, where a long line is cut at the view's
        width: where first, no topic, no threshold (drawn in the plot). The place was what was cut
        off (at 1600 pixels: "... since snapshot 6 ar")."""
        where = "" if self.region_m is None else f" around {region_text(self.region_m)}"
        return (
            f"break at snapshot {self.index}{where}: {self.score_m:.2f} m contradicted since "
            f"snapshot {self.trusted_index}"
        )

    def _describe(self, threshold: str) -> str:
        where = "" if self.region_m is None else f" around {region_text(self.region_m)}"
        return (
            f"map breaks at snapshot {self.index}: {self.score_m:.2f} m of established map "
            f"contradicted{threshold} since snapshot {self.trusted_index}{where}"
        )


def region_text(region_m: tuple[float, float, float, float]) -> str:
    """``(x_min, y_min, x_max, y_max)`` in metres as reports print it: ``x 1.2..3.4 m, y 0..2 m``."""
    x0, y0, x1, y1 = (metres_text(v) for v in region_m)
    return f"x {x0}..{x1} m, y {y0}..{y1} m"


def metres_text(value: float) -> str:
    """A length or map coordinate in metres as the reports print it: to the mm (as the JSON report
    rounds it), without exponent or trailing zeros (-4.75, 9.1, 5400001.25; :g gave 5.4e+06)."""
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


_CLEAR = BreakScore(0.0, False, False, None, None, 0.0)


#: Origins rotated by less than this are one placement: it moves a cell 4000 cells from the origin
#: by under 0.005 cell (float noise in a quaternion, or q and -q, are the same rotation).
_SAME_ROTATION_RAD = 1e-6


#: Characters of a frame id said at most in why two snapshots are not comparable.
_FRAME_CHARS = 40


def _rotation_between(a: MapSnapshot, b: MapSnapshot) -> float:
    """Angle (radians, 0..pi) between two snapshots' origin yaws.

    A grid is placed flat, turned by its origin's yaw (a tilted origin is taken so, as Nav2 takes
    it, and as :func:`_cells_of` places the cells): a tilt alone moves no cell. The whole
    quaternions were compared, so a map whose origin's roll changed (or was tilted in one snapshot)
    restarted the detector, and a break across it went unseen."""
    turn = (a.origin_yaw_rad - b.origin_yaw_rad) % math.tau
    return min(turn, math.tau - turn)


def _placement(
    trusted: MapSnapshot, snapshot: MapSnapshot, *, rounding: float = 0.01
) -> tuple[int, int] | str:
    """``(row, col)`` of the trusted grid's cell (0, 0) in the new grid, to the nearest cell when
    at most ``rounding`` cells off it (:meth:`BreakDetector._rounding`); else what keeps the two
    apart (another cell size, frame or orientation, or an origin further off the cells) as the
    session's warning says it, "cell size 0.1 m, trusted 0.05 m" (it listed the four causes,
    whichever it was).

    On fine cells any fraction is rounded: a node whose origin moved by millimetres between maps
    made every snapshot incomparable, the detector blind (a 7.6 m ghost wall passed)."""
    res = snapshot.resolution_m
    if trusted.resolution_m != res:
        now, then = (metres_text(s.resolution_decimal_m) for s in (snapshot, trusted))
        if now == then:  # a float32 and a float64 0.05 (a map made in Python): tell them apart
            now, then = repr(res), repr(trusted.resolution_m)
        return f"cell size {now} m, trusted {then} m"
    if trusted.frame_id != snapshot.frame_id:
        # Cut: a frame id is the publisher's text (thousands of characters made a warning and
        # a Rerun event of as many, which the events view cuts at about 140, losing what it says).
        now, then = (short(repr(s.frame_id), _FRAME_CHARS) for s in (snapshot, trusted))
        return f"frame {now}, trusted {then}"
    # A turn that moves the grids' farthest cell by less than the rounding is no turn: a heading
    # re-estimated at each publish (microradians) made every snapshot incomparable, the detector
    # blind, as an origin moving by millimetres did.
    extent = math.hypot(*trusted.shape) + math.hypot(*snapshot.shape)
    turn = _rotation_between(trusted, snapshot)
    if turn * extent > max(rounding, _SAME_ROTATION_RAD):
        return f"origin turned by {math.degrees(turn):.3g} degrees"
    row, col = _cells_of(snapshot, trusted.origin_position_m[0], trusted.origin_position_m[1])
    off = max(abs(col - round(col)), abs(row - round(row)))
    if off > rounding:
        return f"origin {off:.2f} cell off the trusted grid's cells"
    return round(row), round(col)


def _frame_origin_px(snapshot: MapSnapshot) -> tuple[int, int]:
    """``(row, col)`` of the map frame's origin in ``snapshot``'s grid, to the nearest cell: the
    break score's tiles start there, so that a grid that grew on its negative side (its origin
    moved by cells) is tiled as before and its score and region do not change."""
    row, col = _cells_of(snapshot, 0.0, 0.0)
    # Far-away origins (UTM coordinates) give huge cell numbers: only the lattice's phase matters.
    return round(row), round(col)


def _cells_of(snapshot: MapSnapshot, x_m: float, y_m: float) -> tuple[float, float]:
    """``(row, col)`` of the map-frame point ``(x_m, y_m)`` in ``snapshot``'s grid, in cells (not
    rounded; cell (0, 0)'s corner at 0)."""
    res = snapshot.resolution_m
    yaw = snapshot.origin_yaw_rad
    dx, dy = x_m - snapshot.origin_position_m[0], y_m - snapshot.origin_position_m[1]
    c, s = math.cos(yaw), math.sin(yaw)  # into the grid's own axes
    return (-s * dx + c * dy) / res, (c * dx + s * dy) / res


def _region_m(
    snapshot: MapSnapshot, region_px: tuple[int, int, int, int]
) -> tuple[float, float, float, float]:
    """A cell box (inclusive) as a map-frame box in metres (outer cell edges)."""
    r0, c0, r1, c1 = region_px
    res = snapshot.resolution_decimal_m
    yaw = snapshot.origin_yaw_rad
    ox, oy = snapshot.origin_position_m[0], snapshot.origin_position_m[1]
    c, s = math.cos(yaw), math.sin(yaw)
    xs, ys = [], []
    for col, row in ((c0, r0), (c1 + 1, r0), (c0, r1 + 1), (c1 + 1, r1 + 1)):
        u, v = col * res, row * res
        xs.append(ox + c * u - s * v)
        ys.append(oy + s * u + c * v)
    return min(xs), min(ys), max(xs), max(ys)


#: Snapshots between two comparisons with the anchor at most (see BreakDetector._anchor_due).
_ANCHOR_EVERY = 8


@dataclass(frozen=True)
class _TopicState:
    """What the detector keeps of one topic: snapshots seen (``count``), the last trusted snapshot
    and the anchor (``(index, snapshot)``), when the anchor was last compared with (log time, ns;
    snapshot index), whether the last snapshot was broken (``by_anchor``: a break that the anchor
    held at some snapshot, against the trusted one or not since) and whether the trusted one has no
    wall (``blank``)."""

    count: int
    trusted: tuple[int, MapSnapshot]
    anchor: tuple[int, MapSnapshot]
    anchor_checked_ns: int
    anchor_checked_index: int
    broken: bool
    blank: bool
    by_anchor: bool = False

    @classmethod
    def start(cls, index: int, snapshot: MapSnapshot, blank: bool) -> _TopicState:
        """A topic starting (again) from ``snapshot``: trusted, and the anchor."""
        now = (index, snapshot)
        return cls(index + 1, now, now, snapshot.log_time_ns, index, broken=False, blank=blank)


class BreakDetector:
    """Break scores for the snapshots of one or more map topics, in log-time order.

    Parameters
    ----------
    params : BreakParams, optional
        Threshold, tolerance, window; defaults when omitted.
    """

    def __init__(self, params: BreakParams | None = None) -> None:
        if params is not None and not isinstance(params, BreakParams):
            msg = f"params must be a BreakParams, got {type(params).__name__}"
            raise RoseError(msg)
        self.params = params if params is not None else BreakParams()
        self._state: dict[str, _TopicState] = {}
        self._too_fine_said: set[str] = set()  # topics warned of maps too fine to check
        # Per topic, its state before its last update (withdraw_last puts it back).
        self._before: dict[str, _TopicState | None] = {}
        # Occupied cells of the snapshots seen (grids are read-only): counted once per snapshot,
        # not at every comparison with it (a trusted snapshot or anchor is compared with several
        # later ones). Held as long as the snapshot is.
        self._wall_cells: weakref.WeakKeyDictionary[MapSnapshot, int] = weakref.WeakKeyDictionary()
        # What the comparisons found of each trusted snapshot and anchor alone (its long walls,
        # the cells near its cells not known free: rose.breaks.EarlierGridMemo), for its next
        # comparisons with later snapshots.
        self._memos: weakref.WeakKeyDictionary[MapSnapshot, EarlierGridMemo] = (
            weakref.WeakKeyDictionary()
        )

    def update(self, snapshot: MapSnapshot) -> BreakScore:
        """Score the next snapshot of ``snapshot.topic`` and update the topic's state."""
        topic = snapshot.topic
        state = self._state.get(topic)
        self._before[topic] = state
        index = 0 if state is None else state.count
        if not self._kernels_fit(snapshot.resolution_m):
            self._say_too_fine(topic, snapshot.resolution_m)
            self._state[topic] = _TopicState.start(index, snapshot, self._blank(snapshot))
            return _CLEAR
        trusted = None if state is None else state.trusted
        placed = None if trusted is None else self._placement(trusted[1], snapshot)
        offset = None if isinstance(placed, str) else placed
        if state is None or trusted is None or offset is None or state.blank:
            self._state[topic] = _TopicState.start(index, snapshot, self._blank(snapshot))
            if trusted is not None and isinstance(placed, str):
                # Said by the session once the snapshot stays (one whose analysis fails is
                # withdrawn, and the next is compared with the trusted one again).
                return dataclasses.replace(
                    _CLEAR, incomparable_with=trusted[0], incomparable_why=placed
                )
            return _CLEAR
        verdict = self._score(trusted, snapshot, offset)
        from_anchor = False
        returned_from, returned_from_m = None, 0.0
        anchor, checked_ns = state.anchor, state.anchor_checked_ns
        checked_index = state.anchor_checked_index
        if anchor[0] != trusted[0] and self._anchor_due(state, snapshot, index, verdict.broken):
            anchor_offset = self._offset(anchor[1], snapshot)
            if anchor_offset is None:  # placed apart from the trusted one's: starts again here
                anchor = trusted
            else:
                checked_ns, checked_index = snapshot.log_time_ns, index
                against_anchor = self._score(anchor, snapshot, anchor_offset)
                anchor_broken = against_anchor.score_m >= self._anchor_threshold_m
                if (
                    verdict.broken
                    and not anchor_broken
                    # Far closer to the anchor than to the trusted snapshot: a break contradicts
                    # both alike (the anchor may hold a minute's growth more).
                    and 2 * against_anchor.score_m <= verdict.score_m
                    and self._anchor_knew(anchor[1], anchor_offset, trusted[1], offset, snapshot)
                ):
                    returned_from, returned_from_m = trusted[0], verdict.score_m
                    # Judged at the anchor's threshold: its score may exceed the detector's.
                    verdict = dataclasses.replace(
                        against_anchor, broken=False, threshold_m=2.0 * self.params.threshold_m
                    )
                elif anchor_broken and (
                    against_anchor.score_m > verdict.score_m or (state.broken and state.by_anchor)
                ):
                    # Drifted away from the anchor: broken since the anchor, for the rest of the
                    # break. (Under the anchor's own threshold, a minute of a log-odds map's
                    # growth: the trusted one says.)
                    verdict = dataclasses.replace(
                        against_anchor, broken=True, threshold_m=2.0 * self.params.threshold_m
                    )
                    from_anchor = True
        started = verdict.broken and not state.broken
        if verdict.broken:
            self._state[topic] = dataclasses.replace(
                state,
                count=index + 1,
                broken=True,
                # Once the anchor held it, for the rest of the break (its end may be a return).
                by_anchor=(state.broken and state.by_anchor) or from_anchor,
                anchor=anchor,
                anchor_checked_ns=checked_ns,
                anchor_checked_index=checked_index,
            )
        else:
            now = (index, snapshot)
            # The anchor moves up once old enough, to a snapshot checked against it just now.
            old = snapshot.log_time_ns - anchor[1].log_time_ns >= self._anchor_ns
            moved = old and checked_index == index
            self._state[topic] = _TopicState(
                count=index + 1,
                trusted=now,
                anchor=now if moved else anchor,
                anchor_checked_ns=checked_ns,
                anchor_checked_index=checked_index,
                broken=False,
                blank=self._blank(snapshot),
            )
        return dataclasses.replace(
            verdict, started=started, returned_from=returned_from, returned_from_m=returned_from_m
        )

    def finish(self, topic: str) -> tuple[int, MapSnapshot, BreakScore] | None:
        """The end of ``topic``'s session: its last snapshot compared with the anchor when the
        schedule had not compared it (:meth:`_anchor_due`: every sixth of ``anchor_s`` and
        every :data:`_ANCHOR_EVERY` snapshots, so that a session shorter than that, or its last
        few seconds, went unseen by the anchor). ``(index, snapshot, verdict)`` when it breaks
        against the anchor (at twice ``threshold_m``, as during the session: a break since the
        anchor that starts at that snapshot), else None (also when the last snapshot is broken
        already, was compared, is the anchor, or cannot be placed on it). Called once, after the
        topic's last :meth:`update`; the last update cannot be withdrawn after it."""
        state = self._state.get(topic)
        self._before.pop(topic, None)
        if state is None or state.broken or self.params.anchor_s == math.inf:
            return None
        index, snapshot = state.trusted  # the last snapshot: not broken, so trusted
        anchor = state.anchor
        if anchor[0] == index or state.anchor_checked_index == index:
            return None
        anchor_offset = self._offset(anchor[1], snapshot)
        if anchor_offset is None:
            return None
        against_anchor = self._score(anchor, snapshot, anchor_offset)
        checked = dataclasses.replace(
            state, anchor_checked_ns=snapshot.log_time_ns, anchor_checked_index=index
        )
        if against_anchor.score_m < self._anchor_threshold_m:
            self._state[topic] = checked
            return None
        self._state[topic] = dataclasses.replace(checked, broken=True, by_anchor=True)
        verdict = dataclasses.replace(
            against_anchor, broken=True, started=True, threshold_m=2.0 * self.params.threshold_m
        )
        return index, snapshot, verdict

    @property
    def _anchor_ns(self) -> float:
        return self.params.anchor_s * 1e9

    @property
    def _anchor_threshold_m(self) -> float:
        """Score against the anchor from which a snapshot is broken: twice ``threshold_m``. A
        minute of a log-odds map's own growth contradicts more than a few seconds' (a faint line
        across a hall: the correct Freiburg 101 and 079 sessions at 5 s per map broke against the
        anchor at 1.25-2 m, and stayed broken); 2.5 m kept the correct sessions quiet with
        snapshots 60 and 120 s apart (README, Measured). Scores are whole tiles: no float noise."""
        return 2.0 * self.params.threshold_m * (1.0 - 1e-9)

    def _anchor_due(
        self, state: _TopicState, snapshot: MapSnapshot, index: int, broken: bool
    ) -> bool:
        """Whether ``snapshot`` (the topic's ``index``-th; ``broken`` against the trusted one) is
        also compared with the anchor.

        While the topic is broken: on every snapshot when the anchor holds the break (a drift: the
        snapshots agree with the trusted one); when the trusted one does, every half ``anchor_s``
        and every :data:`_ANCHOR_EVERY` snapshots (a return in steps ends it; on every snapshot, a
        session broken for good paid a second comparison per snapshot).
        Otherwise: when the snapshot breaks against the trusted one (it may be the map returning
        to the anchor's), when the anchor is old enough to move up, and at least every sixth of
        ``anchor_s`` and every :data:`_ANCHOR_EVERY` snapshots (maps many times a second drift
        within a few seconds)."""
        if self.params.anchor_s == math.inf:
            return False
        now = snapshot.log_time_ns
        if state.broken:
            # A break the trusted snapshot holds: every half ``anchor_s`` and every
            # :data:`_ANCHOR_EVERY` snapshots, for a return that comes in steps.
            return state.by_anchor or (
                now - state.anchor_checked_ns >= self._anchor_ns / 2
                or index - state.anchor_checked_index >= _ANCHOR_EVERY
            )
        return (
            broken
            or now - state.anchor[1].log_time_ns >= self._anchor_ns
            or now - state.anchor_checked_ns >= self._anchor_ns / 6
            or index - state.anchor_checked_index >= _ANCHOR_EVERY
        )

    def _offset(self, trusted: MapSnapshot, snapshot: MapSnapshot) -> tuple[int, int] | None:
        placed = self._placement(trusted, snapshot)
        return None if isinstance(placed, str) else placed

    def _placement(self, trusted: MapSnapshot, snapshot: MapSnapshot) -> tuple[int, int] | str:
        return _placement(trusted, snapshot, rounding=self._rounding(snapshot.resolution_decimal_m))

    def _score(
        self, against: tuple[int, MapSnapshot], snapshot: MapSnapshot, offset: tuple[int, int]
    ) -> BreakScore:
        """The verdict on ``snapshot`` measured against the snapshot ``against`` (index, snapshot);
        ``started`` is left False."""
        found = self.compare(against[1], snapshot, offset)
        res = snapshot.resolution_m
        score = found.peak_tiles * found.tile_px * res
        region = None if found.region_px is None else _region_m(snapshot, found.region_px)
        return BreakScore(
            score,
            # Scores are whole tiles times the tile side: compare without float noise in the
            # product.
            score >= self.params.threshold_m * (1.0 - 1e-9),
            False,
            against[0],
            region,
            found.contradicted_tiles * found.tile_px * res,
        )

    def _anchor_knew(
        self,
        anchor: MapSnapshot,
        anchor_offset: tuple[int, int],
        trusted: MapSnapshot,
        trusted_offset: tuple[int, int],
        snapshot: MapSnapshot,
    ) -> bool:
        """Whether the anchor knew (free or occupied) most of the cells where ``snapshot``
        contradicts the trusted snapshot: then agreeing with the anchor is the map returning to it.
        A break in space mapped after the anchor contradicts nothing of it (its cells were
        unknown there): no return, a break."""
        from rose.breaks import erased_walls, placed_grid, risen_evidence

        p = self.params
        cells = p.in_cells(snapshot.resolution_m)
        contradicted = erased_walls(
            trusted.grid,
            snapshot.grid,
            offset_px=trusted_offset,
            tolerance_px=cells.tolerance_px,
            min_extent_px=cells.min_extent_px,
            bridge_px=cells.bridge_px,
            occupied_threshold=p.occupied_threshold,
            free_threshold=p.free_threshold,
        ) | risen_evidence(
            trusted.grid,
            snapshot.grid,
            offset_px=trusted_offset,
            rise_points=p.rise_points,
            rise_margin_px=cells.rise_margin_px,
            min_extent_px=cells.min_extent_px,
            bridge_px=cells.bridge_px,
            free_threshold=p.free_threshold,
        )
        known = placed_grid(anchor.grid, snapshot.grid.shape, anchor_offset) >= 0
        total = int(np.count_nonzero(contradicted))
        return total > 0 and 2 * int(np.count_nonzero(contradicted & known)) >= total

    def _blank(self, snapshot: MapSnapshot) -> bool:
        """Whether ``snapshot`` has no wall at all (a blank map establishes nothing)."""
        return self._walls_of(snapshot) == 0

    def _walls_of(self, snapshot: MapSnapshot) -> int:
        """Occupied cells of ``snapshot`` (at ``occupied_threshold``), counted once."""
        count = self._wall_cells.get(snapshot)
        if count is None:
            count = int(np.count_nonzero(snapshot.grid >= self.params.occupied_threshold))
            self._wall_cells[snapshot] = count
        return count

    def _rounding(self, resolution_m: float) -> float:
        """How far (cells) an origin may lie off the trusted grid's cells to be placed to the
        nearest one: any fraction when half a cell is at most a quarter of the detector's
        tolerance and rise margin (cells of 0.1 m or finer at the defaults; ``resolution_m`` as
        written in decimal: a message's float32 0.1 is 0.10000000149), else 1 %: on coarse
        cells the walls drawn anew a cell over contradict the map (0.5 m cells, an origin 4 cm
        off: a 10 m false break)."""
        p = self.params
        return 0.5 if resolution_m / 2 <= min(p.tolerance_m, p.rise_margin_m) / 4 else 0.01

    def _kernels_fit(self, resolution_m: float) -> bool:
        """Whether the detector's lengths are at most :data:`rose.breaks.MAX_KERNEL_PX` cells of
        ``resolution_m`` (a map finer than about 0.3 mm per cell: its 0.3 m tolerance would be a
        square kernel of over 2000 cells a side)."""
        return round(self._longest_kernel_m() / resolution_m) <= MAX_KERNEL_PX

    def _longest_kernel_m(self) -> float:
        """The longest of the detector's lengths taken as a square kernel or tile (metres)."""
        p = self.params
        return max(p.tolerance_m, p.bridge_m, p.rise_margin_m, p.tile_m)

    def _say_too_fine(self, topic: str, resolution_m: float) -> None:
        """Warn once per topic that the detector's lengths span too many of its maps' cells."""
        if topic in self._too_fine_said:
            return
        self._too_fine_said.add(topic)
        _LOG.warning(
            "%s: the break detector's longest length (tolerance_m, bridge_m, rise_margin_m, tile_m: "
            "%g m) would span more than %d cells of these maps (%g m per cell): they are not "
            "checked for breaks (their break score is 0); said once per topic",
            topic,
            self._longest_kernel_m(),
            MAX_KERNEL_PX,
            resolution_m,
        )

    def withdraw_last(self, topic: str) -> None:
        """Undo the last :meth:`update` of ``topic``, as if that snapshot had never come: a
        session scores each snapshot while it is still being analysed, and one whose analysis
        fails is no snapshot of the session. At most once per update."""
        if topic not in self._before:
            msg = f"no update of {topic!r} to withdraw"
            raise RuntimeError(msg)
        before = self._before.pop(topic)
        if before is None:
            self._state.pop(topic, None)
        else:
            self._state[topic] = before

    def compare(
        self, trusted: MapSnapshot, snapshot: MapSnapshot, offset_px: tuple[int, int]
    ) -> WallContradiction:
        """:func:`rose.breaks.contradicted_walls` with this detector's parameters in cells."""
        p = self.params
        return contradicted_walls(
            trusted.grid,
            snapshot.grid,
            offset_px=offset_px,
            **p.in_cells(snapshot.resolution_m)._asdict(),
            occupied_threshold=p.occupied_threshold,
            free_threshold=p.free_threshold,
            rise_points=p.rise_points,
            tile_origin_px=_frame_origin_px(snapshot),
            established_px=self._walls_of(trusted),
            memo=self._memos.setdefault(trusted, EarlierGridMemo()),
        )
