"""Running a batch: find the recordings, skip finished ones, run the rest (in-process or Dask)."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import os
import re
import signal
import time
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rose.errors import OutputError
from rose.outputs import is_bag_folder, refuse_output_in_bag_folder
from rose_logs.batch.errors import BatchError
from rose_logs.batch.sources import Recording, cleaned_log_name, discover, distinct_name
from rose_logs.batch.store import OutputStore, expand_user, is_local, storage_errors
from rose_logs.batch.task import (
    RESULTS_DIR,
    RecordingOptions,
    RecordingResult,
    changed_settings,
    error_result,
    load_result,
    output_owners,
    process_recording,
    result_key,
    result_settings,
    setting_changes,
    store_result,
)

__all__ = ["BatchReport", "run_batch"]

_LOG = logging.getLogger(__name__)

#: Seconds to connect to an existing Dask scheduler before giving up.
CONNECT_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class BatchReport:
    """What a batch did.

    Attributes
    ----------
    out : str
        Output root.
    results : tuple of RecordingResult
        One per recording found (finished ones), sorted by URI; recordings not finished because of an
        interruption are missing.
    processed : int
        Recordings processed by this run (the others were skipped: finished before).
    skipped : int
        Recordings whose stored result was reused.
    interrupted : bool
        The batch was stopped (Ctrl-C, SIGTERM, SIGHUP) before every recording finished.
    failure_level : float
        W above which a snapshot counts as broken.
    elapsed_s : float
        Wall time of the run, seconds.
    signal : int or None
        The signal that stopped the batch (``signal.SIGINT`` for Ctrl-C), None if it was not stopped.
    found : int
        Recordings the inputs named (more than ``results`` when interrupted).
    redone : tuple of (str, int)
        Why recordings with a stored result of other settings were processed again, and how many
        for each reason (e.g. ``("options changed: clean_method", 12)``), most first.
    """

    out: str
    results: tuple[RecordingResult, ...]
    processed: int
    skipped: int
    interrupted: bool
    failure_level: float
    elapsed_s: float
    signal: int | None = None
    found: int = 0
    redone: tuple[tuple[str, int], ...] = ()

    @property
    def errors(self) -> tuple[RecordingResult, ...]:
        """Recordings that failed."""
        return tuple(r for r in self.results if r.status == "error")

    @property
    def broken(self) -> tuple[RecordingResult, ...]:
        """Recordings whose map broke: the break detector fired, or W rose above the failure level."""
        return tuple(r for r in self.results if r.first_break is not None)


ResultCallback = Callable[[RecordingResult, int, int], None]
GatesCallback = Callable[["BatchReport"], Mapping[str, Any]]


def run_batch(
    inputs: Sequence[str | Path],
    out: str | Path,
    *,
    client: Any = None,
    workers: int = 1,
    scheduler: str | None = None,
    scheduler_file: str | Path | None = None,
    memory_limit: str | float | None = None,
    options: RecordingOptions | None = None,
    storage_options: Mapping[str, Any] | None = None,
    force: bool = False,
    retry_errors: bool = False,
    progress: bool = False,
    on_result: ResultCallback | None = None,
    write_tables: bool = True,
    gates: GatesCallback | None = None,
) -> BatchReport:
    """Process every recording of ``inputs``; write the tables and report to ``out``.

    Parameters
    ----------
    inputs : sequence of str or Path
        Files, folders, glob patterns or fsspec URLs (see :func:`rose_logs.batch.discover`).
    out : str or Path
        Output folder or fsspec URL (``s3://bucket/prefix``).
    client : distributed.Client, optional
        Run on this Dask client's cluster. Otherwise ``scheduler`` / ``scheduler_file`` name an
        existing cluster, ``workers > 1`` starts a local one (processes, one thread each) and
        ``workers == 1`` runs in this process without Dask.
    workers : int, default 1
        Worker processes of the local cluster.
    scheduler, scheduler_file : optional
        Address (``tcp://host:8786``) or scheduler file of an existing Dask cluster.
    memory_limit : str or float, optional
        Per-worker memory limit of the local cluster (``"2GB"``, bytes, or a fraction of RAM);
        a worker that exceeds it is restarted and its recording reported as an error.
    options : RecordingOptions, optional
        Per-recording options (ROSE parameters, topics, outputs, retries).
    storage_options : mapping, optional
        fsspec options for remote inputs and ``out``.
    force : bool, default False
        Redo every recording, even those finished before.
    retry_errors : bool, default False
        Redo the recordings that failed before (finished ones are still skipped).
    progress : bool, default False
        Show a progress bar on stderr.
    on_result : callable, optional
        Called with ``(result, done, total)`` after each recording processed by this run.
    write_tables : bool, default True
        Write ``recordings.parquet``, ``snapshots.parquet``, ``summary.json`` and ``report.md``.
    gates : callable, optional
        Called with the :class:`BatchReport` before the tables are written; what it returns (the
        gates asked for and those that failed, JSON-ready) goes into ``summary.json`` as
        ``gates``, so that a pipeline reading it sees why the batch failed.

    Returns
    -------
    BatchReport

    Raises
    ------
    BatchError
        If an input does not exist or matches nothing, a URL's scheme is unknown or its fsspec
        backend not installed, ``out`` cannot be created, ``workers`` is out of range, the
        scheduler file is unusable, the scheduler cannot be reached, or the tables cannot be written
        (then none of them is replaced; the results of finished recordings are kept for a re-run).
    """
    started = time.perf_counter()
    options = RecordingOptions() if options is None else options
    if not isinstance(options, RecordingOptions):
        msg = f"options must be a RecordingOptions, got {type(options).__name__}"
        raise BatchError(msg)
    if workers < 1:
        msg = f"workers must be >= 1, got {workers}"
        raise BatchError(msg)
    if client is None and scheduler is None and scheduler_file is None:
        from rose_logs.batch.cluster import WORKERS_PER_CPU, max_local_workers

        if workers > max_local_workers():
            msg = f"workers must be <= {max_local_workers()} ({WORKERS_PER_CPU} per CPU), got {workers}"
            raise BatchError(msg)
    with storage_errors(str(out)):
        store = OutputStore(str(out), storage_options)
    if isinstance(inputs, str | Path):  # one input, not its characters
        inputs = [inputs]
    recordings = _outside(discover(inputs, storage_options=storage_options), store)
    keys = {rec.uri: result_key(rec, options) for rec in recordings}
    finished: dict[str, RecordingResult] = {}
    todo: list[Recording] = []
    before: dict[str, RecordingResult | None] = {}  # stored results of the recordings to do
    unasked: dict[str, int] = {}  # finished recordings redone though neither asked nor changed
    named_outputs = options.cleaned or options.rrd  # files named after the recordings
    with storage_errors(store.root):
        stored_results = {rec.uri: load_result(store, keys[rec.uri]) for rec in recordings}
        owners = output_owners(store) if named_outputs else {}
    names = _run_names(recordings, stored_results, owners, keep_stored=named_outputs)
    for rec in recordings:
        previous = stored_results[rec.uri]
        rec = dataclasses.replace(rec, name=names[rec.uri])
        if previous is not None and previous.name != rec.name and not named_outputs:
            previous = dataclasses.replace(previous, name=rec.name)  # no file has its name
        with storage_errors(store.root):
            redo, why = _redo_decision(previous, rec, store, force=force, retry_errors=retry_errors)
        if previous is not None and not redo:
            finished[rec.uri] = previous
        else:
            todo.append(rec)
            before[rec.uri] = previous
            if why is not None:
                unasked[why] = unasked.get(why, 0) + 1
    skipped = len(finished)
    _LOG.info("%d recordings, %d finished before, %d to do", len(recordings), skipped, len(todo))
    try:
        redone = _redone(
            store, [rec for rec in todo if before[rec.uri] is None], options, keys.values()
        )
    except Exception as err:  # only says why: the run's own steps report the store
        # A store this run cannot read (denied, missing bucket) is said by the steps that need
        # it, in their words: the reasons are no step of the run.
        _LOG.debug("cannot tell why recordings are redone: %s", err)
        redone = ()
    # A finished recording is never redone without a word (it took its time again).
    redone = tuple(sorted((*redone, *unasked.items()), key=lambda item: (-item[1], item[0])))
    for reason, count in redone:
        _LOG.info("%d recording(s) redone: %s", count, reason)
    named_by = None  # the scheduler file, for errors
    if scheduler_file is not None and client is None and todo:
        from rose_logs.batch.cluster import scheduler_address

        # Read before anything runs (and only when there is something to run): Dask would wait
        # forever for a missing file and fail with a bare AssertionError on one not its own.
        scheduler = scheduler_address(scheduler_file)
        named_by = str(scheduler_file)
    stopped_by: int | None = None
    if write_tables and todo:
        from rose_logs.batch.report import warm_imports

        warm_imports()
    bar = _Progress(total=len(todo), enabled=progress)
    try:
        with _executor(
            client if todo else None,
            workers if todo else 1,  # nothing to do: no cluster to start or connect to
            scheduler if todo else None,
            named_by,
            memory_limit,
            options,
        ) as (run, slots):
            # Created once the engine is ready: a scheduler that cannot be reached leaves no folder.
            store.prepare(folders=(RESULTS_DIR,))
            bar.slots = slots
            from rose_logs.session.held_logs import said_above_bar  # (with the session's code)

            with said_above_bar(bar.bar is not None):
                for result in run(todo, store, options, storage_options, keys):
                    finished[result.uri] = result
                    bar.update(result)
                    for line in result.warnings:
                        named = line.startswith(f"{result.uri}:")
                        _LOG.warning("%s", line if named else f"{result.uri}: {line}")
                    if on_result is not None:
                        on_result(result, bar.done, len(todo))
    except KeyboardInterrupt as err:
        stopped_by = getattr(err, "signum", signal.SIGINT)  # Terminated: SIGTERM / SIGHUP
        # Workers store each result as they finish it, also those this process had not collected
        # yet when the signal came (the cluster is closed by now): the tables include them.
        for rec in todo:
            if rec.uri not in finished:
                stored = load_result(store, keys[rec.uri])
                if stored is not None and not _same(stored, before[rec.uri]):
                    finished[rec.uri] = stored
        _LOG.info("interrupted: %d of %d recordings finished", len(finished) - skipped, len(todo))
    finally:
        bar.close()
        store.remove_staging()
    report = BatchReport(
        out=store.root,
        results=tuple(finished[r.uri] for r in recordings if r.uri in finished),
        processed=len(finished) - skipped,
        skipped=skipped,
        interrupted=stopped_by is not None,
        failure_level=options.failure_level,
        elapsed_s=time.perf_counter() - started,
        signal=stopped_by,
        found=len(recordings),
        redone=redone,
    )
    if write_tables:
        from rose.signals import signals_deferred
        from rose_logs.batch.tables import write_outputs

        # A signal between two tables would leave them out of step: they are written first (in a
        # second), and the report then says the batch was stopped.
        try:
            with signals_deferred(), storage_errors(store.root):
                write_outputs(
                    store, report, options, gates=None if gates is None else gates(report)
                )
        except KeyboardInterrupt as err:
            stopped_by = getattr(err, "signum", signal.SIGINT)
            report = dataclasses.replace(report, interrupted=True, signal=stopped_by)
    return report


def _redo_decision(
    previous: RecordingResult | None,
    rec: Recording,
    store: OutputStore,
    *,
    force: bool,
    retry_errors: bool,
) -> tuple[bool, str | None]:
    """Whether ``rec`` (named for this run) is processed again rather than its stored result
    ``previous`` reused; and, for a finished recording redone though neither asked for nor
    changed, why (for the summary), else None."""
    if force or previous is None or (retry_errors and previous.status == "error"):
        return True, None
    if previous.name != rec.name:
        # Its outputs carry a name another recording takes this run: redone under its new name,
        # or two rows would share one cleaned log.
        return True, "its outputs' name is another recording's now"
    if _outputs_missing(previous, store):
        return True, "its --cleaned / --rrd output was deleted or changed since"
    return False, None


def _redone(
    store: OutputStore,
    recordings: Sequence[Recording],
    options: RecordingOptions,
    keys: Collection[str],
) -> tuple[tuple[str, int], ...]:
    """Why ``recordings`` (none with a result under this run's key) have results stored under
    other keys: each reason (:func:`changed_settings`) and how many recordings it holds for, most
    first. Reads only the stored results of other keys than this run's ``keys`` (a run that adds
    recordings to a finished fleet reads none)."""
    if not recordings:
        return ()
    wanted = {rec.uri for rec in recordings}
    earlier: dict[str, list[Any]] = {}
    for data in store.iter_folder(RESULTS_DIR, ".json", skip={f"{key}.json" for key in keys}):
        uri = _stored_uri(data)
        if uri not in wanted:
            continue
        try:
            fields = json.loads(data)
        except ValueError:
            continue
        if isinstance(fields, dict) and fields.get("uri") == uri:
            earlier.setdefault(uri, []).append(fields.get("settings"))
    reasons: dict[str, int] = {}
    for rec in recordings:
        if rec.uri not in earlier:
            continue
        now = result_settings(rec, options)
        # Of several stored results (a run per set of options), the nearest that says its
        # settings tells the most; of those as near, one of this very file (the options say
        # why): the order the results were listed in chose, and a fleet of like recordings was
        # "redone 4 (options changed: salvage)" and "redone 2 (the file changed)".
        nearest = min(
            earlier[rec.uri],
            key=lambda settings: (
                settings is None,
                len(changes := setting_changes(settings, now)),
                "the file changed" in changes,
            ),
        )
        why = changed_settings(nearest, now)
        reasons[why] = reasons.get(why, 0) + 1
    return tuple(sorted(reasons.items(), key=lambda item: (-item[1], item[0])))


_URI_FIELD = re.compile(rb'"uri": "')


def _stored_uri(data: bytes) -> str | None:
    """The ``uri`` field of a stored result (as :func:`store_result` writes it), read without
    parsing the rest (a result holds every snapshot's record); None if there is none."""
    found = _URI_FIELD.search(data)
    if found is None:
        return None
    try:
        start = found.end() - 1  # the opening quote; a URI is far shorter than a megabyte
        value, _ = json.JSONDecoder().raw_decode(
            data[start : start + (1 << 20)].decode("utf-8", "replace")
        )
    except ValueError:
        return None
    return value if isinstance(value, str) else None


def _same(result: RecordingResult, other: RecordingResult | None) -> bool:
    """Whether two results are the same stored result (as JSON: a NaN equals itself there)."""
    if other is None:
        return False
    return json.dumps(result.to_json(), sort_keys=True) == json.dumps(
        other.to_json(), sort_keys=True
    )


def _outputs_missing(result: RecordingResult, store: OutputStore) -> bool:
    """Whether a cleaned log or recording of a finished result is gone or no longer the size it was
    written with (deleted, cut short, a bag folder missing a file since): the recording is done
    again, so that every output the table names is whole."""
    written = ((result.cleaned_uri, result.cleaned_bytes), (result.rrd_uri, result.rrd_bytes))
    for uri, size in written:
        if uri is None:
            continue
        if size is None:  # stored by an older rose-bag: its presence is all there is to check
            if not store.has(uri):
                return True
        elif store.size(uri) != size:
            return True
    return False


def _run_names(
    recordings: tuple[Recording, ...],
    stored: Mapping[str, RecordingResult | None],
    owners: Mapping[str, str],
    *,
    keep_stored: bool,
) -> dict[str, str]:
    """The name of each recording in this run (by URI), for its row and outputs.

    With outputs named after recordings (``keep_stored``): a recording keeps the name its stored
    result has, or without one (its file or the options changed) a name its outputs have (they
    are there: a smaller run, or the inputs in another order, must not write another recording's
    outputs over them, nor leave its own behind), and no recording takes a name whose outputs are
    another's, of this run or an earlier one (``owners``: name -> URI; two daily folders' ``run.bag``
    wrote one cleaned log, and the older row named the newer log), nor one whose outputs would
    hold or lie inside another's (:class:`_TakenNames`). The others get the name discovery gave
    them, made distinct (:func:`~rose_logs.batch.sources.distinct_name`) when taken. Without
    outputs, the names discovery gave."""
    if not keep_stored:
        return {rec.uri: rec.name for rec in recordings}
    taken = _TakenNames()
    for name, uri in owners.items():
        taken.add(name, uri)
    owned: dict[str, list[str]] = {}  # URI -> the names whose outputs are its, in name order
    for name, uri in sorted(owners.items()):
        owned.setdefault(uri, []).append(name)
    names: dict[str, str] = {}
    for rec in recordings:  # stored names first: this key's result's, else any its outputs have
        previous = stored.get(rec.uri)
        mine = [previous.name] if previous is not None else owned.get(rec.uri, [])
        if rec.name in mine and previous is None:
            mine = [rec.name]  # (discovery's name, when it is one of them)
        free = [name for name in mine if not taken.clashes(name, rec.uri)]
        if free:
            names[rec.uri] = free[0]
            taken.add(free[0], rec.uri)
    for rec in recordings:
        if rec.uri in names:
            continue
        name = rec.name if not taken.clashes(rec.name, rec.uri) else _free_name(rec, taken)
        names[rec.uri] = name
        taken.add(name, rec.uri)
    return names


def _free_name(rec: Recording, taken: _TakenNames) -> str:
    """A name for ``rec`` that clashes with no other recording's: its name made distinct, or,
    when that still lies inside another's outputs (a file ``robot/run.mcap`` beside a bag folder
    ``robot``), its top folder made distinct (``robot-1a2b3c4d/run.mcap``)."""
    name = distinct_name(rec.name, rec)
    top, _, rest = rec.name.partition("/")
    if taken.clashes(name, rec.uri) and rest:
        folder = distinct_name(top, dataclasses.replace(rec, is_dir=True))
        name = f"{folder}/{rest}"
    return name


class _TakenNames:
    """Recording names whose outputs belong to a recording (by URI). A name clashes with another
    recording's when their outputs would be one (the same name, or a salvaged ``x.bag.active``'s
    cleaned ``x.bag``) or one would lie inside the other (a bag folder ``robot`` and a file
    ``robot/run.mcap``: writing the folder's cleaned bag deleted the file's cleaned log)."""

    def __init__(self) -> None:
        self._owner: dict[str, str] = {}  # name (and cleaned log name) -> URI
        self._holder: dict[str, str] = {}  # a folder some name lies in -> a URI of such a name

    def add(self, name: str, uri: str) -> None:
        for spelled in {name, cleaned_log_name(name)}:
            self._owner.setdefault(spelled, uri)
            for folder in _folders_of(spelled):
                self._holder.setdefault(folder, uri)

    def clashes(self, name: str, uri: str) -> bool:
        for spelled in {name, cleaned_log_name(name)}:
            if self._owner.get(spelled, uri) != uri or self._holder.get(spelled, uri) != uri:
                return True
            if any(self._owner.get(folder, uri) != uri for folder in _folders_of(spelled)):
                return True
        return False


def _folders_of(name: str) -> list[str]:
    """The folders a ``/``-separated name lies in: ``a/b/c`` -> ``a``, ``a/b``."""
    parts = name.split("/")
    return ["/".join(parts[:i]) for i in range(1, len(parts))]


def _outside(recordings: tuple[Recording, ...], store: OutputStore) -> tuple[Recording, ...]:
    """The recordings not inside the output root (its cleaned logs are no inputs of a re-run)."""
    root = store.root.removeprefix("file://")

    def where(uri: str) -> str:  # local paths compared as the file system sees them ('..', links)
        local = store.local and is_local(uri)  # a remote recording is never inside a local OUT
        return os.path.realpath(uri.removeprefix("file://")) if local else uri

    if store.local:
        root = where(str(expand_user(root)))
    prefix = root.rstrip("/") + "/"
    inside = [where(r.uri).startswith(prefix) for r in recordings]
    kept = tuple(r for r, i in zip(recordings, inside, strict=True) if not i)
    # The batch's own outputs are left out quietly; anything else there is the user's recording.
    ours = tuple(prefix + folder + "/" for folder in ("cleaned", ".staging"))
    theirs = [
        r.uri
        for r, i in zip(recordings, inside, strict=True)
        if i and not where(r.uri).startswith(ours)
    ]
    if theirs:
        _LOG.warning(
            "%s: %d recording(s) inside the output folder are not processed (the batch writes "
            "there; choose another -o to include them), first: %s",
            store.root,
            len(theirs),
            theirs[0],
        )
    if not kept:
        msg = f"no recording found outside the output folder {store.root}"
        raise BatchError(msg)
    if store.local:
        _refuse_out_in_a_bag(root, [where(r.uri) for r in recordings if r.is_dir])
    return kept


def _refuse_out_in_a_bag(root: str, bag_folders: Sequence[str]) -> None:
    """A local output folder inside a ROS 2 bag folder of the inputs, or one itself, is refused:
    the tables would be written into a recording (and, inside an input, change its resume key, so
    that no run ever resumed)."""
    for folder in bag_folders:
        if (root + "/").startswith(folder.rstrip("/") + "/"):
            where = "is" if root.rstrip("/") == folder.rstrip("/") else "is inside"
            msg = (
                f"{root}: the output folder {where} the recording {folder} (a ROS 2 bag "
                "folder): the batch would write into its input; choose another -o"
            )
            raise BatchError(msg)
    # A folder: is_bag_folder takes what it cannot read for a bag, and a symlink loop there was
    # said to have a metadata.yaml (OutputStore.prepare says what it is).
    if Path(root).is_dir() and is_bag_folder(root):
        msg = (
            f"{root}: the output folder is a ROS 2 bag folder (it has metadata.yaml): the batch "
            "would write its tables into a recording; choose another -o"
        )
        raise BatchError(msg)
    try:  # nor inside another recording (`-o SOMEBAG/out`), as process's outputs
        refuse_output_in_bag_folder(root, "-o", what="output folder")
    except OutputError as err:
        raise BatchError(str(err)) from None


Runner = Callable[
    [Sequence[Recording], OutputStore, RecordingOptions, Mapping[str, Any] | None, dict[str, str]],
    Iterator[RecordingResult],
]


@contextlib.contextmanager
def _executor(
    client: Any,
    workers: int,
    scheduler: str | None,
    named_by: str | None,
    memory_limit: str | float | None,
    options: RecordingOptions,
) -> Iterator[tuple[Runner, int]]:
    """A function running recordings, in-process or on a (local or existing) Dask cluster, and
    how many recordings it runs at once.

    ``named_by`` is the scheduler file that gave ``scheduler`` (errors name it).
    """
    if client is not None:
        yield _dask_runner(client, memory_limit)
        return
    if scheduler is not None:
        from distributed import Client

        from rose_logs.batch.cluster import check_scheduler

        try:
            check_scheduler(scheduler, timeout_s=CONNECT_TIMEOUT_S)
            own = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S:g}s")
        except (OSError, TimeoutError, ValueError) as err:
            where = (
                f"{named_by}: cannot connect to the Dask scheduler {scheduler} it names"
                if named_by is not None
                else f"{scheduler or repr(scheduler)}: cannot connect to the Dask scheduler"
            )
            msg = f"{where} ({err})"
            raise BatchError(msg) from err
        with own:
            yield _dask_runner(own, memory_limit)
        return
    if workers == 1:
        yield _in_process, 1
        return
    from rose_logs.batch.cluster import local_client

    with local_client(workers, memory_limit=memory_limit, retries=options.retries) as own:
        yield _dask_runner(own, memory_limit)


def _in_process(
    todo: Sequence[Recording],
    store: OutputStore,
    options: RecordingOptions,
    storage_options: Mapping[str, Any] | None,
    keys: dict[str, str],
) -> Iterator[RecordingResult]:
    del keys
    for rec in todo:
        yield process_recording(
            rec, out=store.root, options=options, storage_options=storage_options
        )


def _dask_runner(client: Any, memory_limit: str | float | None) -> tuple[Runner, int]:
    """A runner of recordings on ``client``'s cluster, and its workers' count."""
    from rose_logs.batch.workerenv import tune_worker_process

    slots = len(client.run(tune_worker_process))  # workers we did not start: malloc, 1-thread pools

    def run(
        todo: Sequence[Recording],
        store: OutputStore,
        options: RecordingOptions,
        storage_options: Mapping[str, Any] | None,
        keys: dict[str, str],
    ) -> Iterator[RecordingResult]:
        from distributed import as_completed

        # A worker runs one thread: the cluster, not each recording, spreads work over the cores.
        options = dataclasses.replace(options, analysis_threads=1)
        futures = {
            client.submit(
                _dask_task,
                rec,
                out=store.root,
                options=options,
                storage_options=storage_options,
                key=f"rose-bag-{keys[rec.uri]}",
                pure=False,
                # Largest first: a big recording started last would leave the other workers idle.
                priority=rec.size,
            ): rec
            for rec in todo
        }
        try:
            for future in as_completed(futures):
                rec = futures[future]
                yield _collect(future, rec, keys[rec.uri], store, options, memory_limit)
        finally:
            pending = [f for f in futures if not f.done()]
            if pending:
                client.cancel(pending)

    return run, slots


def _dask_task(
    recording: Recording,
    *,
    out: str,
    options: RecordingOptions,
    storage_options: Mapping[str, Any] | None,
) -> RecordingResult:
    """:func:`process_recording` in a Dask worker, tuned first (a restarted worker needs it again)."""
    from rose_logs.batch.workerenv import tune_worker_process

    tune_worker_process()
    return process_recording(recording, out=out, options=options, storage_options=storage_options)


def _collect(
    future: Any,
    rec: Recording,
    key: str,
    store: OutputStore,
    options: RecordingOptions,
    memory_limit: str | float | None,
) -> RecordingResult:
    """A finished future's result; a worker death or task failure becomes an error. A task failure
    is stored; a worker death is not, as an I/O error is not (:func:`process_recording`): it says
    more about the cluster than the recording (a memory limit raised for the next run did
    nothing: the stored death was reported again, naming the old limit)."""
    from distributed import KilledWorker

    try:
        return future.result()
    except KilledWorker as err:
        limit = f" (memory limit {memory_limit})" if memory_limit is not None else ""
        # Dask's first sentence says how often it was tried; the rest is advice about its logs.
        tried = str(err).split(". ", 1)[0]
        message = f"the worker processing it died{limit}, out of memory or killed ({tried})"
        return error_result(rec, key, options, message)
    except Exception as err:  # the task itself never raises for a bad recording
        message = f"{type(err).__name__}: {err}"
    result = error_result(rec, key, options, message)
    try:
        store_result(store, result)
    except OSError as err:
        _LOG.warning("%s: cannot store the error result (%s)", rec.uri, err)
    return result


class _Progress:
    """tqdm bar over the recordings of this run: finished / failed / running."""

    def __init__(self, *, total: int, enabled: bool, slots: int = 1) -> None:
        self.total = total
        self.slots = slots
        self.done = 0
        self.ok = 0
        self.failed = 0
        self.bar: Any = None
        if enabled and total:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="rec", desc="recordings", dynamic_ncols=True)

    def update(self, result: RecordingResult) -> None:
        self.done += 1
        if result.status == "ok":
            self.ok += 1
        else:
            self.failed += 1
        if self.bar is not None:
            running = min(self.slots, self.total - self.done)
            self.bar.set_postfix_str(
                f"ok {self.ok}, failed {self.failed}, running {running}", refresh=False
            )
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
