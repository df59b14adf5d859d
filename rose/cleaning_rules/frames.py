"""Rotated frames along the dominant directions, in which walls at an angle to the grid lie along rows.

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

#: Directions closer than this to a right angle of each other share one rotated frame.
_PAIR_TOLERANCE_RAD = math.radians(3.0)


def _frames(directions: npt.NDArray[np.float64]) -> list[float]:
    """One rotation per group of directions at right angles to each other, in ``[0, pi/2)``."""
    frames: list[float] = []
    for angle in np.mod(directions, math.pi / 2).tolist():
        if all(
            min(abs(angle - f), math.pi / 2 - abs(angle - f)) > _PAIR_TOLERANCE_RAD for f in frames
        ):
            frames.append(angle)
    return frames


def _rotate(
    source: npt.NDArray[np.uint8], angle: float
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float64] | None]:
    """``source`` rotated so that ``angle`` lies along the columns, and the forward affine matrix
    (None when ``angle`` is within half a degree of an axis and nothing was rotated)."""
    import cv2

    if min(angle, math.pi / 2 - angle) < math.radians(0.5):
        return source, None
    rows, cols = source.shape
    c, s = math.cos(angle), math.sin(angle)
    corners = np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], dtype=np.float64)
    u = corners[:, 0] * c + corners[:, 1] * s
    v = -corners[:, 0] * s + corners[:, 1] * c
    matrix = np.array([[c, s, -u.min()], [-s, c, -v.min()]], dtype=np.float64)
    size = (math.ceil(u.max() - u.min()) + 1, math.ceil(v.max() - v.min()) + 1)
    rotated = cv2.warpAffine(source, matrix, size, flags=cv2.INTER_NEAREST)
    return np.asarray(rotated, dtype=np.uint8), matrix
