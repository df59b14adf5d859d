"""The batch's outputs: two Parquet tables, a JSON summary and a markdown report with a figure."""

from __future__ import annotations

import io
import json
import logging
from typing import TYPE_CHECKING, Any

import pyarrow as pa
import pyarrow.parquet as pq

from rose.limits import short, visible
from rose_logs.batch.sources import printable
from rose_logs.batch.store import OutputStore
from rose_logs.batch.task import RecordingOptions, package_version

if TYPE_CHECKING:
    from collections.abc import Mapping

    from rose_logs.batch.engine import BatchReport

__all__ = [
    "RECORDING_SCHEMA",
    "SNAPSHOT_SCHEMA",
    "recordings_table",
    "snapshots_table",
    "write_outputs",
]

_LOG = logging.getLogger(__name__)

# Log times are unsigned 64-bit nanoseconds (MCAP's, ROS 1's and rosbag2's); a log time of 2**63
# or more is valid and overflowed an int64 column. Header stamps fit an int64 (32-bit seconds).
RECORDING_SCHEMA = pa.schema(
    [
        ("uri", pa.string()),
        ("name", pa.string()),
        ("format", pa.string()),
        ("status", pa.string()),
        ("error", pa.string()),
        ("losses", pa.list_(pa.string())),
        ("skipped_messages", pa.int64()),
        ("skipped_reasons", pa.string()),
        ("warnings", pa.list_(pa.string())),
        ("map_topics", pa.list_(pa.string())),
        ("snapshots", pa.int64()),
        ("start_ns", pa.uint64()),
        ("end_ns", pa.uint64()),
        ("w_min", pa.float64()),
        ("w_median", pa.float64()),
        ("w_max", pa.float64()),
        ("broke", pa.bool_()),
        ("first_break_topic", pa.string()),
        ("first_break_index", pa.int64()),
        ("first_break_ns", pa.uint64()),
        ("seconds", pa.float64()),
        ("cpu_seconds", pa.float64()),
        ("cleaned", pa.string()),
        ("rrd", pa.string()),
    ]
)
"""``recordings.parquet``: one row per recording, sorted by URI."""

SNAPSHOT_SCHEMA = pa.schema(
    [
        ("uri", pa.string()),
        ("topic", pa.string()),
        ("index", pa.int64()),
        ("log_time_ns", pa.uint64()),
        ("stamp_ns", pa.int64()),
        ("time_s", pa.float64()),
        ("width", pa.int64()),
        ("height", pa.int64()),
        ("resolution_m", pa.float64()),
        ("structure_score", pa.float64()),
        ("break_score_m", pa.float64()),
        (
            "break_region_m",
            pa.struct([(k, pa.float64()) for k in ("x_min", "y_min", "x_max", "y_max")]),
        ),
        ("break_detected", pa.bool_()),
        ("break_start", pa.bool_()),
        ("w_above_failure", pa.bool_()),
        ("broken", pa.bool_()),
        ("directions_deg", pa.list_(pa.float64())),
        ("threshold", pa.float64()),
        ("occupied", pa.int64()),
        ("clutter", pa.int64()),
        ("seconds", pa.float64()),
        ("reused", pa.bool_()),
        ("from_update", pa.bool_()),
        ("clean_method", pa.string()),
        ("removed", pa.int64()),
        ("kept", pa.int64()),
        ("rescued", pa.int64()),
        ("guarded", pa.int64()),
        ("completed", pa.int64()),
        ("degenerate", pa.string()),
    ]
)
"""``snapshots.parquet``: one row per snapshot (the JSON report's records), by URI, topic, index."""


def recordings_table(report: BatchReport) -> pa.Table:
    """``recordings.parquet`` as a pyarrow table."""
    rows = [r.row() for r in report.results]
    return pa.Table.from_pylist(rows, schema=RECORDING_SCHEMA)


def snapshots_table(report: BatchReport) -> pa.Table:
    """``snapshots.parquet`` as a pyarrow table."""
    rows: list[dict[str, Any]] = []
    for result in report.results:
        ordered = sorted(result.snapshots, key=lambda s: (s["topic"], s["index"]))
        rows.extend({"uri": printable(result.uri), **s} for s in ordered)
    names = SNAPSHOT_SCHEMA.names
    return pa.Table.from_pylist(
        [{k: row.get(k) for k in names} for row in rows], schema=SNAPSHOT_SCHEMA
    )


def _parquet_bytes(table: pa.Table) -> bytes:
    sink = io.BytesIO()
    pq.write_table(table, sink, compression="zstd")
    return sink.getvalue()


def summary(report: BatchReport, options: RecordingOptions) -> dict[str, Any]:
    """``summary.json``: counts, broken recordings and errors (no timings: same inputs, same bytes)."""
    rows = [r.row() for r in report.results]
    return {
        "rose_bag": package_version(),
        "failure_level": report.failure_level,
        "options": options.stated(),
        "recordings": len(rows),
        # More than ``recordings`` when the run was interrupted: what is left to do.
        "recordings_found": report.found,
        "ok": sum(r["status"] == "ok" for r in rows),
        "errors": sum(r["status"] == "error" for r in rows),
        "salvaged": sum(bool(r["losses"]) for r in rows),
        "skipped_messages": sum(r["skipped_messages"] for r in rows),
        "with_warnings": sum(bool(r["warnings"]) for r in rows),
        "broken": sum(bool(r["broke"]) for r in rows),
        "snapshots": sum(r["snapshots"] for r in rows),
        "interrupted": report.interrupted,
        "broken_recordings": [
            {
                "uri": r["uri"],
                "w_max": r["w_max"],
                "first_break_topic": r["first_break_topic"],
                "first_break_index": r["first_break_index"],
                "first_break_ns": r["first_break_ns"],
            }
            for r in rows
            if r["broke"]
        ],
        "failed_recordings": [{"uri": r["uri"], "error": r["error"]} for r in rows if r["error"]],
    }


def _drawn_figure(report: BatchReport) -> tuple[bytes | None, str | None]:
    """``w_over_time.png`` (None: nothing to draw, or no matplotlib) and, when drawing it failed,
    why, in one line (the figure then None): a figure is not worth the batch's tables and report,
    which a user's matplotlib settings (``text.usetex`` without LaTeX) or a matplotlib error on
    odd data lost entirely."""
    from rose_logs.batch.report import figure_png

    try:
        return figure_png(report), None
    except Exception as err:  # matplotlib's errors of every kind (interrupts pass)
        first = next((line for line in str(err).splitlines() if line.strip()), "")
        reason = f"{type(err).__name__}: {first.strip()}" if first else type(err).__name__
        return None, short(visible(reason), 200)


def write_outputs(
    store: OutputStore,
    report: BatchReport,
    options: RecordingOptions,
    *,
    gates: Mapping[str, Any] | None = None,
) -> None:
    """Write the tables, ``summary.json``, ``report.md`` and its figure to the output root, together.

    Everything is rendered first and then committed as one set (:meth:`OutputStore.write_set`): a
    full disk or a failed upload leaves the previous run's files in place, never a new
    ``recordings.parquet`` beside an old ``snapshots.parquet``.

    Raises
    ------
    BatchError
        If a file cannot be written (the message names it); none of them is replaced then.
    """
    from rose_logs.batch.report import markdown

    payload = summary(report, options)
    if gates is not None:
        payload["gates"] = dict(gates)
    png, not_drawn = _drawn_figure(report)
    if not_drawn is not None:
        _LOG.warning(
            "%s: not drawn (%s); the tables and report.md are written without it",
            store.uri("w_over_time.png"),
            not_drawn,
        )
    files = {
        "recordings.parquet": _parquet_bytes(recordings_table(report)),
        "snapshots.parquet": _parquet_bytes(snapshots_table(report)),
        "summary.json": (
            json.dumps(payload, indent=2, sort_keys=True, allow_nan=False) + "\n"
        ).encode(),
    }
    if png is not None:
        files["w_over_time.png"] = png
    files["report.md"] = markdown(
        report, payload, figure=png is not None, not_drawn=not_drawn
    ).encode()
    store.write_set(files)
    if png is None:  # no W to draw: an earlier run's figure would describe other recordings
        store.remove("w_over_time.png")
