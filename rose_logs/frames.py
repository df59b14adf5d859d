"""Planar orientations as ROS stores them: yaw (radians, counter-clockwise about +z) <-> quaternion.

The one place rose-bag converts between the two (map origins, CARMEN poses on ``/tf`` and ``/odom``).
Quaternions are ``(x, y, z, w)`` tuples, the order of ``geometry_msgs/Quaternion`` and Rerun.
"""

from __future__ import annotations

import math

__all__ = ["quaternion_tilt", "quaternion_to_yaw", "yaw_to_quaternion"]


def yaw_to_quaternion(yaw_rad: float) -> tuple[float, float, float, float]:
    """Unit quaternion ``(x, y, z, w)`` of a rotation by ``yaw_rad`` about +z."""
    half = 0.5 * yaw_rad
    return 0.0, 0.0, math.sin(half), math.cos(half)


def quaternion_to_yaw(xyzw: tuple[float, float, float, float]) -> float:
    """Yaw (rotation about +z, radians in ``[-pi, pi]``) of the quaternion ``(x, y, z, w)``.

    The z-y-x Euler yaw: the heading of the rotated x axis. The quaternion need not be normalised (map
    origins in logs sometimes are not; the scale cancels, as in tf2, which normalises on use); the zero
    quaternion gives 0.
    """
    x, y, z, w = xyzw
    return math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def quaternion_tilt(xyzw: tuple[float, float, float, float]) -> float:
    """Angle (radians, 0..pi) between +z and +z rotated by the quaternion ``(x, y, z, w)``: how far
    roll and pitch tilt a grid out of the x-y plane (0 for a pure yaw). Not normalised is fine; the
    zero quaternion gives 0."""
    x, y, z, w = xyzw
    norm2 = x * x + y * y + z * z + w * w
    if norm2 == 0.0 or not math.isfinite(norm2):
        return 0.0
    # The z component of the rotated z axis: 1 - 2 (x^2 + y^2) for a unit quaternion.
    cos_tilt = 1.0 - 2.0 * (x * x + y * y) / norm2
    return math.acos(min(max(cos_tilt, -1.0), 1.0))
