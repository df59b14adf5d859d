"""``rose-bag evaluate OUT_DIR``: the paper's experiments (and ours) as a report with tables and figures."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

from rose_logs.datasets import ENV_VAR
from rose_logs.evaluation.config import BENCHMARK_SUBDIR, LOGS_SUBDIR, EvaluationConfig

__all__ = ["add_parser", "config_from_args", "run"]


def _csv(value: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in value.split(",") if v.strip())


def _ints(value: str) -> tuple[int, ...]:
    try:
        return tuple(int(v) for v in _csv(value))
    except ValueError as err:
        msg = f"expected comma-separated integers, got {value!r}"
        raise argparse.ArgumentTypeError(msg) from err


def _configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("out_dir", type=Path, help="report folder (created; files overwritten)")
    parser.add_argument(
        "--config",
        choices=("small", "full"),
        default="small",
        help="small: 1 log + 1 benchmark map, 12 clutter maps each (seconds); "
        "full: 5 logs + 19 benchmark maps, 243 clutter maps each, 3 drift levels x 3 seeds",
    )
    parser.add_argument("--seed", type=int, default=None, help="base seed (default 2021)")
    parser.add_argument(
        "--maps-dir",
        type=Path,
        default=None,
        help=f"folder with {LOGS_SUBDIR}/ and {BENCHMARK_SUBDIR}/ "
        f"(default: ${ENV_VAR}, else ../shared/maps beside the source checkout)",
    )
    parser.add_argument("--logs", type=_csv, default=None, help="comma-separated Radish logs")
    parser.add_argument("--maps", type=_csv, default=None, help="comma-separated benchmark maps")
    parser.add_argument("--sizes", type=_ints, default=None, help="obstacle sizes in px")
    parser.add_argument("--counts", type=_ints, default=None, help="obstacle counts per map")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG figures")


def add_parser(subparsers: Any) -> None:
    """Add the ``evaluate`` sub-command to an ``argparse`` sub-parser collection."""
    parser = subparsers.add_parser(
        "evaluate",
        help="reproduce the paper's experiments on real maps and logs",
        description="Run the clutter-sensitivity, broken-map and confidence experiments and "
        "write a markdown report with CSV tables and PNG figures.",
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
    ):
        value = getattr(args, attr, None)
        if value is not None:
            changes[field] = value
    if getattr(args, "no_plots", False):
        changes["plots"] = False
    base = EvaluationConfig.full() if args.config == "full" else EvaluationConfig.small()
    return dataclasses.replace(base, **changes)  # type: ignore[arg-type]


def run(args: argparse.Namespace) -> int:
    """Run the evaluation the parsed arguments ask for; print the report path. Returns 0."""
    from rose_logs.evaluation.report import run_evaluation

    config = config_from_args(args)
    report = run_evaluation(config, args.out_dir, progress=lambda m: print(m, file=sys.stderr))
    print(report.markdown_path)
    return 0
