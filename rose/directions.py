"""Dominant directions and the global structure score W."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rose.errors import RoseError
from rose.limits import finite_number
from rose.params import MIN_PADDED_SIDE

__all__ = [
    "FAILURE_LEVEL",
    "MIN_JUDGED_CELLS",
    "TRUST_LEVEL",
    "DirectionPeaks",
    "degenerate_input",
    "find_direction_peaks",
    "fold_deg",
    "local_maxima",
    "map_frame_deg",
    "peak_prominences",
    "refine_peak_positions",
    "structure_score",
    "w_judges",
]


def fold_deg(angle_deg: float, digits: int | None = None) -> float:
    """A line orientation in degrees folded into ``[0, 180)`` (rounded to ``digits`` if given).

    Rounded after folding, and folded again, so that neither 179.996 (at 2 digits) nor a tiny
    negative angle (whose ``% 180`` is 180.0 in floating point) comes out as 180.0.
    """
    folded = angle_deg % 180.0
    if digits is not None:
        folded = round(folded, digits) % 180.0
    return 0.0 if folded >= 180.0 else folded + 0.0  # + 0.0: no -0.0


#: Decimals of the directions in every report (JSON, tables): 0.01 degrees.
REPORT_DIGITS = 2


def map_frame_deg(
    directions_rad: npt.ArrayLike, *, yaw_rad: float = 0.0, digits: int = 2
) -> list[float]:
    """Dominant directions (radians, grid frame) in degrees in the map frame, in ``[0, 180)`` and
    rounded to ``digits`` (0.01, the precision of every report; the views' labels give 0.1).

    Fewer digits round the reported value, not the exact one: every view then shows what the
    reports' numbers round to (176.15 is 176.2 everywhere; from the exact 176.1499... the views said
    176.1 and the tables 176.2).

    ROSE measures directions in the grid (counter-clockwise from the grid's +x, the column axis); a
    map whose origin is rotated by ``yaw_rad`` has its walls that much further round in the map frame.
    """
    exact = [math.degrees(float(a) + yaw_rad) for a in np.ravel(directions_rad)]
    if digits >= REPORT_DIGITS:
        return [fold_deg(d, digits) for d in exact]
    return [fold_deg(fold_deg(d, REPORT_DIGITS), digits) for d in exact]


# The paper's rule of thumb for reading W; the one definition every command, report and view uses.
TRUST_LEVEL = 0.2
"""W below which the paper trusts a map's decluttering."""
FAILURE_LEVEL = 0.4
"""W above which the paper considers the decluttering (and the map) failed."""

#: Fewest occupied cells for W to judge a map: a 1 m wall at 5 cm per cell. An empty map has
#: W = 1 by convention (so has a single cell: its spectrum is flat), and a few cells' W says nothing
#: about a building.
MIN_JUDGED_CELLS = 20


def w_judges(occupied_cells: int) -> bool:
    """Whether W says something about a map with ``occupied_cells`` occupied cells.

    An empty or all-unknown map (a SLAM session's first maps, W = 1 by convention), or one of a few
    occupied cells (fewer than :data:`MIN_JUDGED_CELLS`), says nothing about the building: it stays
    in the per-snapshot records but is left out of W's statistics, the failure-level events, the
    gates and the W plot of ``rose-bag``, and gets no verdict from ``rose``.
    """
    return occupied_cells >= MIN_JUDGED_CELLS


def degenerate_input(grid: npt.NDArray[np.int8], occupied: npt.NDArray[np.bool_]) -> str | None:
    """Why ROSE's input, the ``occupied`` mask of ``grid``, cannot show a building's structure, so
    that W says nothing about the map; None when it can.

    ROSE sees a building in the outline of the occupied cells: the spectrum of the mask is that of
    its edges. It cannot when

    - *a side is too thin for a 2D spectrum*: under :data:`rose.params.MIN_PADDED_SIDE` cells, the
      side ROSE pads because so few cells sample the spectrum too coarsely to tell directions apart
      (a solid 1 x 300 strip read W = 0.007, "structured");
    - *the occupied cells fill the grid*: their outline inside the grid is shorter than where they
      meet its border as a mass (a border cell with occupied cells two further in: thicker than a
      scanned wall), so the grid's rectangle outweighs them in the spectrum (a solid 40 x 50 block
      read W = 0.016, the rectangle's directions). A map whose outside is drawn occupied (Bormann's
      lab_ipa: 82 % of its cells) still has twice as long an outline inside as on its border, and
      a room whose one-cell walls are the grid's border (a map cropped to its walls) is a room;
    - *there is no free space*: fewer free cells than :data:`MIN_JUDGED_CELLS`, so nothing lies
      between walls (a solid block amid unknown cells: the outline of a blob, not of rooms).
    """
    if not occupied.any():  # no input at all: W = 1 by convention, nothing to be degenerate
        return None
    thinnest = min(occupied.shape, default=0)
    if thinnest < MIN_PADDED_SIDE:
        noun = "cell" if thinnest == 1 else "cells"
        return f"a side of {thinnest} {noun} (fewer than {MIN_PADDED_SIDE}, too thin for a 2D spectrum)"
    border = sum(int(np.count_nonzero(side)) for side in _solid_sides(occupied))
    # Counted only when some mass meets the border: a SLAM map's edge is unknown space, and the
    # outline is two whole-grid passes (0.5 ms of a 1000 x 1000 session snapshot).
    outline = _outline_length(occupied) if border else 0
    if outline < border:
        return (
            f"occupied cells fill the grid ({border} cell sides on its border, {outline} inside it)"
        )
    # Free cells anywhere, not only next to walls: drawn maps (Bormann's office_g) edge their walls
    # with grey, unknown cells.
    free = int(np.count_nonzero(grid >= 0)) - int(np.count_nonzero(occupied))
    if free < MIN_JUDGED_CELLS:
        noun = "cell" if free == 1 else "cells"
        return f"only {free} free {noun} (fewer than {MIN_JUDGED_CELLS}, no space between walls)"
    return None


def _outline_length(mask: npt.NDArray[np.bool_]) -> int:
    """Cell sides inside the grid between a True and a False cell."""
    return int(
        np.count_nonzero(mask[1:] != mask[:-1]) + np.count_nonzero(mask[:, 1:] != mask[:, :-1])
    )


def _solid_sides(mask: npt.NDArray[np.bool_]) -> tuple[npt.NDArray[np.bool_], ...]:
    """The grid's four sides (first and last rows and columns), True where the cell and the two
    next to it inwards are True (walls on the border one or two cells thick are not counted)."""
    return (
        mask[0] & mask[1] & mask[2],
        mask[-1] & mask[-2] & mask[-3],
        mask[:, 0] & mask[:, 1] & mask[:, 2],
        mask[:, -1] & mask[:, -2] & mask[:, -3],
    )


@dataclass(frozen=True, eq=False)
class DirectionPeaks:
    """Peaks of the cumulative amplitude, strongest (most prominent) first.

    Attributes
    ----------
    indices : ndarray of intp, shape (K,)
        Bin indices of the peaks.
    prominences : ndarray of float64, shape (K,)
        Prominence of each peak as a fraction of ``max - min``.
    """

    indices: npt.NDArray[np.intp]
    prominences: npt.NDArray[np.float64]


def find_direction_peaks(
    cumulative: npt.NDArray[np.float64], *, prominence_fraction: float
) -> DirectionPeaks:
    """Peaks of a circular signal whose prominence is at least ``prominence_fraction * (max - min)``.

    Prominence follows ``scipy.signal.peak_prominences``. Directions wrap around at pi, so the signal is
    tripled and only peaks in the middle copy are kept: a peak at 0 or near pi is found once, with its
    true prominence. A constant signal has no peaks, and neither has one whose spread is below
    ``1e-4`` of its level: that is float rounding (a single occupied cell has a flat spectrum).

    Raises
    ------
    RoseError
        If ``cumulative`` is not 1-D or ``prominence_fraction`` not a finite number >= 0.
    """
    cumulative = _curve(cumulative, "find_direction_peaks")
    if not (finite_number(prominence_fraction) and prominence_fraction >= 0):
        msg = f"prominence_fraction must be a finite number >= 0, got {prominence_fraction!r}"
        raise RoseError(msg)
    n = cumulative.size
    span = float(cumulative.max() - cumulative.min()) if n else 0.0
    level = float(np.abs(cumulative).max()) if n else 0.0
    if n < 3 or not np.isfinite(span) or span <= 1e-4 * level:
        return DirectionPeaks(np.empty(0, dtype=np.intp), np.empty(0))
    tripled = np.concatenate([cumulative, cumulative, cumulative])
    peaks = local_maxima(tripled)
    peaks = peaks[(peaks >= n) & (peaks < 2 * n)]
    # A peak's prominence is at most its height above the signal's minimum (rounding is monotonic):
    # lower peaks cannot pass, and skipping them saves most of the work on noisy signals.
    threshold = prominence_fraction * span
    peaks = peaks[tripled[peaks] - float(cumulative.min()) >= threshold]
    prominences = peak_prominences(tripled, peaks)
    keep = prominences >= threshold
    indices = peaks[keep] - n
    prominences = prominences[keep] / span
    order = np.argsort(-prominences, kind="stable")
    return DirectionPeaks(indices[order].astype(np.intp), prominences[order])


def local_maxima(signal: npt.NDArray[np.float64]) -> npt.NDArray[np.intp]:
    """Indices of the local maxima of a 1-D signal, as ``scipy.signal.find_peaks`` finds them.

    A flat top counts once, at its middle (rounded down); the first and last samples are never peaks.
    Written in numpy because importing ``scipy.signal`` costs about 1.5 s, most of every process's
    start-up (CLI commands, batch workers); ``tests/test_directions.py`` checks it against SciPy.
    """
    n = signal.size
    if n < 3:
        return np.empty(0, dtype=np.intp)
    # Runs of equal samples: a run is a peak when both neighbouring runs are lower.
    starts = np.flatnonzero(np.concatenate([[True], signal[1:] != signal[:-1]]))
    ends = np.append(starts[1:], n) - 1
    values = signal[starts]
    inner = np.zeros(starts.size, dtype=bool)
    inner[1:-1] = (values[:-2] < values[1:-1]) & (values[2:] < values[1:-1])
    return ((starts[inner] + ends[inner]) // 2).astype(np.intp)


def peak_prominences(
    signal: npt.NDArray[np.float64], peaks: npt.NDArray[np.intp]
) -> npt.NDArray[np.float64]:
    """Prominence of each peak, as ``scipy.signal.peak_prominences`` defines it (no window).

    Each side's base is the lowest sample between the peak and the nearest strictly higher sample (or
    the signal's end); the prominence is the peak's height above the higher of the two bases.
    Vectorised over peaks x samples: the signals here have a few hundred samples.
    """
    if peaks.size == 0:
        return np.empty(0)
    position = np.arange(signal.size)
    height = signal[peaks][:, None]
    higher = signal[None, :] > height
    before = position[None, :] < peaks[:, None]
    after = position[None, :] > peaks[:, None]
    # The nearest strictly higher sample on each side bounds the search (-1 / n when there is none).
    left_stop = np.where(higher & before, position, -1).max(axis=1)
    right_stop = np.where(higher & after, position, signal.size).min(axis=1)
    window = (position[None, :] > left_stop[:, None]) & (position[None, :] < right_stop[:, None])
    left_base = np.where(window & ~after, signal, np.inf).min(axis=1)
    right_base = np.where(window & ~before, signal, np.inf).min(axis=1)
    return np.asarray(height[:, 0] - np.maximum(left_base, right_base), dtype=np.float64)


def refine_peak_positions(
    cumulative: npt.NDArray[np.float64], indices: npt.NDArray[np.intp]
) -> npt.NDArray[np.float64]:
    """Sub-bin peak positions (in bins) by fitting a parabola through each peak and its two neighbours.

    Raises
    ------
    RoseError
        If ``cumulative`` is not 1-D or ``indices`` are not integers in ``0 .. cumulative.size - 1``.
    """
    cumulative = _curve(cumulative, "refine_peak_positions")
    indices = _peak_indices(indices, cumulative.size)
    n = cumulative.size
    left = cumulative[(indices - 1) % n]
    centre = cumulative[indices]
    right = cumulative[(indices + 1) % n]
    curvature = left - 2.0 * centre + right
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = np.where(curvature < 0, 0.5 * (left - right) / curvature, 0.0)
    return indices + np.clip(offset, -0.5, 0.5)


def structure_score(
    cumulative: npt.NDArray[np.float64], peak_indices: npt.NDArray[np.intp]
) -> float:
    """The paper's W: mean of the min-max scaled cumulative amplitude over its mean at the peaks.

    Near 0 for maps with strong structure, near 1 without; exactly 1 when there is no peak, above 1
    when the peaks' mean is below the curve's (weak peaks kept by a very low prominence).

    Raises
    ------
    RoseError
        If ``cumulative`` is empty, not 1-D or not finite, ``peak_indices`` are not integers in
        ``0 .. cumulative.size - 1``, or there are peaks on a constant curve (which has none).
    """
    cumulative = _curve(cumulative, "structure_score")
    if cumulative.size == 0:
        msg = "structure_score needs the cumulative amplitude of at least one direction"
        raise RoseError(msg)
    peak_indices = _peak_indices(peak_indices, cumulative.size)
    if peak_indices.size == 0:
        return 1.0
    if not np.isfinite(cumulative).all():
        msg = "structure_score: the cumulative amplitude holds NaN or infinite values"
        raise RoseError(msg)
    low, high = float(cumulative.min()), float(cumulative.max())
    if not high > low:
        msg = "structure_score: the cumulative amplitude is constant: it has no peak"
        raise RoseError(msg)
    scaled = (cumulative - low) / (high - low)
    return float(scaled.mean() / scaled[peak_indices].mean())


def _curve(cumulative: npt.ArrayLike, caller: str) -> npt.NDArray[np.float64]:
    """``cumulative`` as a 1-D float array, or a RoseError naming ``caller``."""
    curve = np.asarray(cumulative)
    if curve.ndim != 1 or curve.dtype.kind not in "iuf":  # (timedelta64 is no number here)
        msg = (
            f"{caller}: the cumulative amplitude must be a 1-D array of numbers, got "
            f"{curve.dtype} of shape {curve.shape}"
        )
        raise RoseError(msg)
    return curve


def _peak_indices(indices: npt.ArrayLike, n: int) -> npt.NDArray[np.intp]:
    """``indices`` as a 1-D integer array within ``0 .. n - 1``, or a RoseError."""
    array = np.asarray(indices)
    if array.size == 0:
        return np.empty(0, dtype=np.intp)
    if array.ndim != 1 or array.dtype.kind not in "iu":
        msg = f"peak indices must be a 1-D array of integers, got {array.dtype} of shape {array.shape}"
        raise RoseError(msg)
    if array.min() < 0 or array.max() >= n:
        msg = f"peak indices must be in 0..{n - 1}, got {array.tolist()}"
        raise RoseError(msg)
    return array
