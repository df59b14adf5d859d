"""The session clock of a CARMEN log: its own stamps, or a replacement when they do not resolve the scans.

Most logs stamp every scan (a handful of backward steps are nudged forward by 1 ns, with a warning
that counts them; a stamp far out
of line with the rest, e.g. one wrong by a day, is placed between its neighbours with a warning, so
that it does not drag every later scan along; the scans before a clock restart keep their steps
and end at the log's scan period before it). Some do not: the
CSAIL log writes its stamps with six significant digits, so nearly all scans share one stamp and a
session cut into map periods would be a single snapshot. Such a log gets a replacement clock: every
scan takes the time a robot needs to move to it at :data:`NOMINAL_SPEED_M_S` and turn at
:data:`NOMINAL_TURN_RAD_S`, at least :data:`MIN_SCAN_PERIOD_S` (walking pace, a typical laser rate).
``rose-bag convert`` and the break evaluation's replay use the same clock.
"""

from __future__ import annotations

import bisect
import logging
from typing import Literal, NamedTuple

import numpy as np
import numpy.typing as npt

from rose_logs.carmen.parse import CarmenLog

__all__ = [
    "MIN_SCAN_PERIOD_S",
    "NOMINAL_SPEED_M_S",
    "NOMINAL_TURN_RAD_S",
    "ClockName",
    "ScanClock",
    "scan_clock_ns",
]

_LOG = logging.getLogger(__name__)

OUT_OF_LINE_S = 10.0
"""A stamp off the log's ordered stamps by more than this (seconds) is a wrong stamp, not jitter."""

RESTART_MIN_S = 1.0
"""A step back by more than this (seconds) that the scans on both sides agree with is a clock
restart (:func:`_restarts_joined`); shorter ones are jitter or swapped lines, nudged."""

#: Scans on each side of a step back whose median stamps tell a restart from a wrong stamp.
_RESTART_SIDE = 9

#: Fewest scans on each side of a restart: fewer at a log's end are wrong stamps.
_RESTART_MIN_SIDE = 3

NOMINAL_SPEED_M_S = 0.3
"""Robot speed of the replacement clock, metres per second."""
NOMINAL_TURN_RAD_S = 0.5
"""Turn rate of the replacement clock, radians per second."""
MIN_SCAN_PERIOD_S = 0.25
"""Shortest scan period of the replacement clock, seconds."""

ClockName = Literal["log", "nominal-speed"]


class ScanClock(NamedTuple):
    """Scan times of a log: ``offsets_ns`` since the first scan (strictly increasing), the clock's
    ``name``, and ``start_ns``, the first scan's stamp (where its neighbours put it when it is out
    of line with them; 0 when that is before 0)."""

    offsets_ns: npt.NDArray[np.int64]
    name: ClockName
    start_ns: int


def scan_clock_ns(log: CarmenLog) -> ScanClock:
    """The session clock of ``log`` (see :class:`ScanClock`).

    The log's own stamps (``"log"``) unless fewer than half of the scan-to-scan steps are positive;
    then the replacement clock of the module notes (``"nominal-speed"``).
    """
    stamps = log.stamps_ns.astype(np.int64)
    steps = np.diff(stamps)
    if steps.size == 0 or np.count_nonzero(steps > 0) >= steps.size / 2:
        stamps = _stamps_in_line(_restarts_joined(stamps, log), log)
        out = stamps - stamps[0]
        steps = np.diff(stamps)
        backward = int(np.count_nonzero(steps < 0))  # in the log, not after the nudges below
        moved = 0
        for i in range(1, out.size):  # a handful of backward stamps at most (Intel)
            if out[i] <= out[i - 1]:
                moved += int(out[i] < out[i - 1])  # an equal stamp moved by 1 ns is no news
                out[i] = out[i - 1] + 1
        if backward:
            # Scans keep their file order; a stamp earlier than the scan before it takes that
            # scan's time (+1 ns), and so may the scans after it: two swapped lines put every
            # scan between them on one time.
            _LOG.warning(
                "%s: %d scan stamp(s) earlier than the scan before them in the log (at most "
                "%.3f s back): scans kept in file order, %d stamp(s) moved to just after the scan "
                "before them",
                log.path,
                backward,
                -int(steps.min()) / 1e9,
                moved,
            )
        return ScanClock(out, "log", _start_ns(stamps))
    poses = log.laser_poses
    dist = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    turn = np.abs((np.diff(poses[:, 2]) + np.pi) % (2 * np.pi) - np.pi)
    dt = np.maximum.reduce(
        [dist / NOMINAL_SPEED_M_S, turn / NOMINAL_TURN_RAD_S, np.full(dist.size, MIN_SCAN_PERIOD_S)]
    )
    offsets = np.concatenate([[0], np.cumsum(np.round(dt * 1e9).astype(np.int64))])
    return ScanClock(offsets, "nominal-speed", _start_ns(stamps))


def _start_ns(stamps: npt.NDArray[np.int64]) -> int:
    """The session's first stamp: the first scan's, or 0 when that is before 0 (ROS time starts
    there; the scans before a clock restart are placed before its first stamp, which may be 0)."""
    return max(int(stamps[0]), 0) if stamps.size else 0


def _restarts_joined(stamps: npt.NDArray[np.int64], log: CarmenLog) -> npt.NDArray[np.int64]:
    """``stamps`` with the scans before each clock restart moved, as a block, to end at the log's
    scan period before the first stamp after it (the last part keeps its own stamps).

    A restart is a step back by more than :data:`RESTART_MIN_S` that the scans on both sides (at
    least :data:`_RESTART_MIN_SIDE` of them) agree with: the median of up to :data:`_RESTART_SIDE` stamps before it lies past the middle of the
    jump, and so does that of the stamps after it (one stamp wrong by a day, forward or back, has
    its neighbours against it and is left to :func:`_stamps_in_line`). Each part keeps its own
    steps: found as out of line instead, the scans on one side were spread at the median period
    or, with the restart early in the log, squeezed onto one time (213 of ACES's 440 scans)."""
    steps = np.diff(stamps)
    jumps = np.flatnonzero(steps < -RESTART_MIN_S * 1e9) + 1  # first scan after each
    restarts = []
    for i in jumps.tolist():
        if min(i, stamps.size - i) < _RESTART_MIN_SIDE:
            # A few stamps at an end agree with themselves: wrong stamps there, for
            # _stamps_in_line (the last stamp a day early shifted the whole session a day back).
            continue
        middle = (int(stamps[i - 1]) + int(stamps[i])) / 2
        before = np.median(stamps[max(i - _RESTART_SIDE, 0) : i])
        after = np.median(stamps[i : i + _RESTART_SIDE])
        if before > middle > after:
            restarts.append(i)
    if not restarts:
        return stamps
    forward = steps[steps > 0]
    period = int(np.median(forward)) if forward.size else 0
    out = stamps.copy()
    bounds = [0, *restarts, stamps.size]
    for k in range(len(restarts) - 1, -1, -1):  # from the last restart back: parts already moved
        first, last = bounds[k], bounds[k + 1]
        out[first:last] += out[last] - period - out[last - 1]
    _LOG.warning(
        "%s: the clock restarted %d time(s) (first before scan %d, %.3f s back): the scans before "
        "each restart placed at the log's scan period before the first stamp after it",
        log.path,
        len(restarts),
        restarts[0] + 1,
        -int(steps[restarts[0] - 1]) / 1e9,
    )
    return out


def _stamps_in_line(stamps: npt.NDArray[np.int64], log: CarmenLog) -> npt.NDArray[np.int64]:
    """``stamps`` with those far out of line with the rest placed between their neighbours.

    The stamps in line are the longest non-decreasing run through the log (not necessarily
    consecutive scans). A stamp off that run is wrong when it lies more than :data:`OUT_OF_LINE_S`
    outside the span of its neighbours in line (before the first or after the last of them: of
    where the log's median scan period puts it), or more than :data:`RESTART_MIN_S` ahead of the
    scans in line after it (which it would otherwise squeeze onto one time). A wrong stamp is interpolated (by scan index)
    between its neighbours, or placed on at that period at the ends (possibly before 0). Small
    backward steps, also next to a long pause, stay as they are, for the caller's 1 ns nudge. A
    first stamp that is too early or a last one too late stays in line and cannot be told from a
    real pause.
    """
    kept = _longest_non_decreasing(stamps)
    if kept.size == stamps.size:
        return stamps
    index = np.arange(stamps.size)
    in_line = stamps[kept].astype(np.float64)
    period = float(np.median(np.diff(in_line) / np.diff(kept))) if kept.size > 1 else 0.0
    expected = np.interp(index, kept, in_line)
    expected[: kept[0]] = in_line[0] - (kept[0] - index[: kept[0]]) * period
    expected[kept[-1] + 1 :] = in_line[-1] + (index[kept[-1] + 1 :] - kept[-1]) * period
    # The span of every scan's neighbours in line (its own stamp for a scan in line).
    after = np.searchsorted(kept, index)  # first scan in line at or after each scan
    before = np.searchsorted(kept, index, side="right") - 1  # last at or before
    low = np.where(before >= 0, in_line[np.maximum(before, 0)], expected)
    high = np.where(after < kept.size, in_line[np.minimum(after, kept.size - 1)], expected)
    tolerance = OUT_OF_LINE_S * 1e9
    # A stamp ahead of the scans in line after it is nudged onto by all of them (a stamp 5 s ahead
    # put the next 5 s of scans on one time): placed between its neighbours from a second on.
    ahead = min(tolerance, RESTART_MIN_S * 1e9)
    wrong = (stamps < low - tolerance) | (stamps > high + ahead)
    if not wrong.any():
        return stamps
    first = int(np.flatnonzero(wrong)[0])
    _LOG.warning(
        "%s: %d scan stamp(s) out of line with the rest (by more than %g s, or %g s ahead of "
        "the scans after them; first: scan %d, %.3f s): placed between their neighbours",
        log.path,
        int(np.count_nonzero(wrong)),
        OUT_OF_LINE_S,
        RESTART_MIN_S,
        first + 1,
        stamps[first] / 1e9,
    )
    out = stamps.copy()
    # Not clamped at 0: scans before a clock that restarted near 0 would all share that time (the
    # caller starts the session at 0 instead, every scan keeping its period).
    out[wrong] = np.round(expected[wrong]).astype(np.int64)
    return out


def _longest_non_decreasing(values: npt.NDArray[np.int64]) -> npt.NDArray[np.intp]:
    """Indices of a longest non-decreasing subsequence of ``values`` (patience sorting, n log n)."""
    tails: list[int] = []  # values of the smallest tail of each length
    tail_at: list[int] = []  # their indices
    before = np.full(values.size, -1, dtype=np.intp)
    for i, value in enumerate(values.tolist()):
        length = bisect.bisect_right(tails, value)
        if length == len(tails):
            tails.append(value)
            tail_at.append(i)
        else:
            tails[length] = value
            tail_at[length] = i
        before[i] = tail_at[length - 1] if length > 0 else -1
    chain = []
    i = tail_at[-1] if tail_at else -1
    while i >= 0:
        chain.append(i)
        i = int(before[i])
    return np.array(chain[::-1], dtype=np.intp)
