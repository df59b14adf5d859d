"""Yaw <-> quaternion (rose_logs.frames)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from rose_logs.frames import quaternion_to_yaw, yaw_to_quaternion


@pytest.mark.parametrize("yaw", [0.0, 0.3, -1.2, math.pi / 2, -math.pi / 2, 3.1])
def test_round_trip_and_unit_norm(yaw: float) -> None:
    q = yaw_to_quaternion(yaw)
    assert q[:2] == (0.0, 0.0)
    assert_allclose(np.linalg.norm(q), 1.0, rtol=1e-12)
    assert_allclose(quaternion_to_yaw(q), yaw, atol=1e-12)


def test_yaw_matches_scipy_rotation() -> None:
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(1)
    for xyzw in rng.normal(size=(20, 4)):
        q = xyzw / np.linalg.norm(xyzw)
        heading = Rotation.from_quat(q).apply([1.0, 0.0, 0.0])  # where +x points
        yaw = quaternion_to_yaw(tuple(q))
        assert_allclose(yaw, math.atan2(heading[1], heading[0]), atol=1e-9)


def test_scale_and_identity() -> None:
    assert quaternion_to_yaw((0.0, 0.0, 0.0, 1.0)) == 0.0
    assert_allclose(quaternion_to_yaw((0.0, 0.0, 2.0, 2.0)), math.pi / 2, atol=1e-12)
    assert quaternion_to_yaw((0.0, 0.0, 0.0, 0.0)) == 0.0
    assert_allclose(quaternion_to_yaw(yaw_to_quaternion(math.pi)), math.pi, atol=1e-12)
