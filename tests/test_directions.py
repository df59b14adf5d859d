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


def _random_signals() -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    signals = [rng.random(n) for n in (3, 4, 5, 17, 360)]
    # Flat tops and flat valleys of every length, also touching the ends.
    signals += [np.round(rng.random(n) * 4) for n in (3, 8, 50, 361)]
    signals += [np.array([1.0, 1, 1]), np.array([0.0, 1, 1, 0]), np.array([2.0, 1, 2, 2, 1, 2])]
    signals += [np.cumsum(rng.standard_normal(1080)) for _ in range(5)]
    return signals


@pytest.mark.parametrize("index", range(17))
def test_peaks_and_prominences_match_scipy(index: int) -> None:
    # Our numpy peak finder replaces scipy.signal.find_peaks (whose import costs ~1.5 s per process):
    # it must find the same peaks, plateaus included, with the same prominences.
    from scipy.signal import find_peaks
    from scipy.signal import peak_prominences as scipy_prominences

    from rose.directions import local_maxima, peak_prominences

    signal = _random_signals()[index]
    expected, _ = find_peaks(signal)
    found = local_maxima(signal)
    assert_array_equal(found, expected)
    assert_array_equal(peak_prominences(signal, found), scipy_prominences(signal, expected)[0])


@pytest.mark.parametrize(
    "relative",
    [
        *(f"rose2_aislabunimi/Freiburg_Building_079_partial/map{i}.yaml" for i in (2, 8, 15)),
        "bormann_ipa_room_segmentation/Freiburg52_scan_furnitures.png",
        "aws_small_warehouse_005/map_rotated.png",
    ],
)
def test_direction_peaks_match_scipy_on_real_maps(relative: str) -> None:
    from real_data import repo_data
    from scipy.signal import find_peaks

    import rose

    cumulative = rose.analyze(rose.load_map(repo_data(relative)).grid).cumulative_amplitude
    n = cumulative.size
    span = cumulative.max() - cumulative.min()
    peaks, props = find_peaks(np.tile(cumulative, 3), prominence=0.1 * span)
    middle = (peaks >= n) & (peaks < 2 * n)
    ours = find_direction_peaks(cumulative, prominence_fraction=0.1)
    order = np.argsort(-props["prominences"][middle], kind="stable")
    assert ours.indices.size >= 2  # buildings: at least two directions
    assert_array_equal(ours.indices, (peaks[middle] - n)[order])
    assert_allclose(ours.prominences, props["prominences"][middle][order] / span, rtol=0)


@pytest.mark.parametrize("fraction", [0.0, 0.1, 0.5, 0.9])
@pytest.mark.parametrize("index", range(17))
def test_direction_peaks_match_scipy_at_every_threshold(index: int, fraction: float) -> None:
    # Peaks too low to reach the threshold are skipped before their prominence is computed: the
    # result must stay what SciPy's prominence filter keeps.
    from scipy.signal import find_peaks

    signal = _random_signals()[index]
    n = signal.size
    span = signal.max() - signal.min()
    if n < 3 or span <= 1e-4 * np.abs(signal).max():
        return
    peaks, props = find_peaks(np.tile(signal, 3), prominence=fraction * span)
    middle = (peaks >= n) & (peaks < 2 * n)
    order = np.argsort(-props["prominences"][middle], kind="stable")
    ours = find_direction_peaks(signal, prominence_fraction=fraction)
    assert_array_equal(ours.indices, (peaks[middle] - n)[order])
    assert_allclose(ours.prominences, props["prominences"][middle][order] / span, rtol=0)


@pytest.mark.parametrize(
    ("angle", "digits", "folded"),
    [
        (-1e-15, None, 0.0),  # % 180 alone gives 180.0 in floating point
        (179.996, 2, 0.0),  # rounds up to 180
        (24.80000000000001, 2, 24.8),
        (-90.0, None, 90.0),
        (360.5, 1, 0.5),
    ],
)
def test_fold_deg_stays_in_half_open_range(angle: float, digits: int | None, folded: float) -> None:
    from rose.directions import fold_deg

    value = fold_deg(angle, digits)
    assert value == pytest.approx(folded, abs=1e-12)
    assert 0.0 <= value < 180.0


@pytest.mark.parametrize("shape", [(64, 64), (9, 40), (736, 1152)])
def test_per_direction_sums_are_those_of_a_bincount(shape: tuple[int, int]) -> None:
    """The grouped reduction gives np.bincount's sums up to rounding, also with empty bins (a
    small map leaves some bins without a cell, at the end too), on amplitudes spanning many
    orders of magnitude as real spectra do."""
    from rose.unfold import cumulative_amplitude, direction_bins

    rng = np.random.default_rng(1)
    size = (shape[0], shape[1] // 2 + 1)
    amplitude = (10.0 ** rng.uniform(-3, 6, size) * rng.random(size)).astype(np.float32)
    bins = direction_bins(shape, angular_resolution_deg=0.5, min_radius_px=4.0)
    sums = np.bincount(
        bins.bin_index, weights=amplitude.ravel()[bins.cell_index], minlength=bins.centres.size
    )
    filled = bins.counts > 0
    expected = sums[filled] / bins.counts[filled] * bins.radius_span_px
    got = cumulative_amplitude(amplitude, bins, smoothing_bins=0)
    # Rounding differs by an ulp or so; one cell missing from a bin (it did, at the last filled
    # bin before empty ones) is off by far more. Empty bins are interpolated, not compared.
    assert_allclose(got[filled], expected, rtol=1e-12)


@pytest.mark.parametrize(
    ("shape", "resolution_deg", "min_radius_px"),
    [((750, 1152), 0.25, 3.0), ((1, 1), 0.25, 0.0), ((17, 33), 0.01, 0.0), ((64, 40), 30.0, 4.0)],
)
def test_direction_bins_are_the_plain_computations(
    shape: tuple[int, int], resolution_deg: float, min_radius_px: float
) -> None:
    """The bins are worked out without full frequency grids and sorted by a 16-bit radix sort
    (a growing SLAM map needs them for a new padded shape every few snapshots): every cell in the
    very bin, and in the very order, of the plain computation, which W and the labels rest on."""
    import math

    from rose.unfold import direction_bins, frequency_grid

    bins = direction_bins(shape, angular_resolution_deg=resolution_deg, min_radius_px=min_radius_px)
    n_bins = max(1, round(180.0 / resolution_deg))
    u, v = frequency_grid(shape)
    radius = np.hypot(u, v)
    inside = (radius >= min_radius_px) & (radius <= max(shape) / 2.0)
    mirrored = np.arange(shape[0]) > (-np.arange(shape[0])) % shape[0]
    inside[mirrored, 0] = False
    if shape[1] % 2 == 0:
        inside[mirrored, -1] = False
    cells = np.flatnonzero(inside)
    angle = np.arctan2(v.ravel()[cells], u.ravel()[cells]) + math.pi / 2
    plain = np.rint(angle / (math.pi / n_bins)).astype(np.intp) % n_bins
    order = np.argsort(plain, kind="stable")
    assert np.array_equal(bins.cell_index, cells[order])
    assert np.array_equal(bins.bin_index, plain[order])
    assert np.array_equal(bins.counts, np.bincount(plain, minlength=n_bins))
    assert np.array_equal(bins.bin_starts, np.searchsorted(plain[order], np.arange(n_bins)))


def test_one_decimal_views_round_the_reported_direction() -> None:
    """The same wall read 176.2 in the tables (one decimal of the reported 176.15) and 176.1 in
    Rerun (one decimal of the exact 176.1499...): every view rounds the reported value."""
    import math

    from rose.directions import map_frame_deg

    exact = [math.radians(176.1499999), math.radians(86.2649)]
    assert map_frame_deg(exact) == [176.15, 86.26]
    assert map_frame_deg(exact, digits=1) == [round(176.15, 1), round(86.26, 1)] == [176.2, 86.3]
