"""rose.params.RoseParams: every value is checked on construction, with an error naming the parameter."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import rose
from rose import RoseError, RoseParams
from rose.params import make_params

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "fr079_session.mcap"


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("peak_prominence", 5, "peak_prominence must be in (0, 1], got 5"),
        ("peak_prominence", 0.0, "peak_prominence must be in (0, 1], got 0.0"),
        ("peak_prominence", math.nan, "peak_prominence must be finite, got nan"),
        ("peak_prominence", True, "peak_prominence must be a number, got True"),
        ("peak_prominence", "0.5", "peak_prominence must be a number, got '0.5'"),
        ("angular_resolution_deg", 0.0, "angular_resolution_deg must be in [0.01, 30], got 0.0"),
        ("smoothing_deg", -1.0, "smoothing_deg must be in [0, 30], got -1.0"),
        ("min_radius_px", -0.5, "min_radius_px must be in [0, 1e+06], got -0.5"),
        ("min_radius_px", 1e300, "min_radius_px must be in [0, 1e+06], got 1e+300"),
        ("min_radius_px", math.inf, "min_radius_px must be finite, got inf"),
        ("mask_half_width_px", 0.0, "mask_half_width_px must be in (0, 1e+06], got 0.0"),
        # Crashed the strip mask's index arithmetic (an IndexError, a traceback from the CLI).
        ("mask_half_width_px", 1e19, "mask_half_width_px must be in (0, 1e+06], got 1e+19"),
        ("mask_half_width_px", math.inf, "mask_half_width_px must be finite, got inf"),
        ("occupied_threshold", 0, "occupied_threshold must be in 1..100, got 0"),
        ("occupied_threshold", 101, "occupied_threshold must be in 1..100, got 101"),
        ("occupied_threshold", 65.5, "occupied_threshold must be an integer, got 65.5"),
        ("threshold_mode", "otsu", "threshold_mode must be 'gmm' or 'fixed', got 'otsu'"),
        ("fixed_threshold", 1.5, "fixed_threshold must be in [0, 1], got 1.5"),
        ("clutter_value", "grey", "clutter_value must be 'free' or 'unknown', got 'grey'"),
        ("max_gmm_samples", 5, "max_gmm_samples must be >= 100, got 5"),
        ("max_gmm_samples", 10, "max_gmm_samples must be >= 100, got 10"),
        ("seed", -1, "seed must be in 0..2**32-1, got -1"),
        ("seed", 2**32, "seed must be in 0..2**32-1, got 4294967296"),
        ("seed", 1.5, "seed must be an integer, got 1.5"),
    ],
)
def test_invalid_value_fails_on_construction(field: str, value: object, message: str) -> None:
    with pytest.raises(RoseError) as info:
        RoseParams(**{field: value})  # type: ignore[arg-type]
    assert str(info.value) == message
    # ... and when changed on a valid instance (dataclasses.replace builds a new, checked one).
    with pytest.raises(RoseError, match=field):
        dataclasses.replace(RoseParams(), **{field: value})


def test_every_problem_is_reported_on_one_line() -> None:
    with pytest.raises(RoseError) as info:
        RoseParams(peak_prominence=5, seed=-1, clutter_value="grey")  # type: ignore[arg-type]
    message = str(info.value)
    assert "\n" not in message
    for name in ("peak_prominence", "seed", "clutter_value"):
        assert name in message


@pytest.mark.parametrize(
    "changes",
    [
        {},
        {"peak_prominence": 1.0},
        {"smoothing_deg": 0.0, "min_radius_px": 0.0, "fixed_threshold": 0.0},
        {"occupied_threshold": 1, "seed": 2**32 - 1, "max_gmm_samples": 100},
        {"occupied_threshold": 100, "threshold_mode": "fixed", "clutter_value": "unknown"},
    ],
)
def test_boundary_values_are_accepted(changes: dict[str, object]) -> None:
    params = RoseParams(**changes)  # type: ignore[arg-type]
    assert all(getattr(params, k) == v for k, v in changes.items())


def test_make_params_names_unknown_parameters() -> None:
    with pytest.raises(RoseError, match=r"unknown ROSE parameter in \['prominence'\]"):
        make_params(prominence=0.3)
    assert make_params(RoseParams(seed=3), peak_prominence=0.2) == RoseParams(
        seed=3, peak_prominence=0.2
    )


def test_process_log_with_invalid_params_fails_before_reading(tmp_path: Path) -> None:
    from rose_logs import process_log

    out = tmp_path / "out.mcap"
    # The error comes from building the parameters, before any snapshot is analysed or any output
    # is opened; not a warning per snapshot followed by "malformed log".
    with pytest.raises(RoseError, match=r"^peak_prominence must be in \(0, 1\], got 5$"):
        process_log(SAMPLE, output_path=out, params=RoseParams(peak_prominence=5))
    assert list(tmp_path.iterdir()) == []


def test_analyze_accepts_checked_params() -> None:
    import numpy as np

    grid = np.zeros((16, 16), dtype=np.int8)
    grid[4, 2:14] = 100
    result = rose.analyze(grid, RoseParams(threshold_mode="fixed"))
    assert result.occupied_count == 12


def test_numpy_scalars_are_numbers_and_a_dict_of_params_is_named() -> None:
    params = RoseParams(occupied_threshold=np.int64(60), peak_prominence=np.float32(0.5))
    assert type(params.occupied_threshold) is int and params.occupied_threshold == 60
    assert type(params.peak_prominence) is float
    with pytest.raises(RoseError, match="params must be a RoseParams, got dict"):
        make_params({"peak_prominence": 0.3})  # type: ignore[arg-type]


def test_numpy_scalars_in_the_cleaning_and_wall_parameters_are_python_numbers() -> None:
    """CleanParams and WallParams kept numpy scalars: guard_window_m=np.float16(0.5) overflowed
    float16 in the cell arithmetic and failed deep in the cleaning ("cannot convert float NaN to
    integer")."""
    from synthetic import floor_plan

    grid = np.where(floor_plan(), 100, 0).astype(np.int8)
    params = rose.CleanParams(guard_window_m=np.float16(0.5), run_tolerance_px=np.int64(1))
    assert type(params.guard_window_m) is float and type(params.run_tolerance_px) is int
    got = rose.clean(grid, params=params)
    assert got.cleaned.tobytes() == rose.clean(grid).cleaned.tobytes()
    walls = rose.WallParams(hough_max_gap_px=np.float16(3), hough_votes=np.int64(15))
    assert type(walls.hough_max_gap_px) is float and type(walls.hough_votes) is int


def test_a_numpy_resolution_is_a_python_float_in_the_cleaning() -> None:
    """clean(resolution_m=np.float16(0.05)) kept float16 in the rules' cell arithmetic, which
    overflowed and failed deep inside ("cannot convert float NaN to integer")."""
    from synthetic import floor_plan

    grid = np.where(floor_plan(), 100, 0).astype(np.int8)
    result = rose.analyze(grid)
    half = rose.clean(grid, result, resolution_m=np.float16(0.05))
    assert type(half.resolution_m) is float
    assert half.cleaned.tobytes() == rose.clean(grid, result, resolution_m=0.05).cleaned.tobytes()
    single = rose.clean(grid, result, resolution_m=np.float32(0.05))
    exact = rose.clean(grid, result, resolution_m=float(np.float32(0.05)))
    assert single.cleaned.tobytes() == exact.cleaned.tobytes()


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        # A ValueError from numpy's truth value, not an error naming the field.
        ("threshold_mode", np.array(["gmm", "fixed"]), "threshold_mode must be 'gmm' or 'fixed'"),
        ("clutter_value", np.array([]), "clutter_value must be 'free' or 'unknown'"),
        # Accepted, and the params could then not be hashed (a frozen dataclass holding an array).
        ("clutter_value", np.array(["free"]), "clutter_value must be 'free' or 'unknown'"),
        ("threshold_mode", np.array("gmm"), "threshold_mode must be 'gmm' or 'fixed'"),
        # An OverflowError from math.isfinite: an int too large for a float is not finite.
        ("peak_prominence", 10**400, "peak_prominence must be finite"),
    ],
)
def test_modes_and_huge_numbers_fail_with_an_error_naming_the_field(
    field: str, value: object, message: str
) -> None:
    with pytest.raises(RoseError) as info:
        RoseParams(**{field: value})  # type: ignore[arg-type]
    assert str(info.value).startswith(message)


def test_numpy_strings_and_long_doubles_are_python_values() -> None:
    """A np.longdouble was refused as "must be a number" (its .item() is a np.longdouble, not a
    float), where CleanParams and WallParams take it."""
    params = RoseParams(
        fixed_threshold=np.longdouble(0.25),
        threshold_mode=np.str_("fixed"),
        clutter_value=np.str_("unknown"),
    )
    assert type(params.fixed_threshold) is float and params.fixed_threshold == 0.25
    assert type(params.threshold_mode) is str and type(params.clutter_value) is str
    same = RoseParams(fixed_threshold=0.25, threshold_mode="fixed", clutter_value="unknown")
    assert params == same and hash(params) == hash(same)
