"""The messages rose-bag adds to a log, for ROS 1 and ROS 2 (see :func:`derived_topics`).

- ``<map>/rose/cleaned``: ``nav_msgs/msg/OccupancyGrid``, the header and info of the snapshot and the
  cleaned grid;
- ``<map>/rose/structure_score``: ``std_msgs/msg/Float32``, the score W;
- ``<map>/rose/walls``: ``visualization_msgs/msg/MarkerArray``, one ``LINE_LIST`` marker with a line through
  the map centre along each dominant direction (in the map's frame, so RViz and Foxglove draw it over the
  map), a ``TEXT_VIEW_FACING`` marker showing W and, with ``--walls``, a second ``LINE_LIST`` of the
  wall segments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from rose.result import RoseResult
from rose.walls.segments import WallSet
from rose_logs.snapshots import MapSnapshot
from rose_logs.storage.typesys import (
    FLOAT32_TYPE,
    MAP_TYPE,
    MARKER_ARRAY_TYPE,
    typestore_for,
)

_NS_PER_S = 1_000_000_000

__all__ = [
    "DerivedTopics",
    "derived_topics",
    "encode_cleaned",
    "encode_score",
    "encode_walls",
    "grid_centre_m",
    "wall_line_endpoints",
]


@dataclass(frozen=True)
class DerivedTopics:
    """Names of the topics added next to one map topic."""

    cleaned: str
    structure_score: str
    walls: str

    @property
    def names(self) -> tuple[str, str, str]:
        """All three, in the order they are added to an output log."""
        return self.cleaned, self.structure_score, self.walls


def derived_topics(map_topic: str) -> DerivedTopics:
    """Output topics of ``map_topic``: ``<map>/rose/cleaned``, ``.../structure_score``, ``.../walls``."""
    base = map_topic.rstrip("/") + "/rose"
    return DerivedTopics(f"{base}/cleaned", f"{base}/structure_score", f"{base}/walls")


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


def _height_m(snapshot: MapSnapshot, above_m: float) -> float:
    """z in the map frame, metres, ``above_m`` over the grid: RViz draws a map at its origin's z
    (a floor of a multi-storey map), and markers at z near 0 were drawn floors below it."""
    return snapshot.origin_position_m[2] + above_m


def _line_list_marker(
    types: Any,
    serialization: str,
    snapshot: MapSnapshot,
    *,
    marker_id: int,
    points_xy_m: npt.NDArray[np.float64],
    color: Any,
) -> Any:
    """A ``LINE_LIST`` marker through ``points_xy_m`` (shape (2N, 2), metres, map frame), 0.05 m
    above the grid (its origin's z).

    The line width is three cells, at least 0.05 m.
    """
    point = types["geometry_msgs/msg/Point"]
    z = _height_m(snapshot, 0.05)
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
        points=[point(x=float(x), y=float(y), z=z) for x, y in points_xy_m],
    )


def encode_walls(
    snapshot: MapSnapshot,
    result: RoseResult,
    walls: WallSet | None = None,
    *,
    serialization: str,
) -> bytes:
    """Serialise the dominant directions (and wall segments) as a ``visualization_msgs/MarkerArray``.

    All markers are in the map's frame, above the grid (its origin's z). Marker 0 (``LINE_LIST``):
    a line through the grid centre along each dominant direction (none when the map has no
    structure). Marker 1 (``TEXT_VIEW_FACING``): ``"W = 0.123"`` 1 m above the grid centre.
    Marker 2 (``LINE_LIST``, only when ``walls`` is given): the wall segments,
    ``walls.line_list_m``.
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
        pose=_pose(types, (cx, cy, _height_m(snapshot, 1.0)), (0.0, 0.0, 0.0, 1.0)),
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
