"""What library users rely on beyond the numbers: results cannot be changed by accident (also
after pickling, and not through a shared cache), reprs a user can read, and clear errors for
invalid arguments instead of Python's own words from deep inside."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from synthetic import add_clutter, floor_plan

import rose
from rose.breaks import contradicted_walls
from rose.cleaning import clean
from rose.unfold import direction_bins


@pytest.fixture(scope="module")
def furnished() -> np.ndarray:
    plan = floor_plan(angle_deg=10.0)
    mask, _ = add_clutter(plan, blobs=12, specks=40, seed=1)
    return np.where(mask, np.int8(100), np.int8(0))


def _arrays(obj: object) -> dict[str, np.ndarray]:
    return {k: v for k, v in vars(obj).items() if isinstance(v, np.ndarray)}


def test_results_arrays_are_read_only_also_after_pickling(furnished) -> None:
    result = rose.analyze(furnished)
    cleaned = clean(furnished, result, resolution_m=0.05)
    walls = rose.extract_walls(furnished, result=result)
    for obj in (
        result,
        cleaned,
        walls,
        pickle.loads(pickle.dumps(result)),
        pickle.loads(pickle.dumps(walls)),
    ):
        arrays = _arrays(obj)
        assert arrays, type(obj).__name__
        for name, array in arrays.items():
            assert not array.flags.writeable, f"{type(obj).__name__}.{name}"
    with pytest.raises(ValueError, match="read-only"):
        result.clutter[:] = False  # would have changed what clean(method="paper") removes
    pickled = [pickle.loads(pickle.dumps(obj)) for obj in (result, cleaned, walls)]
    for obj in (result, cleaned, walls, *pickled):  # what the library made stays read-only
        for array in _arrays(obj).values():
            with pytest.raises(ValueError, match="cannot set WRITEABLE"):
                array.flags.writeable = True
    assert clean(furnished, result, method="paper").removed_count == result.clutter_count > 0


def test_the_direction_bins_cache_cannot_be_changed_through_a_result(furnished) -> None:
    first = rose.analyze(furnished)
    bins = direction_bins(first.padded_shape, angular_resolution_deg=0.5, min_radius_px=3.0)
    for array in _arrays(bins).values():
        assert not array.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        np.degrees(first.direction_bins, out=first.direction_bins)
    with pytest.raises(ValueError, match="cannot set WRITEABLE"):
        bins.counts.flags.writeable = True
    assert rose.analyze(furnished).structure_score == first.structure_score


def test_the_input_stays_writable_and_unchanged(furnished) -> None:
    grid = furnished.copy()
    rose.analyze(grid)
    assert grid.flags.writeable and np.array_equal(grid, furnished)


def test_the_papers_cleaning_leaves_the_arrays_of_a_callers_result_writable(furnished) -> None:
    """clean(method="paper") sealed the result's arrays it passes on: those of a RoseResult made
    with dataclasses.replace from the caller's arrays became read-only for good."""
    import dataclasses

    result = rose.analyze(furnished)
    mine = {name: getattr(result, name).copy() for name in ("structure", "clutter", "cleaned")}
    cleaning = clean(furnished, dataclasses.replace(result, **mine), method="paper")
    assert all(array.flags.writeable for array in mine.values())
    assert cleaning.removed_count == result.clutter_count > 0
    for own in (clean(furnished, result, method="paper"), cleaning):
        for name in ("rescued", "guarded", "completed", "cleaned", "kept", "removed"):
            array = getattr(own, name)
            assert not array.flags.writeable, name
            if own is not cleaning or name in ("rescued", "guarded", "completed"):
                with pytest.raises(ValueError, match="cannot set WRITEABLE"):
                    array.flags.writeable = True


def test_reprs_are_summaries(furnished) -> None:
    result = rose.analyze(furnished)
    cleaned = clean(furnished, result, resolution_m=0.05)
    walls = rose.extract_walls(furnished, result=result)
    error = rose.wall_error(walls, walls)
    for obj in (result, cleaned, walls, error):
        text = repr(obj)
        assert text.startswith(type(obj).__name__ + "(") and len(text) < 300 and "\n" not in text
    assert f"structure_score={result.structure_score:.4f}" in repr(result)
    assert f"removed={cleaned.removed_count}" in repr(cleaned)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"origin_xy_m": (0.0, "a")}, "origin_xy_m must be two finite numbers"),
        ({"origin_xy_m": 5.0}, "origin_xy_m must be two finite numbers"),
        ({"origin_yaw_rad": "0.x"}, "origin_yaw_rad must be a finite number"),
        ({"resolution_m": "0.1"}, "resolution_m must be a positive number"),
    ],
)
def test_wall_placement_arguments_are_checked(furnished, kwargs, words) -> None:
    for extract in (rose.extract_walls, rose.extract_walls_hough):
        with pytest.raises(rose.RoseError, match=words):
            extract(furnished, **kwargs)


@pytest.mark.parametrize(
    "bad",
    [{"tile_px": 2.5}, {"window_px": 100.5}, {"tile_px": "5"}, {"window_px": None}, {"tile_px": 0}],
)
def test_break_tile_and_window_are_checked(furnished, bad) -> None:
    with pytest.raises(rose.RoseError, match=r"must be an integer (>= 1|in 1\.\.1000)"):
        contradicted_walls(furnished, furnished, **bad)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"match_angle_deg": -5}, "match_angle_deg must be a finite number >= 0"),
        ({"match_distance_m": float("nan")}, "match_distance_m must be a finite number > 0"),
        ({"sample_step_m": "0.05"}, "sample_step_m must be a finite number > 0"),
        ({"sample_step_m": 1e-9}, "too fine"),
        ({"min_coverage": 2}, "min_coverage must be a finite number in 0..1"),
    ],
)
def test_wall_error_parameters_are_checked(kwargs, words) -> None:
    segments = np.array([[[0.0, 0.0], [10.0, 0.0]]])
    with pytest.raises(rose.RoseError, match=words):
        rose.wall_error(segments, segments, **kwargs)


@pytest.mark.parametrize(
    ("segments", "words"),
    [
        ([[[np.nan, 0.0], [1.0, 0.0]]], "finite endpoints"),
        ([[["a", 0], [1, 0]]], "must be numbers"),
    ],
)
def test_wall_error_segments_are_checked(segments, words) -> None:
    with pytest.raises(rose.RoseError, match=words):
        rose.wall_error(segments, [[[0.0, 0.0], [1.0, 0.0]]])


def test_a_zero_one_integer_mask_is_warned_about(furnished) -> None:
    import warnings

    mask = (furnished == 100).astype(np.uint8)
    with pytest.warns(UserWarning, match="only 0 and 1"):
        result = rose.analyze(mask)
    assert result.occupied_count == 0  # read as percent: all free, as documented
    assert rose.analyze(mask.astype(bool)).occupied_count == int(mask.sum())
    with pytest.warns(UserWarning, match="only 0 and 1"):  # with its unknown cells: as free
        unknown_around = np.pad(mask.astype(np.int16), 5, constant_values=-1)
        rose.analyze(unknown_around)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # A ROS grid (int8, from a log or a map file) all free but for 1 % cells, and a threshold
        # that reads 1 as occupied: not masks by mistake.
        rose.analyze(mask.astype(np.int8))
        assert rose.analyze(mask, occupied_threshold=1).occupied_count == int(mask.sum())
    # clean() and the wall extractions read it themselves: warned there too (they were silent).
    with pytest.warns(UserWarning, match="only 0 and 1"):
        assert rose.clean(mask).kept_count == 0
    with pytest.warns(UserWarning, match="only 0 and 1"):
        assert not rose.extract_walls(mask).segments
    with pytest.warns(UserWarning, match="only 0 and 1"):
        assert not rose.extract_walls_hough(mask).segments


def test_the_stage_functions_say_what_is_wrong_with_their_input() -> None:
    """The README's public stage functions returned NaN or failed in numpy."""
    from rose.directions import structure_score
    from rose.threshold import gmm_threshold
    from rose.unfold import direction_bins

    with pytest.raises(rose.RoseError, match="NaN"):
        gmm_threshold([np.nan, 0.1, 0.5, 0.9, 1.0], max_samples=10)
    with pytest.raises(rose.RoseError, match="max_samples"):
        gmm_threshold([0.1, 0.5], max_samples=0)
    with pytest.raises(rose.RoseError, match="angular_resolution_deg"):
        direction_bins((16, 16), angular_resolution_deg=0, min_radius_px=4)
    with pytest.raises(rose.RoseError, match="min_radius_px"):
        direction_bins((16, 16), angular_resolution_deg=1.0, min_radius_px=math.nan)
    with pytest.raises(rose.RoseError, match="at least one direction"):
        structure_score(np.array([]), np.array([0]))
    with pytest.raises(rose.RoseError, match="peak indices"):
        structure_score(np.array([0.0, 1.0]), np.array([2]))


def test_grids_of_durations_are_refused_as_contradiction_inputs() -> None:
    grid = np.zeros((30, 30), dtype=np.int8)
    with pytest.raises(rose.RoseError, match="earlier grid must hold int8"):
        contradicted_walls(grid.astype("m8[s]"), grid)


def test_the_stage_functions_refuse_what_failed_deep_inside_or_passed_silently() -> None:
    """More of the README's public stages: a NaN direction made an index of -3.5e17 in the strip
    search, a peak index out of range or a mismatched half-plane failed in numpy, a NaN smoothing
    or prominence and infinite scores gave a result, a negative or float shape failed in numpy."""
    from rose.directions import find_direction_peaks, refine_peak_positions, structure_score
    from rose.scoring import structure_mask
    from rose.spectrum import full_amplitude_spectrum, half_spectrum, padded_shape
    from rose.threshold import gmm_threshold
    from rose.unfold import cumulative_amplitude, direction_bins

    curve = np.cos(np.linspace(0.0, 2 * math.pi, 360, endpoint=False)) + 2.0
    bins = direction_bins((16, 16), angular_resolution_deg=0.5, min_radius_px=4)
    amplitude = np.ones((16, 9), dtype=np.float32)
    refused = [
        (lambda: padded_shape((-1, 5)), "padded_shape: shape must be two whole numbers"),
        (lambda: padded_shape((3.5, 4)), "padded_shape: shape must be two whole numbers"),
        (lambda: half_spectrum(np.ones(5, bool), (16, 16)), "occupied must be a 2D mask"),
        (lambda: half_spectrum(np.ones((5, 5), bool), (0, 16)), "half_spectrum: shape"),
        (lambda: full_amplitude_spectrum(amplitude, (16, 20)), "not the padded shape"),
        (lambda: full_amplitude_spectrum(amplitude, (16, 17)), "even column count"),
        (lambda: direction_bins((0, 0), angular_resolution_deg=1, min_radius_px=4), "shape"),
        (lambda: cumulative_amplitude(amplitude[:, :2], bins, smoothing_bins=1), "smaller"),
        (lambda: cumulative_amplitude(amplitude, bins, smoothing_bins=math.nan), "smoothing"),
        (lambda: cumulative_amplitude(amplitude, "bins", smoothing_bins=1), "bins must be"),
        (lambda: find_direction_peaks(curve, prominence_fraction=math.nan), "prominence"),
        (lambda: find_direction_peaks(curve.reshape(20, 18), prominence_fraction=0.5), "1-D"),
        (lambda: refine_peak_positions(curve, np.array([360])), r"peak indices must be in"),
        (lambda: refine_peak_positions(curve, np.array([-1])), r"peak indices must be in"),
        (lambda: refine_peak_positions(curve, np.array([1.5])), "integers"),
        (lambda: structure_score(np.full(360, np.nan), np.array([0])), "NaN or infinite"),
        (lambda: structure_score(np.ones(360), np.array([0])), "constant"),
        (lambda: structure_mask((16, 16), np.array([math.nan]), half_width_px=2.5), "finite"),
        (lambda: structure_mask((16, 16), np.array([0.1]), half_width_px=-1), "half_width_px"),
        (lambda: structure_mask((16, 16), np.array([0.1]), half_width_px=1e19), "half_width_px"),
        (lambda: gmm_threshold([0.1, 0.5, np.inf], max_samples=10), "infinite"),
        (lambda: gmm_threshold(["a", "b"], max_samples=10), "must be numbers"),
        # numpy counts timedelta64 among its integers
        (lambda: gmm_threshold(np.zeros(5, "m8[s]"), max_samples=10), "must be numbers"),
        (lambda: structure_score(np.zeros(5, "m8[s]"), np.array([0])), "1-D array of numbers"),
        (lambda: refine_peak_positions(curve, np.array([1], "m8[s]")), "integers"),
    ]
    for call, words in refused:
        with pytest.raises(rose.RoseError, match=words):
            call()
    # What stays valid: a half-plane of the right shape, the peaks of a curve, a padded shape.
    assert full_amplitude_spectrum(amplitude, (16, 16)).shape == (16, 16)
    assert find_direction_peaks(curve, prominence_fraction=0.0).indices.tolist() == [0]
    assert padded_shape((0, 0)) == (1, 2)


def test_direction_bins_take_a_shape_as_the_other_stages_do() -> None:
    """direction_bins' cache took its arguments as keys: a shape given as a list or an array
    (padded_shape, half_spectrum and structure_mask take both) was a TypeError, 'unhashable
    type'."""
    from rose.unfold import direction_bins

    expected = direction_bins((16, 20), angular_resolution_deg=0.5, min_radius_px=4.0)
    for shape in ([16, 20], np.array([16, 20]), (np.int64(16), np.int32(20))):
        bins = direction_bins(shape, angular_resolution_deg=0.5, min_radius_px=4)  # type: ignore[arg-type]
        np.testing.assert_array_equal(bins.cell_index, expected.cell_index)
        np.testing.assert_array_equal(bins.counts, expected.counts)
    with pytest.raises(rose.RoseError, match="shape"):
        direction_bins([16], angular_resolution_deg=0.5, min_radius_px=4)  # type: ignore[arg-type]
