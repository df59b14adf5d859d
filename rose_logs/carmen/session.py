"""A CARMEN log as a ROS mapping session: ``/scan``, the pose, ``/map`` snapshots.

Messages, all stamped with the scan time (log time = header stamp, nanoseconds):

- ``/scan``: ``sensor_msgs/LaserScan`` in ``base_frame`` (the laser is the robot's reference point);
- ``/tf`` (``tf2_msgs/TFMessage``, ``world_frame -> base_frame``) and/or ``/odom``
  (``nav_msgs/Odometry``), from the log's poses, optionally drifted (:mod:`rose_logs.carmen.drift`);
- ``/map``: ``nav_msgs/OccupancyGrid`` in ``world_frame`` built incrementally from the scans so far
  (:mod:`rose_logs.carmen.raycast`), every ``map_period_s`` seconds of log time and after the last scan.

Timestamps that go backwards in the log (a few in the Intel log) are moved 1 ns after their
predecessor so every output topic is time-ordered. Writing goes through the project's writer
(:func:`rose_logs.writer.open_output`): written to a temporary path and renamed at the end; ``.mcap``
is a bare MCAP file, as ``rose-bag process`` writes it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from rose.outputs import OutputSet
from rose_logs.carmen.clock import ClockName, scan_clock_ns
from rose_logs.carmen.drift import apply_drift
from rose_logs.carmen.parse import MAX_STAMP_S, CarmenFormatError, CarmenLog, beam_angles
from rose_logs.carmen.raycast import BuilderParams, OccupancyGridBuilder
from rose_logs.errors import LogWriteError
from rose_logs.formats import format_from_path
from rose_logs.frames import yaw_to_quaternion
from rose_logs.writer import open_output

__all__ = [
    "SessionFormat",
    "SessionOptions",
    "SessionSummary",
    "write_carmen_session",
]

_LOG = logging.getLogger(__name__)

SessionFormat = Literal["ros1", "db3", "mcap", "mcap-dir"]
PoseOutput = Literal["tf", "odom", "both"]


@dataclass(frozen=True)
class SessionSummary:
    """What :func:`write_carmen_session` wrote.

    Attributes
    ----------
    path : Path
        Output bag (file for ROS 1, folder for ROS 2).
    format : str
        ``"ros1"``, ``"db3"`` or ``"mcap"``.
    scans : int
        ``/scan`` messages.
    maps : int
        ``/map`` messages.
    start_ns, end_ns : int
        First and last message time, nanoseconds.
    final_grid : ndarray of int8, shape (rows, cols)
        The last ``/map`` grid (ROS convention).
    final_origin_xy_m : tuple of float
        Its origin in ``world_frame``, metres.
    resolution_m : float
        Its cell size, metres.
    skipped_lines : int
        Malformed ``FLASER`` lines the parser skipped.
    clock : {"log", "nominal-speed"}
        The session's clock (:mod:`rose_logs.carmen.clock`): the log's stamps, or a replacement
        when they do not resolve the scans.
    """

    path: Path
    format: str
    scans: int
    maps: int
    start_ns: int
    end_ns: int
    final_grid: npt.NDArray[np.int8]
    final_origin_xy_m: tuple[float, float]
    resolution_m: float
    skipped_lines: int
    clock: ClockName = "log"


def _session_format(path: Path) -> SessionFormat:
    fmt = format_from_path(path) or "db3"
    if fmt not in ("ros1", "db3", "mcap"):
        msg = f"{path}: a session cannot be written as {fmt}"
        raise LogWriteError(msg)
    return fmt


# -- the writer adapter ---------------------------------------------------------------------
class _Sink:
    """Output session through :func:`rose_logs.writer.open_output` (atomic; any of our formats),
    plus the headers the converter needs (ROS 1 headers carry a sequence number)."""

    def __init__(
        self, path: Path, fmt: SessionFormat, *, force: bool, outputs: OutputSet | None = None
    ) -> None:
        self.ros1 = fmt == "ros1"
        self.writer = open_output(path, fmt, force=force, outputs=outputs)
        self.typestore = self.writer.typestore
        self.seq = 0

    def __enter__(self) -> _Sink:
        self.writer.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.writer.__exit__(*exc)

    def add(self, topic: str, msgtype: str) -> None:
        # Maps are latched, as map_server and SLAM nodes publish them.
        self.writer.add_topic(topic, msgtype, latching=msgtype.endswith("OccupancyGrid"))

    def write(self, topic: str, time_ns: int, msg: Any) -> None:
        self.writer.write(topic, time_ns, msg)

    def header(self, time_ns: int, frame_id: str) -> Any:
        types = self.typestore.types
        stamp = types["builtin_interfaces/msg/Time"](
            sec=time_ns // 1_000_000_000, nanosec=time_ns % 1_000_000_000
        )
        if self.ros1:
            self.seq += 1
            return types["std_msgs/msg/Header"](seq=self.seq, stamp=stamp, frame_id=frame_id)
        return types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)


def _open_sink(
    path: Path, fmt: SessionFormat, *, force: bool, outputs: OutputSet | None = None
) -> _Sink:
    return _Sink(path, fmt, force=force, outputs=outputs)


# -- messages -----------------------------------------------------------------------------------
def _quaternion(types: dict[str, Any], yaw: float) -> Any:
    x, y, z, w = yaw_to_quaternion(yaw)
    return types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)


def _scan_msg(
    sink: _Sink, t_ns: int, frame: str, ranges: npt.NDArray[np.float32], max_m: float
) -> Any:
    angles = beam_angles(ranges.size)
    return sink.typestore.types["sensor_msgs/msg/LaserScan"](
        header=sink.header(t_ns, frame),
        angle_min=float(angles[0]),
        angle_max=float(angles[-1]),
        angle_increment=float(angles[1] - angles[0]) if ranges.size > 1 else 0.0,
        time_increment=0.0,
        scan_time=0.0,
        range_min=0.0,
        range_max=float(max_m),
        ranges=np.asarray(ranges, dtype=np.float32),
        intensities=np.zeros(0, dtype=np.float32),
    )


def _pose_msgs(
    sink: _Sink, t_ns: int, pose: npt.NDArray[np.float64], world: str, base: str
) -> tuple[Any, Any]:
    types = sink.typestore.types
    x, y, yaw = (float(v) for v in pose)
    q = _quaternion(types, yaw)
    transform = types["geometry_msgs/msg/TransformStamped"](
        header=sink.header(t_ns, world),
        child_frame_id=base,
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0), rotation=q
        ),
    )
    tf = types["tf2_msgs/msg/TFMessage"](transforms=[transform])
    point = types["geometry_msgs/msg/Point"](x=x, y=y, z=0.0)
    zeros36 = np.zeros(36, dtype=np.float64)
    odom = types["nav_msgs/msg/Odometry"](
        header=sink.header(t_ns, world),
        child_frame_id=base,
        pose=types["geometry_msgs/msg/PoseWithCovariance"](
            pose=types["geometry_msgs/msg/Pose"](position=point, orientation=q), covariance=zeros36
        ),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](
            twist=types["geometry_msgs/msg/Twist"](
                linear=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
            ),
            covariance=zeros36,
        ),
    )
    return tf, odom


def _map_msg(sink: _Sink, t_ns: int, world: str, builder: OccupancyGridBuilder) -> Any:
    types = sink.typestore.types
    grid = builder.grid()
    ox, oy = builder.origin_xy_m
    rows, cols = grid.shape
    time_type = types["builtin_interfaces/msg/Time"]
    info = types["nav_msgs/msg/MapMetaData"](
        map_load_time=time_type(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000),
        resolution=float(builder.params.resolution_m),
        width=cols,
        height=rows,
        origin=types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=ox, y=oy, z=0.0),
            orientation=_quaternion(types, 0.0),
        ),
    )
    return types["nav_msgs/msg/OccupancyGrid"](
        header=sink.header(t_ns, world), info=info, data=grid.reshape(-1).astype(np.int8)
    )


@dataclass(frozen=True)
class SessionOptions:
    """How :func:`write_carmen_session` turns a CARMEN log into a ROS session.

    Attributes
    ----------
    builder_params : BuilderParams
        Grid resolution, ranges and log-odds of the ``/map`` snapshots.
    map_period_s : float, default 10.0
        Log time between ``/map`` snapshots, seconds (> 0).
    pose_output : {"tf", "odom", "both"}, default "tf"
        Pose topic(s).
    world_frame, base_frame : str, default "map", "base_link"
        Frame ids of the map/pose parent and of the robot (laser).
    drift_level : float, default 0.0
        Odometry drift applied to the poses (0: the log's corrected poses; see
        :mod:`rose_logs.carmen.drift`).
    drift_seed : int, default 0
        Seed of the drift.
    drift_start_s : float, default 0.0
        Drift starts this many seconds after the first scan.

    Raises
    ------
    ValueError
        On a period that is not > 0 or an unknown pose output.
    """

    builder_params: BuilderParams = field(default_factory=BuilderParams)
    map_period_s: float = 10.0
    pose_output: PoseOutput = "tf"
    world_frame: str = "map"
    base_frame: str = "base_link"
    drift_level: float = 0.0
    drift_seed: int = 0
    drift_start_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.map_period_s > 0:
            msg = f"map_period_s must be > 0, got {self.map_period_s}"
            raise ValueError(msg)
        if self.pose_output not in ("tf", "odom", "both"):
            msg = f"pose_output must be 'tf', 'odom' or 'both', got {self.pose_output!r}"
            raise ValueError(msg)

    @property
    def topics(self) -> tuple[tuple[str, str], ...]:
        """``(topic, message type)`` of the session, in the order they are added."""
        poses = []
        if self.pose_output in ("tf", "both"):
            poses.append(("/tf", "tf2_msgs/msg/TFMessage"))
        if self.pose_output in ("odom", "both"):
            poses.append(("/odom", "nav_msgs/msg/Odometry"))
        return (
            ("/scan", "sensor_msgs/msg/LaserScan"),
            *poses,
            ("/map", "nav_msgs/msg/OccupancyGrid"),
        )


def write_carmen_session(
    log: CarmenLog,
    path: str | Path,
    *,
    fmt: SessionFormat | None = None,
    options: SessionOptions | None = None,
    progress: Callable[[int, int], None] | None = None,
    force: bool = False,
    outputs: OutputSet | None = None,
) -> SessionSummary:
    """Write a CARMEN log as a ROS session (see module notes for topics and frames).

    Parameters
    ----------
    log : CarmenLog
        Parsed log (:func:`rose_logs.carmen.parse.read_carmen_log`).
    path : str or Path
        Output: ``*.bag`` file (ROS 1), ``*.mcap`` file, or ROS 2 bag folder; must not exist.
    fmt : {"ros1", "db3", "mcap", "mcap-dir"}, optional
        Output format; from the path when omitted (:func:`rose_logs.formats.format_from_path`;
        a name without a known suffix is a ROS 2 db3 bag folder; ``"mcap-dir"``, a ROS 2 bag folder
        with MCAP storage, is never implied).
    options : SessionOptions, optional
        Grid, map period, pose topics, frames and drift; defaults of :class:`SessionOptions`.
    progress : callable, optional
        Called with ``(scans_done, scans_total)``.
    outputs : rose.outputs.OutputSet, optional
        Stage the session there (the caller commits it with its other outputs, and protects inputs).
    force : bool, default False
        Replace an existing output (once the new one is complete).

    Returns
    -------
    SessionSummary

    Raises
    ------
    LogWriteError
        When ``path`` exists (and ``force`` is False) or cannot be written; nothing is left behind.
    """
    out = Path(path)
    options = options if options is not None else SessionOptions()
    fmt = fmt if fmt is not None else _session_format(out)
    offsets, clock, start_ns = scan_clock_ns(log)
    stamps = start_ns + offsets
    # The last map comes 1 ns after the last scan.
    end_s = (int(stamps[-1]) + 1) / 1e9 if stamps.size else 0.0
    if end_s >= MAX_STAMP_S:
        # The nominal-speed clock runs on from the first stamp: near 2**31 s it runs past it.
        msg = f"{log.path}: the session would end at {end_s:.0f} s, past 2**31 s (ROS time)"
        raise CarmenFormatError(msg)
    if clock != "log":
        _LOG.warning(
            "%s: the log's timestamps do not resolve its scans; using a nominal-speed clock "
            "(see rose_logs.carmen.clock)",
            log.path,
        )
    poses = apply_drift(
        log.laser_poses,
        stamps_ns=stamps,
        start_ns=int(stamps[0] + options.drift_start_s * 1e9),
        level=options.drift_level,
        seed=options.drift_seed,
    )
    builder = OccupancyGridBuilder(options.builder_params)
    with _open_sink(out, fmt, force=force, outputs=outputs) as sink:
        for topic, msgtype in options.topics:
            sink.add(topic, msgtype)
        maps, end_ns = _write_messages(sink, log, stamps, poses, builder, options, progress)
    _LOG.info("%s: %d scans, %d maps", out, len(log.scans), maps)
    return SessionSummary(
        path=out,
        format=fmt,
        scans=len(log.scans),
        maps=maps,
        start_ns=int(stamps[0]),
        end_ns=end_ns,
        final_grid=builder.grid(),
        final_origin_xy_m=builder.origin_xy_m,
        resolution_m=options.builder_params.resolution_m,
        skipped_lines=log.malformed,
        clock=clock,
    )


def _write_messages(
    sink: _Sink,
    log: CarmenLog,
    stamps: npt.NDArray[np.int64],
    poses: npt.NDArray[np.float64],
    builder: OccupancyGridBuilder,
    options: SessionOptions,
    progress: Callable[[int, int], None] | None,
) -> tuple[int, int]:
    """Scans and poses in log order, a ``/map`` every ``map_period_s`` and one after the last scan.

    Scans go into the grid in batches, just before each map. Returns ``(maps written, last time ns)``.
    """
    world, base = options.world_frame, options.base_frame
    period_ns = round(options.map_period_s * 1e9)
    next_map_ns = int(stamps[0]) + period_ns
    maps = 0
    total = len(log.scans)
    pending = 0  # scans written but not yet in the grid
    for i, scan in enumerate(log.scans):
        t_ns = int(stamps[i])
        if t_ns >= next_map_ns and i > 0:
            builder.integrate_scans(log.scans[i - pending : i], poses[i - pending : i])
            pending = 0
            sink.write("/map", t_ns, _map_msg(sink, t_ns, world, builder))
            maps += 1
            next_map_ns = t_ns + period_ns
        tf, odom = _pose_msgs(sink, t_ns, poses[i], world, base)
        if options.pose_output in ("tf", "both"):
            sink.write("/tf", t_ns, tf)
        if options.pose_output in ("odom", "both"):
            sink.write("/odom", t_ns, odom)
        max_m = options.builder_params.max_range_m
        sink.write("/scan", t_ns, _scan_msg(sink, t_ns, base, scan.ranges_m, max_m))
        pending += 1
        if progress is not None:
            progress(i + 1, total)
    builder.integrate_scans(log.scans[total - pending :], poses[total - pending :])
    end_ns = int(stamps[-1]) + 1
    sink.write("/map", end_ns, _map_msg(sink, end_ns, world, builder))
    return maps + 1, end_ns
