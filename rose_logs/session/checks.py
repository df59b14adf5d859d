"""The checks of :func:`~rose_logs.session.process_log`'s arguments, before any work: an argument
of the wrong kind or a parameter out of range is one :class:`rose.RoseError` naming it, before the
input is read (not a traceback from inside the session, nor one error per map)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NamedTuple

import rose
from rose.cleaning import CLEAN_METHODS, CleanMethod
from rose.limits import cell_limit, finite_number, integer_number
from rose.outputs import OutputSet
from rose.params import RoseParams, make_params
from rose.result import RoseResult
from rose_logs.reader import topic_names
from rose_logs.session.breaks import BreakParams
from rose_logs.session.report import SnapshotRecord
from rose_logs.snapshots import MapSnapshot

__all__ = ["CheckedArguments", "check_arguments"]


class CheckedArguments(NamedTuple):
    """The arguments :func:`check_arguments` gives in the form the session uses."""

    input_path: Path
    topics: tuple[str, ...] | None
    params: RoseParams
    break_params: BreakParams
    max_cells: int | None


def check_arguments(
    input_path: Path,
    *,
    output_path: Path | None,
    rrd_path: Path | None,
    on_snapshot: Callable[[MapSnapshot, RoseResult, SnapshotRecord], None] | None,
    on_outputs_ready: Callable[[], None] | None,
    outputs: OutputSet | None,
    salvage: bool,
    topics: Sequence[str] | None,
    params: RoseParams | None,
    break_params: BreakParams | None,
    failure_level: float,
    analysis_threads: int,
    max_cells: int | None,
    clean_method: CleanMethod,
) -> CheckedArguments:
    """:func:`~rose_logs.session.process_log`'s arguments checked, in its order: the input as a
    path, the topics as a tuple of names (None: every map topic), the ROSE parameters, the break
    detector's (default: following the occupied threshold) and the cell limit as an int or None.

    Raises
    ------
    RoseError
        On the first argument of the wrong kind or out of range.
    """
    # Arguments of the wrong kind, before any work: a callback that is not callable failed after
    # the first snapshot was analysed, an int path in pathlib, outputs=... with an AttributeError.
    for name, path in (("input_path", input_path), ("output_path", output_path)):
        if not (isinstance(path, str | os.PathLike) or (path is None and name != "input_path")):
            msg = f"{name} must be a file or folder name (str or path), got {type(path).__name__}"
            raise rose.RoseError(msg)
    if rrd_path is not None and not isinstance(rrd_path, str | os.PathLike):
        msg = f"rrd_path must be a file name (str or path), got {type(rrd_path).__name__}"
        raise rose.RoseError(msg)
    for name, hook in (("on_snapshot", on_snapshot), ("on_outputs_ready", on_outputs_ready)):
        if hook is not None and not callable(hook):
            msg = f"{name} must be callable, got {type(hook).__name__}"
            raise rose.RoseError(msg)
    if outputs is not None and not isinstance(outputs, OutputSet):
        msg = f"outputs must be a rose.outputs.OutputSet, got {type(outputs).__name__}"
        raise rose.RoseError(msg)
    if salvage not in (True, False):  # salvage="no" salvaged
        msg = f"salvage must be True or False, got {salvage!r}"
        raise rose.RoseError(msg)
    input_path = Path(input_path)
    try:  # one name is one topic, not its characters; b"/map" was its bytes' numbers
        topics = topic_names(topics)
    except TypeError as err:
        raise rose.RoseError(str(err)) from None
    params = make_params(params)  # a RoseParams, or a RoseError saying what it got
    if break_params is None:
        break_params = BreakParams.following(params.occupied_threshold)
    if not isinstance(break_params, BreakParams):
        msg = f"break_params must be a BreakParams, got {type(break_params).__name__}"
        raise rose.RoseError(msg)
    # Parameters before the log is read: one error, not one per map (the CLI's ranges).
    if not (finite_number(failure_level) and 0 < failure_level <= 1):
        msg = f"failure_level must be a number in (0, 1], got {failure_level!r}"
        raise rose.RoseError(msg)
    if not (integer_number(analysis_threads) and analysis_threads >= 1):
        msg = f"analysis_threads must be an integer >= 1, got {analysis_threads!r}"
        raise rose.RoseError(msg)
    try:
        max_cells = cell_limit(max_cells)
    except ValueError as err:
        raise rose.RoseError(str(err)) from None
    if clean_method not in CLEAN_METHODS:
        msg = f"clean_method must be one of {', '.join(CLEAN_METHODS)}, got {clean_method!r}"
        raise rose.RoseError(msg)
    return CheckedArguments(input_path, topics, params, break_params, max_cells)
