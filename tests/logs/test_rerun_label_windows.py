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
    return a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]


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
    row of 2.5 / 1.8 / 2.3 / 3.0, less a 28-pixel title), 2 less."""
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
    inside the view, apart from the others, clear of the y axis's tick labels (16 pixels right of
    their centre) and of every peak's dot (4 pixels) and bar."""
    result = _result_with_peaks(peaks)
    plot = conv.amplitude_plot(result)
    layout = blueprint.TopicLayout("map", bounds_m=(0.0, 0.0, 10.0, 10.0))
    view = _view(blueprint._topic_container(layout), "cumulative amplitude")
    bounds = _bounds(view)
    for window in WINDOWS:
        view_px = _amplitude_view_px(window)
        scale, x0, y0 = _to_px(bounds, view_px)
        boxes = [_box(((x - x0) * scale, (y - y0) * scale)) for x, y in plot.label_anchors.tolist()]
        axis_right = (-9.0 - x0) * scale + 16.0
        for k, label in enumerate(boxes):
            assert _inside(label, view_px), (window, plot.peak_labels[k], label, view_px)
            assert label[0] >= axis_right, (window, plot.peak_labels[k])
            for x, y in plot.peaks.tolist():  # no peak's dot or bar (down from it) under it
                peak_x, peak_y = (x - x0) * scale, (y - y0) * scale
                assert not (label[0] < peak_x < label[2] and label[3] > peak_y - 4.0), (
                    window,
                    plot.peak_labels[k],
                )
            for other in boxes[k + 1 :]:
                assert _apart(label, other), (window, plot.peak_labels)
