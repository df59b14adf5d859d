"""Map snapshots: one decoded occupancy grid at one point of a log, and decoding map messages into them.

The ``int8[] data`` of a grid is decoded by rosbags straight into a numpy array (no Python lists);
``map_msgs/OccupancyGridUpdate`` patches are applied to the last full map of their topic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from rose.grid import OCCUPIED, UNKNOWN
from rose.limits import finite_number
from rose.mapfile import MAX_ORIGIN_M, MAX_RESOLUTION_M
from rose_logs.errors import EmptyMapError, MapMessageError
from rose_logs.frames import quaternion_to_yaw
from rose_logs.storage.typesys import MAP_TYPE, UPDATE_TYPE, typestore_for

__all__ = [
    "MAX_RESOLUTION_M",
    "GridUpdate",
    "MapSnapshot",
    "apply_update",
    "check_log_time",
    "decode_map",
    "decode_update",
    "float32_decimal",
]

_NS_PER_S = 1_000_000_000
_MAX_TIME_NS = 2**63 - 1


@dataclass(frozen=True, eq=False)
class MapSnapshot:
    """One full occupancy grid as it stood at ``log_time_ns`` on ``topic``.

    Attributes
    ----------
    topic : str
        Map topic the grid came from (for an update patch: the map topic it was applied to).
    log_time_ns : int
        Log (receive) time of the message that produced this snapshot, in nanoseconds.
    stamp_ns : int
        ``header.stamp`` of the map, in nanoseconds.
    frame_id : str
        ``header.frame_id`` of the map.
    grid : ndarray of int8, shape (height, width)
        ROS convention: row 0 at the origin, -1 unknown, 0..100. Read-only, the snapshot's own (a
        writable array given is copied: reusing that buffer for the next map changes no snapshot).
    resolution_m : float
        Cell size in metres.
    origin_position_m : tuple of float
        ``info.origin.position`` (x, y, z) in metres, map frame.
    origin_orientation_xyzw : tuple of float
        ``info.origin.orientation`` quaternion.
    map_load_time_ns : int
        ``info.map_load_time`` in nanoseconds.
    header_seq : int
        ROS 1 ``header.seq`` (0 for ROS 2), kept so derived messages repeat it.
    out_of_range_cells : int
        Cells of the message outside -1..100, read as occupied (100) in ``grid``.
    """

    topic: str
    log_time_ns: int
    stamp_ns: int
    frame_id: str
    grid: npt.NDArray[np.int8]
    resolution_m: float
    origin_position_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    origin_orientation_xyzw: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    map_load_time_ns: int = 0
    header_seq: int = 0
    out_of_range_cells: int = 0

    def __post_init__(self) -> None:
        grid = np.asarray(self.grid)
        # By kind: numpy counts timedelta64 among its integers.
        if grid.ndim != 2 or grid.dtype.kind not in "iu":
            msg = (
                f"{self.topic}: a MapSnapshot's grid must be a 2-D int8 array (ROS occupancy), "
                f"got {grid.ndim}-D {grid.dtype}"
            )
            raise ValueError(msg)
        if grid.dtype != np.int8 and grid.size and (grid.min() < -128 or grid.max() > 127):
            msg = f"{self.topic}: a MapSnapshot's grid holds values beyond int8"
            raise ValueError(msg)
        if not finite_number(self.resolution_m) or not self.resolution_m > 0:
            msg = f"{self.topic}: resolution_m must be a positive number, got {self.resolution_m!r}"
            raise ValueError(msg)
        # Tuples of Python floats of its own, as the fields say: a list given was held as it
        # was, and changing it afterwards moved the snapshot (and the walls drawn over it).
        for name, size in (("origin_position_m", 3), ("origin_orientation_xyzw", 4)):
            value = getattr(self, name)
            try:
                numbers = tuple(float(v) for v in value)
            except (TypeError, ValueError):
                numbers = ()
            if len(numbers) != size:
                msg = f"{self.topic}: {name} must be {size} numbers, got {value!r}"
                raise ValueError(msg)
            object.__setattr__(self, name, numbers)
        object.__setattr__(self, "resolution_m", float(self.resolution_m))
        # The snapshot owns its cells: a caller that reuses one buffer for each new map must not
        # change the break detector's trusted snapshot (decoded grids are read-only and owned
        # already: no copy).
        if grid.dtype != np.int8 or grid.flags.writeable or not grid.flags.owndata:
            grid = grid.astype(np.int8)
            grid.flags.writeable = False
        object.__setattr__(self, "grid", grid)

    @property
    def origin_yaw_rad(self) -> float:
        """Yaw of the grid in the map frame, in radians (from the origin quaternion)."""
        return quaternion_to_yaw(self.origin_orientation_xyzw)

    @property
    def resolution_decimal_m(self) -> float:
        """The message's float32 resolution as its shortest decimal (0.05, not 0.0500000007), for
        what users read: metres in reports would otherwise carry float noise (9.100001 m)."""
        return float32_decimal(self.resolution_m)

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)`` in cells."""
        return self.grid.shape[0], self.grid.shape[1]


@dataclass(frozen=True, eq=False)
class GridUpdate:
    """One ``map_msgs/OccupancyGridUpdate``: a rectangular patch of a full map.

    Attributes
    ----------
    topic : str
        Topic of the update message (usually ``<map>_updates``).
    log_time_ns, stamp_ns : int
        Log time and ``header.stamp`` of the update, nanoseconds.
    frame_id : str
        ``header.frame_id``.
    x_px, y_px : int
        Column and row of the patch's first cell in the full grid.
    patch : ndarray of int8, shape (height, width)
        New cell values, ROS convention (row 0 towards the origin). Read-only.
    out_of_range_cells : int
        Cells of the message outside -1..100, read as occupied (100) in ``patch``.
    """

    topic: str
    log_time_ns: int
    stamp_ns: int
    frame_id: str
    x_px: int
    y_px: int
    patch: npt.NDArray[np.int8]
    out_of_range_cells: int = 0


def float32_decimal(value: float) -> float:
    """A float32 message field as its shortest decimal (0.05, not 0.05000000074505806)."""
    return float(str(np.float32(value)))


def apply_update(snapshot: MapSnapshot, update: GridUpdate) -> MapSnapshot:
    """The snapshot that results from writing ``update.patch`` into ``snapshot.grid``.

    The result keeps the topic and map metadata (resolution, origin, load time, frame) of ``snapshot``
    and takes the log time and stamp of the update. Neither input is modified.

    Raises
    ------
    ValueError
        If the patch does not lie inside the grid, or the update names another frame than the
        map (cells of another map's grid; an empty frame is taken as the map's).
    """
    # A leading slash names the same frame (tf's old spelling "/map"; tf2 drops it).
    frames = (update.frame_id.lstrip("/"), snapshot.frame_id.lstrip("/"))
    if all(frames) and frames[0] != frames[1]:
        msg = (
            f"{update.topic}: update in frame {update.frame_id!r}, the map of {snapshot.topic} "
            f"in {snapshot.frame_id!r}"
        )
        raise ValueError(msg)
    rows, cols = snapshot.shape
    h, w = update.patch.shape
    x, y = update.x_px, update.y_px
    if x < 0 or y < 0 or x + w > cols or y + h > rows:
        msg = (
            f"{update.topic}: update patch {w} x {h} at ({x}, {y}) does not fit the "
            f"{cols} x {rows} map of {snapshot.topic}"
        )
        raise ValueError(msg)
    grid = snapshot.grid.copy()
    grid[y : y + h, x : x + w] = update.patch
    grid.setflags(write=False)
    return MapSnapshot(
        topic=snapshot.topic,
        log_time_ns=update.log_time_ns,
        stamp_ns=update.stamp_ns,
        frame_id=snapshot.frame_id,
        grid=grid,
        resolution_m=snapshot.resolution_m,
        origin_position_m=snapshot.origin_position_m,
        origin_orientation_xyzw=snapshot.origin_orientation_xyzw,
        map_load_time_ns=snapshot.map_load_time_ns,
        header_seq=snapshot.header_seq,
        out_of_range_cells=update.out_of_range_cells,
    )


# -- decoding map messages ------------------------------------------------------------------------------------
def check_log_time(topic: str, log_time_ns: int) -> None:
    """Raise MapMessageError unless ``0 <= log_time_ns < 2**63`` (what Rerun and ROS time can hold)."""
    if not 0 <= log_time_ns <= _MAX_TIME_NS:
        msg = f"{topic}: log time {log_time_ns} ns is outside 0 .. 2**63 - 1"
        raise MapMessageError(msg)


def _time_ns(stamp: Any, topic: str, what: str) -> int:
    sec, nanosec = int(stamp.sec), int(stamp.nanosec)
    if not 0 <= nanosec < _NS_PER_S:
        msg = f"{topic}: {what} has nanosec = {nanosec}, not in 0 .. 999999999"
        raise MapMessageError(msg)
    if sec < 0:
        msg = f"{topic}: {what} is negative ({sec} s)"
        raise MapMessageError(msg)
    return sec * _NS_PER_S + nanosec


def _check_placement(
    topic: str, resolution: float, position: tuple[float, ...], quaternion: tuple[float, ...]
) -> None:
    """Raise MapMessageError for a resolution, origin or orientation no real map has."""
    if not math.isfinite(resolution) or not 0 < resolution <= MAX_RESOLUTION_M:
        # As the message stores it (float32): -0.05, not -0.05000000074505806.
        shown = float32_decimal(resolution) if abs(resolution) < 3.4e38 else resolution
        msg = f"{topic}: resolution {shown} m is not in (0, {MAX_RESOLUTION_M:g}]"
        raise MapMessageError(msg)
    if not all(math.isfinite(v) for v in position):
        msg = f"{topic}: origin position {position} is not finite"
        raise MapMessageError(msg)
    if max(abs(v) for v in position) > MAX_ORIGIN_M:
        msg = f"{topic}: origin position {position} is beyond +-{MAX_ORIGIN_M:g} m"
        raise MapMessageError(msg)
    norm = math.sqrt(sum(v * v for v in quaternion)) if all(map(math.isfinite, quaternion)) else 0.0
    if not norm > 1e-6:
        msg = f"{topic}: origin orientation {quaternion} is not a rotation (zero or not finite)"
        raise MapMessageError(msg)


def _deserialize(data: bytes | memoryview, msgtype: str, serialization: str, topic: str) -> Any:
    store = typestore_for(serialization)
    try:
        if serialization == "ros1":
            return store.deserialize_ros1(data, msgtype)
        return store.deserialize_cdr(data, msgtype)
    except Exception as err:  # rosbags raises struct/index/value errors on short or garbled data
        msg = f"{topic}: cannot decode {msgtype} message ({type(err).__name__}: {err})"
        raise MapMessageError(msg) from err


def _grid_from(
    data: Any, width: int, height: int, topic: str, what: str
) -> tuple[npt.NDArray[np.int8], int]:
    """The cells as a read-only ``(height, width)`` grid, and how many were outside -1..100.

    Those are read as occupied, as Nav2's static layer reads them (as unsigned bytes, every value
    but -1 = 255 from 100 up is lethal): one stray value must not cost the whole map.
    """
    flat = np.asarray(data)
    if flat.dtype != np.int8:
        flat = flat.astype(np.int8)
    if width * height == 0:
        msg = f"{topic}: zero-area {what} ({width} x {height} cells)"
        raise MapMessageError(msg)
    if flat.size != width * height:
        msg = f"{topic}: {what} data has {flat.size} cells, width x height is {width} x {height} = {width * height}"
        raise MapMessageError(msg)
    grid = flat.reshape(height, width).copy()
    odd_count = 0
    if grid.min() < UNKNOWN or grid.max() > OCCUPIED:  # rare: no mask on every map's hot path
        odd = (grid < UNKNOWN) | (grid > OCCUPIED)
        odd_count = int(np.count_nonzero(odd))
        grid[odd] = OCCUPIED
    grid.setflags(write=False)
    return grid, odd_count


def decode_map(
    data: bytes | memoryview, *, serialization: str, topic: str, log_time_ns: int
) -> MapSnapshot:
    """Decode one serialised ``nav_msgs/OccupancyGrid`` into a :class:`MapSnapshot`.

    Parameters
    ----------
    data : bytes or memoryview
        Serialised message (ROS 1 or CDR).
    serialization : {"ros1", "cdr"}
        Its serialisation.
    topic : str
        Topic, for the snapshot and error messages.
    log_time_ns : int
        Log time of the message, ns.

    Raises
    ------
    EmptyMapError
        If the map has no cells (and no data).
    MapMessageError
        If the bytes do not decode, the map has zero area but data or ``len(data) != width * height``, the
        resolution is not in ``(0, MAX_RESOLUTION_M]``, the origin is not finite, the orientation is a
        zero or non-finite quaternion, or a time has ``nanosec >= 1e9`` or a negative ``sec``.
    """
    msg = _deserialize(data, MAP_TYPE, serialization, topic)
    info = msg.info
    if int(info.width) * int(info.height) == 0 and len(msg.data) == 0:
        # Before any placement check: a default-constructed message (resolution 0) is empty too.
        empty = f"{topic}: empty map ({int(info.width)} x {int(info.height)} cells)"
        raise EmptyMapError(empty)
    pos, ori = info.origin.position, info.origin.orientation
    position = (float(pos.x), float(pos.y), float(pos.z))
    quaternion = (float(ori.x), float(ori.y), float(ori.z), float(ori.w))
    _check_placement(topic, float(info.resolution), position, quaternion)
    stamp_ns = _time_ns(msg.header.stamp, topic, "header.stamp")
    load_ns = _time_ns(info.map_load_time, topic, "info.map_load_time")
    grid, odd = _grid_from(msg.data, int(info.width), int(info.height), topic, "map")
    return MapSnapshot(
        topic=topic,
        log_time_ns=int(log_time_ns),
        stamp_ns=stamp_ns,
        frame_id=str(msg.header.frame_id),
        grid=grid,
        resolution_m=float(info.resolution),
        origin_position_m=position,
        origin_orientation_xyzw=quaternion,
        map_load_time_ns=load_ns,
        header_seq=int(getattr(msg.header, "seq", 0)),
        out_of_range_cells=odd,
    )


def decode_update(
    data: bytes | memoryview, *, serialization: str, topic: str, log_time_ns: int
) -> GridUpdate:
    """Decode one serialised ``map_msgs/OccupancyGridUpdate`` into a :class:`GridUpdate`.

    Raises
    ------
    MapMessageError
        If the bytes do not decode or ``len(data) != width * height``.
    """
    msg = _deserialize(data, UPDATE_TYPE, serialization, topic)
    patch, odd = _grid_from(msg.data, int(msg.width), int(msg.height), topic, "update")
    return GridUpdate(
        topic=topic,
        log_time_ns=int(log_time_ns),
        stamp_ns=_time_ns(msg.header.stamp, topic, "header.stamp"),
        frame_id=str(msg.header.frame_id),
        x_px=int(msg.x),
        y_px=int(msg.y),
        patch=patch,
        out_of_range_cells=odd,
    )
