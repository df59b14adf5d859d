"""One recording of a batch: fetch, ``process_log``, store outputs and the result. No Dask here.

:func:`process_recording` is a plain function: the engine runs it in-process or as a Dask task, and
tests call it directly. It never raises for a bad recording: the result then has ``status="error"``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import socket
import statistics
import tempfile
import time
import uuid
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from rose.cleaning import CLEAN_METHODS, CleanMethod
from rose.directions import FAILURE_LEVEL
from rose.errors import OutputError, RoseError
from rose.limits import DEFAULT_MAX_CELLS, cell_limit, finite_number, integer_number
from rose.params import RoseParams
from rose_logs.batch.errors import BatchError
from rose_logs.batch.recording_log import RecordingWarnings, collecting
from rose_logs.batch.sources import Recording, cleaned_log_name, printable
from rose_logs.batch.store import OutputStore, filesystem, is_local, work_folder_prefix
from rose_logs.errors import LogError, LogWriteError, storage_failure
from rose_logs.formats import LogFormat, detect_format
from rose_logs.session.report import row_judged

if TYPE_CHECKING:  # the session package is imported when a recording is processed
    from rose_logs.session.breaks import BreakParams

__all__ = [
    "RESULTS_DIR",
    "RecordingOptions",
    "RecordingResult",
    "process_recording",
    "result_key",
]

_LOG = logging.getLogger(__name__)

#: Folder under the output root holding one JSON result per recording, named by its key.
RESULTS_DIR = "results"

Status = Literal["ok", "error"]


@dataclass(frozen=True)
class RecordingOptions:
    """What is done to every recording (the options of ``rose-bag process``).

    Attributes
    ----------
    params : RoseParams
        ROSE parameters.
    topics : tuple of str, optional
        Map topics to analyse; None: every ``nav_msgs/OccupancyGrid`` topic.
    failure_level : float
        W above which a snapshot counts as broken.
    walls : bool
        Also extract wall segments (markers in the cleaned log, lines in Rerun).
    cleaned : bool
        Write each cleaned log to ``cleaned/<name>`` (same format as the input; a salvaged
        ``x.bag.active`` as ``x.bag``).
    rrd : bool
        Write each Rerun recording to ``rrd/<name>.rrd``.
    retries : int
        How many times an ``OSError`` (network, storage) is retried before the recording fails.
    analysis_threads : int
        Snapshots of a recording analysed at once, in threads (see ``process_log``); 1 on Dask
        workers, which run one thread each while the cluster spreads the recordings.
    salvage : bool
        Keep what can be read of a damaged recording (``process --salvage``); its row is ``ok``
        and lists the ``losses``.
    clean_method : {"walls", "paper"}
        How the cleaned maps are made (``process --clean-method``).
    break_threshold_m : float, optional
        The break detector's threshold, metres of map contradicted (default: ``BreakParams``').
    max_cells : int or None
        Grids of more cells are skipped (``process --max-cells``; None: no limit).
    replace_rose_topics : bool
        A recording processed before gets its ``<map>/rose/*`` topics written anew in its cleaned
        log (``process --replace-rose-topics``); False: it fails when ``cleaned`` is set.
    """

    params: RoseParams = field(default_factory=RoseParams)
    topics: tuple[str, ...] | None = None
    failure_level: float = FAILURE_LEVEL
    walls: bool = False
    cleaned: bool = False
    rrd: bool = False
    retries: int = 2
    analysis_threads: int = 2
    salvage: bool = False
    clean_method: CleanMethod = "walls"
    break_threshold_m: float | None = None
    max_cells: int | None = DEFAULT_MAX_CELLS
    replace_rose_topics: bool = False

    def __post_init__(self) -> None:
        problems = []
        if not isinstance(self.params, RoseParams):
            problems.append(f"params must be a RoseParams, got {type(self.params).__name__}")
        if self.topics is not None and (
            isinstance(self.topics, str)
            or not isinstance(self.topics, tuple | list)
            or not all(isinstance(t, str) for t in self.topics)
        ):
            problems.append(f"topics must be a tuple of topic names or None, got {self.topics!r}")
        elif isinstance(self.topics, list):  # a tuple, as the field says: the options stay hashable
            object.__setattr__(self, "topics", tuple(self.topics))
        if not (finite_number(self.failure_level) and 0 < self.failure_level <= 1):
            problems.append(f"failure_level must be a number in (0, 1], got {self.failure_level!r}")
        for name in ("walls", "cleaned", "rrd", "salvage", "replace_rose_topics"):
            if not isinstance(getattr(self, name), bool | np.bool_):
                problems.append(f"{name} must be True or False, got {getattr(self, name)!r}")
        if not (integer_number(self.retries) and self.retries >= 0):
            problems.append(f"retries must be an integer >= 0, got {self.retries!r}")
        if not (integer_number(self.analysis_threads) and self.analysis_threads >= 1):
            problems.append(
                f"analysis_threads must be an integer >= 1, got {self.analysis_threads!r}"
            )
        if self.clean_method not in CLEAN_METHODS:
            problems.append(
                f"clean_method must be one of {', '.join(CLEAN_METHODS)}, got {self.clean_method!r}"
            )
        threshold = self.break_threshold_m  # finite: summary.json is strict JSON
        if threshold is not None and not (finite_number(threshold) and threshold > 0):
            problems.append(
                f"break_threshold_m must be a finite number > 0 or None, got {threshold!r}"
            )
        try:
            cell_limit(self.max_cells)
        except ValueError as err:
            problems.append(str(err))
        if problems:  # said before any recording is processed, not once per recording
            raise BatchError("RecordingOptions: " + "; ".join(problems))
        self._as_builtin_types()

    def _as_builtin_types(self) -> None:
        """numpy's numbers and flags as Python's (checked above): the options are written to
        strict JSON (summary.json) and hashed into the resume key, where ``np.True_`` and ``True``
        must be the same option."""
        builtin: dict[str, object] = {
            name: bool(getattr(self, name))
            for name in ("walls", "cleaned", "rrd", "salvage", "replace_rose_topics")
        }
        builtin |= {
            "failure_level": float(self.failure_level),
            "retries": int(self.retries),
            "analysis_threads": int(self.analysis_threads),
        }
        if self.break_threshold_m is not None:
            builtin["break_threshold_m"] = float(self.break_threshold_m)
        for name, value in builtin.items():
            object.__setattr__(self, name, value)

    def stated(self) -> dict[str, Any]:
        """Every option that changes a result, defaults written out (``summary.json``: a reader
        sees which break threshold and cleaning were used); :meth:`key_fields` leaves some of them
        out at their defaults to keep older results' keys."""
        from rose_logs.session.breaks import BreakParams

        threshold = self.break_threshold_m
        return {
            **self.key_fields(),
            "salvage": self.salvage,
            "replace_rose_topics": self.replace_rose_topics,
            "clean_method": self.clean_method,
            "break_threshold_m": BreakParams().threshold_m
            if threshold is None
            else float(threshold),
            "max_cells": cell_limit(self.max_cells),
        }

    def key_fields(self) -> dict[str, Any]:
        """Everything that changes a result (not ``retries`` or ``analysis_threads``), JSON-ready."""
        # The seed has no effect (the mixture's start is deterministic): not in the key.
        params = {k: v for k, v in asdict(self.params).items() if k != "seed"}
        fields: dict[str, Any] = {
            "params": params,
            # A set of topics: -t /map -t /local_map, the other way round or /map twice analyse
            # the same (each redid the recording).
            "topics": None if self.topics is None else sorted(set(self.topics)),
            "failure_level": self.failure_level,
            "walls": self.walls,
            "cleaned": self.cleaned,
            "rrd": self.rrd,
        }
        if self.salvage:  # only when set: the keys of results stored without it stay valid
            fields["salvage"] = True
        if self.replace_rose_topics:
            fields["replace_rose_topics"] = True
        # Likewise, only when they differ from process's defaults.
        if self.clean_method != "walls":
            fields["clean_method"] = self.clean_method
        if self.break_threshold_m is not None:
            from rose_logs.session.breaks import BreakParams

            # 2, 2.0 and the default written out are the same option: one key for each value.
            if float(self.break_threshold_m) != BreakParams().threshold_m:
                fields["break_threshold_m"] = float(self.break_threshold_m)
        # 2e8, 200000000 and numpy's int are the same limit: one key for each.
        max_cells = cell_limit(self.max_cells)  # checked when the options were made
        if max_cells != DEFAULT_MAX_CELLS:
            fields["max_cells"] = max_cells
        return fields


@dataclass(frozen=True)
class RecordingResult:
    """What one recording gave: its summary row, its snapshot rows, or the error.

    Attributes
    ----------
    uri, name : str
        The recording (see :class:`Recording`).
    key : str
        Its resume key (see :func:`result_key`).
    status : {"ok", "error"}
        ``error``: the recording could not be processed; ``error`` holds why.
    error : str or None
        One-line message.
    format : str or None
        Log format (``ros1``, ``db3``, ``mcap``, ``mcap-dir``).
    map_topics : tuple of str
        Map topics analysed.
    start_ns, end_ns : int or None
        Log time of the first and last message, ns.
    snapshots : tuple of dict
        One JSON-ready dict per snapshot: ``SnapshotRecord.to_json`` (``break_detected``: the break
        detector marks the snapshot broken) plus ``break_start`` (the first broken snapshot of a
        break), ``w_above_failure`` (W > ``failure_level``) and ``broken`` (detector or W).
    failure_level : float
        W above which a snapshot counted as broken.
    seconds : float
        Wall time spent on the recording, seconds (fetch and upload included).
    cpu_seconds : float
        CPU time of the process doing it (user + system), seconds.
    worker : str
        ``host:pid`` of the process that did the work.
    cleaned_uri, rrd_uri : str or None
        Outputs written.
    cleaned_bytes, rrd_bytes : int or None
        Their sizes as written (all files of a bag folder): a re-run redoes a recording whose
        output has since been cut short or lost a file.
    losses : tuple of str
        With ``salvage``: what could not be read of a damaged recording (empty when intact).
    skipped_messages : int
        Map messages left out (malformed, over the cell limit, not analysable), as ``process``
        reports them; ``skipped_reasons`` counts them by reason ("2 malformed, 1 over --max-cells").
    warnings : tuple of str
        Every warning the recording gave (one line each), in order: kept with the result, and said
        by the batch with the recording's URI.
    settings : dict or None
        What the result depends on besides the URI (:func:`result_settings`): a later batch with
        other options says why it redoes the recording. None in results of older versions.
    """

    uri: str
    name: str
    key: str
    status: Status
    error: str | None = None
    format: str | None = None
    map_topics: tuple[str, ...] = ()
    start_ns: int | None = None
    end_ns: int | None = None
    snapshots: tuple[dict[str, Any], ...] = ()
    failure_level: float = FAILURE_LEVEL
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    worker: str = ""
    cleaned_uri: str | None = None
    rrd_uri: str | None = None
    cleaned_bytes: int | None = None
    rrd_bytes: int | None = None
    losses: tuple[str, ...] = ()
    skipped_messages: int = 0
    skipped_reasons: str = ""
    warnings: tuple[str, ...] = ()
    settings: dict[str, Any] | None = None

    @property
    def first_break(self) -> dict[str, Any] | None:
        """The first snapshot row that counts as broken (the break detector's or W above the
        failure level), None when the map never broke."""
        return next((s for s in self.snapshots if s["broken"]), None)

    def row(self) -> dict[str, Any]:
        """The recording's row of ``recordings.parquet``."""
        scores = [s["structure_score"] for s in self.snapshots if row_judged(s)]
        first = self.first_break
        text = _printable_or_none
        return {
            "uri": printable(self.uri),
            "name": printable(self.name),
            "format": self.format,
            "status": self.status,
            "error": text(self.error),
            "losses": [printable(line) for line in self.losses],
            "skipped_messages": self.skipped_messages,
            "skipped_reasons": self.skipped_reasons,
            "warnings": [printable(line) for line in self.warnings],
            "map_topics": list(self.map_topics),
            "snapshots": len(self.snapshots),
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "w_min": min(scores) if scores else None,
            "w_median": statistics.median(scores) if scores else None,
            "w_max": max(scores) if scores else None,
            "broke": first is not None,
            "first_break_topic": None if first is None else first["topic"],
            "first_break_index": None if first is None else first["index"],
            "first_break_ns": None if first is None else first["log_time_ns"],
            "seconds": round(self.seconds, 6),
            "cpu_seconds": round(self.cpu_seconds, 6),
            "cleaned": text(self.cleaned_uri),
            "rrd": text(self.rrd_uri),
        }

    def to_json(self) -> dict[str, Any]:
        """Everything, JSON-ready (what the results folder stores)."""
        payload = asdict(self)
        payload["map_topics"] = list(self.map_topics)
        payload["snapshots"] = list(self.snapshots)
        payload["losses"] = list(self.losses)
        payload["warnings"] = list(self.warnings)
        return payload

    @classmethod
    def from_json(cls, payload: Mapping[str, Any]) -> RecordingResult:
        """Inverse of :meth:`to_json`."""
        data = dict(payload)
        data["map_topics"] = tuple(data.get("map_topics", ()))
        data["snapshots"] = tuple(data.get("snapshots", ()))
        data["losses"] = tuple(data.get("losses", ()))
        data["warnings"] = tuple(data.get("warnings", ()))
        return cls(**data)


def _format_of(path: Path) -> LogFormat | None:
    """The log format of ``path`` by its content, None when it is no log we know."""
    try:
        return detect_format(path)
    except LogError:
        return None


def _printable_or_none(text: str | None) -> str | None:
    return None if text is None else printable(text)


def package_version() -> str:
    """Version of rose-bag recorded in every resume key."""
    from rose_logs import __version__

    return __version__


#: Layout of a stored result; part of the resume key, so results stored in an older layout are
#: redone instead of mixed into new tables (2: ``break_detected`` marks every snapshot the detector
#: calls broken, not only a break's first; 3: maps without occupied cells are never
#: ``w_above_failure``; 4: directions in the map frame, the ``completed`` count; 5: skipped
#: messages and warnings; 6: thin maps padded to 16 cells, resolution as its float32 reads,
#: warnings counted once; 7: the break detector also counts risen evidence; 8: the walls cleaning's
#: object rules, W judges maps of 20 or more occupied cells; 9: the wide unknown recomputed behind
#: completed walls, complete MCAP files without a summary read in log-time order, cells outside
#: -1..100 read as occupied, unappliable grid updates counted as skipped; 10: hidden walls drawn
#: only between wall ends, partitions kept, output sizes stored; 11: the walls cleaning's
#: flush-furniture rule, also at an angle to the grid; a room walled by the grid's border no
#: degenerate input; 12: the walls cleaning's corner-furniture rule; 13: the walls cleaning's guard
#: judges long openings in pieces, a mixture threshold beyond the scores is one population; 14: the
#: break detector's anchor (slow drifts break, a map returning to the anchor's does not), costmaps
#: left out unless named; 15: a topic's last snapshot compared with the anchor at the end of the
#: log, ROS 1 bags whose index is damaged or renumbers a connection refused).
RESULT_LAYOUT = 15


def result_settings(recording: Recording, options: RecordingOptions) -> dict[str, Any]:
    """What a result depends on besides the recording's URI, JSON-ready: its size and version
    (mtime / ETag), the package version, the result layout and the options. Stored with each
    result, so that a later batch can say why it redoes a recording (:func:`changed_settings`)."""
    settings = {
        "layout": RESULT_LAYOUT,
        "size": recording.size,
        "version": recording.version,
        "rose_bag": package_version(),
        "options": options.key_fields(),
    }
    # Through JSON once: a stored result's settings compare equal to freshly made ones.
    loaded: dict[str, Any] = json.loads(json.dumps(settings, sort_keys=True, default=str))
    return loaded


def result_key(recording: Recording, options: RecordingOptions) -> str:
    """Resume key: SHA-256 of the URI and :func:`result_settings`."""
    payload = {"uri": recording.uri, **result_settings(recording, options)}
    text = json.dumps(payload, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def changed_settings(before: Mapping[str, Any] | None, now: Mapping[str, Any]) -> str:
    """Why a result stored with the settings ``before`` (None: stored by a rose-bag that did not
    record them) is not this run's (``now``), in a few words for people."""
    changes = setting_changes(before, now)
    if not changes:
        return "processed before with other settings"
    options = [c for c in changes if c.startswith(_OPTION)]
    text = [c for c in changes if not c.startswith(_OPTION)]
    if options:
        text.append("options changed: " + ", ".join(c.removeprefix(_OPTION) for c in options))
    return "; ".join(text)


_OPTION = "option "


def setting_changes(before: Mapping[str, Any] | None, now: Mapping[str, Any]) -> list[str]:
    """What differs between a stored result's settings ``before`` and ``now``
    (:func:`result_settings`), one item per difference (each option its own, ``"option NAME"``)."""
    if not isinstance(before, Mapping):
        return ["processed before by an older rose-bag or with other options"]
    changes = []
    if before.get("size") != now["size"] or before.get("version") != now["version"]:
        changes.append("the file changed")
    if before.get("rose_bag") != now["rose_bag"]:
        changes.append(f"rose-bag {before.get('rose_bag')} -> {now['rose_bag']}")
    elif before.get("layout") != now["layout"]:
        changes.append("another result layout")
    old_options = before.get("options")
    old_options = old_options if isinstance(old_options, Mapping) else {}
    changes += [_OPTION + name for name in _changed_fields(old_options, now["options"])]
    return changes


def _changed_fields(before: Mapping[str, Any], now: Mapping[str, Any]) -> list[str]:
    """Names of the fields that differ (one level into ``params``: ``params.occupied_threshold``)."""
    changed = []
    for name in sorted(set(before) | set(now)):
        old, new = before.get(name), now.get(name)
        if old == new:
            continue
        if name == "params" and isinstance(old, Mapping) and isinstance(new, Mapping):
            changed += [f"params.{field}" for field in _changed_fields(old, new)]
        else:
            changed.append(name)
    return changed


def result_path(key: str) -> str:
    """Relative path of a result in the output store."""
    return f"{RESULTS_DIR}/{key}.json"


def recording_id(uri: str) -> str:
    """Rerun recording id of a recording: from its full URI (two robots' ``run.mcap`` stay apart)."""
    return str(uuid.uuid5(uuid.NAMESPACE_URL, printable(uri)))


def worker_name() -> str:
    """``host:pid`` of this process."""
    return f"{socket.gethostname()}:{os.getpid()}"


def process_recording(
    recording: Recording,
    *,
    out: str,
    options: RecordingOptions,
    storage_options: Mapping[str, Any] | None = None,
) -> RecordingResult:
    """Process one recording and store its result under ``out``; never raises for a bad recording.

    The recording is read in place (local) or downloaded to a temporary folder (remote); its cleaned
    log and Rerun recording, if asked for, go to ``<out>/cleaned/<name>`` and ``<out>/rrd/<name>.rrd``.
    ``OSError`` s (also a full disk under ``out``) are retried ``options.retries`` times. The result
    is written atomically to ``<out>/results/<key>.json`` before it is returned, so that a later
    batch can skip the recording; an I/O error's is not (a later batch tries again).

    Parameters
    ----------
    recording : Recording
        What to process.
    out : str
        Output root (folder or fsspec URL).
    options : RecordingOptions
        Per-recording options.
    storage_options : mapping, optional
        fsspec options for remote inputs and outputs.

    Returns
    -------
    RecordingResult

    Raises
    ------
    TypeError
        If ``recording`` is not a :class:`Recording` (``discover([path])`` makes them).
    """
    if not isinstance(recording, Recording):
        msg = (
            "process_recording takes a Recording, e.g. rose_logs.batch.discover([path])[0], got "
            f"{type(recording).__name__} {recording!r}"
        )
        raise TypeError(msg)
    store = OutputStore(out, storage_options)
    key = result_key(recording, options)
    started = time.perf_counter()
    cpu_started = time.process_time()
    attempts = max(0, options.retries) + 1
    lasting = True  # a result that holds for this recording, stored so that a re-run skips it
    for attempt in range(1, attempts + 1):
        said = RecordingWarnings()  # those of the last attempt are the recording's
        try:
            with collecting(said):
                result = _attempt(recording, store, options, storage_options, key, said)
            break
        except OSError as err:
            if attempt == attempts:
                # Not stored: an I/O error (a full disk under OUT, a network file system) says
                # nothing about the recording, and a re-run once it is fixed does it again.
                text = err.strerror if err.strerror and err.filename is None else str(err)
                result = error_result(recording, key, options, f"I/O error: {text}")
                lasting = False
                break
            _LOG.warning(
                "%s: %s (attempt %d of %d, retrying)", recording.uri, err, attempt, attempts
            )
            time.sleep(min(0.2 * 2**attempt, 5.0))
        except (LogError, RoseError, ValueError) as err:
            result = error_result(recording, key, options, str(err))
            break
        except MemoryError:
            # Not stored either, and no traceback: the machine ran short (other workers, a
            # limit), which says nothing lasting about the recording; a re-run does it again.
            _LOG.warning("%s: out of memory", recording.uri)
            text = "out of memory (fewer --workers, or a lower --max-cells?)"
            result = error_result(recording, key, options, text)
            lasting = False
            break
        except Exception as err:  # never crash a batch on one recording
            _LOG.exception("%s: unexpected error", recording.uri)
            result = error_result(recording, key, options, f"{type(err).__name__}: {err}")
            break
    result = dataclasses.replace(
        result,
        warnings=said.lines(),  # an error row keeps them too
        settings=result_settings(recording, options),
    )
    result = _with_seconds(result, time.perf_counter() - started, time.process_time() - cpu_started)
    if lasting:
        for attempt in range(1, attempts + 1):
            try:
                store_result(store, result)
                break
            except OSError as err:
                # An I/O error as any other under OUT (a full disk): retried, then said on the
                # row, whose result is not stored (the next run does the recording again). It
                # escaped before: in this process it ended the whole batch with no tables, on a
                # Dask worker it became an error row, stored, that no later run redid.
                if attempt == attempts:
                    line = f"{recording.uri}: its result could not be stored ({err}); the next run does it again"
                    result = dataclasses.replace(result, warnings=(*result.warnings, line))
                    break
                time.sleep(min(0.2 * 2**attempt, 5.0))
    return result


def error_result(
    recording: Recording,
    key: str,
    options: RecordingOptions,
    message: str,
    *,
    log_format: str | None = None,
) -> RecordingResult:
    """A result saying that ``recording`` (of ``log_format``, when known) failed with ``message``
    (one line, starting with the recording's URI like every error row)."""
    line = " ".join(str(message).split()) or "unknown error"
    # The name spelled as the line spells it: one with a newline, a tab or two spaces in a row
    # (`new\nrun.bag`) was put before the message again, its newline breaking the one line.
    spelled = " ".join(recording.uri.split())
    if not line.startswith(spelled):
        line = f"{spelled}: {line}"
    return RecordingResult(
        uri=recording.uri,
        name=recording.name,
        key=key,
        status="error",
        error=line,
        format=log_format,
        failure_level=options.failure_level,
        worker=worker_name(),
    )


def store_result(store: OutputStore, result: RecordingResult) -> None:
    """Write ``result`` atomically under its key."""
    data = json.dumps(result.to_json(), sort_keys=True)
    store.write_bytes(result_path(result.key), data.encode())


def output_owners(store: OutputStore) -> dict[str, str]:
    """The name of every stored result with outputs (a cleaned log or a recording named after it)
    and the URI of its recording: the outputs of ``cleaned/`` and ``rrd/`` are theirs. Unreadable
    results are passed over (they are redone when their recording comes again)."""
    owners: dict[str, str] = {}
    for data in store.iter_folder(RESULTS_DIR, ".json"):
        try:
            fields = json.loads(data)  # one at a time: a result holds every snapshot's record
        except ValueError:
            continue
        if not isinstance(fields, dict):
            continue
        name, uri = fields.get("name"), fields.get("uri")
        has_outputs = fields.get("cleaned_uri") is not None or fields.get("rrd_uri") is not None
        if isinstance(name, str) and isinstance(uri, str) and has_outputs:
            owners.setdefault(name, uri)
    return owners


def load_result(store: OutputStore, key: str) -> RecordingResult | None:
    """The stored result of ``key``, None if there is none (or it is unreadable)."""
    try:
        data = store.read_bytes(result_path(key))
    except OSError:
        return None
    if data is None:
        return None
    try:
        return RecordingResult.from_json(json.loads(data))
    except (ValueError, TypeError):
        # Named under OUT (a bare results/<key>.json named no file from where the user stands).
        path = store.uri(result_path(key))
        _LOG.warning("%s: unreadable stored result, redoing the recording", path)
        return None


def _with_seconds(result: RecordingResult, seconds: float, cpu_seconds: float) -> RecordingResult:
    data = result.to_json()
    data["seconds"] = seconds
    data["cpu_seconds"] = cpu_seconds
    return RecordingResult.from_json(data)


def _attempt(
    recording: Recording,
    store: OutputStore,
    options: RecordingOptions,
    storage_options: Mapping[str, Any] | None,
    key: str,
    said: RecordingWarnings,
) -> RecordingResult:
    from rose_logs.reader import LogReader
    from rose_logs.session import process_log

    with tempfile.TemporaryDirectory(prefix=work_folder_prefix(), dir=store.staging_dir()) as tmp:
        work = Path(tmp)
        local = _fetch(recording, work / "input", storage_options)
        # The downloaded copy's path means nothing to the reader of the row: name the recording.
        said.aliases[str(local)] = recording.uri
        cleaned_name = cleaned_log_name(recording.name)
        cleaned = work / "cleaned" / Path(cleaned_name).name if options.cleaned else None
        rrd = work / "recording.rrd" if options.rrd else None
        if cleaned is not None:
            cleaned.parent.mkdir()
        reader: LogReader | None = None
        try:
            # Made here, for the session: its format is the cleaned log's, and a bag folder's
            # metadata.yaml, read for it, is not read again (seconds for thousands of topics).
            reader = LogReader(local, salvage=options.salvage)
            report = process_log(
                local,
                reader=reader,
                output_path=cleaned,
                # The cleaned log mirrors the input, also one whose suffix is not its format (an
                # MCAP file named .bag): the suffix would ask for a conversion no log gets.
                output_format=reader.format if cleaned is not None else None,
                topics=options.topics,
                params=options.params,
                failure_level=options.failure_level,
                rrd_path=rrd,
                walls=options.walls,
                recording_id=recording_id(recording.uri),
                analysis_threads=options.analysis_threads,
                salvage=options.salvage,
                clean_method=options.clean_method,
                break_params=_break_params(options),
                max_cells=options.max_cells,
                replace_rose_topics=options.replace_rose_topics,
            )
        except (LogError, RoseError) as err:
            # The message names the downloaded copy, which is gone by the time anyone reads the
            # row: name the recording instead.
            text = str(err)
            if str(local) != recording.uri:
                text = text.replace(str(local), recording.uri)
            # So do the outputs' staging names (gone too): name where they were going.
            if cleaned is not None:
                text = text.replace(str(cleaned), store.uri(f"cleaned/{cleaned_name}"))
            if rrd is not None:
                text = text.replace(str(rrd), store.uri(f"rrd/{recording.name}.rrd"))
            if _output_failure(err):  # a full disk under OUT: not the recording's, retried
                raise OSError(err.__cause__.errno, text) from err  # type: ignore[union-attr]
            failed = storage_failure(err)
            if failed is not None:  # the disk or network under the recording: retried too
                raise OSError(
                    failed.errno, f"cannot read the recording ({failed.strerror or failed})"
                ) from err
            fmt = _format_of(local) if reader is None else reader.format
            return error_result(recording, key, options, text, log_format=fmt)
        cleaned_uri = None if cleaned is None else store.put(cleaned, f"cleaned/{cleaned_name}")
        rrd_uri = None if rrd is None else store.put(rrd, f"rrd/{recording.name}.rrd")
    level = options.failure_level
    starts = {(b.topic, b.index) for b in report.detected_breaks}
    snapshots = []
    for record in report.records:
        row = record.to_json(start_ns=report.start_ns)
        # A map breaks where the break detector fires or where W rises above the paper's level;
        # both reasons stay visible as their own columns.
        row["break_start"] = (record.topic, record.index) in starts
        row["w_above_failure"] = record.judged and record.structure_score > level
        row["broken"] = row["break_detected"] or row["w_above_failure"]
        snapshots.append(row)
    return RecordingResult(
        uri=recording.uri,
        name=recording.name,
        key=key,
        status="ok",
        format=report.input_format,
        map_topics=tuple(report.map_topics),
        start_ns=report.start_ns,
        end_ns=report.end_ns,
        snapshots=tuple(snapshots),
        failure_level=level,
        worker=worker_name(),
        cleaned_uri=cleaned_uri,
        rrd_uri=rrd_uri,
        cleaned_bytes=None if cleaned_uri is None else store.size(cleaned_uri),
        rrd_bytes=None if rrd_uri is None else store.size(rrd_uri),
        # The downloaded copy's path means nothing to the reader of the table: name the recording.
        losses=tuple(loss.replace(str(local), recording.uri) for loss in report.losses),
        skipped_messages=report.skipped_messages,
        skipped_reasons=report.skipped_reasons,
    )


def _output_failure(err: BaseException) -> bool:
    """Whether ``err`` is an output that could not be written for want of space or a working disk
    (an ``OSError`` with an errno underneath): not the recording's fault. A damaged recording's
    read errors (a corrupt bz2 chunk is an ``OSError`` too) are its own."""
    cause = err.__cause__
    return (
        isinstance(err, LogWriteError | OutputError)
        and isinstance(cause, OSError)
        and cause.errno is not None
    )


def _break_params(options: RecordingOptions) -> BreakParams | None:
    """The break detector's parameters for ``options`` (None: process_log's own default)."""
    if options.break_threshold_m is None:
        return None
    from rose_logs.session.breaks import BreakParams

    return BreakParams.following(
        options.params.occupied_threshold, threshold_m=options.break_threshold_m
    )


def _fetch(recording: Recording, target: Path, storage_options: Mapping[str, Any] | None) -> Path:
    """Local path of the recording: itself when local, else a download into ``target``."""
    if is_local(recording.uri):
        return Path(recording.uri.removeprefix("file://"))
    fs, path = filesystem(recording.uri, storage_options)
    local = target / Path(recording.name).name
    target.mkdir(parents=True, exist_ok=True)
    if recording.is_dir:
        local.mkdir()
        for remote in sorted(fs.find(path)):
            relative = remote[len(path.rstrip("/")) + 1 :]
            destination = local / relative
            destination.parent.mkdir(parents=True, exist_ok=True)
            fs.get_file(remote, str(destination))
    else:
        fs.get_file(path, str(local))
    return local
