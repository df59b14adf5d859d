"""``rose clean MAP -o OUT.yaml``: the decluttered map as a map_server map."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

from rose.cleaning import CLEAN_METHODS, CleanResult, clean, rules_cells_text
from rose.cli.options import (
    add_map_arguments,
    add_param_arguments,
    cells,
    directions_deg,
    file_arg,
    load_grid_map,
    map_arg,
    params_from_args,
    resolution_assumed,
    result_summary,
    verdict,
)
from rose.directions import degenerate_input
from rose.errors import MapFileError
from rose.limits import visible
from rose.mapfile import SAVED_OCCUPIED_FROM, OccupancyMap, map_image_path, save_map
from rose.outputs import STDOUT, OutputSet, refuse_output_in_bag_folder, suffix_warning

__all__ = ["add_parser", "cleaning_summary", "run"]


def add_parser(commands: Any) -> None:
    """Register ``clean`` on an argparse subparsers object (``func=run``)."""
    clean = commands.add_parser(
        "clean",
        help="remove clutter from a map, write a map_server map",
        description="Remove the clutter from a map and write the cleaned map as a map_server YAML "
        "and image: by default the walls cleaning (walls kept, no gap a robot fits through), "
        "or the paper's labelling with --method paper.",
    )
    clean.add_argument("map", type=map_arg, help="map_server YAML or a PGM/PNG image")
    clean.add_argument(
        "-o", "--output", type=file_arg, required=True, help="output YAML (PGM beside it)"
    )
    clean.add_argument(
        "--json", type=file_arg, metavar="REPORT", help="also write a JSON report ('-': stdout)"
    )
    clean.add_argument("-f", "--force", action="store_true", help="replace existing output files")
    add_map_arguments(clean)
    clean.add_argument(
        "--method",
        "--clean-method",  # rose-bag process's name for the same choice
        dest="method",
        choices=CLEAN_METHODS,
        default="walls",
        help="walls: remove clutter, keep every wall, open no robot-sized gap (default); "
        "paper: the paper's labelling as it is",
    )
    add_param_arguments(clean)
    clean.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    source = load_grid_map(args.map, max_cells=args.max_cells, resolution_m=args.resolution)
    outputs = OutputSet(inputs=source.input_files, force=args.force, ends_run=True)
    output_path = Path(args.output)
    if str(args.output) == STDOUT:
        msg = "-: a map cannot go to standard output (it is a YAML file and its image beside it)"
        raise MapFileError(msg)
    if output_path.suffix.lower() not in (".yaml", ".yml"):
        msg = f"{output_path}: the output map must be a .yaml file"
        raise MapFileError(msg)
    # Refuse bad outputs (inside a ROS 2 bag, an input, the map's image, each other, existing)
    # before computing anything. A map file is no recording: a bag folder holding it is refused too.
    refuse_output_in_bag_folder(output_path, "-o", what="output map")
    # Its image too: a symlink where the image goes is followed (into a bag folder, say).
    refuse_output_in_bag_folder(map_image_path(output_path), "-o", what="output map's image")
    refuse_output_in_bag_folder(args.json, "--json", what="JSON report")
    outputs.check(output_path, map_image_path(output_path), args.json)
    # After the checks: a refused output is refused alone, not warned about first.
    warning = suffix_warning(args.json, ".json", "a JSON report")
    if warning is not None:
        print(visible(warning), file=sys.stderr)
    from rose.pipeline import analyze  # scipy: loaded by the command, not by the parser

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
    degenerate = degenerate_input(source.grid, result.occupied)
    summary = result_summary(
        result, seconds=elapsed, yaw_rad=source.origin_yaw_rad, degenerate=degenerate
    )
    summary.update(cleaning_summary(cleaning))
    summary["resolution_m"] = source.resolution_m
    # The walls rules work on cells of the size they were designed for: a coarse map's are split,
    # a fine one's joined.
    from rose.cleaning_rules import rules_cell_m  # loaded by the cleaning already

    walls = cleaning.method == "walls"
    cell_m = rules_cell_m(source.resolution_m) if walls else source.resolution_m
    summary["rules_cell_m"] = cell_m if walls else None
    # The rules' lengths are metres: a result at an assumed cell size says so.
    summary["resolution_assumed"] = resolution_assumed(args.map, args.resolution)
    summary["input"] = str(args.map)
    summary["output"] = str(args.output)
    with outputs:  # all files or none
        image_path = save_map(
            output_path,
            output,
            # Written occupied from the threshold analysed with, or map_saver's 65 if that is
            # lower: the cells 65..N-1 ROSE did not count were walls of the input all the same.
            occupied_threshold=min(result.params.occupied_threshold, SAVED_OCCUPIED_FROM),
            outputs=outputs,
        )
        if args.json is not None:
            outputs.write_json(args.json, summary)
    out = sys.stderr if outputs.uses_stdout else sys.stdout
    rows, cols = result.occupied.shape
    share = cleaning.removed_count / result.occupied_count if result.occupied_count else 0.0
    threshold = summary["threshold"]
    angles = ", ".join(f"{d:.2f}" for d in directions_deg(result, yaw_rad=source.origin_yaw_rad))
    directions = f"{angles} deg" if angles else "none"
    w_reading = verdict(
        result.structure_score,
        occupied_cells=result.occupied_count,
        has_structure=result.has_structure,
        degenerate=degenerate,
    )
    lines = [
        # Names escaped (a newline or tab in a file name broke the summary's lines).
        f"map          {visible(str(args.map), keep_undecodable=True)}  "
        f"({cols} x {rows} cells, {source.resolution_m:g} m/cell)",
        f"W            {result.structure_score:.3f}  ({w_reading})",
        f"directions   {directions}",
        f"threshold    {f'{threshold:.6f}' if threshold is not None and math.isfinite(threshold) else 'n/a'}",
        f"occupied     {cells(result.occupied_count)}",
        f"method       {cleaning.method}"
        + (
            f" (on the map's cells {rules_cells_text(source.resolution_m)}, the size the rules "
            "were made for)"
            if cell_m != source.resolution_m
            else ""
        ),
        f"removed      {cells(cleaning.removed_count)} ({share:.1%}), set to {params.clutter_value}",
        f"kept         {cells(cleaning.kept_count)} ({cleaning.rescued_count} of them against "
        f"the paper's labelling, {cleaning.guarded_count} by the gap guard)",
        f"completed    {cells(cleaning.completed_count, 'unknown')} made walls (wall lines "
        "hidden behind what the rules took for clutter)",
        f"written      {visible(str(args.output), keep_undecodable=True)} + "
        + visible(_beside(image_path, Path(args.output)), keep_undecodable=True)
        + (
            f" + {visible(str(args.json), keep_undecodable=True)}"
            if args.json is not None and not outputs.uses_stdout
            else ""
        ),
        f"time         {elapsed * 1000:.0f} ms",
    ]
    print("\n".join(lines), file=out)
    return 0


def cleaning_summary(cleaning: CleanResult) -> dict[str, Any]:
    """JSON-ready counts of a cleaning: method, cells removed, kept, rescued, kept by the guard, and
    unknown cells completed as walls (so removed + kept + completed add up to the output's walls
    plus what was removed)."""
    return {
        "method": cleaning.method,
        "removed_cells": cleaning.removed_count,
        "kept_cells": cleaning.kept_count,
        "rescued_cells": cleaning.rescued_count,
        "guarded_cells": cleaning.guarded_count,
        "completed_cells": cleaning.completed_count,
    }


def _beside(image: Path, yaml_path: Path) -> str:
    """The image's name when it lies beside the YAML as given, else its path (a symlinked YAML's
    image lies beside the link's target)."""
    return image.name if image.parent == yaml_path.parent else str(image)
