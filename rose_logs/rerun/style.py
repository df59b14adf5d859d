"""Colours, class ids and display constants of the recording (one place for how things look).

Colours are chosen to be told apart on the viewer's light and dark themes and by colour-blind users:
structure blue against clutter orange (the blue/orange pair survives the common deficiencies), the
dominant directions magenta and the walls dark green, neither used for a cell class.
"""

from __future__ import annotations

from typing import Final

__all__ = [
    "AMPLITUDE_PLOT_HEIGHT",
    "BREAK_COLOR",
    "BREAK_SCORE_COLOR",
    "CLASS_CLUTTER",
    "CLASS_COMPLETED",
    "CLASS_FREE",
    "CLASS_INFO",
    "CLASS_OCCUPIED",
    "CLASS_RESCUED",
    "CLASS_STRUCTURE",
    "CLASS_UNKNOWN",
    "DIRECTION_COLOR",
    "DISPLAY_LEVELS",
    "DISPLAY_MAX_PX",
    "FAILURE_COLOR",
    "GUIDE_LINE_WIDTH",
    "PEAK_COLOR",
    "REJECTED_PEAK_COLOR",
    "SCORES_DISPLAY_MAX_PX",
    "SCORE_DISPLAY_MIN",
    "SPECTRUM_DISPLAY_PX",
    "TRUST_COLOR",
    "WALL_COLOR",
    "W_COLOR",
]

CLASS_FREE: Final = 1
CLASS_UNKNOWN: Final = 2
CLASS_OCCUPIED: Final = 3
CLASS_STRUCTURE: Final = 4
CLASS_CLUTTER: Final = 5
CLASS_RESCUED: Final = 6
CLASS_COMPLETED: Final = 7

CLASS_INFO: Final = (
    (CLASS_FREE, "free", (250, 250, 250)),
    (CLASS_UNKNOWN, "unknown", (176, 176, 184)),
    (CLASS_OCCUPIED, "occupied (no structure found)", (40, 40, 40)),
    (CLASS_STRUCTURE, "structure", (20, 90, 220)),
    (CLASS_CLUTTER, "clutter", (245, 130, 0)),
    (CLASS_RESCUED, "clutter kept as wall by the cleaning", (0, 170, 170)),
    (CLASS_COMPLETED, "wall drawn by the cleaning behind removed clutter", (190, 0, 80)),
)
"""``(class id, label, RGB)`` of the segmentation classes, logged once as an AnnotationContext."""

#: Longest side, in pixels, of the per-cell images of the 2D views (segmentation, cell scores): a
#: larger map is shown pooled, each pixel a block of cells. Rerun samples a shrunk image without
#: mipmaps (rerun-io/rerun#2039), so a map several times the view's size showed one wall cell in
#: several: dotted walls, a scores view of scattered dots. About a full-HD view's size.
DISPLAY_MAX_PX: Final = 1024
#: Longest side, in pixels, of the cell-score image: its view is a quarter of the segmentation's
#: (about 480 x 330 pixels in a 1600 x 1000 window, with the colour bar under the map), and at
#: 1024 pixels Rerun drew one cell in two or three there: the Freiburg 101 map's walls came out
#: as scattered dots. Each pixel is the lowest score of its block, so a low-scoring cell shows.
SCORES_DISPLAY_MAX_PX: Final = 384

DIRECTION_COLOR: Final = (200, 0, 160)
#: Wall segments (``--walls``): green, drawn thin (Rerun 0.41 draws lines opaque, whatever their
#: alpha), so that the structure cells beside them show.
WALL_COLOR: Final = (0, 130, 60, 140)
PEAK_COLOR: Final = (220, 40, 40)
#: The prominence bars of peaks that are not kept (their prominence is below the threshold).
REJECTED_PEAK_COLOR: Final = (150, 150, 150)
W_COLOR: Final = (20, 90, 220)
BREAK_COLOR: Final = (230, 30, 30)
"""The break detector's region on the map (red, like the levels a map must stay under)."""
BREAK_SCORE_COLOR: Final = (235, 120, 0)
"""The break score series (its threshold is drawn in FAILURE_COLOR)."""
TRUST_COLOR: Final = (40, 160, 60)
GUIDE_LINE_WIDTH: Final = 2.0
"""Width of the level / threshold lines in the plots, points (thinner lines fade in anti-aliasing)."""
FAILURE_COLOR: Final = (220, 40, 40)
AXIS_COLOR: Final = (110, 110, 110)
CURVE_COLOR: Final = (20, 90, 220)
THRESHOLD_COLOR: Final = (245, 130, 0)

SPECTRUM_COLORMAP_NAME: Final = "Inferno"
"""Rerun colour map of the log amplitude spectrum."""

DISPLAY_LEVELS: Final = 32
"""Levels of the score and spectrum images: enough for a colour map, and few levels compress well."""
SCORE_DISPLAY_MIN: Final = -0.5
"""Cell score at the bottom of the score colour map (the best occupied cell scores 1)."""
SPECTRUM_DISPLAY_PX: Final = 256
"""The spectrum image is ``SPECTRUM_DISPLAY_PX + 1`` pixels square, DC at the centre pixel."""
AMPLITUDE_PLOT_HEIGHT: Final = 60.0
"""Height, in plot units, of s = 1 in the cumulative amplitude plot (its width is 180 degrees):
a third of its width, as the view is 3 to 4 times wider than high and its labels take some 70
pixels of its height (at 90 the plot used a third of the view's width)."""
