"""The half-plane spectrum: the real FFT of the occupied cells, transformed row band only."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.fft
from real_data import FR079_DIR, repo_data

import rose
from rose.grid import occupied_mask
from rose.spectrum import half_spectrum, padded_shape


@pytest.mark.parametrize("stage", [2, 9, 15])
def test_half_spectrum_is_bit_identical_to_rfft2_on_real_maps(stage: int) -> None:
    grid = rose.load_map(repo_data(f"{FR079_DIR}/map{stage}.yaml")).grid
    occupied = occupied_mask(grid, occupied_threshold=65)
    shape = padded_shape(grid.shape)
    expected = scipy.fft.rfft2(occupied.astype(np.float32), s=shape)
    spectrum = half_spectrum(occupied, shape)
    assert spectrum.dtype == np.complex64
    np.testing.assert_array_equal(spectrum, expected)


@pytest.mark.parametrize(
    "rows",
    [slice(0, 1), slice(39, 40), slice(10, 25), slice(0, 40), slice(1, 38, 3), slice(0, 40, 2)],
    ids=["first-row", "last-row", "middle-band", "every-row", "every-third", "every-other"],
)
def test_occupied_rows_anywhere_match_rfft2(rows: slice) -> None:
    rng = np.random.default_rng(3)
    occupied = np.zeros((40, 30), dtype=bool)
    occupied[rows] = rng.random((len(range(40)[rows]), 30)) < 0.3
    for shape in (padded_shape(occupied.shape), (36, 32)):  # padded, and cropped like rfft2's s=
        expected = scipy.fft.rfft2(occupied.astype(np.float32), s=shape)
        np.testing.assert_array_equal(half_spectrum(occupied, shape), expected)


def test_an_empty_map_has_a_zero_spectrum() -> None:
    occupied = np.zeros((12, 7), dtype=bool)
    shape = padded_shape(occupied.shape)
    spectrum = half_spectrum(occupied, shape)
    assert spectrum.shape == (shape[0], shape[1] // 2 + 1)
    assert not spectrum.any()


@pytest.mark.parametrize("tiny", [1e-3, 1e-160, 1e-200])
def test_a_vanishing_smoothing_is_no_smoothing(tiny: float) -> None:
    """A Gaussian far narrower than a bin is the identity: W and the directions of no smoothing
    (the kernel underflowed to NaN, a silent W of 1, or raised ZeroDivisionError)."""
    grid = rose.load_map(repo_data(f"{FR079_DIR}/map15.yaml")).grid
    none = rose.analyze(grid, smoothing_deg=0.0)
    narrow = rose.analyze(grid, smoothing_deg=tiny)
    assert narrow.structure_score == none.structure_score < 0.4
    np.testing.assert_array_equal(narrow.dominant_directions, none.dominant_directions)
