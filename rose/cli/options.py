"""Options and summaries shared by every ``rose`` and ``rose-bag`` command: one definition of the ROSE
tuning options (argparse types with range checks, so bad values are usage errors, exit 2)."""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from pathlib import Path
from typing import Any

from rose.directions import (
    FAILURE_LEVEL,
    MIN_JUDGED_CELLS,
    TRUST_LEVEL,
    map_frame_deg,
    w_judges,
)
from rose.errors import RoseError
from rose.grid import as_occupancy_grid
from rose.limits import DEFAULT_MAX_CELLS, MEMORY_PER_CELL, visible
from rose.mapfile import (
    DEFAULT_RESOLUTION_M,
    MAX_RESOLUTION_M,
    YAML_SUFFIXES,
    OccupancyMap,
    load_map,
)
from rose.params import (
    ANGULAR_RESOLUTION_RANGE_DEG,
    MAX_SMOOTHING_DEG,
    MAX_SPECTRUM_PX,
    RoseParams,
    make_params,
)
from rose.result import RoseResult

__all__ = [
    "add_limit_arguments",
    "add_map_arguments",
    "add_param_arguments",
    "cell_count",
    "directions_deg",
    "file_arg",
    "fraction",
    "int_in_range",
    "local_location",
    "map_arg",
    "names_folder",
    "non_negative_float",
    "out_path_arg",
    "params_from_args",
    "parse_args",
    "positive_float",
    "resolution_assumed",
    "result_summary",
    "verdict",
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


def resolution(text: str) -> float:
    """argparse type: metres per cell, a finite number in (0, :data:`MAX_RESOLUTION_M`], the range
    a map file may declare."""
    value = positive_float(text)
    if value > MAX_RESOLUTION_M:
        msg = f"expected metres per cell up to {MAX_RESOLUTION_M:g}, got {text!r}"
        raise argparse.ArgumentTypeError(msg)
    return value


def non_negative_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    value = _number(text)
    if value < 0:
        msg = f"expected a number >= 0, got {text!r}"
        raise argparse.ArgumentTypeError(msg)
    return value


def float_in(low: float, high: float) -> Any:
    """argparse type factory: a finite number in ``[low, high]`` (``low`` > 0)."""

    def parse(text: str) -> float:
        value = _number(text)
        if not low <= value <= high:
            msg = f"expected a number in [{_bound(low)}, {_bound(high)}], got {text!r}"
            raise argparse.ArgumentTypeError(msg)
        return value

    return parse


def float_up_to(high: float, *, zero: bool = False) -> Any:
    """argparse type factory: a finite number in ``(0, high]`` (``[0, high]`` with ``zero``).

    Values beyond any sensible setting are usage errors rather than overflows deep inside."""
    interval = f"{'[' if zero else '('}0, {_bound(high)}]"

    def parse(text: str) -> float:
        value = _number(text)
        # One wording on either side (--fail-above 0 said "a positive number", 1.5 "in (0, 1]").
        low_ok = value >= 0 if zero else value > 0
        if not low_ok or value > high:
            msg = f"expected a number in {interval}, got {text!r}"
            raise argparse.ArgumentTypeError(msg)
        return value

    return parse


def _bound(value: float) -> str:
    """A range's bound as written in its message: every digit a whole number has (``:g`` printed
    2**31 - 1 s as 2.14748e+09, a bound that seemed to be exceeded by 2147483000)."""
    return f"{value:.15g}"


#: argparse types: a number in (0, 1] and in [0, 1].
fraction = float_up_to(1.0)
unit_interval = float_up_to(1.0, zero=True)


def int_in_range(low: int, high: int) -> Any:
    """argparse type factory: an integer in ``[low, high]`` (usage error otherwise)."""

    def parse(text: str) -> int:
        stripped = text.strip()
        digits = stripped[1:] if stripped[:1] in ("+", "-") else stripped  # one sign at most
        try:
            value = int(text, 10) if len(text) <= 40 else None
        except ValueError:
            value = None
        if value is None and digits.isdigit():  # over 40 digits: no limit of ours is that large
            value = -(10**40) if text.strip().startswith("-") else 10**40
        readable = high < 2**40  # 2**62 is no bound to read: its range is said as ">= low"
        if value is not None and value > high and not readable:
            # Said as too large, with the limit: ">= 1" read as if the number were not an integer.
            msg = f"too large, got {text[:40]!r} (at most {_power_text(high)})"
            raise argparse.ArgumentTypeError(msg)
        if value is None or not low <= value <= high:
            span = f"in {low}..{high}" if readable else f">= {low}"
            msg = f"expected an integer {span}, got {text[:40]!r}"
            raise argparse.ArgumentTypeError(msg)
        return value

    parse.__name__ = "integer"
    return parse


def _power_text(number: int) -> str:
    """A large bound as it reads: ``2**62 = 4.6e+18`` for a power of two, else ``4.6e+18``."""
    if number & (number - 1) == 0:
        return f"2**{number.bit_length() - 1} = {number:.2g}"
    return f"{number:.2g}"


def path_arg(text: str) -> Path:
    """argparse type: a local file or folder path to read; an empty one is a usage error
    (``Path("")`` is the current folder, which made ``-o ""`` read as writing over the input), and
    so is a URL (``Path`` made ``s3://b/k.mcap`` the local ``s3:/b/k.mcap``: "no such file"), and
    ``-`` (:func:`_no_stdin`)."""
    return Path(
        _no_stdin(_local(text, "this command reads local files (only rose-bag batch reads URLs)"))
    )


def map_arg(text: str) -> Path:
    """argparse type: a map file to read (:func:`path_arg`, worded for the ``rose`` commands)."""
    return Path(_no_stdin(_local(text, "maps are read from local files")))


def _no_stdin(text: str) -> str:
    """``text``, unless it is ``-`` and no file is named so: an input is never standard input
    (``rose score - < map.pgm`` said "-: no such file", though ``-`` is standard output for
    outputs)."""
    if text == "-" and not os.path.lexists(text):
        msg = "'-': inputs are read from files, not standard input (./- names a file called '-')"
        raise argparse.ArgumentTypeError(msg)
    return text


def out_path_arg(text: str) -> Path:
    """argparse type: a local output file or folder (:func:`local_location`, as a ``Path``)."""
    return Path(local_location(text))


def local_location(text: str) -> str:
    """argparse type: a local output path, as given (``-`` too); not empty, not a URL."""
    return _local(text, _WRITES_LOCAL)


def file_arg(text: str) -> Path:
    """argparse type: the path of a local output *file*. A name ending in ``/`` names a folder:
    refused (``Path`` drops the slash, so ``--rrd out/`` wrote the file ``out``), and so is a URL."""
    if names_folder(text):
        msg = f"{text!r} names a folder (it ends with a separator): give a file name"
        raise argparse.ArgumentTypeError(msg)
    return out_path_arg(text)


_WRITES_LOCAL = "this command writes local files (only rose-bag batch writes to URLs)"

#: A URL as typed: a scheme and ``://`` (``s3://``, ``http://``, ``file://``).
_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")


def _local(text: str, why: str) -> str:
    """``text`` (:func:`location`) if it is no URL; a URL is a usage error naming it, as typed."""
    if _URL.match(text):
        msg = f"{text}: a URL; {why}"
        raise argparse.ArgumentTypeError(msg)
    return location(text)


def names_folder(text: str) -> bool:
    """Whether a path as typed (a ``str``: ``Path`` drops the slash) ends with a separator, or a
    separator and ``.`` (``out/``, ``out/.``): the user means a folder."""
    separators = [sep for sep in (os.sep, os.altsep) if sep]
    endings = (*separators, *(sep + "." for sep in separators))
    return len(text) > 1 and text.endswith(endings)


def location(text: str) -> str:
    """argparse type: a path or URL as given, not empty (``batch -o ""`` wrote into the current
    folder)."""
    if not text:
        msg = "expected a path, got an empty string"
        raise argparse.ArgumentTypeError(msg)
    return text


def cell_count(text: str) -> int:
    """argparse type: a positive number of cells, integer or float notation (``2e8``)."""
    value = positive_float(text)
    if value < 1 or value > 1e15 or value != int(value):
        msg = f"expected a whole number of cells in 1..1e15, got {text!r}"
        raise argparse.ArgumentTypeError(msg)
    return int(value)


def add_limit_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--max-cells`` (the largest grid accepted, :data:`rose.limits.DEFAULT_MAX_CELLS`)."""
    parser.add_argument(
        "--max-cells",
        type=cell_count,
        default=DEFAULT_MAX_CELLS,
        metavar="N",
        help="refuse grids of more than N cells, checked before allocating "
        f"(default %(default).0e; {MEMORY_PER_CELL})",
    )


def add_map_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of a command that reads a map file: ``--max-cells`` and ``--resolution``."""
    add_limit_arguments(parser)
    parser.add_argument(
        "--resolution",
        type=resolution,
        default=None,
        metavar="M",
        help=f"metres per cell of a bare image (no YAML; default {DEFAULT_RESOLUTION_M:g}, with a "
        "warning); a YAML map gives its own",
    )


def add_param_arguments(parser: argparse.ArgumentParser, *, writes_map: bool = True) -> None:
    """Add the ROSE tuning options (defaults from :class:`RoseParams`) to ``parser``; a command
    that writes no cleaned map (``writes_map=False``: ``rose score``) says --clutter-value does
    nothing there."""
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
        type=float_in(*ANGULAR_RESOLUTION_RANGE_DEG),
        default=d.angular_resolution_deg,
        metavar="DEG",
        help="direction bin width in degrees (default %(default)s)",
    )
    group.add_argument(
        "--smoothing",
        type=float_up_to(MAX_SMOOTHING_DEG, zero=True),
        default=d.smoothing_deg,
        metavar="DEG",
        help="angular smoothing of the cumulative amplitude (default %(default)s)",
    )
    group.add_argument(
        "--mask-half-width",
        type=float_up_to(MAX_SPECTRUM_PX),
        default=d.mask_half_width_px,
        metavar="PX",
        help="half-width of the spectrum strip kept per direction (default %(default)s)",
    )
    group.add_argument(
        "--occupied-threshold",
        type=int_in_range(1, 100),
        default=d.occupied_threshold,
        metavar="P",
        help="occupancy (percent) from which a cell is occupied (default %(default)s)",
    )
    group.add_argument(
        "--threshold-mode",
        choices=("gmm", "fixed"),
        default=None,
        help=f"gmm: Gaussian-mixture intersection (paper); fixed: --fixed-threshold (default "
        f"{d.threshold_mode}, fixed when --fixed-threshold is given)",
    )
    group.add_argument(
        "--fixed-threshold",
        type=unit_interval,
        default=None,
        metavar="F",
        help=f"fixed mode: cells scoring above F times the top score are structure (0 keeps every "
        f"cell that scores, 1 none; default {d.fixed_threshold:g}); implies --threshold-mode fixed",
    )
    group.add_argument(
        "--clutter-value",
        choices=("free", "unknown"),
        default=d.clutter_value,
        help=(
            "what clutter cells become in the cleaned map (default %(default)s)"
            if writes_map
            else "no effect here: this command writes no map (what clutter cells become in "
            "rose clean's; default %(default)s)"
        ),
    )
    group.add_argument(
        "--seed",
        type=int_in_range(0, 2**32 - 1),
        default=d.seed,
        help="0..2**32-1; no effect since the mixture fit is deterministic; kept for compatibility",
    )


def parse_args(parser: argparse.ArgumentParser, argv: Any) -> argparse.Namespace:
    """``parser.parse_args(argv)``, with the text of ``--help`` and ``--version`` flushed before
    their exit: standard output that cannot take it is an error line and exit 1 (``--help >
    /dev/full``), a reader that left exit 141, as for any other output (Python's flush at exit
    printed ``Exception ignored ... OSError`` and exited 120)."""
    from rose.console import flush_stdout

    try:
        return parser.parse_args(argv)
    except SystemExit as done:
        if not done.code:  # --help / --version printed; a usage error wrote to stderr
            code = flush_stdout()
            if code:
                raise SystemExit(code) from None
        raise


def params_from_args(args: argparse.Namespace) -> RoseParams:
    """The :class:`RoseParams` given by the options of :func:`add_param_arguments`.

    ``--fixed-threshold`` alone selects the fixed mode (it was ignored without
    ``--threshold-mode fixed``); with ``--threshold-mode gmm`` it is an error.
    """
    d = RoseParams()
    mode, fixed = args.threshold_mode, args.fixed_threshold
    if fixed is not None and mode == "gmm":
        msg = "--fixed-threshold needs --threshold-mode fixed (the mixture picks its own threshold)"
        raise RoseError(msg)
    if mode is None:
        mode = "fixed" if fixed is not None else d.threshold_mode
    return make_params(
        peak_prominence=args.peak_prominence,
        angular_resolution_deg=args.angular_resolution,
        smoothing_deg=args.smoothing,
        mask_half_width_px=args.mask_half_width,
        occupied_threshold=args.occupied_threshold,
        threshold_mode=mode,
        fixed_threshold=d.fixed_threshold if fixed is None else fixed,
        clutter_value=args.clutter_value,
        seed=args.seed,
    )


def check_params(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Reject out-of-range ROSE options as a usage error (exit 2) of ``parser``, before any work.

    argparse checks each option's form; the ranges (and how options combine) are
    :class:`RoseParams`'s to check, once.
    """
    if not hasattr(args, "peak_prominence"):
        return
    try:
        params_from_args(args)
    except RoseError as err:
        parser.error(str(err))


def directions_deg(result: RoseResult, *, yaw_rad: float = 0.0) -> list[float]:
    """:func:`rose.directions.map_frame_deg` of the result's dominant directions."""
    return map_frame_deg(result.dominant_directions, yaw_rad=yaw_rad)


def result_summary(
    result: RoseResult,
    *,
    seconds: float | None = None,
    yaw_rad: float = 0.0,
    degenerate: str | None = None,
) -> dict[str, Any]:
    """JSON-ready summary of a result: W, directions (degrees, map frame), threshold, counts.

    ``degenerate`` says why the input is outside ROSE's domain
    (:func:`rose.directions.degenerate_input`, as ``rose-bag``'s records). There, and on a map of
    too few occupied cells, the structure ROSE found is not judged, as W is not (a solid block's
    directions are its rectangle's), and ``has_structure`` is None rather than True."""
    judged = (degenerate is None and w_judges(result.occupied_count)) or not result.has_structure
    summary: dict[str, Any] = {
        # Unrounded, as rose-bag's records: a gate or a comparison sees the W the tools decide on.
        "structure_score": result.structure_score,
        "has_structure": result.has_structure if judged else None,
        "degenerate": degenerate,
        "dominant_directions_deg": directions_deg(result, yaw_rad=yaw_rad),
        "threshold": None if math.isnan(result.threshold) else result.threshold,
        "occupied_cells": result.occupied_count,
        "clutter_cells": result.clutter_count,
        "shape": list(result.occupied.shape),
    }
    if seconds is not None:
        summary["seconds"] = round(seconds, 4)
    return summary


def verdict(
    score: float,
    *,
    occupied_cells: int | None = None,
    has_structure: bool = True,
    degenerate: str | None = None,
) -> str:
    """The paper's reading of W: trusted below TRUST_LEVEL, failed above FAILURE_LEVEL. A map
    without occupied cells, or in which ROSE found no dominant direction, has W = 1 by convention
    and nothing labelled: W says nothing about decluttering there. Nor does it on a map of a few
    occupied cells, or one whose input is ``degenerate`` (why, from
    :func:`rose.directions.degenerate_input`): a solid block or a thin strip reads a low W."""
    if occupied_cells == 0:
        return "no occupied cells: W says nothing about this map"
    nothing_labelled = "no dominant direction: nothing labelled, the map is kept as it is"
    if degenerate is not None and not has_structure:
        # The cause first, as the JSON's `degenerate` gives it (an 8 x 2 map read "no dominant
        # direction" in the table and "a side of 2 cells" in JSON).
        return f"{degenerate}: W says nothing about this map; {nothing_labelled}"
    if not has_structure:
        return nothing_labelled
    # The cause first here too: a 10 x 10 map of 5 occupied cells read "only 5 occupied cells" in
    # the table and "a side of 10 cells" in JSON.
    if degenerate is not None:
        return f"{degenerate}: W says nothing about this map"
    if occupied_cells is not None and not w_judges(occupied_cells):
        return (
            f"only {cells(occupied_cells, 'occupied')} (fewer than {MIN_JUDGED_CELLS}): "
            "W says nothing about this map"
        )
    if score < TRUST_LEVEL:
        return "structured: decluttering can be trusted"
    if score <= FAILURE_LEVEL:
        return "weak structure: check the result"
    return "little structure: decluttering has likely failed"


def cells(count: int, kind: str = "") -> str:
    """``"1 cell"``, ``"3 cells"``; with ``kind``: ``"1 unknown cell"``."""
    noun = "cell" if count == 1 else "cells"
    return f"{count} {kind} {noun}" if kind else f"{count} {noun}"


def resolution_assumed(path: str | Path, resolution_m: float | None) -> bool:
    """Whether the map at ``path`` gets :data:`rose.mapfile.DEFAULT_RESOLUTION_M` for want of any
    other: a bare image (no YAML) without ``--resolution``."""
    return resolution_m is None and Path(path).suffix.lower() not in YAML_SUFFIXES


def load_grid_map(
    path: str | Path,
    *,
    max_cells: int | None,
    resolution_m: float | None = None,
    metric: bool = True,
) -> OccupancyMap:
    """:func:`rose.load_map`, with the grid checked as ROSE will read it, so that a map whose values
    are no occupancy fails naming the file (a ``mode: raw`` image's grey values above 100 are no
    such values: load_map reads them as unknown, as Nav2 does).

    ``resolution_m`` sets the cell size of a bare image (``--resolution``); without it a bare image
    gets :data:`rose.mapfile.DEFAULT_RESOLUTION_M`, and a warning on stderr when the command works
    in metres (``metric``: cleaning rules, walls, the output YAML; W does not depend on it). A YAML
    map sets its own: giving ``resolution_m`` with one is an error rather than a silent override.
    """
    bare_image = Path(path).suffix.lower() not in YAML_SUFFIXES
    if resolution_m is not None and not bare_image:
        msg = f"{path}: --resolution is for bare images; a YAML map gives its own resolution"
        raise RoseError(msg)
    occupancy_map = load_map(path, resolution_m=resolution_m, max_cells=max_cells)
    try:
        as_occupancy_grid(occupancy_map.grid)
    except RoseError as err:
        text = str(err).rstrip(".")
        msg = f"{path}: {text[:1].lower()}{text[1:]}"
        raise RoseError(msg) from err
    if resolution_assumed(path, resolution_m) and metric:
        print(
            f"warning: {visible(str(path))}: no map YAML, assuming "
            f"{DEFAULT_RESOLUTION_M:g} m/cell (set it with --resolution)",
            file=sys.stderr,
        )
    return occupancy_map
