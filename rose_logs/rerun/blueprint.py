"""The default layout: "when does my map break, and what does ROSE see there?"

Left, large: the segmentation (structure blue, clutter orange, clutter kept as wall teal, walls drawn
by the cleaning crimson, wall segments green) with the dominant directions; below it the map from
above in metres on a metric grid, and the occupied cells' scores. Right: W over session time with
the trust and failure levels and the breaks marked, the break detector's score over the same time,
the cumulative amplitude per direction with its peaks and prominence threshold, the spectrum with
the kept strips, and the events (only when the session has any). Panels are collapsed so the views get the window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import rerun as rr
import rerun.blueprint as rrb
from rerun.encodings import EntityPathLike

from rose_logs.rerun import style
from rose_logs.rerun.amplitude_layout import AmplitudeFrame, amplitude_frame
from rose_logs.rerun.conversions import (
    DIRECTION_LABEL_CLEARANCE_PX,
    DIRECTION_LABEL_EDGE_PX,
    DIRECTION_LABEL_HEIGHT_PX,
    DIRECTION_LABEL_WIDTH_PX,
    SCORE_BAR_ROOM_PX,
    PeakLabelBoxes,
    peak_label_boxes,
    score_bar_width,
)
from rose_logs.rerun.paths import SESSION_TIMELINE, EntityPaths

__all__ = [
    "AMPLITUDE_FRAME",
    "AMPLITUDE_VIEWS_PX",
    "LABEL_WINDOWS_PX",
    "METRIC_MIN_HALF_M",
    "METRIC_VIEWS_PX",
    "PEAK_LABEL_BOXES",
    "SCORES_VIEWS_PX",
    "SEGMENTATION_VIEWS_PX",
    "TopicLayout",
    "amplitude_view_px",
    "default_blueprint",
    "metric_frame",
    "metric_view_px",
    "scores_units_per_px",
    "segmentation_frame",
    "segmentation_title",
    "segmentation_view_px",
]

_FOV_Y_RAD = math.radians(55.0)  # the 3D view's default vertical field of view
_GRID_HEIGHT_M = 0.05  # the metric grid's plane, just above the map (TopicLayout.height_m)
_ONE_TIME_POINT_SIZE = 5.0  # a one-time topic's plotted values, wider than the time cursor

#: Browser windows (width, height, CSS pixels) the map views' direction labels are laid out for,
#: from a 4:3 1024 x 768 screen to a 16:9 1920 x 1080 one (a laptop's 1280 x 720 among them):
#: Rerun draws a label a fixed number of screen pixels in size, and how much of the map a label
#: covers depends on the window. Labels are sized and kept apart for the smallest scale of these
#: (the most cells per pixel), placed in what every one of them shows
#: (:func:`rose_logs.rerun.loggers.direction_label_anchors`).
LABEL_WINDOWS_PX = (
    (1024.0, 768.0),
    (1280.0, 720.0),
    (1366.0, 768.0),
    (1440.0, 900.0),
    (1600.0, 1000.0),
    (1920.0, 1080.0),
)


def segmentation_view_px(
    window_px: tuple[float, float], *, events: bool = False
) -> tuple[float, float]:
    """Screen pixels ``(width, height)`` of the segmentation view in the default layout of a
    ``window_px`` window ``(w, h)``: 3/5 of its width, 3/5 of its height less the viewer's bars
    and the view's title, at least 2 pixels less than measured (labels sized for a view a pixel
    larger than it was overlapped by that much). ``events``: with the events view under the maps
    (the left column's rows 3 / 2 / 1), half the height less the bars and the title.

    Measured in the web viewer with the view filled edge to edge by one colour, at 1024 x 768,
    1280 x 720, 1366 x 768, 1440 x 900, 1600 x 1000, 1920 x 1080: 614, 767, 819, 863, 959, 1151
    wide; 393, 364, 393, 472, 532, 580 high (``0.6 h - 67.6``; read off screenshots of the sample
    map, 396 and 366 at the first two, and at 1280 x 720 labels laid out for 365 touched); with
    the events view 323, 299, 323, 389, 439, 479 high (``0.5 h - 61``)."""
    if events:
        return 0.6 * window_px[0] - 7.0, 0.5 * window_px[1] - 63.0
    return 0.6 * window_px[0] - 7.0, 0.6 * window_px[1] - 70.0


def metric_view_px(window_px: tuple[float, float], *, events: bool = False) -> tuple[float, float]:
    """Screen pixels ``(width, height)`` of the metric view in the default layout of a
    ``window_px`` window ``(w, h)``, ``events`` as :func:`segmentation_view_px`: 3/10 of the width,
    2/5 of the height (with the events view a third) less the bars and the title, at least 2
    pixels less than measured (as there: 306, 383, 409, 431, 479, 575 wide; 253, 234, 253, 306,
    346, 378 high; with the events view 205, 189, 205, 249, 283, 309, ``h / 3 - 50.3``)."""
    if events:
        return 0.3 * window_px[0] - 4.0, window_px[1] / 3.0 - 53.0
    return 0.3 * window_px[0] - 4.0, 0.4 * window_px[1] - 57.0


#: The segmentation views' pixels ``(width, height)`` the direction labels are laid out for: in
#: every window of :data:`LABEL_WINDOWS_PX`, without and with the events view. Both, for every
#: snapshot: the events view comes with a session's first break, after snapshots were logged
#: (a live viewer), and a saved recording's layout shows it at every time (labels laid out for
#: the taller views overlapped under the map from 1024 x 768 to 1366 x 768).
SEGMENTATION_VIEWS_PX = tuple(
    segmentation_view_px(window, events=events)
    for events in (False, True)
    for window in LABEL_WINDOWS_PX
)
#: The metric views' pixels the labels are laid out for (as :data:`SEGMENTATION_VIEWS_PX`).
METRIC_VIEWS_PX = tuple(
    metric_view_px(window, events=events) for events in (False, True) for window in LABEL_WINDOWS_PX
)


def amplitude_view_px(window_px: tuple[float, float]) -> tuple[float, float]:
    """Screen pixels ``(width, height)`` of the amplitude view in the default layout of a
    ``window_px`` window ``(w, h)``: 2/5 of its width, 2.3 / 9.6 of its height less the viewer's
    bars, less the view's title (the right column's rows 2.5 / 1.8 / 2.3 / 3.0, with or without the
    events view, which is in the left column), at least 2 pixels less than measured (as
    :func:`segmentation_view_px`; the views' separators on screenshots at 1024 x 768, 1280 x 720
    and 1920 x 1080: 409 x 140, 512 x 129, 768 x 216)."""
    return 0.4 * window_px[0] - 4.0, 2.3 / 9.6 * (window_px[1] - 67.0) - 30.0


#: The amplitude views' pixels its peaks' labels are laid out for, one per window of
#: :data:`LABEL_WINDOWS_PX`.
AMPLITUDE_VIEWS_PX = tuple(amplitude_view_px(window) for window in LABEL_WINDOWS_PX)
#: The amplitude view's frame and axis labels for those views (worked out once): in a frame 2:1
#: fitted by its height, the axis labels overlapped each other and the threshold's label below
#: 1600 x 1000 ("0" on "0°", "s" on "1", "135°" on "180°", the degrees on the axis's title).
AMPLITUDE_FRAME: AmplitudeFrame = amplitude_frame(AMPLITUDE_VIEWS_PX)
#: The peaks' label boxes in the amplitude plot's units, for those views (every snapshot's labels
#: are placed with them, :func:`rose_logs.rerun.conversions.amplitude_plot`). Sized for
#: 1600 x 1000, labels 20° apart were written over each other at 1024 x 768, and a peak at 0°
#: had its label over the y axis's.
PEAK_LABEL_BOXES: PeakLabelBoxes = peak_label_boxes(AMPLITUDE_FRAME)


#: The scores view's pixels the colour bar is laid out for: the metric view's twin (the two share
#: the left column's second row), with and without the events view in every window.
SCORES_VIEWS_PX = METRIC_VIEWS_PX


#: The narrowest and the lowest of :data:`SCORES_VIEWS_PX` (the lowest less the colour bar's room):
#: a box's units per pixel are largest in them (worked out once: the bar is placed per snapshot).
_SCORES_MIN_W = min(w for w, _ in SCORES_VIEWS_PX)
_SCORES_MIN_H = max(min(h for _, h in SCORES_VIEWS_PX) - SCORE_BAR_ROOM_PX, 1.0)


def scores_units_per_px(width: float, height: float) -> float:
    """Units per screen pixel of the scores view at its smallest (the most of
    :data:`SCORES_VIEWS_PX`) framing a box ``width`` x ``height`` (any units) with its margins
    and the colour bar under it (:data:`~rose_logs.rerun.conversions.SCORE_BAR_ROOM_PX`, solved
    for it, as :func:`_segmentation_room`), as wide as the bar and its labels out of its ends:
    the bar and its labels are laid out in pixels at this scale
    (:func:`rose_logs.rerun.loggers.bar_placement`), so they hold in every window."""
    margin = _margin(width, height)
    per_px = max((width + 2 * margin) / _SCORES_MIN_W, (height + 2 * margin) / _SCORES_MIN_H)
    # A narrow map's bar and labels are wider than the map (at this scale; every view is more
    # than the bar and a label wide, so the scale they need is no larger than this one).
    across = score_bar_width(width, per_px) + DIRECTION_LABEL_WIDTH_PX * per_px + 2 * margin
    return max(per_px, across / _SCORES_MIN_W)


#: Metres the metric view's camera frames at least either side of the map's centre (a map of
#: a few cells is not seen from a few centimetres up); the direction labels' scale there
#: (:func:`metric_frame`) holds the same floor: without it, on a map under about a metre two
#: labels were placed for a view twice as close and overlapped.
METRIC_MIN_HALF_M = 0.5

#: Width / height of the metric view its camera frames the map for: the narrowest of
#: :data:`METRIC_VIEWS_PX` (1024 x 768 without the events view, 1.21; with it the views are
#: wider, and the camera's vertical field of view shows the same height). At the 1.3 of a
#: 1600 x 1000 window the map was cut off at both sides of a 1024 x 768 one.
_ASSUMED_ASPECT = min(w / h for w, h in METRIC_VIEWS_PX)

#: Screen pixels a label under a map takes: its clearance from the line, its height, the view's
#: edge under it.
_LABEL_ROOM_PX = DIRECTION_LABEL_CLEARANCE_PX + DIRECTION_LABEL_HEIGHT_PX + DIRECTION_LABEL_EDGE_PX


@dataclass(frozen=True)
class TopicLayout:
    """What the layout of one map topic depends on.

    Attributes
    ----------
    root : str
        Entity root of the topic.
    bounds_m : tuple of float or None
        ``(x_min, y_min, x_max, y_max)`` of the known part of the map in the map frame, metres (None
        before any map): the metric view looks at it from above, the 2D views frame it north up.
    view_origin_m : tuple of float
        Map-frame point at the views' 0, the 2D views' and the metric view's
        (:func:`rose_logs.rerun.loggers.view_origin_m`).
    height_m : float
        Map-frame height of the maps (their first snapshot's origin z, metres): the metric view's
        grid floats just above it and its camera looks down at it. A floor of a multi-storey map
        lies at its origin's z; at z = 0 the grid was hidden under the map and the camera, that
        much nearer, cut the map off.
    has_events : bool
        Whether the topic has break events (the events view is shown only then).
    has_walls : bool
        Whether wall segments are drawn over the maps (``--walls``): the segmentation's title
        names their colour.
    walls_cleaning : bool
        Whether the maps are cleaned by the walls rules, whose kept and drawn walls the
        segmentation shows (teal, crimson; the paper's labelling has neither).
    w_top, break_top : float or None
        Highest value the W plot / the break-score plot shows (data and guide lines): the plots get
        headroom above it so a guide line at the top stays visible. None: fit to the data (live).
    one_time_window_s : float or None
        For a topic whose snapshots are all at one log time (a map_server log's one latched map):
        the plots' time axis, seconds either side of the time cursor (as wide as the session and
        more, so that the topic's time is in view wherever the cursor is; the topic's own time
        range has no width, and its axis printed labels such as ".000001 ms" over each other),
        its values drawn as large points. None: the whole session.
    """

    root: str
    bounds_m: tuple[float, float, float, float] | None = None
    view_origin_m: tuple[float, float] = (0.0, 0.0)
    height_m: float = 0.0
    has_events: bool = False
    has_walls: bool = False
    walls_cleaning: bool = True
    w_top: float | None = None
    break_top: float | None = None
    one_time_window_s: float | None = None


#: The plots' value axes reach this fraction of their top below 0: values of 0 (a break score
#: that is 0 most of a session) lay on the plot's lower edge, half cut off and hidden by the time
#: axis, and read as no data.
_BELOW_ZERO = 0.05


def _value_axis(top: float | None) -> rrb.ScalarAxis | None:
    """A y axis from a little below 0 (:data:`_BELOW_ZERO`) to ``top`` plus 15 % (None: Rerun fits
    the data, lines at the top edge hide)."""
    if top is None or not math.isfinite(top) or top <= 0:
        return None
    return rrb.ScalarAxis(range=(-_BELOW_ZERO * top, 1.15 * top))


def _grid_spacing_m(bounds_m: tuple[float, float, float, float] | None) -> float:
    """The smallest round spacing (1, 2 or 5 times a power of ten, metres) giving at most 15 lines
    across the map, whatever its size (1 m without a map)."""
    if bounds_m is None:
        return 1.0
    span = max(bounds_m[2] - bounds_m[0], bounds_m[3] - bounds_m[1])
    if not math.isfinite(span) or span <= 0:
        return 1.0
    decade = 10.0 ** math.floor(math.log10(span / 15))
    return next(step * decade for step in (1.0, 2.0, 5.0, 10.0) if span / (step * decade) <= 15)


def _margin(width: float, height: float) -> float:
    """The 2D views' margin around a ``width`` x ``height`` box (each side, same units)."""
    return 0.03 * max(width, height)


def _segmentation_room(width: float, height: float) -> float:
    """Room under a ``width`` x ``height`` box (any units) in the segmentation view for a
    direction's label (:data:`_LABEL_ROOM_PX`) in every view of :data:`SEGMENTATION_VIEWS_PX`: a
    steep line's label hangs under its lower end (a fixed 0.08 of a tall map's height left it
    about 26 pixels at 1280 x 720, against 38 it takes).

    The view fits the box, its margins and the room; the room must be the label's pixels times
    the view's units per pixel, ``max(framed width / view width, framed height / view height)``,
    where the framed height holds the room itself (solved for it)."""
    margin = _margin(width, height)
    rooms = [
        max(
            _LABEL_ROOM_PX * (width + 2 * margin) / view_w,
            _LABEL_ROOM_PX * (height + 2 * margin) / max(view_h - _LABEL_ROOM_PX, 1.0),
        )
        for view_w, view_h in SEGMENTATION_VIEWS_PX
    ]
    return max(rooms)


def _metric_room(width: float, height: float) -> float:
    """Room under a ``width`` x ``height`` box (any units) in the metric view for a direction's
    label in every view of :data:`METRIC_VIEWS_PX` (as :func:`_segmentation_room`; the camera
    sees ``1.05 max(height + room, width / aspect)`` high on the view's height). A fixed 0.08 of
    the map's height cut a tall map's "walls 86.2°" off at the view's lower edge at 1280 x 720."""
    rooms = [
        1.05
        * _LABEL_ROOM_PX
        * max(
            width / (_ASSUMED_ASPECT * view_h),
            height / max(view_h - 1.05 * _LABEL_ROOM_PX, 1.0),
        )
        for _, view_h in METRIC_VIEWS_PX
    ]
    return max(rooms)


def segmentation_frame(width: float, height: float) -> tuple[float, float, float, float]:
    """``(left, bottom, right, top)`` the segmentation view frames around a known box ``width``
    x ``height`` (north up, y up, any units; from the box's lower left corner): its margins and
    the room for a label under it (:func:`_north_up_bounds`). The view shows at least that in
    any window (it fits the frame, keeping its aspect)."""
    margin = _margin(width, height)
    return -margin, -margin - _segmentation_room(width, height), width + margin, height + margin


def metric_frame(
    width: float, height: float, *, min_half: float = 0.0
) -> tuple[float, float, float, float]:
    """``(left, bottom, right, top)`` the metric view shows of the map plane around a known box
    ``width`` x ``height`` (as :func:`segmentation_frame`) in a window of the narrowest view of
    :data:`LABEL_WINDOWS_PX` (a wider one shows more at the sides) (:func:`_metric_eye`);
    ``min_half``: :data:`METRIC_MIN_HALF_M` in the units of the box (the camera frames at least
    that either side of its centre)."""
    room = _metric_room(width, height)
    # The camera's height is 1.05 max(...) / tan(fov / 2): it sees 2 tan(fov / 2) that high,
    # centred on the box and the room under it.
    seen = 1.05 * max(height + room, 2 * min_half, max(width, 2 * min_half) / _ASSUMED_ASPECT)
    middle = (height - room) / 2
    half_width = _ASSUMED_ASPECT * seen / 2
    return width / 2 - half_width, middle - seen / 2, width / 2 + half_width, middle + seen / 2


def _metric_eye(layout: TopicLayout) -> rrb.EyeControls3D | None:
    """A camera straight above the map centre, high enough for the map and the room under it for
    a label (:func:`_metric_room`) to fill the view (the metric view's metres: the map frame's
    less the view origin)."""
    if layout.bounds_m is None:
        return None
    x_min, y_min, x_max, y_max = layout.bounds_m
    # The map frame's y points north, up in the view.
    y_min -= _metric_room(x_max - x_min, y_max - y_min)
    rx, ry = layout.view_origin_m
    cx, cy = (x_min + x_max) / 2 - rx, (y_min + y_max) / 2 - ry
    half_x = max((x_max - x_min) / 2, METRIC_MIN_HALF_M)
    half_y = max((y_max - y_min) / 2, METRIC_MIN_HALF_M)
    tan_half = math.tan(_FOV_Y_RAD / 2)
    height = 1.05 * max(half_y / tan_half, half_x / (tan_half * _ASSUMED_ASPECT))
    return rrb.EyeControls3D(
        kind=rrb.Eye3DKind.Orbital,
        position=[cx, cy, layout.height_m + height],
        look_target=[cx, cy, layout.height_m],
        eye_up=[0.0, 1.0, 0.0],
    )


def _north_up_bounds(
    layout: TopicLayout, *, bar: bool = False, label: bool = False
) -> rrb.VisualBounds2D | None:
    """The known box of ``layout`` in the 2D views' north-up frame (x east, y south, metres from
    its view origin: :func:`rose_logs.rerun.loggers.placement_terms`), with a margin; ``bar``:
    and the colour bar and its labels under it, as wide as they are
    (:func:`scores_units_per_px`, :func:`rose_logs.rerun.loggers.bar_placement`); ``label``: room
    for a direction's label under it (:func:`_segmentation_room`)."""
    if layout.bounds_m is None:
        return None
    x0, y0, x1, y1 = layout.bounds_m
    rx, ry = layout.view_origin_m
    width, height = x1 - x0, y1 - y0
    margin = _margin(width, height)
    extra = 0.0
    if label:
        extra += _segmentation_room(width, height)
    spill = 0.0  # how far the bar's labels reach out of the box on either side
    if bar:
        per_px = scores_units_per_px(width, height)
        extra += SCORE_BAR_ROOM_PX * per_px
        reach = score_bar_width(width, per_px) + DIRECTION_LABEL_WIDTH_PX * per_px
        spill = max(reach - width, 0.0) / 2
    return rrb.VisualBounds2D(
        x_range=(x0 - rx - margin - spill, x1 - rx + margin + spill),
        y_range=(ry - y1 - margin, ry - y0 + margin + extra),
    )


def segmentation_title(root: str, *, has_walls: bool = False, walls_cleaning: bool = True) -> str:
    """The segmentation view's title: the topic and every colour the view draws but magenta (the
    directions, labelled). The walls cleaning's teal and crimson cells are in nearly every
    picture it makes, and the wall segments' green over the walls with ``--walls``: a title naming
    blue and orange only left them unexplained (and with the walls drawn, hardly any blue
    showed). The paper's labelling (``walls_cleaning`` False) keeps and draws no walls."""
    cleaning = ", walls the cleaning kept (teal) / drew (crimson)" if walls_cleaning else ""
    walls = ", wall segments (green)" if has_walls else ""
    return f"{root}: segmentation, structure (blue) / clutter (orange){cleaning}{walls}, north up"


def _topic_container(layout: TopicLayout) -> rrb.Container:
    paths = EntityPaths(layout.root)
    root = paths.root
    # The topic in the first view's title only: in the others' it cut their legends off (a
    # long topic name); the topic's tab names it too.
    segmentation = rrb.Spatial2DView(
        name=segmentation_title(
            root, has_walls=layout.has_walls, walls_cleaning=layout.walls_cleaning
        ),
        origin=f"/{paths.cells}",
        visual_bounds=_north_up_bounds(layout, label=True),  # and a label under the map
    )
    spacing = _grid_spacing_m(layout.bounds_m)
    metric = rrb.Spatial3DView(
        name=f"map from above, metres (grid {spacing:g} m)",
        origin=f"/{paths.metric}",
        # Just above the map (an opaque grid map would hide a grid in its own plane).
        line_grid=rrb.LineGrid3D(
            visible=True,
            spacing=spacing,
            plane=rr.components.Plane3D((0.0, 0.0, 1.0), distance=layout.height_m + _GRID_HEIGHT_M),
            stroke_width=1.0,
            color=(90, 90, 90, 110),
        ),
        eye_controls=_metric_eye(layout),
    )
    scores = rrb.Spatial2DView(
        name="scores of occupied cells",
        origin=f"/{paths.scores_view}",
        visual_bounds=_north_up_bounds(layout, bar=True),  # and the colour bar
    )
    w_plot = _session_plot(
        # (As long as fits a third of 1600 pixels: a longer title was cut.)
        "structure score W (blue), trust (green) / failure (red), x: break, ^: W > failure",
        f"/{paths.score}",
        layout.w_top,
        one_time_window_s=layout.one_time_window_s,
        points={
            f"/{paths.w}": rr.SeriesPoints.from_fields(marker_sizes=[_ONE_TIME_POINT_SIZE] * 3)
        },
    )
    break_plot = _session_plot(
        "break score (orange; m of established map contradicted), threshold (red)",
        f"/{paths.break_score_view}",
        layout.break_top,
        one_time_window_s=layout.one_time_window_s,
        points={
            f"/{paths.break_score}": rr.SeriesPoints.from_fields(marker_sizes=_ONE_TIME_POINT_SIZE),
            f"/{paths.break_threshold}": rr.SeriesPoints.from_fields(
                colors=style.FAILURE_COLOR, marker_sizes=_ONE_TIME_POINT_SIZE
            ),
        },
    )
    amplitude = rrb.Spatial2DView(
        # (The title's length fits a third of 1600 pixels.)
        name="cumulative amplitude s per direction; peaks kept if bar (prominence p) passes t",
        origin=f"/{paths.amplitude_view}",
        # Room for the axes' and the peaks' labels in every window (AMPLITUDE_FRAME).
        visual_bounds=rrb.VisualBounds2D(
            x_range=AMPLITUDE_FRAME.x_range, y_range=AMPLITUDE_FRAME.y_range
        ),
    )
    spectrum = rrb.Spatial2DView(
        name="log amplitude spectrum, kept strips (magenta)",
        origin=f"/{paths.spectrum_view}",
        background=[0, 0, 0],
    )
    left: list[rrb.View | rrb.Horizontal] = [segmentation, rrb.Horizontal(metric, scores)]
    shares = [3.0, 2.0]
    if layout.has_events:
        # Under the maps, across the wider column: room for several rows of long text (in the
        # right column one row showed, cut at the right).
        left.append(_events_view("events", f"/{paths.events}"))
        shares.append(1.0)
    return rrb.Horizontal(
        rrb.Vertical(*left, row_shares=shares),
        rrb.Vertical(w_plot, break_plot, amplitude, spectrum, row_shares=[2.5, 1.8, 2.3, 3.0]),
        column_shares=[3.0, 2.0],
        name=root,
    )


def _events_view(name: str, origin: str) -> rrb.TextLogView:
    """Session time and the event's text: the entity path and level columns would say the same on
    every row (the topic's events, all warnings) and leave the text too little of the width."""
    return rrb.TextLogView(
        name=name,
        origin=origin,
        columns=rrb.TextLogColumns(
            timeline_columns=[rrb.components.TimelineColumn(SESSION_TIMELINE)],
            text_log_columns=[
                rrb.components.TextLogColumn("Body"),
                rrb.components.TextLogColumn("EntityPath", visible=False),
                rrb.components.TextLogColumn("LogLevel", visible=False),
            ],
        ),
    )


def _time_range(one_time_window_s: float | None) -> rrb.TimeRange:
    """The plots' time axis: the whole session, or ``one_time_window_s`` seconds either side of
    the cursor (:class:`TopicLayout`)."""
    if one_time_window_s is not None:
        return rrb.TimeRange(
            start=rrb.TimeRangeBoundary.cursor_relative(seconds=-one_time_window_s),
            end=rrb.TimeRangeBoundary.cursor_relative(seconds=one_time_window_s),
        )
    return rrb.TimeRange(
        start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite()
    )


def _session_plot(
    name: str,
    origin: str,
    top: float | None,
    *,
    one_time_window_s: float | None = None,
    points: dict[str, rr.SeriesPoints] | None = None,
) -> rrb.TimeSeriesView:
    """A time series over the whole session (on any timeline; the default follows the time
    cursor), or for a topic at one time a window around the cursor (:class:`TopicLayout`).

    ``points``: series (entity path: their points' style) drawn with large points as well as their
    lines for a topic at one time, where a line has no length and the time cursor covers small
    points.
    """
    one_time = one_time_window_s is not None
    overrides: dict[EntityPathLike, list[rrb.Visualizer]] | None = (
        {
            path: [rr.SeriesLines.from_fields().visualizer(), style.visualizer()]
            for path, style in points.items()
        }
        if one_time and points
        else None
    )
    return rrb.TimeSeriesView(
        name=name,
        origin=origin,
        overrides=overrides,
        # No legend: in any corner it covered data (the break score's early peak); the titles
        # name each series by its colour.
        plot_legend=rrb.PlotLegend(visible=False),
        axis_y=_value_axis(top),
        axis_x=rrb.TimeAxis(view_range=_time_range(one_time_window_s)),
    )


def default_blueprint(layouts: tuple[TopicLayout, ...], *, live: bool = False) -> rrb.Blueprint:
    """The layout for the map topics of ``layouts`` (tabs when there are several).

    Parameters
    ----------
    layouts : tuple of TopicLayout
        One per map topic, in tab order.
    live : bool
        Streaming to a viewer as the session is processed: the time cursor follows the newest data.
        Otherwise (a saved recording) playback starts paused.
    """
    if not layouts:
        msg = "default_blueprint needs at least one topic layout"
        raise ValueError(msg)
    containers = [_topic_container(layout) for layout in layouts]
    body = containers[0] if len(containers) == 1 else rrb.Tabs(*containers)
    return rrb.Blueprint(
        body,
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(
            state="collapsed",
            timeline=SESSION_TIMELINE,
            play_state="following" if live else "paused",
        ),
        collapse_panels=False,
    )
