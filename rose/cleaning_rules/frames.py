"""Rotated frames along the dominant directions, in which walls at an angle to the grid lie along rows.

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`); masks of shape ``(rows, cols)``
in the grid's cell space (row 0 at the map origin), lengths in cells.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

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
    rows: int, cols: int, angle: float
) -> tuple[npt.NDArray[np.float64], tuple[int, int]]:
    """The forward affine matrix turning a ``rows`` x ``cols`` image so that ``angle`` lies along the
    columns, and the turned image's size ``(width, height)``."""
    c, s = math.cos(angle), math.sin(angle)
    corners = np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], dtype=np.float64)
    u = corners[:, 0] * c + corners[:, 1] * s
    v = -corners[:, 0] * s + corners[:, 1] * c
    matrix = np.array([[c, s, -u.min()], [-s, c, -v.min()]], dtype=np.float64)
    return matrix, (math.ceil(u.max() - u.min()) + 1, math.ceil(v.max() - v.min()) + 1)


Frame = tuple[npt.NDArray[np.float64], tuple[int, int]]
"""A turned frame: the forward affine matrix and the frame's size ``(width, height)``."""


def _piece_frame(
    whole: Frame, corner: tuple[int, int], shape: tuple[int, int], margin: int
) -> Frame:
    """The window of the ``whole`` frame that a piece of its source turns into: the piece's cell
    (0, 0) is the source's cell ``corner`` ``(x, y)`` and its shape ``shape``; the window takes
    ``margin`` more of the whole frame's cells on every side (clipped to the whole frame). The
    piece's frame samples the whole frame's points, and its edges lie as far from the piece's
    cells as the whole frame's do, up to ``margin`` (OpenCV's morphology reads beyond an image's
    edge: a frame's edge beside a thin piece changed the fills along it)."""
    matrix, (width, height) = whole
    rows, cols = shape
    x0, y0 = corner
    points = np.array(
        [[x0, y0], [x0 + cols, y0], [x0, y0 + rows], [x0 + cols, y0 + rows]], dtype=np.float64
    )
    u, v = (points @ matrix[:, :2].T + matrix[:, 2]).T
    u0, v0 = max(math.floor(u.min()) - margin, 0), max(math.floor(v.min()) - margin, 0)
    u1 = min(math.ceil(u.max()) + margin, width - 1)
    v1 = min(math.ceil(v.max()) + margin, height - 1)
    piece = matrix.copy()
    piece[:, 2] = matrix[:, :2] @ np.array([x0, y0], dtype=np.float64) + matrix[:, 2] - (u0, v0)
    return piece, (u1 - u0 + 1, v1 - v0 + 1)


def _along_an_axis(angle: float) -> bool:
    """Whether ``angle`` (in ``[0, pi/2)``) is within half a degree of an axis: not rotated."""
    return min(angle, math.pi / 2 - angle) < math.radians(0.5)


def _rotate(
    source: npt.NDArray[np.uint8], angle: float, frame: Frame | None = None
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float64] | None]:
    """``source`` rotated so that ``angle`` lies along the columns (into ``frame``, default its own
    :func:`_rotation`), and the forward affine matrix (None when ``angle`` is within half a degree
    of an axis and nothing was rotated)."""
    import cv2

    if _along_an_axis(angle):
        return source, None
    rows, cols = source.shape
    matrix, size = frame if frame is not None else _rotation(rows, cols, angle)
    rotated = cv2.warpAffine(source, matrix, size, flags=cv2.INTER_NEAREST)
    return np.asarray(rotated, dtype=np.uint8), matrix


FrameWork = Callable[[npt.NDArray[np.uint8], bool], npt.NDArray[np.uint8]]
"""A rule's work in a rotated frame: ``(rotated image, whether it was turned)`` -> an image of the
rotated image's shape (uint8), sampled back into the source's cells by :func:`in_rotated_frame`."""


@dataclass(frozen=True)
class FrameNeeds:
    """What a rule's work (:data:`FrameWork`) needs in a turned image to find anything: on an image
    with none of it, the work returns zeros. Lengths in cells of the turned image; the work's
    cells are those of at least ``cell_from``.

    Attributes
    ----------
    runs : tuple of (grown_px, length_px)
        A run of ``length_px`` cells along a row or a column of the image grown by ``grown_px``
        (a square of ``2 * grown_px + 1`` cells).
    pairs : tuple of (grown_px, gap_px)
        Two cells of different source cells on one row or column of the image grown by
        ``grown_px``, at most ``gap_px`` cells on from one to the next.
    edge_px : int
        A cell within this many cells of the image's edge, along its rows or columns (a closing
        with OpenCV's borders fills from a cell to the edge).
    cell_from : int
        The least value of the cells the work reads as occupied.
    """

    runs: tuple[tuple[int, int], ...] = ()
    pairs: tuple[tuple[int, int], ...] = ()
    edge_px: int = 0
    cell_from: int = 1


#: How far (Euclidean, cells) a cell of a turned image lies from its source cell's centre turned:
#: nearest-neighbour sampling takes the source cell within half a cell along each axis (half a
#: diagonal, 0.71), OpenCV's fixed-point coordinates a thousandth of a cell more.
_SAMPLED_WITHIN_PX = 0.75


def _cells_that_may_find(
    source: npt.NDArray[np.uint8], frame: Frame, needs: FrameNeeds
) -> npt.NDArray[np.intp]:
    """The (row, col) of each cell of ``source`` (shape ``(2, M)``) that may take part in what
    ``needs`` asks for once turned into ``frame`` (:func:`_rotate`); a turned image of any subset
    of the source's cells (the same points shifted by whole cells: a piece's window,
    :func:`_piece_frame`) without one of them holds none of it, but by that window's own edges.

    Worked out on the source's cells turned exactly, each the centre of a disc of
    ``_SAMPLED_WITHIN_PX`` holding the turned image's cells sampled from it: a row of the image
    (and, swapped, a column), grown by the work's growth, holds cells only of the discs so grown
    that reach it; a run along it needs their centres in a chain without a gap wider than the
    growth and the discs leave, a pair two of them in one chain."""
    rows, cols = np.nonzero(source >= needs.cell_from)
    if rows.size == 0:
        return np.stack([rows, cols])
    matrix, (width, height) = frame
    u = matrix[0, 0] * cols + matrix[0, 1] * rows + matrix[0, 2]
    v = matrix[1, 0] * cols + matrix[1, 1] * rows + matrix[1, 2]
    r = _SAMPLED_WITHIN_PX
    may = np.zeros(rows.size, dtype=bool)
    for along, across, extent in ((u, v, width), (v, u, height)):
        if may.all():
            break
        # The cells in order along (for _in_chains), their flags back in the source's order.
        by_along = np.argsort(along)
        along, across = along[by_along], across[by_along]
        here = np.zeros(rows.size, dtype=bool)
        if needs.edge_px > 0:
            here |= along - r <= needs.edge_px + 1
            here |= along + r >= extent - 2 - needs.edge_px
        for grown, length in needs.runs:
            reach = grown + r
            here |= _in_chains(along, across, reach, 2 * reach + 1, min_span=length - 1 - 2 * reach)
        for grown, gap in needs.pairs:
            reach = grown + r
            here |= _in_chains(along, across, reach, gap + 2 * reach, min_points=2)
        may[by_along] |= here
    return np.stack([rows[may], cols[may]])


def _in_chains(
    along: npt.NDArray[np.float64],
    across: npt.NDArray[np.float64],
    reach: float,
    gap: float,
    *,
    min_span: float = 0.0,
    min_points: int = 1,
) -> npt.NDArray[np.bool_]:
    """Which points (shape ``(N,)``, in order ``along``) lie in a chain spanning at least
    ``min_span`` with at least ``min_points`` points: on a line (integer ``across``), the points
    within ``reach`` of it in order ``along``, steps of at most ``gap``."""
    low = np.ceil(across - reach).astype(np.int64)
    count = np.floor(across + reach).astype(np.int64) - low + 1  # lines per point
    point = np.repeat(np.arange(along.size), count)
    line = (
        np.repeat(low, count) + np.arange(point.size) - np.repeat(np.cumsum(count) - count, count)
    )
    # In order by line, then along it: the points come in order along, and a stable sort by line
    # keeps that order (16-bit keys take numpy's radix sort; a thin strip's lines follow its
    # points nearly in order, which numpy's timsort finds).
    key = line - low.min()
    order = np.argsort(key.astype(np.uint16) if key.max() < 1 << 16 else key, kind="stable")
    line, at, point = line[order], along[point][order], point[order]
    starts = np.ones(at.size, dtype=bool)
    starts[1:] = (line[1:] != line[:-1]) | (np.diff(at) > gap)
    first = np.flatnonzero(starts)
    last = np.append(first[1:], at.size) - 1
    chosen = (at[last] - at[first] >= min_span) & (last - first + 1 >= min_points)
    inside = np.zeros(along.size, dtype=bool)
    inside[point[np.repeat(chosen, last - first + 1)]] = True
    return inside


def in_rotated_frame(
    source: npt.NDArray[np.uint8],
    angle: float,
    work: FrameWork,
    *,
    reach_px: int,
    needs: FrameNeeds | None = None,
) -> tuple[npt.NDArray[np.uint8], bool]:
    """``work`` done on ``source`` turned so that ``angle`` lies along the columns (:func:`_rotate`),
    its output back in ``source``'s cells (nearest-neighbour), and whether it was turned.

    A long, thin ``source`` whose turned frame would be too large (``_MAX_FRAME_GROWTH``) is
    turned in pieces along its length, each with ``reach_px`` cells of the source on either side
    (the farthest a rule looks), into the window of the whole frame around it with ``reach_px``
    more on every side (:func:`_piece_frame`), and each piece's own cells kept: what a rule finds
    there is what it finds in the whole, up to OpenCV's fixed-point sampling (``warpAffine``
    rounds a window's cells a little differently from the whole frame's: a few cells in ten
    thousand of a one-cell strip differ, with ``work`` returning its input). With ``needs`` (what
    the work needs to find anything), a piece none of whose cells may take part in it
    (:func:`_cells_that_may_find`) is not turned: its cells stay zeros, as the work would have
    returned them. Its ``edge_px`` must be at most ``reach_px - 3`` (else every piece is turned).
    """
    if _along_an_axis(angle):
        return work(np.ascontiguousarray(source), False), False
    rows, cols = source.shape
    whole = _rotation(rows, cols, angle)
    width, height = whole[1]
    if width * height <= max(_MAX_FRAME_GROWTH * rows * cols, _FRAME_CELLS_WHOLE):
        return _turned_and_back(source, angle, work), True
    # Pieces along the longer axis (as rows: a transposed view for a wide box).
    wide = cols > rows
    along = source.T if wide else source
    length, short = along.shape
    core = _piece_core(short, length, reach_px, angle)
    # A thin strip's spurious directions: most pieces hold nothing the work looks for along them
    # (no run, no two cells on a line), and turning them cost about the reach per cell. The cells
    # that may take part are found on the whole frame once; a piece's window edges lie
    # ``reach_px`` beyond its cells but where they are the whole frame's.
    wanted = None
    if needs is not None and needs.edge_px + 3 <= reach_px:
        wanted = np.sort(_cells_that_may_find(source, whole, needs)[1 if wide else 0])
    out = np.zeros(along.shape, dtype=np.uint8)
    for start in range(0, length, core):
        stop = min(start + core, length)
        low, high = max(start - reach_px, 0), min(stop + reach_px, length)
        if wanted is not None and np.searchsorted(wanted, low) == np.searchsorted(wanted, high):
            continue  # the work would return zeros
        piece = np.ascontiguousarray(along[low:high].T if wide else along[low:high])
        frame = _piece_frame(whole, (low, 0) if wide else (0, low), piece.shape, reach_px)
        back = _turned_and_back(piece, angle, work, frame)
        out[start:stop] = (back.T if wide else back)[start - low : stop - low]
    return (np.ascontiguousarray(out.T) if wide else out), True


#: Lengths of a piece's own cells that :func:`_piece_core` chooses among, in ``reach_px``.
_CORE_REACHES = (2, 3, 4, 6, 8)


def _piece_core(short: int, length: int, reach_px: int, angle: float) -> int:
    """How many cells along its ``length`` each piece of a long, thin source ``short`` cells across
    keeps as its own (:func:`in_rotated_frame`): of ``_CORE_REACHES`` reaches (at least 4 ``short``
    and 64 cells), the one whose turned window (the piece with ``reach_px`` on either side, turned,
    ``reach_px`` more on every side: :func:`_piece_frame`) has the fewest cells per kept cell. Only
    lengths whose window is at most half a frame turned whole (``_FRAME_CELLS_WHOLE``) and that
    are at most an eighth of ``length`` (a source a few pieces long gains little) are chosen
    among; the shortest, two reaches, always is.

    Longer pieces spread the reach turned on both ends over more cells, but their turned box grows
    with the square of their length: pieces of two reaches, as before, turned 20-40 % more cells of
    a thin strip (1 x 100,000 cells, 3 x 33,333) than the best."""
    c, s = abs(math.cos(angle)), abs(math.sin(angle))

    def window_cells(core: int) -> float:
        piece = core + 2 * reach_px
        return (piece * c + short * s + 2 * reach_px) * (piece * s + short * c + 2 * reach_px)

    cores = [max(4 * short, k * reach_px, 64) for k in _CORE_REACHES]
    # (No window larger than half a frame turned whole may be, but for the shortest pieces: the
    # furniture fronts' passes cost more per cell over larger windows, 4 M cells against 2 M.)
    small = [
        core
        for core in cores[1:]
        if 2 * window_cells(core) <= _FRAME_CELLS_WHOLE and 8 * core <= length
    ]
    return min([cores[0], *small], key=lambda core: window_cells(core) / core)


def _turned_and_back(
    source: npt.NDArray[np.uint8], angle: float, work: FrameWork, frame: Frame | None = None
) -> npt.NDArray[np.uint8]:
    """``work`` in ``source``'s frame turned by ``angle`` (into ``frame``, as :func:`_rotate`), its
    output sampled back into ``source``'s cells (nearest-neighbour: values are copied, bits and
    all)."""
    import cv2

    rows, cols = source.shape
    rotated, matrix = _rotate(source, angle, frame)
    done = work(np.ascontiguousarray(rotated), True)
    assert matrix is not None
    back = cv2.warpAffine(
        done, matrix, (cols, rows), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP
    )
    return np.asarray(back, dtype=np.uint8)
