"""Seeded accumulated odometry drift: turn a corrected trajectory into an odometry-only one.

Between consecutive poses the robot moves by ``(dx, dy, dtheta)`` in the frame of the earlier pose
(metres, radians), ``d = hypot(dx, dy)``. From ``start_ns`` on, every step is perturbed the way wheel
odometry errs, and the perturbed steps are chained again, so errors accumulate::

    dtheta' = dtheta * (1 + rotation_scale) + rotation_bias_rad_per_m * d
              + N(0, rotation_noise_rad_per_sqrt_m**2 * d)
    (dx', dy') = (dx, dy) * (1 + translation_scale) + N(0, translation_noise_m_per_sqrt_m**2 * d) each

The systematic terms (a miscalibrated wheel base and wheel radius) have a seeded random sign; their
magnitudes come from :class:`DriftParams`, scaled as a whole by ``level``. Poses before ``start_ns``
are unchanged.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["DriftParams", "apply_drift"]


@dataclass(frozen=True)
class DriftParams:
    """Magnitudes of the odometry errors at ``level == 1``.

    Attributes
    ----------
    rotation_scale : float
        Relative error of every turn (0.02: a 90 degree turn is measured as 91.8 degrees).
    rotation_bias_rad_per_m : float
        Heading drift per metre travelled, radians per metre.
    rotation_noise_rad_per_sqrt_m : float
        Random heading error, radians per square-root metre.
    translation_scale : float
        Relative error of every translation.
    translation_noise_m_per_sqrt_m : float
        Random position error per axis, metres per square-root metre.
    """

    rotation_scale: float = 0.02
    rotation_bias_rad_per_m: float = math.radians(0.2)
    rotation_noise_rad_per_sqrt_m: float = math.radians(0.5)
    translation_scale: float = 0.01
    translation_noise_m_per_sqrt_m: float = 0.01

    def scaled(self, level: float) -> DriftParams:
        """Every magnitude multiplied by ``level`` (0 gives no drift)."""
        return dataclasses.replace(
            self, **{f.name: getattr(self, f.name) * level for f in dataclasses.fields(self)}
        )


def _wrap(angle: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    return (angle + np.pi) % (2 * np.pi) - np.pi


def apply_drift(
    poses: npt.NDArray[np.float64],
    *,
    stamps_ns: npt.NDArray[np.int64] | None = None,
    start_ns: int | None = None,
    level: float = 1.0,
    params: DriftParams | None = None,
    seed: int = 0,
) -> npt.NDArray[np.float64]:
    """Perturb a trajectory with accumulated, seeded odometry drift.

    Parameters
    ----------
    poses : ndarray of float64, shape (N, 3)
        ``(x_m, y_m, theta_rad)`` in the world frame, in time order. Not modified.
    stamps_ns : ndarray of int64, shape (N,), optional
        Pose times, nanoseconds; needed only with ``start_ns``.
    start_ns : int, optional
        Drift starts with the first step ending at or after this time; from the beginning when omitted.
    level : float
        Multiplier of every magnitude in ``params`` (0: the input trajectory is returned unchanged).
    params : DriftParams, optional
        Error magnitudes at level 1; defaults when omitted.
    seed : int
        Seed of the random signs and noise; the same inputs and seed give the same output.

    Returns
    -------
    ndarray of float64, shape (N, 3)
        The drifted trajectory; theta is wrapped to ``[-pi, pi)`` where drift was added (the
        poses before the drift starts, or all of them without drift, are returned as given).

    Raises
    ------
    ValueError
        On a badly shaped input or ``start_ns`` without ``stamps_ns``.
    """
    poses = np.asarray(poses, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3:
        msg = f"`poses` must have shape (N, 3), got {poses.shape}"
        raise ValueError(msg)
    if level < 0:
        msg = f"`level` must be >= 0, got {level}"
        raise ValueError(msg)
    n = poses.shape[0]
    out = poses.copy()
    if n < 2 or level == 0:
        return out
    first = 0
    if start_ns is not None:
        if stamps_ns is None or np.shape(stamps_ns) != (n,):
            msg = "`start_ns` needs `stamps_ns` of shape (N,)"
            raise ValueError(msg)
        first = int(np.searchsorted(np.asarray(stamps_ns), start_ns, side="left"))
        first = max(first - 1, 0)  # the pose before the start anchors the drifted chain
    if first >= n - 1:
        return out
    p = (params if params is not None else DriftParams()).scaled(level)
    rng = np.random.default_rng(seed)
    sign_rot, sign_bias, sign_trans = rng.choice([-1.0, 1.0], size=3)

    seg = poses[first:]
    d_world = np.diff(seg[:, :2], axis=0)
    theta0 = seg[:-1, 2]
    c, s = np.cos(theta0), np.sin(theta0)
    dx = c * d_world[:, 0] + s * d_world[:, 1]  # step in the frame of the earlier pose
    dy = -s * d_world[:, 0] + c * d_world[:, 1]
    dtheta = _wrap(np.diff(seg[:, 2]))
    dist = np.hypot(dx, dy)
    sqrt_d = np.sqrt(dist)

    dtheta_n = (
        dtheta * (1.0 + sign_rot * p.rotation_scale)
        + sign_bias * p.rotation_bias_rad_per_m * dist
        + rng.standard_normal(dist.size) * p.rotation_noise_rad_per_sqrt_m * sqrt_d
    )
    scale = 1.0 + sign_trans * p.translation_scale
    noise = (
        rng.standard_normal((dist.size, 2)) * (p.translation_noise_m_per_sqrt_m * sqrt_d)[:, None]
    )
    dx_n = dx * scale + noise[:, 0]
    dy_n = dy * scale + noise[:, 1]

    theta_n = seg[0, 2] + np.concatenate([[0.0], np.cumsum(dtheta_n)])
    c_n, s_n = np.cos(theta_n[:-1]), np.sin(theta_n[:-1])
    step_x = c_n * dx_n - s_n * dy_n
    step_y = s_n * dx_n + c_n * dy_n
    out[first:, 0] = seg[0, 0] + np.concatenate([[0.0], np.cumsum(step_x)])
    out[first:, 1] = seg[0, 1] + np.concatenate([[0.0], np.cumsum(step_y)])
    out[first:, 2] = _wrap(theta_n)
    return out
