"""The paper's wall error: zero for identical sets, growth with offset and rotation, counting."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

from rose import RoseError
from rose.walls import wall_error

REFERENCE = np.array(
    [
        [[0.0, 0.0], [10.0, 0.0]],
        [[10.0, 0.0], [10.0, 6.0]],
        [[0.0, 6.0], [10.0, 6.0]],
        [[4.0, 0.0], [4.0, 6.0]],
    ]
)


def moved(segments: npt.NDArray[np.float64], *, angle_rad: float, shift_m: float) -> npt.NDArray:
    """Rotate every segment about its midpoint and shift it along +x and +y by ``shift_m``."""
    mid = segments.mean(axis=1, keepdims=True)
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    rotated = (segments - mid) @ np.array([[c, -s], [s, c]]).T + mid
    return rotated + shift_m


def test_identical_sets_cost_nothing() -> None:
    error = wall_error(REFERENCE, REFERENCE)
    assert error.mean_cost == 0.0
    assert error.n_spurious == 0
    assert error.n_missing == 0
    np.testing.assert_array_equal(error.matched, np.arange(4))


def test_cost_is_the_papers_formula() -> None:
    single = REFERENCE[:1]
    error = wall_error(moved(single, angle_rad=0.1, shift_m=0.2), single, match_distance_m=1.0)
    # theta = 0.1 rad; the midpoint moves by (0.2, 0.2) off a horizontal wall: |T| = 0.2.
    assert error.rotation_rad[0] == pytest.approx(0.1)
    assert error.translation_m[0] == pytest.approx(0.2)
    assert error.mean_cost == pytest.approx(0.1 * 0.2 / 2)


@pytest.mark.parametrize("angle_rad", [0.02, 0.05])
def test_cost_grows_with_offset(angle_rad: float) -> None:
    costs = [
        wall_error(moved(REFERENCE, angle_rad=angle_rad, shift_m=d), REFERENCE).mean_cost
        for d in (0.01, 0.05, 0.1, 0.2)
    ]
    assert all(np.diff(costs) > 0)


@pytest.mark.parametrize("shift_m", [0.05, 0.1])
def test_cost_grows_with_rotation(shift_m: float) -> None:
    costs = [
        wall_error(moved(REFERENCE, angle_rad=a, shift_m=shift_m), REFERENCE).mean_cost
        for a in (0.005, 0.01, 0.03, 0.06)
    ]
    assert all(np.diff(costs) > 0)


def test_pure_offset_costs_nothing_but_is_reported() -> None:
    """The paper's cost vanishes without rotation; the offset is reported beside it."""
    error = wall_error(moved(REFERENCE, angle_rad=0.0, shift_m=0.1), REFERENCE)
    assert error.mean_cost == 0.0
    assert error.mean_offset_m == pytest.approx(0.1)


def test_pieces_of_a_wall_need_no_translation() -> None:
    pieces = np.array([[[1.0, 0.0], [3.0, 0.0]], [[5.0, 0.0], [9.0, 0.0]]])
    error = wall_error(pieces, REFERENCE)
    np.testing.assert_allclose(error.translation_m, 0.0)
    # 6 of 10 m lie on the pieces; coverage also counts points within match_distance_m of them.
    assert 0.6 <= error.reference_coverage[0] <= 0.6 + 4 * 0.25 / 10 + 0.01
    assert error.missing.tolist() == [False, True, True, True]


def test_spurious_and_missing_are_counted() -> None:
    detected = np.concatenate([REFERENCE[:2], [[[20.0, 20.0], [25.0, 21.0]]]])
    error = wall_error(detected, REFERENCE)
    assert error.n_detected == 3
    assert error.n_spurious == 1
    assert error.spurious.tolist() == [False, False, True]
    assert error.n_missing == 2
    assert error.n_reference == 4
    assert math.isfinite(error.mean_cost)


def test_empty_sets() -> None:
    none = np.empty((0, 2, 2))
    assert math.isnan(wall_error(none, REFERENCE).mean_cost)
    assert wall_error(none, REFERENCE).n_missing == 4
    assert wall_error(REFERENCE, none).n_spurious == 4
    with pytest.raises(RoseError, match="shape"):
        wall_error(np.zeros((3, 4)), REFERENCE)


def test_the_wall_section_of_a_drawing_with_no_walls_says_n_a(tmp_path: Path) -> None:
    """A drawing with no walls printed `nan` and "median factor nan", and its plot raised from
    matplotlib (a log axis of nothing but NaN)."""
    import math

    from rose_logs.evaluation.walls import WallRow, WallScore, _markdown, _plot

    none = WallScore(0, math.nan, math.nan, math.nan, 0, 0)
    row = WallRow("blank", 0, none, none, none, 0.1)
    text = _markdown((row,), None)
    assert " nan" not in text and "| blank | 0 | 0 | n/a |" in text
    assert "median factor n/a" in text
    pytest.importorskip("matplotlib")
    assert _plot(tmp_path / "walls.png", (row,)) == tmp_path / "walls.png"


def test_the_wall_evaluation_runs_as_a_script(tmp_path: Path) -> None:
    """A helper defined below the `__main__` block made `python -m rose_logs.evaluation.walls`
    fail with a NameError (imported, the module worked)."""
    import os
    import subprocess
    import sys

    repo = Path(__file__).resolve().parents[1]
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "rose_logs.evaluation.walls",
            str(tmp_path / "out"),
            "Freiburg79_scan",
            "--maps-dir",
            str(repo / "tests" / "data" / "bormann_ipa_room_segmentation"),
        ],
        capture_output=True,
        text=True,
        check=False,
        cwd=repo,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    assert done.returncode == 0, done.stderr
    assert "| Freiburg79_scan |" in done.stdout
