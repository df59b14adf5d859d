"""Rotated frames along the dominant directions, in which walls at an angle to the grid lie along rows.

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import math
from collections.abc import Callable

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


#: A rotated frame holds at most this many times the cells of the box it turns (a square box at
#: 45 degrees: 2 times) or ``_FRAME_CELLS_WHOLE`` cells; a longer, thinner box is turned in
#: overlapping pieces along its length (:func:`in_rotated_frame`): a strip of 3 x 200,000 cells turned
#: 66 degrees asked for 14 GB at once.
_MAX_FRAME_GROWTH = 4.0
_FRAME_CELLS_WHOLE = 1 << 22


def _rotation(
    rows: int, cols: int, angle: float, origin: tuple[float, float] | None = None
) -> tuple[npt.NDArray[np.float64], tuple[int, int]]:
    """The forward affine matrix turning a ``rows`` x ``cols`` image so that ``angle`` lies along the
    columns, and the turned image's size ``(width, height)``.

    ``origin``: where the image's cell (0, 0) lands in a larger image's turned frame (the image a
    piece of it); the piece's frame is then that frame shifted by whole cells, so that both sample
    the same points.
    """
    c, s = math.cos(angle), math.sin(angle)
    corners = np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], dtype=np.float64)
    u = corners[:, 0] * c + corners[:, 1] * s
    v = -corners[:, 0] * s + corners[:, 1] * c
    if origin is None:
        tu, tv = -u.min(), -v.min()
    else:
        tu = origin[0] - math.floor(origin[0] + u.min())
        tv = origin[1] - math.floor(origin[1] + v.min())
    matrix = np.array([[c, s, tu], [-s, c, tv]], dtype=np.float64)
    return matrix, (math.ceil(u.max() + tu) + 1, math.ceil(v.max() + tv) + 1)


def _along_an_axis(angle: float) -> bool:
    """Whether ``angle`` (in ``[0, pi/2)``) is within half a degree of an axis: not rotated."""
    return min(angle, math.pi / 2 - angle) < math.radians(0.5)


def _rotate(
    source: npt.NDArray[np.uint8], angle: float, origin: tuple[float, float] | None = None
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float64] | None]:
    """``source`` rotated so that ``angle`` lies along the columns, and the forward affine matrix
    (None when ``angle`` is within half a degree of an axis and nothing was rotated); ``origin``
    as :func:`_rotation`'s."""
    import cv2

    if _along_an_axis(angle):
        return source, None
    rows, cols = source.shape
    matrix, size = _rotation(rows, cols, angle, origin)
    rotated = cv2.warpAffine(source, matrix, size, flags=cv2.INTER_NEAREST)
    return np.asarray(rotated, dtype=np.uint8), matrix


FrameWork = Callable[[npt.NDArray[np.uint8], bool], npt.NDArray[np.uint8]]
"""A rule's work in a rotated frame: ``(rotated image, whether it was turned)`` -> an image of the
rotated image's shape (uint8), sampled back into the source's cells by :func:`in_rotated_frame`."""


def in_rotated_frame(
    source: npt.NDArray[np.uint8], angle: float, work: FrameWork, *, reach_px: int
) -> tuple[npt.NDArray[np.uint8], bool]:
    """``work`` done on ``source`` turned so that ``angle`` lies along the columns (:func:`_rotate`),
    its output back in ``source``'s cells (nearest-neighbour), and whether it was turned.

    A long, thin ``source`` whose turned frame would be too large (``_MAX_FRAME_GROWTH``) is
    turned in pieces along its length, each with ``reach_px`` cells of the source on either side
    (the farthest a rule looks) and its frame on the whole frame's cells, and each piece's own
    cells kept: what a rule finds there is what it finds in the whole.
    """
    if _along_an_axis(angle):
        return work(np.ascontiguousarray(source), False), False
    rows, cols = source.shape
    whole, (width, height) = _rotation(rows, cols, angle)
    if width * height <= max(_MAX_FRAME_GROWTH * rows * cols, _FRAME_CELLS_WHOLE):
        return _turned_and_back(source, angle, work), True
    # Pieces along the longer axis (as rows: a transposed view for a wide box).
    wide = cols > rows
    along = source.T if wide else source
    length, short = along.shape
    core = max(4 * short, 2 * reach_px, 64)
    out = np.zeros(along.shape, dtype=np.uint8)
    for start in range(0, length, core):
        stop = min(start + core, length)
        low, high = max(start - reach_px, 0), min(stop + reach_px, length)
        piece = along[low:high].T if wide else along[low:high]
        corner = np.array([low, 0] if wide else [0, low], dtype=np.float64)  # its cell (0, 0)
        origin = whole[:, :2] @ corner + whole[:, 2]
        back = _turned_and_back(
            np.ascontiguousarray(piece), angle, work, (float(origin[0]), float(origin[1]))
        )
        out[start:stop] = (back.T if wide else back)[start - low : stop - low]
    return (np.ascontiguousarray(out.T) if wide else out), True


def _turned_and_back(
    source: npt.NDArray[np.uint8],
    angle: float,
    work: FrameWork,
    origin: tuple[float, float] | None = None,
) -> npt.NDArray[np.uint8]:
    """``work`` in ``source``'s frame turned by ``angle`` (``origin`` as :func:`_rotation`'s), its
    output sampled back into ``source``'s cells (nearest-neighbour: values are copied, bits and
    all)."""
    import cv2

    rows, cols = source.shape
    rotated, matrix = _rotate(source, angle, origin)
    done = work(np.ascontiguousarray(rotated), True)
    assert matrix is not None
    back = cv2.warpAffine(
        done, matrix, (cols, rows), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP
    )
    return np.asarray(back, dtype=np.uint8)
