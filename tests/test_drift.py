"""Odometry drift: deterministic, starts when asked, breaks the map and raises W."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from real_data import CARMEN_DIR, repo_data

import rose
from rose_logs.carmen.drift import DriftParams, apply_drift
from rose_logs.carmen.parse import beam_angles, read_carmen_log
from rose_logs.carmen.raycast import OccupancyGridBuilder, ScanBatch, crop_to_known


def _square_path(n: int = 400) -> np.ndarray:
    t = np.linspace(0, 4, n, endpoint=False)
    side = np.floor(t)
    frac = t - side
    corners = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], dtype=float)
    xy = corners[side.astype(int)] + frac[:, None] * (
        corners[side.astype(int) + 1] - corners[side.astype(int)]
    )
    theta = side * math.pi / 2
    return np.column_stack([xy, theta])


def test_level_zero_is_identity_and_input_untouched() -> None:
    poses = _square_path()
    copy = poses.copy()
    assert_array_equal(apply_drift(poses, level=0.0, seed=3), poses)
    drifted = apply_drift(poses, level=1.0, seed=3)
    assert_array_equal(poses, copy)
    assert drifted.shape == poses.shape
    assert not np.allclose(drifted, poses)


def test_seeded_and_accumulating() -> None:
    poses = _square_path()
    a = apply_drift(poses, level=1.0, seed=7)
    assert_array_equal(a, apply_drift(poses, level=1.0, seed=7))
    assert not np.array_equal(a, apply_drift(poses, level=1.0, seed=8))
    error = np.hypot(*(a[:, :2] - poses[:, :2]).T)
    assert error[0] == 0.0
    assert error[-50:].mean() > error[:50].mean()  # drift accumulates
    bigger = apply_drift(poses, level=4.0, seed=7)
    assert np.hypot(*(bigger[-1, :2] - poses[-1, :2])) > error[-1]


def test_start_time() -> None:
    poses = _square_path()
    stamps = np.arange(poses.shape[0], dtype=np.int64) * 100_000_000
    out = apply_drift(poses, stamps_ns=stamps, start_ns=int(stamps[200]), level=2.0, seed=1)
    assert_array_equal(out[:200], poses[:200])
    assert not np.allclose(out[201:], poses[201:])
    with pytest.raises(ValueError, match="stamps_ns"):
        apply_drift(poses, start_ns=5)


def test_straight_line_without_noise_keeps_length_scale() -> None:
    poses = np.column_stack([np.linspace(0, 10, 11), np.zeros(11), np.zeros(11)])
    params = DriftParams(
        rotation_scale=0.0,
        rotation_bias_rad_per_m=0.0,
        rotation_noise_rad_per_sqrt_m=0.0,
        translation_scale=0.1,
        translation_noise_m_per_sqrt_m=0.0,
    )
    out = apply_drift(poses, params=params, seed=0)
    assert out[-1, 0] in (pytest.approx(11.0), pytest.approx(9.0))
    assert_allclose(out[:, 1], 0.0, atol=1e-12)


def test_drift_changes_the_map_and_raises_w() -> None:
    log = read_carmen_log(repo_data(f"{CARMEN_DIR}/aces-corrected.log.gz"))
    ranges = np.stack([s.ranges_m for s in log.scans])
    angles = beam_angles(ranges.shape[1])

    def build(poses: np.ndarray) -> np.ndarray:
        builder = OccupancyGridBuilder()
        builder.integrate(ScanBatch(ranges, angles, poses))
        return crop_to_known(builder.grid())[0]

    correct = build(log.laser_poses)
    drifted = build(apply_drift(log.laser_poses, level=1.0, seed=0))
    assert correct.shape != drifted.shape or np.any(correct != drifted)
    w_correct = rose.analyze(correct).structure_score
    w_drifted = rose.analyze(drifted).structure_score
    assert w_correct < 0.15
    assert w_drifted > w_correct + 0.1
