"""``report.md`` of a batch and its figure: W over time per recording, broken ones highlighted."""

from __future__ import annotations

import contextlib
import importlib.util
import io
import re
import threading
from typing import TYPE_CHECKING, Any

from rose.limits import visible
from rose.outputs import counted
from rose_logs.batch.sources import printable
from rose_logs.session.report import row_judged

if TYPE_CHECKING:
    from rose_logs.batch.engine import BatchReport

__all__ = ["figure_png", "markdown", "warm_imports"]

#: Broken recordings named in the figure's legend (the rest are counted).
_LEGEND_MAX = 12


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


#: Characters Markdown (GitHub's, with its tables, strikethrough and inline HTML) reads as markup
#: in a table cell: a name such as ``run*2*``, ``[a](b)``, ``<img ...>`` or one with a backtick
#: rendered as emphasis, a link, HTML or code instead of as spelled.
_MARKUP = str.maketrans({c: f"\\{c}" for c in "\\`*[]<>|~&"})
#: An underscore that can open or close emphasis (``_a_``): one not between two letters or digits
#: (``robot_b``, most file names, is left as it is, readable in the raw file).
_EMPHASIS_UNDERSCORE = re.compile(r"(?<![^\W_])_|_(?![^\W_])")


def _cell(text: str) -> str:
    """``text`` as one table cell that renders as spelled: characters that do not print escaped
    (:func:`~rose.limits.visible`: a newline as ``\\n``), then markup backslash-escaped."""
    return _EMPHASIS_UNDERSCORE.sub(r"\\_", visible(text).translate(_MARKUP))


def markdown(
    report: BatchReport, summary: dict[str, Any], *, figure: bool, not_drawn: str | None = None
) -> str:
    """The report: counts, the figure, broken recordings, failed recordings, every recording.
    ``not_drawn``: why the figure could not be drawn (said instead of it)."""
    rows = [r.row() for r in report.results]
    level = report.failure_level
    lines = [
        "# rose-bag batch report",
        "",
        f"{counted(summary['recordings'], 'recording')}: {summary['ok']} ok, "
        f"{summary['errors']} failed, {summary['broken']} with a map that broke (break detector, or W > {level:g}); "
        f"{counted(summary['snapshots'], 'map snapshot')}{_losses_in_brief(summary)}.",
        "",
    ]
    if report.interrupted:
        lines += ["**Interrupted:** recordings not finished are missing from this report.", ""]
    if not figure and not_drawn is not None:
        lines += [f"No figure: it could not be drawn ({_cell(not_drawn)}).", ""]
    elif not figure and summary["snapshots"] and not plotting_available():
        lines += ["No figure: matplotlib is not installed (`pip install 'rose-bag[plots]'`).", ""]
    if figure:
        lines += [
            "![W over time per recording; broken ones in colour](w_over_time.png)",
            "",
            "W over time since each recording's first message; grey: maps that did not break; "
            f"in colour: maps that broke (the break detector fired or W rose above {level:g}; "
            "dot: the first broken snapshot).",
            "",
        ]
    broken = [r for r in rows if r["broke"]]
    lines += ["## Broken maps", ""]
    if broken:
        lines += [
            "| recording | topic | first break (s) | snapshot | W max |",
            "|---|---|---|---|---|",
        ]
        for r in broken:
            seconds = (r["first_break_ns"] - r["start_ns"]) / 1e9
            lines.append(
                f"| {_cell(r['name'])} | {_cell(r['first_break_topic'])} | {seconds:.1f} | "
                f"{r['first_break_index']} | {_fmt(r['w_max'])} |"
            )
    else:
        lines.append("None.")
    lines += ["", "## Failed recordings", ""]
    failed = [r for r in rows if r["status"] == "error"]
    if failed:
        # Their warnings here too (summary.json counts them among those that warned).
        lines += ["| recording | error | warnings |", "|---|---|---|"]
        lines += [
            f"| {_cell(r['name'])} | {_cell(r['error'] or '')} | "
            f"{_cell('; '.join(r['warnings']) or '-')} |"
            for r in failed
        ]
    else:
        lines.append("None.")
    lines += _losses_section(rows)
    lines += [
        "",
        "## All recordings",
        "",
        "| recording | format | status | snapshots | W min | W median | W max | broke |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {_cell(r['name'])} | {r['format'] or '-'} | {r['status']} | {r['snapshots']} | "
            f"{_fmt(r['w_min'])} | {_fmt(r['w_median'])} | {_fmt(r['w_max'])} | "
            f"{'yes' if r['broke'] else 'no'} |"
        )
    lines += [
        "",
        "Tables: `recordings.parquet` (one row per recording), `snapshots.parquet` (one row per "
        "snapshot); `summary.json`.",
        "",
    ]
    return "\n".join(lines)


def _losses_in_brief(summary: dict[str, Any]) -> str:
    """``; 1 damaged (what could be read kept, --salvage); 21 map messages skipped`` (empty when
    nothing was lost)."""
    parts = []
    if summary["salvaged"]:
        parts.append(f"{summary['salvaged']} damaged (what could be read kept, --salvage)")
    if summary["skipped_messages"]:
        parts.append(f"{counted(summary['skipped_messages'], 'map message')} skipped")
    return "".join(f"; {part}" for part in parts)


def _losses_section(rows: list[dict[str, Any]]) -> list[str]:
    """A table of the ``ok`` recordings that lost messages (damage, skipped maps) or warned."""
    hit = [
        r
        for r in rows
        if r["status"] == "ok" and (r["losses"] or r["skipped_messages"] or r["warnings"])
    ]
    if not hit:
        return []
    lines = [
        "",
        "## Recordings with losses or warnings",
        "",
        "| recording | lost (damaged, --salvage) | map messages skipped | warnings |",
        "|---|---|---|---|",
    ]
    for r in hit:
        skipped = (
            _cell(f"{r['skipped_messages']} ({r['skipped_reasons']})")
            if r["skipped_messages"]
            else "-"
        )
        lost = "; ".join(r["losses"]) or "-"
        # A salvaged recording's loss is also said as a warning: once is enough.
        warned = "; ".join(w for w in r["warnings"] if w not in r["losses"]) or "-"
        lines.append(f"| {_cell(r['name'])} | {_cell(lost)} | {skipped} | {_cell(warned)} |")
    return lines


def plotting_available() -> bool:
    """Whether matplotlib, which draws the figure (the ``plots`` extra), is installed."""
    return importlib.util.find_spec("matplotlib") is not None


def figure_png(report: BatchReport) -> bytes | None:
    """PNG of W over time per recording and map topic; None without matplotlib or snapshots."""
    try:
        # The object API with its own Agg canvas: no pyplot state, and the backend of a user who
        # calls run_batch from a notebook stays theirs.
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        return None
    series = []
    for result in report.results:
        topics = sorted({s["topic"] for s in result.snapshots})
        for topic in topics:
            rows = sorted(
                (s for s in result.snapshots if s["topic"] == topic), key=lambda s: s["index"]
            )
            name = printable(result.name)  # matplotlib refuses a non-UTF-8 file name's surrogates
            label = name if len(topics) == 1 else f"{name} {topic}"
            # A name with two dollars is mathtext to matplotlib: drawn as a formula, or, not one
            # (`r$\x$.mcap`), an error that lost the whole report; escaped, it shows as spelled.
            series.append((label.replace("$", r"\$"), rows))
    if not series:
        return None
    level = report.failure_level
    fig = Figure(figsize=(9, 4.5), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    broken_count = 0
    for label, rows in series:
        judged = [s for s in rows if row_judged(s)]
        times = [s["time_s"] for s in judged]
        scores = [s["structure_score"] for s in judged]
        first = next((s for s in rows if s["broken"]), None)
        if first is None:
            ax.plot(times, scores, ".-", color="0.65", linewidth=0.8, markersize=3, zorder=1)
            continue
        broken_count += 1
        shown = broken_count <= _LEGEND_MAX
        (line,) = ax.plot(times, scores, linewidth=1.6, zorder=3, label=label if shown else None)
        ax.plot(first["time_s"], first["structure_score"], "o", color=line.get_color(), zorder=4)
    if len(series) > broken_count:
        # Grey: no break (W below the level, and no break detected: a broken map may stay below).
        ax.plot([], [], ".-", color="0.65", label=f"{len(series) - broken_count} did not break")
    ax.axhline(
        level, color="tab:red", linestyle="--", linewidth=1, label=f"failure level {level:g}"
    )
    ax.set_xlabel("time since the recording's first message (s)")
    ax.set_ylabel("structure score W")
    ax.set_ylim(0, 1.02)
    ax.set_title(f"W over time: {len(series)} map series, {broken_count} broken")
    if broken_count > _LEGEND_MAX:
        ax.plot([], [], " ", label=f"... and {broken_count - _LEGEND_MAX} more broken")
    ax.legend(loc="upper left", fontsize=7, framealpha=0.9)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", metadata={"Software": None})
    return buffer.getvalue()


def warm_imports() -> threading.Thread:
    """Import the figure's modules (about half a second) in a daemon thread, started while the
    recordings run: the report is drawn sooner when they are done."""

    def load() -> None:
        with contextlib.suppress(ImportError):
            import matplotlib.backends.backend_agg
            import matplotlib.figure  # noqa: F401

    thread = threading.Thread(target=load, name="rose-report-imports", daemon=True)
    thread.start()
    return thread
