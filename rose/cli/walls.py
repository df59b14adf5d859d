"""``rose walls MAP``: wall segments of a map file, printed and optionally exported (GeoJSON / SVG)."""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING, Any, TextIO

from rose.cli.options import (
    add_map_arguments,
    file_arg,
    float_up_to,
    load_grid_map,
    map_arg,
    result_summary,
    verdict,
)
from rose.directions import degenerate_input, fold_deg
from rose.limits import visible
from rose.outputs import (
    OutputSet,
    counted,
    json_text,
    refuse_output_in_bag_folder,
    suffix_warning,
)

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

    from rose.result import RoseResult
    from rose.walls import WallSet

__all__ = ["add_parser", "format_walls_table", "run"]


#: Longest --min-length (metres): a wall of 1000 km is past any map (1e308 overflowed to inf cells).
_MAX_MIN_LENGTH_M = 1e6


def add_parser(subparsers: Any) -> None:
    """Add the ``walls`` subcommand to an ``argparse`` subparsers object.

    The subparser's defaults set ``func=run``.
    """
    parser = subparsers.add_parser(
        "walls",
        help="extract wall segments (ROSE-snapped, or the plain Hough baseline)",
        description=(
            "Find wall segments in MAP (map_server YAML, or a PGM/PNG image) and print them in the "
            "map frame. By default walls are found on the cells ROSE labels structure (the paper's "
            "labelling, not `rose clean`'s walls method) and snapped to its dominant directions; "
            "--hough gives the probabilistic-Hough baseline on the raw map."
        ),
    )
    parser.add_argument("map", type=map_arg, metavar="MAP", help="map YAML or image file")
    out = parser.add_mutually_exclusive_group()
    out.add_argument(
        "--geojson", type=file_arg, metavar="FILE", help="write the walls as GeoJSON ('-': stdout)"
    )
    out.add_argument(
        "--svg", type=file_arg, metavar="FILE", help="write the walls as SVG ('-': stdout)"
    )
    parser.add_argument("-f", "--force", action="store_true", help="replace an existing file")
    add_map_arguments(parser)
    parser.add_argument(
        "--hough", action="store_true", help="baseline: Hough on the raw map, no ROSE"
    )
    parser.add_argument(
        "--min-length",
        type=float_up_to(_MAX_MIN_LENGTH_M, zero=True),
        default=None,
        metavar="M",
        help="drop walls shorter than M metres (default: 10 cells)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace, *, stdout: TextIO | None = None) -> int:
    """Run ``rose walls``: print a table of segments, write GeoJSON or SVG if asked; return 0.

    Raises
    ------
    RoseError
        ``MapFileError`` for an unreadable map or an unwritable output, ``RoseError`` for bad values;
        messages are one line, for the caller's single error handler.
    """
    out = stdout if stdout is not None else sys.stdout
    occupancy_map = load_grid_map(args.map, max_cells=args.max_cells, resolution_m=args.resolution)
    outputs = OutputSet(inputs=occupancy_map.input_files, force=args.force, ends_run=True)
    refuse_output_in_bag_folder(args.geojson, "--geojson", what="GeoJSON file")
    refuse_output_in_bag_folder(args.svg, "--svg", what="SVG drawing")
    outputs.check(args.geojson, args.svg)
    # After the checks: a refused output is refused alone, not warned about first.
    for warning in (
        suffix_warning(args.geojson, (".geojson", ".json"), "GeoJSON"),
        suffix_warning(args.svg, ".svg", "an SVG drawing"),
    ):
        if warning is not None:
            print(visible(warning), file=sys.stderr)
    # scipy and the wall extraction: loaded by the command, not by the parser.
    from rose.pipeline import analyze
    from rose.walls import WallParams, extract_walls, extract_walls_hough
    from rose.walls.export import walls_to_geojson, walls_to_svg

    params = WallParams()
    if args.min_length is not None:
        params = WallParams(min_wall_length_px=args.min_length / occupancy_map.resolution_m)
    note = None
    if args.hough:
        walls = extract_walls_hough(occupancy_map, params=params)
    else:
        result = analyze(occupancy_map.grid, occupied_threshold=params.occupied_threshold)
        walls = extract_walls(occupancy_map, result, params=params)
        note = _out_of_domain(occupancy_map.grid, result)
    with outputs:
        if args.geojson is not None:
            text = json_text(walls_to_geojson(walls), indent=1)
            outputs.write_bytes(args.geojson, text.encode("utf-8"))
        if args.svg is not None:
            outputs.write_bytes(args.svg, walls_to_svg(walls).encode("utf-8"))
    if outputs.uses_stdout:
        out = sys.stderr
    out.write(format_walls_table(walls))
    if note is not None:
        out.write(f"note: {visible(str(args.map), keep_undecodable=True)}: {note}\n")
    for path in (args.geojson, args.svg):
        if path is not None and str(path) != "-":  # on standard output, the data says it itself
            out.write(f"wrote {visible(str(path), keep_undecodable=True)}\n")
    return 0


def _out_of_domain(grid: npt.NDArray[np.int8], result: RoseResult) -> str | None:
    """Why W says nothing about the map (no structure found, too few occupied cells, a map outside
    ROSE's domain), in the words ``rose score`` and ``rose clean`` use; None when it judges it. The
    walls are snapped to ROSE's directions: on a solid block those are its rectangle's, not a
    building's, and the table alone passed them for walls."""
    summary = result_summary(result, degenerate=degenerate_input(grid, result.occupied))
    if summary["has_structure"] is True:
        return None
    return verdict(
        result.structure_score,
        occupied_cells=result.occupied_count,
        has_structure=summary["has_structure"] is not False,
        degenerate=summary["degenerate"],
    )


def format_walls_table(walls: WallSet) -> str:
    """A plain-text table of the walls (map frame, metres and degrees), with a summary line."""
    rows = [
        (*seg.start_m, *seg.end_m, seg.length_m, math.degrees(seg.orientation_rad))
        for seg in walls.segments
    ]
    finite = [abs(v) for r in rows for v in r[:5] if math.isfinite(v)]
    metres = _metres_format(walls.resolution_m, max(finite, default=0.0))
    # Folded after rounding, as every report: a wall at -0.00002 degrees read 180.00.
    texts = [[format(v, metres) for v in r[:5]] + [f"{fold_deg(r[5], 2):.2f}"] for r in rows]
    heads = ("x0_m", "y0_m", "x1_m", "y1_m", "length_m", "angle_deg")
    least = (9, 9, 9, 9, 8, 9)  # the usual table's columns
    width = [max([least[k], *(len(t[k]) for t in texts)]) for k in range(len(heads))]

    def line(first: str, cells: list[str] | tuple[str, ...]) -> str:
        x0, y0, x1, y1, length, angle = (c.rjust(w) for c, w in zip(cells, width, strict=True))
        return f"{first:>4}  {x0} {y0}  {x1} {y1}  {length}  {angle}"

    total = walls.lengths_m.sum()
    lines = [
        f"{counted(len(walls), 'wall')} ({walls.method}), total length "
        f"{format(total, '.2f' if metres == '.3f' else metres)} m",
        line("#", heads),
        *(line(str(i), t) for i, t in enumerate(texts)),
    ]
    return "\n".join(lines) + "\n"


def _metres_format(resolution_m: float, largest_m: float) -> str:
    """A tenth of a cell, millimetres at least: fixed decimals (--resolution 1e-9 printed every
    length as 0.000); below 1e-11 m per cell, enough significant digits at the largest value."""
    places = max(3, math.ceil(-math.log10(resolution_m)) + 1)
    if places <= 12:
        return f".{places}f"
    digits = math.ceil(math.log10(max(largest_m, resolution_m) / resolution_m)) + 2
    return f".{min(max(digits, 4), 17)}g"
