"""Local structure scoring: keep the spectrum along the dominant directions, transform back."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import scipy.fft

from rose.errors import RoseError
from rose.limits import finite_number, shape_problem
from rose.params import MAX_SPECTRUM_PX
from rose.unfold import frequency_axes

__all__ = ["inverse_to_map", "masked_spectrum", "nominal_reference_map", "structure_mask"]


def structure_mask(
    shape: tuple[int, int], directions: npt.NDArray[np.float64], *, half_width_px: float
) -> npt.NDArray[np.bool_]:
    """The paper's structure part S of the half-plane spectrum of a padded ``shape``.

    Cells within ``half_width_px`` (cells of the longer side) of the line through DC perpendicular to
    each wall direction (radians, grid frame), at every radius, DC included as in the authors' code.

    The strips cover about 1 % of the spectrum: only the cells near each strip (found per column, or
    per row for strips closer to the rows) are tested, with the same float32 arithmetic a test of
    every cell would use, so the mask is the same.

    Returns
    -------
    ndarray of bool, shape (rows, cols // 2 + 1)

    Raises
    ------
    RoseError
        If ``shape`` is not two whole numbers >= 1, ``directions`` not finite numbers, or
        ``half_width_px`` not in ``(0, MAX_SPECTRUM_PX]`` (:data:`rose.params.MAX_SPECTRUM_PX`).
    """
    problem = shape_problem(shape, smallest=1)
    if problem is not None:
        msg = f"structure_mask: shape {problem}"
        raise RoseError(msg)
    try:
        directions = np.asarray(directions, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        directions = np.array([math.nan])
    if not np.isfinite(directions).all():
        # A NaN direction made an index of -3.5e17 deep in the strip search.
        msg = "structure_mask: directions must be finite numbers (radians)"
        raise RoseError(msg)
    if not (finite_number(half_width_px) and 0 < half_width_px <= MAX_SPECTRUM_PX):
        msg = f"half_width_px must be in (0, {MAX_SPECTRUM_PX:g}], got {half_width_px!r}"
        raise RoseError(msg)
    u, v = frequency_axes(shape)
    half_cols = u.size
    mask = np.zeros((v.size, half_cols), dtype=bool)
    for direction in directions:
        c, s = np.float32(np.cos(direction)), np.float32(np.sin(direction))
        cells = _strip_candidates(shape, float(c), float(s), half_width_px)
        row, col = np.divmod(cells, half_cols)
        # The spectrum line of walls at `direction` runs along (cos, sin) of direction + pi/2,
        # i.e. (-sin, cos); the distance from it is the projection on the wall direction itself.
        distance = np.abs(u[col] * c + v[row] * s)
        mask.ravel()[cells[distance <= half_width_px]] = True
    return mask


def _strip_candidates(
    shape: tuple[int, int], c: float, s: float, half_width_px: float
) -> npt.NDArray[np.intp]:
    """Flat half-plane indices of the cells within one cell of the strip ``|u c + v s| <= w``."""
    rows, cols = shape
    half_cols = cols // 2 + 1
    longer = max(rows, cols)
    # Frequencies in cells of the longer side: u = j * longer / cols, v = k * longer / rows, with
    # j in 0 .. cols // 2 and k the signed row frequency (row index k mod rows).
    k = np.arange(-(rows // 2), (rows - 1) // 2 + 1)
    j = np.arange(half_cols)
    if abs(s) >= abs(c):  # a strip closer to the columns: an interval of rows in every column
        along, across = _within(j * (longer / cols), c, s, half_width_px, rows / longer, k)
        return (across % rows) * half_cols + j[along]
    along, across = _within(k * (longer / rows), s, c, half_width_px, cols / longer, j)
    return (k[along] % rows) * half_cols + across


def _within(
    fixed: npt.NDArray[np.floating],
    fixed_weight: float,
    weight: float,
    half_width_px: float,
    per_unit: float,
    values: npt.NDArray[np.intp],
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """For every frequency ``f`` of ``fixed``: the indices ``i`` (frequency ``i / per_unit``, among
    ``values``, consecutive) with ``|f * fixed_weight + i / per_unit * weight| <= half_width_px``,
    one index wider on either side. Returns :func:`_ranges` of the intervals."""
    bounds = np.stack([-half_width_px - fixed * fixed_weight, half_width_px - fixed * fixed_weight])
    ends = np.sort(bounds / weight, axis=0) * per_unit
    low = np.maximum(np.floor(ends[0]).astype(np.intp) - 1, values[0])
    high = np.minimum(np.ceil(ends[1]).astype(np.intp) + 1, values[-1])
    return _ranges(low, high)


def _ranges(
    low: npt.NDArray[np.intp], high: npt.NDArray[np.intp]
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """For the ranges ``low[i] .. high[i]`` (inclusive; empty when high < low): the range each value
    belongs to and the values, concatenated."""
    lengths = np.maximum(high - low + 1, 0)
    owner = np.repeat(np.arange(lengths.size), lengths)
    starts = np.cumsum(lengths) - lengths
    return owner, low[owner] + (np.arange(owner.size) - starts[owner])


def nominal_reference_map(
    spectrum: npt.NDArray[np.complex64], mask: npt.NDArray[np.bool_], shape: tuple[int, int]
) -> npt.NDArray[np.float32]:
    """Inverse transform of the spectrum restricted to ``mask``, cropped to the map's ``shape``.

    The mask is point-symmetric, so the reconstruction is real and ``irfft2`` gives it directly
    (the authors take ``abs`` of a complex ``ifft2``; we keep the sign, which the paper's formula has).
    :func:`masked_spectrum` then :func:`inverse_to_map`, for callers that free ``spectrum`` between.

    Returns
    -------
    ndarray of float32 (float64 for a complex128 spectrum), shape ``shape``
        A view into the padded transform, not contiguous unless nothing was padded (``analyze``
        scales it in place when nothing was, else copies it as it scales it).
    """
    return inverse_to_map(masked_spectrum(spectrum, mask), shape)


def masked_spectrum(
    spectrum: npt.NDArray[np.complex64], mask: npt.NDArray[np.bool_]
) -> npt.NDArray[np.complex64]:
    """A copy of the half-plane ``spectrum`` with every cell outside ``mask`` zero."""
    # The mask keeps about 1 % of the cells: copy those into zeros (calloc'd) instead of a
    # full-size select.
    kept = np.flatnonzero(mask)
    restricted = np.zeros(spectrum.shape, dtype=spectrum.dtype)
    restricted.ravel()[kept] = spectrum.ravel()[kept]
    return restricted


def inverse_to_map(
    restricted: npt.NDArray[np.complex64],
    shape: tuple[int, int],
    rows: slice | None = None,
) -> npt.NDArray[np.float32]:
    """``irfft2`` of a half-plane spectrum (overwritten: used as the transform's buffer) of the
    padded shape, cropped to the map's ``shape`` (a view, as :func:`nominal_reference_map`).

    ``rows``: only these rows of the map (a band within ``shape[0]``, step 1), the others never
    computed: the result has shape ``(len(rows), shape[1])``, each row bit-identical to the same
    row of the whole transform (the row pass transforms rows one by one).
    """
    padded_cols = 2 * (restricted.shape[1] - 1)
    # irfft2 in two passes: the column pass in `restricted` itself (overwrite_x: one map-sized
    # buffer fewer), then the rows. scipy's irfft2 does the same passes but took 7.7 ms of CPU
    # against 4.3-4.9 ms for 1000 x 1000 (and `analyze` 34 -> 17-18 ms per Freiburg 079 stage on a
    # loaded 2-core machine); the results differ by float32 rounding (3e-7 of a cell score).
    columns_done = scipy.fft.ifft(restricted, axis=0, overwrite_x=True)
    if rows is not None:
        band = scipy.fft.irfft(columns_done[rows], n=padded_cols, axis=1)
        return band[:, : shape[1]]
    reference = scipy.fft.irfft(columns_done, n=padded_cols, axis=1, overwrite_x=True)
    return reference[: shape[0], : shape[1]]
