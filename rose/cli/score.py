"""``rose score MAP...``: W and the dominant directions of map files, as a table or JSON."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from rose.cli.options import (
    add_limit_arguments,
    add_param_arguments,
    load_grid_map,
    params_from_args,
    result_summary,
)
from rose.outputs import json_text
from rose.pipeline import analyze

__all__ = ["add_parser", "run"]


def add_parser(commands: Any) -> None:
    """Register ``score`` on an argparse subparsers object (``func=run``)."""
    score = commands.add_parser("score", help="W and dominant directions of maps")
    score.add_argument("maps", type=Path, nargs="+", metavar="MAP")
    score.add_argument(
        "--json",
        action="store_true",
        help="print strict JSON instead of a table (non-finite: null)",
    )
    add_limit_arguments(score)
    add_param_arguments(score)
    score.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    records = []
    for path in args.maps:
        source = load_grid_map(path, max_cells=args.max_cells)
        started = time.perf_counter()
        result = analyze(source.grid, params)
        summary = result_summary(result, seconds=time.perf_counter() - started)
        records.append({"map": str(path), **summary})
    if args.json:
        print(json_text(records), end="")
        return 0
    width = max(len("map"), *(len(r["map"]) for r in records))
    print(f"{'map':<{width}}  {'W':>6}  {'directions (deg)':<24}  {'occupied':>9}  {'clutter':>8}")
    for r in records:
        dirs = ", ".join(f"{d:.1f}" for d in r["dominant_directions_deg"]) or "none"
        print(f"{r['map']:<{width}}  {r['structure_score']:6.3f}  {dirs:<24}  "
              f"{r['occupied_cells']:>9}  {r['clutter_cells']:>8}")  # fmt: skip
    return 0
