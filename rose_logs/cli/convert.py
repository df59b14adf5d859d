"""``rose-bag convert LOG OUT``: a CARMEN laser log as a ROS mapping session (scans, poses, map snapshots)."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from rose.cli.options import (
    add_limit_arguments,
    file_arg,
    float_up_to,
    int_in_range,
    local_location,
    path_arg,
    resolution,
)
from rose.console import stderr_is_terminal
from rose.outputs import OutputSet, counted, refuse_output_in_bag_folder
from rose_logs.carmen.parse import MAX_STAMP_S, CarmenLog, check_carmen_file, read_carmen_log
from rose_logs.carmen.raycast import BuilderParams
from rose_logs.carmen.session import SessionOptions, write_carmen_session
from rose_logs.cli.options import UsageError, output_log_path
from rose_logs.errors import LogReadError, LogWriteError
from rose_logs.formats import format_from_path, suffix_mismatch_warning, unknown_suffix_warning

__all__ = ["add_parser", "run"]

#: Bounds of the options, beyond any sensible setting (larger values overflowed deep inside):
#: laser ranges in metres, log seconds (CARMEN timestamps are refused past 2^31 s) and
#: the drift's multiplier (the benchmark's levels are 0.5-4).
MAX_RANGE_M = 1e4
LATEST_S = float(MAX_STAMP_S)
MAX_DRIFT_LEVEL = 100.0


def add_parser(subparsers: Any) -> None:
    """Add the ``convert`` sub-command (CARMEN log -> ROS session) to argparse sub-parsers."""
    parser = subparsers.add_parser(
        "convert",
        help="turn a CARMEN laser log into a ROS mapping session (/scan, /tf or /odom, /map)",
        description="Parse a CARMEN log (.log or .log.gz), build occupancy-grid snapshots by ray "
        "casting, optionally add odometry drift, and write a ROS 1 bag, a ROS 2 bag (db3 or MCAP "
        "storage) or an MCAP file.",
    )
    parser.add_argument("log", type=path_arg, help="CARMEN log, plain or gzip")
    parser.add_argument(
        "output",
        type=local_location,
        help="*.bag (ROS 1), *.mcap, or a folder (ROS 2 bag: db3, or MCAP with --format mcap-dir)",
    )
    parser.add_argument(
        "--format",
        choices=("ros1", "db3", "mcap", "mcap-dir"),
        default=None,
        dest="fmt",
        help="output format (default: from the output name)",
    )
    parser.add_argument(
        "--resolution", type=resolution, default=0.05, help="map cell size, m (0.05)"
    )
    parser.add_argument(
        "--max-range",
        type=float_up_to(MAX_RANGE_M),
        default=30.0,
        help="readings at or beyond this are 'no return', m (30)",
    )
    parser.add_argument(
        "--map-period",
        type=float_up_to(LATEST_S),
        default=10.0,
        help="log seconds between /map snapshots (10)",
    )
    parser.add_argument(
        "--pose",
        choices=("tf", "odom", "both"),
        default="tf",
        help="pose output: /tf, /odom or both (tf)",
    )
    parser.add_argument(
        "--drift-level",
        type=float_up_to(MAX_DRIFT_LEVEL, zero=True),
        default=0.0,
        help=f"odometry drift level, 0 to {MAX_DRIFT_LEVEL:g} (default 0: the corrected poses; "
        "see rose_logs.carmen.drift)",
    )
    parser.add_argument(
        "--drift-seed", type=int_in_range(0, 2**32 - 1), default=0, help="seed of the drift (0)"
    )
    parser.add_argument(
        "--drift-start",
        type=float_up_to(LATEST_S, zero=True),
        default=0.0,
        help="seconds after the first scan when drift starts (0)",
    )
    parser.add_argument(
        "--max-scans",
        type=int_in_range(1, 2**62),
        default=None,
        metavar="N",
        help="use only the first N scans (N >= 1)",
    )
    parser.add_argument("-f", "--force", action="store_true", help="replace existing outputs")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_limit_arguments(parser)
    parser.add_argument(
        "--map-file",
        type=file_arg,
        default=None,
        help="also save the final map as map_server YAML + PGM at this path",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``convert`` from parsed arguments; prints a one-line summary to stdout. Returns 0.

    The session and ``--map-file`` (YAML + PGM) are committed together, or nothing is written.
    """
    if not args.max_range > BuilderParams.min_range_m:
        msg = (
            f"--max-range must be above the shortest reading kept, {BuilderParams.min_range_m:g} m"
        )
        raise UsageError(msg)
    check_carmen_file(args.log)  # a folder or a missing log first, not its outputs' place in it
    outputs = OutputSet(inputs=[args.log], force=args.force, ends_run=True)
    fmt = args.fmt or format_from_path(Path(args.output)) or "db3"
    args.output = output_log_path(args.output, fmt)
    # No bag folder is exempt: a CARMEN log is no recording, though it may lie in one.
    refuse_output_in_bag_folder(args.output, "OUTPUT")
    if args.map_file is not None and args.map_file.suffix.lower() not in (".yaml", ".yml"):
        msg = f"{args.map_file}: --map-file names the map's YAML (its image goes beside it as .pgm)"
        raise UsageError(msg)
    refuse_output_in_bag_folder(args.map_file, "--map-file", what="map file")
    from rose.mapfile import map_image_path  # with numpy: not at the CLI's start-up

    map_files = (args.map_file, map_image_path(args.map_file)) if args.map_file is not None else ()
    for image in map_files[1:]:  # a symlink where the image goes is followed
        refuse_output_in_bag_folder(image, "--map-file", what="map's image")
    folder = fmt in ("db3", "mcap-dir")
    outputs.check(args.output, directory=folder)
    if folder:  # before the map's own checks: `bag --map-file bag/m.yaml` said bag did not exist
        _check_apart(Path(args.output), map_files)
    # The session against the map's YAML and image too, now: staging the map at the end found a
    # clash only after the whole log was ray cast (`out.pgm --format mcap --map-file out.yaml`).
    outputs.check(None if folder else args.output, *map_files)
    if args.map_file is not None:  # save_map's own refusals, now rather than after the ray casting
        from rose.errors import MapFileError
        from rose.mapfile import map_output_problem

        problem = map_output_problem(args.map_file)
        if problem is not None:  # exit 1, as `rose clean -o` to a FIFO
            raise MapFileError(problem)
    # After the checks: an output refused anyway (the input itself, `convert p.log p.log`) is
    # refused alone, not warned about first.
    _warn_of_suffix(args)
    log = read_carmen_log(args.log, max_scans=args.max_scans)  # warns of malformed lines itself
    _check_extent(log, args)
    with outputs:
        try:
            options = SessionOptions(
                builder_params=BuilderParams(
                    resolution_m=args.resolution,
                    max_range_m=args.max_range,
                    max_cells=args.max_cells,
                ),
                map_period_s=args.map_period,
                pose_output=args.pose,
                drift_level=args.drift_level,
                drift_seed=args.drift_seed,
                drift_start_s=args.drift_start,
            )
            with _scan_progress(
                len(log.scans), enabled=not args.quiet and stderr_is_terminal()
            ) as progress:
                summary = write_carmen_session(
                    log,
                    args.output,
                    fmt=args.fmt,
                    options=options,
                    force=args.force,
                    outputs=outputs,
                    progress=progress,
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
                outputs=outputs,
            )
    duration_s = (summary.end_ns - summary.start_ns) / 1e9
    if args.drift_level > 0 and args.drift_start > duration_s:
        print(
            f"warning: {args.log}: --drift-start {args.drift_start:g} s is after the session's "
            f"last scan (+{duration_s:.1f} s): no drift was applied",
            file=sys.stderr,
        )
    clock = "" if summary.clock == "log" else f" ({summary.clock} clock)"
    print(
        f"{summary.path}: {summary.format}, {counted(summary.scans, 'scan')}, "
        f"{counted(summary.maps, 'map')}, "
        f"{duration_s:.1f} s{clock}"
    )
    return 0


def _check_apart(folder: Path, files: tuple[Path, ...]) -> None:
    """Refuse a ``--map-file`` YAML or image that is the session's bag folder or lies inside it."""
    from rose.errors import OutputError

    # realpath, not resolve: a symlink loop raised a RuntimeError (a traceback); the output check
    # names it.
    here = Path(os.path.realpath(folder))
    for path in files:
        there = Path(os.path.realpath(path))
        if there == here or here in there.parents:
            also = "(each needs a file of its own)" if there == here else f"(also inside {folder})"
            msg = f"{path}: given for two outputs {also}"
            raise OutputError(msg)


def _warn_of_suffix(args: argparse.Namespace) -> None:
    """Warn on stderr of an output suffix that names no format, or another than ``--format``,
    and of drift options given without a drift level."""
    warning = (
        suffix_mismatch_warning(args.output, args.fmt)
        if args.fmt
        else unknown_suffix_warning(args.output, "as a ROS 2 db3 bag folder")
    )
    if (
        warning is not None
    ):  # a typo (out.mcpa), or --format ros1 -o x.mcap, should not pass unnoticed
        print(warning, file=sys.stderr)
    if args.drift_level == 0 and (args.drift_start != 0 or args.drift_seed != 0):
        # Without a level the poses are the corrected ones: a user who meant a drifted session
        # would otherwise get a correct one and take it for drifted.
        print(
            f"warning: {args.log}: --drift-start and --drift-seed take effect with --drift-level "
            "only: the session has the corrected poses, no drift",
            file=sys.stderr,
        )


@contextlib.contextmanager
def _scan_progress(total: int, *, enabled: bool) -> Iterator[Callable[[int, int], None]]:
    """A progress bar over the ``total`` scans on stderr (ray casting a long log takes a while),
    gone when done; what is logged meanwhile goes above it."""
    from tqdm import tqdm

    from rose_logs.session.held_logs import said_above_bar

    with (
        tqdm(total=total, unit="scan", disable=not enabled, dynamic_ncols=True, leave=False) as bar,
        said_above_bar(enabled),
    ):

        def update(done: int, _total: int) -> None:  # the total is known from the start
            bar.update(done - bar.n)

        yield update


#: A count of cells said only as "over" this: beyond it a count is no float (and no map).
_UNCOUNTED_CELLS = 1e300


def _check_extent(log: CarmenLog, args: argparse.Namespace) -> None:
    """Refuse, before any allocation, a map larger than ``--max-cells`` (poses far apart, tiny cells)."""
    import numpy as np  # not at the CLI's start-up

    from rose.mapfile import MAX_ORIGIN_M

    poses = log.laser_poses[:, :2]
    # The map reaches a reading's range (and a margin) beyond the poses: its origin must stay
    # where ROS tools place maps (process refuses an origin beyond, and poses of 1e15 m and more
    # broke the ray casting's arithmetic).
    reach = args.max_range + 10.0
    far = np.abs(poses).max(axis=1) + reach
    if not far.max() <= MAX_ORIGIN_M:
        i = int(np.argmax(~(far <= MAX_ORIGIN_M)))
        x, y = (float(v) for v in poses[i])
        msg = (
            f"{args.log}: scan {i + 1} is at ({x:.12g}, {y:.12g}) m: a map around it would lie "
            f"beyond +-{MAX_ORIGIN_M:g} m of the origin, where no map is placed"
        )
        raise LogReadError(msg)
    span = poses.max(axis=0) - poses.min(axis=0) + 2 * reach
    # Cells per side: past a float's range on tiny cells (--resolution 5e-324), or their product
    # is (1e-300: an int of 600 digits, which the message could not format as a float).
    sides = (float(v) / args.resolution for v in span)
    cells = math.prod(math.ceil(n) if math.isfinite(n) else math.inf for n in sides)
    if cells > args.max_cells:
        count = f"up to {cells:.3g}" if cells < _UNCOUNTED_CELLS else f"over {_UNCOUNTED_CELLS:g}"
        msg = (
            f"{args.log}: the map could have {count} cells ({span[0]:.4g} x {span[1]:.4g} m "
            f"at {args.resolution:g} m: the poses' span and --max-range {args.max_range:g} m plus "
            f"10 m on every side), more than --max-cells {args.max_cells:,}"
        )
        raise LogReadError(msg)
