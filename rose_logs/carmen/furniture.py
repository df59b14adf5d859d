"""Virtual furniture for laser logs: seeded objects in the beams' way, seen as a scanner sees them.

Objects are unions of primitives in the log's world frame (metres, radians):

- ``box``: a rectangle 0.3..1.2 m by 0.3..1.0 m, along a dominant direction of the building or at a
  random angle;
- ``table``: four square legs (0.05..0.08 m) at the corners of a 0.8..1.8 m by 0.6..1.0 m top (a
  planar laser at leg height sees only the legs);
- ``bin``: a disc of radius 0.12..0.25 m;
- ``cabinet``: a rectangle 0.35..0.6 m deep and 0.6..2.0 m long with its back against a wall, along
  the wall.

Objects are placed on known free cells of the map built from the original scans, clear of the robot's
path (``clearance_m`` from every pose) so no scan starts inside one; free-standing objects stay
``gap_m`` clear of occupied cells, cabinets touch them. :func:`shorten_ranges` then cuts every beam at
the first object it meets (a beam without return that meets one now returns), so the map built from
the new ranges shows faces only, with unknown shadows behind.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["Furniture", "place_furniture", "rasterise_furniture", "shorten_ranges"]

_KINDS = ("box", "table", "bin", "cabinet")
#: Relative frequency of each kind.
_WEIGHTS = (0.3, 0.25, 0.2, 0.25)
_ATTEMPTS = 60


@dataclass(frozen=True, eq=False)
class Furniture:
    """Seeded virtual objects.

    Attributes
    ----------
    rects : ndarray of float64, shape (R, 5)
        ``(cx_m, cy_m, half_length_m, half_width_m, angle_rad)`` per rectangle, world frame.
    circles : ndarray of float64, shape (C, 3)
        ``(cx_m, cy_m, radius_m)`` per disc.
    kinds : tuple of str
        The kind of every placed object, in placement order.
    """

    rects: npt.NDArray[np.float64]
    circles: npt.NDArray[np.float64]
    kinds: tuple[str, ...]


def _rect_cells(
    rect: npt.NDArray[np.float64], xs: npt.NDArray[np.float64], ys: npt.NDArray[np.float64]
) -> npt.NDArray[np.bool_]:
    cx, cy, hl, hw, angle = rect.tolist()
    c, s = math.cos(angle), math.sin(angle)
    dx, dy = xs - cx, ys - cy
    return (np.abs(dx * c + dy * s) <= hl) & (np.abs(-dx * s + dy * c) <= hw)


def _circle_cells(
    circle: npt.NDArray[np.float64], xs: npt.NDArray[np.float64], ys: npt.NDArray[np.float64]
) -> npt.NDArray[np.bool_]:
    cx, cy, r = circle.tolist()
    return np.hypot(xs - cx, ys - cy) <= r


def rasterise_furniture(
    furniture: Furniture,
    shape: tuple[int, int],
    *,
    origin_xy_m: tuple[float, float],
    resolution_m: float,
) -> npt.NDArray[np.bool_]:
    """Cells whose centre lies inside an object, shape ``shape``, ROS grid placement (row 0 at ``y0``)."""
    out = np.zeros(shape, dtype=bool)
    for rect in furniture.rects:
        radius = math.hypot(rect[2], rect[3])
        _paint(
            out,
            rect[:2],
            radius,
            origin_xy_m,
            resolution_m,
            functools.partial(_rect_cells, rect),
        )
    for circle in furniture.circles:
        _paint(
            out,
            circle[:2],
            circle[2],
            origin_xy_m,
            resolution_m,
            functools.partial(_circle_cells, circle),
        )
    return out


def _paint(
    out: npt.NDArray[np.bool_],
    centre: npt.NDArray[np.float64],
    radius: float,
    origin: tuple[float, float],
    res: float,
    inside: Callable[[npt.NDArray[np.float64], npt.NDArray[np.float64]], npt.NDArray[np.bool_]],
) -> None:
    """OR the cells of ``out`` whose centre is ``inside`` a shape within ``radius`` of ``centre``."""
    rows, cols = out.shape
    c0 = max(math.floor((centre[0] - radius - origin[0]) / res), 0)
    c1 = min(math.ceil((centre[0] + radius - origin[0]) / res) + 1, cols)
    r0 = max(math.floor((centre[1] - radius - origin[1]) / res), 0)
    r1 = min(math.ceil((centre[1] + radius - origin[1]) / res) + 1, rows)
    if r1 <= r0 or c1 <= c0:
        return
    ys, xs = np.mgrid[r0:r1, c0:c1].astype(np.float64)
    xs = origin[0] + (xs + 0.5) * res
    ys = origin[1] + (ys + 0.5) * res
    out[r0:r1, c0:c1] |= inside(xs, ys)


def place_furniture(
    grid: npt.NDArray[np.int8],
    *,
    origin_xy_m: tuple[float, float],
    resolution_m: float,
    poses: npt.NDArray[np.float64],
    directions: npt.NDArray[np.float64],
    count: int,
    seed: int,
    clearance_m: float = 0.4,
    gap_m: float = 0.1,
) -> Furniture:
    """Place ``count`` seeded objects on the free space of ``grid`` (module notes).

    Parameters
    ----------
    grid : ndarray of int8, shape (rows, cols)
        Map built from the original scans, ROS convention, placed at ``origin_xy_m``.
    origin_xy_m : tuple of float
        World position of the outer corner of cell (0, 0), metres.
    resolution_m : float
        Cell size, metres.
    poses : ndarray of float64, shape (S, 3)
        Laser poses ``(x_m, y_m, theta_rad)``, world frame.
    directions : ndarray of float64, shape (K,)
        Wall orientations of the building (radians, world frame), e.g. ROSE's dominant directions.
    count : int
        Objects to place; fewer when the map has no room for them (after a bounded number of tries).
    seed : int
        Seed: the same inputs give the same objects.
    clearance_m, gap_m : float
        Distance kept from every pose / from occupied cells (free-standing objects), metres.
    """
    res = resolution_m
    space = _placement_space(
        grid, origin_xy_m=origin_xy_m, res=res, poses=poses, gap_m=gap_m, clearance_m=clearance_m
    )
    rng = np.random.default_rng(seed)
    directions = np.asarray(directions, dtype=np.float64)
    if directions.size == 0:
        directions = np.zeros(1)
    rects: list[list[float]] = []
    circles: list[list[float]] = []
    kinds: list[str] = []
    taken = np.zeros(grid.shape, dtype=bool)

    def fits(parts_r: list[list[float]], parts_c: list[list[float]], *, touching: bool) -> bool:
        trial = Furniture(np.array(parts_r).reshape(-1, 5), np.array(parts_c).reshape(-1, 3), ())
        cells = rasterise_furniture(trial, grid.shape, origin_xy_m=origin_xy_m, resolution_m=res)
        if not cells.any():
            return False
        inside = space.allowed & ~taken & (True if touching else space.wall_m > gap_m)
        if not bool(np.all(inside[cells])):
            return False
        taken[cells] = True
        return True

    for _ in range(count):
        kind = str(rng.choice(_KINDS, p=_WEIGHTS))
        pool = space.wall_side if kind == "cabinet" else space.free_cells
        if pool.size == 0:
            continue
        for _attempt in range(_ATTEMPTS):
            cell = int(pool[rng.integers(pool.size)])
            r, c = divmod(cell, grid.shape[1])
            base = float(directions[rng.integers(directions.size)])
            aligned = rng.random() < 0.7
            angle = base if aligned else float(rng.uniform(0, math.pi))
            parts = _object_parts(kind, r, c, base, angle, rng, space, taken, origin_xy_m, res)
            if parts is not None and fits(*parts, touching=kind == "cabinet"):
                rects.extend(parts[0])
                circles.extend(parts[1])
                kinds.append(kind)
                break
    return Furniture(
        rects=np.array(rects, dtype=np.float64).reshape(-1, 5),
        circles=np.array(circles, dtype=np.float64).reshape(-1, 3),
        kinds=tuple(kinds),
    )


@dataclass(frozen=True, eq=False)
class _Space:
    """Where objects may go on a grid (all arrays of the grid's shape, or flat cell indices)."""

    allowed: npt.NDArray[np.bool_]  # free and clear of the robot's path
    wall_m: npt.NDArray[np.float64]  # distance to the nearest occupied cell, metres
    nearest: npt.NDArray[np.intp]  # (2, rows, cols): row and column of that cell
    free_cells: npt.NDArray[np.intp]  # allowed cells at least gap_m from any wall
    wall_side: npt.NDArray[np.intp]  # allowed cells next to a wall (cabinets)


def _placement_space(
    grid: npt.NDArray[np.int8],
    *,
    origin_xy_m: tuple[float, float],
    res: float,
    poses: npt.NDArray[np.float64],
    gap_m: float,
    clearance_m: float,
) -> _Space:
    from scipy.ndimage import distance_transform_edt

    rows, cols = grid.shape
    free = (grid >= 0) & (grid < 50)
    occupied = grid >= 65
    on_path = np.zeros(grid.shape, dtype=bool)
    pc = np.floor((poses[:, 0] - origin_xy_m[0]) / res).astype(np.int64)
    pr = np.floor((poses[:, 1] - origin_xy_m[1]) / res).astype(np.int64)
    ok = (pc >= 0) & (pc < cols) & (pr >= 0) & (pr < rows)
    on_path[pr[ok], pc[ok]] = True
    path_m = distance_transform_edt(~on_path) * res
    wall_m, nearest = distance_transform_edt(~occupied, return_indices=True)
    wall_m = wall_m * res
    allowed = free & (path_m > clearance_m)
    return _Space(
        allowed=allowed,
        wall_m=wall_m,
        nearest=nearest,
        free_cells=np.flatnonzero(allowed & (wall_m > gap_m)),
        wall_side=np.flatnonzero(allowed & (wall_m <= 1.5 * res + 1e-9)),
    )


def _object_parts(
    kind: str,
    r: int,
    c: int,
    base: float,
    angle: float,
    rng: np.random.Generator,
    space: _Space,
    taken: npt.NDArray[np.bool_],
    origin_xy_m: tuple[float, float],
    res: float,
) -> tuple[list[list[float]], list[list[float]]] | None:
    """Rectangles ``(x, y, half_length, half_width, angle)`` and circles ``(x, y, radius)`` of one
    object of ``kind`` at cell ``(r, c)``, metres / radians; None when a table's top does not fit."""
    x = origin_xy_m[0] + (c + 0.5) * res
    y = origin_xy_m[1] + (r + 0.5) * res
    if kind == "box":
        return [[x, y, rng.uniform(0.15, 0.6), rng.uniform(0.15, 0.5), angle]], []
    if kind == "bin":
        return [], [[x, y, rng.uniform(0.12, 0.25)]]
    if kind == "table":
        hl, hw = rng.uniform(0.4, 0.9), rng.uniform(0.3, 0.5)
        leg = rng.uniform(0.025, 0.04)
        ca, sa = math.cos(angle), math.sin(angle)
        legs = []
        for u, v in ((hl, hw), (hl, -hw), (-hl, hw), (-hl, -hw)):
            lx = x + (u - math.copysign(leg, u)) * ca - (v - math.copysign(leg, v)) * sa
            ly = y + (u - math.copysign(leg, u)) * sa + (v - math.copysign(leg, v)) * ca
            legs.append([lx, ly, leg, leg, angle])
        # The top must fit too: the robot does not drive under it.
        if not _top_fits(x, y, hl, hw, angle, space.allowed, taken, origin_xy_m, res):
            return None
        return legs, []
    # cabinet: back against the nearest wall cell, along the wall
    wr, wc = space.nearest[0][r, c], space.nearest[1][r, c]
    away = math.atan2(r - wr, c - wc)
    normal = min(
        (base, base + math.pi / 2, base + math.pi, base - math.pi / 2),
        key=lambda a: abs(math.remainder(a - away, 2 * math.pi)),
    )
    depth = rng.uniform(0.35, 0.6)
    half = rng.uniform(0.3, 1.0)
    cx = x + (depth / 2 - 0.5 * res) * math.cos(normal)
    cy = y + (depth / 2 - 0.5 * res) * math.sin(normal)
    return [[cx, cy, depth / 2, half, normal]], []


def _top_fits(
    x: float,
    y: float,
    hl: float,
    hw: float,
    angle: float,
    allowed: npt.NDArray[np.bool_],
    taken: npt.NDArray[np.bool_],
    origin: tuple[float, float],
    res: float,
) -> bool:
    """Whether a table top lies wholly on allowed, untaken cells."""
    top = Furniture(np.array([[x, y, hl, hw, angle]]), np.zeros((0, 3)), ())
    cells = rasterise_furniture(top, allowed.shape, origin_xy_m=origin, resolution_m=res)
    return bool(cells.any()) and bool(np.all((allowed & ~taken)[cells]))


def shorten_ranges(
    ranges_m: npt.NDArray[np.float32],
    angles_rad: npt.NDArray[np.float64],
    poses: npt.NDArray[np.float64],
    furniture: Furniture,
    *,
    max_range_m: float,
    min_range_m: float = 0.0,
) -> npt.NDArray[np.float32]:
    """Ranges with every beam cut at the first object it meets.

    Parameters
    ----------
    ranges_m : ndarray of float32, shape (S, B)
        Original ranges, metres. Beams at or beyond ``max_range_m`` have no return; an object in their
        way within ``max_range_m`` gives them one.
    angles_rad : ndarray of float64, shape (B,)
        Beam angles in the laser frame, radians (evenly spaced, increasing).
    poses : ndarray of float64, shape (S, 3)
        Laser poses, world frame.
    furniture : Furniture
    max_range_m, min_range_m : float
        Range limits of the scanner, metres; beams below ``min_range_m`` are left alone.

    Returns
    -------
    ndarray of float32, shape (S, B)
        A new array.
    """
    out = np.array(ranges_m, dtype=np.float32, copy=True)
    limit = np.where(out >= max_range_m, np.float32(max_range_m), out).astype(np.float64)
    valid = out >= min_range_m
    step = float(angles_rad[1] - angles_rad[0]) if angles_rad.size > 1 else math.pi
    prims = [("rect", row) for row in furniture.rects] + [
        ("circle", row) for row in furniture.circles
    ]
    if not prims:
        return out
    centres = np.array([p[1][:2] for p in prims])
    radii = np.array([math.hypot(p[1][2], p[1][3]) if p[0] == "rect" else p[1][2] for p in prims])
    hit_t = np.full(out.shape, np.inf)
    for start in range(0, poses.shape[0], 512):
        sl = slice(start, start + 512)
        pose = poses[sl]
        dx = centres[None, :, 0] - pose[:, None, 0]
        dy = centres[None, :, 1] - pose[:, None, 1]
        dist = np.hypot(dx, dy)
        near = dist - radii[None, :] < max_range_m
        s_idx, p_idx = np.nonzero(near)
        if s_idx.size == 0:
            continue
        d = dist[s_idx, p_idx]
        half = np.where(
            d > radii[p_idx], np.arcsin(np.clip(radii[p_idx] / np.maximum(d, 1e-9), 0, 1)), math.pi
        )
        bearing = np.arctan2(dy[s_idx, p_idx], dx[s_idx, p_idx]) - pose[s_idx, 2]
        bearing = np.mod(bearing + math.pi, 2 * math.pi) - math.pi
        lo = (
            np.ceil((bearing - half - angles_rad[0]) / step)
            .astype(np.int64)
            .clip(0, angles_rad.size)
        )
        hi = (
            np.floor((bearing + half - angles_rad[0]) / step)
            .astype(np.int64)
            .clip(-1, angles_rad.size - 1)
        )
        n = (hi - lo + 1).clip(min=0)
        total = int(n.sum())
        if total == 0:
            continue
        pair = np.repeat(np.arange(n.size), n)
        beam = lo[pair] + (np.arange(total) - np.repeat(np.cumsum(n) - n, n))
        scan = s_idx[pair] + start
        prim = p_idx[pair]
        theta = poses[scan, 2] + angles_rad[beam]
        t = _intersect(prims, prim, poses[scan, 0], poses[scan, 1], np.cos(theta), np.sin(theta))
        np.minimum.at(hit_t, (scan, beam), t)
    cut = valid & (hit_t < limit) & (hit_t >= min_range_m)
    out[cut] = hit_t[cut].astype(np.float32)
    return out


def _intersect(
    prims: list[tuple[str, npt.NDArray[np.float64]]],
    prim: npt.NDArray[np.intp],
    ox: npt.NDArray[np.float64],
    oy: npt.NDArray[np.float64],
    dx: npt.NDArray[np.float64],
    dy: npt.NDArray[np.float64],
) -> npt.NDArray[np.float64]:
    """Entry distance of each ray into its primitive (inf when it misses or starts inside)."""
    kinds = np.array([p[0] == "rect" for p in prims])
    params = np.zeros((len(prims), 5))
    for i, (_, row) in enumerate(prims):
        params[i, : row.size] = row
    is_rect = kinds[prim]
    q = params[prim]
    with np.errstate(divide="ignore", invalid="ignore"):
        # Rectangles: slabs in the rectangle's frame.
        c, s = np.cos(q[:, 4]), np.sin(q[:, 4])
        px, py = ox - q[:, 0], oy - q[:, 1]
        lx, ly = px * c + py * s, -px * s + py * c
        ux, uy = dx * c + dy * s, -dx * s + dy * c
        tx1, tx2 = (-q[:, 2] - lx) / ux, (q[:, 2] - lx) / ux
        ty1, ty2 = (-q[:, 3] - ly) / uy, (q[:, 3] - ly) / uy
        tmin = np.maximum(np.minimum(tx1, tx2), np.minimum(ty1, ty2))
        tmax = np.minimum(np.maximum(tx1, tx2), np.maximum(ty1, ty2))
        rect_t = np.where((tmax >= tmin) & (tmin > 0), tmin, np.inf)
        # Discs.
        b = px * dx + py * dy
        cc = px * px + py * py - q[:, 2] ** 2
        disc = b * b - cc
        circ_t = np.where((disc >= 0) & (cc > 0), -b - np.sqrt(np.maximum(disc, 0)), np.inf)
        circ_t = np.where(circ_t > 0, circ_t, np.inf)
    t = np.where(is_rect, rect_t, circ_t)
    return np.nan_to_num(t, nan=np.inf)
