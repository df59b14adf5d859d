"""ROSE's tuning parameters: :class:`RoseParams`, validated on construction."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from rose.errors import RoseError
from rose.grid import FREE, UNKNOWN
from rose.limits import finite_number

__all__ = ["ClutterValue", "RoseParams", "ThresholdMode", "make_params"]

ThresholdMode = Literal["gmm", "fixed"]
ClutterValue = Literal["free", "unknown"]


@dataclass(frozen=True)
class RoseParams:
    """Tuning parameters of :func:`rose.analyze`, with the defaults used everywhere.

    Attributes
    ----------
    peak_prominence : float
        A direction is dominant when its peak prominence in the cumulative amplitude is at least this
        fraction of ``max - min`` (the paper's ``t``; 0.5 in the paper).
    angular_resolution_deg : float
        Width of one direction bin, in degrees; directions cover ``[0, 180)``.
    smoothing_deg : float
        Standard deviation, in degrees, of the circular Gaussian smoothing of the cumulative amplitude
        (0 disables it).
    min_radius_px : float
        Spectrum cells closer than this to DC (in cells of the longer padded side) carry no direction
        information and are left out of the cumulative amplitude.
    mask_half_width_px : float
        Half-width of the strip kept along each dominant direction in the spectrum, in cells of the
        longer padded side (the authors' strip is about 5 cells wide).
    occupied_threshold : int
        Occupancy (percent) from which a cell counts as occupied; unknown cells never do.
    threshold_mode : {"gmm", "fixed"}
        ``"gmm"``: threshold where the two weighted Gaussians of a mixture fitted to the occupied cells'
        scores intersect (the paper). ``"fixed"``: ``fixed_threshold`` on scores scaled to max 1.
    fixed_threshold : float
        Threshold of the fixed mode, as a fraction of the largest occupied cell score: cells
        scoring above it are structure (1 keeps none).
    clutter_value : {"free", "unknown"}
        What clutter cells become in :attr:`RoseResult.cleaned`.
    max_gmm_samples : int
        The mixture is fitted on at most this many occupied cells' scores (an evenly spaced subsample of
        the sorted scores, so the result is deterministic and the cost bounded); at least 100.
    seed : int
        No effect since the mixture's initialisation became deterministic (k-means from the 25 % and
        75 % quantiles); kept so that existing code, options and reports stay valid.
    """

    peak_prominence: float = 0.5
    angular_resolution_deg: float = 0.5
    smoothing_deg: float = 0.5
    min_radius_px: float = 4.0
    mask_half_width_px: float = 2.5
    occupied_threshold: int = 65
    threshold_mode: ThresholdMode = "gmm"
    fixed_threshold: float = 0.18
    clutter_value: ClutterValue = "free"
    max_gmm_samples: int = 2_000
    seed: int = 0

    def __post_init__(self) -> None:
        # numpy scalars (np.int64(65), np.float32(0.3), np.str_("gmm")) as the Python values they
        # stand for; float(), as .item() leaves a np.longdouble one (refused as no number).
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.floating):
                object.__setattr__(self, f.name, float(value))
            elif isinstance(value, np.integer | np.str_):
                object.__setattr__(self, f.name, value.item())
        problems = _problems(self)
        if problems:
            raise RoseError("; ".join(problems))

    @property
    def clutter_cell_value(self) -> int:
        """The ROS cell value clutter cells become: 0 (free) or -1 (unknown), from ``clutter_value``."""
        return FREE if self.clutter_value == "free" else UNKNOWN


def make_params(params: RoseParams | None = None, **overrides: Any) -> RoseParams:
    """``params`` (or the defaults) with ``overrides`` applied and every value checked.

    Raises
    ------
    RoseError
        On an unknown parameter name or a value out of range.
    """
    if params is not None and not isinstance(params, RoseParams):
        msg = (
            f"params must be a RoseParams, got {type(params).__name__}; give single parameters "
            "by name, e.g. analyze(grid, peak_prominence=0.2)"
        )
        raise RoseError(msg)
    if not overrides:
        # A RoseParams was checked when it was made, and it is frozen: no copy to check again
        # (that was a tenth of a millisecond, a few percent of analyze on a small map).
        return params if params is not None else _DEFAULTS
    base = params if params is not None else _DEFAULTS
    try:
        merged = dataclasses.replace(base, **overrides)
    except TypeError as err:
        known = ", ".join(f.name for f in dataclasses.fields(RoseParams))
        msg = f"unknown ROSE parameter in {sorted(overrides)}; known: {known}"
        raise RoseError(msg) from err
    return merged


#: Shortest padded side of a map whose longer side reaches it. A side of a few cells samples the
#: spectrum too coarsely to tell directions apart (a 300 x 12 strip read as 0 degrees, a 3 x 200 one
#: as having no direction while its transpose had one); padding it to this costs next to nothing.
MIN_PADDED_SIDE = 16


def min_padded_side(shape: tuple[int, int]) -> int:
    """Shortest side, cells, a map of ``shape`` ``(rows, cols)`` is zero-padded to for its spectrum:
    :data:`MIN_PADDED_SIDE` when its longer side reaches it, else 1."""
    return MIN_PADDED_SIDE if max(shape) >= MIN_PADDED_SIDE else 1


#: Largest spectrum length a parameter takes, cells (a map of 1e6 cells a side has 1e12 cells).
MAX_SPECTRUM_PX = 1e6

#: Direction bins from 0.01 to 30 degrees wide (finer takes memory, coarser loses the peaks).
ANGULAR_RESOLUTION_RANGE_DEG = (0.01, 30.0)
#: Most angular smoothing, degrees (more blurs the peaks of a right-angled building together).
MAX_SMOOTHING_DEG = 30.0


def _problems(p: RoseParams) -> list[str]:
    numbers = [
        f.name for f in dataclasses.fields(p) if f.name not in ("threshold_mode", "clutter_value")
    ]
    wrong_type = [
        f"{name} must be a number, got {getattr(p, name)!r}"
        for name in numbers
        if isinstance(getattr(p, name), bool) or not isinstance(getattr(p, name), int | float)
    ]
    if wrong_type:
        return wrong_type
    not_finite = [  # (an int too large for a float is not finite: math.isfinite overflowed)
        f"{name} must be finite, got {getattr(p, name)!r}"
        for name in numbers
        if not finite_number(getattr(p, name))
    ]
    if not_finite:
        return not_finite
    problems = []
    for name in ("occupied_threshold", "max_gmm_samples", "seed"):
        if not isinstance(getattr(p, name), int):
            problems.append(f"{name} must be an integer, got {getattr(p, name)!r}")
    if not 0.0 < p.peak_prominence <= 1.0:
        problems.append(f"peak_prominence must be in (0, 1], got {p.peak_prominence}")
    low, high = ANGULAR_RESOLUTION_RANGE_DEG
    if not low <= p.angular_resolution_deg <= high:
        problems.append(
            f"angular_resolution_deg must be in [{low:g}, {high:g}], got {p.angular_resolution_deg}"
        )
    if not 0.0 <= p.smoothing_deg <= MAX_SMOOTHING_DEG:
        problems.append(
            f"smoothing_deg must be in [0, {MAX_SMOOTHING_DEG:g}], got {p.smoothing_deg}"
        )
    # Spectrum lengths (cells of the padded map's longer side): beyond any map's size they mean
    # "all of it", and far beyond they overflow the index arithmetic (1e19 crashed the strip mask).
    if not 0 <= p.min_radius_px <= MAX_SPECTRUM_PX:
        problems.append(f"min_radius_px must be in [0, {MAX_SPECTRUM_PX:g}], got {p.min_radius_px}")
    if not 0 < p.mask_half_width_px <= MAX_SPECTRUM_PX:
        problems.append(
            f"mask_half_width_px must be in (0, {MAX_SPECTRUM_PX:g}], got {p.mask_half_width_px}"
        )
    if not 1 <= p.occupied_threshold <= 100:
        problems.append(f"occupied_threshold must be in 1..100, got {p.occupied_threshold}")
    # Strings first: `in` compares an array elementwise (a ValueError, or an array accepted, which
    # made the params unhashable).
    if not (isinstance(p.threshold_mode, str) and p.threshold_mode in ("gmm", "fixed")):
        problems.append(f"threshold_mode must be 'gmm' or 'fixed', got {p.threshold_mode!r}")
    if not 0.0 <= p.fixed_threshold <= 1.0:
        problems.append(f"fixed_threshold must be in [0, 1], got {p.fixed_threshold}")
    if not (isinstance(p.clutter_value, str) and p.clutter_value in ("free", "unknown")):
        problems.append(f"clutter_value must be 'free' or 'unknown', got {p.clutter_value!r}")
    # Fewer fit the mixture on a handful of quantiles: 10 put the threshold at 0.99 on real maps,
    # every cell clutter (100: within 0.05 of the default's).
    if not p.max_gmm_samples >= 100:
        problems.append(f"max_gmm_samples must be >= 100, got {p.max_gmm_samples}")
    if isinstance(p.seed, int) and not 0 <= p.seed < 2**32:
        problems.append(f"seed must be in 0..2**32-1, got {p.seed}")
    return problems


#: The defaults, made (and checked) once.
_DEFAULTS = RoseParams()
