"""``rose-bag batch``: a fleet's recordings, one task each, on a Dask cluster or in this process.

``run_batch(inputs, out)`` finds the recordings (files, folders, globs, ``s3://`` prefixes), skips those
finished by an earlier run with the same options, processes the rest with
:func:`rose_logs.process_log` and writes ``recordings.parquet``, ``snapshots.parquet``,
``summary.json`` and ``report.md`` to ``out``. :func:`process_recording` does one recording without
Dask.
"""

from rose_logs.batch.engine import BatchReport, run_batch
from rose_logs.batch.errors import BatchError
from rose_logs.batch.sources import Recording, discover, read_list
from rose_logs.batch.task import RecordingOptions, RecordingResult, process_recording, result_key

__all__ = [
    "BatchError",
    "BatchReport",
    "Recording",
    "RecordingOptions",
    "RecordingResult",
    "discover",
    "process_recording",
    "read_list",
    "result_key",
    "run_batch",
]
