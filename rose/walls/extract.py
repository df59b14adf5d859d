"""Wall segments from occupancy grids: a probabilistic-Hough baseline and the ROSE variant.

Both pipelines share every step but two (the paper's Section 4.1):

1. *Wall pixels*: occupied cells (occupancy ``>= occupied_threshold``). With ``faces_only`` (the
   default) only the occupied cells that touch a non-occupied cell (8-neighbourhood) are kept, so a
   map whose outside is filled black (e.g. ``lab_ipa``) yields its inner outline instead of a mat of
   lines through the solid region; a thick wall yields its two faces, which step 3 merges.
2. *Segments*: OpenCV's probabilistic Hough transform (``cv2.HoughLinesP``; deterministic, OpenCV seeds
   its generator on every call) on the wall pixels.
3. *Merging*: segments that are collinear (orientations within ``merge_angle_deg``, every endpoint
   within ``merge_distance_px`` of the other's line) and overlap or leave a gap of at most
   ``merge_gap_px`` are replaced by one segment: length-weighted axial mean orientation, through the
   length-weighted centroid of their midpoints, spanning all their endpoints. Repeated until stable.
4. Segments shorter than ``min_wall_length_px`` are dropped.

:func:`extract_walls_hough` (the baseline) runs this on the raw map. :func:`extract_walls` (ROSE) keeps
only the wall pixels that ROSE labels structure, and rotates every segment within
``snap_tolerance_deg`` of a dominant direction about its midpoint onto it before and after merging,
so parallel near-duplicates collapse. With ``extend_on_raw`` (the default) the merged segments are
then extended along the raw map's wall pixels (structure or not) and merged once more.

"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt
from scipy.ndimage import binary_erosion
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from rose.errors import RoseError
from rose.grid import as_occupancy_grid, occupied_mask, warn_if_mask
from rose.limits import finite_number, integer_number, pair_of
from rose.mapfile import (
    DEFAULT_RESOLUTION_M,
    OccupancyMap,
    origin_problem,
    resolution_problem,
)
from rose.pipeline import analyze
from rose.result import RoseResult, check_result_for
from rose.walls.segments import WallMethod, WallSet, axial_difference, segment_orientations

__all__ = ["WallParams", "extract_walls", "extract_walls_hough", "hough_segments", "wall_pixels"]

logger = logging.getLogger(__name__)

_MAX_MERGE_ROUNDS = 8
_PAIR_BLOCK = 256


@dataclass(frozen=True)
class WallParams:
    """Tuning parameters of :func:`extract_walls_hough` and :func:`extract_walls`.

    Lengths are in cells (``_px``), angles in degrees. The defaults suit maps of about 5 cm per cell.

    Attributes
    ----------
    occupied_threshold : int
        Occupancy (percent, 1..100) from which a cell counts as occupied.
    faces_only : bool
        Keep only occupied cells with a non-occupied 8-neighbour (wall faces) as Hough input.
    hough_rho_px : float
        Distance resolution of the Hough accumulator, in cells.
    hough_theta_deg : float
        Angle resolution of the Hough accumulator, in degrees.
    hough_votes : int
        Accumulator threshold: the fewest wall pixels on a line for it to be considered.
    hough_min_length_px : float
        Shortest segment ``cv2.HoughLinesP`` reports, in cells.
    hough_max_gap_px : float
        Largest gap between wall pixels that ``cv2.HoughLinesP`` bridges within one segment, in cells.
    merge_angle_deg : float
        Largest orientation difference of two segments that may merge, in degrees.
    merge_distance_px : float
        Largest distance of either segment's endpoints from the other's line for a merge, in cells.
        Should exceed the wall thickness so that the two faces of a wall merge.
    merge_gap_px : float
        Largest gap along the line between two segments that may merge, in cells.
    min_wall_length_px : float
        Merged segments shorter than this are dropped, in cells.
    snap_tolerance_deg : float
        ROSE variant only: a segment within this angle of a dominant direction is rotated onto it;
        segments further from every dominant direction keep their own orientation.
    extend_on_raw : bool
        ROSE variant only: extend each segment along its (snapped) line over the raw map's wall
        pixels, within ``extend_band_px`` of the line and bridging gaps up to ``hough_max_gap_px``.
        ROSE's threshold often labels the cells near wall ends and junctions as clutter, which
        leaves walls short; the extension follows only the wall's own line, so clutter off that line
        cannot add walls. A deviation from the paper (which uses the cleaned map alone), on by
        default.
    extend_band_px : float
        Half-width, in cells (at most 100), of the band along a segment's line searched for raw
        wall pixels.
    """

    occupied_threshold: int = 65
    faces_only: bool = True
    hough_rho_px: float = 1.0
    hough_theta_deg: float = 0.5
    hough_votes: int = 15
    hough_min_length_px: float = 8.0
    hough_max_gap_px: float = 3.0
    merge_angle_deg: float = 3.0
    merge_distance_px: float = 4.0
    merge_gap_px: float = 6.0
    min_wall_length_px: float = 10.0
    snap_tolerance_deg: float = 15.0
    extend_on_raw: bool = True
    extend_band_px: float = 2.0

    def __post_init__(self) -> None:
        # numpy scalars as the Python numbers they stand for (a float16 stays float16 in
        # arithmetic), as RoseParams and CleanParams.
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.generic) and not isinstance(value, np.bool_):
                object.__setattr__(self, f.name, value.item())
        problems = []
        for name in ("faces_only", "extend_on_raw"):
            if not isinstance(getattr(self, name), bool | np.bool_):
                problems.append(f"{name} must be True or False, got {getattr(self, name)!r}")
        if not integer_number(self.occupied_threshold) or not 1 <= self.occupied_threshold <= 100:
            problems.append(
                f"occupied_threshold must be an integer in 1..100, got {self.occupied_threshold!r}"
            )
        # OpenCV takes a 32-bit threshold (2**31 was a cv2.error); no map has 1e7 cells on a line.
        if not integer_number(self.hough_votes) or not 1 <= self.hough_votes <= 10**7:
            problems.append(
                f"hough_votes must be an integer in 1..10000000, got {self.hough_votes!r}"
            )
        # OpenCV's Hough transform sizes its accumulator by these two and crashed the interpreter
        # on a distance step of 1e4 cells; steps over a hundred cells or under 0.01 degree mean
        # nothing on a map.
        if not (finite_number(self.hough_rho_px) and 0 < self.hough_rho_px <= 100):
            problems.append(f"hough_rho_px must be in (0, 100] cells, got {self.hough_rho_px!r}")
        if not (finite_number(self.hough_theta_deg) and 0.01 <= self.hough_theta_deg <= 90):
            problems.append(
                f"hough_theta_deg must be in [0.01, 90] degrees, got {self.hough_theta_deg!r}"
            )
        for name in (
            "hough_min_length_px",
            "hough_max_gap_px",
            "merge_angle_deg",
            "merge_distance_px",
            "merge_gap_px",
            "min_wall_length_px",
        ):
            value = getattr(self, name)
            if not (finite_number(value) and value >= 0):
                problems.append(f"{name} must be a finite number >= 0, got {value!r}")
        # The band is searched cell by cell around every segment: 1e5 cells took 45 s, 1e300 failed
        # in numpy; a band of 100 cells (5 m at 5 cm) is no longer "near the line".
        if not (finite_number(self.extend_band_px) and 0 <= self.extend_band_px <= 100):
            problems.append(
                f"extend_band_px must be in [0, 100] cells, got {self.extend_band_px!r}"
            )
        if not (finite_number(self.snap_tolerance_deg) and 0 <= self.snap_tolerance_deg <= 90):
            problems.append(
                f"snap_tolerance_deg must be in [0, 90], got {self.snap_tolerance_deg!r}"
            )
        if problems:
            raise RoseError("; ".join(problems))


def extract_walls_hough(
    grid: npt.ArrayLike | OccupancyMap,
    *,
    params: WallParams | None = None,
    resolution_m: float | None = None,
    origin_xy_m: tuple[float, float] | None = None,
    origin_yaw_rad: float | None = None,
) -> WallSet:
    """Baseline wall segments: probabilistic Hough on the raw map, collinear segments merged.

    Parameters
    ----------
    grid : array_like, shape (rows, cols), or OccupancyMap
        ROS occupancy grid (int8, -1 unknown, 0..100; row 0 at the map origin) or boolean occupied
        mask. An :class:`~rose.OccupancyMap` also supplies the placement. Not modified.
    params : WallParams, optional
        Tuning parameters; :class:`WallParams` defaults if omitted.
    resolution_m, origin_xy_m, origin_yaw_rad : optional
        Map placement used for the metre coordinates. Default: the map's own when ``grid`` is an
        ``OccupancyMap``, else 0.05 m, (0, 0) and 0.

    Returns
    -------
    WallSet
        With ``method="hough"``, longest segments first.

    Raises
    ------
    RoseError
        If the grid is not a 2D grid in ROS convention or a parameter is out of range.
    """
    p = _wall_params(params)
    occupancy, placement = _grid_and_placement(grid, resolution_m, origin_xy_m, origin_yaw_rad)
    warn_if_mask(_given(grid), occupancy, p.occupied_threshold)
    pixels = wall_pixels(
        occupancy, occupied_threshold=p.occupied_threshold, faces_only=p.faces_only
    )
    segments = _merge_collinear(hough_segments(pixels, params=p), params=p, directions=None)
    return _wall_set(segments, occupancy.shape, placement, p, method="hough")


def extract_walls(
    grid: npt.ArrayLike | OccupancyMap,
    result: RoseResult | None = None,
    *,
    params: WallParams | None = None,
    resolution_m: float | None = None,
    origin_xy_m: tuple[float, float] | None = None,
    origin_yaw_rad: float | None = None,
) -> WallSet:
    """ROSE wall segments: Hough on the structure cells, snapped to the dominant directions, merged.

    Parameters
    ----------
    grid : array_like, shape (rows, cols), or OccupancyMap
        As in :func:`extract_walls_hough`. Not modified.
    result : RoseResult, optional
        ROSE's result for ``grid``; computed with :func:`rose.analyze` defaults (at
        ``params.occupied_threshold``) if omitted. Given, its occupied threshold is the walls' too
        (a different ``params.occupied_threshold`` is warned about). When it
        found no structure (``has_structure`` False) there is nothing to snap to: Hough runs on all
        the wall pixels, as in the baseline, but the segments are still merged and extended along
        the raw map (a warning is logged).
    params, resolution_m, origin_xy_m, origin_yaw_rad
        As in :func:`extract_walls_hough`.

    Returns
    -------
    WallSet
        With ``method="rose"`` and ``dominant_directions`` from ``result``, longest segments first.

    Raises
    ------
    RoseError
        As :func:`extract_walls_hough`, or if ``result`` is no RoseResult or was computed on
        another grid (another shape, or other occupied cells).
    """
    p = _wall_params(params)
    occupancy, placement = _grid_and_placement(grid, resolution_m, origin_xy_m, origin_yaw_rad)
    if result is None:  # (a result brings its own warning from rose.analyze)
        warn_if_mask(_given(grid), occupancy, p.occupied_threshold)
        result = analyze(occupancy, occupied_threshold=p.occupied_threshold)
    check_result_for(result, occupancy)
    threshold = result.params.occupied_threshold
    if threshold != p.occupied_threshold:
        # The result says which cells are occupied: at another threshold its structure mask
        # matched no wall pixel (a map analysed at 30 gave no walls at the default 65).
        if params is not None:
            logger.warning(
                "extract_walls: wall pixels read at the result's occupied_threshold %d, not "
                "params.occupied_threshold %d",
                threshold,
                p.occupied_threshold,
            )
        p = dataclasses.replace(p, occupied_threshold=threshold)
    pixels = wall_pixels(
        occupancy, occupied_threshold=p.occupied_threshold, faces_only=p.faces_only
    )
    directions = np.asarray(result.dominant_directions, dtype=np.float64)
    if not result.has_structure:
        if pixels.any():  # an empty or all-unknown map has no segments to snap: nothing to say
            logger.warning("ROSE found no dominant direction: wall segments are not snapped")
        directions = np.empty(0)
    raw_pixels = pixels.copy()
    if result.has_structure:
        pixels &= result.structure
    segments = hough_segments(pixels, params=p)
    segments = _snap(segments, directions, tolerance_rad=math.radians(p.snap_tolerance_deg))
    segments = _merge_collinear(segments, params=p, directions=directions)
    if p.extend_on_raw:
        segments = _extend_along(
            segments, raw_pixels, band_px=p.extend_band_px, max_gap_px=p.hough_max_gap_px
        )
        segments = _merge_collinear(segments, params=p, directions=directions)
    return _wall_set(segments, occupancy.shape, placement, p, method="rose", directions=directions)


def wall_pixels(
    grid: npt.NDArray[np.int8], *, occupied_threshold: int = 65, faces_only: bool = True
) -> npt.NDArray[np.bool_]:
    """Cells that can be part of a wall line.

    Parameters
    ----------
    grid : ndarray of int8, shape (rows, cols)
        Occupancy grid in ROS convention.
    occupied_threshold : int
        Occupancy (percent) from which a cell is occupied.
    faces_only : bool
        Keep only occupied cells with at least one non-occupied cell among their 8 neighbours (cells
        beyond the border count as non-occupied).

    Returns
    -------
    ndarray of bool, shape (rows, cols)
    """
    occupied = occupied_mask(grid, occupied_threshold=occupied_threshold)
    if not faces_only:
        return occupied
    interior = binary_erosion(occupied, structure=np.ones((3, 3), dtype=bool), border_value=0)
    return occupied & ~interior


def hough_segments(pixels: npt.NDArray[np.bool_], *, params: WallParams) -> npt.NDArray[np.float64]:
    """Raw probabilistic-Hough segments of a pixel mask.

    Parameters
    ----------
    pixels : ndarray of bool, shape (rows, cols)
        Wall pixels (row 0 = map origin; no flip is needed since OpenCV's x, y are column, row).
    params : WallParams
        Uses the ``hough_*`` fields.

    Returns
    -------
    ndarray of float64, shape (N, 2, 2)
        Segments ``[start, end]`` as ``(col, row)`` cell coordinates, ordered along their orientation.
    """
    if not pixels.any():
        return np.empty((0, 2, 2))
    lines = cv2.HoughLinesP(
        pixels.astype(np.uint8),
        rho=params.hough_rho_px,
        theta=math.radians(params.hough_theta_deg),
        threshold=params.hough_votes,
        minLineLength=params.hough_min_length_px,
        maxLineGap=params.hough_max_gap_px,
    )
    if lines is None:
        return np.empty((0, 2, 2))
    return _ordered(lines.reshape(-1, 2, 2).astype(np.float64))


def _wall_params(params: WallParams | None) -> WallParams:
    if params is not None and not isinstance(params, WallParams):
        msg = f"params must be a WallParams, got {type(params).__name__}"
        raise RoseError(msg)
    return params if params is not None else WallParams()


def _given(grid: npt.ArrayLike | OccupancyMap) -> npt.ArrayLike:
    """The array the caller handed over (a map's grid)."""
    return grid.grid if isinstance(grid, OccupancyMap) else grid


def _grid_and_placement(
    grid: npt.ArrayLike | OccupancyMap,
    resolution_m: float | None,
    origin_xy_m: tuple[float, float] | None,
    origin_yaw_rad: float | None,
) -> tuple[npt.NDArray[np.int8], tuple[float, tuple[float, float], float]]:
    if isinstance(grid, OccupancyMap):
        defaults = (grid.resolution_m, grid.origin_xy_m, grid.origin_yaw_rad)
        occupancy = as_occupancy_grid(grid.grid)
    else:
        defaults = (DEFAULT_RESOLUTION_M, (0.0, 0.0), 0.0)
        occupancy = as_occupancy_grid(grid)
    resolution = resolution_m if resolution_m is not None else defaults[0]
    origin = origin_xy_m if origin_xy_m is not None else defaults[1]
    yaw = origin_yaw_rad if origin_yaw_rad is not None else defaults[2]
    # Checked before float(): a string would convert (or fail with Python's own words).
    if not finite_number(resolution):
        msg = f"resolution_m must be a positive number of metres, got {resolution!r}"
        raise RoseError(msg)
    if not pair_of(origin, finite_number):
        msg = f"origin_xy_m must be two finite numbers (x, y) in metres, got {origin!r}"
        raise RoseError(msg)
    if not finite_number(yaw):
        msg = f"origin_yaw_rad must be a finite number of radians, got {yaw!r}"
        raise RoseError(msg)
    placement = (float(resolution), (float(origin[0]), float(origin[1])), float(yaw))
    problem = resolution_problem(placement[0])
    if problem is not None:
        msg = f"resolution_m {problem}"
        raise RoseError(msg)
    problem = origin_problem(*placement[1], placement[2])
    if problem is not None:
        msg = f"origin_xy_m {placement[1]!r}, origin_yaw_rad {placement[2]!r}: the origin {problem}"
        raise RoseError(msg)
    return occupancy, placement


def _wall_set(
    segments: npt.NDArray[np.float64],
    shape: tuple[int, int],
    placement: tuple[float, tuple[float, float], float],
    p: WallParams,
    *,
    method: WallMethod,
    directions: npt.NDArray[np.float64] | None = None,
) -> WallSet:
    lengths = np.hypot(*(segments[:, 1] - segments[:, 0]).T) if len(segments) else np.empty(0)
    keep = lengths >= p.min_wall_length_px
    order = np.argsort(-lengths[keep], kind="stable")
    resolution, origin, yaw = placement
    return WallSet(
        endpoints_px=segments[keep][order],
        shape=(int(shape[0]), int(shape[1])),
        resolution_m=resolution,
        origin_xy_m=origin,
        origin_yaw_rad=yaw,
        method=method,
        dominant_directions=directions if directions is not None else np.empty(0),
    )


def _ordered(segments: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Swap endpoints where needed so that ``end - start`` points along the orientation in [0, pi)."""
    theta = segment_orientations(segments)
    u = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    flip = np.einsum("ij,ij->i", segments[:, 1] - segments[:, 0], u) < 0
    out = segments.copy()
    out[flip] = out[flip, ::-1]
    return out


def _snap(
    segments: npt.NDArray[np.float64], directions: npt.NDArray[np.float64], *, tolerance_rad: float
) -> npt.NDArray[np.float64]:
    """Rotate each segment about its midpoint onto the nearest direction within ``tolerance_rad``."""
    if len(segments) == 0 or directions.size == 0:
        return segments
    theta = segment_orientations(segments)
    gaps = axial_difference(theta[:, None], directions[None, :])
    nearest = np.argmin(gaps, axis=1)
    snapped = np.where(
        gaps[np.arange(theta.size), nearest] <= tolerance_rad, directions[nearest], theta
    )
    mid = segments.mean(axis=1)
    half = 0.5 * np.hypot(*(segments[:, 1] - segments[:, 0]).T)
    u = np.stack([np.cos(snapped), np.sin(snapped)], axis=1)
    return _ordered(np.stack([mid - half[:, None] * u, mid + half[:, None] * u], axis=1))


def _merge_collinear(
    segments: npt.NDArray[np.float64],
    *,
    params: WallParams,
    directions: npt.NDArray[np.float64] | None,
) -> npt.NDArray[np.float64]:
    """Merge collinear, overlapping or nearly touching segments until nothing changes."""
    tolerance = math.radians(params.snap_tolerance_deg)
    for _ in range(_MAX_MERGE_ROUNDS):
        if len(segments) < 2:
            break
        count, labels = _collinear_components(segments, params=params)
        if count == len(segments):
            break
        segments = _fit_components(segments, labels, count)
        if directions is not None and directions.size:
            segments = _snap(segments, directions, tolerance_rad=tolerance)
    return segments


def _extend_along(
    segments: npt.NDArray[np.float64],
    pixels: npt.NDArray[np.bool_],
    *,
    band_px: float,
    max_gap_px: float,
) -> npt.NDArray[np.float64]:
    """Grow each segment at both ends while ``pixels`` continue along its line (gaps bridged)."""
    if len(segments) == 0:
        return segments
    offsets = np.arange(-math.floor(band_px), math.floor(band_px) + 1, dtype=np.float64)
    out = segments.copy()
    for k, (a, b) in enumerate(segments):
        length = math.hypot(*(b - a))
        if length == 0:
            continue
        u = (b - a) / length
        normal = np.array([-u[1], u[0]])
        for end, sign in ((1, 1.0), (0, -1.0)):
            found = _probe_line(
                pixels, out[k, end], sign * u, normal * 1.0, offsets, int(max_gap_px)
            )
            out[k, end] += sign * _run_length(found, max_gap=int(max_gap_px)) * u
    return out


def _probe_line(
    pixels: npt.NDArray[np.bool_],
    start: npt.NDArray[np.float64],
    step: npt.NDArray[np.float64],
    normal: npt.NDArray[np.float64],
    offsets: npt.NDArray[np.float64],
    max_gap: int,
) -> npt.NDArray[np.bool_]:
    """Whether ``pixels`` has a cell within the band at each step beyond ``start`` along ``step``.

    Probes in growing chunks and stops once the last ``max_gap + 1`` steps found nothing (the run
    has ended) or the line has left the grid: walls end long before the map's diagonal.
    """
    rows, cols = pixels.shape
    reach = int(math.hypot(rows, cols)) + 1
    found: list[npt.NDArray[np.bool_]] = []
    done, chunk = 0, 64
    while done < reach:
        steps = np.arange(done + 1, min(done + chunk, reach) + 1, dtype=np.float64)
        centre = start[None, :] + steps[:, None] * step[None, :]
        probe = centre[:, None, :] + offsets[None, :, None] * normal[None, None, :]
        c = np.rint(probe[..., 0]).astype(np.intp)
        r = np.rint(probe[..., 1]).astype(np.intp)
        inside = (c >= 0) & (c < cols) & (r >= 0) & (r < rows)
        hit = np.zeros(c.shape, dtype=bool)
        hit[inside] = pixels[r[inside], c[inside]]
        found.append(np.asarray(hit.any(axis=1)))
        done += steps.size
        tail = np.concatenate(found)[-(max_gap + 1) :]
        if not inside.any() or (tail.size == max_gap + 1 and not tail.any()):
            break
        chunk *= 2
    return np.concatenate(found)


def _run_length(found: npt.NDArray[np.bool_], *, max_gap: int) -> float:
    """Distance to the last ``True`` before the first run of more than ``max_gap`` ``False``."""
    idx = np.flatnonzero(found)
    if idx.size == 0 or idx[0] > max_gap:
        return 0.0
    breaks = np.flatnonzero(np.diff(idx) > max_gap + 1)
    last = idx[breaks[0]] if breaks.size else idx[-1]
    return float(last + 1)


def _collinear_components(
    segments: npt.NDArray[np.float64], *, params: WallParams
) -> tuple[int, npt.NDArray[np.intp]]:
    """Label the connected components of the 'may merge' relation between segments."""
    n = len(segments)
    theta = segment_orientations(segments)
    u = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    normal = np.stack([-u[:, 1], u[:, 0]], axis=1)
    mid = segments.mean(axis=1)
    half = 0.5 * np.hypot(*(segments[:, 1] - segments[:, 0]).T)
    angle_tol = math.radians(params.merge_angle_deg)
    rows, cols = [], []
    for start in range(0, n, _PAIR_BLOCK):
        i = np.arange(start, min(start + _PAIR_BLOCK, n))
        # Offsets of every segment's endpoints from the block segments' midpoints: (b, n, 2, 2).
        rel = segments[None, :, :, :] - mid[i, None, None, :]
        along = np.einsum("bnkd,bd->bnk", rel, u[i])
        across = np.abs(np.einsum("bnkd,bd->bnk", rel, normal[i])).max(axis=2)
        gap = np.maximum(along.min(axis=2) - half[i, None], -half[i, None] - along.max(axis=2))
        ok = (
            (axial_difference(theta[i, None], theta[None, :]) <= angle_tol)
            & (across <= params.merge_distance_px)
            & (gap <= params.merge_gap_px)
        )
        bi, j = np.nonzero(ok)
        rows.append(i[bi])
        cols.append(j)
    r, c = np.concatenate(rows), np.concatenate(cols)
    # Distance is tested from each side's line; keep a pair only if both directions agree.
    graph = coo_matrix((np.ones(r.size, dtype=np.int8), (r, c)), shape=(n, n)).tocsr()
    mutual = graph.multiply(graph.T)
    count, labels = connected_components(mutual, directed=False)
    return int(count), labels.astype(np.intp)


def _fit_components(
    segments: npt.NDArray[np.float64], labels: npt.NDArray[np.intp], count: int
) -> npt.NDArray[np.float64]:
    """One segment per component: length-weighted axial mean orientation and centroid, full extent."""
    theta = segment_orientations(segments)
    weight = np.maximum(np.hypot(*(segments[:, 1] - segments[:, 0]).T), 1e-9)
    total = np.bincount(labels, weight, minlength=count)
    s2 = np.bincount(labels, weight * np.sin(2 * theta), minlength=count)
    c2 = np.bincount(labels, weight * np.cos(2 * theta), minlength=count)
    phi = 0.5 * np.arctan2(s2, c2)
    u = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    mid = segments.mean(axis=1)
    centre = np.stack(
        [np.bincount(labels, weight * mid[:, k], minlength=count) / total for k in range(2)], axis=1
    )
    along = np.einsum("nkd,nd->nk", segments - centre[labels, None, :], u[labels])
    lo = np.full(count, np.inf)
    hi = np.full(count, -np.inf)
    np.minimum.at(lo, labels, along.min(axis=1))
    np.maximum.at(hi, labels, along.max(axis=1))
    merged = np.stack([centre + lo[:, None] * u, centre + hi[:, None] * u], axis=1)
    return _ordered(merged)
