"""The structure mask: the half-plane cells within the kept half-width of every direction's strip."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.fft

from rose.scoring import inverse_to_map, structure_mask
from rose.spectrum import padded_shape
from rose.unfold import frequency_grid


def _every_cell(shape: tuple[int, int], directions: np.ndarray, half_width_px: float) -> np.ndarray:
    """The definition, tested on every cell (what structure_mask must equal)."""
    u, v = frequency_grid(shape)
    mask = np.zeros(u.shape, dtype=bool)
    for direction in directions:
        c, s = np.float32(math.cos(direction)), np.float32(math.sin(direction))
        mask |= np.abs(u * c + v * s) <= half_width_px
    return mask


@pytest.mark.parametrize(
    "size", [(736, 1152), (608, 566), (1674, 1006), (5, 7), (1, 2), (10, 1000), (1000, 10)]
)
def test_structure_mask_equals_testing_every_cell(size: tuple[int, int]) -> None:
    shape = padded_shape(size)
    rng = np.random.default_rng(sum(size))
    cases = [np.array([0.0, math.pi / 2]), np.array([math.pi / 4, 3 * math.pi / 4]), np.empty(0)]
    cases += [rng.uniform(0.0, math.pi, rng.integers(1, 4)) for _ in range(12)]
    for directions in cases:
        for half_width in (0.5, 2.3, 2.5, 9.0):
            expected = _every_cell(shape, directions, half_width)
            got = structure_mask(shape, directions, half_width_px=half_width)
            np.testing.assert_array_equal(got, expected, err_msg=f"{directions} {half_width}")


def test_the_strips_keep_a_small_share_of_the_spectrum() -> None:
    shape = padded_shape((736, 1152))
    mask = structure_mask(shape, np.array([0.03, 0.03 + math.pi / 2]), half_width_px=2.5)
    assert mask[0, 0]  # DC is kept, as in the authors' code
    assert 0.002 < mask.mean() < 0.02


@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_the_inverse_transform_is_irfft2_cropped(dtype: type) -> None:
    """``inverse_to_map`` (a column pass, then the rows) gives ``scipy.fft.irfft2`` of the padded
    shape cropped to the map, to the dtype's rounding: maps of 1 x N, N x 1, prime, odd and even
    sides, padded or not, and spectra with any DC and Nyquist column (not Hermitian there)."""
    rng = np.random.default_rng(7)
    sides = [1, 2, 3, 5, 16, 17, 31, 64, 97, 100, 127, 250]
    eps = np.finfo(np.float32 if dtype == np.complex64 else np.float64).eps
    for rows in sides:
        for cols in sides:
            padded = padded_shape((rows, cols))
            half = (padded[0], padded[1] // 2 + 1)
            spectrum = (rng.standard_normal(half) + 1j * rng.standard_normal(half)).astype(dtype)
            expected = scipy.fft.irfft2(spectrum, s=padded)
            got = inverse_to_map(spectrum.copy(), (rows, cols))
            assert got.shape == (rows, cols)
            assert got.dtype == expected.dtype
            tolerance = 8 * eps * float(np.abs(expected).max())
            np.testing.assert_allclose(
                got, expected[:rows, :cols], rtol=0, atol=tolerance, err_msg=f"{rows} x {cols}"
            )


@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_a_band_of_rows_of_the_inverse_is_bit_identical_to_those_rows_of_the_whole(
    dtype: type,
) -> None:
    """``rows``: only those rows are transformed, each bit for bit the row of the whole inverse
    (the scores of a map's occupied cells do not depend on how many margin rows it has)."""
    rng = np.random.default_rng(11)
    for rows, cols in [(1, 17), (17, 1), (97, 100), (250, 127), (64, 64)]:
        padded = padded_shape((rows, cols))
        half = (padded[0], padded[1] // 2 + 1)
        spectrum = (rng.standard_normal(half) + 1j * rng.standard_normal(half)).astype(dtype)
        whole = inverse_to_map(spectrum.copy(), (rows, cols))
        for band in (slice(0, rows), slice(rows // 3, rows // 3 + 1), slice(rows // 2, rows)):
            got = inverse_to_map(spectrum.copy(), (rows, cols), rows=band)
            assert got.shape == (band.stop - band.start, cols)
            assert got.tobytes() == np.ascontiguousarray(whole[band]).tobytes()
