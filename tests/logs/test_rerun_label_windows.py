"""The colour bar's and the amplitude plot's labels in every window of the default layout.

Rerun draws a label a fixed number of screen pixels in size, centred across its point and from
1 to 24 pixels under it; a view fits its visual bounds keeping their aspect, centred. These tests
put the labels' boxes in the views' pixels in every window the layout is made for
(1024 x 768 to 1920 x 1080, with and without the events view) and check that they are whole,
in view and apart.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt
import pytest
import rerun.blueprint as rrb

import rose
from rose_logs.rerun import blueprint, loggers, style
from rose_logs.rerun import conversions as conv

#: Windows (CSS pixels) and a label's box (pixels): "100.0° p 0.67" is 85 wide, "score ≤ -0.5"
#: 80, each box 22-23 high from 1 pixel under its point (Rerun 0.41, web viewer).
WINDOWS = ((1024.0, 768.0), (1280.0, 720.0), (1366.0, 768.0), (1920.0, 1080.0))
LABEL_W, LABEL_TOP, LABEL_BOTTOM = 90.0, 1.0, 24.0


def _view(container: rrb.Container | rrb.View, name: str) -> rrb.View:
    """The view called ``name`` (its start) in the layout ``container``."""
    if isinstance(container, rrb.View):
        if container.name is not None and str(container.name).startswith(name):
            return container
        raise LookupError(name)
    for child in container.contents:
        try:
            return _view(child, name)  # type: ignore[arg-type]
        except LookupError:
            continue
    raise LookupError(name)


def _bounds(view: rrb.View) -> tuple[tuple[float, float], tuple[float, float]]:
    """``(x_range, y_range)`` of a 2D view's visual bounds."""
    ((ranges),) = view.properties["VisualBounds2D"].range.pa_array.to_pylist()
    return tuple(ranges["x_range"]), tuple(ranges["y_range"])


def _to_px(
    bounds: tuple[tuple[float, float], tuple[float, float]], view_px: tuple[float, float]
) -> tuple[float, float, float]:
    """``(scale, x0, y0)``: pixel = (unit - x0 or y0) * scale, as Rerun fits ``bounds`` in a view
    of ``view_px`` keeping their aspect, centred."""
    (xa, xb), (ya, yb) = bounds
    scale = min(view_px[0] / (xb - xa), view_px[1] / (yb - ya))
    return scale, (xa + xb) / 2 - view_px[0] / 2 / scale, (ya + yb) / 2 - view_px[1] / 2 / scale


def _box(anchor_px: tuple[float, float]) -> tuple[float, float, float, float]:
    """A label's box (left, top, right, bottom, pixels) under its point."""
    x, y = anchor_px
    return x - LABEL_W / 2, y + LABEL_TOP, x + LABEL_W / 2, y + LABEL_BOTTOM


def _inside(box: tuple[float, float, float, float], view_px: tuple[float, float]) -> bool:
    left, top, right, bottom = box
    return left >= 0 and top >= 0 and right <= view_px[0] and bottom <= view_px[1]


def _apart(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> bool:
    """Boxes apart or touching (to a millionth of a pixel: labels laid out a width apart)."""
    tol = 1e-6
    return a[2] <= b[0] + tol or b[2] <= a[0] + tol or a[3] <= b[1] + tol or b[3] <= a[1] + tol


def _scores_view_px(window: tuple[float, float], events: bool) -> tuple[float, float]:
    """The scores view's pixels, measured (the metric view's twin: docs/cleaning.md, the table of
    the labels with an events view), 1 to 2 less."""
    w, h = window
    return 0.3 * w - 4.0, (h / 3.0 - 53.0) if events else (0.4 * h - 57.0)


@pytest.mark.parametrize("aspect", [8.0, 2.4, 1.0, 0.42, 0.1])
@pytest.mark.parametrize("events", [False, True])
def test_the_colour_bars_labels_are_whole_and_apart_in_every_window(
    aspect: float, events: bool
) -> None:
    """The sample map turned upright (0.42) at 1280 x 720 and 1024 x 768 with the events view had
    the scale's labels ("score ≤ -0.5", "1 (best cell)") cut at the scores view's lower edge (they
    were placed in fractions of the map's height, the view's room too, and a label is a fixed
    number of pixels); a tall map's end labels touched. In every window, with and without the
    events view, at any aspect: each label inside the view, the end labels apart, the threshold's
    label between the cells and the bar."""
    height = 40.0
    box = (0.0, 0.0, height / aspect, height)  # map frame, metres: x east, y north
    layout = blueprint.TopicLayout("map", bounds_m=box, has_events=events)
    scores = _view(blueprint._topic_container(layout), "scores of occupied cells")
    bounds = _bounds(scores)
    west, north, east, south = box[0], -box[3], box[2], -box[1]  # the views' y points south
    placement = loggers.bar_placement((west, north, east, south))
    ((left, top, _),) = placement.translation.pa_array.to_pylist()
    ((scale_x, scale_y, _),) = placement.scale.pa_array.to_pylist()
    right = left + scale_x * style.DISPLAY_LEVELS
    for window in WINDOWS:
        view_px = _scores_view_px(window, events)
        scale, x0, y0 = _to_px(bounds, view_px)

        def px(x: float, y: float, scale: float = scale, x0: float = x0, y0: float = y0):
            return (x - x0) * scale, (y - y0) * scale

        below = top + loggers._BAR_LABELS_BELOW_PX * scale_y
        low, best = _box(px(left, below)), _box(px(right, below))
        thresholds = [
            _box(px(x, top + loggers._BAR_THRESHOLD_LABEL_PX * scale_y))
            for x in (left, (left + right) / 2, right)
        ]
        where = f"{window} events={events}"
        for label in (low, best, *thresholds):
            assert _inside(label, view_px), (where, label, view_px)
        assert _apart(low, best), where
        _, bar_top_px = px(left, top)
        _, cells_px = px(left, south)
        for label in thresholds:
            assert cells_px <= label[1] and label[3] <= bar_top_px, where


def _amplitude_view_px(window: tuple[float, float]) -> tuple[float, float]:
    """The amplitude view's pixels (409 x 140 measured at 1024 x 768: the right column's third
    row of 2.5 / 1.8 / 2.3 / 3.0, less a 28-pixel title), 2 less. The same with the events view,
    which is in the left column."""
    w, h = window
    return 0.4 * w - 4.0, 2.3 / 9.6 * (h - 67.0) - 30.0


def _result_with_peaks(peaks: list[tuple[float, float]]) -> rose.RoseResult:
    """A result whose cumulative amplitude peaks at ``(degrees, s)`` (s in [0, 1], one at 1)."""
    grid = np.zeros((60, 80), np.int8)
    grid[[0, -1], :] = 100
    grid[:, [0, -1]] = 100
    result = rose.analyze(grid)
    bins = np.asarray(result.direction_bins, dtype=np.float64)
    degrees = np.degrees(bins)
    amplitude = np.zeros_like(bins)
    index = []
    for deg, s in peaks:
        i = int(np.argmin(np.abs(degrees - deg)))
        amplitude[i] = s
        index.append(i)
    return dataclasses.replace(
        result,
        cumulative_amplitude=amplitude,
        peak_indices=np.array(index),
        dominant_directions=bins[index],
        peak_prominences=np.array([s for _, s in peaks]),
    )


#: The windows the amplitude view's labels are checked in: the layout's six and 1280 x 800.
AMPLITUDE_WINDOWS = (*blueprint.LABEL_WINDOWS_PX, (1280.0, 800.0))


def _text_px(text: str) -> float:
    """A label's box width (pixels), measured boxes rounded up: 14 of padding, 3.8 a narrow
    character, 10.5 an m or w, 7.3 any other ("0.5" measured 30, "135°" 39, "t = 0.5" 50,
    "wall direction, map frame (deg)" 195)."""
    narrow, wide = set(" .,:;()ilrtfj"), set("mw")
    return 14.0 + sum(3.8 if c in narrow else 10.5 if c in wide else 7.3 for c in text)


def _text_box(anchor_px: tuple[float, float], text: str) -> tuple[float, float, float, float]:
    """``text``'s box (left, top, right, bottom, pixels) under its point."""
    x, y = anchor_px
    half = _text_px(text) / 2
    return x - half, y + LABEL_TOP, x + half, y + LABEL_BOTTOM


class _Recording:
    """Stands in for a Rerun recording: keeps what is logged."""

    def __init__(self) -> None:
        self.logged: list[tuple[str, tuple[object, ...]]] = []

    def log(self, entity: str, *archetypes: object, static: bool = False) -> None:
        self.logged.append((entity, archetypes))


def _axis_labels() -> list[tuple[float, float, str]]:
    """The amplitude plot's axis labels as the logger logs them: ``(x, y, text)``, plot units."""
    recording = _Recording()
    paths = loggers.EntityPaths("map")
    logger = loggers.TopicLogger(recording, paths)  # type: ignore[arg-type]
    logger._log_amplitude_axes()
    ((points,),) = [a for entity, a in recording.logged if entity == paths.amplitude_axis_labels]
    positions = points.positions.pa_array.to_pylist()
    texts = points.labels.pa_array.to_pylist()
    return [(x, y, text) for (x, y), text in zip(positions, texts, strict=True)]


def _amplitude_bounds(events: bool) -> tuple[tuple[float, float], tuple[float, float]]:
    layout = blueprint.TopicLayout("map", bounds_m=(0.0, 0.0, 10.0, 10.0), has_events=events)
    return _bounds(_view(blueprint._topic_container(layout), "cumulative amplitude"))


@pytest.mark.parametrize("events", [False, True])
def test_the_amplitude_axis_labels_are_whole_and_apart_in_every_window(events: bool) -> None:
    """In a frame fitted by its height (2:1, the view 3 to 4 times wider than high) the axis
    labels overlapped below 1600 x 1000: "0" on "0°", "s" on "1", "135°" on "180°" and the
    degrees on the axis's title. In every window, with and without the events view: each inside
    the view and apart from the others."""
    bounds = _amplitude_bounds(events)
    labels = _axis_labels()
    for window in AMPLITUDE_WINDOWS:
        view_px = _amplitude_view_px(window)
        scale, x0, y0 = _to_px(bounds, view_px)
        boxes = [_text_box(((x - x0) * scale, (y - y0) * scale), t) for x, y, t in labels]
        for k, box in enumerate(boxes):
            assert _inside(box, view_px), (window, labels[k][2], box, view_px)
            for j in range(k + 1, len(boxes)):
                assert _apart(box, boxes[j]), (window, labels[k][2], labels[j][2])


@pytest.mark.parametrize("events", [False, True])
@pytest.mark.parametrize(
    "peaks",
    [
        [(3.0, 1.0), (93.0, 0.8)],  # a building square to the map: the first bar at the s axis
        [(15.0, 1.0), (105.0, 0.6)],
        [(30.0, 1.0)],
        [(86.3, 0.97), (176.2, 1.0)],  # the sample session
        [(176.2, 1.0), (86.3, 0.97)],
        [(178.0, 1.0), (2.0, 0.9)],
        [(90.0, 1.0), (95.0, 0.9)],
        [],  # a flat curve: the threshold is a line at s = t
    ],
)
def test_the_threshold_label_is_off_the_axis_labels_in_every_window(
    peaks: list[tuple[float, float]], events: bool
) -> None:
    """The label "t = 0.5" stood centred 28 degrees beside the first bar, whatever the window: by a peak
    near 0 degrees it lay over the s axis's "0.5" below 1600 x 1000. In every window, with and
    without the events view: inside the view and apart from every axis label."""
    plot = conv.amplitude_plot(_result_with_peaks(peaks))
    (a, level), (b, _) = plot.threshold_strips[0]  # Rerun centres a strip's label on it
    text = f"t = {plot.threshold:g}"
    bounds = _amplitude_bounds(events)
    labels = _axis_labels()
    for window in AMPLITUDE_WINDOWS:
        view_px = _amplitude_view_px(window)
        scale, x0, y0 = _to_px(bounds, view_px)
        box = _text_box((((a + b) / 2 - x0) * scale, (level - y0) * scale), text)
        assert _inside(box, view_px), (window, box, view_px)
        for x, y, label in labels:
            other = _text_box(((x - x0) * scale, (y - y0) * scale), label)
            assert _apart(box, other), (window, label)


@pytest.mark.parametrize(
    "peaks",
    [
        [(80.0, 1.0), (100.0, 0.91)],  # walls 80 / 100 degrees (a constructed map)
        [(86.3, 0.97), (176.2, 1.0)],  # the sample session
        [(0.0, 1.0), (90.0, 1.0)],
        [(0.0, 1.0), (45.0, 0.5), (90.0, 0.95), (135.0, 0.4)],
        [(60.0, 0.8), (70.0, 1.0), (80.0, 0.85)],
    ],
)
def test_the_peaks_labels_are_whole_and_apart_in_every_window(
    peaks: list[tuple[float, float]],
) -> None:
    """Peaks 20 degrees apart wrote their labels ("80.0° p 1.00", "100.0° p 0.91") over each
    other at 1024 x 768 and 1280 x 720, where a label is 90 to 130 degrees wide (laid out for 72);
    a peak at 0 degrees hung its label over the y axis's "s" and "1". In every window: each label
    inside the view, apart from the others, clear of the axis labels and of every peak's dot
    (4 pixels) and bar."""
    result = _result_with_peaks(peaks)
    plot = conv.amplitude_plot(result)
    bounds = _amplitude_bounds(False)
    axis_labels = _axis_labels()
    for window in AMPLITUDE_WINDOWS:
        view_px = _amplitude_view_px(window)
        scale, x0, y0 = _to_px(bounds, view_px)
        boxes = [_box(((x - x0) * scale, (y - y0) * scale)) for x, y in plot.label_anchors.tolist()]
        for k, label in enumerate(boxes):
            assert _inside(label, view_px), (window, plot.peak_labels[k], label, view_px)
            for x, y, text in axis_labels:
                other = _text_box(((x - x0) * scale, (y - y0) * scale), text)
                assert _apart(label, other), (window, plot.peak_labels[k], text)
            for x, y in plot.peaks.tolist():  # no peak's dot or bar (down from it) under it
                peak_x, peak_y = (x - x0) * scale, (y - y0) * scale
                assert not (label[0] < peak_x < label[2] and label[3] > peak_y - 4.0), (
                    window,
                    plot.peak_labels[k],
                )
            for other in boxes[k + 1 :]:
                assert _apart(label, other), (window, plot.peak_labels)


def _peaks_px(
    plot: conv.AmplitudePlot, bounds: tuple[tuple[float, float], tuple[float, float]], view_px
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], float]:
    """``(peaks, anchors, scale)``: the peaks and their labels' points in the view's pixels."""
    scale, x0, y0 = _to_px(bounds, view_px)
    origin = np.array([x0, y0])
    return (plot.peaks - origin) * scale, (plot.label_anchors - origin) * scale, scale


@pytest.mark.parametrize("heights", [(1.0, 0.9), (0.85, 1.0)])
@pytest.mark.parametrize("centre", [60.0, 100.0, 130.0, 168.0])
@pytest.mark.parametrize("apart", [5.0, 10.0, 15.0, 20.0])
def test_close_peaks_labels_stand_by_their_own_peaks_in_every_window(
    apart: float, centre: float, heights: tuple[float, float]
) -> None:
    """Two peaks 5 to 20 degrees apart: the second label stood a label's width away from its
    peak, 90 pixels at 1280 x 720 and 150 at 1920 x 1080, or right of the plot. Laid out side by
    side over the pair, each label's box is over its own peak in the smallest view and at most
    30 pixels across from it in the largest (a label is 90 pixels wide in every view, and the
    pair's two places a label's width apart at the smallest view's scale: 1.67 times that at
    1920 x 1080, 45 x 0.67); its lower edge between 12 and 39 pixels over the higher peak's
    centre (12 at the smallest scale, as high as the s axis's top label over its tick; the
    clearance and a box's height, laid out at that scale, are 36 x 0.67 pixels more at the
    largest)."""
    peaks = [(centre - apart / 2, heights[0]), (centre + apart / 2, heights[1])]
    plot = conv.amplitude_plot(_result_with_peaks(peaks))
    bounds = _amplitude_bounds(False)
    for window in AMPLITUDE_WINDOWS:
        peaks_px, anchors_px, _ = _peaks_px(plot, bounds, _amplitude_view_px(window))
        highest = float(peaks_px[:, 1].min())
        for (peak_x, _), (x, y) in zip(peaks_px.tolist(), anchors_px.tolist(), strict=True):
            left, _, right, bottom = _box((x, y))
            across = max(left - peak_x, peak_x - right, 0.0)
            assert across <= 30.0, (window, peaks, across)
            assert 11.9 <= highest - bottom <= 39.0, (window, peaks, highest - bottom)


@pytest.mark.parametrize("centre", [20.0, 40.0])
def test_close_peaks_labels_near_the_s_axis_stand_over_its_labels(centre: float) -> None:
    """Two close peaks at 20 or 40 degrees: the second label stood a label's width right of the
    s axis's labels and the first, 87 to 177 pixels across from its peak. Over the highest peak
    a label may stand over the s axis's labels (its box ends above them): the pair's labels
    side by side from the view's left edge, each at most 90 pixels across from its peak (the
    left one within 20: two labels do not fit around a pair that far left)."""
    for apart in (5.0, 10.0, 15.0, 20.0):
        peaks = [(centre - apart / 2, 0.9), (centre + apart / 2, 1.0)]
        plot = conv.amplitude_plot(_result_with_peaks(peaks))
        bounds = _amplitude_bounds(False)
        for window in AMPLITUDE_WINDOWS:
            peaks_px, anchors_px, _ = _peaks_px(plot, bounds, _amplitude_view_px(window))
            boxes = [_box((x, y)) for x, y in anchors_px.tolist()]
            for (peak_x, _), (left, _, right, _) in zip(peaks_px.tolist(), boxes, strict=True):
                assert max(left - peak_x, peak_x - right, 0.0) <= 90.0, (window, peaks)
            assert _apart(*boxes), window


@pytest.mark.parametrize("apart", [6.0, 14.0])
def test_close_peaks_labels_move_as_little_as_their_peaks_between_snapshots(apart: float) -> None:
    """Snapshots whose two close peaks drift by half a degree and trade heights (1.0 / 0.9 to
    0.9 / 1.0): the labels jumped a label's width (over 100 pixels) when the heights crossed, as
    the layout that moved them least flipped from left-to-right to highest-first. Side by side
    over the pair, a label moves across at most as far as the pair's peaks (it follows their
    mean) and up or down at most as far as the higher peak (its row is over it): the bound
    checked is that, and half a pixel, between every two consecutive snapshots in every
    window."""
    bounds = _amplitude_bounds(False)
    steps = 11
    plots = [
        conv.amplitude_plot(
            _result_with_peaks(
                [
                    (120.0 + 0.5 * k, 1.0 - 0.01 * k),
                    (120.0 + apart + 0.5 * k, 0.9 + 0.01 * k),
                ]
            )
        )
        for k in range(steps)
    ]
    for window in AMPLITUDE_WINDOWS:
        view_px = _amplitude_view_px(window)
        before = _peaks_px(plots[0], bounds, view_px)
        for plot in plots[1:]:
            after = _peaks_px(plot, bounds, view_px)
            moved_x = float(np.abs(after[0][:, 0] - before[0][:, 0]).max())
            moved_top = abs(float(after[0][:, 1].min() - before[0][:, 1].min()))
            label_moved = np.abs(after[1] - before[1])
            assert label_moved[:, 0].max() <= moved_x + 0.5, (window, label_moved, moved_x)
            assert label_moved[:, 1].max() <= moved_top + 0.5, (window, label_moved, moved_top)
            before = after
