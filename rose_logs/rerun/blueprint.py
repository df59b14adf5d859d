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
from rose_logs.rerun.conversions import score_bar_width
from rose_logs.rerun.paths import SESSION_TIMELINE, EntityPaths

__all__ = [
    "METRIC_VIEW_PX",
    "SEGMENTATION_VIEW_PX",
    "TopicLayout",
    "default_blueprint",
    "metric_framed",
    "segmentation_framed",
    "segmentation_title",
]

_FOV_Y_RAD = math.radians(55.0)  # the 3D view's default vertical field of view
_ASSUMED_ASPECT = 1.3  # width / height of the metric view in the default layout
_GRID_HEIGHT_M = 0.05  # the metric grid's plane, just above the map (TopicLayout.height_m)
_ONE_TIME_POINT_SIZE = 5.0  # a one-time topic's plotted values, wider than the time cursor
#: Screen pixels (width, height) of the segmentation and metric views at the default layout in a
#: 1600 x 1000 window (the screenshot tool's): what a label a fixed number of pixels wide covers
#: of the map there (conversions.direction_label_positions).
SEGMENTATION_VIEW_PX = (955.0, 535.0)
METRIC_VIEW_PX = (478.0, 345.0)


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


#: Room under the map in the segmentation and metric views, as a fraction of the map's height (at
#: least a quarter of its width): a steep direction line's label hangs under its lower end
#: (conversions.direction_label_positions), and on a map taller than its view it was cut off at
#: the view's lower edge (the metric view's entirely).
_LABEL_ROOM = 0.08


def _label_room_m(bounds_m: tuple[float, float, float, float]) -> float:
    """Metres of :data:`_LABEL_ROOM` under the box ``bounds_m``."""
    x_min, y_min, x_max, y_max = bounds_m
    return _LABEL_ROOM * max(y_max - y_min, 0.25 * (x_max - x_min))


def _margin(width: float, height: float) -> float:
    """The 2D views' margin around a ``width`` x ``height`` box (each side, same units)."""
    return 0.03 * max(width, height)


def segmentation_framed(width: float, height: float) -> tuple[float, float]:
    """``(width, height)`` the segmentation view frames around a known box ``width`` x ``height``
    (north up, any units): its margins and the room for a label under it
    (:func:`_north_up_bounds`)."""
    margin = _margin(width, height)
    return width + 2 * margin, height + 2 * margin + _LABEL_ROOM * max(height, 0.25 * width)


def metric_framed(width: float, height: float) -> tuple[float, float]:
    """``(width, height)`` the metric view shows of the map plane around a known box ``width`` x
    ``height`` (north up, any units), at its assumed aspect (:func:`_metric_eye`)."""
    room = _LABEL_ROOM * max(height, 0.25 * width)
    # The camera's height is 1.05 max(...) / tan(fov / 2): it sees 2 tan(fov / 2) that high.
    seen = 1.05 * max(height + room, width / _ASSUMED_ASPECT)
    return _ASSUMED_ASPECT * seen, seen


def _metric_eye(layout: TopicLayout) -> rrb.EyeControls3D | None:
    """A camera straight above the map centre, high enough for the map and the room under it for
    a label (:data:`_LABEL_ROOM`) to fill the view (the metric view's metres: the map frame's less
    the view origin)."""
    if layout.bounds_m is None:
        return None
    x_min, y_min, x_max, y_max = layout.bounds_m
    y_min -= _label_room_m(layout.bounds_m)  # the map frame's y points north, up in the view
    rx, ry = layout.view_origin_m
    cx, cy = (x_min + x_max) / 2 - rx, (y_min + y_max) / 2 - ry
    half_x, half_y = max((x_max - x_min) / 2, 0.5), max((y_max - y_min) / 2, 0.5)
    tan_half = math.tan(_FOV_Y_RAD / 2)
    height = 1.05 * max(half_y / tan_half, half_x / (tan_half * _ASSUMED_ASPECT))
    return rrb.EyeControls3D(
        kind=rrb.Eye3DKind.Orbital,
        position=[cx, cy, layout.height_m + height],
        look_target=[cx, cy, layout.height_m],
        eye_up=[0.0, 1.0, 0.0],
    )


def _north_up_bounds(
    layout: TopicLayout, *, below: float = 0.0, bar: bool = False
) -> rrb.VisualBounds2D | None:
    """The known box of ``layout`` in the 2D views' north-up frame (x east, y south, metres from
    its view origin: :func:`rose_logs.rerun.loggers.placement_terms`), with a margin, and
    ``below`` times its height (at least a quarter of its width, as the colour bar's size:
    :func:`rose_logs.rerun.loggers.bar_placement`) more under it; ``bar``: as wide as the colour
    bar at least (a tall map's is wider than the map)."""
    if layout.bounds_m is None:
        return None
    x0, y0, x1, y1 = layout.bounds_m
    rx, ry = layout.view_origin_m
    margin = _margin(x1 - x0, y1 - y0)
    extra = below * max(y1 - y0, 0.25 * (x1 - x0))
    spill = 0.0  # how far the bar reaches out of the box on either side
    if bar:
        spill = max(score_bar_width(x1 - x0, max(y1 - y0, 0.25 * (x1 - x0))) - (x1 - x0), 0.0) / 2
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
    h = style.AMPLITUDE_PLOT_HEIGHT
    # The topic in the first view's title only: in the others' it cut their legends off (a
    # long topic name); the topic's tab names it too.
    segmentation = rrb.Spatial2DView(
        name=segmentation_title(
            root, has_walls=layout.has_walls, walls_cleaning=layout.walls_cleaning
        ),
        origin=f"/{paths.cells}",
        visual_bounds=_north_up_bounds(layout, below=_LABEL_ROOM),  # and a label under the map
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
        visual_bounds=_north_up_bounds(layout, below=0.45, bar=True),  # and the colour bar
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
        # Above s = 1: the peaks' labels hang over them (conversions.PEAK_LABEL_LIFT).
        visual_bounds=rrb.VisualBounds2D(x_range=(-22.0, 198.0), y_range=(-1.36 * h, 44.0)),
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
