"""Connection metadata for writing: message definitions and hashes, QoS profiles, latching."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any, Literal

from rosbags.interfaces import Qos
from rosbags.typesys import TypesysError

from rose_logs.errors import LogWriteError
from rose_logs.storage.records import Channel, normalize_msgtype
from rose_logs.storage.typesys import msgdef_for

__all__ = [
    "KnownDefinitions",
    "QosStyle",
    "default_qos",
    "definitions",
    "offered_qos",
    "qos_style",
    "qos_yaml",
    "require_definition",
    "transient_local_qos",
    "warn_no_definition",
]

QosStyle = Literal["v8", "v9"]
"""How QoS policies are spelled in rosbag2 metadata: ``"v8"`` integers (rosbag2 format <= 8, what Humble
and Iron write and the only form Humble reads), ``"v9"`` lower-case names (format 9, Jazzy and later)."""
_POLICIES = ("history", "reliability", "durability", "liveliness")

_LOG = logging.getLogger(__name__)
_SEPARATOR = "=" * 80


def transient_local_qos(depth: int = 1) -> Qos:
    """The QoS a latched ROS 2 map publisher offers (reliable, transient local, keep last ``depth``)."""
    return _reliable_qos(depth, transient_local=True)


def default_qos(depth: int = 10) -> Qos:
    """The QoS of a default ROS 2 publisher (``rmw_qos_profile_default``: reliable, volatile, keep last 10)."""
    return _reliable_qos(depth, transient_local=False)


def _reliable_qos(depth: int, *, transient_local: bool) -> Qos:
    from rosbags.interfaces import QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    zero = QosTime(sec=0, nsec=0)
    return Qos(
        history=QosHistory.KEEP_LAST,
        depth=depth,
        reliability=QosReliability.RELIABLE,
        durability=QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
        deadline=zero,
        lifespan=zero,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=zero,
        avoid_ros_namespace_conventions=False,
    )


# -- message definitions -------------------------------------------------------------------------
def definitions(channel: Channel, ros_version: int) -> tuple[str, str]:
    """``(msgdef, digest)`` for an output connection of ``channel``; computed when the input lacked one.

    A type known neither to the input nor to rosbags (a custom type of a Humble bag, which stores
    no definitions) gets ``("", "")`` (:func:`warn_no_definition` says so): its messages are copied byte for byte, which
    needs no definition, and ROS 2 bags and MCAP files may lack one (as Humble's do). A ROS 1 bag
    cannot: its writer refuses an empty definition (:func:`require_definition`).
    """
    serialization = "ros1" if ros_version == 1 else "cdr"
    wanted = "ros1msg" if ros_version == 1 else "ros2"
    if channel.msgdef and channel.digest and channel.msgdef_encoding.startswith(wanted):
        return channel.msgdef, channel.digest
    if channel.msgdef and channel.msgdef_encoding.startswith(wanted):
        try:
            from rosbags.typesys import Stores, get_types_from_msg, get_typestore

            store = get_typestore(Stores.EMPTY)
            for name, text in _split_msgdef(channel.msgtype, channel.msgdef):
                store.register(get_types_from_msg(text, name))
            if ros_version == 1:  # keep the input's text as is, only its md5sum is computed
                return channel.msgdef, store.generate_msgdef(channel.msgtype)[1]
            return channel.msgdef, store.hash_rihs01(channel.msgtype)
        except Exception:  # fall back to the built-in definitions below
            _LOG.debug("could not hash the definition of %s", channel.msgtype, exc_info=True)
    try:
        return msgdef_for(channel.msgtype, serialization)
    except TypesysError:  # a type rosbags does not know either (a custom type)
        return "", ""


class KnownDefinitions:
    """:func:`definitions` of one writer's channels, each input definition worked out once: a log's
    topics share a few types, and where the input has a definition without its digest (a ROS 2
    MCAP file's schemas) each was parsed into a new typestore and hashed, 0.6 ms a topic."""

    def __init__(self) -> None:
        self._known: dict[tuple[str, str, str, str, int], tuple[str, str]] = {}

    def __call__(self, channel: Channel, ros_version: int) -> tuple[str, str]:
        """``definitions(channel, ros_version)``, from the fields it reads."""
        key = (
            channel.msgtype,
            channel.msgdef,
            channel.msgdef_encoding,
            channel.digest,
            ros_version,
        )
        if key not in self._known:
            self._known[key] = definitions(channel, ros_version)
        return self._known[key]


def warn_no_definition(channel: Channel) -> None:
    """Say that ``channel`` is copied without a message definition (:func:`definitions` had none)."""
    _LOG.warning(
        "%s: no message definition of %s in the input (Humble bags store none): copied without "
        "one; tools that decode it need its package",
        channel.topic,
        channel.msgtype or "its type",
    )


def require_definition(channel: Channel, msgdef: str) -> None:
    """Refuse a channel without a message definition in a ROS 1 bag, whose connections need one.

    Raises
    ------
    LogWriteError
        If ``msgdef`` is empty.
    """
    if not msgdef:
        msg = (
            f"a ROS 1 bag needs the message definition of {channel.msgtype or 'an untyped topic'} "
            f"(topic {channel.topic}), which the input does not have: write MCAP (--format mcap)"
        )
        raise LogWriteError(msg)


def _split_msgdef(msgtype: str, text: str) -> list[tuple[str, str]]:
    parts = [(msgtype, "")]
    for line in text.splitlines():
        if line.strip() == _SEPARATOR:
            parts.append(("", ""))
        elif line.startswith("MSG: ") and not parts[-1][0]:
            parts[-1] = (normalize_msgtype(line[5:].strip()), "")
        else:
            name, body = parts[-1]
            parts[-1] = (name, body + line + "\n")
    return [(n, b) for n, b in parts if n]


def qos_yaml(profiles: Sequence[Qos], *, style: QosStyle = "v9") -> str:
    """``offered_qos_profiles`` text of rosbag2 / MCAP channel metadata: a YAML list, one dict per profile.

    ``style`` picks the spelling of the policies (see :data:`QosStyle`); ``""`` for no profiles.
    """
    import yaml
    from rosbags.rosbag2.metadata import dump_qos_v9

    if not profiles:
        return ""
    dicts: list[Any] = list(dump_qos_v9(list(profiles)))
    if style == "v8":
        for dct, profile in zip(dicts, profiles, strict=True):
            for policy in _POLICIES:
                dct[policy] = int(getattr(profile, policy).value)
    return str(yaml.safe_dump(dicts, default_flow_style=False)).strip()


def qos_style(text: str | Sequence[Any]) -> QosStyle | None:
    """Spelling of the QoS policies in ``offered_qos_profiles`` (YAML text or parsed list); None if unknown."""
    import yaml

    items: Any = text
    if isinstance(text, str):
        try:
            items = yaml.safe_load(text)
        except yaml.YAMLError:
            return None
    if not isinstance(items, list):
        return None
    for item in items:
        if not isinstance(item, dict):
            continue
        for policy in _POLICIES:
            value = item.get(policy)
            if isinstance(value, bool):
                continue
            if isinstance(value, int):
                return "v8"
            if isinstance(value, str):
                return "v9"
    return None


def offered_qos(channel: Channel) -> list[Qos]:
    """ROS 2 QoS profiles of ``channel``, from a ROS 2 bag or parsed from MCAP channel metadata."""
    if channel.offered_qos_profiles:
        return list(channel.offered_qos_profiles)
    text = channel.metadata.get("offered_qos_profiles", "")
    if text:
        from rosbags.rosbag2.metadata import parse_qos

        try:
            return parse_qos(text)
        except Exception:  # QoS is metadata; a bad string must not stop the copy
            _LOG.warning("%s: unreadable offered_qos_profiles, not copied", channel.topic)
    return []
