"""Unfolding the amplitude spectrum into directions (the paper's polar form, summed over radius).

Instead of resampling the spectrum onto a polar grid pixel by pixel, every half-plane spectrum cell is
assigned once to a direction bin; the per-direction amplitude is then one ``np.add.reduceat`` over
the cells grouped by bin. The assignment depends only on the padded shape and the binning parameters,
so it is cached.

Each half-plane cell stands for itself and its point-symmetric mirror ``(-u, -v)`` (same amplitude,
same orientation), except in the columns ``u = 0`` and ``u = Nyquist``, which hold both cells of each
pair ``(v, -v)``: there only one of them takes part, so every direction's mean weighs its cells as
the full spectrum's does.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.ndimage import gaussian_filter1d

from rose.errors import RoseError
from rose.frozen import ReadOnlyArrays, seal
from rose.limits import finite_number, shape_problem
from rose.params import ANGULAR_RESOLUTION_RANGE_DEG

__all__ = [
    "DirectionBins",
    "cumulative_amplitude",
    "direction_bins",
    "frequency_axes",
    "frequency_grid",
]


@dataclass(frozen=True, eq=False)
class DirectionBins(ReadOnlyArrays):
    """Assignment of half-plane spectrum cells to wall-orientation bins, for one padded shape.

    Attributes
    ----------
    centres : ndarray of float64, shape (B,)
        Wall orientation at the centre of each bin, radians in ``[0, pi)``; bin 0 is centred on 0.
    cell_index : ndarray of intp, shape (M,)
        Flat indices into the half-plane of the cells that take part (inside the annulus; in the
        columns u = 0 and u = Nyquist, which hold both cells of each mirrored pair, one of them),
        grouped by bin (bin 0's cells first, each bin's in flat order).
    bin_index : ndarray of int32, shape (M,)
        Bin of each of those cells (non-decreasing).
    bin_starts : ndarray of intp, shape (B,)
        Where each bin's cells start in ``cell_index`` (``M`` for empty bins at the end).
    counts : ndarray of float64, shape (B,)
        Number of cells in each bin (0 for bins no cell falls in, on very small maps).
    radius_span_px : float
        Radial extent of the annulus in cells of the longer side (turns a mean into a sum over radius).
    """

    centres: npt.NDArray[np.float64]
    cell_index: npt.NDArray[np.intp]
    bin_index: npt.NDArray[np.int32]
    bin_starts: npt.NDArray[np.intp]
    counts: npt.NDArray[np.float64]
    radius_span_px: float


def frequency_axes(
    shape: tuple[int, int],
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    """Frequencies of the half-plane's columns and rows of a padded ``shape``, in cells of the
    longer side: ``(u, v)``, float32 of shapes ``(cols // 2 + 1,)`` and ``(rows,)``."""
    rows, cols = shape
    longer = max(rows, cols)
    u = (np.fft.rfftfreq(cols) * longer).astype(np.float32)
    v = (np.fft.fftfreq(rows) * longer).astype(np.float32)
    return u, v


def frequency_grid(
    shape: tuple[int, int],
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    """Frequencies of the half-plane cells of a padded ``shape``, in cells of the longer side.

    Returns ``(u, v)``, each float32 of shape ``(rows, cols // 2 + 1)``: ``u`` along columns (map x),
    ``v`` along rows (map y). Scaling by the longer side makes one unit one spectrum cell on that side
    and keeps angles physical on non-square maps. Not cached (4 MB for a 1000 x 1000 map): the
    direction bins made from it are, and the structure mask reads :func:`frequency_axes`.
    """
    u, v = frequency_axes(shape)
    u_grid, v_grid = np.broadcast_arrays(u[np.newaxis, :], v[:, np.newaxis])
    return u_grid.copy(), v_grid.copy()


def direction_bins(
    shape: tuple[int, int], *, angular_resolution_deg: float, min_radius_px: float
) -> DirectionBins:
    """Bin the half-plane cells of a padded ``shape`` by the wall orientation they stand for.

    A spectrum line at angle ``psi`` comes from image lines at ``psi + pi/2``; cells between
    ``min_radius_px`` and the Nyquist circle (half the longer side) take part, so every direction sees
    the same radial range, each once for itself and its mirror (module notes). Cached by value
    (read-only: shared by every call with the same values).

    Raises
    ------
    RoseError
        If ``shape`` is not two whole numbers >= 1, ``angular_resolution_deg`` is outside
        :data:`rose.params.ANGULAR_RESOLUTION_RANGE_DEG` or ``min_radius_px`` is not a finite
        number >= 0.
    """
    problem = shape_problem(shape, smallest=1)
    if problem is not None:
        msg = f"direction_bins: shape {problem}"
        raise RoseError(msg)
    low, high = ANGULAR_RESOLUTION_RANGE_DEG
    if not (finite_number(angular_resolution_deg) and low <= angular_resolution_deg <= high):
        msg = f"angular_resolution_deg must be in {low}..{high}, got {angular_resolution_deg!r}"
        raise RoseError(msg)
    if not (finite_number(min_radius_px) and min_radius_px >= 0):
        msg = f"min_radius_px must be a finite number >= 0, got {min_radius_px!r}"
        raise RoseError(msg)
    # The cache's keys as Python numbers, checked: a shape given as a list or an array (which the
    # other stages take) is unhashable, and one entry serves equal values of any type.
    return _direction_bins(
        (int(shape[0]), int(shape[1])), float(angular_resolution_deg), float(min_radius_px)
    )


@functools.lru_cache(maxsize=8)
def _direction_bins(
    shape: tuple[int, int], angular_resolution_deg: float, min_radius_px: float
) -> DirectionBins:
    """:func:`direction_bins` of checked Python values."""
    n_bins = max(1, round(180.0 / angular_resolution_deg))
    step = math.pi / n_bins
    # Worked out once per padded shape: a SLAM map that grows gets a new one every few snapshots
    # (the fast FFT lengths lie a few percent apart), and its analysis then paid this twice over.
    # So no full grids of u and v (each cell's from its row and column), and the cells grouped by
    # bin with a radix sort of 16-bit bins: the same bins as the plain computation, bit for bit.
    u, v = frequency_axes(shape)
    radius = np.hypot(u[np.newaxis, :], v[:, np.newaxis])
    outer = max(shape) / 2.0
    inside = (radius >= min_radius_px) & (radius <= outer)
    # One cell of each mirrored pair in the columns u = 0 and u = Nyquist (module notes): the rows
    # whose mirror row is lower are left out. Both counted, the cells on the v axis weighed twice
    # in their bins' means, and a map turned by 90 degrees read another curve at 0 and 90 degrees
    # (8 % apart on Bormann's lab_ipa, which found a third direction only when turned).
    rows = shape[0]
    mirrored = np.arange(rows) > (-np.arange(rows)) % rows
    inside[mirrored, 0] = False
    if shape[1] % 2 == 0:
        inside[mirrored, -1] = False
    cell_index = np.flatnonzero(inside)
    row_of, column_of = np.divmod(cell_index, u.size)
    wall_angle = np.arctan2(v[row_of], u[column_of]) + math.pi / 2
    bins = np.rint(wall_angle / step).astype(np.int32)
    # arctan2 lies in [-pi, pi], so the bins in [-n_bins / 2, 3 n_bins / 2]: taken modulo n_bins.
    bins[bins >= n_bins] -= n_bins
    bins[bins < 0] += n_bins
    counts = np.bincount(bins, minlength=n_bins)
    # Grouped by bin, in flat order within each: a bin's sum is then one contiguous reduction
    # (np.add.reduceat: half the time of np.bincount; its pairwise summation rounds differently
    # by an ulp at most, the results of the data set's maps are bit-identical). Bins fit in 16 bits
    # (ANGULAR_RESOLUTION_RANGE_DEG: at most 18,000), for which numpy's stable sort is a radix sort.
    key = bins.astype(np.int16) if n_bins <= np.iinfo(np.int16).max else bins
    order = np.argsort(key, kind="stable")
    starts = np.zeros(n_bins, dtype=np.intp)
    np.cumsum(counts[:-1], out=starts[1:])
    return seal(
        DirectionBins(
            centres=np.arange(n_bins, dtype=np.float64) * step,
            cell_index=cell_index[order],
            # 32 bits: half the memory of intp, held per shape in the cache.
            bin_index=np.repeat(np.arange(n_bins, dtype=np.int32), counts),
            bin_starts=starts,
            counts=counts.astype(np.float64),
            radius_span_px=max(outer - min_radius_px, 0.0),
        )
    )


#: A circular Gaussian narrower than this (standard deviation, bins) leaves every bin as it is.
_SMOOTHING_IDENTITY_BELOW_BINS = 0.125


def cumulative_amplitude(
    amplitude_half: npt.NDArray[np.float32], bins: DirectionBins, *, smoothing_bins: float
) -> npt.NDArray[np.float64]:
    """Amplitude summed along each direction (the paper's ``A_p^C``), shape ``(B,)``.

    Each bin's mean amplitude times the radial span: the sum over radius of a polar resampling, without
    the resampling. Bins no cell falls in (tiny maps) are interpolated from their neighbours; the result
    is then smoothed with a circular Gaussian of ``smoothing_bins`` bins.

    Raises
    ------
    RoseError
        If ``smoothing_bins`` is not a finite number >= 0, or ``amplitude_half`` is smaller than
        the half-plane ``bins`` were made for.
    """
    if not isinstance(bins, DirectionBins):
        msg = f"cumulative_amplitude: bins must be direction_bins(...), got {type(bins).__name__}"
        raise RoseError(msg)
    if not (finite_number(smoothing_bins) and smoothing_bins >= 0):
        msg = f"smoothing_bins must be a finite number >= 0, got {smoothing_bins!r}"
        raise RoseError(msg)
    amplitude_half = np.asarray(amplitude_half)
    if bins.cell_index.size and amplitude_half.size <= int(bins.cell_index.max()):
        msg = (
            f"cumulative_amplitude: the amplitude (shape {amplitude_half.shape}) is smaller than "
            "the half-plane the direction bins were made for"
        )
        raise RoseError(msg)
    n_bins = bins.centres.size
    filled = bins.counts > 0
    if not filled.any():
        return np.zeros(n_bins)
    # One zero past the end: empty bins at the end start there (reduceat needs a valid index),
    # and the last filled bin ends there. Empty bins' entries are not used.
    gathered = np.empty(bins.cell_index.size + 1)
    gathered[:-1] = amplitude_half.ravel()[bins.cell_index]
    gathered[-1] = 0.0
    sums = np.add.reduceat(gathered, bins.bin_starts)
    means = np.zeros(n_bins)
    means[filled] = sums[filled] / bins.counts[filled]
    if not filled.all():
        positions = np.arange(n_bins)
        means = np.interp(positions, positions[filled], means[filled], period=n_bins)
    cumulative = means * bins.radius_span_px
    # SciPy's kernel spans round(4 sigma) bins each side: below 1/8 bin it is [1], the identity
    # (and for sigma < 1e-154 its exp(-x^2 / 2 sigma^2) underflows to NaN, a silent W of 1).
    if smoothing_bins >= _SMOOTHING_IDENTITY_BELOW_BINS and n_bins > 1:
        cumulative = gaussian_filter1d(cumulative, smoothing_bins, mode="wrap")
    return cumulative
