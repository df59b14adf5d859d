"""Mapping sessions from CARMEN logs, in memory: the ``/map`` snapshots ``rose-bag convert`` would write.

:func:`session_grids` replays a log exactly as :func:`rose_logs.carmen.session.write_carmen_session`
does (same drift, same snapshot times, same ray casting) but keeps only the grids, so the break
evaluation can run dozens of sessions without writing and re-reading log files.

Clock: :func:`rose_logs.carmen.clock.scan_clock_ns`, as in ``convert`` (a log whose stamps do not
resolve the scans, like CSAIL's, gets a nominal-speed clock).
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rose_logs.carmen.clock import scan_clock_ns
from rose_logs.carmen.drift import apply_drift
from rose_logs.carmen.parse import CarmenLog
from rose_logs.carmen.raycast import BuilderParams, OccupancyGridBuilder
from rose_logs.evaluation.config import log_name

__all__ = ["SessionGrid", "SessionSpec", "log_clock_ns", "session_grids"]

_LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class SessionSpec:
    """One session to replay.

    Attributes
    ----------
    log_path : Path
        CARMEN log.
    drift_level : float
        Odometry drift level (0: the corrected poses, a correct session).
    drift_start_s : float
        Seconds after the first scan when drift starts.
    drift_seed : int
        Seed of the drift.
    map_period_s : float
        Seconds between snapshots.
    max_scans : int, optional
        Only the first scans of the log (for a quick run); the whole log when None.
    resolution_m : float
        Cell size of the session's maps, metres.
    """

    log_path: Path
    drift_level: float = 0.0
    drift_start_s: float = 0.0
    drift_seed: int = 0
    map_period_s: float = 30.0
    max_scans: int | None = None
    resolution_m: float = 0.05

    @property
    def name(self) -> str:
        """Log name (``aces``, ``freiburg-079``...), as ``--logs`` names it
        (:func:`rose_logs.evaluation.config.log_name`)."""
        return log_name(self.log_path.name)


@dataclass(frozen=True, eq=False)
class SessionGrid:
    """One snapshot of a replayed session.

    Attributes
    ----------
    time_ns : int
        Snapshot time, nanoseconds since the first scan.
    grid : ndarray of int8, shape (rows, cols)
        ROS convention (-1 unknown, 0..100, row 0 at the origin).
    origin_xy_m : tuple of float
        World position of cell (0, 0)'s outer corner, metres.
    resolution_m : float
        Cell size, metres.
    scans : int
        Scans integrated so far.
    """

    time_ns: int
    grid: npt.NDArray[np.int8]
    origin_xy_m: tuple[float, float]
    resolution_m: float
    scans: int


@functools.lru_cache(maxsize=4)
def log_clock_ns(log: CarmenLog) -> npt.NDArray[np.int64]:
    """:func:`scan_clock_ns`'s offsets of ``log`` (read-only), worked out once per parsed log: its
    warnings (Intel's backward stamps) are said once, not again for every session replayed."""
    offsets = scan_clock_ns(log).offsets_ns
    offsets.flags.writeable = False
    return offsets


def session_grids(
    log: CarmenLog,
    spec: SessionSpec,
    *,
    builder_params: BuilderParams | None = None,
) -> Iterator[SessionGrid]:
    """Yield the snapshots of one session, in time order.

    A snapshot is taken at the first scan at or after every ``map_period_s`` (before that scan is
    integrated), and after the last scan, as ``rose-bag convert`` does.

    Parameters
    ----------
    log : CarmenLog
        Parsed log.
    spec : SessionSpec
        Drift, period and cell size.
    builder_params : BuilderParams, optional
        Ray-casting parameters (default: the builder's, with the spec's cell size).
    """
    clock = log_clock_ns(log)
    params = (
        builder_params
        if builder_params is not None
        else BuilderParams(resolution_m=spec.resolution_m)
    )
    poses = apply_drift(
        log.laser_poses,
        stamps_ns=clock,
        start_ns=round(spec.drift_start_s * 1e9),
        level=spec.drift_level,
        seed=spec.drift_seed,
    )
    builder = OccupancyGridBuilder(params)
    period_ns = round(spec.map_period_s * 1e9)
    next_ns = period_ns
    done = 0
    for i in range(1, len(log.scans)):
        t = int(clock[i])
        if t >= next_ns:
            builder.integrate_scans(log.scans[done:i], poses[done:i])
            done = i
            yield SessionGrid(t, builder.grid(), builder.origin_xy_m, params.resolution_m, i)
            next_ns = t + period_ns
    builder.integrate_scans(log.scans[done:], poses[done:])
    end = int(clock[-1]) + 1
    yield SessionGrid(end, builder.grid(), builder.origin_xy_m, params.resolution_m, len(log.scans))
