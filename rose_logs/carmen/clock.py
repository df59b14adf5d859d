"""The session clock of a CARMEN log: its own stamps, or a replacement when they do not resolve the scans.

Most logs stamp every scan (a handful of backward steps are nudged forward by 1 ns). Some do not: the
CSAIL log writes its stamps with six significant digits, so nearly all scans share one stamp and a
session cut into map periods would be a single snapshot. Such a log gets a replacement clock: every
scan takes the time a robot needs to move to it at :data:`NOMINAL_SPEED_M_S` and turn at
:data:`NOMINAL_TURN_RAD_S`, at least :data:`MIN_SCAN_PERIOD_S` (walking pace, a typical laser rate).
``rose-bag convert`` and the break evaluation's replay use the same clock.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import numpy.typing as npt

from rose_logs.carmen.parse import CarmenLog

__all__ = [
    "MIN_SCAN_PERIOD_S",
    "NOMINAL_SPEED_M_S",
    "NOMINAL_TURN_RAD_S",
    "ClockName",
    "scan_clock_ns",
]

NOMINAL_SPEED_M_S = 0.3
"""Robot speed of the replacement clock, metres per second."""
NOMINAL_TURN_RAD_S = 0.5
"""Turn rate of the replacement clock, radians per second."""
MIN_SCAN_PERIOD_S = 0.25
"""Shortest scan period of the replacement clock, seconds."""

ClockName = Literal["log", "nominal-speed"]


def scan_clock_ns(log: CarmenLog) -> tuple[npt.NDArray[np.int64], ClockName]:
    """Scan times in nanoseconds since the first scan, strictly increasing, and the clock's name.

    Returns the log's own stamps (``"log"``) unless fewer than half of the scan-to-scan steps are
    positive; then the replacement clock of the module notes (``"nominal-speed"``).
    """
    stamps = log.stamps_ns.astype(np.int64)
    steps = np.diff(stamps)
    if steps.size == 0 or np.count_nonzero(steps > 0) >= steps.size / 2:
        out = stamps - stamps[0]
        for i in range(1, out.size):  # a handful of backward stamps at most (Intel)
            if out[i] <= out[i - 1]:
                out[i] = out[i - 1] + 1
        return out, "log"
    poses = log.laser_poses
    dist = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    turn = np.abs((np.diff(poses[:, 2]) + np.pi) % (2 * np.pi) - np.pi)
    dt = np.maximum.reduce(
        [dist / NOMINAL_SPEED_M_S, turn / NOMINAL_TURN_RAD_S, np.full(dist.size, MIN_SCAN_PERIOD_S)]
    )
    return np.concatenate([[0], np.cumsum(np.round(dt * 1e9).astype(np.int64))]), "nominal-speed"
