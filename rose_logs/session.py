"""The processing loop: log -> snapshots -> ROSE -> sinks (output log, Rerun, report).

One pass over the input in log-time order. Every message is copied byte for byte to the output log;
map messages (``nav_msgs/OccupancyGrid``) and grid updates (``map_msgs/OccupancyGridUpdate``, applied to
the last full map of their topic) become :class:`~rose_logs.snapshots.MapSnapshot` s, each analysed with
:func:`rose.analyze` on its own grid (a grid equal to the previous one of its topic reuses that result),
and the results go to the output log (derived topics, :mod:`rose_logs.messages`), to Rerun
(:mod:`rose_logs.rerun`) and to the :class:`SessionReport`.

A *break* is a snapshot where W rises above ``failure_level`` (the paper's 0.4) after being at or below
it (or on the first snapshot of a topic); each one is a :class:`BreakEvent`.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

import rose
from rose.directions import FAILURE_LEVEL, TRUST_LEVEL
from rose.params import RoseParams
from rose.result import RoseResult
from rose.walls import WallSet
from rose_logs.errors import LogReadError, LogWriteError, MapMessageError
from rose_logs.messages import (
    FLOAT32_TYPE,
    MAP_TYPE,
    MARKER_ARRAY_TYPE,
    UPDATE_TYPE,
    decode_map,
    decode_update,
    derived_topics,
    encode_cleaned,
    encode_score,
    encode_walls,
)
from rose_logs.reader import Channel, LogFormat, LogReader
from rose_logs.snapshots import MapSnapshot, apply_update
from rose_logs.writer import LogWriter, format_from_path, offered_qos

__all__ = [
    "FAILURE_LEVEL",
    "TRUST_LEVEL",
    "BreakEvent",
    "SessionReport",
    "SnapshotRecord",
    "default_output_path",
    "find_map_topics",
    "process_log",
]

if TYPE_CHECKING:
    from rose_logs.rerun.sink import RerunSink

_LOG = logging.getLogger(__name__)


_DECODABLE = {"ros1", "cdr"}


@dataclass(frozen=True)
class SnapshotRecord:
    """What one snapshot was and what ROSE found (one line of the JSON report).

    Attributes
    ----------
    topic : str
        Map topic.
    index : int
        Position of the snapshot on its topic, from 0.
    log_time_ns, stamp_ns : int
        Log time of the message and ``header.stamp``, ns.
    width, height : int
        Grid size in cells.
    resolution_m : float
        Cell size, metres.
    structure_score : float
        W.
    directions_deg : tuple of float
        Dominant wall orientations in degrees in ``[0, 180)``, grid frame (CCW from the column axis).
    threshold : float
        Cell-score threshold (NaN when nothing was classified).
    occupied_count, clutter_count : int
        Occupied cells and those labelled clutter.
    seconds : float
        Wall time spent on this snapshot (analysis and every sink), seconds.
    reused : bool
        True when the grid equalled the previous one and its result was reused.
    from_update : bool
        True when the snapshot came from an ``OccupancyGridUpdate``.
    """

    topic: str
    index: int
    log_time_ns: int
    stamp_ns: int
    width: int
    height: int
    resolution_m: float
    structure_score: float
    directions_deg: tuple[float, ...]
    threshold: float
    occupied_count: int
    clutter_count: int
    seconds: float
    reused: bool
    from_update: bool

    def to_json(self, *, start_ns: int) -> dict[str, Any]:
        """JSON-ready dict; ``time_s`` is seconds since ``start_ns``; NaN becomes null."""
        return {
            "topic": self.topic,
            "index": self.index,
            "log_time_ns": self.log_time_ns,
            "stamp_ns": self.stamp_ns,
            "time_s": round((self.log_time_ns - start_ns) / 1e9, 9),
            "width": self.width,
            "height": self.height,
            "resolution_m": self.resolution_m,
            "structure_score": self.structure_score,
            "directions_deg": list(self.directions_deg),
            "threshold": None if math.isnan(self.threshold) else self.threshold,
            "occupied": self.occupied_count,
            "clutter": self.clutter_count,
            "seconds": round(self.seconds, 6),
            "reused": self.reused,
            "from_update": self.from_update,
        }


@dataclass(frozen=True)
class BreakEvent:
    """A snapshot where W rose above the failure level."""

    topic: str
    index: int
    log_time_ns: int
    structure_score: float
    text: str


@dataclass(frozen=True)
class SessionReport:
    """Everything a session produced except the output files.

    Attributes
    ----------
    input_path : Path
        The log read.
    input_format : str
        Its format (see :data:`rose_logs.reader.LogFormat`).
    output_path : Path or None
        The log written, if any.
    rrd_path : Path or None
        The Rerun recording saved, if any.
    map_topics : tuple of str
        Map topics analysed.
    records : tuple of SnapshotRecord
        One per snapshot, in log-time order.
    breaks : tuple of BreakEvent
        Every rise of W above ``failure_level``.
    failure_level : float
        The level used.
    message_count : int
        Messages in the input.
    start_ns, end_ns : int
        Log time of the first and last input message, ns.
    skipped_messages : int
        Map or update messages that could not be analysed (copied through unprocessed).
    elapsed_s : float
        Wall time of the whole session, seconds.
    """

    input_path: Path
    input_format: str
    output_path: Path | None
    rrd_path: Path | None
    map_topics: tuple[str, ...]
    records: tuple[SnapshotRecord, ...]
    breaks: tuple[BreakEvent, ...]
    failure_level: float
    message_count: int
    start_ns: int
    end_ns: int
    skipped_messages: int
    elapsed_s: float
    params: RoseParams = field(default_factory=RoseParams)

    def records_of(self, topic: str) -> tuple[SnapshotRecord, ...]:
        """The records of one map topic."""
        return tuple(r for r in self.records if r.topic == topic)

    def first_break(self, topic: str | None = None) -> BreakEvent | None:
        """The first break (of ``topic``, or of any topic), None if W never crossed the level."""
        for event in self.breaks:
            if topic is None or event.topic == topic:
                return event
        return None

    @property
    def max_score(self) -> float:
        """Largest W of the session (NaN without snapshots)."""
        return max((r.structure_score for r in self.records), default=math.nan)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready report: session summary plus one record per snapshot."""
        topics = {}
        for topic in self.map_topics:
            scores = [r.structure_score for r in self.records_of(topic)]
            first = self.first_break(topic)
            topics[topic] = {
                "snapshots": len(scores),
                "w_min": min(scores, default=None),
                "w_median": statistics.median(scores) if scores else None,
                "w_max": max(scores, default=None),
                "first_break": None
                if first is None
                else {
                    "index": first.index,
                    "log_time_ns": first.log_time_ns,
                    "structure_score": first.structure_score,
                },
            }
        return {
            "input": str(self.input_path),
            "input_format": self.input_format,
            "output": None if self.output_path is None else str(self.output_path),
            "rrd": None if self.rrd_path is None else str(self.rrd_path),
            "failure_level": self.failure_level,
            "message_count": self.message_count,
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "skipped_messages": self.skipped_messages,
            "elapsed_s": round(self.elapsed_s, 6),
            "params": {k: getattr(self.params, k) for k in self.params.__dataclass_fields__},
            "topics": topics,
            "snapshots": [r.to_json(start_ns=self.start_ns) for r in self.records],
        }


def is_derived_topic(topic: str) -> bool:
    """Whether ``topic`` is one of our own outputs (``.../rose/...``), never analysed again."""
    return "/rose/" in topic


def find_map_topics(channels: Sequence[Channel]) -> tuple[str, ...]:
    """Topics of type ``nav_msgs/OccupancyGrid`` (ROS 1 or ROS 2), sorted, without our derived topics."""
    return tuple(
        sorted(
            {
                c.topic
                for c in channels
                if c.msgtype == MAP_TYPE
                and c.message_encoding in _DECODABLE
                and not is_derived_topic(c.topic)
            }
        )
    )


def _update_targets(channels: Sequence[Channel], map_topics: Sequence[str]) -> dict[str, str]:
    """Update topic -> map topic: ``<map>_updates`` by name, else the only map topic."""
    targets = {}
    for c in channels:
        if c.msgtype != UPDATE_TYPE or c.message_encoding not in _DECODABLE:
            continue
        if c.topic.endswith("_updates") and c.topic[: -len("_updates")] in map_topics:
            targets[c.topic] = c.topic[: -len("_updates")]
        elif len(map_topics) == 1:
            targets[c.topic] = map_topics[0]
        else:
            _LOG.warning("%s: grid updates for an unknown map topic, not applied", c.topic)
    return targets


def default_output_path(input_path: Path) -> Path:
    """``run.mcap`` -> ``run.rose.mcap``, ``run.bag`` -> ``run.rose.bag``, folder ``run`` -> ``run.rose``."""
    path = Path(input_path)
    if path.is_dir() or path.suffix.lower() == ".db3":
        return path.with_name(f"{path.stem if path.is_file() else path.name}.rose")
    return path.with_name(f"{path.stem}.rose{path.suffix}")


@dataclass(frozen=True)
class _Analysis:
    """What the session computes for one snapshot."""

    result: RoseResult
    walls: WallSet | None
    reused: bool


class _Analyser:
    """rose.analyze (and optionally wall extraction) per snapshot, reusing the previous analysis of a
    topic when its grid and placement are unchanged."""

    def __init__(self, params: RoseParams, *, walls: bool) -> None:
        self.params = params
        self.walls = walls
        self.previous: dict[str, tuple[MapSnapshot, _Analysis]] = {}

    def __call__(self, snapshot: MapSnapshot) -> _Analysis:
        prev = self.previous.get(snapshot.topic)
        if prev is not None and _same_placed_grid(prev[0], snapshot):
            return dataclasses.replace(prev[1], reused=True)
        result = rose.analyze(snapshot.grid, self.params)
        walls = None
        if self.walls:
            placed = rose.OccupancyMap(
                grid=snapshot.grid,
                resolution_m=snapshot.resolution_m,
                origin_xy_m=(snapshot.origin_position_m[0], snapshot.origin_position_m[1]),
                origin_yaw_rad=snapshot.origin_yaw_rad,
            )
            walls = rose.extract_walls(placed, result)
        analysis = _Analysis(result, walls, reused=False)
        self.previous[snapshot.topic] = (snapshot, analysis)
        return analysis


def _same_placed_grid(a: MapSnapshot, b: MapSnapshot) -> bool:
    # Walls are in metres, so a reused analysis also needs the same placement.
    return (
        a.resolution_m == b.resolution_m
        and a.origin_position_m == b.origin_position_m
        and a.origin_orientation_xyzw == b.origin_orientation_xyzw
        and np.array_equal(a.grid, b.grid)
    )


def _open_rerun(
    input_path: Path,
    *,
    rrd_path: Path | None,
    spawn: bool,
    connect: str | None,
    topics: Sequence[str],
    start_ns: int,
    failure_level: float,
) -> RerunSink:
    """The session's Rerun recording; its id names the input (full path and content)."""
    from rose_logs.rerun.sink import RerunSink, recording_id_for  # rerun loads only when used

    try:
        return RerunSink(
            rrd_path=rrd_path,
            spawn=spawn,
            connect=connect,
            topics=topics,
            recording_id=recording_id_for(input_path),
            start_ns=start_ns,
            failure_level=failure_level,
        )
    except (ValueError, OSError, RuntimeError) as err:
        msg = f"{rrd_path or connect or 'viewer'}: cannot open the Rerun recording ({err})"
        raise LogWriteError(msg) from err


def _select_topics(
    path: Path, channels: Sequence[Channel], topics: Sequence[str] | None
) -> tuple[str, ...]:
    found = find_map_topics(channels)
    if topics:
        known = {c.topic: c for c in channels}
        for topic in topics:
            if topic not in known:
                msg = f"{path}: no topic {topic} (map topics: {', '.join(found) or 'none'})"
                raise LogReadError(msg)
            if topic not in found:
                msg = f"{path}: topic {topic} is {known[topic].msgtype}, not nav_msgs/OccupancyGrid"
                raise LogReadError(msg)
        return tuple(dict.fromkeys(topics))
    if not found:
        names = ", ".join(sorted({c.topic for c in channels})) or "none"
        msg = f"{path}: no nav_msgs/OccupancyGrid topic (topics: {names})"
        raise LogReadError(msg)
    return found


def process_log(
    input_path: Path,
    *,
    output_path: Path | None = None,
    output_format: LogFormat | None = None,
    force: bool = False,
    topics: Sequence[str] | None = None,
    params: RoseParams | None = None,
    failure_level: float = FAILURE_LEVEL,
    rrd_path: Path | None = None,
    spawn: bool = False,
    connect: str | None = None,
    progress: bool = False,
    on_snapshot: Callable[[MapSnapshot, RoseResult, SnapshotRecord], None] | None = None,
    walls: bool = False,
) -> SessionReport:
    """Run ROSE over every map snapshot of a log; write the output log and Rerun recording.

    Parameters
    ----------
    input_path : Path
        ROS 1 bag, ROS 2 bag (folder, ``.db3``) or MCAP file. Never modified.
    output_path : Path, optional
        Output log: every input message unchanged plus ``<map>/rose/{cleaned,structure_score,walls}``.
        None: no output log.
    output_format : {"ros1", "db3", "mcap", "mcap-dir"}, optional
        Default: implied by ``output_path``'s suffix, else the input's format.
    force : bool, default False
        Replace an existing output log / recording.
    topics : sequence of str, optional
        Map topics to analyse; default every ``nav_msgs/OccupancyGrid`` topic.
    params : RoseParams, optional
        ROSE parameters (defaults of :class:`rose.RoseParams`).
    failure_level : float, default 0.4
        W above which a snapshot counts as broken.
    rrd_path : Path, optional
        Save a Rerun recording here.
    spawn : bool, default False
        Stream the recording to a new Rerun viewer.
    connect : str, optional
        Stream the recording to a running Rerun viewer at this address (``PORT``, ``HOST:PORT`` or
        a ``rerun+http://`` URL), as the session is processed.
    progress : bool, default False
        Show a tqdm progress bar on stderr.
    walls : bool, default False
        Also extract wall segments (``rose.extract_walls``) per snapshot: a ``LINE_LIST`` marker in
        ``<map>/rose/walls`` and line strips in Rerun. Costs about 20-45 ms per 1000 x 1000 snapshot.
    on_snapshot : callable, optional
        Called with ``(snapshot, result, record)`` after each snapshot.

    Returns
    -------
    SessionReport

    Raises
    ------
    LogReadError
        If the input is missing, corrupt or truncated, or has no (usable) map topic.
    LogWriteError
        If an output cannot be written. Nothing is left under the output names on any error.
    """
    started = time.perf_counter()
    input_path = Path(input_path)
    params = params or RoseParams()
    if not math.isfinite(failure_level):
        msg = f"failure level must be finite, got {failure_level}"
        raise ValueError(msg)
    reader = LogReader(input_path)
    if rrd_path is not None and Path(rrd_path).exists() and not force:
        msg = f"{rrd_path}: exists already (use --force to replace it)"
        raise LogWriteError(msg)
    with reader:
        channels = reader.channels
        map_topics = _select_topics(input_path, channels, topics)
        updates = _update_targets(channels, map_topics)
        writer: LogWriter | None = None
        if output_path is not None:
            fmt = output_format or format_from_path(output_path) or reader.format
            writer = LogWriter(
                output_path,
                fmt,
                serialization=reader.serialization,
                force=force,
                protected=(input_path,),
            )
        rerun: RerunSink | None = None
        try:
            if writer is not None:
                writer.open()
            handles, derived = _prepare_output(writer, channels, map_topics)
            if rrd_path is not None or spawn or connect is not None:
                rerun = _open_rerun(
                    input_path,
                    rrd_path=None if rrd_path is None else Path(rrd_path),
                    spawn=spawn,
                    connect=connect,
                    topics=map_topics,
                    start_ns=reader.start_ns,
                    failure_level=failure_level,
                )
            loop = _Loop(
                reader=reader,
                writer=writer,
                handles=handles,
                derived=derived,
                map_topics=map_topics,
                updates=updates,
                analyser=_Analyser(params, walls=walls),
                failure_level=failure_level,
                rerun=rerun,
                on_snapshot=on_snapshot,
            )
            loop.run(progress=progress)
            if not loop.records:
                msg = (
                    f"{input_path}: no map message on {', '.join(map_topics)} could be analysed "
                    f"({loop.skipped} malformed)"
                )
                raise LogReadError(msg)
            if writer is not None:
                writer.close()
            if rerun is not None:
                rerun.close()
        except BaseException:
            if writer is not None:
                writer.abort()
            if rerun is not None:
                rerun.abort()
            raise
        return SessionReport(
            input_path=input_path,
            input_format=reader.format,
            output_path=None if writer is None else writer.path,
            rrd_path=None if rrd_path is None else Path(rrd_path),
            map_topics=map_topics,
            records=tuple(loop.records),
            breaks=tuple(loop.breaks),
            failure_level=failure_level,
            message_count=reader.message_count,
            start_ns=reader.start_ns,
            end_ns=reader.end_ns,
            skipped_messages=loop.skipped,
            elapsed_s=time.perf_counter() - started,
            params=params,
        )


def _prepare_output(
    writer: LogWriter | None, channels: Sequence[Channel], map_topics: Sequence[str]
) -> tuple[dict[int, int], dict[str, tuple[int, int, int]]]:
    """Output connections: input channel id -> handle, and map topic -> derived handles."""
    if writer is None:
        return {}, {}
    handles = {c.id: writer.add_channel(c) for c in channels}
    derived = {}
    for topic in map_topics:
        names = derived_topics(topic)
        for name in (names.cleaned, names.structure_score, names.walls):
            if writer.has_topic(name):
                msg = f"{writer.path}: the input has topic {name} already (processed before?)"
                raise LogWriteError(msg)
        source = next(c for c in channels if c.topic == topic)
        qos = offered_qos(source)
        latched = (
            bool(source.latching)
            or any(q.durability.name == "TRANSIENT_LOCAL" for q in qos)
            or "transient_local" in source.metadata.get("offered_qos_profiles", "")
        )
        derived[topic] = (
            writer.add_topic(
                names.cleaned,
                MAP_TYPE,
                latching=latched,
                qos=qos or None,
                callerid=source.callerid,
            ),
            writer.add_topic(names.structure_score, FLOAT32_TYPE, callerid=source.callerid),
            writer.add_topic(
                names.walls, MARKER_ARRAY_TYPE, latching=latched, callerid=source.callerid
            ),
        )
    return handles, derived


class _Loop:
    """State of one pass: last full map per topic, per-topic counters, break detection."""

    def __init__(
        self,
        *,
        reader: LogReader,
        writer: LogWriter | None,
        handles: dict[int, int],
        derived: dict[str, tuple[int, int, int]],
        map_topics: Sequence[str],
        updates: dict[str, str],
        analyser: _Analyser,
        failure_level: float,
        rerun: RerunSink | None,
        on_snapshot: Callable[[MapSnapshot, RoseResult, SnapshotRecord], None] | None,
    ) -> None:
        self.reader = reader
        self.writer = writer
        self.handles = handles
        self.derived = derived
        self.map_topics = set(map_topics)
        self.updates = updates
        self.analyser = analyser
        self.failure_level = failure_level
        self.rerun = rerun
        self.on_snapshot = on_snapshot
        self.serialization = reader.serialization
        self.last_map: dict[str, MapSnapshot] = {}
        self.count: dict[str, int] = {}
        self.above: dict[str, bool] = {}
        self.records: list[SnapshotRecord] = []
        self.breaks: list[BreakEvent] = []
        self.skipped = 0

    def run(self, *, progress: bool) -> None:
        from tqdm import tqdm

        bar = tqdm(
            total=self.reader.message_count,
            unit="msg",
            unit_scale=True,
            disable=not progress,
            dynamic_ncols=True,
            leave=False,
        )
        pending = 0
        try:
            writer, handles = self.writer, self.handles
            for message in self.reader.messages():
                channel = message.channel
                if writer is not None:
                    writer.write_raw(
                        handles[channel.id],
                        message.log_time_ns,
                        message.data,
                        publish_time_ns=message.publish_time_ns,
                        sequence=message.sequence,
                    )
                if channel.topic in self.map_topics and channel.msgtype == MAP_TYPE:
                    self._on_map(message.data, channel.topic, message.log_time_ns)
                elif channel.topic in self.updates:
                    self._on_update(message.data, channel.topic, message.log_time_ns)
                pending += 1
                if pending >= 64:
                    bar.update(pending)
                    pending = 0
            bar.update(pending)
        finally:
            bar.close()

    def _on_map(self, data: bytes | memoryview, topic: str, log_time_ns: int) -> None:
        try:
            snapshot = decode_map(
                data, serialization=self.serialization, topic=topic, log_time_ns=log_time_ns
            )
        except MapMessageError as err:
            self.skipped += 1
            _LOG.warning("%s at %d ns, copied unprocessed", err, log_time_ns)
            return
        self.last_map[topic] = snapshot
        self._analyse(snapshot, from_update=False)

    def _on_update(self, data: bytes | memoryview, topic: str, log_time_ns: int) -> None:
        target = self.updates[topic]
        try:
            update = decode_update(
                data, serialization=self.serialization, topic=topic, log_time_ns=log_time_ns
            )
            base = self.last_map.get(target)
            if base is None:
                msg = f"{topic}: grid update before the first full map on {target}"
                raise MapMessageError(msg)
            snapshot = apply_update(base, update)
        except (MapMessageError, ValueError) as err:
            self.skipped += 1
            _LOG.warning("%s at %d ns, copied unprocessed", err, log_time_ns)
            return
        self.last_map[target] = snapshot
        self._analyse(snapshot, from_update=True)

    def _analyse(self, snapshot: MapSnapshot, *, from_update: bool) -> None:
        t0 = time.perf_counter()
        topic = snapshot.topic
        try:
            analysis = self.analyser(snapshot)
            result, reused = analysis.result, analysis.reused
        except rose.RoseError as err:  # e.g. cell values outside -1..100
            self.skipped += 1
            _LOG.warning(
                "%s: map at %d ns not analysed (%s), copied unprocessed",
                topic,
                snapshot.log_time_ns,
                err,
            )
            return
        index = self.count.get(topic, 0)
        self.count[topic] = index + 1
        score = float(result.structure_score)
        if self.writer is not None:
            cleaned_h, score_h, walls_h = self.derived[topic]
            t = snapshot.log_time_ns
            ser = self.serialization
            self.writer.write_raw(
                cleaned_h, t, encode_cleaned(snapshot, result.cleaned, serialization=ser)
            )
            self.writer.write_raw(score_h, t, encode_score(score, serialization=ser))
            self.writer.write_raw(
                walls_h, t, encode_walls(snapshot, result, analysis.walls, serialization=ser)
            )
        broke = score > self.failure_level and not self.above.get(topic, False)
        self.above[topic] = score > self.failure_level
        if self.rerun is not None:
            self.rerun.snapshot(snapshot, result, index, analysis.walls)
        if broke:
            text = (
                f"{topic}: W = {score:.3f} rose above the failure level {self.failure_level:g} "
                f"at snapshot {index}"
            )
            self.breaks.append(BreakEvent(topic, index, snapshot.log_time_ns, score, text))
            if self.rerun is not None:
                self.rerun.event(snapshot, text, index, score)
        height, width = snapshot.shape
        record = SnapshotRecord(
            topic=topic,
            index=index,
            log_time_ns=snapshot.log_time_ns,
            stamp_ns=snapshot.stamp_ns,
            width=width,
            height=height,
            resolution_m=snapshot.resolution_m,
            structure_score=score,
            directions_deg=tuple(float(np.degrees(d)) for d in result.dominant_directions),
            threshold=float(result.threshold),
            occupied_count=result.occupied_count,
            clutter_count=result.clutter_count,
            seconds=time.perf_counter() - t0,
            reused=reused,
            from_update=from_update,
        )
        self.records.append(record)
        if self.on_snapshot is not None:
            self.on_snapshot(snapshot, result, record)
