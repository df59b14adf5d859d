"""The Rerun side of a session: open the recording, log snapshots in a background thread, close.

:class:`RerunSink` is what :func:`rose_logs.process_log` talks to. Logging runs on its own thread
(bounded queue, so memory stays flat) while the session loop decodes and analyses the next snapshot;
Rerun encodes, compresses and writes on its own threads too. Static data is logged once when the
recording opens; the layout (:mod:`rose_logs.rerun.blueprint`) is sent when it is known: at the end of
a saved recording (so it can frame the final map and show the events view only when there are events),
and to a live viewer when the recording opens, then again at each topic's first map, whenever its
maps outgrow the views (framed with room to grow, :data:`_LIVE_MARGIN`), and at its first event (a
break, W rising above the failure level, the break detector restarting).
"""

from __future__ import annotations

import atexit
import contextlib
import contextvars
import dataclasses
import hashlib
import logging
import math
import os
import queue
import struct
import sys
import threading
import time
import uuid
import weakref
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import rerun as rr

from rose.cleaning import CleanResult
from rose.directions import FAILURE_LEVEL, TRUST_LEVEL
from rose.result import RoseResult
from rose.walls import WallSet
from rose_logs.malloc import release_free_heap
from rose_logs.rerun.blueprint import TopicLayout, default_blueprint
from rose_logs.rerun.conversions import image_window, known_bounds_cells
from rose_logs.rerun.loggers import TopicLogger, cells_to_map_m, set_snapshot_time, view_origin_m
from rose_logs.rerun.paths import EntityPaths, entity_root_for_topic
from rose_logs.rerun.viewer import (
    SPAWNED_VIEWER,
    ViewerLost,
    ViewerNotStarted,
    grpc_url,
    viewer_unreachable,
)
from rose_logs.session.analysis import same_placed_grid
from rose_logs.session.breaks import BreakScore
from rose_logs.session.report import w_judges
from rose_logs.snapshots import MapSnapshot
from rose_logs.storage.records import read_at

__all__ = ["APPLICATION_ID", "RerunSink", "recording_id_for"]

_LOG = logging.getLogger(__name__)

APPLICATION_ID = "rose_bag"
_QUEUE_DEPTH = 2
#: The logging thread looks at its queue at least this often, seconds (see RerunSink._work).
_WAKE_S = 0.25
#: How long abort() waits for the logging thread, seconds.
_ABORT_WAIT_S = 10.0
_FLUSH_NUM_BYTES = 64 * 1024
"""Rerun's batcher flushes a chunk at this many bytes (its default is 2 MiB). A snapshot logs up to
1 MB of images, so Rerun's default held several snapshots' data at once: on the one-hour benchmark
session the peak memory went 425 -> 386 MB at 256 kB (a 4 % larger recording, 96.5 -> 100.2 MB),
and 321-329 -> 305-311 MB at 64 kB (3 runs each; recording 94.8 -> 97.0 MB; 2 and 8 MiB: 346-378
MB). ``RERUN_FLUSH_NUM_BYTES`` in the environment still wins."""
_FLUSH_STEP_S = 5.0
"""Longest wait for one flush of the recording, seconds (see :meth:`RerunSink._flush`)."""
_STALL_STEPS = 2
"""Flush waits in a row without the ``.rrd`` growing after which writing counts as stalled."""
_STALLED: list[rr.RecordingStream] = []
"""Recordings whose file writer died (a full disk): releasing one blocks forever inside Rerun."""
_IDENTITY_BYTES = 1 << 20


def _keep_stalled(recording: rr.RecordingStream) -> None:
    """Never release ``recording``, and end the process without releasing it.

    Rerun 0.41 flushes a recording's sinks, without a timeout, when the last reference goes away; with
    its file writer dead that wait never ends. So the recording stays referenced, and at exit the
    process leaves before interpreter teardown would drop it (exit status 1: a write failed).
    """
    if not _STALLED:
        atexit.register(_exit_without_release)
    _STALLED.append(recording)


def _exit_without_release() -> None:
    # Registered after `import rerun`, so it runs before Rerun's own exit hooks (atexit is LIFO).
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
    os._exit(1)


def recording_id_for(input_path: Path) -> str:
    """A recording id that names this input: its absolute path and its content's identity.

    The identity is the size and a SHA-256 of the first and last MiB of every file (a ROS 2 bag folder:
    of each file in it, by relative name), so the same log gives the same id wherever it is read from
    the same place, and a different log at the same path (re-recorded, edited) a different one.
    """
    path = Path(input_path).resolve()
    # os.fsencode: file names need not be UTF-8 (the same bytes as str.encode for those that are).
    digest = hashlib.sha256(os.fsencode(path))
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for file in files:
        size = file.stat().st_size
        name = os.fsencode(file.relative_to(path)) if path.is_dir() else b""
        digest.update(b"\0" + name + f"\0{size}\0".encode())
        with file.open("rb") as handle:
            digest.update(handle.read(_IDENTITY_BYTES))
            if size > _IDENTITY_BYTES:
                handle.seek(max(size - _IDENTITY_BYTES, _IDENTITY_BYTES))
                digest.update(handle.read(_IDENTITY_BYTES))
    return str(uuid.UUID(bytes=digest.digest()[:16], version=5))


def _top(*values: float) -> float:
    """The largest finite value of ``values`` (0.0 without any)."""
    return max((v for v in values if math.isfinite(v)), default=0.0)


Box = tuple[float, float, float, float]
"""``(x_min, y_min, x_max, y_max)`` in map-frame metres."""


def known_box_m(snapshot: MapSnapshot, known: tuple[int, int, int, int] | None) -> Box | None:
    """The map-frame box around ``snapshot``'s known cells ``known`` (cells, exclusive max, from
    :func:`~rose_logs.rerun.conversions.known_bounds_cells`); None when nothing is known."""
    if known is None:
        return None
    x0, y0, x1, y1 = known
    corners = cells_to_map_m(snapshot, np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]], float))
    return (
        float(corners[:, 0].min()),
        float(corners[:, 1].min()),
        float(corners[:, 0].max()),
        float(corners[:, 1].max()),
    )


#: Seconds beyond the session's span that the plots of a topic at one time show either side of
#: the time cursor.
_ONE_TIME_MARGIN_S = 10.0


def _union(a: Box | None, b: Box | None) -> Box | None:
    if a is None or b is None:
        return a or b
    return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))


#: A live viewer's views frame the known part of the maps this much wider on every side (times its
#: larger side): a growing SLAM map ran out of the views, which were framed on its first map only,
#: and re-sending the layout resets what a user zoomed or panned, so it is re-sent only when the
#: maps outgrow that frame (a map growing from 5 m to 50 m: about 6 times).
_LIVE_MARGIN = 0.25


def _contains(outer: Box | None, inner: Box | None) -> bool:
    """Whether ``inner`` lies inside ``outer`` (a missing ``inner`` does; a missing ``outer`` holds
    nothing)."""
    if inner is None:
        return True
    if outer is None:
        return False
    return (
        outer[0] <= inner[0]
        and outer[1] <= inner[1]
        and inner[2] <= outer[2]
        and inner[3] <= outer[3]
    )


def _widened(box: Box | None, margin: float) -> Box | None:
    """``box`` with ``margin`` times its larger side added on every side (square boxes of a
    one-cell map stay small but not empty)."""
    if box is None:
        return None
    pad = margin * max(box[2] - box[0], box[3] - box[1])
    return (box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad)


def _layout_of(
    root: str,
    bounds_m: Box | None,
    *,
    has_events: bool,
    view_origin: tuple[float, float] | None,
    has_walls: bool = False,
    walls_cleaning: bool = True,
    height_m: float = 0.0,
) -> TopicLayout:
    """Layout of a topic framed on ``bounds_m``, the known part of every map of the session so far
    (``view_origin``: the 2D views' 0, see :func:`rose_logs.rerun.loggers.view_origin_m`;
    ``height_m``: the maps' height in the map frame, their first origin's z, metres)."""
    if bounds_m is None:
        return TopicLayout(
            root, has_events=has_events, has_walls=has_walls, walls_cleaning=walls_cleaning
        )
    return TopicLayout(
        root,
        bounds_m=bounds_m,
        view_origin_m=view_origin if view_origin is not None else (0.0, 0.0),
        height_m=height_m,
        has_events=has_events,
        has_walls=has_walls,
        walls_cleaning=walls_cleaning,
    )


class _RecordingStream(rr.RecordingStream):
    """Rerun's recording stream, whose finaliser skips a stream that never got its native recording.

    Rerun's ``__del__`` reads ``self.inner``: when the native side fails to start (no thread left
    for its batcher under ``ulimit -v``), the error's one line was followed by Rerun's "Exception
    ignored in RecordingStream.__del__ ... AttributeError: ... no attribute 'inner'" traceback."""

    def __del__(self) -> None:
        if "inner" in self.__dict__:
            super().__del__()


def _batcher_config() -> rr.ChunkBatcherConfig:
    """Rerun's batching thresholds from the environment, with a smaller flush size unless set."""
    if "RERUN_FLUSH_NUM_BYTES" in os.environ:
        return rr.ChunkBatcherConfig()
    return rr.ChunkBatcherConfig(flush_num_bytes=_FLUSH_NUM_BYTES)


class RerunSink:
    """A Rerun recording of one session: a saved ``.rrd`` and/or a live viewer.

    Parameters
    ----------
    rrd_path : Path or None
        Save here (written to a temporary name beside it, renamed by :meth:`close`).
    spawn : bool
        Start a Rerun viewer (``rerun`` on ``PATH``) and stream to it.
    connect : str or None
        Stream to a running viewer at this address (see :func:`~rose_logs.rerun.viewer.grpc_url`).
    topics : sequence of str
        Map topics of the session (one entity root each).
    recording_id : str
        Rerun recording id (see :func:`recording_id_for`).
    start_ns : int
        Log time of the session's first message: 0 of the ``session_time`` timeline.
    failure_level, trust_level : float
        Levels drawn on the W plot.
    threaded : bool
        Log on a background thread (default); False logs in the caller's thread.

    Raises
    ------
    ValueError
        If no destination is given or ``rrd_path``'s directory does not exist.
    ViewerNotStarted
        With ``spawn``, if the viewer started is not listening (it could not open a window).
    """

    def __init__(
        self,
        *,
        rrd_path: Path | None,
        spawn: bool = False,
        connect: str | None = None,
        topics: Sequence[str],
        recording_id: str,
        start_ns: int,
        failure_level: float = FAILURE_LEVEL,
        trust_level: float = TRUST_LEVEL,
        threaded: bool = True,
    ) -> None:
        if rrd_path is None and not spawn and connect is None:
            msg = "a Rerun recording needs rrd_path, spawn or connect, got none"
            raise ValueError(msg)
        if rrd_path is not None and not Path(rrd_path).parent.is_dir():
            msg = f"cannot write Rerun recording {rrd_path}: directory {Path(rrd_path).parent} does not exist"
            raise ValueError(msg)
        self.rrd_path: Path | None = None
        self.tmp: Path | None = None
        if rrd_path is not None:
            self.rrd_path = Path(rrd_path)
            self.tmp = self.rrd_path.with_name(f".{self.rrd_path.name}.rose-tmp")
        self.live = spawn or connect is not None
        self.start_ns = int(start_ns)
        self.recording = _RecordingStream(
            APPLICATION_ID, recording_id=recording_id, batcher_config=_batcher_config()
        )
        self.recording.set_log_time_enabled(False)
        if spawn:
            self.recording.spawn(connect=False)
            # Rerun's spawn waits a few seconds for its viewer, then only warns: a viewer that died
            # at start (a display set but unusable) failed the session at its final flush.
            reason = viewer_unreachable(SPAWNED_VIEWER)
            if reason is not None:
                msg = (
                    f"the Rerun viewer did not start (nothing listens at {SPAWNED_VIEWER}: "
                    f"{reason}; its own message above says why)"
                )
                raise ViewerNotStarted(msg)
        sinks: list[rr.FileSink | rr.GrpcSink] = []
        if self.tmp is not None:
            # No footer: Rerun 0.41 keeps every chunk's entry of its index (the footer) in memory
            # until the end, about 25 kB per snapshot (18 MB of the one-hour session's peak, 44
            # MB at two hours): the session's memory would grow with its length.
            sinks.append(rr.FileSink(str(self.tmp), write_footer=False))
        if spawn:
            sinks.append(rr.GrpcSink())
        if connect is not None:
            sinks.append(rr.GrpcSink(grpc_url(connect)))
        self._error: BaseException | None = None
        self._queue: queue.Queue[Callable[[], None] | None] | None = None
        self._thread: threading.Thread | None = None
        self._flush_failed = False
        self._aborted = False
        self.loggers = {
            topic: TopicLogger(
                self.recording,
                EntityPaths(entity_root_for_topic(topic)),
                failure_level=failure_level,
                trust_level=trust_level,
                live=self.live,
            )
            for topic in topics
        }
        self._latest: dict[str, MapSnapshot] = {}
        # Per topic, its first map's origin z (metres): where the metric view looks.
        self._height_m: dict[str, float] = dict.fromkeys(topics, 0.0)
        # Per topic, what its last snapshot showed (result, walls, cleaning), held weakly: an
        # analysis reused for an unchanged map is the same objects (see RerunSink.snapshot).
        self._shown: dict[str, tuple[weakref.ref[object] | None, ...]] = {}
        # Per topic: log time of its last fully logged snapshot, and the latest of any.
        self._full_at: dict[str, tuple[int, int]] = {}
        # Per topic: the first and last log time of any of its snapshots (the plots' time range).
        self._span_ns: dict[str, tuple[int, int]] = {}
        # Known part of every map so far, per topic: the views frame them all, so that scrubbing
        # back over a map that moved (a new origin) does not show an empty view.
        self._bounds_m: dict[str, Box | None] = dict.fromkeys(topics)
        # The grids' whole boxes: framed only while no map of the topic knows a cell.
        self._grid_bounds_m: dict[str, Box | None] = dict.fromkeys(topics)
        self._closing = False
        self._has_events: dict[str, bool] = dict.fromkeys(topics, False)
        # Whether a snapshot of the topic came with wall segments (--walls): the layout names them.
        self._has_walls: dict[str, bool] = dict.fromkeys(topics, False)
        # Whether the topic's last cleaning was the walls rules' (the paper's draws no walls).
        self._walls_cleaning: dict[str, bool] = dict.fromkeys(topics, True)
        # Highest value each topic's W / break-score plot shows, guide lines included (final layout).
        # Both guide lines in view: a --failure-level under the trust level cut the trust off.
        self._w_top: dict[str, float] = dict.fromkeys(topics, max(failure_level, trust_level))
        self._break_top: dict[str, float] = dict.fromkeys(topics, 0.0)
        # Live: what the views of each topic frame in the layout sent last (the known maps widened
        # by _LIVE_MARGIN); the layout is sent again once a map outgrows it.
        self._live_frame_m: dict[str, Box | None] = dict.fromkeys(topics)
        self._sent_key: tuple[tuple[str, bool, bool, bool, bool, Box | None], ...] | None = None
        try:
            self.recording.set_sinks(*sinks)
            self._start(threaded=threaded)
        except BaseException:
            # A signal or error between here and a returned sink: nobody else can abort it, and
            # Rerun's writer would create the file after any cleanup of the folder around it.
            self.abort()
            raise
        _LOG.debug(
            "opened Rerun recording (rrd=%s, spawn=%s, connect=%s)", rrd_path, spawn, connect
        )

    def _start(self, *, threaded: bool) -> None:
        """The static data, the first layout (live) and the logging thread."""
        for logger in self.loggers.values():
            logger.log_static()
        if self.live:
            self._send_blueprint()
        if threaded:
            self._queue = queue.Queue(maxsize=_QUEUE_DEPTH)
            # In the caller's context, like the session's other threads (see process_log).
            self._thread = threading.Thread(
                target=contextvars.copy_context().run,
                args=(self._work, self._queue),
                name="rose-rerun",
                daemon=True,
            )
            self._thread.start()

    # -- worker ------------------------------------------------------------------------------

    def _work(self, jobs: queue.Queue[Callable[[], None] | None]) -> None:
        while not self._aborted:  # abort(): the queued snapshots are not wanted
            try:
                # Not an endless wait: a Ctrl-C that lands inside the session thread's put, in
                # Condition.notify between its waking a waiter and its forgetting it, leaves that
                # waiter behind (CPython 3.11), and the next put wakes it instead of this thread,
                # which slept beside the queued end of the work while abort() waited for it.
                job = jobs.get(timeout=_WAKE_S)
            except queue.Empty:
                continue
            try:
                if job is None:
                    return
                if self._error is None and not self._aborted:
                    job()
            except BaseException as err:  # handed to the session thread by _check
                self._error = err
            finally:
                jobs.task_done()

    def _submit(self, job: Callable[[], None]) -> None:
        self._check()
        if self._queue is None:
            job()
        else:
            self._queue.put(job)

    def _check(self) -> None:
        if self._error is not None:
            err, self._error = self._error, None
            msg = f"Rerun logging failed: {err}"
            raise RuntimeError(msg) from err

    # -- session interface ---------------------------------------------------------------------

    def snapshot(
        self,
        snapshot: MapSnapshot,
        result: RoseResult,
        index: int,
        walls: WallSet | None,
        cleaning: CleanResult | None = None,
        *,
        judged: bool | None = None,
    ) -> None:
        """Log every stream of an analysed snapshot (at its log time); ``cleaning``: its cleaning,
        shown in the segmentation; ``judged``: whether W says something about it (default: enough
        occupied cells). A snapshot with the topic's last grid, placed alike, shown with the very
        same ``result``, ``walls`` and ``cleaning`` (an analysis reused for an unchanged map) and
        no earlier in log time than any map of the topic logged before adds its W only: the views
        show the latest images, which are the same."""
        topic_logger = self.loggers[snapshot.topic]
        previous = self._latest.get(snapshot.topic)
        first = previous is None
        if first:  # here, not on the logging thread: the layout sent below uses it
            topic_logger.view_origin_m = view_origin_m(snapshot)
            self._height_m[snapshot.topic] = float(snapshot.origin_position_m[2])
        self._latest[snapshot.topic] = snapshot
        if walls is not None:
            self._has_walls[snapshot.topic] = True
        if cleaning is not None:
            self._walls_cleaning[snapshot.topic] = cleaning.method == "walls"
        t = snapshot.log_time_ns
        span = self._span_ns.get(snapshot.topic, (t, t))
        self._span_ns[snapshot.topic] = (min(span[0], t), max(span[1], t))
        if judged is None:
            judged = w_judges(result.occupied_count)
        shown_again = self._shows_again(snapshot.topic, (result, walls, cleaning))
        full_at = self._full_at.get(snapshot.topic)
        # Latest-at on the time timelines finds the images shown again only if they are the
        # topic's latest images at or before this snapshot's log time (a salvaged bag is read in
        # file order: log times can go back).
        in_order = full_at is not None and full_at[0] == full_at[1] <= snapshot.log_time_ns
        if (
            shown_again
            and in_order
            and previous is not None
            and same_placed_grid(previous, snapshot)
        ):
            # The analysis of the topic's last snapshot, reused (its grid and placement did not
            # change): its images are in the recording, and the views show the latest of each,
            # so only W gets a point here. A robot standing still while its SLAM republishes the
            # map cost a full snapshot's logging and about 135 kB of recording per map.
            self._submit_at(
                snapshot, index, lambda: topic_logger.log_structure_score(result, judged=judged)
            )
            return
        self._full_at[snapshot.topic] = (t, t if full_at is None else max(t, full_at[1]))
        known = known_bounds_cells(snapshot.grid)
        window = known or image_window(snapshot.grid)  # the whole grid when nothing is known
        self._bounds_m[snapshot.topic] = _union(
            self._bounds_m[snapshot.topic], known_box_m(snapshot, known)
        )
        rows, cols = snapshot.grid.shape
        self._grid_bounds_m[snapshot.topic] = _union(
            self._grid_bounds_m[snapshot.topic], known_box_m(snapshot, (0, 0, cols, rows))
        )
        if judged:  # an empty map's W (1 by convention) is not plotted
            self._w_top[snapshot.topic] = _top(self._w_top[snapshot.topic], result.structure_score)

        self._submit_at(
            snapshot,
            index,
            lambda: topic_logger.log_snapshot(
                snapshot, result, walls, cleaning, window=window, judged=judged
            ),
        )
        framed = self._framed_m(snapshot.topic)
        if self.live and not _contains(self._live_frame_m[snapshot.topic], framed):
            # The topic's first map, or a map grown out of the views: frame it, with room to grow.
            self._live_frame_m[snapshot.topic] = _widened(framed, _LIVE_MARGIN)
            self._send_blueprint()

    def _submit_at(self, snapshot: MapSnapshot, index: int, log: Callable[[], None]) -> None:
        """Run ``log`` on the logging thread, the recording's time put at ``snapshot`` first."""

        def job() -> None:
            set_snapshot_time(
                self.recording,
                log_time_ns=snapshot.log_time_ns,
                start_ns=self.start_ns,
                index=index,
            )
            log()

        self._submit(job)

    def _shows_again(self, topic: str, shown: tuple[object, ...]) -> bool:
        """Whether ``shown`` (result, walls, cleaning) are the very objects the topic's last
        snapshot showed; remembers them (weakly: a result is not kept alive for this)."""
        before = self._shown.get(topic)
        refs = tuple(None if item is None else weakref.ref(item) for item in shown)
        self._shown[topic] = refs
        if before is None:
            return False
        return all(
            (ref is None and item is None) or (ref is not None and ref() is item)
            for ref, item in zip(before, shown, strict=True)
        )

    def break_score(
        self, snapshot: MapSnapshot, verdict: BreakScore, index: int, threshold_m: float
    ) -> None:
        """Log the break detector's verdict on ``snapshot`` (score, threshold, region)."""
        topic_logger = self.loggers[snapshot.topic]
        top = _top(self._break_top[snapshot.topic], verdict.score_m, threshold_m)
        self._break_top[snapshot.topic] = top

        self._submit_at(
            snapshot, index, lambda: topic_logger.log_break_score(snapshot, verdict, threshold_m)
        )

    def event(
        self,
        snapshot: MapSnapshot,
        text: str,
        index: int,
        score: float | None,
        *,
        failure: bool = False,
    ) -> None:
        """Log an event of ``snapshot``'s topic (a break, W rising above the failure level, the
        break detector restarting): a marker on the W plot at ``score`` (None: none,
        W says nothing about the snapshot; ``failure``: W rose above the failure level, its own
        marker) and a WARN event ``text`` (without the topic: the events view is the topic's
        own)."""
        topic_logger = self.loggers[snapshot.topic]
        first = not self._has_events[snapshot.topic]
        self._has_events[snapshot.topic] = True

        self._submit_at(
            snapshot, index, lambda: topic_logger.log_break(score, text, failure=failure)
        )
        if self.live and first:
            self._send_blueprint()

    def _one_time_window_s(self, topic: str) -> float | None:
        """For a topic whose snapshots are all at one log time, its plots' window either side of
        the time cursor: the session's span of snapshot times and 10 s more, so its time is in
        view wherever the cursor is (a recording holds data at snapshot times only). None for
        any other topic."""
        span = self._span_ns.get(topic)
        if span is None or span[0] != span[1]:
            return None
        first = min(start for start, _ in self._span_ns.values())
        last = max(end for _, end in self._span_ns.values())
        return (last - first) / 1e9 + _ONE_TIME_MARGIN_S

    def _framed_m(self, topic: str) -> Box | None:
        """The map-frame box the views of ``topic`` frame: every snapshot's known cells, or the
        grids themselves in a session that knows none (an all-unknown map is still drawn)."""
        return self._bounds_m[topic] or self._grid_bounds_m[topic]

    def _send_blueprint(self) -> None:
        """Send the layout for what is known now (skipped when nothing it depends on changed)."""
        key = tuple(
            (
                topic,
                topic in self._latest,
                self._has_events[topic],
                self._has_walls[topic],
                self._walls_cleaning[topic],
                self._live_frame_m[topic],
            )
            for topic in self.loggers
        )
        if key == self._sent_key and not self._closing:
            return
        layouts = tuple(
            _layout_of(
                logger.paths.root,
                # A live viewer's views: room to grow; the final layout frames the maps exactly.
                self._framed_m(topic)
                if self._closing or not self.live
                else self._live_frame_m[topic] or self._framed_m(topic),
                has_events=self._has_events[topic],
                view_origin=logger.view_origin_m,
                has_walls=self._has_walls[topic],
                walls_cleaning=self._walls_cleaning[topic],
                height_m=self._height_m[topic],
            )
            for topic, logger in self.loggers.items()
        )
        if self._closing:  # the plots' ranges are known: leave headroom above lines and data
            layouts = tuple(
                dataclasses.replace(
                    layout,
                    w_top=self._w_top[topic],
                    break_top=self._break_top[topic] or None,
                    one_time_window_s=self._one_time_window_s(topic),
                )
                for topic, layout in zip(self.loggers, layouts, strict=True)
            )
        self.recording.send_blueprint(
            default_blueprint(layouts, live=self.live), make_active=True, make_default=True
        )
        self._sent_key = key

    def _drain(self) -> None:
        """End the logging thread after its queued jobs."""
        if self._queue is not None and self._thread is not None:
            self._queue.put(None)
            self._thread.join()
            self._queue = None

    def _flush(self) -> None:
        """Flush in bounded steps while the file grows; RuntimeError when writing stalls.

        Rerun's unbounded flush waits forever once its file writer has died (a full disk), so every
        wait has a timeout and ``_STALL_STEPS`` waits in a row without the file growing are an error.
        """
        self._flush_failed = True
        last_size, stalled = -1, 0
        while True:
            started = time.monotonic()
            try:
                self.recording.flush(timeout_sec=_FLUSH_STEP_S)
            except RuntimeError as err:
                if self._viewer_refused(time.monotonic() - started):
                    # Nothing waits on a dead writer: abort() may disconnect and release it.
                    self._flush_failed = False
                    raise ViewerLost(str(err)) from err
                size = self.written_bytes()
                stalled = stalled + 1 if size <= last_size else 0
                if stalled >= _STALL_STEPS:
                    raise
                last_size = size
                continue
            except KeyboardInterrupt:
                # A signal that came during the flush is raised once flush returned (success, not a
                # dead writer): abort() may disconnect, and the run exits 130 / 143, not 1.
                self._flush_failed = False
                raise
            self._flush_failed = False
            return

    def _viewer_refused(self, waited_s: float) -> bool:
        """Whether a flush that failed after ``waited_s`` seconds failed for the live viewer alone:
        at once (a viewer that went away refuses at once; a dead file writer, or a stalled
        viewer, only ever times out), with the recording's file, if any, whole. With ``--rrd``
        too, the viewer's failure was said to be the recording's file that could not be written."""
        if not self.live or waited_s >= _FLUSH_STEP_S / 2:
            return False
        if self.tmp is None:
            return True
        try:
            _require_whole_stream(self.tmp)
        except OSError:
            return False
        return True

    def written_bytes(self) -> int:
        """Bytes of the recording's file written so far (0 without a file or once it is gone)."""
        try:
            return 0 if self.tmp is None else self.tmp.stat().st_size
        except OSError:
            return 0

    def close(self) -> None:
        """Finish logging, send the final layout, flush, and move the ``.rrd`` into place."""
        self._drain()
        self._check()
        # The session's arrays are gone: what Rerun allocates for its last writes comes on top
        # of glibc's free heap otherwise.
        release_free_heap()
        self._closing = True  # the final layout frames every map of the session
        if not self.live:  # a live viewer placed the bar with each map
            for topic, logger in self.loggers.items():
                logger.log_final_placement(self._framed_m(topic))
        self._send_blueprint()
        self._flush()
        self.recording.disconnect()
        if self.tmp is not None and self.rrd_path is not None:
            _require_whole_stream(self.tmp)
            self.tmp.replace(self.rrd_path)

    def abort(self) -> None:
        """Stop logging and remove the temporary ``.rrd``; never raises for logging errors."""
        try:
            self._error = None
            self._aborted = True  # the logging thread ends after the job it is running, if any
            if self._thread is not None:
                # Not for ever: a job stuck in Rerun is left behind (a daemon thread).
                self._thread.join(_ABORT_WAIT_S)
            self._queue = None
            if self._flush_failed:  # disconnect or release would wait forever on the dead writer
                _keep_stalled(self.recording)
            else:
                self.recording.disconnect()
        finally:
            if self.tmp is not None:
                self.tmp.unlink(missing_ok=True)


#: How an ``.rrd`` of Rerun 0.41 starts: its stream header's magic (then 8 bytes of version and
#: options), followed by messages of a 16-byte header (kind, payload length; little-endian u64).
_STREAM_MAGIC = b"RRF2"
_STREAM_HEADER_BYTES = 12
_MESSAGE_HEADER = struct.Struct("<QQ")


def _require_whole_stream(path: Path) -> None:
    """OSError unless the file at ``path`` is a recording stream whose last message is whole.

    Rerun's file writer reports a failed write (the last ones, on a disk that just filled up)
    nowhere: the recording was cut short, the run said nothing and placed it. The messages' headers
    are walked (their payloads skipped): the last must end where the file does.
    """
    try:
        # Unbuffered reads of the headers alone (a buffered file read 8 KiB at every seek).
        with path.open("rb", buffering=0) as f:
            size = os.fstat(f.fileno()).st_size
            if read_at(f, len(_STREAM_MAGIC), 0) != _STREAM_MAGIC:
                msg = "not a Rerun recording stream (no RRF2 header)"
                raise OSError(msg)
            at = _STREAM_HEADER_BYTES
            while at < size:
                header = read_at(f, _MESSAGE_HEADER.size, at)
                if len(header) < _MESSAGE_HEADER.size:
                    break
                at += _MESSAGE_HEADER.size + _MESSAGE_HEADER.unpack(header)[1]
    except OSError as err:
        if err.errno is None:  # ours, above
            raise
        msg = f"cannot read it back ({err.strerror or err})"
        raise OSError(msg) from err
    if at != size:
        msg = f"incomplete: its last message is cut short at byte {size} (a full disk?)"
        raise OSError(msg)
