"""``rose clean MAP -o OUT.yaml``: the decluttered map as a map_server map."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from rose.clean import CLEAN_METHODS, CleanResult, clean
from rose.cli.options import (
    add_param_arguments,
    directions_deg,
    params_from_args,
    result_summary,
    verdict,
)
from rose.errors import RoseError
from rose.mapfile import OccupancyMap, load_map, save_map, write_atomically
from rose.pipeline import analyze

__all__ = ["add_parser", "cleaning_summary", "run"]


def add_parser(commands: Any) -> None:
    """Register ``clean`` on an argparse subparsers object (``func=run``)."""
    clean = commands.add_parser("clean", help="remove clutter from a map, write a map_server map")
    clean.add_argument("map", type=Path, help="map_server YAML or a PGM/PNG image")
    clean.add_argument(
        "-o", "--output", type=Path, required=True, help="output YAML (PGM beside it)"
    )
    clean.add_argument("--json", type=Path, metavar="REPORT", help="also write a JSON report")
    clean.add_argument(
        "--method",
        choices=CLEAN_METHODS,
        default="walls",
        help="walls: remove clutter, keep every wall, open no robot-sized gap (default); "
        "paper: the paper's labelling as it is",
    )
    add_param_arguments(clean)
    clean.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    source = load_map(args.map)
    started = time.perf_counter()
    result = analyze(source.grid, params)
    cleaning = clean(source.grid, result, method=args.method, resolution_m=source.resolution_m)
    elapsed = time.perf_counter() - started
    output = OccupancyMap(
        grid=cleaning.cleaned,
        resolution_m=source.resolution_m,
        origin_xy_m=source.origin_xy_m,
        origin_yaw_rad=source.origin_yaw_rad,
    )
    for target in (Path(args.output), Path(args.output).with_suffix(".pgm")):
        if target.resolve() in _input_files(source):
            msg = f"{target}: refusing to overwrite the input map"
            raise RoseError(msg)
    image_path = save_map(args.output, output)
    summary = result_summary(result, seconds=elapsed)
    summary.update(cleaning_summary(cleaning))
    summary["input"] = str(args.map)
    summary["output"] = str(args.output)
    if args.json:
        text = json.dumps(summary, indent=2) + "\n"
        write_atomically(Path(args.json), lambda f: f.write(text.encode()))
    rows, cols = result.occupied.shape
    share = cleaning.removed_count / result.occupied_count if result.occupied_count else 0.0
    print(f"map          {args.map}  ({cols} x {rows} cells, {source.resolution_m:g} m/cell)")
    print(f"W            {result.structure_score:.3f}  ({verdict(result.structure_score)})")
    print(f"directions   {', '.join(f'{d:.1f}' for d in directions_deg(result)) or 'none'} deg")
    print(f"threshold    {summary['threshold'] if summary['threshold'] is not None else 'n/a'}")
    print(f"occupied     {result.occupied_count} cells")
    print(f"method       {cleaning.method}")
    print(
        f"removed      {cleaning.removed_count} cells ({share:.1%}), set to {params.clutter_value}"
    )
    print(
        f"kept         {cleaning.kept_count} cells ({cleaning.rescued_count} of them against "
        f"the paper's labelling, {cleaning.guarded_count} by the gap guard)"
    )
    print(f"written      {args.output} + {image_path.name}")
    print(f"time         {elapsed * 1000:.0f} ms")
    return 0


def cleaning_summary(cleaning: CleanResult) -> dict[str, Any]:
    """JSON-ready counts of a cleaning: method, cells removed, kept, rescued, kept by the guard."""
    return {
        "method": cleaning.method,
        "removed_cells": cleaning.removed_count,
        "kept_cells": cleaning.kept_count,
        "rescued_cells": cleaning.rescued_count,
        "guarded_cells": cleaning.guarded_count,
    }


def _input_files(source: OccupancyMap) -> set[Path]:
    if source.source is None:
        return set()
    files = {source.source.resolve()}
    if source.source.suffix.lower() in (".yaml", ".yml"):
        files |= {p.resolve() for p in source.source.parent.glob(source.source.stem + ".*")}
    return files
