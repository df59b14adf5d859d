"""ROS message types: rosbags typestores per serialisation, type names and full definitions.

Serialisation goes through rosbags typestores (``ROS1_NOETIC`` for ``"ros1"``, ``ROS2_HUMBLE`` for
``"cdr"``), extended with ``map_msgs/msg/OccupancyGridUpdate`` and ``tf2_msgs/msg/TFMessage``.
"""

from __future__ import annotations

import functools
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

__all__ = [
    "FLOAT32_TYPE",
    "MAP_TYPE",
    "MARKER_ARRAY_TYPE",
    "UPDATE_TYPE",
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

    The digest is the md5sum for ``"ros1"`` and the RIHS01 hash for ``"cdr"``. ROS 1 definitions are
    the canonical full texts of :mod:`rose_logs.storage.ros1_definitions` for the types rose-bag adds
    (what ``rosbag record`` stores; rosbags would drop the comments), else rosbags' generated text.
    """
    store = typestore_for(serialization)
    if serialization == "ros1":
        from rose_logs.storage.ros1_definitions import ROS1_FULL_TEXT

        msgdef, md5 = store.generate_msgdef(msgtype)
        # ROS's own full text (comments and all) where we have it, as a bag recorded by ROS stores it.
        return ROS1_FULL_TEXT.get(msgtype, msgdef), md5
    msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
    return msgdef, store.hash_rihs01(msgtype)
