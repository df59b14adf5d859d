"""Local structure scoring: keep the spectrum along the dominant directions, transform back."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import scipy.fft

from rose.unfold import frequency_grid

__all__ = ["nominal_reference_map", "structure_mask"]


def structure_mask(
    shape: tuple[int, int], directions: npt.NDArray[np.float64], *, half_width_px: float
) -> npt.NDArray[np.bool_]:
    """The paper's structure part S of the half-plane spectrum of a padded ``shape``.

    Cells within ``half_width_px`` (cells of the longer side) of the line through DC perpendicular to
    each wall direction (radians, map frame), at every radius, DC included as in the authors' code.

    Returns
    -------
    ndarray of bool, shape (rows, cols // 2 + 1)
    """
    u, v = frequency_grid(shape)
    mask = np.zeros(u.shape, dtype=bool)
    for direction in directions:
        # The spectrum line of walls at `direction` runs along (cos, sin) of direction + pi/2,
        # i.e. (-sin, cos); the distance from it is the projection on the wall direction itself.
        distance = np.abs(u * np.float32(np.cos(direction)) + v * np.float32(np.sin(direction)))
        mask |= distance <= half_width_px
    return mask


def nominal_reference_map(
    spectrum: npt.NDArray[np.complex64], mask: npt.NDArray[np.bool_], shape: tuple[int, int]
) -> npt.NDArray[np.float32]:
    """Inverse transform of the spectrum restricted to ``mask``, cropped to the map's ``shape``.

    The mask is point-symmetric, so the reconstruction is real and ``irfft2`` gives it directly
    (the authors take ``abs`` of a complex ``ifft2``; we keep the sign, which the paper's formula has).

    Returns
    -------
    ndarray of float32, shape ``shape``
    """
    padded_rows = spectrum.shape[0]
    padded_cols = 2 * (spectrum.shape[1] - 1)
    restricted = np.where(mask, spectrum, np.complex64(0))
    reference = scipy.fft.irfft2(restricted, s=(padded_rows, padded_cols))
    return np.ascontiguousarray(reference[: shape[0], : shape[1]], dtype=np.float32)
