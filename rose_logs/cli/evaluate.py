"""``rose-bag evaluate OUT_DIR``: the paper's experiments (and ours) as a report with tables and figures."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rose.cli.options import int_in_range, out_path_arg, path_arg
from rose_logs.datasets import ENV_VAR, DataSetError
from rose_logs.evaluation.config import (
    BENCHMARK_SUBDIR,
    LOGS_SUBDIR,
    EvaluationConfig,
    log_name,
)

__all__ = ["add_parser", "config_from_args", "run"]


def _items(value: str) -> list[str]:
    """The comma-separated items of ``value``, stripped; none when every item is empty (``""``,
    ``","``). One empty item among others (``1,,2``, ``aces,``) is a usage error: ``--counts 1,,2``
    ran with counts 1 and 2, silently."""
    items = [v.strip() for v in value.split(",")]
    if not any(items):  # "", " " or only commas: no items (an empty --logs runs no experiment)
        return []
    if "" in items:
        msg = f"an empty item in {value[:40]!r} (two commas in a row, or one at an end)"
        raise argparse.ArgumentTypeError(msg)
    return items


def _csv(value: str) -> tuple[str, ...]:
    """Comma-separated names, each once (a name given twice would run, and be tabled, twice)."""
    return tuple(dict.fromkeys(_items(value)))


def _log_names(value: str) -> tuple[str | Path, ...]:
    """Log names, also as their files are called (``aces-corrected.log.gz`` is ``aces``; see
    :meth:`EvaluationConfig.log_path`), and paths to CARMEN logs anywhere (an item with a ``/``,
    or a file in the current folder: ``--logs /data/intel.log``, ``--logs intel.log``), each
    named by its file's name (``intel``). Two logs of one name are a usage error: their maps,
    tables and figures would take each other's place; so is an ``@`` in a name, which names a
    log's drifted maps (``intel@1.0``)."""
    logs: dict[str, str | Path] = {}
    for item in _csv(value):
        log: str | Path = item
        if any(sep and sep in item for sep in (os.sep, os.altsep)) or Path(item).is_file():
            log = Path(item)
            name = log_name(log.name)
        else:
            name = log_name(item)  # (the item as typed is kept: an error names it)
        if not name:
            msg = f"{item!r}: no log name in it (a log's file, or a name such as aces)"
            raise argparse.ArgumentTypeError(msg)
        if "@" in name:  # (x@1.0.log's map and x.log's at drift 1.0 would be one)
            msg = (
                f"{item!r}: a log named {name!r}: '@' names a log's drifted maps (LOG@LEVEL); "
                "give it under a name without '@'"
            )
            raise argparse.ArgumentTypeError(msg)
        known = logs.setdefault(name, log)
        # One file given twice (by an absolute and a relative path, through a link) runs once.
        if isinstance(known, Path) != isinstance(log, Path) or (
            isinstance(known, Path) and isinstance(log, Path) and not _same_file(known, log)
        ):
            msg = (
                f"two logs named {name!r} ({known}, {log}): their maps and tables would take "
                "each other's place; give one of them under another name"
            )
            raise argparse.ArgumentTypeError(msg)
    return tuple(logs.values())


def _same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` name one file (a missing one by its resolved path)."""
    try:
        return a.samefile(b)
    except OSError:
        return _resolved(a) == _resolved(b)


def _resolved(path: Path | str) -> Path:
    """``path`` resolved as ``Path.resolve`` does, also a symlink loop (which it raised as a
    RuntimeError, a traceback; the output and input checks then say what is wrong)."""
    return Path(os.path.realpath(path))


def _map_names(value: str) -> tuple[str, ...]:
    """Benchmark map names, also as their files are called (``Freiburg79_scan.png`` or its
    ``_furnitures.png`` drawing is ``Freiburg79_scan``)."""
    names = (v.removesuffix(".png").removesuffix("_furnitures") for v in _csv(value))
    return tuple(dict.fromkeys(names))


#: Bounds of the experiment options. The paper's ranges (``--config full``) are sizes 2..39 px and
#: counts 20..180 per map; far larger values only make each map slower to build and analyse (an
#: obstacle of 100000 px, 1e8 obstacles) without telling anything new.
MAX_SIZE_PX = 200
MAX_COUNT = 1000
MAX_LIST_VALUES = 50
MAX_BREAK_SEEDS = 20
MAX_SEED = 2**32 - 1


def _ints(low: int, high: int) -> Callable[[str], tuple[int, ...]]:
    """argparse type: comma-separated integers in ``low..high``, at most :data:`MAX_LIST_VALUES`."""

    def parse(value: str) -> tuple[int, ...]:
        items = _items(value)
        if not items:
            msg = f"expected at least one integer, got {value[:40]!r}"
            raise argparse.ArgumentTypeError(msg)
        if len(items) > MAX_LIST_VALUES:
            msg = f"at most {MAX_LIST_VALUES} values, got {len(items)}"
            raise argparse.ArgumentTypeError(msg)
        try:
            numbers = tuple(dict.fromkeys(int(v, 10) for v in items))
        except ValueError as err:
            msg = f"expected comma-separated integers, got {value[:40]!r}"
            raise argparse.ArgumentTypeError(msg) from err
        bad = [n for n in numbers if not low <= n <= high]
        if bad:
            msg = f"each value must be in {low}..{high}, got {bad[0]}"
            raise argparse.ArgumentTypeError(msg)
        return numbers

    parse.__name__ = "integers"  # argparse names the type in its messages
    return parse


def _configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "out_dir",
        type=out_path_arg,
        help="report folder (written whole at the end; an earlier report there is replaced with --force)",
    )
    parser.add_argument(
        "-f", "--force", action="store_true", help="replace an earlier report in OUT_DIR"
    )
    parser.add_argument(
        "--config",
        choices=("small", "full"),
        default="small",
        help="small (the default): 1 log + 1 benchmark map, 12 clutter maps each (5-10 s); "
        "full: 5 logs + 19 benchmark maps, 243 clutter maps each, 3 drift levels x 3 seeds",
    )
    parser.add_argument(
        "--seed",
        type=int_in_range(0, MAX_SEED),
        default=None,
        help="base seed, 0..2**32-1 (default 2021)",
    )
    parser.add_argument(
        "--maps-dir",
        type=path_arg,
        default=None,
        help=f"folder with {LOGS_SUBDIR}/ and {BENCHMARK_SUBDIR}/ "
        f"(default: ${ENV_VAR}, else ../shared/maps beside the source checkout)",
    )
    parser.add_argument(
        "--logs",
        type=_log_names,
        default=None,
        help=f"comma-separated Radish logs (aces, intel...), the names of other CARMEN logs "
        f"in {LOGS_SUBDIR}/ (csail-corrected.head400.log.gz), or paths to CARMEN logs anywhere "
        "(/data/intel.log, ./intel.log.gz; a file in the current folder is taken first), each "
        "named by its file (intel)",
    )
    parser.add_argument(
        "--maps",
        type=_map_names,
        default=None,
        help="comma-separated benchmark maps (Freiburg79_scan...; their file names too)",
    )
    parser.add_argument(
        "--sizes",
        type=_ints(1, MAX_SIZE_PX),
        default=None,
        help=f"comma-separated obstacle sizes in px, each 1..{MAX_SIZE_PX} (small: 4,20; full: "
        f"2..39), at most {MAX_LIST_VALUES} values",
    )
    parser.add_argument(
        "--counts",
        type=_ints(1, MAX_COUNT),
        default=None,
        help=f"comma-separated obstacle counts per map, each 1..{MAX_COUNT} (small: 20,100; full: "
        f"20..180), at most {MAX_LIST_VALUES} values",
    )
    parser.add_argument(
        "--break-seeds",
        type=int_in_range(0, MAX_BREAK_SEEDS),
        default=None,
        help="experiment 4 (break detection on replayed sessions): seeds per log, drift level "
        f"and start, 0..{MAX_BREAK_SEEDS} (small: 0 = skipped, full: 3)",
    )
    parser.add_argument(
        "--no-plots",
        action="store_true",
        help="write no figures: no plots (matplotlib), no wall_error.png, no "
        "cleaning_before_after.png; the rasterised logs map_*.png are data and still written",
    )


def add_parser(subparsers: Any) -> None:
    """Add the ``evaluate`` sub-command to an ``argparse`` sub-parser collection."""
    parser = subparsers.add_parser(
        "evaluate",
        help="reproduce the paper's experiments on real maps and logs, and measure ours",
        description="Run the paper's clutter-sensitivity, broken-map and confidence experiments, "
        "the wall extraction's error, the cleaning benchmark (walls kept, clutter removed, robot "
        "gaps) and the break detector on replayed sessions (experiment 4), and write a markdown "
        "report with CSV tables and PNG figures.",
    )
    _configure(parser)
    parser.set_defaults(func=run)


def config_from_args(args: argparse.Namespace) -> EvaluationConfig:
    """The :class:`EvaluationConfig` an ``evaluate`` command line asks for."""
    changes: dict[str, object] = {}
    for attr, field in (
        ("seed", "seed"),
        ("maps_dir", "maps_dir"),
        ("logs", "logs"),
        ("maps", "benchmark_maps"),
        ("sizes", "sizes_px"),
        ("counts", "counts"),
        ("break_seeds", "break_seeds"),
    ):
        value = getattr(args, attr, None)
        if value is not None and attr == "logs":
            logs: tuple[str | Path, ...] = value
            changes["logs"] = tuple(
                log_name(log.name if isinstance(log, Path) else log) for log in logs
            )
            changes["log_files"] = tuple(
                (log_name(log.name), log) for log in logs if isinstance(log, Path)
            )
        elif value is not None:
            changes[field] = value
    if getattr(args, "no_plots", False):
        changes["plots"] = False
    base = EvaluationConfig.full() if args.config == "full" else EvaluationConfig.small()
    return dataclasses.replace(base, **changes)  # type: ignore[arg-type]


def run(args: argparse.Namespace) -> int:
    """Run the evaluation the parsed arguments ask for; print the report path. Returns 0.

    The report is written in a temporary folder beside ``out_dir`` and moved into place when complete:
    an interrupted or failed run leaves no half report, and the data set is never written to.

    Raises
    ------
    rose_logs.evaluation.files.ReportWriteError
        If a file of the report cannot be written; it names the file in ``out_dir``, not in the
        temporary folder, and nothing is committed.
    """
    from rose.outputs import OutputSet, refuse_output_in_bag_folder
    from rose_logs.evaluation.files import ReportWriteError
    from rose_logs.evaluation.report import MARKDOWN_NAME, run_evaluation

    config = config_from_args(args)
    if not config.logs and not config.benchmark_maps:
        # Empty lists run no experiment (a quick check of the report's files); said, so that an
        # unset shell variable (`--logs $LOGS`) is not mistaken for an evaluation.
        print(
            "warning: --logs and --maps are both empty: no experiment runs, the tables stay empty",
            file=sys.stderr,
        )
    # The data set is read, never written (data_root raises DataSetError, one line, if it is
    # absent). A --maps-dir given is looked up though nothing is read from it: a typo
    # (`--maps-dir dat`) was taken silently.
    _refuse_missing_log_files(args, config)
    reads = bool(config.data_logs or config.benchmark_maps)
    if reads or config.maps_dir is not None:
        data_root: Path | None = config.data_root
    else:  # nothing read from it, but a data folder found is never written into either
        try:
            data_root = config.data_root
        except DataSetError:
            data_root = None
    # Protected even when no experiment reads it (`--logs '' --maps ''`, or logs given as paths):
    # the report of such a run was written into $ROSE_DATA_DIR.
    inputs = [data_root] if data_root is not None else []
    # And the sub-folders read, each in its own right: one may be a symlink out of the data folder
    # (a shared copy of the benchmark), and the report was written inside its target.
    inputs += [config.logs_dir] if config.data_logs else []
    inputs += [path for _, path in config.log_files]  # logs given as files, anywhere
    inputs += [config.benchmark_dir] if config.benchmark_maps else []
    # A report folder's parents are made, as `batch` makes OUT's (`evaluate out/eval` in a fresh
    # checkout), but never inside the data set (the output check refuses that path next); a path
    # through a file stays an error of the output check.
    # Nor inside a ROS 2 bag folder (a recording; `-o bag --force` would delete the report with it).
    refuse_output_in_bag_folder(args.out_dir, "OUT_DIR", what="report folder", inputs=inputs)
    parent = _resolved(args.out_dir).parent
    made: list[Path] = []  # the folders this run made, deepest first
    if not any(parent.is_relative_to(_resolved(i)) for i in inputs):
        made = _make_folders(parent)
    try:
        with OutputSet(inputs=inputs, force=args.force, ends_run=True) as outputs:
            staged = outputs.stage(args.out_dir, directory=True, replaceable=is_report_folder)
            assert staged.temp is not None  # a folder output is never a stream
            try:
                run_evaluation(config, staged.temp, progress=lambda m: print(m, file=sys.stderr))
            except ReportWriteError as err:  # raised inside `with`: the staged report is removed
                raise err.relocated(staged.temp, args.out_dir) from err
    except BaseException:
        # No report: the folders made for it go too (an interrupted run left `a/b/` behind).
        for folder in made:
            with contextlib.suppress(OSError):
                folder.rmdir()  # only while empty
        raise
    print(args.out_dir / MARKDOWN_NAME)
    return 0


def _refuse_missing_log_files(args: argparse.Namespace, config: EvaluationConfig) -> None:
    """Raise DataSetError for a log's file name typed (``--logs intel.log``) that is neither a
    file here nor in the data folder, naming it as typed (the error named the Radish file
    looked for, ``intel-corrected.log.gz``, or said only that there was no data set)."""
    for item in getattr(args, "logs", None) or ():
        if not isinstance(item, str) or not item.endswith((".log", ".gz")):
            continue  # a path (read as given), or a log's name
        try:
            if config.log_path(log_name(item)).is_file():
                continue
            where = f"here or in {config.logs_dir}"
        except DataSetError:
            where = f"here, and no data folder to look in (${ENV_VAR}, --maps-dir)"
        msg = f"{item}: no such file, {where} (--logs)"
        raise DataSetError(msg)


def _make_folders(folder: Path) -> list[Path]:
    """Make ``folder`` and its missing parents, one level at a time; return those this call made,
    deepest first (one that another process makes meanwhile is not ours to remove). Errors are
    left to the output check, which names them."""
    missing = [p for p in (folder, *folder.parents) if not p.exists()]
    made: list[Path] = []
    for level in reversed(missing):
        try:
            level.mkdir()
        except FileExistsError:
            continue
        except OSError:
            break
        made.append(level)
    return made[::-1]


def is_report_folder(path: Path) -> bool:
    """Whether ``path`` is empty or holds an earlier ``evaluate`` report and nothing else
    (``--force`` may replace only that): its ``report.md`` says so in its title, and every entry is
    a file of the kinds a report holds (no sub-folder, no notes of the user's)."""
    import os
    import re

    from rose_logs.evaluation.report import MARKDOWN_NAME

    try:
        entries = list(os.scandir(path))
    except OSError:
        return False
    if not entries:
        return True  # nothing to lose
    try:
        with (path / MARKDOWN_NAME).open("rb") as fh:
            title = fh.read(64)
    except OSError:
        return False
    # Any name of those kinds: a log's own name is in its map's (`map_my log.png`), and a report
    # of `--logs "my log.log"` was no report of ours to replace.
    kinds = re.compile(r".+\.(?:csv|png|md)", re.DOTALL)
    return title.startswith(b"# ROSE evaluation") and all(
        e.is_file(follow_symlinks=False) and kinds.fullmatch(e.name) for e in entries
    )
