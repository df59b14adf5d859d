"""Decode map messages into snapshots and build the derived output messages, for ROS 1 and ROS 2.

Serialisation goes through rosbags typestores (``ROS1_NOETIC`` for ``"ros1"``, ``ROS2_HUMBLE`` for
``"cdr"``), extended with ``map_msgs/msg/OccupancyGridUpdate`` and ``tf2_msgs/msg/TFMessage``. The
``int8[] data`` of a grid is decoded by rosbags straight into a numpy array (no Python lists).

Derived messages per map topic (see :func:`derived_topics`):

- ``<map>/rose/cleaned``: ``nav_msgs/msg/OccupancyGrid``, the header and info of the snapshot and the
  cleaned grid;
- ``<map>/rose/structure_score``: ``std_msgs/msg/Float32``, the score W;
- ``<map>/rose/walls``: ``visualization_msgs/msg/MarkerArray``, one ``LINE_LIST`` marker with a line through
  the map centre along each dominant direction (in the map's frame, so RViz and Foxglove draw it over the
  map) and a ``TEXT_VIEW_FACING`` marker showing W.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from rose.result import RoseResult
from rose.walls import WallSet
from rose_logs.errors import MapMessageError
from rose_logs.snapshots import GridUpdate, MapSnapshot

__all__ = [
    "FLOAT32_TYPE",
    "MAP_TYPE",
    "MARKER_ARRAY_TYPE",
    "UPDATE_TYPE",
    "DerivedTopics",
    "decode_map",
    "decode_update",
    "derived_topics",
    "encode_cleaned",
    "encode_score",
    "encode_walls",
    "msgdef_for",
    "typestore_for",
]

MAP_TYPE = "nav_msgs/msg/OccupancyGrid"
UPDATE_TYPE = "map_msgs/msg/OccupancyGridUpdate"
FLOAT32_TYPE = "std_msgs/msg/Float32"
MARKER_ARRAY_TYPE = "visualization_msgs/msg/MarkerArray"

_UPDATE_MSGDEF = """std_msgs/Header header
int32 x
int32 y
uint32 width
uint32 height
int8[] data
"""
_TF_MSGDEF = "geometry_msgs/TransformStamped[] transforms\n"
_NS_PER_S = 1_000_000_000


@functools.cache
def typestore_for(serialization: str) -> Any:
    """rosbags typestore for ``"ros1"`` (Noetic) or ``"cdr"`` (Humble), with ``map_msgs`` and ``tf2_msgs``.

    Cached: one typestore per serialisation and process.
    """
    if serialization not in {"ros1", "cdr"}:
        msg = f"serialization must be 'ros1' or 'cdr', got {serialization!r}"
        raise ValueError(msg)
    store = get_typestore(Stores.ROS1_NOETIC if serialization == "ros1" else Stores.ROS2_HUMBLE)
    extra: dict[str, Any] = {}
    if UPDATE_TYPE not in store.types:
        extra.update(get_types_from_msg(_UPDATE_MSGDEF, UPDATE_TYPE))
    if "tf2_msgs/msg/TFMessage" not in store.types:
        extra.update(get_types_from_msg(_TF_MSGDEF, "tf2_msgs/msg/TFMessage"))
    if extra:
        store.register(extra)
    return store


@functools.cache
def msgdef_for(msgtype: str, serialization: str) -> tuple[str, str]:
    """``(message definition, digest)`` of ``msgtype`` for a new output connection.

    The digest is the md5sum for ``"ros1"`` and the RIHS01 hash for ``"cdr"``.
    """
    store = typestore_for(serialization)
    if serialization == "ros1":
        return store.generate_msgdef(msgtype)
    msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
    return msgdef, store.hash_rihs01(msgtype)


@dataclass(frozen=True)
class DerivedTopics:
    """Names of the topics added next to one map topic."""

    cleaned: str
    structure_score: str
    walls: str


def derived_topics(map_topic: str) -> DerivedTopics:
    """Output topics of ``map_topic``: ``<map>/rose/cleaned``, ``.../structure_score``, ``.../walls``."""
    base = map_topic.rstrip("/") + "/rose"
    return DerivedTopics(f"{base}/cleaned", f"{base}/structure_score", f"{base}/walls")


# -- decoding ------------------------------------------------------------------------------------
def _time_ns(stamp: Any) -> int:
    return int(stamp.sec) * _NS_PER_S + int(stamp.nanosec)


def _deserialize(data: bytes | memoryview, msgtype: str, serialization: str, topic: str) -> Any:
    store = typestore_for(serialization)
    try:
        if serialization == "ros1":
            return store.deserialize_ros1(data, msgtype)
        return store.deserialize_cdr(data, msgtype)
    except Exception as err:  # rosbags raises struct/index/value errors on short or garbled data
        msg = f"{topic}: cannot decode {msgtype} message ({type(err).__name__}: {err})"
        raise MapMessageError(msg) from err


def _grid_from(data: Any, width: int, height: int, topic: str, what: str) -> npt.NDArray[np.int8]:
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
    grid.setflags(write=False)
    return grid


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
    MapMessageError
        If the bytes do not decode, the map has zero area or ``len(data) != width * height``.
    """
    msg = _deserialize(data, MAP_TYPE, serialization, topic)
    info = msg.info
    grid = _grid_from(msg.data, int(info.width), int(info.height), topic, "map")
    pos, ori = info.origin.position, info.origin.orientation
    return MapSnapshot(
        topic=topic,
        log_time_ns=int(log_time_ns),
        stamp_ns=_time_ns(msg.header.stamp),
        frame_id=str(msg.header.frame_id),
        grid=grid,
        resolution_m=float(info.resolution),
        origin_position_m=(float(pos.x), float(pos.y), float(pos.z)),
        origin_orientation_xyzw=(float(ori.x), float(ori.y), float(ori.z), float(ori.w)),
        map_load_time_ns=_time_ns(info.map_load_time),
        header_seq=int(getattr(msg.header, "seq", 0)),
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
    patch = _grid_from(msg.data, int(msg.width), int(msg.height), topic, "update")
    return GridUpdate(
        topic=topic,
        log_time_ns=int(log_time_ns),
        stamp_ns=_time_ns(msg.header.stamp),
        frame_id=str(msg.header.frame_id),
        x_px=int(msg.x),
        y_px=int(msg.y),
        patch=patch,
    )


# -- encoding ------------------------------------------------------------------------------------
def _serialize(message: Any, msgtype: str, serialization: str) -> bytes:
    store = typestore_for(serialization)
    if serialization == "ros1":
        return bytes(store.serialize_ros1(message, msgtype))
    return bytes(store.serialize_cdr(message, msgtype))


def _stamp(types: Any, time_ns: int) -> Any:
    return types["builtin_interfaces/msg/Time"](
        sec=time_ns // _NS_PER_S, nanosec=time_ns % _NS_PER_S
    )


def _header(types: Any, serialization: str, snapshot: MapSnapshot) -> Any:
    stamp = _stamp(types, snapshot.stamp_ns)
    if serialization == "ros1":
        return types["std_msgs/msg/Header"](
            seq=snapshot.header_seq, stamp=stamp, frame_id=snapshot.frame_id
        )
    return types["std_msgs/msg/Header"](stamp=stamp, frame_id=snapshot.frame_id)


def _pose(types: Any, xyz: tuple[float, float, float], xyzw: tuple[float, ...]) -> Any:
    return types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=xyz[0], y=xyz[1], z=xyz[2]),
        orientation=types["geometry_msgs/msg/Quaternion"](
            x=xyzw[0], y=xyzw[1], z=xyzw[2], w=xyzw[3]
        ),
    )


def encode_cleaned(
    snapshot: MapSnapshot, cleaned: npt.NDArray[np.int8], *, serialization: str
) -> bytes:
    """Serialise ``cleaned`` as a ``nav_msgs/OccupancyGrid`` with the header and info of ``snapshot``.

    Parameters
    ----------
    snapshot : MapSnapshot
        Source of header (stamp, frame, ROS 1 seq) and info (resolution, origin, load time).
    cleaned : ndarray of int8, shape (height, width)
        Grid in ROS convention, same shape as ``snapshot.grid``.
    serialization : {"ros1", "cdr"}
    """
    if cleaned.shape != snapshot.grid.shape:
        msg = (
            f"cleaned grid shape {cleaned.shape} differs from the snapshot's {snapshot.grid.shape}"
        )
        raise ValueError(msg)
    types = typestore_for(serialization).types
    height, width = snapshot.shape
    info = types["nav_msgs/msg/MapMetaData"](
        map_load_time=_stamp(types, snapshot.map_load_time_ns),
        resolution=snapshot.resolution_m,
        width=width,
        height=height,
        origin=_pose(types, snapshot.origin_position_m, snapshot.origin_orientation_xyzw),
    )
    grid = types[MAP_TYPE](
        header=_header(types, serialization, snapshot),
        info=info,
        data=np.ascontiguousarray(cleaned, dtype=np.int8).reshape(-1),
    )
    return _serialize(grid, MAP_TYPE, serialization)


def encode_score(score: float, *, serialization: str) -> bytes:
    """Serialise W as a ``std_msgs/Float32``."""
    types = typestore_for(serialization).types
    return _serialize(types[FLOAT32_TYPE](data=float(score)), FLOAT32_TYPE, serialization)


def grid_centre_m(snapshot: MapSnapshot) -> tuple[float, float]:
    """Centre of the grid in the map frame, metres: the grid's half extent turned by the origin yaw."""
    height, width = snapshot.shape
    res = snapshot.resolution_m
    yaw = snapshot.origin_yaw_rad
    c, s = math.cos(yaw), math.sin(yaw)
    cx_g, cy_g = 0.5 * width * res, 0.5 * height * res
    ox, oy = snapshot.origin_position_m[0], snapshot.origin_position_m[1]
    return ox + c * cx_g - s * cy_g, oy + s * cx_g + c * cy_g


def wall_line_endpoints(snapshot: MapSnapshot, result: RoseResult) -> npt.NDArray[np.float64]:
    """End points of one line per dominant direction through the grid centre, in the map frame.

    Returns
    -------
    ndarray of float64, shape (K, 2, 2)
        ``[k, end, (x, y)]`` in metres in ``snapshot.frame_id``; each line spans the grid's diagonal.
        Grid angles (counter-clockwise from the grid's +x, the column axis) are turned by the origin yaw.
    """
    height, width = snapshot.shape
    centre = np.array(grid_centre_m(snapshot))
    half = 0.5 * math.hypot(width, height) * snapshot.resolution_m
    angles = np.asarray(result.dominant_directions, dtype=np.float64) + snapshot.origin_yaw_rad
    unit = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    return np.stack([centre - half * unit, centre + half * unit], axis=1)


def _marker(types: Any, serialization: str, snapshot: MapSnapshot, **fields: Any) -> Any:
    common: dict[str, Any] = {
        "header": _header(types, serialization, snapshot),
        "ns": "rose",
        "action": 0,
        "pose": _pose(types, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)),
        "lifetime": types["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
        "frame_locked": False,
        "colors": [],
        "text": "",
        "mesh_resource": "",
        "mesh_use_embedded_materials": False,
    }
    if serialization == "cdr":
        common.update(
            texture_resource="",
            texture=types["sensor_msgs/msg/CompressedImage"](
                header=_header(types, serialization, snapshot),
                format="",
                data=np.zeros(0, dtype=np.uint8),
            ),
            uv_coordinates=[],
            mesh_file=types["visualization_msgs/msg/MeshFile"](
                filename="", data=np.zeros(0, dtype=np.uint8)
            ),
        )
    common.update(fields)
    return types["visualization_msgs/msg/Marker"](**common)


def _line_list_marker(
    types: Any,
    serialization: str,
    snapshot: MapSnapshot,
    *,
    marker_id: int,
    points_xy_m: npt.NDArray[np.float64],
    color: Any,
) -> Any:
    """A ``LINE_LIST`` marker through ``points_xy_m`` (shape (2N, 2), metres, map frame), at z 0.05 m.

    The line width is three cells, at least 0.05 m.
    """
    point = types["geometry_msgs/msg/Point"]
    return _marker(
        types,
        serialization,
        snapshot,
        id=marker_id,
        type=5,  # LINE_LIST
        scale=types["geometry_msgs/msg/Vector3"](
            x=max(3.0 * snapshot.resolution_m, 0.05), y=0.0, z=0.0
        ),
        color=color,
        points=[point(x=float(x), y=float(y), z=0.05) for x, y in points_xy_m],
    )


def encode_walls(
    snapshot: MapSnapshot,
    result: RoseResult,
    walls: WallSet | None = None,
    *,
    serialization: str,
) -> bytes:
    """Serialise the dominant directions (and wall segments) as a ``visualization_msgs/MarkerArray``.

    All markers are in the map's frame. Marker 0 (``LINE_LIST``): a line through the grid centre
    along each dominant direction (none when the map has no structure). Marker 1
    (``TEXT_VIEW_FACING``): ``"W = 0.123"`` at the grid centre. Marker 2 (``LINE_LIST``, only when
    ``walls`` is given): the wall segments, ``walls.line_list_m``.
    """
    types = typestore_for(serialization).types
    lines = wall_line_endpoints(snapshot, result)
    res = snapshot.resolution_m
    cx, cy = grid_centre_m(snapshot)
    rgba = types["std_msgs/msg/ColorRGBA"]
    vec = types["geometry_msgs/msg/Vector3"]
    lines_marker = _line_list_marker(
        types,
        serialization,
        snapshot,
        marker_id=0,
        points_xy_m=lines.reshape(-1, 2),
        color=rgba(r=1.0, g=0.55, b=0.0, a=0.9),
    )
    text_marker = _marker(
        types,
        serialization,
        snapshot,
        id=1,
        type=9,  # TEXT_VIEW_FACING
        pose=_pose(types, (cx, cy, 1.0), (0.0, 0.0, 0.0, 1.0)),
        scale=vec(x=0.0, y=0.0, z=max(20.0 * res, 0.5)),
        color=rgba(r=1.0, g=1.0, b=1.0, a=0.9),
        points=[],
        text=f"W = {result.structure_score:.3f}",
    )
    markers = [lines_marker, text_marker]
    if walls is not None:
        markers.append(
            _line_list_marker(
                types,
                serialization,
                snapshot,
                marker_id=2,
                points_xy_m=walls.line_list_m,
                color=rgba(r=0.0, g=0.8, b=1.0, a=0.9),
            )
        )
    array = types[MARKER_ARRAY_TYPE](markers=markers)
    return _serialize(array, MARKER_ARRAY_TYPE, serialization)
