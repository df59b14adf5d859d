"""The amplitude view's frame and axis labels, laid out in screen pixels for every window.

Rerun 0.41 draws a label a fixed number of screen pixels in size, a box about 23 pixels high and
as wide as its text, centred across its point and hanging from 1 to 24 pixels under it; it fits a
2D view's visual bounds in the view keeping their aspect, centred. Labels whose points are placed
(in plot units) at the most plot units per pixel of the views they are laid out for stay apart in
every larger view: their points move apart there, the boxes keep their size.

Plot units: x in degrees (0 to 180), y ``-AMPLITUDE_PLOT_HEIGHT * s`` (down on screen is +).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from rose_logs.rerun.style import AMPLITUDE_PLOT_HEIGHT

__all__ = [
    "AXIS_TICK_PX",
    "LABEL_BOTTOM_PX",
    "LABEL_GAP_PX",
    "LABEL_TOP_PX",
    "S_TICKS",
    "X_TICKS_DEG",
    "X_TITLE",
    "AmplitudeFrame",
    "amplitude_frame",
    "label_width_px",
]

#: A label's box under its point, screen pixels (Rerun 0.41, web viewer: 22-23 high).
LABEL_TOP_PX = 1.0
LABEL_BOTTOM_PX = 24.0
#: Between two labels, and from a label to a line it names or to the view's edge.
LABEL_GAP_PX = 4.0
#: The ticks' length, screen pixels.
AXIS_TICK_PX = 3.0
X_TICKS_DEG = (0.0, 45.0, 90.0, 135.0, 180.0)
S_TICKS = (0.0, 0.5, 1.0)
#: The x axis's title, beside its tick labels right of 180 degrees: in a row of its own under them
#: it cost a small window's plot 24 of its 55 pixels of height. Degrees are on the ticks.
X_TITLE = "wall direction, map frame"
#: The peaks' labels (``"100.0° p 0.67"``: 85 pixels measured) are laid out this wide.
PEAK_LABEL_PX = 90.0
#: Room over a peak for its label, from the peak's centre (the dot is 4 points) to the box: the
#: box over a peak at s = 1 ends half a pixel above the s axis's labels ("s = 1" is centred on
#: its tick), so that it may stand over them (with 6, labels there kept right of them: two close
#: peaks left of 95 degrees had no room side by side).
PEAK_LABEL_CLEARANCE_PX = (LABEL_TOP_PX + LABEL_BOTTOM_PX) / 2 + 0.5

_NARROW = frozenset(" .,:;()ilrtfj")
_WIDE = frozenset("mw")


def label_width_px(text: str) -> float:
    """Width (screen pixels) of the box Rerun 0.41's web viewer draws for ``text``, from a little
    above: 14 pixels of padding, 3.8 a narrow character, 10.5 an ``m`` or ``w``, 7.3 any other.
    Measured boxes: "s" 18, "0.5" 30, "45°" 33, "135°" 39, "t = 0.5" 50, "86.3° p 0.82" 84,
    "176.2° p 1.00" 87, "wall direction, map frame (deg)" 195 (this gives 21, 32, 35, 42, 51, 93,
    94, 197)."""
    return 14.0 + sum(3.8 if c in _NARROW else 10.5 if c in _WIDE else 7.3 for c in text)


@dataclass(frozen=True)
class AmplitudeFrame:
    """The amplitude view's visual bounds and axis labels (plot units), laid out at ``per_px``.

    Attributes
    ----------
    per_px : float
        Plot units per screen pixel in the smallest view laid out for (the most units per pixel).
    x_range, y_range : tuple of float
        The view's visual bounds.
    label_positions : tuple of (float, float)
        Each axis label's point (its box hangs under it, centred across).
    labels : tuple of str
        The tick labels (``"0°"``, ...; ``"0"``, ``"0.5"``, ``"s = 1"``) and :data:`X_TITLE`.
    tick : float
        The ticks' length (x ticks down from the axis, s ticks left of it).
    axis_labels_right : float
        x of the s axis's labels' right edge: a label right of it (and a gap) is off them.
    axis_labels_top : float
        y of the s axis's labels' top: a label whose box ends above it is off them.
    shown_right : float
        The rightmost x every view shows.
    """

    per_px: float
    x_range: tuple[float, float]
    y_range: tuple[float, float]
    label_positions: tuple[tuple[float, float], ...]
    labels: tuple[str, ...]
    tick: float
    axis_labels_right: float
    axis_labels_top: float
    shown_right: float


def amplitude_frame(views_px: Sequence[tuple[float, float]]) -> AmplitudeFrame:
    """The amplitude view's frame for views of ``views_px`` (width, height, screen pixels).

    Around the plot (180 degrees by :data:`~rose_logs.rerun.style.AMPLITUDE_PLOT_HEIGHT`), in
    pixels: left of it the s axis's labels (``"0"``, ``"0.5"``, ``"s = 1"``), centred on their
    ticks and apart across from the ``"0°"`` under the axis; above it a peak's label over a peak
    at ``s = 1``; under it the degrees' labels, :data:`X_TITLE` beside them right of 180
    degrees.
    Rerun fits the frame keeping its aspect, so the units per pixel are the most over the views
    of ``max(frame width / view width, frame height / view height)``, the rooms in pixels (solved
    for it). The degrees are labelled every 45 where those labels are apart, else every 90."""
    if not views_px:
        msg = "views_px must name at least one view"
        raise ValueError(msg)
    height = AMPLITUDE_PLOT_HEIGHT
    # The axis is named on its top label ("s" over "1" cost the plot 5 of its 55 pixels).
    s_labels = [f"{s:g}" for s in S_TICKS[:-1]] + [f"s = {S_TICKS[-1]:g}"]
    s_width = max(label_width_px(text) for text in s_labels)
    # The s labels' centre left of the axis: off its ticks, and across from "0°" (centred on the
    # axis, under it) though "0" is level with it.
    centre_px = max(
        AXIS_TICK_PX + LABEL_GAP_PX + s_width / 2,
        label_width_px("0°") / 2 + LABEL_GAP_PX + label_width_px(s_labels[0]) / 2,
    )
    left_px = centre_px + s_width / 2 + LABEL_GAP_PX
    last = f"{X_TICKS_DEG[-1]:g}°"
    title_px = label_width_px(X_TITLE)
    right_px = label_width_px(last) / 2 + LABEL_GAP_PX + title_px + LABEL_GAP_PX
    # Above s = 1: "s = 1" is centred on its tick (half a box over it); a peak's label over the
    # peak (its point a box's height over the box's lower edge). Under the axis: a row of labels
    # hanging from the ticks' ends.
    half_box = (LABEL_TOP_PX + LABEL_BOTTOM_PX) / 2
    peak_top_px = PEAK_LABEL_CLEARANCE_PX + (LABEL_BOTTOM_PX - LABEL_TOP_PX)
    top_px = max(half_box, peak_top_px) + LABEL_GAP_PX
    bottom_px = AXIS_TICK_PX + LABEL_BOTTOM_PX + LABEL_GAP_PX
    per_px = max(
        max(180.0 / max(w - left_px - right_px, 1.0) for w, _ in views_px),
        max(height / max(h - top_px - bottom_px, 1.0) for _, h in views_px),
    )
    x_range = (-left_px * per_px, 180.0 + right_px * per_px)
    y_range = (-height - top_px * per_px, bottom_px * per_px)
    span_x, span_y = x_range[1] - x_range[0], y_range[1] - y_range[0]
    # What every view shows across: at least the frame, more where the view is wider.
    shown = min(w * max(span_x / w, span_y / h) for w, h in views_px)
    shown_right = (x_range[0] + x_range[1]) / 2 + shown / 2

    tick = AXIS_TICK_PX * per_px
    widest = max(label_width_px(f"{x:g}°") for x in X_TICKS_DEG)
    step = 1 if 45.0 / per_px >= widest + LABEL_GAP_PX else 2
    ticks_deg = X_TICKS_DEG[::step]
    positions = [(x, tick) for x in ticks_deg]
    labels = [f"{x:g}°" for x in ticks_deg]
    x_s = -centre_px * per_px
    # A point half a box over its tick: Rerun hangs the box under the point.
    positions += [(x_s, -height * s - half_box * per_px) for s in S_TICKS]
    labels += s_labels
    title_x = 180.0 + (label_width_px(last) / 2 + LABEL_GAP_PX + title_px / 2) * per_px
    positions.append((title_x, tick))
    labels.append(X_TITLE)
    return AmplitudeFrame(
        per_px=per_px,
        x_range=x_range,
        y_range=y_range,
        label_positions=tuple(positions),
        labels=tuple(labels),
        tick=tick,
        axis_labels_right=x_s + s_width / 2 * per_px,
        axis_labels_top=-height - (half_box - LABEL_TOP_PX) * per_px,
        shown_right=shown_right,
    )
