"""The processing loop: log -> snapshots -> ROSE -> sinks (output log, Rerun, report).

One pass over the input in log-time order. Every message is copied byte for byte to the output log;
map messages (``nav_msgs/OccupancyGrid``) and grid updates (``map_msgs/OccupancyGridUpdate``, applied to
the last full map of their topic) become :class:`~rose_logs.snapshots.MapSnapshot` s, each analysed with
:func:`rose.analyze` on its own grid (a grid equal to the previous one of its topic reuses that result),
and the results go to the output log (derived topics, :mod:`rose_logs.derived`), to Rerun
(:mod:`rose_logs.rerun`) and to the :class:`SessionReport`.

Breaks: every snapshot also goes through the break detector (:mod:`rose_logs.session.breaks`), which
scores it against the last trusted snapshot of its topic; the start of each run of broken snapshots
is a :class:`~rose_logs.session.breaks.DetectedBreak`. Separately, a snapshot where W rises above
``failure_level`` (the paper's 0.4) after being at or below it (or on the first snapshot of a topic)
is a :class:`BreakEvent`.

Here: :func:`process_log`, the session around the loop, and the loop (:class:`_Loop`). Beside it:
:mod:`.checks` (process_log's arguments), :mod:`.sinks` (the output log and the Rerun recording,
opened), :mod:`.records` (a snapshot's record, the map messages copied unprocessed).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import struct
import time
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, Future
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import rose
from rose.cleaning import CleanMethod
from rose.directions import FAILURE_LEVEL
from rose.limits import (
    DEFAULT_MAX_CELLS,
    check_cells,
    short,
)
from rose.outputs import OutputSet
from rose.params import RoseParams
from rose.result import RoseResult
from rose.signals import signals_deferred
from rose.threads import threads_in_this_context
from rose_logs.derived import encode_cleaned, encode_score, encode_walls
from rose_logs.errors import EmptyMapError, LogReadError, LogWriteError, MapMessageError
from rose_logs.formats import LogFormat
from rose_logs.frames import quaternion_tilt
from rose_logs.reader import LogReader
from rose_logs.session.analysis import SnapshotAnalyser, SnapshotAnalysis
from rose_logs.session.breaks import BreakDetector, BreakParams, BreakScore, DetectedBreak
from rose_logs.session.checks import check_arguments
from rose_logs.session.held_logs import (
    call_held,
    held_by,
    held_log_records,
    said_above_bar,
    said_at_once,
    say_held,
)
from rose_logs.session.records import WARN_FIRST, Skips, returned_text, snapshot_record
from rose_logs.session.report import (
    BreakEvent,
    SessionReport,
    SnapshotRecord,
    score_beside_level,
)
from rose_logs.session.sinks import output_writer, prepare_output, rerun_failure, rerun_sink
from rose_logs.session.topics import (
    orphan_updates,
    select_topics,
    update_targets,
    warn_shared_map_topics,
    warn_unknown_definitions,
)
from rose_logs.snapshots import (
    MapSnapshot,
    apply_update,
    check_log_time,
    decode_map,
    decode_update,
)
from rose_logs.storage.records import Channel, RawMessage
from rose_logs.storage.typesys import MAP_TYPE
from rose_logs.writer import LogWriter

__all__ = ["process_log"]

if TYPE_CHECKING:
    from rose_logs.rerun import RerunSink

_LOG = logging.getLogger(__name__)

#: Origins tilted less than this out of the x-y plane (float noise in a quaternion) are flat.
_FLAT_TILT_RAD = math.radians(0.1)

#: Bytes of input messages held behind running analyses at most: past it, the reading waits for the
#: analysis at the queue's head. Without a bound, a camera's images read while a large map was
#: analysed were all held in memory (600 MB of them behind one 2400 x 2400 map: 1.46 GB at peak).
_MAX_HELD_BYTES = 256 * 2**20
#: What a held message costs beyond its data (its queue item and numbers, about 270 bytes): held
#: 40-byte messages take seven times their data.
_HELD_ITEM_BYTES = 256


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
    on_outputs_ready: Callable[[], None] | None = None,
    walls: bool = False,
    clean_method: CleanMethod = "walls",
    recording_id: str | None = None,
    break_params: BreakParams | None = None,
    outputs: OutputSet | None = None,
    salvage: bool = False,
    max_cells: int | None = DEFAULT_MAX_CELLS,
    analysis_threads: int = 2,
    replace_rose_topics: bool = False,
    reader: LogReader | None = None,
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
        Stream the recording to a new Rerun viewer as the session is processed.
    connect : str, optional
        Stream the recording to a running Rerun viewer at this address (``PORT``, ``HOST:PORT`` or
        a ``rerun+http://`` URL), as the session is processed.
    progress : bool, default False
        Show a tqdm progress bar on stderr.
    walls : bool, default False
        Also extract wall segments (``rose.extract_walls``) per snapshot: a ``LINE_LIST`` marker in
        ``<map>/rose/walls`` and line strips in Rerun. Costs about 20-45 ms per 1000 x 1000 snapshot.
    clean_method : {"walls", "paper"}, default "walls"
        How ``<map>/rose/cleaned`` is made (:func:`rose.cleaning.clean`): walls kept and no robot-sized
        gap opened, or the paper's labelling as it is.
    on_snapshot : callable, optional
        Called with ``(snapshot, result, record)`` after each snapshot.
    on_outputs_ready : callable, optional
        Called once every output is accepted (the log's format against the input's messages, the
        input's ``<map>/rose/*`` topics, the recording) and before the first snapshot: ``rose-bag
        process`` says its warnings about the outputs' names then, so that a refused output gets
        its error alone.
    recording_id : str, optional
        Rerun recording id; default: :func:`rose_logs.rerun.sink.recording_id_for` (the input's
        absolute path and content, so a re-run of the same file joins it). ``rose-bag batch`` passes
        one derived from the full URI, so that two robots' ``run.mcap`` stay separate recordings.
    break_params : BreakParams, optional
        Break detector parameters; default
        ``BreakParams.following(params.occupied_threshold)`` (the defaults, with the occupied
        threshold the analysis uses).
    outputs : rose.outputs.OutputSet, optional
        The run's outputs: the log and recording are staged there and the caller commits them together
        with its own (a JSON report). Default: a set of its own, committed before returning.
    salvage : bool, default False
        When messages are lost (corrupt chunk, CRC, fewer than declared): False raises
        :class:`~rose_logs.reader.MessageLossError` and writes nothing; True keeps what could be read
        and lists the problems in :attr:`SessionReport.losses`.
    max_cells : int or None, default :data:`rose.limits.DEFAULT_MAX_CELLS`
        Larger maps are not analysed (a warning; copied through like malformed maps).
    analysis_threads : int, default 2
        Snapshots analysed at once, in threads, while messages are copied and results written in
        log order (outputs do not depend on it). Each costs one analysis of memory.
    replace_rose_topics : bool, default False
        An input that holds ``<map>/rose/*`` topics already (a processed log; of any of its maps,
        analysed now or not): leave them all out of the output log and write the analysed maps'
        anew (the output of the log as it was before). False: such an input is refused for an
        output log (it would hold results of two runs, made with two sets of options).
    reader : LogReader, optional
        The input's reader, made by the caller of ``input_path`` with ``salvage`` and not opened,
        whose :attr:`~rose_logs.reader.LogReader.format` it used already (to choose
        ``output_format``): a ROS 2 bag folder's metadata.yaml, which it holds as read, is not read
        again (seconds for thousands of topics). Default: a reader made here.

    Returns
    -------
    SessionReport

    Raises
    ------
    LogReadError
        If the input is missing, corrupt or truncated, or has no (usable) map topic.
    LogWriteError
        If an output cannot be written. Nothing is left under the output names on any error.
    OutputError
        If the recording touches the input or another output, or exists without ``force``.
    RoseError
        On a parameter out of range (``params``, ``failure_level``, ``clean_method``,
        ``analysis_threads``), ``topics`` that are not topic names, or an argument of the wrong
        kind (a path that is no file name, a callback that is not callable, ``outputs`` that is no
        OutputSet, ``salvage`` not True or False), before the input is read.
    """
    started = time.perf_counter()
    input_path, topics, params, break_params, max_cells = check_arguments(
        input_path,
        output_path=output_path,
        rrd_path=rrd_path,
        on_snapshot=on_snapshot,
        on_outputs_ready=on_outputs_ready,
        outputs=outputs,
        salvage=salvage,
        topics=topics,
        params=params,
        break_params=break_params,
        failure_level=failure_level,
        analysis_threads=analysis_threads,
        max_cells=max_cells,
        clean_method=clean_method,
    )
    if reader is not None and (
        not isinstance(reader, LogReader) or (reader.path, reader.salvage) != (input_path, salvage)
    ):
        msg = "reader must be a LogReader of input_path, made with the same salvage"
        raise rose.RoseError(msg)
    own_outputs = outputs is None
    outputs = OutputSet(force=force) if outputs is None else outputs
    outputs.add_input(input_path)
    reader = LogReader(input_path, salvage=salvage) if reader is None else reader
    rrd_temp: Path | None = None
    try:
        if rrd_path is not None:
            rrd_temp = outputs.stage(rrd_path).temp
            if rrd_temp is None:
                msg = f"{rrd_path}: a Rerun recording cannot be written to a stream or device"
                raise LogWriteError(msg)
        report = _run_session(
            reader,
            input_path=input_path,
            output_path=output_path,
            output_format=output_format,
            force=force,
            topics=topics,
            params=params,
            failure_level=failure_level,
            rrd_path=rrd_path,
            rrd_temp=rrd_temp,
            spawn=spawn,
            connect=connect,
            progress=progress,
            on_snapshot=on_snapshot,
            on_outputs_ready=on_outputs_ready,
            walls=walls,
            clean_method=clean_method,
            recording_id=recording_id,
            break_params=break_params,
            outputs=outputs,
            max_cells=max_cells,
            analysis_threads=analysis_threads,
            replace_rose_topics=replace_rose_topics,
        )
    except BaseException:
        if own_outputs:
            outputs.abort()
        raise
    if own_outputs:
        outputs.commit()
    return dataclasses.replace(report, elapsed_s=time.perf_counter() - started)


def _run_session(
    reader: LogReader,
    *,
    input_path: Path,
    output_path: Path | None,
    output_format: LogFormat | None,
    force: bool,
    topics: Sequence[str] | None,
    params: RoseParams,
    failure_level: float,
    rrd_path: Path | None,
    rrd_temp: Path | None,
    spawn: bool,
    connect: str | None,
    progress: bool,
    on_snapshot: Callable[[MapSnapshot, RoseResult, SnapshotRecord], None] | None,
    on_outputs_ready: Callable[[], None] | None,
    walls: bool,
    clean_method: CleanMethod,
    recording_id: str | None,
    break_params: BreakParams,
    outputs: OutputSet,
    max_cells: int | None,
    analysis_threads: int,
    replace_rose_topics: bool,
) -> SessionReport:
    """The session proper; outputs are staged in ``outputs`` (committed by the caller)."""
    with reader:
        channels = reader.channels
        map_topics = select_topics(input_path, channels, topics)
        warn_shared_map_topics(channels, map_topics)
        updates = update_targets(channels, map_topics)
        warn_unknown_definitions(channels, [*map_topics, *updates])
        writer = output_writer(
            reader, input_path, output_path, output_format, force=force, outputs=outputs
        )
        rerun: RerunSink | None = None
        try:
            if writer is not None:
                writer.open()
            handles, derived = prepare_output(
                writer, channels, map_topics, input_path, replace=replace_rose_topics
            )
            if writer is not None:  # an MCAP file's records of no channel (a URDF attached...)
                writer.add_file_records(reader.file_records())
                writer.add_custom_data(reader.custom_data)  # and a ROS 2 bag's own key-values
            if rrd_path is not None or spawn or connect is not None:
                # Signals held until `rerun` is bound: an interrupt in between would leave Rerun's
                # writer running, to create its file after the abort removed the folder around it.
                with signals_deferred():
                    rerun = rerun_sink(
                        input_path,
                        rrd_temp,
                        map_topics,
                        spawn=spawn,
                        connect=connect,
                        recording_id=recording_id,
                        start_ns=reader.start_ns,
                        failure_level=failure_level,
                        shown_as=rrd_path,
                    )
            if on_outputs_ready is not None:
                on_outputs_ready()
            loop = _Loop(
                reader=reader,
                writer=writer,
                handles=handles,
                derived=derived,
                map_topics=map_topics,
                updates=updates,
                orphans={c.topic for c in orphan_updates(channels)},
                analyser=SnapshotAnalyser(params, walls=walls, clean_method=clean_method),
                failure_level=failure_level,
                rerun=rerun,
                on_snapshot=on_snapshot,
                detector=BreakDetector(break_params),
                max_cells=max_cells,
                in_flight=analysis_threads,
            )
            loop.run(progress=progress)
            # A log of empty maps only is valid: nothing to analyse, no error (the gates, which
            # cannot judge a topic without a snapshot, say so if asked).
            if not loop.records and set(loop.skips.by_reason) != {"empty"}:
                skipped = loop.skips.describe()
                if skipped != "none":
                    why = skipped
                elif reader.losses:  # (warned about as the reader met them)
                    why = "the damage above lost them"
                else:
                    why = "it holds none: declared only"
                msg = (
                    f"{input_path}: no map message on {', '.join(map_topics)} could be analysed "
                    f"({why})"
                )
                raise LogReadError(msg)
            if writer is not None:
                writer.close()
            if rerun is not None:
                try:
                    rerun.close()
                except (RuntimeError, OSError) as err:  # e.g. the disk filled up, no viewer
                    raise LogWriteError(
                        rerun_failure(rrd_path, connect, err, written=rerun.written_bytes())
                    ) from err
        except BaseException:
            if writer is not None:
                writer.abort()
            if rerun is not None:
                rerun.abort()
            raise
        return _session_report(
            reader,
            loop,
            input_path=input_path,
            output_path=None if writer is None else writer.path,
            rrd_path=rrd_path,
            map_topics=map_topics,
            failure_level=failure_level,
            params=params,
            break_threshold_m=break_params.threshold_m,
        )


def _session_report(
    reader: LogReader,
    loop: _Loop,
    *,
    input_path: Path,
    output_path: Path | None,
    rrd_path: Path | None,
    map_topics: Sequence[str],
    failure_level: float,
    params: RoseParams,
    break_threshold_m: float,
) -> SessionReport:
    """What one pass found, with the input's counts and time range (``elapsed_s`` filled in by
    :func:`process_log`, which times the whole call, the outputs' commit included)."""
    return SessionReport(
        input_path=input_path,
        input_format=reader.format,
        output_path=output_path,
        rrd_path=None if rrd_path is None else Path(rrd_path),
        map_topics=tuple(map_topics),
        records=tuple(loop.records),
        breaks=tuple(loop.breaks),
        failure_level=failure_level,
        message_count=reader.read_count,
        start_ns=reader.start_ns,
        # A damaged log's index still declares its whole range: give what was read.
        end_ns=(
            max(reader.start_ns, min(reader.end_ns, loop.latest_ns))
            if reader.losses
            else reader.end_ns
        ),
        skipped_messages=loop.skipped,
        skipped_reasons=loop.skips.describe() if loop.skipped else "",
        elapsed_s=0.0,
        params=params,
        detected_breaks=tuple(loop.detected),
        break_threshold_m=break_threshold_m,
        losses=tuple(reader.losses),
    )


class _Copy(NamedTuple):
    """An input message to copy to the output log (a tuple: one is made for every message, and a
    frozen dataclass's fields are set one call each)."""

    handle: int
    log_time_ns: int
    data: bytes | memoryview
    publish_time_ns: int
    sequence: int


@dataclass(frozen=True)
class _Said:
    """What the session logged while reading messages, said when the snapshots before them are."""

    records: tuple[logging.LogRecord, ...]


@dataclass(frozen=True)
class _Pending:
    """A snapshot whose analysis runs; its outputs are written when it is at the queue's head."""

    snapshot: MapSnapshot
    from_update: bool
    reused: bool
    future: Future[SnapshotAnalysis]
    #: The break detector's verdict, and what it logged (said in log order, see :meth:`_finish`).
    verdict: Future[tuple[BreakScore, tuple[logging.LogRecord, ...]]]
    read: int  # the place of its message in the reading (Skips's order)


class _Loop:
    """State of one pass: last full map per topic, per-topic counters, break detection.

    Messages are copied and snapshots finished strictly in log order through one queue; analyses run
    ahead (up to ``in_flight``, in threads: NumPy's FFT and OpenCV release the GIL), so the output
    log is byte-identical whatever the timing.
    """

    def __init__(
        self,
        *,
        reader: LogReader,
        writer: LogWriter | None,
        handles: dict[int, int],
        derived: dict[str, tuple[int, int, int]],
        map_topics: Sequence[str],
        updates: dict[str, str],
        analyser: SnapshotAnalyser,
        orphans: set[str],
        failure_level: float,
        rerun: RerunSink | None,
        on_snapshot: Callable[[MapSnapshot, RoseResult, SnapshotRecord], None] | None,
        detector: BreakDetector,
        max_cells: int | None = DEFAULT_MAX_CELLS,
        in_flight: int = 2,
    ) -> None:
        self.in_flight_limit = in_flight
        self.max_cells = max_cells
        self.reader = reader
        self.detector = detector
        self.detected: list[DetectedBreak] = []
        self.writer = writer
        self.handles = handles
        self.derived = derived
        self.map_topics = set(map_topics)
        self.updates = updates
        self.orphans = orphans  # update topics whose map cannot be told
        self.analyser = analyser
        self.failure_level = failure_level
        self.rerun = rerun
        self.on_snapshot = on_snapshot
        self.serialization = reader.serialization
        self.last_map: dict[str, MapSnapshot] = {}
        # Topics whose latest full map was skipped, and why ("malformed" or "empty").
        self.lost_map: dict[str, str] = {}
        self.analysed: dict[str, int] = {}  # per topic: snapshots analysed (the next one's index)
        # Per topic: whether W of its last judged snapshot was above the failure level.
        self.w_above: dict[str, bool] = {}
        self.broken: dict[str, bool] = {}  # per topic: whether its last snapshot was broken
        self.restarts: dict[str, int] = {}  # per topic: maps the break detector restarted at
        # Per topic: the first restart past WARN_FIRST, where Rerun's event counting the rest goes.
        self.unshown_restart: dict[str, tuple[MapSnapshot, int, BreakScore]] = {}
        self.records: list[SnapshotRecord] = []
        self.breaks: list[BreakEvent] = []
        self.skips = Skips(_LOG)
        self.said: set[tuple[str, str]] = set()  # (topic, what): warnings given once per topic
        self.latest_ns = 0  # log time of the latest message read (a salvaged log ends there)
        self.read = 0  # messages read: the place of the one being read (Skips's order)
        self.queue: deque[_Copy | _Said | _Pending] = deque()
        self.said_while_reading: list[logging.LogRecord] = []  # held, see _step
        self.in_flight = 0
        self.held_bytes = 0  # what the _Copy items in the queue hold (bounded: _MAX_HELD_BYTES)
        self.executor: Executor | None = None
        self.detection: Executor | None = None
        # Per topic, the analysis of its last snapshot submitted (see _detect).
        self.last_analysis: dict[str, Future[SnapshotAnalysis]] = {}

    def run(self, *, progress: bool) -> None:
        from tqdm import tqdm

        bar = tqdm(
            total=self.reader.message_count,
            unit="msg",
            # Whole counts ("47/973 msg"; scaled ones read "47.0/973"), a scaled rate ("1.2Mmsg/s").
            unit_scale=True,
            bar_format="{l_bar}{bar}| {n}/{total} {unit} [{elapsed}<{remaining}, {rate_fmt}]",
            disable=not progress,
            dynamic_ncols=True,
            leave=False,
        )
        pending = 0
        pool = threads_in_this_context(self.in_flight_limit, "rose-analyse")
        # One thread, first in first out: the break detector sees the snapshots in log order.
        detection = threads_in_this_context(1, "rose-breaks")
        self.executor, self.detection = pool, detection
        # Lines logged while the bar is drawn go above it, also those said as the run ends.
        with said_above_bar(not bar.disable):
            try:
                # An interrupt is taken between two messages, not where it lands: raised inside
                # the futures' bookkeeping (a Future's lock held by this thread), it left an
                # analysis thread waiting on that lock for ever and the run hung at Ctrl-C (1 in
                # about 20). A second one ends the run at once (a slow read or write holds the
                # first). What the session says while it reads (the reader's losses, a skipped or
                # tilted map) is held too, and said after the snapshots before it (see _step):
                # said at once, it came before or after their analyses' warnings as the threads
                # kept up.
                with signals_deferred(second_ends=True) as held, held_log_records() as said:
                    self.said_while_reading = said
                    for message in self.reader.messages():
                        if held:  # raised as the block ends
                            break
                        self._step(message)
                        pending += 1
                        # Every 64 messages, and at every map (a log of maps alone moved in big
                        # jumps).
                        if pending >= 64 or self._is_map(message.channel):
                            bar.update(pending)
                            pending = 0
                    else:
                        self._queue_said()
                        with said_at_once():
                            self._drain(0)
                            self._finish_sessions()
                            bar.update(pending)
                            self.skips.warn_rest()
                            self._warn_more_restarts()
            finally:
                try:
                    # Interrupted or failed: what was read is said still, not the unfinished
                    # analyses.
                    said_last = [
                        r for item in self.queue if isinstance(item, _Said) for r in item.records
                    ]
                    said_last += self.said_while_reading
                    self.said_while_reading = []
                    say_held(said_last)
                # Saying may fail too (a program's filter, a second Ctrl-C): the threads end.
                finally:
                    with signals_deferred(second_ends=True):  # while the threads finish: as above
                        pool.shutdown(wait=True, cancel_futures=True)
                        detection.shutdown(wait=True, cancel_futures=True)
                    bar.close()

    def _warn_more_restarts(self) -> None:
        """One line per topic for the break detector's restarts past the first few warned, and
        in Rerun one event at the first of them counting them all."""
        for topic, restarts in self.restarts.items():
            if restarts > WARN_FIRST:
                more = restarts - WARN_FIRST
                _LOG.warning(
                    "%s: %d more maps not comparable with their trusted snapshot: the break "
                    "detector started again from each",
                    topic,
                    more,
                )
                if self.rerun is not None and topic in self.unshown_restart:
                    snapshot, index, verdict = self.unshown_restart[topic]
                    maps = "1 more map" if more == 1 else f"{more} more maps"
                    text = (
                        f"break detector restarted at {maps} from here (here: "
                        f"{verdict.incomparable_why}): a break across a change is not seen"
                    )
                    self.rerun.event(snapshot, text, index, None)

    def _is_map(self, channel: Channel) -> bool:
        return channel.topic in self.map_topics and channel.msgtype == MAP_TYPE

    def _step(self, message: RawMessage) -> None:
        """Copy ``message``, start the analysis of the snapshot it makes, write what is ready."""
        channel = message.channel
        self.latest_ns = max(self.latest_ns, message.log_time_ns)
        self.read += 1
        self._copy(message)
        if self._is_map(channel):
            self._on_map(message.data, channel, message.log_time_ns)
        elif channel.topic in self.updates:
            self._on_update(message.data, channel, message.log_time_ns)
        elif channel.topic in self.orphans:
            self.skips.add(
                "updates of no known map",
                f"{channel.topic}: grid update {self._at(message.log_time_ns)} whose map "
                "cannot be told (<map>_updates whose map is not in the log, or another "
                "name and several map topics)",
                at_ns=message.log_time_ns,
                read=self.read,
            )
        self._queue_said()
        # Most messages find the queue empty, or its head an analysis still running: no context
        # to enter, 36,000 times an hour.
        if self.queue and self._drains(self.in_flight_limit):
            with said_at_once():  # the snapshots' outputs are said in their turn
                self._drain(self.in_flight_limit)

    def _queue_said(self) -> None:
        """What was said while reading, held: said now if no snapshot before it waits, else
        queued behind them (said in log order whatever the analyses' timing)."""
        if not self.said_while_reading:
            return
        records = tuple(self.said_while_reading)
        self.said_while_reading.clear()
        if self.queue:
            self.queue.append(_Said(records))
        else:
            say_held(records)

    def _copy(self, message: RawMessage) -> None:
        """Copy ``message`` to the output log, after the results of every snapshot before it
        (unless its channel is one of ours being written anew: no handle)."""
        handle = self.handles.get(message.channel.id)
        if self.writer is None or handle is None:
            return
        # Held until the analyses before it are written (the output's order never depends on
        # timing): then a copy of its data, which the reader's buffer does not outlive.
        held = bool(self.queue)
        item = _Copy(
            handle,
            message.log_time_ns,
            bytes(message.data) if held else message.data,
            message.publish_time_ns,
            message.sequence,
        )
        if held:
            self.queue.append(item)
            self.held_bytes += len(item.data) + _HELD_ITEM_BYTES
        else:
            self._write(item)

    def _write(self, item: _Copy) -> None:
        assert self.writer is not None
        self.writer.write_raw(
            item.handle,
            item.log_time_ns,
            item.data,
            publish_time_ns=item.publish_time_ns,
            sequence=item.sequence,
        )

    def _drains(self, limit: int) -> bool:
        """Whether :meth:`_drain` takes the queue's head now (a held message or what was said,
        or an analysis done or waited for), else it stops."""
        head = self.queue[0]
        return (
            not isinstance(head, _Pending)
            or self.in_flight > limit
            or self.held_bytes > _MAX_HELD_BYTES  # memory: wait for the analysis
            or head.future.done()
        )

    def _drain(self, limit: int) -> None:
        """Write what is ready, in log order; wait for analyses while more than ``limit`` are out,
        or while the messages held behind them exceed :data:`_MAX_HELD_BYTES`."""
        while self.queue:
            head = self.queue[0]
            if isinstance(head, _Copy):
                self._write(head)
                self.held_bytes -= len(head.data) + _HELD_ITEM_BYTES
            elif isinstance(head, _Said):
                # Out of the queue first: saying may fail part way (a program's filter raising, a
                # second Ctrl-C), and what the queue still holds is said again as the run ends.
                self.queue.popleft()
                say_held(head.records)
                continue
            elif self._drains(limit):
                self.in_flight -= 1
                self._finish(head)
            else:
                return
            self.queue.popleft()

    def _at(self, log_time_ns: int) -> str:
        """When a message was logged, as people and tools read it: session time and log time."""
        return f"at +{(log_time_ns - self.reader.start_ns) / 1e9:.1f} s ({log_time_ns} ns)"

    @property
    def skipped(self) -> int:
        """Map messages copied unprocessed."""
        return self.skips.total

    def _encoding(self, channel: Channel) -> str:
        """How ``channel``'s messages are serialised: its own encoding (an MCAP file may mix ROS 1
        and ROS 2 channels, on one topic too: a merged recording), else the log's."""
        encoding = channel.message_encoding
        return encoding if encoding in {"ros1", "cdr"} else self.serialization

    def _on_map(self, data: bytes | memoryview, channel: Channel, log_time_ns: int) -> None:
        topic = channel.topic
        try:
            check_log_time(topic, log_time_ns)
            snapshot = decode_map(
                data,
                serialization=self._encoding(channel),
                topic=topic,
                log_time_ns=log_time_ns,
            )
        except MapMessageError as err:
            # An empty map is a valid message with nothing to analyse, not a malformed one.
            reason = "empty" if isinstance(err, EmptyMapError) else "malformed"
            self.skips.add(
                reason,
                f"{short(err, 240)} {self._at(log_time_ns)}",
                at_ns=log_time_ns,
                read=self.read,
            )
            # The updates after it patch it, not the map before it: they are skipped too (one
            # was applied to the earlier map, a snapshot the robot never had).
            self.last_map.pop(topic, None)
            self.lost_map[topic] = reason
            return
        self.last_map[topic] = snapshot
        self.lost_map.pop(topic, None)
        self._note_out_of_range(topic, snapshot.out_of_range_cells, log_time_ns)
        tilt = quaternion_tilt(snapshot.origin_orientation_xyzw)
        if tilt > _FLAT_TILT_RAD:
            self._warn_once(
                topic,
                "tilted",
                f"{topic}: the map's origin is tilted {math.degrees(tilt):.1f}° out of the x-y "
                f"plane {self._at(log_time_ns)}; its grid is taken as lying in that plane, turned "
                "by the origin's yaw (as Nav2 takes it); said once per topic",
            )
        self._analyse(snapshot, from_update=False)

    def _note_out_of_range(self, topic: str, cells: int, log_time_ns: int) -> None:
        """Say once per topic that cells outside -1..100 were read as occupied."""
        if cells:
            self._warn_once(
                topic,
                "out of range",
                f"{topic}: {cells} cell(s) outside -1..100 in the map {self._at(log_time_ns)}, "
                "read as occupied (as Nav2 reads them); said once per topic",
            )

    def _warn_once(self, topic: str, what: str, text: str) -> None:
        """Log ``text`` as a warning the first time ``what`` is said of ``topic``."""
        if (topic, what) not in self.said:
            self.said.add((topic, what))
            _LOG.warning("%s", text)

    def _on_update(self, data: bytes | memoryview, channel: Channel, log_time_ns: int) -> None:
        topic = channel.topic
        target = self.updates[topic]
        try:
            check_log_time(topic, log_time_ns)
            update = decode_update(
                data,
                serialization=self._encoding(channel),
                topic=topic,
                log_time_ns=log_time_ns,
            )
            base = self.last_map.get(target)
            if base is None and target in self.lost_map:
                lost = self.lost_map[target]
                article = "an" if lost == "empty" else "a"
                self.skips.add(
                    f"after {article} {lost} map",
                    f"{topic}: grid update {self._at(log_time_ns)} of {article} {lost} full map "
                    f"on {target}",
                    at_ns=log_time_ns,
                    read=self.read,
                )
                return
            if base is None:
                self.skips.add(
                    "before the first full map",
                    f"{topic}: grid update {self._at(log_time_ns)} before the first full map on "
                    f"{target}",
                    at_ns=log_time_ns,
                    read=self.read,
                )
                return
            snapshot = apply_update(base, update)
        except (MapMessageError, ValueError) as err:
            self.skips.add(
                "malformed",
                f"{short(err, 240)} {self._at(log_time_ns)}",
                at_ns=log_time_ns,
                read=self.read,
            )
            return
        self.last_map[target] = snapshot
        self._note_out_of_range(target, snapshot.out_of_range_cells, log_time_ns)
        self._analyse(snapshot, from_update=True)

    def _analyse(self, snapshot: MapSnapshot, *, from_update: bool) -> None:
        """Start the analysis of ``snapshot``; :meth:`_finish` takes its result, in order."""
        topic = snapshot.topic
        too_large = check_cells(*snapshot.shape, self.max_cells)
        if too_large is not None:
            # An update names its own message: the map it patches came earlier.
            what = "map updated by a grid update" if from_update else "map"
            self.skips.add(
                "over --max-cells",
                f"{topic}: {what} of {too_large} {self._at(snapshot.log_time_ns)}",
                at_ns=snapshot.log_time_ns,
                read=self.read,
            )
            return
        assert self.executor is not None and self.detection is not None, "called inside run()"
        future, reused = self.analyser.submit(snapshot, self.executor)
        previous = self.last_analysis.get(topic)
        self.last_analysis[topic] = future
        verdict = self.detection.submit(self._detect, snapshot, previous)
        self._queue_said()  # what was said of the message before its analysis's outputs
        self.queue.append(_Pending(snapshot, from_update, reused, future, verdict, self.read))
        self.in_flight += 1

    def _detect(
        self, snapshot: MapSnapshot, previous: Future[SnapshotAnalysis] | None
    ) -> tuple[BreakScore, tuple[logging.LogRecord, ...]]:
        """The break detector's verdict on a snapshot, scored while it is analysed.

        The detector must see the analysed snapshots only (its numbering is the records'). Waiting
        for a snapshot's own analysis put the two in series, and the session waited for both: so
        each snapshot is scored at once, and withdrawn by the next one of its topic if its
        analysis failed (``previous``: the analysis of the topic's snapshot before, None for the
        first). The verdict of a snapshot whose analysis fails is never read. What the detector
        logs meanwhile is returned with it (with its error if it fails), to be said in log order.
        """

        def score() -> BreakScore:
            if previous is not None and previous.exception() is not None:  # waits for it
                self.detector.withdraw_last(snapshot.topic)
            return self.detector.update(snapshot)

        return call_held(score)

    def _finish(self, pending: _Pending) -> None:
        """Outputs of one analysed snapshot: derived messages, break detection, Rerun, the record."""
        snapshot = pending.snapshot
        topic = snapshot.topic
        # What the analysis and the break detector said on their threads, said now: in log order,
        # the same from run to run (a reused analysis said its own with the snapshot it was made for).
        # Through an error too (the session then fails with it, or skips a map not analysable).
        if not pending.reused:
            error = pending.future.exception()
            say_held(
                pending.future.result().log_records if error is None else held_by(error), topic
            )
        # A snapshot whose analysis fails is no snapshot of the session: its verdict is not read
        # (the next one of its topic withdraws it), but what the detector said of it is.
        failed = pending.verdict.exception()
        say_held(pending.verdict.result()[1] if failed is None else held_by(failed), topic)
        try:
            analysis = pending.future.result()
        except rose.RoseError as err:  # e.g. a map too thin to analyse
            self.skips.add(
                "not analysable",
                f"{topic}: map {self._at(snapshot.log_time_ns)} not analysed ({err})",
                at_ns=snapshot.log_time_ns,
                read=pending.read,
            )
            return
        # Numbered among the analysed snapshots, as the break detector (which has seen this one)
        # numbers them: its trusted index and the records' must name the same snapshot.
        index = self.analysed.get(topic, 0)
        self.analysed[topic] = index + 1
        verdict = pending.verdict.result()[0]
        if verdict.incomparable_with is not None:
            # Two publishers of one topic at other cell sizes or frames restart it at every map:
            # the first few said, the rest counted (a one-hour session said it 3,600 times).
            restarts = self.restarts.get(topic, 0) + 1
            self.restarts[topic] = restarts
            if restarts <= WARN_FIRST:
                _LOG.warning(
                    "%s: the map %s is not comparable with trusted snapshot %d (%s): the break "
                    "detector starts again from it, and a break across the change is not seen",
                    topic,
                    self._at(snapshot.log_time_ns),
                    verdict.incomparable_with,
                    verdict.incomparable_why,
                )
        returned = returned_text(verdict)
        if returned is not None:
            # A broken topic coming back is the end of its break; otherwise a drift the detector
            # had not flagged was undone: worth a warning.
            level = logging.INFO if self.broken.get(topic, False) else logging.WARNING
            _LOG.log(level, "%s: the map %s %s", topic, self._at(snapshot.log_time_ns), returned)
        # From here: the time spent on this snapshot's outputs. Not before, where the wait for the
        # analysis would count its compute time twice (the record's seconds exceeded the run's).
        t0 = time.perf_counter()
        # A snapshot whose results cannot be written to the output log (counted as skipped) is
        # still analysed: its record, Rerun and break events stay, so every gate sees it.
        self._write_results(snapshot, analysis, pending.read)
        record = snapshot_record(
            snapshot,
            analysis,
            index,
            verdict,
            reused=pending.reused,
            from_update=pending.from_update,
        )
        if self.rerun is not None:
            self._show_in_rerun(
                self.rerun,
                snapshot,
                analysis,
                index,
                verdict,
                judged=record.judged,
                returned=returned,
            )
        self._report_breaks(snapshot, analysis.result, index, verdict, judged=record.judged)
        self.broken[topic] = verdict.broken
        compute_s = 0.0 if pending.reused else analysis.seconds
        record = dataclasses.replace(record, seconds=compute_s + time.perf_counter() - t0)
        self.records.append(record)
        if self.on_snapshot is not None:
            self.on_snapshot(snapshot, analysis.result, record)

    def _show_in_rerun(
        self,
        rerun: RerunSink,
        snapshot: MapSnapshot,
        analysis: SnapshotAnalysis,
        index: int,
        verdict: BreakScore,
        *,
        judged: bool,
        returned: str | None,
    ) -> None:
        """An analysed snapshot in the Rerun recording: its streams, the break detector's score,
        and as events a restart of the detector and a return to an earlier map (``returned``)."""
        rerun.snapshot(
            snapshot, analysis.result, index, analysis.walls, analysis.cleaning, judged=judged
        )
        rerun.break_score(snapshot, verdict, index, self._threshold_in_force(verdict))
        if verdict.incomparable_with is not None:
            # In the viewer too: the break score falls to 0 there, which read as a recovery. The
            # first few as the log's warnings (_finish counted this one); the rest in one event
            # at the end of the session (a restart at every map made 3,600 events in an hour).
            # Short enough for the events view, which cuts a line (at about 140 characters).
            restarts = self.restarts[snapshot.topic]
            if restarts <= WARN_FIRST:
                restart = (
                    f"break detector restarted ({verdict.incomparable_why}; trusted snapshot "
                    f"{verdict.incomparable_with}): a break across the change is not seen"
                )
                rerun.event(snapshot, restart, index, None)
            elif restarts == WARN_FIRST + 1:
                self.unshown_restart[snapshot.topic] = (snapshot, index, verdict)
        if returned is not None:
            rerun.event(snapshot, returned, index, None)

    def _finish_sessions(self) -> None:
        """At the end of the log, each topic's last snapshot compared with the break detector's
        anchor when the schedule had not (:meth:`BreakDetector.finish`: a session of fewer than
        eight snapshots within 10 s never was). A break found then is reported as any other (the
        log line, the event in Rerun, the report's breaks and gates) and the snapshot's record
        and Rerun break score say it. The output log holds no break; ``on_snapshot`` had that
        snapshot's record before."""
        # The verdict of a snapshot whose analysis failed is never read (_finish): the detector
        # thread may still be scoring it. Wait for it before using the detector here.
        assert self.detection is not None, "called inside run()"
        self.detection.submit(lambda: None).result()
        for topic, last in self.last_analysis.items():
            if last.exception() is not None:  # no snapshot of the session (see _detect)
                self.detector.withdraw_last(topic)
            found = self.detector.finish(topic)
            if found is None:
                continue
            index, snapshot, verdict = found
            # Its record: the topic's last (the detector numbers the analysed snapshots).
            at = next(
                (k for k in range(len(self.records) - 1, -1, -1) if self.records[k].topic == topic),
                None,
            )
            if at is None or self.records[at].index != index:
                continue
            record = self.records[at]
            self.records[at] = dataclasses.replace(
                record,
                break_score_m=verdict.score_m,
                break_region_m=verdict.region_m,
                break_detected=True,
            )
            if self.rerun is not None:
                self.rerun.break_score(snapshot, verdict, index, self._threshold_in_force(verdict))
            self._say_break(
                snapshot, index, verdict, record.structure_score if record.judged else None
            )
            self.broken[topic] = True

    def _write_results(self, snapshot: MapSnapshot, analysis: SnapshotAnalysis, read: int) -> None:
        """The derived messages of a snapshot into the output log; none (a skip) if one cannot be
        encoded (all three are encoded before any is written). ``read``: the place of its message
        in the reading."""
        if self.writer is None:
            return
        result, t, ser = analysis.result, snapshot.log_time_ns, self.serialization
        cleaned = analysis.cleaning.cleaned if analysis.cleaning else result.cleaned
        try:
            encoded = (
                encode_cleaned(snapshot, cleaned, serialization=ser),
                encode_score(float(result.structure_score), serialization=ser),
                encode_walls(snapshot, result, analysis.walls, serialization=ser),
            )
        except (struct.error, OverflowError, ValueError, TypeError) as err:
            self.skips.add(
                "not encodable",
                f"{snapshot.topic}: cannot encode the results ({err}) {self._at(t)}",
                at_ns=t,
                read=read,
            )
            return
        for handle, data in zip(self.derived[snapshot.topic], encoded, strict=True):
            self.writer.write_raw(handle, t, data)

    def _report_breaks(
        self,
        snapshot: MapSnapshot,
        result: RoseResult,
        index: int,
        verdict: BreakScore,
        *,
        judged: bool,
    ) -> None:
        """The detector's break starts and W's crossings of the failure level: events and logs.
        ``judged``: whether W says something about the snapshot (else neither a crossing nor a
        break's marker on the W plot, where a solid block's W = 0.009 read as a fine map)."""
        topic, score = snapshot.topic, float(result.structure_score)
        if verdict.started:
            self._say_break(snapshot, index, verdict, score if judged else None)
        if not judged:  # an empty map's W = 1, a solid block's 0.009: they say nothing
            return
        above = score > self.failure_level
        if above and not self.w_above.get(topic, False):
            w, level = score_beside_level(score, self.failure_level)
            detail = f"W = {w} rose above the failure level {level} at snapshot {index}"
            text = f"{topic}: {detail}"
            self.breaks.append(BreakEvent(topic, index, snapshot.log_time_ns, score, text))
            if self.rerun is not None:
                self.rerun.event(snapshot, detail, index, score, failure=True)
        self.w_above[topic] = above

    def _threshold_in_force(self, verdict: BreakScore) -> float:
        """The threshold ``verdict`` was judged at, metres: twice the detector's against the anchor
        (a return's score may stand above the detector's own line, unbroken)."""
        return verdict.threshold_m or self.detector.params.threshold_m

    def _say_break(
        self, snapshot: MapSnapshot, index: int, verdict: BreakScore, score: float | None
    ) -> None:
        """The start of a break: the report's list (in log order), the log line, the event in
        Rerun (on the W plot at ``score``: None, W says nothing of the snapshot)."""
        event = DetectedBreak.from_score(snapshot, index, verdict, self.detector.params.threshold_m)
        # In log order: a break found at a topic's end may come before another topic's.
        at = len(self.detected)
        while at > 0 and self.detected[at - 1].log_time_ns > event.log_time_ns:
            at -= 1
        self.detected.insert(at, event)
        _LOG.info("%s", event.text)
        if self.rerun is not None:
            self.rerun.event(snapshot, event.detail, index, score)
