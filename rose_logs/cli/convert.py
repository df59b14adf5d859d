"""``rose-bag convert LOG OUT``: a CARMEN laser log as a ROS mapping session (scans, poses, map snapshots)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from rose_logs.carmen.parse import read_carmen_log
from rose_logs.carmen.raycast import BuilderParams
from rose_logs.carmen.session import SessionOptions, write_carmen_session
from rose_logs.errors import LogWriteError

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    """Add the ``convert`` sub-command (CARMEN log -> ROS session) to argparse sub-parsers."""
    parser = subparsers.add_parser(
        "convert",
        help="turn a CARMEN laser log into a ROS mapping session (/scan, /tf or /odom, /map)",
        description="Parse a CARMEN log (.log or .log.gz), build occupancy-grid snapshots by ray "
        "casting, optionally add odometry drift, and write a ROS 1 bag, ROS 2 db3 or MCAP bag.",
    )
    parser.add_argument("log", type=Path, help="CARMEN log, plain or gzip")
    parser.add_argument("output", type=Path, help="*.bag (ROS 1), *.mcap or a folder (ROS 2 db3)")
    parser.add_argument(
        "--format",
        choices=("ros1", "db3", "mcap"),
        default=None,
        dest="fmt",
        help="output format (default: from the output name)",
    )
    parser.add_argument("--resolution", type=float, default=0.05, help="map cell size, m (0.05)")
    parser.add_argument(
        "--max-range",
        type=float,
        default=30.0,
        help="readings at or beyond this are 'no return', m (30)",
    )
    parser.add_argument(
        "--map-period", type=float, default=10.0, help="log seconds between /map snapshots (10)"
    )
    parser.add_argument(
        "--pose",
        choices=("tf", "odom", "both"),
        default="tf",
        help="pose output: /tf, /odom or both (tf)",
    )
    parser.add_argument(
        "--drift-level",
        type=float,
        default=0.0,
        help="odometry drift level, 0 = corrected poses (see rose_logs.carmen.drift)",
    )
    parser.add_argument("--drift-seed", type=int, default=0, help="seed of the drift (0)")
    parser.add_argument(
        "--drift-start",
        type=float,
        default=0.0,
        help="seconds after the first scan when drift starts (0)",
    )
    parser.add_argument("--max-scans", type=int, default=None, help="use only the first N scans")
    parser.add_argument("--force", action="store_true", help="replace an existing output")
    parser.add_argument(
        "--map-file",
        type=Path,
        default=None,
        help="also save the final map as map_server YAML + PGM at this path",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``convert`` from parsed arguments; prints a one-line summary to stdout. Returns 0."""
    log = read_carmen_log(args.log, max_scans=args.max_scans)
    if log.malformed:
        print(f"warning: skipped {log.malformed} malformed FLASER lines", file=sys.stderr)
    try:
        options = SessionOptions(
            builder_params=BuilderParams(resolution_m=args.resolution, max_range_m=args.max_range),
            map_period_s=args.map_period,
            pose_output=args.pose,
            drift_level=args.drift_level,
            drift_seed=args.drift_seed,
            drift_start_s=args.drift_start,
        )
        summary = write_carmen_session(
            log, args.output, fmt=args.fmt, options=options, force=args.force
        )
    except ValueError as err:  # a parameter out of range: one line, like every other error
        msg = f"{args.output}: {err}"
        raise LogWriteError(msg) from err
    if args.map_file is not None:
        import rose

        rose.save_map(
            args.map_file,
            rose.OccupancyMap(
                grid=summary.final_grid,
                resolution_m=summary.resolution_m,
                origin_xy_m=summary.final_origin_xy_m,
            ),
        )
    print(
        f"{summary.path}: {summary.format}, {summary.scans} scans, {summary.maps} maps, "
        f"{(summary.end_ns - summary.start_ns) / 1e9:.1f} s"
    )
    return 0
