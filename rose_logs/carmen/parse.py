"""CARMEN laser logs: ``FLASER`` lines to laser scans with poses and timestamps.

The old CARMEN ``FLASER`` line is::

    FLASER n r_1 ... r_n x y theta odom_x odom_y odom_theta timestamp hostname logger_timestamp

with ranges in metres, poses in metres and radians in the log's world frame (``x y theta`` is the laser
pose, ``odom_*`` the odometry pose) and timestamps in seconds. The beams cover a 180 degree field of
view centred on the laser's +x axis, counter-clockwise from -pi/2: with an odd ``n`` (181, 361) the
first and the last beam sit at -pi/2 and +pi/2, with an even ``n`` (180, 360) the increment is pi / n.

Ranges of ``inf`` or ``nan`` (and beyond float32) are readings without a return, as in ROS. The
hostname and logger timestamp may be missing; any other field count is a malformed line.

Every other line type (``ODOM``, ``PARAM``, ``NEFF``, ``SYNC``, comments...) is ignored and counted;
``FLASER`` lines that cannot be parsed are skipped and counted, so a damaged log still yields the scans
it holds. ``.gz`` files are read transparently.
"""

from __future__ import annotations

import gzip
import logging
import math
import zlib
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import numpy as np
import numpy.typing as npt

from rose.limits import regular_file_problem, short, visible
from rose_logs.errors import LogReadError

__all__ = [
    "CarmenFormatError",
    "CarmenLog",
    "FlaserScan",
    "beam_angles",
    "check_carmen_file",
    "parse_flaser_line",
    "read_carmen_log",
]

_LOG = logging.getLogger(__name__)
_GZIP_MAGIC = b"\x1f\x8b"
#: Latest timestamp a ROS time can hold in both ROS 1 (uint32 s) and ROS 2 (int32 s), seconds.
MAX_STAMP_S = 2**31

#: Values after the ranges: six pose values, timestamp, hostname, logger timestamp.
_TRAILER_FIELDS = 9

#: Most beams a FLASER line may announce (laser scanners give up to a few thousand): a line of
#: millions of ranges, a few kB gzipped, held gigabytes.
MAX_BEAMS = 100_000

#: Line kinds (first words) counted one by one; lines of further kinds are counted together.
_MAX_KINDS = 100


class CarmenFormatError(LogReadError, ValueError):
    """A CARMEN log or one of its lines cannot be read; the message names the file or the problem."""


@dataclass(frozen=True, eq=False)
class FlaserScan:
    """One front-laser scan of a CARMEN log.

    Attributes
    ----------
    stamp_ns : int
        Timestamp of the scan (the line's ``timestamp`` field), in nanoseconds.
    ranges_m : ndarray of float32, shape (n,)
        Measured ranges in metres, beam ``i`` at ``angle_min_rad + i * angle_increment_rad``.
    angle_min_rad, angle_increment_rad : float
        First beam angle and beam spacing in radians, counter-clockwise in the laser frame.
    laser_pose : tuple of float
        ``(x_m, y_m, theta_rad)`` of the laser in the log's world frame.
    odom_pose : tuple of float
        ``(x_m, y_m, theta_rad)`` odometry pose of the robot, world frame of the odometry.
    line_number : int
        1-based line of the log the scan came from.
    """

    stamp_ns: int
    ranges_m: npt.NDArray[np.float32] = field(repr=False)
    angle_min_rad: float
    angle_increment_rad: float
    laser_pose: tuple[float, float, float]
    odom_pose: tuple[float, float, float]
    line_number: int = 0

    @property
    def angles_rad(self) -> npt.NDArray[np.float64]:
        """Beam angles in the laser frame, radians, shape (n,)."""
        return beam_angles(self.ranges_m.size)


@dataclass(frozen=True, eq=False)
class CarmenLog:
    """The scans of a CARMEN log and an account of what was not used.

    Attributes
    ----------
    path : Path
        The file read.
    scans : tuple of FlaserScan
        Every well-formed ``FLASER`` scan, in file order.
    ignored : dict of str to int
        Lines of other types that were skipped, per first token (``"#"`` for comments, ``""`` for
        blank lines).
    malformed : int
        ``FLASER`` lines that could not be parsed and were skipped.
    first_errors : tuple of str
        Up to five messages describing the first malformed lines (with line numbers).
    """

    path: Path
    scans: tuple[FlaserScan, ...]
    ignored: dict[str, int]
    malformed: int
    first_errors: tuple[str, ...] = ()

    @property
    def stamps_ns(self) -> npt.NDArray[np.int64]:
        """Scan timestamps in nanoseconds, shape (N,)."""
        return np.array([s.stamp_ns for s in self.scans], dtype=np.int64)

    @property
    def laser_poses(self) -> npt.NDArray[np.float64]:
        """Laser poses ``(x_m, y_m, theta_rad)``, shape (N, 3), world frame."""
        return np.array([s.laser_pose for s in self.scans], dtype=np.float64).reshape(-1, 3)

    @property
    def odom_poses(self) -> npt.NDArray[np.float64]:
        """Odometry poses ``(x_m, y_m, theta_rad)``, shape (N, 3)."""
        return np.array([s.odom_pose for s in self.scans], dtype=np.float64).reshape(-1, 3)

    @property
    def duration_s(self) -> float:
        """Time from the first to the last scan, in seconds (0 for fewer than two scans)."""
        if len(self.scans) < 2:
            return 0.0
        return (self.scans[-1].stamp_ns - self.scans[0].stamp_ns) / 1e9


def beam_angles(n: int) -> npt.NDArray[np.float64]:
    """Beam angles of an ``n``-beam CARMEN front laser, radians, shape (n,), laser frame.

    A 180 degree field of view from -pi/2: odd ``n`` includes both ends (increment pi / (n - 1)),
    even ``n`` has increment pi / n.
    """
    if n < 1:
        msg = f"the number of beams `n` must be >= 1, got {n}"
        raise CarmenFormatError(msg)
    increment = math.pi / (n - 1) if n % 2 == 1 and n > 1 else math.pi / n
    return -math.pi / 2 + increment * np.arange(n, dtype=np.float64)


def parse_flaser_line(line: str, *, line_number: int = 0) -> FlaserScan:
    """Parse one ``FLASER`` line.

    Parameters
    ----------
    line : str
        The line, with or without its newline.
    line_number : int
        Recorded in the scan and in error messages.

    Returns
    -------
    FlaserScan

    Raises
    ------
    CarmenFormatError
        When the line is not a complete, numeric ``FLASER`` record.
    """
    where = f"line {line_number}"
    head = line.split(maxsplit=2)  # the beam count first: a huge one is refused before the rest
    if not head or head[0] != "FLASER":
        msg = f"{where}: not a FLASER line"
        raise CarmenFormatError(msg)
    try:
        n = int(head[1])
    except (IndexError, ValueError) as err:
        msg = f"{where}: bad beam count {head[1:2]}"
        raise CarmenFormatError(msg) from err
    if not 1 <= n <= MAX_BEAMS:
        msg = f"{where}: beam count {n} outside 1..{MAX_BEAMS}"
        raise CarmenFormatError(msg)
    tokens = line.split()
    trailer = len(tokens) - 2 - n
    # x y theta odom_x odom_y odom_theta timestamp, then hostname and logger timestamp (optional):
    # a count that does not match the ranges would read ranges as the pose and the time.
    if not _TRAILER_FIELDS - 2 <= trailer <= _TRAILER_FIELDS:
        msg = (
            f"{where}: {n} beams announced, but {len(tokens) - 2} fields follow "
            f"(expected {n} ranges and {_TRAILER_FIELDS - 2}..{_TRAILER_FIELDS} more)"
        )
        raise CarmenFormatError(msg)
    try:
        with np.errstate(over="ignore"):  # a range beyond float32 becomes inf: no return
            ranges = np.array(tokens[2 : 2 + n], dtype=np.float32)
        values = [float(v) for v in tokens[2 + n : 2 + n + 7]]
    except ValueError as err:
        msg = f"{where}: non-numeric value ({err})"
        raise CarmenFormatError(msg) from err
    if not all(math.isfinite(v) for v in values):
        msg = f"{where}: non-finite pose or timestamp"
        raise CarmenFormatError(msg)
    if np.any(ranges < 0):
        msg = f"{where}: negative range"
        raise CarmenFormatError(msg)
    # inf (and a range beyond float32) is no return, as in ROS; so is nan, a reading without one.
    ranges[np.isnan(ranges)] = np.inf
    if not 0 <= values[6] < MAX_STAMP_S:
        msg = f"{where}: timestamp {values[6]:g} s is outside 0 .. 2**31 s (ROS time)"
        raise CarmenFormatError(msg)
    angles = beam_angles(n)
    return FlaserScan(
        stamp_ns=round(values[6] * 1e9),
        ranges_m=ranges,
        angle_min_rad=float(angles[0]),
        angle_increment_rad=float(angles[1] - angles[0]) if n > 1 else math.pi,
        laser_pose=(values[0], values[1], values[2]),
        odom_pose=(values[3], values[4], values[5]),
        line_number=line_number,
    )


#: Longest line read whole, characters: a FLASER line of MAX_BEAMS ranges written with 17 digits
#: each is under 2 MiB. The rest of a longer line is skipped (a line of 1 GB of junk, a few MB
#: gzipped, held 1.8 GB while it was read).
MAX_LINE_CHARS = 8 * 1024 * 1024


def _bounded_lines(fh: IO[str]) -> Iterator[str]:
    """The lines of a text file, each cut after :data:`MAX_LINE_CHARS` (its rest skipped)."""
    readline = fh.readline
    while True:
        line = readline(MAX_LINE_CHARS)
        if not line:
            return
        if len(line) >= MAX_LINE_CHARS and not line.endswith("\n"):
            while True:  # skip to the end of the line, a bounded piece at a time
                rest = readline(MAX_LINE_CHARS)
                if not rest or rest.endswith("\n"):
                    break
        yield line


def _open_lines(path: Path) -> Iterator[str]:
    with path.open("rb") as probe:
        magic = probe.read(2)
    if magic == _GZIP_MAGIC:
        with gzip.open(path, "rt", encoding="utf-8-sig", errors="replace") as fh:
            try:
                yield from _bounded_lines(fh)
            except EOFError:  # cut short (a download, a copy): read as a cut plain log is
                _LOG.warning(
                    "%s: the compressed log ends before its end marker (a copy cut short?): "
                    "the scans before the cut are read",
                    path,
                )
    else:  # utf-8-sig: a byte-order mark before the first line is no part of it
        with path.open("rt", encoding="utf-8-sig", errors="replace") as fh:
            yield from _bounded_lines(fh)


def parse_carmen_lines(
    lines: Iterable[str], *, path: Path | None = None, max_scans: int | None = None
) -> CarmenLog:
    """Parse CARMEN log lines (see :func:`read_carmen_log`)."""
    scans: list[FlaserScan] = []
    ignored: Counter[str] = Counter()
    errors: list[str] = []
    malformed = 0
    for number, line in enumerate(lines, start=1):
        head = line.split(maxsplit=1)
        kind = head[0] if head else ""
        if kind != "FLASER":
            kind = "#" if kind.startswith("#") else kind
            if kind not in ignored and len(ignored) >= _MAX_KINDS:
                # one count for the rest: a kind per line of junk held GBs
                kind = "(other kinds)"
            ignored[kind] += 1
            continue
        try:
            scans.append(parse_flaser_line(line, line_number=number))
        except CarmenFormatError as err:
            malformed += 1
            if len(errors) < 5:
                errors.append(str(err))
            continue
        if max_scans is not None and len(scans) >= max_scans:
            break
    return CarmenLog(
        path=path if path is not None else Path("<lines>"),
        scans=tuple(scans),
        ignored=dict(ignored),
        malformed=malformed,
        first_errors=tuple(errors),
    )


def _why_no_scans(path: Path, log: CarmenLog) -> str:
    """Why a file gave no scan: not what its name says, not text, or no good FLASER line."""
    try:
        with path.open("rb") as probe:
            head = probe.read(4096)
    except OSError:
        head = b""
    if path.suffix == ".gz" and head[:2] != _GZIP_MAGIC:
        return "not gzip-compressed (its name ends in .gz) and no FLASER scan in it as text"
    if head[:2] == _GZIP_MAGIC:
        try:
            with gzip.open(path, "rb") as unpacked:
                head = unpacked.read(4096)
        except (OSError, EOFError, zlib.error):
            head = b""
    if b"\0" in head:  # text logs hold no NUL byte
        return "not a CARMEN log (binary data, no FLASER scan)"
    first = f"; first: {log.first_errors[0]}" if log.first_errors else ""
    held = sorted(
        ((count, kind) for kind, count in log.ignored.items() if kind not in ("", "#")),
        key=lambda item: (-item[0], item[1]),
    )
    if log.malformed:
        return f"no FLASER scan found ({log.malformed} malformed FLASER lines{first})"
    if not held:
        return "no FLASER scan found: the log is empty, or holds only comments and blank lines"
    # An ODOM-only or ROBOTLASER1 log: say what it holds, and that only FLASER lines are read.
    kinds = ", ".join(f"{visible(short(kind, 20))} ({count})" for count, kind in held[:3])
    more = ", ..." if len(held) > 3 else ""
    return f"no FLASER scan found: only FLASER lines are read; its lines start {kinds}{more}"


def check_carmen_file(path: str | Path) -> None:
    """Raise :class:`CarmenFormatError` unless ``path`` is an existing regular file (a folder, FIFO
    or device is no log): cheap, so a command says it before judging its outputs (``convert .
    out.mcap`` said the output was "inside the input .")."""
    problem = regular_file_problem(path, missing="no such file")
    if problem is not None:
        msg = f"{path}: {problem}"
        raise CarmenFormatError(msg)


def read_carmen_log(path: str | Path, *, max_scans: int | None = None) -> CarmenLog:
    """Read the ``FLASER`` scans of a CARMEN log (plain text or gzip).

    Parameters
    ----------
    path : str or Path
        The log file; gzip is detected from the file's magic bytes.
    max_scans : int, optional
        Stop after this many scans.

    Returns
    -------
    CarmenLog
        Scans in file order plus counts of ignored and malformed lines.

    Raises
    ------
    CarmenFormatError
        When the file cannot be opened or decompressed, or holds no ``FLASER`` scan at all.
    """
    path = Path(path)
    check_carmen_file(path)
    try:
        log = parse_carmen_lines(_open_lines(path), path=path, max_scans=max_scans)
    # BadGzipFile: an OSError whose words ("Not a gzipped file") mislead; zlib.error: damaged
    # compressed data ("invalid distance too far back"), which is no OSError at all.
    except (gzip.BadGzipFile, zlib.error) as err:
        msg = (
            f"{path}: corrupt gzip data ({err}): bytes that are no gzip member follow or "
            "interrupt the compressed log (zcat may read the part before them)"
        )
        raise CarmenFormatError(msg) from err
    except (OSError, EOFError) as err:
        msg = f"{path}: cannot read CARMEN log ({getattr(err, 'strerror', None) or err})"
        raise CarmenFormatError(msg) from err
    if not log.scans:
        raise CarmenFormatError(f"{path}: {_why_no_scans(path, log)}")
    if log.malformed:
        _LOG.warning(
            "%s: skipped %d malformed FLASER lines, first: %s",
            path,
            log.malformed,
            log.first_errors[0],
        )
    _LOG.info("%s: %d scans over %.1f s", path, len(log.scans), log.duration_s)
    return log
