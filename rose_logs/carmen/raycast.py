"""Occupancy grids from laser scans: incremental, vectorised log-odds ray casting.

Frames and conventions
----------------------
Poses and points are in the log's world frame, metres and radians. The grid follows ROS: cell
``(row, col)`` covers ``x in [origin_x + col * res, origin_x + (col + 1) * res)`` and the same for
``y`` with ``row``; row 0 is at the origin (the bottom of a picture). The grid grows in steps of
``grow_margin_m`` whenever a scan reaches past its border, so the origin moves by whole cells.

The update
----------
For every beam the endpoint cell gains ``log_odds_hit`` and every cell sampled along the ray before
it (one sample per cell length) gains ``log_odds_miss`` (negative). Beams at or beyond
``max_range_m`` count as "no return": they mark nothing and clear free space only up to
``no_return_free_m`` (0 by default, as in the published Radish maps: a missing echo says little).
Scans are integrated in chunks of ``chunk_scans``: all samples of a chunk are summed with one
``np.bincount`` and the log-odds are clamped to ``[clamp_min, clamp_max]`` after each chunk (chunk 1 is
the textbook per-scan update; larger chunks trade exactness of the clamping for speed).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rose.limits import DEFAULT_MAX_CELLS, check_cells
from rose_logs.carmen.parse import beam_angles

__all__ = ["BuilderParams", "OccupancyGridBuilder", "ScanBatch", "crop_to_known"]

_LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class BuilderParams:
    """Parameters of :class:`OccupancyGridBuilder`.

    Attributes
    ----------
    resolution_m : float
        Cell size in metres.
    max_range_m : float
        Readings at or beyond this range are "no return": they mark nothing and clear free space
        only up to ``no_return_free_m``.
    min_range_m : float
        Readings below this range are dropped.
    no_return_free_m : float
        Free space cleared along a "no return" beam, metres (0: none).
    log_odds_hit, log_odds_miss : float
        Log-odds added to an endpoint cell and to every traversed cell (``log_odds_miss < 0``).
    clamp_min, clamp_max : float
        Log-odds bounds applied after every chunk.
    grow_margin_m : float
        Extra border added whenever the grid has to grow, in metres.
    chunk_scans : int
        Scans summed per bincount (see module notes).
    max_cells : int or None
        Refuse to grow the grid beyond this many cells (None: no limit); the size is checked
        before allocating (:data:`rose.limits.DEFAULT_MAX_CELLS`).
    """

    resolution_m: float = 0.05
    max_range_m: float = 30.0
    min_range_m: float = 0.05
    no_return_free_m: float = 0.0
    log_odds_hit: float = 0.85
    log_odds_miss: float = -0.4
    clamp_min: float = -2.0
    clamp_max: float = 3.5
    grow_margin_m: float = 10.0
    chunk_scans: int = 16
    max_cells: int | None = DEFAULT_MAX_CELLS


@dataclass(frozen=True, eq=False)
class ScanBatch:
    """Scans with a common beam layout, ready for :meth:`OccupancyGridBuilder.integrate`.

    Attributes
    ----------
    ranges_m : ndarray of float32, shape (S, B)
        Ranges in metres.
    angles_rad : ndarray of float64, shape (B,)
        Beam angles in the laser frame, radians.
    poses : ndarray of float64, shape (S, 3)
        Laser poses ``(x_m, y_m, theta_rad)`` in the world frame.
    """

    ranges_m: npt.NDArray[np.float32]
    angles_rad: npt.NDArray[np.float64]
    poses: npt.NDArray[np.float64]


class OccupancyGridBuilder:
    """Accumulates laser scans into a growing log-odds occupancy grid.

    Parameters
    ----------
    params : BuilderParams, optional
        Resolution, ranges, log-odds increments; defaults when omitted.

    Examples
    --------
    >>> builder = OccupancyGridBuilder(BuilderParams(resolution_m=0.05))
    >>> builder.integrate(ScanBatch(ranges, angles, poses))  # doctest: +SKIP
    >>> grid = builder.grid()  # int8, ROS convention
    """

    def __init__(self, params: BuilderParams | None = None) -> None:
        self.params = params if params is not None else BuilderParams()
        p = self.params
        if not p.resolution_m > 0:
            msg = f"resolution_m must be > 0, got {p.resolution_m}"
            raise ValueError(msg)
        if not p.max_range_m > p.min_range_m >= 0:
            msg = f"need max_range_m > min_range_m >= 0, got {p.max_range_m}, {p.min_range_m}"
            raise ValueError(msg)
        if not (p.log_odds_hit > 0 > p.log_odds_miss):
            msg = "need log_odds_hit > 0 > log_odds_miss"
            raise ValueError(msg)
        if p.chunk_scans < 1:
            msg = f"chunk_scans must be >= 1, got {p.chunk_scans}"
            raise ValueError(msg)
        self._log_odds = np.zeros((0, 0), dtype=np.float32)
        self._observed = np.zeros((0, 0), dtype=bool)
        self._origin_cell = np.zeros(2, dtype=np.int64)  # world cell index (ix, iy) of grid (0, 0)
        self.scan_count = 0

    # -- state ------------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the grid, cells."""
        return self._log_odds.shape[0], self._log_odds.shape[1]

    @property
    def origin_xy_m(self) -> tuple[float, float]:
        """World position of the outer corner of cell (0, 0), metres, to the nanometre (-726 cells of
        0.05 m are -36.300000000000004 m as a product; map_saver writes -36.3)."""
        res = self.params.resolution_m
        return round(float(self._origin_cell[0] * res), 9), round(
            float(self._origin_cell[1] * res), 9
        )

    @property
    def log_odds(self) -> npt.NDArray[np.float32]:
        """Copy of the log-odds, float32, shape (rows, cols), row 0 at the origin."""
        return self._log_odds.copy()

    def grid(self) -> npt.NDArray[np.int8]:
        """The ROS occupancy grid: ``round(100 * sigmoid(log_odds))``, -1 where never observed.

        Returns
        -------
        ndarray of int8, shape (rows, cols)
        """
        prob = 1.0 / (1.0 + np.exp(-self._log_odds.astype(np.float64)))
        out = np.rint(100.0 * prob).astype(np.int8)
        out[~self._observed] = -1
        return out

    # -- growth -----------------------------------------------------------------------------
    def _ensure_covers(
        self, lo_cell: npt.NDArray[np.int64], hi_cell: npt.NDArray[np.int64]
    ) -> None:
        """Grow so that world cells ``lo_cell..hi_cell`` (inclusive, (ix, iy)) are inside."""
        rows, cols = self.shape
        cur_lo = self._origin_cell
        cur_hi = cur_lo + np.array([cols, rows]) - 1
        if rows and np.all(lo_cell >= cur_lo) and np.all(hi_cell <= cur_hi):
            return
        margin = math.ceil(self.params.grow_margin_m / self.params.resolution_m)
        if rows == 0:
            new_lo = lo_cell - margin
            new_hi = hi_cell + margin
        else:
            new_lo = np.where(lo_cell < cur_lo, lo_cell - margin, cur_lo)
            new_hi = np.where(hi_cell > cur_hi, hi_cell + margin, cur_hi)
        new_cols, new_rows = (new_hi - new_lo + 1).tolist()
        too_large = check_cells(new_rows, new_cols, self.params.max_cells)
        if too_large is not None:  # checked before allocating (a pose far away, a tiny resolution)
            msg = f"the map would grow to {too_large}"
            raise ValueError(msg)
        log_odds = np.zeros((new_rows, new_cols), dtype=np.float32)
        observed = np.zeros((new_rows, new_cols), dtype=bool)
        if rows:
            dx, dy = (cur_lo - new_lo).tolist()
            log_odds[dy : dy + rows, dx : dx + cols] = self._log_odds
            observed[dy : dy + rows, dx : dx + cols] = self._observed
        self._log_odds, self._observed, self._origin_cell = log_odds, observed, new_lo
        _LOG.debug("grid grown to %d x %d cells", new_rows, new_cols)

    # -- integration ------------------------------------------------------------------------
    def integrate(self, batch: ScanBatch) -> None:
        """Add scans to the map, in order, in chunks of ``params.chunk_scans``.

        Parameters
        ----------
        batch : ScanBatch
            Ranges (S, B) metres, beam angles (B,) radians, laser poses (S, 3) world frame.
        """
        ranges = np.asarray(batch.ranges_m, dtype=np.float32)
        poses = np.asarray(batch.poses, dtype=np.float64)
        angles = np.asarray(batch.angles_rad, dtype=np.float64)
        if (
            ranges.ndim != 2
            or poses.shape != (ranges.shape[0], 3)
            or angles.shape != ranges.shape[1:]
        ):
            msg = (
                f"inconsistent batch: ranges {ranges.shape}, poses {poses.shape}, "
                f"angles {angles.shape}; expected (S, B), (S, 3), (B,)"
            )
            raise ValueError(msg)
        step = self.params.chunk_scans
        for start in range(0, ranges.shape[0], step):
            self._integrate_chunk(ranges[start : start + step], poses[start : start + step], angles)

    def integrate_scans(self, scans: Sequence[object], poses: npt.ArrayLike | None = None) -> None:
        """Add :class:`rose_logs.carmen.parse.FlaserScan`-like scans (``ranges_m``, ``laser_pose``), in order.

        The one way from parsed scans to the grid (conversion, evaluation, benchmarks): consecutive
        scans with the same beam count are batched together.

        Parameters
        ----------
        scans : sequence of FlaserScan
            Scans; their ``ranges_m`` (B,) metres may differ in length B from group to group.
        poses : array_like of float, shape (len(scans), 3), optional
            Laser poses ``(x_m, y_m, theta_rad)`` to use instead of the scans' own ``laser_pose``
            (e.g. drifted odometry).
        """
        override = None if poses is None else np.asarray(poses, dtype=np.float64)
        if override is not None and override.shape != (len(scans), 3):
            msg = f"poses must have shape ({len(scans)}, 3), got {override.shape}"
            raise ValueError(msg)
        i = 0
        while i < len(scans):
            n = scans[i].ranges_m.size  # type: ignore[attr-defined]
            j = i
            while j < len(scans) and scans[j].ranges_m.size == n:  # type: ignore[attr-defined]
                j += 1
            group = scans[i:j]
            self.integrate(
                ScanBatch(
                    ranges_m=np.stack([s.ranges_m for s in group]),  # type: ignore[attr-defined]
                    angles_rad=beam_angles(n),
                    poses=np.array([s.laser_pose for s in group], dtype=np.float64)  # type: ignore[attr-defined]
                    if override is None
                    else override[i:j],
                )
            )
            i = j

    def _integrate_chunk(
        self,
        ranges: npt.NDArray[np.float32],
        poses: npt.NDArray[np.float64],
        angles: npt.NDArray[np.float64],
    ) -> None:
        p = self.params
        res = p.resolution_m
        valid = ranges >= p.min_range_m
        hit = valid & (ranges < p.max_range_m)
        no_return = min(p.no_return_free_m, p.max_range_m)
        length = np.where(hit, ranges, np.where(valid, no_return, 0.0)).astype(np.float64)
        theta = poses[:, 2:3] + angles[None, :]  # (S, B)
        cos_t, sin_t = np.cos(theta), np.sin(theta)
        ox, oy = poses[:, 0:1], poses[:, 1:2]
        ex, ey = ox + length * cos_t, oy + length * sin_t
        # World cell indices (ix along x, iy along y) of ray origins and ends bound the update.
        all_x = np.concatenate([ex.ravel(), poses[:, 0]])
        all_y = np.concatenate([ey.ravel(), poses[:, 1]])
        lo = np.floor(np.array([all_x.min(), all_y.min()]) / res).astype(np.int64)
        hi = np.floor(np.array([all_x.max(), all_y.max()]) / res).astype(np.int64)
        self._ensure_covers(lo, hi)
        rows, cols = self.shape
        ox0, oy0 = self._origin_cell * res

        # Free samples: one per cell length, from the ray origin to one cell short of the end.
        # Counted over pieces of at most _MAX_FREE_SAMPLES samples (the counts add up, so the map
        # is the same): 16 scans of 100,000 beams of 25 m are 800 million samples, which took
        # all of a 24 GB machine's memory at once.
        n_free_all = np.floor(length / res - 1.0).clip(min=0).astype(np.int64).ravel()
        ox_rays = (ox - ox0).astype(np.float32).repeat(angles.size, axis=1).ravel()
        oy_rays = (oy - oy0).astype(np.float32).repeat(angles.size, axis=1).ravel()
        cos_rays = cos_t.astype(np.float32).ravel()
        sin_rays = sin_t.astype(np.float32).ravel()
        size = rows * cols
        miss_count = np.zeros(size, dtype=np.int64)
        ends = np.cumsum(n_free_all)
        first = 0
        while first < n_free_all.size:
            done = int(ends[first - 1]) if first else 0
            # the rays whose samples fit in the piece (at least one ray)
            last = max(
                int(np.searchsorted(ends, done + _MAX_FREE_SAMPLES, side="right")), first + 1
            )
            n_free = n_free_all[first:last]
            total = int(n_free.sum())
            beam = np.repeat(np.arange(n_free.size), n_free)
            starts = np.cumsum(n_free) - n_free
            t = (np.arange(total, dtype=np.int64) - np.repeat(starts, n_free)).astype(np.float32)
            t = (t + 0.5) * np.float32(res)
            fx = ox_rays[first:last][beam]
            fy = oy_rays[first:last][beam]
            fx += t * cos_rays[first:last][beam]
            fy += t * sin_rays[first:last][beam]
            free_idx = (np.floor(fy / res).astype(np.int64) * cols) + np.floor(fx / res).astype(
                np.int64
            )
            counts = np.bincount(free_idx)
            miss_count[: counts.size] += counts
            first = last

        hx = np.floor((ex[hit] - ox0) / res).astype(np.int64)
        hy = np.floor((ey[hit] - oy0) / res).astype(np.int64)
        hit_idx = hy * cols + hx

        hit_count = np.bincount(hit_idx, minlength=size)
        delta = (p.log_odds_miss * miss_count + p.log_odds_hit * hit_count).astype(np.float32)
        flat = self._log_odds.reshape(-1)
        flat += delta
        np.clip(flat, p.clamp_min, p.clamp_max, out=flat)
        touched = (miss_count > 0) | (hit_count > 0)
        self._observed.reshape(-1)[touched] = True
        self.scan_count += ranges.shape[0]


#: Most free-space samples of one ray-casting piece (about 40 bytes each while they are counted).
_MAX_FREE_SAMPLES = 4_000_000


def crop_to_known(
    grid: npt.NDArray[np.int8], *, margin_px: int = 10
) -> tuple[npt.NDArray[np.int8], tuple[int, int]]:
    """Crop a ROS grid to the bounding box of its known cells plus ``margin_px`` cells.

    Parameters
    ----------
    grid : ndarray of int8, shape (rows, cols)
        ROS convention (-1 unknown).
    margin_px : int
        Unknown border kept around the known cells, in cells.

    Returns
    -------
    cropped : ndarray of int8, shape (r, c)
        A copy; the whole grid when nothing is known.
    offset : tuple of int
        ``(row, col)`` of the cropped grid's cell (0, 0) in ``grid``.
    """
    known = grid >= 0
    if not known.any():
        return grid.copy(), (0, 0)
    rows = np.flatnonzero(known.any(axis=1))
    cols = np.flatnonzero(known.any(axis=0))
    r0 = max(int(rows[0]) - margin_px, 0)
    c0 = max(int(cols[0]) - margin_px, 0)
    r1 = min(int(rows[-1]) + margin_px + 1, grid.shape[0])
    c1 = min(int(cols[-1]) + margin_px + 1, grid.shape[1])
    return grid[r0:r1, c0:c1].copy(), (r0, c0)
