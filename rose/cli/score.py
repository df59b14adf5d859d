"""``rose score MAP...``: W and the dominant directions of map files, as a table or JSON.

A map that cannot be read or analysed is reported (one ``error:`` line on stderr, and in ``--json``
a record with its ``error``) and the others are still scored; the exit code is then 1.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from rose.cli.options import (
    add_limit_arguments,
    add_param_arguments,
    load_grid_map,
    map_arg,
    params_from_args,
    result_summary,
    verdict,
)
from rose.directions import degenerate_input
from rose.errors import RoseError
from rose.limits import visible
from rose.outputs import json_text
from rose.params import RoseParams
from rose.signals import reraise_interrupt_behind

__all__ = ["add_parser", "run"]


def add_parser(commands: Any) -> None:
    """Register ``score`` on an argparse subparsers object (``func=run``)."""
    score = commands.add_parser(
        "score",
        help="W and dominant directions of maps",
        description="Score the structure of maps: W (near 0 strong structure, above 0.4 ROSE has "
        "failed) and the dominant wall directions of each map, as a table or JSON.",
    )
    score.add_argument(
        "maps", type=map_arg, nargs="+", metavar="MAP", help="map_server YAML or a PGM/PNG image"
    )
    score.add_argument(
        "--json",
        action="store_true",
        help="print strict JSON instead of a table (non-finite: null)",
    )
    add_limit_arguments(score)  # no --resolution: W does not depend on it
    add_param_arguments(score, writes_map=False)
    score.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    records = [_score(path, args, params) for path in args.maps]
    failed = sum("error" in r for r in records)
    if args.json:
        print(json_text(records), end="")
        _say_failed(failed, len(records))
        return 1 if failed else 0
    scored = [r for r in records if "error" not in r]
    if scored:
        # A name with a newline or tab (a valid file name) printed raw broke the table's rows.
        names = {id(r): visible(r["map"], keep_undecodable=True) for r in scored}
        width = max(len("map"), *(len(name) for name in names.values()))
        print(
            f"{'map':<{width}}  {'W':>6}   {'directions (deg)':<24}  {'occupied':>9}  {'clutter':>8}"
        )
        # A W that says nothing (no structure found, too few occupied cells, a solid block) must
        # not pass for a building's: marked in its row, the reason under the table (as `clean`).
        unjudged = [r for r in scored if r["has_structure"] is not True]
        for r in scored:
            dirs = ", ".join(f"{d:.2f}" for d in r["dominant_directions_deg"]) or "none"
            mark = " " if r["has_structure"] is True else "*"
            print(f"{names[id(r)]:<{width}}  {r['structure_score']:6.3f}{mark}  {dirs:<24}  "
                  f"{r['occupied_cells']:>9}  {r['clutter_cells']:>8}")  # fmt: skip
        for r in unjudged:
            reading = verdict(
                r["structure_score"],
                occupied_cells=r["occupied_cells"],
                has_structure=r["has_structure"] is not False,
                degenerate=r["degenerate"],
            )
            print(f"* {names[id(r)]}: {reading}")
    _say_failed(failed, len(records))
    return 1 if failed else 0


def _say_failed(failed: int, maps: int) -> None:
    """The last ``error:`` line of several maps some of which failed: how many (with ``--json``
    too, where it was left out and the lines above it were the only count)."""
    if failed and maps > 1:  # one map: its own error line says it all
        print(f"error: {failed} of {maps} maps could not be scored", file=sys.stderr)


def _score(path: Path, args: argparse.Namespace, params: RoseParams) -> dict[str, Any]:
    """The summary record of one map, or ``{"map", "error"}`` (also printed) when it fails."""
    from rose.cli import error_text  # the package imports this module: import at call time
    from rose.pipeline import analyze  # scipy: loaded by the command, not by the parser

    try:
        source = load_grid_map(path, max_cells=args.max_cells, metric=False)
        started = time.perf_counter()
        result = analyze(source.grid, params)
    except (RoseError, OSError, MemoryError) as err:
        reraise_interrupt_behind(err)  # a signal inside a library: exit 130 / 143, not "error"
        text = error_text(err, where=str(path))
        if getattr(args, "debug", False):  # the traceback, as --debug gives it for other commands
            import traceback

            traceback.print_exception(err, file=sys.stderr)
        print(f"error: {text}", file=sys.stderr)
        return {"map": str(path), "error": text}
    seconds = time.perf_counter() - started
    summary = result_summary(
        result,
        seconds=seconds,
        yaw_rad=source.origin_yaw_rad,
        degenerate=degenerate_input(source.grid, result.occupied),
    )
    return {"map": str(path), **summary}
