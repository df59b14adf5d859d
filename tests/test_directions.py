"""rose.directions: peaks of the circular cumulative amplitude, found once across the wrap at pi."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rose.directions import find_direction_peaks, refine_peak_positions

N = 360  # bins over [0, pi)


def circular_bump(centre: float, *, width: float = 4.0, n: int = N) -> np.ndarray:
    """A Gaussian bump on the circle of ``n`` bins (distance measured around the wrap)."""
    k = np.arange(n)
    d = np.abs(k - centre) % n
    d = np.minimum(d, n - d)
    return np.exp(-0.5 * (d / width) ** 2)


@pytest.mark.parametrize("centre", [0, 1, N - 1, N // 2])
def test_a_single_bump_is_found_once_with_full_prominence(centre: int) -> None:
    signal = 1.0 + circular_bump(centre)
    peaks = find_direction_peaks(signal, prominence_fraction=0.5)
    assert_array_equal(peaks.indices, [centre])
    # The bump rises from the floor on both sides of the wrap: its prominence is the whole span.
    assert_allclose(peaks.prominences, [1.0], atol=1e-9)


def test_plain_find_peaks_misses_a_peak_at_zero() -> None:
    # Why the signal is tripled: scipy cannot see a peak at the array's first sample.
    from scipy.signal import find_peaks

    signal = 1.0 + circular_bump(0)
    assert 0 not in find_peaks(signal)[0]
    assert_array_equal(find_direction_peaks(signal, prominence_fraction=0.5).indices, [0])


def test_a_plateau_across_the_wrap_is_one_peak() -> None:
    signal = 1.0 + circular_bump(N - 0.5)  # bins N-1 and 0 equally high
    assert signal[N - 1] == pytest.approx(signal[0])
    peaks = find_direction_peaks(signal, prominence_fraction=0.5)
    assert peaks.indices.size == 1
    assert int(peaks.indices[0]) in (N - 1, 0)


@pytest.mark.parametrize("shift", [0, 1, 45, N - 46, N - 1])
def test_rotating_the_signal_rotates_the_peaks(shift: int) -> None:
    signal = 1.0 + circular_bump(3) + 0.8 * circular_bump(93) + 0.3 * circular_bump(200)
    base = find_direction_peaks(signal, prominence_fraction=0.2)
    rolled = find_direction_peaks(np.roll(signal, shift), prominence_fraction=0.2)
    assert_array_equal(rolled.indices, (base.indices + shift) % N)
    assert_allclose(rolled.prominences, base.prominences, rtol=1e-12)
    assert_array_equal(base.indices, [3, 93, 200])  # strongest first


def test_prominence_threshold_drops_small_peaks() -> None:
    signal = 1.0 + circular_bump(10) + 0.3 * circular_bump(100)
    assert_array_equal(find_direction_peaks(signal, prominence_fraction=0.5).indices, [10])
    assert_array_equal(find_direction_peaks(signal, prominence_fraction=0.2).indices, [10, 100])


@pytest.mark.parametrize("signal", [np.full(N, 3.0), np.ones(2), np.empty(0)])
def test_constant_or_tiny_signals_have_no_peak(signal: np.ndarray) -> None:
    peaks = find_direction_peaks(signal, prominence_fraction=0.5)
    assert peaks.indices.size == 0 and peaks.prominences.size == 0


@pytest.mark.parametrize("centre", [0.3, N - 0.3, 0.0, 17.25])
def test_refined_position_across_the_wrap(centre: float) -> None:
    signal = circular_bump(centre, width=3.0)
    index = int(np.argmax(signal))
    refined = refine_peak_positions(signal, np.array([index]))[0]
    # A parabola through three samples of a Gaussian: within a few hundredths of a bin.
    error = (refined - centre + N / 2) % N - N / 2
    assert abs(error) < 0.05
