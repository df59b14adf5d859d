"""``analyze``: the ROSE stages in order."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from rose.directions import find_direction_peaks, refine_peak_positions, structure_score
from rose.frozen import seal
from rose.grid import as_occupancy_grid, occupied_mask, warn_if_mask
from rose.mapfile import OccupancyMap
from rose.params import RoseParams, make_params
from rose.result import RoseResult
from rose.scoring import inverse_to_map, masked_spectrum, structure_mask
from rose.spectrum import half_spectrum, padded_shape
from rose.threshold import gmm_threshold
from rose.unfold import cumulative_amplitude, direction_bins

__all__ = ["analyze"]

#: Directions this close below pi are 0 (radians): half the 0.01 degree the reports print angles to
#: (a refined peak a hair below bin 0 read 180.00), far below any peak's refinement accuracy (9e-3).
_WRAP_RAD = math.radians(0.005)


def analyze(
    grid: npt.ArrayLike | OccupancyMap, params: RoseParams | None = None, **overrides: Any
) -> RoseResult:
    """Run ROSE on one occupancy grid.

    Parameters
    ----------
    grid : array_like, shape (rows, cols), or OccupancyMap
        ROS occupancy grid (int8: -1 unknown, 0..100; row 0 at the map origin) or a boolean occupied
        mask, or a map read by :func:`rose.load_map` (its grid). Not modified.
    params : RoseParams, optional
        Parameters; the defaults of :class:`RoseParams` if omitted.
    **overrides
        Any :class:`RoseParams` field by name, e.g. ``peak_prominence=0.2``.

    Returns
    -------
    RoseResult

    Raises
    ------
    RoseError
        If ``grid`` is not a 2D boolean or numeric array in -1..100, or a parameter is invalid.
    """
    p = make_params(params, **overrides)
    given = grid.grid if isinstance(grid, OccupancyMap) else grid
    occupancy = as_occupancy_grid(given)
    warn_if_mask(given, occupancy, p.occupied_threshold)
    occupied = occupied_mask(occupancy, occupied_threshold=p.occupied_threshold)
    shape = padded_shape(occupancy.shape)

    spectrum = half_spectrum(occupied, shape)
    amplitude = np.abs(spectrum)
    bins = direction_bins(
        shape, angular_resolution_deg=p.angular_resolution_deg, min_radius_px=p.min_radius_px
    )
    step_deg = 180.0 / bins.centres.size
    cumulative = cumulative_amplitude(amplitude, bins, smoothing_bins=p.smoothing_deg / step_deg)
    peaks = find_direction_peaks(cumulative, prominence_fraction=p.peak_prominence)
    directions = np.mod(
        refine_peak_positions(cumulative, peaks.indices) * (math.pi / bins.centres.size), math.pi
    )
    # A peak refined a hair below bin 0 wraps to pi - 2e-11: that is 0 (axis-aligned walls read
    # 180 degrees in `rose walls` and 0 in `rose score` otherwise).
    directions[directions > math.pi - _WRAP_RAD] = 0.0
    score = structure_score(cumulative, peaks.indices)
    has_structure = peaks.indices.size > 0 and bool(occupied.any())

    if has_structure:
        mask = structure_mask(shape, directions, half_width_px=p.mask_half_width_px)
        restricted = masked_spectrum(spectrum, mask)
        # The spectrum is the largest array here: freed before the inverse transform makes its
        # output (sessions run two analyses at once, and their peaks add up).
        del spectrum
        # Only the rows from the first to the last occupied one are scored: the inverse transform
        # skips the rows above and below (a SLAM map's unknown margins, often most of its rows).
        band = _occupied_rows(occupied)
        reference = inverse_to_map(restricted, occupancy.shape, rows=band)
        del restricted
        cell_scores, threshold = _scale_and_threshold(reference, occupied, band, p)
        structure = occupied & (cell_scores > threshold)
        clutter = occupied & ~structure
    else:
        cell_scores = np.zeros(occupancy.shape, dtype=np.float32)
        threshold = math.nan
        structure = np.zeros(occupancy.shape, dtype=bool)
        clutter = structure.copy()

    cleaned = occupancy.copy()
    cleaned[clutter] = p.clutter_cell_value
    return seal(
        RoseResult(
            structure_score=score,
            dominant_directions=directions,
            direction_bins=bins.centres,
            cumulative_amplitude=cumulative,
            peak_indices=peaks.indices,
            peak_prominences=peaks.prominences,
            cell_scores=cell_scores,
            threshold=threshold,
            occupied=occupied,
            structure=structure,
            clutter=clutter,
            cleaned=cleaned,
            has_structure=has_structure,
            spectrum_half=amplitude,
            params=p,
        )
    )


def _occupied_rows(occupied: npt.NDArray[np.bool_]) -> slice:
    """The rows from the first to the last that holds an occupied cell (``occupied`` has one)."""
    rows = np.flatnonzero(occupied.any(axis=1))
    return slice(int(rows[0]), int(rows[-1]) + 1)


def _scale_and_threshold(
    reference: npt.NDArray[np.float32],
    occupied: npt.NDArray[np.bool_],
    band: slice,
    p: RoseParams,
) -> tuple[npt.NDArray[np.float32], float]:
    """Scale the nominal reference map so the best occupied cell scores 1; pick the threshold.

    ``reference``: the map's rows ``band`` (every occupied cell lies in them). Returns the scores
    of the whole map, shape ``occupied.shape``, 0 on the rows outside ``band``.
    """
    occupied_scores = reference[occupied[band]]
    top = float(occupied_scores.max())
    scale = 1.0 / top if top > 0 else 1.0
    cell_scores = np.empty(occupied.shape, dtype=np.float32)
    cell_scores[: band.start] = 0.0
    cell_scores[band.stop :] = 0.0
    np.multiply(reference, np.float32(scale), out=cell_scores[band], dtype=np.float32)
    if p.threshold_mode == "fixed":
        return cell_scores, p.fixed_threshold
    threshold = gmm_threshold(occupied_scores * np.float32(scale), max_samples=p.max_gmm_samples)
    return cell_scores, threshold
