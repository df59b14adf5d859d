"""The evaluation's input maps: Radish logs rasterised at a resolution, benchmark map images."""

from __future__ import annotations

import functools
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rose import MapFileError, load_map
from rose_logs.carmen.drift import apply_drift
from rose_logs.carmen.parse import CarmenLog, read_carmen_log
from rose_logs.carmen.raycast import (
    BuilderParams,
    OccupancyGridBuilder,
    crop_to_known,
)
from rose_logs.evaluation.config import log_name

__all__ = ["LogMap", "furniture_pair", "load_benchmark_map", "rasterise_log", "read_log"]

_LOG = logging.getLogger(__name__)
#: Grey levels below this are obstacles in the benchmark's furniture drawings (Bormann et al. treat
#: every non-white pixel as an obstacle); furniture is drawn in mid greys.
_FURNITURE_GREY_BELOW = 250


@dataclass(frozen=True, eq=False)
class LogMap:
    """A map rasterised from a log.

    Attributes
    ----------
    name : str
        Log name (``aces``...).
    grid : ndarray of int8, shape (rows, cols)
        ROS convention, cropped to the known cells plus a margin.
    resolution_m : float
        Cell size, metres.
    drift_level : float
        Drift level of the poses (0: corrected poses).
    drift_seed : int
        Seed of the drift.
    scans : int
        Scans integrated.
    build_s : float
        Wall time of the rasterisation, seconds.
    """

    name: str
    grid: npt.NDArray[np.int8]
    resolution_m: float
    drift_level: float
    drift_seed: int
    scans: int
    build_s: float


@functools.lru_cache(maxsize=8)
def read_log(path: Path) -> CarmenLog:
    """:func:`rose_logs.carmen.parse.read_carmen_log`, cached per path."""
    return read_carmen_log(path)


def rasterise_log(
    path: Path,
    *,
    resolution_m: float,
    drift_level: float = 0.0,
    drift_seed: int = 0,
    name: str | None = None,
) -> LogMap:
    """Build the occupancy grid of a CARMEN log, optionally with odometry drift on the poses."""
    log = read_log(Path(path))
    start = time.perf_counter()
    poses = apply_drift(log.laser_poses, level=drift_level, seed=drift_seed)
    builder = OccupancyGridBuilder(BuilderParams(resolution_m=resolution_m))
    builder.integrate_scans(log.scans, poses)
    grid, _ = crop_to_known(builder.grid(), margin_px=10)
    elapsed = time.perf_counter() - start
    label = name if name is not None else log_name(Path(path).name)
    _LOG.info(
        "%s drift %.2f seed %d: %s cells in %.2f s",
        label,
        drift_level,
        drift_seed,
        grid.shape,
        elapsed,
    )
    return LogMap(
        name=label,
        grid=grid,
        resolution_m=resolution_m,
        drift_level=drift_level,
        drift_seed=drift_seed,
        scans=len(log.scans),
        build_s=elapsed,
    )


def load_benchmark_map(path: Path) -> npt.NDArray[np.int8]:
    """A benchmark image as a ROS grid (map_server trinary thresholds, see :func:`rose.load_map`)."""
    return load_map(path).grid


def _grey(path: Path) -> npt.NDArray[np.uint8]:
    import cv2

    from rose.mapfile import checked_image_bytes

    # Sized from its header before decoding, as load_map sizes the clean drawing: a 0.4 MB PNG
    # declaring 20000 x 20000 pixels took 0.9 GB in cv2.imread.
    raw = checked_image_bytes(Path(path))
    image = cv2.imdecode(np.frombuffer(raw, dtype=np.uint8), cv2.IMREAD_GRAYSCALE)
    if image is None:
        msg = f"{path}: cannot read image"
        raise MapFileError(msg)
    # Image rows are top first; ROS grids start at the bottom.
    return np.ascontiguousarray(image[::-1], dtype=np.uint8)


def furniture_pair(
    clean_path: Path, furniture_path: Path
) -> tuple[npt.NDArray[np.int8], npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """The furnished benchmark map and its exact ground truth.

    Furniture cells are the cells that are free in the clean map (map_server thresholds) and darker
    than grey 250 in the ``_furnitures`` image, which draws furniture in mid greys. The returned grid
    is the clean grid with those cells occupied (100).

    Returns
    -------
    grid : ndarray of int8, shape (rows, cols)
    structure : ndarray of bool, shape (rows, cols)
        Occupied cells of the clean map.
    clutter : ndarray of bool, shape (rows, cols)
        Furniture cells.
    """
    clean = load_benchmark_map(clean_path)
    grey = _grey(furniture_path)
    if grey.shape != clean.shape:
        msg = f"{furniture_path}: shape {grey.shape} differs from {clean_path} {clean.shape}"
        raise MapFileError(msg)
    structure = clean >= 65
    clutter = (clean >= 0) & ~structure & (grey < _FURNITURE_GREY_BELOW)
    grid = clean.copy()
    grid[clutter] = 100
    return grid, structure, clutter
