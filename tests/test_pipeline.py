"""ROSE on synthetic maps with known answers, and the edge cases of analyze()."""

from __future__ import annotations

import math

import numpy as np
import pytest
from synthetic import add_clutter, floor_plan

import rose
from rose import RoseError
from rose.scoring import nominal_reference_map, structure_mask
from rose.spectrum import half_spectrum, padded_shape


def angular_error_deg(found: np.ndarray, expected: list[float]) -> float:
    """Largest distance, in degrees modulo 180, from each expected direction to the nearest found one."""
    found_deg = np.degrees(found)
    worst = 0.0
    for e in expected:
        diff = np.abs((found_deg - e + 90.0) % 180.0 - 90.0)
        worst = max(worst, float(diff.min()))
    return worst


@pytest.mark.parametrize("angle_deg", [0.0, 7.0, 22.5, 33.0, 45.0, 61.0, 87.0])
def test_rotated_floor_plan_directions_within_one_degree(angle_deg: float) -> None:
    result = rose.analyze(floor_plan(angle_deg=angle_deg))
    assert result.dominant_directions.size == 2
    assert angular_error_deg(result.dominant_directions, [angle_deg, angle_deg + 90]) < 1.0


@pytest.mark.parametrize("size", [(400, 500), (301, 301), (257, 640)])
def test_directions_on_odd_and_non_square_shapes(size: tuple[int, int]) -> None:
    result = rose.analyze(floor_plan(size=size, angle_deg=13.0))
    assert angular_error_deg(result.dominant_directions, [13.0, 103.0]) < 1.0


@pytest.mark.parametrize(("angle_deg", "seed"), [(0.0, 1), (17.0, 2), (33.0, 3), (52.0, 4)])
def test_blobs_and_specks_are_labelled_clutter(angle_deg: float, seed: int) -> None:
    cluttered, truth = add_clutter(floor_plan(angle_deg=angle_deg), blobs=40, specks=300, seed=seed)
    result = rose.analyze(cluttered)
    caught = np.count_nonzero(result.clutter & truth)
    precision = caught / np.count_nonzero(result.clutter)
    recall = caught / np.count_nonzero(truth)
    assert precision >= 0.9
    assert recall >= 0.5
    # Clutter is gone from the cleaned map, walls are kept.
    assert not np.any(result.cleaned[truth & result.clutter] == 100)
    assert np.count_nonzero(result.structure & ~truth) > 0.9 * np.count_nonzero(cluttered & ~truth)


def test_structure_score_separates_plan_from_noise() -> None:
    rng = np.random.default_rng(0)
    assert rose.analyze(floor_plan(angle_deg=20.0)).structure_score < 0.2
    for density in (0.01, 0.05, 0.2):
        # Above the paper's failure level (README: 0.46-0.65 over 20 seeds).
        assert rose.analyze(rng.random((300, 400)) < density).structure_score > 0.4


def test_rotating_the_map_by_90_degrees_shifts_directions_by_90() -> None:
    plan = floor_plan(size=(360, 360), angle_deg=20.0)
    before = rose.analyze(plan).dominant_directions
    after = rose.analyze(np.rot90(plan)).dominant_directions
    # np.rot90 turns rows into columns: a line at theta becomes one at theta + 90 degrees.
    assert angular_error_deg(after, list(np.degrees(before) + 90.0)) < 0.5


def test_a_map_turned_by_90_degrees_has_the_same_curve_turned() -> None:
    """The half-plane's columns u = 0 and u = Nyquist hold both cells of each mirrored pair: counted
    whole, the cells on the spectrum's v axis weighed twice in their bin's mean, and the bins of
    axis-aligned walls read differently after a turn by 90 degrees (8 % on Bormann's lab_ipa,
    which found a third direction only when turned)."""
    plan, _ = add_clutter(floor_plan(size=(400, 480)), blobs=20, specks=100, seed=3)
    before, after = rose.analyze(plan), rose.analyze(np.rot90(plan))
    assert after.padded_shape == before.padded_shape[::-1]  # no padding: the same spectrum turned
    half_turn = before.cumulative_amplitude.size // 2
    np.testing.assert_allclose(
        np.roll(after.cumulative_amplitude, -half_turn), before.cumulative_amplitude, rtol=1e-5
    )
    assert after.structure_score == pytest.approx(before.structure_score, rel=1e-5)


def test_results_identical_across_runs() -> None:
    cluttered, _ = add_clutter(floor_plan(angle_deg=11.0), blobs=30, specks=200, seed=5)
    first, second = rose.analyze(cluttered), rose.analyze(cluttered.copy())
    assert first.structure_score == second.structure_score
    assert first.threshold == second.threshold
    np.testing.assert_array_equal(first.cell_scores, second.cell_scores)
    np.testing.assert_array_equal(first.cleaned, second.cleaned)


def test_input_grid_is_not_modified() -> None:
    grid = np.where(floor_plan(), 100, 0).astype(np.int8)
    grid[:5] = -1
    before = grid.copy()
    rose.analyze(grid)
    np.testing.assert_array_equal(grid, before)


def test_result_shapes_and_types_follow_the_input() -> None:
    grid = np.where(floor_plan(size=(123, 321)), 100, 0).astype(np.int8)
    result = rose.analyze(grid)
    for mask in (result.occupied, result.structure, result.clutter):
        assert mask.shape == grid.shape and mask.dtype == bool
    assert result.cell_scores.shape == grid.shape and result.cell_scores.dtype == np.float32
    assert result.cleaned.shape == grid.shape and result.cleaned.dtype == np.int8
    assert not np.any(result.structure & result.clutter)
    np.testing.assert_array_equal(result.structure | result.clutter, result.occupied)
    assert result.cumulative_amplitude.shape == result.direction_bins.shape
    assert np.all((result.dominant_directions >= 0) & (result.dominant_directions < math.pi))
    rows, cols = result.padded_shape
    assert result.amplitude_spectrum.shape == (rows, cols) and rows >= 123 and cols >= 321


@pytest.mark.parametrize(
    "grid",
    [
        np.zeros((50, 60), dtype=np.int8),
        np.full((50, 60), -1, dtype=np.int8),
        np.zeros((1, 1), dtype=np.int8),
        np.full((1, 1), 100, dtype=np.int8),
        np.zeros((0, 0), dtype=np.int8),
    ],
    ids=["empty", "all-unknown", "1x1-free", "1x1-occupied", "zero-area"],
)
def test_maps_without_structure_are_left_unchanged(grid: np.ndarray) -> None:
    result = rose.analyze(grid)
    assert not result.has_structure
    assert result.structure_score == 1.0
    assert result.dominant_directions.size == 0
    assert not result.structure.any() and not result.clutter.any()
    assert math.isnan(result.threshold)
    np.testing.assert_array_equal(result.cleaned, grid)


def test_single_occupied_cell() -> None:
    grid = np.zeros((64, 64), dtype=np.int8)
    grid[10, 20] = 100
    result = rose.analyze(grid)
    # A point has a flat spectrum: no direction stands out.
    assert not result.has_structure
    assert result.structure_score == 1.0


@pytest.mark.parametrize("shape", [(3, 2000), (2000, 3)])
def test_very_elongated_maps(shape: tuple[int, int]) -> None:
    grid = np.zeros(shape, dtype=np.int8)
    if shape[0] < shape[1]:
        grid[1, 100:1900] = 100
    else:
        grid[100:1900, 1] = 100
    result = rose.analyze(grid)
    assert result.cleaned.shape == shape
    assert result.has_structure
    expected = 0.0 if shape[0] < shape[1] else 90.0
    assert angular_error_deg(result.dominant_directions, [expected]) < 1.0


def test_clutter_value_unknown_marks_removed_cells_unknown() -> None:
    cluttered, _ = add_clutter(floor_plan(), blobs=20, specks=100, seed=7)
    result = rose.analyze(cluttered, clutter_value="unknown")
    assert np.all(result.cleaned[result.clutter] == -1)
    assert np.all(result.cleaned[result.structure] == 100)


def test_fixed_threshold_mode() -> None:
    cluttered, _ = add_clutter(floor_plan(), blobs=20, specks=100, seed=7)
    result = rose.analyze(cluttered, threshold_mode="fixed", fixed_threshold=0.3)
    assert result.threshold == 0.3
    scores = result.cell_scores
    assert np.all(scores[result.clutter] <= 0.3) and np.all(scores[result.structure] > 0.3)


def test_cell_scores_are_the_reference_map_over_the_occupied_rows_and_0_beyond() -> None:
    """The rows from the first to the last occupied one hold the nominal reference map (as the
    stages give it, scaled); the margins above and below are 0 (not transformed)."""
    plan = np.where(floor_plan(), 100, 0).astype(np.int8)
    margin = np.full((40, plan.shape[1]), -1, dtype=np.int8)
    grid = np.vstack([margin, plan, margin[:25]])
    result = rose.analyze(grid)
    rows = np.flatnonzero(result.occupied.any(axis=1))
    first, last = int(rows[0]), int(rows[-1]) + 1
    assert first >= 40 and last <= 40 + plan.shape[0]
    assert not result.cell_scores[:first].any() and not result.cell_scores[last:].any()
    shape = padded_shape(grid.shape)
    mask = structure_mask(
        shape, result.dominant_directions, half_width_px=result.params.mask_half_width_px
    )
    whole = nominal_reference_map(half_spectrum(result.occupied, shape), mask, grid.shape)
    top = whole[result.occupied].max()
    np.testing.assert_allclose(
        result.cell_scores[first:last], whole[first:last] / top, rtol=0, atol=1e-6
    )
    assert result.cell_scores[result.occupied].max() == pytest.approx(1.0, abs=1e-6)


def test_unknown_cells_are_never_occupied() -> None:
    grid = np.where(floor_plan(), 100, -1).astype(np.int8)
    result = rose.analyze(grid)
    assert result.occupied_count == np.count_nonzero(grid == 100)


@pytest.mark.parametrize(
    ("grid", "overrides", "match"),
    [
        (np.zeros((4, 4, 2)), {}, "must be 2D"),
        (np.full((4, 4), 101), {}, "-1 \\(unknown\\) or 0..100"),
        (np.array([["a"]]), {}, "boolean or numeric"),
        # numpy counts timedelta64 among its integers: a grid of durations was analysed
        (np.zeros((4, 4), dtype="m8[s]"), {}, "boolean or numeric"),
        # the values under the mask were read as they are: masked walls stayed walls
        (np.ma.masked_equal(np.full((4, 4), 100), 100), {}, r"grid\.filled\(-1\)"),
        (np.zeros((4, 4)), {"peak_prominence": 0.0}, "peak_prominence"),
        (np.zeros((4, 4)), {"threshold_mode": "otsu"}, "threshold_mode"),
        (np.zeros((4, 4)), {"no_such_param": 1}, "unknown ROSE parameter"),
    ],
)
def test_invalid_input_raises_rose_error(grid: np.ndarray, overrides: dict, match: str) -> None:
    with pytest.raises(RoseError, match=match):
        rose.analyze(grid, **overrides)


@pytest.mark.parametrize("shape", [(1, 50), (3, 200), (12, 300)])
def test_a_thin_map_and_its_transpose_agree(shape: tuple[int, int]) -> None:
    """A strip of occupied cells runs along its long side, whichever way it lies: a 300 x 12 strip
    read as 0 degrees, a 3 x 200 one as having no direction while its transpose had one."""
    strip = np.full(shape, 100, dtype=np.int8)
    along, across = rose.analyze(strip), rose.analyze(strip.T)
    assert angular_error_deg(along.dominant_directions, [0.0]) < 1.0
    assert angular_error_deg(across.dominant_directions, [90.0]) < 1.0
    assert along.structure_score == pytest.approx(across.structure_score, abs=1e-6)


def test_a_masked_array_without_masked_cells_is_its_data() -> None:
    grid = np.where(floor_plan(), 100, 0).astype(np.int8)
    expected = rose.analyze(grid)
    got = rose.analyze(np.ma.masked_array(grid, mask=False))
    assert got.cell_scores.tobytes() == expected.cell_scores.tobytes()


def test_nan_in_a_float_grid_is_refused() -> None:
    """NaN passed the range check (its comparisons are False) and became free space."""
    grid = np.zeros((20, 20))
    grid[3, 4] = np.nan
    with pytest.raises(rose.RoseError, match="got NaN"):
        rose.analyze(grid)


def test_axis_aligned_walls_read_zero_not_pi() -> None:
    # The refined peak of an axis-aligned room landed a hair below bin 0 and wrapped to pi - 2e-11:
    # `rose walls` then printed 180 degrees where `rose score` printed 0.
    grid = np.zeros((200, 300), dtype=np.int8)
    grid[20, 20:280] = grid[180, 20:280] = 100
    grid[20:181, 20] = grid[20:181, 280] = 100
    directions = rose.analyze(grid).dominant_directions
    assert 0.0 in directions.tolist()
    assert np.all((directions >= 0) & (directions < np.pi - 1e-6))
    # Two occupied cells side by side: refined to pi - 3.8e-8, which printed as 180.00 degrees.
    two = np.pad(np.full((1, 2), 100, np.int8), 10)
    assert rose.analyze(two).dominant_directions.tolist() == [0.0]


def test_a_path_or_a_ragged_list_is_named_as_such() -> None:
    with pytest.raises(rose.RoseError, match=r"got the path 'map\.yaml'; read a map file with"):
        rose.analyze("map.yaml")
    with pytest.raises(rose.RoseError, match="must be a 2D array, got list"):
        rose.analyze([[0, 100], [0]])


def test_easy_slips_with_the_api_are_rose_errors_that_say_what_to_pass() -> None:
    """A notebook user's first tries (AttributeError or a shape () message before)."""
    occupancy = rose.OccupancyMap(grid=np.zeros((8, 8), np.int8))
    with pytest.raises(rose.RoseError, match="method='paper'"):
        rose.clean(occupancy.grid, "paper")  # type: ignore[arg-type]
    with pytest.raises(rose.RoseError, match="must be a RoseResult"):
        rose.clean(occupancy.grid, occupancy)  # type: ignore[arg-type]
    with pytest.raises(rose.RoseError, match="probabilities"):
        rose.analyze(np.array([[0.0, 0.7], [1.0, -1.0]]))  # a free map once truncated
    with pytest.raises(rose.RoseError, match="probabilities"):
        rose.analyze(np.eye(8))  # a 0/1 mask as floats: 1 % occupancy, a free map
    with pytest.raises(rose.RoseError, match="origin_xy_m must be"):
        rose.OccupancyMap(grid=occupancy.grid, origin_xy_m=(1.0, 2.0, 3.0))  # type: ignore[arg-type]
    # An AttributeError ('no attribute grid') and os's TypeError before.
    with pytest.raises(rose.RoseError, match=r"save_map needs an OccupancyMap .* got ndarray"):
        rose.save_map("m.yaml", occupancy.grid)  # type: ignore[arg-type]
    for name in (5, None):
        with pytest.raises(rose.RoseError, match="a map file name must be a str, bytes or path"):
            rose.load_map(name)  # type: ignore[arg-type]
