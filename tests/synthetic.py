"""Synthetic maps with known answers, shared by the tests."""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt


def floor_plan(
    *, size: tuple[int, int] = (400, 500), angle_deg: float = 0.0, wall_px: int = 2
) -> npt.NDArray[np.bool_]:
    """A rectangular building with rooms, rotated by ``angle_deg`` about the centre (bool mask).

    Walls run along ``angle_deg`` and ``angle_deg + 90`` in the map frame (x = columns, y = rows).
    """
    rows, cols = size
    # Wall segments in a local frame centred on the map, before rotation: (x0, y0, x1, y1).
    half_w, half_h = 0.32 * min(rows, cols) * 1.3, 0.32 * min(rows, cols)
    segments = [
        (-half_w, -half_h, half_w, -half_h),
        (half_w, -half_h, half_w, half_h),
        (half_w, half_h, -half_w, half_h),
        (-half_w, half_h, -half_w, -half_h),
        (-half_w, 0.1 * half_h, 0.6 * half_w, 0.1 * half_h),
        (-0.3 * half_w, -half_h, -0.3 * half_w, 0.1 * half_h),
        (0.3 * half_w, 0.1 * half_h, 0.3 * half_w, half_h),
        (0.6 * half_w, -half_h, 0.6 * half_w, -0.2 * half_h),
    ]
    image = np.zeros((rows, cols), dtype=np.uint8)
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    cx, cy = cols / 2.0, rows / 2.0
    for x0, y0, x1, y1 in segments:
        p0 = (round(cx + c * x0 - s * y0), round(cy + s * x0 + c * y0))
        p1 = (round(cx + c * x1 - s * y1), round(cy + s * x1 + c * y1))
        cv2.line(image, p0, p1, 1, thickness=wall_px)
    return image.astype(bool)


def add_clutter(
    mask: npt.NDArray[np.bool_], *, blobs: int, specks: int, seed: int
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Add filled round blobs and single-cell specks away from the walls.

    Returns ``(cluttered, truth)`` where ``truth`` marks the added cells.
    """
    rng = np.random.default_rng(seed)
    rows, cols = mask.shape
    near_wall = cv2.dilate(mask.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    clutter = np.zeros_like(mask)
    blob_image = np.zeros(mask.shape, dtype=np.uint8)
    for _ in range(blobs):
        centre = (int(rng.integers(10, cols - 10)), int(rng.integers(10, rows - 10)))
        cv2.circle(blob_image, centre, int(rng.integers(2, 6)), 1, thickness=-1)
    clutter |= blob_image.astype(bool)
    speck_rows = rng.integers(0, rows, specks)
    speck_cols = rng.integers(0, cols, specks)
    clutter[speck_rows, speck_cols] = True
    clutter &= ~near_wall
    return mask | clutter, clutter


def ros_floor_plan(size: tuple[int, int] = (300, 360)) -> npt.NDArray[np.int8]:
    """:func:`floor_plan` as a ROS occupancy grid (100 walls, 0 free), int8."""
    return np.where(floor_plan(size=size), 100, 0).astype(np.int8)


def right_half_drifted(plan: npt.NDArray[np.int8], cells: int) -> npt.NDArray[np.int8]:
    """``plan`` with its right half redrawn ``cells`` cells further right: a map redrawn from a
    pose graph whose right part drifts (its old walls move with it)."""
    half = plan.shape[1] // 2
    out = plan.copy()
    out[:, half:] = 0
    out[:, half + cells :] = plan[:, half : plan.shape[1] - cells]
    return out
