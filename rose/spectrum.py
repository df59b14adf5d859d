"""Fourier transform of the occupied mask.

The amplitude spectrum of a real image is point-symmetric, so only the half-plane computed by
``rfft2`` is kept; every stage downstream works on it. Frequencies are expressed in cycles per cell,
which makes spectrum angles equal image angles on non-square maps without padding to a square.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import scipy.fft

from rose.errors import RoseError
from rose.limits import shape_problem
from rose.params import MIN_PADDED_SIDE, min_padded_side

__all__ = ["MIN_PADDED_SIDE", "full_amplitude_spectrum", "half_spectrum", "padded_shape"]

#: Largest share of the rows in use for which transforming only those rows beats ``rfft2``
#: (measured on the benchmark maps: 42 % of the rows: 16-40 % faster; 97 %: 18 % slower).
_ROWS_IN_USE_FRACTION = 0.75


def padded_shape(shape: tuple[int, int]) -> tuple[int, int]:
    """Shape ``(rows, cols)`` the map is zero-padded to: fast FFT lengths, with an even column count,
    and no side under 16 cells unless the whole map is smaller.

    The even column count lets the half-plane width determine the full width.
    """
    problem = shape_problem(shape, smallest=0)
    if problem is not None:
        msg = f"padded_shape: shape {problem}"
        raise RoseError(msg)
    shortest = min_padded_side(shape)
    rows = scipy.fft.next_fast_len(max(shape[0], shortest), real=True)
    cols = scipy.fft.next_fast_len(max(shape[1], shortest, 2), real=True)
    while cols % 2:
        cols = scipy.fft.next_fast_len(cols + 1, real=True)
    return rows, cols


def half_spectrum(
    occupied: npt.NDArray[np.bool_], shape: tuple[int, int]
) -> npt.NDArray[np.complex64]:
    """Real FFT of ``occupied`` zero-padded to ``shape`` (cut to it along an axis where it is longer,
    as ``scipy.fft.rfft2``'s ``s`` does; :func:`padded_shape` is never shorter).

    Returns
    -------
    ndarray of complex64, shape (shape[0], shape[1] // 2 + 1)
        Unshifted half-plane spectrum: row ``k`` holds vertical frequency ``fftfreq(rows)[k]``,
        column ``j`` horizontal frequency ``j / cols`` (cycles per cell).

    Raises
    ------
    RoseError
        If ``occupied`` is not 2D or ``shape`` not two whole numbers >= 1.
    """
    occupied = np.asarray(occupied)
    if occupied.ndim != 2:
        msg = f"half_spectrum: occupied must be a 2D mask, got an array of shape {occupied.shape}"
        raise RoseError(msg)
    problem = shape_problem(shape, smallest=1)
    if problem is not None:
        msg = f"half_spectrum: shape {problem}"
        raise RoseError(msg)
    # rfft2 is a real FFT of every row, then a complex FFT of every column. Rows without an occupied
    # cell transform to zeros: when they are many (SLAM maps often hold wide unknown margins, and
    # sparse maps whole empty rows between walls), only the rows in use are transformed,
    # bit-identical to rfft2. When nearly every row is in use, rfft2 is faster (no extra copy).
    rows_in_use = np.flatnonzero(occupied[: shape[0]].any(axis=1))
    if rows_in_use.size == 0 or rows_in_use.size > _ROWS_IN_USE_FRACTION * shape[0]:
        return scipy.fft.rfft2(occupied.astype(np.float32), s=shape)
    first, last = int(rows_in_use[0]), int(rows_in_use[-1]) + 1
    half = np.zeros((shape[0], shape[1] // 2 + 1), dtype=np.complex64)
    if last - first == rows_in_use.size:  # one band: a slice, no gather
        band = occupied[first:last, : shape[1]].astype(np.float32)
        half[first:last] = scipy.fft.rfft(band, n=shape[1], axis=1)
    else:
        rows = occupied[rows_in_use, : shape[1]].astype(np.float32)
        half[rows_in_use] = scipy.fft.rfft(rows, n=shape[1], axis=1)
    return scipy.fft.fft(half, axis=0, overwrite_x=True)


def full_amplitude_spectrum(
    amplitude_half: npt.NDArray[np.float32], shape: tuple[int, int]
) -> npt.NDArray[np.float32]:
    """Rebuild the full, fftshifted amplitude spectrum of shape ``shape`` from its half-plane.

    Uses ``|F(-k)| = |F(k)|`` for real images; DC ends up at ``(rows // 2, cols // 2)``.

    Raises
    ------
    RoseError
        If ``shape`` is not two whole numbers >= 1, the column count even, with ``amplitude_half``
        of shape ``(rows, cols // 2 + 1)``.
    """
    amplitude_half = np.asarray(amplitude_half)
    problem = shape_problem(shape, smallest=1)
    if problem is None and shape[1] % 2:
        problem = f"must have an even column count (a padded shape), got {shape!r}"
    if problem is None and amplitude_half.shape != (shape[0], shape[1] // 2 + 1):
        problem = (
            f"{shape!r} is not the padded shape of a half-plane of shape {amplitude_half.shape} "
            f"(that is (rows, cols // 2 + 1))"
        )
    if problem is not None:
        msg = f"full_amplitude_spectrum: shape {problem}"
        raise RoseError(msg)
    rows, cols = shape
    half_cols = amplitude_half.shape[1]
    full = np.empty((rows, cols), dtype=np.float32)
    full[:, :half_cols] = amplitude_half
    mirrored_rows = (-np.arange(rows)) % rows
    full[:, half_cols:] = amplitude_half[mirrored_rows, 1 : cols // 2][:, ::-1]
    return np.fft.fftshift(full)
