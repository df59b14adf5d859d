"""Log-odds ray casting: walls land on the right cells, free space behind the robot, growth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rose_logs.carmen.raycast import (
    BuilderParams,
    OccupancyGridBuilder,
    ScanBatch,
    crop_to_known,
)

RES = 0.05


def _wall_scan(distance_m: float, n_beams: int = 181) -> tuple[np.ndarray, np.ndarray]:
    """Ranges of a laser at the origin facing +x towards an infinite wall ``x = distance_m``."""
    angles = np.linspace(-math.pi / 3, math.pi / 3, n_beams)
    return (distance_m / np.cos(angles)).astype(np.float32), angles


def _world_to_cell(builder: OccupancyGridBuilder, x: float, y: float) -> tuple[int, int]:
    ox, oy = builder.origin_xy_m
    return math.floor((y - oy) / RES + 1e-9), math.floor((x - ox) / RES + 1e-9)


def test_wall_at_the_right_cells() -> None:
    ranges, angles = _wall_scan(2.02)  # wall inside the column of x in [2.00, 2.05)
    builder = OccupancyGridBuilder(BuilderParams(resolution_m=RES, grow_margin_m=1.0))
    builder.integrate(ScanBatch(ranges[None, :], angles, np.zeros((1, 3))))
    grid = builder.grid()
    occupied_rows, occupied_cols = np.nonzero(grid >= 65)
    _, wall_col = _world_to_cell(builder, 2.02, 0.0)
    assert set(occupied_cols.tolist()) == {wall_col}
    # The wall spans y = +-2.02 * tan(60 deg) = +-3.5 m.
    row_lo, _ = _world_to_cell(builder, 0.0, -3.45)
    row_hi, _ = _world_to_cell(builder, 0.0, 3.45)
    assert occupied_rows.min() <= row_lo
    assert occupied_rows.max() >= row_hi
    # Free between robot and wall, unknown behind it.
    row0, col0 = _world_to_cell(builder, 1.0, 0.0)
    assert 0 <= grid[row0, col0] < 50
    row_b, col_b = _world_to_cell(builder, 2.5, 0.0)
    assert grid[row_b, col_b] == -1
    row_r, col_r = _world_to_cell(builder, -0.5, 0.0)
    assert grid[row_r, col_r] == -1


def test_rotated_pose_puts_wall_on_rows() -> None:
    # Laser at (1, -1) facing +y: the wall y = 1 is a row.
    ranges, angles = _wall_scan(2.0 + 0.02)
    builder = OccupancyGridBuilder(BuilderParams(resolution_m=RES))
    builder.integrate(ScanBatch(ranges[None, :], angles, np.array([[1.0, -1.0, math.pi / 2]])))
    rows, _ = np.nonzero(builder.grid() >= 65)
    wall_row, _ = _world_to_cell(builder, 1.0, 1.02)
    assert set(rows.tolist()) == {wall_row}


def test_repeated_scans_saturate_and_no_return_beams_mark_nothing() -> None:
    ranges, angles = _wall_scan(1.52)
    ranges[:10] = 81.9  # no return
    params = BuilderParams(resolution_m=RES, chunk_scans=1)
    builder = OccupancyGridBuilder(params)
    builder.integrate(ScanBatch(np.tile(ranges, (20, 1)), angles, np.zeros((20, 3))))
    log_odds = builder.log_odds
    assert log_odds.max() == pytest.approx(params.clamp_max)
    assert log_odds.min() == pytest.approx(params.clamp_min)
    assert builder.scan_count == 20
    assert builder.grid().max() == round(100 / (1 + math.exp(-params.clamp_max)))


def test_grid_grows_and_keeps_old_cells() -> None:
    ranges, angles = _wall_scan(1.0)
    builder = OccupancyGridBuilder(BuilderParams(resolution_m=RES, grow_margin_m=0.5))
    builder.integrate(ScanBatch(ranges[None, :], angles, np.zeros((1, 3))))
    before = builder.grid()
    origin_before = builder.origin_xy_m
    builder.integrate(ScanBatch(ranges[None, :], angles, np.array([[-20.0, 5.0, math.pi]])))
    after = builder.grid()
    assert after.shape[0] >= before.shape[0] and after.shape[1] > before.shape[1]
    dr = round((origin_before[1] - builder.origin_xy_m[1]) / RES)
    dc = round((origin_before[0] - builder.origin_xy_m[0]) / RES)
    window = after[dr : dr + before.shape[0], dc : dc + before.shape[1]]
    np.testing.assert_array_equal(window, before)


def test_bad_batch_and_params() -> None:
    builder = OccupancyGridBuilder()
    with pytest.raises(ValueError, match="inconsistent batch"):
        builder.integrate(ScanBatch(np.ones((2, 3), np.float32), np.zeros(3), np.zeros((3, 3))))
    with pytest.raises(ValueError, match="resolution_m"):
        OccupancyGridBuilder(BuilderParams(resolution_m=0.0))


def test_crop_to_known() -> None:
    grid = np.full((50, 60), -1, dtype=np.int8)
    grid[10:20, 30:35] = 0
    cropped, offset = crop_to_known(grid, margin_px=2)
    assert offset == (8, 28)
    assert cropped.shape == (14, 9)
    all_unknown, off = crop_to_known(np.full((4, 4), -1, dtype=np.int8))
    assert all_unknown.shape == (4, 4) and off == (0, 0)


def test_the_origin_is_written_as_map_saver_writes_it() -> None:
    """-726 cells of 0.05 m: -36.300000000000004 m as a product, in the log and the YAML."""
    from rose_logs.carmen.raycast import BuilderParams, OccupancyGridBuilder

    builder = OccupancyGridBuilder(BuilderParams(resolution_m=0.05))
    builder._origin_cell[:] = (-726, -1002)
    assert builder.origin_xy_m == (-36.3, -50.1)
