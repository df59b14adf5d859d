"""One ``log_<stream>()`` per stream of a map topic, and the static data, logged once.

:class:`TopicLogger` holds what must not be re-sent (static data, the score legend of the current map
shape) for one map topic; :mod:`rose_logs.rerun.sink` drives one per topic. Every image-like buffer is
converted by :mod:`rose_logs.rerun.conversions` (north up, image row order).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import TypeVar

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import rerun as rr

from rose.cleaning import CleanResult
from rose.directions import FAILURE_LEVEL, TRUST_LEVEL, map_frame_deg
from rose.result import RoseResult
from rose.walls import WallSet
from rose.walls.segments import cells_to_metres
from rose_logs.frames import yaw_to_quaternion
from rose_logs.rerun import arrow, style
from rose_logs.rerun import conversions as conv
from rose_logs.rerun.amplitude_layout import S_TICKS, X_TICKS_DEG
from rose_logs.rerun.blueprint import (
    AMPLITUDE_FRAME,
    METRIC_MIN_HALF_M,
    METRIC_VIEWS_PX,
    PEAK_LABEL_BOXES,
    SEGMENTATION_VIEWS_PX,
    metric_frame,
    scores_units_per_px,
    segmentation_frame,
)
from rose_logs.rerun.paths import SEQUENCE_TIMELINE, SESSION_TIMELINE, TIMELINE, EntityPaths
from rose_logs.session.breaks import BreakScore
from rose_logs.session.report import w_judges
from rose_logs.snapshots import MapSnapshot

__all__ = ["TopicLogger", "set_snapshot_time"]

#: Height of the metric view's overlays above the grid map, as a fraction of the map's larger
#: side (at least 2 cm): a fixed 2-3 cm lost the depth test against the map's plane once the
#: camera backed off to show a 50 m map (the direction lines vanished, the break rectangle kept
#: two of its sides). Seen from above, the height moves nothing in the picture.
_OVERLAY_HEIGHT_FRACTION = 0.005
_MIN_OVERLAY_HEIGHT_M = 0.02


@functools.lru_cache(maxsize=64)
def _curve_style(peaks: int, rejected: int = 0) -> tuple[pa.Array, pa.Array]:
    """Colours and radii of the amplitude curve, its ``peaks`` prominence bars and the
    ``rejected`` peaks' (grey), converted once per count (Arrow arrays are immutable: shared by
    every log call)."""
    colors = rr.components.ColorBatch(
        [style.CURVE_COLOR] + [style.PEAK_COLOR] * peaks + [style.REJECTED_PEAK_COLOR] * rejected
    )
    radii = rr.components.RadiusBatch(rr.Radius.ui_points([1.5] + [1.0] * (peaks + rejected)))
    return colors.as_arrow_array(), radii.as_arrow_array()


def segmentation_image(image: npt.NDArray[np.uint8]) -> list[rr.DescribedComponentBatch]:
    """The components of ``rr.SegmentationImage(image)`` (class ids, image row order) without its
    copies (:func:`~rose_logs.rerun.arrow.image_buffer`)."""
    return arrow.described(
        rr.SegmentationImage, buffer=arrow.image_buffer(image), format=arrow.u8_format(image)
    )


#: Components logged unchanged again and again, converted once (:func:`arrow.batches`).
_CLEAR = arrow.batches(rr.Clear(recursive=False))
_CLEAR_RECURSIVE = arrow.batches(rr.Clear(recursive=True))


# What most snapshots of a session log again with the same values (a grid's cell size and place,
# the detector's threshold, the amplitude plot's threshold line, the colour bar's labels),
# converted once per value: Arrow arrays are immutable, so one is shared by every log call.

_Components = TypeVar("_Components")


def _by_value(convert: Callable[..., _Components], maxsize: int = 64) -> Callable[..., _Components]:
    """``convert`` remembered by the exact values of its arguments (their ``repr``: 0.0 and -0.0
    are two values, as they are two labels and two bit patterns; ``lru_cache`` took them for one)."""
    cache: dict[str, _Components] = {}

    @functools.wraps(convert)
    def cached(*args: object) -> _Components:
        key = repr(args)
        found = cache.get(key)
        if found is None:
            if len(cache) >= maxsize:
                cache.clear()
            found = cache[key] = convert(*args)
        return found

    return cached


@_by_value
def _grid_placement(
    cell_size: float, translation: tuple[float, float, float], yaw_rad: float
) -> list[rr.DescribedComponentBatch]:
    """The GridMap's cell size, translation and rotation (a quaternion of ``yaw_rad``)."""
    return arrow.described(
        rr.GridMap,
        cell_size=cell_size,
        translation=list(translation),
        quaternion=rr.Quaternion(xyzw=yaw_to_quaternion(yaw_rad)),
    )


@_by_value
def _scalar(value: float) -> list[rr.DescribedComponentBatch]:
    """``rr.Scalars(value)``'s components."""
    return arrow.described(rr.Scalars, scalars=arrow.floats(value))


@_by_value
def _placement(
    translation: tuple[float, float], angle: float, scale: float
) -> list[rr.DescribedComponentBatch]:
    """The components of the transform that places pixels by :func:`placement_terms`' terms
    (translation in x-y, rotation about z, scale in x-y), built as Arrow arrays (Rerun's
    Transform3D cost about 0.1 ms to build, three times per snapshot of a map that grows); a
    snapshot's images share placements, as do snapshots of a map that did not grow."""
    return arrow.described(
        rr.Transform3D,
        translation=arrow.points([[*translation, 0.0]], dims=3),
        rotation_axis_angle=arrow.axis_angle((0.0, 0.0, 1.0), angle),
        scale=arrow.points([[scale, scale, 1.0]], dims=3),
    )


#: The break region's style (its outline's and its label's colour and width).
_BREAK_COLOR = rr.components.ColorBatch(style.BREAK_COLOR).as_arrow_array()
_BREAK_RADIUS = rr.components.RadiusBatch(rr.Radius.ui_points(2.5)).as_arrow_array()


def _amplitude_threshold(
    strips: list[list[tuple[float, float]]], threshold: float
) -> list[rr.DescribedComponentBatch]:
    """The prominence threshold's ``strips`` (:attr:`conv.AmplitudePlot.threshold_strips`), the
    first labelled with its value."""
    return arrow.described(
        rr.LineStrips2D,
        strips=arrow.strips(np.asarray(strips, dtype=np.float64).reshape(-1, 2, 2)),
        labels=arrow.texts([f"t = {threshold:g}"] + [""] * (len(strips) - 1)),
    )


@_by_value
def _score_bar(threshold: float | None) -> list[rr.DescribedComponentBatch]:
    """The colour bar's labels (scale; the ROSE threshold, None: none) and the threshold's tick."""
    levels = style.DISPLAY_LEVELS

    def u_of(score: float) -> float:
        return levels * float(conv.score_to_unit(np.array([score]))[0])

    # In the bar's pixels (levels x 2): the labels keep their places when the session ends and
    # the bar moves under the final map (:meth:`TopicLogger.log_final_placement`).
    positions = [
        (u_of(style.SCORE_DISPLAY_MIN), _BAR_LABELS_BELOW_PX),
        (u_of(1.0), _BAR_LABELS_BELOW_PX),
    ]
    labels = [f"score ≤ {style.SCORE_DISPLAY_MIN:g}", "1 (best cell)"]  # lower ones clipped
    tick = np.empty((0, 2, 2))
    if threshold is not None:
        at = u_of(threshold)
        positions.append((at, _BAR_THRESHOLD_LABEL_PX))
        labels.append(f"threshold {threshold:.2f}")
        # A tick across the bar, from above it (where the label is) to its lower edge.
        tick = np.array([[(at, -0.6), (at, 2.0)]])
    return [
        *arrow.described(rr.Points2D, positions=arrow.points(positions), labels=labels),
        *arrow.described(rr.LineStrips2D, strips=arrow.strips(tick)),
    ]


def view_origin_m(snapshot: MapSnapshot) -> tuple[float, float]:
    """Map-frame point (metres, on a 100 m lattice) that the views of a topic put at their 0 (the
    2D views and the metric view): its first snapshot's origin, rounded. Rerun places things in
    float32, whose steps are 0.5 m at a UTM northing; near 0 they are micrometres."""
    x, y = (float(v) for v in snapshot.origin_position_m[:2])
    return round(x, -2), round(y, -2)


def placement_terms(
    snapshot: MapSnapshot,
    view_origin: tuple[float, float],
    window: conv.Window | None = None,
    factor: int = 1,
) -> tuple[tuple[float, float], float, float]:
    """Where the 2D views draw pixels of ``snapshot``'s north-up images of ``window`` (default: the
    whole grid), each pixel ``factor`` x ``factor`` cells (a pooled image: ``window`` is then its
    :func:`~conv.pooled_window`): in metres of the map frame from ``view_origin``
    (:func:`view_origin_m`), north up (x east, y south: 2D views draw y downwards). Returns
    ``(translation, rotation angle (radians, about z), scale)``: a pixel ``p`` lands at
    ``translation + R(angle) (scale * p)`` (:func:`_placement` makes it Rerun's transform).

    Every snapshot lands where it lies in the map, so a map that grows, moves its origin or changes
    resolution during a session stays in place in the views (in pixels, each grid size had its own
    frame: a growing map jumped and shrank in a fixed view).
    """
    res = float(snapshot.resolution_m)
    yaw = float(snapshot.origin_yaw_rad)
    c, s = math.cos(yaw), math.sin(yaw)
    ox, oy = (float(v) for v in snapshot.origin_position_m[:2])
    x0, _, _, y1 = window or (0, 0, 0, snapshot.grid.shape[0])
    # Pixel (u, v) is grid point (res (x0 + u), res (y1 - v)); rotate by yaw, translate by the
    # origin (less the view's), negate y: X = ox - rx + res (c (x0 + u) - s (y1 - v)), Y likewise.
    translation = (
        ox - view_origin[0] + res * (c * x0 - s * y1),
        -(oy - view_origin[1]) - res * (s * x0 + c * y1),
    )
    return translation, -yaw, res * factor


def north_up_m(
    snapshot: MapSnapshot, cells: npt.NDArray[np.float64], view_origin: tuple[float, float]
) -> npt.NDArray[np.float64]:
    """Continuous grid-frame cells ``(..., 2)`` -> the 2D views' north-up metres ``(..., 2)``."""
    xy = _cells_to_map_xy(snapshot, cells)
    return np.stack([xy[..., 0] - view_origin[0], view_origin[1] - xy[..., 1]], axis=-1)


def metric_m(
    snapshot: MapSnapshot, cells: npt.NDArray[np.float64], view_origin: tuple[float, float]
) -> npt.NDArray[np.float64]:
    """Continuous grid-frame cells ``(..., 2)`` -> the metric view's metres ``(..., 3)``: the map
    frame's, less ``view_origin`` (:func:`view_origin_m`), just above the grid. Worked out in
    float64 before Rerun's float32 (at a UTM northing, map-frame metres are 0.5 m steps there)."""
    return map_to_metric_m(cells_to_map_m(snapshot, cells), view_origin)


def map_to_metric_m(
    points_m: npt.NDArray[np.float64], view_origin: tuple[float, float]
) -> npt.NDArray[np.float64]:
    """Map-frame points ``(..., 2 or 3)`` (metres) -> the metric view's (``view_origin`` at 0)."""
    out = np.array(points_m, dtype=np.float64)
    out[..., 0] -= view_origin[0]
    out[..., 1] -= view_origin[1]
    return out


def set_snapshot_time(
    recording: rr.RecordingStream, *, log_time_ns: int, start_ns: int, index: int | None
) -> None:
    """Put the recording's time at a snapshot: session time, ROS log time and snapshot index."""
    recording.reset_time()
    recording.set_time(SESSION_TIMELINE, duration=np.timedelta64(int(log_time_ns - start_ns), "ns"))
    recording.set_time(TIMELINE, timestamp=np.datetime64(int(log_time_ns), "ns"))
    if index is not None:
        recording.set_time(SEQUENCE_TIMELINE, sequence=int(index))


def cells_to_map_m(
    snapshot: MapSnapshot, cells: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """Continuous grid-frame cells ``(..., 2)`` (0 = a cell's corner) -> map-frame metres ``(..., 3)``,
    just above the grid (ROS maps are planar: the origin's yaw places them)."""
    xy = _cells_to_map_xy(snapshot, cells)
    out = np.empty((*xy.shape[:-1], 3))
    out[..., :2] = xy
    out[..., 2] = overlay_z_m(snapshot, layer=1)
    return out


def _cells_to_map_xy(
    snapshot: MapSnapshot, cells: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """:func:`cells_to_map_m`'s map-frame x and y ``(..., 2)``."""
    return cells_to_metres(
        np.asarray(cells, dtype=np.float64) - 0.5,  # cells_to_metres counts from cell centres
        resolution_m=float(snapshot.resolution_m),
        origin_xy_m=(float(snapshot.origin_position_m[0]), float(snapshot.origin_position_m[1])),
        origin_yaw_rad=snapshot.origin_yaw_rad,
    )


def overlay_z_m(snapshot: MapSnapshot, *, layer: int) -> float:
    """Height (map frame, metres) of the metric view's overlays of ``layer`` 1 (directions), 2
    (walls) or 3 (the break region, on top) above ``snapshot``'s grid map."""
    rows, cols = snapshot.grid.shape
    step = max(
        _MIN_OVERLAY_HEIGHT_M, _OVERLAY_HEIGHT_FRACTION * max(rows, cols) * snapshot.resolution_m
    )
    return float(snapshot.origin_position_m[2]) + layer * step


def direction_label_anchors(
    segments: npt.NDArray[np.float64],
    *,
    yaw_rad: float,
    window: tuple[float, float, float, float],
    resolution_m: float,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The direction labels' points in the segmentation and the metric view.

    The views frame the known box ``window`` ``(x0, y0, x1, y1)`` (cells, grid frame) north up
    (the grid turned by ``yaw_rad``) and room under it (:func:`segmentation_frame`,
    :func:`metric_frame`; the metric view at least :data:`METRIC_MIN_HALF_M` either side of its
    centre, ``resolution_m`` metres per cell). Rerun's labels are a fixed number of screen pixels
    in size: in cells they are taken at the most cells per pixel of the views of
    :data:`SEGMENTATION_VIEWS_PX` / :data:`METRIC_VIEWS_PX` (the smallest view: each window of
    :data:`~rose_logs.rerun.blueprint.LABEL_WINDOWS_PX`, with the events view under the maps and
    without), so that labels kept off their lines and each other there stay so in a larger view,
    and placed in what every one of those views shows (the frame, and more across or up where all
    the views are wider or taller than it) (:func:`conv.direction_label_positions`).
    A label is further from its line's end in a large window than in a small one (up to about
    twice as far at 1920 x 1080 as at 1024 x 768). (The scale came from a 1600 x 1000 window: in
    a 1024 x 768 one a label beside a flat line's end hung out of the view.)

    Returns
    -------
    tuple of ndarray of float64, shape (K, 2)
        Segmentation and metric views' points, grid-frame cells as ``segments`` (K, 2, 2).
    """
    x0, y0, x1, y1 = window
    screen = conv.screen_ends(segments, yaw_rad=yaw_rad)  # the same in both views
    # The window's corners on screen, turned as the lines' ends are (the grid frame -> screen).
    known = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]], dtype=np.float64) @ screen.turn.T
    low, high = known.min(axis=0), known.max(axis=0)  # on screen, cells
    corner_x, corner_y = low.tolist()
    width, height = (high - low).tolist()  # np.ptp's arithmetic

    def anchors_in(
        frame: tuple[float, float, float, float], views: tuple[tuple[float, float], ...]
    ) -> npt.NDArray[np.float64]:
        left, bottom, right, top = frame
        framed_w, framed_h = right - left, top - bottom
        # Plain floats, as numpy's corner + [left + right, bottom + top] / 2 (the same arithmetic).
        centre = (corner_x + (left + right) / 2, corner_y + (bottom + top) / 2)
        # Plain floats: a dozen views, each a few operations (numpy's per-call cost is more).
        scales = [max(framed_w / w, framed_h / h) for w, h in views]  # conv.view_units_per_px
        per_px = max(scales)  # cells per screen pixel in the smallest view
        # What every view shows: at least the frame, more across (or up) where the view's aspect
        # is wider (taller) than the frame's.
        edge = conv.DIRECTION_LABEL_EDGE_PX * per_px
        half_w = min(w * scale for (w, _), scale in zip(views, scales, strict=True)) / 2 - edge
        half_h = min(h * scale for (_, h), scale in zip(views, scales, strict=True)) / 2 - edge
        return conv.direction_label_positions(
            segments,
            yaw_rad=yaw_rad,
            x_range=(centre[0] - half_w, centre[0] + half_w),
            y_range=(centre[1] - half_h, centre[1] + half_h),
            label_width=conv.DIRECTION_LABEL_WIDTH_PX * per_px,
            label_height=conv.DIRECTION_LABEL_HEIGHT_PX * per_px,
            clearance=conv.DIRECTION_LABEL_CLEARANCE_PX * per_px,
            screen=screen,
        )

    return (
        anchors_in(segmentation_frame(width, height), SEGMENTATION_VIEWS_PX),
        anchors_in(
            metric_frame(width, height, min_half=METRIC_MIN_HALF_M / resolution_m), METRIC_VIEWS_PX
        ),
    )


#: The colour bar's labels' places in its pixels (it is 2 pixels high, each
#: ``conv.SCORE_BAR_HEIGHT_PX / 2`` screen pixels at the layout's smallest scale): the scale and
#: best-cell labels ``conv.SCORE_BAR_LABELS_GAP_PX`` under it, the threshold's above it, its box
#: (1 to 24 pixels under its point) 3 pixels clear of the bar, between the bar and the cells.
_BAR_PX = conv.SCORE_BAR_HEIGHT_PX / 2
_BAR_LABELS_BELOW_PX = 2.0 + conv.SCORE_BAR_LABELS_GAP_PX / _BAR_PX
_BAR_THRESHOLD_LABEL_PX = -(conv.DIRECTION_LABEL_HEIGHT_PX + 3.0) / _BAR_PX


def bar_placement(box: tuple[float, float, float, float]) -> rr.Transform3D:
    """The colour bar's placement (metres per bar pixel) under ``box`` = (west, north, east, south),
    the 2D views' north-up metres (y south), centred, :func:`conv.score_bar_width` wide (0.6 of
    the box's width, and wide enough for its end labels to stay apart), its labels clear of the
    box.

    Laid out in screen pixels at the scores view's smallest scale for that box
    (:func:`scores_units_per_px`, the scale the view's frame leaves room for), so that the labels'
    places in the bar's pixels hold whatever the box and they stay in view in every window."""
    translation, scale = _bar_terms(box)
    return rr.Transform3D(translation=translation, scale=scale)


def _bar_terms(box: tuple[float, float, float, float]) -> tuple[list[float], list[float]]:
    """:func:`bar_placement`'s translation and scale."""
    west, north, east, south = box
    width = east - west
    per_px = scores_units_per_px(width, south - north)
    bar = conv.score_bar_width(width, per_px)
    return (
        [(west + east - bar) / 2, south + conv.SCORE_BAR_TOP_PX * per_px, 0.0],
        [bar / style.DISPLAY_LEVELS, _BAR_PX * per_px, 1.0],
    )


def _bar_components(box: tuple[float, float, float, float]) -> list[rr.DescribedComponentBatch]:
    """:func:`bar_placement`'s components, without building the Transform3D (its translation and
    scale are Rerun's float32 triples, the type of :func:`arrow.points` of 3D points)."""
    translation, scale = _bar_terms(box)
    return arrow.described(
        rr.Transform3D,
        translation=arrow.points([translation], dims=3),
        scale=arrow.points([scale], dims=3),
    )


class TopicLogger:
    """Loggers of one map topic's streams below ``paths``.

    Parameters
    ----------
    recording : rerun.RecordingStream
        Where to log.
    paths : EntityPaths
        Entity paths of the topic.
    failure_level, trust_level : float
        Guide lines of the W plot (the failure level is the session's ``--failure-level``).
    live : bool, default True
        The colour bar is placed under each snapshot's map (as a viewer streamed to shows it).
        False: it is placed once, under the final map, by :meth:`log_final_placement` (a saved
        recording, whose scores view frames the final map).
    display_max_px : int, default ``style.DISPLAY_MAX_PX``
        Longest side of the segmentation and cell-score images: a larger map is shown pooled
        (:func:`conv.display_factor`); the metric view's grid stays at full resolution.
    scores_max_px : int, default ``style.SCORES_DISPLAY_MAX_PX``
        Longest side of the cell-score image (at most ``display_max_px``): its view is smaller.
    """

    def __init__(
        self,
        recording: rr.RecordingStream,
        paths: EntityPaths,
        *,
        failure_level: float = FAILURE_LEVEL,
        trust_level: float = TRUST_LEVEL,
        live: bool = True,
        display_max_px: int = style.DISPLAY_MAX_PX,
        scores_max_px: int = style.SCORES_DISPLAY_MAX_PX,
    ) -> None:
        self.recording = recording
        self.live = live
        self.display_max_px = display_max_px
        self.scores_max_px = min(scores_max_px, display_max_px)
        self.paths = paths
        self.failure_level = float(failure_level)
        self.trust_level = float(trust_level)
        self.view_origin_m: tuple[float, float] | None = None  # set by the first snapshot
        self._threshold_logged = False
        # The metric view's direction labels of the latest snapshot (None: no directions), and
        # whether the break region's label has them hidden (log_break_score).
        self._metric_labels: list[str] | None = None
        self._metric_labels_hidden = False
        # Of the last snapshot (``live``), else of the session's end (log_final_placement).
        self.score_legend_placement: list[rr.DescribedComponentBatch] | None = None
        # The spectrum image's pooling of the latest spectrum shape (a session's keep theirs).
        self._spectrum_pooling: conv.SpectrumPooling | None = None

    def _image_placement(
        self, snapshot: MapSnapshot, window: conv.Window | None = None, factor: int = 1
    ) -> list[rr.DescribedComponentBatch]:
        """Rerun's transform of ``snapshot``'s images of ``window`` in this topic's views, pooled
        ``factor`` times (:func:`placement_terms`)."""
        return _placement(*placement_terms(snapshot, self._origin_for(snapshot), window, factor))

    def _pooled_placement(
        self, snapshot: MapSnapshot, window: conv.Window, factor: int
    ) -> list[rr.DescribedComponentBatch]:
        """The transform of ``window``'s images pooled ``factor`` times (:func:`conv.pool_classes`)."""
        return self._image_placement(snapshot, conv.pooled_window(window, factor), factor)

    def _origin_for(self, snapshot: MapSnapshot) -> tuple[float, float]:
        """The views' 0 in the map frame, the 2D views' and the metric view's (:func:`view_origin_m`
        of the topic's first snapshot)."""
        if self.view_origin_m is None:
            self.view_origin_m = view_origin_m(snapshot)
        return self.view_origin_m

    # ------------------------------------------------------------------------------------------
    # Static data: sent once per recording (the web viewer drops a class table sent again)
    # ------------------------------------------------------------------------------------------

    def log_static(self) -> None:
        """Segmentation classes, axes, series styles and the amplitude plot's axes, once."""
        rec, paths = self.recording, self.paths
        rec.log(
            paths.cells,
            rr.AnnotationContext(
                [
                    rr.AnnotationInfo(id=class_id, label=label, color=color)
                    for class_id, label, color in style.CLASS_INFO
                ]
            ),
            static=True,
        )
        rec.log(paths.metric, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        rec.log(
            paths.scores_view,
            rr.AnnotationContext(
                [
                    rr.AnnotationInfo(id=class_id, label=label, color=color)
                    for class_id, label, color in conv.score_classes()
                ]
            ),
            static=True,
        )
        series_colors = [style.W_COLOR, style.TRUST_COLOR, style.FAILURE_COLOR]
        series_names = [
            "W",
            f"trust level {self.trust_level:g}",
            f"failure level {self.failure_level:g}",
        ]
        rec.log(
            paths.w,
            rr.SeriesLines(
                colors=series_colors,
                names=series_names,
                widths=[2.5, style.GUIDE_LINE_WIDTH, style.GUIDE_LINE_WIDTH],
            ),
            # A point on each line too: a W between two gaps (maps not judged) or a session of one
            # snapshot has no line to draw, and its plot was empty.
            rr.SeriesPoints(
                colors=series_colors,
                names=series_names,
                markers=["Circle"] * 3,
                marker_sizes=[2.5, style.GUIDE_LINE_WIDTH / 2, style.GUIDE_LINE_WIDTH / 2],
            ),
            static=True,
        )
        # Markers on the W plot: the detector's breaks and W's rises above the failure level, each
        # a shape of its own (three identical crosses could not be told apart).
        for entity, name, marker, size in (
            (paths.breaks, "break", rr.components.MarkerShape.Cross, 10.0),
            (paths.failures, "W above the failure level", rr.components.MarkerShape.Up, 8.0),
        ):
            rec.log(
                entity,
                rr.SeriesPoints(
                    colors=style.FAILURE_COLOR, names=name, markers=marker, marker_sizes=size
                ),
                static=True,
            )
        rec.log(
            paths.break_score,
            rr.SeriesLines(colors=style.BREAK_SCORE_COLOR, names="break score (m)", widths=2.5),
            rr.SeriesPoints(  # as W's: a single value is drawn too
                colors=style.BREAK_SCORE_COLOR, names="break score (m)", marker_sizes=2.5
            ),
            static=True,
        )
        rec.log(
            paths.break_threshold,
            rr.SeriesLines(
                colors=style.FAILURE_COLOR,
                names="break threshold (m)",
                widths=style.GUIDE_LINE_WIDTH,
            ),
            static=True,
        )
        self._log_amplitude_axes()
        self._log_styles()

    def _log_styles(self) -> None:
        """What every snapshot would send unchanged (colours, sizes, label switches, colour maps),
        as static components: each snapshot then sends only what changes. Rerun's Python archetypes
        cost about 4x more to build with these fields than without (~180 against ~45 us each)."""
        rec, paths = self.recording, self.paths
        line = rr.Radius.ui_points(1.5)
        # The directions' labels without a dot: their points lie off the lines, under or beside
        # an end (conv.direction_label_positions), where a dot marked nothing of the line.
        point = 0.0
        direction = style.DIRECTION_COLOR
        static: list[tuple[str, list[rr.AsComponents]]] = [
            (paths.grid, [rr.GridMap.from_fields(colormap=rr.components.Colormap.RvizMap)]),
            (
                paths.cell_directions,
                [
                    rr.LineStrips2D.from_fields(colors=direction, radii=line),
                    rr.Points2D.from_fields(colors=direction, radii=point, show_labels=True),
                ],
            ),
            (
                paths.metric_directions,
                [
                    rr.LineStrips3D.from_fields(colors=direction, radii=line),
                    rr.Points3D.from_fields(colors=direction, radii=point, show_labels=True),
                ],
            ),
            (paths.cell_scores, [rr.SegmentationImage.from_fields(opacity=1.0)]),
            (
                paths.score_bar,
                [
                    # The colour bar (levels x 2 pixels; its placement follows the map).
                    rr.SegmentationImage(
                        np.repeat(
                            np.arange(1, style.DISPLAY_LEVELS + 1, dtype=np.uint8)[np.newaxis],
                            2,
                            axis=0,
                        ),
                        opacity=1.0,
                    ),
                    rr.Points2D.from_fields(colors=style.AXIS_COLOR, radii=0.0, show_labels=True),
                    rr.LineStrips2D.from_fields(
                        colors=style.AXIS_COLOR, radii=rr.Radius.ui_points(1.5)
                    ),
                ],
            ),
            (
                paths.spectrum,
                [
                    rr.DepthImage.from_fields(
                        meter=1.0,
                        colormap=style.SPECTRUM_COLORMAP_NAME,
                        depth_range=(1.0, 255.0),
                    ),
                    rr.LineStrips2D.from_fields(colors=(*direction, 150)),
                ],
            ),
            (
                paths.amplitude_curve,
                [rr.Points2D.from_fields(colors=style.PEAK_COLOR, radii=rr.Radius.ui_points(4.0))],
            ),
            (
                paths.amplitude_peak_labels,
                [rr.Points2D.from_fields(colors=style.PEAK_COLOR, radii=0.0, show_labels=True)],
            ),
        ]
        for entity, archetypes in static:
            rec.log(entity, *archetypes, static=True)

    def _log_amplitude_axes(self) -> None:
        """The amplitude plot's axes, ticks and labels (static), laid out in pixels for every
        window (:data:`AMPLITUDE_FRAME`)."""
        rec, paths, frame = self.recording, self.paths, AMPLITUDE_FRAME
        h, tick = style.AMPLITUDE_PLOT_HEIGHT, frame.tick
        ticks = [[(x, 0.0), (x, tick)] for x in X_TICKS_DEG]
        ticks += [[(0.0, -h * s), (-tick, -h * s)] for s in S_TICKS]
        ticks += [[(0.0, 0.0), (180.0, 0.0)], [(0.0, 0.0), (0.0, -h * 1.05)]]
        rec.log(
            paths.amplitude_axes,
            rr.LineStrips2D(ticks, colors=style.AXIS_COLOR, radii=rr.Radius.ui_points(1.0)),
            static=True,
        )
        rec.log(
            paths.amplitude_axis_labels,
            rr.Points2D(
                list(frame.label_positions),
                labels=list(frame.labels),
                colors=style.AXIS_COLOR,
                radii=0.0,
            ),
            static=True,
        )

    # ------------------------------------------------------------------------------------------
    # Per snapshot
    # ------------------------------------------------------------------------------------------

    def log_snapshot(
        self,
        snapshot: MapSnapshot,
        result: RoseResult,
        walls: WallSet | None,
        cleaning: CleanResult | None = None,
        *,
        window: conv.Window | None = None,
        judged: bool | None = None,
    ) -> None:
        """Every stream of one analysed snapshot, at the time set by :func:`set_snapshot_time`.

        ``cleaning``: the snapshot's cleaning, shown in the segmentation (:meth:`log_segmentation`);
        ``window``: the snapshot's :func:`~conv.image_window`, when the caller has it; ``judged``:
        whether W says something about it (:meth:`log_structure_score`).
        """
        if result.cell_scores.shape != snapshot.grid.shape:
            msg = (
                f"result shape {result.cell_scores.shape} does not match snapshot grid shape "
                f"{snapshot.grid.shape} (topic {snapshot.topic}, log time {snapshot.log_time_ns} ns)"
            )
            raise ValueError(msg)
        window = window or conv.image_window(snapshot.grid)
        occupied = conv.occupied_cells(result, window)
        self.log_grid_map(snapshot, window)
        self.log_segmentation(snapshot, result, occupied, cleaning=cleaning)
        self.log_directions(snapshot, result, occupied)
        self.log_cell_scores(snapshot, result, occupied)
        self.log_spectrum(result)
        self.log_amplitude(result, yaw_rad=snapshot.origin_yaw_rad)
        if judged is None:  # the occupied cells are counted already (a pass over the mask less)
            judged = w_judges(occupied.grid_index.size)
        self.log_structure_score(result, judged=judged)
        if walls is not None:
            self.log_walls(snapshot, walls)

    def log_grid_map(self, snapshot: MapSnapshot, window: conv.Window | None = None) -> None:
        """The occupancy grid's ``window`` (default :func:`~conv.image_window`: its known cells) as
        a GridMap in the metric view's metres (the map frame's from the view origin,
        :func:`metric_m`), RViz map colours.

        The int8 cells go as their uint8 bit pattern (-1 unknown -> 255), the convention of
        :attr:`rerun.components.Colormap.RvizMap`; the image's lower-left corner is the window's.
        """
        x0, y0, x1, y1 = window or conv.image_window(snapshot.grid)
        # Image row order, a copy of its own (Rerun reads it later, see arrow.image_buffer).
        image = snapshot.grid[y0:y1, x0:x1].view(np.uint8)[::-1].copy()
        # Flat, turned by the origin's yaw: where the session takes a grid to lie (a tilted origin
        # is warned about), and where the overlays (cells_to_map_m) are drawn.
        # metric_m's x and y of the corner (its last steps in plain floats: the same arithmetic).
        rx, ry = self._origin_for(snapshot)
        cx, cy = _cells_to_map_xy(snapshot, np.array([[x0, y0]], dtype=np.float64))[0].tolist()
        self.recording.log(
            self.paths.grid,
            arrow.described(
                rr.GridMap,
                data=arrow.image_buffer(image),
                format=arrow.u8_format(image, color_model="L"),
            ),
            _grid_placement(
                float(snapshot.resolution_m),
                (cx - rx, cy - ry, float(snapshot.origin_position_m[2])),
                float(snapshot.origin_yaw_rad),
            ),
        )

    def log_segmentation(
        self,
        snapshot: MapSnapshot,
        result: RoseResult,
        occupied: conv.OccupiedCells | None = None,
        *,
        cleaning: CleanResult | None = None,
    ) -> None:
        """Free / unknown / occupied / structure / clutter as a segmentation image (the class
        table is static); with ``cleaning``, what it changed: clutter it kept as walls, structure
        it removed (shown as clutter), walls it drew behind removed clutter."""
        occupied = occupied or conv.occupied_cells(result, conv.image_window(snapshot.grid))
        changes = {}
        if cleaning is not None:
            changes = {
                "rescued": cleaning.rescued,
                "removed": cleaning.removed,
                "completed": cleaning.completed,
            }
        image = conv.segmentation_image(snapshot.grid, result, occupied, **changes)
        factor = conv.display_factor(occupied.window, self.display_max_px)
        self.recording.log(
            self.paths.segmentation,
            segmentation_image(conv.pool_classes(image, factor)),
            self._pooled_placement(snapshot, occupied.window, factor),
        )

    def log_directions(
        self,
        snapshot: MapSnapshot,
        result: RoseResult,
        occupied: conv.OccupiedCells | None = None,
    ) -> None:
        """Dominant directions across the mapped area (the occupied cells' box), over the
        segmentation and in metres.

        Each direction is labelled once, under its line's lower end on screen (all lines cross at
        the centre), clear of the lines and of the other labels and in view in each view, in any
        window from 1024 x 768 to 1920 x 1080; the views' scale is worked out from the snapshot's
        known box (the views frame the session's: the same for the last map of a growing one)
        (:func:`direction_label_anchors`).
        """
        rec, paths = self.recording, self.paths
        directions = np.asarray(result.dominant_directions, dtype=np.float64)
        if directions.size == 0:
            rec.log(paths.cell_directions, _CLEAR)
            rec.log(paths.metric_directions, _CLEAR)
            self._metric_labels, self._metric_labels_hidden = None, False
            return
        rows, cols = snapshot.grid.shape
        occupied = occupied or conv.occupied_cells(result)
        bounds = occupied.bounds
        segments = conv.direction_segments_cells(directions, (rows, cols), bounds=bounds)
        # Both views show the map frame (placement_terms): a map whose origin has a yaw shows its
        # walls that much further round than the grid does (as the JSON report gives them).
        yaw = snapshot.origin_yaw_rad
        anchors, metric_anchors = direction_label_anchors(
            segments, yaw_rad=yaw, window=occupied.window, resolution_m=snapshot.resolution_m
        )
        map_labels = [f"walls {d:.1f}°" for d in map_frame_deg(directions, yaw_rad=yaw, digits=1)]
        # Colours, sizes and the label switch are static (log_static).
        labels = arrow.texts(map_labels)
        rec.log(
            paths.cell_directions,
            arrow.described(
                rr.LineStrips2D, strips=arrow.strips(conv.cells_to_pixels(segments, rows))
            ),
            arrow.described(
                rr.Points2D,
                positions=arrow.points(conv.cells_to_pixels(anchors, rows)),
                labels=labels,
            ),
            self._image_placement(snapshot),
        )
        # The lines' ends and the labels' points in one conversion (its fixed cost paid once).
        count = len(segments)
        metric = metric_m(
            snapshot,
            np.concatenate([segments.reshape(-1, 2), metric_anchors]),
            self._origin_for(snapshot),
        )
        rec.log(
            paths.metric_directions,
            arrow.described(
                rr.LineStrips3D, strips=arrow.strips(metric[: 2 * count].reshape(count, 2, 3))
            ),
            arrow.described(
                rr.Points3D, positions=arrow.points(metric[2 * count :]), labels=labels
            ),
        )
        self._metric_labels, self._metric_labels_hidden = map_labels, False

    def log_walls(self, snapshot: MapSnapshot, walls: WallSet) -> None:
        """Wall segments over the segmentation (pixels) and in the metric view (metres from the
        view origin).

        ``walls`` must come from this snapshot's grid placed with its resolution and origin. No walls:
        both entities are cleared.
        """
        rec, paths = self.recording, self.paths
        if len(walls) == 0:
            rec.log(paths.metric_walls, _CLEAR)
            rec.log(paths.cell_walls, _CLEAR)
            return
        ends_m = map_to_metric_m(walls.endpoints_m, self._origin_for(snapshot))
        height_m = overlay_z_m(snapshot, layer=2)
        metric = np.concatenate([ends_m, np.full((*ends_m.shape[:2], 1), height_m)], axis=-1)
        radius = rr.Radius.ui_points(1.0)
        rec.log(
            paths.metric_walls,
            rr.LineStrips3D.from_fields(
                strips=arrow.strips(metric), colors=style.WALL_COLOR, radii=radius
            ),
        )
        centres = walls.endpoints_px + 0.5  # cell centres
        pixels = conv.cells_to_pixels(centres, snapshot.grid.shape[0])
        rec.log(
            paths.cell_walls,
            rr.LineStrips2D.from_fields(
                strips=arrow.strips(pixels), colors=style.WALL_COLOR, radii=radius
            ),
            self._image_placement(snapshot),
        )

    def log_cell_scores(
        self,
        snapshot: MapSnapshot,
        result: RoseResult,
        occupied: conv.OccupiedCells | None = None,
    ) -> None:
        """Occupied cells' scores, colour-mapped (other cells transparent; pooled beyond
        ``scores_max_px``, each pixel the lowest score of its block), the labels (scale,
        threshold) of the colour bar and, ``live``, its placement under the occupied cells."""
        rec, paths = self.recording, self.paths
        occupied = occupied or conv.occupied_cells(result, conv.image_window(snapshot.grid))
        factor = conv.display_factor(occupied.window, self.scores_max_px)
        rec.log(
            paths.cell_scores,
            segmentation_image(conv.pooled_score_image(result, occupied, factor)),
            self._pooled_placement(snapshot, occupied.window, factor),
        )
        if self.live:
            self.score_legend_placement = self._bar_under(snapshot, occupied)
            rec.log(paths.score_legend, self.score_legend_placement)
        threshold = float(result.threshold)
        rec.log(paths.score_bar, _score_bar(threshold if math.isfinite(threshold) else None))

    def _bar_under(
        self, snapshot: MapSnapshot, occupied: conv.OccupiedCells
    ) -> list[rr.DescribedComponentBatch]:
        """The colour bar's placement under the occupied cells' box (a SLAM map's grid is mostly
        unknown), north up in the view's metres whatever the origin's yaw."""
        rows, cols = snapshot.grid.shape
        x0, y0, x1, y1 = occupied.bounds or (0, 0, cols, rows)
        # north_up_m's corners, its last steps in plain floats (four points: numpy's calls cost
        # more than the arithmetic, which is the same).
        rx, ry = self._origin_for(snapshot)
        corners = _cells_to_map_xy(
            snapshot, np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]], float)
        ).tolist()
        xs, ys = [x - rx for x, _ in corners], [ry - y for _, y in corners]
        return _bar_components((min(xs), min(ys), max(xs), max(ys)))

    def log_final_placement(self, bounds_m: tuple[float, float, float, float] | None) -> None:
        """Place the colour bar under the session's known box ``bounds_m`` (map frame, metres: the
        box the scores view frames), at every time. Under the last map, a map that shrank, moved
        or changed its cell size had a bar too small for its labels, which covered it."""
        # Only where no placement was logged per snapshot (not ``live``): the web viewer kept
        # those over a static one logged after them.
        if bounds_m is None or self.view_origin_m is None:
            return
        x0, y0, x1, y1 = bounds_m
        rx, ry = self.view_origin_m
        self.score_legend_placement = _bar_components((x0 - rx, ry - y1, x1 - rx, ry - y0))
        self.recording.log(self.paths.score_legend, self.score_legend_placement, static=True)

    def log_spectrum(self, result: RoseResult) -> None:
        """The log amplitude spectrum (display resolution) with the kept strip of every direction."""
        size = style.SPECTRUM_DISPLAY_PX
        shape, half_cols = tuple(result.padded_shape), result.spectrum_half.shape[1]
        pooling = self._spectrum_pooling
        if pooling is None or (pooling.padded_shape, pooling.half_cols) != (shape, half_cols):
            pooling = conv.spectrum_pooling(result.padded_shape, half_cols, size=size)
            self._spectrum_pooling = pooling
        image = conv.display_spectrum(
            result.spectrum_half, result.padded_shape, size=size, pooling=pooling
        )
        directions = np.asarray(result.dominant_directions, dtype=np.float64)
        half_width = result.params.mask_half_width_px * size / max(result.padded_shape)
        self.recording.log(
            self.paths.spectrum,
            arrow.described(
                rr.DepthImage, buffer=arrow.image_buffer(image), format=arrow.u8_format(image)
            ),
            # The strips' width is the kept half-width at display scale (at least a line).
            arrow.described(
                rr.LineStrips2D,
                strips=arrow.strips(conv.spectrum_strip_segments(directions, size=size)),
                radii=arrow.radii(max(half_width, 0.75)),
            ),
        )

    def log_amplitude(self, result: RoseResult, *, yaw_rad: float = 0.0) -> None:
        """The scaled cumulative amplitude ``s`` per map-frame direction (ROSE's grid-frame
        directions turned by the origin's ``yaw_rad``), its peaks and prominences.

        One entity: the curve and a vertical bar per peak (its prominence, down from the peak to
        its base) as line strips, the labelled peaks as points; grey bars for the peaks that rise
        above ``s = t`` but are not kept. The prominence threshold ``t`` is a tick on each bar at
        its base + ``t``, which a kept peak's bar passes (:func:`conv.threshold_ticks`): a line
        at ``s = t`` showed a bump on a high base crossing it as if it were dominant. Its style is
        static (a parameter of the session).
        """
        rec, paths = self.recording, self.paths
        plot = conv.amplitude_plot(result, yaw_rad=yaw_rad, label_boxes=PEAK_LABEL_BOXES)
        if not self._threshold_logged:
            # The ticks' style is static (a parameter of the session); they are logged with each
            # snapshot, on its peaks' bars.
            rec.log(
                paths.amplitude_threshold,
                rr.LineStrips2D.from_fields(
                    colors=style.THRESHOLD_COLOR,
                    radii=rr.Radius.ui_points(1.0),
                    show_labels=True,
                ),
                static=True,
            )
            self._threshold_logged = True
        rec.log(
            paths.amplitude_threshold,
            _amplitude_threshold(plot.threshold_strips, plot.threshold),
        )
        colors, radii = _curve_style(len(plot.peak_labels), len(plot.rejected_bars))
        rec.log(
            paths.amplitude_curve,
            arrow.described(
                rr.LineStrips2D,
                strips=arrow.strips([plot.curve, *plot.prominence_bars, *plot.rejected_bars]),
                colors=colors,
                radii=radii,
            ),
            arrow.described(rr.Points2D, positions=arrow.points(plot.peaks)),
        )
        rec.log(
            paths.amplitude_peak_labels,
            arrow.described(
                rr.Points2D,
                positions=arrow.points(plot.label_anchors),
                labels=arrow.texts(plot.peak_labels),
            ),
        )

    def log_structure_score(self, result: RoseResult, *, judged: bool | None = None) -> None:
        """W and the trust / failure guide lines (three series of one entity, one log call).

        A map without occupied cells has W = 1 by convention, which says nothing about it: its W is
        left out of the plot (NaN, a gap), as out of the report's statistics; so is the W of any
        snapshot not ``judged`` (default: :func:`w_judges` of its occupied cells)."""
        if judged is None:
            judged = w_judges(result.occupied_count)
        w = float(result.structure_score) if judged else math.nan
        self.recording.log(
            self.paths.w,
            arrow.described(
                rr.Scalars, scalars=arrow.floats([w, self.trust_level, self.failure_level])
            ),
        )

    def log_break_score(
        self, snapshot: MapSnapshot, verdict: BreakScore, threshold_m: float
    ) -> None:
        """The break detector's score and threshold, and its region while the snapshot is broken
        (a rectangle in the metric view's metres, from the view origin, just above the grid map;
        cleared otherwise). While the region is drawn, the metric view's direction labels are
        hidden (:meth:`_show_metric_labels`)."""
        rec, paths = self.recording, self.paths
        rec.log(
            paths.break_score,
            arrow.described(rr.Scalars, scalars=arrow.floats(float(verdict.score_m))),
        )
        rec.log(paths.break_threshold, _scalar(float(threshold_m)))
        region = verdict.region_m if verdict.broken else None
        self._show_metric_labels(region is None)
        if region is None:
            rec.log(paths.break_region, _CLEAR_RECURSIVE)  # its label too
            return
        x0, y0, x1, y1 = region
        z = overlay_z_m(snapshot, layer=3)
        corners = map_to_metric_m(
            np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z], [x0, y0, z]]),
            self._origin_for(snapshot),
        )
        rec.log(
            paths.break_region,
            arrow.described(
                rr.LineStrips3D,
                strips=arrow.strips(corners[np.newaxis]),
                radii=_BREAK_RADIUS,
                colors=_BREAK_COLOR,
            ),
        )
        # On the middle of the region's south edge: Rerun centres a label below its point, so it
        # hangs under the region (on the strip's middle it covered a region of a metre or two).
        rec.log(
            paths.break_label,
            arrow.described(
                rr.Points3D,
                positions=arrow.points((corners[0:1] + corners[1:2]) / 2),
                radii=_BREAK_RADIUS,
                colors=_BREAK_COLOR,
                # As the event and the summary say it (1.25 m read "1.3 m" beside them).
                labels=arrow.texts([f"break: {verdict.score_m:.2f} m of map contradicted"]),
            ),
        )

    def _show_metric_labels(self, show: bool) -> None:
        """Show or hide the metric view's direction labels (their lines stay). The break region's
        label is wide (half the view on a 50 m map) and hangs under the region, where it covered a
        direction's label, or the direction's label covered it ("walls 168 break: 22.00 m ..."):
        while the region is drawn, the segmentation view above names the directions alone."""
        if self._metric_labels is None or show != self._metric_labels_hidden:
            return
        labels = self._metric_labels if show else []
        self.recording.log(
            self.paths.metric_directions, arrow.described(rr.Points3D, labels=arrow.texts(labels))
        )
        self._metric_labels_hidden = not show

    def log_break(self, score: float | None, text: str, *, failure: bool = False) -> None:
        """A break: a marker on the W plot at ``score`` (None: none, W is not plotted there; a
        cross for the detector's break, a triangle for W rising above the failure level with
        ``failure``) and a WARN event (time set by the caller)."""
        if score is not None:
            where = self.paths.failures if failure else self.paths.breaks
            self.recording.log(where, rr.Scalars(float(score)))
        self.recording.log(self.paths.events, rr.TextLog(text, level=rr.TextLogLevel.WARN))
