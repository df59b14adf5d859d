"""The ``rose`` command: ROSE on single map files.

``rose clean MAP -o OUT.yaml`` writes the decluttered map; ``rose score MAP...`` prints W and the
dominant directions. Errors are one line on stderr with exit code 1 (2 for usage errors).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rose.errors import RoseError
from rose.mapfile import OccupancyMap, load_map, save_map, write_atomically
from rose.pipeline import analyze, make_params
from rose.result import RoseParams, RoseResult
from rose.walls_cli import add_walls_parser

__all__ = [
    "add_param_arguments",
    "fraction",
    "main",
    "non_negative_float",
    "params_from_args",
    "positive_float",
    "result_summary",
]


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError as err:
        msg = f"expected a number, got {text!r}"
        raise argparse.ArgumentTypeError(msg) from err
    if not math.isfinite(value):
        msg = f"expected a finite number, got {text!r}"
        raise argparse.ArgumentTypeError(msg)
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0 (usage error otherwise)."""
    value = _number(text)
    if value <= 0:
        msg = f"expected a positive number, got {text!r}"
        raise argparse.ArgumentTypeError(msg)
    return value


def non_negative_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    value = _number(text)
    if value < 0:
        msg = f"expected a number >= 0, got {text!r}"
        raise argparse.ArgumentTypeError(msg)
    return value


def fraction(text: str) -> float:
    """argparse type: a number in (0, 1]."""
    value = positive_float(text)
    if value > 1:
        msg = f"expected a number in (0, 1], got {text!r}"
        raise argparse.ArgumentTypeError(msg)
    return value


def add_param_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ROSE tuning options (defaults from :class:`RoseParams`) to ``parser``."""
    d = RoseParams()
    group = parser.add_argument_group("ROSE parameters")
    group.add_argument(
        "--peak-prominence",
        type=fraction,
        default=d.peak_prominence,
        metavar="F",
        help="dominant-direction prominence as a fraction of max-min (default %(default)s)",
    )
    group.add_argument(
        "--angular-resolution",
        type=positive_float,
        default=d.angular_resolution_deg,
        metavar="DEG",
        help="direction bin width in degrees (default %(default)s)",
    )
    group.add_argument(
        "--smoothing",
        type=non_negative_float,
        default=d.smoothing_deg,
        metavar="DEG",
        help="angular smoothing of the cumulative amplitude (default %(default)s)",
    )
    group.add_argument(
        "--mask-half-width",
        type=positive_float,
        default=d.mask_half_width_px,
        metavar="PX",
        help="half-width of the spectrum strip kept per direction (default %(default)s)",
    )
    group.add_argument(
        "--occupied-threshold",
        type=int,
        default=d.occupied_threshold,
        metavar="P",
        help="occupancy (percent) from which a cell is occupied (default %(default)s)",
    )
    group.add_argument(
        "--threshold-mode",
        choices=("gmm", "fixed"),
        default=d.threshold_mode,
        help="gmm: Gaussian-mixture intersection (paper); fixed: --fixed-threshold",
    )
    group.add_argument(
        "--fixed-threshold",
        type=fraction,
        default=d.fixed_threshold,
        metavar="F",
        help="score threshold of the fixed mode, fraction of the top score (default %(default)s)",
    )
    group.add_argument(
        "--clutter-value",
        choices=("free", "unknown"),
        default=d.clutter_value,
        help="what clutter cells become in the cleaned map (default %(default)s)",
    )
    group.add_argument("--seed", type=int, default=d.seed, help="mixture seed (default %(default)s)")  # fmt: skip


def params_from_args(args: argparse.Namespace) -> RoseParams:
    """The :class:`RoseParams` given by the options of :func:`add_param_arguments`."""
    return make_params(
        peak_prominence=args.peak_prominence,
        angular_resolution_deg=args.angular_resolution,
        smoothing_deg=args.smoothing,
        mask_half_width_px=args.mask_half_width,
        occupied_threshold=args.occupied_threshold,
        threshold_mode=args.threshold_mode,
        fixed_threshold=args.fixed_threshold,
        clutter_value=args.clutter_value,
        seed=args.seed,
    )


def directions_deg(result: RoseResult) -> list[float]:
    """Dominant directions in degrees, rounded to 0.01 and folded into [0, 180)."""
    return [round(float(np.degrees(a)), 2) % 180.0 for a in result.dominant_directions]


def result_summary(result: RoseResult, *, seconds: float | None = None) -> dict[str, Any]:
    """JSON-ready summary of a result: W, directions (degrees), threshold, counts."""
    summary: dict[str, Any] = {
        "structure_score": round(result.structure_score, 6),
        "has_structure": result.has_structure,
        "dominant_directions_deg": directions_deg(result),
        "threshold": None if math.isnan(result.threshold) else round(result.threshold, 6),
        "occupied_cells": result.occupied_count,
        "clutter_cells": result.clutter_count,
        "shape": list(result.occupied.shape),
    }
    if seconds is not None:
        summary["seconds"] = round(seconds, 4)
    return summary


def _run_clean(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    source = load_map(args.map)
    started = time.perf_counter()
    result = analyze(source.grid, params)
    elapsed = time.perf_counter() - started
    output = OccupancyMap(
        grid=result.cleaned,
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
    summary["input"] = str(args.map)
    summary["output"] = str(args.output)
    if args.json:
        text = json.dumps(summary, indent=2) + "\n"
        write_atomically(Path(args.json), lambda f: f.write(text.encode()))
    rows, cols = result.occupied.shape
    share = result.clutter_count / result.occupied_count if result.occupied_count else 0.0
    print(f"map          {args.map}  ({cols} x {rows} cells, {source.resolution_m:g} m/cell)")
    print(f"W            {result.structure_score:.3f}  ({_verdict(result.structure_score)})")
    print(f"directions   {', '.join(f'{d:.1f}' for d in directions_deg(result)) or 'none'} deg")
    print(f"threshold    {summary['threshold'] if summary['threshold'] is not None else 'n/a'}")
    print(f"occupied     {result.occupied_count} cells")
    print(f"clutter      {result.clutter_count} cells ({share:.1%}), set to {params.clutter_value}")
    print(f"written      {args.output} + {image_path.name}")
    print(f"time         {elapsed * 1000:.0f} ms")
    return 0


def _input_files(source: OccupancyMap) -> set[Path]:
    if source.source is None:
        return set()
    files = {source.source.resolve()}
    if source.source.suffix.lower() in (".yaml", ".yml"):
        files |= {p.resolve() for p in source.source.parent.glob(source.source.stem + ".*")}
    return files


def _verdict(score: float) -> str:
    if score < 0.2:
        return "structured: decluttering can be trusted"
    if score <= 0.4:
        return "weak structure: check the result"
    return "little structure: decluttering has likely failed"


def _run_score(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    records = []
    for path in args.maps:
        source = load_map(path)
        started = time.perf_counter()
        result = analyze(source.grid, params)
        summary = result_summary(result, seconds=time.perf_counter() - started)
        records.append({"map": str(path), **summary})
    if args.json:
        print(json.dumps(records, indent=2))
        return 0
    width = max(len("map"), *(len(r["map"]) for r in records))
    print(f"{'map':<{width}}  {'W':>6}  {'directions (deg)':<24}  {'occupied':>9}  {'clutter':>8}")
    for r in records:
        dirs = ", ".join(f"{d:.1f}" for d in r["dominant_directions_deg"]) or "none"
        print(f"{r['map']:<{width}}  {r['structure_score']:6.3f}  {dirs:<24}  "
              f"{r['occupied_cells']:>9}  {r['clutter_cells']:>8}")  # fmt: skip
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``rose`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="rose", description="ROSE structure extraction and decluttering for map files."
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    clean = commands.add_parser("clean", help="remove clutter from a map, write a map_server map")
    clean.add_argument("map", type=Path, help="map_server YAML or a PGM/PNG image")
    clean.add_argument(
        "-o", "--output", type=Path, required=True, help="output YAML (PGM beside it)"
    )
    clean.add_argument("--json", type=Path, metavar="REPORT", help="also write a JSON report")
    add_param_arguments(clean)
    clean.set_defaults(func=_run_clean)

    score = commands.add_parser("score", help="W and dominant directions of maps")
    score.add_argument("maps", type=Path, nargs="+", metavar="MAP")
    score.add_argument("--json", action="store_true", help="print JSON instead of a table")
    add_param_arguments(score)
    score.set_defaults(func=_run_score)

    add_walls_parser(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``rose`` command; return the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s: %(message)s")
    try:
        return int(args.func(args))
    except RoseError as err:
        if args.debug:
            raise
        print(f"error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
